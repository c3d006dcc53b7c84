//! Newton's method on one patch (PHYSICS.md 2; H15 5.2): projected Hessians, sparse Cholesky,
//! Armijo backtracking (H15 eq. 5.27), quasistatic or implicit Euler (LK14 eq. 5.1 / 5.2).

use glam::DVec3;

use super::error::{Quantity, SolveError};
use super::eval::{assemble, energy, Assembly, EnergyParts};
use super::kkt::KktSystem;
use super::linear::CholeskySolver;
use super::packed::PackedPatch;
use super::pattern::{Pattern, NONE};
use super::progress::{Progress, ADAPTIVE_SWITCH};
use super::settings::{LinearSolver, Precision, SolveMode, SolverSettings, StabilityTest};
use super::stability::{self, Verdict};
use crate::physics::psd::Filter;
use crate::physics::Projection;

/// Armijo sufficient-decrease constant.
pub(super) const ARMIJO: f64 = 1e-4;
const MAX_HALVINGS: u32 = 40;
/// Round-off band of an energy sum, relative to its elements' energy at unit strain.
pub(super) const ROUND_OFF: f64 = 1e-13;
/// Saddles left per frame at most.
pub(super) const MAX_ESCAPES: u32 = 4;
/// Mixed precision: a Newton step is refined until |H dx + g| <= REFINED |g|, with at most
/// MAX_REFINEMENTS conjugate-gradient iterations (an f64 factor solves to ~1e-12).
const REFINED: f64 = 1e-10;
const MAX_REFINEMENTS: u32 = 20;

/// What happened in one frame's solve.
#[derive(Clone, Debug, Default)]
pub struct FrameOutcome {
    pub iterations: u32,
    pub converged: bool,
    pub residual: f64,
    pub energy: f64,
    pub parts: EnergyParts,
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
    /// Largest kernel-constraint violation, relative to the patch size (0 without kernels).
    pub constraint_violation: f64,
    /// Energy and constraint violation at the frame's first iterate: after the drivers and any
    /// remesh, before the solve (a remesh "pop" shows as a jump from the previous frame's end).
    pub start_energy: f64,
    pub start_violation: f64,
    /// The merit after each accepted trust-region step (empty with the line search).
    pub merits: Vec<f64>,
    /// Wall time inside the solve (ms): element evaluation and assembly, numeric
    /// factorization and triangular solves (with their f32 refinement), line-search energy
    /// evaluations, the stability test.
    pub counters: SolveCounters,
}

/// Per-frame timers inside Newton (rapier's `counters`).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct SolveCounters {
    pub assemble_ms: f64,
    pub factorize_ms: f64,
    pub line_search_ms: f64,
    /// The stability test at converged points: its factorizations, eigen-solve and escape search.
    pub stability_ms: f64,
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
    pub fn add_to(&self, pattern: &Pattern, x: &[DVec3], grad: &mut [f64], values: &mut [f64]) -> f64 {
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

    pub fn energy(&self, x: &[DVec3]) -> f64 {
        x.iter()
            .zip(self.x_hat)
            .zip(self.mass)
            .map(|((a, b), m)| 0.5 * m * self.inv_h2 * (*a - *b).length_squared())
            .sum()
    }
}

/// Solves one frame in place on `packed.state.x` (prescribed coordinates already at their targets).
/// Returns Err with a reason when the state becomes non-finite.
pub fn solve_frame(packed: &mut PackedPatch, settings: &SolverSettings, dt: f64) -> Result<FrameOutcome, SolveError> {
    let (pattern, mut chol) = match packed.cache.system.take() {
        Some(system) => system,
        None => {
            let p = Pattern::build(&packed.state.x, &packed.state.fixed, &packed.state.tie, &packed.elements);
            let s = CholeskySolver::analyze(&p);
            (p, s)
        }
    };
    if !packed.constraints.is_empty() {
        let mut kkt = match packed.cache.kkt.take() {
            Some(k) => k,
            None => KktSystem::build(&pattern, &packed.constraints, settings.kkt),
        };
        let before = kkt.factorizations;
        let result = super::constrained::newton_kkt(packed, &pattern, &mut kkt, settings, dt).map(|mut o| {
            o.factorizations = (kkt.factorizations - before) as u32;
            o
        });
        packed.cache.kkt = Some(kkt);
        packed.cache.system = Some((pattern, chol));
        return result;
    }
    chol.set_precision(settings.precision);
    let before = chol.factorizations;
    let result = newton(packed, &pattern, &mut chol, settings, dt).map(|mut o| {
        o.factorizations = (chol.factorizations - before) as u32;
        o
    });
    packed.cache.system = Some((pattern, chol));
    result
}

fn newton(
    packed: &mut PackedPatch,
    pattern: &Pattern,
    chol: &mut CholeskySolver,
    settings: &SolverSettings,
    dt: f64,
) -> Result<FrameOutcome, SolveError> {
    let n = pattern.n;
    let start = FrameStart::begin(packed, settings, dt);
    let inertia = start.inertia();
    let total = |parts: &EnergyParts, x: &[DVec3]| parts.total() + inertia.as_ref().map_or(0.0, |i| i.energy(x));

    let energy_scale = packed.elements.energy_scale(packed.length_scale);
    let mut grad = vec![0.0; n];
    let mut values = vec![0.0; pattern.nnz()];
    let mut dx = vec![0.0; n];
    let mut scratch = Vec::new();
    let mut out = FrameOutcome::default();
    let mut progress = Progress::new(settings.tolerance, settings.projection, energy_scale, packed.length_scale, n);

    loop {
        let filter = progress.filter();
        let clock = std::time::Instant::now();
        let Assembly { parts, mut force_scale } =
            assemble(&packed.elements, pattern, &packed.state.x, filter, &mut grad, &mut values);
        out.counters.assemble_ms += clock.elapsed().as_secs_f64() * 1e3;
        if let Some(inr) = &inertia {
            force_scale += inr.add_to(pattern, &packed.state.x, &mut grad, &mut values);
        }
        let phi = total(&parts, &packed.state.x);
        let gnorm = grad.iter().map(|g| g * g).sum::<f64>().sqrt();
        if !phi.is_finite() || !gnorm.is_finite() {
            let quantity = if phi.is_finite() { Quantity::Gradient } else { Quantity::Energy };
            return Err(SolveError::NonFinite { quantity, iterations: out.iterations });
        }
        let residual = progress.residual(gnorm, force_scale);
        out.energy = phi;
        out.parts = parts;
        out.residual = residual;
        if progress.first() && out.escapes == 0 {
            out.start_energy = phi;
        }
        if progress.record(residual) {
            out.converged = true;
            let check = settings.stability_check && inertia.is_none() && n > 0 && out.escapes < MAX_ESCAPES;
            if check {
                if filter != Filter::Exact {
                    assemble(&packed.elements, pattern, &packed.state.x, Filter::Exact, &mut grad, &mut values);
                }
                let energy_at = |x: &[DVec3]| energy(&packed.elements, x).total();
                let settle = out.escapes > 0 && out.iterations < settings.max_iterations;
                let clock = std::time::Instant::now();
                let left = match settings.stability_test {
                    StabilityTest::Inertia => {
                        leave_unstable(packed, pattern, chol, &values, &grad, phi, energy_scale, settle, &energy_at)
                    }
                    StabilityTest::ShiftedCholesky => {
                        leave_saddle(packed, pattern, chol, &values, phi, energy_scale, &energy_at)
                            .map_or(Leave::Stay, Leave::Escape)
                    }
                };
                out.counters.stability_ms += clock.elapsed().as_secs_f64() * 1e3;
                match left {
                    Leave::Stay => {}
                    Leave::Escape(x) => {
                        packed.state.x = x;
                        out.escapes += 1;
                        out.converged = false;
                        progress.restart();
                        continue;
                    }
                    Leave::Settle(dx) => {
                        out.converged = false;
                        let slope: f64 = dx.iter().zip(&grad).map(|(a, b)| a * b).sum();
                        let (tol, total) = (settings.tolerance, &total);
                        if line_search(packed, pattern, &dx, slope, phi, residual, energy_scale, tol, total, &mut out) {
                            continue;
                        }
                    }
                }
            }
            break;
        }
        if out.iterations >= settings.max_iterations {
            break;
        }
        // Search direction: H dx = -g. Krylov mode first tries CG preconditioned by the last
        // factor (inexact Newton: relative tolerance min(0.1, sqrt(residual))).
        let krylov = (settings.linear, chol.is_factored() && settings.mode != SolveMode::LinearizedEuler);
        if let (LinearSolver::Krylov { max_iterations }, true) = krylov {
            let clock = std::time::Instant::now();
            let b: Vec<f64> = grad.iter().map(|g| -g).collect();
            let tol = 0.1f64.min(residual.sqrt()) * gnorm;
            let cg = pcg(pattern, &values, chol, &b, &mut dx, tol, max_iterations);
            out.counters.factorize_ms += clock.elapsed().as_secs_f64() * 1e3;
            out.cg_iterations += cg.unwrap_or_else(|e| e);
            if cg.is_ok() {
                let slope: f64 = dx.iter().zip(&grad).map(|(a, b)| a * b).sum();
                if slope < 0.0 {
                    if line_search(
                        packed,
                        pattern,
                        &dx,
                        slope,
                        phi,
                        residual,
                        energy_scale,
                        settings.tolerance,
                        &total,
                        &mut out,
                    ) {
                        continue;
                    }
                    break;
                }
            }
        }
        // Direct: factorize H, shifting the diagonal if it is not positive definite.
        let clock = std::time::Instant::now();
        let factorized = chol.factorize(pattern, &values);
        out.counters.factorize_ms += clock.elapsed().as_secs_f64() * 1e3;
        let mut factorized_matrix = &values;
        if factorized.is_err() {
            if filter == Filter::Exact && settings.projection == Projection::Adaptive {
                progress.projecting = true; // H15: fall back to the projected Hessian
                continue;
            }
            out.regularized += 1;
            if factorize_shifted(chol, pattern, &values, &mut scratch, 1e-8, 100.0, 8).is_none() {
                return Err(SolveError::Unfactorizable);
            }
            factorized_matrix = &scratch;
        }
        let clock = std::time::Instant::now();
        if chol.precision() == Precision::F32 {
            // Mixed precision: the f32 factor's solve refined in f64 by CG on the matrix it
            // factorizes (one pass of CG from the f32 solve is the first iterate).
            let b: Vec<f64> = grad.iter().map(|g| -g).collect();
            let refined = pcg(pattern, factorized_matrix, chol, &b, &mut dx, REFINED * gnorm, MAX_REFINEMENTS);
            out.cg_iterations += refined.unwrap_or_else(|e| e);
            if dx.iter().all(|&d| d == 0.0) {
                // (CG met round-off curvature at once: the f32 solve alone)
                dx.copy_from_slice(&b);
                chol.solve(&mut dx);
            }
        } else {
            for (d, g) in dx.iter_mut().zip(&grad) {
                *d = -g;
            }
            chol.solve(&mut dx);
        }
        out.counters.factorize_ms += clock.elapsed().as_secs_f64() * 1e3;
        let slope: f64 = dx.iter().zip(&grad).map(|(a, b)| a * b).sum();
        if slope.is_nan() || slope >= 0.0 {
            if filter == Filter::Exact && settings.projection == Projection::Adaptive {
                progress.projecting = true;
                continue;
            }
            // Not a descent direction (round-off at convergence): fall back to steepest descent.
            let scale = 1.0 / gnorm.max(f64::MIN_POSITIVE) * 1e-6 * packed.length_scale;
            for (d, g) in dx.iter_mut().zip(&grad) {
                *d = -g * scale;
            }
        }
        if settings.mode == SolveMode::LinearizedEuler {
            let x0 = packed.state.x.clone();
            step(&mut packed.state.x, &x0, &pattern.dof, &dx, 1.0);
            (out.iterations, out.converged) = (1, true);
            break;
        }
        let slope: f64 = dx.iter().zip(&grad).map(|(a, b)| a * b).sum();
        if !line_search(packed, pattern, &dx, slope, phi, residual, energy_scale, settings.tolerance, &total, &mut out)
        {
            break;
        }
    }
    start.finish(packed);
    Ok(out)
}

/// Armijo backtracking on the total potential along `dx`; counts the iteration. Returns false
/// when no step is accepted (the state is restored; near round-off it counts as converged).
#[allow(clippy::too_many_arguments)]
pub(super) fn line_search(
    packed: &mut PackedPatch,
    pattern: &Pattern,
    dx: &[f64],
    slope: f64,
    phi: f64,
    residual: f64,
    energy_scale: f64,
    tolerance: f64,
    total: &dyn Fn(&EnergyParts, &[DVec3]) -> f64,
    out: &mut FrameOutcome,
) -> bool {
    let clock = std::time::Instant::now();
    let x0 = packed.state.x.clone();
    let mut alpha = 1.0;
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
    accepted
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

/// Preconditioned conjugate gradients on H x = b (x starts at 0), M^-1 = the factor in `chol`.
/// Ok(iterations) when |r| <= tol; Err(iterations) on negative curvature or no convergence.
fn pcg(
    pattern: &Pattern,
    h: &[f64],
    chol: &mut CholeskySolver,
    b: &[f64],
    x: &mut [f64],
    tol: f64,
    max_iterations: u32,
) -> Result<u32, u32> {
    x.iter_mut().for_each(|v| *v = 0.0);
    let mut r = b.to_vec();
    let mut z = r.clone();
    chol.solve(&mut z);
    let mut p = z.clone();
    let mut rz: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
    let mut hp = vec![0.0; b.len()];
    for it in 1..=max_iterations {
        symmetric_product_into(pattern, h, &p, &mut hp);
        let php: f64 = p.iter().zip(&hp).map(|(a, b)| a * b).sum();
        // (a NaN counts as negative curvature)
        if php.is_nan() || php <= 0.0 {
            return Err(it);
        }
        let alpha = rz / php;
        x.iter_mut().zip(&p).for_each(|(xi, pi)| *xi += alpha * pi);
        r.iter_mut().zip(&hp).for_each(|(ri, hi)| *ri -= alpha * hi);
        if r.iter().map(|v| v * v).sum::<f64>().sqrt() <= tol {
            return Ok(it);
        }
        z.copy_from_slice(&r);
        chol.solve(&mut z);
        let rz_new: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
        let beta = rz_new / rz;
        rz = rz_new;
        p.iter_mut().zip(&z).for_each(|(pi, zi)| *pi = zi + beta * *pi);
    }
    Err(max_iterations)
}

/// What the stability check does at a converged point.
enum Leave {
    /// Accept it.
    Stay,
    /// Leave an unstable equilibrium for this lower-energy state.
    Escape(Vec<DVec3>),
    /// Not yet converged: take this exact Newton step.
    Settle(Vec<f64>),
}

/// After leaving an unstable equilibrium: the largest exact Newton step (of the patch size) at
/// convergence. Near a bifurcation the buckling mode's force is far below the membrane force
/// scale, so the residual test alone stops on the way to the buckled state (the Euler strip
/// just past its critical load: at 65 % of the amplitude, 1.06 P_cr).
const SETTLED_STEP: f64 = 1e-7;

/// At a converged point: the inertia test of the exact Hessian `h` (`stability.rs`); when
/// unstable, a lower-energy state along its most negative curvature. With `settle` (a saddle
/// was left this frame), a stable point whose exact Newton step -H^-1 g (from the same LDL^T)
/// is above SETTLED_STEP is not converged yet. Where the LDL^T breaks down (a zero pivot), the
/// shifted-Cholesky test decides.
#[allow(clippy::too_many_arguments)]
fn leave_unstable(
    packed: &PackedPatch,
    pattern: &Pattern,
    chol: &mut CholeskySolver,
    h: &[f64],
    grad: &[f64],
    phi: f64,
    energy_scale: f64,
    settle: bool,
    energy_at: &dyn Fn(&[DVec3]) -> f64,
) -> Leave {
    match stability::test(pattern, chol, h) {
        Some(Verdict::Stable) if settle => {
            let mut dx: Vec<f64> = grad.iter().map(|g| -g).collect();
            chol.solve_ldl(&mut dx);
            if max_abs(&dx) > SETTLED_STEP * packed.length_scale {
                Leave::Settle(dx)
            } else {
                Leave::Stay
            }
        }
        Some(Verdict::Stable) => Leave::Stay,
        Some(Verdict::Unstable { direction, .. }) => {
            stability::escape(&packed.state.x, &pattern.dof, &direction, phi, packed.length_scale, energy_at)
                .map_or(Leave::Stay, Leave::Escape)
        }
        None => leave_saddle(packed, pattern, chol, h, phi, energy_scale, energy_at).map_or(Leave::Stay, Leave::Escape),
    }
}

/// The shifted-Cholesky test (`StabilityTest::ShiftedCholesky`): if the exact Hessian `h` is
/// indefinite, returns a lower-energy state along its most negative curvature direction
/// (shifted inverse iteration with a Cholesky of
/// H + sigma I, then a search over the step length and sign); None at a stable equilibrium.
fn leave_saddle(
    packed: &PackedPatch,
    pattern: &Pattern,
    chol: &mut CholeskySolver,
    h: &[f64],
    phi: f64,
    energy_scale: f64,
    energy_at: &dyn Fn(&[DVec3]) -> f64,
) -> Option<Vec<DVec3>> {
    if chol.factorize(pattern, h).is_ok() {
        return None;
    }
    let n = pattern.n;
    let mean_diag = mean_abs_diagonal(pattern, h);
    // Inverse iteration amplifies the eigenvector whose eigenvalue is nearest the shift.
    let inverse_iteration = |chol: &mut CholeskySolver| {
        let mut y: Vec<f64> = (0..n).map(|i| ((i as f64 + 1.0) * 12.9898).sin().fract() - 0.5).collect();
        for _ in 0..16 {
            chol.solve(&mut y);
            let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt();
            y.iter_mut().for_each(|v| *v /= norm);
        }
        let hy = symmetric_product(pattern, h, &y);
        let curvature: f64 = y.iter().zip(&hy).map(|(a, b)| a * b).sum();
        (curvature < -1e-9 * mean_diag).then_some(y)
    };
    // Shifted Cholesky factorizations of H + sigma I until positive definite: inverse iteration
    // then finds the most negative curvature (the fastest-growing mode; an LDL^T of H itself
    // picked other modes: `README.md`).
    factorize_shifted(chol, pattern, h, &mut Vec::new(), 1e-6, 4.0, 14)?;
    let y = inverse_iteration(chol)?;
    // Step along +-y, scaled so the largest displacement is t, growing t while energy falls.
    let max = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let noise = ROUND_OFF * energy_scale;
    let mut best: Option<(f64, Vec<DVec3>)> = None;
    for sign in [1.0, -1.0] {
        let mut t = 1e-5 * packed.length_scale;
        for _ in 0..10 {
            let mut x = packed.state.x.clone();
            step(&mut x, &packed.state.x, &pattern.dof, &y, sign * t / max);
            let e = energy_at(&x);
            // (a NaN energy ends the search too)
            if e.is_nan() || e >= phi - noise {
                break;
            }
            if best.as_ref().is_none_or(|b| e < b.0) {
                best = Some((e, x));
            }
            t *= 3.0;
        }
    }
    best.map(|b| b.1)
}

fn mean_abs_diagonal(pattern: &Pattern, h: &[f64]) -> f64 {
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
fn symmetric_product(pattern: &Pattern, values: &[f64], x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; pattern.n];
    symmetric_product_into(pattern, values, x, &mut y);
    y
}

/// y = H x into a caller's buffer (the CG loop).
fn symmetric_product_into(pattern: &Pattern, values: &[f64], x: &[f64], y: &mut [f64]) {
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
