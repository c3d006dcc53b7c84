//! Scratch: one case-9 run (cells_per_wave dermis_elements hypodermis_elements).
use skinsim_tools::skin_section::SkinSection;
fn main() {
    let a: Vec<u32> = std::env::args().skip(1).map(|s| s.parse().unwrap()).collect();
    let r = SkinSection { cells_per_wave: a[0], dermis_elements: a[1], hypodermis_elements: a[2] }.run().unwrap();
    println!(
        "{a:?}: first {:.3} mm onset {:.4} at {:?} | {:.0} ms/inc {} it conv {} verts {}",
        r.first_wavelength_mm,
        r.onset,
        r.at,
        1e3 * r.wall_per_increment_s,
        r.newton_iterations,
        r.all_converged,
        r.vertices
    );
}
