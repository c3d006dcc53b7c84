//! Kernels measured on the surface (LK14 6.2; issue 24). Planar kernels measure supports and
//! Gaussian distances in material space, so where the material embedding (the UVs) stretches,
//! a kernel's support and its imposed wavelength stretch with it. Here a kernel's centre is
//! still a material point (the same point on both layers), but each layer's support, weights and
//! centring are measured on that layer's rest surface:
//! - distances: Dijkstra over the rest mesh's edges, started from the three corners of the face
//!   holding the centre at their straight distances (edge paths overestimate a geodesic by a few
//!   per cent on triangle meshes, far below the distortions this corrects);
//! - the adjustment (LK14 eq. 4.4-4.8) in the kernel's tangent chart: each support vertex's
//!   offset from the centre projected on the tangent plane of the face holding the centre, the
//!   chart's first axis along the material u direction (so that the charts of two layers agree).
//!   Centred there, the weights reproduce the centre exactly along the surface (a log map would
//!   differ by O(r^3 / R^2) for a support of radius r on a curvature radius R).

use std::collections::{BinaryHeap, HashMap};

use glam::{DVec2, DVec3};

use super::kernels::{Item, KernelShape, Sample};
use crate::mesh::locate::XyLocator;

/// One layer's rest surface, indexed for kernel sampling.
pub struct SurfaceSpace {
    rest: Vec<DVec3>,
    uv3: Vec<DVec3>,
    faces: Vec<[u32; 3]>,
    adjacency: Vec<Vec<(u32, f64)>>,
    area: Vec<f64>,
    boundary: Vec<bool>,
}

/// A kernel sampled on a surface: the weights, each support vertex's tangent-chart position,
/// and whether the layer's boundary cuts the support.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SurfaceSample {
    pub sample: Sample,
    pub chart: Vec<DVec2>,
    pub cut: bool,
}

impl SurfaceSpace {
    /// `rest` positions (m), material coordinates `uv` (m) and faces of one layer.
    pub fn new(rest: &[DVec3], uv: &[DVec2], faces: &[[u32; 3]]) -> Self {
        let n = rest.len();
        let mut adjacency: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
        for e in crate::mesh::edges(faces) {
            let [a, b] = e.v;
            let length = (rest[a as usize] - rest[b as usize]).length();
            adjacency[a as usize].push((b, length));
            adjacency[b as usize].push((a, length));
        }
        let mut area = vec![0.0; n];
        for f in faces {
            let [a, b, c] = f.map(|i| rest[i as usize]);
            let third = (b - a).cross(c - a).length() / 6.0;
            f.iter().for_each(|&i| area[i as usize] += third);
        }
        SurfaceSpace {
            rest: rest.to_vec(),
            uv3: uv.iter().map(|u| u.extend(0.0)).collect(),
            faces: faces.to_vec(),
            adjacency,
            area,
            boundary: crate::mesh::boundary_vertices(faces, n),
        }
    }

    /// The rest-surface point of material point `centre`: its face's corners, the point, and
    /// the tangent frame (first axis along the material u direction). None off the mesh or on a
    /// degenerate face.
    fn anchor(&self, locator: &XyLocator, centre: DVec2) -> Option<([u32; 3], DVec3, [DVec3; 2])> {
        let (f, w) = locator.locate(centre.extend(0.0))?;
        let v = self.faces[f];
        let p = (0..3).map(|k| self.rest[v[k] as usize] * w[k]).sum::<DVec3>();
        // dX/du from the face's map material -> rest: X = X0 + J (u - u0), J = [dX] [du]^-1.
        let (x0, x1, x2) = (self.rest[v[0] as usize], self.rest[v[1] as usize], self.rest[v[2] as usize]);
        let (u0, u1, u2) = (self.uv3[v[0] as usize], self.uv3[v[1] as usize], self.uv3[v[2] as usize]);
        let du = glam::DMat2::from_cols((u1 - u0).truncate(), (u2 - u0).truncate());
        if du.determinant().abs() < 1e-300 {
            return None;
        }
        let inv = du.inverse();
        let along_u = (x1 - x0) * inv.x_axis.x + (x2 - x0) * inv.x_axis.y;
        let normal = (x1 - x0).cross(x2 - x0).normalize_or_zero();
        let e1 = (along_u - normal * along_u.dot(normal)).normalize_or_zero();
        if e1 == DVec3::ZERO || normal == DVec3::ZERO {
            return None;
        }
        Some((v, p, [e1, normal.cross(e1)]))
    }

    /// LK14 eq. 4.3 on the surface: w_i = s a_i exp(-d_i^2 / (2 sigma^2)) for geodesic d_i <
    /// radius = 2 sigma, s making the weights sum to one; with the chart positions.
    pub fn sample(&self, locator: &XyLocator, centre: DVec2, radius: f64) -> SurfaceSample {
        let Some((corners, p, [e1, e2])) = self.anchor(locator, centre) else { return SurfaceSample::default() };
        let sources: Vec<(u32, f64)> = corners.iter().map(|&v| (v, (self.rest[v as usize] - p).length())).collect();
        let near = bounded_distances(&self.adjacency, &sources, radius);
        let sigma = 0.5 * radius;
        let mut out = SurfaceSample::default();
        for (v, d) in near {
            let w = self.area[v as usize] * (-d * d / (2.0 * sigma * sigma)).exp();
            if w <= 0.0 {
                continue;
            }
            let offset = self.rest[v as usize] - p;
            out.chart.push(DVec2::new(offset.dot(e1), offset.dot(e2)));
            out.sample.vertices.push(v);
            out.sample.weights.push(w);
            out.cut |= self.boundary[v as usize];
        }
        let total: f64 = out.sample.weights.iter().sum();
        if total > 0.0 {
            out.sample.weights.iter_mut().for_each(|w| *w /= total);
        }
        out
    }

    /// A locator of material points on this layer's faces.
    pub fn locator(&self) -> XyLocator<'_> {
        XyLocator::new(&self.uv3, &self.faces)
    }

    /// Kernels clustered by distances on this surface (LK14 4.1 with a surface metric), one per
    /// centre vertex: centre = its material point, radius = lambda / 2, and for a support cut
    /// by the boundary a target offset (target - centre) equal to the chart centroid of the cut
    /// Gaussian, which the adjustment then reproduces on every layer.
    pub(crate) fn build_kernels(&self, uv: &[DVec2], wavelength: &[f64], seed: u64) -> Vec<KernelShape> {
        let edges: Vec<[u32; 2]> = crate::mesh::edges(&self.faces).iter().map(|e| e.v).collect();
        let locator = self.locator();
        super::kernels::cluster_by_length(&edges, wavelength, seed, |a, b| (self.rest[a] - self.rest[b]).length())
            .into_iter()
            .map(|c| {
                let centre = uv[c as usize];
                let radius = 0.5 * wavelength[c as usize];
                let s = self.sample(&locator, centre, radius);
                let offset = if s.cut { chart_centroid(&s) } else { DVec2::ZERO };
                KernelShape { centre, radius, target: centre + offset }
            })
            .collect()
    }
}

/// The weighted centroid of a sample's chart positions.
pub(crate) fn chart_centroid(s: &SurfaceSample) -> DVec2 {
    let sum: f64 = s.sample.weights.iter().sum();
    s.chart.iter().zip(&s.sample.weights).map(|(c, &w)| *c * w).sum::<DVec2>() / sum
}

/// Shortest edge-path distances below `limit` from several sources with start distances, in
/// increasing vertex order.
pub(crate) fn bounded_distances(adjacency: &[Vec<(u32, f64)>], sources: &[(u32, f64)], limit: f64) -> Vec<(u32, f64)> {
    let mut best: HashMap<u32, f64> = HashMap::new();
    let mut heap = BinaryHeap::new();
    for &(v, d) in sources {
        if d < limit && best.get(&v).is_none_or(|&b| d < b) {
            best.insert(v, d);
            heap.push(Item(d, v));
        }
    }
    while let Some(Item(d, v)) = heap.pop() {
        if d > best[&v] {
            continue;
        }
        for &(w, cost) in &adjacency[v as usize] {
            let nd = d + cost;
            if nd < limit && best.get(&w).is_none_or(|&b| nd < b) {
                best.insert(w, nd);
                heap.push(Item(nd, w));
            }
        }
    }
    let mut out: Vec<(u32, f64)> = best.into_iter().collect();
    out.sort_unstable_by_key(|x| x.0);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coupling::kernels::{adjust, Adjusted};

    /// A cylinder of radius `r` along x (length `len`), its material coordinates the unrolled
    /// surface (x, r theta) distorted by `stretch` along v.
    fn cylinder(r: f64, len: f64, cells: (u32, u32), stretch: f64) -> (Vec<DVec3>, Vec<DVec2>, Vec<[u32; 3]>) {
        let arc = std::f64::consts::PI * r; // half a cylinder
        let m = crate::mesh::grid(DVec2::new(len, arc), cells, crate::mesh::GridPattern::Equilateral, 0.0);
        let rest = m.uv.iter().map(|u| DVec3::new(u.x, r * (u.y / r).sin(), r * (u.y / r).cos())).collect();
        let uv = m.uv.iter().map(|u| DVec2::new(u.x, u.y * stretch)).collect();
        (rest, uv, m.faces)
    }

    /// On a cylinder whose UVs are stretched 2:1, a surface kernel's support is the same
    /// geodesic disc as with undistorted UVs (the planar support would be an ellipse half as
    /// wide across), its weights sum to one and, adjusted in the chart, centre on the kernel.
    #[test]
    fn supports_are_geodesic_discs_whatever_the_uvs() {
        let (rest, uv, faces) = cylinder(0.2, 0.4, (60, 90), 1.0);
        let (_, uv2, _) = cylinder(0.2, 0.4, (60, 90), 2.0);
        let plain = SurfaceSpace::new(&rest, &uv, &faces);
        let stretched = SurfaceSpace::new(&rest, &uv2, &faces);
        let centre = DVec2::new(0.2, 0.3);
        let radius = 0.05;
        let a = plain.sample(&plain.locator(), centre, radius);
        let b = stretched.sample(&stretched.locator(), DVec2::new(centre.x, 2.0 * centre.y), radius);
        assert!(!a.cut && !b.cut);
        assert_eq!(a.sample.vertices, b.sample.vertices, "the same support");
        for (x, y) in a.sample.weights.iter().zip(&b.sample.weights) {
            assert!((x - y).abs() < 1e-12);
        }
        // The support is a disc of geodesic radius 0.05 (straight distance at most that; edge
        // paths overestimate a geodesic, so the disc's rim is a few per cent inside).
        let c3 = DVec3::new(0.2, 0.2 * (0.3f64 / 0.2).sin(), 0.2 * (0.3f64 / 0.2).cos());
        let farthest = a.sample.vertices.iter().map(|&v| (rest[v as usize] - c3).length()).fold(0.0, f64::max);
        assert!(farthest < radius && farthest > 0.9 * radius, "{farthest}");
        for s in [a, b] {
            // The adjustment reads chart positions by the sample's (local) indices.
            let n = s.sample.vertices.len() as u32;
            let mut sample = Sample { vertices: (0..n).collect(), weights: s.sample.weights.clone() };
            assert!((sample.weights.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            assert_eq!(adjust(&s.chart, &mut sample, DVec2::ZERO), Adjusted::Centred);
            // The adjusted weights reproduce the centre along the surface: exactly in the plane of
            // the face holding it; here measured against the smooth cylinder's tangent plane,
            // which the face's tilts from by about an edge over the radius.
            let point: DVec3 = s.sample.vertices.iter().zip(&sample.weights).map(|(&v, &w)| rest[v as usize] * w).sum();
            let tangential = {
                let d = point - c3;
                let n = c3 - DVec3::new(c3.x, 0.0, 0.0);
                d - n.normalize() * d.dot(n.normalize())
            };
            assert!(tangential.length() < 1e-3 * radius, "{}", tangential.length());
        }
    }

    #[test]
    fn bounded_distances_stop_at_the_limit() {
        // A path 0 - 1 - 2 - 3 of unit edges.
        let adjacency = vec![vec![(1, 1.0)], vec![(0, 1.0), (2, 1.0)], vec![(1, 1.0), (3, 1.0)], vec![(2, 1.0)]];
        assert_eq!(bounded_distances(&adjacency, &[(0, 0.5)], 2.0), vec![(0, 0.5), (1, 1.5)]);
        assert_eq!(
            bounded_distances(&adjacency, &[(0, 0.2), (3, 0.1)], 1.5),
            vec![(0, 0.2), (1, 1.2), (2, 1.1), (3, 0.1)]
        );
    }
}
