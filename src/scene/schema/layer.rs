//! A patch's layers: kind, mesh, material, bending, prestrain, randomized moduli, property maps
//! and remeshing.

use serde::{Deserialize, Serialize};

use super::{default_one, Axis};
use crate::mesh::GridPattern;
use crate::model::LayerKind;
use crate::physics::{ConstitutiveModel, HingeModel};

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename = "Layer")]
pub struct LayerSpec {
    pub name: String,
    pub kind: LayerKind,
    pub mesh: MeshSpec,
    /// Required for shell and volume layers.
    #[serde(default)]
    pub material: Option<MaterialSpec>,
    /// Shell layers only; no hinges without it.
    #[serde(default)]
    pub bending: Option<BendingSpec>,
    /// A stored prestrain (H15 4.3): F0 per element, and for shells a rest curvature.
    #[serde(default)]
    pub prestrain: Option<PrestrainSpec>,
    /// Per-element Young's modulus E (1 + amplitude u), u seeded-uniform in [-1, 1]: breaks the
    /// symmetry of uniform compression (H15 6.2, fig. 6.7b).
    #[serde(default)]
    pub randomize: Option<RandomizeSpec>,
    /// A property map over the layer's material rectangle (LK14 5.2); shells only.
    #[serde(default)]
    pub properties: Option<PropertiesSpec>,
    /// Adaptive remeshing in material space (REMESH.md); shells only.
    #[serde(default)]
    pub remesh: Option<RemeshSpec>,
}

/// Remeshing thresholds (REMESH.md), lengths in the scene's length unit.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Remesh")]
pub struct RemeshSpec {
    /// Smallest and largest edge length.
    pub size_min: f64,
    pub size_max: f64,
    /// Smallest ratio of the two sizes of an anisotropic metric, in (0, 1].
    #[serde(default = "default_aspect_min")]
    pub aspect_min: f64,
    /// Largest turn of the normal across an edge (radians).
    #[serde(default = "default_refine_angle")]
    pub refine_angle: f64,
    /// Largest unresolved buckle amplitude (a length).
    pub refine_compression: f64,
    /// Velocity-gradient term (length per second), for the implicit-Euler mode.
    #[serde(default)]
    pub refine_velocity: Option<f64>,
    /// Remesh after the first solved frame, then every this many frames (the first frame runs on
    /// the mesh given).
    #[serde(default = "default_every")]
    pub every: u32,
    /// Split midpoints on the curved surface (default); false puts them on the straight edge
    /// (only to measure the energy jump the curved placement avoids).
    #[serde(default = "default_curved_splits")]
    pub curved_splits: bool,
    /// Relax the vertices of every changed face on the layer's own energy before the frame's
    /// solve (default); false leaves them where the operations put them (only to measure the
    /// jump settling avoids).
    #[serde(default = "default_settle")]
    pub settle: bool,
    /// Rings of neighbours settled with the changed faces' vertices (issue 26 item 2; 0: only
    /// the changed faces, the policy before it).
    #[serde(default = "default_settle_rings")]
    pub settle_rings: u32,
    /// Then solve those vertices (the changed faces' and the rings') to equilibrium with the
    /// patch's own Newton, the rest of the patch held, before the frame's solve (issue 26 item
    /// 2; default false, the policy before it).
    #[serde(default)]
    pub local_solve: bool,
    /// Keep the mesh unless a remesh would split or collapse at least this fraction of its
    /// faces' count (issue 26 item 3: refine mostly; default 0, every remesh kept).
    #[serde(default)]
    pub min_change: f64,
    /// Refine before the wrinkles form (issue 26): edges at most lambda / `per_wavelength`
    /// across the compression wherever the layer's driver compresses it past `onset` times its
    /// critical strain, lambda(x) the wavelength of the layer's kernels there. Needs a coupling
    /// with this layer above; the first remesh then runs before the first solve.
    #[serde(default)]
    pub wavelength: Option<RefineWavelengthSpec>,
}

/// Wavelength-aware refinement of a remeshed layer.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "RefineWavelength")]
pub struct RefineWavelengthSpec {
    /// Elements per wavelength across the wrinkles.
    #[serde(default = "default_per_wavelength")]
    pub per_wavelength: f64,
    /// The fraction of the critical compressive strain from which the bound holds.
    #[serde(default = "default_onset")]
    pub onset: f64,
    /// Bound every edge there, not only those across the compression (default false).
    #[serde(default)]
    pub isotropic: bool,
    /// Also where the kinematic layers below will be compressed at their drivers' later
    /// keyframes, and from theirs only, not the layers' between (default false: the compression
    /// every layer below has at this frame).
    #[serde(default)]
    pub lookahead: bool,
    /// And within this distance (length units) of those faces (default 0).
    #[serde(default)]
    pub margin: f64,
    /// Leave alone the faces there whose edges already meet the bound: refined before they
    /// wrinkle, they are not remeshed again (default false).
    #[serde(default)]
    pub hold: bool,
}

fn default_per_wavelength() -> f64 {
    8.0
}

fn default_onset() -> f64 {
    0.5
}

fn default_settle() -> bool {
    true
}

fn default_settle_rings() -> u32 {
    0
}

fn default_curved_splits() -> bool {
    true
}

fn default_aspect_min() -> f64 {
    0.2
}

fn default_refine_angle() -> f64 {
    0.3
}

fn default_every() -> u32 {
    1
}

/// An RGB property map and how each channel (0 to 1) scales the layer's reference values:
/// factor = lo + (hi - lo) x channel. Red: the critical wavelength of couplings whose upper
/// layer this is; green: Young's modulus; blue: thickness. A channel without a mapping is
/// ignored. Sampled bilinearly: faces at their centroid, hinges at their edge midpoint, kernels
/// at their centre.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Properties")]
pub struct PropertiesSpec {
    pub map: MapSource,
    #[serde(default)]
    pub wavelength: Option<(f64, f64)>,
    #[serde(default)]
    pub young: Option<(f64, f64)>,
    #[serde(default)]
    pub thickness: Option<(f64, f64)>,
}

/// Where a property map's colours come from. Colours are (r, g, b) in [0, 1].
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum MapSource {
    /// An RGB (or RGBA) PNG, path relative to the scene, stretched over the layer's rectangle.
    Png(String),
    Constant((f64, f64, f64)),
    /// Linear from `from` at the min side to `to` at the max side along `axis`.
    Ramp {
        axis: Axis,
        from: (f64, f64, f64),
        to: (f64, f64, f64),
    },
    /// `inner` at the centre to `outer` at half the smaller side and beyond.
    Radial {
        inner: (f64, f64, f64),
        outer: (f64, f64, f64),
    },
    /// Seeded value noise: a random colour between `low` and `high` (per channel, one shared
    /// random number) at the nodes of a `cells` x `cells` lattice, smoothly interpolated.
    Noise {
        seed: u64,
        cells: u32,
        low: (f64, f64, f64),
        high: (f64, f64, f64),
    },
}

/// Prestrain of a layer (H15 4.3, eq. 4.8: F = dx/dX F0).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Prestrain")]
pub struct PrestrainSpec {
    /// Principal stretches of F0 along the material x, y, z axes (1.02: stretched 2 % at rest,
    /// H15 table 6.1). Shells use the in-plane part.
    #[serde(default = "unit_stretch")]
    pub stretch: (f64, f64, f64),
    /// A greyscale PNG over the layer's rectangle (path relative to the scene; white = 1):
    /// F0 = I + w (S - I) with w the map at the element's centre.
    #[serde(default)]
    pub map: Option<String>,
    /// Shells: rest curvature (1 / length unit) that replaces the flat rest bend of every hinge,
    /// curving along `curvature_along` (the shape of a cylinder across that axis).
    #[serde(default)]
    pub curvature: f64,
    #[serde(default)]
    pub curvature_along: Axis,
}

fn unit_stretch() -> (f64, f64, f64) {
    (1.0, 1.0, 1.0)
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Randomize")]
pub struct RandomizeSpec {
    /// Relative amplitude, in [0, 1): E stays positive.
    pub amplitude: f64,
    pub seed: u64,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum MeshSpec {
    /// Rectangle [0, size.0] x [0, size.1] at height z, `cells` cells.
    Grid {
        size: (f64, f64),
        cells: (u32, u32),
        #[serde(default)]
        pattern: GridPattern,
        #[serde(default)]
        z: f64,
    },
    /// A tetrahedral slab over the same rectangle, from z = top - depth up to z = top,
    /// `elements` tetrahedral prisms through the depth (three tets each).
    TetSlab {
        size: (f64, f64),
        cells: (u32, u32),
        depth: f64,
        elements: u32,
        #[serde(default)]
        top: f64,
        /// Bottom element thickness over top element thickness (1: uniform; > 1 refines towards
        /// the surface, where wrinkle displacements are largest).
        #[serde(default = "default_one")]
        grading: f64,
        /// In-plane coarsening with depth; layers stacked on the slab (TetOn) share it.
        #[serde(default)]
        coarsen: Option<CoarsenSpec>,
    },
    /// A triangle surface from an OBJ file (path relative to the scene file), in length units.
    Obj { path: String },
    /// A tetrahedral slab stacked on the top of an earlier volume layer (TetSlab or TetOn),
    /// sharing its top vertices: `depth` thick with `elements` prisms through it (H15 4.1).
    TetOn {
        layer: String,
        depth: f64,
        elements: u32,
        #[serde(default = "default_one")]
        grading: f64,
    },
    /// The top surface of an earlier volume layer: a shell (or kinematic) layer whose vertices
    /// are that layer's top vertices (H15: the stratum corneum over the dermis).
    SurfaceOf { layer: String },
    /// An open tube along x centred on the origin: `cells` = (around, along).
    /// `arc` (degrees, default 360: closed): an open part of the tube that wide, centred on +z.
    Tube {
        radius: f64,
        length: f64,
        cells: (u32, u32),
        #[serde(default)]
        arc: Option<f64>,
    },
    /// A closed lumpy creature (torso, four legs, head, tail) of 20 x 4^subdivisions triangles.
    Creature { radius: f64, subdivisions: u32 },
    /// An earlier surface layer's rest mesh moved `distance` along its vertex normals (a skin
    /// over a body; its own vertices). With `region`, only the faces it selects: a patch on a
    /// part of the body, its material space the body's.
    Offset {
        layer: String,
        distance: f64,
        #[serde(default)]
        region: Option<RegionSpec>,
        /// Refine the selected faces (issue 62): subdivided until their edges meet the target,
        /// the new vertices on the base's smooth (Loop limit) surface. A kinematic layer refined
        /// from a body is embedded in it: each vertex a fixed combination of body vertices, so
        /// the body's motion (skinning, morphs, joints, sequences) carries it exactly.
        #[serde(default)]
        refine: Option<RefineSpec>,
    },
    /// A glTF 2.0 asset (`.gltf` with its buffers, or `.glb`; path relative to the scene): a
    /// kinematic body with its UVs, skin and morph targets, moved by a `Rig` driver. glTF is in
    /// metres with +Y up: it is turned to +Z up (as Blender imports it) and never rescaled.
    Gltf {
        path: String,
        /// The asset's mesh by name (default: its only mesh).
        #[serde(default)]
        mesh: Option<String>,
    },
}

/// How finely a refined region is subdivided: each level halves its edges.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum RefineSpec {
    /// At least this many edges per wavelength of the smallest coupling on this layer (or, for a
    /// kinematic layer, of the couplings it is the lower layer of, and of the layers offset from
    /// it) (the elements-per-wavelength rule, REMESH.md).
    Wavelength(f64),
    /// The longest refined edge at most this long (length units).
    Edge(f64),
    /// This many subdivision levels (0: the base's own faces, placed on its limit surface).
    Levels(u32),
}

/// A slab's grid halves along each axis whose cell count is even every `every` (length units)
/// below z = `from` (default: the slab's top; give the skin surface's z when layers are stacked
/// on the slab): wrinkle displacements decay like exp(-2 pi depth / lambda), so about lambda / 2
/// keeps VALIDATION.md case 7 (issue 25 item 3). Element grids step by at most one halving.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Coarsen")]
pub struct CoarsenSpec {
    pub every: f64,
    #[serde(default)]
    pub from: Option<f64>,
}

/// A part of a surface: by UV rectangle or mask, the faces all of whose vertices it selects; by
/// group, the group's faces.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum RegionSpec {
    /// Vertices whose material coordinates (the UVs; length units) lie in [min, max].
    Uv { min: (f64, f64), max: (f64, f64) },
    /// Vertices a painted greyscale image covers (>= threshold) stretched over the surface's
    /// material rectangle, row 0 at its largest v (path relative to the scene file).
    Mask { image: String, threshold: f64 },
    /// The faces of an OBJ group (`o` or `g` name) of the surface's OBJ file.
    Group(String),
    /// Vertices inside a box (length units; the body's frame, where it sits in the world).
    Box { min: (f64, f64, f64), max: (f64, f64, f64) },
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename = "Material")]
pub struct MaterialSpec {
    /// Default: Bazant-Hencky; Stable Neo-Hookean for the skin layer of KCK18 anchors.
    #[serde(default)]
    pub model: Option<ConstitutiveModel>,
    /// A shipped reference material: supplies young, poisson and thickness wherever they are
    /// not stated.
    #[serde(default)]
    pub preset: Option<MaterialPreset>,
    /// Young's modulus (stress units).
    #[serde(default)]
    pub young: Option<f64>,
    #[serde(default)]
    pub poisson: Option<f64>,
    /// kg/m^3.
    #[serde(default = "default_density")]
    pub density: f64,
    /// Shell thickness (length units); shells only.
    #[serde(default)]
    pub thickness: Option<f64>,
    /// Volume layers only: `Tet` evaluates the model's lambda term in every tetrahedron, `Cell`
    /// once per hexahedral cell of six (no volumetric locking near incompressibility). Default:
    /// `Cell` from Poisson's ratio `physics::cell::CELL_FROM_POISSON` up, else `Tet`.
    #[serde(default)]
    pub volume_element: Option<crate::physics::cell::VolumeElement>,
}

/// Reference materials (LK14 5.2): the two-layer skin model and the soft substructure under
/// its blend shape. LK14 states E and h; the Poisson ratio 0.45 (nearly incompressible soft
/// tissue) is ours.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
pub enum MaterialPreset {
    /// E = 4 MPa, h = 1.3 mm.
    Lk14Dermis,
    /// E = 600 MPa, h = 0.12 mm.
    Lk14Epidermis,
    /// E = 0.5 MPa, h = 15 mm (the Eq31 stand-in for a kinematic base).
    Lk14Substructure,
}

impl MaterialPreset {
    /// (Young's modulus in Pa, Poisson ratio, thickness in m).
    pub(crate) fn si(self) -> (f64, f64, f64) {
        match self {
            MaterialPreset::Lk14Dermis => (4e6, 0.45, 1.3e-3),
            MaterialPreset::Lk14Epidermis => (600e6, 0.45, 0.12e-3),
            MaterialPreset::Lk14Substructure => (0.5e6, 0.45, 15e-3),
        }
    }
}

fn default_density() -> f64 {
    1000.0
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename = "Bending")]
pub struct BendingSpec {
    #[serde(default)]
    pub model: HingeModel,
    /// `Hinge` (default) or `Quadratic`: the squared cotangent Laplacian, accurate on irregular
    /// and anisotropic (remeshed) meshes, for layers with a flat rest state.
    #[serde(default)]
    pub element: crate::physics::BendingElement,
    /// Multiplies the calibrated hinge stiffness k_b = D / 6 (PHYSICS.md 1.2).
    #[serde(default = "default_one")]
    pub scale: f64,
}
