//! Point location in the plane (x, y): the face of a triangle mesh over a point, with the point's
//! barycentric weights on it (an attachment to a layer whose vertices a remesh has moved).

use glam::{DVec2, DVec3};

/// Faces of a mesh bucketed on a uniform (x, y) grid.
pub struct XyLocator<'a> {
    rest: &'a [DVec3],
    faces: &'a [[u32; 3]],
    origin: DVec2,
    cell: f64,
    dims: (usize, usize),
    buckets: Vec<Vec<u32>>,
}

impl<'a> XyLocator<'a> {
    pub fn new(rest: &'a [DVec3], faces: &'a [[u32; 3]]) -> Self {
        let xy = |v: u32| rest[v as usize].truncate();
        let (lo, hi) = faces
            .iter()
            .flatten()
            .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), &v| (lo.min(xy(v)), hi.max(xy(v))));
        let extent = (hi - lo).max(DVec2::splat(1e-300));
        // About one face per cell.
        let cell = (extent.x * extent.y / faces.len().max(1) as f64).sqrt().max(extent.max_element() / 4096.0);
        let dims = ((extent.x / cell).ceil().max(1.0) as usize, (extent.y / cell).ceil().max(1.0) as usize);
        let mut locator = XyLocator { rest, faces, origin: lo, cell, dims, buckets: vec![Vec::new(); dims.0 * dims.1] };
        for (i, f) in faces.iter().enumerate() {
            let (a, b) =
                f.iter().fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(a, b), &v| (a.min(xy(v)), b.max(xy(v))));
            let ((i0, j0), (i1, j1)) = (locator.cell_of(a), locator.cell_of(b));
            for j in j0..=j1 {
                for c in i0..=i1 {
                    locator.buckets[j * dims.0 + c].push(i as u32);
                }
            }
        }
        locator
    }

    fn cell_of(&self, p: DVec2) -> (usize, usize) {
        let c = ((p - self.origin) / self.cell).floor();
        ((c.x.max(0.0) as usize).min(self.dims.0 - 1), (c.y.max(0.0) as usize).min(self.dims.1 - 1))
    }

    /// The face over `p` in (x, y), the topmost (largest z at p) where several are (a slab's
    /// surface), and p's barycentric weights on it; a point over no face goes to the nearest
    /// point of the nearest face. None only for a mesh without faces.
    pub fn locate(&self, p: DVec3) -> Option<(usize, [f64; 3])> {
        let q = p.truncate();
        let (i, j) = self.cell_of(q);
        let tol = 1e-9;
        let mut best: Option<(usize, [f64; 3], f64)> = None;
        for &f in &self.buckets[j * self.dims.0 + i] {
            let w = self.weights(f as usize, q);
            if w.iter().all(|&x| x >= -tol) {
                let z: f64 = (0..3).map(|k| w[k] * self.rest[self.faces[f as usize][k] as usize].z).sum();
                if best.is_none_or(|b| z > b.2) {
                    best = Some((f as usize, w, z));
                }
            }
        }
        if let Some((f, w, _)) = best {
            return Some((f, w));
        }
        // Outside every face (a boundary's round-off, or a point beyond the mesh): the nearest.
        (0..self.faces.len())
            .map(|f| {
                let (w, d) = self.nearest(f, q);
                (f, w, d)
            })
            .min_by(|a, b| a.2.total_cmp(&b.2))
            .map(|(f, w, _)| (f, w))
    }

    fn corners(&self, f: usize) -> [DVec2; 3] {
        self.faces[f].map(|v| self.rest[v as usize].truncate())
    }

    fn weights(&self, f: usize, q: DVec2) -> [f64; 3] {
        let [a, b, c] = self.corners(f);
        let det = (b - a).perp_dot(c - a);
        if det.abs() < 1e-300 {
            return [f64::NEG_INFINITY; 3];
        }
        let wb = (q - a).perp_dot(c - a) / det;
        let wc = (b - a).perp_dot(q - a) / det;
        [1.0 - wb - wc, wb, wc]
    }

    /// The weights of the point of face `f` nearest to q, and its distance.
    fn nearest(&self, f: usize, q: DVec2) -> ([f64; 3], f64) {
        let w = self.weights(f, q);
        if w.iter().all(|&x| x >= 0.0) {
            return (w, 0.0);
        }
        let p = self.corners(f);
        let mut best = ([0.0; 3], f64::INFINITY);
        for k in 0..3 {
            let (a, b) = (p[k], p[(k + 1) % 3]);
            let t = ((q - a).dot(b - a) / (b - a).length_squared().max(1e-300)).clamp(0.0, 1.0);
            let d = (a + t * (b - a)).distance(q);
            if d < best.1 {
                let mut w = [0.0; 3];
                w[k] = 1.0 - t;
                w[(k + 1) % 3] = t;
                best = (w, d);
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_point_is_found_on_its_face_with_its_weights() {
        let g = crate::mesh::grid(glam::DVec2::new(2.0, 1.0), (8, 4), crate::mesh::GridPattern::Alternating, 0.0);
        let locator = XyLocator::new(&g.rest, &g.faces);
        for p in [DVec3::new(0.3, 0.7, 0.0), DVec3::new(1.99, 0.01, 0.0), DVec3::new(0.0, 0.0, 0.0)] {
            let (f, w) = locator.locate(p).unwrap();
            let back: DVec3 = (0..3).map(|k| w[k] * g.rest[g.faces[f][k] as usize]).sum();
            assert!(back.distance(p) < 1e-12, "{p} -> {back}");
            assert!(w.iter().all(|&x| x >= -1e-9));
        }
        // Beyond the mesh: the nearest point of its boundary.
        let (f, w) = locator.locate(DVec3::new(2.5, 0.5, 0.0)).unwrap();
        let back: DVec3 = (0..3).map(|k| w[k] * g.rest[g.faces[f][k] as usize]).sum();
        assert!(back.distance(DVec3::new(2.0, 0.5, 0.0)) < 1e-12, "{back}");
    }
}
