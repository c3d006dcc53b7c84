//! Errors a user can see (issue 26 item 4), beside the energy error: the wrinkle-map error (the
//! mean angle between the normals two baked wrinkle maps encode, pixel by pixel, on the same
//! material grid) and the height-field error (the difference of two height fields on the same
//! material points after removing its best affine fit: a small rigid motion of a nearly flat
//! sheet, a drift of its mean plane or a tilt, changes heights by an affine function).

use glam::{DMat3, DVec2, DVec3};
use image::RgbImage;
use skinsim::mesh::wrinkle_map::decode;

/// Mean angle (radians) between the normals of two wrinkle maps of the same size, as baked
/// (8-bit).
pub fn map_error(a: &RgbImage, b: &RgbImage) -> f64 {
    assert_eq!(a.dimensions(), b.dimensions(), "maps compared must have the same size");
    let (a, b): (Vec<DVec3>, Vec<DVec3>) =
        (a.pixels().map(|p| decode(*p)).collect(), b.pixels().map(|p| decode(*p)).collect());
    sample_error(&a, &b)
}

/// Mean angle (radians) between two maps' normals before the encoding
/// (`wrinkle_map::normal_samples`): the report's map error.
pub fn sample_error(a: &[DVec3], b: &[DVec3]) -> f64 {
    assert_eq!(a.len(), b.len(), "maps compared must have the same size");
    let total: f64 = a.iter().zip(b).map(|(p, q)| if p == q { 0.0 } else { p.angle_between(*q) }).sum();
    total / a.len().max(1) as f64
}

/// The residual of `h` (one value per material point) after its least-squares affine fit
/// a + b u + c v.
fn without_affine(material: &[DVec2], h: &[f64]) -> Vec<f64> {
    let mut normal = DMat3::ZERO;
    let mut rhs = DVec3::ZERO;
    for (u, &z) in material.iter().zip(h) {
        let row = DVec3::new(1.0, u.x, u.y);
        normal += DMat3::from_cols(row * row.x, row * row.y, row * row.z);
        rhs += row * z;
    }
    let coef = if normal.determinant().abs() > 0.0 { normal.inverse() * rhs } else { DVec3::ZERO };
    material.iter().zip(h).map(|(u, &z)| z - coef.dot(DVec3::new(1.0, u.x, u.y))).collect()
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// Height-field error of `run` against `reference` (positions at the same material points):
/// the RMS of their height difference without its affine part, over the RMS wrinkle height of
/// the reference (its heights without their affine part).
pub fn height_error(material: &[DVec2], reference: &[DVec3], run: &[DVec3]) -> f64 {
    assert_eq!(reference.len(), run.len(), "height fields compared must share their points");
    let d: Vec<f64> = run.iter().zip(reference).map(|(a, b)| a.z - b.z).collect();
    let h: Vec<f64> = reference.iter().map(|p| p.z).collect();
    rms(&without_affine(material, &d)) / rms(&without_affine(material, &h))
}

#[cfg(test)]
mod tests {
    use super::*;
    use skinsim::mesh::wrinkle_map::{normal_map, normal_samples};
    use skinsim::mesh::{grid, shading::vertex_normals, GridPattern};

    /// A wrinkled unit sheet (waves along x of wavelength 0.1 and amplitude a, shifted by
    /// `phase` radians) baked into a 128-pixel map.
    fn baked(a: f64, phase: f64) -> (RgbImage, Vec<DVec2>, Vec<DVec3>) {
        let m = grid(DVec2::ONE, (100, 50), GridPattern::Equilateral, 0.0);
        let x: Vec<DVec3> =
            m.uv.iter().map(|u| u.extend(a * (2.0 * std::f64::consts::PI * u.x / 0.1 + phase).sin())).collect();
        let n = vertex_normals(&x, &m.faces);
        (normal_map(&m.uv, &m.faces, &n, 128, DVec2::ZERO, DVec2::ONE), m.uv, x)
    }

    #[test]
    fn the_map_error_is_zero_for_identical_runs_and_grows_with_a_phase_shift() {
        let (reference, ..) = baked(0.005, 0.0);
        assert_eq!(map_error(&reference, &baked(0.005, 0.0).0), 0.0);
        let errors: Vec<f64> = [0.1, 0.3, 1.0].iter().map(|&p| map_error(&reference, &baked(0.005, p).0)).collect();
        assert!(errors[0] > 0.0 && errors[0] < errors[1] && errors[1] < errors[2], "{errors:?}");
        // A uniform tilt by theta reads as theta (to the 8-bit encoding's resolution).
        let flat = RgbImage::from_pixel(8, 8, skinsim::mesh::wrinkle_map::encode(DVec3::Z));
        let theta = 0.1f64;
        let tilted = skinsim::mesh::wrinkle_map::encode(DVec3::new(theta.sin(), 0.0, theta.cos()));
        let err = map_error(&flat, &RgbImage::from_pixel(8, 8, tilted));
        assert!((err - theta).abs() < 0.01, "{err}");
        // Before the encoding: exact, and as fine as the geometry.
        let flat = vec![DVec3::Z; 64];
        assert_eq!(sample_error(&flat, &flat), 0.0);
        let tilted = vec![DVec3::new(theta.sin(), 0.0, theta.cos()); 64];
        assert!((sample_error(&flat, &tilted) - theta).abs() < 1e-12);
        let m = grid(DVec2::ONE, (100, 50), GridPattern::Equilateral, 0.0);
        let bake = |phase: f64| {
            let x: Vec<DVec3> =
                m.uv.iter().map(|u| u.extend(0.005 * (2.0 * std::f64::consts::PI * u.x / 0.1 + phase).sin())).collect();
            normal_samples(&m.uv, &m.faces, &vertex_normals(&x, &m.faces), 128, DVec2::ZERO, DVec2::ONE)
        };
        let errors: Vec<f64> = [0.01, 0.1, 1.0].iter().map(|&p| sample_error(&bake(0.0), &bake(p))).collect();
        assert!(errors[0] > 0.0 && errors[0] < errors[1] && errors[1] < errors[2], "{errors:?}");
    }

    #[test]
    fn the_height_error_ignores_affine_motion_and_measures_a_known_bump() {
        let (_, uv, reference) = baked(0.005, 0.0);
        assert_eq!(height_error(&uv, &reference, &reference), 0.0);
        // Lifted and tilted: no error.
        let moved: Vec<DVec3> =
            reference.iter().zip(&uv).map(|(p, u)| *p + DVec3::Z * (0.3 + 0.02 * u.x - 0.01 * u.y)).collect();
        let e = height_error(&uv, &reference, &moved);
        assert!(e < 1e-8, "{e}");
        // The same waves at 1.2 times the amplitude: an error of 0.2.
        let (_, _, taller) = baked(0.006, 0.0);
        let e = height_error(&uv, &reference, &taller);
        assert!((e - 0.2).abs() < 1e-3, "{e}");
    }
}
