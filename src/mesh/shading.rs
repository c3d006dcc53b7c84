//! What a viewer needs of a deformed surface: vertex normals and a strain colour per vertex
//! (blue for stretch, red for compression, as LK14 fig. 6-4).

use glam::DVec3;

/// Area of triangle `t` of the points `p`.
pub fn triangle_area(p: &[DVec3], t: &[u32; 3]) -> f64 {
    let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
    0.5 * (b - a).cross(c - a).length()
}

/// Area-weighted unit vertex normals.
pub fn vertex_normals(pos: &[DVec3], tris: &[[u32; 3]]) -> Vec<DVec3> {
    let mut normals = vec![DVec3::ZERO; pos.len()];
    for t in tris {
        let (a, b, c) = (pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize]);
        let n = (b - a).cross(c - a);
        t.iter().for_each(|&v| normals[v as usize] += n);
    }
    normals.iter_mut().for_each(|n| *n = n.normalize_or_zero());
    normals
}

/// Area-weighted unit vertex normals, and per vertex the mean area strain (area / rest area - 1)
/// of its triangles.
pub fn normals_and_strain(pos: &[DVec3], tris: &[[u32; 3]], rest_area: &[f64]) -> (Vec<DVec3>, Vec<f64>) {
    let mut normals = vec![DVec3::ZERO; pos.len()];
    let mut strain = vec![0.0; pos.len()];
    let mut count = vec![0.0f64; pos.len()];
    for (t, ra) in tris.iter().zip(rest_area) {
        let (a, b, c) = (pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize]);
        let n = (b - a).cross(c - a);
        let s = 0.5 * n.length() / ra - 1.0;
        for &v in t {
            normals[v as usize] += n;
            strain[v as usize] += s;
            count[v as usize] += 1.0;
        }
    }
    normals.iter_mut().for_each(|n| *n = n.normalize_or_zero());
    strain.iter_mut().zip(&count).for_each(|(s, c)| *s /= c.max(1.0));
    (normals, strain)
}

/// The stress-free area of a rest triangle of area `rest_area` whose membrane prestrain is `f0`
/// (H15 eq. 4.8, F = dx/dX F0): the elastic area strain is area det(F0) / rest_area - 1, so a
/// prestretched layer at its placed shape draws stretched, and relaxed, unstrained.
pub fn stress_free_area(rest_area: f64, f0: glam::DMat2) -> f64 {
    rest_area / f0.determinant()
}

/// RGBA colour of an area strain: white at rest, blue for stretch, red for compression,
/// saturated at 10 %.
pub fn strain_colour(strain: f64) -> [u8; 4] {
    let s = (strain / 0.1).clamp(-1.0, 1.0);
    let fade = |s: f64| (255.0 * (1.0 - s.abs())).round() as u8;
    if s >= 0.0 {
        [fade(s), fade(s), 255, 255]
    } else {
        [255, fade(s), fade(s), 255]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stretch_is_blue_compression_red_rest_white() {
        assert_eq!(strain_colour(0.0), [255, 255, 255, 255]);
        assert_eq!(strain_colour(0.2), [0, 0, 255, 255]);
        assert_eq!(strain_colour(-0.2), [255, 0, 0, 255]);
    }

    #[test]
    fn a_prestretched_triangle_is_unstrained_where_it_relaxed() {
        let rest = [DVec3::ZERO, DVec3::X * 1.1, DVec3::Y];
        let tri = [[0, 1, 2]];
        let f0 = glam::DMat2::from_diagonal(glam::DVec2::new(1.1, 1.0));
        let area = [stress_free_area(triangle_area(&rest, &tri[0]), f0)];
        let relaxed = [DVec3::ZERO, DVec3::X, DVec3::Y];
        assert!(normals_and_strain(&relaxed, &tri, &area).1[0].abs() < 1e-12);
        assert!((normals_and_strain(&rest, &tri, &area).1[0] - 0.1).abs() < 1e-12);
    }

    #[test]
    fn a_stretched_triangle_has_its_strain_and_normal() {
        let rest = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let tri = [[0, 1, 2]];
        let area = [triangle_area(&rest, &tri[0])];
        let pos = [DVec3::ZERO, DVec3::X * 1.1, DVec3::Y];
        let (n, s) = normals_and_strain(&pos, &tri, &area);
        assert!(n.iter().all(|n| (*n - DVec3::Z).length() < 1e-12));
        assert!(s.iter().all(|s| (s - 0.1).abs() < 1e-12));
    }
}
