//! Triangles that pass through each other, by exact predicates (Shewchuk's orient3d from the
//! `robust` crate): an edge of one triangle properly crosses the other. Touching (a zero
//! orientation) is not crossing. Used by `check` on a start state with contact and by the
//! contact tests on every frame; it shares no code with the contact module.

use glam::DVec3;
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy};
use rayon::prelude::*;
use robust::{orient3d, Coord3D};

fn c(p: DVec3) -> Coord3D<f64> {
    Coord3D { x: p.x, y: p.y, z: p.z }
}

/// Whether segment p-q passes through the interior of triangle a-b-c: p and q strictly on
/// opposite sides of its plane, and the line strictly inside its three edges.
pub fn segment_crosses_triangle(p: DVec3, q: DVec3, a: DVec3, b: DVec3, t: DVec3) -> bool {
    let (sp, sq) = (orient3d(c(a), c(b), c(t), c(p)), orient3d(c(a), c(b), c(t), c(q)));
    if sp == 0.0 || sq == 0.0 || (sp > 0.0) == (sq > 0.0) {
        return false;
    }
    let e = [orient3d(c(p), c(q), c(a), c(b)), orient3d(c(p), c(q), c(b), c(t)), orient3d(c(p), c(q), c(t), c(a))];
    e.iter().all(|&s| s > 0.0) || e.iter().all(|&s| s < 0.0)
}

/// Whether two triangles cross: an edge of either passes through the other.
pub fn triangles_cross(s: [DVec3; 3], t: [DVec3; 3]) -> bool {
    let through =
        |u: [DVec3; 3], v: [DVec3; 3]| (0..3).any(|k| segment_crosses_triangle(u[k], u[(k + 1) % 3], v[0], v[1], v[2]));
    through(s, t) || through(t, s)
}

/// Every pair (i < j) of triangles that share no vertex and cross, ascending.
pub fn crossing_pairs(tris: &[[u32; 3]], x: &[DVec3]) -> Vec<(usize, usize)> {
    let at = |t: &[u32; 3]| t.map(|v| x[v as usize]);
    let boxes: Vec<Aabb> = tris
        .iter()
        .map(|t| {
            let p = at(t);
            let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
            Aabb::new(Vector::new(lo.x, lo.y, lo.z), Vector::new(hi.x, hi.y, hi.z))
        })
        .collect();
    let bvh = Bvh::from_leaves(BvhBuildStrategy::default(), &boxes);
    (0..tris.len())
        .into_par_iter()
        .flat_map_iter(|i| {
            let mut found: Vec<usize> = bvh
                .intersect_aabb(&boxes[i])
                .map(|j| j as usize)
                .filter(|&j| j > i && !tris[j].iter().any(|v| tris[i].contains(v)))
                .filter(|&j| triangles_cross(at(&tris[i]), at(&tris[j])))
                .collect();
            found.sort_unstable();
            found.into_iter().map(move |j| (i, j))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crossing_is_proper_passage_not_touching() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let through = [DVec3::new(0.2, 0.2, -1.0), DVec3::new(0.2, 0.2, 1.0), DVec3::new(2.0, 2.0, 0.5)];
        assert!(triangles_cross(t, through));
        let beside = through.map(|p| p + DVec3::new(3.0, 0.0, 0.0));
        assert!(!triangles_cross(t, beside));
        // Resting on the face (a vertex in the plane) is touching.
        let resting = [DVec3::new(0.2, 0.2, 0.0), DVec3::new(0.2, 0.2, 1.0), DVec3::new(0.5, 0.1, 1.0)];
        assert!(!triangles_cross(t, resting));
        let tris = [[0, 1, 2], [3, 4, 5], [0, 4, 5]];
        let x = [t[0], t[1], t[2], through[0], through[1], through[2]];
        assert_eq!(crossing_pairs(&tris, &x), vec![(0, 1)]);
    }
}
