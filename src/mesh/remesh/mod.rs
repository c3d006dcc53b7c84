//! Adaptive anisotropic remeshing of a shell layer in its material space (REMESH.md; LK14 on
//! ARCSim, Narain, Samii, O'Brien 2012): split edges longer than the sizing field allows, flip
//! to the metric Delaunay triangulation, collapse edges the field no longer needs.
//!
//! Plain arrays in, plain arrays out: the Remesh system copies a layer out of the ECS, calls
//! `remesh`, and spawns or despawns entities from the result's `origin` map.

pub mod identity;
mod ops;
pub mod sizing;

use glam::{DMat2, DVec2, DVec3};

pub use ops::RemeshStats;

/// Remeshing thresholds of one layer, SI units (lengths in metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RemeshParams {
    /// Smallest and largest edge length the field may ask for.
    pub size_min: f64,
    pub size_max: f64,
    /// Smallest ratio of a metric's two sizes (0 < aspect_min <= 1).
    pub aspect_min: f64,
    /// Largest angle (radians) the normal may turn across an edge.
    pub refine_angle: f64,
    /// Largest buckle amplitude (m) a compressed edge may leave unresolved.
    pub refine_compression: f64,
    /// Velocity-gradient term (m/s), dynamic scenes only.
    pub refine_velocity: Option<f64>,
    /// Split midpoints placed on the curved surface through the ends' normals (else on the
    /// straight edge; off only to measure the pop it avoids).
    pub curved_splits: bool,
}

/// The longest edge a kernel support allows, relative to the kernel radius.
pub(crate) const KERNEL_EDGES: f64 = 0.5;

impl RemeshParams {
    /// These thresholds with `size_max` capped by the radii of the kernels on the layer. A
    /// kernel's support must keep enough vertices for its weights to be adjusted (at least
    /// three, not collinear; LK14 4.2.1): edges at most `KERNEL_EDGES` of the smallest radius.
    /// (Measured without the cap: a 1.3 mm kernel radius under a 2 mm size_max left supports of
    /// one or two vertices, and the frame did not converge.)
    pub fn capped_by_kernels(mut self, radii: impl IntoIterator<Item = f64>) -> Self {
        self.size_max =
            radii.into_iter().fold(self.size_max, |m, r| m.min(KERNEL_EDGES * r)).max(self.size_min * 1.0001);
        self
    }

    /// The first violated condition, as (field, message).
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        let positive = |name: &'static str, v: f64| {
            if v > 0.0 && v.is_finite() {
                Ok(())
            } else {
                Err((name, format!("must be a positive number (got {v})")))
            }
        };
        positive("size_min", self.size_min)?;
        positive("size_max", self.size_max)?;
        if self.size_min >= self.size_max {
            return Err(("size_min", format!("must be below size_max ({} >= {})", self.size_min, self.size_max)));
        }
        if !(self.aspect_min > 0.0 && self.aspect_min <= 1.0) {
            return Err(("aspect_min", format!("must be in (0, 1] (got {})", self.aspect_min)));
        }
        positive("refine_angle", self.refine_angle)?;
        positive("refine_compression", self.refine_compression)?;
        if let Some(v) = self.refine_velocity {
            positive("refine_velocity", v)?;
        }
        Ok(())
    }
}

/// One vertex of a mesh being remeshed, with the state that moves with it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RemeshVertex {
    /// Material-space position.
    pub uv: DVec2,
    /// Current position, velocity and rest position.
    pub x: DVec3,
    pub v: DVec3,
    pub rest: DVec3,
    /// Prescribed coordinates; a vertex with any is kept (a handle).
    pub fixed: [bool; 3],
    /// Index in the input mesh, None for a vertex a split created.
    pub origin: Option<u32>,
}

/// A remeshed surface: vertices (inputs that survived keep their `origin`), faces, and what
/// the operations did.
#[derive(Clone, Debug, Default)]
pub struct Remeshed {
    pub vertices: Vec<RemeshVertex>,
    pub faces: Vec<[u32; 3]>,
    /// The sizing metric of each output vertex.
    pub sizing: Vec<DMat2>,
    pub stats: RemeshStats,
    /// The input was at rest and so is the output (`imperfection::remesh_under`): nothing to
    /// settle.
    pub at_rest: bool,
}

impl Remeshed {
    /// Whether it changed the mesh at all.
    pub fn changed(&self) -> bool {
        let s = &self.stats;
        s.splits + s.collapses + s.flips > 0
    }

    /// Whether it split or collapsed fewer than `min_change` of `faces_before` (refine mostly,
    /// issue 26 item 3): such a remesh is not worth the resampling, the new symbolic
    /// factorization and the solve it disturbs.
    pub fn is_small(&self, min_change: f64, faces_before: usize) -> bool {
        f64::from(self.stats.splits + self.stats.collapses) < min_change * faces_before as f64
    }
}

/// Remeshes a checked, consistently oriented surface (REMESH.md "Operations, in order").
/// `vertices[i].origin` is ignored on input and set to Some(i). Deterministic: the same input
/// gives the same output.
pub fn remesh(vertices: &[RemeshVertex], faces: &[[u32; 3]], p: &RemeshParams) -> Remeshed {
    remesh_sized(vertices, faces, &[], &FaceRules::default(), p)
}

/// What the operations may do to each input face (one flag per face, or none).
#[derive(Clone, Debug, Default)]
pub struct FaceRules {
    /// Faces no operation may change (refined before they wrinkle: `sizing::held_faces`).
    pub held: Vec<bool>,
    /// Faces near contact, whose shape is kept: split on the straight edge only, never flipped
    /// or collapsed, so that the remesh moves no surface into what it touches.
    pub kept: Vec<bool>,
}

/// `remesh` with one more sizing term per input face (`sizing::wavelength_term`), or none, and
/// what the operations may do to each input face.
pub(crate) fn remesh_sized(
    vertices: &[RemeshVertex],
    faces: &[[u32; 3]],
    extra: &[DMat2],
    rules: &FaceRules,
    p: &RemeshParams,
) -> Remeshed {
    let uv: Vec<DVec2> = vertices.iter().map(|v| v.uv).collect();
    let x: Vec<DVec3> = vertices.iter().map(|v| v.x).collect();
    let vel: Vec<DVec3> = vertices.iter().map(|v| v.v).collect();
    let sizing = sizing::vertex_sizing(&uv, &x, p.refine_velocity.map(|_| vel.as_slice()), faces, extra, p);
    let mut mesh = ops::WorkMesh::new(vertices, faces, sizing, &rules.held, &rules.kept, p);
    mesh.flip_all();
    mesh.refine();
    mesh.coarsen();
    mesh.finish()
}

#[cfg(test)]
mod tests;
