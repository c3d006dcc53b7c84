//! Assemble's rebuild: the packed vertex list and element lists of one patch, read from the
//! ECS when a layer's topology changes (`assemble::gather_bodies` decides when).

use std::collections::HashMap;

use bevy_ecs::prelude::*;
use glam::DVec3;
use skinsim::model::*;
use skinsim::physics::{BendingElement, QuadraticBending};
use skinsim::solve::{Elements, HingeElem, MembraneElem, SolverBody, SpringElem, TetElem};

use crate::assemble::LayerItems;

/// Packs the patch's vertices (each once), their state and ties, and every element of its
/// layers into `body`, and drops the cached pattern.
#[allow(clippy::too_many_arguments)]
pub(crate) fn rebuild(
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
                let boundary = skinsim::mesh::boundary_vertices(&tris, body.vertices.len());
                let (q, g) = QuadraticBending::plate(&tris, rest_at, &stiffness, &boundary, poisson);
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
    body.length_scale = skinsim::mesh::bounds::diagonal(&body.x);
    body.elements = el;
    body.face_count = face_count;
    body.tet_count = tet_count;
    body.invalidate_pattern();
}
