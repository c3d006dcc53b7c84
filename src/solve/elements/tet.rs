//! The linear tetrahedron (PHYSICS.md 1.3; H15 section 5) of a volume layer.

use glam::DVec3;

use crate::physics::psd::Filter;
use crate::physics::tet::{self, TetRest};
use crate::physics::{ConstitutiveModel, Lame};
use crate::solve::element::{gather, renumbered, Element, Part};
use crate::solve::scatter::Derivatives;

#[derive(Clone, Copy, Debug)]
pub struct TetElem {
    pub v: [u32; 4],
    pub rest: TetRest,
    pub model: ConstitutiveModel,
    pub lame: Lame,
}

impl Element for TetElem {
    type Vertices = [u32; 4];
    type Local = Derivatives<12>;
    const PART: Part = Part::Volume;
    fn vertices(&self) -> [u32; 4] {
        self.v
    }
    fn energy(&self, x: &[DVec3]) -> f64 {
        tet::energy(self.model, self.lame, &self.rest, &gather(x, &self.v))
    }
    fn eval(&self, x: &[DVec3], filter: Filter) -> Self::Local {
        tet::eval(self.model, self.lame, &self.rest, &gather(x, &self.v), filter)
    }
    fn unit_energy(&self, _length: f64) -> f64 {
        (self.lame.mu + self.lame.lambda.abs()) * self.rest.volume
    }
    fn reindexed(&self, to: &dyn Fn(u32) -> u32) -> Self {
        TetElem { v: renumbered(self.v, to), ..*self }
    }
}
