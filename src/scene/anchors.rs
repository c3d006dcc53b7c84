//! Building the KCK18 parts of a scene: body animations (articulated poses, OBJ sequences) and
//! the anchors' initial binding to the body.

use glam::DVec3;

use super::built::{BuiltAnchors, BuiltLayer, LayerMesh};
use super::context::{not_a_file, Builder, PatchContext};
use super::schema::{AnchorSpec, PoseSpec};
use super::SceneError;
use crate::coupling::walk::{BodySurface, Projector, SurfacePoint};
use crate::mesh::{self, bodies, SurfaceMesh};
use crate::model::{Interpolation, Keyframes, LayerKind};

/// The most memory an articulation's precomputed poses may take (bytes).
const MAX_PRECOMPUTED_BYTES: f64 = 4e9;

impl Builder {
    /// Displacements of the posed layer for frames 0 to `frames` (an exact pose per weight).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn articulate(
        &self,
        at: &str,
        pose: &PoseSpec,
        weights: &[(u32, f64)],
        interpolation: Interpolation,
        layer: &BuiltLayer,
        len: f64,
        frames: u32,
    ) -> Result<Vec<Vec<DVec3>>, SceneError> {
        if weights.is_empty() {
            return Err(self.err(format!("{at}.weights"), "needs at least one keyframe"));
        }
        if let Some(i) = (1..weights.len()).find(|&i| weights[i].0 <= weights[i - 1].0) {
            return Err(self.err(format!("{at}.weights[{i}]"), "keyframes out of order"));
        }
        if let Some(i) = weights.iter().position(|w| !w.1.is_finite()) {
            return Err(self.err(format!("{at}.weights[{i}]"), "must be finite"));
        }
        if let PoseSpec::Elbow { bend_radius, .. } = pose {
            if !(*bend_radius > 0.0 && bend_radius.is_finite()) {
                return Err(self.err(format!("{at}.pose.bend_radius"), format!("must be > 0 (got {bend_radius})")));
            }
        }
        let (PoseSpec::Elbow { angle, .. } | PoseSpec::Fold { angle }) = pose;
        if !(-360.0..=360.0).contains(angle) {
            return Err(self.err(format!("{at}.pose.angle"), format!("must be in [-360, 360] degrees (got {angle:e})")));
        }
        let rest = layer.mesh.rest();
        // The poses are precomputed for every frame.
        let bytes = (frames as f64 + 1.0) * rest.len() as f64 * std::mem::size_of::<DVec3>() as f64;
        if bytes > MAX_PRECOMPUTED_BYTES {
            let message = format!(
                "{} frames x {} vertices of precomputed poses need {:.1} GB, more than {:.0} GB: fewer frames",
                frames,
                rest.len(),
                bytes / 1e9,
                MAX_PRECOMPUTED_BYTES / 1e9
            );
            return Err(self.err(at, message));
        }
        let (lo, hi) = mesh::bounds(rest);
        let centre = 0.5 * (lo + hi);
        let keys = Keyframes(weights.to_vec());
        Ok((0..=frames)
            .map(|f| {
                let w = keys.at(f as f64, interpolation);
                rest.iter()
                    .map(|&p| {
                        let posed = match *pose {
                            PoseSpec::Elbow { angle, bend_radius } => {
                                bodies::elbow(p, centre, w * bodies::radians(angle), bend_radius * len)
                            }
                            PoseSpec::Fold { angle } => bodies::fold(p, centre, w * bodies::radians(angle)),
                        };
                        posed - p
                    })
                    .collect()
            })
            .collect())
    }

    /// Displacements from rest of every file of an OBJ sequence (the vertex count checked).
    pub(super) fn obj_sequence(
        &self,
        at: &str,
        files: &[String],
        layer: &BuiltLayer,
        len: f64,
        offset: DVec3,
    ) -> Result<Vec<Vec<DVec3>>, SceneError> {
        if files.is_empty() {
            return Err(self.err(format!("{at}.files"), "needs at least one file"));
        }
        let rest = layer.mesh.rest();
        files
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let full = self.dir.join(f);
                let field = format!("{at}.files[{i}]");
                if let Some(problem) = not_a_file(&full) {
                    return Err(SceneError::at_field(&full, &field, format!("file {problem}")));
                }
                let m = mesh::obj::load(&full, len).map_err(|e| SceneError::at_field(&full, &field, e.to_string()))?;
                if m.rest.len() != rest.len() {
                    return Err(SceneError::at_field(
                        &full,
                        &field,
                        format!(
                            "{} vertices, but layer \"{}\" has {}: a sequence keeps the mesh's vertices",
                            m.rest.len(),
                            layer.name,
                            rest.len()
                        ),
                    ));
                }
                Ok(m.rest.iter().zip(rest).map(|(p, r)| *p + offset - *r).collect())
            })
            .collect()
    }

    /// Validates the anchors and binds each skin vertex and face barycentre to its closest
    /// body point (KCK18 section 3).
    pub(super) fn anchors(&self, at: &str, a: &AnchorSpec, cx: &PatchContext) -> Result<BuiltAnchors, SceneError> {
        let PatchContext { layers, len, stress, .. } = *cx;
        let find = |field: &str, name: &str| cx.find(self, format!("{at}.{field}"), name);
        let (skin, body) = (find("skin", &a.skin)?, find("body", &a.body)?);
        let (LayerMesh::Surface(skin_mesh), LayerKind::Shell) = (&layers[skin].mesh, layers[skin].kind) else {
            return Err(self.err(format!("{at}.skin"), format!("\"{}\" is not a shell layer", a.skin)));
        };
        let (LayerMesh::Surface(body_mesh), LayerKind::Kinematic) = (&layers[body].mesh, layers[body].kind) else {
            return Err(self.err(format!("{at}.body"), format!("\"{}\" is not a kinematic surface layer", a.body)));
        };
        if !(a.stiffness > 0.0 && a.stiffness.is_finite()) {
            return Err(self.err(format!("{at}.stiffness"), format!("must be > 0 (got {})", a.stiffness)));
        }
        if !(a.slide > 0.0 && a.slide <= 1.0) {
            return Err(self.err(format!("{at}.slide"), format!("must be in (0, 1] (got {})", a.slide)));
        }
        let (lo, hi) = mesh::bounds(&body_mesh.rest);
        let limit = match a.max_distance {
            Some(d) if d > 0.0 && d.is_finite() => d * len,
            Some(d) => return Err(self.err(format!("{at}.max_distance"), format!("must be > 0 (got {d})"))),
            None => 0.05 * (hi - lo).length(),
        };
        let (surface, issues) = BodySurface::new(body_mesh.faces.clone(), &body_mesh.rest);
        if !issues.degenerate.is_empty() || !issues.non_manifold.is_empty() {
            // Meshes are checked at load, so only procedural slivers get here: documented
            // fallback, they are walked around as boundaries.
            tracing::warn!(?issues, "body \"{}\": faces or edges the walk treats as boundaries", a.body);
        }
        let projector = Projector::new(&surface, &body_mesh.rest);
        let mut bind_distance = 0.0f64;
        let mut bind = |p: DVec3, what: &dyn Fn() -> String| -> Result<SurfacePoint, SceneError> {
            let q = projector.project(&surface, &body_mesh.rest, p).ok_or_else(|| {
                self.err(format!("{at}.body"), format!("\"{}\" has no usable face to bind to", a.body))
            })?;
            let d = (surface.position(&body_mesh.rest, q) - p).length();
            if d > limit {
                return Err(self.err(
                    format!("{at}.max_distance"),
                    format!(
                        "{} starts {:.4} length units from the body, beyond the limit {:.4}",
                        what(),
                        d / len,
                        limit / len
                    ),
                ));
            }
            bind_distance = bind_distance.max(d);
            Ok(q)
        };
        let k_area = a.stiffness * stress / len;
        let uv = skin_mesh.uv.clone();
        let factor = self.stiffness_factors(at, a, &uv)?;
        let face_uv = |f: &[u32; 3]| f.iter().map(|&v| uv[v as usize]).sum::<glam::DVec2>() / 3.0;
        let (vertex_share, face_share) = if a.faces { (1.0 / 6.0, 0.5) } else { (1.0 / 3.0, 0.0) };
        let areas = face_areas(skin_mesh);
        let mut vertex_k = vec![0.0; skin_mesh.rest.len()];
        for (f, area) in skin_mesh.faces.iter().zip(&areas) {
            f.iter().for_each(|&v| vertex_k[v as usize] += vertex_share * k_area * area);
        }
        let mut vertex = Vec::with_capacity(skin_mesh.rest.len());
        for (v, p) in skin_mesh.rest.iter().enumerate() {
            let k = vertex_k[v] * factor(uv[v]);
            vertex.push((v as u32, bind(*p, &|| format!("skin vertex {v}"))?, k));
        }
        let mut face = Vec::new();
        if a.faces {
            for (i, f) in skin_mesh.faces.iter().enumerate() {
                let centre = f.iter().map(|&v| skin_mesh.rest[v as usize]).sum::<DVec3>() / 3.0;
                let k = face_share * k_area * areas[i] * factor(face_uv(f));
                face.push((i as u32, bind(centre, &|| format!("the centre of skin face {i}"))?, k));
            }
        }
        tracing::info!(
            "anchors: {} at vertices, {} at faces; farthest skin point from the body at load {:.3e} m",
            vertex.len(),
            face.len(),
            bind_distance
        );
        Ok(BuiltAnchors { skin, body, method: a.method, slide: a.slide, surface, vertex, face, bind_distance })
    }
}

impl Builder {
    /// The stiffness factor over the skin's material space: 1, or the painted red channel.
    #[allow(clippy::type_complexity)]
    fn stiffness_factors(
        &self,
        at: &str,
        a: &AnchorSpec,
        uv: &[glam::DVec2],
    ) -> Result<Box<dyn Fn(glam::DVec2) -> f64>, SceneError> {
        let Some(m) = &a.stiffness_map else { return Ok(Box::new(|_| 1.0)) };
        let (lo, hi) = mesh::bounds(uv);
        let map = self.rgb_map(&format!("{at}.stiffness_map.map"), &m.map, lo, hi)?;
        let (k0, k1) = m.range;
        let reds = map.values.iter().map(|v| v[0] as f64);
        let (rmin, rmax) = reds.fold((f64::INFINITY, f64::NEG_INFINITY), |(x, y), r| (x.min(r), y.max(r)));
        for r in [rmin, rmax] {
            let f = k0 + (k1 - k0) * r;
            if !(f > 0.0 && f.is_finite()) {
                return Err(self.err(
                    format!("{at}.stiffness_map.range"),
                    format!("maps red {r:.3} (present in the map) to a stiffness factor of {f}: must be > 0"),
                ));
            }
        }
        Ok(Box::new(move |p| k0 + (k1 - k0) * map.sample(p).x))
    }
}

fn face_areas(m: &SurfaceMesh) -> Vec<f64> {
    m.faces.iter().map(|f| mesh::shading::triangle_area(&m.rest, f)).collect()
}
