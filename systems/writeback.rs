//! Writeback: scatters each body's positions and velocities back to its vertex entities.

use bevy_ecs::prelude::*;
use skinsim::model::*;
use skinsim::solve::SolverBody;

pub fn scatter_bodies(
    bodies: Query<&SolverBody>,
    mut vertices: Query<(&mut Position, &mut Velocity)>,
    failure: Res<SimFailure>,
) {
    if failure.0.is_some() {
        return; // keep the last good state
    }
    for body in &bodies {
        for (i, &e) in body.vertices.iter().enumerate() {
            if let Ok((mut p, mut v)) = vertices.get_mut(e) {
                p.0 = body.x[i];
                v.0 = body.v[i];
            }
        }
    }
}
