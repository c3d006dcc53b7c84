//! EXPERIMENT (issue 67 item 6; removed in the next commit, figures in `README.md` "Damped
//! continuation"): a damped flow off an unstable equilibrium, as Abaqus stabilizes unstable
//! static steps with viscous forces kappa M dx. Each damped step minimizes
//! E(x) + kappa/2 |x - x_k|^2_M from the last one's end x_k (a proximal step, implicit Euler on
//! the gradient flow): along a mode of curvature lambda < 0 a step multiplies the displacement
//! by kappa m / (kappa m - |lambda|), so the flow leaves every unstable mode at once. The flow
//! stops once a step dissipates (kappa |x_{k+1} - x_k|^2_M) at most DISSIPATION of the strain
//! energy; the plain solve then polishes and tests once. `SKINSIM_FLOW_TOL` and
//! `SKINSIM_FLOW_RATIO` set the damped steps' tolerance and the first ratio (the variants).

use glam::DVec3;

use super::eval::energy;
use super::iteration::{FrameOutcome, Inertia};
use super::linear::CholeskySolver;
use super::newton::minimize;
use super::packed::PackedPatch;
use super::pattern::{Pattern, NONE};
use super::settings::SolverSettings;

/// The dissipated energy per step, relative to the strain energy, at which the flow stops.
const DISSIPATION: f64 = 2e-4;
/// Damped steps per flow at most.
const MAX_STEPS: u32 = 30;
/// The first coefficient makes the damped curvature along the escape direction this multiple of
/// its |lambda|.
const FIRST_RATIO: f64 = 2.0;
/// Steps that converge within EASY iterations halve kappa; those that need more than HARD double it.
const EASY: u32 = 3;
const HARD: u32 = 10;

/// The first viscous coefficient: kappa d^T M d = FIRST_RATIO |lambda| along the unit escape
/// direction `direction` (free DOFs) of curvature `curvature`.
pub(super) fn coefficient(packed: &PackedPatch, pattern: &Pattern, direction: &[f64], curvature: f64) -> f64 {
    let mut mass = 0.0;
    for (v, m) in packed.state.mass.iter().enumerate() {
        for k in 0..3 {
            let d = pattern.dof[3 * v + k];
            if d != NONE {
                mass += m * direction[d as usize].powi(2);
            }
        }
    }
    let ratio: f64 = std::env::var("SKINSIM_FLOW_RATIO").ok().and_then(|v| v.parse().ok()).unwrap_or(FIRST_RATIO);
    ratio * curvature.abs() / mass.max(f64::MIN_POSITIVE)
}

/// The damped flow from the state (just past an escape); returns the work it did.
pub(super) fn flow(
    packed: &mut PackedPatch,
    pattern: &mut Pattern,
    chol: &mut CholeskySolver,
    settings: &SolverSettings,
    mut kappa: f64,
) -> FrameOutcome {
    let mass = packed.state.mass.clone();
    let tolerance = std::env::var("SKINSIM_FLOW_TOL").ok().and_then(|v| v.parse().ok()).unwrap_or(settings.tolerance);
    let step_settings = SolverSettings { stability_check: false, tolerance, ..settings.clone() };
    let mut out = FrameOutcome::default();
    for step in 0..MAX_STEPS {
        let centre: Vec<DVec3> = packed.state.x.clone();
        let inertia = Inertia { x_hat: &centre, mass: &mass, inv_h2: kappa };
        let iterations = match minimize(packed, pattern, chol, &step_settings, Some(&inertia)) {
            Ok(o) => {
                let iterations = o.iterations;
                out.absorb(o);
                iterations
            }
            Err(e) => {
                tracing::debug!(step, error = %e, "damped step failed: flow stopped");
                packed.state.x.copy_from_slice(&centre);
                break;
            }
        };
        let dissipated = 2.0 * inertia.energy(&packed.state.x);
        let strain = energy(&packed.elements, &packed.state.x).total();
        tracing::debug!(step, kappa, iterations, dissipated, strain, "damped step");
        if dissipated <= DISSIPATION * strain.abs() {
            break;
        }
        if iterations <= EASY {
            kappa *= 0.5;
        } else if iterations > HARD {
            kappa *= 2.0;
        }
    }
    out
}

/// Abaqus's own form (`SKINSIM_ABAQUS`): the first increment solved plainly sizes kappa so that
/// its motion would dissipate DISSIPATION of its strain energy; every later increment is one
/// damped solve from the increment's start, then the plain solve polishes and tests once.
pub(super) fn increment(
    packed: &mut PackedPatch,
    pattern: &mut Pattern,
    chol: &mut CholeskySolver,
    settings: &SolverSettings,
) -> Result<FrameOutcome, super::SolveError> {
    static KAPPA: std::sync::Mutex<Option<f64>> = std::sync::Mutex::new(None);
    let x0 = packed.state.x.clone();
    let mass = packed.state.mass.clone();
    let plain = SolverSettings { stability_test: super::StabilityTest::Inertia, ..settings.clone() };
    let norm =
        |x: &[DVec3]| -> f64 { x.iter().zip(&x0).zip(&mass).map(|((a, b), m)| m * (*a - *b).length_squared()).sum() };
    let kappa = *KAPPA.lock().unwrap();
    let Some(kappa) = kappa else {
        let out = minimize(packed, pattern, chol, &plain, None)?;
        let strain = energy(&packed.elements, &packed.state.x).total();
        let k = DISSIPATION * strain.abs() / norm(&packed.state.x).max(f64::MIN_POSITIVE);
        tracing::info!(kappa = k, strain, "abaqus: kappa from the first increment");
        *KAPPA.lock().unwrap() = Some(k);
        return Ok(out);
    };
    let quiet = SolverSettings { stability_check: false, ..plain.clone() };
    let inertia = Inertia { x_hat: &x0, mass: &mass, inv_h2: kappa };
    let mut out = minimize(packed, pattern, chol, &quiet, Some(&inertia))?;
    let dissipated = kappa * norm(&packed.state.x);
    let strain = energy(&packed.elements, &packed.state.x).total();
    tracing::info!(
        kappa,
        dissipated,
        strain,
        ratio = dissipated / strain.abs(),
        iterations = out.iterations,
        "abaqus: damped increment"
    );
    let polish = minimize(packed, pattern, chol, &plain, None)?;
    tracing::info!(iterations = polish.iterations, escapes = polish.escapes, "abaqus: polish");
    out.absorb(polish);
    Ok(out)
}
