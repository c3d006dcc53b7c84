//! Remesh (ARCHITECTURE.md 2, REMESH.md): after the first solved frame and every `every` frames
//! after that, each shell layer with `RemeshSettings` is copied out, remeshed in material space (`skinsim::mesh::remesh`), and
//! written back. Surviving vertices, faces and edges keep their entities; new ones are spawned
//! (without rest data: PropertyResample fills it in), removed ones despawned, and the layer's
//! topology epoch bumped so that kernels, the solver pattern and the render mesh follow.

use std::collections::HashMap;

use bevy_ecs::prelude::*;
use glam::{DMat2, DVec2, DVec3};
use skinsim::mesh::imperfection::remesh_under;
use skinsim::mesh::remesh::identity::{match_keys, sorted};
use skinsim::mesh::remesh::sizing::{add_wavelength_terms, WavelengthSizing};
use skinsim::mesh::remesh::RemeshVertex;
use skinsim::model::*;

pub fn remesh_layers(world: &mut World) {
    let frame = world.resource::<SimClock>().frame;
    let mut layers: Vec<(Entity, RemeshSettings)> = world
        .query::<(Entity, &RemeshSettings)>()
        .iter(world)
        // Frames count from 1. The first frame is solved on the scene's own mesh, as in ARCSim
        // (remesh after each step): a remesh of the unsolved start sees no curvature and no
        // compression, so it would coarsen everything and the wrinkle mode would be chosen on
        // the coarsest mesh allowed (measured: LK14 case 10 then ends 13 % long). The
        // wavelength term sees the compression the driver imposes before any solve: with it
        // the first remesh comes before the first solve (issue 26 item 1).
        .filter(|(_, r)| {
            let first = if r.wavelength.is_some() { 1 } else { 2 };
            frame >= first && (frame - first).is_multiple_of(r.every)
        })
        .map(|(e, r)| (e, *r))
        .collect();
    layers.sort_by_key(|(e, _)| e.to_bits());
    let kernels: Vec<Kernel> = world.query::<&Kernel>().iter(world).copied().collect();
    for (layer, mut settings) in layers {
        // A kernel's support must keep enough vertices for its weights to be adjusted (at
        // least three, not collinear; LK14 4.2.1): edges at most half the smallest radius of a
        // kernel on this layer. (Measured without the cap: a 1.3 mm kernel radius under a 2 mm
        // size_max left supports of one or two vertices, and the frame did not converge.)
        let radius = kernels.iter().filter(|k| k.upper == layer || k.lower == layer).map(|k| k.shape.radius);
        let p = &mut settings.params;
        p.size_max = radius.fold(p.size_max, |m, r| m.min(KERNEL_EDGES * r)).max(p.size_min * 1.0001);
        let epoch = |w: &World| w.get::<TopologyEpoch>(layer).map(|e| e.0);
        let before = epoch(world);
        remesh_layer(world, layer, &settings, frame);
        if epoch(world) != before {
            crate::attach::reattach(world, layer);
        }
    }
}

/// The longest edge a kernel support allows, relative to the kernel radius.
const KERNEL_EDGES: f64 = 0.5;

fn remesh_layer(world: &mut World, layer: Entity, settings: &RemeshSettings, frame: u32) {
    let verts: Vec<Entity> = world.get::<LayerVertices>(layer).map_or(Vec::new(), |v| v.entities().to_vec());
    let old_faces: Vec<Entity> = world.get::<LayerFaces>(layer).map_or(Vec::new(), |f| f.entities().to_vec());
    let old_edges: Vec<Entity> = world.get::<LayerEdges>(layer).map_or(Vec::new(), |e| e.entities().to_vec());
    let index: HashMap<Entity, u32> = verts.iter().enumerate().map(|(i, &v)| (v, i as u32)).collect();
    let input: Vec<RemeshVertex> = verts
        .iter()
        .map(|&v| {
            let e = world.entity(v);
            RemeshVertex {
                uv: e.get::<MaterialPos>().expect("shell vertex").0,
                x: e.get::<Position>().expect("vertex").0,
                v: e.get::<Velocity>().map_or(glam::DVec3::ZERO, |v| v.0),
                rest: e.get::<RestPos>().expect("vertex").0,
                fixed: e.get::<Prescribed>().map_or([false; 3], |p| p.0),
                origin: None,
            }
        })
        .collect();
    let tris: Vec<[Entity; 3]> = old_faces.iter().map(|&f| world.get::<FaceVerts>(f).expect("face").0).collect();
    let faces: Vec<[u32; 3]> = tris.iter().map(|t| t.map(|v| index[&v])).collect();
    let imperfection = world.get::<LayerImperfection>(layer).map(|i| i.0);
    let extra = match settings.wavelength {
        Some(w) => wavelength_terms(world, layer, &input, &faces, &w),
        None => Vec::new(),
    };
    let out = remesh_under(imperfection.as_ref(), input, &faces, &extra, &settings.params);
    // Refine mostly (issue 26 item 3): a remesh that changes too little is not worth the
    // resampling, the new symbolic factorization and the solve it disturbs.
    let small = f64::from(out.stats.splits + out.stats.collapses) < settings.min_change * faces.len() as f64;
    let changed = !small && out.stats.splits + out.stats.collapses + out.stats.flips > 0;
    let report = RemeshReport {
        size_max: settings.params.size_max,
        frame: frame as u64,
        stats: if small { Default::default() } else { out.stats },
        vertices: if small { verts.len() } else { out.vertices.len() } as u32,
        faces: if small { faces.len() } else { out.faces.len() } as u32,
    };
    world.entity_mut(layer).insert(report);
    if !changed {
        return;
    }
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

/// The wavelength term of each face of `layer` (issue 26 item 1; `sizing::add_wavelength_terms`):
/// lambda(x) the wavelength of the nearest kernel holding the layer (twice its radius, LK14
/// 4.1), the strain that of every layer below it (`coupling::kernels::layers_below`).
fn wavelength_terms(
    world: &mut World,
    layer: Entity,
    input: &[RemeshVertex],
    faces: &[[u32; 3]],
    w: &WavelengthSizing,
) -> Vec<DMat2> {
    let kernels: Vec<Kernel> = world.query::<&Kernel>().iter(world).copied().collect();
    let centres: Vec<(DVec2, f64)> =
        kernels.iter().filter(|k| k.upper == layer).map(|k| (k.shape.centre, 2.0 * k.shape.radius)).collect();
    let Some(thickness) = world.get::<Thickness>(layer).map(|t| t.0) else { return Vec::new() };
    let centroids: Vec<DVec2> =
        faces.iter().map(|f| f.iter().map(|&i| input[i as usize].uv).sum::<DVec2>() / 3.0).collect();
    let mut terms = vec![DMat2::ZERO; faces.len()];
    for below in skinsim::coupling::kernels::layers_below(&kernels, layer) {
        let (uv, x, lower) = layer_arrays(world, below);
        add_wavelength_terms(&mut terms, &centroids, &centres, thickness, (&uv, &x, &lower), w);
    }
    terms
}

/// A layer's material positions, positions and faces (empty for a layer without faces).
fn layer_arrays(world: &World, layer: Entity) -> (Vec<DVec2>, Vec<DVec3>, Vec<[u32; 3]>) {
    let verts: Vec<Entity> = world.get::<LayerVertices>(layer).map_or(Vec::new(), |v| v.entities().to_vec());
    let index: HashMap<Entity, u32> = verts.iter().enumerate().map(|(i, &v)| (v, i as u32)).collect();
    let uv = verts.iter().map(|&v| world.get::<MaterialPos>(v).expect("vertex").0).collect();
    let x = verts.iter().map(|&v| world.get::<Position>(v).expect("vertex").0).collect();
    let faces = world.get::<LayerFaces>(layer).map_or(Vec::new(), |f| f.entities().to_vec());
    let faces = faces.iter().map(|&f| world.get::<FaceVerts>(f).expect("face").0.map(|v| index[&v])).collect();
    (uv, x, faces)
}
