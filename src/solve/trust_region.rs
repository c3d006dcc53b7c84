//! The trust-region step of the kernel-constrained Newton (`Globalization::TrustRegion`; issue
//! 21): More-Sorensen on the KKT factorization. The step is p(mu) from
//! `[[H + mu W, J^T], [J, 0]] [p; lambda] = [-g; -c]` (W the shift metric of `kkt.rs`), with mu
//! at least the inertia bound (the KKT matrix definite on the null space of J) and, when p(mu)
//! is longer than the radius Delta in the W-norm, raised by Newton's method on the secular
//! equation 1/|p(mu)| = 1/Delta (its derivative from one more solve with the same factor,
//! d|p|^2/dmu = -2 mean p^T W K^-1 [W p; 0]). Delta follows the ratio of the actual to the
//! predicted decrease of the l1 merit function Phi + rho |c|_1.

use glam::DVec3;

use super::constraints::Constraints;
use super::error::SolveError;
use super::eval::{energy, EnergyParts};
use super::iteration::{correction, step, FrameOutcome};
use super::kkt::{KktPoint, KktSystem};
use super::packed::PackedPatch;
use super::pattern::Pattern;
use super::progress::ADAPTIVE_SWITCH;

/// Accept a step whose actual decrease is at least this fraction of the predicted one.
const ETA: f64 = 1e-4;
/// Shrink Delta below this ratio, grow it above GOOD when the step reached the boundary.
const POOR: f64 = 0.25;
const GOOD: f64 = 0.5;
/// A step within this fraction of Delta counts as on the boundary.
const BOUNDARY: f64 = 0.2;
/// Secular-equation refactorizations per trial at most; a step still too long is then cut
/// back to Delta.
const SECULAR_STEPS: u32 = 2;
/// Rejected trials per iteration at most.
const MAX_TRIALS: u32 = 8;
/// Round-off band of an energy sum, relative to its elements' energy at unit strain (as the
/// line search's).
const ROUND_OFF: f64 = 1e-13;

/// A frame's trust region.
pub(super) struct TrustRegion {
    /// The radius in the W-norm (m); infinite until a step is rejected or predicted badly.
    pub radius: f64,
}

/// What one trust-region iteration needs from the constrained Newton loop.
pub(super) struct Iterate<'a> {
    pub point: KktPoint<'a>,
    pub constraints: &'a Constraints,
    /// The objective Phi (without the penalty) at the iterate, and its residual.
    pub phi: f64,
    pub residual: f64,
    pub energy_scale: f64,
}

impl TrustRegion {
    pub(super) fn new() -> Self {
        TrustRegion { radius: f64::INFINITY }
    }

    /// One iteration: moves `packed.state.x` to an accepted point and returns true, with
    /// `lambda` the new multipliers and `rho` the penalty; false when no trial was accepted
    /// (the state is unchanged). Every trial counts as a Newton iteration.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn step(
        &mut self,
        packed: &mut PackedPatch,
        pattern: &Pattern,
        kkt: &mut KktSystem,
        it: &Iterate,
        objective: &dyn Fn(&EnergyParts, &[DVec3]) -> f64,
        lambda: &mut [f64],
        rho: &mut f64,
        out: &mut FrameOutcome,
    ) -> Result<bool, SolveError> {
        let n = pattern.n;
        let (w, mean) = kkt.shift_weights(pattern, it.point.h);
        let wnorm = |p: &[f64]| p.iter().zip(&w).map(|(a, b)| b * a * a).sum::<f64>().sqrt();
        let c_l1: f64 = it.point.c.iter().map(|v| v.abs()).sum();
        let noise = ROUND_OFF * it.energy_scale;
        let (mut p, mut q, mut hp) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut shift = kkt.first_shift();
        let x0 = packed.state.x.clone();
        for _ in 0..MAX_TRIALS {
            // The inertia bound, then the secular equation.
            let mut secular = 0;
            loop {
                let clock = std::time::Instant::now();
                let solved = kkt.step_shifted(pattern, &it.point, &mut p, lambda, shift);
                out.counters.factorize_ms += clock.elapsed().as_secs_f64() * 1e3;
                if solved.is_err() {
                    shift = kkt.raise(shift).ok_or(SolveError::NoDescent { iterations: out.iterations })?;
                    continue;
                }
                let norm = wnorm(&p);
                if norm <= (1.0 + BOUNDARY) * self.radius || secular >= SECULAR_STEPS {
                    break;
                }
                let wp: Vec<f64> = p.iter().zip(&w).map(|(a, b)| a * b).collect();
                if kkt.solve_null(&wp, &mut q).is_err() {
                    break;
                }
                let pwq: f64 = wp.iter().zip(&q).map(|(a, b)| a * b).sum();
                if pwq.is_nan() || pwq <= 0.0 {
                    break;
                }
                // Newton on 1/|p(mu)| = 1/Delta (More & Sorensen 1983).
                shift += (norm / self.radius - 1.0) * norm * norm / (mean * pwq);
                secular += 1;
            }
            let norm = wnorm(&p);
            let scale = if norm > (1.0 + BOUNDARY) * self.radius { self.radius / norm } else { 1.0 };
            // The model's decrease: -(g.s + s^2/2 p^T H p) + rho s |c|_1 (J p = -c).
            super::linear::symmetric_product_into(&pattern.col_ptr, &pattern.row_idx, it.point.h, &p, &mut hp);
            let gp: f64 = p.iter().zip(it.point.grad).map(|(a, b)| a * b).sum();
            let php: f64 = p.iter().zip(&hp).map(|(a, b)| a * b).sum();
            let model = scale * gp + 0.5 * scale * scale * php;
            *rho = rho.max(2.0 * lambda.iter().fold(0.0f64, |a, l| a.max(l.abs())));
            if c_l1 > 0.0 && model > 0.0 {
                // The penalty must outweigh a model rise for the step to be predicted a
                // decrease (with margin 2).
                *rho = rho.max(2.0 * model / (scale * c_l1));
            }
            let predicted = -model + *rho * scale * c_l1;
            let merit0 = it.phi + *rho * c_l1;
            let clock = std::time::Instant::now();
            step(&mut packed.state.x, &x0, &pattern.dof, &p, scale);
            let trial = objective(&energy(&packed.elements, &packed.state.x), &packed.state.x)
                + *rho * it.constraints.violation_l1(&packed.state.x);
            out.counters.line_search_ms += clock.elapsed().as_secs_f64() * 1e3;
            out.iterations += 1;
            let ratio = (merit0 - trial) / predicted;
            let flat = it.residual < ADAPTIVE_SWITCH && scale == 1.0 && trial <= merit0 + noise;
            let mut accepted = trial.is_finite() && ((predicted > 0.0 && ratio >= ETA) || flat);
            if !accepted && scale == 1.0 && predicted > 0.0 {
                // The Maratos effect (as the line search's second-order correction).
                let merit =
                    |parts: &EnergyParts, x: &[DVec3]| objective(parts, x) + *rho * it.constraints.violation_l1(x);
                let target = merit0 - ETA * predicted;
                accepted = correction(packed, pattern, kkt, it.constraints, &x0, &p, target, &merit);
            }
            tracing::debug!(
                iteration = out.iterations,
                residual = it.residual,
                ratio,
                radius = self.radius,
                norm,
                scale,
                shift,
                accepted,
                "trust region"
            );
            let length = scale * norm;
            if !accepted || ratio < POOR {
                self.radius = POOR * length;
            } else if ratio > GOOD && length >= (1.0 - BOUNDARY) * self.radius {
                self.radius *= 2.0;
            }
            if accepted {
                out.merits.push(trial);
                return Ok(true);
            }
            out.line_search_failures += 1;
            packed.state.x.copy_from_slice(&x0);
        }
        Ok(false)
    }
}
