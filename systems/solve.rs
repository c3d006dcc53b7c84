//! Solve: Newton on every patch, patches in parallel (rayon). Results are per patch and do not
//! depend on which other patches share the world.

use bevy_ecs::prelude::*;
use rayon::prelude::*;
use skinsim::model::*;
use skinsim::solve::{solve_frame, SolverBody, SolverSettings};

pub fn solve_patches(
    clock: Res<SimClock>,
    mut patches: Query<(&Patch, &SolverSettings, &mut SolverBody, Option<&AnchorReport>)>,
    mut report: ResMut<FrameReport>,
    mut failure: ResMut<SimFailure>,
) {
    let mut work: Vec<_> = patches.iter_mut().collect();
    work.sort_by_key(|(p, ..)| p.index);
    let outcomes: Vec<_> = work
        .par_iter_mut()
        .map(|(patch, settings, body, anchors)| {
            let body: &mut SolverBody = body;
            let out = solve_frame(body, settings, clock.dt);
            let counts =
                (body.vertices.len(), body.face_count, body.tet_count, body.inverted_tets(), body.constraints.rows());
            (patch.name.clone(), counts, out, anchors.copied())
        })
        .collect();
    report.patches.clear();
    for (name, (vertices, faces, tets, inverted, constraints), out, anchors) in outcomes {
        match out {
            Ok(o) => report.patches.push(PatchReport {
                name,
                vertices,
                faces,
                tets,
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
                solve_breakdown_ms: o.counters,
                escapes: o.escapes,
                factorizations: o.factorizations,
                cg_iterations: o.cg_iterations,
                constraints,
                constraint_violation: o.constraint_violation,
                start_energy: o.start_energy,
                start_violation: o.start_violation,
                inverted,
                anchors,
            }),
            Err(reason) => {
                if failure.0.is_none() {
                    failure.0 = Some(format!("frame {}: patch \"{name}\": {reason}", clock.frame));
                }
                report.patches.push(PatchReport {
                    name,
                    vertices,
                    faces,
                    tets,
                    converged: false,
                    residual: f64::NAN,
                    energy: f64::NAN,
                    anchors,
                    ..Default::default()
                });
            }
        }
    }
}
