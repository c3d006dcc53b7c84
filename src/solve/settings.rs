//! The solver's own settings: how Newton runs on a patch, when it stops, and how its linear
//! systems are solved. The scene's `solver` block (`scene::schema::SolverSpec`) converts into
//! these; the enums are also the scene format (as `physics::Projection` is).

use bevy_ecs::prelude::*;
use serde::{Deserialize, Serialize};

use crate::physics::Projection;

/// A patch's solver settings (a component on the patch entity).
#[derive(Component, Clone, Debug, PartialEq)]
pub struct SolverSettings {
    pub mode: SolveMode,
    /// Converged when |grad| <= tolerance x (internal force scale).
    pub tolerance: f64,
    pub max_iterations: u32,
    pub projection: Projection,
    /// Quasistatic mode: at convergence, test the exact Hessian; at an unstable equilibrium
    /// (a saddle: the flat state past the buckling load) leave it along negative curvature.
    pub stability_check: bool,
    pub stability_test: StabilityTest,
    pub globalization: Globalization,
    pub linear: LinearSolver,
    pub precision: Precision,
    pub kkt: KktMethod,
}

impl Default for SolverSettings {
    fn default() -> Self {
        SolverSettings {
            mode: SolveMode::Quasistatic,
            tolerance: 1e-8,
            max_iterations: 50,
            projection: Projection::default(),
            stability_check: true,
            stability_test: StabilityTest::default(),
            globalization: Globalization::default(),
            linear: LinearSolver::Direct,
            precision: Precision::default(),
            kkt: KktMethod::default(),
        }
    }
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq, Default)]
pub enum SolveMode {
    /// Equilibrium at every frame (LK14 eq. 5.1, H15 chapter 5).
    #[default]
    Quasistatic,
    /// Implicit Euler in optimization form (LK14 eq. 5.2), time step = frame_time: Newton on
    /// the incremental potential to the tolerance.
    ImplicitEuler,
    /// LK14's own velocity-based scheme (eq. 5.2 as ARCSim solves it): one linearized implicit
    /// Euler step per frame, the full Newton step of the incremental potential from the
    /// predictor x + h v (one factorization, no line search). Converged by construction: the
    /// residual reported is the one the step started from.
    LinearizedEuler,
}

impl SolveMode {
    /// Whether the frame is a time step (an inertia term and velocities).
    pub(crate) fn is_dynamic(self) -> bool {
        self != SolveMode::Quasistatic
    }
}

/// How the stability check tests an equilibrium and finds the way off an unstable one.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq, Default)]
pub enum StabilityTest {
    /// The inertia of one LDL^T of the exact Hessian (exact: no curvature threshold); the
    /// escape along the most negative curvature from LOBPCG preconditioned by that factor.
    #[default]
    Inertia,
    /// The test before issue 21, kept for comparison: a Cholesky of H, then Cholesky
    /// factorizations of H + sigma I (sigma x4 from 1e-6 mean |diag|) and inverse iteration;
    /// misses curvatures above -1e-9 mean |diag| (just past a critical load).
    ShiftedCholesky,
    /// The inertia as `Inertia`; the escape along the most negative curvature in the span of
    /// the factor's own negative-pivot directions (`CholeskySolver::negative_pivot_directions`:
    /// one solve each, no eigen-solver; issue 67 item 6). LOBPCG as `Inertia` only where they
    /// show no curvature above round-off.
    FactorModes,
}

/// How a Newton step is made safe where the Hessian is indefinite (buckling): the step's
/// length and the inertia-correcting shift.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq, Default)]
pub enum Globalization {
    /// The smallest shift of a x10 ladder (from a third of the last one) that makes the system
    /// definite on the constraints' null space, then Armijo backtracking (H15 eq. 5.27).
    #[default]
    LineSearch,
    /// A trust region on the kernel-constrained (KKT) step (More-Sorensen): the shift at least
    /// the inertia bound and large enough that the step stays within the radius, the radius
    /// sized by the ratio of actual to predicted merit decrease. Patches without kernels use
    /// the line search.
    TrustRegion,
}

/// How Newton solves H dx = -g.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq, Default)]
pub enum LinearSolver {
    /// A sparse Cholesky factorization of every Newton Hessian.
    #[default]
    Direct,
    /// Preconditioned conjugate gradients, the preconditioner an earlier Cholesky factor (of an
    /// earlier iteration or frame); a fresh factorization only when CG does not converge in
    /// `max_iterations` or meets negative curvature. Pays off when factorizing dominates (large
    /// 3D patches).
    Krylov { max_iterations: u32 },
}

/// The arithmetic of the Newton Hessian's Cholesky factor (patches without kernels; the KKT
/// systems of patches with kernels stay f64: `README.md`). Matrices, gradients and solutions
/// are f64 either way.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq, Default)]
pub enum Precision {
    #[default]
    F64,
    /// Mixed precision: the factor in f32 (half the memory and about half the flops' time on
    /// SIMD), each Newton step refined in f64 by conjugate gradients preconditioned by it. The
    /// stability test's inertia stays an f64 LDL^T (its verdict reads the signs of pivots).
    F32,
}

/// How the constrained (KKT) system of a patch with kernels is solved (LK14 eq. 5.1; `kkt`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum KktMethod {
    /// One sparse LDL^T of the whole KKT matrix, with inertia correction.
    #[default]
    Ldlt,
    /// The Cholesky of the Hessian and the dense Schur complement on the constraint rows.
    Schur,
}
