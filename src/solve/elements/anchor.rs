//! Zero-length springs from a weighted sum of vertices to a fixed point: KCK18 anchors (section
//! 3; at a vertex, NV = 1, or a face barycentre, NV = 3) and the attachment of a vertex to a
//! point of another layer's face (NV = 4, target 0).

use glam::DVec3;

use crate::physics::psd::Filter;
use crate::physics::spring;
use crate::solve::element::{gather, renumbered, Element, Part};
use crate::solve::scatter::Derivatives;

/// A spring from the point sum_i w_i x[v_i] to `target` (fixed during a solve; an anchor's is
/// moved by the walk between frames).
#[derive(Clone, Copy, Debug)]
pub struct AnchorElem<const NV: usize> {
    pub v: [u32; NV],
    pub w: [f64; NV],
    pub k: f64,
    pub target: DVec3,
}

impl<const NV: usize> AnchorElem<NV> {
    fn residual(&self, x: &[DVec3]) -> DVec3 {
        (0..NV).map(|i| self.w[i] * x[self.v[i] as usize]).sum::<DVec3>() - self.target
    }
}

macro_rules! anchor_element {
    ($nv:literal) => {
        impl Element for AnchorElem<$nv> {
            type Vertices = [u32; $nv];
            type Local = Derivatives<{ 3 * $nv }>;
            const PART: Part = Part::Springs;
            fn vertices(&self) -> [u32; $nv] {
                self.v
            }
            fn energy(&self, x: &[DVec3]) -> f64 {
                0.5 * self.k * self.residual(x).length_squared()
            }
            fn eval(&self, x: &[DVec3], _filter: Filter) -> Self::Local {
                spring::anchor_eval(self.k, &self.w, &gather(x, &self.v), self.target)
            }
            fn unit_energy(&self, length: f64) -> f64 {
                self.k * length * length
            }
            fn reindexed(&self, to: &dyn Fn(u32) -> u32) -> Self {
                AnchorElem { v: renumbered(self.v, to), ..*self }
            }
        }
    };
}

anchor_element!(1);
anchor_element!(3);
anchor_element!(4);
