//! The scene schema. Every struct denies unknown fields so that a typo is an error.
//! Lengths and stresses are in the scene's `units`; densities in kg/m^3; times in seconds.
//! See scenes/README.md and the commented scenes for examples of every feature.

use serde::{Deserialize, Serialize};

use crate::mesh::GridPattern;
use crate::model::LayerKind;
use crate::physics::{ConstitutiveModel, HingeModel, Projection};
use crate::solve::{KktMethod, LinearSolver, SolveMode, SolverSettings};

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    pub name: String,
    #[serde(default)]
    pub units: Units,
    /// Number of frames to compute.
    pub frames: u32,
    /// Seconds per frame (the time step of the implicit-Euler mode).
    #[serde(default = "default_frame_time")]
    pub frame_time: f64,
    pub patches: Vec<PatchSpec>,
    #[serde(default)]
    pub output: OutputSpec,
}

fn default_frame_time() -> f64 {
    1.0 / 30.0
}
fn default_true() -> bool {
    true
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Units {
    #[serde(default)]
    pub length: LengthUnit,
    #[serde(default)]
    pub stress: StressUnit,
}

impl Default for Units {
    fn default() -> Self {
        Units { length: LengthUnit::Millimetre, stress: StressUnit::MegaPascal }
    }
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq, Default)]
pub enum LengthUnit {
    Metre,
    Centimetre,
    #[default]
    Millimetre,
    Micrometre,
}

impl LengthUnit {
    pub fn to_si(self) -> f64 {
        match self {
            LengthUnit::Metre => 1.0,
            LengthUnit::Centimetre => 1e-2,
            LengthUnit::Millimetre => 1e-3,
            LengthUnit::Micrometre => 1e-6,
        }
    }
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq, Default)]
pub enum StressUnit {
    Pascal,
    KiloPascal,
    #[default]
    MegaPascal,
    GigaPascal,
}

impl StressUnit {
    pub fn to_si(self) -> f64 {
        match self {
            StressUnit::Pascal => 1.0,
            StressUnit::KiloPascal => 1e3,
            StressUnit::MegaPascal => 1e6,
            StressUnit::GigaPascal => 1e9,
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename = "Patch")]
pub struct PatchSpec {
    pub name: String,
    /// Where the patch sits in the world (length units).
    #[serde(default)]
    pub offset: (f64, f64, f64),
    #[serde(default)]
    pub solver: SolverSpec,
    pub layers: Vec<LayerSpec>,
    #[serde(default)]
    pub drivers: Vec<DriverSpec>,
    /// LK14 constraint kernels between pairs of layers (chapter 4).
    #[serde(default)]
    pub couplings: Vec<CouplingSpec>,
    /// KCK18 anchors holding a skin layer to a kinematic body.
    #[serde(default)]
    pub anchors: Option<AnchorSpec>,
}

/// KCK18 sliding skin: zero-length springs from every vertex and face barycentre of the shell
/// layer `skin` to points on the kinematic layer `body`, bound to the closest body point at
/// load. Each frame an anchor is offered a* = a0 + slide (x_skin - a0) and moves to it over the
/// body by `method`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Anchors")]
pub struct AnchorSpec {
    pub skin: String,
    pub body: String,
    /// Stiffness per unit skin area (stress / length units). A face of area A gives k A / 2 to
    /// its barycentre anchor and k A / 6 to each of its vertex anchors (all to the vertices
    /// without face anchors).
    pub stiffness: f64,
    #[serde(default)]
    pub method: crate::model::AnchorMethod,
    /// 1: the anchor follows the skin's tangential pull fully each frame; 0: it never slides.
    #[serde(default = "default_one")]
    pub slide: f64,
    /// Anchors at face barycentres too (KCK18 section 3: vertex anchors alone let a face
    /// straddle a crease). Off only to show that.
    #[serde(default = "default_true")]
    pub faces: bool,
    /// The farthest a skin point may start from the body (length units); default 5 % of the
    /// body's bounding-box diagonal. Farther is an error.
    #[serde(default)]
    pub max_distance: Option<f64>,
    /// Paints the stiffness: factor = lo + (hi - lo) x red of `map`, sampled at each anchor's
    /// skin point in the skin's material space.
    #[serde(default)]
    pub stiffness_map: Option<StiffnessMapSpec>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "StiffnessMap")]
pub struct StiffnessMapSpec {
    pub map: MapSource,
    pub range: (f64, f64),
}

/// Constraint kernels that hold `upper` to `lower` at frequencies below the critical
/// wavelength (LK14 chapter 4): clustered once at load, resampled whenever either mesh changes.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Coupling")]
pub struct CouplingSpec {
    /// A shell layer.
    pub upper: String,
    /// A shell or kinematic layer (the blend-shape base).
    pub lower: String,
    pub wavelength: WavelengthSpec,
    /// Seed of the first cluster centre (LK14 4.1).
    #[serde(default)]
    pub seed: u64,
    /// Adjust the sampled weights so their centroid is the kernel centre (LK14 4.2.1). Off only
    /// to measure what the adjustment does.
    #[serde(default = "default_true")]
    pub adjust: bool,
}

/// Where a coupling's critical wavelength comes from.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum WavelengthSpec {
    /// A declared wavelength (length units), the same everywhere.
    Constant(f64),
    /// LK14 eq. 3.1: constant x (h_upper h_lower)^(1/2) (E_upper / E_lower)^(1/6), from the two
    /// layers' materials; `lower` = (young, thickness) stands in for a kinematic lower layer's
    /// (the substructure under a blend shape: LK14 uses 0.5 MPa, 15 mm).
    Eq31 {
        constant: f64,
        #[serde(default)]
        lower: Option<(f64, f64)>,
    },
    /// Stiff film on a deep substrate: 2 pi h (Ebar_f / (3 Ebar_s))^(1/3), the film the upper
    /// layer, `substrate` = (young, poisson) of the foundation.
    Film { substrate: (f64, f64) },
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Solver")]
pub struct SolverSpec {
    #[serde(default)]
    pub mode: SolveMode,
    /// Converged when |grad| <= tolerance x (internal force scale).
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    #[serde(default = "default_max_iterations")]
    pub max_iterations: u32,
    #[serde(default)]
    pub projection: Projection,
    /// A seeded random normal displacement of free shell vertices before the first frame.
    #[serde(default)]
    pub perturbation: Option<Perturbation>,
    /// Quasistatic mode: at convergence, test the exact Hessian; at an unstable equilibrium
    /// (a saddle: the flat state past the buckling load) leave it along negative curvature.
    #[serde(default = "default_true")]
    pub stability_check: bool,
    /// How Newton solves H dx = -g.
    #[serde(default)]
    pub linear: LinearSolver,
    /// How the constrained (KKT) system of a patch with kernels is solved (LK14 eq. 5.1).
    #[serde(default)]
    pub kkt: KktMethod,
}

fn default_tolerance() -> f64 {
    SolverSettings::default().tolerance
}
fn default_max_iterations() -> u32 {
    SolverSettings::default().max_iterations
}

impl Default for SolverSpec {
    fn default() -> Self {
        let s = SolverSettings::default();
        SolverSpec {
            mode: s.mode,
            tolerance: s.tolerance,
            max_iterations: s.max_iterations,
            projection: s.projection,
            perturbation: None,
            stability_check: s.stability_check,
            linear: s.linear,
            kkt: s.kkt,
        }
    }
}

impl SolverSpec {
    /// The solver's settings (the perturbation is the scene's: spawn applies it).
    pub fn settings(&self) -> SolverSettings {
        SolverSettings {
            mode: self.mode,
            tolerance: self.tolerance,
            max_iterations: self.max_iterations,
            projection: self.projection,
            stability_check: self.stability_check,
            linear: self.linear,
            kkt: self.kkt,
        }
    }
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Perturbation {
    /// Largest displacement (length units), uniform in [-amplitude, amplitude].
    pub amplitude: f64,
    pub seed: u64,
    /// With a length: a smooth field instead of independent vertex values, amplitude x Perlin
    /// noise of this cell size over material space. Every mesh of the patch then gets the same
    /// imperfection, so refining (or remeshing) does not redraw the wrinkle mode it seeds.
    #[serde(default)]
    pub cell: Option<f64>,
}

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
}

fn default_settle() -> bool {
    true
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
    Tube { radius: f64, length: f64, cells: (u32, u32) },
    /// A closed lumpy creature (torso, four legs, head, tail) of 20 x 4^subdivisions triangles.
    Creature { radius: f64, subdivisions: u32 },
    /// An earlier surface layer's rest mesh moved `distance` along its vertex normals (a skin
    /// over a body; its own vertices).
    Offset { layer: String, distance: f64 },
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
    pub fn si(self) -> (f64, f64, f64) {
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

fn default_one() -> f64 {
    1.0
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq, Default)]
pub enum Axis {
    #[default]
    X,
    Y,
    Z,
}

impl Axis {
    pub fn index(self) -> usize {
        self as usize
    }
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
pub enum Side {
    XMin,
    XMax,
    YMin,
    YMax,
    ZMin,
    ZMax,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum Select {
    All,
    /// Vertices on the given sides of the layer's bounding box.
    Sides(Vec<Side>),
    /// Vertices inside a box (length units).
    Box {
        min: (f64, f64, f64),
        max: (f64, f64, f64),
    },
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Dofs {
    #[serde(default = "default_true")]
    pub x: bool,
    #[serde(default = "default_true")]
    pub y: bool,
    #[serde(default = "default_true")]
    pub z: bool,
}

impl Default for Dofs {
    fn default() -> Self {
        Dofs { x: true, y: true, z: true }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum DriverSpec {
    /// Prescribes coordinates of selected vertices (held at their driven position).
    Pin {
        layer: String,
        select: Select,
        #[serde(default)]
        dofs: Dofs,
    },
    /// Uniform compression of the listed layers along an axis about the patch centre:
    /// `keyframes` are (frame, strain); strain 0.1 shortens by 10 %. Moves prescribed
    /// coordinates; with `predict`, free vertices get the same incremental map as a guess.
    Compress {
        layers: Vec<String>,
        #[serde(default)]
        axis: Axis,
        keyframes: Vec<(u32, f64)>,
        #[serde(default = "default_true")]
        predict: bool,
    },
    /// Bends the listed layers into a cylinder about an axis through the patch centre:
    /// `keyframes` are (frame, curvature in 1 / length unit). Moves prescribed coordinates.
    Bend {
        layers: Vec<String>,
        #[serde(default = "axis_y")]
        axis: Axis,
        keyframes: Vec<(u32, f64)>,
    },
    /// Zero-length springs from every vertex of `layer` to the vertex of `to` at the same
    /// material position; `stiffness` per unit area (stress / length units).
    Attach { layer: String, to: String, stiffness: f64 },
    /// Plane strain along `axis` (H15 6.1): the axis coordinate of every vertex of the layers
    /// is held, and vertices that differ only along the axis share their other coordinates, so
    /// a strip one cell deep deforms as a 2D section (no twist, no transverse curvature).
    PlaneStrain {
        layers: Vec<String>,
        #[serde(default = "axis_y")]
        axis: Axis,
    },
    /// Periodic along `axis`: vertices on the max side share their other coordinates with the
    /// vertex at the same place on the min side, so waves continue across (a domain of a whole
    /// number of wavelengths). The axis coordinate itself is left to Pin and Compress.
    Periodic {
        layers: Vec<String>,
        #[serde(default)]
        axis: Axis,
    },
    /// Blend shapes (LK14 5.3) on a layer, usually the kinematic base under a LK14 patch:
    /// x = X + sum over targets of w(frame) (target - X). Moves the layer's prescribed
    /// coordinates (every coordinate of a kinematic layer).
    BlendShape {
        layer: String,
        targets: Vec<BlendTargetSpec>,
        #[serde(default)]
        interpolation: crate::model::Interpolation,
        /// The declared range of every weight; a keyframe outside it is an error.
        #[serde(default = "unit_range")]
        range: (f64, f64),
    },
    /// Poses a kinematic body (KCK18 scenes): the pose at weight w is evaluated exactly (an
    /// elbow bent by w x angle), not blended linearly between rest and target.
    Articulate {
        layer: String,
        pose: PoseSpec,
        weights: Vec<(u32, f64)>,
        #[serde(default)]
        interpolation: crate::model::Interpolation,
    },
    /// An OBJ sequence (paths relative to the scene, length units): frame `start + i` takes the
    /// positions of `files[i]`, the last file holds after; the same vertex count and order as
    /// the layer's mesh.
    ObjSequence {
        layer: String,
        files: Vec<String>,
        #[serde(default)]
        start: u32,
    },
    /// Makes wrinkles permanent (H15 4.3): after the solve of `frame`, `fraction` of each
    /// element's current stretch becomes its prestrain (F0 <- F0 U^-fraction) and each hinge's
    /// rest bend moves that fraction towards its current bend. `map` paints the fraction
    /// (greyscale PNG over the layer's rectangle, white = 1).
    Capture {
        layers: Vec<String>,
        frame: u32,
        #[serde(default = "default_one")]
        fraction: f64,
        #[serde(default)]
        map: Option<String>,
    },
}

/// A procedural body pose (about the centre of the layer's bounding box; angles in degrees).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum PoseSpec {
    /// A tube along x bends upwards from its centre along an arc of `bend_radius` (length
    /// units); below the tube radius the inside of the elbow pinches and then folds through.
    Elbow { angle: f64, bend_radius: f64 },
    /// The part beyond the centre (x) folds upwards about a line along y: at 180 degrees the
    /// crease closes to zero width, past it the halves pass through each other.
    Fold { angle: f64 },
}

fn unit_range() -> (f64, f64) {
    (0.0, 1.0)
}

/// One blend-shape target and its weight keyframes (frame, weight).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Target")]
pub struct BlendTargetSpec {
    pub shape: TargetShape,
    pub weights: Vec<(u32, f64)>,
}

/// The full (weight 1) pose of a target, about the centre of the layer's bounding box. The
/// procedural shapes mimic LK14 fig. 5-1.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum TargetShape {
    /// Shortens the layer along `axis` by `strain` (0.3: 30 %).
    Compress {
        #[serde(default)]
        axis: Axis,
        strain: f64,
    },
    /// Turns the layer about its normal through the centre by `angle` degrees at the centre,
    /// falling smoothly to none at `radius` (length units; default half the smaller side): the
    /// shear of skin twisted over a turning limb.
    Twist {
        angle: f64,
        #[serde(default)]
        radius: Option<f64>,
    },
    /// Draws the skin within `radius` towards the centre (by `squeeze` times the distance at
    /// the centre, smoothly less outwards) and lifts it by `lift` (length units): a pinch while
    /// pulling up.
    Pinch { radius: f64, squeeze: f64, lift: f64 },
    /// A target mesh (path relative to the scene, length units): the same vertices in the same
    /// order as the layer's mesh.
    Obj(String),
}

fn axis_y() -> Axis {
    Axis::Y
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields, rename = "Output")]
pub struct OutputSpec {
    /// stats.jsonl
    #[serde(default = "default_true")]
    pub stats: bool,
    /// recording.rrd
    #[serde(default = "default_true")]
    pub rerun: bool,
    /// obj/<patch>/<layer>/<frame>.obj
    #[serde(default)]
    pub obj: bool,
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec { stats: true, rerun: true, obj: false }
    }
}
