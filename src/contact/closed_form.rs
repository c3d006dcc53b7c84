//! A pair's squared distance and the edge-edge mollifier's argument with their gradients and
//! Hessians in closed form (the formulas of `distance::squared`, differentiated by hand), for
//! `Pair::derivatives`.
//!
//! Why: second-order dual numbers over a pair's 12 coordinates carry 157 numbers through every
//! product; on the creature with contact (`scenes/kck18/creature_contact_quick.ron`) copying them
//! took 16 % of the run and the pairs' derivatives about a quarter. Every formula here is a
//! quotient of products of cross and dot products of at most three difference vectors, so it is
//! differentiated over those (9 numbers) and mapped to the 12 coordinates.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use super::distance::DistanceType;

pub type Gradient = SVector<f64, 12>;
pub type Hessian = SMatrix<f64, 12, 12>;
type G9 = SVector<f64, 9>;
type H9 = SMatrix<f64, 9, 9>;

/// A value with its gradient and Hessian over up to three difference vectors.
struct Reduced {
    f: f64,
    g: G9,
    h: H9,
}

fn v3(x: [f64; 3]) -> Vector3<f64> {
    Vector3::new(x[0], x[1], x[2])
}

/// [a]x: [a]x b = a x b.
fn skew(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

fn set_block(h: &mut H9, i: usize, j: usize, m: &Matrix3<f64>) {
    h.fixed_view_mut::<3, 3>(3 * i, 3 * j).copy_from(m);
}

/// |u x v|^2 over the difference vectors in blocks bu, bv.
fn cross_squared(u: &Vector3<f64>, v: &Vector3<f64>, bu: usize, bv: usize) -> Reduced {
    let n = u.cross(v);
    // dn/du = -[v]x, dn/dv = [u]x; d2 n_k / du_i dv_j = eps_kij, and sum_k n_k eps_kij = -[n]x_ij.
    let (ju, jv) = (-skew(v), skew(u));
    let mut g = G9::zeros();
    g.fixed_rows_mut::<3>(3 * bu).copy_from(&(2.0 * ju.transpose() * n));
    g.fixed_rows_mut::<3>(3 * bv).copy_from(&(2.0 * jv.transpose() * n));
    let mut h = H9::zeros();
    let uv = 2.0 * ju.transpose() * jv - 2.0 * skew(&n);
    set_block(&mut h, bu, bu, &(2.0 * ju.transpose() * ju));
    set_block(&mut h, bv, bv, &(2.0 * jv.transpose() * jv));
    set_block(&mut h, bu, bv, &uv);
    set_block(&mut h, bv, bu, &uv.transpose());
    Reduced { f: n.norm_squared(), g, h }
}

/// n / d, from both with their derivatives.
fn quotient(n: &Reduced, d: &Reduced) -> Reduced {
    let (inv, q) = (1.0 / d.f, n.f / d.f);
    let g = (n.g - q * d.g) * inv;
    let cross = n.g * d.g.transpose();
    let h = (n.h - (cross + cross.transpose()) * inv + 2.0 * q * inv * d.g * d.g.transpose() - q * d.h) * inv;
    Reduced { f: q, g, h }
}

/// (w . (u x v))^2 / |u x v|^2, w, u, v in blocks 0, 1, 2: the squared distance of a point from
/// a plane, or of two lines.
fn plane_squared(w: &Vector3<f64>, u: &Vector3<f64>, v: &Vector3<f64>) -> Reduced {
    let n = u.cross(v);
    let s = w.dot(&n);
    let mut gs = G9::zeros();
    gs.fixed_rows_mut::<3>(0).copy_from(&n);
    gs.fixed_rows_mut::<3>(3).copy_from(&v.cross(w));
    gs.fixed_rows_mut::<3>(6).copy_from(&w.cross(u));
    // d(u x v)/du = -[v]x, d(u x v)/dv = [u]x, d(v x w)/dv = -[w]x.
    let mut hs = H9::zeros();
    for (i, j, m) in [(0, 1, -skew(v)), (0, 2, skew(u)), (1, 2, -skew(w))] {
        set_block(&mut hs, i, j, &m);
        set_block(&mut hs, j, i, &m.transpose());
    }
    let numerator = Reduced { f: s * s, g: 2.0 * s * gs, h: 2.0 * (gs * gs.transpose() + s * hs) };
    quotient(&numerator, &cross_squared(u, v, 1, 2))
}

/// |w x e|^2 / |e|^2, w, e in blocks 0, 1: the squared distance of a point from a line.
fn line_squared(w: &Vector3<f64>, e: &Vector3<f64>) -> Reduced {
    let mut g = G9::zeros();
    g.fixed_rows_mut::<3>(3).copy_from(&(2.0 * e));
    let mut h = H9::zeros();
    set_block(&mut h, 1, 1, &(2.0 * Matrix3::identity()));
    quotient(&cross_squared(w, e, 0, 1), &Reduced { f: e.norm_squared(), g, h })
}

/// Maps derivatives over difference vectors (block b is x[plus[b]] - x[minus[b]]) to the pair's
/// 12 coordinates.
fn lift(r: &Reduced, blocks: &[(usize, usize)]) -> (f64, Gradient, Hessian) {
    let mut g = Gradient::zeros();
    let mut h = Hessian::zeros();
    let signed = |b: usize| [(blocks[b].0, 1.0), (blocks[b].1, -1.0)];
    for (a, _) in blocks.iter().enumerate() {
        let ga = r.g.fixed_rows::<3>(3 * a);
        for (i, si) in signed(a) {
            let mut gi = g.fixed_rows_mut::<3>(3 * i);
            gi += si * ga;
        }
        for (b, _) in blocks.iter().enumerate() {
            let hab = r.h.fixed_view::<3, 3>(3 * a, 3 * b);
            for (i, si) in signed(a) {
                for (j, sj) in signed(b) {
                    let mut hij = h.fixed_view_mut::<3, 3>(3 * i, 3 * j);
                    hij += (si * sj) * hab;
                }
            }
        }
    }
    (r.f, g, h)
}

/// The squared distance by the formula of the features `t` at `x`, its gradient and Hessian.
pub fn squared(t: DistanceType, x: &[[f64; 3]; 4]) -> (f64, Gradient, Hessian) {
    let y = x.map(v3);
    let d = |i: usize, j: usize| y[i] - y[j];
    match t {
        DistanceType::PointPoint(i, j) => {
            let w = d(i, j);
            let mut h = H9::zeros();
            set_block(&mut h, 0, 0, &(2.0 * Matrix3::identity()));
            let mut g = G9::zeros();
            g.fixed_rows_mut::<3>(0).copy_from(&(2.0 * w));
            lift(&Reduced { f: w.norm_squared(), g, h }, &[(i, j)])
        }
        DistanceType::PointEdge(p, a, b) => lift(&line_squared(&d(p, a), &d(b, a)), &[(p, a), (b, a)]),
        DistanceType::PointPlane => lift(&plane_squared(&d(0, 1), &d(2, 1), &d(3, 1)), &[(0, 1), (2, 1), (3, 1)]),
        DistanceType::LineLine => lift(&plane_squared(&d(0, 2), &d(1, 0), &d(3, 2)), &[(0, 2), (1, 0), (3, 2)]),
    }
}

/// |ea x eb|^2 of two edges `[a0, a1, b0, b1]` (the mollifier's argument), its gradient and
/// Hessian.
pub fn edges_cross_squared(x: &[[f64; 3]; 4]) -> (f64, Gradient, Hessian) {
    let y = x.map(v3);
    lift(&cross_squared(&(y[1] - y[0]), &(y[3] - y[2]), 0, 1), &[(1, 0), (3, 2)])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::dual::{cross3, dot3, sub3};
    use num_dual::Dual2SVec64;
    use rand::{Rng, SeedableRng};

    /// Value, gradient and Hessian of `f` by second-order dual numbers.
    fn dual(f: impl Fn(&[[Dual2SVec64<12>; 3]; 4]) -> Dual2SVec64<12>, x: &[[f64; 3]; 4]) -> (f64, Gradient, Hessian) {
        let xd: [[Dual2SVec64<12>; 3]; 4] =
            std::array::from_fn(|i| std::array::from_fn(|k| Dual2SVec64::from_re(x[i][k]).derivative(3 * i + k)));
        let e = f(&xd);
        let g = e.v1.unwrap_generic(nalgebra::U1, nalgebra::Const::<12>).transpose();
        (e.re, g, e.v2.unwrap_generic(nalgebra::Const::<12>, nalgebra::Const::<12>))
    }

    /// The closed forms equal the dual numbers' derivatives of the same formulas, for every
    /// feature type and the mollifier's argument, on random pairs (to round-off).
    #[test]
    fn closed_forms_match_dual_numbers() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let types = [
            DistanceType::PointPoint(0, 2),
            DistanceType::PointPoint(1, 3),
            DistanceType::PointEdge(0, 1, 2),
            DistanceType::PointEdge(2, 0, 1),
            DistanceType::PointEdge(3, 1, 2),
            DistanceType::PointPlane,
            DistanceType::LineLine,
        ];
        for _ in 0..50 {
            let x: [[f64; 3]; 4] = std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
            for t in types {
                let (f, g, h) = squared(t, &x);
                let (fd, gd, hd) = dual(|y| super::super::distance::squared(t, y), &x);
                let scale = 1.0 + hd.abs().max();
                assert!((f - fd).abs() <= 1e-12 * (1.0 + fd.abs()), "{t:?}: {f} against {fd}");
                assert!((g - gd).abs().max() <= 1e-11 * scale, "{t:?}: gradient off by {}", (g - gd).abs().max());
                assert!((h - hd).abs().max() <= 1e-11 * scale, "{t:?}: Hessian off by {}", (h - hd).abs().max());
            }
            let (c, gc, hc) = edges_cross_squared(&x);
            let (cd, gcd, hcd) = dual(
                |y| {
                    let n = cross3(sub3(y[1], y[0]), sub3(y[3], y[2]));
                    dot3(n, n)
                },
                &x,
            );
            let scale = 1.0 + hcd.abs().max();
            assert!((c - cd).abs() <= 1e-12 * (1.0 + cd.abs()));
            assert!((gc - gcd).abs().max() <= 1e-11 * scale && (hc - hcd).abs().max() <= 1e-11 * scale);
        }
    }
}
