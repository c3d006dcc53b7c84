//! Texture maps a shader samples in an asset's UV layout (issue 65): a pixel grid with square
//! texels over a UV rectangle, per-pixel values drawn from triangles (barycentric), the drawn
//! region padded across its UV borders (so that filtering and mip-maps near a border never
//! fetch the background), per-vertex weights that fade a patch into its body's unwrinkled
//! surface at its edges, and 16-bit encodings of normals and heights.

use glam::{DVec2, DVec3};
use image::{ImageBuffer, Luma, Rgb};

use super::locate::XyLocator;
use super::shading::vertex_normals;
use super::wrinkle_map::tangent_frames;

/// The pixels of a map over the UV rectangle [lo, hi]: row 0 at max v, texels square in UV.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapGrid {
    pub width: u32,
    pub height: u32,
    pub lo: DVec2,
    pub hi: DVec2,
}

impl MapGrid {
    /// `size` pixels along the rectangle's longer side, the other in proportion (at least 1), the
    /// rectangle grown on that side to a whole number of texels: texels are square in UV.
    pub fn square_texels(lo: DVec2, hi: DVec2, size: u32) -> MapGrid {
        let span = (hi - lo).max(DVec2::splat(f64::MIN_POSITIVE));
        let texel = span.max_element() / size as f64;
        let (width, height) = ((span.x / texel).ceil().max(1.0) as u32, (span.y / texel).ceil().max(1.0) as u32);
        let hi = DVec2::new(lo.x + width as f64 * texel, lo.y + height as f64 * texel);
        MapGrid { width, height, lo, hi }
    }

    /// The UV rectangle a map of these UVs covers: the unit square when they lie in it (an
    /// atlas: the map then lines up with the asset's other textures), else their bounds.
    pub fn rectangle_of(uv: &[DVec2]) -> (DVec2, DVec2) {
        let (lo, hi) = super::bounds(uv);
        if lo.min_element() >= 0.0 && hi.max_element() <= 1.0 {
            (DVec2::ZERO, DVec2::ONE)
        } else {
            (lo, hi)
        }
    }

    /// A UV position in pixel units (pixel (i, j) has its centre at (i + 0.5, j + 0.5)).
    pub fn to_pixel(&self, p: DVec2) -> DVec2 {
        let span = (self.hi - self.lo).max(DVec2::splat(f64::MIN_POSITIVE));
        DVec2::new((p.x - self.lo.x) / span.x * self.width as f64, (self.hi.y - p.y) / span.y * self.height as f64)
    }

    /// The UV position of pixel (x, y)'s centre.
    pub fn uv_of(&self, x: u32, y: u32) -> DVec2 {
        let span = self.hi - self.lo;
        DVec2::new(
            self.lo.x + (x as f64 + 0.5) / self.width as f64 * span.x,
            self.hi.y - (y as f64 + 0.5) / self.height as f64 * span.y,
        )
    }
}

/// N values per pixel, and which pixels hold drawn (or padded) values.
#[derive(Clone, Debug)]
pub struct MapBuffer<const N: usize> {
    pub grid: MapGrid,
    pub values: Vec<[f64; N]>,
    pub covered: Vec<bool>,
    fill: [f64; N],
}

impl<const N: usize> MapBuffer<N> {
    /// Every pixel `fill`, none covered.
    pub fn new(grid: MapGrid, fill: [f64; N]) -> Self {
        let n = (grid.width * grid.height) as usize;
        MapBuffer { grid, values: vec![fill; n], covered: vec![false; n], fill }
    }

    pub fn at(&self, x: u32, y: u32) -> [f64; N] {
        self.values[(y * self.grid.width + x) as usize]
    }

    /// Draws the triangles `faces` at `uv` with `values` per vertex, interpolated
    /// barycentrically at every pixel centre they cover (the last drawn wins).
    pub fn draw(&mut self, uv: &[DVec2], faces: &[[u32; 3]], values: &[[f64; N]]) {
        let g = self.grid;
        for f in faces {
            let [a, b, c] = f.map(|i| g.to_pixel(uv[i as usize]));
            let area = (b - a).perp_dot(c - a);
            if area.abs() < 1e-300 {
                continue;
            }
            let (min, max) = (a.min(b).min(c), a.max(b).max(c));
            let x0 = (min.x - 0.5).ceil().max(0.0);
            let x1 = (max.x - 0.5).floor().min(g.width as f64 - 1.0);
            let y0 = (min.y - 0.5).ceil().max(0.0);
            let y1 = (max.y - 0.5).floor().min(g.height as f64 - 1.0);
            if x1 < x0 || y1 < y0 {
                continue;
            }
            let v = f.map(|i| values[i as usize]);
            for y in y0 as u32..=y1 as u32 {
                for x in x0 as u32..=x1 as u32 {
                    let p = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                    let (wa, wb) = ((b - p).perp_dot(c - p) / area, (c - p).perp_dot(a - p) / area);
                    let wc = 1.0 - wa - wb;
                    if wa >= -1e-9 && wb >= -1e-9 && wc >= -1e-9 {
                        let i = (y * g.width + x) as usize;
                        self.values[i] = std::array::from_fn(|k| v[0][k] * wa + v[1][k] * wb + v[2][k] * wc);
                        self.covered[i] = true;
                    }
                }
            }
        }
    }

    /// Pads the covered region by `pixels` rings: each pass gives every uncovered pixel next to
    /// covered ones (8-neighbourhood) the mean of their values.
    pub fn dilate(&mut self, pixels: u32) {
        let (w, h) = (self.grid.width as i64, self.grid.height as i64);
        for _ in 0..pixels {
            let mut grown = Vec::new();
            for y in 0..h {
                for x in 0..w {
                    if self.covered[(y * w + x) as usize] {
                        continue;
                    }
                    let (mut sum, mut n) = ([0.0; N], 0);
                    for (dx, dy) in [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)] {
                        let (i, j) = (x + dx, y + dy);
                        if i < 0 || j < 0 || i >= w || j >= h || !self.covered[(j * w + i) as usize] {
                            continue;
                        }
                        let v = self.values[(j * w + i) as usize];
                        (0..N).for_each(|k| sum[k] += v[k]);
                        n += 1;
                    }
                    if n > 0 {
                        grown.push(((y * w + x) as usize, sum.map(|s| s / n as f64)));
                    }
                }
            }
            if grown.is_empty() {
                break;
            }
            for (i, v) in grown {
                self.values[i] = v;
                self.covered[i] = true;
            }
        }
    }

    /// The uncovered pixels back to the fill value.
    pub fn clear_uncovered(&mut self) {
        let fill = self.fill;
        self.values.iter_mut().zip(&self.covered).filter(|(_, c)| !**c).for_each(|(v, _)| *v = fill);
    }
}

/// A surface at the current frame and at rest: positions, rest positions, triangles.
#[derive(Clone, Copy)]
pub struct Surface<'a> {
    pub pos: &'a [DVec3],
    pub rest: &'a [DVec3],
    pub faces: &'a [[u32; 3]],
}

impl<'a> Surface<'a> {
    pub fn of(pos: &'a [DVec3], rest: &'a [DVec3], faces: &'a [[u32; 3]]) -> Self {
        Surface { pos, rest, faces }
    }
}

/// Where each point of a patch lies on its body, by UV: the body's vertex of the same UV (a
/// skin cut from the body), else the body's face over it in UV (a refined skin); and the
/// body's tangent frames (T along +u, N its normal) and normals at rest there.
pub struct BodyField<'a> {
    body: Surface<'a>,
    frames: Vec<glam::DMat3>,
    rest_normals: Vec<DVec3>,
    at_uv: std::collections::HashMap<[u64; 2], usize>,
    face_of: Vec<u32>,
    uv3: Vec<DVec3>,
}

impl<'a> BodyField<'a> {
    /// `uv`: the body's UVs, per vertex.
    pub fn new(body: Surface<'a>, uv: &[DVec2]) -> Self {
        let normals = vertex_normals(body.pos, body.faces);
        let frames = tangent_frames(body.pos, uv, body.faces, &normals);
        let rest_normals = vertex_normals(body.rest, body.faces);
        let at_uv = uv.iter().enumerate().map(|(i, u)| (u.to_array().map(f64::to_bits), i)).collect();
        let mut face_of = vec![u32::MAX; uv.len()];
        for (f, t) in body.faces.iter().enumerate() {
            t.iter().for_each(|&v| face_of[v as usize] = f as u32);
        }
        let uv3 = uv.iter().map(|u| u.extend(0.0)).collect();
        BodyField { body, frames, rest_normals, at_uv, face_of, uv3 }
    }

    /// For each vertex of `skin` (UVs `uv`, in the body's layout): its normal in the body's
    /// tangent frame there (the world normal where it lies on no body face) and its height over
    /// the body along the body's normal, less that height at rest (the wrinkle's displacement).
    pub fn tangent_normals_and_heights(&self, skin: Surface, uv: &[DVec2]) -> (Vec<DVec3>, Vec<f64>) {
        let locator = XyLocator::new(&self.uv3, self.body.faces);
        let normals = vertex_normals(skin.pos, skin.faces);
        let b = self.body;
        let mut tangent = Vec::with_capacity(uv.len());
        let mut height = Vec::with_capacity(uv.len());
        for (i, u) in uv.iter().enumerate() {
            let under = match self.at_uv.get(&u.to_array().map(f64::to_bits)) {
                Some(&v) if self.face_of[v] != u32::MAX => {
                    let f = self.face_of[v] as usize;
                    let w: [f64; 3] = std::array::from_fn(|k| (b.faces[f][k] as usize == v) as u8 as f64);
                    Some((f, w))
                }
                _ => locator.locate(u.extend(0.0)),
            };
            let Some((f, w)) = under else {
                tangent.push(normals[i]);
                height.push(0.0);
                continue;
            };
            let mix = |v: &dyn Fn(usize) -> DVec3| (0..3).map(|k| w[k] * v(b.faces[f][k] as usize)).sum::<DVec3>();
            let n = mix(&|v| self.frames[v].z_axis).normalize_or(DVec3::Z);
            let t = mix(&|v| self.frames[v].x_axis);
            let t = (t - n * t.dot(n)).normalize_or(n.any_orthonormal_vector());
            let frame = glam::DMat3::from_cols(t, n.cross(t), n);
            tangent.push(frame.transpose() * normals[i]);
            let n0 = mix(&|v| self.rest_normals[v]).normalize_or(DVec3::Z);
            let (x, x0) = (mix(&|v| b.pos[v]), mix(&|v| b.rest[v]));
            height.push((skin.pos[i] - x).dot(n) - (skin.rest[i] - x0).dot(n0));
        }
        (tangent, height)
    }
}

/// Per-vertex weights in [0, 1] that fade a patch into its body at its edges: `fade` of each
/// vertex's `boundary_distances`.
pub fn edge_weights(rest: &[DVec3], faces: &[[u32; 3]], width: f64) -> Vec<f64> {
    boundary_distances(rest, faces).into_iter().map(|d| fade(d, width)).collect()
}

/// 0 on a patch's edge, rising smoothly (smoothstep) to 1 at `width` (m) from it; `width` <= 0:
/// 1 everywhere. Applied per pixel to the interpolated distance (`boundary_distances`), the
/// fade is as fine as the map, not as coarse as the mesh.
pub fn fade(distance: f64, width: f64) -> f64 {
    if width <= 0.0 {
        return 1.0;
    }
    let t = (distance / width).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Each vertex's distance (rest positions, m) to the mesh's boundary (its edges with one face);
/// infinite for a closed mesh and for vertices no face uses.
pub fn boundary_distances(rest: &[DVec3], faces: &[[u32; 3]]) -> Vec<f64> {
    let mut count = std::collections::HashMap::new();
    for f in faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_insert(0u32) += 1;
        }
    }
    let mut boundary: Vec<(u32, u32)> = count.into_iter().filter(|(_, n)| *n == 1).map(|(e, _)| e).collect();
    boundary.sort_unstable();
    let mut used = vec![false; rest.len()];
    faces.iter().flatten().for_each(|&v| used[v as usize] = true);
    rest.iter()
        .zip(&used)
        .map(|(p, &u)| {
            if !u {
                return f64::INFINITY;
            }
            boundary
                .iter()
                .map(|&(a, b)| segment_distance(*p, rest[a as usize], rest[b as usize]))
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}

fn segment_distance(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let t = if ab.length_squared() > 0.0 { ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0) } else { 0.0 };
    (p - (a + t * ab)).length()
}

/// A unit normal as 16-bit RGB: each component mapped from [-1, 1] to [0, 65535].
pub fn encode16(n: DVec3) -> Rgb<u16> {
    let c = |v: f64| (65535.0 * (0.5 + 0.5 * v.clamp(-1.0, 1.0))).round() as u16;
    Rgb([c(n.x), c(n.y), c(n.z)])
}

/// The unit normal a 16-bit colour stands for.
pub fn decode16(c: Rgb<u16>) -> DVec3 {
    DVec3::from_array(c.0.map(|v| v as f64 / 65535.0 * 2.0 - 1.0)).normalize_or(DVec3::Z)
}

/// A height (m) as a 16-bit grey level: 32768 at 0, 0 and 65535 at -range and +range.
pub fn encode_height(h: f64, range: f64) -> Luma<u16> {
    let s = if range > 0.0 && h.is_finite() { (h / range).clamp(-1.0, 1.0) } else { 0.0 };
    Luma([(32767.5 + 32767.5 * s).round() as u16])
}

/// The height (m) a grey level stands for.
pub fn decode_height(l: Luma<u16>, range: f64) -> f64 {
    (l.0[0] as f64 - 32767.5) / 32767.5 * range
}

/// A buffer of unit normals as a 16-bit RGB image.
pub fn normal_image16(b: &MapBuffer<3>) -> ImageBuffer<Rgb<u16>, Vec<u16>> {
    ImageBuffer::from_fn(b.grid.width, b.grid.height, |x, y| {
        encode16(DVec3::from_array(b.at(x, y)).normalize_or(DVec3::Z))
    })
}

/// A buffer of heights as a 16-bit grey image over [-range, range].
pub fn height_image16(b: &MapBuffer<1>, range: f64) -> ImageBuffer<Luma<u16>, Vec<u16>> {
    ImageBuffer::from_fn(b.grid.width, b.grid.height, |x, y| encode_height(b.at(x, y)[0], range))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texels_are_square_and_an_atlas_maps_the_unit_square() {
        let g = MapGrid::square_texels(DVec2::new(-0.09, 0.0), DVec2::new(0.075, 0.194), 512);
        assert_eq!(g.height, 512);
        let texel = ((g.hi.x - g.lo.x) / g.width as f64, (g.hi.y - g.lo.y) / g.height as f64);
        assert!((texel.0 - texel.1).abs() < 1e-15, "{texel:?}");
        assert!(g.hi.x >= 0.075 && g.width == (0.165f64 / 0.194 * 512.0).ceil() as u32, "{g:?}");
        let atlas = [DVec2::new(0.2, 0.3), DVec2::new(0.4, 0.9)];
        assert_eq!(MapGrid::rectangle_of(&atlas), (DVec2::ZERO, DVec2::ONE));
        let p = g.uv_of(3, 7);
        assert!((g.to_pixel(p) - DVec2::new(3.5, 7.5)).length() < 1e-9);
    }

    #[test]
    fn padding_leaves_no_background_pixel_within_its_width_of_the_drawn_region() {
        let g = MapGrid::square_texels(DVec2::ZERO, DVec2::ONE, 64);
        let mut b = MapBuffer::new(g, [0.0]);
        let uv = [DVec2::new(0.3, 0.3), DVec2::new(0.7, 0.3), DVec2::new(0.5, 0.7)];
        b.draw(&uv, &[[0, 1, 2]], &[[1.0], [1.0], [1.0]]);
        let drawn = b.covered.clone();
        b.dilate(4);
        let near = |x: i64, y: i64, r: i64| {
            (-r..=r).any(|dy| {
                (-r..=r).any(|dx| {
                    let (i, j) = (x + dx, y + dy);
                    (0..64).contains(&i) && (0..64).contains(&j) && drawn[(j * 64 + i) as usize]
                })
            })
        };
        for y in 0..64i64 {
            for x in 0..64i64 {
                let i = (y * 64 + x) as usize;
                if near(x, y, 4) {
                    let padded = b.covered[i] && (b.values[i][0] - 1.0).abs() < 1e-12;
                    assert!(padded, "({x}, {y}) within 4 px is padded: {:?}", (b.covered[i], b.values[i]));
                } else {
                    assert!(!b.covered[i] && b.values[i][0] == 0.0, "({x}, {y}) beyond 4 px is background");
                }
            }
        }
    }

    #[test]
    fn edge_weights_vanish_on_the_boundary_and_reach_one_inside() {
        // A 1 x 1 grid of 10 x 10 cells: boundary at the square's sides.
        let m = crate::mesh::grid(DVec2::ONE, (10, 10), crate::mesh::GridPattern::RightTriangle, 0.0);
        let w = edge_weights(&m.rest, &m.faces, 0.25);
        for (p, w) in m.rest.iter().zip(&w) {
            let d = p.x.min(p.y).min(1.0 - p.x).min(1.0 - p.y);
            let t = (d / 0.25f64).min(1.0);
            assert!((w - t * t * (3.0 - 2.0 * t)).abs() < 1e-12, "{p} {w}");
        }
        assert!(edge_weights(&m.rest, &m.faces, 0.0).iter().all(|w| *w == 1.0));
    }

    /// A known height field, 1 + sin(2 pi x / 0.25) / 2, on a square patch over [0.25, 0.75]^2
    /// of a 128-pixel map (20 x 20 cells, 3.2 pixels each): blended over 0.1 from the patch's
    /// edge it meets the background (0) with no step larger than the field's own steps between
    /// neighbouring pixels inside (measured 0.036 against 0.167); unblended it steps by at least
    /// 0.5 there.
    #[test]
    fn a_blended_edge_is_continuous_and_an_unblended_one_steps() {
        let m = crate::mesh::grid(DVec2::splat(0.5), (20, 20), crate::mesh::GridPattern::RightTriangle, 0.0);
        let rest: Vec<DVec3> = m.rest.iter().map(|p| *p + DVec3::new(0.25, 0.25, 0.0)).collect();
        let uv: Vec<DVec2> = rest.iter().map(|p| p.truncate()).collect();
        let h: Vec<f64> = rest.iter().map(|p| 1.0 + 0.5 * (std::f64::consts::TAU * p.x / 0.25).sin()).collect();
        let grid = MapGrid::square_texels(DVec2::ZERO, DVec2::ONE, 128);
        let steps = |width: f64| {
            let w = edge_weights(&rest, &m.faces, width);
            let values: Vec<[f64; 1]> = h.iter().zip(&w).map(|(h, w)| [h * w]).collect();
            let mut b = MapBuffer::new(grid, [0.0]);
            b.draw(&uv, &m.faces, &values);
            let (mut border, mut inside) = (0.0f64, 0.0f64);
            for y in 0..128 {
                for x in 0..127 {
                    for (p, q) in [((x, y), (x + 1, y)), ((y, x), (y, x + 1))] {
                        let (i, j) = ((p.1 * 128 + p.0) as usize, (q.1 * 128 + q.0) as usize);
                        let step = (b.values[i][0] - b.values[j][0]).abs();
                        if b.covered[i] != b.covered[j] {
                            border = border.max(step);
                        } else {
                            inside = inside.max(step);
                        }
                    }
                }
            }
            (border, inside)
        };
        let (border, inside) = steps(0.1);
        assert!(border < 0.05 && border < inside, "blended: a step of {border} at the edge, {inside} inside");
        let (border, _) = steps(0.0);
        assert!(border >= 0.5, "unblended: {border}");
    }

    #[test]
    fn sixteen_bit_encodings_round_trip() {
        let n = DVec3::new(0.3, -0.5, 0.8).normalize();
        assert!((decode16(encode16(n)) - n).length() < 1e-4);
        assert_eq!(encode_height(0.0, 1e-3).0[0], 32768);
        for h in [-1e-3, -2.5e-4, 0.0, 7e-4, 1e-3] {
            assert!((decode_height(encode_height(h, 1e-3), 1e-3) - h).abs() < 2e-8, "{h}");
        }
        assert_eq!(encode_height(5.0, 1e-3).0[0], 65535);
    }
}
