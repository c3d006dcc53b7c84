//! Issue 27: VALIDATION.md case 7 (stiff film on a deep substrate, Ebar_f / Ebar_s = 1000) at
//! substrate Poisson's ratios 0.45 and 0.495 with the per-tet and the per-cell volume element
//! (`physics::cell`), alternating in one run (this VM drifts between hours), then the per-tet
//! element at 0.495 on finer meshes, to compare time at equal error.
//! `cargo bench -p skinsim-cli --bench volume_element [-- --rounds N]` (about 4 minutes).

use skinsim::physics::cell::VolumeElement;
use skinsim_tools::film::{FilmResult, FilmSubstrate};

fn run(nu: f64, element: VolumeElement, cells_per_wave: u32, depth_elements: u32) -> FilmResult {
    let mut s = FilmSubstrate::deep(1000.0, 8, cells_per_wave, depth_elements);
    s.grading = 20.0;
    s.substrate_poisson = nu;
    s.volume_element = Some(element);
    s.run().expect("the film scene loads")
}

fn row(nu: f64, element: VolumeElement, mesh: (u32, u32), r: &FilmResult) {
    println!(
        "| {nu} | {element:?} | {} x {} | {} | {:.0} | {:+.2} | {:+.2} | {:.2} | {} | {} |",
        mesh.0,
        mesh.1,
        r.tets,
        1e3 * r.wall_per_increment_s,
        100.0 * r.wavelength_error(),
        100.0 * r.onset_error(),
        100.0 * r.worst_amplitude_error(),
        r.newton_iterations,
        r.all_converged,
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let rounds = args
        .iter()
        .position(|a| a == "--rounds")
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(2);
    println!("| nu_s | element | cells per wave x depth elements | tets | ms per increment | wavelength % | onset % | worst amplitude % | Newton iterations | converged |");
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    for _ in 0..rounds {
        for nu in [0.45, 0.495] {
            for element in [VolumeElement::Tet, VolumeElement::Cell] {
                row(nu, element, (20, 20), &run(nu, element, 20, 20));
            }
        }
    }
    for mesh in [(40, 20), (20, 40), (40, 40)] {
        row(0.495, VolumeElement::Tet, mesh, &run(0.495, VolumeElement::Tet, mesh.0, mesh.1));
    }
}
