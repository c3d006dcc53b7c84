//! Assemble: copies each patch out of the ECS into its packed `SolverBody`. Element lists are
//! rebuilt only when a layer's topology epoch (or element count) changes; positions,
//! velocities and fixed coordinates are gathered every frame.

use std::collections::HashMap;

use bevy_ecs::prelude::*;
use glam::DVec3;
use skinsim::model::*;
use skinsim::physics::{BendingElement, QuadraticBending};
use skinsim::solve::{Elements, HingeElem, MembraneElem, SolverBody, SpringElem, TetElem};

pub(crate) type LayerItems<'a> = (
    &'a Layer,
    &'a TopologyEpoch,
    Option<&'a Material>,
    Option<&'a Bending>,
    Option<&'a LayerVertices>,
    Option<&'a LayerFaces>,
    Option<&'a LayerEdges>,
    Option<&'a LayerTets>,
    Option<&'a LayerSprings>,
    Option<&'a LayerAnchors>,
    Has<AnchorBody>,
);

#[allow(clippy::too_many_arguments)]
pub fn gather_bodies(
    mut patches: Query<(&PatchLayers, Option<&PatchKernels>, &mut SolverBody)>,
    kernels: Query<crate::kernels::KernelItems>,
    thickness: Query<(&Thickness, Option<&LayerProperties>)>,
    layers: Query<LayerItems>,
    vertices: Query<(&Position, &Velocity, &Mass, &Prescribed)>,
    ties: Query<&Tied>,
    rest: Query<&RestPos>,
    faces: Query<(&FaceVerts, Option<&FaceRest>, Option<&ModulusScale>)>,
    hinges: Query<(&EdgeVerts, &Hinge)>,
    tets: Query<(&TetVerts, &TetRestShape, Option<&ModulusScale>)>,
    springs: Query<&Spring>,
    anchors: Query<(&Anchor, &AnchorState)>,
) {
    for (patch_layers, patch_kernels, mut body) in &mut patches {
        let key = topology_key(patch_layers, &layers);
        let rebuilt = key != body.topology_key;
        if rebuilt {
            rebuild(&mut body, patch_layers, &layers, &vertices, &ties, &faces, &hinges, &tets, &springs, &rest);
            crate::anchors::rebuild_anchor_springs(&mut body, patch_layers, &layers, &anchors);
            body.topology_key = key;
        }
        if let Some(pk) = patch_kernels {
            let resampled = pk.entities().iter().any(|&k| kernels.get(k).is_ok_and(|(_, w)| w.is_changed()));
            if rebuilt || resampled {
                let (items, faces) = (&kernels, &faces);
                body.constraints = crate::kernels::kernel_rows(&body, pk, items, &layers, faces, &thickness);
                body.invalidate_pattern(); // the pattern holds the kernels' J^T J couplings
            }
        }
        let body = body.as_mut();
        let mut fixed_changed = false;
        for (i, &e) in body.vertices.iter().enumerate() {
            let (p, v, _, f) = vertices.get(e).expect("vertex of a live layer");
            body.x[i] = p.0;
            body.v[i] = v.0;
            if body.fixed[i] != f.0 {
                body.fixed[i] = f.0;
                fixed_changed = true;
            }
        }
        if fixed_changed {
            body.invalidate_pattern();
        }
        crate::anchors::update_anchor_targets(body, &anchors);
    }
}

fn topology_key(patch_layers: &PatchLayers, layers: &Query<LayerItems>) -> u64 {
    // A cheap fingerprint: epochs and element counts of every layer, in order.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut mix = |v: u64| {
        h ^= v;
        h = h.wrapping_mul(0x100_0000_01b3);
    };
    for &l in patch_layers.entities() {
        if let Ok((_, epoch, _, _, v, f, e, t, s, a, _)) = layers.get(l) {
            mix(l.to_bits());
            mix(epoch.0);
            mix(v.map_or(0, |x| x.entities().len()) as u64);
            mix(f.map_or(0, |x| x.entities().len()) as u64);
            mix(e.map_or(0, |x| x.entities().len()) as u64);
            mix(t.map_or(0, |x| x.entities().len()) as u64);
            mix(s.map_or(0, |x| x.entities().len()) as u64);
            mix(a.map_or(0, |x| x.entities().len()) as u64);
        }
    }
    h
}

#[allow(clippy::too_many_arguments)]
fn rebuild(
    body: &mut SolverBody,
    patch_layers: &PatchLayers,
    layers: &Query<LayerItems>,
    vertices: &Query<(&Position, &Velocity, &Mass, &Prescribed)>,
    ties: &Query<&Tied>,
    faces: &Query<(&FaceVerts, Option<&FaceRest>, Option<&ModulusScale>)>,
    hinges: &Query<(&EdgeVerts, &Hinge)>,
    tets: &Query<(&TetVerts, &TetRestShape, Option<&ModulusScale>)>,
    springs: &Query<&Spring>,
    rest: &Query<&RestPos>,
) {
    let mut index: HashMap<Entity, u32> = HashMap::new();
    body.vertices.clear();
    for &l in patch_layers.entities() {
        // A body under anchors is not solved for: the walk reads it, the springs hold targets.
        let Ok((.., Some(verts), _, _, _, _, _, false)) = layers.get(l) else { continue };
        for &v in verts.entities() {
            index.entry(v).or_insert_with(|| {
                body.vertices.push(v);
                (body.vertices.len() - 1) as u32
            });
        }
    }
    let n = body.vertices.len();
    body.x = vec![DVec3::ZERO; n];
    body.v = vec![DVec3::ZERO; n];
    body.mass = vec![0.0; n];
    body.fixed = vec![[false; 3]; n];
    for (i, &e) in body.vertices.iter().enumerate() {
        let (p, v, m, f) = vertices.get(e).expect("vertex");
        body.x[i] = p.0;
        body.v[i] = v.0;
        body.mass[i] = m.0;
        body.fixed[i] = f.0;
    }
    let idx = |e: &Entity| index[e];
    body.tie = (0..n as u32).map(|i| (i, [false; 3])).collect();
    for (i, &e) in body.vertices.iter().enumerate() {
        if let Ok(t) = ties.get(e) {
            if let Some(&m) = index.get(&t.master) {
                if (m as usize) < i {
                    body.tie[i] = (m, t.dofs);
                }
            }
        }
    }
    let mut el = Elements::default();
    let (mut face_count, mut tet_count) = (0, 0);
    for &l in patch_layers.entities() {
        let Ok((layer, _, material, bending, _, lfaces, ledges, ltets, lsprings, _, false)) = layers.get(l) else {
            continue;
        };
        if let Some(lf) = lfaces {
            face_count += lf.entities().len();
            if let (LayerKind::Shell, Some(m)) = (layer.kind, material) {
                for &f in lf.entities() {
                    if let Ok((fv, Some(rest), scale)) = faces.get(f) {
                        el.membranes.push(MembraneElem {
                            v: fv.0.map(|e| idx(&e)),
                            rest: rest.0,
                            model: m.model,
                            lame: m.lame.scaled(scale.map_or(1.0, |s| s.0)),
                        });
                    }
                }
            }
        }
        if let (Some(le), Some(b)) = (ledges, bending) {
            let layer_hinges = le.entities().iter().filter_map(|&e| hinges.get(e).ok()).map(|(ev, h)| {
                let v = [idx(&ev.0[0]), idx(&ev.0[1]), idx(&h.opposite[0]), idx(&h.opposite[1])];
                HingeElem { v, rest: h.rest, model: b.model, image: h.image.map(|[a, b]| (idx(&a), idx(&b))) }
            });
            if let (BendingElement::Quadratic, Some(lf)) = (b.element, lfaces) {
                // Built from the hinges' stiffness (property maps and scale included).
                let tris: Vec<[u32; 3]> =
                    lf.entities().iter().filter_map(|&f| faces.get(f).ok()).map(|f| f.0 .0.map(|e| idx(&e))).collect();
                let stiffness: Vec<([u32; 4], f64)> = layer_hinges.map(|h| (h.v, h.rest.weight)).collect();
                let rest_at = |i: u32| rest.get(body.vertices[i as usize]).expect("vertex").0;
                let poisson = material.map_or(0.0, |m| m.poisson); // (a shell always has one)
                let (q, g) = QuadraticBending::plate(&tris, rest_at, &stiffness, poisson);
                el.quadratic.extend(q);
                el.gaussian.extend(g);
            } else {
                el.hinges.extend(layer_hinges);
            }
        }
        if let (Some(lt), Some(m)) = (ltets, material) {
            tet_count += lt.entities().len();
            for &t in lt.entities() {
                if let Ok((tv, rest, scale)) = tets.get(t) {
                    let lame = m.lame.scaled(scale.map_or(1.0, |s| s.0));
                    el.tets.push(TetElem { v: tv.0.map(|e| idx(&e)), rest: rest.0, model: m.model, lame });
                }
            }
        }
        if let Some(ls) = lsprings {
            for &s in ls.entities() {
                if let Ok(sp) = springs.get(s) {
                    el.springs.push(SpringElem { v: [idx(&sp.a), idx(&sp.b)], k: sp.stiffness });
                }
            }
        }
    }
    let (lo, hi) = body.x.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
    body.length_scale = (hi - lo).length();
    body.elements = el;
    body.face_count = face_count;
    body.tet_count = tet_count;
    body.invalidate_pattern();
}
