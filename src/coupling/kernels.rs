//! LK14 constraint kernels as pure math: the critical wavelength (eq. 3.1), clustering of
//! material space into kernel centres (LK14 4.1), area-weighted truncated-Gaussian sampling
//! (eq. 4.2-4.3) and the adjustment that keeps the weights affine and centred (eq. 4.4-4.8).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use glam::{DMat3, DVec2, DVec3};
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy};
use rand::{Rng, SeedableRng};

/// The kernel geometry's length over the wavelength it imposes. With LK14's geometry at
/// lambda (centres 2/pi lambda apart, supports of radius lambda / 2) a thin layer held to a
/// base compressed in large steps wrinkled at 0.842 lambda (measured: h / lambda <= 0.0125, 8
/// and 12 elements per wavelength, within 0.5 %), so kernels for a critical wavelength lambda
/// are laid out at lambda / 0.842. The pattern under kernels is multistable, though: kernels
/// bound the wavelength to a band (measured 0.9-1.4 lambda) and the loading path and the
/// imperfection pick within it; thicker layers sit higher in the band (their own bending
/// competes). The closing note of the LK14 issue has the figures.
pub const KERNEL_SCALE: f64 = 1.0 / 0.842;

/// LK14 eq. 3.1: lambda = c (h_upper h_lower)^(1/2) (E_upper / E_lower)^(1/6), the constant c
/// stated by the scene.
pub(crate) fn wavelength_two_layer(constant: f64, h_upper: f64, h_lower: f64, e_upper: f64, e_lower: f64) -> f64 {
    constant * (h_upper * h_lower).sqrt() * (e_upper / e_lower).powf(1.0 / 6.0)
}

/// How eq. 3.1's wavelength scales with the upper layer's (E, h): E^1/6 h^1/2.
pub(crate) const TWO_LAYER_EXPONENTS: (f64, f64) = (1.0 / 6.0, 0.5);

/// Stiff film on a deep substrate (Chen & Hutchinson 2004): lambda = 2 pi h (Ebar_f / (3 Ebar_s))^(1/3),
/// with plane-strain moduli Ebar = E / (1 - nu^2).
pub(crate) fn wavelength_film(h: f64, ebar_film: f64, ebar_substrate: f64) -> f64 {
    2.0 * std::f64::consts::PI * h * (ebar_film / (3.0 * ebar_substrate)).cbrt()
}

/// How the film wavelength scales with the film's (E, h): E^1/3 h.
pub(crate) const FILM_EXPONENTS: (f64, f64) = (1.0 / 3.0, 1.0);

/// Greedy farthest-point clustering (LK14 4.1) on a mesh of material space: distances are
/// Dijkstra paths over `edges` with cost |e| / mean(lambda at its ends), i.e. in wavelengths.
/// The first centre is a seeded random vertex; each next centre is the vertex farthest from
/// all centres among those at least 2/pi wavelengths from every centre. LK14 repeats "until all
/// vertices are within half a wavelength", which the spacing rule can forbid (a vertex 0.5-0.64
/// wavelengths from every centre): the spacing rule wins, so the loop ends when no vertex is
/// 2/pi away (measured: letting coverage win packs centres half a wavelength apart along the
/// boundary and makes the wrinkle wavelength depend on the patch width). Returns the centres'
/// vertex indices in the order chosen.
pub(crate) fn cluster_centres(points: &[DVec2], edges: &[[u32; 2]], wavelength: &[f64], seed: u64) -> Vec<u32> {
    cluster_by_length(edges, wavelength, seed, |a, b| (points[a] - points[b]).length())
}

/// `cluster_centres` with edge lengths from `length(a, b)` (material space, or a rest surface:
/// `geodesic`), one vertex per entry of `wavelength`.
pub(crate) fn cluster_by_length(
    edges: &[[u32; 2]],
    wavelength: &[f64],
    seed: u64,
    length: impl Fn(usize, usize) -> f64,
) -> Vec<u32> {
    let n = wavelength.len();
    if n == 0 {
        return Vec::new();
    }
    let mut adjacency: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
    for &[a, b] in edges {
        let (a, b) = (a as usize, b as usize);
        let cost = length(a, b) / (0.5 * (wavelength[a] + wavelength[b]));
        adjacency[a].push((b as u32, cost));
        adjacency[b].push((a as u32, cost));
    }
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut distance = vec![f64::INFINITY; n];
    let mut centres = vec![rng.random_range(0..n) as u32];
    let min_spacing = 2.0 / std::f64::consts::PI;
    loop {
        relax_from(*centres.last().unwrap(), &adjacency, &mut distance);
        // Ties go to the lowest index: the same mesh and seed give the same centres.
        let farthest_where = |ok: &dyn Fn(f64) -> bool| {
            (0..n).filter(|&v| ok(distance[v])).max_by(|&a, &b| distance[a].total_cmp(&distance[b]).then(b.cmp(&a)))
        };
        // An island no path reaches gets its own centre first.
        if let Some(v) = distance.iter().position(|d| !d.is_finite()) {
            centres.push(v as u32);
            continue;
        }
        match farthest_where(&|d| d >= min_spacing) {
            Some(next) => centres.push(next as u32),
            None => return centres,
        }
    }
}

/// A Dijkstra heap entry (distance, vertex): the nearest first, ties to the lowest vertex.
#[derive(PartialEq)]
pub(crate) struct Item(pub f64, pub u32);

impl Eq for Item {}

impl PartialOrd for Item {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

impl Ord for Item {
    fn cmp(&self, o: &Self) -> Ordering {
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}

/// Lowers `distance` with the shortest paths from `source` (incremental multi-source Dijkstra:
/// only vertices that get closer are visited).
fn relax_from(source: u32, adjacency: &[Vec<(u32, f64)>], distance: &mut [f64]) {
    distance[source as usize] = 0.0;
    let mut heap = BinaryHeap::from([Item(0.0, source)]);
    while let Some(Item(d, v)) = heap.pop() {
        if d > distance[v as usize] {
            continue;
        }
        for &(w, cost) in &adjacency[v as usize] {
            let nd = d + cost;
            if nd < distance[w as usize] {
                distance[w as usize] = nd;
                heap.push(Item(nd, w));
            }
        }
    }
}

/// One third of the areas of the faces around each vertex (the a_i of LK14 eq. 4.3).
pub fn vertex_areas(points: &[DVec2], faces: &[[u32; 3]]) -> Vec<f64> {
    let mut area = vec![0.0; points.len()];
    for f in faces {
        let [a, b, c] = f.map(|i| points[i as usize]);
        let third = (b - a).perp_dot(c - a).abs() / 6.0;
        for &i in f {
            area[i as usize] += third;
        }
    }
    area
}

/// A BVH over the vertices of one layer's material space: finds kernel supports.
pub struct SupportIndex {
    bvh: Bvh,
    points: Vec<DVec2>,
}

impl SupportIndex {
    pub fn new(points: &[DVec2]) -> SupportIndex {
        let leaves: Vec<Aabb> = points
            .iter()
            .map(|p| {
                let v = Vector::new(p.x, p.y, 0.0);
                Aabb::new(v, v)
            })
            .collect();
        SupportIndex { bvh: Bvh::from_leaves(BvhBuildStrategy::default(), &leaves), points: points.to_vec() }
    }

    /// Vertices strictly within `radius` of `centre`, in increasing index order.
    pub fn within(&self, centre: DVec2, radius: f64) -> Vec<u32> {
        let query = Aabb::new(
            Vector::new(centre.x - radius, centre.y - radius, -1.0),
            Vector::new(centre.x + radius, centre.y + radius, 1.0),
        );
        let mut found: Vec<u32> =
            self.bvh.intersect_aabb(&query).filter(|&i| (self.points[i as usize] - centre).length() < radius).collect();
        found.sort_unstable();
        found
    }
}

/// The weights of one kernel on one layer's mesh: vertex indices (increasing) and weights.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Sample {
    pub vertices: Vec<u32>,
    pub weights: Vec<f64>,
}

/// LK14 eq. 4.3: w_i = s_c a_i exp(-d_i^2 / (2 sigma^2)) for d_i < 2 sigma = radius, s_c making
/// the weights sum to one. Empty when no vertex (with positive area) lies in the support.
pub fn sample(index: &SupportIndex, area: &[f64], centre: DVec2, radius: f64) -> Sample {
    let sigma = 0.5 * radius;
    let mut s = Sample::default();
    for v in index.within(centre, radius) {
        let d2 = (index.points[v as usize] - centre).length_squared();
        let w = area[v as usize] * (-d2 / (2.0 * sigma * sigma)).exp();
        if w > 0.0 {
            s.vertices.push(v);
            s.weights.push(w);
        }
    }
    let total: f64 = s.weights.iter().sum();
    if total > 0.0 {
        s.weights.iter_mut().for_each(|w| *w /= total);
    }
    s
}

/// What the adjustment could do with a support.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Adjusted {
    /// Sum one and centroid on the centre (eq. 4.4-4.8, with the sum as a third condition).
    Centred,
    /// Fewer than three vertices or collinear ones: the centroid cannot be moved in both
    /// directions; the weights keep their normalized values (sum one, centroid off-centre).
    Degenerate,
    /// No vertex in the support: the kernel constrains nothing on this layer.
    Empty,
}

/// LK14 4.2.1 with the sum kept: w*_i = w_i + a0 + a1 (u_i - c)_x + a2 (u_i - c)_y, with
/// (a0, a1, a2) from the 3x3 system sum w* = 1, sum w* (u - c) = 0. (The source's 2x2 form drops
/// a0, so its weights stop summing to one; an affine combination needs both.)
pub fn adjust(points: &[DVec2], sample: &mut Sample, centre: DVec2) -> Adjusted {
    if sample.vertices.is_empty() {
        return Adjusted::Empty;
    }
    let mut a = DMat3::ZERO;
    let mut b = DVec3::new(1.0, 0.0, 0.0);
    let scale = sample.vertices.iter().map(|&v| (points[v as usize] - centre).length()).fold(0.0, f64::max);
    for (&v, &w) in sample.vertices.iter().zip(&sample.weights) {
        // Moments in units of the support's extent keep the 3x3 system well scaled.
        let d = (points[v as usize] - centre) / scale.max(f64::MIN_POSITIVE);
        let m = DVec3::new(1.0, d.x, d.y);
        a += DMat3::from_cols(m * m.x, m * m.y, m * m.z);
        b -= m * w;
    }
    // Collinear or too few points: the moment matrix is (near) singular.
    let det = a.determinant();
    let trace = a.x_axis.x + a.y_axis.y + a.z_axis.z;
    if sample.vertices.len() < 3 || det.abs() <= 1e-9 * trace.powi(3) {
        return Adjusted::Degenerate;
    }
    let alpha = a.inverse() * b;
    for (&v, w) in sample.vertices.iter().zip(sample.weights.iter_mut()) {
        let d = (points[v as usize] - centre) / scale.max(f64::MIN_POSITIVE);
        *w += alpha.x + alpha.y * d.x + alpha.z * d.y;
    }
    Adjusted::Centred
}

/// Sum of the weights and their material-space centroid (for tests and reports).
pub fn moments(points: &[DVec2], sample: &Sample) -> (f64, DVec2) {
    let sum: f64 = sample.weights.iter().sum();
    let centroid = sample.vertices.iter().zip(&sample.weights).map(|(&v, &w)| points[v as usize] * w).sum::<DVec2>();
    (sum, centroid / sum)
}

/// How a coupling's kernels measure distances.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum KernelDistance {
    /// In material space (LK14 4.1-4.2): supports and weights follow the UVs.
    #[default]
    Planar,
    /// On each layer's rest surface (LK14 6.2, `coupling::geodesic`): independent of how the UVs
    /// are distorted.
    Geodesic,
}

/// A continuous constraint kernel in material space (LK14 4.1-4.2): its centre, support radius
/// r = lambda / 2 (sigma = r / 2), and the centroid the adjusted weights must reproduce.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KernelShape {
    pub centre: DVec2,
    pub radius: f64,
    /// The centre itself, unless the patch boundary cuts the support: then the centroid of the
    /// truncated Gaussian over the part inside the patch (measured on the clustering mesh), so
    /// the weights of a cut kernel need not turn strongly negative to reach a centre at the
    /// edge, and still mean the same point on every discretization. For geodesic kernels,
    /// target - centre is that centroid's offset in the kernel's tangent chart.
    pub target: DVec2,
}

/// The kernels of a coupling: clusters a fine mesh of material space (`points`, `faces`) whose
/// vertices carry the critical wavelength, one kernel per centre (LK14 4.1).
pub(crate) fn build_kernels(points: &[DVec2], faces: &[[u32; 3]], wavelength: &[f64], seed: u64) -> Vec<KernelShape> {
    let edges = crate::mesh::edges(faces);
    let plain: Vec<[u32; 2]> = edges.iter().map(|e| e.v).collect();
    let boundary: Vec<u32> = edges.iter().filter(|e| !e.is_interior()).flat_map(|e| e.v).collect();
    let index = SupportIndex::new(points);
    let area = vertex_areas(points, faces);
    cluster_centres(points, &plain, wavelength, seed)
        .into_iter()
        .map(|c| {
            let centre = points[c as usize];
            let radius = 0.5 * wavelength[c as usize];
            let cut = boundary.iter().any(|&b| (points[b as usize] - centre).length() < radius);
            let target = if cut { moments(points, &sample(&index, &area, centre, radius)).1 } else { centre };
            KernelShape { centre, radius, target }
        })
        .collect()
}

/// The layers below `layer` along the kernels' couplings (upper, lower), nearest first (each
/// coupling ties a layer's kernel averages to the layer below, LK14 eq. 4.1): every one of them
/// carries the membrane strain the layer's mean surface follows. The remesher's wavelength term
/// reads the most compressive of them (issue 26 item 1): the kinematic bottom moves first,
/// before any solve; the solved layers between spread its compression (the localized pinch's
/// epidermis wrinkles out to about twice the pinch radius, where its base does not move). A
/// cycle of couplings ends the walk.
pub fn layers_below<L: Copy + PartialEq>(couplings: &[(L, L)], layer: L) -> Vec<L> {
    let mut out = Vec::new();
    let mut below = layer;
    while let Some(&(_, lower)) = couplings.iter().find(|c| c.0 == below).filter(|_| out.len() < couplings.len()) {
        below = lower;
        out.push(below);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{grid, GridPattern};

    #[test]
    fn layers_below_walk_the_chain_nearest_first_and_stop_at_a_cycle() {
        // epidermis 0 over dermis 1 over base 2; layer 3 couples to nothing.
        let chain = [(1, 2), (0, 1), (0, 1)];
        assert_eq!(layers_below(&chain, 0), [1, 2]);
        assert_eq!(layers_below(&chain, 2), Vec::<i32>::new());
        assert_eq!(layers_below(&chain, 3), Vec::<i32>::new());
        let cycle = [(0, 1), (1, 0)];
        assert!(layers_below(&cycle, 0).len() <= cycle.len());
    }

    fn sheet(cells: u32) -> crate::mesh::SurfaceMesh {
        grid(DVec2::new(1.0, 1.0), (cells, cells), GridPattern::Equilateral, 0.0)
    }

    /// Every vertex ends within 2/pi wavelengths (path metric) of a centre; centres keep 2/pi
    /// wavelengths apart; the same seed gives the same centres.
    #[test]
    fn clustering_covers_and_spaces_centres() {
        let m = sheet(40);
        let lambda: Vec<f64> = m.uv.iter().map(|u| 0.1 + 0.1 * u.x).collect();
        let edges: Vec<[u32; 2]> = crate::mesh::edges(&m.faces).iter().map(|e| e.v).collect();
        let c = cluster_centres(&m.uv, &edges, &lambda, 3);
        assert_eq!(c, cluster_centres(&m.uv, &edges, &lambda, 3));
        let adjacency = {
            let mut a: Vec<Vec<(u32, f64)>> = vec![Vec::new(); m.uv.len()];
            for &[p, q] in &edges {
                let cost =
                    (m.uv[p as usize] - m.uv[q as usize]).length() / (0.5 * (lambda[p as usize] + lambda[q as usize]));
                a[p as usize].push((q, cost));
                a[q as usize].push((p, cost));
            }
            a
        };
        let mut d = vec![f64::INFINITY; m.uv.len()];
        for (k, &centre) in c.iter().enumerate() {
            if k > 0 {
                assert!(d[centre as usize] >= 2.0 / std::f64::consts::PI, "centre {k} too close");
            }
            relax_from(centre, &adjacency, &mut d);
        }
        assert!(d.iter().all(|x| *x < 2.0 / std::f64::consts::PI));
        // Smaller wavelength at small x: more centres on the left half.
        let left = c.iter().filter(|&&v| m.uv[v as usize].x < 0.5).count();
        assert!(left > c.len() - left, "{left} of {}", c.len());
    }

    /// After adjustment the weights sum to one and their centroid is the centre to 1e-12, on an
    /// irregular (jittered) mesh.
    #[test]
    fn adjusted_weights_are_affine_and_centred() {
        let mut m = sheet(30);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        for u in &mut m.uv {
            if u.x > 0.0 && u.x < 1.0 && u.y > 0.0 && u.y < 1.0 {
                *u += DVec2::new(rng.random_range(-0.01..0.01), rng.random_range(-0.01..0.01));
            }
        }
        let index = SupportIndex::new(&m.uv);
        let area = vertex_areas(&m.uv, &m.faces);
        let centre = DVec2::new(0.43, 0.57);
        let mut s = sample(&index, &area, centre, 0.2);
        let (sum, before) = moments(&m.uv, &s);
        assert!((sum - 1.0).abs() < 1e-14);
        assert!((before - centre).length() > 1e-5, "the jitter moves the raw centroid");
        assert_eq!(adjust(&m.uv, &mut s, centre), Adjusted::Centred);
        let (sum, after) = moments(&m.uv, &s);
        assert!((sum - 1.0).abs() < 1e-12, "sum {sum}");
        assert!((after - centre).length() < 1e-12, "centroid off by {}", (after - centre).length());
    }

    /// A kernel at a corner: its target is the centroid of the cut Gaussian, inside the patch,
    /// and the adjusted weights reach it with weights that stay bounded.
    #[test]
    fn boundary_cut_kernel_targets_the_cut_centroid() {
        let m = sheet(40);
        let lambda = vec![0.2; m.uv.len()];
        let kernels = build_kernels(&m.uv, &m.faces, &lambda, 1);
        let corner = kernels.iter().find(|k| k.centre.x < 0.05 && k.centre.y < 0.05);
        let interior = kernels.iter().find(|k| k.centre.min_element() > 0.11 && k.centre.max_element() < 0.89);
        let interior = interior.expect("an interior kernel");
        assert_eq!(interior.target, interior.centre);
        if let Some(k) = corner {
            assert!(k.target.min_element() > k.centre.min_element());
            let coarse = sheet(17);
            let index = SupportIndex::new(&coarse.uv);
            let area = vertex_areas(&coarse.uv, &coarse.faces);
            let mut s = sample(&index, &area, k.centre, k.radius);
            assert_eq!(adjust(&coarse.uv, &mut s, k.target), Adjusted::Centred);
            assert!((moments(&coarse.uv, &s).1 - k.target).length() < 1e-12);
            let worst = s.weights.iter().fold(0.0f64, |a, w| a.max(w.abs()));
            assert!(worst < 1.0, "largest |weight| {worst}");
        }
        for k in &kernels {
            assert!((k.radius - 0.1).abs() < 1e-15);
        }
    }

    /// Tiny supports: one or two vertices (or collinear ones) keep their normalized weights and
    /// report Degenerate; none report Empty.
    #[test]
    fn tiny_supports_are_reported() {
        let m = sheet(10);
        let index = SupportIndex::new(&m.uv);
        let area = vertex_areas(&m.uv, &m.faces);
        let v = m.uv[37];
        let mut one = sample(&index, &area, v, 0.01);
        assert_eq!(one.vertices, vec![37]);
        assert_eq!(adjust(&m.uv, &mut one, v + DVec2::new(0.001, 0.0)), Adjusted::Degenerate);
        assert_eq!(one.weights, vec![1.0]);
        let mut none = sample(&index, &area, DVec2::new(5.0, 5.0), 0.01);
        assert_eq!(adjust(&m.uv, &mut none, DVec2::new(5.0, 5.0)), Adjusted::Empty);
        let line = [DVec2::new(0.0, 0.0), DVec2::new(0.5, 0.0), DVec2::new(1.0, 0.0)];
        let mut s = Sample { vertices: vec![0, 1, 2], weights: vec![0.25, 0.5, 0.25] };
        assert_eq!(adjust(&line, &mut s, DVec2::new(0.4, 0.1)), Adjusted::Degenerate);
    }

    #[test]
    fn wavelength_formulas() {
        // E x64 doubles, h / 4 halves (both layers' h scaled) the eq. 3.1 wavelength.
        let base = wavelength_two_layer(1.0, 1e-4, 1e-3, 600e6, 4e6);
        assert!((wavelength_two_layer(1.0, 1e-4, 1e-3, 64.0 * 600e6, 4e6) / base - 2.0).abs() < 1e-12);
        assert!((wavelength_two_layer(1.0, 0.25e-4, 0.25e-3, 600e6, 4e6) / base - 0.25).abs() < 1e-12);
        // VALIDATION.md case 7: lambda / h = 43.565 at Ebar ratio 1000.
        assert!((wavelength_film(1.0, 1000.0, 1.0) - 43.565).abs() < 1e-3);
    }
}
