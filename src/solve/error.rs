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

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SolveError {
    #[error("non-finite {quantity} after {iterations} Newton iterations")]
    NonFinite { quantity: Quantity, iterations: u32 },
    #[error("the Hessian could not be factorized even with a diagonal shift")]
    Unfactorizable,
    #[error("the constrained Newton system has no descent direction after {iterations} iterations")]
    NoDescent { iterations: u32 },
    #[error("prescribed vertices could not reach their targets without passing through the skin ({substeps} solves)")]
    Blocked { substeps: u32 },
    #[error(
        "the skin starts {distance:.3e} m from what it touches, inside the contact thickness's {offset:.3e} m: \
         move it apart or give a smaller thickness"
    )]
    TooClose { distance: f64, offset: f64 },
}
