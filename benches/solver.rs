//! Assembly and factorization against DOF count (1k to 200k DOFs) on a shell grid, and one full
//! Newton iteration (assemble + factorize + solve + line search) on a 100k-DOF patch.
//! Targets (issue 2): numeric refactorization of a 100k-DOF shell Hessian (cached symbolic)
//! under 0.3 s; a Newton iteration on 100k DOFs under 0.6 s; peak memory under 2 GB.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::{DVec2, DVec3};
use skinsim::mesh::{grid, GridPattern};
use skinsim::physics::psd::Filter;
use skinsim::physics::{ConstitutiveModel, HingeModel, Lame};
use skinsim::solve::eval::assemble;
use skinsim::solve::linear::CholeskySolver;
use skinsim::solve::pattern::Pattern;
use skinsim::solve::SolverSettings;
use skinsim::solve::{solve_frame, PackedPatch};

/// A square film with about `dofs` free DOFs, clamped on its x sides, slightly compressed
/// and perturbed so that elements are in a generic (projected) state.
pub fn film(dofs: usize) -> PackedPatch {
    let side = ((dofs as f64 / 3.0).sqrt().ceil() as u32).max(4);
    let mut m = grid(DVec2::new(0.02, 0.02), (side, side), GridPattern::RightTriangle, 0.0);
    for (i, p) in m.rest.iter_mut().enumerate() {
        p.z = 1e-5 * ((i as f64) * 0.37).sin();
    }
    let young = 1e7;
    let h = 1e-4;
    let d = young * h * h * h / (12.0 * 0.91);
    let mut packed = PackedPatch::from_shell(
        &m,
        ConstitutiveModel::BazantHencky,
        Lame::plane_stress(young, 0.3),
        h,
        Some((HingeModel::Tan, d / 6.0)),
        |p| {
            let held = p.x <= 1e-12 || p.x >= 0.02 - 1e-12;
            [held; 3]
        },
    );
    for p in packed.state.x.iter_mut() {
        p.x = 0.01 + (p.x - 0.01) * 0.99;
    }
    packed
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("assemble_and_factorize");
    g.sample_size(10);
    for dofs in [1_000usize, 10_000, 50_000, 100_000, 200_000] {
        let packed = film(dofs);
        let pattern = Pattern::build(&packed.state.x, &packed.state.fixed, &packed.state.tie, &packed.elements);
        let mut chol = CholeskySolver::analyze(&pattern);
        let mut grad = vec![0.0; pattern.n];
        let mut values = vec![0.0; pattern.nnz()];
        g.bench_with_input(BenchmarkId::new("assemble", pattern.n), &(), |b, _| {
            b.iter(|| assemble(&packed.elements, &pattern, &packed.state.x, Filter::Clamp, &mut grad, &mut values))
        });
        assemble(&packed.elements, &pattern, &packed.state.x, Filter::Clamp, &mut grad, &mut values);
        g.bench_with_input(BenchmarkId::new("refactorize", pattern.n), &(), |b, _| {
            b.iter(|| chol.factorize(&pattern, &values).unwrap())
        });
    }
    g.finish();

    let mut g = c.benchmark_group("newton_iteration");
    g.sample_size(10);
    let settings = SolverSettings { max_iterations: 1, tolerance: 1e-30, ..Default::default() };
    for dofs in [10_000usize, 100_000] {
        let mut packed = film(dofs);
        solve_frame(&mut packed, &settings, 1.0).unwrap(); // pattern and symbolic factorization
        let x0 = packed.state.x.clone();
        g.bench_with_input(BenchmarkId::new("full", dofs), &(), |b, _| {
            b.iter(|| {
                packed.state.x.copy_from_slice(&x0);
                solve_frame(&mut packed, &settings, 1.0).unwrap()
            })
        });
    }
    g.finish();
    if let Ok(status) = std::fs::read_to_string("/proc/self/status") {
        if let Some(line) = status.lines().find(|l| l.starts_with("VmHWM")) {
            println!(
                "peak memory of this benchmark process (up to 200k DOFs): {}",
                line.trim_start_matches("VmHWM:").trim()
            );
        }
    }
    let _ = DVec3::ZERO;
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(std::time::Duration::from_millis(500)).measurement_time(std::time::Duration::from_secs(3));
    targets = bench
}
criterion_main!(benches);
