//! What a viewer needs of a deformed surface: vertex normals and a colour per vertex, by strain
//! (blue for stretch, red for compression, as LK14 fig. 6-4), curvature, height or layer.

use glam::DVec3;

/// Area of triangle `t` of the points `p`.
pub(crate) fn triangle_area(p: &[DVec3], t: &[u32; 3]) -> f64 {
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
pub(crate) fn stress_free_area(rest_area: f64, f0: glam::DMat2) -> f64 {
    rest_area / f0.determinant()
}

/// What the vertex colour of a drawn layer shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ColourBy {
    /// Elastic area strain: blue stretch, red compression, white at rest (saturated at 10 %).
    #[default]
    Strain,
    /// Signed mean curvature: blue crests, red troughs (the wrinkles show where strain is white).
    Curvature,
    /// Height over the layer's best-fit plane: blue up, red down (for patches flat at large scale).
    Height,
    /// One fixed colour per layer of a patch.
    Layer,
}

impl ColourBy {
    pub const ALL: [ColourBy; 4] = [ColourBy::Strain, ColourBy::Curvature, ColourBy::Height, ColourBy::Layer];

    /// What the colours mean (the legend's heading; per-layer scales follow it).
    pub fn legend(self) -> &'static str {
        match self {
            ColourBy::Strain => {
                "Elastic area strain, from the prestrained rest shape: white at rest, blue stretch, red compression; \
                 saturated at 10 %."
            }
            ColourBy::Curvature => {
                "Mean curvature: blue crest, red trough, white flat. Each layer saturates at the 98th percentile \
                 of |H| at the first solved frame (or `--colour-scale`, 1/m), fixed for the run:"
            }
            ColourBy::Height => {
                "Height over the layer's best-fit plane: blue above, red below. Each layer saturates at the 98th \
                 percentile of |height| at the first solved frame (or `--colour-scale`, mm), fixed for the run:"
            }
            ColourBy::Layer => "One colour per layer:",
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            ColourBy::Strain => "strain",
            ColourBy::Curvature => "curvature",
            ColourBy::Height => "height",
            ColourBy::Layer => "layer",
        }
    }
}

/// The area strain at which the strain colour saturates.
pub const STRAIN_SATURATION: f64 = 0.1;

/// A drawn triangle's prestrain: a shell face's F0, or that of the tet a boundary face bounds.
pub enum Prestrain {
    Face(glam::DMat2),
    Tet(glam::DMat3),
}

/// Per triangle the area its elastic strain is measured from: the rest area, or with a
/// prestrain the stress-free shape's.
pub fn stress_free_areas(rest: &[DVec3], tris: &[[u32; 3]], prestrain: &[Option<Prestrain>]) -> Vec<f64> {
    let mut areas: Vec<f64> = tris.iter().map(|t| triangle_area(rest, t)).collect();
    for ((a, f0), t) in areas.iter_mut().zip(prestrain).zip(tris) {
        match f0 {
            Some(Prestrain::Face(f0)) => *a = stress_free_area(*a, *f0),
            Some(Prestrain::Tet(f0)) => {
                let [p, q, r] = t.map(|v| rest[v as usize]);
                *a = stress_free_face_area(*a, (q - p).cross(r - p).normalize_or_zero(), *f0);
            }
            None => {}
        }
    }
    areas
}

/// The stress-free area of a boundary face (area `rest_area`, unit normal `normal`) of a tet
/// whose prestrain is `f0` (F = dx/dX F0): the face mapped by F0^-1 has the area
/// |F0^T n| rest_area / det(F0) (Nanson's formula).
pub(crate) fn stress_free_face_area(rest_area: f64, normal: DVec3, f0: glam::DMat3) -> f64 {
    rest_area * (f0.transpose() * normal).length() / f0.determinant()
}

/// RGBA colour of a signed value: white at 0, blue for positive, red for negative, saturated
/// at |value| = `scale` (white everywhere for a zero or non-finite scale).
pub fn diverging_colour(value: f64, scale: f64) -> [u8; 4] {
    let s = if scale > 0.0 && scale.is_finite() { (value / scale).clamp(-1.0, 1.0) } else { 0.0 };
    let s = if s.is_nan() { 0.0 } else { s };
    let fade = |s: f64| (255.0 * (1.0 - s.abs())).round() as u8;
    if s >= 0.0 {
        [fade(s), fade(s), 255, 255]
    } else {
        [255, fade(s), fade(s), 255]
    }
}

/// Per vertex the signed mean curvature H (1/m) of a triangle surface: half the normal
/// component of the cotangent Laplacian, K(x_i) = 1/(2 A_i) sum_j (cot a_ij + cot b_ij)(x_i - x_j)
/// = 2 H n_i (Meyer et al. 2003), with A_i a third of the vertex's triangle areas. Positive
/// where the surface bulges along its normal (a crest), negative in a trough.
pub fn mean_curvature(pos: &[DVec3], tris: &[[u32; 3]], normals: &[DVec3]) -> Vec<f64> {
    let mut k = vec![DVec3::ZERO; pos.len()];
    let mut area = vec![0.0f64; pos.len()];
    for t in tris {
        let p = t.map(|v| pos[v as usize]);
        let double_area = (p[1] - p[0]).cross(p[2] - p[0]).length();
        if double_area <= 0.0 || !double_area.is_finite() {
            continue;
        }
        for c in 0..3 {
            // The angle at corner c weighs the opposite edge (i, j).
            let (i, j) = ((c + 1) % 3, (c + 2) % 3);
            let (a, b) = (p[i] - p[c], p[j] - p[c]);
            let cot = a.dot(b) / double_area;
            let (vi, vj) = (t[i] as usize, t[j] as usize);
            k[vi] += cot * (p[i] - p[j]);
            k[vj] += cot * (p[j] - p[i]);
        }
        t.iter().for_each(|&v| area[v as usize] += double_area / 6.0);
    }
    k.iter().zip(&area).zip(normals).map(|((k, a), n)| if *a > 0.0 { 0.25 * k.dot(*n) / a } else { 0.0 }).collect()
}

/// Per vertex the signed height above the least-squares plane of the points (the rigid and
/// affine part of the shape removed), the plane's normal turned toward the mean of `normals`:
/// the wrinkle relief of a patch that is flat at large scale.
pub fn plane_height(pos: &[DVec3], normals: &[DVec3]) -> Vec<f64> {
    if pos.is_empty() {
        return Vec::new();
    }
    let centre = pos.iter().copied().sum::<DVec3>() / pos.len() as f64;
    let mut cov = nalgebra::Matrix3::<f64>::zeros();
    for p in pos {
        let d = nalgebra::Vector3::new(p.x - centre.x, p.y - centre.y, p.z - centre.z);
        cov += d * d.transpose();
    }
    let eig = nalgebra::SymmetricEigen::new(cov);
    let smallest = eig.eigenvalues.imin();
    let e = eig.eigenvectors.column(smallest);
    let mut n = DVec3::new(e[0], e[1], e[2]);
    if n.dot(normals.iter().copied().sum::<DVec3>()) < 0.0 {
        n = -n;
    }
    pos.iter().map(|p| (*p - centre).dot(n)).collect()
}

/// A scale for the colours of `values` that does not flicker from frame to frame: the larger
/// of `previous` and the 98th percentile of |value| (a few spikes do not wash the rest out).
pub fn running_scale(previous: f64, values: &[f64]) -> f64 {
    let mut abs: Vec<f64> = values.iter().map(|v| v.abs()).filter(|v| v.is_finite()).collect();
    if abs.is_empty() {
        return previous;
    }
    let at = ((abs.len() - 1) as f64 * 0.98).round() as usize;
    let (_, p98, _) = abs.select_nth_unstable_by(at, f64::total_cmp);
    previous.max(*p98)
}

/// The diverging palette from -1 (left) to +1 (right) as `width` x `height` RGB bytes, row by
/// row: the viewer's colour bar.
pub fn colour_bar_rgb(width: u32, height: u32) -> Vec<u8> {
    let row: Vec<u8> = (0..width)
        .flat_map(|x| {
            let c = diverging_colour(2.0 * x as f64 / (width.max(2) - 1) as f64 - 1.0, 1.0);
            [c[0], c[1], c[2]]
        })
        .collect();
    row.repeat(height as usize)
}

/// The colour of the `index`th layer of a patch (a fixed palette, repeating after eight).
pub fn layer_colour(index: usize) -> [u8; 4] {
    const PALETTE: [[u8; 3]; 8] = [
        [240, 200, 170], // skin
        [200, 110, 110],
        [240, 220, 120],
        [130, 170, 220],
        [140, 200, 140],
        [190, 150, 210],
        [230, 160, 90],
        [160, 160, 160],
    ];
    let [r, g, b] = PALETTE[index % PALETTE.len()];
    [r, g, b, 255]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stretch_is_blue_compression_red_rest_white() {
        assert_eq!(diverging_colour(0.0, STRAIN_SATURATION), [255, 255, 255, 255]);
        assert_eq!(diverging_colour(0.2, STRAIN_SATURATION), [0, 0, 255, 255]);
        assert_eq!(diverging_colour(-0.2, STRAIN_SATURATION), [255, 0, 0, 255]);
    }

    /// A grid over a height function z = f(x, y) on [-1, 1]^2, n x n cells.
    fn surface(n: usize, f: impl Fn(f64, f64) -> f64) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let mut pos = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (2.0 * i as f64 / n as f64 - 1.0, 2.0 * j as f64 / n as f64 - 1.0);
                pos.push(DVec3::new(x, y, f(x, y)));
            }
        }
        let id = |i: usize, j: usize| (j * (n + 1) + i) as u32;
        let mut tris = Vec::new();
        for j in 0..n {
            for i in 0..n {
                tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        (pos, tris)
    }

    #[test]
    fn a_cap_has_the_mean_curvature_of_its_sphere() {
        // The top of a sphere of radius 5: H = 1/5 (a crest: positive along the upward normal).
        let r = 5.0f64;
        let (pos, tris) = surface(40, |x, y| (r * r - x * x - y * y).sqrt());
        let normals = vertex_normals(&pos, &tris);
        let h = mean_curvature(&pos, &tris, &normals);
        let centre = 20 * 41 + 20;
        assert!((h[centre] - 1.0 / r).abs() < 1e-3 * (1.0 / r), "{}", h[centre]);
        // A crest of a wave is positive, a trough negative; a plane has none.
        let (pos, tris) = surface(40, |x, _| 0.01 * (2.0 * std::f64::consts::PI * x).cos());
        let h = mean_curvature(&pos, &tris, &vertex_normals(&pos, &tris));
        assert!(h[centre] > 0.0 && h[20 * 41 + 10] < 0.0, "{} {}", h[centre], h[20 * 41 + 10]);
        let (pos, tris) = surface(10, |x, y| 0.3 * x - 0.2 * y);
        assert!(mean_curvature(&pos, &tris, &vertex_normals(&pos, &tris)).iter().all(|h| h.abs() < 1e-12));
    }

    #[test]
    fn height_is_the_relief_over_the_best_plane() {
        // A tilted plane carrying a bump: the tilt goes, the bump stays (up along the normal).
        let bump = |x: f64, y: f64| 0.05 * (-(x * x + y * y) * 20.0).exp();
        let (pos, tris) = surface(30, |x, y| 0.4 * x + 0.1 * y + bump(x, y));
        let h = plane_height(&pos, &vertex_normals(&pos, &tris));
        let centre = 15 * 31 + 15;
        assert!(h[centre] > 0.04 && h[0].abs() < 0.01, "{} {}", h[centre], h[0]);
        let (flat, _) = surface(5, |x, y| 0.4 * x + 0.1 * y);
        assert!(plane_height(&flat, &vec![DVec3::Z; flat.len()]).iter().all(|h| h.abs() < 1e-12));
    }

    #[test]
    fn the_colour_scale_keeps_its_largest_and_ignores_spikes() {
        let mut v: Vec<f64> = (0..100).map(|i| i as f64 / 100.0).collect();
        v[3] = 1e6;
        let s = running_scale(0.0, &v);
        assert!(s < 1.0, "{s}");
        assert_eq!(running_scale(2.0, &v), 2.0);
        assert_eq!(diverging_colour(1.0, 0.0), [255, 255, 255, 255]);
        assert_eq!(diverging_colour(-3.0, 1.0), [255, 0, 0, 255]);
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
    fn a_prestrained_tet_face_measures_from_its_stress_free_shape() {
        // Stretched 10 % along x: a face across x keeps its area, a face along x loses 1/1.1.
        let f0 = glam::DMat3::from_diagonal(DVec3::new(1.1, 1.0, 1.0));
        assert!((stress_free_face_area(1.0, DVec3::X, f0) - 1.0).abs() < 1e-12);
        assert!((stress_free_face_area(1.0, DVec3::Z, f0) - 1.0 / 1.1).abs() < 1e-12);
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
