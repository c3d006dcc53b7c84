//! The quadratic element's Gaussian-curvature term, per triangle (`physics::gaussian_bending`).

use glam::DVec3;

use crate::physics::gaussian_bending::{self, GaussianElem};
use crate::physics::psd::Filter;
use crate::solve::element::{gather, renumbered, Element, Part};
use crate::solve::scatter::Derivatives;

impl Element for GaussianElem {
    type Vertices = [u32; 3];
    type Local = Derivatives<9>;
    const PART: Part = Part::Bending;
    const SETTLES: bool = true;
    fn vertices(&self) -> [u32; 3] {
        self.v
    }
    fn energy(&self, x: &[DVec3]) -> f64 {
        gaussian_bending::energy(self, &gather(x, &self.v))
    }
    fn eval(&self, x: &[DVec3], filter: Filter) -> Self::Local {
        gaussian_bending::eval(self, &gather(x, &self.v), filter)
    }
    fn unit_energy(&self, _length: f64) -> f64 {
        0.0 // (its scale is the quadratic element's rigidity)
    }
    fn reindexed(&self, to: &dyn Fn(u32) -> u32) -> Self {
        GaussianElem { v: renumbered(self.v, to), ..*self }
    }
}
