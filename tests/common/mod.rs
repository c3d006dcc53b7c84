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
