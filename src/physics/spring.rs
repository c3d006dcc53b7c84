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

/// A zero-length anchor spring (KCK18 section 3) from a skin point, the weighted sum of `NV`
/// vertices (a vertex, or a face barycentre), to a body point `target` held fixed during a
/// solve: energy 1/2 k |sum_i w_i x_i - target|^2, gradient k w_i r per vertex, Hessian
/// k w_i w_j I per vertex pair. `N` = 3 NV.
pub(crate) fn anchor_eval<const NV: usize, const N: usize>(
    k: f64,
    w: &[f64; NV],
    x: &[DVec3; NV],
    target: DVec3,
) -> (f64, nalgebra::SVector<f64, N>, nalgebra::SMatrix<f64, N, N>) {
    debug_assert_eq!(N, 3 * NV);
    let r = (0..NV).map(|i| w[i] * x[i]).sum::<DVec3>() - target;
    let mut g = nalgebra::SVector::<f64, N>::zeros();
    let mut h = nalgebra::SMatrix::<f64, N, N>::zeros();
    for i in 0..NV {
        for c in 0..3 {
            g[3 * i + c] = k * w[i] * r[c];
            for j in 0..NV {
                h[(3 * i + c, 3 * j + c)] = k * w[i] * w[j];
            }
        }
    }
    (0.5 * k * r.length_squared(), g, h)
}
