//! World-wide resources: the clock, per-stage timings, the frame report and failures.

use bevy_ecs::prelude::*;
use serde::Serialize;

/// Simulation clock: the frame being computed and its time.
#[derive(Resource, Clone, Copy, Debug, Default)]
pub struct SimClock {
    /// Frame index being computed: the first solved frame is 1 (0 is the initial state).
    pub frame: u32,
    /// Time at the end of this frame (s).
    pub time: f64,
    /// Time per frame (s).
    pub dt: f64,
}

/// The eleven stages of a frame (ARCHITECTURE.md 2), in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Stage {
    /// Prescribed motions (the design card's blend-shape update; ARCHITECTURE.md's BlendShapes).
    Motion,
    Remesh,
    PropertyResample,
    ConstraintResample,
    ConstraintAdjust,
    AnchorWalk,
    Assemble,
    /// After a remesh: the touched vertices relaxed before the solve (REMESH.md "Split").
    Settle,
    Solve,
    Writeback,
    Log,
}

impl Stage {
    pub const ALL: [Stage; 11] = [
        Stage::Motion,
        Stage::Remesh,
        Stage::PropertyResample,
        Stage::ConstraintResample,
        Stage::ConstraintAdjust,
        Stage::AnchorWalk,
        Stage::Assemble,
        Stage::Settle,
        Stage::Solve,
        Stage::Writeback,
        Stage::Log,
    ];
    /// Column name in stats.jsonl.
    pub fn key(self) -> &'static str {
        match self {
            Stage::Motion => "motion",
            Stage::Remesh => "remesh",
            Stage::PropertyResample => "property_resample",
            Stage::ConstraintResample => "constraint_resample",
            Stage::ConstraintAdjust => "constraint_adjust",
            Stage::AnchorWalk => "anchor_walk",
            Stage::Assemble => "assemble",
            Stage::Settle => "settle",
            Stage::Solve => "solve",
            Stage::Writeback => "writeback",
            Stage::Log => "log",
        }
    }
}

/// Wall time per stage in the current frame (ms), reset at the start of each frame.
#[derive(Resource, Clone, Debug, Default)]
pub struct Timings {
    pub ms: [f64; Stage::ALL.len()],
    started: Option<std::time::Instant>,
}

impl Timings {
    pub fn reset(&mut self) {
        self.ms = [0.0; Stage::ALL.len()];
        self.started = None;
    }
    pub fn begin(&mut self) {
        self.started = Some(std::time::Instant::now());
    }
    pub fn end(&mut self, stage: Stage) {
        if let Some(t) = self.started.take() {
            self.ms[stage as usize] += t.elapsed().as_secs_f64() * 1e3;
        }
    }
    pub fn get(&self, stage: Stage) -> f64 {
        self.ms[stage as usize]
    }
}

/// One patch's result for the frame.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PatchReport {
    pub name: String,
    pub vertices: usize,
    pub faces: usize,
    pub tets: usize,
    pub newton_iterations: u32,
    pub converged: bool,
    /// Final gradient norm over free DOFs divided by the internal force scale.
    pub residual: f64,
    /// Total energy (J): elastic + springs (+ inertia term in dynamic mode).
    pub energy: f64,
    /// Energy by element kind (J).
    pub energy_membrane: f64,
    pub energy_bending: f64,
    pub energy_volume: f64,
    pub energy_springs: f64,
    /// Factorizations that needed a diagonal shift.
    pub regularized: u32,
    pub line_search_failures: u32,
    /// Unstable equilibria left along negative curvature (quasistatic stability check).
    pub escapes: u32,
    /// Full steps under a held load taken back because the energy rose far past their quadratic
    /// model (counted in `newton_iterations`).
    pub unmodelled_steps: u32,
    /// Numeric Cholesky factorizations and conjugate-gradient iterations in the frame.
    pub factorizations: u32,
    pub cg_iterations: u32,
    /// LK14 kernels: constraint rows and the largest violation relative to the patch size.
    pub constraints: usize,
    pub constraint_violation: f64,
    /// Energy (J) and constraint violation at the frame's first iterate, after the drivers and
    /// any remesh: a remesh pop is the jump from the previous frame's `energy`.
    pub start_energy: f64,
    pub start_violation: f64,
    /// Tetrahedra with non-positive volume at the end of the frame (models that allow inversion).
    pub inverted: usize,
    /// Time inside the solve: element assembly, factorization, line search (ms).
    pub solve_breakdown_ms: crate::solve::SolveCounters,
    /// KCK18 anchors: what this frame's walk (or projection) did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub anchors: Option<super::AnchorReport>,
    /// The Settle stage's region solve before this frame's (remeshed layers with `local_solve`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub local_solve: Option<crate::solve::LocalReport>,
}

/// A patch's size in a frame, for its report.
#[derive(Clone, Copy, Debug, Default)]
pub struct PatchSize {
    pub vertices: usize,
    pub faces: usize,
    pub tets: usize,
    pub inverted: usize,
    pub constraints: usize,
}

impl PatchReport {
    /// The report of a frame the solver finished (converged or not).
    pub fn solved(
        name: String,
        size: PatchSize,
        o: &crate::solve::FrameOutcome,
        anchors: Option<super::AnchorReport>,
    ) -> Self {
        PatchReport {
            name,
            vertices: size.vertices,
            faces: size.faces,
            tets: size.tets,
            newton_iterations: o.iterations,
            converged: o.converged,
            residual: o.residual,
            energy: o.energy,
            energy_membrane: o.parts.membrane,
            energy_bending: o.parts.bending,
            energy_volume: o.parts.volume,
            energy_springs: o.parts.springs,
            regularized: o.regularized,
            line_search_failures: o.line_search_failures,
            escapes: o.escapes,
            unmodelled_steps: o.unmodelled_steps,
            factorizations: o.factorizations,
            cg_iterations: o.cg_iterations,
            constraints: size.constraints,
            constraint_violation: o.constraint_violation,
            start_energy: o.start_energy,
            start_violation: o.start_violation,
            inverted: size.inverted,
            solve_breakdown_ms: o.counters,
            anchors,
            local_solve: None,
        }
    }

    /// The report of a frame whose solve failed (non-finite, no descent): no energy, no residual.
    pub fn failed(name: String, size: PatchSize, anchors: Option<super::AnchorReport>) -> Self {
        PatchReport {
            name,
            vertices: size.vertices,
            faces: size.faces,
            tets: size.tets,
            converged: false,
            residual: f64::NAN,
            energy: f64::NAN,
            anchors,
            ..Default::default()
        }
    }
}

/// Per-patch reports of the last solved frame, in patch order.
#[derive(Resource, Clone, Debug, Default)]
pub struct FrameReport {
    pub patches: Vec<PatchReport>,
}

/// A simulation failure (NaN, breakdown): the run stops after the frame that set it.
#[derive(Resource, Clone, Debug, Default)]
pub struct SimFailure(pub Option<String>);
