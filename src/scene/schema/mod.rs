//! The scene schema. Every struct denies unknown fields so that a typo is an error.
//! Lengths and stresses are in the scene's `units`; densities in kg/m^3; times in seconds.
//! See scenes/README.md and the commented scenes for examples of every feature. The parts of a
//! patch are in `layer` (layers and their meshes, materials and maps), `driver` (drivers and
//! selections) and `coupling` (LK14 kernels, KCK18 anchors).

use serde::{Deserialize, Serialize};

use crate::physics::Projection;
use crate::solve::{Globalization, KktMethod, LinearSolver, Precision, SolveMode, SolverSettings, StabilityTest};

mod coupling;
mod driver;
mod layer;

pub use coupling::*;
pub use driver::*;
pub use layer::*;

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
    /// Kinematic bodies that several patches sit on (issue 24): each is one entity, moved by
    /// its own drivers, which the patches that name it read and never copy.
    #[serde(default)]
    pub bodies: Vec<BodySpec>,
    pub patches: Vec<PatchSpec>,
    #[serde(default)]
    pub output: OutputSpec,
    /// The memory the run may take (GB; default: the machine's physical memory). `check`
    /// refuses a scene whose estimate passes it, naming the layer and the estimate.
    #[serde(default)]
    pub memory: Option<f64>,
}

/// A kinematic body shared by patches: its surface, where it sits, and the drivers that move it
/// (motions only: Joint, Bend, Compress, BlendShape, Sequence). A patch that names it as its
/// `body` sees it as a layer of the same name, below its own.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename = "Body")]
pub struct BodySpec {
    pub name: String,
    pub mesh: MeshSpec,
    /// Where the body sits in the world (length units).
    #[serde(default)]
    pub offset: (f64, f64, f64),
    #[serde(default)]
    pub drivers: Vec<DriverSpec>,
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
    /// The shared body (`bodies`) the patch sits on: its layers, couplings and anchors may name
    /// it as a layer; it is not copied, and the patch does not drive it.
    #[serde(default)]
    pub body: Option<String>,
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
    /// Barrier contact between the patch's shell surfaces (IPC), so that folds of skin do not
    /// pass through each other.
    #[serde(default)]
    pub contact: Option<ContactSpec>,
}

/// `contact: (thickness: 0.5, d_hat: 0.25, friction: 0.0)` (length units).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Contact")]
pub struct ContactSpec {
    /// The distance the barrier keeps two skin surfaces apart (the shell's half thickness on
    /// each side).
    pub thickness: f64,
    /// How far beyond the thickness the barrier acts; half the thickness when absent.
    #[serde(default)]
    pub d_hat: Option<f64>,
    /// Coulomb's friction coefficient between touching surfaces (0: frictionless), lagged once
    /// per frame (IPC).
    #[serde(default)]
    pub friction: f64,
    /// The slip per frame below which friction holds (length units): a hundredth of the
    /// thickness when absent.
    #[serde(default)]
    pub sticking: Option<f64>,
    /// Other patches and scene bodies the patch's skin touches, by name (solved in turn:
    /// `systems::solve`).
    #[serde(default)]
    pub with: Vec<String>,
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
    /// How the stability check tests an equilibrium (`Inertia`, or the older `ShiftedCholesky`).
    #[serde(default)]
    pub stability_test: StabilityTest,
    /// How a step is made safe where the Hessian is indefinite (`LineSearch`, or `TrustRegion`
    /// for patches with kernels).
    #[serde(default)]
    pub globalization: Globalization,
    /// How Newton solves H dx = -g.
    #[serde(default)]
    pub linear: LinearSolver,
    /// The Cholesky factor's arithmetic: `F64`, or `F32` (mixed precision, refined in f64).
    #[serde(default)]
    pub precision: Precision,
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
            stability_test: s.stability_test,
            globalization: s.globalization,
            linear: s.linear,
            precision: s.precision,
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
            stability_test: self.stability_test,
            globalization: self.globalization,
            linear: self.linear,
            precision: self.precision,
            kkt: self.kkt,
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
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
    /// Sinusoids added to the smooth field (they need `cell`). Noise leaves a buckling mode's
    /// phase and sign to a small projection that the mesh can tip; a wave at the mode's
    /// wavelength sets them (the report's case 11).
    #[serde(default)]
    pub waves: Vec<Wave>,
}

/// amplitude x sin(2 pi u / wavelength), u the material coordinate along `axis` (X or Y) from
/// the layer's material origin.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Wave {
    /// Length units.
    pub wavelength: f64,
    /// Length units.
    pub amplitude: f64,
    #[serde(default)]
    pub axis: Axis,
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
    /// skinsim.usdc: a USD cache of every layer (Pixar's binary crate format)
    #[serde(default)]
    pub usd: bool,
    /// skinsim.usda instead: the same stage as text
    #[serde(default)]
    pub usd_text: bool,
    /// The USD meshes double-sided (`doubleSided`)
    #[serde(default)]
    pub double_sided: bool,
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec { stats: true, rerun: true, obj: false, usd: false, usd_text: false, double_sided: false }
    }
}
