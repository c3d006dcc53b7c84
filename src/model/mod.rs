//! The ECS vocabulary (ARCHITECTURE.md 3): small components, named relationships, resources.
//!
//! Entity handles are the identity; the solver's packed indices are a cache (`PackedIndex`
//! beside `solve::PackedPatch`).

use bevy_ecs::prelude::*;
use glam::{DMat2, DMat3, DVec2, DVec3};

use crate::physics::{ConstitutiveModel, HingeModel, HingeRest, Lame};

mod anchors;
pub mod checkpoint;
mod keyframes;
mod maps;
mod motion;
mod resources;
mod rest;
mod rig;
pub use anchors::*;
pub use keyframes::*;
pub use maps::*;
pub use motion::*;
pub use resources::*;
pub use rest::*;
pub use rig::*;

// ---------------------------------------------------------------- patches and layers

/// A skin patch: one independent solve problem.
#[derive(Component, Clone, Debug)]
pub struct Patch {
    pub name: String,
    /// Position of the patch in the scene file (stable ordering for outputs).
    pub index: u32,
}

/// On a patch: barrier contact between its shell surfaces (SI lengths; `crate::contact`).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    /// The barrier's offset xi: the distance it keeps two surfaces apart (m).
    pub thickness: f64,
    /// Its reach d_hat beyond the offset (m).
    pub reach: f64,
    /// Coulomb's coefficient between touching surfaces (0: frictionless).
    pub friction: f64,
    /// The slip per frame below which friction holds a pair (m): eps_u of `contact::friction`.
    pub sticking: f64,
}

/// On a patch with contact: the layers of scene bodies and other patches its skin touches
/// (`contact.with`), packed after its own vertices and held (`systems::solve` solves such
/// patches in turn, each against the others' latest positions).
#[derive(Component, Clone, Debug, Default, PartialEq)]
pub struct ContactObstacles(pub Vec<Entity>);

/// What a layer is made of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum LayerKind {
    /// A thin shell: membrane triangles and hinge bending.
    Shell,
    /// A tetrahedral solid.
    Volume,
    /// Prescribed motion only (a blend-shape base or a body).
    Kinematic,
}

#[derive(Component, Clone, Debug)]
pub struct Layer {
    pub name: String,
    pub kind: LayerKind,
    /// Position of the layer in its patch (stable ordering).
    pub index: u32,
}

/// Layer -> Patch.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
#[relationship(relationship_target = PatchLayers)]
pub struct LayerOf(pub Entity);

/// Patch -> its layers (maintained by bevy).
#[derive(Component, Debug, Default)]
#[relationship_target(relationship = LayerOf, linked_spawn)]
pub struct PatchLayers(Vec<Entity>);

impl PatchLayers {
    pub fn entities(&self) -> &[Entity] {
        &self.0
    }
}

/// Patch -> the shared body layers its solve packs (held fixed) besides its own: those its
/// kernels hold it to.
#[derive(Component, Clone, Debug, Default)]
pub struct PatchBodies(pub Vec<Entity>);

/// Elastic material of a shell or volume layer, SI units.
#[derive(Component, Clone, Copy, Debug)]
pub struct Material {
    pub model: ConstitutiveModel,
    pub young: f64,
    pub poisson: f64,
    pub density: f64,
    /// Lame parameters used by the elements (plane stress for shells).
    pub lame: Lame,
    /// Where a volume layer's lambda term is evaluated: per tet, or once per cell.
    pub volume_element: crate::physics::cell::VolumeElement,
}

/// Shell thickness (m).
#[derive(Component, Clone, Copy, Debug)]
pub struct Thickness(pub f64);

/// Hinge bending of a shell layer: k_b = D / 6 x scale (PHYSICS.md 1.2).
#[derive(Component, Clone, Copy, Debug)]
pub struct Bending {
    pub model: HingeModel,
    /// Hinge elements, or quadratic ones built from the hinges' stiffness (D = 6 k_b).
    pub element: crate::physics::BendingElement,
    pub stiffness: f64,
}

/// The map between a patch's entities and its packed solver indices (beside the patch's
/// `solve::PackedPatch`), rebuilt by Assemble when the topology changes.
#[derive(Component, Clone, Debug)]
pub struct PackedIndex {
    /// The topology fingerprint (epochs and element counts of the patch's layers) it was built
    /// for; `u64::MAX` before the first rebuild.
    pub key: u64,
    /// Packed vertex index -> entity, and entity -> packed vertex index.
    pub vertices: Vec<Entity>,
    pub index: std::collections::HashMap<Entity, u32>,
    /// The first `own` packed vertices are the patch's; the rest are a shared body's (read, not
    /// written back).
    pub own: usize,
    /// From `held` on, the packed vertices are what contact touches besides the patch and its
    /// body (`ContactObstacles`): held, whatever their own layers' pins.
    pub held: usize,
    /// Anchor entities in element order: the vertex anchors, then the face anchors.
    pub anchors: Vec<Entity>,
    /// Faces and tets of the patch's solved layers (for reports).
    pub faces: usize,
    pub tets: usize,
}

impl Default for PackedIndex {
    fn default() -> Self {
        PackedIndex {
            key: u64::MAX,
            vertices: Vec::new(),
            index: Default::default(),
            own: 0,
            held: 0,
            anchors: Vec::new(),
            faces: 0,
            tets: 0,
        }
    }
}

/// Bumped whenever a layer's connectivity changes; the solver rebuilds its pattern then.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TopologyEpoch(pub u64);

/// Adaptive remeshing of a shell layer (REMESH.md), SI thresholds: after the first solved frame,
/// then every `every` frames.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct RemeshSettings {
    pub params: crate::mesh::remesh::RemeshParams,
    pub every: u32,
    /// Settle the vertices of changed faces after a remesh (`Unsettled`, the Settle stage).
    pub settle: bool,
    /// Rings of neighbours settled with them.
    pub settle_rings: u32,
    /// Then solve them to equilibrium, the rest held (`solve::local`).
    pub local_solve: bool,
    /// A remesh splitting or collapsing fewer than this fraction of the faces' count is dropped.
    pub min_change: f64,
    /// Wavelength-aware refinement from the layer's kernels and driver (issue 26); the first
    /// remesh then runs before the first solve.
    pub wavelength: Option<crate::mesh::remesh::sizing::WavelengthSizing>,
}

impl RemeshSettings {
    /// Whether the layer is remeshed in `frame` (frames count from 1). The first frame is
    /// solved on the scene's own mesh, as in ARCSim (remesh after each step): a remesh of the
    /// unsolved start sees no curvature and no compression, so it would coarsen everything and
    /// the wrinkle mode would be chosen on the coarsest mesh allowed (measured: LK14 case 10
    /// then ends 13 % long). The wavelength term sees the compression the driver imposes
    /// before any solve: with it the first remesh comes before the first solve (issue 26
    /// item 1).
    pub fn due(&self, frame: u32) -> bool {
        let first = if self.wavelength.is_some() { 1 } else { 2 };
        frame >= first && (frame - first).is_multiple_of(self.every)
    }
}

/// What the last remesh of a layer did, and the layer's size after it.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RemeshReport {
    pub frame: u64,
    /// The size_max used: the scene's, capped by the layer's kernels (m).
    pub size_max: f64,
    pub stats: crate::mesh::remesh::RemeshStats,
    pub vertices: u32,
    pub faces: u32,
}

impl RemeshReport {
    /// The report of `out`, a remesh in `frame` under `size_max` of a layer of `before`
    /// (vertices, faces); a remesh too small to apply reports no change and the old size.
    pub fn new(
        frame: u32,
        size_max: f64,
        out: &crate::mesh::remesh::Remeshed,
        small: bool,
        before: (usize, usize),
    ) -> Self {
        let (vertices, faces) = if small { before } else { (out.vertices.len(), out.faces.len()) };
        RemeshReport {
            frame: frame as u64,
            size_max,
            stats: if small { Default::default() } else { out.stats },
            vertices: vertices as u32,
            faces: faces as u32,
        }
    }
}

// ---------------------------------------------------------------- vertices

/// A vertex of a face a remesh created, to be relaxed by the Settle stage before the solve.
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct Unsettled {
    /// Relax by sweeps (`solve::settle`), then solve the region (`solve::local`).
    pub sweeps: bool,
    pub solve: bool,
}

/// Vertex -> Layer.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
#[relationship(relationship_target = LayerVertices)]
pub struct VertexOf(pub Entity);

#[derive(Component, Debug, Default)]
#[relationship_target(relationship = VertexOf, linked_spawn)]
pub struct LayerVertices(Vec<Entity>);

impl LayerVertices {
    pub fn entities(&self) -> &[Entity] {
        &self.0
    }
}

/// Material-space coordinates (m): the 2D parameterization of a shell, the rest xy of a solid.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct MaterialPos(pub DVec2);

/// A vertex's texture coordinates in its character asset's own UV layout (issue 62: a glTF body
/// and the layers refined from it), as the asset states them: what the USD cache's `st` carries
/// back to the DCC. Material space (`MaterialPos`) is these made length-true.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct AssetUv(pub DVec2);

/// Reference (rest) position in 3D (m).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct RestPos(pub DVec3);

/// Current position (m).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Position(pub DVec3);

/// Current velocity (m/s).
#[derive(Component, Clone, Copy, Debug, PartialEq, Default)]
pub struct Velocity(pub DVec3);

/// Lumped mass (kg).
#[derive(Component, Clone, Copy, Debug, PartialEq, Default)]
pub struct Mass(pub f64);

/// Which coordinates of a vertex are prescribed (eliminated from the solve). Drivers write
/// their values into `Position`.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
pub struct Prescribed(pub [bool; 3]);

/// Coordinates of this vertex that move with another vertex's (shared solver DOFs): how a
/// plane-strain strip one cell deep stays two-dimensional (H15 6.1).
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tied {
    pub master: Entity,
    pub dofs: [bool; 3],
}

// ---------------------------------------------------------------- edges, faces, tets

/// Edge -> Layer.
#[derive(Component, Clone, Copy, Debug)]
#[relationship(relationship_target = LayerEdges)]
pub struct EdgeOf(pub Entity);

#[derive(Component, Debug, Default)]
#[relationship_target(relationship = EdgeOf, linked_spawn)]
pub struct LayerEdges(Vec<Entity>);

impl LayerEdges {
    pub fn entities(&self) -> &[Entity] {
        &self.0
    }
}

#[derive(Component, Clone, Copy, Debug)]
pub struct EdgeVerts(pub [Entity; 2]);

/// The two vertices opposite an interior edge, on an edge a remesh created: PropertyResample
/// turns it into a `Hinge` (with the rest data and the map's stiffness at the midpoint).
#[derive(Component, Clone, Copy, Debug)]
pub struct EdgeOpposite(pub [Entity; 2]);

/// A bending hinge on an interior edge: the two opposite vertices and the rest data.
#[derive(Component, Clone, Copy, Debug)]
pub struct Hinge {
    pub opposite: [Entity; 2],
    pub rest: HingeRest,
    /// A hinge across a periodic seam: the second opposite vertex stands at its periodic image,
    /// its position plus (position of image[0] - position of image[1]).
    pub image: Option<[Entity; 2]>,
}

/// Face -> Layer.
#[derive(Component, Clone, Copy, Debug)]
#[relationship(relationship_target = LayerFaces)]
pub struct FaceOf(pub Entity);

#[derive(Component, Debug, Default)]
#[relationship_target(relationship = FaceOf, linked_spawn)]
pub struct LayerFaces(Vec<Entity>);

impl LayerFaces {
    pub fn entities(&self) -> &[Entity] {
        &self.0
    }
}

#[derive(Component, Clone, Copy, Debug)]
pub struct FaceVerts(pub [Entity; 3]);

/// Rest shape of a membrane triangle: Dm^-1 F0 and thickness x area.
#[derive(Component, Clone, Copy, Debug)]
pub struct FaceRest(pub crate::physics::membrane::MembraneRest);

/// Membrane prestrain F0 (H15 4.3) in the triangle's own rest frame (that of FaceRest);
/// identity when absent. FaceRest already holds it folded in; this is the record.
#[derive(Component, Clone, Copy, Debug)]
pub struct FacePrestrain(pub DMat2);

/// A shell layer's scene prestrain (H15 4.3), SI: principal stretches (times a map weight,
/// I + w (S - I)) and a rest curvature along x (0) or y (1). Kept on the layer so that the
/// elements a remesh creates get the same prestrain as those spawned with the scene.
#[derive(Component, Clone, Debug)]
pub struct LayerPrestrain {
    pub stretch: DVec3,
    pub map: Option<WeightMap>,
    /// Rest curvature (1/m) along `along`.
    pub curvature: f64,
    pub along: usize,
}

impl LayerPrestrain {
    /// The principal stretches at a material point.
    pub(crate) fn stretch_at(&self, uv: DVec2) -> DVec3 {
        self.map
            .as_ref()
            .map_or(self.stretch, |m| crate::physics::prestrain::weighted_stretch(self.stretch, m.sample(uv)))
    }

    /// F0 of a rest triangle whose centroid is at `centre` in material space.
    pub fn face_f0(&self, rest: [DVec3; 3], centre: DVec2) -> DMat2 {
        crate::physics::prestrain::membrane_f0(rest, self.stretch_at(centre))
    }
}

/// A remeshed shell's smooth imperfection (scene perturbation with a `cell`): the vertices a
/// remesh creates get it at their own material point, not interpolated from their parents'.
#[derive(Component, Clone, Debug)]
pub struct LayerImperfection(pub crate::mesh::imperfection::Imperfection);

/// A per-element factor on the layer's Young's modulus (randomized properties, H15 6.2);
/// 1 when absent. On faces and tets.
#[derive(Component, Clone, Copy, Debug)]
pub struct ModulusScale(pub f64);

/// Tet -> Layer.
#[derive(Component, Clone, Copy, Debug)]
#[relationship(relationship_target = LayerTets)]
pub struct TetOf(pub Entity);

#[derive(Component, Debug, Default)]
#[relationship_target(relationship = TetOf, linked_spawn)]
pub struct LayerTets(Vec<Entity>);

impl LayerTets {
    pub fn entities(&self) -> &[Entity] {
        &self.0
    }
}

#[derive(Component, Clone, Copy, Debug)]
pub struct TetVerts(pub [Entity; 4]);

#[derive(Component, Clone, Copy, Debug)]
pub struct TetRestShape(pub crate::physics::tet::TetRest);

/// The hexahedral cell of its layer a tet belongs to (six tets, eight vertices): in a layer
/// whose material has `VolumeElement::Cell`, the cell's tets share one dilatation.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
pub struct TetCell(pub u32);

/// Tetrahedron prestrain F0 (world axes); identity when absent. TetRestShape holds it folded in.
#[derive(Component, Clone, Copy, Debug)]
pub struct TetPrestrain(pub DMat3);

// ---------------------------------------------------------------- springs

/// A zero-length attachment spring between two vertices (PHYSICS.md 1.5), held by the layer of `a`.
#[derive(Component, Clone, Copy, Debug)]
pub struct Spring {
    pub a: Entity,
    pub b: Entity,
    pub stiffness: f64,
}

/// A zero-length attachment spring from vertex `a` to the point sum_i w_i x(b_i) of a face of
/// another layer: what an Attach becomes once a remesh has moved its vertices off each other's
/// (PHYSICS.md 1.5), held by the layer of `a`.
#[derive(Component, Clone, Copy, Debug)]
pub struct FaceSpring {
    pub a: Entity,
    pub b: [Entity; 3],
    pub w: [f64; 3],
    pub stiffness: f64,
}

/// On a layer attached by an Attach driver: the layer it is attached to and the stiffness per
/// unit area, to make its springs again after a remesh of either layer.
#[derive(Component, Clone, Debug, Default)]
pub struct Attachments(pub Vec<(Entity, f64)>);

/// Spring -> Layer.
#[derive(Component, Clone, Copy, Debug)]
#[relationship(relationship_target = LayerSprings)]
pub struct SpringOf(pub Entity);

#[derive(Component, Debug, Default)]
#[relationship_target(relationship = SpringOf, linked_spawn)]
pub struct LayerSprings(Vec<Entity>);

impl LayerSprings {
    pub fn entities(&self) -> &[Entity] {
        &self.0
    }
}

// ---------------------------------------------------------------- constraint kernels

/// An LK14 constraint kernel (4.1-4.2): holds the `upper` layer to the `lower` one around a
/// material-space centre, with support radius half the critical wavelength.
#[derive(Component, Clone, Copy, Debug)]
pub struct Kernel {
    pub upper: Entity,
    pub lower: Entity,
    pub shape: crate::coupling::kernels::KernelShape,
    /// Whether ConstraintAdjust centres the weights (LK14 4.2.1).
    pub adjust: bool,
    pub distance: crate::coupling::kernels::KernelDistance,
}

/// Kernel -> Patch.
#[derive(Component, Clone, Copy, Debug)]
#[relationship(relationship_target = PatchKernels)]
pub struct KernelOf(pub Entity);

#[derive(Component, Debug, Default)]
#[relationship_target(relationship = KernelOf, linked_spawn)]
pub struct PatchKernels(Vec<Entity>);

impl PatchKernels {
    pub fn entities(&self) -> &[Entity] {
        &self.0
    }
}

/// A kernel's weights on one layer: (vertex, weight).
pub type LayerWeights = Vec<(Entity, f64)>;

/// The area-weighted truncated Gaussian sampled on both layers' current meshes (LK14 eq. 4.3),
/// written by ConstraintResample.
#[derive(Component, Clone, Debug, Default)]
pub struct KernelSamples {
    pub upper: LayerWeights,
    pub lower: LayerWeights,
    /// Geodesic kernels: each support vertex's position in the kernel's tangent chart (upper,
    /// lower), where ConstraintAdjust centres the weights; empty for planar kernels.
    pub chart: [Vec<glam::DVec2>; 2],
}

/// The weights the solver uses: the samples after ConstraintAdjust (LK14 eq. 4.4-4.8).
#[derive(Component, Clone, Debug, Default)]
pub struct KernelWeights {
    pub upper: LayerWeights,
    pub lower: LayerWeights,
    /// What the adjustment could do on each layer.
    pub adjusted: [Option<crate::coupling::kernels::Adjusted>; 2],
}

#[cfg(test)]
mod tests {
    use super::RemeshSettings;
    use crate::mesh::remesh::sizing::WavelengthSizing;
    use crate::mesh::remesh::RemeshParams;

    #[test]
    fn a_layer_is_first_remeshed_after_the_first_solve_or_before_it_with_the_wavelength_term() {
        let params = RemeshParams {
            size_min: 1e-4,
            size_max: 1e-3,
            aspect_min: 0.2,
            refine_angle: 0.3,
            refine_compression: 0.01,
            refine_velocity: None,
            curved_splits: true,
        };
        let plain = RemeshSettings {
            params,
            every: 3,
            settle: false,
            settle_rings: 0,
            local_solve: false,
            min_change: 0.0,
            wavelength: None,
        };
        let due = |s: &RemeshSettings| (1..=8).filter(|&f| s.due(f)).collect::<Vec<_>>();
        assert_eq!(due(&plain), [2, 5, 8]);
        let term = RemeshSettings {
            wavelength: Some(WavelengthSizing { per_wavelength: 8.0, onset: 0.5, ..Default::default() }),
            ..plain
        };
        assert_eq!(due(&term), [1, 4, 7]);
        assert_eq!(due(&RemeshSettings { every: 1, ..plain }), [2, 3, 4, 5, 6, 7, 8]);
    }
}
