//! Real characters at the scene boundary (issue 62): glTF bodies (their UVs made length-true per
//! island), patches refined finer than their body on its smooth surface and embedded in it, and
//! the `Rig` driver that poses a glTF body by its clips, joints and morph targets.

use std::sync::Arc;

use glam::{DVec2, DVec3};

use super::built::{BodyAsset, BuiltEmbedding, BuiltLayer, LayerMesh};
use super::context::Builder;
use super::schema::{RefineSpec, SkinningSpec};
use super::SceneError;
use crate::mesh::{self, rig, subdivision, uv_islands, SurfaceMesh};
use crate::model::{Interpolation, Keyframes, LayerKind, RigMotion};

/// A region whose faces stretch their island's UVs by more than this (the area-weighted mean
/// ratio of principal stretches), or whose own area ratio differs from its island's by more than
/// this factor, gets a conformal chart of its own as its material space.
pub(crate) const CHART_STRETCH: f64 = 1.1;

/// A refined layer's mesh, its embedding (kinematic layers) and each vertex's parent face and
/// barycentric coordinates in the base.
pub(super) struct Refined {
    pub mesh: SurfaceMesh,
    pub embedding: Option<BuiltEmbedding>,
    pub parents: Vec<(u32, DVec3)>,
}

impl Builder {
    /// A glTF body: its welded surface in the engine's frame (+Z up, metres), the material
    /// coordinates length-true per UV island, and the asset for its `Rig` driver.
    pub(super) fn gltf_body(
        &self,
        field: &str,
        path: &str,
        mesh_name: Option<&str>,
        kind: LayerKind,
    ) -> Result<(SurfaceMesh, Arc<BodyAsset>), SceneError> {
        if kind != LayerKind::Kinematic {
            return Err(self.err(field, "a glTF mesh is a body: use it for a kinematic layer or a `Body`"));
        }
        let full = self.dir.join(path);
        if let Some(problem) = super::context::not_a_file(&full) {
            return Err(SceneError::at_field(&full, field, format!("mesh file {problem}")));
        }
        let fail = |e: &dyn std::fmt::Display| SceneError::at_field(&full, field, e.to_string());
        let asset = rig::Asset::load_mesh(&full, mesh_name).map_err(|e| fail(&e))?;
        for w in &asset.warnings {
            self.note(format!("warning: {}: {field}: {w}", full.display()));
        }
        let to_world = (crate::model::y_up_to_z_up(), DVec3::ZERO);
        let rest: Vec<DVec3> = asset.rest_positions().iter().map(|p| to_world.0 * *p).collect();
        let faces = asset.welded_faces.clone();
        let (material, islands, of_face, corner_uv) = match asset.corner_uv() {
            Ok(corner_uv) => {
                let corner_uv = corner_uv.to_vec();
                let islands = uv_islands::islands(&faces, &corner_uv);
                let (corners, report) =
                    uv_islands::length_true(&rest, &faces, &corner_uv, &islands).map_err(|e| fail(&e))?;
                let uv = first_corner_per_vertex(&faces, &corners, rest.len());
                for (i, r) in report.iter().enumerate() {
                    self.note(format!(
                        "{}: UV island {i}: {} faces, scale {:.4e} m per UV unit, principal-stretch ratio mean {:.3} \
                         max {:.3}, {} flipped",
                        full.display(),
                        r.faces,
                        r.scale,
                        r.stretch_mean,
                        r.stretch_max,
                        r.flipped
                    ));
                }
                (uv, report, islands.of_face, Some((corner_uv, corners)))
            }
            // Without UVs the body moves and carries anchors; a region or refined patch on it
            // asks for them (`corner_material`).
            Err(_) => (rest.iter().map(|p| p.truncate()).collect(), Vec::new(), Vec::new(), None),
        };
        let m = SurfaceMesh { rest, uv: material, faces };
        mesh::check_surface(&m).map_err(|e| fail(&e))?;
        let body = BodyAsset { asset: Arc::new(asset), path: full, to_world, islands, of_face, corner_uv };
        Ok((m, Arc::new(body)))
    }

    /// The selected faces of `base` refined and placed on its Loop limit surface, `distance` (m)
    /// along the limit normal; a kinematic layer refined from a moving surface is embedded in it.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn refined(
        &self,
        field: &str,
        base: &BuiltLayer,
        base_index: usize,
        keep: &[bool],
        distance: f64,
        refine: &RefineSpec,
        lambda: Option<f64>,
        len: f64,
        kind: LayerKind,
    ) -> Result<Refined, SceneError> {
        let LayerMesh::Surface(bm) = &base.mesh else {
            return Err(self.err(format!("{field}.layer"), format!("\"{}\" is not a surface", base.name)));
        };
        let region: Vec<u32> = (0..bm.faces.len() as u32).filter(|&f| keep[f as usize]).collect();
        if region.is_empty() {
            return Err(self.err(format!("{field}.region"), format!("selects no face of \"{}\"", base.name)));
        }
        let levels = match *refine {
            RefineSpec::Levels(k) => k,
            RefineSpec::Edge(e) => {
                if !(e > 0.0 && e.is_finite()) {
                    return Err(self.err(format!("{field}.refine.Edge"), format!("must be > 0 (got {e})")));
                }
                subdivision::levels_for(&bm.rest, &bm.faces, &region, e * len)
                    .map_err(|e| self.err(format!("{field}.refine"), e.to_string()))?
            }
            RefineSpec::Wavelength(n) => {
                if !(n >= 1.0 && n.is_finite()) {
                    return Err(self.err(format!("{field}.refine.Wavelength"), format!("must be at least 1 (got {n})")));
                }
                let Some(lambda) = lambda else {
                    return Err(self.err(
                        format!("{field}.refine"),
                        "Wavelength refines to the couplings' wavelength, and no coupling with a Constant or Eq31 \
                         wavelength names this layer or a layer offset from it: give Edge(length) or Levels(n)",
                    ));
                };
                subdivision::levels_for(&bm.rest, &bm.faces, &region, lambda / n)
                    .map_err(|e| self.err(format!("{field}.refine"), e.to_string()))?
            }
        };
        if levels > subdivision::MAX_LEVELS {
            return Err(self.err(
                format!("{field}.refine"),
                format!(
                    "needs {levels} subdivision levels, more than {}: a coarser target, or a finer body",
                    subdivision::MAX_LEVELS
                ),
            ));
        }
        // `check` estimates the refined size and its memory before anything is built.
        let (vertices, faces) = subdivision::estimate(region.len(), levels);
        self.with_memory_estimate(&format!("{field}.refine"), kind, vertices as u64, levels, faces as u64)?;
        let r = subdivision::refine(&bm.rest, &bm.faces, &region, levels)
            .map_err(|e| self.err(format!("{field}.refine"), e.to_string()))?;
        let mut rest = Vec::new();
        subdivision::apply_all(&r.stencils, &bm.rest, &mut rest);
        if distance != 0.0 {
            let normals = mesh::shading::vertex_normals(&rest, &r.faces);
            rest.iter_mut().zip(normals).for_each(|(p, n)| *p += distance * n);
        }
        let corners = self.region_material(field, base, &region)?;
        let uv = r
            .parent
            .iter()
            .map(|&(f, b)| {
                let c = corners(f);
                b.x * c[0] + b.y * c[1] + b.z * c[2]
            })
            .collect();
        let embedding = (kind == LayerKind::Kinematic).then(|| {
            // A base that is itself embedded passes its stencils on: the refined vertices read
            // the body's vertices directly.
            let (stencils, base) = match &base.embedding {
                Some(e) => (r.stencils.iter().map(|s| compose(s, &e.stencils)).collect(), e.base),
                None => (r.stencils.clone(), base_index),
            };
            BuiltEmbedding { base, stencils, distance }
        });
        Ok(Refined { mesh: SurfaceMesh { rest, uv, faces: r.faces }, embedding, parents: r.parent })
    }

    /// The material coordinates (m) of the corners of each face of `region` of `base`: its UV
    /// island's length-true UVs, or where the region spans islands or is distorted in its
    /// island, a conformal chart of the region scaled to its true area.
    fn region_material<'a>(
        &self,
        field: &str,
        base: &'a BuiltLayer,
        region: &[u32],
    ) -> Result<Box<dyn Fn(u32) -> [DVec2; 3] + 'a>, SceneError> {
        let LayerMesh::Surface(bm) = &base.mesh else { unreachable!("checked by the caller") };
        let Some(asset) = &base.asset else {
            // Generated bodies and OBJ files: their per-vertex material coordinates.
            return Ok(Box::new(move |f| bm.faces[f as usize].map(|v| bm.uv[v as usize])));
        };
        let Some((_, corners)) = &asset.corner_uv else {
            let message = format!(
                "the glTF mesh of \"{}\" has no UVs (TEXCOORD_0): a region's material space is its UVs",
                base.name
            );
            return Err(SceneError::at_field(&asset.path, format!("{field}.region"), message));
        };
        let island = asset.of_face[region[0] as usize];
        let one_island = region.iter().all(|&f| asset.of_face[f as usize] == island);
        let (stretch, area_ratio) = uv_islands::region_distortion(&bm.rest, &bm.faces, corners, region);
        if one_island && stretch <= CHART_STRETCH && (area_ratio.ln().abs() <= CHART_STRETCH.ln()) {
            self.note(format!(
                "{field}: material space from UV island {island} (stretch ratio {stretch:.3}, area ratio {area_ratio:.3})"
            ));
            return Ok(Box::new(move |f| corners[f as usize]));
        }
        let chart = uv_islands::conformal_chart(&bm.rest, &bm.faces, region)
            .map_err(|e| SceneError::at_field(&asset.path, format!("{field}.region"), e.to_string()))?;
        self.note(format!(
            "{field}: material space from a conformal chart of the region ({} of its UV island {island}: stretch \
             ratio {stretch:.3}, area ratio {area_ratio:.3})",
            if one_island { "distorted" } else { "it spans islands, beside" }
        ));
        Ok(Box::new(move |f| bm.faces[f as usize].map(|v| chart[v as usize])))
    }

    /// The `Rig` driver of a glTF body layer: names resolved, keyframes checked, in SI.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn rig_motion(
        &self,
        dat: &str,
        layer: &BuiltLayer,
        clip: Option<&str>,
        start: u32,
        speed: f64,
        joints: &[super::schema::JointKeysSpec],
        morphs: &[super::schema::MorphKeysSpec],
        skinning: SkinningSpec,
        interpolation: Interpolation,
        frame_time: f64,
        frames: u32,
        offset: DVec3,
    ) -> Result<RigMotion, SceneError> {
        let Some(body) = &layer.asset else {
            return Err(self.err(format!("{dat}.layer"), format!("\"{}\" is not a glTF body", layer.name)));
        };
        let a = &body.asset;
        // (a name the scene gives that the asset lacks: the scene's field, the asset named)
        let at_file = |f: String, e: &dyn std::fmt::Display| self.err(f, format!("{}: {e}", body.path.display()));
        let clip = match clip {
            None => None,
            Some(name) => {
                a.clip(name).map_err(|e| at_file(format!("{dat}.clip"), &e))?;
                a.clips.iter().position(|c| c.name == name)
            }
        };
        if !(speed > 0.0 && speed.is_finite()) {
            return Err(self.err(format!("{dat}.speed"), format!("must be > 0 (got {speed})")));
        }
        let keys = |f: String, k: &[(u32, f64)]| -> Result<Keyframes, SceneError> {
            if k.is_empty() {
                return Err(self.err(f, "needs at least one keyframe"));
            }
            if let Some(i) = k.windows(2).position(|w| w[1].0 <= w[0].0) {
                return Err(self.err(format!("{f}[{}]", i + 1), "keyframes out of frame order"));
            }
            if let Some(i) = k.iter().position(|v| !v.1.is_finite()) {
                return Err(self.err(format!("{f}[{i}]"), "must be finite"));
            }
            Ok(Keyframes(k.to_vec()))
        };
        let mut jk = Vec::new();
        for (i, j) in joints.iter().enumerate() {
            let f = format!("{dat}.joints[{i}]");
            let joint = a.joint(&j.joint).map_err(|e| at_file(format!("{f}.joint"), &e))?;
            let node = a.skin.as_ref().map_or(joint, |s| s.joints[joint]);
            let axis = DVec3::new(j.axis.0, j.axis.1, j.axis.2);
            if !(axis.is_finite() && axis.length() > 0.0) {
                return Err(self.err(format!("{f}.axis"), "must be a finite, non-zero direction"));
            }
            let k = keys(format!("{f}.keyframes"), &j.keyframes)?;
            jk.push((node, axis.normalize(), Keyframes(k.0.iter().map(|&(fr, d)| (fr, d.to_radians())).collect())));
        }
        let mut mk = Vec::new();
        for (i, m) in morphs.iter().enumerate() {
            let f = format!("{dat}.morphs[{i}]");
            let target = a.morph(&m.target).map_err(|e| at_file(format!("{f}.target"), &e))?;
            mk.push((target, keys(format!("{f}.keyframes"), &m.keyframes)?));
        }
        let skinning = match skinning {
            SkinningSpec::Linear => rig::Skinning::Linear,
            SkinningSpec::DualQuaternion => rig::Skinning::DualQuaternion,
        };
        let motion = RigMotion {
            asset: a.clone(),
            clip: clip.map(|c| (c, start, speed)),
            frame_time,
            joints: jk,
            morphs: mk,
            interpolation,
            skinning,
            to_world: (body.to_world.0, body.to_world.1 + offset),
        };
        if skinning == rig::Skinning::DualQuaternion {
            // Dual quaternions hold rigid joints only: check the rest pose and every clip key.
            // Dual quaternions hold rigid joints only: check every frame of the run (a clip's scale
            // may be between its keys).
            for f in 0..=frames {
                a.pose_positions(&motion.pose(f64::from(f)), skinning)
                    .map_err(|e| at_file(format!("{dat}.skinning"), &format!("at frame {f}: {e}")))?;
            }
        }
        Ok(motion)
    }
}

impl Builder {
    /// Per layer of a patch, the smallest wavelength (m) of the couplings on it or on a layer
    /// offset from it (transitively): what `refine: Wavelength(n)` divides. Constant and Eq31
    /// wavelengths only (a Film wavelength needs the film's material: give `Edge` there).
    pub(super) fn refine_wavelengths(&self, p: &super::schema::PatchSpec, len: f64, stress: f64) -> Vec<Option<f64>> {
        use super::schema::{MeshSpec, WavelengthSpec};
        let layer = |name: &str| p.layers.iter().find(|l| l.name == name);
        let young_thickness = |name: &str| {
            let m = layer(name)?.material.as_ref()?;
            let r = self.resolve_material("", m, len, stress).ok()?;
            Some((r.young * stress, r.thickness? * len))
        };
        let own: Vec<Option<f64>> = p
            .layers
            .iter()
            .map(|l| {
                p.couplings
                    .iter()
                    .filter(|c| c.upper == l.name || c.lower == l.name)
                    .filter_map(|c| match &c.wavelength {
                        WavelengthSpec::Constant(w) => Some(w * len),
                        WavelengthSpec::Eq31 { constant, lower } => {
                            let (eu, hu) = young_thickness(&c.upper)?;
                            let (el, hl) = match lower {
                                Some((e, h)) => (e * stress, h * len),
                                None => young_thickness(&c.lower)?,
                            };
                            Some(crate::coupling::kernels::wavelength_two_layer(*constant, hu, hl, eu, el))
                        }
                        WavelengthSpec::Film { .. } => None,
                    })
                    .filter(|w| *w > 0.0 && w.is_finite())
                    .reduce(f64::min)
            })
            .collect();
        // A layer's family: itself and every layer offset from a member (listed later).
        let mut out = own.clone();
        for (i, l) in p.layers.iter().enumerate().rev() {
            if let MeshSpec::Offset { layer: base, .. } = &l.mesh {
                if let Some(b) = p.layers.iter().position(|x| &x.name == base) {
                    if b < i {
                        out[b] = match (out[b], out[i]) {
                            (Some(a), Some(c)) => Some(a.min(c)),
                            (a, c) => a.or(c),
                        };
                    }
                }
            }
        }
        out
    }
}

/// The stencil over the inner stencils' vertices of a point that is `outer` of points given by
/// `inner` (a refinement of an embedded layer, read from the body directly).
fn compose(outer: &subdivision::Stencil, inner: &[subdivision::Stencil]) -> subdivision::Stencil {
    let mut terms: Vec<(u32, f64)> = outer
        .vertices
        .iter()
        .zip(&outer.weights)
        .flat_map(|(&v, &w)| {
            let s = &inner[v as usize];
            s.vertices.iter().zip(&s.weights).map(move |(&u, &x)| (u, w * x))
        })
        .collect();
    terms.sort_by_key(|t| t.0);
    let mut out = subdivision::Stencil { vertices: Vec::new(), weights: Vec::new() };
    for (v, w) in terms {
        if out.vertices.last() == Some(&v) {
            *out.weights.last_mut().unwrap() += w;
        } else {
            out.vertices.push(v);
            out.weights.push(w);
        }
    }
    out
}

/// Per vertex, the value of its first corner (in face order): a body's UVs per vertex, where a
/// seam vertex takes one side's (`uv_islands::per_vertex` instead refuses corners that differ).
pub(super) fn first_corner_per_vertex(faces: &[[u32; 3]], corners: &[[DVec2; 3]], n: usize) -> Vec<DVec2> {
    let mut out = vec![DVec2::ZERO; n];
    let mut seen = vec![false; n];
    for (f, c) in faces.iter().zip(corners) {
        for k in 0..3 {
            let v = f[k] as usize;
            if !seen[v] {
                (out[v], seen[v]) = (c[k], true);
            }
        }
    }
    out
}

/// A refined layer's asset UVs: each vertex's parent face's corner UVs interpolated (None where
/// the base has no asset UVs per corner).
pub(super) fn interpolated_asset_uv(base: &BuiltLayer, parents: &[(u32, DVec3)]) -> Option<Vec<DVec2>> {
    let corners = &base.asset.as_ref()?.corner_uv.as_ref()?.0;
    Some(
        parents
            .iter()
            .map(|&(f, b)| {
                let c = corners[f as usize];
                b.x * c[0] + b.y * c[1] + b.z * c[2]
            })
            .collect(),
    )
}
