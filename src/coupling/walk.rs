//! KCK18 section 2: anchors walk over a kinematic body surface by 2D ray tracing in each
//! triangle's canonical frame, and the "projection springs" baseline they are compared with.
//!
//! A surface point is a face and canonical coordinates (s, t): p = v0 + s (v1 - v0) + t (v2 - v0),
//! inside the canonical triangle s, t >= 0, s + t <= 1. Edge k of a face joins its vertices k and
//! k + 1: edge 0 is t = 0, edge 1 is s + t = 1, edge 2 is s = 0.

use glam::{DVec2, DVec3};

pub(crate) const NO_FACE: u32 = u32::MAX;

/// A point on a body surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    pub face: u32,
    pub st: DVec2,
}

/// Why a walk ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// The displacement ran out inside a face.
    Inside,
    /// The ray left the mesh across a boundary edge (KCK18: a1 = h).
    Boundary,
    /// The next face was already visited in this walk: a crease, the anchor rests on the edge.
    Crease,
}

/// The result of one walk.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Walk {
    pub end: SurfacePoint,
    /// Length of the path walked over the surface (an upper bound of the geodesic jump).
    pub length: f64,
    pub faces: u32,
    pub stop: Stop,
}

/// What building a body surface skipped (documented fallbacks, reported at load).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SurfaceIssues {
    /// Faces of (near) zero area: never entered, their neighbours see a boundary.
    pub degenerate: Vec<u32>,
    /// Edges shared by more than two faces: boundaries for the walk.
    pub non_manifold: Vec<[u32; 2]>,
}

/// A body's triangles with the face across each edge, for walking.
#[derive(Clone, Debug, Default)]
pub struct BodySurface {
    pub faces: Vec<[u32; 3]>,
    /// Face across edge k (vertices k, k + 1), or NO_FACE.
    pub neighbours: Vec<[u32; 3]>,
    /// Faces a walk may enter (not degenerate in the rest pose).
    pub usable: Vec<bool>,
}

impl BodySurface {
    /// Adjacency over the faces; degenerate faces (area below 1e-14 of the squared longest
    /// edge) and non-manifold edges become boundaries.
    pub fn new(faces: Vec<[u32; 3]>, rest: &[DVec3]) -> (BodySurface, SurfaceIssues) {
        let mut issues = SurfaceIssues::default();
        let usable: Vec<bool> = faces
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let p = f.map(|v| rest[v as usize]);
                let (a, b) = (p[1] - p[0], p[2] - p[0]);
                let longest = a.length_squared().max(b.length_squared()).max((p[2] - p[1]).length_squared());
                let ok = f[0] != f[1] && f[1] != f[2] && f[0] != f[2] && a.cross(b).length() > 1e-14 * longest;
                if !ok {
                    issues.degenerate.push(i as u32);
                }
                ok
            })
            .collect();
        let mut by_edge: std::collections::HashMap<(u32, u32), Vec<(u32, u8)>> = Default::default();
        for (i, f) in faces.iter().enumerate().filter(|(i, _)| usable[*i]) {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                by_edge.entry((a.min(b), a.max(b))).or_default().push((i as u32, k as u8));
            }
        }
        let mut neighbours = vec![[NO_FACE; 3]; faces.len()];
        let mut keys: Vec<_> = by_edge.keys().copied().collect();
        keys.sort_unstable();
        for key in keys {
            match by_edge[&key].as_slice() {
                [(f, k), (g, l)] => {
                    neighbours[*f as usize][*k as usize] = *g;
                    neighbours[*g as usize][*l as usize] = *f;
                }
                [_] => {}
                _ => issues.non_manifold.push([key.0, key.1]),
            }
        }
        (BodySurface { faces, neighbours, usable }, issues)
    }

    pub fn position(&self, x: &[DVec3], p: SurfacePoint) -> DVec3 {
        let f = self.faces[p.face as usize].map(|v| x[v as usize]);
        f[0] + p.st.x * (f[1] - f[0]) + p.st.y * (f[2] - f[0])
    }

    /// KCK18 section 2: walks `start` along the displacement `d` (world space, usually
    /// a* - a0) over the surface at positions `x`. `visited` is scratch space.
    pub fn walk(&self, x: &[DVec3], start: SurfacePoint, d: DVec3, visited: &mut Vec<u32>) -> Walk {
        visited.clear();
        let (mut face, mut st) = (start.face, clamp_canonical(start.st));
        let mut remaining = d;
        let mut length = 0.0;
        loop {
            visited.push(face);
            let frame = CanonicalFrame::new(self.faces[face as usize].map(|v| x[v as usize]));
            let dir = frame.to_canonical(remaining);
            let (tau, edge) = exit(st, dir);
            if tau >= 1.0 {
                length += frame.to_world(dir).length();
                let end = SurfacePoint { face, st: clamp_canonical(st + dir) };
                return Walk { end, length, faces: visited.len() as u32, stop: Stop::Inside };
            }
            let hit = clamp_canonical(st + tau * dir);
            length += frame.to_world(tau * dir).length();
            let here = SurfacePoint { face, st: hit };
            let next = self.neighbours[face as usize][edge];
            let stop = if next == NO_FACE {
                Some(Stop::Boundary)
            } else if visited.contains(&next) {
                Some(Stop::Crease)
            } else {
                None
            };
            if let Some(stop) = stop {
                return Walk { end: here, length, faces: visited.len() as u32, stop };
            }
            // The same world point in the neighbour's frame: the shared edge's parameter.
            let f = self.faces[face as usize];
            let (a, b) = (f[edge], f[(edge + 1) % 3]);
            let u = edge_parameter(hit, edge);
            st = on_edge(self.faces[next as usize], a, b, u);
            remaining *= 1.0 - tau;
            face = next;
        }
    }

    /// Faces around each vertex (for N-ring projection), usable faces only.
    pub fn vertex_faces(&self, vertices: usize) -> Vec<Vec<u32>> {
        let mut out = vec![Vec::new(); vertices];
        for (i, f) in self.faces.iter().enumerate().filter(|(i, _)| self.usable[*i]) {
            for &v in f {
                out[v as usize].push(i as u32);
            }
        }
        out
    }

    /// The projection-springs baseline restricted to an N-ring (KCK18 section 1): the closest
    /// point to `p` among the faces within `rings` vertex rings of `from`'s face.
    pub fn project_ring(
        &self,
        x: &[DVec3],
        vertex_faces: &[Vec<u32>],
        from: u32,
        p: DVec3,
        rings: u32,
    ) -> SurfacePoint {
        let mut ring = vec![from];
        for _ in 0..rings {
            let mut next: Vec<u32> = ring
                .iter()
                .flat_map(|&f| self.faces[f as usize])
                .flat_map(|v| vertex_faces[v as usize].iter().copied())
                .collect();
            next.sort_unstable();
            next.dedup();
            // (the rings only grow: once they stop, they cover the connected body, and a large
            // `rings` costs no more)
            let covered = next.len() == ring.len();
            ring = next;
            if covered {
                break;
            }
        }
        let mut best = (f64::INFINITY, SurfacePoint { face: from, st: DVec2::ZERO });
        for f in ring {
            let q = self.locate(x, f, p);
            let d = (self.position(x, q) - p).length_squared();
            if d < best.0 {
                best = (d, q);
            }
        }
        best.1
    }

    /// Canonical coordinates of the point of face `face` closest to `p` (clamped).
    pub fn locate(&self, x: &[DVec3], face: u32, p: DVec3) -> SurfacePoint {
        let tri = self.faces[face as usize].map(|v| x[v as usize]);
        let frame = CanonicalFrame::new(tri);
        SurfacePoint { face, st: closest_canonical(frame.to_canonical(p - tri[0]), &frame) }
    }
}

/// The projection-springs baseline over the whole body (KCK18 section 1): closest points by
/// parry's BVH over the body's current triangles.
pub struct Projector {
    mesh: Option<parry3d_f64::shape::TriMesh>,
    /// Parry's triangle index -> body face (degenerate faces are left out).
    faces: Vec<u32>,
}

impl Projector {
    pub fn new(surface: &BodySurface, x: &[DVec3]) -> Projector {
        use parry3d_f64::math::Vector;
        let faces: Vec<u32> = (0..surface.faces.len() as u32).filter(|&f| surface.usable[f as usize]).collect();
        let points = x.iter().map(|p| Vector::new(p.x, p.y, p.z)).collect();
        let indices = faces.iter().map(|&f| surface.faces[f as usize]).collect();
        let mesh = parry3d_f64::shape::TriMesh::new(points, indices).ok();
        Projector { mesh, faces }
    }

    /// The closest point of the body to `p`; None for a body with no usable face.
    pub fn project(&self, surface: &BodySurface, x: &[DVec3], p: DVec3) -> Option<SurfacePoint> {
        use parry3d_f64::query::PointQuery;
        let mesh = self.mesh.as_ref()?;
        let (proj, _) = mesh.project_local_point_and_get_feature(parry3d_f64::math::Vector::new(p.x, p.y, p.z));
        let face = *self.faces.get(proj.subshape as usize)?;
        Some(surface.locate(x, face, DVec3::new(proj.point.x, proj.point.y, proj.point.z)))
    }
}

/// KCK18 eq. 1: Dm = [v1 - v0, v2 - v0] = Q R; canonical coordinates R^-1 Q^T (p - v0).
struct CanonicalFrame {
    q: [DVec3; 2],
    r_inv: glam::DMat2,
    dm: [DVec3; 2],
}

impl CanonicalFrame {
    fn new(v: [DVec3; 3]) -> CanonicalFrame {
        let dm = [v[1] - v[0], v[2] - v[0]];
        // Gram-Schmidt QR of the 3x2 matrix Dm.
        let r00 = dm[0].length();
        let q0 = dm[0] / r00;
        let r01 = q0.dot(dm[1]);
        let w = dm[1] - r01 * q0;
        let r11 = w.length();
        let q1 = w / r11;
        let r = glam::DMat2::from_cols(DVec2::new(r00, 0.0), DVec2::new(r01, r11));
        CanonicalFrame { q: [q0, q1], r_inv: r.inverse(), dm }
    }

    fn to_canonical(&self, d: DVec3) -> DVec2 {
        self.r_inv * DVec2::new(self.q[0].dot(d), self.q[1].dot(d))
    }

    fn to_world(&self, c: DVec2) -> DVec3 {
        c.x * self.dm[0] + c.y * self.dm[1]
    }
}

/// The closest point of the canonical triangle to `c` in the face's metric (Dm^T Dm).
fn closest_canonical(c: DVec2, frame: &CanonicalFrame) -> DVec2 {
    if c.x >= 0.0 && c.y >= 0.0 && c.x + c.y <= 1.0 {
        return c;
    }
    let corners = [DVec2::ZERO, DVec2::X, DVec2::Y];
    let mut best = (f64::INFINITY, DVec2::ZERO);
    for k in 0..3 {
        let (a, b) = (corners[k], corners[(k + 1) % 3]);
        let (wa, wb, wc) = (frame.to_world(a), frame.to_world(b), frame.to_world(c));
        let t = ((wc - wa).dot(wb - wa) / (wb - wa).length_squared()).clamp(0.0, 1.0);
        let p = a + t * (b - a);
        let dist = (frame.to_world(p) - wc).length_squared();
        if dist < best.0 {
            best = (dist, p);
        }
    }
    best.1
}

/// KCK18: "a simple clamp suffices" to keep a point inside the canonical triangle.
pub(crate) fn clamp_canonical(c: DVec2) -> DVec2 {
    let c = c.max(DVec2::ZERO);
    let sum = c.x + c.y;
    if sum > 1.0 {
        c / sum
    } else {
        c
    }
}

/// The first edge the ray st + tau dir leaves the canonical triangle by: (tau, edge), tau > 1
/// (infinite) when it stays inside for tau in [0, 1].
fn exit(st: DVec2, dir: DVec2) -> (f64, usize) {
    let towards = dir.x + dir.y;
    let edges =
        [(dir.y < 0.0, -st.y / dir.y), (towards > 0.0, (1.0 - st.x - st.y) / towards), (dir.x < 0.0, -st.x / dir.x)];
    let mut best = (f64::INFINITY, 0);
    for (edge, (hits, tau)) in edges.into_iter().enumerate() {
        if hits && tau < best.0 {
            best = (tau.max(0.0), edge);
        }
    }
    best
}

/// Position along edge k of a canonical point on it, from vertex k (0) to vertex k + 1 (1).
fn edge_parameter(st: DVec2, edge: usize) -> f64 {
    match edge {
        0 => st.x,
        1 => st.y / (st.x + st.y).max(f64::MIN_POSITIVE),
        _ => 1.0 - st.y,
    }
    .clamp(0.0, 1.0)
}

/// Canonical coordinates in `face` of the point (1 - u) a + u b on its edge (a, b).
fn on_edge(face: [u32; 3], a: u32, b: u32, u: f64) -> DVec2 {
    let corner = |v: u32| match face.iter().position(|&w| w == v) {
        Some(1) => DVec2::X,
        Some(2) => DVec2::Y,
        _ => DVec2::ZERO,
    };
    clamp_canonical((1.0 - u) * corner(a) + u * corner(b))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles forming the unit square, and a third folded down along x = 1.
    fn strip() -> (BodySurface, Vec<DVec3>) {
        let x = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(1.0, 0.5, -1.0),
        ];
        let (s, issues) = BodySurface::new(vec![[0, 1, 2], [0, 2, 3], [1, 4, 2]], &x);
        assert_eq!(issues, SurfaceIssues::default());
        (s, x)
    }

    #[test]
    fn a_short_walk_stays_in_its_face() {
        let (s, x) = strip();
        let start = s.locate(&x, 0, DVec3::new(0.6, 0.2, 0.0));
        let w = s.walk(&x, start, DVec3::new(0.1, 0.05, 0.3), &mut vec![]);
        assert_eq!((w.stop, w.end.face, w.faces), (Stop::Inside, 0, 1));
        assert!((s.position(&x, w.end) - DVec3::new(0.7, 0.25, 0.0)).length() < 1e-15);
        // The out-of-plane part of d is dropped: the path is the tangential displacement.
        assert!((w.length - DVec3::new(0.1, 0.05, 0.0).length()).abs() < 1e-15);
    }

    #[test]
    fn a_walk_crosses_edges_with_the_remaining_displacement() {
        let (s, x) = strip();
        let start = s.locate(&x, 0, DVec3::new(0.8, 0.2, 0.0));
        let w = s.walk(&x, start, DVec3::new(-0.6, 0.6, 0.0), &mut vec![]);
        assert_eq!((w.stop, w.end.face, w.faces), (Stop::Inside, 1, 2));
        assert!((s.position(&x, w.end) - DVec3::new(0.2, 0.8, 0.0)).length() < 1e-14);
        assert!((w.length - (0.72f64).sqrt()).abs() < 1e-14);
    }

    #[test]
    fn a_walk_stops_at_the_boundary_and_goes_over_a_fold() {
        let (s, x) = strip();
        let start = s.locate(&x, 0, DVec3::new(0.5, 0.1, 0.0));
        let w = s.walk(&x, start, DVec3::new(0.0, -1.0, 0.0), &mut vec![]);
        assert_eq!(w.stop, Stop::Boundary);
        assert!((s.position(&x, w.end) - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-15);
        assert!((w.length - 0.1).abs() < 1e-15);
        // Into the folded face: the remaining displacement is projected onto its plane.
        let start = s.locate(&x, 0, DVec3::new(0.9, 0.5, 0.0));
        let w = s.walk(&x, start, DVec3::new(0.2, 0.0, -0.2), &mut vec![]);
        assert_eq!((w.stop, w.end.face), (Stop::Inside, 2));
        assert!(w.length <= DVec3::new(0.2, 0.0, -0.2).length());
    }

    #[test]
    fn a_crease_stops_the_walk_on_the_edge() {
        // A closed fold: face 1 lies on top of face 0 (a zero-width crease along x = 0).
        let x = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(1.0, 0.5, 0.0),
            DVec3::new(1.0, 0.5, 1e-9),
        ];
        let (s, _) = BodySurface::new(vec![[0, 1, 2], [1, 0, 3]], &x);
        let start = s.locate(&x, 0, DVec3::new(0.2, 0.5, 0.0));
        let mut visited = vec![];
        let w = s.walk(&x, start, DVec3::new(-1.0, 0.0, 0.0), &mut visited);
        // Into face 1, which folds back: the walk returns to face 0's edge and stops there.
        assert_eq!(w.stop, Stop::Crease);
        assert_eq!(visited, vec![0, 1]);
        assert!(s.position(&x, w.end).x.abs() < 1e-12, "on the crease edge: {:?}", s.position(&x, w.end));
        assert!(w.length <= 1.0 + 1e-12);
    }

    #[test]
    fn projection_picks_the_closest_face_anywhere_or_within_the_ring() {
        let (s, x) = strip();
        let p = DVec3::new(1.3, 0.5, -0.5);
        let global = Projector::new(&s, &x).project(&s, &x, p).unwrap();
        assert_eq!(global.face, 2);
        let vf = s.vertex_faces(x.len());
        // Face 2 shares vertices with face 0: within one ring, not within zero.
        assert_eq!(s.project_ring(&x, &vf, 0, p, 1), global);
        assert_eq!(s.project_ring(&x, &vf, 0, p, 0).face, 0);
        let q = s.position(&x, global);
        let brute = (0..3).map(|f| (s.position(&x, s.locate(&x, f, p)) - p).length()).fold(f64::INFINITY, f64::min);
        assert!(((q - p).length() - brute).abs() < 1e-12);
    }

    /// Random walks over a curved closed body: every walk ends inside a triangle, never visits
    /// a face twice, and walks no farther than the displacement it was given.
    #[test]
    fn random_walks_over_a_creature_are_bounded_and_visit_each_face_once() {
        use rand::{Rng, SeedableRng};
        let body = crate::mesh::bodies::creature(1.0, 3);
        let (s, _) = BodySurface::new(body.faces.clone(), &body.rest);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let mut visited = Vec::new();
        let mut crossings = 0;
        for _ in 0..2000 {
            let face = rng.random_range(0..s.faces.len() as u32);
            let st = clamp_canonical(DVec2::new(rng.random(), rng.random()));
            let d = DVec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            let w = s.walk(&body.rest, SurfacePoint { face, st }, 0.5 * d, &mut visited);
            let mut unique = visited.clone();
            unique.sort_unstable();
            unique.dedup();
            assert_eq!(unique.len(), visited.len(), "a face visited twice: {visited:?}");
            assert!(w.end.st.x >= 0.0 && w.end.st.y >= 0.0 && w.end.st.x + w.end.st.y <= 1.0 + 1e-15);
            assert!(w.length <= 0.5 * d.length() * (1.0 + 1e-12));
            crossings += w.faces - 1;
        }
        assert!(crossings > 5000, "the walks cross edges: {crossings}");
    }

    #[test]
    fn points_outside_are_clamped_into_the_triangle() {
        assert_eq!(clamp_canonical(DVec2::new(-0.5, 0.3)), DVec2::new(0.0, 0.3));
        assert_eq!(clamp_canonical(DVec2::new(1.0, 1.0)), DVec2::new(0.5, 0.5));
        let (s, x) = strip();
        let p = s.locate(&x, 0, DVec3::new(2.0, -1.0, 5.0));
        assert_eq!(s.position(&x, p), DVec3::new(1.0, 0.0, 0.0));
    }

    #[test]
    fn degenerate_faces_and_non_manifold_edges_become_boundaries() {
        let x = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.5, 1.0, 0.0),
            DVec3::new(0.5, -1.0, 0.0),
            DVec3::new(0.5, 0.0, 1.0),
            DVec3::new(2.0, 0.0, 0.0),
        ];
        // Faces 0, 1, 2 share edge (0, 1); face 3 is a sliver with zero area.
        let faces = vec![[0, 1, 2], [1, 0, 3], [0, 1, 4], [1, 5, 1]];
        let (s, issues) = BodySurface::new(faces, &x);
        assert_eq!(issues.degenerate, vec![3]);
        assert_eq!(issues.non_manifold, vec![[0, 1]]);
        let start = s.locate(&x, 0, DVec3::new(0.5, 0.3, 0.0));
        let w = s.walk(&x, start, DVec3::new(0.0, -1.0, 0.0), &mut vec![]);
        assert_eq!((w.stop, w.end.face), (Stop::Boundary, 0));
    }
}
