//! VALIDATION.md cases 7 and 8: a stiff film (shell) on a soft tetrahedral substrate in plane
//! strain, periodic along the compression axis, against the wrinkling theory of Chen and
//! Hutchinson (2004) and Huang, Hong and Suo (2005). Shared by the validation tests and
//! `skinsim report` (the speed-against-error sweep).

use std::time::Instant;

use skinsim::physics::cell::VolumeElement;
use skinsim::physics::ConstitutiveModel;
use skinsim::scene::{load_str, SceneError};
use skinsim::solve::Precision;
use skinsim_systems::Simulation;

use crate::wrinkles::{amplitude, onset_strain, peaks, profile};

/// A film-on-substrate set-up. Lengths in film thicknesses (h = 1 mm), moduli relative to the
/// substrate's plane-strain modulus.
#[derive(Clone, Copy, Debug)]
pub struct FilmSubstrate {
    /// Ebar_f / Ebar_s.
    pub ratio: f64,
    pub film_poisson: f64,
    pub substrate_poisson: f64,
    /// Substrate depth over the infinite-depth wavelength lambda_c; None for a deep substrate
    /// (the depth is then `deep` wavelengths).
    pub depth: Depth,
    /// The domain holds this many wavelengths (of `expected_wavelength`).
    pub waves: u32,
    pub cells_per_wave: u32,
    /// Tetrahedral prisms through the substrate depth, and the bottom-to-top thickness ratio.
    pub depth_elements: u32,
    pub grading: f64,
    /// In-plane coarsening with depth: the grid halves along x every this many lambda_c below
    /// the film (issue 25 item 3); None: uniform.
    pub coarsen: Option<f64>,
    /// Increments up to `max_strain` x the expected onset strain.
    pub increments: u32,
    pub max_strain: f64,
    /// The substrate's volume element; None: the default for its Poisson's ratio.
    pub volume_element: Option<VolumeElement>,
    /// The substrate's constitutive model.
    pub substrate_model: ConstitutiveModel,
    /// The Newton factor's arithmetic (mixed precision: `F32`).
    pub precision: Precision,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Depth {
    /// A deep substrate `n` infinite-depth wavelengths deep, its bottom held.
    Deep(f64),
    /// A finite layer H = depth x lambda_c on a rigid base (VALIDATION.md case 8).
    OnRigid(f64),
}

/// The theory for a deep substrate (VALIDATION.md case 7).
pub fn deep_theory(ratio: f64) -> (f64, f64) {
    let wavelength = 2.0 * std::f64::consts::PI * (ratio / 3.0).powf(1.0 / 3.0);
    let onset = 0.25 * (3.0 / ratio).powf(2.0 / 3.0);
    (wavelength, onset)
}

/// Layered elasticity (plane strain) for a film bonded to a substrate layer of depth
/// `depth` x lambda_c (None: a half-space) on a rigid base, with Poisson's ratio `nu`: the
/// critical wavelength and strain relative to `deep_theory`'s. The film is a plate
/// (D = Ebar_f h^3 / 12) that holds the substrate surface at zero tangential displacement; the
/// substrate's normal stiffness K(k) comes from the Navier equations in depth (four exponential
/// solutions, matrix exponential), and eps(k) = (D k^4 + K(k)) / (Ebar_f h k^2) is minimised
/// over k. With nu = 0.495 this gives VALIDATION.md case 8's table.
pub fn layered_theory(ratio: f64, nu: f64, depth: Option<f64>) -> (f64, f64) {
    use nalgebra::{Matrix2, Matrix4, Vector2};
    let (lambda_c, eps_c) = deep_theory(ratio);
    let young = 1.0 - nu * nu; // Ebar_s = 1
    let (mu, la) = (young / (2.0 * (1.0 + nu)), young * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)));
    let stiffness = |k: f64| {
        let h = depth.map_or(30.0 / k, |d| d * lambda_c);
        // y from the base up; Y = (U, U', W, W'), u_x = U(y) sin kx, u_y = W(y) cos kx.
        #[rustfmt::skip]
        let m = Matrix4::new(
            0.0, 1.0, 0.0, 0.0,
            k * k * (la + 2.0 * mu) / mu, 0.0, 0.0, (la + mu) / mu * k,
            0.0, 0.0, 0.0, 1.0,
            0.0, -(la + mu) * k / (la + 2.0 * mu), mu * k * k / (la + 2.0 * mu), 0.0,
        );
        let p = (m * h).exp();
        // Base held (U = W = 0); top: W = 1, U = 0 (bonded to the inextensible film).
        let a = Matrix2::new(p[(2, 1)], p[(2, 3)], p[(0, 1)], p[(0, 3)]);
        let s = a.lu().solve(&Vector2::new(1.0, 0.0)).unwrap_or_default();
        let top = p.column(1) * s[0] + p.column(3) * s[1];
        (la + 2.0 * mu) * top[3] + la * k * top[0]
    };
    let d = ratio / 12.0;
    let eps = |k: f64| (d * k.powi(4) + stiffness(k)) / (ratio * k * k);
    // Golden-section search on ln k around the deep value.
    let k0 = (2.0 * std::f64::consts::PI / lambda_c).ln();
    let (mut a, mut b) = (k0 - 1.5, k0 + 1.5);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..200 {
        let (c, e) = (b - g * (b - a), a + g * (b - a));
        if eps(c.exp()) < eps(e.exp()) {
            b = e;
        } else {
            a = c;
        }
    }
    let k = (0.5 * (a + b)).exp();
    (2.0 * std::f64::consts::PI / k / lambda_c, eps(k) / eps_c)
}

/// What one run measured.
#[derive(Clone, Debug, Default)]
pub struct FilmResult {
    /// (applied strain, amplitude / h) per increment.
    pub series: Vec<(f64, f64)>,
    /// Dominant wavelength / h at the last increment.
    pub wavelength: f64,
    /// Onset strain from the fit of A^2 against strain.
    pub onset: f64,
    /// (eps / eps_c, relative amplitude error) at 1.5, 2 and 3 eps_c (those reached).
    pub amplitude_errors: Vec<(f64, f64)>,
    pub expected_wavelength: f64,
    pub expected_onset: f64,
    pub newton_iterations: u32,
    pub all_converged: bool,
    pub wall_per_increment_s: f64,
    pub vertices: usize,
    pub tets: usize,
}

impl FilmResult {
    pub fn wavelength_error(&self) -> f64 {
        self.wavelength / self.expected_wavelength - 1.0
    }
    pub fn onset_error(&self) -> f64 {
        self.onset / self.expected_onset - 1.0
    }
    pub fn worst_amplitude_error(&self) -> f64 {
        self.amplitude_errors.iter().fold(0.0f64, |m, (_, e)| m.max(e.abs()))
    }
}

impl FilmSubstrate {
    /// Case 7 at a stiffness ratio, deep substrate (1.5 wavelengths), to 3 eps_c.
    pub fn deep(ratio: f64, waves: u32, cells_per_wave: u32, depth_elements: u32) -> Self {
        FilmSubstrate {
            ratio,
            film_poisson: 0.3,
            substrate_poisson: 0.45,
            depth: Depth::Deep(1.5),
            waves,
            cells_per_wave,
            depth_elements,
            grading: 1.0,
            coarsen: None,
            increments: 30,
            max_strain: 3.0,
            volume_element: None,
            substrate_model: ConstitutiveModel::BazantHencky,
            precision: Precision::F64,
        }
    }

    /// Case 8: a substrate layer `depth` x lambda_c thick on a rigid base.
    pub fn on_rigid(depth: f64, substrate_poisson: f64, cells_per_wave: u32, depth_elements: u32) -> Self {
        FilmSubstrate {
            substrate_poisson,
            depth: Depth::OnRigid(depth),
            ..Self::deep(1000.0, 8, cells_per_wave, depth_elements)
        }
    }

    /// Expected (wavelength / h, onset strain): VALIDATION.md's formulas for a deep substrate,
    /// layered elasticity on a rigid base.
    pub fn expected(&self) -> (f64, f64) {
        let (l, e) = deep_theory(self.ratio);
        match self.depth {
            Depth::Deep(_) => (l, e),
            Depth::OnRigid(depth) => {
                let (lr, er) = layered_theory(self.ratio, self.substrate_poisson, Some(depth));
                (l * lr, e * er)
            }
        }
    }

    /// The scene (millimetres, megapascals; h = 1 mm, Ebar_s = 1 MPa).
    pub fn scene_text(&self) -> String {
        let (lambda_inf, _) = deep_theory(self.ratio);
        let (lambda, eps_c) = self.expected();
        let length = lambda * self.waves as f64;
        let cells = self.waves * self.cells_per_wave;
        let dx = length / cells as f64;
        let depth = match self.depth {
            Depth::Deep(n) | Depth::OnRigid(n) => n * lambda_inf,
        };
        let (nf, ns) = (self.film_poisson, self.substrate_poisson);
        let young_s = 1.0 - ns * ns;
        let young_f = self.ratio * (1.0 - nf * nf);
        let max = self.max_strain * eps_c;
        format!(
            r#"Scene(name: "film_substrate", units: (length: Millimetre, stress: MegaPascal), frames: {frames},
    output: (stats: false, rerun: false),
    patches: [Patch(name: "bilayer",
        solver: (projection: Adaptive, precision: {precision:?}, max_iterations: 100, perturbation: (amplitude: 0.001, seed: 1)),
        layers: [
            Layer(name: "substrate", kind: Volume,
                mesh: TetSlab(size: ({length}, {dx}), cells: ({cells}, 1), depth: {depth}, elements: {de}, grading: {grading}{coarsen}),
                material: (model: {model:?}, young: {young_s}, poisson: {ns}{element})),
            Layer(name: "film", kind: Shell, mesh: SurfaceOf(layer: "substrate"),
                material: (young: {young_f}, poisson: {nf}, thickness: 1.0), bending: (model: Tan)),
        ],
        drivers: [
            PlaneStrain(layers: ["substrate", "film"], axis: Y),
            Periodic(layers: ["substrate", "film"], axis: X),
            Pin(layer: "substrate", select: Sides([ZMin])),
            Pin(layer: "substrate", select: Sides([XMin, XMax]), dofs: (x: true, y: false, z: false)),
            Compress(layers: ["substrate", "film"], axis: X, keyframes: [(0, 0.0), ({frames}, {max})]),
        ],
    )],
)"#,
            frames = self.increments,
            de = self.depth_elements,
            grading = self.grading,
            model = self.substrate_model,
            precision = self.precision,
            coarsen = self.coarsen.map_or(String::new(), |c| format!(", coarsen: (every: {})", c * lambda_inf)),
            element = self.volume_element.map_or(String::new(), |v| format!(", volume_element: {v:?}")),
        )
    }

    pub fn run(&self) -> Result<FilmResult, SceneError> {
        let scene = load_str(&self.scene_text(), std::path::Path::new("film_substrate.ron"))?;
        let (expected_wavelength, expected_onset) = self.expected();
        let mut sim = Simulation::new(&scene);
        let mut out = FilmResult { expected_wavelength, expected_onset, all_converged: true, ..Default::default() };
        let h = 1e-3;
        let max = self.max_strain * expected_onset;
        let start = Instant::now();
        let mut last = None;
        for i in 1..=self.increments {
            let stats = sim.step();
            let p = &stats.patches[0];
            out.newton_iterations += p.outcome.iterations;
            out.all_converged &= p.outcome.converged;
            out.vertices = p.vertices;
            out.tets = p.tets;
            let (material, positions): (Vec<_>, Vec<_>) = sim.layer_points("bilayer", "film").into_iter().unzip();
            let prof = profile(&positions, &material, 0);
            let strain = max * i as f64 / self.increments as f64;
            out.series.push((strain, amplitude(&prof) / h));
            last = Some(prof);
        }
        out.wall_per_increment_s = start.elapsed().as_secs_f64() / self.increments as f64;
        if let Some(prof) = last {
            out.wavelength = peaks(&prof, true, 0.2).first().map_or(f64::NAN, |p| p.wavelength / h);
        }
        let top = out.series.iter().fold(0.0f64, |m, s| m.max(s.1));
        out.onset = onset_strain(&out.series, 0.05 * top).unwrap_or(f64::NAN);
        // A = h sqrt(eps / eps_c - 1) holds for a deep substrate only.
        let deep = matches!(self.depth, Depth::Deep(_));
        for target in [1.5, 2.0, 3.0].into_iter().filter(|_| deep) {
            let strain = target * expected_onset;
            if let Some(&(e, a)) = out.series.iter().find(|(e, _)| (e / strain - 1.0).abs() < 1e-9) {
                // A = h sqrt(eps / eps_c - 1) (Chen and Hutchinson 2004)
                let theory = (e / expected_onset - 1.0).sqrt();
                out.amplitude_errors.push((target, a / theory - 1.0));
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layered_elasticity_reproduces_the_validation_table() {
        // VALIDATION.md case 8 (nu_s = 0.495): H / lambda -> (lambda / lambda_inf, eps_c / eps_inf).
        let (l_inf, e_inf) = layered_theory(1000.0, 0.495, None);
        assert!((l_inf - 1.0).abs() < 1e-3 && (e_inf - 1.0).abs() < 1e-3, "{l_inf} {e_inf}");
        for (h, l, e) in [(0.2, 0.628, 1.55), (0.3, 0.745, 1.24), (0.5, 0.896, 1.05)] {
            let (lr, er) = layered_theory(1000.0, 0.495, Some(h));
            assert!((lr / l - 1.0).abs() < 0.005 && (er / e - 1.0).abs() < 0.005, "H {h}: {lr} {er}");
        }
    }
}
