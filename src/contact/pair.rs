//! One contact pair's energy and its exact derivatives (IPC: Li et al. 2020, eq. 6 and 12):
//! the barrier on the pair's squared distance, times the mollifier for two edges. The gradient
//! and Hessian: the closed forms of the distance and the mollifier's argument
//! (`closed_form`), by the chain rule through the barrier and the mollifier (scalar dual
//! numbers).

use nalgebra::{SMatrix, SVector};
use num_dual::{Dual2_64, DualNum};

use super::barrier::{mollifier, Barrier};
use super::closed_form;
use super::distance::{box_gap_squared, squared, DistanceType, Primitives};
use crate::physics::dual::{cross3, dot3, sub3};
use crate::physics::psd::{project, Filter};

/// A point and a triangle, or two edges, of surfaces that may touch.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Pair {
    /// `[p, t0, t1, t2]` or `[a0, a1, b0, b1]`.
    pub v: [u32; 4],
    pub kind: Primitives,
    pub barrier: Barrier,
    /// The edge-edge mollifier's threshold on |ea x eb|^2 (`mollifier_threshold`); 0 for a
    /// point and a triangle.
    pub eps: f64,
}

impl Pair {
    /// The pair's energy without the stiffness, in any number type, for the features `t`.
    fn energy_of<D: DualNum<Primitive = f64> + Copy>(&self, t: DistanceType, x: &[[D; 3]; 4]) -> D {
        let b = self.barrier.value(self.barrier.z(squared(t, x)));
        if self.kind == Primitives::EdgeEdge && self.eps > 0.0 {
            let c = cross3(sub3(x[1], x[0]), sub3(x[3], x[2]));
            mollifier(dot3(c, c), self.eps) * b
        } else {
            b
        }
    }

    /// Whether the pair's boxes alone put it beyond the barrier's reach (then it is).
    fn surely_inactive(&self, x: &[[f64; 3]; 4]) -> bool {
        !self.barrier.active(box_gap_squared(self.kind, x))
    }

    /// Whether the pair is within the barrier's reach at the pair's positions.
    pub fn active(&self, x: &[[f64; 3]; 4]) -> bool {
        !self.surely_inactive(x) && self.barrier.active(self.squared_distance(x))
    }

    /// The barrier energy (without the stiffness) at the pair's positions.
    pub fn energy(&self, x: &[[f64; 3]; 4]) -> f64 {
        if self.surely_inactive(x) {
            return 0.0;
        }
        let t = DistanceType::of(self.kind, x);
        if !self.barrier.active(squared(t, x)) {
            return 0.0;
        }
        self.energy_of(t, x)
    }

    /// Energy, gradient and Hessian (without the stiffness); the Hessian projected by `filter`.
    pub fn derivatives(&self, x: &[[f64; 3]; 4], filter: Filter) -> (f64, SVector<f64, 12>, SMatrix<f64, 12, 12>) {
        if self.surely_inactive(x) {
            return (0.0, SVector::zeros(), SMatrix::zeros());
        }
        let t = DistanceType::of(self.kind, x);
        if !self.barrier.active(squared(t, x)) {
            return (0.0, SVector::zeros(), SMatrix::zeros());
        }
        // b(d^2) and its first two derivatives in d^2, then the chain rule on the closed forms.
        let (d2, gd, hd) = closed_form::squared(t, x);
        let b = self.barrier.value(self.barrier.z(Dual2_64::from_re(d2).derivative()));
        let (e, g, mut h) = if self.kind == Primitives::EdgeEdge && self.eps > 0.0 {
            // E = m(c) b(d^2) (IPC eq. 12)
            let (c, gc, hc) = closed_form::edges_cross_squared(x);
            let m = mollifier(Dual2_64::from_re(c).derivative(), self.eps);
            let mixed = m.v1 * b.v1 * (gc * gd.transpose() + gd * gc.transpose());
            let h = m.re * (b.v2 * gd * gd.transpose() + b.v1 * hd) + b.re * (m.v2 * gc * gc.transpose() + m.v1 * hc);
            (m.re * b.re, m.re * b.v1 * gd + b.re * m.v1 * gc, h + mixed)
        } else {
            (b.re, b.v1 * gd, b.v2 * gd * gd.transpose() + b.v1 * hd)
        };
        project(&mut h, filter);
        (e, g, h)
    }

    /// The pair's squared distance.
    pub fn squared_distance(&self, x: &[[f64; 3]; 4]) -> f64 {
        super::distance::squared_distance(self.kind, x)
    }
}
