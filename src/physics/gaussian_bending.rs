//! The Gaussian-curvature part of Kirchhoff's plate energy, which completes the quadratic
//! bending element (`quadratic_bending`). Per unit area the plate stores
//! D / 2 [(2H)^2 - 2 (1 - nu) K]; the quadratic element holds the first term. Alone it lets
//! an out-of-plane field that is harmonic in material space (a saddle, an edge wave) bend for
//! free; this term charges it (1 - nu) D |K|.
//!
//! Discretized by the angle defect: the integrated Gaussian curvature at an interior vertex is
//! 2 pi - sum of its corner angles (Meyer, Desbrun, Schroeder, Barr 2003), so the term is
//! (1 - nu) D_v (sum_corners theta - 2 pi) per interior vertex. It is split per triangle: each
//! corner at an interior vertex carries c = (1 - nu) D_v times its angle's change from rest.
//! The energy is not convex (a saddle raises it, a dome lowers it); in the continuum its sum
//! with the quadratic element is the plate's, positive for 0 <= nu < 1.

use glam::DVec3;
use nalgebra::{SMatrix, SVector};

use super::dual::{cross3, dot3, sub3, Dual, Real};
use super::psd::{project, Filter};
use super::QuadraticBending;

/// One triangle's share: corner k (at vertex v[k]) carries `weight[k]` (J per radian) times
/// its angle's change from `rest[k]` (zero weight at boundary vertices).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GaussianElem {
    pub v: [u32; 3],
    pub weight: [f64; 3],
    pub rest: [f64; 3],
}

/// The triangle's corner angles.
fn angles(x: &[DVec3; 3]) -> [f64; 3] {
    std::array::from_fn(|k| {
        let (a, b) = (x[(k + 1) % 3] - x[k], x[(k + 2) % 3] - x[k]);
        a.cross(b).length().atan2(a.dot(b))
    })
}

/// Each corner's share of the energy (J): its vertex's integrated Gaussian curvature, lost.
pub fn corner_energies(e: &GaussianElem, x: &[DVec3; 3]) -> [f64; 3] {
    let theta = angles(x);
    std::array::from_fn(|k| e.weight[k] * (theta[k] - e.rest[k]))
}

/// Energy (J).
pub fn energy(e: &GaussianElem, x: &[DVec3; 3]) -> f64 {
    corner_energies(e, x).iter().sum()
}

/// The gradient of the angle at p0 between p1 - p0 and p2 - p0: with a = p1 - p0,
/// b = p2 - p0, n = a x b, s = |n|, c = a . b, theta = atan2(s, c) and
/// d theta = (c ds - s dc) / (s^2 + c^2), ds/da = b x n / s, ds/db = n x a / s.
/// Returns (d/dp0, d/dp1, d/dp2).
fn angle_gradient<T: Real>(p: [[T; 3]; 3]) -> [[T; 3]; 3] {
    let (sub, dot, cross) = (sub3::<T>, dot3::<T>, cross3::<T>);
    let (a, b) = (sub(p[1], p[0]), sub(p[2], p[0]));
    let n = cross(a, b);
    let (s, c) = (dot(n, n).sqrt(), dot(a, b));
    let r2 = (s * s + c * c).recip();
    let (bn, na) = (cross(b, n), cross(n, a));
    // c / s (b x n) - s b, over r2: the s in ds cancels into c / s.
    let cs = c / s;
    let ga: [T; 3] = std::array::from_fn(|i| (cs * bn[i] - s * b[i]) * r2);
    let gb: [T; 3] = std::array::from_fn(|i| (cs * na[i] - s * a[i]) * r2);
    let g0 = std::array::from_fn(|i| -(ga[i] + gb[i]));
    [g0, ga, gb]
}

/// The element's weighted angle gradient, as 9 components.
fn gradient<T: Real>(e: &GaussianElem, x: [[T; 3]; 3], zero: T) -> [T; 9] {
    let mut g = [zero; 9];
    for k in 0..3 {
        if e.weight[k] == 0.0 {
            continue;
        }
        let corner = [k, (k + 1) % 3, (k + 2) % 3];
        let gk = angle_gradient(corner.map(|i| x[i]));
        for (j, &vertex) in corner.iter().enumerate() {
            for c in 0..3 {
                g[3 * vertex + c] = g[3 * vertex + c] + gk[j][c] * e.weight[k];
            }
        }
    }
    g
}

/// Energy, gradient and Hessian (the gradient differentiated by forward dual numbers). The
/// Hessian is indefinite by nature; `filter` projects it when the solve asks for that.
pub fn eval(e: &GaussianElem, x: &[DVec3; 3], filter: Filter) -> (f64, SVector<f64, 9>, SMatrix<f64, 9, 9>) {
    let xd: [[Dual<9>; 3]; 3] = std::array::from_fn(|v| std::array::from_fn(|k| Dual::variable(x[v][k], 3 * v + k)));
    let g = gradient(e, xd, Dual { re: 0.0, eps: [0.0; 9] });
    let grad = SVector::<f64, 9>::from_fn(|i, _| g[i].re);
    let mut h = SMatrix::<f64, 9, 9>::from_fn(|r, c| g[r].eps[c]);
    h = 0.5 * (h + h.transpose());
    if filter != Filter::Exact {
        project(&mut h, filter);
    }
    (energy(e, x), grad, h)
}

/// The elements of a layer's triangles `faces` (indices into `rest`, flat) for its quadratic
/// elements `q`: corner weights (1 - nu) D_v at the vertices that carry one.
pub fn elements(
    q: &QuadraticBending,
    faces: &[[u32; 3]],
    rest: impl Fn(u32) -> DVec3,
    poisson: f64,
) -> Vec<GaussianElem> {
    let mut rigidity = std::collections::HashMap::with_capacity(q.len());
    for i in 0..q.len() {
        rigidity.insert(q.stencil(i).0[0], q.k[i] * q.area[i]);
    }
    faces
        .iter()
        .filter_map(|f| {
            let weight = f.map(|v| rigidity.get(&v).map_or(0.0, |d| (1.0 - poisson) * d));
            (weight != [0.0; 3]).then(|| GaussianElem { v: *f, weight, rest: angles(&f.map(&rest)) })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shifted(x: &[DVec3; 3], i: usize, h: f64) -> [DVec3; 3] {
        let mut y = *x;
        y[i / 3][i % 3] += h;
        y
    }

    #[test]
    fn derivatives_match_central_differences() {
        let e = GaussianElem { v: [0, 1, 2], weight: [1.3, 0.0, 0.7], rest: [0.9, 1.1, 1.14] };
        for x in [
            [DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, 0.1, 0.2), DVec3::new(0.3, 0.9, -0.1)],
            // a sliver: one angle near pi
            [DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.5, 0.02, 0.01)],
        ] {
            let (_, g, h) = eval(&e, &x, Filter::Exact);
            let step = 1e-6;
            for i in 0..9 {
                let fd = (energy(&e, &shifted(&x, i, step)) - energy(&e, &shifted(&x, i, -step))) / (2.0 * step);
                assert!((fd - g[i]).abs() < 1e-6 * (1.0 + g.abs().max()), "gradient {i}: {fd} vs {}", g[i]);
                let (_, gp, _) = eval(&e, &shifted(&x, i, step), Filter::Exact);
                let (_, gm, _) = eval(&e, &shifted(&x, i, -step), Filter::Exact);
                let col = (gp - gm) / (2.0 * step);
                let err = (col - h.column(i)).abs().max();
                assert!(err < 1e-5 * (1.0 + h.abs().max()), "Hessian column {i}: {err}");
            }
        }
    }

    #[test]
    fn rigid_motions_cost_nothing() {
        let x = [DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, 0.2, 0.0), DVec3::new(0.4, 0.8, 0.0)];
        let e = GaussianElem { v: [0, 1, 2], weight: [1.0, 2.0, 3.0], rest: angles(&x) };
        let rot = glam::DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
        let moved = x.map(|p| rot * p + DVec3::new(0.3, -2.0, 5.0));
        assert!(energy(&e, &moved).abs() < 1e-14);
        // No net force or torque: the gradient is orthogonal to translations and rotations.
        let (_, g, _) = eval(&e, &moved, Filter::Exact);
        let gv: [DVec3; 3] = std::array::from_fn(|i| DVec3::new(g[3 * i], g[3 * i + 1], g[3 * i + 2]));
        assert!(gv.iter().sum::<DVec3>().length() < 1e-12);
        assert!(moved.iter().zip(&gv).map(|(p, f)| p.cross(*f)).sum::<DVec3>().length() < 1e-12);
    }
}
