//! PropertyResample (ARCHITECTURE.md 2; LK14 5.2): rest data for the elements a remesh created.
//! A face without `FaceRest` gets its rest shape, the layer's prestrain F0 (H15 4.3) and the
//! property map's thickness and modulus at its centroid; an edge with `EdgeOpposite` gets its
//! `Hinge` (with the prestrain's rest curvature), the map's bending factor sampled at its
//! midpoint; the lumped masses of every layer that got new faces are recomputed.

use std::collections::HashMap;

use bevy_ecs::prelude::*;
use glam::{DMat2, DVec2};
use skinsim::model::*;
use skinsim::physics::membrane::MembraneRest;
use skinsim::physics::prestrain::hinge_with_curvature;

pub fn resample_properties(world: &mut World) {
    let faces: Vec<(Entity, [Entity; 3], Entity)> = world
        .query_filtered::<(Entity, &FaceVerts, &FaceOf), Without<FaceRest>>()
        .iter(world)
        .map(|(e, v, of)| (e, v.0, of.0))
        .collect();
    let edges: Vec<(Entity, [Entity; 2], [Entity; 2], Entity)> = world
        .query_filtered::<(Entity, &EdgeVerts, &EdgeOpposite, &EdgeOf), Without<Hinge>>()
        .iter(world)
        .map(|(e, v, o, of)| (e, v.0, o.0, of.0))
        .collect();
    // Per layer once (a property map is large: not cloned per element).
    let mut layer_data: HashMap<Entity, LayerData> = HashMap::new();
    for &layer in faces.iter().map(|f| &f.2).chain(edges.iter().map(|e| &e.3)) {
        layer_data.entry(layer).or_insert_with(|| LayerData {
            thickness: world.get::<Thickness>(layer).map(|t| t.0),
            bending: world.get::<Bending>(layer).copied(),
            properties: world.get::<LayerProperties>(layer).cloned(),
            prestrain: world.get::<LayerPrestrain>(layer).cloned(),
        });
    }
    let mut layers: Vec<Entity> = Vec::new();
    for (face, tri, layer) in faces {
        let data = &layer_data[&layer];
        let Some(h) = data.thickness else { continue };
        let rest = tri.map(|v| world.get::<RestPos>(v).expect("vertex").0);
        let uv = tri.map(|v| world.get::<MaterialPos>(v).expect("vertex").0);
        let centre = (uv[0] + uv[1] + uv[2]) / 3.0;
        let local = factors_at(data.properties.as_ref(), centre);
        let f0 = |tri: [glam::DVec3; 3]| data.prestrain.as_ref().map(|p| p.face_f0(tri, centre));
        // (a rest triangle a remesh made degenerate falls back to its material-space shape,
        // which a remesh keeps positive)
        let flat = uv.map(|u| u.extend(0.0));
        let shape = [rest, flat].into_iter().find_map(|tri| {
            let f0 = f0(tri);
            MembraneRest::from_rest_triangle(tri, h * local.thickness, f0.unwrap_or(DMat2::IDENTITY)).map(|s| (s, f0))
        });
        let Some((shape, f0)) = shape else { continue };
        let mut e = world.entity_mut(face);
        e.insert(FaceRest(shape));
        if let Some(f0) = f0 {
            e.insert(FacePrestrain(f0));
        }
        if data.properties.is_some() {
            e.insert(ModulusScale(local.young));
        }
        layers.push(layer);
    }
    for (edge, ends, opposite, layer) in edges {
        let data = &layer_data[&layer];
        let Some(bending) = data.bending else { continue };
        let q = [ends[0], ends[1], opposite[0], opposite[1]];
        let rest = q.map(|v| world.get::<RestPos>(v).expect("vertex").0);
        let mid: DVec2 = ends.iter().map(|&v| world.get::<MaterialPos>(v).expect("vertex").0).sum::<DVec2>() / 2.0;
        let k_b = bending.stiffness * factors_at(data.properties.as_ref(), mid).bending();
        let (kappa, along) = data.prestrain.as_ref().map_or((0.0, 0), |p| (p.curvature, p.along));
        let hinge = Hinge { opposite, rest: hinge_with_curvature(bending.model, k_b, rest, kappa, along), image: None };
        world.entity_mut(edge).insert(hinge).remove::<EdgeOpposite>();
    }
    layers.sort_unstable();
    layers.dedup();
    for layer in layers {
        lump_masses(world, layer);
    }
}

struct LayerData {
    thickness: Option<f64>,
    bending: Option<Bending>,
    properties: Option<LayerProperties>,
    prestrain: Option<LayerPrestrain>,
}

/// Lumped masses: density x thickness x rest area / 3 per vertex (as at spawn).
fn lump_masses(world: &mut World, layer: Entity) {
    let Some(density) = world.get::<Material>(layer).map(|m| m.density) else { return };
    let faces: Vec<Entity> = world.get::<LayerFaces>(layer).map_or(Vec::new(), |f| f.entities().to_vec());
    let verts: Vec<Entity> = world.get::<LayerVertices>(layer).map_or(Vec::new(), |v| v.entities().to_vec());
    let mut mass: HashMap<Entity, f64> = verts.iter().map(|&v| (v, 0.0)).collect();
    for f in faces {
        let (Some(tri), Some(rest)) = (world.get::<FaceVerts>(f), world.get::<FaceRest>(f)) else { continue };
        let m = density * rest.0.volume / 3.0;
        for v in tri.0 {
            *mass.get_mut(&v).expect("a face's vertex is its layer's") += m;
        }
    }
    for (v, m) in mass {
        world.entity_mut(v).insert(Mass(m));
    }
}
