//! The scene's size from its text, before any mesh is made (issue 66): a kinematic tube of 8.1
//! million vertices was generated (44 s, 2.6 GB) before the shell offset from it was found too
//! big to run. The counts here are those of the meshes as declared: generated meshes to within
//! a row,
//! an offset as many as its base (a region only removes some), a refinement by `Levels` 4 to
//! the power of its levels; file meshes (OBJ, glTF) and refinements to a length are counted
//! when they are loaded, as before.

use std::collections::HashMap;

use super::schema::{MeshSpec, RefineSpec, Scene};
use crate::model::LayerKind;

/// A layer's declared vertex count: (its field, e.g. `patches[0].layers[1].mesh`, its kind, the
/// count). Counts saturate at u64::MAX.
pub(super) type Declared = (String, LayerKind, u64);

/// Every layer's declared vertex count, bodies first, in the order the build makes them; the
/// field names what sets the count (`mesh.cells`, `mesh.subdivisions`, `mesh.refine`).
pub(super) fn declared_vertices(scene: &Scene) -> Vec<Declared> {
    let mut out = Vec::new();
    let mut bodies: HashMap<&str, u64> = HashMap::new();
    for (bi, b) in scene.bodies.iter().enumerate() {
        let n = count(&b.mesh, &HashMap::new()).unwrap_or(0);
        bodies.insert(b.name.as_str(), n);
        out.push((format!("bodies[{bi}].mesh{}", what(&b.mesh)), LayerKind::Kinematic, n));
    }
    for (pi, p) in scene.patches.iter().enumerate() {
        // (a patch on a body reaches the body's surface by the body's name)
        let mut known: HashMap<&str, u64> = HashMap::new();
        if let Some(b) = p.body.as_deref().and_then(|b| bodies.get_key_value(b)) {
            known.insert(b.0, *b.1);
        }
        for (li, l) in p.layers.iter().enumerate() {
            let n = count(&l.mesh, &known).unwrap_or(0);
            known.insert(l.name.as_str(), n);
            out.push((format!("patches[{pi}].layers[{li}].mesh{}", what(&l.mesh)), l.kind, n));
        }
    }
    out
}

/// The field of a mesh that sets its count.
fn what(mesh: &MeshSpec) -> &'static str {
    match mesh {
        MeshSpec::Grid { .. } | MeshSpec::TetSlab { .. } | MeshSpec::Tube { .. } => ".cells",
        MeshSpec::Creature { .. } => ".subdivisions",
        MeshSpec::Offset { refine: Some(_), .. } => ".refine",
        _ => "",
    }
}

/// A mesh's declared vertex count (a grid's as (cells + 1) per side: an equilateral grid's odd
/// rows carry one vertex more); None where only loading it tells (files, unknown bases).
fn count(mesh: &MeshSpec, known: &HashMap<&str, u64>) -> Option<u64> {
    let grid = |a: u32, b: u32| (a as u64 + 1).saturating_mul(b as u64 + 1);
    match mesh {
        MeshSpec::Grid { cells, .. } => Some(grid(cells.0, cells.1)),
        MeshSpec::TetSlab { cells, elements, .. } => Some(grid(cells.0, cells.1).saturating_mul(*elements as u64 + 1)),
        MeshSpec::Tube { cells, .. } => Some(grid(cells.0, cells.1)),
        // 20 x 4^s triangles on a closed surface: 10 x 4^s + 2 vertices
        MeshSpec::Creature { subdivisions, .. } => {
            Some(4u64.checked_pow(*subdivisions).map_or(u64::MAX, |p| p.saturating_mul(10).saturating_add(2)))
        }
        MeshSpec::Offset { layer, refine, .. } => {
            let base = *known.get(layer.as_str())?;
            match refine {
                Some(RefineSpec::Levels(l)) => Some(4u64.checked_pow(*l).map_or(u64::MAX, |p| p.saturating_mul(base))),
                _ => Some(base),
            }
        }
        MeshSpec::SurfaceOf { .. } | MeshSpec::TetOn { .. } | MeshSpec::Obj { .. } | MeshSpec::Gltf { .. } => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_offset_counts_its_base_before_the_base_is_made() {
        let text = r#"Scene(name: "t", frames: 1, patches: [Patch(name: "p", layers: [
            Layer(name: "bone", kind: Kinematic, mesh: Tube(radius: 8.0, length: 60.0, cells: (2000, 4049))),
            Layer(name: "skin", kind: Shell, mesh: Offset(layer: "bone", distance: 1.0, refine: Some(Levels(2)))),
            Layer(name: "slab", kind: Volume, mesh: TetSlab(size: (1.0, 1.0), cells: (9, 19), depth: 1.0, elements: 3)),
            Layer(name: "c", kind: Kinematic, mesh: Creature(radius: 1.0, subdivisions: 40)),
        ])])"#;
        let scene: Scene = ron::from_str(text).unwrap();
        let d = declared_vertices(&scene);
        assert_eq!(d[0], ("patches[0].layers[0].mesh.cells".to_string(), LayerKind::Kinematic, 2001 * 4050));
        assert_eq!(d[1].0, "patches[0].layers[1].mesh.refine");
        assert_eq!(d[1].2, 16 * 2001 * 4050);
        assert_eq!(d[2].2, 10 * 20 * 4);
        assert_eq!(d[3].2, u64::MAX);
    }
}
