//! VALIDATION.md cases 10 and 11 on the quick LK14 scenes (scenes/lk14/*_quick.ron).
//! Case 10 holds for these scenes' protocol (thin layers, a gentle start); the wrinkle pattern
//! under kernels is multistable - the same (scaled) problem has been measured to settle at 0.98
//! and 1.15 lambda depending on the solver's path, and thicker layers ramped gently at up to
//! 1.36 lambda - so this test also guards which equilibrium the solver reaches.
//! Case 10: one shell held to a compressed blend-shape base by eq. 3.1 kernels wrinkles at the
//! kernel wavelength, for E x1, E x64 (lambda doubles) and h / 4 (lambda halves). Case 11: a
//! second, stiffer layer on top adds a second spectral peak near its own kernel wavelength.
//! Wavelengths come from the summed power spectra of the grid rows along the compression axis
//! (`wrinkles::row_peaks`). `cargo test --release -p skinsim-cli --test lk14_validation --
//! --nocapture` prints the figures.

use std::path::Path;

use skinsim::scene;
use skinsim_systems::Simulation;
use skinsim_tools::wrinkles::{row_peaks, Peak};

/// Runs a scene; returns the spectral peaks of `layer` at the last frame and whether every
/// frame converged.
fn wrinkles(file: &str, layer: &str) -> (Vec<Peak>, bool, f64) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/lk14").join(file);
    let built = scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    wrinkles_of(&built, file, layer).0
}

/// `wrinkles` of a loaded scene, and the frames' escapes from unstable equilibria.
fn wrinkles_of(built: &scene::BuiltScene, file: &str, layer: &str) -> ((Vec<Peak>, bool, f64), u32) {
    let mut escapes = 0;
    let mut sim = Simulation::new(built);
    let mut converged = true;
    let clock = std::time::Instant::now();
    for _ in 0..built.scene.frames {
        let stats = sim.step();
        assert!(sim.failure().is_none(), "{file}: {:?}", sim.failure());
        converged &= stats.patches.iter().all(|p| p.outcome.converged);
        escapes += stats.patches.iter().map(|p| p.outcome.escapes).sum::<u32>();
    }
    let per_frame = clock.elapsed().as_secs_f64() / built.scene.frames as f64;
    let (uv, pos): (Vec<_>, Vec<_>) = sim.layer_points("skin", layer).into_iter().unzip();
    ((row_peaks(&pos, &uv, 0, 0.05), converged, per_frame), escapes)
}

#[test]
fn case_10_kernels_set_the_wavelength() {
    // (scene, eq. 3.1 wavelength: 5.657 (h x 15 mm)^1/2 (E / 0.5 MPa)^1/6 in mm)
    let lambda = |e: f64, h: f64| 5.657 * (h * 15.0f64).sqrt() * (e / 0.5f64).powf(1.0 / 6.0);
    for (file, expected) in [
        ("fig3_3_e1_h1_quick.ron", lambda(4.0, 0.0375)),
        ("fig3_3_e64_quick.ron", lambda(256.0, 0.0375)),
        ("fig3_3_h_quarter_quick.ron", lambda(4.0, 0.0375 / 4.0)),
    ] {
        let (peaks, converged, per_frame) = wrinkles(file, "skin");
        let measured = 1e3 * peaks[0].wavelength;
        let error = measured / expected - 1.0;
        println!(
            "case 10 {file}: wavelength {measured:.3} mm, kernels {expected:.3} mm, {:+.1} %, {per_frame:.2} s/frame",
            100.0 * error
        );
        assert!(converged, "{file}: every frame converges");
        assert!(error.abs() < 0.10, "{file}: {measured:.3} mm against {expected:.3} mm");
    }
}

/// Case 10 from a perfect sheet (the E x1 scene without its imperfection). Past its buckling
/// strain the flat held sheet is a constrained saddle: H is indefinite on the null space of the
/// kernels' Jacobian, and Newton reaches it in two iterations. The stability test must leave it
/// along its most negative curvature (issue 26 item 5: the 512 x 72 strip stopped at such a
/// saddle, with 137 unstable directions at 0.1 % strain, and wrinkled 16 % short). Measured
/// without the test: 5.22 mm (-13 %), two frames at the iteration cap.
#[test]
fn case_10_holds_from_a_perfect_sheet() {
    let file = "fig3_3_e1_h1_quick.ron";
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/lk14").join(file);
    let text = std::fs::read_to_string(&path).unwrap();
    let perfect = text.replace(",\n                     perturbation: Some((amplitude: 0.00375, seed: 3))", "");
    assert_ne!(perfect, text, "the imperfection removed");
    let built = scene::load_str(&perfect, &path).unwrap_or_else(|e| panic!("{e}"));
    let ((peaks, converged, _), escapes) = wrinkles_of(&built, file, "skin");
    let measured = 1e3 * peaks[0].wavelength;
    println!("case 10 from a perfect sheet: wavelength {measured:.3} mm, {escapes} escapes");
    assert!(escapes > 0, "the flat sheet left through the stability test");
    assert!(converged, "every frame converges");
    assert!((measured / 6.0 - 1.0).abs() < 0.10, "{measured:.3} mm against 6 mm");
}

/// The dermis is thick against its kernels (h / lambda_1 = 0.125, as LK14's 1.3 mm at about
/// 6 mm), so it wrinkles longer than lambda_1 (case 10's thick regime) and stays compressed,
/// which is what wrinkles the epidermis at lambda_2 on top of it. The test: the one-layer
/// spectrum has its dermis peak and nothing near lambda_2; the two-layer top layer has that
/// same peak and one near lambda_2.
#[test]
fn case_11_two_layers_two_peaks() {
    let lambda_2 = 2.0;
    let near =
        |peaks: &[Peak], lambda: f64, tol: f64| peaks.iter().any(|p| (1e3 * p.wavelength / lambda - 1.0).abs() < tol);
    let table = |peaks: &[Peak]| {
        peaks.iter().map(|p| format!("{:.2} mm ({:.2})", 1e3 * p.wavelength, p.strength)).collect::<Vec<_>>()
    };
    let (one, converged, _) = wrinkles("fig6_3_one_layer_quick.ron", "dermis");
    println!("case 11 one layer (lambda_1 = 8 mm): peaks {:?}", table(&one));
    assert!(converged);
    let dermis = 1e3 * one[0].wavelength;
    assert!(!near(&one, lambda_2, 0.25), "no second scale without a second layer");
    let (two, converged, per_frame) = wrinkles("fig6_3_two_layers_quick.ron", "epidermis");
    println!("case 11 two layers ({per_frame:.2} s/frame): peaks {:?}", table(&two));
    assert!(converged);
    assert!(near(&two, dermis, 0.10), "the dermis peak ({dermis:.2} mm) carries through");
    assert!(near(&two, lambda_2, 0.25), "a second peak near lambda_2 = {lambda_2} mm");
}
