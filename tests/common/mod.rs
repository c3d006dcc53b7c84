//! Helpers shared by the system-level tests.
#![allow(dead_code)]

pub mod gltf;

use std::path::{Path, PathBuf};

use glam::DVec2;
use skinsim::coupling::kernels::{moments, Adjusted, Sample};
use skinsim::model::{Kernel, KernelWeights, MaterialPos};
use skinsim::scene::{self, BuiltScene};
use skinsim_systems::{FrameStats, Simulation};

pub fn scene_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(rel)
}

pub fn load(rel: &str) -> BuiltScene {
    scene::load(&scene_path(rel)).unwrap_or_else(|e| panic!("{e}"))
}

/// A scene of `scenes/` with text edits (each must be found), built.
pub fn variant(rel: &str, edits: &[(&str, &str)]) -> BuiltScene {
    let mut text = std::fs::read_to_string(scene_path(rel)).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{rel} has no {from:?}");
        text = text.replace(from, to);
    }
    scene::load_str(&text, &scene_path(rel)).unwrap_or_else(|e| panic!("{e}"))
}

/// Runs every frame of a scene and returns the per-frame stats.
pub fn run(scene: &BuiltScene) -> (Simulation, Vec<FrameStats>) {
    let mut sim = Simulation::new(scene);
    let stats = (0..scene.scene.frames).map(|_| sim.step()).collect();
    (sim, stats)
}

/// Relative error.
pub fn rel(measured: f64, expected: f64) -> f64 {
    (measured - expected) / expected
}

/// A scratch folder for one test binary (scene files and assets written by the tests).
pub fn scratch_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("skinsim-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Asserts that a scene error's message contains every word.
pub fn mentions(e: &scene::SceneError, words: &[&str]) {
    let msg = e.to_string();
    for w in words {
        assert!(msg.contains(w), "{msg:?} does not mention {w:?}");
    }
}

/// Weights of every kernel: affine (sum 1) and centred on the kernel's target to 1e-12.
pub fn check_weights(sim: &mut Simulation) -> usize {
    let mut q = sim.world.query::<(&Kernel, &KernelWeights)>();
    let mut points = sim.world.query::<&MaterialPos>();
    let mut checked = 0;
    for (k, w) in q.iter(&sim.world) {
        for (side, adjusted) in [(&w.upper, w.adjusted[0]), (&w.lower, w.adjusted[1])] {
            if adjusted != Some(Adjusted::Centred) {
                continue;
            }
            let pts: Vec<DVec2> = side.iter().map(|(v, _)| points.get(&sim.world, *v).unwrap().0).collect();
            let s = Sample { vertices: (0..pts.len() as u32).collect(), weights: side.iter().map(|x| x.1).collect() };
            let (sum, centroid) = moments(&pts, &s);
            assert!((sum - 1.0).abs() < 1e-12, "sum {sum}");
            assert!((centroid - k.shape.target).length() < 1e-12, "off by {:e}", (centroid - k.shape.target).length());
            checked += 1;
        }
    }
    checked
}
