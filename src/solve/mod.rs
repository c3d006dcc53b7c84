//! The per-patch solver: a packed body copied out of the ECS, a sparse pattern with cached
//! scatter maps and symbolic factorization, and Newton with Armijo backtracking.

pub mod body;
mod constrained;
pub mod constraints;
pub mod eval;
pub mod kkt;
pub mod linear;
pub mod newton;
pub mod ordering;
pub mod pattern;
pub mod settle;

pub use body::{AnchorElem, Elements, HingeElem, MembraneElem, SolverBody, SpringElem, TetElem};
pub use newton::{solve_frame, FrameOutcome, SolveCounters};
