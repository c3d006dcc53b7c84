//! Fill-reducing orderings on the real matrices (issue 21 item 4): our geometric nested
//! dissection (`solve::ordering`), faer's AMD and METIS nested dissection (METIS_NodeND, from
//! `metis-sys` with its vendored build), each given to faer's symbolic factorization. (The
//! solver picks between ours and METIS's by these flops: `CholeskySolver::analyze`.) Prints
//! nnz(L), the factorization's flops (sum over columns of their count squared), the symbolic
//! time and the median of three numeric factorizations, per matrix:
//! - the two-layer fig. 6-3 KKT matrix (LDL^T; the multiplier rows after the Hessian's order,
//!   or ordered with it by AMD / METIS over the whole matrix),
//! - the KCK18 creature's shell Hessian and the H15 3D patch's (small) tet Hessian (LL^T of
//!   the Abs-projected Hessian).
//!
//! The LL^T matrices are also factorized in f32 (the mixed-precision factor, issue 25 item 2).
//!
//! `cargo bench --bench orderings` (scenes as arguments, e.g. `-- h15/patch_3d.ron`, to choose;
//! `--at-rest` takes the matrix before any Newton step, for patches too large to solve a frame).

use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Par, Side};
use skinsim::physics::psd::Filter;
use skinsim::solve::eval::assemble;
use skinsim::solve::pattern::{Pattern, NONE};
use skinsim::solve::PackedPatch;

/// A symmetric matrix's lower triangle (CSC) and whether it is a KKT matrix (LDL^T).
struct Matrix {
    name: String,
    n: usize,
    col_ptr: Vec<u32>,
    row_idx: Vec<u32>,
    values: Vec<f64>,
    kkt: bool,
    /// Our order: the pattern's nested dissection, then the multipliers.
    ours: Vec<u32>,
}

fn main() {
    let at_rest = std::env::args().any(|a| a == "--at-rest");
    let args: Vec<String> = std::env::args().skip(1).filter(|a| a.ends_with(".ron")).collect();
    let scenes = if args.is_empty() {
        vec![
            "lk14/fig6_3_two_layers.ron".to_string(),
            "kck18/creature.ron".to_string(),
            "h15/patch_3d_small.ron".to_string(),
        ]
    } else {
        args
    };
    println!("| matrix | n | ordering | nnz(L) | flops | symbolic (s) | factorization (ms) | f32 (ms) |");
    println!("| --- | --- | --- | --- | --- | --- | --- | --- |");
    for scene in scenes {
        let m = matrix(&scene, at_rest);
        let metis = metis_order(&m);
        for (label, order) in [("ours (geometric ND)", Some(m.ours.clone())), ("AMD", None), ("METIS ND", Some(metis))]
        {
            let (symbolic, symbolic_s) = analyze(&m, order.as_deref());
            let (nnz, flops) = fill(&symbolic);
            let ms = factorize_ms(&m, &symbolic);
            let f32_ms = if m.kkt { "-".to_string() } else { format!("{:.0}", factorize_f32_ms(&m, &symbolic)) };
            println!("| {} | {} | {label} | {nnz} | {flops:.3e} | {symbolic_s:.2} | {ms:.0} | {f32_ms} |", m.name, m.n);
        }
    }
}

/// The scene's first-frame matrix (after one frame: buckled where it buckles; `at_rest`: after
/// one Newton step, without the stability check).
fn matrix(scene: &str, at_rest: bool) -> Matrix {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(scene);
    let mut built = skinsim::scene::load(&path).expect("a valid scene");
    if at_rest {
        for patch in &mut built.patches {
            (patch.solver.max_iterations, patch.solver.stability_check) = (1, false);
        }
    }
    let mut sim = skinsim_systems::Simulation::new(&built);
    sim.step();
    let mut q = sim.world.query::<&PackedPatch>();
    let packed = q.iter(&sim.world).next().expect("a patch");
    let s = &packed.state;
    let p = Pattern::build(&s.x, &s.fixed, &s.tie, &packed.elements);
    let (mut grad, mut h) = (vec![0.0; p.n], vec![0.0; p.nnz()]);
    let kkt = !packed.constraints.is_empty();
    assemble(&packed.elements, &p, &s.x, if kkt { Filter::Exact } else { Filter::Abs }, &mut grad, &mut h);
    let name = std::path::Path::new(scene).file_stem().unwrap().to_string_lossy().to_string();
    if !kkt {
        return Matrix { name, n: p.n, col_ptr: p.col_ptr, row_idx: p.row_idx, values: h, kkt, ours: p.order };
    }
    // [[H, s J^T], [s J, -delta]], as kkt.rs factorizes it.
    let c = &packed.constraints;
    let mut jac = Vec::new();
    c.jacobian(&s.x, &mut jac);
    let (n, m) = (p.n, c.rows());
    let mean = p.diag.iter().map(|&d| h[d as usize].abs()).sum::<f64>() / n as f64;
    let scale = mean.sqrt();
    let mut by_col: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
    for (e, &(r, v, coord)) in c.entries.iter().enumerate() {
        let d = p.dof[3 * v as usize + coord as usize];
        if d != NONE {
            by_col[d as usize].push((n as u32 + r, scale * jac[e]));
        }
    }
    let (mut col_ptr, mut row_idx, mut values) = (vec![0u32], Vec::new(), Vec::new());
    for (col, extra) in by_col.iter_mut().enumerate() {
        let span = p.col_ptr[col] as usize..p.col_ptr[col + 1] as usize;
        row_idx.extend_from_slice(&p.row_idx[span.clone()]);
        values.extend_from_slice(&h[span]);
        extra.sort_by_key(|e| e.0);
        for &(r, v) in extra.iter() {
            if row_idx.last() == Some(&r) {
                *values.last_mut().unwrap() += v;
            } else {
                row_idx.push(r);
                values.push(v);
            }
        }
        col_ptr.push(row_idx.len() as u32);
    }
    for r in 0..m {
        row_idx.push((n + r) as u32);
        values.push(-1e-10 * mean);
        col_ptr.push(row_idx.len() as u32);
    }
    let ours = p.order.iter().copied().chain((n..n + m).map(|r| r as u32)).collect();
    Matrix { name: format!("{name} (KKT, {m} rows)"), n: n + m, col_ptr, row_idx, values, kkt, ours }
}

fn metis_order(m: &Matrix) -> Vec<u32> {
    skinsim::solve::ordering::metis_nested_dissection(&m.col_ptr, &m.row_idx).expect("METIS_NodeND")
}

fn analyze(m: &Matrix, order: Option<&[u32]>) -> (SymbolicCholesky<u32>, f64) {
    let sym = SymbolicSparseColMatRef::new_checked(m.n, m.n, &m.col_ptr, None, &m.row_idx);
    let clock = Instant::now();
    let symbolic = match order {
        Some(forward) => {
            let mut inverse = vec![0u32; m.n];
            for (k, &d) in forward.iter().enumerate() {
                inverse[d as usize] = k as u32;
            }
            let perm = faer::perm::PermRef::new_checked(forward, &inverse, m.n);
            factorize_symbolic_cholesky(sym, Side::Lower, SymmetricOrdering::Custom(perm), Default::default())
        }
        None => {
            factorize_symbolic_cholesky(sym, Side::Lower, SymmetricOrdering::Amd, CholeskySymbolicParams::default())
        }
    }
    .expect("symbolic factorization");
    (symbolic, clock.elapsed().as_secs_f64())
}

/// nnz(L) and the flops of the factorization (sum over columns of the column count squared).
fn fill(symbolic: &SymbolicCholesky<u32>) -> (usize, f64) {
    (symbolic.len_val(), skinsim::solve::linear::factor_flops(symbolic))
}

/// Sequential below the solver's threshold, parallel above (as `CholeskySolver` factorizes).
fn parallelism(m: &Matrix) -> Par {
    if m.n >= skinsim::solve::linear::PARALLEL_MIN_DOFS {
        Par::rayon(0)
    } else {
        Par::Seq
    }
}

/// Median of three numeric LL^T factorizations in f32 (ms).
fn factorize_f32_ms(m: &Matrix, symbolic: &SymbolicCholesky<u32>) -> f64 {
    let par = parallelism(m);
    let mut mem = MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<f32>(par, Default::default()));
    let mut l = vec![0.0f32; symbolic.len_val()];
    let values: Vec<f32> = m.values.iter().map(|&v| v as f32).collect();
    let sym = SymbolicSparseColMatRef::new_checked(m.n, m.n, &m.col_ptr, None, &m.row_idx);
    let a = SparseColMatRef::new(sym, &values[..]);
    let mut times: Vec<f64> = (0..3)
        .map(|_| {
            let clock = Instant::now();
            let stack = MemStack::new(&mut mem);
            let ok = symbolic
                .factorize_numeric_llt(&mut l, a, Side::Lower, Default::default(), par, stack, Default::default())
                .is_ok();
            assert!(ok, "{}: f32 numeric factorization", m.name);
            clock.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[1]
}

/// Median of three numeric factorizations (ms): LDL^T for a KKT matrix, LL^T otherwise.
fn factorize_ms(m: &Matrix, symbolic: &SymbolicCholesky<u32>) -> f64 {
    let par = parallelism(m);
    let req = StackReq::any_of(&[
        symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()),
        symbolic.factorize_numeric_ldlt_scratch::<f64>(par, Default::default()),
    ]);
    let mut mem = MemBuffer::new(req);
    let mut l = vec![0.0; symbolic.len_val()];
    let sym = SymbolicSparseColMatRef::new_checked(m.n, m.n, &m.col_ptr, None, &m.row_idx);
    let a = SparseColMatRef::new(sym, &m.values);
    let mut times: Vec<f64> = (0..3)
        .map(|_| {
            let clock = Instant::now();
            let stack = MemStack::new(&mut mem);
            let ok = if m.kkt {
                symbolic
                    .factorize_numeric_ldlt(&mut l, a, Side::Lower, Default::default(), par, stack, Default::default())
                    .is_ok()
            } else {
                symbolic
                    .factorize_numeric_llt(&mut l, a, Side::Lower, Default::default(), par, stack, Default::default())
                    .is_ok()
            };
            assert!(ok, "{}: numeric factorization", m.name);
            clock.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[1]
}
