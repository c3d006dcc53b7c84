//! Building a layer's mesh: the generators (grids, slabs, tubes, bodies), OBJ files, layers
//! stacked on or offset from earlier ones (their shared vertices resolved), checked and placed.

use std::collections::HashMap;

use glam::{DVec2, DVec3};

use super::built::{BuiltLayer, LayerMesh, SlabGrid};
use super::context::{not_a_file, Builder};
use super::schema::*;
use super::SceneError;
use crate::mesh;
use crate::mesh::obj::FaceGroups;
use crate::model::LayerKind;

/// A layer's mesh as built, with what comes with it.
pub(super) struct BuiltMesh {
    pub mesh: LayerMesh,
    /// Per vertex: Some((layer, vertex)) where it is an earlier layer's.
    pub shared: Vec<Option<(usize, u32)>>,
    pub slab: Option<SlabGrid>,
    pub groups: Option<FaceGroups>,
    pub asset: Option<std::sync::Arc<super::built::BodyAsset>>,
    pub embedding: Option<super::built::BuiltEmbedding>,
    pub parents: Option<Vec<(u32, DVec3)>>,
    pub asset_uv: Option<Vec<DVec2>>,
}

/// Where a layer's mesh is built: its field path, spec, units and placement, the layers
/// before it, and the smallest wavelength (m) of the couplings on it (for `refine:
/// Wavelength(n)`).
struct MeshAt<'a> {
    field: String,
    l: &'a LayerSpec,
    len: f64,
    offset: DVec3,
    earlier: &'a [BuiltLayer],
    index: &'a HashMap<String, usize>,
    lambda: Option<f64>,
}

impl BuiltMesh {
    /// A mesh of its own: nothing shared, no slab, groups, asset, embedding or parents.
    fn of(mesh: LayerMesh) -> BuiltMesh {
        BuiltMesh {
            mesh,
            shared: Vec::new(),
            slab: None,
            groups: None,
            asset: None,
            embedding: None,
            parents: None,
            asset_uv: None,
        }
    }
}

impl Builder {
    /// `lambda`: the smallest wavelength (m) of the couplings on the layer, for `refine:
    /// Wavelength(n)`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn mesh(
        &self,
        at: &str,
        l: &LayerSpec,
        len: f64,
        offset: DVec3,
        earlier: &[BuiltLayer],
        index: &HashMap<String, usize>,
        lambda: Option<f64>,
    ) -> Result<BuiltMesh, SceneError> {
        let field = format!("{at}.mesh");
        let cx = MeshAt { field: field.clone(), l, len, offset, earlier, index, lambda };
        let positive = |v: f64, what: &str| self.positive(&cx, v, what);
        let mut built = match &l.mesh {
            MeshSpec::Grid { size, cells, pattern, z } => {
                if l.kind == LayerKind::Volume {
                    return Err(self.err(&field, "a volume layer needs a TetSlab mesh"));
                }
                positive(size.0, "size")?;
                positive(size.1, "size")?;
                if cells.0 == 0 || cells.1 == 0 {
                    return Err(self.err(format!("{field}.cells"), "needs at least one cell in each direction"));
                }
                self.vertex_budget(&format!("{field}.cells"), [cells.0 as u64 + 1, cells.1 as u64 + 1, 1], l.kind)?;
                BuiltMesh::of(LayerMesh::Surface(mesh::grid(
                    DVec2::new(size.0, size.1) * len,
                    *cells,
                    *pattern,
                    z * len,
                )))
            }
            MeshSpec::TetSlab { .. } => self.tet_slab(&cx)?,
            MeshSpec::Obj { .. } => self.obj_mesh(&cx)?,
            MeshSpec::TetOn { .. } => self.tet_on(&cx)?,
            MeshSpec::SurfaceOf { layer } => {
                if l.kind == LayerKind::Volume {
                    return Err(self.err(&field, "SurfaceOf makes a surface: use it for shell or kinematic layers"));
                }
                let (bi, base) = self.base_slab(&cx, layer)?;
                let top_local = base.top - base.origin.z;
                let mut m = mesh::grid(base.size, base.top_cells, mesh::GridPattern::RightTriangle, top_local);
                // The slab's prisms split each cell along the same diagonal as RightTriangle.
                let shared = (0..m.rest.len()).map(|v| Some((bi, (base.top_first + v) as u32))).collect();
                m.uv.iter_mut().for_each(|u| *u += base.origin.truncate() - offset.truncate());
                BuiltMesh { shared, ..BuiltMesh::of(LayerMesh::Surface(m)) }
            }
            MeshSpec::Tube { radius, length, cells, arc } => {
                self.surface_only(&field, l.kind)?;
                positive(*radius, "radius")?;
                positive(*length, "length")?;
                if cells.0 < 3 || cells.1 == 0 {
                    return Err(self.err(format!("{field}.cells"), "needs at least 3 cells around and 1 along"));
                }
                self.vertex_budget(&format!("{field}.cells"), [cells.0 as u64, cells.1 as u64 + 1, 1], l.kind)?;
                let arc = match arc {
                    None => 360.0,
                    Some(a) if *a > 0.0 && *a <= 360.0 => *a,
                    Some(a) => {
                        return Err(self.err(format!("{field}.arc"), format!("must be in (0, 360] degrees (got {a})")))
                    }
                };
                let (r, l) = (radius * len, length * len);
                BuiltMesh::of(LayerMesh::Surface(mesh::bodies::tube_arc(r, l, cells.0, cells.1, arc.to_radians())))
            }
            MeshSpec::Creature { radius, subdivisions } => {
                self.surface_only(&field, l.kind)?;
                positive(*radius, "radius")?;
                if *subdivisions > 7 {
                    return Err(self.err(format!("{field}.subdivisions"), "at most 7 (327,680 triangles)"));
                }
                BuiltMesh::of(LayerMesh::Surface(mesh::bodies::creature(radius * len, *subdivisions)))
            }
            MeshSpec::Gltf { path, mesh: name } => {
                let (m, a) = self.gltf_body(&field, path, name.as_deref(), l.kind)?;
                let asset_uv = a
                    .corner_uv
                    .as_ref()
                    .map(|(c, _)| super::character::first_corner_per_vertex(&m.faces, c, m.rest.len()));
                BuiltMesh { asset: Some(a), asset_uv, ..BuiltMesh::of(LayerMesh::Surface(m)) }
            }
            MeshSpec::Offset { refine: Some(_), .. } => self.refined_offset(&cx)?,
            MeshSpec::Offset { refine: None, .. } => self.offset_mesh(&cx)?,
        };
        let BuiltMesh { mesh, shared, embedding, .. } = &mut built;
        self.charge_memory(&field, l.kind, mesh.rest().len() as u64)?;
        // A kinematic copy of an embedded layer (an Offset of it, not refined again) is embedded
        // too, farther along the normal; shells offset from it are free.
        if embedding.is_none() && l.kind == LayerKind::Kinematic {
            if let MeshSpec::Offset { layer, distance, refine: None, region: None } = &l.mesh {
                let base = index.get(layer).and_then(|&i| earlier.get(i));
                if let Some(e) = base.and_then(|b| b.embedding.as_ref()) {
                    *embedding =
                        Some(super::built::BuiltEmbedding { distance: e.distance + distance * len, ..e.clone() });
                }
            }
        }
        if shared.is_empty() {
            *shared = vec![None; mesh.rest().len()];
        }
        if let LayerMesh::Surface(m) = &*mesh {
            mesh::check_surface(m).map_err(|e| self.err(&field, e.to_string()))?;
        }
        match mesh {
            LayerMesh::Surface(m) => m.rest.iter_mut().for_each(|p| *p += offset),
            LayerMesh::Volume(m) => m.rest.iter_mut().for_each(|p| *p += offset),
        }
        // Shared vertices resolve to their owner (a stacked layer's owner may itself share).
        for s in shared.iter_mut().flatten() {
            while let Some(owner) = earlier[s.0].shared[s.1 as usize] {
                *s = owner;
            }
        }
        Ok(built)
    }

    fn positive(&self, m: &MeshAt, v: f64, what: &str) -> Result<(), SceneError> {
        if v > 0.0 && v.is_finite() {
            Ok(())
        } else {
            Err(self.err(format!("{}.{what}", m.field), format!("must be > 0 (got {v})")))
        }
    }

    /// The earlier slab layer `name` a TetOn or SurfaceOf mesh builds on, and its grid.
    fn base_slab(&self, m: &MeshAt, name: &str) -> Result<(usize, SlabGrid), SceneError> {
        let field = &m.field;
        let i = *m.index.get(name).ok_or_else(|| {
            self.err(
                format!("{field}.layer"),
                format!("no earlier layer named \"{name}\" (layers are listed bottom to top)"),
            )
        })?;
        let slab = m.earlier.get(i).and_then(|b| b.slab).ok_or_else(|| {
            self.err(format!("{field}.layer"), format!("\"{name}\" is not a TetSlab or TetOn volume layer"))
        })?;
        Ok((i, slab))
    }

    /// A TetSlab volume layer (and the slab grid the layers on it read).
    fn tet_slab(&self, cx: &MeshAt) -> Result<BuiltMesh, SceneError> {
        let MeshAt { field, l, len, offset, .. } = cx;
        let (field, len, offset) = (field.clone(), *len, *offset);
        let positive = |v: f64, what: &str| self.positive(cx, v, what);
        let MeshSpec::TetSlab { size, cells, depth, elements, top, grading, coarsen } = &l.mesh else {
            unreachable!("tet_slab builds its own spec")
        };
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
        self.vertex_budget(&format!("{field}.cells"), counts, l.kind)?;
        let size = DVec2::new(size.0, size.1) * len;
        positive(*grading, "grading")?;
        let coarsen = match coarsen {
            None => None,
            Some(c) => {
                positive(c.every, "coarsen.every")?;
                let from = c.from.unwrap_or(*top);
                if !from.is_finite() {
                    return Err(self.err(format!("{field}.coarsen.from"), "must be finite"));
                }
                Some(mesh::Coarsening { every: c.every * len, from: from * len })
            }
        };
        let levels = [(depth * len, *elements, *grading)];
        let (m, _, planes) = mesh::tet_slab(size, *cells, top * len, &levels, coarsen)
            .map_err(|e| self.err(format!("{field}.coarsen.every"), halves_twice(e, len)))?;
        let slab = Some(SlabGrid {
            size,
            cells: *cells,
            origin: offset,
            top: top * len + offset.z,
            top_cells: *planes.cells.last().unwrap(),
            top_first: *planes.first.last().unwrap(),
            coarsen,
        });
        Ok(BuiltMesh { slab, ..BuiltMesh::of(LayerMesh::Volume(m)) })
    }

    /// An OBJ surface (with its groups).
    fn obj_mesh(&self, cx: &MeshAt) -> Result<BuiltMesh, SceneError> {
        let MeshAt { field, l, len, .. } = cx;
        let (field, len) = (field.clone(), *len);
        let MeshSpec::Obj { path } = &l.mesh else { unreachable!("obj_mesh builds its own spec") };
        if l.kind == LayerKind::Volume {
            return Err(self.err(&field, "OBJ meshes are surfaces: use them for shell or kinematic layers"));
        }
        let full = self.dir.join(path);
        if let Some(problem) = not_a_file(&full) {
            return Err(SceneError::at_field(&full, &field, format!("mesh file {problem}")));
        }
        let (m, g) =
            mesh::obj::load_groups(&full, len).map_err(|e| SceneError::at_field(&full, &field, e.to_string()))?;
        let groups = Some(g);
        mesh::check_surface(&m).map_err(|e| SceneError::at_field(&full, &field, e.to_string()))?;
        // A shell's material space (kernels, property and wrinkle maps) falls back to the
        // rest xy without `vt`: right for a flat sheet, a distortion of a curved one.
        let io = |e: std::io::Error| SceneError::at_field(&full, &field, e.to_string());
        let (lo, hi) = m.rest.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
        let curved = hi.z - lo.z > 1e-9 * (hi - lo).length();
        if l.kind == LayerKind::Shell && curved && !mesh::obj::has_texture_coordinates(&full).map_err(io)? {
            return Err(SceneError::at_field(
                &full,
                &field,
                "a curved shell needs texture coordinates (`vt`): they are its material space; \
                 without them it would be the rest x and y, which distort a curved surface",
            ));
        }
        Ok(BuiltMesh { groups, ..BuiltMesh::of(LayerMesh::Surface(m)) })
    }

    /// A TetOn volume layer stacked on an earlier slab (its bottom plane is the base's top).
    fn tet_on(&self, cx: &MeshAt) -> Result<BuiltMesh, SceneError> {
        let MeshAt { field, l, len, .. } = cx;
        let (field, len) = (field.clone(), *len);
        let positive = |v: f64, what: &str| self.positive(cx, v, what);
        let base_slab = |name: &str| self.base_slab(cx, name);
        let MeshSpec::TetOn { layer, depth, elements, grading } = &l.mesh else {
            unreachable!("tet_on builds its own spec")
        };
        if l.kind != LayerKind::Volume {
            return Err(self.err(&field, "a TetOn mesh belongs to a volume layer"));
        }
        positive(*depth, "depth")?;
        if *elements == 0 {
            return Err(self.err(format!("{field}.elements"), "zero elements through the thickness"));
        }
        let (bi, base) = base_slab(layer)?;
        let counts = [base.cells.0 as u64 + 1, base.cells.1 as u64 + 1, *elements as u64 + 1];
        self.vertex_budget(&format!("{field}.elements"), counts, l.kind)?;
        let new_top = base.top - base.origin.z + depth * len;
        positive(*grading, "grading")?;
        let levels = [(depth * len, *elements, *grading)];
        let (m, _, planes) = mesh::tet_slab(base.size, base.cells, new_top, &levels, base.coarsen)
            .map_err(|e| self.err(format!("{field}.elements"), halves_twice(e, len)))?;
        if planes.cells[0] != base.top_cells {
            return Err(self.err(
                format!("{field}.depth"),
                format!(
                    "the bottom plane's grid {:?} differs from \"{layer}\"'s top grid {:?} (a plane on a \
                     coarsening boundary: move it off by a little)",
                    planes.cells[0], base.top_cells
                ),
            ));
        }
        let slab = Some(SlabGrid {
            top: new_top + base.origin.z,
            top_cells: *planes.cells.last().unwrap(),
            top_first: *planes.first.last().unwrap(),
            ..base
        });
        // The bottom plane is the base's top plane.
        let plane = base.top_len();
        let shared: Vec<_> =
            (0..m.rest.len()).map(|v| (v < plane).then(|| (bi, (base.top_first + v) as u32))).collect();
        Ok(BuiltMesh { slab, shared, ..BuiltMesh::of(LayerMesh::Volume(m)) })
    }

    /// An Offset with `refine`: the base's limit surface, refined and embedded in it.
    fn refined_offset(&self, cx: &MeshAt) -> Result<BuiltMesh, SceneError> {
        let MeshAt { field, l, len, offset, earlier, index, lambda } = cx;
        let (field, len, offset, lambda) = (field.clone(), *len, *offset, *lambda);
        let MeshSpec::Offset { layer, distance, region, refine: Some(refine) } = &l.mesh else {
            unreachable!("refined_offset builds its own spec")
        };
        self.surface_only(&field, l.kind)?;
        if !distance.is_finite() {
            return Err(self.err(format!("{field}.distance"), "must be finite"));
        }
        let bi = *index
            .get(layer)
            .filter(|&&i| i < earlier.len())
            .ok_or_else(|| self.err(format!("{field}.layer"), format!("no earlier layer named \"{layer}\"")))?;
        let base = &earlier[bi];
        let LayerMesh::Surface(bm) = &base.mesh else {
            return Err(self.err(format!("{field}.layer"), format!("\"{layer}\" is not a surface")));
        };
        let keep = match region {
            Some(r) => self.region(&format!("{field}.region"), r, bm, base, len)?,
            None => vec![true; bm.faces.len()],
        };
        let r = self.refined(&field, base, bi, &keep, distance * len, refine, lambda, len, l.kind)?;
        let mut m = r.mesh;
        let asset_uv = super::character::interpolated_asset_uv(base, &r.parents);
        let (embedding, parents) = (r.embedding, Some(r.parents));
        m.rest.iter_mut().for_each(|p| *p -= offset); // the base is already placed
        Ok(BuiltMesh { asset_uv, embedding, parents, ..BuiltMesh::of(LayerMesh::Surface(m)) })
    }

    /// An Offset without `refine`: the base moved along its normals, vertex for vertex (a region of it).
    fn offset_mesh(&self, cx: &MeshAt) -> Result<BuiltMesh, SceneError> {
        let MeshAt { field, l, len, offset, earlier, index, .. } = cx;
        let (field, len, offset) = (field.clone(), *len, *offset);
        let MeshSpec::Offset { layer, distance, region, refine: None } = &l.mesh else {
            unreachable!("offset_mesh builds its own spec")
        };
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
        // A glTF body's material space is its UVs per face corner (islands overlap, seams
        // split): a shell or a UV region on it goes through `refine`.
        let uv_region = matches!(region, Some(RegionSpec::Uv { .. } | RegionSpec::Mask { .. }));
        if base.asset.is_some() && (l.kind == LayerKind::Shell || uv_region) {
            return Err(self.err(
                &field,
                format!(
                    "an Offset of the glTF body \"{layer}\" takes its material space from the UVs of each \
                     face corner: give it `refine` (Levels(0) keeps the body's faces, on its smooth surface)"
                ),
            ));
        }
        let mut m = mesh::bodies::offset(m, distance * len);
        let mut groups = base.groups.clone();
        // (a shell offset vertex for vertex keeps its base's asset UVs)
        let asset_uv = region.is_none().then(|| base.asset_uv.clone()).flatten();
        if let Some(r) = region {
            let keep = self.region(&format!("{field}.region"), r, &m, base, len)?;
            m = mesh::select::faces_within(&m, &keep);
            if m.faces.is_empty() {
                let message = format!("selects no face of \"{layer}\"");
                return Err(self.err(format!("{field}.region"), message));
            }
            if let Some(g) = &mut groups {
                g.of_face = g.of_face.iter().zip(&keep).filter(|(_, k)| **k).map(|(f, _)| *f).collect();
            }
        }
        m.rest.iter_mut().for_each(|p| *p -= offset); // the base is already placed
        Ok(BuiltMesh { groups, asset_uv, ..BuiltMesh::of(LayerMesh::Surface(m)) })
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

/// Peak memory of a run per vertex (bytes), measured on one frame with every patch solved at
/// once: shells 12.4-15 KB (examples/free_sheet, 10k vertices, 127 MB; lk14/fig6_4_pinch, 12k,
/// 182 MB); tetrahedral layers 33-34 KB (h15/patch_3d_small, 20k, 680 MB; h15/patch_3d, 314k,
/// 10.3 GB); kinematic layers hold no Newton system. The factor's fill grows faster than the
/// vertex count, so this is a lower bound on large meshes.
fn bytes_per_vertex(kind: LayerKind) -> f64 {
    match kind {
        LayerKind::Shell => 12e3,
        LayerKind::Volume => 32e3,
        LayerKind::Kinematic => 1e3,
    }
}

/// The machine's physical memory (bytes) from /proc/meminfo; None where it cannot be read.
fn machine_memory() -> Option<f64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024.0)
}

/// Why a scene's meshes would not fit in `limit` bytes (`whose`: "this machine's memory" or "the
/// scene's `memory` budget"), with `total` bytes estimated for them.
pub(super) fn memory_error(vertices: u64, kind: LayerKind, total: f64, limit: f64, whose: &str) -> Option<String> {
    (total > limit).then(|| {
        format!(
            "with these {vertices} vertices (a {} layer) the scene needs about {} to run, more than {whose} ({})",
            format!("{kind:?}").to_lowercase(),
            bytes(total),
            bytes(limit)
        )
    })
}

/// A memory size for a message: GB from 1 GB up, else MB.
fn bytes(b: f64) -> String {
    if b >= 1e9 {
        format!("{:.1} GB", b / 1e9)
    } else {
        format!("{:.0} MB", b / 1e6)
    }
}

impl Builder {
    /// Which faces of `m` (a copy of `base`'s surface) a region selects: by UV rectangle or mask
    /// the faces all of whose vertices it covers, by group the faces of the base's OBJ group.
    fn region(
        &self,
        field: &str,
        r: &RegionSpec,
        m: &mesh::SurfaceMesh,
        base: &BuiltLayer,
        len: f64,
    ) -> Result<Vec<bool>, SceneError> {
        let uv = &m.uv;
        let inside: Vec<bool> = match r {
            RegionSpec::Group(name) => {
                let Some(groups) = &base.groups else {
                    let message = format!("\"{}\" is not an OBJ mesh: it has no groups (`o` / `g`)", base.name);
                    return Err(self.err(field, message));
                };
                let Some(g) = groups.names.iter().position(|n| n == name) else {
                    let names: Vec<String> = groups.names.iter().map(|n| format!("\"{n}\"")).collect();
                    let message =
                        format!("no group \"{name}\" in \"{}\" (its groups: {})", base.name, names.join(", "));
                    return Err(self.err(field, message));
                };
                return Ok(groups.of_face.iter().map(|&f| f == g as u32).collect());
            }
            RegionSpec::Box { min, max } => {
                let (lo, hi) = (DVec3::new(min.0, min.1, min.2) * len, DVec3::new(max.0, max.1, max.2) * len);
                if !(lo.is_finite() && hi.is_finite() && lo.cmplt(hi).all()) {
                    let message = format!("needs finite min < max in x, y and z (got {min:?} to {max:?})");
                    return Err(self.err(field, message));
                }
                m.rest.iter().map(|p| p.cmpge(lo).all() && p.cmple(hi).all()).collect()
            }
            RegionSpec::Uv { min, max } => {
                let (lo, hi) = (DVec2::new(min.0, min.1) * len, DVec2::new(max.0, max.1) * len);
                if !(lo.is_finite() && hi.is_finite() && lo.cmplt(hi).all()) {
                    let message = format!("needs finite min < max in u and in v (got {min:?} to {max:?})");
                    return Err(self.err(field, message));
                }
                uv.iter().map(|p| p.cmpge(lo).all() && p.cmple(hi).all()).collect()
            }
            RegionSpec::Mask { image, threshold } => {
                if !(0.0..=1.0).contains(threshold) {
                    return Err(self.err(format!("{field}.threshold"), format!("must be in [0, 1] (got {threshold})")));
                }
                let rect = LayerMesh::Surface(mesh::SurfaceMesh { uv: uv.to_vec(), ..Default::default() });
                let map = self.weight_map(&format!("{field}.image"), image, &rect)?;
                if map.values.is_empty() {
                    return Err(self.err(format!("{field}.image"), "the mask is empty (0 pixels)"));
                }
                uv.iter().map(|&p| map.sample(p) >= *threshold).collect()
            }
        };
        Ok(m.faces.iter().map(|f| f.iter().all(|&v| inside[v as usize])).collect())
    }

    /// Refuses a generated mesh of more than MAX_GENERATED_VERTICES vertices (counts per axis),
    /// or one the machine's memory cannot run beside the scene's earlier layers, before it is
    /// generated.
    fn vertex_budget(&self, field: &str, counts: [u64; 3], kind: LayerKind) -> Result<(), SceneError> {
        let total = counts.iter().try_fold(1u64, |a, &c| a.checked_mul(c));
        match total {
            Some(n) if n <= MAX_GENERATED_VERTICES => self.with_memory(field, kind, n).map(|_| ()),
            _ => Err(self.err(
                field,
                format!(
                    "would generate {} vertices, more than the {MAX_GENERATED_VERTICES} a patch can hold in memory",
                    total.map_or("over 1.8e19".to_string(), |n| n.to_string())
                ),
            )),
        }
    }

    /// The memory a run may take (bytes): the scene's budget where it states one, else the
    /// machine's; and whose it is, for the message.
    fn memory_limit(&self) -> Option<(f64, &'static str)> {
        self.budget.get().or_else(|| machine_memory().map(|m| (m, "this machine's memory")))
    }

    /// Refuses a scene whose declared meshes (`preflight`) need more memory than the budget,
    /// naming the layer that takes it past: counted from the text, before any mesh is made.
    pub(super) fn preflight(&self, scene: &super::schema::Scene) -> Result<(), SceneError> {
        let Some((limit, whose)) = self.memory_limit() else { return Ok(()) };
        let mut total = 0.0;
        for (field, kind, n) in super::preflight::declared_vertices(scene) {
            // (past the cap, the mesh's own check says so, as quickly and more exactly)
            if n > MAX_GENERATED_VERTICES {
                continue;
            }
            total += n as f64 * bytes_per_vertex(kind);
            if let Some(message) = memory_error(n, kind, total, limit, whose) {
                return Err(self.err(field, message));
            }
        }
        Ok(())
    }

    /// Refuses a refinement to `vertices` vertices (`faces` faces, `levels` levels) that the
    /// machine's memory or the scene's budget cannot hold beside the earlier layers, naming the
    /// estimate; and says the estimate (`skinsim check` shows it).
    pub(super) fn with_memory_estimate(
        &self,
        field: &str,
        kind: LayerKind,
        vertices: u64,
        levels: u32,
        faces: u64,
    ) -> Result<(), SceneError> {
        let bytes = vertices as f64 * bytes_per_vertex(kind);
        self.note(format!(
            "{field}: {levels} subdivision levels: about {vertices} vertices and {faces} faces, {:.1} MB to run",
            bytes / 1e6
        ));
        self.with_memory(field, kind, vertices).map(|_| ()).map_err(|mut e| {
            e.message = format!("the refinement ({levels} levels, about {vertices} vertices): {}", e.message);
            e
        })
    }

    /// Adds a built layer's estimated memory to the scene's (every patch runs at once) and
    /// refuses the layer that takes the scene past the machine's memory.
    fn charge_memory(&self, field: &str, kind: LayerKind, vertices: u64) -> Result<(), SceneError> {
        self.memory.set(self.with_memory(field, kind, vertices)?);
        Ok(())
    }

    /// The scene's estimated memory with `vertices` more of a `kind` layer, or the error naming
    /// `field` when that passes the machine's memory.
    fn with_memory(&self, field: &str, kind: LayerKind, vertices: u64) -> Result<f64, SceneError> {
        let bytes = self.memory.get() + vertices as f64 * bytes_per_vertex(kind);
        match self.memory_limit().and_then(|(limit, whose)| memory_error(vertices, kind, bytes, limit, whose)) {
            Some(message) => Err(self.err(field, message)),
            None => Ok(bytes),
        }
    }
}

/// The error of a coarsening that would halve the grid twice across one element (z in scene
/// units).
fn halves_twice(e: mesh::CoarseningError, len: f64) -> String {
    format!(
        "the grid would halve twice across the element from z = {:.4} to {:.4}: `coarsen.every` must be at least \
         the element thicknesses (or use more, thinner elements)",
        e.bottom / len,
        e.top / len
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The estimate is the scene's running total: a layer that fits alone is refused when the
    /// earlier layers already hold most of the memory.
    #[test]
    fn the_memory_estimate_counts_the_whole_scene() {
        let limit = 16e9;
        let layer = 1_000_000 * bytes_per_vertex(LayerKind::Shell) as u64;
        assert!(memory_error(1_000_000, LayerKind::Shell, layer as f64, limit, "this machine's memory").is_none());
        let message =
            memory_error(1_000_000, LayerKind::Shell, 2.0 * layer as f64, limit, "this machine's memory").unwrap();
        assert!(message.contains("1000000 vertices (a shell layer)") && message.contains("24.0 GB"), "{message}");
    }
}
