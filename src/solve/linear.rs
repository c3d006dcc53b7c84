//! Sparse Cholesky with faer: the symbolic factorization is computed once per pattern and
//! reused for every numeric factorization; buffers are allocated once.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LdltRef, LltRef, SymbolicCholesky, SymbolicCholeskyRaw,
    SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use super::pattern::Pattern;
use super::settings::Precision;

/// Below this many DOFs the factorization runs sequentially. Measured on 2 cores: a 30.7k-DOF
/// shell (KCK18 creature) 110-135 ms sequential against 150-180 ms parallel per factorization;
/// a 55k-DOF tet slab (H15 patch_3d_small) 230 ms either way. Parallel is left to larger problems.
pub const PARALLEL_MIN_DOFS: usize = 200_000;
/// From this many DOFs nested dissection orders the factorization - ours or METIS's, whichever
/// needs fewer flops; below, AMD (measured: 37 vs 62 ms per frame on the 4.4k-DOF default scene;
/// about 5 % less fill at 100k DOFs; on the 30.7k-DOF creature shell 90-110 against 110-135 ms
/// per factorization). METIS against ours (benches/orderings.rs): the H15 3D patch (small,
/// 47.6k DOFs) nnz(L) 22.2M against 26.0M, 357 against 476 ms; the creature 3.9M against 4.5M,
/// 54 ms both.
pub(crate) const NESTED_DISSECTION_MIN_DOFS: usize = 20_000;

pub struct CholeskySolver {
    symbolic: SymbolicCholesky<u32>,
    precision: Precision,
    /// The LL^T factor in the chosen precision (the other stays empty), and the f32 copies of
    /// the matrix and of a right-hand side (F32 only).
    l_values: Vec<f64>,
    l32: Vec<f32>,
    a32: Vec<f32>,
    x32: Vec<f32>,
    mem: MemBuffer,
    par: Par,
    factored: bool,
    /// The LDL^T of the last `inertia` call (empty until then): the stability test's. Its
    /// negative pivots (positions in `ldl`) are flipped in place while it serves as the |D|
    /// preconditioner, rather than kept in a second copy of the factor.
    ldl: Vec<f64>,
    negative_pivots: Vec<usize>,
    pivots: Vec<usize>,
    /// Numeric factorizations so far (LL^T and LDL^T).
    pub factorizations: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NotPositiveDefinite;

impl CholeskySolver {
    /// Symbolic analysis of the pattern: AMD below NESTED_DISSECTION_MIN_DOFS, else the nested
    /// dissection (the pattern's geometric one or METIS's) whose factor needs fewer flops.
    pub fn analyze(p: &Pattern) -> Self {
        let par = if p.n >= PARALLEL_MIN_DOFS { Par::rayon(rayon::current_num_threads()) } else { Par::Seq };
        let sym = SymbolicSparseColMatRef::new_checked(p.n, p.n, &p.col_ptr, None, &p.row_idx);
        let with_order = |order: &[u32]| symbolic_in_order(sym, order);
        let symbolic = if p.n >= NESTED_DISSECTION_MIN_DOFS {
            let ours = with_order(&p.order);
            match super::ordering::metis_nested_dissection(&p.col_ptr, &p.row_idx).map(|o| with_order(&o)) {
                Some(metis) if factor_flops(&metis) < factor_flops(&ours) => metis,
                _ => ours,
            }
        } else {
            factorize_symbolic_cholesky(sym, Side::Lower, SymmetricOrdering::Amd, CholeskySymbolicParams::default())
                .expect("symbolic Cholesky of a valid pattern")
        };
        // (f32's scratch is never larger than f64's)
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()),
            symbolic.factorize_numeric_ldlt_scratch::<f64>(par, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, par),
        ]);
        CholeskySolver {
            symbolic,
            precision: Precision::F64,
            l_values: Vec::new(),
            l32: Vec::new(),
            a32: Vec::new(),
            x32: Vec::new(),
            mem: MemBuffer::new(req),
            par,
            factored: false,
            ldl: Vec::new(),
            negative_pivots: Vec::new(),
            pivots: Vec::new(),
            factorizations: 0,
        }
    }

    /// The LL^T factor's arithmetic from now on (a change forgets the last factor).
    pub(crate) fn set_precision(&mut self, precision: Precision) {
        if precision != self.precision {
            self.precision = precision;
            self.factored = false;
            self.l_values = Vec::new();
            self.l32 = Vec::new();
        }
    }

    pub fn precision(&self) -> Precision {
        self.precision
    }

    /// Numeric factorization of the pattern's matrix with `values` (rounded to f32 first in
    /// mixed precision).
    pub fn factorize(&mut self, p: &Pattern, values: &[f64]) -> Result<(), NotPositiveDefinite> {
        let sym = SymbolicSparseColMatRef::new_checked(p.n, p.n, &p.col_ptr, None, &p.row_idx);
        let stack = MemStack::new(&mut self.mem);
        self.factorizations += 1;
        let len = self.symbolic.len_val();
        self.factored = match self.precision {
            Precision::F64 => {
                self.l_values.resize(len, 0.0);
                llt_into(&self.symbolic, &mut self.l_values, SparseColMatRef::new(sym, values), self.par, stack)
            }
            Precision::F32 => {
                self.a32.clear();
                self.a32.extend(values.iter().map(|&v| v as f32));
                self.l32.resize(len, 0.0);
                llt_into(&self.symbolic, &mut self.l32, SparseColMatRef::new(sym, &self.a32[..]), self.par, stack)
            }
        };
        if self.factored {
            Ok(())
        } else {
            Err(NotPositiveDefinite)
        }
    }

    /// Solves A x = rhs in place with the last factorization (in its precision: in f32 the
    /// solution carries the factor's round-off; `newton` refines it).
    pub fn solve(&mut self, rhs: &mut [f64]) {
        assert!(self.factored, "solve after a successful factorization");
        let n = rhs.len();
        let stack = MemStack::new(&mut self.mem);
        match self.precision {
            Precision::F64 => {
                let llt = LltRef::new(&self.symbolic, &self.l_values);
                let mat = MatMut::from_column_major_slice_mut(rhs, n, 1);
                llt.solve_in_place_with_conj(Conj::No, mat, self.par, stack);
            }
            Precision::F32 => {
                self.x32.clear();
                self.x32.extend(rhs.iter().map(|&v| v as f32));
                let llt = LltRef::new(&self.symbolic, &self.l32[..]);
                let mat = MatMut::from_column_major_slice_mut(&mut self.x32[..], n, 1);
                llt.solve_in_place_with_conj(Conj::No, mat, self.par, stack);
                rhs.iter_mut().zip(&self.x32).for_each(|(r, &v)| *r = f64::from(v));
            }
        }
    }

    /// Solves A X = B in place for every column of B with the last factorization (one blocked
    /// pass over the factor instead of one per column).
    pub(crate) fn solve_columns(&mut self, rhs: MatMut<'_, f64>) {
        assert!(self.factored, "solve after a successful factorization");
        assert!(self.precision == Precision::F64, "blocked solves are f64 only (the KKT Schur path)");
        let k = rhs.ncols();
        let req = self.symbolic.solve_in_place_scratch::<f64>(k, self.par);
        let mut mem = MemBuffer::new(req);
        let llt = LltRef::new(&self.symbolic, &self.l_values);
        llt.solve_in_place_with_conj(Conj::No, rhs, self.par, MemStack::new(&mut mem));
    }

    /// The inertia of the pattern's matrix with `values`: the number of its negative eigenvalues,
    /// read from the signs of D in its LDL^T (Sylvester's law of inertia: the count is the same
    /// for any congruence, so for any ordering). None when the unpivoted LDL^T breaks down (a
    /// zero pivot). Keeps the factor for `solve_abs`; the Cholesky factor is left as it was.
    pub fn inertia(&mut self, p: &Pattern, values: &[f64]) -> Option<usize> {
        let sym = SymbolicSparseColMatRef::new_checked(p.n, p.n, &p.col_ptr, None, &p.row_idx);
        let a = SparseColMatRef::new(sym, values);
        self.ldl.resize(self.symbolic.len_val(), 0.0);
        self.factorizations += 1;
        let res = self.symbolic.factorize_numeric_ldlt(
            &mut self.ldl,
            a,
            Side::Lower,
            Default::default(),
            self.par,
            MemStack::new(&mut self.mem),
            Default::default(),
        );
        if res.is_err() || !self.ldl.iter().all(|v| v.is_finite()) {
            return None;
        }
        if self.pivots.is_empty() {
            self.pivots = pivot_positions(&self.symbolic);
        }
        self.negative_pivots.clear();
        for &k in &self.pivots {
            if self.ldl[k] == 0.0 {
                return None;
            }
            if self.ldl[k] < 0.0 {
                self.negative_pivots.push(k);
            }
        }
        Some(self.negative_pivots.len())
    }

    /// Directions of negative curvature read from the last `inertia` factor, one per negative
    /// pivot, for up to `count` of the most negative (issue 67 item 6; More and Sorensen 1979).
    /// With P A P^T = L D L^T, d_k = P^T L^-T e_k has d_k^T A d_k = D_kk < 0, and d_j^T A d_k = 0
    /// for j != k: every combination of them has negative curvature. A d_k = D_kk P^T L e_k, so
    /// each is one solve with the same factor.
    pub(crate) fn negative_pivot_directions(&mut self, count: usize) -> Vec<Vec<f64>> {
        assert!(!self.ldl.is_empty(), "negative_pivot_directions after a successful inertia");
        let mut columns: Vec<usize> =
            self.pivots.iter().enumerate().filter(|&(_, &k)| self.ldl[k] < 0.0).map(|(j, _)| j).collect();
        // (most negative first; ties by column: deterministic)
        columns.sort_by(|&a, &b| self.ldl[self.pivots[a]].total_cmp(&self.ldl[self.pivots[b]]).then(a.cmp(&b)));
        columns.truncate(count);
        let n = self.pivots.len();
        let fwd: Option<Vec<usize>> = self.symbolic.perm().map(|p| p.arrays().0.iter().map(|&i| i as usize).collect());
        columns
            .into_iter()
            .map(|j| {
                let mut b = vec![0.0; n];
                let d = self.ldl[self.pivots[j]];
                for (row, l) in l_column(&self.symbolic, &self.ldl, j) {
                    let original = fwd.as_ref().map_or(row, |f| f[row]);
                    b[original] = d * if row == j { 1.0 } else { l };
                }
                self.solve_ldl(&mut b);
                b
            })
            .collect()
    }

    /// Solves A x = rhs in place with the last `inertia` factor (A's LDL^T).
    pub(crate) fn solve_ldl(&mut self, rhs: &mut [f64]) {
        assert!(!self.ldl.is_empty(), "solve_ldl after a successful inertia");
        ldlt_solve(&self.symbolic, &self.ldl, self.par, &mut self.mem, rhs);
    }

    /// Solves (P^T L |D| L^T P) x = rhs in place with the last `inertia` factor: a symmetric
    /// positive definite approximation of |H|^-1 (the eigen-solver's preconditioner; for a
    /// definite H it is H^-1 itself).
    pub(crate) fn solve_abs(&mut self, rhs: &mut [f64]) {
        assert!(!self.ldl.is_empty(), "solve_abs after a successful inertia");
        let flip = |ldl: &mut [f64], at: &[usize]| at.iter().for_each(|&k| ldl[k] = -ldl[k]);
        flip(&mut self.ldl, &self.negative_pivots);
        ldlt_solve(&self.symbolic, &self.ldl, self.par, &mut self.mem, rhs);
        flip(&mut self.ldl, &self.negative_pivots);
    }

    /// Whether the last factorization succeeded (its factor can precondition CG).
    pub(crate) fn is_factored(&self) -> bool {
        self.factored
    }
}

/// The LL^T of `a` into `l` (f64 or f32); whether it succeeded with a finite factor.
fn llt_into<T: faer::traits::RealField + faer::traits::ComplexField<Real = T> + Copy + Into<f64>>(
    symbolic: &SymbolicCholesky<u32>,
    l: &mut [T],
    a: SparseColMatRef<'_, u32, T>,
    par: Par,
    stack: &mut MemStack,
) -> bool {
    let res =
        symbolic.factorize_numeric_llt(l, a, Side::Lower, LltRegularization::default(), par, stack, Default::default());
    res.is_ok() && l.iter().all(|&v| v.into().is_finite())
}

/// Solves in place with an LDL^T factor's values on `symbolic`.
fn ldlt_solve(symbolic: &SymbolicCholesky<u32>, values: &[f64], par: Par, mem: &mut MemBuffer, rhs: &mut [f64]) {
    let n = rhs.len();
    let mat = MatMut::from_column_major_slice_mut(rhs, n, 1);
    LdltRef::new(symbolic, values).solve_in_place_with_conj(Conj::No, mat, par, MemStack::new(mem));
}

/// Where each entry of D sits in an LDL^T factor's values (faer stores D on L's diagonal).
pub(super) fn pivot_positions(symbolic: &SymbolicCholesky<u32>) -> Vec<usize> {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Simplicial(s) => {
            let (col_ptr, row_idx) = (s.col_ptr(), s.row_idx());
            (0..s.nrows())
                .filter_map(|j| {
                    let span = col_ptr[j] as usize..col_ptr[j + 1] as usize;
                    row_idx[span.clone()].iter().position(|&r| r as usize == j).map(|p| span.start + p)
                })
                .collect()
        }
        // (D on each supernode block's diagonal)
        SymbolicCholeskyRaw::Supernodal(s) => {
            supernode_blocks(s).flat_map(|(offset, rows, cols)| (0..cols).map(move |j| offset + j * rows + j)).collect()
        }
    }
}

/// The flops of a numeric factorization with this symbolic factor: the sum over L's columns of
/// their entry count squared.
/// The symbolic factorization of a symmetric pattern (lower CSC) under the elimination order
/// `order` (order[k] is the k-th row eliminated).
pub(super) fn symbolic_in_order(sym: SymbolicSparseColMatRef<'_, u32>, order: &[u32]) -> SymbolicCholesky<u32> {
    let mut inverse = vec![0u32; order.len()];
    for (k, &d) in order.iter().enumerate() {
        inverse[d as usize] = k as u32;
    }
    let perm = faer::perm::PermRef::new_checked(order, &inverse, order.len());
    factorize_symbolic_cholesky(sym, Side::Lower, SymmetricOrdering::Custom(perm), Default::default())
        .expect("symbolic factorization of a valid pattern")
}

pub fn factor_flops(symbolic: &SymbolicCholesky<u32>) -> f64 {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Simplicial(s) => {
            let cp = s.col_ptr();
            (0..s.nrows()).map(|j| ((cp[j + 1] - cp[j]) as f64).powi(2)).sum()
        }
        SymbolicCholeskyRaw::Supernodal(s) => {
            supernode_blocks(s).map(|(_, rows, cols)| (0..cols).map(|j| ((rows - j) as f64).powi(2)).sum::<f64>()).sum()
        }
    }
}

/// Each supernode's block of factor values: (offset, rows, columns), column-major, its
/// columns first (the diagonal block), then its off-block rows.
fn supernode_blocks(s: &SymbolicSupernodalCholesky<u32>) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
    let (begin, end, val) = (s.supernode_begin(), s.supernode_end(), s.col_ptr_for_val());
    (0..s.n_supernodes()).map(move |k| {
        let cols = (end[k] - begin[k]) as usize;
        (val[k] as usize, (val[k + 1] - val[k]) as usize / cols.max(1), cols)
    })
}

/// Column `j` of an LDL^T factor stored on `symbolic` (rows in the factor's own order, the
/// diagonal first, where faer keeps D_jj).
fn l_column<'a>(symbolic: &'a SymbolicCholesky<u32>, values: &'a [f64], j: usize) -> Vec<(usize, f64)> {
    match symbolic.raw() {
        SymbolicCholeskyRaw::Simplicial(s) => {
            let span = s.col_ptr()[j] as usize..s.col_ptr()[j + 1] as usize;
            s.row_idx()[span.clone()].iter().zip(&values[span]).map(|(&r, &v)| (r as usize, v)).collect()
        }
        SymbolicCholeskyRaw::Supernodal(s) => {
            let begin = s.supernode_begin();
            let k = begin.partition_point(|&b| b as usize <= j) - 1;
            let (offset, rows, cols) = supernode_blocks(s).nth(k).expect("a supernode holds every column");
            let (first, jj) = (begin[k] as usize, j - begin[k] as usize);
            let below = &s.row_idx()[s.col_ptr_for_row_idx()[k] as usize..s.col_ptr_for_row_idx()[k + 1] as usize];
            let column = &values[offset + jj * rows..offset + (jj + 1) * rows];
            (jj..cols)
                .map(|i| (first + i, column[i]))
                .chain(below.iter().zip(&column[cols..]).map(|(&r, &v)| (r as usize, v)))
                .collect()
        }
    }
}

/// The number of negative entries of D in an LDL^T factor (its matrix's negative inertia).
pub(super) fn negative_pivots(symbolic: &SymbolicCholesky<u32>, l_values: &[f64]) -> usize {
    pivot_positions(symbolic).iter().filter(|&&k| l_values[k] < 0.0).count()
}

/// y = A x for the symmetric matrix whose lower triangle is stored as CSC (col_ptr, row_idx).
pub(crate) fn symmetric_product_into(col_ptr: &[u32], row_idx: &[u32], values: &[f64], x: &[f64], y: &mut [f64]) {
    y.iter_mut().for_each(|v| *v = 0.0);
    for c in 0..col_ptr.len() - 1 {
        let span = col_ptr[c] as usize..col_ptr[c + 1] as usize;
        for (&r, &v) in row_idx[span.clone()].iter().zip(&values[span]) {
            let r = r as usize;
            y[r] += v * x[c];
            if r != c {
                y[c] += v * x[r];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use faer::Mat;

    use super::*;
    use crate::solve::{Elements, SpringElem};

    /// A grid of `nx` x `ny` vertices joined by springs along and across its cells, and a
    /// symmetric matrix on that pattern: a Laplacian per coordinate less a spread of shifts
    /// (some eigenvalues negative), with a weak coupling between coordinates.
    fn indefinite(nx: usize, ny: usize) -> (Pattern, Vec<f64>) {
        let x: Vec<glam::DVec3> =
            (0..nx * ny).map(|i| glam::DVec3::new((i % nx) as f64, (i / nx) as f64, 0.0)).collect();
        let mut springs = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let v = (j * nx + i) as u32;
                for (di, dj) in [(1, 0), (0, 1), (1, 1)] {
                    if i + di < nx && j + dj < ny {
                        springs.push(SpringElem { v: [v, ((j + dj) * nx + i + di) as u32], k: 1.0 });
                    }
                }
            }
        }
        let p = Pattern::build(&x, &vec![[false; 3]; nx * ny], &[], &Elements { springs, ..Default::default() });
        let mut h = vec![0.0; p.nnz()];
        for c in 0..p.n {
            let span = p.col_ptr[c] as usize..p.col_ptr[c + 1] as usize;
            for (&r, v) in p.row_idx[span.clone()].iter().zip(&mut h[span]) {
                let r = r as usize;
                *v = if r == c {
                    6.0 - 7.0 * (((c * 7919) % 97) as f64 / 97.0)
                } else if r % 3 == c % 3 {
                    -1.0
                } else {
                    0.05
                };
            }
        }
        (p, h)
    }

    fn dense(p: &Pattern, h: &[f64]) -> Mat<f64> {
        let mut a = Mat::zeros(p.n, p.n);
        for c in 0..p.n {
            let span = p.col_ptr[c] as usize..p.col_ptr[c + 1] as usize;
            for (&r, &v) in p.row_idx[span.clone()].iter().zip(&h[span]) {
                let r = r as usize;
                a[(r, c)] = v;
                a[(c, r)] = v;
            }
        }
        a
    }

    fn quadratic(a: &Mat<f64>, x: &[f64], y: &[f64]) -> f64 {
        (0..x.len()).map(|i| (0..y.len()).map(|j| x[i] * a[(i, j)] * y[j]).sum::<f64>()).sum()
    }

    /// Issue 67 item 6: every negative pivot's direction has the pivot as its curvature, the
    /// directions are conjugate, and together they span as many dimensions of negative curvature
    /// as H has negative eigenvalues (a dense eigen-solve); the lowest curvature in their span
    /// lies at or above H's lowest eigenvalue.
    #[test]
    fn negative_pivots_give_conjugate_directions_of_negative_curvature() {
        for (nx, ny, supernodal) in [(3, 2, false), (12, 10, false), (12, 10, true)] {
            let (p, h) = indefinite(nx, ny);
            let mut chol = CholeskySolver::analyze(&p);
            if supernodal {
                let sym = SymbolicSparseColMatRef::new_checked(p.n, p.n, &p.col_ptr, None, &p.row_idx);
                let params = CholeskySymbolicParams {
                    supernodal_flop_ratio_threshold: faer::sparse::linalg::SupernodalThreshold::FORCE_SUPERNODAL,
                    ..Default::default()
                };
                chol.symbolic = factorize_symbolic_cholesky(sym, Side::Lower, SymmetricOrdering::Amd, params).unwrap();
            }
            let negative = chol.inertia(&p, &h).expect("no zero pivot");
            let a = dense(&p, &h);
            let eigen = a.self_adjoint_eigen(Side::Lower).unwrap();
            let values: Vec<f64> = (0..p.n).map(|i| eigen.S()[i]).collect();
            let expected = values.iter().filter(|&&v| v < 0.0).count();
            assert_eq!(negative, expected, "{nx} x {ny}: Sylvester's law");
            assert!(negative >= 2, "{nx} x {ny}: the test needs several negative modes");
            assert_eq!(supernodal, matches!(chol.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)));
            let dirs = chol.negative_pivot_directions(usize::MAX);
            assert_eq!(dirs.len(), negative);
            let mut pivots: Vec<f64> = chol.negative_pivots.iter().map(|&k| chol.ldl[k]).collect();
            pivots.sort_by(f64::total_cmp);
            let scale = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (i, d) in dirs.iter().enumerate() {
                let curvature = quadratic(&a, d, d);
                assert!(curvature < 0.0, "{nx} x {ny} (supernodal {supernodal}): pivot {i}");
                assert!((curvature - pivots[i]).abs() < 1e-9 * scale * quadratic(&Mat::identity(p.n, p.n), d, d));
                for e in &dirs[..i] {
                    let cross = quadratic(&a, d, e);
                    assert!(
                        cross.abs()
                            < 1e-9
                                * scale
                                * (d.iter().map(|v| v * v).sum::<f64>() * e.iter().map(|v| v * v).sum::<f64>()).sqrt()
                    );
                }
            }
            let mut apply = |x: &[f64], y: &mut [f64]| symmetric_product_into(&p.col_ptr, &p.row_idx, &h, x, y);
            let (lowest, v) = super::super::eigen::lowest_in_span(dirs.clone(), &mut apply).unwrap();
            assert!(lowest < 0.0 && lowest >= values[0] - 1e-9 * scale, "{lowest} against {}", values[0]);
            assert!((quadratic(&a, &v, &v) - lowest).abs() < 1e-9 * scale);
            println!(
                "{nx} x {ny}: {negative} negative, supernodal {supernodal}, span's lowest {lowest:.4} against {:.4}",
                values[0]
            );
        }
    }

    /// `StabilityTest::FactorModes`: the verdict's direction comes from the factor (no LOBPCG
    /// iteration) and has the verdict's negative curvature; the default test's LOBPCG finds one
    /// at least as negative.
    #[test]
    fn the_factor_modes_verdict_needs_no_eigen_solver() {
        let (p, h) = indefinite(12, 10);
        let a = dense(&p, &h);
        let mut chol = CholeskySolver::analyze(&p);
        let verdict = |chol: &mut CholeskySolver, how| match super::super::stability::test(&p, chol, &h, how) {
            Some(super::super::stability::Verdict::Unstable { negative, curvature, direction, eigen_iterations }) => {
                (negative, curvature, direction, eigen_iterations)
            }
            other => panic!("{other:?}"),
        };
        let (negative, curvature, direction, iterations) = verdict(&mut chol, crate::solve::StabilityTest::FactorModes);
        assert_eq!((negative, iterations), (76, 0));
        assert!(curvature < 0.0);
        assert!((quadratic(&a, &direction, &direction) - curvature).abs() < 1e-9 * curvature.abs());
        let (_, lobpcg, _, iterations) = verdict(&mut chol, crate::solve::StabilityTest::Inertia);
        assert!(iterations > 0 && lobpcg <= curvature, "{lobpcg} against {curvature}");
    }
}
