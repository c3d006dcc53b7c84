//! A patch's contact surface: the triangles, edges and points of its shell layers that may
//! touch, in packed vertex numbers, with what the pair rules need (layers, rest positions).

use std::collections::BTreeSet;

use glam::DVec3;

use super::barrier::{mollifier_threshold, Barrier};
use super::distance::{squared_distance, Primitives};
use super::pair::Pair;

/// The least cosine between a close pair's separation and its triangle's normal for the two
/// parts to face each other (`Surface::close_vertices`): 45 degrees.
const FACING: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// One layer's part of a surface.
#[derive(Clone, Debug, Default)]
pub struct SurfaceLayer {
    pub triangles: Vec<[u32; 3]>,
    /// Its share of a pair's offset: half the skin's thickness, 0 for a body.
    pub half_thickness: f64,
    /// Whether it is solved for (a kinematic body is not: two of them never form a pair).
    pub moving: bool,
}

/// The primitives of one patch that contact acts between.
#[derive(Clone, Debug, Default)]
pub struct Surface {
    pub triangles: Vec<[u32; 3]>,
    /// Every edge of the triangles once, `[lo, hi]`.
    pub edges: Vec<[u32; 2]>,
    /// Every vertex of the triangles once, ascending.
    pub points: Vec<u32>,
    /// The layer of each triangle, edge and point (the first triangle's that holds it).
    tri_layer: Vec<u32>,
    edge_layer: Vec<u32>,
    point_layer: Vec<u32>,
    /// Rest positions by packed vertex (the rule "near at rest is not contact").
    rest: Vec<DVec3>,
    /// Layer pairs (a < b) bound to each other (LK14 kernels), each once: they do not touch.
    bound: BTreeSet<(u32, u32)>,
    /// Each layer's half thickness and whether it moves.
    half: Vec<f64>,
    moving: Vec<bool>,
    /// The barrier's reach d_hat beyond a pair's offset (m).
    pub reach: f64,
    /// The median length of the edges at rest (m; 0 without edges).
    pub median_edge: f64,
    /// Neighbours at rest (`neighbours`), found once: for each point the triangles, for each
    /// edge the later edges, ascending.
    point_near: Vec<Vec<u32>>,
    edge_near: Vec<Vec<u32>>,
}

impl Surface {
    /// From each layer's triangles (packed numbers) and the packed rest positions; `reach`:
    /// the barrier's d_hat; `bound`: pairs of layers (indices into `layers`) that kernels bind,
    /// which do not touch (one per kernel will do).
    pub fn new(layers: &[SurfaceLayer], rest: Vec<DVec3>, reach: f64, bound: &[(u32, u32)]) -> Surface {
        let half = layers.iter().map(|l| l.half_thickness).collect();
        let moving = layers.iter().map(|l| l.moving).collect();
        let bound = bound.iter().map(|&(a, b)| (a.min(b), a.max(b))).collect();
        let mut s = Surface { rest, reach, bound, half, moving, ..Default::default() };
        let mut edges = std::collections::BTreeMap::new();
        let mut points = std::collections::BTreeMap::new();
        for (l, layer) in layers.iter().enumerate() {
            for t in &layer.triangles {
                s.triangles.push(*t);
                s.tri_layer.push(l as u32);
                for k in 0..3 {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    edges.entry([a.min(b), a.max(b)]).or_insert(l as u32);
                    points.entry(t[k]).or_insert(l as u32);
                }
            }
        }
        (s.edges, s.edge_layer) = edges.into_iter().unzip();
        (s.points, s.point_layer) = points.into_iter().unzip();
        let mut lengths: Vec<f64> =
            s.edges.iter().map(|e| (s.rest[e[0] as usize] - s.rest[e[1] as usize]).length()).collect();
        lengths.sort_by(f64::total_cmp);
        s.median_edge = lengths.get(lengths.len() / 2).copied().unwrap_or(0.0);
        s.find_neighbours();
        s
    }

    /// On one layer, primitives within twice the barrier's reach (offset plus d_hat) of each
    /// other at rest, so that compressing the skin in its plane to half does not bring them into
    /// it: neighbours on one surface, never a pair. (Two layers near each other at rest, a skin
    /// on a body, do touch.)
    fn near(&self, layer: u32) -> f64 {
        2.0 * (self.barrier(layer, layer).offset + self.reach)
    }

    fn find_neighbours(&mut self) {
        use rayon::prelude::*;
        let r = self.half.iter().map(|&h| 2.0 * (2.0 * h + self.reach)).fold(0.0f64, f64::max);
        let (by_point, by_edge) = super::broad::overlaps(self, &self.rest, r);
        let s = &*self;
        let rest4 = |v: &[u32; 4]| v.map(|i| s.rest[i as usize].to_array());
        let point_near = by_point
            .into_par_iter()
            .enumerate()
            .map(|(p, found)| {
                let (l, near) = (s.point_layer[p], s.near(s.point_layer[p]));
                found
                    .into_iter()
                    .filter(|&t| {
                        let tri = s.triangles[t as usize];
                        let v = [s.points[p], tri[0], tri[1], tri[2]];
                        s.tri_layer[t as usize] == l
                            && !tri.contains(&s.points[p])
                            && squared_distance(Primitives::PointTriangle, &rest4(&v)) < near * near
                    })
                    .collect()
            })
            .collect();
        let edge_near = by_edge
            .into_par_iter()
            .enumerate()
            .map(|(i, found)| {
                let (l, near, a) = (s.edge_layer[i], s.near(s.edge_layer[i]), s.edges[i]);
                found
                    .into_iter()
                    .filter(|&j| {
                        let b = s.edges[j as usize];
                        let v = [a[0], a[1], b[0], b[1]];
                        s.edge_layer[j as usize] == l
                            && !(a.contains(&b[0]) || a.contains(&b[1]))
                            && squared_distance(Primitives::EdgeEdge, &rest4(&v)) < near * near
                    })
                    .collect()
            })
            .collect();
        (self.point_near, self.edge_near) = (point_near, edge_near);
    }

    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Whether two primitives of layers a and b, with vertices `v` (the pair's four), may form
    /// a pair: they share no vertex, their layers are not bound, at least one moves, and they
    /// are not `neighbours` at rest (`near`).
    /// (`neighbours` is asked last: most pairs whose boxes meet share a vertex or are neighbours,
    /// and on the full-size creature the pairs the boxes let through number millions a frame)
    fn admits(&self, kind: Primitives, v: &[u32; 4], a: u32, b: u32, neighbours: impl FnOnce() -> bool) -> bool {
        let shared = match kind {
            Primitives::PointTriangle => v[1..].contains(&v[0]),
            Primitives::EdgeEdge => v[0] == v[2] || v[0] == v[3] || v[1] == v[2] || v[1] == v[3],
        };
        !shared
            && (self.moving[a as usize] || self.moving[b as usize])
            && (self.bound.is_empty() || !self.bound.contains(&(a.min(b), a.max(b))))
            && !neighbours()
    }

    /// The barrier between primitives of layers a and b: offset by both half thicknesses.
    pub fn barrier(&self, a: u32, b: u32) -> Barrier {
        Barrier { offset: self.half[a as usize] + self.half[b as usize], reach: self.reach }
    }

    /// The largest pair offset (the broad phase's reach).
    pub fn max_offset(&self) -> f64 {
        let max = self.half.iter().fold(0.0f64, |m, &h| m.max(h));
        2.0 * max
    }

    /// The point-triangle pair of point `p` (index into `points`) and triangle `t`, if admitted.
    pub(super) fn point_triangle(&self, p: usize, t: usize) -> Option<Pair> {
        let tri = self.triangles[t];
        let v = [self.points[p], tri[0], tri[1], tri[2]];
        let kind = Primitives::PointTriangle;
        let (a, b) = (self.point_layer[p], self.tri_layer[t]);
        let neighbours = || self.point_near[p].binary_search(&(t as u32)).is_ok();
        self.admits(kind, &v, a, b, neighbours).then(|| Pair { v, kind, barrier: self.barrier(a, b), eps: 0.0 })
    }

    /// The edge-edge pair of edges i and j, if admitted.
    pub(super) fn edge_edge(&self, i: usize, j: usize) -> Option<Pair> {
        let (a, b) = (self.edges[i], self.edges[j]);
        let v = [a[0], a[1], b[0], b[1]];
        let kind = Primitives::EdgeEdge;
        let length = |e: [u32; 2]| (self.rest[e[0] as usize] - self.rest[e[1] as usize]).length();
        let (la, lb) = (self.edge_layer[i], self.edge_layer[j]);
        let neighbours = || self.edge_near[i.min(j)].binary_search(&(i.max(j) as u32)).is_ok();
        self.admits(kind, &v, la, lb, neighbours).then(|| Pair {
            v,
            kind,
            barrier: self.barrier(la, lb),
            eps: mollifier_threshold(length(a), length(b)),
        })
    }

    /// The rest positions of every packed vertex.
    pub fn rest_positions(&self) -> Vec<DVec3> {
        self.rest.clone()
    }

    /// The vertices of admitted point-triangle pairs closer than `distance` at `x` whose point
    /// lies over or under its triangle (the two parts face each other), and of triangles that
    /// cross each other there (`mesh::crossing`).
    ///
    /// Why facing: a surface compressed along itself (the inside of a bent elbow under linear
    /// blend skinning) brings vertices that were far apart to within `distance` beside each
    /// other, with no fold. Counted, they released 104 of the elbow's 180 kernels at frame 3,
    /// whose skin then stayed within 12 um of its body points while the free skin crawled
    /// (600 iterations, unconverged).
    pub fn close_vertices(&self, x: &[DVec3], distance: f64) -> BTreeSet<u32> {
        let facing = |p: &Pair| {
            let [q, a, b, c] = p.v.map(|i| x[i as usize]);
            let n = (b - a).cross(c - a).normalize_or_zero();
            let d2 = p.squared_distance(&super::gather(x, &p.v));
            let over = n.dot(q - a);
            d2 < distance * distance && over * over >= FACING * FACING * d2
        };
        let mut out: BTreeSet<u32> = super::broad::candidates(self, x, None, distance)
            .into_iter()
            .filter(|p| p.kind == Primitives::PointTriangle && facing(p))
            .flat_map(|p| p.v)
            .collect();
        for (a, b) in crate::mesh::crossing::crossing_pairs(&self.triangles, x) {
            out.extend(self.triangles[a].iter().chain(&self.triangles[b]));
        }
        out
    }

    /// The packed vertices of the surface (a set, for tests and reports).
    pub fn vertex_set(&self) -> BTreeSet<u32> {
        self.points.iter().copied().collect()
    }
}
