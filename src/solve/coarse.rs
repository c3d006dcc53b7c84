//! A coarse start (issue 67 items 2, 3b and 5): before the fine Newton loop, Newton on the fine
//! potential restricted to the range of a prolongation P, x = x_0 + P y. The coarse unknowns y
//! are the displacements of a coarse grid over the patch's material rectangle; P is bilinear in
//! material space. Gradient P^T g, Hessian P^T H P (H projected, on a fixed coarse pattern),
//! factorized at the coarse size; the fine loop then polishes. Progressive Simulation (Zhang
//! et al. 2022) minimizes the finest energy through the prolongation for the same reason: the
//! coarse result is a state of the fine model, so the polish starts on the fine landscape.

use std::collections::BTreeMap;

use glam::DVec3;

use super::eval::EnergyParts;
use super::iteration::{evaluate, factorize_shifted, line_search, FrameOutcome, Inertia, Search};
use super::linear::CholeskySolver;
use super::packed::PackedPatch;
use super::pattern::{Pattern, NONE};
use super::progress::element_filter;
use super::settings::SolverSettings;

/// The coarse loop stops at this relative residual of the restricted gradient.
const COARSE_TOLERANCE: f64 = 1e-4;
const MAX_COARSE_ITERATIONS: u32 = 50;

/// The prolongation and the coarse system, built once per fine pattern.
pub struct CoarseStart {
    /// Per fine free DOF: (coarse DOF, weight), coarse DOFs only where free.
    rows: Vec<Vec<(u32, f64)>>,
    pattern: Pattern,
    chol: CholeskySolver,
    /// The fine pattern it was built for.
    stamp: u64,
}

impl CoarseStart {
    /// P from `cells` coarse cells over the bounding rectangle of `material` (the fine vertices'
    /// material positions, x and y). A coarse coordinate is held where the fine vertex with its
    /// largest weight is held.
    pub fn build(material: &[DVec3], fine: &Pattern, cells: (usize, usize)) -> CoarseStart {
        let (lo, hi) = material.iter().fold((DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)), |(a, b), p| (a.min(*p), b.max(*p)));
        let (nx, ny) = (cells.0.max(1), cells.1.max(1));
        let cw = ((hi.x - lo.x) / nx as f64, (hi.y - lo.y) / ny as f64);
        // Per fine vertex: its 4 coarse vertices and bilinear weights.
        let weights: Vec<[(usize, f64); 4]> = material
            .iter()
            .map(|p| {
                let s = ((p.x - lo.x) / cw.0).clamp(0.0, nx as f64);
                let t = ((p.y - lo.y) / cw.1).clamp(0.0, ny as f64);
                let (i, j) = ((s.floor() as usize).min(nx - 1), (t.floor() as usize).min(ny - 1));
                let (a, b) = (s - i as f64, t - j as f64);
                let at = |di: usize, dj: usize| (j + dj) * (nx + 1) + i + di;
                [(at(0, 0), (1.0 - a) * (1.0 - b)), (at(1, 0), a * (1.0 - b)), (at(0, 1), (1.0 - a) * b), (at(1, 1), a * b)]
            })
            .collect();
        let nc = (nx + 1) * (ny + 1);
        // The fine vertex with the largest weight on each coarse vertex decides its held coordinates.
        let mut best = vec![(usize::MAX, 0.0f64); nc];
        for (v, w) in weights.iter().enumerate() {
            for &(c, x) in w {
                if x > best[c].1 {
                    best[c] = (v, x);
                }
            }
        }
        let mut cdof = vec![NONE; 3 * nc];
        let mut n = 0u32;
        for (c, &(v, _)) in best.iter().enumerate() {
            for k in 0..3 {
                if v != usize::MAX && fine.dof[3 * v + k] != NONE {
                    cdof[3 * c + k] = n;
                    n += 1;
                }
            }
        }
        let mut rows = vec![Vec::new(); fine.n];
        for (v, w) in weights.iter().enumerate() {
            for k in 0..3 {
                let d = fine.dof[3 * v + k];
                if d == NONE || !rows[d as usize].is_empty() {
                    continue; // (a tied coordinate: its owner's row)
                }
                rows[d as usize] =
                    w.iter().filter(|(c, x)| *x > 0.0 && cdof[3 * c + k] != NONE).map(|&(c, x)| (cdof[3 * c + k], x)).collect();
            }
        }
        let pattern = coarse_pattern(fine, &rows, n as usize);
        let chol = CholeskySolver::analyze(&pattern);
        CoarseStart { rows, pattern, chol, stamp: fine.stamp }
    }

    /// Whether this was built for `fine`.
    pub fn fits(&self, fine: &Pattern) -> bool {
        self.stamp == fine.stamp
    }

    /// Coarse DOFs.
    pub fn dofs(&self) -> usize {
        self.pattern.n
    }

    /// The restricted Newton loop from the state; returns its iterations (their fine
    /// assemblies, factorizations and line searches go to `out`'s counters, not its count).
    pub(super) fn solve(
        &mut self,
        packed: &mut PackedPatch,
        fine: &Pattern,
        settings: &SolverSettings,
        inertia: Option<&Inertia>,
        out: &mut FrameOutcome,
    ) -> u32 {
        let total = |parts: &EnergyParts, x: &[DVec3]| parts.total() + inertia.map_or(0.0, |i| i.energy(x));
        let filter = element_filter(settings.projection, true);
        let energy_scale = packed.elements.energy_scale(packed.length_scale);
        let (mut grad, mut values) = (vec![0.0; fine.n], vec![0.0; fine.nnz()]);
        let mut coarse_values = vec![0.0; self.pattern.nnz()];
        let mut scratch = Vec::new();
        let mut work = FrameOutcome::default();
        let mut iterations = 0;
        while iterations < MAX_COARSE_ITERATIONS {
            let a = evaluate(packed, fine, filter, inertia, &mut grad, &mut values, &mut work);
            let phi = total(&a.parts, &packed.state.x);
            let gc = self.restrict(&grad);
            let gnorm = gc.iter().map(|g| g * g).sum::<f64>().sqrt();
            let residual = gnorm / a.force_scale.max(f64::MIN_POSITIVE);
            tracing::debug!(iterations, residual, phi, "coarse");
            if !phi.is_finite() || !gnorm.is_finite() || residual <= COARSE_TOLERANCE {
                break;
            }
            self.galerkin(fine, &values, &mut coarse_values);
            let clock = std::time::Instant::now();
            let factored = self.chol.factorize(&self.pattern, &coarse_values).is_ok()
                || factorize_shifted(&mut self.chol, &self.pattern, &coarse_values, &mut scratch, 1e-8, 100.0, 8).is_some();
            if !factored {
                break;
            }
            let mut dy: Vec<f64> = gc.iter().map(|g| -g).collect();
            self.chol.solve(&mut dy);
            work.counters.factorize_ms += clock.elapsed().as_secs_f64() * 1e3;
            let dx = self.prolong(&dy);
            let slope: f64 = dx.iter().zip(&grad).map(|(a, b)| a * b).sum();
            iterations += 1;
            if slope >= 0.0 {
                break;
            }
            let search =
                Search { dx: &dx, slope, phi, residual, energy_scale, tolerance: COARSE_TOLERANCE, first: 1.0 };
            if !line_search(packed, fine, search, &total, &mut work) {
                break;
            }
        }
        out.counters.assemble_ms += work.counters.assemble_ms;
        out.counters.factorize_ms += work.counters.factorize_ms;
        out.counters.line_search_ms += work.counters.line_search_ms;
        iterations
    }

    /// P^T g.
    fn restrict(&self, g: &[f64]) -> Vec<f64> {
        let mut gc = vec![0.0; self.pattern.n];
        for (row, gi) in self.rows.iter().zip(g) {
            for &(c, w) in row {
                gc[c as usize] += w * gi;
            }
        }
        gc
    }

    /// P y over the fine free DOFs.
    fn prolong(&self, y: &[f64]) -> Vec<f64> {
        self.rows.iter().map(|row| row.iter().map(|&(c, w)| w * y[c as usize]).sum()).collect()
    }

    /// P^T H P into the coarse pattern's values (lower triangle of each, as stored).
    fn galerkin(&self, fine: &Pattern, h: &[f64], out: &mut [f64]) {
        out.iter_mut().for_each(|v| *v = 0.0);
        for j in 0..fine.n {
            for e in fine.col_ptr[j] as usize..fine.col_ptr[j + 1] as usize {
                let (i, v) = (fine.row_idx[e] as usize, h[e]);
                for &(a, wa) in &self.rows[i] {
                    for &(b, wb) in &self.rows[j] {
                        let add = v * wa * wb;
                        if i == j {
                            if a >= b {
                                out[position(&self.pattern, a, b)] += add;
                            }
                        } else {
                            let (r, c) = (a.max(b), a.min(b));
                            out[position(&self.pattern, r, c)] += if a == b { 2.0 * add } else { add };
                        }
                    }
                }
            }
        }
    }
}

/// Where entry (row, col), row >= col, sits in the pattern's values.
fn position(p: &Pattern, row: u32, col: u32) -> usize {
    let (s, e) = (p.col_ptr[col as usize] as usize, p.col_ptr[col as usize + 1] as usize);
    s + p.row_idx[s..e].binary_search(&row).expect("an entry of the coarse pattern")
}

/// The pattern of P^T H P (lower triangle).
fn coarse_pattern(fine: &Pattern, rows: &[Vec<(u32, f64)>], n: usize) -> Pattern {
    let mut cols: Vec<BTreeMap<u32, ()>> = vec![BTreeMap::new(); n];
    for j in 0..fine.n {
        for e in fine.col_ptr[j] as usize..fine.col_ptr[j + 1] as usize {
            let i = fine.row_idx[e] as usize;
            for &(a, _) in &rows[i] {
                for &(b, _) in &rows[j] {
                    cols[a.min(b) as usize].insert(a.max(b), ());
                }
            }
        }
    }
    let mut col_ptr = vec![0u32];
    let (mut row_idx, mut diag) = (Vec::new(), Vec::new());
    for (c, rows) in cols.iter_mut().enumerate() {
        rows.insert(c as u32, ());
        diag.push((row_idx.len() + rows.keys().position(|&r| r == c as u32).unwrap_or(0)) as u32);
        row_idx.extend(rows.keys().copied());
        col_ptr.push(row_idx.len() as u32);
    }
    Pattern {
        dof: (0..n as u32).collect(),
        n,
        col_ptr,
        row_idx,
        diag,
        maps: Vec::new(),
        order: (0..n as u32).collect(),
        stamp: 0,
    }
}
