//! The constrained Newton system of LK14 eq. 5.1, `[[H, J^T], [J, 0]] [dx; lambda] = [-g; -c]`,
//! solved two ways with faer (PHYSICS.md 2; ENGINEERING-NOTES: faer's KKT behaviour):
//! - `Ldlt`: one sparse LDL^T of the whole KKT matrix (AMD ordering) with sign-based dynamic
//!   regularization (+ on DOF rows, - on multiplier rows) and one step of iterative refinement;
//! - `Schur`: the sparse Cholesky of H, then the dense Schur complement S = J H^-1 J^T on the
//!   constraint rows: lambda = S^-1 (c - J H^-1 g), dx = -H^-1 (g + J^T lambda).
//!
//! Both check their residual; the constraint rows are scaled by s = sqrt(mean |diag H|) so the
//! two blocks have comparable pivots.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::ldlt::factor::LdltRegularization;
use faer::linalg::solvers::{Llt, Solve};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LdltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Mat, MatMut, Par, Side};

use super::constraints::Constraints;
use super::linear::{symmetric_product_into, CholeskySolver, NotPositiveDefinite, PARALLEL_MIN_DOFS};
use super::pattern::{Pattern, NONE};

/// How the KKT system is solved (a scene's `solver.kkt`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum KktMethod {
    #[default]
    Ldlt,
    Schur,
}

/// Relative residual above which a KKT solve is refused (after refinement).
const MAX_RESIDUAL: f64 = 1e-8;

/// The KKT matrix's lower-triangular pattern over [free DOFs; multipliers], and the maps from the
/// Hessian's and the Jacobian's values into it.
pub struct KktSystem {
    pub n: usize,
    pub m: usize,
    col_ptr: Vec<u32>,
    row_idx: Vec<u32>,
    h_map: Vec<u32>,
    j_map: Vec<u32>,
    values: Vec<f64>,
    scale: f64,
    method: Solver,
    pub factorizations: u64,
    /// Per constraint entry: its row and DOF (NONE when fixed).
    entry_row: Vec<u32>,
    entry_dof: Vec<u32>,
    /// J^T J on the Hessian pattern: (position, entry, entry, multiplicity).
    pairs: Vec<(u32, u32, u32, f64)>,
    /// The augmented Hessian H + rho J^T J, its rho, and the Jacobian it was built with.
    h_aug: Vec<f64>,
    rho: f64,
    jac: Vec<f64>,
}

enum Solver {
    Ldlt { symbolic: SymbolicCholesky<u32>, l_values: Vec<f64>, signs: Vec<i8>, mem: MemBuffer, par: Par },
    Schur { chol: CholeskySolver, jt: Vec<Vec<(u32, f64)>>, y: Mat<f64>, llt: Option<Llt<f64>> },
}

impl KktSystem {
    /// `augment`: whether `step` may add rho J^T J (the pattern must then hold the kernels'
    /// vertex groups, Pattern::build_with_groups).
    pub fn build(h: &Pattern, c: &Constraints, method: KktMethod, augment: bool) -> KktSystem {
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
        for r in 0..m {
            row_idx.push((n + r) as u32);
            col_ptr.push(row_idx.len() as u32);
        }
        let values = vec![0.0; row_idx.len()];
        let method = match method {
            KktMethod::Ldlt => {
                let par = if n + m >= PARALLEL_MIN_DOFS { Par::rayon(rayon::current_num_threads()) } else { Par::Seq };
                let sym = SymbolicSparseColMatRef::new_checked(n + m, n + m, &col_ptr, None, &row_idx);
                let symbolic = factorize_symbolic_cholesky(
                    sym,
                    Side::Lower,
                    SymmetricOrdering::Amd,
                    CholeskySymbolicParams::default(),
                )
                .expect("symbolic LDL^T of a valid KKT pattern");
                let req = StackReq::any_of(&[
                    symbolic.factorize_numeric_ldlt_scratch::<f64>(par, Default::default()),
                    symbolic.solve_in_place_scratch::<f64>(1, par),
                ]);
                let signs = (0..n + m).map(|i| if i < n { 1 } else { -1 }).collect();
                let l_values = vec![0.0; symbolic.len_val()];
                Solver::Ldlt { symbolic, l_values, signs, mem: MemBuffer::new(req), par }
            }
            KktMethod::Schur => Solver::Schur {
                chol: CholeskySolver::analyze(h),
                jt: vec![Vec::new(); m],
                y: Mat::zeros(n, m),
                llt: None,
            },
        };
        let entry_row: Vec<u32> = c.entries.iter().map(|e| e.0).collect();
        let entry_dof: Vec<u32> = c.entries.iter().map(|&(_, v, k)| h.dof[3 * v as usize + k as usize]).collect();
        let mut per_row: Vec<Vec<u32>> = vec![Vec::new(); m];
        for (e, (&r, &d)) in entry_row.iter().zip(&entry_dof).enumerate() {
            if d != NONE {
                per_row[r as usize].push(e as u32);
            }
        }
        let mut pairs = Vec::new();
        for row in per_row.iter().filter(|_| augment) {
            for (i, &e1) in row.iter().enumerate() {
                for &e2 in &row[..=i] {
                    let (d1, d2) = (entry_dof[e1 as usize], entry_dof[e2 as usize]);
                    // (J^T J)_{d1 d2} sums J_e1 J_e2 over both orders of a pair of entries.
                    let mult = if e1 != e2 && d1 == d2 { 2.0 } else { 1.0 };
                    pairs.push((h.position(d1, d2), e1, e2, mult));
                }
            }
        }
        KktSystem {
            n,
            m,
            col_ptr,
            row_idx,
            h_map,
            j_map,
            values,
            scale: 1.0,
            method,
            factorizations: 0,
            entry_row,
            entry_dof,
            pairs,
            h_aug: Vec::new(),
            rho: 0.0,
            jac: Vec::new(),
        }
    }

    /// One SQP step: (dx, lambda) from H, J, g and c. H is augmented to H + rho J^T J (and the
    /// gradient by rho J^T c), which leaves the solution unchanged while J dx = -c holds, and
    /// makes H positive definite wherever the constrained problem is stable (Finsler's lemma):
    /// a buckled shell's own Hessian is indefinite, the kernels are what hold it. rho starts at
    /// mean diag H / mean diag J^T J and grows 100x on each failed attempt.
    #[allow(clippy::too_many_arguments)]
    pub fn step(
        &mut self,
        h: &Pattern,
        h_values: &[f64],
        j_values: &[f64],
        g: &[f64],
        c: &[f64],
        dx: &mut [f64],
        lambda: &mut [f64],
    ) -> Result<(), NotPositiveDefinite> {
        let mut jtj_diag = vec![0.0; self.n];
        for &(_, e1, e2, _) in &self.pairs {
            if e1 == e2 {
                jtj_diag[self.entry_dof[e1 as usize] as usize] += j_values[e1 as usize].powi(2);
            }
        }
        let mean = |v: &mut dyn Iterator<Item = f64>| {
            let (s, k) = v.fold((0.0, 0usize), |(s, k), x| (s + x.abs(), k + 1));
            s / k.max(1) as f64
        };
        let h_diag = mean(&mut h.diag.iter().map(|&d| h_values[d as usize]));
        let j_diag = mean(&mut jtj_diag.iter().copied().filter(|v| *v > 0.0));
        let mut rho = if j_diag > 0.0 { h_diag / j_diag } else { 0.0 };
        self.jac.clear();
        self.jac.extend_from_slice(j_values);
        // Without pairs (a projected, positive semi-definite H) one plain attempt.
        let attempts = if self.pairs.is_empty() { 1 } else { 2 };
        for _ in 0..attempts {
            self.h_aug.clear();
            self.h_aug.extend_from_slice(h_values);
            for &(p, e1, e2, mult) in &self.pairs {
                self.h_aug[p as usize] += rho * mult * j_values[e1 as usize] * j_values[e2 as usize];
            }
            self.rho = rho;
            let h_aug = std::mem::take(&mut self.h_aug);
            let ok = self.factorize(h, &h_aug, j_values).and_then(|_| self.solve(g, c, dx, lambda));
            self.h_aug = h_aug;
            if ok.is_ok() {
                return Ok(());
            }
            rho *= 100.0;
        }
        Err(NotPositiveDefinite)
    }

    /// Loads H (values on the Hessian pattern) and J (values aligned with the constraint
    /// entries) and factorizes.
    fn factorize(&mut self, h: &Pattern, h_values: &[f64], j_values: &[f64]) -> Result<(), NotPositiveDefinite> {
        let (n, m) = (self.n, self.m);
        self.values.iter_mut().for_each(|v| *v = 0.0);
        let mean_diag = h.diag.iter().map(|&d| h_values[d as usize].abs()).sum::<f64>() / n.max(1) as f64;
        self.scale = mean_diag.sqrt().max(f64::MIN_POSITIVE);
        for (p, &k) in self.h_map.iter().enumerate() {
            self.values[k as usize] = h_values[p];
        }
        for (e, &k) in self.j_map.iter().enumerate() {
            if k != NONE {
                self.values[k as usize] += self.scale * j_values[e];
            }
        }
        self.factorizations += 1;
        match &mut self.method {
            Solver::Ldlt { symbolic, l_values, signs, mem, par } => {
                let sym = SymbolicSparseColMatRef::new_checked(n + m, n + m, &self.col_ptr, None, &self.row_idx);
                let a = SparseColMatRef::new(sym, &self.values);
                let regularization = LdltRegularization {
                    dynamic_regularization_signs: Some(signs),
                    dynamic_regularization_delta: 1e-10 * mean_diag.max(f64::MIN_POSITIVE),
                    dynamic_regularization_epsilon: 1e-13 * mean_diag.max(f64::MIN_POSITIVE),
                };
                let stack = MemStack::new(mem);
                let ok = symbolic
                    .factorize_numeric_ldlt(l_values, a, Side::Lower, regularization, *par, stack, Default::default())
                    .is_ok();
                if ok && l_values.iter().all(|v| v.is_finite()) {
                    Ok(())
                } else {
                    Err(NotPositiveDefinite)
                }
            }
            Solver::Schur { chol, jt, y, llt } => {
                chol.factorize(h, h_values)?;
                fill_rows(jt, &self.col_ptr, &self.row_idx, &self.values, n);
                // Y = H^-1 (s J)^T column by column, then S = (s J) Y.
                let mut col = vec![0.0; n];
                for (r, row) in jt.iter().enumerate() {
                    col.iter_mut().for_each(|v| *v = 0.0);
                    for &(c, v) in row {
                        col[c as usize] = v;
                    }
                    chol.solve(&mut col);
                    y.col_mut(r).iter_mut().zip(&col).for_each(|(a, b)| *a = *b);
                }
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
        for (e, (&r, &d)) in self.entry_row.iter().zip(&self.entry_dof).enumerate() {
            if d != NONE && self.rho != 0.0 {
                b[d as usize] -= self.rho * self.jac[e] * c[r as usize];
            }
        }
        let mut z = b.clone();
        self.raw_solve(&mut z)?;
        // One step of iterative refinement (the regularization perturbs the factor slightly).
        let mut kz = vec![0.0; n + m];
        symmetric_product_into(&self.col_ptr, &self.row_idx, &self.values, &z, &mut kz);
        let mut r: Vec<f64> = b.iter().zip(&kz).map(|(a, k)| a - k).collect();
        self.raw_solve(&mut r)?;
        z.iter_mut().zip(&r).for_each(|(a, d)| *a += d);
        symmetric_product_into(&self.col_ptr, &self.row_idx, &self.values, &z, &mut kz);
        let res = b.iter().zip(&kz).map(|(a, k)| (a - k) * (a - k)).sum::<f64>().sqrt();
        let norm = b.iter().map(|a| a * a).sum::<f64>().sqrt();
        if res.is_nan() || res > MAX_RESIDUAL * norm.max(f64::MIN_POSITIVE) {
            return Err(NotPositiveDefinite);
        }
        dx.copy_from_slice(&z[..n]);
        lambda.iter_mut().zip(&z[n..]).for_each(|(l, v)| *l = s * v);
        Ok(())
    }

    fn raw_solve(&mut self, z: &mut [f64]) -> Result<(), NotPositiveDefinite> {
        let (n, m) = (self.n, self.m);
        match &mut self.method {
            Solver::Ldlt { symbolic, l_values, mem, par, .. } => {
                let ldlt = LdltRef::new(symbolic, l_values);
                let stack = MemStack::new(mem);
                let mat = MatMut::from_column_major_slice_mut(z, n + m, 1);
                ldlt.solve_in_place_with_conj(Conj::No, mat, *par, stack);
            }
            Solver::Schur { chol, jt, y, llt } => {
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
