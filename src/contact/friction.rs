//! Lagged friction (IPC: Li et al. 2020, sec. 5), for quasistatic frames: a pair touching at
//! the frame's start resists the tangential slip of its closest points over the frame,
//!   D = mu lambda f0(|u|),   u = P^T sum_i w_i (x_i - x0_i),
//! with the normal force lambda, the closest points' weights w (`distance::closest_weights`)
//! and the tangent basis P (2 columns) all fixed ("lagged") at the frame's start x0. IPC's
//! slip per time step h v becomes the slip per frame; f0 (IPC eq. 15) is |u| beyond the
//! sticking slip eps_u and a C1 smooth convex blend below it, so the friction force is
//! mu lambda where the pair slides and proportional to the slip where it sticks. D is convex in
//! x: its Hessian is PSD as it stands.

use glam::DVec3;
use nalgebra::{Matrix2, SMatrix, SVector, Vector2};

use super::distance::closest_weights;
use super::pair::Pair;
use super::{gather, Primitives};

/// f0(y): eps/3 + y^2/eps - y^3/(3 eps^2) below eps, y beyond (C1 at eps; f0(0) > 0 is a
/// constant that leaves the gradient alone).
pub fn f0(y: f64, eps: f64) -> f64 {
    if y < eps {
        eps / 3.0 + y * y / eps - y * y * y / (3.0 * eps * eps)
    } else {
        y
    }
}

/// f0'(y) / y (finite at 0: 2 / eps) and f0''(y).
fn slopes(y: f64, eps: f64) -> (f64, f64) {
    if y < eps {
        (2.0 / eps - y / (eps * eps), 2.0 / eps - 2.0 * y / (eps * eps))
    } else {
        (1.0 / y, 0.0)
    }
}

/// One lagged friction pair: a contact pair touching at the frame's start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrictionPair {
    pub v: [u32; 4],
    /// The closest points' weights at the frame's start.
    pub w: [f64; 4],
    /// The tangent plane there (orthonormal, normal to the closest points' offset).
    pub basis: [DVec3; 2],
    /// mu lambda: the friction coefficient times the normal force at the frame's start (N).
    pub force: f64,
    /// The four vertices at the frame's start.
    pub x0: [DVec3; 4],
}

impl FrictionPair {
    /// The pair `p`, touching at `x` under barrier stiffness `stiffness`; None when it is not
    /// within the barrier's reach there. lambda = |d (kappa b) / d d| (with the edge-edge
    /// mollifier's factor), the normal force the barrier exerts.
    pub fn lagged(p: &Pair, x: &[DVec3], stiffness: f64, mu: f64) -> Option<FrictionPair> {
        let y = gather(x, &p.v);
        let d2 = p.squared_distance(&y);
        if !p.barrier.active(d2) || stiffness <= 0.0 {
            return None;
        }
        let z = num_dual::Dual64::from_re(p.barrier.z(d2)).derivative();
        let mut lambda = stiffness * p.barrier.value(z).eps.abs() * 2.0 * d2.sqrt();
        if p.kind == Primitives::EdgeEdge && p.eps > 0.0 {
            let c = (x[p.v[1] as usize] - x[p.v[0] as usize]).cross(x[p.v[3] as usize] - x[p.v[2] as usize]);
            lambda *= super::barrier::mollifier(c.length_squared(), p.eps);
        }
        let w = closest_weights(p.kind, &y);
        let offset: DVec3 = (0..4).map(|i| w[i] * x[p.v[i] as usize]).sum();
        // (the normal of the features where the closest points coincide numerically)
        let n = offset.try_normalize().unwrap_or_else(|| feature_normal(p.kind, &y));
        let (a, b) = n.any_orthonormal_pair();
        let force = mu * lambda;
        (force > 0.0 && force.is_finite()).then(|| FrictionPair {
            v: p.v,
            w,
            basis: [a, b],
            force,
            x0: p.v.map(|i| x[i as usize]),
        })
    }

    /// The tangential slip u of the closest points since the frame's start.
    pub fn slip(&self, x: &[DVec3]) -> Vector2<f64> {
        let r: DVec3 = (0..4).map(|i| self.w[i] * (x[self.v[i] as usize] - self.x0[i])).sum();
        Vector2::new(r.dot(self.basis[0]), r.dot(self.basis[1]))
    }

    pub fn energy(&self, x: &[DVec3], eps: f64) -> f64 {
        self.force * f0(self.slip(x).norm(), eps)
    }

    /// Energy, gradient and (PSD) Hessian over the pair's 12 coordinates.
    pub fn derivatives(&self, x: &[DVec3], eps: f64) -> (f64, SVector<f64, 12>, SMatrix<f64, 12, 12>) {
        let u = self.slip(x);
        let y = u.norm();
        let (over_y, second) = slopes(y, eps);
        // d f0 / du and its Hessian in the tangent plane.
        let gu = over_y * u;
        let hu = if y > 0.0 {
            let n = u / y;
            second * n * n.transpose() + over_y * (Matrix2::identity() - n * n.transpose())
        } else {
            over_y * Matrix2::identity()
        };
        // u = J x with J = P^T (w_0 I, .., w_3 I): 2 x 12.
        let mut j = SMatrix::<f64, 2, 12>::zeros();
        for i in 0..4 {
            for k in 0..3 {
                j[(0, 3 * i + k)] = self.w[i] * self.basis[0][k];
                j[(1, 3 * i + k)] = self.w[i] * self.basis[1][k];
            }
        }
        let g = self.force * j.transpose() * gu;
        let h = self.force * j.transpose() * hu * j;
        (self.force * f0(y, eps), g, h)
    }
}

/// A unit normal of the pair's features where its closest points coincide (never at a valid
/// state: the barrier keeps them the thickness apart).
fn feature_normal(kind: Primitives, y: &[[f64; 3]; 4]) -> DVec3 {
    let p = y.map(DVec3::from_array);
    let n = match kind {
        Primitives::PointTriangle => (p[2] - p[1]).cross(p[3] - p[1]),
        Primitives::EdgeEdge => (p[1] - p[0]).cross(p[3] - p[2]),
    };
    n.try_normalize().unwrap_or(DVec3::Z)
}

/// The friction pairs of a frame, and the sticking slip eps_u (m) they share.
#[derive(Clone, Debug, Default)]
pub struct FrictionPairs {
    pub pairs: Vec<FrictionPair>,
    pub eps: f64,
}
