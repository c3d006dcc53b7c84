//! The rebuild: the packed index and element lists of one patch, read from the ECS when a
//! layer's topology changes.

use bevy_ecs::prelude::*;
use glam::DVec3;
use skinsim::model::*;
use skinsim::physics::cell::VolumeElement;
use skinsim::physics::BendingElement;
use skinsim::solve::{AnchorElem, Elements, HingeElem, MembraneElem, PackedPatch, SpringElem, TetElem};

use super::{ElementItems, LayerItems, LayerItemsItem};

/// Packs the patch's vertices (each once), their state and ties, and every element of its
/// layers, and drops the solver's cache. `bodies`: shared body layers packed after the patch's
/// own, held fixed (`PatchBodies`); `obstacles`: layers contact touches besides them, packed
/// last and held (`ContactObstacles`).
pub(super) fn rebuild(
    packed: &mut PackedPatch,
    index: &mut PackedIndex,
    patch_layers: &PatchLayers,
    bodies: &[Entity],
    obstacles: &[Entity],
    layers: &Query<LayerItems>,
    items: &ElementItems,
) {
    index.vertices.clear();
    index.index.clear();
    // A body under KCK18 anchors is not packed for its own patch; a shared one for kernels is.
    let own: Vec<Entity> =
        patch_layers.entities().iter().copied().filter(|&l| layers.get(l).is_ok_and(|i| !i.anchor_body)).collect();
    pack_vertices(index, &own, layers);
    index.own = index.vertices.len();
    pack_vertices(index, bodies, layers);
    index.held = index.vertices.len();
    pack_vertices(index, obstacles, layers);
    let solved: Vec<Entity> = own.into_iter().chain(bodies.iter().copied()).collect();
    let n = index.vertices.len();
    let state = &mut packed.state;
    state.x = vec![DVec3::ZERO; n];
    state.v = vec![DVec3::ZERO; n];
    state.mass = vec![0.0; n];
    state.fixed = vec![[false; 3]; n];
    for (i, &e) in index.vertices.iter().enumerate() {
        let (p, v, m, f) = items.vertices.get(e).expect("vertex");
        state.x[i] = p.0;
        state.v[i] = v.0;
        state.mass[i] = m.0;
        state.fixed[i] = if i < index.held { f.0 } else { [true; 3] };
    }
    let idx = |e: &Entity| index.index[e];
    state.tie = (0..n as u32).map(|i| (i, [false; 3])).collect();
    for (i, &e) in index.vertices[..index.held].iter().enumerate() {
        if let Ok(t) = items.ties.get(e) {
            if let Some(&m) = index.index.get(&t.master) {
                if (m as usize) < i {
                    state.tie[i] = (m, t.dofs);
                }
            }
        }
    }
    let mut el = Elements::default();
    let (mut face_count, mut tet_count) = (0, 0);
    for &l in &solved {
        let Ok(layer) = layers.get(l) else { continue };
        let material = layer.material;
        if let Some(lf) = layer.faces {
            face_count += lf.entities().len();
            if let (LayerKind::Shell, Some(m)) = (layer.layer.kind, material) {
                for &f in lf.entities() {
                    if let Ok((fv, Some(rest), scale)) = items.faces.get(f) {
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
        if let (Some(le), Some(b)) = (layer.edges, layer.bending) {
            let layer_hinges = le.entities().iter().filter_map(|&e| items.hinges.get(e).ok()).map(|(ev, h)| {
                let v = [idx(&ev.0[0]), idx(&ev.0[1]), idx(&h.opposite[0]), idx(&h.opposite[1])];
                HingeElem { v, rest: h.rest, model: b.model, image: h.image.map(|[a, b]| (idx(&a), idx(&b))) }
            });
            if let (BendingElement::Quadratic, Some(lf)) = (b.element, layer.faces) {
                // Built from the hinges' stiffness (property maps and scale included).
                let tris: Vec<[u32; 3]> = lf
                    .entities()
                    .iter()
                    .filter_map(|&f| items.faces.get(f).ok())
                    .map(|f| f.0 .0.map(|e| idx(&e)))
                    .collect();
                let stiffness: Vec<([u32; 4], f64)> = layer_hinges.map(|h| (h.v, h.rest.weight)).collect();
                let rest_at = |i: u32| items.rest.get(index.vertices[i as usize]).expect("vertex").0;
                let poisson = material.map_or(0.0, |m| m.poisson); // (a shell always has one)
                el.add_plate(&tris, rest_at, &stiffness, n, poisson);
            } else {
                el.hinges.extend(layer_hinges);
            }
        }
        if let (Some(lt), Some(m)) = (layer.tets, material) {
            tet_count += lt.entities().len();
            let mut tets = Vec::with_capacity(lt.entities().len());
            let mut cell_of = Vec::with_capacity(lt.entities().len());
            for &t in lt.entities() {
                if let Ok((tv, rest, scale, cell)) = items.tets.get(t) {
                    let lame = m.lame.scaled(scale.map_or(1.0, |s| s.0));
                    cell_of.push(cell.filter(|_| m.volume_element == VolumeElement::Cell).map(|c| c.0));
                    tets.push(TetElem { v: tv.0.map(|e| idx(&e)), rest: rest.0, model: m.model, lame });
                }
            }
            // Cells take their tets' lambda terms (physics::cell).
            el.add_volume(tets, &cell_of);
        }
        if let Some(ls) = layer.springs {
            for &s in ls.entities() {
                if let Ok(sp) = items.springs.get(s) {
                    el.springs.push(SpringElem { v: [idx(&sp.a), idx(&sp.b)], k: sp.stiffness });
                }
                if let Ok(sp) = items.face_springs.get(s) {
                    let [b0, b1, b2] = sp.b.map(|b| idx(&b));
                    el.face_springs.push(AnchorElem {
                        v: [idx(&sp.a), b0, b1, b2],
                        w: [1.0, -sp.w[0], -sp.w[1], -sp.w[2]],
                        k: sp.stiffness,
                        target: glam::DVec3::ZERO,
                    });
                }
            }
        }
    }
    packed.length_scale = skinsim::mesh::bounds::diagonal(&packed.state.x);
    packed.elements = el;
    index.faces = face_count;
    index.tets = tet_count;
    packed.cache.invalidate();
}

/// Gives every vertex of `list`'s layers a packed index, each once, in order.
fn pack_vertices(index: &mut PackedIndex, list: &[Entity], layers: &Query<LayerItems>) {
    for &l in list {
        let Ok(LayerItemsItem { vertices: Some(verts), .. }) = layers.get(l) else { continue };
        for &v in verts.entities() {
            if let std::collections::hash_map::Entry::Vacant(slot) = index.index.entry(v) {
                slot.insert(index.vertices.len() as u32);
                index.vertices.push(v);
            }
        }
    }
}
