//! Solve: Newton on every patch, patches in parallel (rayon). Results are per patch and do not
//! depend on which other patches share the world.

use bevy_ecs::prelude::*;
use rayon::prelude::*;
use skinsim::model::*;
use skinsim::solve::{solve_frame, PackedPatch, SolverSettings};

pub fn solve_patches(
    clock: Res<SimClock>,
    mut patches: Query<(&Patch, &SolverSettings, &mut PackedPatch, &PackedIndex, Option<&AnchorReport>)>,
    mut report: ResMut<FrameReport>,
    mut failure: ResMut<SimFailure>,
) {
    let mut work: Vec<_> = patches.iter_mut().collect();
    work.sort_by_key(|(p, ..)| p.index);
    let outcomes: Vec<_> = work
        .par_iter_mut()
        .map(|(patch, settings, packed, index, anchors)| {
            let packed: &mut PackedPatch = packed;
            let local = packed.local.take();
            let out = solve_frame(packed, settings, clock.dt);
            let size = PatchSize {
                vertices: index.vertices.len(),
                faces: index.faces,
                tets: index.tets,
                inverted: packed.inverted_tets(),
                constraints: packed.constraints.rows(),
            };
            (patch.name.clone(), size, out, anchors.copied(), local)
        })
        .collect();
    report.patches.clear();
    for (name, size, out, anchors, local) in outcomes {
        report.patches.push(match out {
            Ok(outcome) => PatchReport { local_solve: local, ..PatchReport::solved(name, size, &outcome, anchors) },
            Err(reason) => {
                if failure.0.is_none() {
                    failure.0 = Some(format!("frame {}: patch \"{name}\": {reason}", clock.frame));
                }
                PatchReport::failed(name, size, anchors)
            }
        });
    }
}
