//! Settle (REMESH.md "Split"): after a remesh, the vertices of the faces it created are relaxed
//! on the patch's own membrane and bending energy (`skinsim::solve::settle`), the rest of the
//! patch held, so that the solve starts near the new mesh's equilibrium instead of at a
//! geometric guess; with `local_solve` they are then solved to equilibrium, still with the rest
//! held (`skinsim::solve::local`, issue 26 item 2). Runs between Assemble and Solve, on the
//! packed patch, only in a frame whose remesh changed a face.

use bevy_ecs::prelude::*;
use skinsim::model::{PackedIndex, Unsettled};
use skinsim::solve::local::solve_region;
use skinsim::solve::settle::{settle, Bound};
use skinsim::solve::{PackedPatch, SolverSettings};

pub fn settle_remeshed(
    mut commands: Commands,
    mut patches: Query<(&mut PackedPatch, &PackedIndex, &SolverSettings)>,
    unsettled: Query<(Entity, &Unsettled)>,
) {
    for (mut packed, index, settings) in &mut patches {
        let marked = |pick: fn(&Unsettled) -> bool| -> Vec<u32> {
            (0..index.vertices.len() as u32)
                .filter(|&i| unsettled.get(index.vertices[i as usize]).is_ok_and(|(_, u)| pick(u)))
                .collect()
        };
        let (sweeps, solve) = (marked(|u| u.sweeps), marked(|u| u.solve));
        let PackedPatch { state, elements, constraints, contact, .. } = packed.as_mut();
        if !sweeps.is_empty() {
            let s = match contact.as_mut().filter(|c| c.last.len() == state.x.len()) {
                // With contact, the settle moves the skin where the last solve left it, the
                // bodies there too (a state no pair crosses), each step under the collision
                // bound; the frame's solve then moves on from there (`solve::contact`).
                Some(c) => {
                    let bound = Bound::new(c, &c.last, &state.fixed);
                    let mut y = c.last.clone();
                    let s = settle(elements, constraints, &mut y, (&state.fixed, &state.tie), &sweeps, Some(&bound));
                    for (v, (y, last)) in y.iter().zip(&c.last).enumerate() {
                        if y != last {
                            state.x[v] = *y;
                        }
                    }
                    c.last = y;
                    c.settle_cuts += s.ccd_cuts;
                    s
                }
                None => settle(elements, constraints, &mut state.x, (&state.fixed, &state.tie), &sweeps, None),
            };
            tracing::debug!(
                vertices = s.vertices,
                sweeps = s.sweeps,
                before = s.energy_before,
                after = s.energy_after,
                ccd_cuts = s.ccd_cuts,
                "settle"
            );
        }
        if !solve.is_empty() {
            let r = solve_region(&mut packed, settings, &solve);
            tracing::debug!(?r, "region solve");
            packed.local = Some(r);
        }
    }
    for (e, _) in &unsettled {
        commands.entity(e).remove::<Unsettled>();
    }
}
