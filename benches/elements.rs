//! Element kernels: energy + gradient + (projected) Hessian per second, one thread.
//! Target (issue 2): at least 300k projected membrane Hessians per second per core.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::{DMat2, DMat3, DVec3};
use skinsim::physics::hinge::{self, HingeModel, HingeRest};
use skinsim::physics::membrane::{self, MembraneRest};
use skinsim::physics::psd::Filter;
use skinsim::physics::tet::{self, TetRest};
use skinsim::physics::{ConstitutiveModel as M, Lame};

/// A spread of states, from stretched to strongly compressed (compressed ones need projection).
fn triangles() -> Vec<[DVec3; 3]> {
    (0..64)
        .map(|i| {
            let s = 0.6 + 0.8 * (i as f64 / 63.0);
            let t = (i as f64 * 0.7).sin() * 0.2;
            [DVec3::ZERO, DVec3::new(1e-3 * s, 0.0, 1e-4 * t), DVec3::new(0.4e-3, 0.9e-3 * (2.0 - s), 1e-4 * t)]
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let rest_tri = [DVec3::ZERO, DVec3::new(1e-3, 0.0, 0.0), DVec3::new(0.5e-3, 0.866e-3, 0.0)];
    let mrest = MembraneRest::from_rest_triangle(rest_tri, 1e-4, DMat2::IDENTITY).unwrap();
    let lame = Lame::plane_stress(1e7, 0.3);
    let tris = triangles();
    let mut g = c.benchmark_group("membrane");
    g.throughput(Throughput::Elements(tris.len() as u64));
    for model in [M::BazantHencky, M::StableNeoHookean, M::StVenantKirchhoff, M::Corotational] {
        for filter in [Filter::Exact, Filter::Clamp] {
            g.bench_with_input(BenchmarkId::new(format!("{model:?}"), format!("{filter:?}")), &filter, |b, &f| {
                b.iter(|| tris.iter().map(|x| membrane::eval(model, lame, &mrest, x, f).0).sum::<f64>())
            });
        }
    }
    g.finish();

    let quad = [DVec3::ZERO, DVec3::new(1e-3, 0.0, 0.0), DVec3::new(0.4e-3, 1e-3, 0.0), DVec3::new(0.6e-3, -1e-3, 0.0)];
    let hinges: Vec<[DVec3; 4]> = (0..64)
        .map(|i| {
            let a = -1.0 + 2.0 * i as f64 / 63.0;
            let mut q = quad;
            q[3] = DVec3::new(0.6e-3, -1e-3 * a.cos(), -1e-3 * a.sin());
            q
        })
        .collect();
    let mut g = c.benchmark_group("hinge");
    g.throughput(Throughput::Elements(hinges.len() as u64));
    let hrest = HingeRest::from_rest(HingeModel::Tan, 1e-6, quad);
    for filter in [Filter::Exact, Filter::Clamp] {
        g.bench_with_input(BenchmarkId::new("Tan", format!("{filter:?}")), &filter, |b, &f| {
            b.iter(|| hinges.iter().map(|x| hinge::eval(HingeModel::Tan, &hrest, x, f).0).sum::<f64>())
        });
    }
    g.finish();

    let tet4 =
        [DVec3::ZERO, DVec3::new(1e-3, 0.0, 0.0), DVec3::new(0.3e-3, 1e-3, 0.0), DVec3::new(0.2e-3, 0.3e-3, 1e-3)];
    let trest = TetRest::from_rest(tet4, DMat3::IDENTITY).unwrap();
    let tets: Vec<[DVec3; 4]> = (0..64)
        .map(|i| {
            let s = 0.6 + 0.8 * (i as f64 / 63.0);
            [tet4[0], tet4[1] * s, tet4[2], tet4[3] * (2.0 - s)]
        })
        .collect();
    let lame = Lame::solid(1e4, 0.45);
    let mut g = c.benchmark_group("tet");
    g.throughput(Throughput::Elements(tets.len() as u64));
    for model in [M::BazantHencky, M::StableNeoHookean, M::StVenantKirchhoff, M::Corotational] {
        for filter in [Filter::Exact, Filter::Clamp] {
            g.bench_with_input(BenchmarkId::new(format!("{model:?}"), format!("{filter:?}")), &filter, |b, &f| {
                b.iter(|| tets.iter().map(|x| tet::eval(model, lame, &trest, x, f).0).sum::<f64>())
            });
        }
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).warm_up_time(std::time::Duration::from_millis(300)).measurement_time(std::time::Duration::from_secs(1));
    targets = bench
}
criterion_main!(benches);
