//! Helpers shared by the system-level tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use skinsim::scene::{self, BuiltScene};
use skinsim_systems::{FrameStats, Simulation};

pub fn scene_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(rel)
}

pub fn load(rel: &str) -> BuiltScene {
    scene::load(&scene_path(rel)).unwrap_or_else(|e| panic!("{e}"))
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
