//! Solve: Newton on every patch, patches in parallel (rayon), or in turn where contact touches
//! other patches. Results are per patch and, without such contact, do not depend on which other
//! patches share the world.

use bevy_ecs::prelude::*;
use bevy_ecs::query::QueryData;
use rayon::prelude::*;
use skinsim::model::*;
use std::collections::HashMap;

use glam::DVec3;
use skinsim::solve::{solve_frame, FrameOutcome, LocalReport, PackedPatch, SolveError, SolverSettings};

type Outcome = (String, PatchSize, Result<FrameOutcome, SolveError>, Option<AnchorReport>, Option<LocalReport>);

/// Solves one patch's frame.
fn solve_one(p: &mut SolveItemsItem, dt: f64) -> Outcome {
    let packed: &mut PackedPatch = &mut p.packed;
    let local = packed.local.take();
    // (walking anchors change the load under held drivers)
    packed.load_held = p.held.is_some_and(|h| h.0) && p.anchors.is_none();
    let out = solve_frame(packed, p.settings, dt);
    let size = PatchSize { vertices: p.index.vertices.len(), faces: p.index.faces, tets: p.index.tets };
    (p.patch.name.clone(), size, out, p.anchors.copied(), local)
}

/// What Solve works on of a patch.
#[derive(QueryData)]
#[query_data(mutable)]
pub struct SolveItems {
    pub patch: &'static Patch,
    pub settings: &'static SolverSettings,
    pub packed: &'static mut PackedPatch,
    pub index: &'static PackedIndex,
    pub anchors: Option<&'static AnchorReport>,
    pub held: Option<&'static LoadHeld>,
}

pub fn solve_patches(
    clock: Res<SimClock>,
    mut patches: Query<SolveItems>,
    mut report: ResMut<FrameReport>,
    mut failure: ResMut<SimFailure>,
) {
    let mut work: Vec<_> = patches.iter_mut().collect();
    work.sort_by_key(|p| p.patch.index);
    // Patches whose contact touches other patches are solved in turn (Gauss-Seidel), each
    // against the others' latest positions: this frame's for those solved before it. Each one
    // ends its frame clear of the others as it saw them, and those solved after it moved
    // against its end: so the frame ends with no two patches crossing.
    let outcomes: Vec<_> = if work.iter().any(|p| p.index.held < p.index.vertices.len()) {
        let mut fresh: HashMap<Entity, DVec3> = HashMap::new();
        work.iter_mut()
            .map(|p| {
                let index = p.index;
                for (k, e) in index.vertices.iter().enumerate().skip(index.held) {
                    if let Some(x) = fresh.get(e) {
                        p.packed.state.x[k] = *x;
                    }
                }
                let out = solve_one(p, clock.dt);
                fresh.extend(index.vertices[..index.own].iter().zip(&p.packed.state.x).map(|(e, x)| (*e, *x)));
                out
            })
            .collect()
    } else {
        work.par_iter_mut().map(|p| solve_one(p, clock.dt)).collect()
    };
    report.patches.clear();
    for (name, size, out, anchors, local) in outcomes {
        report.patches.push(match out {
            Ok(outcome) => PatchReport { local_solve: local, ..PatchReport::solved(name, size, outcome, anchors) },
            Err(error) => {
                let report = PatchReport::failed(name.clone(), size, anchors);
                failure.0.get_or_insert(Failure::Solve { frame: clock.frame, patch: name, error });
                report
            }
        });
    }
}
