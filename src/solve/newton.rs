//! Newton's method on one patch (PHYSICS.md 2; H15 5.2): projected Hessians, sparse Cholesky,
//! Armijo backtracking (H15 eq. 5.27), quasistatic or implicit Euler (LK14 eq. 5.1 / 5.2).

use glam::DVec3;

use super::contact;
use super::error::{Quantity, SolveError};
use super::eval::{assemble, energy, Assembly, EnergyParts};
use super::iteration::{
    evaluate, factorize_shifted, line_search, mean_abs_diagonal, step, symmetric_product, symmetric_product_into,
    timed, FrameOutcome, FrameStart, Search, MAX_ESCAPES, ROUND_OFF,
};
use super::linear::CholeskySolver;
use super::packed::PackedPatch;
use super::pattern::Pattern;
use super::progress::Progress;
use super::settings::{LinearSolver, Precision, SolveMode, SolverSettings, StabilityTest};
use super::stability::{self, Verdict};
use crate::physics::psd::Filter;
use crate::physics::Projection;

/// Mixed precision: a Newton step is refined until |H dx + g| <= REFINED |g|, with at most
/// MAX_REFINEMENTS conjugate-gradient iterations (an f64 factor solves to ~1e-12).
const REFINED: f64 = 1e-10;
const MAX_REFINEMENTS: u32 = 20;

pub(super) fn newton(
    packed: &mut PackedPatch,
    pattern: &mut Pattern,
    chol: &mut CholeskySolver,
    settings: &SolverSettings,
    dt: f64,
) -> Result<FrameOutcome, SolveError> {
    let n = pattern.n;
    let start = FrameStart::begin(packed, settings, dt);
    let inertia = start.inertia();
    let total = |parts: &EnergyParts, x: &[DVec3]| parts.total() + inertia.as_ref().map_or(0.0, |i| i.energy(x));
    let energy_scale = packed.elements.energy_scale(packed.length_scale);
    let mut it = Loop {
        energy_scale,
        grad: vec![0.0; n],
        values: vec![0.0; pattern.nnz()],
        dx: vec![0.0; n],
        scratch: Vec::new(),
        out: FrameOutcome::default(),
        relisted: false,
        progress: Progress::new(settings.tolerance, settings.projection, energy_scale, packed.length_scale, n),
    };

    loop {
        let filter = it.progress.filter();
        let ms = &mut it.out.counters.contact_ms;
        if std::mem::take(&mut it.relisted) && timed(ms, || contact::fit(packed, pattern)) {
            timed(ms, || contact::reanalyse(chol, pattern, settings));
            it.values.resize(pattern.nnz(), 0.0);
        }
        let mut assembly =
            evaluate(packed, pattern, filter, inertia.as_ref(), &mut it.grad, &mut it.values, &mut it.out);
        let stiffened =
            timed(&mut it.out.counters.contact_ms, || contact::stiffen(packed, pattern, &it.grad, &it.values));
        if stiffened {
            assembly = evaluate(packed, pattern, filter, inertia.as_ref(), &mut it.grad, &mut it.values, &mut it.out);
        }
        let Assembly { parts, force_scale } = assembly;
        let phi = total(&parts, &packed.state.x);
        let gnorm = it.grad.iter().map(|g| g * g).sum::<f64>().sqrt();
        if !phi.is_finite() || !gnorm.is_finite() {
            let quantity = if phi.is_finite() { Quantity::Gradient } else { Quantity::Energy };
            return Err(SolveError::NonFinite { quantity, iterations: it.out.iterations });
        }
        let residual = it.progress.residual(gnorm, force_scale);
        (it.out.energy, it.out.parts, it.out.residual) = (phi, parts, residual);
        if it.progress.first() && it.out.escapes == 0 {
            it.out.start_energy = phi;
        }
        let at = Point { phi, residual, gnorm, filter };
        if it.progress.record(residual) {
            it.out.converged = true;
            let check = settings.stability_check && inertia.is_none() && n > 0 && it.out.escapes < MAX_ESCAPES;
            if check && it.leave(packed, pattern, chol, settings, &at, &total) {
                continue;
            }
            break;
        }
        if it.out.iterations >= settings.max_iterations {
            break;
        }
        // Search direction: H dx = -g. Krylov mode first tries CG preconditioned by the last
        // factor (inexact Newton: relative tolerance min(0.1, sqrt(residual))).
        let krylov = (settings.linear, chol.is_factored() && settings.mode != SolveMode::LinearizedEuler);
        if let (LinearSolver::Krylov { max_iterations }, true) = krylov {
            match it.krylov_step(packed, pattern, chol, (settings, max_iterations), &at, &total) {
                Some(true) => continue,
                Some(false) => break,
                None => {}
            }
        }
        if !it.direct_direction(packed, pattern, chol, settings, &at)? {
            it.progress.projecting = true; // H15: fall back to the projected Hessian
            continue;
        }
        if settings.mode == SolveMode::LinearizedEuler {
            let x0 = packed.state.x.clone();
            step(&mut packed.state.x, &x0, &pattern.dof, &it.dx, 1.0);
            (it.out.iterations, it.out.converged) = (1, true);
            break;
        }
        if !it.line_search(packed, pattern, settings, &at, &total) {
            break;
        }
    }
    start.finish(packed);
    Ok(it.out)
}

/// The unconstrained loop's buffers and record.
struct Loop {
    energy_scale: f64,
    grad: Vec<f64>,
    values: Vec<f64>,
    dx: Vec<f64>,
    /// The shifted Hessian's values when H itself does not factorize.
    scratch: Vec<f64>,
    out: FrameOutcome,
    /// Contact: the pair list changed since the pattern's maps were made (`contact::fit`).
    relisted: bool,
    progress: Progress,
}

/// The iterate: its potential, relative residual, gradient norm and the Hessian filter it was
/// assembled with.
struct Point {
    phi: f64,
    residual: f64,
    gnorm: f64,
    filter: Filter,
}

type Total<'a> = dyn Fn(&EnergyParts, &[DVec3]) -> f64 + 'a;

impl Loop {
    /// Armijo backtracking along `dx` (`iteration::line_search`); false when no step is taken.
    fn line_search(
        &mut self,
        packed: &mut PackedPatch,
        pattern: &Pattern,
        settings: &SolverSettings,
        at: &Point,
        total: &Total,
    ) -> bool {
        let slope: f64 = self.dx.iter().zip(&self.grad).map(|(a, b)| a * b).sum();
        let (phi, residual, scale, tol) = (at.phi, at.residual, self.energy_scale, settings.tolerance);
        let first = timed(&mut self.out.counters.contact_ms, || contact::bound_step(packed, pattern, &self.dx));
        self.relisted |= packed.contact.is_some();
        let search = Search { dx: &self.dx, slope, phi, residual, energy_scale: scale, tolerance: tol, first };
        line_search(packed, pattern, search, total, &mut self.out)
    }

    /// At a converged point, the stability check (`settings.stability_test`): true when the
    /// solve goes on (a saddle left, or an exact step still to settle), false when it stops.
    fn leave(
        &mut self,
        packed: &mut PackedPatch,
        pattern: &Pattern,
        chol: &mut CholeskySolver,
        settings: &SolverSettings,
        at: &Point,
        total: &Total,
    ) -> bool {
        if at.filter != Filter::Exact {
            assemble(&packed.elements, pattern, &packed.state.x, Filter::Exact, &mut self.grad, &mut self.values);
        }
        let energy_at = |x: &[DVec3]| energy(&packed.elements, x).total();
        let settle = self.out.escapes > 0 && self.out.iterations < settings.max_iterations;
        let clock = std::time::Instant::now();
        let (values, scale) = (&self.values, self.energy_scale);
        let left = match settings.stability_test {
            StabilityTest::Inertia | StabilityTest::FactorModes => {
                self.leave_unstable(packed, pattern, chol, (at.phi, settle, settings.stability_test), &energy_at)
            }
            StabilityTest::ShiftedCholesky => leave_saddle(packed, pattern, chol, values, at.phi, scale, &energy_at)
                .map_or(Leave::Stay, Leave::Escape),
        };
        self.out.counters.stability_ms += clock.elapsed().as_secs_f64() * 1e3;
        // (with contact, an escape may not pass the surfaces through each other: one that would
        // is not taken)
        let left = match left {
            Leave::Escape(x) if !contact::clear_path(packed, &packed.state.x, &x) => Leave::Stay,
            other => other,
        };
        match left {
            Leave::Stay => false,
            Leave::Escape(x) => {
                packed.state.x = x;
                self.relisted |= contact::relist(packed);
                self.out.escapes += 1;
                self.out.converged = false;
                self.progress.restart();
                true
            }
            Leave::Settle(dx) => {
                self.out.converged = false;
                self.dx.copy_from_slice(&dx);
                self.line_search(packed, pattern, settings, at, total)
            }
        }
    }

    /// At a converged point: the inertia test of the exact Hessian (`values`) (`stability.rs`); when
    /// unstable, a lower-energy state along its most negative curvature. With `settle` (a saddle
    /// was left this frame), a stable point whose exact Newton step -H^-1 g (from the same LDL^T)
    /// is above SETTLED_STEP is not converged yet. Where the LDL^T breaks down (a zero pivot), the
    /// shifted-Cholesky test decides.
    fn leave_unstable(
        &self,
        packed: &PackedPatch,
        pattern: &Pattern,
        chol: &mut CholeskySolver,
        (phi, settle, how): (f64, bool, StabilityTest),
        energy_at: &dyn Fn(&[DVec3]) -> f64,
    ) -> Leave {
        let (h, grad, energy_scale) = (&self.values, &self.grad, self.energy_scale);
        match stability::test(pattern, chol, h, how) {
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
            None => {
                leave_saddle(packed, pattern, chol, h, phi, energy_scale, energy_at).map_or(Leave::Stay, Leave::Escape)
            }
        }
    }

    /// Krylov mode: CG preconditioned by the last factor, then the line search when it gives a
    /// descent direction: Some(whether a step was taken), None to fall back to a factorization.
    fn krylov_step(
        &mut self,
        packed: &mut PackedPatch,
        pattern: &Pattern,
        chol: &mut CholeskySolver,
        (settings, max_iterations): (&SolverSettings, u32),
        at: &Point,
        total: &Total,
    ) -> Option<bool> {
        let clock = std::time::Instant::now();
        let b: Vec<f64> = self.grad.iter().map(|g| -g).collect();
        let tol = 0.1f64.min(at.residual.sqrt()) * at.gnorm;
        let cg = pcg(pattern, &self.values, chol, &b, &mut self.dx, tol, max_iterations);
        self.out.counters.factorize_ms += clock.elapsed().as_secs_f64() * 1e3;
        self.out.cg_iterations += cg.unwrap_or_else(|e| e);
        if cg.is_ok() {
            let slope: f64 = self.dx.iter().zip(&self.grad).map(|(a, b)| a * b).sum();
            if slope < 0.0 {
                return Some(self.line_search(packed, pattern, settings, at, total));
            }
        }
        None
    }

    /// The direct Newton direction into `dx`: H factorized, its diagonal shifted if it is not
    /// positive definite, solved (refined in f64 under mixed precision); steepest descent where
    /// round-off leaves no descent direction. False when the exact Hessian should give way to
    /// the projected one first (`Projection::Adaptive`).
    fn direct_direction(
        &mut self,
        packed: &PackedPatch,
        pattern: &Pattern,
        chol: &mut CholeskySolver,
        settings: &SolverSettings,
        at: &Point,
    ) -> Result<bool, SolveError> {
        let gnorm = at.gnorm;
        let adaptive = at.filter == Filter::Exact && settings.projection == Projection::Adaptive;
        let clock = std::time::Instant::now();
        let factorized = chol.factorize(pattern, &self.values);
        self.out.counters.factorize_ms += clock.elapsed().as_secs_f64() * 1e3;
        let mut factorized_matrix = &self.values;
        if factorized.is_err() {
            if adaptive {
                return Ok(false);
            }
            self.out.regularized += 1;
            if factorize_shifted(chol, pattern, &self.values, &mut self.scratch, 1e-8, 100.0, 8).is_none() {
                return Err(SolveError::Unfactorizable);
            }
            factorized_matrix = &self.scratch;
        }
        let clock = std::time::Instant::now();
        if chol.precision() == Precision::F32 {
            // Mixed precision: the f32 factor's solve refined in f64 by CG on the matrix it
            // factorizes (one pass of CG from the f32 solve is the first iterate).
            let b: Vec<f64> = self.grad.iter().map(|g| -g).collect();
            let refined = pcg(pattern, factorized_matrix, chol, &b, &mut self.dx, REFINED * gnorm, MAX_REFINEMENTS);
            self.out.cg_iterations += refined.unwrap_or_else(|e| e);
            if self.dx.iter().all(|&d| d == 0.0) {
                // (CG met round-off curvature at once: the f32 solve alone)
                self.dx.copy_from_slice(&b);
                chol.solve(&mut self.dx);
            }
        } else {
            for (d, g) in self.dx.iter_mut().zip(&self.grad) {
                *d = -g;
            }
            chol.solve(&mut self.dx);
        }
        self.out.counters.factorize_ms += clock.elapsed().as_secs_f64() * 1e3;
        let slope: f64 = self.dx.iter().zip(&self.grad).map(|(a, b)| a * b).sum();
        if slope.is_nan() || slope >= 0.0 {
            if adaptive {
                return Ok(false);
            }
            // Not a descent direction (round-off at convergence): fall back to steepest descent.
            let scale = 1.0 / gnorm.max(f64::MIN_POSITIVE) * 1e-6 * packed.length_scale;
            for (d, g) in self.dx.iter_mut().zip(&self.grad) {
                *d = -g * scale;
            }
        }
        Ok(true)
    }
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
