//! AnchorWalk (KCK18 section 2): each anchor is offered a* = a0 + slide (x_skin - a_prev): a0 its
//! body point on the body as posed this frame, x_skin - a_prev the pull of its spring at the end
//! of the last solve (carried with the body, so a fast body does not drag anchors backwards),
//! and moves towards it over the body: by the 2D ray-tracing walk, or by the projection-springs
//! baseline. Anchors are independent: they run in parallel and the result does not depend on
//! the thread count.
//!
//! In quasistatic mode each free skin vertex then moves with its anchor (the skin rides on the
//! body): Newton's first guess. Dynamic mode leaves the guess to the implicit-Euler predictor.
//! Assemble packs the anchors as springs (`assemble::anchor_springs`).

use bevy_ecs::prelude::*;
use glam::DVec3;
use rayon::prelude::*;
use skinsim::coupling::walk::{Projector, Stop, SurfacePoint};

use skinsim::model::*;
use skinsim::solve::{SolveMode, SolverSettings};

pub fn walk_anchors(
    skins: Query<(&Anchoring, &LayerAnchors, &LayerOf)>,
    bodies: Query<(&AnchorBody, &LayerVertices)>,
    settings: Query<&SolverSettings>,
    mut positions: Query<(&mut Position, &Prescribed)>,
    mut anchors: Query<(&mut Anchor, &mut AnchorState)>,
    mut reports: Query<&mut AnchorReport>,
) {
    for (anchoring, list, patch) in &skins {
        let Ok((body, body_vertices)) = bodies.get(anchoring.body) else { continue };
        let at = |v: Entity| positions.get(v).expect("vertex of a live layer").0 .0;
        let x: Vec<DVec3> = body_vertices.entities().iter().map(|&v| at(v)).collect();
        let skin_point = |p: &SkinPoint| match p {
            SkinPoint::Vertex(v) => at(*v),
            SkinPoint::Face(f) => f.iter().map(|&v| at(v)).sum::<DVec3>() / 3.0,
        };
        let offered: Vec<(SurfacePoint, DVec3)> = list
            .entities()
            .iter()
            .map(|&a| {
                let (anchor, state) = anchors.get(a).expect("anchor");
                (anchor.body, skin_point(&anchor.skin) - state.position)
            })
            .collect();
        let surface = &body.surface;
        let projector = (anchoring.method == AnchorMethod::Project).then(|| Projector::new(surface, &x));
        let moved: Vec<(SurfacePoint, AnchorState, Option<Stop>, DVec3)> = offered
            .par_iter()
            .map_init(Vec::new, |visited, &(from, pull)| {
                let a0 = surface.position(&x, from);
                let target = a0 + anchoring.slide * pull;
                let (to, walked, stop) = match anchoring.method {
                    AnchorMethod::Walk => {
                        let w = surface.walk(&x, from, target - a0, visited);
                        (w.end, w.length, Some(w.stop))
                    }
                    AnchorMethod::Project => {
                        let p = projector.as_ref().and_then(|p| p.project(surface, &x, target));
                        (p.unwrap_or(from), 0.0, None)
                    }
                    AnchorMethod::ProjectRing(n) => {
                        (surface.project_ring(&x, &body.vertex_faces, from.face, target, n), 0.0, None)
                    }
                };
                let jump = (surface.position(&body.rest, to) - surface.position(&body.rest, from)).length();
                let state =
                    AnchorState { position: surface.position(&x, to), step: (target - a0).length(), walked, jump };
                (to, state, stop, a0)
            })
            .collect();
        let quasistatic = settings.get(patch.0).is_ok_and(|s| s.mode == SolveMode::Quasistatic);
        let mut report = AnchorReport { anchors: moved.len(), ..Default::default() };
        for (&a, (to, state, stop, a0)) in list.entities().iter().zip(moved) {
            report.add(&state, stop);
            let (mut anchor, mut s) = anchors.get_mut(a).expect("anchor");
            if let (true, SkinPoint::Vertex(v)) = (quasistatic, anchor.skin) {
                let (mut p, fixed) = positions.get_mut(v).expect("skin vertex");
                // The body's motion under the anchor, not its slide (the skin led that).
                let moved_by = a0 - s.position;
                for k in (0..3).filter(|&k| !fixed.0[k]) {
                    p.0[k] += moved_by[k];
                }
            }
            anchor.body = to;
            *s = state;
        }
        if let Ok(mut r) = reports.get_mut(patch.0) {
            *r = report;
        }
    }
}
