//! Geometric selections on a mesh's rest positions: vertices on the sides of the bounding box or
//! in a box, vertices that coincide up to one axis (plane strain) or across a periodic seam, the
//! hinges across such a seam, and vertices of two layers at the same (x, y) (attachment).
//! Matching is to 1e-9 of the bounding-box diagonal.

use std::collections::HashMap;

use glam::DVec3;

use super::{bounds, edges, SurfaceMesh};

/// Which vertices of a mesh.
#[derive(Clone, Debug, PartialEq)]
pub enum Region {
    All,
    /// On any of these sides of the bounding box: (axis, the max side?).
    Sides(Vec<(usize, bool)>),
    /// Inside this box (m).
    Box {
        min: DVec3,
        max: DVec3,
    },
}

/// The indices of the vertices in `region`.
pub fn select(rest: &[DVec3], region: &Region) -> Vec<u32> {
    let (lo, hi) = bounds(rest);
    let tol = 1e-9 * (hi - lo).length();
    rest.iter()
        .enumerate()
        .filter(|(_, p)| match region {
            Region::All => true,
            Region::Sides(sides) => {
                sides.iter().any(|&(k, max)| if max { p[k] >= hi[k] - tol } else { p[k] <= lo[k] + tol })
            }
            Region::Box { min, max } => p.cmpge(*min - tol).all() && p.cmple(*max + tol).all(),
        })
        .map(|(i, _)| i as u32)
        .collect()
}

/// The faces `keep` selects, over the vertices they use (in their old order): a region of a
/// surface as a mesh of its own.
pub(crate) fn faces_within(m: &SurfaceMesh, keep: &[bool]) -> SurfaceMesh {
    let faces: Vec<[u32; 3]> = m.faces.iter().zip(keep).filter(|(_, k)| **k).map(|(f, _)| *f).collect();
    let mut new_index = vec![u32::MAX; m.rest.len()];
    faces.iter().flatten().for_each(|&v| new_index[v as usize] = 0);
    let mut out = SurfaceMesh::default();
    for (i, slot) in new_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = out.rest.len() as u32;
            out.rest.push(m.rest[i]);
            out.uv.push(m.uv[i]);
        }
    }
    out.faces = faces.iter().map(|f| f.map(|v| new_index[v as usize])).collect();
    out
}

/// Vertices that differ only along `axis` form a group; each is tied to the group's first.
pub(crate) fn plane_strain_ties(rest: &[DVec3], axis: usize) -> Vec<(u32, u32)> {
    let tol = 1e-9 * super::bounds::diagonal(rest).max(1e-300);
    let (a, b) = match axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let key = |p: &DVec3| ((p[a] / tol).round() as i64, (p[b] / tol).round() as i64);
    let mut first: HashMap<(i64, i64), u32> = HashMap::new();
    let mut ties = Vec::new();
    for (i, p) in rest.iter().enumerate() {
        match first.get(&key(p)) {
            Some(&m) => ties.push((i as u32, m)),
            None => {
                first.insert(key(p), i as u32);
            }
        }
    }
    ties
}

/// Pairs each vertex on the max side along `axis` with the min-side vertex at the same other
/// coordinates.
pub(crate) fn periodic_ties(rest: &[DVec3], axis: usize) -> Vec<(u32, u32)> {
    let (lo, hi) = bounds(rest);
    let tol = 1e-9 * (hi - lo).length().max(1e-300);
    let key = |p: &DVec3| {
        let mut q = *p;
        q[axis] = 0.0;
        ((q.x / tol).round() as i64, (q.y / tol).round() as i64, (q.z / tol).round() as i64)
    };
    let min_side: HashMap<_, u32> =
        rest.iter().enumerate().filter(|(_, p)| p[axis] <= lo[axis] + tol).map(|(i, p)| (key(p), i as u32)).collect();
    rest.iter()
        .enumerate()
        .filter(|(_, p)| p[axis] >= hi[axis] - tol)
        .filter_map(|(i, p)| min_side.get(&key(p)).map(|&m| (i as u32, m)))
        .collect()
}

/// A hinge across a periodic seam: `v` in hinge order (edge on the max side, its face's
/// opposite vertex, the min-side face's opposite vertex), and the (max, min) pair of vertices
/// whose difference is the period.
#[derive(Clone, Copy, Debug)]
pub struct SeamHinge {
    pub v: [u32; 4],
    pub image: (u32, u32),
}

/// Hinges joining a shell's boundary edges on the max side to the matching ones on the min side.
pub(crate) fn periodic_seams(m: &SurfaceMesh, axis: usize) -> Vec<SeamHinge> {
    let (lo, hi) = bounds(&m.rest);
    let tol = 1e-9 * (hi - lo).length().max(1e-300);
    let key = |v: u32| {
        let mut q = m.rest[v as usize];
        q[axis] = 0.0;
        ((q.x / tol).round() as i64, (q.y / tol).round() as i64, (q.z / tol).round() as i64)
    };
    let on = |v: u32, side: f64| (m.rest[v as usize][axis] - side).abs() <= tol;
    let boundary: Vec<_> = edges(&m.faces).into_iter().filter(|e| !e.is_interior()).collect();
    let min_side: HashMap<_, (u32, u32, u32)> = boundary
        .iter()
        .filter(|e| on(e.v[0], lo[axis]) && on(e.v[1], lo[axis]))
        .map(|e| ((key(e.v[0]), key(e.v[1])), (e.v[0], e.v[1], e.opposite[0])))
        .collect();
    let mut out = Vec::new();
    for e in boundary.iter().filter(|e| on(e.v[0], hi[axis]) && on(e.v[1], hi[axis])) {
        let (a, b) = (e.v[0], e.v[1]);
        // The matching min-side edge runs the other way in its face.
        let found = min_side
            .get(&(key(b), key(a)))
            .map(|&(_, a0, o)| (a0, o))
            .or_else(|| min_side.get(&(key(a), key(b))).map(|&(a0, _, o)| (a0, o)));
        if let Some((a0, o2)) = found {
            out.push(SeamHinge { v: [a, b, e.opposite[0], o2], image: (a, a0) });
        }
    }
    out
}

/// For every point of `from`, the topmost point of `to` at the same (x, y) (several points of a
/// slab share one), matched to 1e-9 of `from`'s bounding-box diagonal.
pub(crate) fn match_xy(from: &[DVec3], to: &[DVec3]) -> Vec<Option<u32>> {
    let tol = 1e-9 * super::bounds::diagonal(from).max(1e-300);
    let key = |p: DVec3| ((p.x / tol).round() as i64, (p.y / tol).round() as i64);
    let mut lookup: HashMap<(i64, i64), u32> = HashMap::new();
    for (i, p) in to.iter().enumerate() {
        let e = lookup.entry(key(*p)).or_insert(i as u32);
        if to[*e as usize].z < p.z {
            *e = i as u32;
        }
    }
    from.iter().map(|p| lookup.get(&key(*p)).copied()).collect()
}

/// The bottom (lowest z) faces of a tetrahedral mesh, and which vertices lie on the bottom.
pub(crate) fn bottom_faces(rest: &[DVec3], tets: &[[u32; 4]]) -> (Vec<[u32; 3]>, Vec<bool>) {
    let zmin = rest.iter().fold(f64::INFINITY, |z, p| z.min(p.z));
    let tol = 1e-9 * super::bounds::diagonal(rest).max(1e-300);
    let bottom: Vec<bool> = rest.iter().map(|p| p.z <= zmin + tol).collect();
    let faces = super::surface_of_tets(tets).into_iter().filter(|f| f.iter().all(|&v| bottom[v as usize])).collect();
    (faces, bottom)
}

/// A third of the area of each face around every vertex (m^2).
pub fn vertex_areas(rest: &[DVec3], faces: &[[u32; 3]]) -> Vec<f64> {
    let mut area = vec![0.0; rest.len()];
    for f in faces {
        let p = |i: usize| rest[f[i] as usize];
        let ar = 0.5 * (p(1) - p(0)).cross(p(2) - p(0)).length();
        for &v in f {
            area[v as usize] += ar / 3.0;
        }
    }
    area
}

impl SurfaceMesh {
    /// Mean edge length in material space.
    pub(crate) fn mean_material_edge(&self) -> f64 {
        let total: f64 = self
            .faces
            .iter()
            .map(|f| (0..3).map(|k| (self.uv[f[k] as usize] - self.uv[f[(k + 1) % 3] as usize]).length()).sum::<f64>())
            .sum();
        total / (3 * self.faces.len()).max(1) as f64
    }
}
