//! Rigged meshes from glTF 2.0: reading a skinned, morphable mesh with its node hierarchy and
//! animation clips, and posing it by linear blend or dual quaternion skinning.
//!
//! Why this exists: the wrinkling simulation needs the skin surface driven by a skeleton the way an
//! artist rigged it, so the rig is read from the interchange format artists export (glTF, as written
//! by Blender) instead of being rebuilt by hand. Everything is f64 and SI (glTF is metres and seconds),
//! although the file stores f32: values are widened exactly and never re-rounded.
//!
//! The module is self-contained (glam, gltf, serde_json, thiserror and std only):
//! - [`Asset::load`] / [`Asset::load_mesh`] (in `gltf.rs`) read the file, validate it and weld the
//!   vertices that glTF splits at UV seams;
//! - [`Asset::pose_positions`] (in `skin.rs`) applies morph targets, then skinning;
//! - [`Clip::sample`] (in `animation.rs`) writes an animation clip's values at a time into a [`Pose`].

mod animation;
mod gltf;
mod skin;
#[cfg(test)]
mod tests;

use std::fmt;
use std::path::PathBuf;

use glam::{DMat3, DMat4, DQuat, DVec2, DVec3};

pub use animation::{hermite_basis, slerp, Channel, Clip, Interpolation, Property};
pub use skin::{rigid_deviation, DualQuat, Skinning, F32_BIND_SLACK, RIGID_TOLERANCE};

/// Everything that can go wrong reading or posing a rig. Messages name the file, accessor, mesh,
/// primitive, joint, target or clip involved, so a user can find the problem in the exporter.
#[derive(Debug, thiserror::Error)]
pub enum RigError {
    #[error("cannot read glTF file {path}: {source}")]
    Open {
        path: PathBuf,
        #[source]
        source: ::gltf::Error,
    },
    #[error("buffer {buffer} of {gltf} refers to file {file}, which does not exist or is not a file")]
    MissingBufferFile { gltf: PathBuf, buffer: usize, file: PathBuf },
    #[error("buffer {buffer} of {gltf} has an unusable uri {uri:?}: {reason}")]
    BadBufferUri { gltf: PathBuf, buffer: usize, uri: String, reason: String },
    #[error("cannot load the buffers of {path}: {source}")]
    Buffers {
        path: PathBuf,
        #[source]
        source: ::gltf::Error,
    },
    #[error("{path} has no mesh")]
    NoMesh { path: PathBuf },
    #[error("{path} has several meshes, name one of: {known}")]
    SeveralMeshes { path: PathBuf, known: Names },
    #[error("no mesh named {name:?}; known meshes: {known}")]
    UnknownMesh { name: String, known: Names },
    #[error("no joint named {name:?}; known joints: {known}")]
    UnknownJoint { name: String, known: Names },
    #[error("no morph target named {name:?}; known morph targets: {known}")]
    UnknownMorph { name: String, known: Names },
    #[error("no animation clip named {name:?}; known clips: {known}")]
    UnknownClip { name: String, known: Names },
    #[error("primitive {primitive} of mesh {mesh:?} has mode {mode}; only TRIANGLES is supported")]
    NotTriangles { mesh: String, primitive: usize, mode: String },
    #[error("primitive {primitive} of mesh {mesh:?} has no {semantic} attribute")]
    MissingAttribute { mesh: String, primitive: usize, semantic: String },
    #[error("{accessor}: {problem}")]
    BadAccessor { accessor: AccessorRef, problem: String },
    #[error("{accessor}: element {element} has a non-finite value ({value})")]
    NonFinite { accessor: AccessorRef, element: usize, value: f64 },
    #[error("{accessor}: vertex {vertex} uses joint {joint}, but the skin has only {joints} joints")]
    JointOutOfRange { accessor: AccessorRef, vertex: usize, joint: u32, joints: usize },
    #[error("{accessor}: the weights of vertex {vertex} sum to zero, so it follows no joint")]
    ZeroWeights { accessor: AccessorRef, vertex: usize },
    #[error("mesh {mesh:?}: {problem}")]
    BadMesh { mesh: String, problem: String },
    #[error(
        "morph target {target:?}: glTF vertices {first} and {other} weld to one vertex (same position and \
         joints) but have different deltas"
    )]
    WeldConflict { target: String, first: usize, other: usize },
    #[error("node hierarchy: {0}")]
    BadHierarchy(String),
    #[error("animation {clip:?}, channel {channel}: {problem}")]
    BadChannel { clip: String, channel: usize, problem: String },
    #[error("animation {clip:?} sampled at a non-finite time {time}")]
    BadTime { clip: String, time: f64 },
    #[error("the pose does not fit the asset: {0}")]
    PoseMismatch(String),
    #[error(
        "dual quaternion skinning needs rigid joint matrices, but joint {joint:?} has scale or shear {deviation:e} \
         (tolerance {tolerance:e})"
    )]
    NotRigid { joint: String, deviation: f64, tolerance: f64 },
    #[error("a rotation axis must be finite and non-zero, got {0}")]
    BadAxis(DVec3),
}

/// Which accessor a problem is in and what it is for, displayed as
/// `accessor 7 (WEIGHTS_0 of mesh "arm", primitive 0)`: the index finds it in the JSON, the role
/// says why it matters.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AccessorRef {
    pub index: usize,
    pub role: String,
}

impl fmt::Display for AccessorRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "accessor {} ({})", self.index, self.role)
    }
}

/// A list of known names for "unknown name" errors, displayed quoted and comma separated, so the
/// user sees the spelling the file uses.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Names(pub Vec<String>);

impl fmt::Display for Names {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.is_empty() {
            return write!(f, "(none)");
        }
        for (i, name) in self.0.iter().enumerate() {
            if i > 0 {
                write!(f, ", ")?;
            }
            write!(f, "{name:?}")?;
        }
        Ok(())
    }
}

impl Names {
    fn of<'a>(names: impl IntoIterator<Item = &'a str>) -> Names {
        Names(names.into_iter().map(str::to_owned).collect())
    }
}

/// A node's local transform as glTF keeps it: the matrix is `T * R * S` (scale first).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trs {
    pub translation: DVec3,
    /// Unit quaternion; [`Trs::matrix`] normalises it anyway, so f32-rounded input stays a rotation.
    pub rotation: DQuat,
    pub scale: DVec3,
}

impl Default for Trs {
    fn default() -> Self {
        Trs::IDENTITY
    }
}

impl Trs {
    pub const IDENTITY: Trs = Trs { translation: DVec3::ZERO, rotation: DQuat::IDENTITY, scale: DVec3::ONE };

    pub fn new(translation: DVec3, rotation: DQuat, scale: DVec3) -> Trs {
        Trs { translation, rotation, scale }
    }

    /// `T * R * S`. The rotation is normalised here so that a quaternion rounded to f32 (or blended
    /// by a caller) does not smuggle a scale of 1 ± 1e-7 into the joint matrices, which would break
    /// the rigidity test of dual quaternion skinning.
    pub fn matrix(&self) -> DMat4 {
        DMat4::from_scale_rotation_translation(self.scale, self.rotation.normalize(), self.translation)
    }

    /// Splits an affine matrix into `T * R * S`. A negative determinant is carried by the x scale.
    /// Returns the decomposition and the largest absolute difference between its matrix and `m`,
    /// which is non-zero when `m` has shear or a projective row (glTF forbids both for nodes).
    pub fn from_matrix(m: &DMat4) -> (Trs, f64) {
        let a = DMat3::from_mat4(*m);
        let mut scale = DVec3::new(a.x_axis.length(), a.y_axis.length(), a.z_axis.length());
        if a.determinant() < 0.0 {
            scale.x = -scale.x;
        }
        let unscale = |v: DVec3, s: f64| if s != 0.0 { v / s } else { v };
        let r = DMat3::from_cols(unscale(a.x_axis, scale.x), unscale(a.y_axis, scale.y), unscale(a.z_axis, scale.z));
        let q = DQuat::from_mat3(&r);
        let rotation = unit_quat(q).unwrap_or(DQuat::IDENTITY);
        let trs = Trs { translation: m.w_axis.truncate(), rotation, scale };
        let back = trs.matrix();
        let residual = (0..4)
            .flat_map(|c| (0..4).map(move |r| (c, r)))
            .map(|(c, r)| (back.col(c)[r] - m.col(c)[r]).abs())
            .fold(0.0, f64::max);
        (trs, residual)
    }
}

/// `q` scaled to unit length, or `None` for a zero or non-finite quaternion (glam's `normalize`
/// would return NaN there, which must not reach a pose).
pub fn unit_quat(q: DQuat) -> Option<DQuat> {
    let len = q.length();
    (len.is_finite() && len > 0.0).then(|| q * (1.0 / len))
}

/// A rotation by `degrees` about `axis` (any length), for a caller's own keyframes. Right-handed:
/// positive angles turn counter-clockwise looking down the axis towards the origin.
pub fn rotation_about(axis: DVec3, degrees: f64) -> Result<DQuat, RigError> {
    let unit = axis.try_normalize().filter(|_| axis.is_finite()).ok_or(RigError::BadAxis(axis))?;
    Ok(DQuat::from_axis_angle(unit, degrees.to_radians()))
}

/// One node of the glTF scene graph. Parents are derived from the children lists.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    /// The node's name, or `node_<index>` when the file gives none.
    pub name: String,
    pub parent: Option<usize>,
    pub children: Vec<usize>,
    /// The local transform at rest (a node matrix is decomposed).
    pub rest: Trs,
    /// The node's own morph weights, which override the mesh's default weights.
    pub weights: Option<Vec<f64>>,
}

/// The skin of the node carrying the mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct Skin {
    /// Node index of each joint; `JOINTS_n` values index this list.
    pub joints: Vec<usize>,
    /// The joint nodes' names (the same as `nodes[joints[j]].name`).
    pub joint_names: Vec<String>,
    /// `B_j^-1`: maps mesh space at bind time into joint j's space. Identity when absent (per spec).
    pub inverse_bind: Vec<DMat4>,
    /// Whether the inverse bind matrices came from the file (f32-rounded) rather than identity;
    /// dual quaternion skinning's rigidity tolerance allows for that rounding.
    pub inverse_bind_from_file: bool,
}

/// Joint influences per welded vertex in compressed rows: vertex v's joints are
/// `joint[start[v]..start[v+1]]` with the matching `weight`s. Zero weights are dropped, a joint
/// listed twice is merged, joints are sorted, and weights sum to one.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Influences {
    pub start: Vec<u32>,
    pub joint: Vec<u32>,
    pub weight: Vec<f64>,
}

impl Influences {
    /// The joints and weights of vertex `v`; empty for an unskinned mesh.
    pub fn of(&self, v: usize) -> (&[u32], &[f64]) {
        match (self.start.get(v), self.start.get(v + 1)) {
            (Some(&a), Some(&b)) => (&self.joint[a as usize..b as usize], &self.weight[a as usize..b as usize]),
            _ => (&[], &[]),
        }
    }
}

/// A morph target's name and POSITION deltas (m) per welded vertex.
#[derive(Clone, Debug, PartialEq)]
pub struct MorphTarget {
    pub name: String,
    pub deltas: Vec<DVec3>,
}

/// A mesh read from a glTF file with everything needed to pose it.
///
/// Two vertex numberings exist: glTF vertices (primitives concatenated, split at UV seams) and
/// welded vertices (one per distinct rest position and joint influences), which the simulation uses.
#[derive(Clone, Debug)]
pub struct Asset {
    pub path: PathBuf,
    /// Index of the mesh in the file and its name (`mesh_<index>` when unnamed).
    pub mesh: usize,
    pub mesh_name: String,
    /// The first node carrying the mesh, if any node does.
    pub mesh_node: Option<usize>,
    pub nodes: Vec<Node>,
    pub skin: Option<Skin>,
    /// Rest positions (m) per glTF vertex.
    pub positions: Vec<DVec3>,
    /// TEXCOORD_0 per glTF vertex, when every primitive has it; see [`Asset::uv()`].
    pub uv: Option<Vec<DVec2>>,
    /// Triangles in glTF vertex indices.
    pub faces: Vec<[u32; 3]>,
    /// Welded vertex of each glTF vertex.
    pub weld: Vec<u32>,
    /// Rest positions (m) per welded vertex.
    pub rest: Vec<DVec3>,
    /// Triangles in welded vertex indices, in the order of `faces`.
    pub welded_faces: Vec<[u32; 3]>,
    /// TEXCOORD_0 at each corner of each face, which keeps both sides of a seam.
    pub corner_uv: Option<Vec<[DVec2; 3]>>,
    /// Joint influences per welded vertex (empty rows without a skin).
    pub influences: Influences,
    pub morphs: Vec<MorphTarget>,
    /// `mesh.weights`, zeros when absent.
    pub default_morph_weights: Vec<f64>,
    /// The file's animations; [`Asset::clips`] lists their names, [`Asset::clip`] finds one by name.
    pub clips: Vec<Clip>,
    /// Things the file did that the spec allows but a user may want to know (e.g. normalised weights).
    pub warnings: Vec<String>,
    /// The first primitive lacking TEXCOORD_0, reported by [`Asset::uv()`].
    uv_missing: Option<usize>,
    /// Node indices with every parent before its children, for one-pass global matrices.
    order: Vec<usize>,
}

/// The state a mesh is posed in: a local transform per node and a weight per morph target.
#[derive(Clone, Debug, PartialEq)]
pub struct Pose {
    pub locals: Vec<Trs>,
    pub morph_weights: Vec<f64>,
}

impl Asset {
    /// The rest pose: every node's own transform, and the node's morph weights if it has them,
    /// else the mesh's (as the spec orders).
    pub fn rest_pose(&self) -> Pose {
        let node_weights = self.mesh_node.and_then(|n| self.nodes[n].weights.clone());
        let morph_weights =
            node_weights.filter(|w| w.len() == self.morphs.len()).unwrap_or_else(|| self.default_morph_weights.clone());
        Pose { locals: self.nodes.iter().map(|n| n.rest).collect(), morph_weights }
    }

    /// Index into the skin's joints of the first joint named `name`.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.skin.as_ref()?.joint_names.iter().position(|n| n == name)
    }

    /// As [`Asset::joint_index`], with an error listing the known joints.
    pub fn joint(&self, name: &str) -> Result<usize, RigError> {
        self.joint_index(name).ok_or_else(|| RigError::UnknownJoint {
            name: name.to_owned(),
            known: Names::of(self.skin.iter().flat_map(|s| s.joint_names.iter().map(String::as_str))),
        })
    }

    /// Node index of the first node named `name` (joints are nodes; so are non-joint parents).
    pub fn node_index(&self, name: &str) -> Option<usize> {
        self.nodes.iter().position(|n| n.name == name)
    }

    /// Index of the morph target named `name`.
    pub fn morph_index(&self, name: &str) -> Option<usize> {
        self.morphs.iter().position(|m| m.name == name)
    }

    /// As [`Asset::morph_index`], with an error listing the known targets.
    pub fn morph(&self, name: &str) -> Result<usize, RigError> {
        self.morph_index(name).ok_or_else(|| RigError::UnknownMorph {
            name: name.to_owned(),
            known: Names::of(self.morphs.iter().map(|m| m.name.as_str())),
        })
    }

    /// Names of the animation clips (`animation_<index>` when unnamed), in file order.
    pub fn clips(&self) -> Vec<&str> {
        self.clips.iter().map(|c| c.name.as_str()).collect()
    }

    /// The clip named `name`, with an error listing the known clips.
    pub fn clip(&self, name: &str) -> Result<&Clip, RigError> {
        self.clips
            .iter()
            .find(|c| c.name == name)
            .ok_or_else(|| RigError::UnknownClip { name: name.to_owned(), known: Names::of(self.clips()) })
    }

    /// TEXCOORD_0 per glTF vertex. Reading does not require UVs, because only some callers need
    /// them; those get an error naming the primitive without them.
    pub fn uv(&self) -> Result<&[DVec2], RigError> {
        self.uv.as_deref().ok_or_else(|| self.missing_uv())
    }

    /// TEXCOORD_0 at each corner of each welded face; see [`Asset::uv()`].
    pub fn corner_uv(&self) -> Result<&[[DVec2; 3]], RigError> {
        self.corner_uv.as_deref().ok_or_else(|| self.missing_uv())
    }

    fn missing_uv(&self) -> RigError {
        RigError::MissingAttribute {
            mesh: self.mesh_name.clone(),
            primitive: self.uv_missing.unwrap_or(0),
            semantic: "TEXCOORD_0".into(),
        }
    }

    /// Rest positions per welded vertex (m), before morphs and skinning.
    pub fn rest_positions(&self) -> &[DVec3] {
        &self.rest
    }

    /// Node indices, parents before children.
    pub fn node_order(&self) -> &[usize] {
        &self.order
    }
}
