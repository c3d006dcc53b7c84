//! Zero-length attachment springs between two vertices (PHYSICS.md 1.5).

use glam::DVec3;
use nalgebra::{SMatrix, SVector};

use crate::physics::psd::Filter;
use crate::physics::spring;
use crate::solve::element::{renumbered, Element, Part};
use crate::solve::scatter::Derivatives;

#[derive(Clone, Copy, Debug)]
pub struct SpringElem {
    pub v: [u32; 2],
    pub k: f64,
}

impl Element for SpringElem {
    type Vertices = [u32; 2];
    type Local = Derivatives<6>;
    const PART: Part = Part::Springs;
    fn vertices(&self) -> [u32; 2] {
        self.v
    }
    fn energy(&self, x: &[DVec3]) -> f64 {
        spring::energy(self.k, x[self.v[0] as usize], x[self.v[1] as usize])
    }
    fn eval(&self, x: &[DVec3], _filter: Filter) -> Self::Local {
        let (a, b) = (x[self.v[0] as usize], x[self.v[1] as usize]);
        let g = spring::gradient(self.k, a, b);
        let gv = SVector::<f64, 6>::from_column_slice(&[g.x, g.y, g.z, -g.x, -g.y, -g.z]);
        let mut h = SMatrix::<f64, 6, 6>::zeros();
        for k in 0..3 {
            h[(k, k)] = self.k;
            h[(k + 3, k + 3)] = self.k;
            h[(k, k + 3)] = -self.k;
            h[(k + 3, k)] = -self.k;
        }
        (spring::energy(self.k, a, b), gv, h)
    }
    fn unit_energy(&self, length: f64) -> f64 {
        self.k * length * length
    }
    fn reindexed(&self, to: &dyn Fn(u32) -> u32) -> Self {
        SpringElem { v: renumbered(self.v, to), ..*self }
    }
}
