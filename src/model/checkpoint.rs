//! A checkpoint's data (issue 66): the state a frame leaves behind, as `systems::checkpoint`
//! captures it from a World and restores it into a fresh one. Entities are saved by their bits
//! (`Entity::to_bits`) in the saved run; the file is CBOR, so every f64 is bit-exact.

use glam::{DMat2, DMat3, DVec2, DVec3};
use serde::{Deserialize, Serialize};

use crate::coupling::kernels::Adjusted;
use crate::solve::Carry;

use super::RemeshReport;

/// The state after `frame`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint {
    pub frame: u32,
    pub time: f64,
    /// Every layer (patches' and bodies'), in entity order.
    pub layers: Vec<LayerState>,
    /// Every patch, in entity order.
    pub patches: Vec<PatchState>,
    /// `log::LogState`: frame 0 written, and the layers' colour scales.
    pub log: (bool, Vec<(u64, f64)>),
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LayerState {
    pub id: u64,
    pub name: String,
    pub epoch: u64,
    pub remesh: Option<RemeshReport>,
    pub vertices: Vec<VertexState>,
    pub faces: Vec<FaceState>,
    pub edges: Vec<EdgeState>,
    pub tets: Vec<TetState>,
    pub springs: Vec<SpringState>,
    pub anchors: Vec<AnchorSaved>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VertexState {
    pub id: u64,
    pub uv: DVec2,
    pub rest: DVec3,
    pub x: DVec3,
    pub v: DVec3,
    pub mass: f64,
    pub fixed: [bool; 3],
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FaceState {
    pub id: u64,
    pub verts: [u64; 3],
    /// `MembraneRest`'s b and volume.
    pub rest: Option<(DMat2, f64)>,
    pub prestrain: Option<DMat2>,
    pub scale: Option<f64>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EdgeState {
    pub id: u64,
    pub verts: [u64; 2],
    pub opposite: Option<[u64; 2]>,
    pub hinge: Option<HingeState>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HingeState {
    pub opposite: [u64; 2],
    pub weight: f64,
    pub rest_phi: f64,
    pub image: Option<[u64; 2]>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TetState {
    pub rest: (DMat3, f64),
    pub prestrain: Option<DMat3>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum SpringState {
    Point { id: u64, a: u64, b: u64, stiffness: f64 },
    Face { id: u64, a: u64, b: [u64; 3], w: [f64; 3], stiffness: f64 },
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AnchorSaved {
    /// The skin point: one vertex, or a face's three.
    pub skin: Vec<u64>,
    pub face: u32,
    pub st: DVec2,
    pub stiffness: f64,
    /// `AnchorState`: position, step, walked, jump.
    pub state: (DVec3, f64, f64, f64),
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PatchState {
    pub id: u64,
    pub name: String,
    pub carry: Carry,
    pub kernels: Vec<KernelState>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct KernelState {
    pub samples: [Vec<(u64, f64)>; 2],
    pub chart: [Vec<DVec2>; 2],
    pub weights: [Vec<(u64, f64)>; 2],
    pub adjusted: [Option<Adjusted>; 2],
}

/// Why a checkpoint does not fit the World it is restored into.
#[derive(Debug, thiserror::Error)]
pub enum RestoreError {
    #[error("the checkpoint has {saved} {what}, the scene {scene}")]
    Count { what: &'static str, saved: usize, scene: usize },
    #[error("the checkpoint's {what} \"{saved}\" is \"{scene}\" in the scene")]
    Name { what: &'static str, saved: String, scene: String },
    #[error("the checkpoint names an entity the scene does not make ({0:#x})")]
    Entity(u64),
    #[error("layer \"{0}\": its {1} could not be put back in the saved order")]
    Order(String, &'static str),
}

impl Checkpoint {
    /// The checkpoint as CBOR (every f64 bit-exact).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        ciborium::into_writer(self, &mut out).expect("a checkpoint encodes");
        out
    }

    pub fn from_bytes(bytes: &[u8]) -> Result<Checkpoint, String> {
        ciborium::from_reader(bytes).map_err(|e| e.to_string())
    }
}
