//! The per-patch solver: a patch packed out of the ECS (`packed`), a sparse pattern with cached
//! scatter maps and symbolic factorization, and Newton with Armijo backtracking. Measured and
//! rejected variants are recorded in `README.md` beside this file.

mod constrained;
pub mod constraints;
mod contact;
pub mod eigen;
pub mod element;
pub mod elements;
pub mod error;
pub mod eval;
mod frame;
mod iteration;
pub mod kkt;
pub mod linear;
pub mod local;
pub mod newton;
pub mod ordering;
pub mod packed;
pub mod pattern;
mod progress;
mod release;
pub(crate) mod scatter;
pub mod settings;
pub mod settle;
pub mod stability;
mod trust_region;

pub use elements::{AnchorElem, CellElem, Elements, HingeElem, MembraneElem, PinElem, SpringElem, TetElem};
pub use error::SolveError;
pub use frame::solve_frame;
pub use iteration::{FrameOutcome, SolveCounters};
pub use packed::{Carry, LocalReport, PackedPatch, PackedState, SolverCache};
pub use settings::{Globalization, KktMethod, LinearSolver, Precision, SolveMode, SolverSettings, StabilityTest};
