//! Settle (REMESH.md "Split"): after a remesh, the vertices of the faces it created are relaxed
//! on the patch's own membrane and bending energy (`skinsim::solve::settle`), the rest of the
//! patch held, so that the solve starts near the new mesh's equilibrium instead of at a
//! geometric guess. Runs between Assemble and Solve, on the packed patch, only in a frame whose
//! remesh changed a face.

use bevy_ecs::prelude::*;
use skinsim::model::{PackedIndex, Unsettled};
use skinsim::solve::settle::settle;
use skinsim::solve::PackedPatch;

pub fn settle_remeshed(
    mut commands: Commands,
    mut patches: Query<(&mut PackedPatch, &PackedIndex)>,
    unsettled: Query<Entity, With<Unsettled>>,
) {
    for (mut packed, index) in &mut patches {
        let which: Vec<u32> =
            (0..index.vertices.len() as u32).filter(|&i| unsettled.contains(index.vertices[i as usize])).collect();
        if which.is_empty() {
            continue;
        }
        let PackedPatch { state, elements, constraints, .. } = packed.as_mut();
        let s = settle(elements, constraints, &mut state.x, &state.fixed, &state.tie, &which);
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
