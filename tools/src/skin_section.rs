//! VALIDATION.md case 9: H15's 3D parameter set (table 6.4: SC 1 MPa, nu 0.495, 22.5 um; dermis
//! 1 kPa, 1.2 mm; hypodermis 13 kPa, 1.5 mm; nu 0.4) as a plane-strain section on a held base,
//! periodic over eight predicted wavelengths, against the layered-elasticity prediction:
//! first wavelength about 0.98 mm, onset about 0.52 %, amplitude about 66 / 96 / 138 um at
//! 5 / 10 / 20 % compression.

use std::time::Instant;

use skinsim::scene::{load_str, SceneError};
use skinsim_systems::Simulation;

use crate::wrinkles::{amplitude, onset_strain, peaks, profile};

pub const PREDICTED_WAVELENGTH_MM: f64 = 0.98;
pub const PREDICTED_ONSET: f64 = 0.0052;
/// (compression, amplitude in um).
pub const PREDICTED_AMPLITUDE_UM: [(f64, f64); 3] = [(0.05, 66.0), (0.10, 96.0), (0.20, 138.0)];

#[derive(Clone, Copy, Debug)]
pub struct SkinSection {
    pub cells_per_wave: u32,
    pub dermis_elements: u32,
    pub hypodermis_elements: u32,
}

#[derive(Clone, Debug, Default)]
pub struct SectionResult {
    /// Dominant wavelength (mm) at the first increment past the onset, and at each reported
    /// compression.
    pub first_wavelength_mm: f64,
    pub onset: f64,
    /// (compression, amplitude um, dominant wavelength mm).
    pub at: Vec<(f64, f64, f64)>,
    pub wall_per_increment_s: f64,
    pub newton_iterations: u32,
    pub all_converged: bool,
    pub vertices: usize,
}

/// Keyframes: ten fine increments to 3 eps_c for the onset, then coarser ones to 20 %.
const KEYFRAMES: [(u32, f64); 5] = [(0, 0.0), (10, 0.0156), (18, 0.05), (23, 0.10), (33, 0.20)];

impl SkinSection {
    pub fn scene_text(&self) -> String {
        let waves = 8;
        let length = PREDICTED_WAVELENGTH_MM * waves as f64;
        let cells = waves * self.cells_per_wave;
        let dx = length / cells as f64;
        let frames = KEYFRAMES[KEYFRAMES.len() - 1].0;
        let keys = KEYFRAMES.iter().map(|(f, e)| format!("({f}, {e})")).collect::<Vec<_>>().join(", ");
        format!(
            r#"Scene(name: "h15_section", units: (length: Millimetre, stress: KiloPascal), frames: {frames},
    output: (stats: false, rerun: false),
    patches: [Patch(name: "skin",
        solver: (projection: Adaptive, tolerance: 1e-7, max_iterations: 200, perturbation: (amplitude: 0.00002, seed: 1)),
        layers: [
            Layer(name: "hypodermis", kind: Volume,
                mesh: TetSlab(size: ({length}, {dx}), cells: ({cells}, 1), depth: 1.5, elements: {he}, top: -1.2, grading: 3.0),
                material: (young: 13.0, poisson: 0.4)),
            Layer(name: "dermis", kind: Volume, mesh: TetOn(layer: "hypodermis", depth: 1.2, elements: {de}, grading: 10.0),
                material: (young: 1.0, poisson: 0.4)),
            Layer(name: "corneum", kind: Shell, mesh: SurfaceOf(layer: "dermis"),
                material: (young: 1000.0, poisson: 0.495, thickness: 0.0225), bending: (model: Tan)),
        ],
        drivers: [
            PlaneStrain(layers: ["hypodermis", "dermis", "corneum"], axis: Y),
            Periodic(layers: ["hypodermis", "dermis", "corneum"], axis: X),
            Pin(layer: "hypodermis", select: Sides([ZMin])),
            Pin(layer: "hypodermis", select: Sides([XMin, XMax]), dofs: (x: true, y: false, z: false)),
            Pin(layer: "dermis", select: Sides([XMin, XMax]), dofs: (x: true, y: false, z: false)),
            Compress(layers: ["hypodermis", "dermis", "corneum"], axis: X, keyframes: [{keys}]),
        ],
    )],
)"#,
            de = self.dermis_elements,
            he = self.hypodermis_elements,
        )
    }

    pub fn run(&self) -> Result<SectionResult, SceneError> {
        let scene = load_str(&self.scene_text(), std::path::Path::new("h15_section.ron"))?;
        let mut sim = Simulation::new(&scene);
        let mut out = SectionResult { all_converged: true, ..Default::default() };
        let keys = skinsim::model::Keyframes(KEYFRAMES.to_vec());
        let mut series = Vec::new();
        let start = Instant::now();
        for frame in 1..=scene.scene.frames {
            let stats = sim.step();
            let p = &stats.patches[0];
            out.newton_iterations += p.outcome.iterations;
            out.all_converged &= p.outcome.converged;
            out.vertices = p.vertices;
            let (material, positions): (Vec<_>, Vec<_>) = sim.layer_points("skin", "corneum").into_iter().unzip();
            let prof = profile(&positions, &material, 0);
            let strain = keys.at(frame as f64, skinsim::model::Interpolation::Linear);
            let amp = amplitude(&prof);
            let wavelength = peaks(&prof, true, 0.2).first().map_or(f64::NAN, |p| p.wavelength * 1e3);
            series.push((strain, amp, wavelength));
        }
        out.wall_per_increment_s = start.elapsed().as_secs_f64() / scene.scene.frames as f64;
        let early: Vec<(f64, f64)> = series.iter().filter(|s| s.0 <= 0.0156 + 1e-12).map(|s| (s.0, s.1)).collect();
        let top = early.iter().fold(0.0f64, |m, s| m.max(s.1));
        out.onset = onset_strain(&early, 0.05 * top).unwrap_or(f64::NAN);
        out.first_wavelength_mm = series.iter().find(|s| s.0 > out.onset && s.1 > 0.05 * top).map_or(f64::NAN, |s| s.2);
        for (c, _) in PREDICTED_AMPLITUDE_UM {
            if let Some(s) = series.iter().find(|s| (s.0 - c).abs() < 1e-9) {
                out.at.push((c, s.1 * 1e6, s.2));
            }
        }
        Ok(out)
    }
}
