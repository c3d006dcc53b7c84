//! Unsigned distances between the primitives of a contact pair (IPC: Li et al. 2020, sec. 4):
//! a point and a triangle, or two edges. The squared distance is piecewise: by the pair's
//! closest features it is a point-point, point-line, point-plane or line-line distance. The
//! feature is chosen in f64 (`DistanceType::of`); the formula for that feature is then
//! evaluated in any number type (`squared`), so that second-order dual numbers give its exact
//! gradient and Hessian. The squared distance is C1 across the features' boundaries.

use num_dual::DualNum;

use crate::physics::dual::{cross3, dot3, sub3};

/// A pair's primitives: four points, `[p, t0, t1, t2]` (point-triangle) or `[a0, a1, b0, b1]`
/// (edge-edge).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
pub enum Primitives {
    PointTriangle,
    EdgeEdge,
}

/// Which features of the pair are closest; indices into its four points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DistanceType {
    /// Two points.
    PointPoint(usize, usize),
    /// Point, then the line through two points.
    PointEdge(usize, usize, usize),
    /// Point 0 and the plane of points 1, 2, 3.
    PointPlane,
    /// The lines through 0-1 and 2-3.
    LineLine,
}

fn length2(a: [f64; 3]) -> f64 {
    dot3(a, a)
}

/// The parameter of the closest point of the line a-b to p, and its squared distance, when the
/// closest point lies strictly inside the segment.
fn inside_segment(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> Option<f64> {
    let e = sub3(b, a);
    let l2 = length2(e);
    if l2 <= 0.0 {
        return None;
    }
    let t = dot3(sub3(p, a), e) / l2;
    (t > 0.0 && t < 1.0).then(|| length2(cross3(sub3(a, p), sub3(b, p))) / l2)
}

impl DistanceType {
    /// The closest features of the pair at positions `x`: the candidate with the least
    /// squared distance among the vertex pairs, the vertex-edge pairs whose foot lies inside
    /// the edge, and the face (point-triangle: the foot inside the triangle) or the two edges'
    /// interiors (edge-edge, not parallel).
    pub fn of(kind: Primitives, x: &[[f64; 3]; 4]) -> DistanceType {
        let mut best = (f64::INFINITY, DistanceType::PointPoint(0, 1));
        let mut offer = |d: f64, t: DistanceType| {
            if d < best.0 {
                best = (d, t);
            }
        };
        let pp = |i: usize, j: usize| length2(sub3(x[i], x[j]));
        match kind {
            Primitives::PointTriangle => {
                for j in 1..4 {
                    offer(pp(0, j), DistanceType::PointPoint(0, j));
                }
                for (a, b) in [(1, 2), (2, 3), (3, 1)] {
                    if let Some(d) = inside_segment(x[0], x[a], x[b]) {
                        offer(d, DistanceType::PointEdge(0, a, b));
                    }
                }
                if let Some(d) = inside_triangle(x) {
                    offer(d, DistanceType::PointPlane);
                }
            }
            Primitives::EdgeEdge => {
                for (i, j) in [(0, 2), (0, 3), (1, 2), (1, 3)] {
                    offer(pp(i, j), DistanceType::PointPoint(i, j));
                }
                for (p, a, b) in [(0, 2, 3), (1, 2, 3), (2, 0, 1), (3, 0, 1)] {
                    if let Some(d) = inside_segment(x[p], x[a], x[b]) {
                        offer(d, DistanceType::PointEdge(p, a, b));
                    }
                }
                if let Some(d) = inside_segments(x) {
                    offer(d, DistanceType::LineLine);
                }
            }
        }
        best.1
    }
}

/// The squared distance of point 0 to its foot on the plane of 1, 2, 3 when the foot lies
/// strictly inside the triangle (barycentric coordinates from the normal equations).
fn inside_triangle(x: &[[f64; 3]; 4]) -> Option<f64> {
    let (e1, e2, r) = (sub3(x[2], x[1]), sub3(x[3], x[1]), sub3(x[0], x[1]));
    let (a, b, c) = (dot3(e1, e1), dot3(e1, e2), dot3(e2, e2));
    let det = a * c - b * b;
    if det <= 1e-30 * a * c {
        return None;
    }
    let (d, e) = (dot3(r, e1), dot3(r, e2));
    let (u, v) = ((c * d - b * e) / det, (a * e - b * d) / det);
    if u <= 0.0 || v <= 0.0 || u + v >= 1.0 {
        return None;
    }
    // (the distance to the foot itself: a foot from an ill-conditioned solve is a point of the
    // triangle, never closer than the truth)
    let foot: [f64; 3] = std::array::from_fn(|k| x[1][k] + u * e1[k] + v * e2[k]);
    Some(length2(sub3(x[0], foot)))
}

/// The squared distance of the lines 0-1 and 2-3 at their closest points, when those lie
/// strictly inside both segments (None for parallel edges: the vertex-edge candidates cover them).
fn inside_segments(x: &[[f64; 3]; 4]) -> Option<f64> {
    let (ea, eb, r) = (sub3(x[1], x[0]), sub3(x[3], x[2]), sub3(x[0], x[2]));
    let (a, b, c) = (dot3(ea, ea), dot3(ea, eb), dot3(eb, eb));
    let det = a * c - b * b;
    // Within 1e-5 rad of parallel the line-line formula is ill-conditioned (two coplanar lines
    // are at distance 0 wherever they are), and the vertex-edge candidates are within
    // |e| 1e-5 of the truth: they decide.
    if det <= 1e-10 * a * c {
        return None;
    }
    let (d, e) = (dot3(ea, r), dot3(eb, r));
    let (s, t) = ((b * e - c * d) / det, (a * e - b * d) / det);
    if s <= 0.0 || s >= 1.0 || t <= 0.0 || t >= 1.0 {
        return None;
    }
    // The distance between the two points found, not the lines': for nearly parallel edges the
    // solve is ill-conditioned, and two coplanar lines are at distance 0 wherever s and t land.
    // Points of the segments are never closer than the truth, so a wrong s, t loses to the
    // vertex candidates.
    let (p, q): ([f64; 3], [f64; 3]) =
        (std::array::from_fn(|k| x[0][k] + s * ea[k]), std::array::from_fn(|k| x[2][k] + t * eb[k]));
    Some(length2(sub3(p, q)))
}

/// The squared distance by the formula of the features `t`, in any number type.
pub fn squared<D: DualNum<Primitive = f64> + Copy>(t: DistanceType, x: &[[D; 3]; 4]) -> D {
    match t {
        DistanceType::PointPoint(i, j) => {
            let d = sub3(x[i], x[j]);
            dot3(d, d)
        }
        DistanceType::PointEdge(p, a, b) => {
            let c = cross3(sub3(x[a], x[p]), sub3(x[b], x[p]));
            let e = sub3(x[b], x[a]);
            dot3(c, c) / dot3(e, e)
        }
        DistanceType::PointPlane => {
            let n = cross3(sub3(x[2], x[1]), sub3(x[3], x[1]));
            let h = dot3(sub3(x[0], x[1]), n);
            h * h / dot3(n, n)
        }
        DistanceType::LineLine => {
            let n = cross3(sub3(x[1], x[0]), sub3(x[3], x[2]));
            let h = dot3(sub3(x[0], x[2]), n);
            h * h / dot3(n, n)
        }
    }
}

/// The weights w of the pair's closest points: sum_i w_i x_i is the closest point of the first
/// primitive (the point; edge a) minus that of the second (the triangle; edge b). Friction's
/// slip and the viewer's segments read them.
pub fn closest_weights(kind: Primitives, x: &[[f64; 3]; 4]) -> [f64; 4] {
    let along = |p: [f64; 3], a: [f64; 3], b: [f64; 3]| {
        let e = sub3(b, a);
        (dot3(sub3(p, a), e) / length2(e).max(f64::MIN_POSITIVE)).clamp(0.0, 1.0)
    };
    // (+1 on the first primitive's points, -1 on the second's)
    let side = |i: usize| if i == 0 || (kind == Primitives::EdgeEdge && i == 1) { 1.0 } else { -1.0 };
    let mut w = [0.0; 4];
    match DistanceType::of(kind, x) {
        DistanceType::PointPoint(i, j) => (w[i], w[j]) = (side(i), side(j)),
        DistanceType::PointEdge(p, a, b) => {
            let t = along(x[p], x[a], x[b]);
            (w[p], w[a], w[b]) = (side(p), side(a) * (1.0 - t), side(b) * t);
        }
        DistanceType::PointPlane => {
            let (e1, e2, r) = (sub3(x[2], x[1]), sub3(x[3], x[1]), sub3(x[0], x[1]));
            let (a, b, c, d, e) = (dot3(e1, e1), dot3(e1, e2), dot3(e2, e2), dot3(r, e1), dot3(r, e2));
            let det = a * c - b * b;
            let (u, v) = ((c * d - b * e) / det, (a * e - b * d) / det);
            w = [1.0, -(1.0 - u - v), -u, -v];
        }
        DistanceType::LineLine => {
            let (ea, eb, r) = (sub3(x[1], x[0]), sub3(x[3], x[2]), sub3(x[0], x[2]));
            let (a, b, c, d, e) = (dot3(ea, ea), dot3(ea, eb), dot3(eb, eb), dot3(ea, r), dot3(eb, r));
            let det = a * c - b * b;
            let (s, t) = ((b * e - c * d) / det, (a * e - b * d) / det);
            w = [1.0 - s, s, -(1.0 - t), -t];
        }
    }
    w
}

/// The pair's closest points (one on each primitive), for drawing.
pub fn closest_points(kind: Primitives, x: &[[f64; 3]; 4]) -> ([f64; 3], [f64; 3]) {
    let w = closest_weights(kind, x);
    let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
    for (i, &wi) in w.iter().enumerate() {
        let (to, s) = if wi > 0.0 { (&mut a, wi) } else { (&mut b, -wi) };
        for k in 0..3 {
            to[k] += s * x[i][k];
        }
    }
    (a, b)
}

/// The pair's squared distance at f64 positions.
pub fn squared_distance(kind: Primitives, x: &[[f64; 3]; 4]) -> f64 {
    squared(DistanceType::of(kind, x), x)
}

/// The squared distance between the bounding boxes of the pair's two primitives: a lower bound
/// on `squared_distance` at a few comparisons' cost (most listed pairs are not near: their
/// boxes tell so without the features).
pub fn box_gap_squared(kind: Primitives, x: &[[f64; 3]; 4]) -> f64 {
    let (a, b) = match kind {
        Primitives::PointTriangle => (&x[..1], &x[1..]),
        Primitives::EdgeEdge => (&x[..2], &x[2..]),
    };
    let mut gap = 0.0;
    for k in 0..3 {
        let (alo, ahi) = a.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| (l.min(p[k]), h.max(p[k])));
        let (blo, bhi) = b.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| (l.min(p[k]), h.max(p[k])));
        let d = (blo - ahi).max(alo - bhi).max(0.0);
        gap += d * d;
    }
    gap
}
