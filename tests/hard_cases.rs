//! VALIDATION.md E (stability), the cases the engine core meets: each finishes without NaN,
//! converged, and without inverted elements where the model forbids them.

mod common;

use common::*;
use skinsim_systems::Simulation;

fn run_all_converged(scene: &skinsim::scene::BuiltScene) -> Simulation {
    let mut sim = Simulation::new(scene);
    for frame in 1..=scene.scene.frames {
        let s = sim.step();
        assert!(sim.failure().is_none(), "{:?}", sim.failure());
        for p in &s.patches {
            assert!(p.outcome.converged && p.outcome.energy.is_finite(), "frame {frame}: {p:?}");
        }
    }
    sim
}

#[test]
fn film_on_foundation_compressed_to_half() {
    let scene = variant(
        "strip_wrinkles.ron",
        &[
            ("frames: 30,", "frames: 60,"),
            ("keyframes: [(0, 0.0), (30, 0.06)]", "keyframes: [(0, 0.0), (60, 0.5)]"),
            ("max_iterations: 60,", "max_iterations: 150,"),
            (
                "cells: (80, 8), pattern: Equilateral),\n                ),",
                "cells: (40, 4), pattern: Equilateral),\n                ),",
            ),
            (
                "mesh: Grid(size: (40.0, 4.0), cells: (80, 8), pattern: Equilateral),\n                    material",
                "mesh: Grid(size: (40.0, 4.0), cells: (40, 4), pattern: Equilateral),\n                    material",
            ),
        ],
    );
    let mut sim = run_all_converged(&scene);
    let film = sim.layer_positions("strip", "film");
    let (lo, hi) = film.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.x), b.max(p.x)));
    // The pinned ends sit at half the length; wrinkles may lean slightly past them.
    assert!(((hi - lo) / 0.04 - 0.5).abs() < 0.05, "film extent {}", (hi - lo) / 0.04);
}

#[test]
fn a_20_micrometre_film_on_a_millimetre_mesh() {
    let scene = variant(
        "strip_wrinkles.ron",
        &[
            ("thickness: 0.1),", "thickness: 0.02),"),
            ("max_iterations: 60,", "max_iterations: 300,"),
            (
                "cells: (80, 8), pattern: Equilateral),\n                ),",
                "cells: (40, 4), pattern: Equilateral),\n                ),",
            ),
            (
                "mesh: Grid(size: (40.0, 4.0), cells: (80, 8), pattern: Equilateral),\n                    material",
                "mesh: Grid(size: (40.0, 4.0), cells: (40, 4), pattern: Equilateral),\n                    material",
            ),
        ],
    );
    run_all_converged(&scene);
}

#[test]
fn a_solid_slab_compressed_to_half_keeps_every_tet_upright() {
    let scene = variant(
        "examples/volume_slab.ron",
        &[("keyframes: [(0, 0.0), (10, 0.2)]", "keyframes: [(0, 0.0), (10, 0.5)]")],
    );
    let mut sim = run_all_converged(&scene);
    let mut q = sim.world.query::<&skinsim::solve::PackedPatch>();
    let body = q.single(&sim.world).unwrap();
    assert_eq!(body.inverted_tets(), 0, "Bazant-Hencky must not invert");
}

#[test]
fn implicit_euler_with_a_hundred_times_larger_step() {
    let scene = variant("examples/dynamic_strip.ron", &[("frame_time: 0.001,", "frame_time: 0.1,")]);
    run_all_converged(&scene);
}

// ---- The H15 construction (shell SC over tetrahedral layers), VALIDATION.md E.

/// H15 experiment 1 (three layers, Bazant-Hencky) at half the resolution along the strip,
/// with more edits.
fn three_layers(edits: &[(&str, &str)]) -> skinsim::scene::BuiltScene {
    let mut all = vec![("cells: (250, 1)", "cells: (125, 1)"), ("size: (29.4, 0.1176)", "size: (29.4, 0.2352)")];
    all.extend_from_slice(edits);
    variant("h15/exp1_bazant_hencky.ron", &all)
}

fn upright_to_the_end(scene: &skinsim::scene::BuiltScene) {
    let mut sim = run_all_converged(scene);
    let mut q = sim.world.query::<&skinsim::solve::PackedPatch>();
    let body = q.single(&sim.world).unwrap();
    assert_eq!(body.inverted_tets(), 0, "Bazant-Hencky must not invert");
    assert!(body.state.x.iter().all(|p| p.is_finite()));
}

#[test]
fn three_layer_skin_compressed_to_70_and_50_percent() {
    // 30 % in 20 increments (1.5 % each), then on to 50 % (2 % each).
    upright_to_the_end(&three_layers(&[
        ("frames: 40,", "frames: 30,"),
        ("keyframes: [(0, 0.0), (40, 0.2)]", "keyframes: [(0, 0.0), (20, 0.3), (30, 0.5)]"),
    ]));
}

#[test]
fn three_layer_skin_with_a_20_micrometre_sc_on_a_millimetre_mesh() {
    upright_to_the_end(&three_layers(&[
        ("cells: (125, 1)", "cells: (30, 1)"),
        ("size: (29.4, 0.2352)", "size: (29.4, 0.98)"),
        ("thickness: 0.05)", "thickness: 0.02)"),
        ("frames: 40,", "frames: 20,"),
        ("(40, 0.2)]", "(20, 0.2)]"),
    ]));
}

#[test]
fn stiffness_ratios_up_to_1e5_between_layers() {
    // SC 100 kPa over dermis 1 Pa and hypodermis 1 Pa: ratio 1e5 (1e3 is experiment 1 and case 7).
    upright_to_the_end(&three_layers(&[
        ("young: 10.0, poisson: 0.42)", "young: 1.0, poisson: 0.42)"),
        ("young: 100.0, poisson: 0.42)", "young: 1.0, poisson: 0.42)"),
        ("frames: 40,", "frames: 20,"),
        ("(40, 0.2)]", "(20, 0.2)]"),
    ]));
}

#[test]
fn nearly_incompressible_substrate_layers() {
    upright_to_the_end(&three_layers(&[
        ("young: 10.0, poisson: 0.42)", "young: 10.0, poisson: 0.495)"),
        ("young: 100.0, poisson: 0.42)", "young: 100.0, poisson: 0.495)"),
        ("frames: 40,", "frames: 20,"),
        ("(40, 0.2)]", "(20, 0.2)]"),
    ]));
}
