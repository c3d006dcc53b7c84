//! Why a frame's solve failed (the run stops after that frame).

/// What became non-finite.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    Energy,
    Gradient,
    /// The constrained solve: the energy or the Lagrangian gradient.
    State,
}

impl std::fmt::Display for Quantity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Quantity::Energy => "energy",
            Quantity::Gradient => "gradient",
            Quantity::State => "state",
        })
    }
}

/// A constrained solve with contact is pinched (`SolveError::Pinched`) when the collision test
/// cuts its step below this fraction this many iterations in a row: the kernels' rows press
/// skin into skin (`release`). Measured on the elbow at frame 2: the cut fell below 1e-2 by
/// iteration 24 and 1e-3 by 36, with no progress, before no descent at 95.
pub const PINCH_STEP: f64 = 1e-3;
pub const PINCH_ITERATIONS: u32 = 3;

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SolveError {
    #[error("non-finite {quantity} after {iterations} Newton iterations")]
    NonFinite { quantity: Quantity, iterations: u32 },
    #[error("the Hessian could not be factorized even with a diagonal shift")]
    Unfactorizable,
    #[error("the constrained Newton system has no descent direction after {iterations} iterations")]
    NoDescent { iterations: u32 },
    #[error(
        "the kernels hold the skin against contact: every step was cut below {PINCH_STEP} of its length \
         {PINCH_ITERATIONS} iterations in a row (after {iterations} iterations)"
    )]
    Pinched { iterations: u32 },
    #[error("prescribed vertices could not reach their targets without passing through the skin ({substeps} solves)")]
    Blocked { substeps: u32 },
    #[error(
        "the skin starts {distance:.3e} m from what it touches, inside the contact thickness's {offset:.3e} m: \
         move it apart or give a smaller thickness"
    )]
    TooClose { distance: f64, offset: f64 },
}
