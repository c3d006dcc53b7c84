//! The per-patch solver: a packed body copied out of the ECS, a sparse pattern with cached
//! scatter maps and symbolic factorization, and Newton with Armijo backtracking.

pub mod body;
mod constrained;
pub mod constraints;
pub mod error;
pub mod eval;
pub mod kkt;
pub mod linear;
pub mod newton;
pub mod ordering;
pub mod pattern;
pub mod settings;
pub mod settle;

pub use body::{AnchorElem, Elements, HingeElem, MembraneElem, SolverBody, SpringElem, TetElem};
pub use error::SolveError;
pub use newton::{solve_frame, FrameOutcome, SolveCounters};
pub use settings::{KktMethod, LinearSolver, SolveMode, SolverSettings};
