//! The broad phase: pairs within a reach of each other, from parry's BVH over the triangles and
//! over the edges (boxes grown by the reach), then each pair's distance. At one state (the
//! pairs that may be active) or over a step from one state to another (the pairs CCD must
//! bound).

use glam::DVec3;
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy, BvhWorkspace};
use rayon::prelude::*;

use super::distance::Primitives;
use super::pair::Pair;
use super::surface::Surface;

/// The box of `vertices` at `x` (and at `x1`, over a step), grown by `r`.
fn aabb(vertices: &[u32], x: &[DVec3], x1: Option<&[DVec3]>, r: f64) -> Aabb {
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for &v in vertices {
        for p in std::iter::once(x[v as usize]).chain(x1.map(|y| y[v as usize])) {
            (lo, hi) = (lo.min(p), hi.max(p));
        }
    }
    let (lo, hi) = (lo - DVec3::splat(r), hi + DVec3::splat(r));
    Aabb::new(Vector::new(lo.x, lo.y, lo.z), Vector::new(hi.x, hi.y, hi.z))
}

/// For each point the triangles whose boxes at `x`, grown by `r`, hold it, and for each edge
/// the later edges whose boxes, each grown by r / 2, overlap its own: ascending, no rules
/// applied (`Surface`'s neighbours at rest).
pub(super) fn overlaps(s: &Surface, x: &[DVec3], r: f64) -> (Vec<Vec<u32>>, Vec<Vec<u32>>) {
    let tri_boxes: Vec<Aabb> = s.triangles.par_iter().map(|t| aabb(t, x, None, r)).collect();
    let tris = Bvh::from_leaves(BvhBuildStrategy::default(), &tri_boxes);
    let points = s
        .points
        .par_iter()
        .map(|&p| {
            let query = aabb(&[p], x, None, 0.0);
            let mut found: Vec<u32> = tris.intersect_aabb(&query).collect();
            found.sort_unstable();
            found
        })
        .collect();
    let edge_boxes: Vec<Aabb> = s.edges.par_iter().map(|e| aabb(e, x, None, 0.5 * r)).collect();
    let edges = Bvh::from_leaves(BvhBuildStrategy::default(), &edge_boxes);
    let later = (0..s.edges.len())
        .into_par_iter()
        .map(|i| {
            let mut found: Vec<u32> = edges.intersect_aabb(&edge_boxes[i]).filter(|&j| j as usize > i).collect();
            found.sort_unstable();
            found
        })
        .collect();
    (points, later)
}

/// Every admitted pair (`Surface::admits`) that comes within its offset plus `beyond` at `x`,
/// or anywhere on the straight step from `x` to `x1` (`near`). The trees' boxes are grown by
/// the largest offset plus `beyond`; each pair found is then held to its own reach.
/// Point-triangle pairs first, then edge-edge, each kind in the order of its vertices
/// (`Pair::v`).
///
/// Why a traversal of two trees at once (the points' against the triangles', the edges'
/// against themselves) and not one query per point and per edge, and why only the pairs kept
/// are sorted: on the full-size creature with contact (`scenes/kck18/creature_contact.ron`,
/// 20,480 triangles) the boxes let 1.4 million pairs through at each broad phase, nearly all
/// of them neighbours at rest; sorting them took 13 % of the run, and a broad phase took
/// 96 ms with a query each against 78 ms so. (The traversal the fifth session measured and
/// rejected on the fist, 56.0 s against 46.7 s, ran on one thread; here the two traversals and
/// the tests of what they find run side by side.)
pub fn candidates(s: &Surface, x: &[DVec3], x1: Option<&[DVec3]>, beyond: f64) -> Vec<Pair> {
    if s.is_empty() {
        return Vec::new();
    }
    let r = s.max_offset() + beyond;
    let near = |p: &Pair| near(p, x, x1, beyond);
    let tri_boxes: Vec<Aabb> = s.triangles.par_iter().map(|t| aabb(t, x, x1, r)).collect();
    let point_boxes: Vec<Aabb> = s.points.par_iter().map(|&p| aabb(&[p], x, x1, 0.0)).collect();
    let (tris, points) = rayon::join(
        || Bvh::from_leaves(BvhBuildStrategy::default(), &tri_boxes),
        || Bvh::from_leaves(BvhBuildStrategy::default(), &point_boxes),
    );
    // (each edge box grown by r / 2: two boxes within r of each other overlap)
    let edge_boxes: Vec<Aabb> = s.edges.par_iter().map(|e| aabb(e, x, x1, 0.5 * r)).collect();
    let (by_point, by_edge) = rayon::join(
        || points.leaf_pairs(&tris, |a, b| a.intersects(b)).collect::<Vec<(u32, u32)>>(),
        || {
            let edges = Bvh::from_leaves(BvhBuildStrategy::default(), &edge_boxes);
            let mut found = Vec::new();
            let mut workspace = BvhWorkspace::default();
            edges.traverse_bvtt_single_tree::<false>(&mut workspace, &mut |a, b| found.push((a.min(b), a.max(b))));
            found
        },
    );
    // (the traversals' order is their trees', fixed by the boxes: the pairs found are sorted,
    // not the many more that the boxes let through)
    let mut pairs: Vec<Pair> =
        by_point.par_iter().filter_map(|&(p, t)| s.point_triangle(p as usize, t as usize)).filter(near).collect();
    pairs.par_sort_unstable_by_key(|p| p.v);
    let mut edge_pairs: Vec<Pair> = by_edge
        .par_iter()
        .filter(|(i, j)| i != j)
        .filter_map(|&(i, j)| s.edge_edge(i as usize, j as usize))
        .filter(near)
        .collect();
    edge_pairs.par_sort_unstable_by_key(|p| p.v);
    edge_pairs.dedup_by_key(|p| p.v);
    pairs.append(&mut edge_pairs);
    pairs
}

/// The pairs of `pairs` (a wider list, in its order) that come within their offset plus
/// `beyond` at `x` or on the step to `x1` (`near`).
pub fn filtered(pairs: &[Pair], x: &[DVec3], x1: Option<&[DVec3]>, beyond: f64) -> Vec<Pair> {
    pairs.par_iter().filter(|p| near(p, x, x1, beyond)).copied().collect()
}

/// Whether the pair may come within its offset plus `beyond` (its reach) at `x` or on the
/// straight step to `x1`: its boxes, swept over the step, come within the reach of each other,
/// and its distance at `x`, less the most the step can shrink it (`ccd::relative_motion`), is
/// below the reach. A pair left out stays beyond its reach all along the step. (On a sheet,
/// most pairs whose boxes overlap are a triangle's width apart, farther than the reach.)
pub fn near(p: &Pair, x: &[DVec3], x1: Option<&[DVec3]>, beyond: f64) -> bool {
    use parry3d_f64::bounding_volume::BoundingVolume;
    let reach = p.barrier.offset + beyond;
    let boxes = match p.kind {
        Primitives::PointTriangle => aabb(&p.v[..1], x, x1, 0.0).intersects(&aabb(&p.v[1..], x, x1, reach)),
        Primitives::EdgeEdge => aabb(&p.v[..2], x, x1, 0.5 * reach).intersects(&aabb(&p.v[2..], x, x1, 0.5 * reach)),
    };
    if !boxes {
        return false;
    }
    let y = super::gather(x, &p.v);
    let shrink = x1.map_or(0.0, |x1| {
        let d = std::array::from_fn(|i| (x1[p.v[i] as usize] - x[p.v[i] as usize]).to_array());
        super::ccd::relative_motion(p.kind, &d).1
    });
    let r = reach + shrink;
    super::distance::box_gap_squared(p.kind, &y) < r * r && p.squared_distance(&y) < r * r
}
