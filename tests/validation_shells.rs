//! VALIDATION.md B: shell mechanics against theory, as system tests (a World built from the
//! scenes in scenes/validation/, run through the real schedule).

mod common;

use common::*;
use glam::DVec3;
use skinsim::model::PackedIndex;
use skinsim::model::RestPos;
use skinsim::physics::{gaussian_bending, hinge, BendingElement};
use skinsim::scene::built::{BuiltDriver, LayerMesh};
use skinsim::solve::eval::vertex_gradient;
use skinsim::solve::PackedPatch;

/// Plate bending stiffness D = E h^3 / (12 (1 - nu^2)) of the first layer.
fn plate_d(scene: &skinsim::scene::BuiltScene) -> f64 {
    let l = &scene.patches[0].layers[0];
    let m = l.material.unwrap();
    skinsim::physics::plate_rigidity(m.young, l.thickness.unwrap(), m.poisson)
}

/// Hinge energy per unit area of a sheet bent into a cylinder, against Kirchhoff D / (2 R^2).
/// Measured over hinges away from the boundary (boundary edges carry none): the mesh is a
/// lattice with one edge per direction per cell, so the energy per area is the sum over edge
/// directions of the mean of W / A_bar (A_bar, the hinge's two faces, is one cell).
/// `jitter` moves interior vertices by up to that fraction of the spacing (seeded): an
/// irregular mesh whose edges are grouped by their direction before the jitter.
fn cylinder_error(mut scene: skinsim::scene::BuiltScene, axis: usize, jitter: f64) -> f64 {
    for d in &mut scene.patches[0].drivers {
        if let BuiltDriver::Bend { axis: a, .. } = d {
            *a = axis;
        }
    }
    let LayerMesh::Surface(m) = &mut scene.patches[0].layers[0].mesh else { unreachable!() };
    let lattice = m.rest.clone();
    let (lo, hi) = lattice.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
    jitter_interior(m, jitter);
    let rest_mesh = m.rest.clone();
    let d = plate_d(&scene);
    let BuiltDriver::Bend { keyframes, .. } = &scene.patches[0].drivers[1] else { unreachable!() };
    let r = 1.0 / keyframes[0].1;
    let (mut sim, _) = run(&scene);
    let mut q = sim.world.query::<&PackedPatch>();
    let body = q.single(&sim.world).unwrap();
    // One layer: packed vertex i is mesh vertex i.
    let margin = 3e-3;
    let inside = |p: DVec3| p.x > lo.x + margin && p.x < hi.x - margin && p.y > lo.y + margin && p.y < hi.y - margin;
    let mut by_direction: std::collections::BTreeMap<i64, (f64, usize)> = Default::default();
    for h in &body.elements.hinges {
        let (a, b) = (lattice[h.v[0] as usize], lattice[h.v[1] as usize]);
        if !inside(0.5 * (a + b)) {
            continue;
        }
        let e = b - a;
        let direction = e.y.atan2(e.x).to_degrees().rem_euclid(180.0).round() as i64 % 180;
        let x = h.v.map(|v| body.state.x[v as usize]);
        let w = hinge::energy(h.model, &h.rest, &x);
        let tri = |a: u32, b: u32, c: u32| {
            let p = |i: u32| rest_mesh[i as usize];
            0.5 * (p(b) - p(a)).cross(p(c) - p(a)).length()
        };
        let a_bar = tri(h.v[0], h.v[1], h.v[2]) + tri(h.v[1], h.v[0], h.v[3]);
        let entry = by_direction.entry(direction).or_default();
        entry.0 += w / a_bar;
        entry.1 += 1;
    }
    assert!(by_direction.len() == 3, "{by_direction:?}");
    let measured: f64 = by_direction.values().map(|(s, n)| s / *n as f64).sum();
    rel(measured, d / (2.0 * r * r))
}

/// Moves the interior vertices of a lattice in mm by up to `jitter` of a millimetre (seeded,
/// the boundary kept), material coordinates along.
fn jitter_interior(m: &mut skinsim::mesh::SurfaceMesh, jitter: f64) {
    let (lo, hi) = m.rest.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
    if jitter <= 0.0 {
        return;
    }
    for (i, p) in m.rest.iter_mut().enumerate() {
        if p.x > lo.x + 1e-9 && p.x < hi.x - 1e-9 && p.y > lo.y + 1e-9 && p.y < hi.y - 1e-9 {
            let s = (i as f64 * 12.9898).sin() * 43758.5453;
            let t = (i as f64 * 78.233).sin() * 12345.678;
            p.x += 1e-3 * jitter * (2.0 * s.fract().abs() - 1.0);
            p.y += 1e-3 * jitter * (2.0 * t.fract().abs() - 1.0);
            m.uv[i] = p.truncate();
        }
    }
}

/// The same cylinder, either element, on a mesh jittered and/or stretched along x (`stretch`
/// < 1: short edges along x): energy per unit area away from the boundary. Quadratic: sum of
/// W_v over sum of M_v; hinge: sum of W over sum of a third of each hinge's two faces.
fn cylinder_error_by_area(
    mut scene: skinsim::scene::BuiltScene,
    axis: usize,
    jitter: f64,
    stretch: f64,
    element: BendingElement,
) -> f64 {
    scene.patches[0].layers[0].bending.as_mut().unwrap().element = element;
    for d in &mut scene.patches[0].drivers {
        if let BuiltDriver::Bend { axis: a, .. } = d {
            *a = axis;
        }
    }
    let LayerMesh::Surface(m) = &mut scene.patches[0].layers[0].mesh else { unreachable!() };
    let (lo, hi) = m.rest.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
    jitter_interior(m, jitter);
    for (i, p) in m.rest.iter_mut().enumerate() {
        p.x = lo.x + stretch * (p.x - lo.x);
        m.uv[i] = p.truncate();
    }
    let hi = DVec3::new(lo.x + stretch * (hi.x - lo.x), hi.y, hi.z);
    let rest = m.rest.clone();
    let d = plate_d(&scene);
    let BuiltDriver::Bend { keyframes, .. } = &scene.patches[0].drivers[1] else { unreachable!() };
    let r = 1.0 / keyframes[0].1;
    let (mut sim, _) = run(&scene);
    let mut q = sim.world.query::<&PackedPatch>();
    let body = q.single(&sim.world).unwrap();
    let quad = &body.elements.quadratic;
    let margin = 0.15 * (hi - lo);
    let inside =
        |p: DVec3| p.x > lo.x + margin.x && p.x < hi.x - margin.x && p.y > lo.y + margin.y && p.y < hi.y - margin.y;
    let (mut energy, mut area) = (0.0, 0.0);
    for i in (0..quad.len()).filter(|&i| inside(rest[quad.stencil(i).0[0] as usize])) {
        energy += quad.element_energy(i, &body.state.x);
        area += quad.area[i];
    }
    // The quadratic element's Gaussian term: the corners at vertices inside (K = 0 on a
    // cylinder, so it adds only the discretization's defects).
    for g in &body.elements.gaussian {
        let corners = gaussian_bending::corner_energies(g, &g.v.map(|v| body.state.x[v as usize]));
        energy += (0..3).filter(|&k| inside(rest[g.v[k] as usize])).map(|k| corners[k]).sum::<f64>();
    }
    for h in body.elements.hinges.iter().filter(|h| inside(0.5 * (rest[h.v[0] as usize] + rest[h.v[1] as usize]))) {
        let p = h.v.map(|v| rest[v as usize]);
        energy += hinge::energy(h.model, &h.rest, &h.positions(&body.state.x));
        area += ((p[1] - p[0]).cross(p[2] - p[0]).length() + (p[1] - p[0]).cross(p[3] - p[0]).length()) / 6.0;
    }
    rel(energy / area, d / (2.0 * r * r))
}

#[test]
fn case5_cylinder_bending_energy() {
    let eq = load("validation/cylinder_equilateral.ron");
    for axis in [0, 1] {
        let err = cylinder_error(eq.clone(), axis, 0.0);
        println!("case 5: equilateral mesh, cylinder axis {axis}: error {:+.3} %", 100.0 * err);
        assert!(err.abs() < 0.01, "equilateral axis {axis}: {err}");
    }
    let rt = load("validation/cylinder_righttriangle.ron");
    for axis in [0, 1] {
        let err = cylinder_error(rt.clone(), axis, 0.0);
        println!(
            "case 5: right-triangle mesh, cylinder axis {axis}: error {:+.3} % (mesh-dependent, reported)",
            100.0 * err
        );
        assert!(err > -0.30 && err < 0.05, "right-triangle hinge error outside the documented range: {err}");
    }
    let err = cylinder_error(eq.clone(), 1, 0.25);
    println!("case 5: jittered equilateral mesh (25 % of the spacing): error {:+.3} % (reported)", 100.0 * err);
    assert!(err.abs() < 0.5);
    // The quadratic element (PHYSICS.md 1.2's mesh dependence is the hinge's): within 1 % on
    // the lattices and the jittered mesh, both axes, and on a 4:1 anisotropic mesh whose short
    // edges run across the cylinder axis (as the remesher makes them across wrinkles). The
    // hinge on that mesh is reported: it holds less energy there, as in the adaptive LK14 runs.
    let quadratic = BendingElement::Quadratic;
    for (name, scene, jitter) in [("equilateral", &eq, 0.0), ("right-triangle", &rt, 0.0), ("jittered", &eq, 0.25)] {
        for axis in [0, 1] {
            let err = cylinder_error_by_area(scene.clone(), axis, jitter, 1.0, quadratic);
            println!("case 5: quadratic element, {name} mesh, cylinder axis {axis}: error {:+.3} %", 100.0 * err);
            assert!(err.abs() < 0.01, "quadratic, {name}, axis {axis}: {err}");
        }
    }
    for (name, scene) in [("equilateral", &eq), ("right-triangle", &rt)] {
        let hinge = cylinder_error_by_area(scene.clone(), 1, 0.0, 0.25, BendingElement::Hinge);
        let err = cylinder_error_by_area(scene.clone(), 1, 0.0, 0.25, quadratic);
        println!(
            "case 5: {name} mesh stretched 1:4 across the axis: hinge {:+.3} %, quadratic {:+.3} %",
            100.0 * hinge,
            100.0 * err
        );
        assert!(err.abs() < 0.01, "quadratic, anisotropic {name}: {err}");
    }
}

/// Complete elliptic integrals K(k), E(k) by the arithmetic-geometric mean.
fn elliptic(k: f64) -> (f64, f64) {
    let (mut a, mut b, mut c) = (1.0f64, (1.0 - k * k).sqrt(), k);
    let mut sum = 0.5 * c * c;
    let mut pow = 0.5;
    for _ in 0..30 {
        let (an, bn, cn) = ((a + b) / 2.0, (a * b).sqrt(), (a - b) / 2.0);
        a = an;
        b = bn;
        c = cn;
        pow *= 2.0;
        sum += pow * c * c;
    }
    let kk = std::f64::consts::PI / (2.0 * a);
    (kk, kk * (1.0 - sum))
}

/// Elastica for a given end shortening: (P / P_cr, w / L, theta0), by bisection on k.
fn elastica(shortening: f64) -> (f64, f64, f64) {
    let (mut lo, mut hi) = (1e-9, 1.0 - 1e-12);
    for _ in 0..200 {
        let k = 0.5 * (lo + hi);
        let (kk, ee) = elliptic(k);
        if 2.0 * (1.0 - ee / kk) < shortening {
            lo = k;
        } else {
            hi = k;
        }
    }
    let k = 0.5 * (lo + hi);
    let (kk, _) = elliptic(k);
    let p = (2.0 * kk / std::f64::consts::PI).powi(2);
    (p, k / kk, 2.0 * k.asin())
}

/// End force per unit width at the x-max end and midspan deflection, both from the World.
fn strip_measures(sim: &mut skinsim_systems::Simulation) -> (f64, f64, f64) {
    let mut q = sim.world.query::<(&PackedPatch, &PackedIndex)>();
    let (body, index) = q.single(&sim.world).unwrap();
    let rest: Vec<DVec3> = index.vertices.iter().map(|e| sim.world.get::<RestPos>(*e).unwrap().0).collect();
    let (lo, hi) = rest.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
    let g = vertex_gradient(&body.elements, &body.state.x);
    // Every vertex whose x is held on the x-max half carries part of the end force.
    let held: Vec<bool> = body.state.fixed.iter().map(|f| f[0]).collect();
    let mid = 0.5 * (lo.x + hi.x);
    let force: f64 =
        rest.iter().zip(&g).zip(&held).filter(|((p, _), h)| **h && p.x > mid).map(|((_, g), _)| -g.x).sum();
    let width = hi.y - lo.y;
    let deflection = body.state.x.iter().map(|p| p.z.abs()).fold(0.0, f64::max);
    (force / width, deflection, hi.x - lo.x)
}

#[test]
fn case6_euler_buckling_pinned_critical_load_and_post_buckling() {
    let scene = load("validation/euler_pinned.ron");
    let d = plate_d(&scene);
    let BuiltDriver::Compress { keyframes, .. } = &scene.patches[0].drivers[2] else { unreachable!() };
    let keys = keyframes.clone();
    let mut sim = skinsim_systems::Simulation::new(&scene);
    let mut checked = 0;
    for frame in 1..=scene.scene.frames {
        let stats = sim.step();
        assert!(stats.patches[0].outcome.converged, "frame {frame} did not converge: {:?}", stats.patches[0]);
        let Some(&(_, shortening)) = keys.iter().find(|k| k.0 == frame) else { continue };
        let (p, w, l) = strip_measures(&mut sim);
        let p_cr = std::f64::consts::PI.powi(2) * d / (l * l);
        let (p_theory, w_theory, theta0) = elastica(shortening);
        let (ep, ew) = (rel(p / p_cr, p_theory), rel(w / l, w_theory));
        println!(
            "case 6 pinned: Delta/L {shortening:.4} (theta0 {:.1} deg): P/Pcr {:.5} vs {:.5} ({:+.3} %), w/L {:.5} vs {:.5} ({:+.3} %)",
            theta0.to_degrees(), p / p_cr, p_theory, 100.0 * ep, w / l, w_theory, 100.0 * ew
        );
        if frame == 1 {
            assert!(ep.abs() < 0.01, "critical load off by {ep}");
        } else {
            assert!(ep.abs() < 0.005, "P/Pcr off by {ep} at Delta/L {shortening}");
            assert!(ew.abs() < 0.005, "w/L off by {ew} at Delta/L {shortening}");
        }
        checked += 1;
    }
    assert_eq!(checked, 4);
}

#[test]
fn case6_euler_buckling_clamped_critical_load() {
    let scene = load("validation/euler_clamped.ron");
    let d = plate_d(&scene);
    let (mut sim, stats) = run(&scene);
    assert!(stats.iter().all(|s| s.patches[0].outcome.converged));
    let (p, _, l) = strip_measures(&mut sim);
    // The held end cells are flat; the first free hinge lumps the curvature of half a cell on
    // each side, so the clamp acts at the centre of the held cell: span = L - one cell (0.5 mm).
    let l = l - 0.5e-3;
    let p_cr = 4.0 * std::f64::consts::PI.powi(2) * d / (l * l);
    let (p_theory, _, _) = elastica(1e-3);
    let err = rel(p / p_cr, p_theory);
    println!("case 6 clamped: P/Pcr {:.5} vs {:.5} ({:+.3} %)", p / p_cr, p_theory, 100.0 * err);
    assert!(err.abs() < 0.01, "clamped critical load off by {err}");
}

/// Hard case: a perfect strip (no imperfection at all) compressed past the buckling load sits
/// on an unstable straight equilibrium; the stability check must leave it and find the buckled
/// state, whose end force is the critical load.
#[test]
fn a_perfect_strip_still_buckles() {
    let mut scene = load("validation/euler_pinned.ron");
    scene.patches[0].perturbation = None;
    let d = plate_d(&scene);
    let mut sim = skinsim_systems::Simulation::new(&scene);
    let stats = sim.step();
    assert!(stats.patches[0].outcome.converged, "{:?}", stats.patches[0]);
    assert!(stats.patches[0].outcome.escapes >= 1, "the straight state was accepted");
    let (p, w, l) = strip_measures(&mut sim);
    let p_cr = std::f64::consts::PI.powi(2) * d / (l * l);
    let (p_theory, w_theory, _) = elastica(1e-3);
    println!("perfect strip: P/Pcr {:.5} (theory {p_theory:.5}), w/L {:.5} (theory {w_theory:.5})", p / p_cr, w / l);
    assert!(rel(p / p_cr, p_theory).abs() < 0.01);
    assert!(rel(w / l, w_theory).abs() < 0.01);
}

/// Issue 21: the strip compressed in 40 equal increments to 4x its critical strain must leave
/// the straight state at the first increment past the critical load: no frame's end force more
/// than 2 % above P_cr (on the straight state it grows with the strain; buckled, it stays near
/// P_cr), and the strip buckled by the end. Before the inertia-based stability test the
/// straight state was kept to 1.6-1.8 P_cr.
fn fine_increments(name: &str, clamped: bool) {
    let mut scene = load(name);
    let d = plate_d(&scene);
    let layer = &scene.patches[0].layers[0];
    let (young, nu) = (layer.material.unwrap().young, layer.material.unwrap().poisson);
    let h = layer.thickness.unwrap();
    let LayerMesh::Surface(mesh) = &layer.mesh else { unreachable!() };
    let l_full = skinsim::mesh::bounds(&mesh.rest).1.x - skinsim::mesh::bounds(&mesh.rest).0.x;
    let l = if clamped { l_full - 0.5e-3 } else { l_full };
    let p_cr = if clamped { 4.0 } else { 1.0 } * std::f64::consts::PI.powi(2) * d / (l * l);
    // Straight state: P = E h eps / (1 - nu^2) (plane strain), so eps_cr = P_cr (1 - nu^2) / (E h).
    let eps_cr = p_cr * (1.0 - nu * nu) / (young * h);
    let frames = 40;
    for drv in &mut scene.patches[0].drivers {
        if let BuiltDriver::Compress { keyframes, .. } = drv {
            *keyframes = vec![(1, 0.1 * eps_cr * l_full / l), (frames, 4.0 * eps_cr * l_full / l)];
        }
    }
    scene.scene.frames = frames;
    let mut sim = skinsim_systems::Simulation::new(&scene);
    let mut worst: f64 = 0.0;
    let mut deflection = 0.0;
    for frame in 1..=frames {
        let stats = sim.step();
        assert!(stats.patches[0].outcome.converged, "{name} frame {frame} did not converge: {:?}", stats.patches[0]);
        let (p, w, _) = strip_measures(&mut sim);
        println!(
            "{name} frame {frame}: eps/eps_cr {:.2}, P/Pcr {:.4}, w/L {:.2e}",
            0.1 * frame as f64,
            p / p_cr,
            w / l
        );
        worst = worst.max(p / p_cr);
        deflection = w / l;
    }
    assert!(worst < 1.02, "{name}: the straight state was kept to {worst:.3} P_cr");
    assert!(deflection > 1e-4, "{name}: not buckled at 4 eps_cr (w/L {deflection:.2e})");
}

#[test]
fn fine_increments_buckle_at_the_critical_load_pinned() {
    fine_increments("validation/euler_pinned.ron", false);
}

#[test]
fn fine_increments_buckle_at_the_critical_load_clamped() {
    fine_increments("validation/euler_clamped.ron", true);
}

/// The strip's exact Hessian on its straight state at `ratio` x the critical strain (stability
/// check off, no imperfection: it stays straight), with its pattern.
fn straight_strip_hessian(ratio: f64) -> (skinsim::solve::pattern::Pattern, Vec<f64>) {
    let mut scene = load("validation/euler_pinned.ron");
    scene.patches[0].perturbation = None;
    scene.patches[0].solver.stability_check = false;
    let layer = &scene.patches[0].layers[0];
    let h = layer.thickness.unwrap();
    let LayerMesh::Surface(mesh) = &layer.mesh else { unreachable!() };
    let l = skinsim::mesh::bounds(&mesh.rest).1.x - skinsim::mesh::bounds(&mesh.rest).0.x;
    let eps_cr = std::f64::consts::PI.powi(2) * h * h / (12.0 * l * l);
    for drv in &mut scene.patches[0].drivers {
        if let BuiltDriver::Compress { keyframes, .. } = drv {
            *keyframes = vec![(1, ratio * eps_cr)];
        }
    }
    let mut sim = skinsim_systems::Simulation::new(&scene);
    assert!(sim.step().patches[0].outcome.converged);
    let mut q = sim.world.query::<&PackedPatch>();
    let packed = q.single(&sim.world).unwrap();
    let s = &packed.state;
    let pattern = skinsim::solve::pattern::Pattern::build(&s.x, &s.fixed, &s.tie, &packed.elements);
    let (mut grad, mut values) = (vec![0.0; pattern.n], vec![0.0; pattern.nnz()]);
    skinsim::solve::eval::assemble(
        &packed.elements,
        &pattern,
        &s.x,
        skinsim::physics::psd::Filter::Exact,
        &mut grad,
        &mut values,
    );
    (pattern, values)
}

/// The dense spectrum (nondecreasing) and the lowest eigenvector of a pattern's matrix.
fn dense_spectrum(p: &skinsim::solve::pattern::Pattern, values: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut a = faer::Mat::<f64>::zeros(p.n, p.n);
    for c in 0..p.n {
        let span = p.col_ptr[c] as usize..p.col_ptr[c + 1] as usize;
        for (&r, &v) in p.row_idx[span.clone()].iter().zip(&values[span]) {
            a[(r as usize, c)] = v;
            a[(c, r as usize)] = v;
        }
    }
    let e = a.self_adjoint_eigen(faer::Side::Lower).unwrap();
    ((0..p.n).map(|i| e.S()[i]).collect(), (0..p.n).map(|i| e.U()[(i, 0)]).collect())
}

/// Issue 21: the inertia test's verdict, curvature and direction against a dense eigen-solve of
/// the strip's exact Hessian: stable below the critical load, one eigenvalue barely below zero
/// just past it (about 1e-12 of the mean diagonal), two past the second critical load.
#[test]
fn the_inertia_test_agrees_with_a_dense_eigen_solve() {
    use skinsim::solve::stability::{test, Verdict};
    for (ratio, expected) in [(0.9, 0), (1.02, 1), (4.2, 2)] {
        let (pattern, values) = straight_strip_hessian(ratio);
        let (spectrum, lowest) = dense_spectrum(&pattern, &values);
        let negative = spectrum.iter().filter(|l| **l < 0.0).count();
        let mean_diag = pattern.diag.iter().map(|&d| values[d as usize].abs()).sum::<f64>() / pattern.n as f64;
        println!(
            "{ratio} eps_cr: {negative} negative, lowest {:.3e} ({:.2e} of the mean diagonal)",
            spectrum[0],
            spectrum[0] / mean_diag
        );
        assert_eq!(negative, expected, "the dense spectrum at {ratio} eps_cr");
        let mut chol = skinsim::solve::linear::CholeskySolver::analyze(&pattern);
        match test(&pattern, &mut chol, &values, skinsim::solve::StabilityTest::Inertia).expect("an LDL^T") {
            Verdict::Stable => assert_eq!(expected, 0, "{ratio} eps_cr: called stable"),
            Verdict::Unstable { negative: k, curvature, direction, .. } => {
                assert_eq!(k, expected, "{ratio} eps_cr: inertia");
                assert!((curvature - spectrum[0]).abs() < 1e-3 * spectrum[0].abs(), "{curvature} vs {}", spectrum[0]);
                let overlap: f64 = direction.iter().zip(&lowest).map(|(a, b)| a * b).sum();
                assert!(overlap.abs() > 0.999, "{ratio} eps_cr: direction overlap {overlap}");
            }
        }
    }
}
