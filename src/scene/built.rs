//! A scene after validation: meshes built, layer names resolved to indices, every value in SI
//! units. What `load` returns and `spawn` reads.

use std::path::PathBuf;

use glam::{DVec2, DVec3};

use super::schema::{Perturbation, Scene};
use crate::coupling::walk::{BodySurface, SurfacePoint};
use crate::mesh::select::SeamHinge;
use crate::mesh::{SurfaceMesh, TetMesh};
use crate::model::{AnchorMethod, LayerKind, WeightMap};

/// A validated scene with its meshes built, in SI units.
#[derive(Clone, Debug)]
pub struct BuiltScene {
    pub path: PathBuf,
    pub scene: Scene,
    /// Shared kinematic bodies: one layer each, no solver.
    pub bodies: Vec<BuiltPatch>,
    pub patches: Vec<BuiltPatch>,
    /// What the user should know that is not an error (issue 62: refined sizes and their memory,
    /// UV islands' distortion, glTF weights normalised): `check` prints it, `run` too.
    pub notes: Vec<String>,
    /// The memory a run needs (bytes), estimated from the layers' vertex counts (`meshes.rs`,
    /// `bytes_per_vertex`): `check` prints it.
    pub memory: f64,
}

#[derive(Clone, Debug)]
pub struct BuiltPatch {
    pub name: String,
    /// The shared body the patch sits on (an index into `BuiltScene::bodies`): a copy of its
    /// layer is `layers[0]` for building; spawn uses the body's own entity.
    pub body: Option<usize>,
    pub solver: crate::solve::SolverSettings,
    /// The imperfection spawn applies to free shell vertices (SI lengths).
    pub perturbation: Option<Perturbation>,
    pub layers: Vec<BuiltLayer>,
    pub drivers: Vec<BuiltDriver>,
    pub couplings: Vec<BuiltCoupling>,
    pub anchors: Option<BuiltAnchors>,
    pub contact: Option<crate::model::Contact>,
    /// What else its skin touches (`contact.with`).
    pub contact_with: Vec<ContactWith>,
}

/// A scene body or another patch a patch's contact names (indices into `BuiltScene`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ContactWith {
    Body(usize),
    Patch(usize),
}

/// A coupling's kernels, clustered at load (SI units).
#[derive(Clone, Debug)]
pub struct BuiltCoupling {
    pub upper: usize,
    pub lower: usize,
    pub kernels: Vec<crate::coupling::kernels::KernelShape>,
    pub adjust: bool,
    pub distance: crate::coupling::kernels::KernelDistance,
}

#[derive(Clone, Debug)]
pub enum LayerMesh {
    Surface(SurfaceMesh),
    Volume(TetMesh),
}

impl LayerMesh {
    pub fn rest(&self) -> &[DVec3] {
        match self {
            LayerMesh::Surface(m) => &m.rest,
            LayerMesh::Volume(m) => &m.rest,
        }
    }
}

#[derive(Clone, Debug)]
pub struct BuiltLayer {
    pub name: String,
    pub kind: LayerKind,
    pub mesh: LayerMesh,
    /// Per mesh vertex: Some((layer, vertex)) when the vertex is another (earlier) layer's.
    pub shared: Vec<Option<(usize, u32)>>,
    /// The prism grid of a volume slab, for layers stacked on it.
    pub slab: Option<SlabGrid>,
    /// An OBJ surface's `o` / `g` groups (for regions cut out of it).
    pub groups: Option<crate::mesh::obj::FaceGroups>,
    pub material: Option<crate::model::Material>,
    pub thickness: Option<f64>,
    pub bending: Option<crate::model::Bending>,
    pub prestrain: Option<crate::model::LayerPrestrain>,
    /// (relative amplitude, seed) of the per-element modulus randomization.
    pub randomize: Option<(f64, u64)>,
    pub properties: Option<crate::model::LayerProperties>,
    pub remesh: Option<crate::model::RemeshSettings>,
    /// A glTF body's asset (its rig, clips and UVs).
    pub asset: Option<std::sync::Arc<BodyAsset>>,
    /// A kinematic layer refined from a moving surface: carried by it.
    pub embedding: Option<BuiltEmbedding>,
    /// A refined layer: per vertex, the base's face it came from and its barycentric
    /// coordinates there (the midpoint-split parameterisation).
    pub parents: Option<Vec<(u32, DVec3)>>,
    /// Per vertex, the asset's own UVs (a glTF body and the layers refined or offset from it).
    pub asset_uv: Option<Vec<DVec2>>,
}

/// A glTF body (issue 62): the asset, its frame and its UV islands.
#[derive(Clone, Debug)]
pub struct BodyAsset {
    pub asset: std::sync::Arc<crate::mesh::rig::Asset>,
    pub path: PathBuf,
    /// glTF to the engine's frame: a rotation, then a translation (m).
    pub to_world: (glam::DQuat, DVec3),
    /// Per UV island: its scale and distortion.
    pub islands: Vec<crate::mesh::uv_islands::IslandReport>,
    /// Per face of the welded surface, its UV island.
    pub of_face: Vec<u32>,
    /// Per face corner: the asset's UVs, and the length-true material coordinates (m); None for
    /// an asset without UVs.
    pub corner_uv: Option<(Corners, Corners)>,
}

/// Per face, a value at each of its corners.
pub(crate) type Corners = Vec<[DVec2; 3]>;

/// A layer embedded in a surface of its patch (a body's layer 0 or an earlier kinematic layer):
/// each vertex the stencil of that layer's vertices, moved `distance` along the normal.
#[derive(Clone, Debug)]
pub struct BuiltEmbedding {
    pub base: usize,
    pub stencils: Vec<crate::mesh::subdivision::Stencil>,
    pub distance: f64,
}

impl LayerMesh {
    /// Material (2D) positions of the mesh's vertices, as spawned into `MaterialPos`.
    pub(crate) fn material_positions(&self) -> Vec<DVec2> {
        match self {
            LayerMesh::Surface(m) => m.uv.clone(),
            LayerMesh::Volume(m) => m.rest.iter().map(|p| p.truncate()).collect(),
        }
    }
}

/// The structured grid of a tetrahedral slab (SI, offset included).
#[derive(Clone, Copy, Debug)]
pub struct SlabGrid {
    pub size: DVec2,
    /// The finest grid (the top plane's without coarsening).
    pub cells: (u32, u32),
    pub origin: DVec3,
    /// z of the top plane.
    pub top: f64,
    /// The top plane's grid and first vertex.
    pub top_cells: (u32, u32),
    pub top_first: usize,
    /// In-plane coarsening with depth (the slab's frame, before the offset); layers stacked on
    /// the slab share it.
    pub coarsen: Option<crate::mesh::Coarsening>,
}

impl SlabGrid {
    pub(super) fn top_len(&self) -> usize {
        (self.top_cells.0 as usize + 1) * (self.top_cells.1 as usize + 1)
    }
}

impl BuiltDriver {
    /// The layers the driver acts on.
    pub fn layers(&self) -> Vec<usize> {
        match self {
            BuiltDriver::Pin { layer, .. }
            | BuiltDriver::BlendShape { layer, .. }
            | BuiltDriver::Sequence { layer, .. }
            | BuiltDriver::Rig { layer, .. } => vec![*layer],
            BuiltDriver::Attach { layer, to, .. } => vec![*layer, *to],
            BuiltDriver::Compress { layers, .. }
            | BuiltDriver::Bend { layers, .. }
            | BuiltDriver::Joint { layers, .. }
            | BuiltDriver::PlaneStrain { layers, .. }
            | BuiltDriver::Periodic { layers, .. }
            | BuiltDriver::Capture { layers, .. } => layers.clone(),
        }
    }

    /// Whether it only moves its layers (what a shared body may take).
    pub(crate) fn is_motion(&self) -> bool {
        matches!(
            self,
            BuiltDriver::Compress { .. }
                | BuiltDriver::Bend { .. }
                | BuiltDriver::Joint { .. }
                | BuiltDriver::BlendShape { .. }
                | BuiltDriver::Sequence { .. }
                | BuiltDriver::Rig { .. }
        )
    }
}

/// A blend-shape target: displacements of the layer's vertices (m) and weight keyframes.
pub(crate) type BuiltTarget = (Vec<DVec3>, Vec<(u32, f64)>);

/// Drivers with layer names resolved to indices and values in SI units.
#[derive(Clone, Debug)]
pub enum BuiltDriver {
    Pin {
        layer: usize,
        vertices: Vec<u32>,
        dofs: [bool; 3],
    },
    Compress {
        layers: Vec<usize>,
        axis: usize,
        keyframes: Vec<(u32, f64)>,
        predict: bool,
    },
    Bend {
        layers: Vec<usize>,
        axis: usize,
        keyframes: Vec<(u32, f64)>,
    },
    /// Keyframes in radians; pivot in metres (the patch offset applied).
    Joint {
        layers: Vec<usize>,
        joint: crate::model::Joint,
        keyframes: Vec<(u32, f64)>,
    },
    /// Springs (vertex of `layer`, vertex of `to`, stiffness N/m), and their stiffness per unit
    /// area of `layer` (N/m^3: for the springs made again after a remesh).
    Attach {
        layer: usize,
        to: usize,
        springs: Vec<(u32, u32, f64)>,
        k_area: f64,
    },
    /// Per layer: (vertex, master vertex) pairs whose in-plane coordinates are shared.
    PlaneStrain {
        layers: Vec<usize>,
        axis: usize,
        ties: Vec<Vec<(u32, u32)>>,
    },
    /// Per layer: (max-side vertex, min-side vertex) pairs sharing the non-axis coordinates,
    /// and for shells the hinges across the seam.
    Periodic {
        layers: Vec<usize>,
        axis: usize,
        ties: Vec<Vec<(u32, u32)>>,
        seams: Vec<Vec<SeamHinge>>,
    },
    /// Per target: displacements of the layer's vertices (m) and weight keyframes.
    BlendShape {
        layer: usize,
        targets: Vec<BuiltTarget>,
        interpolation: crate::model::Interpolation,
    },
    /// Per frame from `start`: displacements of the layer's vertices from rest (m).
    Sequence {
        layer: usize,
        frames: Vec<Vec<DVec3>>,
        start: u32,
    },
    /// A glTF body posed by its rig.
    Rig {
        layer: usize,
        rig: std::sync::Arc<crate::model::RigMotion>,
    },
    Capture {
        layers: Vec<usize>,
        frame: u32,
        fraction: f64,
        /// Per listed layer: the painted fraction over its rectangle.
        maps: Vec<Option<WeightMap>>,
    },
}

/// Anchors bound at load (SI units): (skin vertex, body point, stiffness N/m) and (skin face,
/// body point, stiffness) for the barycentres.
#[derive(Clone, Debug)]
pub struct BuiltAnchors {
    pub skin: usize,
    pub body: usize,
    pub method: AnchorMethod,
    pub slide: f64,
    pub surface: BodySurface,
    pub vertex: Vec<(u32, SurfacePoint, f64)>,
    pub face: Vec<(u32, SurfacePoint, f64)>,
    /// The farthest skin point from the body at load (m), reported.
    pub bind_distance: f64,
}
