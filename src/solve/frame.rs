//! A frame's solve: the patch's cached pattern and factorizations, and the loop its problem
//! needs (`newton` without kernels, `constrained` with them).

use super::constrained::newton_kkt;
use super::contact;
use super::error::SolveError;
use super::iteration::FrameOutcome;
use super::kkt::KktSystem;
use super::linear::CholeskySolver;
use super::newton::newton;
use super::packed::PackedPatch;
use super::pattern::Pattern;
use super::release;
use super::settings::SolverSettings;

/// Solves one frame in place on `packed.state.x` (prescribed coordinates already at their targets).
/// Returns Err with a reason when the state becomes non-finite.
pub fn solve_frame(packed: &mut PackedPatch, settings: &SolverSettings, dt: f64) -> Result<FrameOutcome, SolveError> {
    let mut out = solve(packed, settings, dt)?;
    (out.constraints, out.inverted) = (packed.constraints.rows(), packed.inverted_tets());
    Ok(out)
}

fn solve(packed: &mut PackedPatch, settings: &SolverSettings, dt: f64) -> Result<FrameOutcome, SolveError> {
    let (mut pattern, mut chol) = match packed.cache.system.take() {
        Some(system) => system,
        None => {
            let p = Pattern::build(&packed.state.x, &packed.state.fixed, &packed.state.tie, &packed.elements);
            let s = CholeskySolver::analyze(&p);
            (p, s)
        }
    };
    if let (None, Some(memory), false) =
        (&packed.cache.kkt, packed.cache.kkt_memory.take(), packed.constraints.is_empty())
    {
        let mut kkt = KktSystem::build(&pattern, &packed.constraints, settings.kkt);
        kkt.remember(memory);
        packed.cache.kkt = Some(kkt);
    }
    if !packed.constraints.is_empty() && packed.contact.is_some() {
        let mut cache = packed.cache.kkt.take();
        let result = release::solve(packed, &mut pattern, &mut cache, settings, dt);
        (packed.cache.kkt, packed.cache.system) = (cache, Some((pattern, chol)));
        return result;
    }
    if !packed.constraints.is_empty() {
        let mut kkt = match packed.cache.kkt.take() {
            Some(k) => k,
            None => KktSystem::build(&pattern, &packed.constraints, settings.kkt),
        };
        let before = kkt.factorizations;
        let result = newton_kkt(packed, &mut pattern, &mut kkt, settings, dt).map(|mut o| {
            o.factorizations = (kkt.factorizations - before) as u32;
            o
        });
        packed.cache.kkt = Some(kkt);
        packed.cache.system = Some((pattern, chol));
        return result;
    }
    chol.set_precision(settings.precision);
    let before = chol.factorizations;
    let result = if packed.contact.is_some() {
        contact::continuation(packed, &mut pattern, &mut Direct(&mut chol), settings, dt)
    } else {
        newton(packed, &mut pattern, &mut chol, settings, dt)
    };
    let result = result.map(|mut o| {
        o.factorizations = (chol.factorizations - before) as u32;
        o.contact = contact::report(packed);
        o
    });
    packed.cache.system = Some((pattern, chol));
    result
}

/// The unconstrained loop with its Cholesky analysis (`contact::continuation`'s substeps).
struct Direct<'a>(&'a mut CholeskySolver);

impl contact::Loop for Direct<'_> {
    fn reanalyse(&mut self, _packed: &PackedPatch, pattern: &Pattern, settings: &SolverSettings) {
        contact::reanalyse(self.0, pattern, settings);
    }
    fn solve(
        &mut self,
        packed: &mut PackedPatch,
        pattern: &mut Pattern,
        settings: &SolverSettings,
        dt: f64,
    ) -> Result<FrameOutcome, SolveError> {
        newton(packed, pattern, self.0, settings, dt)
    }
}

/// The constrained loop with its KKT system.
pub(super) struct Kkt<'a>(pub(super) &'a mut KktSystem);

impl contact::Loop for Kkt<'_> {
    fn reanalyse(&mut self, packed: &PackedPatch, pattern: &Pattern, settings: &SolverSettings) {
        let count = self.0.factorizations;
        *self.0 = KktSystem::build(pattern, &packed.constraints, settings.kkt);
        self.0.factorizations = count;
    }
    fn solve(
        &mut self,
        packed: &mut PackedPatch,
        pattern: &mut Pattern,
        settings: &SolverSettings,
        dt: f64,
    ) -> Result<FrameOutcome, SolveError> {
        newton_kkt(packed, pattern, self.0, settings, dt)
    }
}
