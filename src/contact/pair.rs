//! One contact pair's energy and its exact derivatives (IPC: Li et al. 2020, eq. 6 and 12):
//! the barrier on the pair's squared distance, times the mollifier for two edges. Second-order
//! dual numbers over the pair's 12 coordinates give the gradient and Hessian.

use nalgebra::{SMatrix, SVector};
use num_dual::{Dual2SVec64, DualNum};

use super::barrier::{mollifier, Barrier};
use super::distance::{squared, DistanceType, Primitives};
use crate::physics::dual::{cross3, dot3, sub3};
use crate::physics::psd::{project, Filter};

/// A point and a triangle, or two edges, of surfaces that may touch.
#[derive(Clone, Copy, Debug, PartialEq)]
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

    /// The barrier energy (without the stiffness) at the pair's positions.
    pub fn energy(&self, x: &[[f64; 3]; 4]) -> f64 {
        let t = DistanceType::of(self.kind, x);
        if !self.barrier.active(squared(t, x)) {
            return 0.0;
        }
        self.energy_of(t, x)
    }

    /// Energy, gradient and Hessian (without the stiffness); the Hessian projected by `filter`.
    pub fn derivatives(&self, x: &[[f64; 3]; 4], filter: Filter) -> (f64, SVector<f64, 12>, SMatrix<f64, 12, 12>) {
        let t = DistanceType::of(self.kind, x);
        if !self.barrier.active(squared(t, x)) {
            return (0.0, SVector::zeros(), SMatrix::zeros());
        }
        let xd: [[Dual2SVec64<12>; 3]; 4] =
            std::array::from_fn(|i| std::array::from_fn(|k| Dual2SVec64::from_re(x[i][k]).derivative(3 * i + k)));
        let e = self.energy_of(t, &xd);
        let g = e.v1.unwrap_generic(nalgebra::U1, nalgebra::Const::<12>).transpose();
        let mut h = e.v2.unwrap_generic(nalgebra::Const::<12>, nalgebra::Const::<12>);
        project(&mut h, filter);
        (e.re, g, h)
    }

    /// The pair's squared distance.
    pub fn squared_distance(&self, x: &[[f64; 3]; 4]) -> f64 {
        super::distance::squared_distance(self.kind, x)
    }
}
