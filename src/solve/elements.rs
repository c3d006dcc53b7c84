//! Element lists indexed by packed vertex number: what Assemble builds from a patch's layers
//! and what the solver evaluates.

use glam::DVec3;

use crate::physics::cell::{CellRest, Dilatation, CELL_TETS, CELL_VERTS};
use crate::physics::hinge::HingeRest;
use crate::physics::membrane::MembraneRest;
use crate::physics::tet::TetRest;
use crate::physics::{ConstitutiveModel, GaussianElem, HingeModel, Lame, QuadraticBending};

#[derive(Clone, Copy, Debug)]
pub struct MembraneElem {
    pub v: [u32; 3],
    pub rest: MembraneRest,
    pub model: ConstitutiveModel,
    pub lame: Lame,
}

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
        crate::physics::hinge::positions(self.v, self.image, |i| x[i as usize])
    }
}

#[derive(Clone, Copy, Debug)]
pub struct TetElem {
    pub v: [u32; 4],
    pub rest: TetRest,
    pub model: ConstitutiveModel,
    pub lame: Lame,
}

/// The shared dilatation of a cell of tetrahedra (`physics::cell`).
#[derive(Clone, Copy, Debug)]
pub struct CellElem {
    pub v: [u32; CELL_VERTS],
    pub rest: CellRest,
}

impl CellElem {
    /// The cell of six tetrahedra over eight distinct vertices (their lambda terms, to be
    /// evaluated here instead); None for any other group.
    pub fn from_tets(tets: &[TetElem]) -> Option<CellElem> {
        if tets.len() != CELL_TETS {
            return None;
        }
        let mut v = Vec::with_capacity(CELL_VERTS);
        for t in tets {
            for &i in &t.v {
                if !v.contains(&i) {
                    v.push(i);
                }
            }
        }
        let v: [u32; CELL_VERTS] = v.try_into().ok()?;
        let local = |i: u32| v.iter().position(|&w| w == i).unwrap() as u8;
        let rest = CellRest {
            tets: std::array::from_fn(|e| tets[e].v.map(local)),
            // V_e det(B_e): V_e J_e = w_e det(Ds_e), prestrain included.
            weight: std::array::from_fn(|e| tets[e].rest.volume * tets[e].rest.b.determinant()),
            volume: tets.iter().map(|t| t.rest.volume).sum(),
            bulk: tets.iter().map(|t| t.lame.lambda * t.rest.volume).sum(),
            dilatation: Dilatation::of(tets[0].model),
        };
        Some(CellElem { v, rest })
    }
}

#[derive(Clone, Copy, Debug)]
pub struct SpringElem {
    pub v: [u32; 2],
    pub k: f64,
}

/// A KCK18 anchor spring from the skin point sum_i w_i x[v_i] to `target` on the body (fixed
/// during a solve, moved by the walk between frames).
#[derive(Clone, Copy, Debug)]
pub struct AnchorElem<const NV: usize> {
    pub v: [u32; NV],
    pub w: [f64; NV],
    pub k: f64,
    pub target: DVec3,
}

#[derive(Clone, Debug, Default)]
pub struct Elements {
    pub membranes: Vec<MembraneElem>,
    pub hinges: Vec<HingeElem>,
    /// Quadratic bending, one element per interior vertex (layers that choose it).
    pub quadratic: QuadraticBending,
    /// Its Gaussian-curvature term, per triangle (`gaussian_bending`).
    pub gaussian: Vec<GaussianElem>,
    pub tets: Vec<TetElem>,
    /// The lambda terms of volume layers with `VolumeElement::Cell` (their tets have lambda 0).
    pub cells: Vec<CellElem>,
    pub springs: Vec<SpringElem>,
    /// Anchors at skin vertices and at skin face barycentres (KCK18 section 3).
    pub vertex_anchors: Vec<AnchorElem<1>>,
    pub face_anchors: Vec<AnchorElem<3>>,
    /// Attachment springs from a vertex to a point of a face of another layer (an Attach whose
    /// layers are remeshed): v = [vertex, face corners], w = [1, -barycentric], target 0.
    pub face_springs: Vec<AnchorElem<4>>,
}

impl Elements {
    /// Sum of the elements' energies at unit strain (stiffness x volume): the scale of the
    /// round-off in an energy evaluation, whose densities cancel O(1) terms to O(strain^2).
    pub fn energy_scale(&self, length: f64) -> f64 {
        let m: f64 = self.membranes.iter().map(|e| (e.lame.mu + e.lame.lambda.abs()) * e.rest.volume).sum();
        let t: f64 = self.tets.iter().map(|e| (e.lame.mu + e.lame.lambda.abs()) * e.rest.volume).sum::<f64>()
            + self.cells.iter().map(|e| e.rest.bulk.abs()).sum::<f64>();
        let h: f64 = self.hinges.iter().map(|e| e.rest.weight).sum();
        let s: f64 = self.springs.iter().map(|e| e.k).chain(self.face_springs.iter().map(|e| e.k)).sum::<f64>()
            * length
            * length;
        let a: f64 =
            self.vertex_anchors.iter().map(|e| e.k).sum::<f64>() + self.face_anchors.iter().map(|e| e.k).sum::<f64>();
        m + t + h + self.quadratic.rigidity_sum() + s + a * length * length
    }
}
