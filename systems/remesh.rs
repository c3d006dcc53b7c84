//! Remesh (ARCHITECTURE.md 2, REMESH.md): in the frames `RemeshSettings::due` names, each shell
//! layer with `RemeshSettings` is copied out, remeshed in material space
//! (`skinsim::mesh::remesh`), and written back (`remesh_write`): surviving vertices, faces and
//! edges keep their entities, new ones are spawned (without rest data: PropertyResample fills it
//! in), removed ones despawned, and the layer's topology epoch bumped so that kernels, the solver
//! pattern and the render mesh follow.

use bevy_ecs::prelude::*;
use glam::{DMat2, DVec2, DVec3};
use skinsim::coupling::kernels::layers_below;
use skinsim::mesh::imperfection::remesh_under;
use skinsim::mesh::remesh::sizing::{held_faces, wavelength_terms, LowerLayer, WavelengthSizing, HOLD_SLACK};
use skinsim::mesh::remesh::{FaceRules, RemeshVertex};
use skinsim::model::*;

use crate::layer_arrays::LayerArrays;

pub fn remesh_layers(world: &mut World) {
    let frame = world.resource::<SimClock>().frame;
    let mut layers: Vec<(Entity, RemeshSettings)> = world
        .query::<(Entity, &RemeshSettings)>()
        .iter(world)
        .filter(|(_, r)| r.due(frame))
        .map(|(e, r)| (e, *r))
        .collect();
    layers.sort_by_key(|(e, _)| e.to_bits());
    let kernels: Vec<Kernel> = world.query::<&Kernel>().iter(world).copied().collect();
    for (layer, mut settings) in layers {
        let radii = kernels.iter().filter(|k| k.upper == layer || k.lower == layer).map(|k| k.shape.radius);
        settings.params = settings.params.capped_by_kernels(radii);
        let epoch = |w: &World| w.get::<TopologyEpoch>(layer).map(|e| e.0);
        let before = epoch(world);
        remesh_layer(world, layer, &settings, &kernels, frame);
        if epoch(world) != before {
            crate::attach::reattach(world, layer);
        }
    }
}

fn remesh_layer(world: &mut World, layer: Entity, settings: &RemeshSettings, kernels: &[Kernel], frame: u32) {
    let arrays = LayerArrays::of(world, layer);
    let old_faces: Vec<Entity> = world.get::<LayerFaces>(layer).map_or(Vec::new(), |f| f.entities().to_vec());
    let input: Vec<RemeshVertex> = arrays
        .vertices
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
    let (verts, faces) = (arrays.vertices, arrays.tris);
    let imperfection = world.get::<LayerImperfection>(layer).map(|i| i.0.clone());
    let extra = match settings.wavelength {
        Some(w) => wavelength_terms_of(world, layer, kernels, (&input, &faces), &w),
        None => Vec::new(),
    };
    // (nothing is held at a layer's first remesh: nothing has been refined yet, and a start mesh
    // within `HOLD_SLACK` of the bound would never be refined to it)
    let refined = world.get::<RemeshReport>(layer).is_some_and(|r| r.frame > 0);
    let held = match settings.wavelength {
        Some(w) if w.hold && refined => {
            let uv: Vec<DVec2> = input.iter().map(|v| v.uv).collect();
            held_faces(&extra, &uv, &faces, HOLD_SLACK)
        }
        _ => Vec::new(),
    };
    let rules = FaceRules { held, kept: crate::remesh_contact::kept_faces(world, layer, &verts, &faces) };
    let out = remesh_under(imperfection.as_ref(), input, &faces, &extra, &rules, &settings.params);
    let small = out.is_small(settings.min_change, faces.len());
    let report = RemeshReport::new(frame, settings.params.size_max, &out, small, (verts.len(), faces.len()));
    world.entity_mut(layer).insert(report);
    if !small && out.changed() {
        let mut settings = *settings;
        if out.at_rest {
            (settings.settle, settings.local_solve) = (false, false);
        }
        crate::remesh_write::apply(world, layer, &settings, &verts, (&old_faces, &tris), &out);
    }
}

/// The wavelength term of each face of `layer` (issue 26 item 1; `sizing::add_wavelength_terms`):
/// lambda(x) the wavelength of the nearest kernel holding the layer (twice its radius, LK14
/// 4.1), the strain that of every layer below it (`coupling::kernels::layers_below`); under
/// `lookahead` of the kinematic ones only, now and at their later keyframes, so that what the
/// layers between take once wrinkled does not refine the driver's mesh again (design note).
fn wavelength_terms_of(
    world: &World,
    layer: Entity,
    kernels: &[Kernel],
    (input, faces): (&[RemeshVertex], &[[u32; 3]]),
    w: &WavelengthSizing,
) -> Vec<DMat2> {
    let centres: Vec<(DVec2, f64)> =
        kernels.iter().filter(|k| k.upper == layer).map(|k| (k.shape.centre, 2.0 * k.shape.radius)).collect();
    let Some(thickness) = world.get::<Thickness>(layer).map(|t| t.0) else { return Vec::new() };
    let couplings: Vec<(Entity, Entity)> = kernels.iter().map(|k| (k.upper, k.lower)).collect();
    let frame = world.resource::<SimClock>().frame;
    let mut below = Vec::new();
    for layer in layers_below(&couplings, layer) {
        let later = match w.lookahead.then(|| keyframe_positions(world, layer, frame)) {
            None => Vec::new(),
            Some(Some(later)) => later,
            Some(None) => continue,
        };
        let (uv, x, faces) = layer_arrays(world, layer);
        below.push(LowerLayer { uv, faces, poses: std::iter::once(x).chain(later).collect() });
    }
    let uv: Vec<DVec2> = input.iter().map(|v| v.uv).collect();
    wavelength_terms(&uv, faces, &centres, thickness, &below, w)
}

/// The positions of a kinematic layer (every coordinate of every vertex prescribed) at each
/// keyframe after `frame` of the motions that drive it (none without a motion); None for any
/// other layer. Values and weights are interpolated between keys, so a single motion's extremes
/// are at its keys.
fn keyframe_positions(world: &World, layer: Entity, frame: u32) -> Option<Vec<Vec<DVec3>>> {
    let verts: Vec<Entity> = world.get::<LayerVertices>(layer).map_or(Vec::new(), |v| v.entities().to_vec());
    if verts.iter().any(|&v| world.get::<Prescribed>(v).is_none_or(|p| p.0 != [true; 3])) {
        return None;
    }
    let patch = world.iter_entities().find(|e| e.get::<PatchLayers>().is_some_and(|l| l.entities().contains(&layer)));
    let Some(motion) = patch.and_then(|p| p.get::<PatchMotion>()) else { return Some(Vec::new()) };
    let acting: Vec<&Motion> = motion.motions.iter().filter(|m| m.layers.contains(&layer)).collect();
    let rest: Vec<DVec3> = verts.iter().map(|&v| world.get::<RestPos>(v).expect("vertex").0).collect();
    let at = |k: u32| pose_at(&acting, &rest, motion.centre, f64::from(k));
    Some(keyframes_after(&acting, frame).into_iter().map(at).collect())
}

/// A layer's material positions, positions and faces (empty for a layer without faces).
fn layer_arrays(world: &World, layer: Entity) -> (Vec<DVec2>, Vec<DVec3>, Vec<[u32; 3]>) {
    let a = LayerArrays::of(world, layer);
    let uv = a.map(|&v| world.get::<MaterialPos>(v).expect("vertex").0);
    let x = a.map(|&v| world.get::<Position>(v).expect("vertex").0);
    (uv, x, a.tris)
}
