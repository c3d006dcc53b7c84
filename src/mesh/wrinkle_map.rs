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
                    img.put_pixel(x, y, encode((n[0] * wa + n[1] * wb + n[2] * wc).normalize_or(DVec3::Z)));
                }
            }
        }
    }
    img
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
