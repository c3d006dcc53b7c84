//! The Newton loop's side of barrier contact (`crate::contact`): the pair list kept near the
//! state and inside the sparse pattern, the barrier stiffness, and the continuous collision
//! bound on every step.
//!
//! The list holds every pair within offset + d_hat + margin of the state, or of the step just
//! searched (a swept broad phase), so the energy of any state the line search tries counts
//! every pair that can be active there. The pattern holds the couplings of every pair listed
//! since it was built: a list that changes inside it only needs new scatter maps; one that
//! leaves it needs a new pattern and symbolic analysis (both counted).

use std::collections::HashMap;

use glam::DVec3;
use rayon::prelude::*;

use super::element::Term;
use super::error::SolveError;
use super::iteration::mean_abs_diagonal;
use super::iteration::FrameOutcome;
use super::linear::CholeskySolver;
use super::packed::PackedPatch;
use super::pattern::{Pattern, NONE};
use super::settings::SolverSettings;
use crate::contact::{gather, ContactReport, ContactState};

/// The index of the registered kind `term` (a field of `packed.elements`) among the terms.
fn kind(packed: &PackedPatch, term: &dyn Term) -> usize {
    let at = term as *const dyn Term;
    packed
        .elements
        .terms()
        .iter()
        .position(|t| std::ptr::addr_eq(*t as *const dyn Term, at))
        .expect("a registered kind")
}

/// Puts the listed pairs inside the pattern: new scatter maps when their couplings are in it,
/// else a new pattern. Returns whether the pattern was rebuilt: the caller then analyses it
/// anew (`reanalyse`, or its KKT system) and resizes its value buffers.
pub(super) fn fit(packed: &mut PackedPatch, pattern: &mut Pattern) -> bool {
    // Only the pairs active at the state have derivatives: the others scatter nowhere (NONE),
    // so a pair listed but not yet near needs no new analysis.
    // (the frame's friction pairs all have derivatives)
    let (x, pairs) = (&packed.state.x, &packed.elements.contacts.pairs);
    let friction = &packed.elements.friction.pairs;
    let active = active(pairs, x);
    let state = packed.contact.as_ref().expect("a patch with contact");
    // The pairs active in the last map made in this pattern, by stencil: inside it, their
    // slots made. (Most active pairs stay active from one step to the next, while pairs
    // entering or leaving the list move the others' places in it.)
    let before: HashMap<[u32; 4], usize> = if state.mapped_for == pattern.stamp {
        state.mapped.iter().enumerate().filter(|(_, m)| m.1).map(|(i, m)| (m.0, i)).collect()
    } else {
        HashMap::new()
    };
    let covered =
        pairs.iter().zip(&active).all(|(p, &a)| !a || before.contains_key(&p.v) || pattern.covers_stencil(&p.v))
            && friction.iter().all(|p| pattern.covers_stencil(&p.v));
    let (contacts, friction_kind) = (kind(packed, &packed.elements.contacts), kind(packed, &packed.elements.friction));
    let state = packed.contact.as_mut().expect("a patch with contact");
    if covered {
        let now: Vec<([u32; 4], bool)> = pairs.iter().zip(&active).map(|(p, &a)| (p.v, a)).collect();
        let mut map = std::mem::take(&mut state.spare_map);
        remap(&mut map, &pattern.maps[contacts], &before, &now, |v| pattern.element_map(v));
        state.spare_map = std::mem::replace(&mut pattern.maps[contacts], map);
        state.mapped = now;
        state.mapped_for = pattern.stamp;
        let map = friction.iter().flat_map(|p| pattern.element_map(&p.v)).collect();
        pattern.maps[friction_kind] = map;
        state.report.remaps += 1;
        return false;
    }
    state.report.reanalyses += 1;
    *pattern = Pattern::build(&packed.state.x, &packed.state.fixed, &packed.state.tie, &packed.elements);
    true
}

/// Whether each listed pair is active at the state.
fn active(pairs: &[crate::contact::Pair], x: &[DVec3]) -> Vec<bool> {
    pairs.par_iter().map(|p| p.active(&gather(x, &p.v))).collect()
}

/// Writes into `map` the contact kind's scatter map for the pairs `now` (each with whether it
/// is active): `element_map`'s slots for an active pair, NONE for the others. `before`: the
/// place in `old` (a map made in the same pattern) of each stencil it holds active, whose slots
/// are copied (the list holds thousands of pairs and a few change per step; making every active
/// pair's map anew, 78 slots a pair, cost 16 % of a touching fist's run).
fn remap(
    map: &mut Vec<u32>,
    old: &[u32],
    before: &HashMap<[u32; 4], usize>,
    now: &[([u32; 4], bool)],
    element_map: impl Fn(&[u32; 4]) -> Vec<u32>,
) {
    let stride = super::scatter::pairs(4);
    map.clear();
    map.reserve(now.len() * stride);
    for (v, active) in now {
        match before.get(v).map(|&i| i * stride..(i + 1) * stride) {
            _ if !active => map.extend(std::iter::repeat_n(NONE, stride)),
            Some(slots) if slots.end <= old.len() => map.extend_from_slice(&old[slots]),
            _ => map.extend(element_map(v)),
        }
    }
}

/// The symbolic analysis of a rebuilt pattern (its factorization count carried on).
pub(super) fn reanalyse(chol: &mut CholeskySolver, pattern: &Pattern, settings: &SolverSettings) {
    let count = chol.factorizations;
    *chol = CholeskySolver::analyze(pattern);
    chol.set_precision(settings.precision);
    chol.factorizations = count;
}

/// What a frame's solve with contact runs between substeps: the patch's Newton loop and the
/// analysis it keeps of the pattern.
pub(super) trait Loop {
    /// Analyses a rebuilt pattern.
    fn reanalyse(&mut self, packed: &PackedPatch, pattern: &Pattern, settings: &SolverSettings);
    fn solve(
        &mut self,
        packed: &mut PackedPatch,
        pattern: &mut Pattern,
        settings: &SolverSettings,
        dt: f64,
    ) -> Result<FrameOutcome, SolveError>;
}

/// After an assembly at the state: records the iterate and applies IPC's stiffness rule
/// (`ContactState::update_stiffness`). `grad`, `values`: the assembled gradient and Hessian.
/// Returns whether the stiffness changed (the assembly is then stale).
pub(super) fn stiffen(packed: &mut PackedPatch, pattern: &Pattern, grad: &[f64], values: &[f64]) -> bool {
    let Some(state) = packed.contact.as_mut() else { return false };
    // Released kernels' springs: KERNEL_SPRING times the Hessian's mean diagonal at the patch's
    // first assembly, before any barrier adds to it (a squeezed pair's curvature is 1e10 times
    // the skin's), kept for the run.
    if state.kernel_spring == 0.0 && state.stiffness == 0.0 {
        state.kernel_spring = KERNEL_SPRING * mean_abs_diagonal(pattern, values);
    }
    let springs = &mut packed.elements.kernel_springs;
    let sprung = !springs.is_empty() && springs.stiffness != state.kernel_spring;
    if sprung {
        springs.stiffness = state.kernel_spring;
    }
    let x = &packed.state.x;
    let min_z = state.observe(&packed.elements.contacts.pairs, x);
    let first = state.stiffness == 0.0;
    // The barrier's gradient at unit stiffness, over free DOFs (only needed the first time).
    let mut barrier = vec![0.0; if first { pattern.n } else { 0 }];
    if first && min_z.is_finite() {
        let unit = crate::contact::ContactPairs { pairs: packed.elements.contacts.pairs.clone(), stiffness: 1.0 };
        let mut g = vec![DVec3::ZERO; x.len()];
        super::element::Term::add_gradient(&unit, x, &mut g);
        for (v, gv) in g.iter().enumerate() {
            for c in 0..3 {
                let d = pattern.dof[3 * v + c];
                if d != NONE {
                    barrier[d as usize] += gv[c];
                }
            }
        }
    }
    let changed = state.update_stiffness(min_z, mean_abs_diagonal(pattern, values), grad, &barrier);
    packed.elements.contacts.stiffness = state.stiffness;
    changed || sprung
}

/// The released kernels' spring stiffness over the Hessian's mean diagonal, per unit of a
/// kernel's sum of squared weights (`elements/kernel_spring.rs`). Measured on the elbow with
/// contact (scratch runs, `src/solve/README.md`): 1e-2 converged every frame, 1e-1 took 1416
/// Newton iterations at frame 3 against 1013.
pub(super) const KERNEL_SPRING: f64 = 1e-2;

/// Before a line search along `dx` (free DOFs) from the state: lists the pairs near the step
/// (unless the last list still covers it) and returns the largest fraction of it no pair
/// crosses (additive CCD), counting a cut. (The caller fits the list to the pattern after the
/// step either way: which listed pairs are active changes with the state.)
pub(super) fn bound_step(packed: &mut PackedPatch, pattern: &Pattern, dx: &[f64]) -> f64 {
    let Some(state) = packed.contact.as_mut() else { return 1.0 };
    let x = &packed.state.x;
    let mut end = x.clone();
    super::iteration::step(&mut end, x, &pattern.dof, dx, 1.0);
    if !state.still_listed(x, &end) {
        packed.elements.contacts.pairs = state.pairs_near(x, Some(&end), &packed.state.fixed);
    }
    let d: Vec<DVec3> = end.iter().zip(x).map(|(a, b)| *a - *b).collect();
    let alpha = ContactState::step_bound(&packed.elements.contacts.pairs, x, &d);
    if alpha < 1.0 {
        state.report.ccd_cuts += 1;
    }
    alpha
}

/// Lists the pairs near the state (after a jump the line search did not make: an escape).
/// Returns whether the patch has contact.
pub(super) fn relist(packed: &mut PackedPatch) -> bool {
    let Some(state) = packed.contact.as_mut() else { return false };
    packed.elements.contacts.pairs = state.pairs_near(&packed.state.x, None, &packed.state.fixed);
    true
}

/// Whether the straight path from `from` to `to` crosses no pair (the stability test's escape).
pub(super) fn clear_path(packed: &PackedPatch, from: &[DVec3], to: &[DVec3]) -> bool {
    let Some(state) = packed.contact.as_ref() else { return true };
    let pairs = state.free_pairs(from, Some(to), &packed.state.fixed);
    let d: Vec<DVec3> = to.iter().zip(from).map(|(a, b)| *a - *b).collect();
    ContactState::step_bound(&pairs, from, &d) >= 1.0
}

/// Most solves in one frame (`continuation`).
const MAX_SUBSTEPS: u32 = 64;

/// The relative residual a substep short of the frame's targets is solved to (`continuation`),
/// or to where it stalls within the progress test's band of it (`progress::Progress::record`:
/// 1000 times). The creature's frame 3 ended its first substep so at 0.045; holding that band
/// at the patch's own (1e-3) took 136 iterations over the run against 134, in the same time.
const SUBSTEP_TOLERANCE: f64 = 1e-4;

/// A frame's solve with contact. Prescribed coordinates (a body in the patch, held skin) jump to
/// their targets between frames, and free ones to Newton's first guess; a jump may pass through
/// the skin. Everything moves instead from where the last solve left it, as far towards the
/// frame's start as no pair crosses (additive CCD), and the skin is solved there; then the
/// prescribed coordinates go on towards their targets, solving after each step, until they
/// arrive. Quasistatic only (the scene refuses contact with dynamics).
pub(super) fn continuation(
    packed: &mut PackedPatch,
    pattern: &mut Pattern,
    solver: &mut dyn Loop,
    settings: &SolverSettings,
    dt: f64,
) -> Result<FrameOutcome, SolveError> {
    // The frame's start: prescribed coordinates at their targets, free ones at Newton's first
    // guess (the last frame's end, or moved with the body under KCK18 anchors).
    let target = packed.state.x.clone();
    let state = packed.contact.as_mut().expect("a patch with contact");
    state.begin_frame();
    let from = if state.last.len() == target.len() { state.last.clone() } else { state.surface.rest_positions() };
    // Everything starts where the last solve left it; the first step moves it all towards the
    // start (the guess may jump as far as the body does), later ones the prescribed only.
    packed.state.x.copy_from_slice(&from);
    // Friction lagged at the frame's start (IPC's single lagged update per step).
    packed.elements.friction = state.lag_friction(&from, &packed.state.fixed);
    let mut total = FrameOutcome::default();
    let mut first = true;
    loop {
        let clock = std::time::Instant::now();
        let x = packed.state.x.clone();
        let goal = if first { target.clone() } else { target_with_free(&target, &x, &packed.state.fixed) };
        first = false;
        let d: Vec<DVec3> = goal.iter().zip(&x).map(|(t, p)| *t - *p).collect();
        let end: Vec<DVec3> = x.iter().zip(&d).map(|(p, d)| *p + *d).collect();
        let state = packed.contact.as_mut().expect("a patch with contact");
        let pairs = state.pairs_near(&x, Some(&end), &packed.state.fixed);
        if state.report.substeps == 0 {
            // (a pair inside its offset at the start has an infinite barrier: nothing to solve)
            let inside = pairs.iter().map(|p| (p.squared_distance(&gather(&x, &p.v)).sqrt(), p.barrier.offset));
            if let Some((distance, offset)) = inside.filter(|(d, o)| d <= o).min_by(|a, b| a.0.total_cmp(&b.0)) {
                return Err(SolveError::TooClose { distance, offset });
            }
        }
        let alpha = if d.iter().all(|v| *v == DVec3::ZERO) { 1.0 } else { ContactState::step_bound(&pairs, &x, &d) };
        state.report.substeps += 1;
        tracing::debug!(substep = state.report.substeps, alpha, pairs = pairs.len(), "contact continuation");
        for (p, d) in packed.state.x.iter_mut().zip(&d) {
            *p += alpha * *d;
        }
        if alpha >= 1.0 {
            packed.state.x = target_with_free(&goal, &packed.state.x, &packed.state.fixed);
        }
        // (the list of the sweep covers where it stopped: no second broad phase)
        packed.elements.contacts.pairs = pairs;
        packed.elements.contacts.stiffness = state.stiffness;
        if fit(packed, pattern) {
            solver.reanalyse(packed, pattern, settings);
        }
        total.counters.contact_ms += clock.elapsed().as_secs_f64() * 1e3;
        // A substep short of the targets only clears the way for the next: solved loosely and
        // not tested for stability (the last one is, at the patch's own settings).
        let loose = (alpha < 1.0).then(|| SolverSettings {
            tolerance: settings.tolerance.max(SUBSTEP_TOLERANCE),
            stability_check: false,
            ..settings.clone()
        });
        let out = solver.solve(packed, pattern, loose.as_ref().unwrap_or(settings), dt)?;
        total.absorb(out);
        let state = packed.contact.as_mut().expect("a patch with contact");
        if alpha >= 1.0 {
            state.last = packed.state.x.clone();
            return Ok(total);
        }
        // (a step of the prescribed motion below a millionth: the skin is squeezed between
        // held parts; the first step may be short, its free part is left to Newton)
        if state.report.substeps >= MAX_SUBSTEPS || (state.report.substeps > 1 && alpha < 1e-6) {
            return Err(SolveError::Blocked { substeps: state.report.substeps });
        }
    }
}

/// The target's prescribed coordinates with the free ones of `x` (exactly: no round-off of
/// x + 1 (target - x)).
pub(super) fn target_with_free(target: &[DVec3], x: &[DVec3], fixed: &[[bool; 3]]) -> Vec<DVec3> {
    target
        .iter()
        .zip(x)
        .zip(fixed)
        .map(|((t, p), f)| {
            DVec3::new(if f[0] { t.x } else { p.x }, if f[1] { t.y } else { p.y }, if f[2] { t.z } else { p.z })
        })
        .collect()
}

/// The frame's record, with the state's end.
pub(super) fn report(packed: &PackedPatch) -> Option<ContactReport> {
    let state = packed.contact.as_ref()?;
    let mut r = state.report;
    r.stiffness = state.stiffness;
    let friction = &packed.elements.friction;
    r.friction_pairs = friction.pairs.len();
    r.slip = friction.pairs.iter().map(|p| p.slip(&packed.state.x).norm()).fold(0.0, f64::max);
    r.energy = super::element::Term::energy(&packed.elements.contacts, &packed.state.x);
    Some(r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Over random changes of the list (pairs inserted anywhere, dropped, activated), the map
    /// made from the last one equals the map made afresh.
    #[test]
    fn a_remapped_list_equals_a_fresh_map() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let element_map = |v: &[u32; 4]| {
            (0..super::super::scatter::pairs(4) as u32).map(|k| v.iter().sum::<u32>() * 100 + k).collect()
        };
        let (mut map, mut before): (Vec<u32>, Vec<([u32; 4], bool)>) = (Vec::new(), Vec::new());
        for step in 0..400 {
            let mut now = before.clone();
            match rng.random_range(0..4) {
                0 => now.insert(rng.random_range(0..=now.len()), ([rng.random_range(0..50), 1, 2, 3], rng.random())),
                1 if !now.is_empty() => {
                    now.remove(rng.random_range(0..now.len()));
                }
                _ if !now.is_empty() => {
                    let i = rng.random_range(0..now.len());
                    now[i].1 = !now[i].1;
                }
                _ => {}
            }
            let index = before.iter().enumerate().filter(|(_, m)| m.1).map(|(i, m)| (m.0, i)).collect();
            let last = std::mem::take(&mut map);
            remap(&mut map, &last, &index, &now, element_map);
            let mut fresh = vec![7; 3];
            remap(&mut fresh, &[], &HashMap::new(), &now, element_map);
            assert_eq!(map, fresh, "step {step}");
            before = now;
        }
    }
}
