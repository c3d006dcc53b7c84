//! One reader of a layer's arrays for the systems: its vertices in index order, each vertex's
//! index, and its triangles as slots. Per-vertex values are read with `map`.

use std::collections::HashMap;

use bevy_ecs::prelude::*;
use skinsim::model::*;

/// A layer's vertices and triangles, indexed.
pub struct LayerArrays {
    pub vertices: Vec<Entity>,
    /// The layer's faces as slots into `vertices` (a face over a vertex of another layer is
    /// left out).
    pub tris: Vec<[u32; 3]>,
}

impl LayerArrays {
    pub fn new(vertices: Vec<Entity>, faces: impl IntoIterator<Item = [Entity; 3]>) -> LayerArrays {
        let slot: HashMap<Entity, u32> = vertices.iter().enumerate().map(|(i, &e)| (e, i as u32)).collect();
        let tris = faces
            .into_iter()
            .filter_map(|f| {
                let t = f.map(|v| slot.get(&v).copied());
                Some([t[0]?, t[1]?, t[2]?])
            })
            .collect();
        LayerArrays { vertices, tris }
    }

    /// From a World (exclusive systems and the inspection API); empty for an unknown layer.
    pub fn of(world: &World, layer: Entity) -> LayerArrays {
        let vertices = world.get::<LayerVertices>(layer).map_or(Vec::new(), |v| v.entities().to_vec());
        let faces = world.get::<LayerFaces>(layer).map_or(&[][..], |f| f.entities());
        LayerArrays::new(vertices, faces.iter().filter_map(|&f| world.get::<FaceVerts>(f)).map(|f| f.0))
    }

    /// From a system's queries.
    pub fn queried(
        vertices: &LayerVertices,
        faces: Option<&LayerFaces>,
        face_verts: &Query<&FaceVerts>,
    ) -> LayerArrays {
        let faces = faces.map_or(&[][..], |f| f.entities());
        LayerArrays::new(
            vertices.entities().to_vec(),
            faces.iter().filter_map(|&f| face_verts.get(f).ok()).map(|f| f.0),
        )
    }

    /// A value per vertex, in index order.
    pub fn map<T>(&self, f: impl FnMut(&Entity) -> T) -> Vec<T> {
        self.vertices.iter().map(f).collect()
    }
}
