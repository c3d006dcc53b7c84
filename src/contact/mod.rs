//! Barrier contact with a guarantee (IPC: Li et al. 2020; codimensional IPC with thickness:
//! Li et al. 2021): unsigned point-triangle and edge-edge distances (`distance`), a log barrier
//! on them offset by the skin's thickness (`barrier`), each pair's energy and exact derivatives
//! (`pair`), a conservative continuous collision test that bounds every step (`ccd`), and the
//! broad phase over a patch's surface (`surface`, `broad`).
//!
//! The solver sees contact as one more energy term (`solve::elements`, `ContactPairs`): the
//! pairs near the state, scaled by the barrier stiffness. `ContactState` is what a patch keeps
//! between iterations and frames: its surface, the stiffness and the frame's record.

pub mod barrier;
pub mod broad;
pub mod ccd;
pub mod closed_form;
pub mod distance;
pub mod friction;
pub mod pair;
pub mod surface;

use glam::DVec3;

pub use barrier::Barrier;
pub use distance::{DistanceType, Primitives};
pub use friction::{FrictionPair, FrictionPairs};
pub use pair::Pair;
pub use surface::{Surface, SurfaceLayer};

/// The pairs a solve evaluates, and the barrier stiffness kappa (J/m^4) they are scaled by.
#[derive(Clone, Debug, Default)]
pub struct ContactPairs {
    pub pairs: Vec<Pair>,
    pub stiffness: f64,
}

impl ContactPairs {
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }
}

/// Positions of a pair's four vertices.
#[inline]
pub fn gather(x: &[DVec3], v: &[u32; 4]) -> [[f64; 3]; 4] {
    v.map(|i| x[i as usize].to_array())
}

/// The wide list's extra reach (`ContactState::wide`): WIDE list reaches, at most WIDE_EDGE of
/// the surface's median edge. Measured with the same output bit for bit, one run each:
/// - `fist_contact_quick` (uncapped): 4 reaches 46.1 s, 8: 41.6 s, 16: 44.3 s, 64: 79.7 s
///   (every step filters a longer list), against 46.7 s building the trees at every broad phase;
/// - `pinch_folded_quick`, whose cells are 5 list reaches across: uncapped, 8 reaches took
///   53.8 and 58.3 s against 42.2 and 44.2 s (two rounds, alternating); capped at 0.4 edges,
///   50.5 and 44.3 s against 50.5 and 48.5 s, and the fist 48.3 and 43.2 s against 53.2 and 47.0 s.
const WIDE: f64 = 8.0;
const WIDE_EDGE: f64 = 0.4;

/// What a patch with contact keeps between iterations and frames.
#[derive(Clone, Debug, Default)]
pub struct ContactState {
    pub surface: Surface,
    /// Extra reach of the pair list beyond the barrier's (m): pairs that may become active
    /// within a step stay in the pattern, so it is re-analysed less often.
    pub margin: f64,
    /// kappa; 0 until pairs first become active (`stiffness`).
    pub stiffness: f64,
    /// The stiffness's floor and ceiling, set with it.
    pub stiffness_min: f64,
    pub stiffness_max: f64,
    /// The smallest z / z_hat (z = d^2 - xi^2) of a pair at the last iterate (IPC's stiffness
    /// update: below 1 a pair is active).
    pub last_min_z: f64,
    /// The friction coefficient mu (0: frictionless) and the sticking slip eps_u (m).
    pub friction: f64,
    pub sticking: f64,
    /// This frame's record.
    pub report: ContactReport,
    /// The state at the end of the last solve: where prescribed vertices move from.
    pub last: Vec<DVec3>,
    /// Where the last broad phase started: while every vertex stays within margin / 2 of it,
    /// no pair it left out can come within offset + d_hat (a Verlet list's rule), and its
    /// list still holds every pair that can be active or crossed.
    pub listed_at: Vec<DVec3>,
    /// A wider list for the broad phase (`pairs_near`): the admitted pairs within their list
    /// reach plus an extra reach of each other at `wide_at`. While every vertex stays within
    /// half of that extra reach of `wide_at`, at both ends of a step (so along it too), every
    /// pair that comes within its list reach is in it, and a broad phase filters it instead of
    /// building the trees.
    pub wide: Vec<Pair>,
    pub wide_at: Vec<DVec3>,
    /// Which kernels the last frame released (`solve::release`).
    pub released: Vec<bool>,
    /// The pairs (and whether each was active) that the contact kind's scatter map holds, and
    /// the pattern it was made in (`Pattern::stamp`; `solve::contact::fit`).
    pub mapped: Vec<([u32; 4], bool)>,
    pub mapped_for: u64,
    /// The map before the last (`solve::contact::remap` writes the next one into it: its pages
    /// are already there).
    pub spare_map: Vec<u32>,
    /// The released kernels' spring stiffness (N/m; 0 until first needed: `solve::contact::stiffen`).
    pub kernel_spring: f64,
    /// The kinematic layers that kernels bind skin to, as one surface whose pairs are the
    /// body's parts closer than `fold` to each other and facing (`Surface::close_vertices`;
    /// neighbours within twice that at rest are not pairs): where the body folds onto or
    /// through itself.
    pub body: Surface,
    pub fold: f64,
    /// The Settle's shortened steps before this frame's solve (`ContactReport::settle_cuts`).
    pub settle_cuts: u32,
}

/// Per frame: what contact did (the report's `contact` object).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ContactReport {
    /// Pairs within the barrier's reach at the end of the frame.
    pub active_pairs: usize,
    /// The largest number of active pairs at any iterate.
    pub peak_pairs: usize,
    /// The smallest distance over the thickness offset at any iterate (> 1: never closer than
    /// the thickness; infinite when no pair came within the list's reach).
    pub min_distance_ratio: f64,
    /// The barrier stiffness at the end of the frame (J/m^4).
    pub stiffness: f64,
    /// Line searches whose first step the continuous collision test shortened.
    pub ccd_cuts: u32,
    /// Steps of the Settle after a remesh that the collision bound shortened.
    pub settle_cuts: u32,
    /// Solves the frame took: more than one where prescribed vertices (a body, a held edge)
    /// could not move to their targets in one step without meeting the skin.
    pub substeps: u32,
    /// Broad phases run (one per Newton step, and at the frame's start).
    pub broad_phases: u32,
    /// Times active pairs fell outside the sparse pattern: a new pattern and symbolic
    /// analysis. `remaps`: times the pair list changed inside the pattern (scatter maps only).
    pub reanalyses: u32,
    pub remaps: u32,
    /// The contact energy at the end of the frame (J).
    pub energy: f64,
    /// Friction pairs (touching at the frame's start), and the largest slip of one over the
    /// frame (m): below the sticking slip a pair holds.
    pub friction_pairs: usize,
    pub slip: f64,
    /// LK14 kernels left out of the frame's rows where their skin touches
    /// (`solve::release`), the solves it took, and the largest distance of a released
    /// kernel's skin average from its body point at the frame's end (m).
    pub released_kernels: usize,
    pub release_attempts: u32,
    pub kernel_gap: f64,
}

/// What contact carries from frame to frame beyond a rebuild's reach (`ContactState::memory`):
/// the barrier's stiffness history, where prescribed vertices move from, and the pair lists
/// and their reference positions (a list's order is the order its pairs are summed in).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ContactMemory {
    pub margin: f64,
    pub stiffness: f64,
    pub stiffness_min: f64,
    pub stiffness_max: f64,
    pub last_min_z: f64,
    pub kernel_spring: f64,
    pub last: Vec<DVec3>,
    pub listed_at: Vec<DVec3>,
    pub wide: Vec<Pair>,
    pub wide_at: Vec<DVec3>,
    pub released: Vec<bool>,
}

impl ContactState {
    /// What the state carries to the next frame (`ContactMemory`).
    pub fn memory(&self) -> ContactMemory {
        ContactMemory {
            margin: self.margin,
            stiffness: self.stiffness,
            stiffness_min: self.stiffness_min,
            stiffness_max: self.stiffness_max,
            last_min_z: self.last_min_z,
            kernel_spring: self.kernel_spring,
            last: self.last.clone(),
            listed_at: self.listed_at.clone(),
            wide: self.wide.clone(),
            wide_at: self.wide_at.clone(),
            released: self.released.clone(),
        }
    }

    /// Takes up a saved memory (a resumed run's first frame, after the rebuild).
    pub fn remember(&mut self, m: ContactMemory) {
        (self.margin, self.stiffness, self.stiffness_min, self.stiffness_max) =
            (m.margin, m.stiffness, m.stiffness_min, m.stiffness_max);
        (self.last_min_z, self.kernel_spring) = (m.last_min_z, m.kernel_spring);
        (self.last, self.listed_at, self.wide, self.wide_at, self.released) =
            (m.last, m.listed_at, m.wide, m.wide_at, m.released);
    }

    pub fn new(surface: Surface, margin: f64) -> ContactState {
        ContactState { surface, margin, ..Default::default() }
    }

    /// The reach of the pair list: the largest offset + d_hat + margin.
    pub fn list_reach(&self) -> f64 {
        self.surface.max_offset() + self.beyond()
    }

    /// How far beyond its offset a pair is listed: d_hat + margin.
    fn beyond(&self) -> f64 {
        self.surface.reach + self.margin
    }

    /// Pairs near `x` (or near the step from `x` to `x1`) with a free coordinate (two held
    /// primitives have nothing to solve for: a clamp beside a held body part), counted as a
    /// broad phase.
    pub fn pairs_near(&mut self, x: &[DVec3], x1: Option<&[DVec3]>, fixed: &[[bool; 3]]) -> Vec<Pair> {
        self.report.broad_phases += 1;
        self.listed_at = x.to_vec();
        let extra = (WIDE * self.list_reach()).min(WIDE_EDGE * self.surface.median_edge);
        let within = |at: &[DVec3]| {
            let r2 = (0.5 * extra).powi(2);
            at.len() == self.wide_at.len() && at.iter().zip(&self.wide_at).all(|(a, c)| a.distance_squared(*c) <= r2)
        };
        if !(within(x) && x1.is_none_or(within)) {
            if x1.is_some_and(|y| y.iter().zip(x).any(|(a, b)| a.distance_squared(*b) > extra * extra)) {
                // (a step longer than the extra reach: straight to the trees)
                return self.free_pairs(x, x1, fixed);
            }
            self.wide = broad::candidates(&self.surface, x, None, self.beyond() + extra);
            self.wide_at = x.to_vec();
        }
        let mut pairs = broad::filtered(&self.wide, x, x1, self.beyond());
        pairs.retain(|p| p.v.iter().any(|&v| fixed[v as usize] != [true; 3]));
        pairs
    }

    /// Which `faces` keep their shape in a remesh (`mesh::remesh::FaceRules::kept`): those with
    /// a vertex in `near_vertices` within a median edge. `packed`: each face vertex's packed
    /// number (None outside the patch). Empty before the first solve.
    pub fn kept_faces(&self, packed: &[Option<u32>], faces: &[[u32; 3]]) -> Vec<bool> {
        if self.last.is_empty() {
            return Vec::new();
        }
        let near = self.near_vertices(self.surface.median_edge);
        let near = |v: u32| packed[v as usize].is_some_and(|i| near.contains(&i));
        faces.iter().map(|t| t.iter().any(|&v| near(v))).collect()
    }

    /// The vertices of every pair within its list reach plus `extra` (`broad::near`) at the end
    /// of the last solve (none before it): where a remesh must keep the surface's shape
    /// (`mesh::remesh::FaceRules::kept`).
    pub fn near_vertices(&self, extra: f64) -> std::collections::BTreeSet<u32> {
        if self.last.is_empty() {
            return Default::default();
        }
        broad::candidates(&self.surface, &self.last, None, self.beyond() + extra)
            .into_iter()
            .flat_map(|p| p.v)
            .collect()
    }

    /// The same pairs, neither counted nor kept as the list (a one-off check).
    pub fn free_pairs(&self, x: &[DVec3], x1: Option<&[DVec3]>, fixed: &[[bool; 3]]) -> Vec<Pair> {
        let mut pairs = broad::candidates(&self.surface, x, x1, self.beyond());
        pairs.retain(|p| p.v.iter().any(|&v| fixed[v as usize] != [true; 3]));
        pairs
    }

    /// Whether the last list still covers the states from `x` to `x1` (every vertex within
    /// margin / 2 of where it was listed, at both ends of the straight step: so along it too).
    pub fn still_listed(&self, x: &[DVec3], x1: &[DVec3]) -> bool {
        let r2 = (0.5 * self.margin).powi(2);
        self.listed_at.len() == x.len()
            && x.iter()
                .zip(x1)
                .zip(&self.listed_at)
                .all(|((a, b), c)| a.distance_squared(*c) <= r2 && b.distance_squared(*c) <= r2)
    }

    /// The friction pairs of a frame starting at `x`: the pairs touching there, lagged
    /// (`FrictionPair::lagged`); none without friction or before pairs first touched.
    pub fn lag_friction(&self, x: &[DVec3], fixed: &[[bool; 3]]) -> FrictionPairs {
        let eps = self.sticking;
        if self.friction == 0.0 || self.stiffness == 0.0 {
            return FrictionPairs { pairs: Vec::new(), eps };
        }
        let pairs = self.free_pairs(x, None, fixed);
        let pairs = pairs.iter().filter_map(|p| FrictionPair::lagged(p, x, self.stiffness, self.friction)).collect();
        FrictionPairs { pairs, eps }
    }

    /// Starts a frame's record (the stiffness carries over).
    pub fn begin_frame(&mut self) {
        let settle_cuts = std::mem::take(&mut self.settle_cuts);
        self.report = ContactReport { min_distance_ratio: f64::INFINITY, settle_cuts, ..Default::default() };
    }

    /// Records the iterate `x` with the pairs `pairs`: active count and the smallest distance
    /// ratio; returns the smallest z / z_hat over them (infinite when there are none).
    pub fn observe(&mut self, pairs: &[Pair], x: &[DVec3]) -> f64 {
        let (mut active, mut min_z) = (0, f64::INFINITY);
        for p in pairs {
            let y = gather(x, &p.v);
            // (a pair whose boxes are beyond the reach and farther than the closest so far
            // changes neither figure that matters: its z / z_hat is above 1 either way)
            let gap = distance::box_gap_squared(p.kind, &y);
            if !p.barrier.active(gap) && gap.sqrt() / p.barrier.offset >= self.report.min_distance_ratio {
                min_z = min_z.min(p.barrier.z(gap) / p.barrier.z_hat());
                continue;
            }
            let d2 = p.squared_distance(&y);
            if p.barrier.active(d2) {
                active += 1;
            }
            min_z = min_z.min(p.barrier.z(d2) / p.barrier.z_hat());
            let ratio = d2.sqrt() / p.barrier.offset;
            self.report.min_distance_ratio = self.report.min_distance_ratio.min(ratio);
        }
        self.report.active_pairs = active;
        self.report.peak_pairs = self.report.peak_pairs.max(active);
        min_z
    }

    /// IPC's stiffness rule (Li et al. 2020, sec. 4.3 and supplement): the first time pairs are
    /// active, kappa balances the elastic gradient `ge` against the barrier's at unit stiffness
    /// `gb` (least squares), within [kappa_min, 100 kappa_min]; kappa_min gives the barrier at
    /// half its reach the curvature `mean_diagonal` of the elastic Hessian. Later, kappa doubles
    /// (up to the ceiling) while the closest pair keeps closing within a small fraction of the
    /// reach. Returns whether kappa changed.
    pub fn update_stiffness(&mut self, min_z: f64, mean_diagonal: f64, ge: &[f64], gb: &[f64]) -> bool {
        // (the skin-on-skin barrier sets the scale)
        let b = Barrier { offset: self.surface.max_offset(), reach: self.surface.reach };
        let changed = if self.stiffness == 0.0 {
            if min_z >= 1.0 {
                return false;
            }
            let z0 = 0.5 * b.z_hat();
            let d0_squared = z0 + b.offset * b.offset;
            self.stiffness_min = mean_diagonal / (4.0 * d0_squared * b.curvature(z0));
            self.stiffness_max = 100.0 * self.stiffness_min;
            let gg: f64 = gb.iter().map(|g| g * g).sum();
            let balance = if gg > 0.0 { -ge.iter().zip(gb).map(|(a, b)| a * b).sum::<f64>() / gg } else { 0.0 };
            // (max, min: a non-finite Hessian leaves no NaN bound; the solve reports it)
            self.stiffness = balance.max(self.stiffness_min).min(self.stiffness_max);
            true
        } else {
            let small = 1e-3;
            let closing = min_z < small && self.last_min_z < small && min_z < self.last_min_z;
            let doubled = (2.0 * self.stiffness).min(self.stiffness_max);
            let changed = closing && doubled > self.stiffness;
            if changed {
                self.stiffness = doubled;
            }
            changed
        };
        self.last_min_z = min_z;
        changed
    }

    /// The largest fraction of the step `dx` (per vertex, from `x`) that no pair of `pairs`
    /// crosses (additive CCD); 1 when none comes within its offset.
    pub fn step_bound(pairs: &[Pair], x: &[DVec3], dx: &[DVec3]) -> f64 {
        use rayon::prelude::*;
        let tois: Vec<f64> = pairs
            .par_iter()
            .map(|p| {
                let (y, d) = (gather(x, &p.v), gather(dx, &p.v));
                ccd::additive_toi(p.kind, &y, &d, p.barrier.offset, 1.0).unwrap_or(1.0)
            })
            .collect();
        tois.into_iter().fold(1.0, f64::min)
    }
}

#[cfg(test)]
mod tests;
