//! Attachments across a remesh (for Remesh): an Attach driver's springs join vertex pairs at one
//! rest position, and a remesh of either layer moves vertices off each other. After it, the
//! attached layer's springs to the remeshed layer are made again, each from a vertex to the
//! point at its rest (x, y) on the other layer's surface (`FaceSpring`), with the stiffness the
//! scene gave per unit area.

use bevy_ecs::prelude::*;
use glam::DVec3;
use skinsim::mesh::locate::XyLocator;
use skinsim::mesh::{self, select};
use skinsim::model::*;

/// Makes again the springs of every attachment that `remeshed` is either end of.
pub fn reattach(world: &mut World, remeshed: Entity) {
    let mut touched: Vec<(Entity, Vec<(Entity, f64)>)> = world
        .query::<(Entity, &Attachments)>()
        .iter(world)
        .filter(|(a, list)| *a == remeshed || list.0.iter().any(|(b, _)| *b == remeshed))
        .map(|(a, list)| (a, list.0.clone()))
        .collect();
    touched.sort_by_key(|(a, _)| a.to_bits());
    for (a_layer, list) in touched {
        for (b_layer, k_area) in list.into_iter().filter(|(b, _)| a_layer == remeshed || *b == remeshed) {
            let old = springs_to(world, a_layer, b_layer, b_layer == remeshed);
            // The attached vertices keep their springs' stiffness, unless their own layer was
            // remeshed: then every vertex (a shell's) by its new area.
            let attached: Vec<(Entity, f64)> = if a_layer == remeshed {
                let (verts, rest, faces) = surface(world, a_layer);
                let area = select::vertex_areas(&rest, &faces);
                verts.into_iter().zip(area).map(|(v, a)| (v, k_area * a)).collect()
            } else {
                old.iter().map(|&(_, a, k)| (a, k)).collect()
            };
            for (spring, _, _) in old {
                world.despawn(spring);
            }
            let (b_verts, b_rest, b_faces) = surface(world, b_layer);
            let locator = XyLocator::new(&b_rest, &b_faces);
            let batch: Vec<_> = attached
                .into_iter()
                .filter_map(|(a, stiffness)| {
                    let p = world.get::<RestPos>(a)?.0;
                    let (f, w) = locator.locate(p)?;
                    let b = b_faces[f].map(|v| b_verts[v as usize]);
                    Some((FaceSpring { a, b, w, stiffness }, SpringOf(a_layer)))
                })
                .collect();
            world.spawn_batch(batch);
        }
    }
}

/// The springs of `a_layer` whose other end is on `b_layer` (or is gone, when `b_remeshed`: the
/// remesh despawned it): (spring, its vertex of a_layer, stiffness), in the layer's order.
fn springs_to(world: &World, a_layer: Entity, b_layer: Entity, b_remeshed: bool) -> Vec<(Entity, Entity, f64)> {
    let Some(springs) = world.get::<LayerSprings>(a_layer) else { return Vec::new() };
    let on_b = |v: Entity| match world.get_entity(v).ok().and_then(|e| e.get::<VertexOf>()) {
        Some(l) => l.0 == b_layer,
        None => b_remeshed,
    };
    springs
        .entities()
        .iter()
        .filter_map(|&s| {
            let e = world.entity(s);
            if let Some(sp) = e.get::<Spring>() {
                on_b(sp.b).then_some((s, sp.a, sp.stiffness))
            } else {
                let sp = e.get::<FaceSpring>()?;
                on_b(sp.b[0]).then_some((s, sp.a, sp.stiffness))
            }
        })
        .collect()
}

/// A layer's surface: its vertices, their rest positions, and its faces (a shell's own, or the
/// boundary of its tetrahedra) as indices into them.
fn surface(world: &World, layer: Entity) -> (Vec<Entity>, Vec<DVec3>, Vec<[u32; 3]>) {
    let faces: Vec<[Entity; 3]> = match world.get::<LayerFaces>(layer).filter(|f| !f.entities().is_empty()) {
        Some(lf) => lf.entities().iter().filter_map(|f| world.get::<FaceVerts>(*f).map(|v| v.0)).collect(),
        None => {
            let tets: Vec<[Entity; 4]> = world.get::<LayerTets>(layer).map_or(Vec::new(), |lt| {
                lt.entities().iter().filter_map(|t| world.get::<TetVerts>(*t).map(|v| v.0)).collect()
            });
            let (ents, idx) = mesh::compact(&tets);
            mesh::surface_of_tets(&idx).into_iter().map(|f| f.map(|i| ents[i as usize])).collect()
        }
    };
    let (verts, tris) = mesh::compact(&faces);
    let rest = verts.iter().map(|v| world.get::<RestPos>(*v).map_or(DVec3::NAN, |r| r.0)).collect();
    (verts, rest, tris)
}
