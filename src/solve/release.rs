//! LK14 kernels released where skin touches skin (issue 64, scope 3).
//!
//! A kernel holds the average of its skin stencil to its body point as a hard row (LK14
//! eq. 4.1). Where a rigged body folds through itself (linear blend skinning collapses the
//! inside of a bent joint), the body points of the fold's two sides come together or cross, and
//! rows that follow them pull the skin through itself against the barrier. No state meets both.
//! The constrained Newton loop then stalls: the CCD cuts every step, the multipliers and the l1
//! merit's penalty grow without bound, and it ends with no descent direction (the elbow at
//! frame 2: 95 iterations, steps of 3e-5, penalty 8e10). Holding the kernels by stiff
//! penalties instead crawled everywhere (`src/solve/README.md`).
//!
//! So a kernel whose skin touches is left out of the frame's rows, and held instead by a spring
//! much softer than the skin (`elements/kernel_spring.rs`), which the barrier outweighs. Left
//! free, the released skin of the bent elbow bulged 19 mm off its body points and its frames
//! crawled unconverged. Which kernels:
//! - at a frame's start, those whose skin stencil holds a vertex of a pair active where the last
//!   frame ended, and those whose body stencil holds a vertex where the body's parts face each
//!   other within the fold distance, or cross (`Surface::close_vertices`);
//! - when the solve stalls (pinched: `SolveError::Pinched`; no descent; blocked), those with
//!   skin in the stalled state's active pairs as well, and the solve goes on from there.
//!
//! Every other kernel holds exactly. A released kernel is held again in the first frame that
//! starts with its skin out of contact. Kernels binding skin to skin (an epidermis on its
//! dermis) are never released: they pass their skin's touching down to the skin below, and the
//! two skins touch each other (`systems::assemble::contact_surface`).

use std::collections::BTreeSet;

use glam::DVec3;
use rayon::prelude::*;

use super::constraints::{Constraints, KernelRows};
use super::contact;
use super::elements::KernelSprings;
use super::error::SolveError;
use super::frame::Kkt;
use super::iteration::FrameOutcome;
use super::kkt::KktSystem;
use super::packed::PackedPatch;
use super::pattern::Pattern;
use super::settings::SolverSettings;
use crate::contact::{ccd, gather, ContactState};

/// Most solves of one frame, each with more kernels released than the one before.
const MAX_ATTEMPTS: u32 = 8;

/// The vertices of the pairs that the straight path from `from` to `to` crosses, or that end
/// within the barrier's reach at `to`.
pub(super) fn touching(state: &ContactState, from: &[DVec3], to: &[DVec3], fixed: &[[bool; 3]]) -> BTreeSet<u32> {
    let pairs = state.free_pairs(from, Some(to), fixed);
    let d: Vec<DVec3> = to.iter().zip(from).map(|(a, b)| *a - *b).collect();
    let hit: Vec<[u32; 4]> = pairs
        .par_iter()
        .filter(|p| {
            let crosses = ccd::additive_toi(p.kind, &gather(from, &p.v), &gather(&d, &p.v), p.barrier.offset, 1.0);
            crosses.is_some() || p.barrier.active(p.squared_distance(&gather(to, &p.v)))
        })
        .map(|p| p.v)
        .collect();
    hit.into_iter().flatten().collect()
}

/// Whether each kernel binding skin to a body has a skin stencil that holds a vertex of
/// `touching`, or a body stencil that holds one of `folded`.
///
/// A kernel binding skin to skin (its lower side moves: LK14's epidermis on its dermis) is never
/// released, and what its skin touches counts as touching its lower skin too. Released (while
/// bound skins did not touch yet), it let the dermis pass through its own epidermis (a pinch
/// folded over itself, frame 4: 120 crossing faces).
pub(super) fn released(kernels: &[KernelRows], touching: &BTreeSet<u32>, folded: &BTreeSet<u32>) -> Vec<bool> {
    let holds = |k: &KernelRows, set: &BTreeSet<u32>| k.upper.iter().any(|(v, w)| *w > 0.0 && set.contains(v));
    let mut touching = touching.clone();
    // (down a stack of skins, one layer per round)
    loop {
        let below: Vec<u32> = kernels
            .iter()
            .filter(|k| k.lower_moves && holds(k, &touching))
            .flat_map(|k| k.lower.iter().filter(|t| t.w > 0.0).map(|t| t.v))
            .filter(|v| !touching.contains(v))
            .collect();
        if below.is_empty() {
            break;
        }
        touching.extend(below);
    }
    kernels
        .iter()
        .map(|k| !k.lower_moves && (holds(k, &touching) || k.lower.iter().any(|t| t.w > 0.0 && folded.contains(&t.v))))
        .collect()
}

/// `released` and, `rings` times, every kernel whose skin stencil shares a vertex with one
/// released: after each stall the released region grows by a kernel's width around the skin
/// that touched.
pub(super) fn grown(kernels: &[KernelRows], mut out: Vec<bool>, rings: u32) -> Vec<bool> {
    for _ in 0..rings {
        let skin: BTreeSet<u32> =
            kernels.iter().zip(&out).filter(|(_, r)| **r).flat_map(|(k, _)| k.upper.iter().map(|u| u.0)).collect();
        out = released(kernels, &skin, &BTreeSet::new()).iter().zip(&out).map(|(a, b)| *a || *b).collect();
    }
    out
}

/// A frame's solve with contact and kernels: the continuation (`contact::continuation`) on the
/// rows of the kernels not released, again with more released while it stalls. `cache`: the
/// KKT system of the last frame's rows, reused when the same kernels are released.
pub(super) fn solve(
    packed: &mut PackedPatch,
    pattern: &mut Pattern,
    cache: &mut Option<KktSystem>,
    settings: &SolverSettings,
    dt: f64,
) -> Result<FrameOutcome, SolveError> {
    let all = std::mem::take(&mut packed.constraints);
    let target = packed.state.x.clone();
    let state = packed.contact.as_ref().expect("a patch with contact");
    let from = if state.last.len() == target.len() { state.last.clone() } else { state.surface.rest_positions() };
    let mut near = touching(state, &from, &from, &packed.state.fixed);
    let folded = state.body.close_vertices(&target, state.fold);
    let mut factorizations = 0;
    let mut attempts = 0;
    // (the stalled solves' iterations count in the frame's)
    let mut spent = FrameOutcome::default();
    let result = loop {
        attempts += 1;
        let released = grown(&all.kernels, released(&all.kernels, &near, &folded), attempts - 1);
        let (kept, freed): (Vec<_>, Vec<_>) = all.kernels.iter().zip(&released).partition(|(_, r)| !**r);
        packed.constraints = Constraints::new(kept.into_iter().map(|(k, _)| k.clone()).collect(), &packed.state.x);
        let state = packed.contact.as_mut().expect("a patch with contact");
        let same = attempts == 1 && state.released == released;
        if !same {
            // (the springs' stencils change the pattern)
            let freed = freed.into_iter().map(|(k, _)| k.clone()).collect();
            packed.elements.kernel_springs = KernelSprings::new(freed, state.kernel_spring);
            let s = &packed.state;
            *pattern = Pattern::build(&s.x, &s.fixed, &s.tie, &packed.elements);
        }
        let state = packed.contact.as_mut().expect("a patch with contact");
        tracing::debug!(
            attempt = attempts,
            folded = folded.len(),
            touching = near.len(),
            released = released.iter().filter(|r| **r).count(),
            "release"
        );
        state.released = released;
        let mut kkt = match cache.take() {
            Some(k) if same => k,
            _ => KktSystem::build(pattern, &packed.constraints, settings.kkt),
        };
        let before = kkt.factorizations;
        let result = contact::continuation(packed, pattern, &mut Kkt(&mut kkt), settings, dt);
        factorizations += kkt.factorizations - before;
        *cache = Some(kkt);
        let stalled = match &result {
            Ok(out) => !out.converged,
            Err(e) => {
                matches!(e, SolveError::NoDescent { .. } | SolveError::Blocked { .. } | SolveError::Pinched { .. })
            }
        };
        if stalled && attempts < MAX_ATTEMPTS {
            let (x, fixed) = (&packed.state.x, &packed.state.fixed);
            let state = packed.contact.as_mut().expect("a patch with contact");
            let more = touching(state, x, x, fixed);
            let grown = more.iter().any(|v| !near.contains(v));
            tracing::debug!(attempt = attempts, touching = more.len(), grown, "kernels released after a stall");
            if grown {
                // (on from the stalled state: it crosses nothing, and fewer rows only relax it)
                match result {
                    Ok(out) => spent.absorb(out),
                    Err(SolveError::NoDescent { iterations } | SolveError::Pinched { iterations }) => {
                        spent.iterations += iterations
                    }
                    Err(_) => {}
                }
                near.extend(more);
                state.last = x.clone();
                packed.state.x = contact::target_with_free(&target, x, fixed);
                continue;
            }
        }
        break result;
    };
    let state = packed.contact.as_mut().expect("a patch with contact");
    let released: Vec<&KernelRows> =
        all.kernels.iter().zip(&state.released).filter(|(_, r)| **r).map(|(k, _)| k).collect();
    state.report.released_kernels = released.len();
    state.report.release_attempts = attempts;
    state.report.kernel_gap = released.iter().map(|k| k.value(&packed.state.x).length()).fold(0.0, f64::max);
    packed.constraints = all;
    result.map(|o| {
        spent.absorb(o);
        spent.factorizations = factorizations as u32;
        spent.contact = contact::report(packed);
        spent
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::constraints::LowerTerm;

    /// Three kernels along a strip: skin stencils [0, 1], [1, 2], [3, 4]; body vertices 10, 11, 12.
    fn kernels() -> Vec<KernelRows> {
        let lower = |v| vec![LowerTerm { v, w: 1.0, offset: 0.0, ring: Vec::new() }];
        let k = |a, b, body| KernelRows { upper: vec![(a, 0.5), (b, 0.5)], lower: lower(body), lower_moves: false };
        vec![k(0, 1, 10), k(1, 2, 11), k(3, 4, 12)]
    }

    #[test]
    fn kernels_are_released_by_their_skin_touching_or_their_body_folding() {
        let set = |v: &[u32]| v.iter().copied().collect::<BTreeSet<u32>>();
        let k = kernels();
        assert_eq!(released(&k, &set(&[0]), &set(&[])), [true, false, false]);
        assert_eq!(released(&k, &set(&[]), &set(&[12])), [false, false, true]);
        assert_eq!(released(&k, &set(&[7]), &set(&[0, 1, 2])), [false, false, false], "skin and body are apart");
        // a ring: the kernels sharing skin with a released one (1 with 0), not beyond
        assert_eq!(grown(&k, vec![true, false, false], 1), [true, true, false]);
        assert_eq!(grown(&k, vec![true, false, false], 3), [true, true, false]);
        assert_eq!(grown(&k, vec![true, false, false], 0), [true, false, false]);
    }

    /// An epidermis (20, 21) on skin vertex 3 by a kernel whose lower side moves: never
    /// released, and its touching releases the kernel of the skin below it on the body.
    #[test]
    fn skin_on_skin_kernels_hold_and_pass_touching_down() {
        let set = |v: &[u32]| v.iter().copied().collect::<BTreeSet<u32>>();
        let mut k = kernels();
        let lower = vec![LowerTerm { v: 3, w: 1.0, offset: 0.0, ring: Vec::new() }];
        k.push(KernelRows { upper: vec![(20, 0.5), (21, 0.5)], lower, lower_moves: true });
        assert_eq!(released(&k, &set(&[21]), &set(&[])), [false, false, true, false]);
        assert_eq!(released(&k, &set(&[3]), &set(&[])), [false, false, true, false]);
    }
}
