//! Prestrain (H15 4.3) at system level: a uniform F0 sets the stress-free size; a rest
//! curvature sets the stress-free shape; a capture makes a buckled shape permanent; a painted
//! map and randomized moduli act per element.

mod common;

use common::*;
use glam::DVec3;
use skinsim::model::{FacePrestrain, ModulusScale, TetPrestrain};
use skinsim::scene::load_str;
use skinsim_systems::Simulation;

fn extent(p: &[DVec3]) -> DVec3 {
    let lo = p.iter().fold(DVec3::INFINITY, |a, q| a.min(*q));
    let hi = p.iter().fold(DVec3::NEG_INFINITY, |a, q| a.max(*q));
    hi - lo
}

/// A block with symmetry supports on its min sides, free to take its stress-free size.
const BLOCK: &str = r#"Scene(name: "block", frames: 1, units: (length: Millimetre, stress: KiloPascal), patches: [
    Patch(name: "p", solver: (projection: Adaptive), layers: [
        Layer(name: "slab", kind: Volume, mesh: TetSlab(size: (4.0, 2.0), cells: (4, 2), depth: 1.0, elements: 2),
              material: (young: 1.0, poisson: 0.45), prestrain: (stretch: (1.02, 1.04, 1.0))),
        Layer(name: "skin", kind: Shell, mesh: SurfaceOf(layer: "slab"),
              material: (young: 100.0, poisson: 0.45, thickness: 0.02), bending: (model: Tan),
              prestrain: (stretch: (1.02, 1.04, 1.0))),
    ], drivers: [
        Pin(layer: "slab", select: Sides([XMin]), dofs: (x: true, y: false, z: false)),
        Pin(layer: "slab", select: Sides([YMin]), dofs: (x: false, y: true, z: false)),
        Pin(layer: "slab", select: Sides([ZMin]), dofs: (x: false, y: false, z: true)),
    ]),
])"#;

#[test]
fn uniform_prestrain_sets_the_stress_free_size() {
    let scene = load_str(BLOCK, &scene_path("block.ron")).unwrap();
    let mut sim = Simulation::new(&scene);
    let stats = sim.step();
    assert!(stats.patches[0].outcome.converged, "{:?}", stats.patches[0]);
    let size = extent(&sim.layer_positions("p", "slab"));
    // F = dx/dX F0 = I at rest: the block shrinks by 1/1.02 and 1/1.04 in plane, keeps its depth.
    let expected = DVec3::new(4e-3 / 1.02, 2e-3 / 1.04, 1e-3);
    let err = ((size - expected) / expected).abs().max_element();
    println!("prestrained block: size {size:?}, expected {expected:?}, max rel. error {err:.2e}");
    assert!(err < 1e-6, "{size:?} vs {expected:?}");
    let recorded = sim.world.query::<&TetPrestrain>().iter(&sim.world).count();
    assert_eq!(recorded, 4 * 2 * 2 * 6, "every tet records its F0");
    assert_eq!(sim.world.query::<&FacePrestrain>().iter(&sim.world).count(), 4 * 2 * 2);
}

#[test]
fn a_painted_map_scales_the_prestrain_per_element() {
    // A white-to-black ramp along x: elements on the left are prestretched, on the right not.
    let dir = std::env::temp_dir().join(format!("skinsim-prestrain-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let img = image::GrayImage::from_fn(16, 4, |x, _| image::Luma([if x < 8 { 255 } else { 0 }]));
    img.save(dir.join("ramp.png")).unwrap();
    let text = BLOCK.replace(
        "prestrain: (stretch: (1.02, 1.04, 1.0))),\n        Layer",
        "prestrain: (stretch: (1.02, 1.04, 1.0), map: \"ramp.png\")),\n        Layer",
    );
    let scene = load_str(&text, &dir.join("block.ron")).unwrap();
    let mut sim = Simulation::new(&scene);
    let f0: Vec<f64> = sim.world.query::<&TetPrestrain>().iter(&sim.world).map(|p| p.0.x_axis.x).collect();
    assert!(f0.iter().any(|&s| (s - 1.02).abs() < 1e-12) && f0.iter().any(|&s| (s - 1.0).abs() < 1e-12));
    assert!(sim.step().patches[0].outcome.converged);
}

#[test]
fn randomized_moduli_stay_within_their_amplitude_and_are_seeded() {
    let text = BLOCK.replace(
        "material: (young: 100.0, poisson: 0.45, thickness: 0.02),",
        "material: (young: 100.0, poisson: 0.45, thickness: 0.02), randomize: (amplitude: 0.3, seed: 7),",
    );
    let scene = load_str(&text, &scene_path("block.ron")).unwrap();
    let scales = |scene| {
        let mut sim = Simulation::new(scene);
        sim.world.query::<&ModulusScale>().iter(&sim.world).map(|s| s.0).collect::<Vec<_>>()
    };
    let (a, b) = (scales(&scene), scales(&scene));
    assert_eq!(a.len(), 16);
    assert_eq!(a, b, "same seed, same moduli");
    assert!(a.iter().all(|&s| (0.7..=1.3).contains(&s)));
    let spread = a.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - a.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(spread > 0.1, "the moduli vary: {a:?}");
}

/// A plane-strain strip on a soft foundation, compressed past its buckling strain, then released.
fn strip(capture: &str) -> String {
    format!(
        r#"Scene(name: "strip", frames: 12, units: (length: Millimetre, stress: MegaPascal), patches: [
    Patch(name: "p", solver: (projection: Adaptive, max_iterations: 100, perturbation: (amplitude: 0.001, seed: 1)), layers: [
        Layer(name: "substrate", kind: Volume, mesh: TetSlab(size: (87.13, 1.0), cells: (40, 1), depth: 43.6, elements: 12),
              material: (young: 1.0, poisson: 0.3)),
        Layer(name: "film", kind: Shell, mesh: SurfaceOf(layer: "substrate"),
              material: (young: 1000.0, poisson: 0.3, thickness: 1.0), bending: (model: Tan)),
    ], drivers: [
        PlaneStrain(layers: ["substrate", "film"], axis: Y),
        Periodic(layers: ["substrate", "film"], axis: X),
        Pin(layer: "substrate", select: Sides([ZMin])),
        Pin(layer: "substrate", select: Sides([XMin, XMax]), dofs: (x: true, y: false, z: false)),
        Compress(layers: ["substrate", "film"], keyframes: [(0, 0.0), (6, 0.02), (12, 0.0)]),
        {capture}
    ]),
])"#
    )
}

fn film_amplitude(sim: &mut Simulation) -> f64 {
    let z: Vec<f64> = sim.layer_points("p", "film").iter().map(|p| p.1.z).collect();
    0.5 * (z.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - z.iter().cloned().fold(f64::INFINITY, f64::min))
}

#[test]
fn captured_wrinkles_stay_after_the_load_is_released() {
    let run_amplitudes = |capture: &str| {
        let scene = load_str(&strip(capture), &scene_path("strip.ron")).unwrap();
        let mut sim = Simulation::new(&scene);
        let mut amplitude = Vec::new();
        for _ in 0..12 {
            let s = sim.step();
            assert!(s.patches[0].outcome.converged, "{:?}", s.patches[0]);
            amplitude.push(film_amplitude(&mut sim));
        }
        amplitude
    };
    let plain = run_amplitudes("");
    let kept = run_amplitudes(r#"Capture(layers: ["substrate", "film"], frame: 6, fraction: 1.0),"#);
    println!("wrinkle amplitude (mm) by frame\n  no capture: {plain:.4?}\n  captured:   {kept:.4?}");
    let (peak, released, kept_end) = (plain[5] * 1e3, plain[11] * 1e3, kept[11] * 1e3);
    assert!(peak > 1.0, "buckled at 2 % (eps_c = 0.52 %): amplitude {peak} mm");
    assert!(released < 0.01 * peak, "without capture the film flattens again: {released} of {peak}");
    // Pulling the ends back to the original length stretches the captured (now stress-free) wavy
    // state by 2 %, which flattens it partly (measured: 42 % of the amplitude stays).
    assert!(kept_end > 0.3 * peak, "captured wrinkles are permanent: {kept_end} of {peak}");
}
