//! One patch packed for the solver: its state and elements indexed by packed vertex number, and
//! the solver's caches. No entity handles: the map to the ECS is the patch's
//! `model::PackedIndex`. Assemble rebuilds it when the topology changes and gathers the state
//! every frame; Writeback scatters the state back.

use bevy_ecs::prelude::*;
use glam::DVec3;

use super::constraints::Constraints;
use super::elements::{Elements, HingeElem, MembraneElem};
use super::kkt::KktSystem;
use super::linear::CholeskySolver;
use super::pattern::Pattern;
use crate::physics::hinge::HingeRest;
use crate::physics::membrane::MembraneRest;
use crate::physics::{ConstitutiveModel, HingeModel, Lame};

/// A patch's packed problem (a component on the patch entity).
#[derive(Component, Default)]
pub struct PackedPatch {
    pub state: PackedState,
    pub elements: Elements,
    /// LK14 kernel constraints (empty without kernels).
    pub constraints: Constraints,
    /// Characteristic length (bounding-box diagonal of the positions at the rebuild), m.
    pub length_scale: f64,
    pub cache: SolverCache,
    /// What the Settle stage's region solve did this frame (issue 26 item 2), for the report.
    pub local: Option<LocalReport>,
    /// Barrier contact on the patch's surface (a scene's `contact`), with what it keeps
    /// between iterations and frames.
    pub contact: Option<crate::contact::ContactState>,
    /// Whether this frame's load is the one the last solve was accepted under (`LoadHeld`,
    /// set by the Solve system): the frame is then converged once its residual is back within
    /// the one the load was accepted at (`SolverCache::accepted`; twice it when that was the
    /// stall test's floor, `constrained::held_level`), on a remeshed layer too.
    pub load_held: bool,
    /// A resumed run's saved solver state (`Carry`), taken up after the first rebuild.
    pub carry: Option<Carry>,
}

/// What a patch's solver carries from frame to frame and a rebuild from the ECS does not make
/// again: a checkpoint saves it (`PackedPatch::carry`), a resumed run's first Assemble takes it
/// up after its rebuild (`PackedPatch::take_up`).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Carry {
    /// The topology key the patch was packed for (`model::PackedIndex::key`): a resumed frame
    /// whose key differs is one where the saved run rebuilt too, and kept only what a rebuild
    /// keeps.
    pub key: u64,
    /// Set at the last rebuild from the positions then (not the resumed ones).
    pub length_scale: f64,
    pub multipliers: Vec<f64>,
    pub accepted: f64,
    pub kkt: Option<super::kkt::KktMemory>,
    pub contact: Option<crate::contact::ContactMemory>,
}

/// What a region's solve did (the frame report's `local_solve`).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct LocalReport {
    /// Free vertices, and the held ones around them in the small problem.
    pub vertices: usize,
    pub held: usize,
    pub kernels: usize,
    pub iterations: u32,
    pub factorizations: u32,
    pub converged: bool,
    /// Wall time of the whole region solve, building included (ms).
    pub ms: f64,
}

/// Per packed vertex: what Newton iterates on.
#[derive(Clone, Debug, Default)]
pub struct PackedState {
    pub x: Vec<DVec3>,
    pub v: Vec<DVec3>,
    pub mass: Vec<f64>,
    pub fixed: Vec<[bool; 3]>,
    /// The vertex whose coordinates this one shares (itself when none) and which ones.
    pub tie: Vec<(u32, [bool; 3])>,
}

impl PackedState {
    /// An unmoving, unfixed, untied state at the positions `x`.
    pub fn at_rest(x: Vec<DVec3>) -> Self {
        let n = x.len();
        PackedState {
            x,
            v: vec![DVec3::ZERO; n],
            mass: vec![0.0; n],
            fixed: vec![[false; 3]; n],
            tie: (0..n as u32).map(|i| (i, [false; 3])).collect(),
        }
    }

    /// Copies every tied coordinate from its master, so shared DOFs start equal.
    pub(crate) fn sync_ties(&mut self) {
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

/// What the solver keeps between frames: the sparse pattern with its symbolic and numeric
/// Cholesky factor, and the KKT system of a patch with kernels. Built lazily by the first solve,
/// dropped when the topology, the fixed coordinates or the kernels change.
#[derive(Default)]
pub struct SolverCache {
    pub system: Option<(Pattern, CholeskySolver)>,
    pub kkt: Option<KktSystem>,
    /// The kernel rows' multipliers at the end of the last solve: the next solve's first
    /// Lagrangian gradient (kept across a remesh while the rows' count holds: a row is one
    /// kernel's, in the patch's kernel order).
    pub multipliers: Vec<f64>,
    /// The relative residual the last solve was accepted at, when it converged (above the
    /// tolerance when it ended at the round-off floor), else 0; under a held load never below
    /// the one the load was first accepted at. Kept across a remesh: it is the load's, not the
    /// mesh's.
    pub accepted: f64,
    /// A resumed run's KKT memory, for the first KKT system built (`KktSystem::remember`).
    pub kkt_memory: Option<super::kkt::KktMemory>,
}

impl SolverCache {
    pub fn invalidate(&mut self) {
        self.system = None;
        self.kkt = None;
    }
}

impl PackedPatch {
    /// What the solver carries to the next frame (`Carry`).
    pub fn carry(&self, key: u64) -> Carry {
        Carry {
            key,
            length_scale: self.length_scale,
            multipliers: self.cache.multipliers.clone(),
            accepted: self.cache.accepted,
            kkt: self.cache.kkt.as_ref().map(|k| k.memory()).or(self.cache.kkt_memory),
            contact: self.contact.as_ref().map(|c| c.memory()),
        }
    }

    /// Takes up a saved `Carry` after the rebuild of a resumed run's first frame. `key`: the
    /// topology key of this frame. Where it differs from the saved one, the uninterrupted run
    /// rebuilt in this frame as well: then only what its rebuild kept is taken up (the kernel
    /// multipliers and the accepted residual), the rest stays as the rebuild made it.
    pub fn take_up(&mut self, carry: Carry, key: u64) {
        self.cache.multipliers = carry.multipliers;
        self.cache.accepted = carry.accepted;
        if key != carry.key {
            return;
        }
        self.length_scale = carry.length_scale;
        self.cache.kkt_memory = carry.kkt;
        if let (Some(state), Some(memory)) = (self.contact.as_mut(), carry.contact) {
            state.remember(memory);
        }
    }

    /// Tetrahedra whose current volume is not positive.
    pub fn inverted_tets(&self) -> usize {
        let x = &self.state.x;
        self.elements
            .tets
            .iter()
            .filter(|t| {
                let p = t.v.map(|i| x[i as usize]);
                (p[1] - p[0]).cross(p[2] - p[0]).dot(p[3] - p[0]) <= 0.0
            })
            .count()
    }

    /// One shell layer packed straight from a mesh, without a World (benchmarks and bare-pipeline
    /// tests). `fixed` chooses the held coordinates from the rest position.
    pub fn from_shell(
        mesh: &crate::mesh::SurfaceMesh,
        model: ConstitutiveModel,
        lame: Lame,
        thickness: f64,
        bending: Option<(HingeModel, f64)>,
        fixed: impl Fn(DVec3) -> [bool; 3],
    ) -> PackedPatch {
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
        let mut state = PackedState::at_rest(mesh.rest.clone());
        state.fixed = mesh.rest.iter().map(|p| fixed(*p)).collect();
        PackedPatch {
            state,
            length_scale: crate::mesh::bounds::diagonal(&mesh.rest),
            elements: el,
            constraints: Constraints::default(),
            cache: SolverCache::default(),
            local: None,
            load_held: false,
            contact: None,
            carry: None,
        }
    }
}
