//! PropertyResample (ARCHITECTURE.md 2; LK14 5.2): rest data for the elements a remesh created,
//! by the same rules as at spawn (`skinsim::model::ShellRest`). A face without `FaceRest` gets
//! its rest shape, the layer's prestrain F0 (H15 4.3) and the property map's thickness and
//! modulus at its centroid; an edge with `EdgeOpposite` gets its `Hinge` (with the prestrain's
//! rest curvature), the map's bending factor sampled at its midpoint; the lumped masses of
//! every layer that got new faces are recomputed.

use std::collections::HashMap;

use bevy_ecs::prelude::*;
use skinsim::model::*;

use crate::layer_arrays::LayerArrays;

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
    let rest_of = |world: &World, v: Entity| world.get::<RestPos>(v).expect("vertex").0;
    let uv_of = |world: &World, v: Entity| world.get::<MaterialPos>(v).expect("vertex").0;
    let mut layers: Vec<Entity> = Vec::new();
    for (face, tri, layer) in faces {
        let data = &layer_data[&layer];
        let Some(rules) = data.rules() else { continue };
        let uv = tri.map(|v| uv_of(world, v));
        // (a rest triangle a remesh made degenerate falls back to its material-space shape,
        // which a remesh keeps positive)
        let flat = uv.map(|u| u.extend(0.0));
        let Some(shape) = [tri.map(|v| rest_of(world, v)), flat].into_iter().find_map(|t| rules.face(t, uv)) else {
            continue;
        };
        let mut e = world.entity_mut(face);
        e.insert(FaceRest(shape.rest));
        if let Some(f0) = shape.prestrain {
            e.insert(FacePrestrain(f0));
        }
        if data.properties.is_some() {
            e.insert(ModulusScale(shape.young));
        }
        layers.push(layer);
    }
    for (edge, ends, opposite, layer) in edges {
        let data = &layer_data[&layer];
        let (Some(bending), Some(rules)) = (data.bending, data.rules()) else { continue };
        let x = [ends[0], ends[1], opposite[0], opposite[1]].map(|v| rest_of(world, v));
        let rest = rules.hinge(&bending, 1.0, x, ends.map(|v| uv_of(world, v)));
        world.entity_mut(edge).insert(Hinge { opposite, rest, image: None }).remove::<EdgeOpposite>();
    }
    layers.sort_unstable();
    layers.dedup();
    for layer in layers {
        lump_masses(world, layer, &layer_data[&layer]);
    }
}

struct LayerData {
    thickness: Option<f64>,
    bending: Option<Bending>,
    properties: Option<LayerProperties>,
    prestrain: Option<LayerPrestrain>,
}

impl LayerData {
    /// A shell's rest rules (None for a layer without a thickness).
    fn rules(&self) -> Option<ShellRest<'_>> {
        Some(ShellRest {
            thickness: self.thickness?,
            prestrain: self.prestrain.as_ref(),
            properties: self.properties.as_ref(),
        })
    }
}

/// The layer's lumped masses, recomputed from its rest mesh (as at spawn).
fn lump_masses(world: &mut World, layer: Entity, data: &LayerData) {
    let (Some(density), Some(rules)) = (world.get::<Material>(layer).map(|m| m.density), data.rules()) else { return };
    let a = LayerArrays::of(world, layer);
    let rest = a.map(|&v| world.get::<RestPos>(v).expect("vertex").0);
    let uv = a.map(|&v| world.get::<MaterialPos>(v).expect("vertex").0);
    let mass = rules.masses(density, &rest, &uv, &a.tris);
    for (v, m) in a.vertices.into_iter().zip(mass) {
        world.entity_mut(v).insert(Mass(m));
    }
}
