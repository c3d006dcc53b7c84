//! Solve: Newton on every patch, patches in parallel (rayon). Results are per patch and do not
//! depend on which other patches share the world.

use bevy_ecs::prelude::*;
use bevy_ecs::query::QueryData;
use rayon::prelude::*;
use skinsim::model::*;
use skinsim::solve::{solve_frame, PackedPatch, SolverSettings};

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
    let outcomes: Vec<_> = work
        .par_iter_mut()
        .map(|p| {
            let packed: &mut PackedPatch = &mut p.packed;
            let local = packed.local.take();
            // (walking anchors change the load under held drivers)
            packed.load_held = p.held.is_some_and(|h| h.0) && p.anchors.is_none();
            let out = solve_frame(packed, p.settings, clock.dt);
            let size = PatchSize { vertices: p.index.vertices.len(), faces: p.index.faces, tets: p.index.tets };
            (p.patch.name.clone(), size, out, p.anchors.copied(), local)
        })
        .collect();
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
