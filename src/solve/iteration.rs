//! The pieces every Newton loop of a frame shares (`newton`, `constrained`, `trust_region`,
//! `stability`): the frame's start and outcome, the inertia term, the step and its Armijo line
//! search, the shifted factorization, the correction back onto the kernels, and the constants.

use glam::DVec3;

use super::constraints::Constraints;
use super::eval::{assemble, energy, Assembly, EnergyParts};
use super::kkt::KktSystem;
use super::linear::CholeskySolver;
use super::packed::PackedPatch;
use super::pattern::{Pattern, NONE};
use super::progress::ADAPTIVE_SWITCH;
use super::settings::SolverSettings;
use crate::physics::psd::Filter;

/// Armijo sufficient-decrease constant.
pub(super) const ARMIJO: f64 = 1e-4;
const MAX_HALVINGS: u32 = 40;
/// Round-off band of an energy sum, relative to its elements' energy at unit strain.
pub(super) const ROUND_OFF: f64 = 1e-13;
/// Saddles left per frame at most.
pub(super) const MAX_ESCAPES: u32 = 4;
/// What happened in one frame's solve: the columns of a patch's report in `stats.jsonl`
/// (serialized under those names).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct FrameOutcome {
    #[serde(rename = "newton_iterations")]
    pub iterations: u32,
    pub converged: bool,
    /// Final gradient norm over free DOFs divided by the internal force scale.
    pub residual: f64,
    /// Total energy (J): elastic + springs (+ inertia term in dynamic mode).
    pub energy: f64,
    #[serde(flatten)]
    pub parts: EnergyParts,
    /// Factorizations that needed a diagonal shift.
    pub regularized: u32,
    pub line_search_failures: u32,
    /// Times the solve left an unstable equilibrium along negative curvature.
    pub escapes: u32,
    /// Full steps under a held load taken back because the energy rose past their quadratic
    /// model (`constrained`; each counted in `iterations`).
    pub unmodelled_steps: u32,
    /// Numeric Cholesky factorizations, and conjugate-gradient iterations (Krylov mode).
    pub factorizations: u32,
    pub cg_iterations: u32,
    /// LK14 kernels: constraint rows.
    pub constraints: usize,
    /// Largest kernel-constraint violation, relative to the patch size (0 without kernels).
    pub constraint_violation: f64,
    /// Energy and constraint violation at the frame's first iterate: after the drivers and any
    /// remesh, before the solve (a remesh "pop" shows as a jump from the previous frame's end).
    pub start_energy: f64,
    pub start_violation: f64,
    /// Tetrahedra with non-positive volume at the end of the frame (models that allow inversion).
    pub inverted: usize,
    /// Barrier contact (a patch with `contact`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact: Option<crate::contact::ContactReport>,
    /// The merit after each accepted trust-region step (empty with the line search).
    #[serde(skip)]
    pub merits: Vec<f64>,
    /// Wall time inside the solve (ms): element evaluation and assembly, numeric
    /// factorization and triangular solves (with their f32 refinement), line-search energy
    /// evaluations, the stability test, contact's broad phases and collision bounds.
    #[serde(rename = "solve_breakdown_ms")]
    pub counters: SolveCounters,
}

impl FrameOutcome {
    /// Adds a later solve of the same frame (contact's substeps): counts and timers add up, the
    /// end state's figures are the later solve's, the start's this one's.
    pub(crate) fn absorb(&mut self, next: FrameOutcome) {
        let first = self.iterations == 0 && self.factorizations == 0;
        let (start_energy, start_violation) = (self.start_energy, self.start_violation);
        let sum = |a: u32, b: u32| a + b;
        let mut out = FrameOutcome {
            iterations: sum(self.iterations, next.iterations),
            regularized: sum(self.regularized, next.regularized),
            line_search_failures: sum(self.line_search_failures, next.line_search_failures),
            escapes: sum(self.escapes, next.escapes),
            unmodelled_steps: sum(self.unmodelled_steps, next.unmodelled_steps),
            factorizations: sum(self.factorizations, next.factorizations),
            cg_iterations: sum(self.cg_iterations, next.cg_iterations),
            counters: SolveCounters {
                assemble_ms: self.counters.assemble_ms + next.counters.assemble_ms,
                factorize_ms: self.counters.factorize_ms + next.counters.factorize_ms,
                line_search_ms: self.counters.line_search_ms + next.counters.line_search_ms,
                stability_ms: self.counters.stability_ms + next.counters.stability_ms,
                contact_ms: self.counters.contact_ms + next.counters.contact_ms,
            },
            ..next
        };
        if !first {
            (out.start_energy, out.start_violation) = (start_energy, start_violation);
        }
        *self = out;
    }
}

/// Per-frame timers inside Newton (rapier's `counters`).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct SolveCounters {
    pub assemble_ms: f64,
    pub factorize_ms: f64,
    pub line_search_ms: f64,
    /// The stability test at converged points: its factorizations, eigen-solve and escape search.
    pub stability_ms: f64,
    /// Contact's work besides the energy: broad phases, the collision bound on each step, the
    /// pair list's scatter maps (or a new pattern and its analysis), the barrier stiffness.
    pub contact_ms: f64,
}

/// Runs `f`, adding its wall time to `ms`.
pub(super) fn timed<T>(ms: &mut f64, f: impl FnOnce() -> T) -> T {
    let clock = std::time::Instant::now();
    let out = f();
    *ms += clock.elapsed().as_secs_f64() * 1e3;
    out
}

/// The implicit-Euler predictor x_n + h v_n (prescribed coordinates stay); empty when quasistatic.
fn predictor(packed: &PackedPatch, dynamic: bool, dt: f64) -> Vec<DVec3> {
    if !dynamic {
        return Vec::new();
    }
    packed
        .state
        .x
        .iter()
        .zip(&packed.state.v)
        .zip(&packed.state.fixed)
        .map(|((x, v), f)| {
            let mut p = *x + *v * dt;
            for k in 0..3 {
                if f[k] {
                    p[k] = x[k];
                }
            }
            p
        })
        .collect()
}

/// What a frame's solve starts from (both solvers): the positions at its start and, in the
/// implicit-Euler mode, the predictor and the masses of the inertia term.
pub(super) struct FrameStart {
    dynamic: bool,
    dt: f64,
    x_n: Vec<DVec3>,
    x_hat: Vec<DVec3>,
    mass: Vec<f64>,
}

impl FrameStart {
    /// Syncs ties and, when dynamic, moves the state to the predictor.
    pub(super) fn begin(packed: &mut PackedPatch, settings: &SolverSettings, dt: f64) -> FrameStart {
        packed.state.sync_ties();
        let dynamic = settings.mode.is_dynamic();
        let x_n = packed.state.x.clone();
        let x_hat = predictor(packed, dynamic, dt);
        if dynamic {
            packed.state.x.copy_from_slice(&x_hat);
        }
        // (a copy: the line search mutates the state)
        let mass = if dynamic { packed.state.mass.clone() } else { Vec::new() };
        FrameStart { dynamic, dt, x_n, x_hat, mass }
    }

    pub(super) fn inertia(&self) -> Option<Inertia<'_>> {
        self.dynamic.then(|| Inertia { x_hat: &self.x_hat, mass: &self.mass, inv_h2: 1.0 / (self.dt * self.dt) })
    }

    /// Implicit Euler: the velocities of the step taken.
    pub(super) fn finish(&self, packed: &mut PackedPatch) {
        if self.dynamic {
            for ((v, x), x0) in packed.state.v.iter_mut().zip(&packed.state.x).zip(&self.x_n) {
                *v = (*x - *x0) / self.dt;
            }
        }
    }
}

/// The incremental potential's inertia term: sum m / (2 h^2) |x - x_hat|^2 (LK14 eq. 5.2).
pub(super) struct Inertia<'a> {
    pub x_hat: &'a [DVec3],
    pub mass: &'a [f64],
    pub inv_h2: f64,
}

impl Inertia<'_> {
    /// Adds the inertia gradient and mass diagonal; returns the sum of the inertial forces.
    pub(crate) fn add_to(&self, pattern: &Pattern, x: &[DVec3], grad: &mut [f64], values: &mut [f64]) -> f64 {
        let mut total = 0.0;
        for (v, ((x, xh), m)) in x.iter().zip(self.x_hat).zip(self.mass).enumerate() {
            let f = (*x - *xh) * (m * self.inv_h2);
            total += f.length();
            for k in 0..3 {
                let d = pattern.dof[3 * v + k];
                if d != NONE {
                    grad[d as usize] += f[k];
                    values[pattern.diag[d as usize] as usize] += m * self.inv_h2;
                }
            }
        }
        total
    }

    pub(super) fn energy(&self, x: &[DVec3]) -> f64 {
        x.iter()
            .zip(self.x_hat)
            .zip(self.mass)
            .map(|((a, b), m)| 0.5 * m * self.inv_h2 * (*a - *b).length_squared())
            .sum()
    }
}

/// Assembles the elastic energy, gradient and Hessian at the state (timed) and adds the
/// inertia term's (implicit Euler) to them and to the force scale.
pub(super) fn evaluate(
    packed: &PackedPatch,
    pattern: &Pattern,
    filter: Filter,
    inertia: Option<&Inertia>,
    grad: &mut [f64],
    values: &mut [f64],
    out: &mut FrameOutcome,
) -> Assembly {
    let clock = std::time::Instant::now();
    let mut a = assemble(&packed.elements, pattern, &packed.state.x, filter, grad, values);
    out.counters.assemble_ms += clock.elapsed().as_secs_f64() * 1e3;
    if let Some(inr) = inertia {
        a.force_scale += inr.add_to(pattern, &packed.state.x, grad, values);
    }
    a
}

/// What a line search starts from: the step `dx` over free DOFs, the potential's slope along
/// it, the potential `phi` and the relative residual at the iterate; the energy's round-off
/// scale (`Elements::energy_scale`) and the solve's tolerance.
pub(super) struct Search<'a> {
    pub dx: &'a [f64],
    pub slope: f64,
    pub phi: f64,
    pub residual: f64,
    pub energy_scale: f64,
    pub tolerance: f64,
    /// The first step length tried: 1, or less where contact's collision test bounds it.
    pub first: f64,
}

/// Armijo backtracking on the total potential along `dx`; counts the iteration. Returns false
/// when no step is accepted (the state is restored; near round-off it counts as converged).
pub(super) fn line_search(
    packed: &mut PackedPatch,
    pattern: &Pattern,
    search: Search,
    total: &dyn Fn(&EnergyParts, &[DVec3]) -> f64,
    out: &mut FrameOutcome,
) -> bool {
    search_step(packed, pattern, search, total, out).is_some()
}

/// `line_search`, returning the fraction of `dx` accepted.
pub(super) fn search_step(
    packed: &mut PackedPatch,
    pattern: &Pattern,
    search: Search,
    total: &dyn Fn(&EnergyParts, &[DVec3]) -> f64,
    out: &mut FrameOutcome,
) -> Option<f64> {
    let Search { dx, slope, phi, residual, energy_scale, tolerance, first } = search;
    let clock = std::time::Instant::now();
    let x0 = packed.state.x.clone();
    let mut alpha = first;
    let mut accepted = false;
    // Near the solution the decrease can fall below the energy's round-off: there a full
    // Newton step is accepted if the energy stays within that band.
    let noise = ROUND_OFF * energy_scale;
    for i in 0..MAX_HALVINGS {
        step(&mut packed.state.x, &x0, &pattern.dof, dx, alpha);
        let trial = total(&energy(&packed.elements, &packed.state.x), &packed.state.x);
        let armijo = trial <= phi + ARMIJO * alpha * slope;
        let flat = i == 0 && residual < ADAPTIVE_SWITCH && trial <= phi + noise;
        if trial.is_finite() && (armijo || flat) {
            accepted = true;
            break;
        }
        alpha *= 0.5;
    }
    out.counters.line_search_ms += clock.elapsed().as_secs_f64() * 1e3;
    out.iterations += 1;
    tracing::debug!(iteration = out.iterations, residual, alpha, slope, phi, accepted, "newton");
    if !accepted {
        out.line_search_failures += 1;
        packed.state.x.copy_from_slice(&x0);
        // At round-off level no decrease is measurable: accept a near-converged state.
        if residual <= 1e3 * tolerance {
            out.converged = true;
        }
    }
    accepted.then_some(alpha)
}

pub(super) fn mean_abs_diagonal(pattern: &Pattern, h: &[f64]) -> f64 {
    pattern.diag.iter().map(|&d| h[d as usize].abs()).sum::<f64>() / pattern.n.max(1) as f64
}

/// Factorizes H + sigma I for the smallest sigma = first x mean|diag| x growth^k (k < tries)
/// that is positive definite; the shifted values go to `scratch`. Returns sigma.
pub(super) fn factorize_shifted(
    chol: &mut CholeskySolver,
    pattern: &Pattern,
    h: &[f64],
    scratch: &mut Vec<f64>,
    first: f64,
    growth: f64,
    tries: u32,
) -> Option<f64> {
    let mut sigma = first * mean_abs_diagonal(pattern, h).max(f64::MIN_POSITIVE);
    for _ in 0..tries {
        scratch.clear();
        scratch.extend_from_slice(h);
        for &d in &pattern.diag {
            scratch[d as usize] += sigma;
        }
        if chol.factorize(pattern, scratch).is_ok() {
            return Some(sigma);
        }
        sigma *= growth;
    }
    None
}

/// y = H x for the symmetric matrix whose lower triangle is stored in the pattern.
pub(super) fn symmetric_product(pattern: &Pattern, values: &[f64], x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; pattern.n];
    symmetric_product_into(pattern, values, x, &mut y);
    y
}

/// y = H x into a caller's buffer (the CG loop).
pub(super) fn symmetric_product_into(pattern: &Pattern, values: &[f64], x: &[f64], y: &mut [f64]) {
    super::linear::symmetric_product_into(&pattern.col_ptr, &pattern.row_idx, values, x, y);
}

pub(super) fn step(x: &mut [DVec3], x0: &[DVec3], dof: &[u32], dx: &[f64], alpha: f64) {
    for (v, (p, p0)) in x.iter_mut().zip(x0).enumerate() {
        for k in 0..3 {
            let d = dof[3 * v + k];
            p[k] = if d == NONE { p0[k] } else { p0[k] + alpha * dx[d as usize] };
        }
    }
}
/// The full step `dx` from `x0` plus a correction back onto the constraints (one more solve with
/// the last factorization): true when its merit is at most `target` (the state moved), false
/// with the state back at `x0`.
#[allow(clippy::too_many_arguments)]
pub(super) fn correction(
    packed: &mut PackedPatch,
    pattern: &Pattern,
    kkt: &mut KktSystem,
    constraints: &Constraints,
    x0: &[DVec3],
    dx: &[f64],
    target: f64,
    merit: &dyn Fn(&EnergyParts, &[DVec3]) -> f64,
) -> bool {
    if !constraints.is_empty() {
        step(&mut packed.state.x, x0, &pattern.dof, dx, 1.0);
        let c: Vec<f64> = constraints.values(&packed.state.x).iter().flat_map(|v| v.to_array()).collect();
        let mut correction = vec![0.0; dx.len()];
        if kkt.correct(&c, &mut correction).is_ok() {
            let corrected: Vec<f64> = dx.iter().zip(&correction).map(|(a, b)| a + b).collect();
            step(&mut packed.state.x, x0, &pattern.dof, &corrected, 1.0);
            let value = merit(&energy(&packed.elements, &packed.state.x), &packed.state.x);
            if value.is_finite() && value <= target {
                tracing::trace!("second-order correction taken");
                return true;
            }
        }
    }
    packed.state.x.copy_from_slice(x0);
    false
}
