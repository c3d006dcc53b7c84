//! The constrained Newton system of LK14 eq. 5.1, `[[H + mu I, J^T], [J, 0]] [dx; lambda] =
//! [-g; -c]`, solved two ways with faer (PHYSICS.md 2; ENGINEERING-NOTES: faer's KKT behaviour):
//! - `Ldlt`: one sparse LDL^T of the whole KKT matrix (ordered by the Hessian's nested
//!   dissection then the multipliers, or by the whole matrix's, whichever fills less), the
//!   multiplier diagonal
//!   set to a tiny -delta so that no pivot is exactly zero, then iterative refinement against
//!   the matrix without delta;
//! - `Schur`: the sparse Cholesky of H + mu I, then the dense Schur complement
//!   S = J (H + mu I)^-1 J^T on the constraint rows (one multi-column solve).
//!
//! Inertia correction (as in interior-point codes): a step is a descent direction of the merit
//! function when the Hessian is positive definite on the null space of J, i.e. when the KKT
//! matrix has exactly m negative pivots (Sylvester's law of inertia, for any ordering). A
//! buckled shell's own Hessian is indefinite - the kernels are what hold it - so the exact
//! Hessian usually passes this test where a plain Cholesky of H would fail. When it does not,
//! mu grows by factors of 10 from a small fraction of the mean diagonal; a successful mu is
//! remembered and tried a third smaller next time. Schur needs H + mu I itself positive definite
//! (the Cholesky succeeding), a stronger condition. (Variants measured and rejected: `README.md`.)
//!
//! The constraint rows are scaled by s = sqrt(mean |diag H|) so the two blocks have comparable
//! pivots.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::solvers::{Llt, Solve};
use faer::sparse::linalg::cholesky::{LdltRef, SymbolicCholesky};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Mat, MatMut, Par, Side};

use super::constraints::Constraints;
use super::linear::{
    factor_flops, negative_pivots, symbolic_in_order, symmetric_product_into, CholeskySolver, NotPositiveDefinite,
};
use super::pattern::{Pattern, NONE};
use super::settings::KktMethod;

/// Relative residual above which a KKT solve is refused (after refinement).
const MAX_RESIDUAL: f64 = 1e-8;
/// The multiplier diagonal during factorization, relative to the scaled constraint block.
const MULTIPLIER_DELTA: f64 = 1e-10;
/// Inertia correction, relative to the mean diagonal of H: the smallest shift once one was
/// needed, the smallest against negative curvature, and the largest.
const SHIFT_MIN: f64 = 1e-9;
const SHIFT_FIRST: f64 = 1e-4;
const SHIFT_MAX: f64 = 1e2;
/// How much smaller than the last successful shift the next step tries first.
const SHIFT_DECREASE: f64 = 3.0;
/// Refinement steps against the matrix without the multiplier delta, at most, and the relative
/// residual at which they stop.
const REFINEMENTS: usize = 2;
const REFINED: f64 = 1e-12;

/// The KKT matrix's lower-triangular pattern over [free DOFs; multipliers], and the maps from the
/// Hessian's and the Jacobian's values into it.
pub struct KktSystem {
    pub n: usize,
    pub m: usize,
    col_ptr: Vec<u32>,
    row_idx: Vec<u32>,
    h_map: Vec<u32>,
    j_map: Vec<u32>,
    /// Position of each diagonal entry (DOFs, then multipliers) in `values`.
    diag: Vec<u32>,
    values: Vec<f64>,
    scale: f64,
    method: Solver,
    pub factorizations: u64,
    /// The inertia-correcting shift of the last successful step (relative to mean diag H).
    last_shift: f64,
    /// The shift of the last step (absolute), for the frame report.
    pub shift: f64,
    /// Whether the last failed factorization had more negative pivots than constraints (true
    /// negative curvature) rather than fewer (round-off of the unpivoted LDL^T).
    curvature: bool,
    /// Set under a held load (the constrained Newton's `held`): a zero-shift factor singular
    /// to round-off is then shifted as for negative curvature (SHIFT_FIRST), not by SHIFT_MIN.
    /// The state sits near the load's equilibrium, where the wrinkles' soft modes have
    /// curvatures of round-off size; a step shifted by SHIFT_MIN runs far along them (the fig.
    /// 6-4 pinch's third held remesh: the energy up 0.8 %, 12 iterations to come back; 2 with
    /// this and the load's level kept, `src/mesh/remesh/README.md`).
    pub held: bool,
    /// The negative pivots of the last LDL^T (None after a breakdown, or with Schur).
    negative: Option<usize>,
}

enum Solver {
    Ldlt { symbolic: SymbolicCholesky<u32>, l_values: Vec<f64>, mem: MemBuffer, par: Par },
    Schur { chol: Box<CholeskySolver>, jt: Vec<Vec<(u32, f64)>>, y: Mat<f64>, llt: Option<Llt<f64>>, shifted: Vec<f64> },
}

/// What a KKT system carries from one frame's solve to the next besides its factor: the shift
/// history and the last inertia. A checkpoint saves it and a resumed run's first system takes
/// it (`KktSystem::remember`), so that the frames after a resume repeat the uninterrupted run's.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KktMemory {
    pub last_shift: f64,
    pub curvature: bool,
    pub held: bool,
    pub negative: Option<usize>,
}

/// What an SQP step is solved from at an iterate: the Hessian's values over its pattern, the
/// kernels' Jacobian values (`Constraints::entries` order), the gradient over free DOFs and the
/// constraint values.
#[derive(Clone, Copy)]
pub struct KktPoint<'a> {
    pub h: &'a [f64],
    pub jac: &'a [f64],
    pub grad: &'a [f64],
    pub c: &'a [f64],
}

impl KktSystem {
    pub fn build(h: &Pattern, c: &Constraints, method: KktMethod) -> KktSystem {
        let (n, m) = (h.n, c.rows());
        // Constraint entries per DOF column: (row n + r, entry).
        let mut by_col: Vec<Vec<(u32, u32)>> = vec![Vec::new(); n];
        for (e, &(r, v, coord)) in c.entries.iter().enumerate() {
            let d = h.dof[3 * v as usize + coord as usize];
            if d != NONE {
                by_col[d as usize].push((n as u32 + r, e as u32));
            }
        }
        let mut col_ptr = vec![0u32];
        let mut row_idx = Vec::with_capacity(h.nnz() + c.entries.len() + m);
        let mut h_map = vec![0u32; h.nnz()];
        let mut j_map = vec![NONE; c.entries.len()];
        for (col, extra) in by_col.iter_mut().enumerate() {
            let span = h.col_ptr[col] as usize..h.col_ptr[col + 1] as usize;
            for (p, &r) in span.clone().zip(&h.row_idx[span]) {
                h_map[p] = row_idx.len() as u32;
                row_idx.push(r);
            }
            extra.sort_unstable();
            let mut last = NONE;
            for &(r, e) in extra.iter() {
                if r != last {
                    row_idx.push(r);
                    last = r;
                }
                j_map[e as usize] = (row_idx.len() - 1) as u32;
            }
            col_ptr.push(row_idx.len() as u32);
        }
        let mut diag: Vec<u32> = h.diag.iter().map(|&p| h_map[p as usize]).collect();
        for r in 0..m {
            diag.push(row_idx.len() as u32);
            row_idx.push((n + r) as u32);
            col_ptr.push(row_idx.len() as u32);
        }
        let values = vec![0.0; row_idx.len()];
        let method = match method {
            KktMethod::Ldlt => {
                // Sequential: measured on this 2-core machine, faer's parallel supernodal LDL^T of
                // the KKT matrix is slower (21k DOFs: 145-155 against 230-264 ms; 33k DOFs:
                // 216-305 against 425-448 ms per factorization).
                let par = Par::Seq;
                let sym = SymbolicSparseColMatRef::new_checked(n + m, n + m, &col_ptr, None, &row_idx);
                let symbolic = symbolic_ldlt(sym, &h.order, n, m, &col_ptr, &row_idx);
                let req = StackReq::any_of(&[
                    symbolic.factorize_numeric_ldlt_scratch::<f64>(par, Default::default()),
                    symbolic.solve_in_place_scratch::<f64>(1, par),
                ]);
                let l_values = vec![0.0; symbolic.len_val()];
                Solver::Ldlt { symbolic, l_values, mem: MemBuffer::new(req), par }
            }
            KktMethod::Schur => Solver::Schur {
                chol: Box::new(CholeskySolver::analyze(h)),
                jt: vec![Vec::new(); m],
                y: Mat::zeros(n, m),
                llt: None,
                shifted: Vec::new(),
            },
        };
        KktSystem {
            n,
            m,
            col_ptr,
            row_idx,
            h_map,
            j_map,
            diag,
            values,
            scale: 1.0,
            method,
            factorizations: 0,
            last_shift: 0.0,
            shift: 0.0,
            curvature: true,
            held: false,
            negative: None,
        }
    }

    /// What the system carries to the next frame (`KktMemory`).
    pub fn memory(&self) -> KktMemory {
        KktMemory { last_shift: self.last_shift, curvature: self.curvature, held: self.held, negative: self.negative }
    }

    /// Takes up a saved system's memory (a resumed run's first solve).
    pub fn remember(&mut self, m: KktMemory) {
        (self.last_shift, self.curvature, self.held, self.negative) = (m.last_shift, m.curvature, m.held, m.negative);
    }

    /// The stability verdict at a constrained equilibrium (the LDL^T method): how many negative
    /// curvatures H has on the null space of J. By Sylvester's law the KKT matrix has m + that
    /// many negative eigenvalues (J of full rank), so it is the unshifted LDL^T's negative pivot
    /// count less m. None when the LDL^T breaks down or has fewer than m negative pivots
    /// (round-off), and with Schur. Replaces the last factorization.
    pub(crate) fn unstable_directions(&mut self, h: &Pattern, h_values: &[f64], j_values: &[f64]) -> Option<usize> {
        let mean_diag = mean_abs_diagonal(h, h_values);
        self.load(h, h_values, j_values, mean_diag, 0.0);
        self.negative = None;
        let _ = self.factorize(h);
        self.negative.and_then(|k| k.checked_sub(self.m))
    }

    /// Factorizes the KKT matrix at the smallest shift of the ladder (from SHIFT_FIRST, x10)
    /// that gives it the inertia of a stable constrained problem, for solves on the null space
    /// of J (`solve_null`); the shift remembered for the Newton steps is left as it was. False
    /// past SHIFT_MAX.
    pub(crate) fn factorize_definite(&mut self, h: &Pattern, h_values: &[f64], j_values: &[f64]) -> bool {
        let mean_diag = mean_abs_diagonal(h, h_values);
        let mut shift = SHIFT_FIRST;
        while shift <= SHIFT_MAX {
            self.load(h, h_values, j_values, mean_diag, shift * mean_diag);
            if self.factorize(h).is_ok() {
                return true;
            }
            shift *= 10.0;
        }
        false
    }

    /// One SQP step: (dx, lambda) from H, J, g and c, with the smallest shift mu (of the
    /// sequence 0 or last/3, then x10) that gives the KKT matrix the inertia of a stable
    /// constrained problem.
    pub fn step(
        &mut self,
        h: &Pattern,
        at: &KktPoint,
        dx: &mut [f64],
        lambda: &mut [f64],
    ) -> Result<(), NotPositiveDefinite> {
        let mut shift = self.first_shift();
        loop {
            match self.step_shifted(h, at, dx, lambda, shift) {
                Ok(()) => return Ok(()),
                Err(_) => {
                    tracing::trace!(shift, negative = ?self.negative, m = self.m, curvature = self.curvature, "KKT try failed");
                    shift = self.raise(shift).ok_or(NotPositiveDefinite)?
                }
            }
        }
    }

    /// The shift an iteration tries first (relative to mean |diag H|): zero until a shift was
    /// first needed, then a third of the last one but never below SHIFT_MIN: at a wrinkled state
    /// the unshifted KKT matrix is often singular to round-off, its unpivoted LDL^T then has
    /// fewer than m negative pivots and a failed try at zero costs a factorization per step.
    pub(crate) fn first_shift(&self) -> f64 {
        match self.last_shift {
            0.0 => 0.0,
            last => (last / SHIFT_DECREASE).max(SHIFT_MIN),
        }
    }

    /// After a step its quadratic model did not predict (`constrained`, under a held load): the
    /// next step's first shift is ten times this one's, at least ten times SHIFT_FIRST. False
    /// past SHIFT_MAX, where there is nothing stiffer to try.
    pub(crate) fn stiffen(&mut self) -> bool {
        if self.last_shift >= SHIFT_MAX {
            return false;
        }
        self.last_shift = 10.0 * SHIFT_DECREASE * self.last_shift.max(SHIFT_FIRST);
        true
    }

    /// Whether the last successful step's KKT matrix had the stable inertia at a shift of
    /// round-off size (at most SHIFT_MIN): H was then positive definite on the null space of J
    /// up to round-off, as the stability test would find it a step later.
    pub(crate) fn stable_at_round_off(&self) -> bool {
        self.last_shift <= SHIFT_MIN
    }

    /// The next shift after `shift` failed the inertia test; None past SHIFT_MAX (and the
    /// remembered shift is forgotten).
    pub(crate) fn raise(&mut self, shift: f64) -> Option<f64> {
        if shift >= SHIFT_MAX {
            self.last_shift = 0.0;
            return None;
        }
        // Round-off is cured by a tiny shift; negative curvature needs at least SHIFT_FIRST
        // (measured on fig. 6-3: climbing x10 from 1e-9 cost 5 more factorizations at each new
        // wrinkle).
        Some(match (shift, self.curvature) {
            (_, true) => (10.0 * shift).max(SHIFT_FIRST),
            (0.0, false) if self.held => SHIFT_FIRST,
            (0.0, false) => SHIFT_MIN,
            (_, false) => 10.0 * shift,
        })
    }

    /// The SQP step with the KKT matrix shifted by `shift` x diag(max(|H_ii|, mean |diag H|));
    /// Err when it does not have the inertia of a stable constrained problem (or the solve is
    /// inaccurate). Remembers a successful shift.
    pub(crate) fn step_shifted(
        &mut self,
        h: &Pattern,
        at: &KktPoint,
        dx: &mut [f64],
        lambda: &mut [f64],
        shift: f64,
    ) -> Result<(), NotPositiveDefinite> {
        let mean_diag = mean_abs_diagonal(h, at.h);
        self.load(h, at.h, at.jac, mean_diag, shift * mean_diag);
        self.factorize(h).and_then(|_| self.solve(at.grad, at.c, dx, lambda))?;
        self.last_shift = shift;
        self.shift = shift * mean_diag;
        Ok(())
    }

    /// The shift's metric: d(K)/d(shift) is diag(w) x mean |diag H| on the DOF block, with
    /// w_i = max(|H_ii|, mean) / mean (dimensionless).
    pub(crate) fn shift_weights(&self, h: &Pattern, h_values: &[f64]) -> (Vec<f64>, f64) {
        let mean = mean_abs_diagonal(h, h_values).max(f64::MIN_POSITIVE);
        (h.diag.iter().map(|&d| h_values[d as usize].abs().max(mean) / mean).collect(), mean)
    }

    /// With the last factorization: the DOF part of K^-1 [r; 0] (a solve on the constraints'
    /// null space).
    pub(crate) fn solve_null(&mut self, r: &[f64], out: &mut [f64]) -> Result<(), NotPositiveDefinite> {
        let g: Vec<f64> = r.iter().map(|v| -v).collect();
        let (c, mut mu) = (vec![0.0; self.m], vec![0.0; self.m]);
        self.solve(&g, &c, out, &mut mu)
    }

    /// A second-order correction with the last factorization: the step that, to first order,
    /// brings the constraints from `c` back to zero with no gradient, `K [d; mu] = [0; -c]`.
    pub(crate) fn correct(&mut self, c: &[f64], d: &mut [f64]) -> Result<(), NotPositiveDefinite> {
        let g = vec![0.0; self.n];
        let mut mu = vec![0.0; self.m];
        self.solve(&g, c, d, &mut mu)
    }

    /// Loads H + shift I (values on the Hessian pattern) and the scaled J (values aligned with
    /// the constraint entries).
    fn load(&mut self, h: &Pattern, h_values: &[f64], j_values: &[f64], mean_diag: f64, shift: f64) {
        self.values.iter_mut().for_each(|v| *v = 0.0);
        self.scale = mean_diag.sqrt().max(f64::MIN_POSITIVE);
        for (p, &k) in self.h_map.iter().enumerate() {
            self.values[k as usize] = h_values[p];
        }
        for &k in &self.diag[..h.n] {
            // Scaled like the diagonal where it is large (stiff in-plane DOFs), at least the
            // mean where it is small (the out-of-plane DOFs buckling makes negative).
            let d = self.values[k as usize].abs().max(mean_diag);
            self.values[k as usize] += shift / mean_diag.max(f64::MIN_POSITIVE) * d;
        }
        for (e, &k) in self.j_map.iter().enumerate() {
            if k != NONE {
                self.values[k as usize] += self.scale * j_values[e];
            }
        }
    }

    fn factorize(&mut self, h: &Pattern) -> Result<(), NotPositiveDefinite> {
        let (n, m) = (self.n, self.m);
        self.factorizations += 1;
        // A failed Cholesky (Schur) means an indefinite H; a failed LDL^T, round-off.
        self.curvature = matches!(self.method, Solver::Schur { .. });
        match &mut self.method {
            Solver::Ldlt { symbolic, l_values, mem, par } => {
                for &k in &self.diag[n..] {
                    self.values[k as usize] = -MULTIPLIER_DELTA;
                }
                let sym = SymbolicSparseColMatRef::new_checked(n + m, n + m, &self.col_ptr, None, &self.row_idx);
                let a = SparseColMatRef::new(sym, &self.values);
                let stack = MemStack::new(mem);
                let ok = symbolic
                    .factorize_numeric_ldlt(
                        l_values,
                        a,
                        Side::Lower,
                        Default::default(),
                        *par,
                        stack,
                        Default::default(),
                    )
                    .is_ok();
                for &k in &self.diag[n..] {
                    self.values[k as usize] = 0.0;
                }
                self.negative = None;
                if !ok || !l_values.iter().all(|v| v.is_finite()) {
                    return Err(NotPositiveDefinite);
                }
                let negative = negative_pivots(symbolic, l_values);
                self.negative = Some(negative);
                tracing::trace!(negative, m, "KKT inertia");
                self.curvature = negative > m;
                if negative != m {
                    return Err(NotPositiveDefinite);
                }
                Ok(())
            }
            Solver::Schur { chol, jt, y, llt, shifted } => {
                // H + mu I on the Hessian pattern, read back from the loaded KKT values.
                shifted.clear();
                shifted.resize(self.h_map.len(), 0.0);
                // (h_map is a bijection onto the Hessian part of the KKT pattern.)
                for (p, &k) in self.h_map.iter().enumerate() {
                    shifted[p] = self.values[k as usize];
                }
                chol.factorize(h, shifted).map_err(|_| NotPositiveDefinite)?;
                fill_rows(jt, &self.col_ptr, &self.row_idx, &self.values, n);
                // Y = (H + mu I)^-1 (s J)^T in one multi-column solve, then S = (s J) Y.
                y.fill(0.0);
                for (r, row) in jt.iter().enumerate() {
                    for &(c, v) in row {
                        y[(c as usize, r)] = v;
                    }
                }
                chol.solve_columns(y.as_mut());
                let s = Mat::from_fn(m, m, |r, q| jt[r].iter().map(|&(c, v)| v * y[(c as usize, q)]).sum::<f64>());
                *llt = Some(s.llt(Side::Lower).map_err(|_| NotPositiveDefinite)?);
                Ok(())
            }
        }
    }

    /// Solves for (dx, lambda) given the gradient g and the constraint values c; refuses a
    /// solution whose KKT residual is above MAX_RESIDUAL relative to the right-hand side.
    fn solve(&mut self, g: &[f64], c: &[f64], dx: &mut [f64], lambda: &mut [f64]) -> Result<(), NotPositiveDefinite> {
        let (n, m, s) = (self.n, self.m, self.scale);
        let mut b = Vec::with_capacity(n + m);
        b.extend(g.iter().map(|v| -v));
        b.extend(c.iter().map(|v| -s * v));
        let mut z = b.clone();
        self.raw_solve(&mut z)?;
        let mut r = vec![0.0; n + m];
        let norm = b.iter().map(|a| a * a).sum::<f64>().sqrt();
        let mut res = f64::INFINITY;
        for refinement in 0..=REFINEMENTS {
            self.residual(&b, &z, &mut r);
            res = r.iter().map(|v| v * v).sum::<f64>().sqrt();
            if refinement == REFINEMENTS || res <= REFINED * norm {
                break;
            }
            self.raw_solve(&mut r)?;
            z.iter_mut().zip(&r).for_each(|(a, d)| *a += d);
        }
        tracing::trace!(relative_residual = res / norm, "KKT solve");
        if res.is_nan() || res > MAX_RESIDUAL * norm.max(f64::MIN_POSITIVE) {
            return Err(NotPositiveDefinite);
        }
        dx.copy_from_slice(&z[..n]);
        lambda.iter_mut().zip(&z[n..]).for_each(|(l, v)| *l = s * v);
        Ok(())
    }

    /// r = b - K z with the loaded matrix (no multiplier delta).
    fn residual(&self, b: &[f64], z: &[f64], r: &mut [f64]) {
        symmetric_product_into(&self.col_ptr, &self.row_idx, &self.values, z, r);
        r.iter_mut().zip(b).for_each(|(k, a)| *k = a - *k);
    }

    fn raw_solve(&mut self, z: &mut [f64]) -> Result<(), NotPositiveDefinite> {
        let (n, m) = (self.n, self.m);
        match &mut self.method {
            Solver::Ldlt { symbolic, l_values, mem, par } => {
                let ldlt = LdltRef::new(symbolic, l_values);
                let stack = MemStack::new(mem);
                let mat = MatMut::from_column_major_slice_mut(z, n + m, 1);
                ldlt.solve_in_place_with_conj(Conj::No, mat, *par, stack);
            }
            Solver::Schur { chol, jt, y, llt, .. } => {
                // u = H^-1 b_x;  S lambda = J u - b_c;  x = u - Y lambda.
                let (bx, bc) = z.split_at_mut(n);
                chol.solve(bx);
                let rhs: Vec<f64> =
                    (0..m).map(|r| jt[r].iter().map(|&(c, v)| v * bx[c as usize]).sum::<f64>() - bc[r]).collect();
                let llt = llt.as_ref().ok_or(NotPositiveDefinite)?;
                let mut lam = Mat::from_fn(m, 1, |r, _| rhs[r]);
                llt.solve_in_place(lam.as_mut());
                for (r, l) in bc.iter_mut().enumerate() {
                    *l = lam[(r, 0)];
                }
                for (c, x) in bx.iter_mut().enumerate() {
                    *x -= (0..m).map(|r| y[(c, r)] * bc[r]).sum::<f64>();
                }
            }
        }
        Ok(())
    }
}

fn mean_abs_diagonal(h: &Pattern, h_values: &[f64]) -> f64 {
    h.diag.iter().map(|&d| h_values[d as usize].abs()).sum::<f64>() / h.n.max(1) as f64
}

/// The scaled Jacobian by row (row r -> (DOF column, value)), read from the loaded KKT values.
fn fill_rows(jt: &mut [Vec<(u32, f64)>], col_ptr: &[u32], row_idx: &[u32], values: &[f64], n: usize) {
    jt.iter_mut().for_each(|r| r.clear());
    for c in 0..n {
        for p in col_ptr[c] as usize..col_ptr[c + 1] as usize {
            let r = row_idx[p] as usize;
            if r >= n {
                jt[r - n].push((c as u32, values[p]));
            }
        }
    }
}

/// The symbolic LDL^T under the cheaper (fewer factor flops) of two elimination orders:
/// - the Hessian's nested dissection `h_order`, then the multipliers (the fig. 6-3 two-layer
///   quick scene, 21k DOFs and 342 rows: 177-184 ms per factorization against 199-213 ms with
///   AMD over the whole KKT matrix; 1.24e9 flops against 1.93e9 with the order below);
/// - METIS's nested dissection of the whole KKT graph, each multiplier then moved after the last
///   DOF of its row: with the rows last, J H^-1 J^T is a dense m x m block, which dominates
///   once the kernels are many (the localized pinch at 128 x 111, 61k DOFs and 3405 rows:
///   2.24e10 against 4.00e10 flops, a frame's factorizations 46-52 s against 79-82 s).
fn symbolic_ldlt(
    sym: SymbolicSparseColMatRef<'_, u32>,
    h_order: &[u32],
    n: usize,
    m: usize,
    col_ptr: &[u32],
    row_idx: &[u32],
) -> SymbolicCholesky<u32> {
    let with_order = |order: &[u32]| symbolic_in_order(sym, order);
    let rows_last: Vec<u32> = h_order.iter().copied().chain((n..n + m).map(|r| r as u32)).collect();
    let rows_last = with_order(&rows_last);
    let whole = (m > 0)
        .then(|| super::ordering::metis_nested_dissection(col_ptr, row_idx))
        .flatten()
        .map(|order| with_order(&rows_after_support(&order, n, col_ptr, row_idx)));
    let flops_last = factor_flops(&rows_last);
    match whole.map(|w| (factor_flops(&w), w)) {
        Some((flops, whole)) if flops < flops_last => {
            tracing::debug!(n, m, flops_last, flops, "KKT ordered as a whole");
            whole
        }
        _ => rows_last,
    }
}

/// `order` (an elimination order of the KKT pattern, lower CSC over n DOFs then the
/// multipliers) with each multiplier moved after the last DOF of its row: its pivot is then
/// -J_r S^-1 J_r^T over the DOFs eliminated before it, not the bare (zero) multiplier diagonal.
/// The DOFs keep their relative order, and so do multipliers placed after the same DOF.
fn rows_after_support(order: &[u32], n: usize, col_ptr: &[u32], row_idx: &[u32]) -> Vec<u32> {
    let mut pos = vec![0usize; order.len()];
    for (k, &d) in order.iter().enumerate() {
        pos[d as usize] = k;
    }
    let mut key = pos.clone();
    for c in 0..n {
        for &r in &row_idx[col_ptr[c] as usize..col_ptr[c + 1] as usize] {
            if r as usize >= n {
                key[r as usize] = key[r as usize].max(pos[c]);
            }
        }
    }
    let mut nodes: Vec<u32> = (0..order.len() as u32).collect();
    nodes.sort_by_key(|&d| (key[d as usize], usize::from(d as usize >= n), pos[d as usize]));
    nodes
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::solve::constraints::KernelRows;
    use crate::solve::{Elements, SpringElem};

    /// Two vertices joined by a spring (6 DOFs, all coupled), H diagonal with the given entries,
    /// and one kernel holding vertex 0 in place (rows x0 = 0): the null space of J is vertex 1.
    fn setup(diag: [f64; 6], method: KktMethod) -> (Pattern, Vec<f64>, Vec<f64>, KktSystem) {
        let x = [DVec3::ZERO, DVec3::X];
        let elements = Elements { springs: vec![SpringElem { v: [0, 1], k: 1.0 }], ..Default::default() };
        let p = Pattern::build(&x, &[[false; 3]; 2], &[], &elements);
        let mut h = vec![0.0; p.nnz()];
        for (d, v) in p.diag.iter().zip(diag) {
            h[*d as usize] = v;
        }
        let c = Constraints::new(vec![KernelRows { upper: vec![(0, 1.0)], lower: vec![], lower_moves: false }], &x);
        let mut jac = Vec::new();
        c.jacobian(&x, &mut jac);
        let kkt = KktSystem::build(&p, &c, method);
        (p, h, jac, kkt)
    }

    #[test]
    fn ldlt_takes_the_exact_step_when_only_held_directions_are_negative() {
        // H is indefinite on vertex 0, which the kernel holds: the constrained problem is stable.
        let (p, h, jac, mut kkt) = setup([-1.0, -2.0, 1.0, 2.0, 3.0, 4.0], KktMethod::Ldlt);
        let (g, c) = (vec![1.0; 6], vec![0.5, 0.0, -0.5]);
        let (mut dx, mut lambda) = (vec![0.0; 6], vec![0.0; 3]);
        kkt.step(&p, &KktPoint { h: &h, jac: &jac, grad: &g, c: &c }, &mut dx, &mut lambda).unwrap();
        assert_eq!(kkt.shift, 0.0, "no shift: the reduced Hessian is positive definite");
        let expect = [-0.5, 0.0, 0.5, -0.5, -1.0 / 3.0, -0.25];
        for (a, b) in dx.iter().zip(expect) {
            assert!((a - b).abs() < 1e-12, "{dx:?}");
        }
        // Lagrangian stationarity on the held DOFs: H dx + g + lambda = 0.
        for k in 0..3 {
            assert!((h[p.diag[k] as usize] * dx[k] + g[k] + lambda[k]).abs() < 1e-9, "{lambda:?}");
        }
    }

    #[test]
    fn under_a_held_load_a_round_off_failure_is_shifted_as_curvature() {
        let (.., mut kkt) = setup([1.0; 6], KktMethod::Ldlt);
        kkt.curvature = false; // fewer negative pivots than constraints: round-off
        assert_eq!(kkt.raise(0.0), Some(SHIFT_MIN));
        assert_eq!(kkt.raise(SHIFT_MIN), Some(10.0 * SHIFT_MIN), "then x10");
        kkt.held = true;
        assert_eq!(kkt.raise(0.0), Some(SHIFT_FIRST));
        assert_eq!(kkt.raise(SHIFT_FIRST), Some(10.0 * SHIFT_FIRST), "then x10, as before");
        kkt.curvature = true;
        assert_eq!(kkt.raise(0.0), Some(SHIFT_FIRST), "negative curvature: as before");
    }

    #[test]
    fn a_stiffened_step_starts_ten_times_stiffer() {
        let (.., mut kkt) = setup([1.0; 6], KktMethod::Ldlt);
        assert!(kkt.stiffen());
        assert_eq!(kkt.first_shift(), 10.0 * SHIFT_FIRST, "from an unshifted step: 10 x SHIFT_FIRST");
        kkt.last_shift = 1e-2;
        assert!(kkt.stiffen());
        assert!((kkt.first_shift() - 1e-1).abs() < 1e-15, "{}", kkt.first_shift());
        kkt.last_shift = SHIFT_MAX;
        assert!(!kkt.stiffen(), "nothing stiffer past SHIFT_MAX");
        assert_eq!(kkt.last_shift, SHIFT_MAX);
    }

    #[test]
    fn a_negative_free_direction_is_shifted_and_schur_needs_a_definite_hessian() {
        let (p, h, jac, mut kkt) = setup([1.0, 1.0, 1.0, -1.0, 2.0, 2.0], KktMethod::Ldlt);
        let (g, c) = (vec![1.0; 6], vec![0.0; 3]);
        let (mut dx, mut lambda) = (vec![0.0; 6], vec![0.0; 3]);
        kkt.step(&p, &KktPoint { h: &h, jac: &jac, grad: &g, c: &c }, &mut dx, &mut lambda).unwrap();
        assert!(kkt.shift > 1.0, "the shift makes the free block positive definite: {}", kkt.shift);
        let slope: f64 = dx.iter().zip(&g).map(|(a, b)| a * b).sum();
        assert!(slope < 0.0, "a descent direction");
        // Schur shifts even when only the held directions are negative.
        let (p, h, jac, mut schur) = setup([-1.0, -2.0, 1.0, 2.0, 3.0, 4.0], KktMethod::Schur);
        schur.step(&p, &KktPoint { h: &h, jac: &jac, grad: &g, c: &c }, &mut dx, &mut lambda).unwrap();
        assert!(schur.shift > 2.0, "{}", schur.shift);
    }
}

#[cfg(test)]
mod verdict_tests {
    use glam::DVec3;

    use super::*;
    use crate::solve::constraints::KernelRows;
    use crate::solve::stability::Verdict;
    use crate::solve::{Elements, SpringElem};

    /// Issue 21: the KKT verdict against a dense eigen-solve of the reduced Hessian Z^T H Z.
    /// Two vertices joined by a spring (all 6 DOFs coupled); a kernel holds vertex 0, so the null
    /// space of J is vertex 1's DOFs. H is a dense symmetric matrix whose reduced block is shifted
    /// to put its lowest eigenvalue at `target` (definite, barely indefinite, indefinite), while
    /// the held block stays indefinite (which alone must not count).
    #[test]
    fn kkt_verdict_counts_negative_curvature_on_the_null_space() {
        let x = [DVec3::ZERO, DVec3::X];
        let elements = Elements { springs: vec![SpringElem { v: [0, 1], k: 1.0 }], ..Default::default() };
        let p = Pattern::build(&x, &[[false; 3]; 2], &[], &elements);
        let c = Constraints::new(vec![KernelRows { upper: vec![(0, 1.0)], lower: vec![], lower_moves: false }], &x);
        let mut jac = Vec::new();
        c.jacobian(&x, &mut jac);
        let base = Mat::from_fn(6, 6, |i, j| {
            let (a, b) = (i.min(j) as f64, i.max(j) as f64);
            (1.3 * a + 0.7 * b + 0.4).sin() + if i == j { 1.0 } else { 0.0 }
        });
        let reduced_lowest = |m: &Mat<f64>| {
            let r = Mat::from_fn(3, 3, |i, j| m[(i + 3, j + 3)]);
            r.self_adjoint_eigenvalues(Side::Lower).unwrap()
        };
        let held_lowest = Mat::from_fn(3, 3, |i, j| base[(i, j)]).self_adjoint_eigenvalues(Side::Lower).unwrap()[0];
        for (target, expected) in [(0.5, 0), (-1e-9, 1), (-0.3, 1), (-40.0, 3)] {
            let mut dense = base.clone();
            let shift = reduced_lowest(&base)[0] - target;
            for i in 3..6 {
                dense[(i, i)] -= shift;
            }
            // The held block made indefinite too: it must not count.
            for i in 0..3 {
                dense[(i, i)] -= held_lowest + 0.5;
            }
            let spectrum = reduced_lowest(&dense);
            assert_eq!(spectrum.iter().filter(|l| **l < 0.0).count(), expected, "{spectrum:?}");
            let mut values = vec![0.0; p.nnz()];
            for col in 0..p.n {
                for k in p.col_ptr[col] as usize..p.col_ptr[col + 1] as usize {
                    values[k] = dense[(p.row_idx[k] as usize, col)];
                }
            }
            let mut kkt = KktSystem::build(&p, &c, KktMethod::Ldlt);
            assert_eq!(kkt.unstable_directions(&p, &values, &jac), Some(expected), "target {target}");
            // The stability test's escape direction: in the null space (vertex 0 held), with
            // negative curvature, not below the lowest (a Rayleigh quotient). A curvature within
            // round-off of zero may read as stable.
            match crate::solve::stability::test_constrained(&p, &mut kkt, &values, &jac).unwrap() {
                Verdict::Stable => assert!(expected == 0 || spectrum[0] > -1e-6, "target {target}"),
                Verdict::Unstable { negative, curvature, direction, .. } => {
                    assert_eq!(negative, expected);
                    assert!(
                        curvature < 0.0 && curvature >= spectrum[0] - 1e-9,
                        "target {target}: {curvature}, {spectrum:?}"
                    );
                    let held = direction[..3].iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    assert!(held < 1e-9, "the direction moves the held vertex by {held}");
                }
            }
        }
    }
}

#[cfg(test)]
mod inertia_tests {
    use super::*;
    use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;
    use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, CholeskySymbolicParams, SymmetricOrdering};

    /// The inertia read from faer's factor matches the known spectrum of a shifted 2D Laplacian
    /// (large enough for the supernodal factorization): eigenvalues 4 - 2 cos(i pi / (k + 1)) -
    /// 2 cos(j pi / (k + 1)).
    #[test]
    fn negative_pivots_count_the_negative_eigenvalues() {
        let k = 150usize;
        let n = k * k;
        let sigma = 0.37;
        let (mut col_ptr, mut row_idx, mut values) = (vec![0u32], Vec::new(), Vec::new());
        for c in 0..n {
            let (i, j) = (c % k, c / k);
            row_idx.push(c as u32);
            values.push(4.0 - sigma);
            if i + 1 < k {
                row_idx.push((c + 1) as u32);
                values.push(-1.0);
            }
            if j + 1 < k {
                row_idx.push((c + k) as u32);
                values.push(-1.0);
            }
            col_ptr.push(row_idx.len() as u32);
        }
        let expected = (1..=k)
            .flat_map(|i| (1..=k).map(move |j| (i, j)))
            .filter(|&(i, j)| {
                let t = |m: usize| (m as f64 * std::f64::consts::PI / (k + 1) as f64).cos();
                4.0 - 2.0 * t(i) - 2.0 * t(j) < sigma
            })
            .count();
        let sym = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        let symbolic =
            factorize_symbolic_cholesky(sym, Side::Lower, SymmetricOrdering::Amd, CholeskySymbolicParams::default())
                .unwrap();
        assert!(matches!(symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)), "the supernodal path is tested");
        let mut l_values = vec![0.0; symbolic.len_val()];
        let mut mem = MemBuffer::new(symbolic.factorize_numeric_ldlt_scratch::<f64>(Par::Seq, Default::default()));
        let a = SparseColMatRef::new(sym, &values);
        symbolic
            .factorize_numeric_ldlt(
                &mut l_values,
                a,
                Side::Lower,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .unwrap();
        assert_eq!(negative_pivots(&symbolic, &l_values), expected);
        assert!(expected > 10);
    }
}

#[cfg(test)]
mod ordering_tests {
    use glam::DVec3;

    use super::*;
    use crate::solve::constraints::KernelRows;
    use crate::solve::{Elements, SpringElem};

    #[test]
    fn each_multiplier_moves_after_the_last_dof_of_its_row() {
        // 4 DOFs, 2 multipliers: row 4 on DOFs 0 and 2, row 5 on DOF 3 (lower CSC).
        let col_ptr = [0, 2, 3, 5, 7, 8, 9];
        let row_idx = [0, 4, 1, 2, 4, 3, 5, 4, 5];
        let order = rows_after_support(&[4, 3, 5, 0, 1, 2], 4, &col_ptr, &row_idx);
        assert_eq!(order, [3, 5, 0, 1, 2, 4]);
    }

    /// A k x k grid of springs, every 2 x 2 block of vertices held by a kernel: many rows
    /// against few DOFs, where ordering the multipliers last makes a dense block. The whole-graph
    /// order is chosen, fills less, and the step equals the Schur complement's.
    #[test]
    fn many_kernels_are_ordered_with_the_dofs_and_solve_the_same_step() {
        let k = 24u32;
        let x: Vec<DVec3> = (0..k * k).map(|i| DVec3::new(f64::from(i % k), f64::from(i / k), 0.0)).collect();
        let mut springs = Vec::new();
        for i in 0..k * k {
            if i % k + 1 < k {
                springs.push(SpringElem { v: [i, i + 1], k: 1.0 });
            }
            if i / k + 1 < k {
                springs.push(SpringElem { v: [i, i + k], k: 1.0 });
            }
        }
        let p = Pattern::build(&x, &vec![[false; 3]; x.len()], &[], &Elements { springs, ..Default::default() });
        // Diagonally dominant: positive definite, so both methods take the unshifted step.
        let mut h = vec![0.0; p.nnz()];
        for col in 0..p.n {
            let span = p.col_ptr[col] as usize..p.col_ptr[col + 1] as usize;
            for (v, &row) in h[span.clone()].iter_mut().zip(&p.row_idx[span]) {
                let row = row as usize;
                *v = if row == col {
                    5.0
                } else if row % 3 == col % 3 {
                    -0.5
                } else {
                    0.0
                };
            }
        }
        let kernels = (0..k / 2)
            .flat_map(|a| (0..k / 2).map(move |b| 2 * a * k + 2 * b))
            .map(|v| KernelRows {
                upper: vec![(v, 0.4), (v + 1, 0.3), (v + k, 0.2), (v + k + 1, 0.1)],
                lower: vec![],
                lower_moves: false,
            })
            .collect();
        let c = Constraints::new(kernels, &x);
        let mut jac = Vec::new();
        c.jacobian(&x, &mut jac);
        let mut ldlt = KktSystem::build(&p, &c, KktMethod::Ldlt);
        let Solver::Ldlt { symbolic, .. } = &ldlt.method else { unreachable!() };
        let last: Vec<u32> = p.order.iter().copied().chain((ldlt.n..ldlt.n + ldlt.m).map(|r| r as u32)).collect();
        let sym =
            SymbolicSparseColMatRef::new_checked(ldlt.n + ldlt.m, ldlt.n + ldlt.m, &ldlt.col_ptr, None, &ldlt.row_idx);
        let rows_last = symbolic_in_order(sym, &last);
        assert!(
            factor_flops(symbolic) < 0.8 * factor_flops(&rows_last),
            "{} against {}",
            factor_flops(symbolic),
            factor_flops(&rows_last)
        );
        let g: Vec<f64> = (0..p.n).map(|i| (i as f64).sin()).collect();
        let cv: Vec<f64> = (0..ldlt.m).map(|r| 0.01 * (r as f64).cos()).collect();
        let (mut dx, mut lambda) = (vec![0.0; p.n], vec![0.0; ldlt.m]);
        ldlt.step(&p, &KktPoint { h: &h, jac: &jac, grad: &g, c: &cv }, &mut dx, &mut lambda).unwrap();
        assert_eq!(ldlt.shift, 0.0);
        let mut schur = KktSystem::build(&p, &c, KktMethod::Schur);
        let (mut dx_s, mut lambda_s) = (vec![0.0; p.n], vec![0.0; ldlt.m]);
        schur.step(&p, &KktPoint { h: &h, jac: &jac, grad: &g, c: &cv }, &mut dx_s, &mut lambda_s).unwrap();
        let scale = dx_s.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (a, b) in dx.iter().zip(&dx_s) {
            assert!((a - b).abs() < 1e-9 * scale, "{a} against {b}");
        }
    }
}
