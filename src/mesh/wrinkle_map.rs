//! Wrinkle (normal) maps (LK14 5.4): the material-space mesh drawn with each vertex coloured by
//! its deformed normal mapped to [0, 1], into an 8-bit RGB image a shader can sample; and the
//! blend of two maps by a weight, as a shader interpolates between key poses.

use glam::{DVec2, DVec3};
use image::{Rgb, RgbImage};

/// The colour of a unit normal: each component mapped from [-1, 1] to [0, 255].
pub fn encode(n: DVec3) -> Rgb<u8> {
    let c = |v: f64| (255.0 * (0.5 + 0.5 * v.clamp(-1.0, 1.0))).round() as u8;
    Rgb([c(n.x), c(n.y), c(n.z)])
}

/// The unit normal a colour stands for.
pub fn decode(c: Rgb<u8>) -> DVec3 {
    DVec3::from_array(c.0.map(|v| v as f64 / 255.0 * 2.0 - 1.0)).normalize_or(DVec3::Z)
}

/// Draws the triangles `faces` at their material positions `uv` (the rectangle [lo, hi] fills
/// the image; row 0 at max y, as the property maps) with the vertex normals interpolated
/// barycentrically and renormalized. Pixels no triangle covers get the flat normal (0, 0, 1).
pub fn normal_map(uv: &[DVec2], faces: &[[u32; 3]], normals: &[DVec3], size: u32, lo: DVec2, hi: DVec2) -> RgbImage {
    let mut img = RgbImage::from_pixel(size, size, encode(DVec3::Z));
    draw_normals(&mut img, uv, faces, normals, lo, hi);
    img
}

/// Draws triangles into a square map as `normal_map` does, over what is already there (several
/// patches into one asset map).
pub fn draw_normals(img: &mut RgbImage, uv: &[DVec2], faces: &[[u32; 3]], normals: &[DVec3], lo: DVec2, hi: DVec2) {
    let size = img.width();
    rasterize(size, uv, faces, normals, lo, hi, |x, y, n| img.put_pixel(x, y, encode(n)));
}

/// The unit normals a `size` map of the triangles holds, before the 8-bit encoding, row by row
/// (row 0 at max y); (0, 0, 1) where no triangle covers a pixel's centre. What the map error
/// compares: the encoding's steps (up to about half a degree) would hide finer differences.
pub fn normal_samples(
    uv: &[DVec2],
    faces: &[[u32; 3]],
    normals: &[DVec3],
    size: u32,
    lo: DVec2,
    hi: DVec2,
) -> Vec<DVec3> {
    let mut out = vec![DVec3::Z; (size * size) as usize];
    rasterize(size, uv, faces, normals, lo, hi, |x, y, n| out[(y * size + x) as usize] = n);
    out
}

/// Calls `put(column, row, unit normal)` for every pixel centre of a `size` square map over
/// [lo, hi] that a triangle covers, the vertex normals interpolated barycentrically.
fn rasterize(
    size: u32,
    uv: &[DVec2],
    faces: &[[u32; 3]],
    normals: &[DVec3],
    lo: DVec2,
    hi: DVec2,
    mut put: impl FnMut(u32, u32, DVec3),
) {
    let span = (hi - lo).max(DVec2::splat(f64::MIN_POSITIVE));
    // Pixel centres: column i at x = lo.x + (i + 0.5) / size * span.x; row j from the top.
    let to_pixel = |p: DVec2| DVec2::new((p.x - lo.x) / span.x * size as f64, (hi.y - p.y) / span.y * size as f64);
    for f in faces {
        let [a, b, c] = f.map(|i| to_pixel(uv[i as usize]));
        let area = (b - a).perp_dot(c - a);
        if area.abs() < 1e-300 {
            continue;
        }
        let (min, max) = (a.min(b).min(c), a.max(b).max(c));
        let (x0, x1) = ((min.x - 0.5).ceil().max(0.0) as u32, ((max.x - 0.5).floor()).min(size as f64 - 1.0));
        let (y0, y1) = ((min.y - 0.5).ceil().max(0.0) as u32, ((max.y - 0.5).floor()).min(size as f64 - 1.0));
        if x1 < 0.0 || y1 < 0.0 {
            continue;
        }
        let n = f.map(|i| normals[i as usize]);
        for y in y0..=y1 as u32 {
            for x in x0..=x1 as u32 {
                let p = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                let (wa, wb) = ((b - p).perp_dot(c - p) / area, (c - p).perp_dot(a - p) / area);
                let wc = 1.0 - wa - wb;
                let eps = -1e-9;
                if wa >= eps && wb >= eps && wc >= eps {
                    put(x, y, (n[0] * wa + n[1] * wb + n[2] * wc).normalize_or(DVec3::Z));
                }
            }
        }
    }
}

/// Triangles whose UVs cannot be baked as they are: `flipped` (their UV winding is against the
/// majority's: a seam or a mirrored piece) and `overlapping` (not flipped, and sharing a pixel's
/// centre of a `size` map over [lo, hi] with another such triangle that is not a neighbour), by
/// face index.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct UvProblems {
    pub flipped: Vec<u32>,
    pub overlapping: Vec<u32>,
}

/// Finds flipped and overlapping UV triangles (`UvProblems`), at the map's resolution.
pub fn uv_problems(uv: &[DVec2], faces: &[[u32; 3]], size: u32, lo: DVec2, hi: DVec2) -> UvProblems {
    let signed = |f: &[u32; 3]| {
        let [a, b, c] = f.map(|i| uv[i as usize]);
        (b - a).perp_dot(c - a)
    };
    let positive = faces.iter().filter(|f| signed(f) > 0.0).count();
    let majority = if 2 * positive >= faces.len() { 1.0 } else { -1.0 };
    let flipped: Vec<u32> = (0..faces.len() as u32).filter(|&i| signed(&faces[i as usize]) * majority < 0.0).collect();
    // The first face whose interior holds each pixel centre; a second one that shares no vertex
    // with it overlaps (neighbours meet only on edges, within rounding).
    let span = (hi - lo).max(DVec2::splat(f64::MIN_POSITIVE));
    let to_pixel = |p: DVec2| DVec2::new((p.x - lo.x) / span.x * size as f64, (hi.y - p.y) / span.y * size as f64);
    let mut owner = vec![u32::MAX; (size * size) as usize];
    let mut overlapping = std::collections::BTreeSet::new();
    let mut skip = flipped.iter().peekable();
    for (fi, f) in faces.iter().enumerate() {
        if skip.next_if_eq(&&(fi as u32)).is_some() {
            continue;
        }
        let [a, b, c] = f.map(|i| to_pixel(uv[i as usize]));
        let area = (b - a).perp_dot(c - a);
        if area.abs() < 1e-300 {
            continue;
        }
        let (min, max) = (a.min(b).min(c), a.max(b).max(c));
        let x0 = (min.x - 0.5).ceil().max(0.0) as i64;
        let x1 = ((max.x - 0.5).floor()).min(size as f64 - 1.0) as i64;
        let y0 = (min.y - 0.5).ceil().max(0.0) as i64;
        let y1 = ((max.y - 0.5).floor()).min(size as f64 - 1.0) as i64;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let p = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                let (wa, wb) = ((b - p).perp_dot(c - p) / area, (c - p).perp_dot(a - p) / area);
                if wa.min(wb).min(1.0 - wa - wb) <= 1e-6 {
                    continue;
                }
                let slot = &mut owner[(y * size as i64 + x) as usize];
                if *slot == u32::MAX {
                    *slot = fi as u32;
                } else if !faces[*slot as usize].iter().any(|v| f.contains(v)) {
                    overlapping.insert(*slot);
                    overlapping.insert(fi as u32);
                }
            }
        }
    }
    UvProblems { flipped, overlapping: overlapping.into_iter().collect() }
}

/// Per vertex, the surface's tangent frame for tangent-space maps: columns (T, B, N) with N the
/// unit vertex normal, T the direction of increasing u (dP/du, averaged over the vertex's faces
/// by area) made orthogonal to N, B = N x T.
pub fn tangent_frames(pos: &[DVec3], uv: &[DVec2], faces: &[[u32; 3]], normals: &[DVec3]) -> Vec<glam::DMat3> {
    let mut du = vec![DVec3::ZERO; pos.len()];
    for f in faces {
        let [p0, p1, p2] = f.map(|i| pos[i as usize]);
        let [t0, t1, t2] = f.map(|i| uv[i as usize]);
        let (e1, e2, d1, d2) = (p1 - p0, p2 - p0, t1 - t0, t2 - t0);
        let det = d1.perp_dot(d2);
        if det.abs() < 1e-300 {
            continue;
        }
        // dP/du of the face's affine map, weighted by its UV area (|det| / 2).
        let dpdu = (e1 * d2.y - e2 * d1.y) / det;
        for &i in f {
            du[i as usize] += dpdu * det.abs();
        }
    }
    du.iter()
        .zip(normals)
        .map(|(&t, &n)| {
            let t = (t - n * t.dot(n)).normalize_or(n.any_orthonormal_vector());
            glam::DMat3::from_cols(t, n.cross(t), n)
        })
        .collect()
}

/// Blends two normal maps of the same size: the normalized (1 - w) a + w b per pixel.
pub fn blend(a: &RgbImage, b: &RgbImage, w: f64) -> RgbImage {
    assert_eq!(a.dimensions(), b.dimensions(), "blended maps must have the same size");
    RgbImage::from_fn(a.width(), a.height(), |x, y| {
        let n = decode(*a.get_pixel(x, y)) * (1.0 - w) + decode(*b.get_pixel(x, y)) * w;
        encode(n.normalize_or(DVec3::Z))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles covering the unit square.
    fn square() -> (Vec<DVec2>, Vec<[u32; 3]>) {
        let uv = vec![DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y];
        (uv, vec![[0, 1, 2], [0, 2, 3]])
    }

    #[test]
    fn flipped_and_overlapping_uv_triangles_are_named() {
        let (mut uv, mut f) = square();
        assert_eq!(uv_problems(&uv, &f, 32, DVec2::ZERO, DVec2::ONE), UvProblems::default());
        // A mirrored copy of the first triangle over the second: flipped, and overlapping it.
        uv.extend([DVec2::new(0.1, 0.2), DVec2::new(0.1, 0.9), DVec2::new(0.8, 0.9)]);
        f.push([4, 5, 6]);
        let p = uv_problems(&uv, &f, 32, DVec2::ZERO, DVec2::ONE);
        assert_eq!(p, UvProblems { flipped: vec![2], overlapping: vec![] }, "a flipped face is left out");
        // The same piece unflipped (a stacked UV shell) overlaps the second square triangle.
        f.push([4, 6, 5]);
        let p = uv_problems(&uv, &f, 32, DVec2::ZERO, DVec2::ONE);
        assert_eq!(p, UvProblems { flipped: vec![2], overlapping: vec![1, 3] });
    }

    #[test]
    fn a_tangent_frame_follows_u_on_the_surface() {
        // A square standing in the xz plane, u along x and v along z: T = x, N = -y, B = N x T.
        let pos = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 0.0, 1.0), DVec3::Z];
        let (uv, f) = square();
        let n = vec![DVec3::NEG_Y; 4];
        for m in tangent_frames(&pos, &uv, &f, &n) {
            assert!((m.x_axis - DVec3::X).length() < 1e-12 && (m.z_axis - DVec3::NEG_Y).length() < 1e-12);
            assert!((m.y_axis - DVec3::Z).length() < 1e-12, "{m:?}");
        }
    }

    #[test]
    fn a_flat_sheet_is_the_flat_normal_everywhere() {
        let (uv, f) = square();
        let img = normal_map(&uv, &f, &[DVec3::Z; 4], 16, DVec2::ZERO, DVec2::ONE);
        assert!(img.pixels().all(|p| *p == Rgb([128, 128, 255])));
    }

    #[test]
    fn normals_interpolate_across_the_map_and_blend() {
        let (uv, f) = square();
        let tilt = DVec3::new(0.6, 0.0, 0.8);
        let normals = [DVec3::Z, tilt, tilt, DVec3::Z];
        let img = normal_map(&uv, &f, &normals, 64, DVec2::ZERO, DVec2::ONE);
        // Left edge (x = 0) flat, right edge tilted: red rises from left to right.
        let left = decode(*img.get_pixel(0, 32));
        let right = decode(*img.get_pixel(63, 32));
        assert!(left.x < 0.02 && (right - tilt).length() < 0.03, "{left} {right}");
        let flat = normal_map(&uv, &f, &[DVec3::Z; 4], 64, DVec2::ZERO, DVec2::ONE);
        let close = |a: &RgbImage, b: &RgbImage| {
            a.pixels().zip(b.pixels()).all(|(p, q)| (0..3).all(|k| p[k].abs_diff(q[k]) <= 1))
        };
        assert!(close(&blend(&flat, &img, 0.0), &flat), "weight 0 is the first map");
        assert!(close(&blend(&flat, &img, 1.0), &img), "weight 1 is the second (to 8-bit round-off)");
        let half = decode(*blend(&flat, &img, 0.5).get_pixel(63, 32));
        assert!((half - (DVec3::Z + tilt).normalize()).length() < 0.02);
    }

    #[test]
    fn an_8_bit_round_trip_is_within_quantization() {
        let n = DVec3::new(0.3, -0.5, 0.8).normalize();
        assert!((decode(encode(n)) - n).length() < 0.01);
    }
}
