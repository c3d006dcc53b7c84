//! The packed solver body of one patch: positions, masses, fixed coordinates and element
//! lists indexed by packed vertex number. Rebuilt by Assemble when the topology changes.

use bevy_ecs::prelude::*;
use glam::DVec3;

use crate::physics::hinge::HingeRest;
use crate::physics::membrane::MembraneRest;
use crate::physics::tet::TetRest;
use crate::physics::{ConstitutiveModel, GaussianElem, HingeModel, Lame, QuadraticBending};

use super::constraints::Constraints;
use super::kkt::KktSystem;
use super::linear::CholeskySolver;
use super::pattern::Pattern;

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
    pub springs: Vec<SpringElem>,
    /// Anchors at skin vertices and at skin face barycentres (KCK18 section 3).
    pub vertex_anchors: Vec<AnchorElem<1>>,
    pub face_anchors: Vec<AnchorElem<3>>,
}

impl Elements {
    /// Sum of the elements' energies at unit strain (stiffness x volume): the scale of the
    /// round-off in an energy evaluation, whose densities cancel O(1) terms to O(strain^2).
    pub fn energy_scale(&self, length: f64) -> f64 {
        let m: f64 = self.membranes.iter().map(|e| (e.lame.mu + e.lame.lambda.abs()) * e.rest.volume).sum();
        let t: f64 = self.tets.iter().map(|e| (e.lame.mu + e.lame.lambda.abs()) * e.rest.volume).sum();
        let h: f64 = self.hinges.iter().map(|e| e.rest.weight).sum();
        let s: f64 = self.springs.iter().map(|e| e.k * length * length).sum();
        let a: f64 =
            self.vertex_anchors.iter().map(|e| e.k).sum::<f64>() + self.face_anchors.iter().map(|e| e.k).sum::<f64>();
        m + t + h + self.quadratic.rigidity_sum() + s + a * length * length
    }
}

/// One patch's packed problem (a component on the patch entity).
#[derive(Component, Default)]
pub struct SolverBody {
    /// The topology key this body was built for (sum of the layers' epochs and counts).
    pub topology_key: u64,
    /// Packed vertex index -> entity.
    pub vertices: Vec<Entity>,
    /// Anchor entities in element order: `elements.vertex_anchors`, then `face_anchors`.
    pub anchors: Vec<Entity>,
    pub x: Vec<DVec3>,
    pub v: Vec<DVec3>,
    pub mass: Vec<f64>,
    pub fixed: Vec<[bool; 3]>,
    /// Per vertex: the vertex whose coordinates it shares (itself when none) and which ones.
    pub tie: Vec<(u32, [bool; 3])>,
    pub elements: Elements,
    /// Faces and tets counted for reports.
    pub face_count: usize,
    pub tet_count: usize,
    /// Characteristic length (bounding-box diagonal of the rest shape), m.
    pub length_scale: f64,
    /// Sparse pattern and factorization: None until first needed, dropped on topology change.
    pub system: Option<(Pattern, CholeskySolver)>,
    /// LK14 kernel constraints (empty without kernels) and their KKT solver, dropped with the
    /// pattern or when the kernels are resampled.
    pub constraints: Constraints,
    pub kkt: Option<KktSystem>,
}

impl SolverBody {
    /// Tetrahedra whose current volume is not positive.
    pub fn inverted_tets(&self) -> usize {
        let x = &self.x;
        self.elements
            .tets
            .iter()
            .filter(|t| {
                let p = t.v.map(|i| x[i as usize]);
                (p[1] - p[0]).cross(p[2] - p[0]).dot(p[3] - p[0]) <= 0.0
            })
            .count()
    }

    /// Drops the cached pattern (call after any change of connectivity or fixed coordinates).
    pub fn invalidate_pattern(&mut self) {
        self.system = None;
        self.kkt = None;
    }

    /// Copies every tied coordinate from its master, so shared DOFs start equal.
    pub fn sync_ties(&mut self) {
        for v in 0..self.x.len() {
            let (m, dofs) = self.tie[v];
            if m as usize != v {
                for (k, _) in dofs.iter().enumerate().filter(|(_, tied)| **tied) {
                    self.x[v][k] = self.x[m as usize][k];
                    self.v[v][k] = self.v[m as usize][k];
                }
            }
        }
    }
}

impl SolverBody {
    /// A body for one shell layer built straight from a mesh, without a World (benchmarks and
    /// bare-pipeline tests). `fixed` chooses the held coordinates from the rest position.
    pub fn from_shell(
        mesh: &crate::mesh::SurfaceMesh,
        model: ConstitutiveModel,
        lame: Lame,
        thickness: f64,
        bending: Option<(HingeModel, f64)>,
        fixed: impl Fn(DVec3) -> [bool; 3],
    ) -> SolverBody {
        let n = mesh.rest.len();
        let mut el = Elements::default();
        for f in &mesh.faces {
            let rest =
                MembraneRest::from_rest_triangle(f.map(|i| mesh.rest[i as usize]), thickness, glam::DMat2::IDENTITY)
                    .expect("valid triangle");
            el.membranes.push(MembraneElem { v: *f, rest, model, lame });
        }
        if let Some((hinge_model, k_b)) = bending {
            for e in crate::mesh::edges(&mesh.faces).into_iter().filter(|e| e.is_interior()) {
                let v = [e.v[0], e.v[1], e.opposite[0], e.opposite[1]];
                let rest = HingeRest::from_rest(hinge_model, k_b, v.map(|i| mesh.rest[i as usize]));
                el.hinges.push(HingeElem { v, rest, model: hinge_model, image: None });
            }
        }
        let length_scale = crate::mesh::bounds::diagonal(&mesh.rest);
        SolverBody {
            topology_key: 0,
            vertices: Vec::new(),
            anchors: Vec::new(),
            x: mesh.rest.clone(),
            v: vec![DVec3::ZERO; n],
            mass: vec![0.0; n],
            fixed: mesh.rest.iter().map(|p| fixed(*p)).collect(),
            tie: (0..n as u32).map(|i| (i, [false; 3])).collect(),
            face_count: mesh.faces.len(),
            tet_count: 0,
            length_scale,
            elements: el,
            system: None,
            constraints: Constraints::default(),
            kkt: None,
        }
    }
}
