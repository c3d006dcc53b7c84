//! Remeshing cost against mesh size (issue 5: no O(n^2) rescans). A wavy sheet, uniform
//! n x n cells, remeshed once: the work is one sizing pass, refinement where the waves curve and
//! coarsening where they are flat. Time per input vertex should stay flat as n grows.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::{DVec2, DVec3};
use skinsim::mesh::remesh::{remesh, RemeshParams, RemeshVertex};
use skinsim::mesh::{grid, GridPattern};

fn sheet(n: u32) -> (Vec<RemeshVertex>, Vec<[u32; 3]>) {
    let m = grid(DVec2::splat(0.02), (n, n), GridPattern::Equilateral, 0.0);
    // Waves of 4 mm over the left half, flat on the right.
    let wave = |u: DVec2| {
        let z = if u.x < 0.01 { 2e-4 * (u.x * std::f64::consts::TAU / 4e-3).sin() } else { 0.0 };
        DVec3::new(u.x, u.y, z)
    };
    let verts =
        m.uv.iter()
            .zip(&m.rest)
            .map(|(&uv, &rest)| RemeshVertex { uv, x: wave(uv), v: DVec3::ZERO, rest, fixed: [false; 3], origin: None })
            .collect();
    (verts, m.faces)
}

fn bench(c: &mut Criterion) {
    let p = RemeshParams {
        size_min: 0.1e-3,
        size_max: 2e-3,
        aspect_min: 0.2,
        refine_angle: 0.3,
        refine_compression: 1e-5,
        refine_velocity: None,
        curved_splits: true,
    };
    let mut g = c.benchmark_group("remesh");
    g.sample_size(10);
    for n in [40u32, 80, 160] {
        let (v, f) = sheet(n);
        g.throughput(Throughput::Elements(v.len() as u64));
        g.bench_with_input(BenchmarkId::from_parameter(v.len()), &(v, f), |b, (v, f)| {
            b.iter(|| remesh(v, f, &p).vertices.len())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
