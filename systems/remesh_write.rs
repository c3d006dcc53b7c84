//! The Remesh stage's write-back (REMESH.md): a remeshed layer's result applied to the ECS by
//! identity (`skinsim::mesh::remesh::identity`). Survivors keep their entities, split midpoints
//! and new faces and edges are spawned, the lost ones despawned in index order, the layer's
//! topology epoch bumped.

use bevy_ecs::prelude::*;
use skinsim::mesh::remesh::identity::{match_keys, sorted};
use skinsim::mesh::remesh::Remeshed;
use skinsim::model::*;

/// Applies `out`, the remesh of `layer` whose vertices were `verts` and whose faces were
/// `faces` (entities, vertex entities).
pub fn apply(
    world: &mut World,
    layer: Entity,
    settings: &RemeshSettings,
    verts: &[Entity],
    faces: (&[Entity], &[[Entity; 3]]),
    out: &Remeshed,
) {
    let (old_faces, tris) = faces;
    let old_edges: Vec<Entity> = world.get::<LayerEdges>(layer).map_or(Vec::new(), |e| e.entities().to_vec());
    // Vertices: survivors keep their entity, split midpoints are spawned, the rest despawned.
    let mut alive = vec![false; verts.len()];
    let ent: Vec<Entity> = out
        .vertices
        .iter()
        .map(|v| match v.origin {
            Some(i) => {
                alive[i as usize] = true;
                verts[i as usize]
            }
            None => world
                .spawn((
                    VertexOf(layer),
                    MaterialPos(v.uv),
                    RestPos(v.rest),
                    Position(v.x),
                    Velocity(v.v),
                    Mass(0.0),
                    Prescribed(v.fixed),
                ))
                .id(),
        })
        .collect();
    let to = |v: [u32; 2]| v.map(|i| ent[i as usize]);
    let new_tris: Vec<[Entity; 3]> = out.faces.iter().map(|f| f.map(|i| ent[i as usize])).collect();
    let (fresh, lost_faces) = match_keys(tris.iter().map(|t| sorted(*t)), new_tris.iter().map(|t| sorted(*t)));
    let mut unsettled = vec![false; out.vertices.len()];
    for ((f, &tri), _) in out.faces.iter().zip(&new_tris).zip(&fresh).filter(|(_, n)| **n) {
        world.spawn((FaceVerts(tri), FaceOf(layer)));
        f.iter().for_each(|&v| unsettled[v as usize] = true);
    }
    if settings.settle || settings.local_solve {
        // The changed region grown by `settle_rings` rings of faces: its boundary then sits
        // where the mesh did not change, so the settle does not pull old vertices against new ones
        // it cannot move.
        skinsim::mesh::grow_rings(&out.faces, &mut unsettled, settings.settle_rings);
        for (i, _) in unsettled.iter().enumerate().filter(|(_, u)| **u) {
            world.entity_mut(ent[i]).insert(Unsettled { sweeps: settings.settle, solve: settings.local_solve });
        }
    }
    // Edges: with bending, a hinge's opposite vertices are part of its identity.
    let bending = world.get::<Bending>(layer).is_some();
    let old_keys: Vec<([Entity; 2], Option<[Entity; 2]>)> = old_edges
        .iter()
        .map(|&e| {
            let r = world.entity(e);
            let opposite = r.get::<Hinge>().map(|h| h.opposite).or(r.get::<EdgeOpposite>().map(|o| o.0));
            (sorted(r.get::<EdgeVerts>().expect("edge").0), opposite.map(sorted))
        })
        .collect();
    let new_edges = skinsim::mesh::edges(&out.faces);
    let opposite = |e: &skinsim::mesh::EdgeInfo| (bending && e.is_interior()).then(|| to(e.opposite));
    let new_keys = new_edges.iter().map(|e| (sorted(to(e.v)), opposite(e).map(sorted)));
    let (fresh, lost_edges) = match_keys(old_keys, new_keys);
    for (e, _) in new_edges.iter().zip(&fresh).filter(|(_, n)| **n) {
        let mut spawned = world.spawn((EdgeVerts(to(e.v)), EdgeOf(layer)));
        if let Some(o) = opposite(e) {
            spawned.insert(EdgeOpposite(o));
        }
    }
    for i in lost_faces {
        world.despawn(old_faces[i]);
    }
    for i in lost_edges {
        world.despawn(old_edges[i]);
    }
    for (v, _) in verts.iter().zip(&alive).filter(|(_, a)| !**a) {
        world.despawn(*v);
    }
    world.get_mut::<TopologyEpoch>(layer).expect("layer").0 += 1;
}
