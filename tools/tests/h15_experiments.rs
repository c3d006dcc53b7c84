//! VALIDATION.md case 12: H15's 2D experiments 1-5 (thesis 6.1, tables 6.1-6.3), run from the
//! shipped scenes, their qualitative claims asserted on counted spectral peaks of the stratum
//! corneum's height profile, inverted-element counts and wavelengths.
//! `cargo test --release -p skinsim-cli --test h15_experiments -- --nocapture` prints the figures.

use std::path::Path;

use skinsim::scene::{load_str, BuiltScene};
use skinsim_systems::Simulation;
use skinsim_tools::wrinkles::{amplitude, peaks, profile, Peak};

/// Peaks weaker than this fraction of the strongest are not counted as a wavelength.
const COUNTED: f64 = 0.15;
/// H15's 86 % and 80.5 % (0.5 % per increment).
const AT_86: u32 = 28;
const AT_80_5: u32 = 39;

fn scene(name: &str, frames: Option<u32>) -> BuiltScene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/h15").join(format!("{name}.ron"));
    let mut text = std::fs::read_to_string(&path).unwrap();
    if let Some(n) = frames {
        let at = text.find("frames: ").unwrap();
        let end = at + text[at..].find(',').unwrap();
        text.replace_range(at..end, &format!("frames: {n}"));
    }
    load_str(&text, &path).unwrap_or_else(|e| panic!("{e}"))
}

/// Per frame: the SC's spectral peaks (counted ones), its amplitude, and inverted tets.
struct Frame {
    peaks: Vec<Peak>,
    amplitude: f64,
    inverted: usize,
}

fn run(name: &str, frames: Option<u32>) -> Vec<Frame> {
    let scene = scene(name, frames);
    let mut sim = Simulation::new(&scene);
    (0..scene.scene.frames)
        .map(|_| {
            let stats = sim.step();
            let p = &stats.patches[0];
            assert!(p.outcome.converged && p.outcome.energy.is_finite(), "{name} frame {}: {p:?}", stats.frame);
            let pts = sim.layer_points("skin", "corneum");
            let (material, positions): (Vec<_>, Vec<_>) = pts.into_iter().unzip();
            let prof = profile(&positions, &material, 0);
            Frame { peaks: peaks(&prof, false, COUNTED), amplitude: amplitude(&prof), inverted: p.outcome.inverted }
        })
        .collect()
}

/// Experiment 1 (Bazant-Hencky), shared by two tests.
fn baseline() -> &'static [Frame] {
    static RUN: std::sync::OnceLock<Vec<Frame>> = std::sync::OnceLock::new();
    RUN.get_or_init(|| run("exp1_bazant_hencky", None))
}

fn mm(peaks: &[Peak]) -> Vec<String> {
    peaks.iter().map(|p| format!("{:.2} mm ({:.2})", p.wavelength * 1e3, p.strength)).collect()
}

fn at(frames: &[Frame], frame: u32) -> &Frame {
    &frames[frame as usize - 1]
}

/// The first frame whose amplitude grows (before it, the prestrained patch only flattens), and
/// its dominant wavelength: the wavelength at which the SC first wrinkles.
fn onset(frames: &[Frame]) -> (usize, f64) {
    let i = (1..frames.len()).find(|&i| frames[i].amplitude > frames[i - 1].amplitude).expect("wrinkles appear");
    (i + 1, frames[i].peaks[0].wavelength)
}

#[test]
fn three_layers_show_two_wavelengths_where_two_layers_show_one() {
    let three = baseline();
    let two = run("exp3_two_layers", None);
    let soft_middle = run("exp4_living_epidermis", None);
    let (f3, onset3) = onset(three);
    println!("three layers: SC wrinkles at {:.2} mm (frame {f3})", onset3 * 1e3);
    for (name, frames) in [("three layers", three), ("two layers", &two), ("soft middle", &soft_middle)] {
        for f in [AT_86, AT_80_5] {
            println!("{name} at frame {f}: {:?}", mm(&at(frames, f).peaks));
        }
    }
    for f in [AT_86, AT_80_5] {
        // Three layers: the dermis furrows (a long wavelength, sharp valleys) over the SC's own
        // wrinkling: at least two counted peaks, the dominant one far longer than the SC's.
        let p = &at(three, f).peaks;
        assert!(p.len() >= 2, "three layers at frame {f}: {:?}", mm(p));
        assert!(p[0].wavelength > 2.0 * onset3, "furrows at frame {f}: {:?} vs SC {onset3}", mm(p));
        // Two layers, and SC / soft living epidermis / dermis: one wavelength, close to the one
        // they first wrinkled at (no second, distinct wavelength: less than 1.5 times it).
        for (name, frames) in [("two layers", &two), ("soft middle", &soft_middle)] {
            let p = &at(frames, f).peaks;
            let (_, first) = onset(frames);
            assert_eq!(p.len(), 1, "{name} at frame {f}: {:?}", mm(p));
            assert!(p[0].wavelength < 1.5 * first, "{name}: {:?} vs first {first}", mm(p));
        }
    }
}

#[test]
fn corotational_elements_invert_where_bazant_hencky_do_not() {
    let bh = baseline();
    let corot = run("exp1_corotational", None);
    let count = |frames: &[Frame]| frames.iter().map(|f| f.inverted).max().unwrap();
    println!(
        "inverted tets, most in any frame: Bazant-Hencky {}, corotational {} (frame 39: {})",
        count(bh),
        count(&corot),
        at(&corot, AT_80_5).inverted
    );
    assert_eq!(count(bh), 0);
    assert!(at(&corot, AT_80_5).inverted > 0);
}

#[test]
fn the_wrinkle_wavelength_grows_with_sc_thickness() {
    let mut last = 0.0;
    for (tag, h) in [("25um", 25.0), ("33_3um", 33.3), ("37_5um", 37.5), ("50um", 50.0), ("100um", 100.0)] {
        let frames = run(&format!("exp5_sc_{tag}"), Some(12));
        let (frame, wavelength) = onset(&frames);
        println!("SC {h} um: first wrinkles at frame {frame}, wavelength {:.3} mm", wavelength * 1e3);
        assert!(wavelength > last, "{h} um: {wavelength} after {last}");
        last = wavelength;
    }
}
