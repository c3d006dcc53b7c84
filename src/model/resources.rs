//! World-wide resources: the clock, per-stage timings, the frame report and failures.

use bevy_ecs::prelude::*;
use serde::Serialize;

use crate::solve::{FrameOutcome, SolveError};

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

/// One patch's result for the frame: its size and what the solve did (`FrameOutcome`, whose
/// fields are the report's columns).
#[derive(Clone, Debug, Default, Serialize)]
pub struct PatchReport {
    pub name: String,
    pub vertices: usize,
    pub faces: usize,
    pub tets: usize,
    #[serde(flatten)]
    pub outcome: FrameOutcome,
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
}

impl PatchReport {
    /// The report of a frame the solver finished (converged or not).
    pub fn solved(name: String, size: PatchSize, outcome: FrameOutcome, anchors: Option<super::AnchorReport>) -> Self {
        let PatchSize { vertices, faces, tets } = size;
        PatchReport { name, vertices, faces, tets, outcome, anchors, local_solve: None }
    }

    /// The report of a frame whose solve failed (non-finite, no descent): no energy, no residual.
    pub fn failed(name: String, size: PatchSize, anchors: Option<super::AnchorReport>) -> Self {
        let outcome = FrameOutcome { converged: false, residual: f64::NAN, energy: f64::NAN, ..Default::default() };
        PatchReport::solved(name, size, outcome, anchors)
    }
}

/// Per-patch reports of the last solved frame, in patch order.
#[derive(Resource, Clone, Debug, Default)]
pub struct FrameReport {
    pub patches: Vec<PatchReport>,
}

/// Why a run stopped.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Failure {
    /// A patch's solve failed in a frame.
    #[error("frame {frame}: patch \"{patch}\": {error}")]
    Solve { frame: u32, patch: String, error: SolveError },
    /// An output of the frame could not be written: the file and the system's reason.
    #[error("cannot write {file}: {reason}")]
    Output { file: String, reason: String },
}

/// A simulation failure (NaN, breakdown): the run stops after the frame that set it.
#[derive(Resource, Clone, Debug, Default)]
pub struct SimFailure(pub Option<Failure>);

/// What logging carries from frame to frame that a checkpoint saves (`systems::checkpoint`): whether
/// frame 0 (the rest state) is written, and each layer's colour scale once fixed. A resumed
/// run's log then neither writes frame 0 again nor rescales its colours.
#[derive(Resource, Clone, Debug, Default, PartialEq)]
pub struct LogState {
    pub rest_logged: bool,
    pub colour_scales: Vec<(Entity, f64)>,
}
