//! Scratch: one case-7 run from the command line (ratio waves cells_per_wave depth_elements).
use skinsim_tools::film::FilmSubstrate;
fn main() {
    let a: Vec<f64> = std::env::args().skip(1).map(|s| s.parse().unwrap()).collect();
    let mut f = if a[0] < 1.0 {
        // depth ratio, nu, cpw, de
        FilmSubstrate::on_rigid(a[0], a[1], a[2] as u32, a[3] as u32)
    } else {
        FilmSubstrate::deep(a[0], a[1] as u32, a[2] as u32, a[3] as u32)
    };
    if a[0] >= 1.0 {
        f.grading = a.get(4).copied().unwrap_or(1.0);
    }
    let r = f.run().unwrap();
    println!(
        "ratio {} waves {} cpw {} de {} g {}: lambda {:+.2}% onset {:+.2}% amp {:?} | {:.1} ms/inc, {} it, conv {} verts {}",
        a[0], a[1], a[2], a[3], f.grading, 100.0 * r.wavelength_error(), 100.0 * r.onset_error(),
        r.amplitude_errors.iter().map(|(t, e)| format!("{t}:{:+.1}%", 100.0 * e)).collect::<Vec<_>>(),
        1e3 * r.wall_per_increment_s, r.newton_iterations, r.all_converged, r.vertices
    );
}
