//! The discrete-shell hinge (PHYSICS.md 1.2): one interior edge of a shell layer and the two
//! vertices opposite it.

use glam::DVec3;

use crate::physics::hinge::{self, HingeRest};
use crate::physics::psd::Filter;
use crate::physics::HingeModel;
use crate::solve::element::{renumbered, Element, Part};
use crate::solve::scatter::Derivatives;

#[derive(Clone, Copy, Debug)]
pub struct HingeElem {
    pub v: [u32; 4],
    pub rest: HingeRest,
    pub model: HingeModel,
    /// Periodic seam: v[3] is placed at x[v[3]] + x[a] - x[b] (the period vector, constant
    /// during a solve because the seam's axis coordinates are prescribed).
    pub image: Option<(u32, u32)>,
}

impl HingeElem {
    /// The four positions of the hinge, the periodic image applied.
    #[inline]
    pub fn positions(&self, x: &[DVec3]) -> [DVec3; 4] {
        hinge::positions(self.v, self.image, |i| x[i as usize])
    }
}

impl Element for HingeElem {
    type Vertices = [u32; 4];
    type Local = Derivatives<12>;
    const PART: Part = Part::Bending;
    const SETTLES: bool = true;
    fn vertices(&self) -> [u32; 4] {
        self.v
    }
    fn energy(&self, x: &[DVec3]) -> f64 {
        hinge::energy(self.model, &self.rest, &self.positions(x))
    }
    fn eval(&self, x: &[DVec3], filter: Filter) -> Self::Local {
        hinge::eval(self.model, &self.rest, &self.positions(x), filter)
    }
    fn unit_energy(&self, _length: f64) -> f64 {
        self.rest.weight
    }
    /// (a periodic seam's hinge also reads the two vertices of its image's period vector)
    fn touches(&self, keep: &mut dyn FnMut(&[u32]) -> bool) -> bool {
        match self.image {
            Some((a, b)) => keep(&[self.v[0], self.v[1], self.v[2], self.v[3], a, b]),
            None => keep(&self.v),
        }
    }
    fn reindexed(&self, to: &dyn Fn(u32) -> u32) -> Self {
        HingeElem { v: renumbered(self.v, to), image: self.image.map(|(a, b)| (to(a), to(b))), ..*self }
    }
    /// (a periodic seam's hinges see an image of one vertex: left to the solve)
    fn settles(&self) -> bool {
        self.image.is_none()
    }
}
