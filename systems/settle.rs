//! Settle (REMESH.md "Split"): after a remesh, the vertices of the faces it created are relaxed
//! on the patch's own membrane and bending energy (`skinsim::solve::settle`), the rest of the
//! patch held, so that the solve starts near the new mesh's equilibrium instead of at a
//! geometric guess. Runs between Assemble and Solve, on the packed body, only in a frame whose
//! remesh changed a face.

use bevy_ecs::prelude::*;
use skinsim::model::Unsettled;
use skinsim::solve::settle::settle;
use skinsim::solve::SolverBody;

pub fn settle_remeshed(
    mut commands: Commands,
    mut patches: Query<&mut SolverBody>,
    unsettled: Query<Entity, With<Unsettled>>,
) {
    for mut body in &mut patches {
        let body = body.as_mut();
        let which: Vec<u32> =
            (0..body.vertices.len() as u32).filter(|&i| unsettled.contains(body.vertices[i as usize])).collect();
        if which.is_empty() {
            continue;
        }
        let s = settle(&body.elements, &body.constraints, &mut body.x, &body.fixed, &body.tie, &which);
        tracing::debug!(
            vertices = s.vertices,
            sweeps = s.sweeps,
            before = s.energy_before,
            after = s.energy_after,
            "settle"
        );
    }
    for e in &unsettled {
        commands.entity(e).remove::<Unsettled>();
    }
}
