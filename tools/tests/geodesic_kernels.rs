//! Issue 24 (LK14 6.2): kernels on a curved patch, measured on the surface. VALIDATION.md case
//! 10's scene (one shell held by eq. 3.1 kernels, lambda = 6 mm, over a base compressed 10 %
//! along x) on a cylindrical patch of radius 20 wavelengths: with undistorted UVs it wrinkles at
//! the kernel wavelength; with UVs stretched 2:1 along the compression axis, or radially
//! distorted (up to 2.5:1 at the ends), geodesic kernels keep the world-space wavelength; planar
//! ones follow the UVs (reported, and asserted off for the stretch). `cargo test --release -p skinsim-cli
//! --test geodesic_kernels -- --nocapture` prints the figures.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};
use skinsim::scene;
use skinsim_systems::Simulation;
use skinsim_tools::wrinkles::row_peaks;

const LAMBDA_MM: f64 = 6.0;
const RADIUS_MM: f64 = 20.0 * LAMBDA_MM;

/// How the texture coordinates distort the unrolled surface (mm).
#[derive(Clone, Copy, Debug)]
enum Uvs {
    Undistorted,
    /// x2 along the compression axis.
    Stretched,
    /// Radially from the patch centre: d (1 + (|d| / 48 mm)^2 / 2).
    Radial,
}

impl Uvs {
    fn map(self, u: DVec2) -> DVec2 {
        match self {
            Uvs::Undistorted => u,
            Uvs::Stretched => DVec2::new(2.0 * u.x, u.y),
            Uvs::Radial => {
                let (c, d) = (DVec2::new(48.0, 6.0), u - DVec2::new(48.0, 6.0));
                c + d * (1.0 + 0.5 * (d.length() / 48.0).powi(2))
            }
        }
    }
}

/// The unrolled surface: 96 x 12 mm, 128 x 18 cells.
fn surface() -> skinsim::mesh::SurfaceMesh {
    skinsim::mesh::grid(DVec2::new(96.0, 12.0), (128, 18), skinsim::mesh::GridPattern::Equilateral, 0.0)
}

/// Writes a cylindrical patch (axis x, the unrolled surface wrapped with its top at z = 0) as an
/// OBJ in millimetres, its texture coordinates the unrolled surface distorted by `uvs`.
fn cylinder_obj(dir: &Path, uvs: Uvs) -> PathBuf {
    let m = surface();
    let mut text = String::new();
    for u in &m.uv {
        let a = (u.y - 6.0) / RADIUS_MM;
        let p = DVec3::new(u.x, RADIUS_MM * a.sin(), RADIUS_MM * (a.cos() - 1.0));
        writeln!(text, "v {} {} {}", p.x, p.y, p.z).unwrap();
    }
    for u in &m.uv {
        let t = uvs.map(*u);
        writeln!(text, "vt {} {}", t.x, t.y).unwrap();
    }
    for f in &m.faces {
        let [a, b, c] = f.map(|i| i + 1);
        writeln!(text, "f {a}/{a} {b}/{b} {c}/{c}").unwrap();
    }
    let path = dir.join(format!("cylinder_{uvs:?}.obj"));
    std::fs::write(&path, text).unwrap();
    path
}

/// Runs the curved case-10 scene; returns the dominant wavelength (mm, along the rest surface)
/// and whether every frame converged.
fn wavelength(uvs: Uvs, distance: &str) -> (f64, bool) {
    let dir = std::env::temp_dir().join(format!("skinsim_geodesic_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let obj = cylinder_obj(&dir, uvs);
    let text = format!(
        r#"Scene(name: "cylinder", units: (length: Millimetre, stress: MegaPascal), frames: 6,
    output: (stats: false, rerun: false),
    patches: [Patch(name: "skin",
        solver: (tolerance: 1e-8, max_iterations: 200, projection: None, perturbation: Some((amplitude: 0.00375, seed: 3))),
        layers: [
            Layer(name: "base", kind: Kinematic, mesh: Obj(path: "{}")),
            Layer(name: "skin", kind: Shell, mesh: Offset(layer: "base", distance: 0.01875),
                  material: (model: BazantHencky, young: 4.0, poisson: 0.45, thickness: 0.0375), bending: Some((model: Tan))),
        ],
        drivers: [BlendShape(layer: "base", targets: [
            Target(shape: Compress(axis: X, strain: 0.1), weights: [(0, 0.0), (1, 0.01), (6, 1.0)]),
        ])],
        couplings: [Coupling(upper: "skin", lower: "base", wavelength: Eq31(constant: 5.657, lower: Some((0.5, 15.0))),
                             seed: 1, distance: {distance})],
    )],
)"#,
        obj.file_name().unwrap().to_str().unwrap()
    );
    let built = scene::load_str(&text, &dir.join("cylinder.ron")).unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(&built);
    let mut converged = true;
    for _ in 0..built.scene.frames {
        let s = sim.step();
        converged &= s.patches.iter().all(|p| p.outcome.converged);
    }
    // Rows along x at their unrolled surface coordinates (the skin's vertices are the base's,
    // offset, in the same order).
    let pos: Vec<DVec3> = sim.layer_points("skin", "skin").into_iter().map(|p| p.1).collect();
    let unrolled: Vec<DVec2> = surface().uv.iter().map(|u| *u * 1e-3).collect();
    assert_eq!(pos.len(), unrolled.len());
    let peaks = row_peaks(&pos, &unrolled, 0, 0.05);
    (1e3 * peaks[0].wavelength, converged)
}

#[test]
fn geodesic_kernels_keep_the_wavelength_where_the_uvs_stretch() {
    let expected = 5.657 * (0.0375f64 * 15.0).sqrt() * (4.0f64 / 0.5).powf(1.0 / 6.0);
    let mut table = Vec::new();
    for (uvs, distance) in [
        (Uvs::Undistorted, "Planar"),
        (Uvs::Undistorted, "Geodesic"),
        (Uvs::Stretched, "Geodesic"),
        (Uvs::Stretched, "Planar"),
        (Uvs::Radial, "Geodesic"),
        (Uvs::Radial, "Planar"),
    ] {
        let (w, converged) = wavelength(uvs, distance);
        println!(
            "cylinder R = 20 lambda, {uvs:?} UVs, {distance} kernels: wavelength {w:.3} mm ({:+.1} % of {expected:.3})",
            100.0 * (w / expected - 1.0)
        );
        assert!(converged, "{uvs:?} {distance}");
        table.push(w);
    }
    // Case 10's rule on the curved surface, both kernel rules.
    assert!((table[0] / expected - 1.0).abs() < 0.10, "planar on undistorted UVs: {}", table[0]);
    assert!((table[1] / expected - 1.0).abs() < 0.10, "geodesic on undistorted UVs: {}", table[1]);
    // Geodesic kernels do not see the distortion; planar ones do.
    assert!((table[2] / table[1] - 1.0).abs() < 0.10, "geodesic, stretched UVs: {} vs {}", table[2], table[1]);
    assert!((table[3] / table[0] - 1.0).abs() > 0.10, "planar kernels follow the UVs: {} vs {}", table[3], table[0]);
    assert!((table[4] / table[1] - 1.0).abs() < 0.10, "geodesic, radial UVs: {} vs {}", table[4], table[1]);
}
