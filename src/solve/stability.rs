//! The stability test at a converged equilibrium (PHYSICS.md 2; H15 5.2's saddle check): an
//! equilibrium is stable exactly when the exact Hessian is positive definite. One LDL^T of H
//! gives its inertia (Sylvester's law: the number of negative pivots is the number of negative
//! eigenvalues), so the verdict needs no threshold on a curvature and fires just past a
//! critical load, where the unstable eigenvalue is ~1e-11 of the mean diagonal. When unstable,
//! the most negative curvature direction (the fastest-growing mode) comes from LOBPCG
//! preconditioned by the same factor with |D| (no further factorization). Where that converges
//! slowly (many unstable modes: a buckled substrate), LOBPCG goes on preconditioned by the
//! Cholesky factor of H + sigma I, sigma sized from its first estimate of the curvature.

use glam::DVec3;

use super::eigen;
use super::kkt::KktSystem;
use super::linear::{symmetric_product_into, CholeskySolver};
use super::pattern::Pattern;
use super::settings::StabilityTest;

/// LOBPCG: block size, iterations at most with each preconditioner, and the relative residual
/// it stops at (an escape direction needs no more; on the H15 3D patch, 1132 unstable modes,
/// blocks of 2-4 and 1e-3 cost 1.9x the shifted-Cholesky test's time per increment).
const BLOCK: usize = 1;
const FIRST_ITERATIONS: u32 = 8;
const MAX_ITERATIONS: u32 = 40;
const TOLERANCE: f64 = 1e-2;
/// The shifted preconditioner: sigma = SHIFT x |first curvature estimate|, x4 per failed try.
/// Sixteen tries span 4^15: on the full H15 3D patch the first stage's estimate is 1e5 times too
/// small (relative residual 6e4), eight tries never reached a definite shift, and the escape went
/// along that poor vector (`README.md`). A failed try stops early in the factorization (0.45 s
/// there against 13 s for a definite one).
const SHIFT: f64 = 2.0;
const SHIFT_TRIES: u32 = 16;
/// `StabilityTest::FactorModes`: the escape's span, in negative pivots (the most negative).
const FACTOR_MODES: usize = 8;
/// Inverse-iteration steps that return the constrained test's direction to the null space.
const NULL_SPACE_STEPS: u32 = 4;
/// A curvature below this fraction of the largest diagonal is round-off (a semidefinite H).
const ROUND_OFF_CURVATURE: f64 = 1e-13;
/// The escape search: first step (of the patch size), growth per try, tries per sign.
const FIRST_STEP: f64 = 1e-5;
const GROWTH: f64 = 3.0;
const TRIES: u32 = 10;
/// An energy decrease counts when larger than this fraction of the energy (its round-off).
const ENERGY_ROUND_OFF: f64 = 1e-12;

/// The verdict on an equilibrium.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    /// H positive (semi)definite.
    Stable,
    /// `negative` eigenvalues below zero; the most negative is `curvature` (per unit
    /// displacement squared) along `direction` (unit length, over the free DOFs).
    Unstable { negative: usize, curvature: f64, direction: Vec<f64>, eigen_iterations: u32 },
}

/// Tests the exact Hessian `h` (values on `pattern`); None when its LDL^T breaks down (a zero
/// pivot: the caller decides). `how`: `FactorModes` escapes along the most negative curvature
/// in the span of the factor's FACTOR_MODES most negative pivots' directions, and runs LOBPCG
/// only where that span shows none; otherwise LOBPCG. (Starting LOBPCG from that direction
/// instead of fixed vectors was measured slower: `README.md`.)
pub fn test(pattern: &Pattern, chol: &mut CholeskySolver, h: &[f64], how: StabilityTest) -> Option<Verdict> {
    let negative = chol.inertia(pattern, h)?;
    tracing::debug!(negative, "inertia");
    if negative == 0 {
        return Some(Verdict::Stable);
    }
    let n = pattern.n;
    let max_diag = pattern.diag.iter().fold(0.0f64, |m, &d| m.max(h[d as usize].abs()));
    let mut apply = |x: &[f64], y: &mut [f64]| symmetric_product_into(&pattern.col_ptr, &pattern.row_idx, h, x, y);
    if how == StabilityTest::FactorModes {
        let directions = chol.negative_pivot_directions(FACTOR_MODES);
        if let Some((curvature, direction)) = eigen::lowest_in_span(directions, &mut apply) {
            tracing::debug!(negative, curvature, "factor modes");
            if curvature < -ROUND_OFF_CURVATURE * max_diag {
                return Some(Verdict::Unstable { negative, curvature, direction, eigen_iterations: 0 });
            }
        }
    }
    let block = (negative + 1).min(BLOCK);
    let mut pair = {
        let mut precondition = |r: &mut [f64]| chol.solve_abs(r);
        eigen::smallest(n, block, &mut apply, &mut precondition, None, FIRST_ITERATIONS, TOLERANCE)
    };
    tracing::debug!(curvature = pair.value, residual = pair.residual, iterations = pair.iterations, "first estimate");
    if pair.residual > TOLERANCE && pair.value < 0.0 {
        // The Ritz value bounds the lowest eigenvalue from above: H + sigma I with sigma a
        // little beyond it is usually definite at the first try, and close to singular along
        // the mode sought, which is what makes it a good preconditioner.
        let mut sigma = SHIFT * pair.value.abs();
        let mut shifted = h.to_vec();
        for _ in 0..SHIFT_TRIES {
            shifted.copy_from_slice(h);
            for &d in &pattern.diag {
                shifted[d as usize] += sigma;
            }
            let definite = chol.factorize(pattern, &shifted).is_ok();
            tracing::debug!(sigma, definite, "shifted preconditioner");
            if definite {
                let mut precondition = |r: &mut [f64]| chol.solve(r);
                let guess = Some(pair.vector.as_slice());
                let better = eigen::smallest(n, block, &mut apply, &mut precondition, guess, MAX_ITERATIONS, TOLERANCE);
                if better.value <= pair.value {
                    pair = better;
                }
                break;
            }
            sigma *= 4.0;
        }
    }
    tracing::debug!(
        negative,
        curvature = pair.value,
        iterations = pair.iterations,
        residual = pair.residual,
        "unstable"
    );
    if pair.value.is_nan() || pair.value >= -ROUND_OFF_CURVATURE * max_diag {
        return Some(Verdict::Stable);
    }
    Some(Verdict::Unstable {
        negative,
        curvature: pair.value,
        direction: pair.vector,
        eigen_iterations: pair.iterations,
    })
}

/// The test at an equilibrium of the kernels' constrained problem (LK14 eq. 5.1): stable
/// exactly when H is positive definite on the null space of the constraint Jacobian `jac`, i.e.
/// when the KKT matrix has m negative eigenvalues (`KktSystem::unstable_directions`). A held
/// shell's own H is indefinite at every buckled state; only the null-space curvature counts.
/// When unstable, the most negative null-space curvature comes from LOBPCG on H preconditioned
/// by K(mu)^-1 [r; 0] (the KKT factor at the smallest definite shift), whose solutions lie in
/// that null space: the direction moves no kernel average to first order. None when the test
/// cannot tell (Schur, or an LDL^T breakdown). Replaces the KKT factorization.
pub(crate) fn test_constrained(pattern: &Pattern, kkt: &mut KktSystem, h: &[f64], jac: &[f64]) -> Option<Verdict> {
    let negative = kkt.unstable_directions(pattern, h, jac)?;
    tracing::debug!(negative, "constrained inertia");
    if negative == 0 {
        return Some(Verdict::Stable);
    }
    if !kkt.factorize_definite(pattern, h, jac) {
        return None;
    }
    let n = pattern.n;
    let max_diag = pattern.diag.iter().fold(0.0f64, |m, &d| m.max(h[d as usize].abs()));
    let mut apply = |x: &[f64], y: &mut [f64]| symmetric_product_into(&pattern.col_ptr, &pattern.row_idx, h, x, y);
    let mut scratch = vec![0.0; n];
    let mut precondition = |r: &mut [f64]| {
        if kkt.solve_null(r, &mut scratch).is_ok() {
            r.copy_from_slice(&scratch);
        }
    };
    // A start in the null space: the preconditioner applied to a fixed pseudo-random vector.
    let mut guess: Vec<f64> = (0..n).map(|i| ((i as f64 + 1.0) * 12.9898).sin().fract() - 0.5).collect();
    precondition(&mut guess);
    let pair = eigen::smallest(n, BLOCK, &mut apply, &mut precondition, Some(&guess), MAX_ITERATIONS, TOLERANCE);
    // Rayleigh-Ritz may pick up round-off outside the null space, where H can be negative too
    // (measured on a 3-dimensional null space: the Ritz vector ended mostly there): inverse
    // iteration steps with the same factor put the direction back in it.
    let mut direction = pair.vector;
    for _ in 0..NULL_SPACE_STEPS {
        precondition(&mut direction);
        let length = direction.iter().map(|v| v * v).sum::<f64>().sqrt();
        direction.iter_mut().for_each(|v| *v /= length);
    }
    let mut hd = vec![0.0; n];
    apply(&direction, &mut hd);
    let curvature: f64 = direction.iter().zip(&hd).map(|(a, b)| a * b).sum();
    tracing::debug!(negative, curvature, iterations = pair.iterations, residual = pair.residual, "unstable");
    if curvature.is_nan() || curvature >= -ROUND_OFF_CURVATURE * max_diag {
        return Some(Verdict::Stable);
    }
    Some(Verdict::Unstable { negative, curvature, direction, eigen_iterations: pair.iterations })
}

/// A lower-energy state along +-`direction` from `x` (energy `phi`): the step grows by GROWTH
/// from FIRST_STEP x `length_scale` (largest displacement) while the energy falls; None when no
/// step lowers the energy by more than its round-off.
pub fn escape(
    x: &[DVec3],
    dof: &[u32],
    direction: &[f64],
    phi: f64,
    length_scale: f64,
    energy_at: &dyn Fn(&[DVec3]) -> f64,
) -> Option<Vec<DVec3>> {
    let max = direction.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if max.is_nan() || max <= 0.0 {
        return None;
    }
    let noise = ENERGY_ROUND_OFF * phi.abs();
    let mut best: Option<(f64, Vec<DVec3>)> = None;
    for sign in [1.0, -1.0] {
        let mut t = FIRST_STEP * length_scale;
        for _ in 0..TRIES {
            let mut trial = x.to_vec();
            super::iteration::step(&mut trial, x, dof, direction, sign * t / max);
            let e = energy_at(&trial);
            // (a NaN energy ends the search too)
            if e.is_nan() || e >= phi - noise {
                break;
            }
            if best.as_ref().is_none_or(|b| e < b.0) {
                best = Some((e, trial));
            }
            t *= GROWTH;
        }
    }
    best.map(|b| b.1)
}
