//! Building a layer's mesh: the generators (grids, slabs, tubes, bodies), OBJ files, layers
//! stacked on or offset from earlier ones (their shared vertices resolved), checked and placed.

use std::collections::HashMap;

use glam::{DVec2, DVec3};

use super::build::Builder;
use super::built::{BuiltLayer, LayerMesh, SlabGrid};
use super::schema::*;
use super::SceneError;
use crate::mesh;
use crate::model::LayerKind;

impl Builder {
    #[allow(clippy::type_complexity)]
    pub(super) fn mesh(
        &self,
        at: &str,
        l: &LayerSpec,
        len: f64,
        offset: DVec3,
        earlier: &[BuiltLayer],
        index: &HashMap<String, usize>,
    ) -> Result<(LayerMesh, Vec<Option<(usize, u32)>>, Option<SlabGrid>), SceneError> {
        let field = format!("{at}.mesh");
        let base_slab = |name: &str| -> Result<(usize, SlabGrid), SceneError> {
            let i = *index.get(name).ok_or_else(|| {
                self.err(
                    format!("{field}.layer"),
                    format!("no earlier layer named \"{name}\" (layers are listed bottom to top)"),
                )
            })?;
            let slab = earlier.get(i).and_then(|b| b.slab).ok_or_else(|| {
                self.err(format!("{field}.layer"), format!("\"{name}\" is not a TetSlab or TetOn volume layer"))
            })?;
            Ok((i, slab))
        };
        let mut shared = Vec::new();
        let mut slab = None;
        let positive = |v: f64, what: &str| -> Result<(), SceneError> {
            if v > 0.0 && v.is_finite() {
                Ok(())
            } else {
                Err(self.err(format!("{field}.{what}"), format!("must be > 0 (got {v})")))
            }
        };
        let mut mesh = match &l.mesh {
            MeshSpec::Grid { size, cells, pattern, z } => {
                if l.kind == LayerKind::Volume {
                    return Err(self.err(&field, "a volume layer needs a TetSlab mesh"));
                }
                positive(size.0, "size")?;
                positive(size.1, "size")?;
                if cells.0 == 0 || cells.1 == 0 {
                    return Err(self.err(format!("{field}.cells"), "needs at least one cell in each direction"));
                }
                self.vertex_budget(&format!("{field}.cells"), [cells.0 as u64 + 1, cells.1 as u64 + 1, 1])?;
                LayerMesh::Surface(mesh::grid(DVec2::new(size.0, size.1) * len, *cells, *pattern, z * len))
            }
            MeshSpec::TetSlab { size, cells, depth, elements, top, grading } => {
                if l.kind != LayerKind::Volume {
                    return Err(self.err(&field, "a TetSlab mesh belongs to a volume layer"));
                }
                positive(size.0, "size")?;
                positive(size.1, "size")?;
                positive(*depth, "depth")?;
                if cells.0 == 0 || cells.1 == 0 {
                    return Err(self.err(format!("{field}.cells"), "needs at least one cell in each direction"));
                }
                if *elements == 0 {
                    return Err(self.err(format!("{field}.elements"), "zero elements through the thickness"));
                }
                let counts = [cells.0 as u64 + 1, cells.1 as u64 + 1, *elements as u64 + 1];
                self.vertex_budget(&format!("{field}.cells"), counts)?;
                let size = DVec2::new(size.0, size.1) * len;
                positive(*grading, "grading")?;
                let (m, _) = mesh::tet_slab(size, *cells, top * len, &[(depth * len, *elements, *grading)]);
                slab = Some(SlabGrid {
                    size,
                    cells: *cells,
                    origin: offset,
                    top: top * len + offset.z,
                    planes: *elements as usize + 1,
                });
                LayerMesh::Volume(m)
            }
            MeshSpec::Obj { path } => {
                if l.kind == LayerKind::Volume {
                    return Err(self.err(&field, "OBJ meshes are surfaces: use them for shell or kinematic layers"));
                }
                let full = self.dir.join(path);
                if let Some(problem) = not_a_file(&full) {
                    return Err(SceneError::at_field(&full, &field, format!("mesh file {problem}")));
                }
                let m = mesh::obj::load(&full, len).map_err(|e| SceneError::at_field(&full, &field, e.to_string()))?;
                mesh::check_surface(&m).map_err(|e| SceneError::at_field(&full, &field, e.to_string()))?;
                LayerMesh::Surface(m)
            }
            MeshSpec::TetOn { layer, depth, elements, grading } => {
                if l.kind != LayerKind::Volume {
                    return Err(self.err(&field, "a TetOn mesh belongs to a volume layer"));
                }
                positive(*depth, "depth")?;
                if *elements == 0 {
                    return Err(self.err(format!("{field}.elements"), "zero elements through the thickness"));
                }
                let (bi, base) = base_slab(layer)?;
                let counts = [base.cells.0 as u64 + 1, base.cells.1 as u64 + 1, *elements as u64 + 1];
                self.vertex_budget(&format!("{field}.elements"), counts)?;
                let new_top = base.top - base.origin.z + depth * len;
                positive(*grading, "grading")?;
                let (m, _) = mesh::tet_slab(base.size, base.cells, new_top, &[(depth * len, *elements, *grading)]);
                slab = Some(SlabGrid { top: new_top + base.origin.z, planes: *elements as usize + 1, ..base });
                // The bottom plane is the base's top plane.
                let plane = base.plane_len();
                shared = (0..m.rest.len()).map(|v| (v < plane).then(|| (bi, (base.top_offset() + v) as u32))).collect();
                LayerMesh::Volume(m)
            }
            MeshSpec::SurfaceOf { layer } => {
                if l.kind == LayerKind::Volume {
                    return Err(self.err(&field, "SurfaceOf makes a surface: use it for shell or kinematic layers"));
                }
                let (bi, base) = base_slab(layer)?;
                let top_local = base.top - base.origin.z;
                let mut m = mesh::grid(base.size, base.cells, mesh::GridPattern::RightTriangle, top_local);
                // The slab's prisms split each cell along the same diagonal as RightTriangle.
                shared = (0..m.rest.len()).map(|v| Some((bi, (base.top_offset() + v) as u32))).collect();
                m.uv.iter_mut().for_each(|u| *u += base.origin.truncate() - offset.truncate());
                LayerMesh::Surface(m)
            }
            MeshSpec::Tube { radius, length, cells } => {
                self.surface_only(&field, l.kind)?;
                positive(*radius, "radius")?;
                positive(*length, "length")?;
                if cells.0 < 3 || cells.1 == 0 {
                    return Err(self.err(format!("{field}.cells"), "needs at least 3 cells around and 1 along"));
                }
                self.vertex_budget(&format!("{field}.cells"), [cells.0 as u64, cells.1 as u64 + 1, 1])?;
                LayerMesh::Surface(mesh::bodies::tube(radius * len, length * len, cells.0, cells.1))
            }
            MeshSpec::Creature { radius, subdivisions } => {
                self.surface_only(&field, l.kind)?;
                positive(*radius, "radius")?;
                if *subdivisions > 7 {
                    return Err(self.err(format!("{field}.subdivisions"), "at most 7 (327,680 triangles)"));
                }
                LayerMesh::Surface(mesh::bodies::creature(radius * len, *subdivisions))
            }
            MeshSpec::Offset { layer, distance } => {
                self.surface_only(&field, l.kind)?;
                if !distance.is_finite() {
                    return Err(self.err(format!("{field}.distance"), "must be finite"));
                }
                let base = index
                    .get(layer)
                    .and_then(|&i| earlier.get(i))
                    .ok_or_else(|| self.err(format!("{field}.layer"), format!("no earlier layer named \"{layer}\"")))?;
                let LayerMesh::Surface(m) = &base.mesh else {
                    return Err(self.err(format!("{field}.layer"), format!("\"{layer}\" is not a surface")));
                };
                let mut m = mesh::bodies::offset(m, distance * len);
                m.rest.iter_mut().for_each(|p| *p -= offset); // the base is already placed
                LayerMesh::Surface(m)
            }
        };
        if shared.is_empty() {
            shared = vec![None; mesh.rest().len()];
        }
        if let LayerMesh::Surface(m) = &mesh {
            mesh::check_surface(m).map_err(|e| self.err(&field, e.to_string()))?;
        }
        match &mut mesh {
            LayerMesh::Surface(m) => m.rest.iter_mut().for_each(|p| *p += offset),
            LayerMesh::Volume(m) => m.rest.iter_mut().for_each(|p| *p += offset),
        }
        // Shared vertices resolve to their owner (a stacked layer's owner may itself share).
        for s in shared.iter_mut().flatten() {
            while let Some(owner) = earlier[s.0].shared[s.1 as usize] {
                *s = owner;
            }
        }
        Ok((mesh, shared, slab))
    }

    fn surface_only(&self, field: &str, kind: LayerKind) -> Result<(), SceneError> {
        if kind == LayerKind::Volume {
            return Err(self.err(field, "this mesh is a surface: use it for shell or kinematic layers"));
        }
        Ok(())
    }
}

/// The most vertices a generated mesh may have: the 3D patch of H15 table 6.4 (0.31 M vertices)
/// peaks at 10.3 GB, so 10 M vertices are already far past any machine's memory.
pub const MAX_GENERATED_VERTICES: u64 = 10_000_000;

impl Builder {
    /// Refuses a generated mesh of more than MAX_GENERATED_VERTICES vertices (counts per axis),
    /// before it is generated.
    fn vertex_budget(&self, field: &str, counts: [u64; 3]) -> Result<(), SceneError> {
        let total = counts.iter().try_fold(1u64, |a, &c| a.checked_mul(c));
        match total {
            Some(n) if n <= MAX_GENERATED_VERTICES => Ok(()),
            _ => Err(self.err(
                field,
                format!(
                    "would generate {} vertices, more than the {MAX_GENERATED_VERTICES} a patch can hold in memory",
                    total.map_or("over 1.8e19".to_string(), |n| n.to_string())
                ),
            )),
        }
    }
}

/// Why an asset path is not a readable file (None when it is one): not found, a directory, or
/// not a regular file (a device or a pipe).
pub(super) fn not_a_file(path: &std::path::Path) -> Option<String> {
    match std::fs::metadata(path) {
        Err(_) => Some(format!("not found: {}", path.display())),
        Ok(m) if m.is_dir() => Some(format!("{} is a directory", path.display())),
        Ok(m) if !m.is_file() => Some(format!("{} is not a regular file", path.display())),
        Ok(_) => None,
    }
}
