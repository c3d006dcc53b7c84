//! The membrane element (PHYSICS.md 1.1): one triangle of a shell layer.

use glam::DVec3;

use crate::physics::membrane::{self, MembraneRest};
use crate::physics::psd::Filter;
use crate::physics::{ConstitutiveModel, Lame};
use crate::solve::element::{gather, renumbered, Element, Part};
use crate::solve::scatter::Derivatives;

#[derive(Clone, Copy, Debug)]
pub struct MembraneElem {
    pub v: [u32; 3],
    pub rest: MembraneRest,
    pub model: ConstitutiveModel,
    pub lame: Lame,
}

impl Element for MembraneElem {
    type Vertices = [u32; 3];
    type Local = Derivatives<9>;
    const PART: Part = Part::Membrane;
    const SETTLES: bool = true;
    fn vertices(&self) -> [u32; 3] {
        self.v
    }
    fn energy(&self, x: &[DVec3]) -> f64 {
        membrane::energy(self.model, self.lame, &self.rest, &gather(x, &self.v))
    }
    fn eval(&self, x: &[DVec3], filter: Filter) -> Self::Local {
        membrane::eval(self.model, self.lame, &self.rest, &gather(x, &self.v), filter)
    }
    fn unit_energy(&self, _length: f64) -> f64 {
        (self.lame.mu + self.lame.lambda.abs()) * self.rest.volume
    }
    fn reindexed(&self, to: &dyn Fn(u32) -> u32) -> Self {
        MembraneElem { v: renumbered(self.v, to), ..*self }
    }
}
