//! Motion: evaluates the patch's prescribed motions at this frame and writes the driven
//! coordinates (H15 6.1: compression increments; bending for validation; LK14 5.3 blend shapes;
//! KCK18 body poses and OBJ sequences), and whether each patch's load is held since the last
//! frame (`LoadHeld`).

use bevy_ecs::prelude::*;
use skinsim::model::*;

pub fn apply_motions(
    clock: Res<SimClock>,
    patches: Query<(&PatchMotion, &PatchLayers)>,
    mut held: Query<(&PatchMotion, Option<&PatchCaptures>, &mut LoadHeld)>,
    layers: Query<(&Layer, &LayerVertices)>,
    mut vertices: Query<(&RestPos, &Prescribed, &mut Position)>,
) {
    let frame = clock.frame as f64;
    for (motion, captures, mut load) in &mut held {
        let captured = captures.is_some_and(|c| c.0.iter().any(|c| c.frame + 1 == clock.frame));
        load.0 = clock.frame >= 2 && !captured && motion.motions.iter().all(|m| m.holds_at(frame));
    }
    for (motion, patch_layers) in &patches {
        for &layer in patch_layers.entities() {
            let Ok((_, verts)) = layers.get(layer) else { continue };
            // (embedded layers move in `carry_embedded`, once every body has)
            let embedded = |m: &&Motion| matches!(m.kind, MotionKind::Embed { .. });
            let acting: Vec<_> = motion.motions.iter().filter(|m| m.layers.contains(&layer) && !embedded(m)).collect();
            if acting.is_empty() {
                continue;
            }
            let posed = LayerPoses::new(&acting, frame);
            for (i, &v) in verts.entities().iter().enumerate() {
                let Ok((rest, fixed, mut pos)) = vertices.get_mut(v) else { continue };
                let target = posed.apply(&acting, i, rest.0, motion.centre, frame);
                let mut p = pos.0;
                for k in 0..3 {
                    if fixed.0[k] {
                        p[k] = target[k];
                    }
                }
                // Predictor for free coordinates: the incremental compression (keeps big load
                // steps from squashing the elements next to the driven boundary).
                for m in &acting {
                    if let MotionKind::Compress { axis, predict: true } = m.kind {
                        if !fixed.0[axis] {
                            let c = motion.centre[axis];
                            let at = |f: f64| m.keyframes.at(f, Interpolation::Linear);
                            let ratio = (1.0 - at(frame)) / (1.0 - at(frame - 1.0));
                            p[axis] = c + (p[axis] - c) * ratio;
                        }
                    }
                }
                if p != pos.0 {
                    pos.0 = p;
                }
            }
        }
    }
}

/// Embedded layers (issue 62) follow their bodies, after every body has moved: each vertex the
/// fixed stencil of the body's current positions. (The shells offset from them start their solve
/// where the last frame ended: moving them along with the embedded layer raised the start energy
/// 10-20x and cost iterations, on the fist and the two-layer forehead: `src/solve/README.md`.)
pub fn carry_embedded(patches: Query<&PatchMotion>, layers: Query<&LayerVertices>, mut vertices: Query<&mut Position>) {
    for motion in &patches {
        for m in &motion.motions {
            let MotionKind::Embed { embedding, .. } = &m.kind else { continue };
            let Ok(base) = layers.get(embedding.base) else { continue };
            let body: Vec<_> = base.entities().iter().map(|&v| position(&vertices, v)).collect();
            let carried = embedding.positions(&body);
            for &layer in &m.layers {
                let Ok(verts) = layers.get(layer) else { continue };
                for (&v, p) in verts.entities().iter().zip(&carried) {
                    if let Ok(mut pos) = vertices.get_mut(v) {
                        if pos.0 != *p {
                            pos.0 = *p;
                        }
                    }
                }
            }
        }
    }
}

fn position(vertices: &Query<&mut Position>, v: Entity) -> glam::DVec3 {
    vertices.get(v).map_or(glam::DVec3::ZERO, |p| p.0)
}
