//! Zero-length springs (PHYSICS.md 1.5): E = 1/2 k |x_a - x_b|^2.

use glam::DVec3;

/// Energy of a zero-length spring between two points.
#[inline]
pub fn energy(k: f64, a: DVec3, b: DVec3) -> f64 {
    0.5 * k * (a - b).length_squared()
}

/// Gradient with respect to `a` (the gradient with respect to `b` is its negative).
/// The Hessian is k I on the (a, a) and (b, b) blocks and -k I off the diagonal.
#[inline]
pub fn gradient(k: f64, a: DVec3, b: DVec3) -> DVec3 {
    k * (a - b)
}
