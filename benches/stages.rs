//! Per-stage time breakdown of a scene (default: the default scene), as fractions of the frame
//! measured in one run. `cargo bench --bench stages [-- SCENE]`.

use skinsim::model::Stage;
use skinsim_systems::Simulation;

fn main() {
    let arg = std::env::args().skip(1).find(|a| a.ends_with(".ron"));
    let path = arg
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/strip_wrinkles.ron"));
    let scene = skinsim::scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(&scene);
    let mut totals = [0.0f64; Stage::ALL.len()];
    let mut total = 0.0;
    let mut iterations = 0;
    let mut inner = [0.0f64; 3];
    for _ in 0..scene.scene.frames {
        let s = sim.step();
        for stage in Stage::ALL {
            totals[stage as usize] += s.timing(stage);
        }
        total += s.total_ms();
        iterations += s.patches.iter().map(|p| p.outcome.iterations).sum::<u32>();
        for p in &s.patches {
            inner[0] += p.outcome.counters.assemble_ms;
            inner[1] += p.outcome.counters.factorize_ms;
            inner[2] += p.outcome.counters.line_search_ms;
        }
    }
    let frames = scene.scene.frames as f64;
    println!(
        "{}: {} frames, {:.1} ms/frame, {:.1} Newton iterations/frame",
        path.display(),
        frames,
        total / frames,
        iterations as f64 / frames
    );
    println!("{:<22}{:>12}{:>10}", "stage", "ms/frame", "share");
    for stage in Stage::ALL {
        let t = totals[stage as usize];
        println!("{:<22}{:>12.3}{:>9.1}%", stage.key(), t / frames, 100.0 * t / total);
    }
    println!("inside solve (summed over patches):");
    for (name, t) in ["element assembly", "factorize + solve", "line search"].iter().zip(inner) {
        println!("  {:<20}{:>12.3}{:>9.1}%", name, t / frames, 100.0 * t / total);
    }
}
