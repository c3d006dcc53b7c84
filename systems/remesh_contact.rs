//! The remesh's side of contact: which faces of a layer a remesh must keep the shape of
//! (`skinsim::mesh::remesh::FaceRules::kept`, `src/mesh/remesh/README.md` "Remeshing with
//! contact").

use bevy_ecs::prelude::*;
use skinsim::model::{PackedIndex, PatchLayers};
use skinsim::solve::PackedPatch;

/// The faces of `layer` near contact at its patch's last solve, whose shape a remesh keeps
/// (`ContactState::kept_faces`); empty without contact.
pub fn kept_faces(world: &World, layer: Entity, verts: &[Entity], faces: &[[u32; 3]]) -> Vec<bool> {
    let patch = world.iter_entities().find(|e| e.get::<PatchLayers>().is_some_and(|l| l.entities().contains(&layer)));
    let Some(patch) = patch else { return Vec::new() };
    let (Some(packed), Some(index)) = (patch.get::<PackedPatch>(), patch.get::<PackedIndex>()) else {
        return Vec::new();
    };
    let Some(state) = packed.contact.as_ref().filter(|c| c.last.len() == index.vertices.len()) else {
        return Vec::new();
    };
    let numbers: Vec<Option<u32>> = verts.iter().map(|v| index.index.get(v).copied()).collect();
    state.kept_faces(&numbers, faces)
}
