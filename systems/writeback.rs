//! Writeback: scatters each patch's packed positions and velocities back to its own vertex
//! entities.

use bevy_ecs::prelude::*;
use skinsim::model::*;
use skinsim::solve::PackedPatch;

pub fn scatter_packed(
    patches: Query<(&PackedPatch, &PackedIndex)>,
    mut vertices: Query<(&mut Position, &mut Velocity)>,
    failure: Res<SimFailure>,
) {
    if failure.0.is_some() {
        return; // keep the last good state
    }
    for (packed, index) in &patches {
        // (a shared body's vertices are the body's: its motion moves them)
        for (i, &e) in index.vertices[..index.own].iter().enumerate() {
            if let Ok((mut p, mut v)) = vertices.get_mut(e) {
                p.0 = packed.state.x[i];
                v.0 = packed.state.v[i];
            }
        }
    }
}
