//! The contact module against references that share none of its code: central differences
//! (derivatives, the A1 style), a brute-force minimization (distances), and a sampled time of
//! impact (CCD).

use rand::{Rng, SeedableRng};

use super::ccd::additive_toi;
use super::distance::{squared_distance, DistanceType, Primitives};
use super::*;
use crate::physics::psd::Filter;

type Points = [[f64; 3]; 4];

/// Minimizes a convex f(u, v) over u in [0, 1], v in [0, vmax(u)] by nested ternary search.
fn ternary(lo: f64, hi: f64, f: &dyn Fn(f64) -> f64) -> f64 {
    let (mut a, mut b) = (lo, hi);
    for _ in 0..200 {
        let (m1, m2) = (a + (b - a) / 3.0, b - (b - a) / 3.0);
        if f(m1) < f(m2) {
            b = m2;
        } else {
            a = m1;
        }
    }
    f(0.5 * (a + b)).min(f(lo)).min(f(hi))
}

fn lerp(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    std::array::from_fn(|k| a[k] + t * (b[k] - a[k]))
}

fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum()
}

/// The brute-force squared distance: the minimum over the primitives' parameter domain.
fn brute_force(kind: Primitives, x: &Points) -> f64 {
    match kind {
        Primitives::PointTriangle => ternary(0.0, 1.0, &|u| {
            ternary(0.0, 1.0 - u, &|v| {
                let q: [f64; 3] = std::array::from_fn(|k| x[1][k] + u * (x[2][k] - x[1][k]) + v * (x[3][k] - x[1][k]));
                dist2(x[0], q)
            })
        }),
        Primitives::EdgeEdge => {
            ternary(0.0, 1.0, &|u| ternary(0.0, 1.0, &|v| dist2(lerp(x[0], x[1], u), lerp(x[2], x[3], v))))
        }
    }
}

fn clamp01(t: f64) -> f64 {
    t.clamp(0.0, 1.0)
}

/// The squared distance of p to the segment a-b by a clamped projection.
fn point_segment(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let e: [f64; 3] = std::array::from_fn(|k| b[k] - a[k]);
    let l2: f64 = e.iter().map(|c| c * c).sum();
    let t = if l2 > 0.0 { clamp01((0..3).map(|k| (p[k] - a[k]) * e[k]).sum::<f64>() / l2) } else { 0.0 };
    dist2(p, lerp(a, b, t))
}

/// A second, cheap reference for the sampled time of impact: clamped projections onto the
/// edges, and the face or the two lines where their feet fall inside (checked against the
/// brute-force minimum in `distances_match_a_brute_force_minimum`).
fn reference(kind: Primitives, x: &Points) -> f64 {
    let sub = |a: [f64; 3], b: [f64; 3]| -> [f64; 3] { std::array::from_fn(|k| a[k] - b[k]) };
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    match kind {
        Primitives::PointTriangle => {
            let mut best = point_segment(x[0], x[1], x[2])
                .min(point_segment(x[0], x[2], x[3]))
                .min(point_segment(x[0], x[3], x[1]));
            let (e1, e2) = (sub(x[2], x[1]), sub(x[3], x[1]));
            let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
            let nn = dot(n, n);
            if nn > 1e-24 {
                let h = dot(sub(x[0], x[1]), n) / nn;
                let foot: [f64; 3] = std::array::from_fn(|k| x[0][k] - h * n[k]);
                // inside when the foot is on the inner side of every edge
                let side = |a: [f64; 3], b: [f64; 3]| {
                    let (e, r) = (sub(b, a), sub(foot, a));
                    dot([e[1] * r[2] - e[2] * r[1], e[2] * r[0] - e[0] * r[2], e[0] * r[1] - e[1] * r[0]], n) >= 0.0
                };
                if side(x[1], x[2]) && side(x[2], x[3]) && side(x[3], x[1]) {
                    best = best.min(h * h * nn);
                }
            }
            best
        }
        Primitives::EdgeEdge => {
            let mut best = point_segment(x[0], x[2], x[3])
                .min(point_segment(x[1], x[2], x[3]))
                .min(point_segment(x[2], x[0], x[1]))
                .min(point_segment(x[3], x[0], x[1]));
            let (u, v, w) = (sub(x[1], x[0]), sub(x[3], x[2]), sub(x[0], x[2]));
            let (a, b, c, d, e) = (dot(u, u), dot(u, v), dot(v, v), dot(u, w), dot(v, w));
            let den = a * c - b * b;
            if den > 1e-14 * a * c {
                let (s, t) = ((b * e - c * d) / den, (a * e - b * d) / den);
                if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) {
                    best = best.min(dist2(lerp(x[0], x[1], s), lerp(x[2], x[3], t)));
                }
            }
            best
        }
    }
}

fn random_points(rng: &mut impl Rng) -> Points {
    std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)))
}

/// Degenerate configurations: coplanar, collinear, parallel and crossing edges, a point on a
/// triangle's edge or vertex, a sliver triangle.
fn degenerate() -> Vec<(Primitives, Points)> {
    use Primitives::*;
    vec![
        (PointTriangle, [[0.2, 0.2, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
        (PointTriangle, [[2.0, 0.5, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
        (PointTriangle, [[0.5, 0.0, 0.3], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
        (PointTriangle, [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
        (PointTriangle, [[0.3, 0.4, 0.2], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 1e-9, 0.0]]),
        (EdgeEdge, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.5], [1.0, 0.0, 0.5]]),
        (EdgeEdge, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.0, 0.5], [1.5, 0.0, 0.5]]),
        (EdgeEdge, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0]]),
        (EdgeEdge, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0]]),
        (EdgeEdge, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, -0.5, 0.2], [0.5 + 1e-9, 0.5, 0.2]]),
        (EdgeEdge, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1e-7, 0.3], [1.0, -1e-7, 0.3]]),
        // Coplanar, parallel to round-off, side by side (a grid's rows and diagonals).
        (
            EdgeEdge,
            [[0.015, 0.003, 0.0], [0.016, 0.002 + 1e-19, 0.0], [0.016, 0.004, 0.0], [0.017, 0.003 - 1e-19, 0.0]],
        ),
        (
            EdgeEdge,
            [[0.0175, 0.001, 0.0], [0.017, 0.002 + 4e-19, 0.0], [0.018, 0.002, 0.0], [0.0175, 0.003 + 8e-19, 0.0]],
        ),
    ]
}

#[test]
fn distances_match_a_brute_force_minimum() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let mut cases = degenerate();
    for i in 0..400 {
        let kind = if i % 2 == 0 { Primitives::PointTriangle } else { Primitives::EdgeEdge };
        cases.push((kind, random_points(&mut rng)));
    }
    for (kind, x) in cases {
        let (ours, reference, cheap) = (squared_distance(kind, &x), brute_force(kind, &x), reference(kind, &x));
        assert!((cheap.sqrt() - reference.sqrt()).abs() <= 1e-9, "the cheap reference: {kind:?} {x:?}");
        assert!(
            (ours.sqrt() - reference.sqrt()).abs() <= 1e-9,
            "{kind:?} {x:?}: {ours} against {reference} ({:?})",
            DistanceType::of(kind, &x)
        );
    }
}

/// One configuration per distance type, each active under the barrier below.
fn every_type() -> Vec<(Primitives, Points, DistanceType)> {
    use DistanceType::*;
    use Primitives::*;
    let t = [[0.0, 0.0, 0.0], [1.0, 0.1, 0.0], [0.2, 0.9, 0.05]];
    let pt = |p: [f64; 3]| [p, t[0], t[1], t[2]];
    vec![
        (PointTriangle, pt([0.3, 0.3, 0.25]), PointPlane),
        (PointTriangle, pt([0.6, -0.2, 0.2]), PointEdge(0, 1, 2)),
        (PointTriangle, pt([-0.2, -0.15, 0.1]), PointPoint(0, 1)),
        (EdgeEdge, [[0.0, 0.0, 0.0], [1.0, 0.1, 0.0], [0.4, -0.5, 0.3], [0.6, 0.5, 0.25]], LineLine),
        (EdgeEdge, [[0.0, 0.0, 0.0], [1.0, 0.1, 0.0], [1.2, -0.5, 0.2], [1.3, 0.5, 0.25]], PointEdge(1, 2, 3)),
        (EdgeEdge, [[0.0, 0.0, 0.0], [1.0, 0.1, 0.0], [1.2, 0.2, 0.2], [1.9, 0.5, 0.25]], PointPoint(1, 2)),
        // Nearly parallel edges, under the mollifier's threshold: crossing, and overlapping.
        (EdgeEdge, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -0.02, 0.2], [1.0, 0.02, 0.2]], LineLine),
        (EdgeEdge, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.3, 0.01, 0.2], [1.3, -0.005, 0.21]], PointEdge(2, 0, 1)),
    ]
}

#[test]
fn pair_derivatives_match_central_differences() {
    let barrier = Barrier { offset: 0.1, reach: 0.3 };
    for (kind, x, expected) in every_type() {
        assert_eq!(DistanceType::of(kind, &x), expected, "{x:?}");
        let eps = if kind == Primitives::EdgeEdge { barrier::mollifier_threshold(1.0, 1.0) * 100.0 } else { 0.0 };
        let pair = Pair { v: [0, 1, 2, 3], kind, barrier, eps };
        let (e, g, h) = pair.derivatives(&x, Filter::Exact);
        assert!(e > 0.0 && (e - pair.energy(&x)).abs() <= 1e-14 * e, "{expected:?}: active");
        let step = 1e-6;
        for i in 0..12 {
            let shifted = |s: f64| {
                let mut y = x;
                y[i / 3][i % 3] += s;
                y
            };
            let fd = (pair.energy(&shifted(step)) - pair.energy(&shifted(-step))) / (2.0 * step);
            assert!((fd - g[i]).abs() <= 1e-6 * (1.0 + g[i].abs()), "{expected:?} g[{i}]: {fd} vs {}", g[i]);
            let (gp, gm) =
                (pair.derivatives(&shifted(step), Filter::Exact).1, pair.derivatives(&shifted(-step), Filter::Exact).1);
            for j in 0..12 {
                let fd = (gp[j] - gm[j]) / (2.0 * step);
                let scale = 1.0 + h.abs().max();
                assert!((fd - h[(j, i)]).abs() <= 1e-5 * scale, "{expected:?} H[{j},{i}]: {fd} vs {}", h[(j, i)]);
            }
        }
        // The projected Hessian is positive semi-definite.
        let (_, _, hp) = pair.derivatives(&x, Filter::Clamp);
        let min = hp.symmetric_eigenvalues().min();
        assert!(min >= -1e-9 * hp.abs().max(), "{expected:?}: {min}");
    }
}

/// The first time in [0, 1] at which the gap d - xi closes, by the brute-force distance at
/// 20 000 samples and bisection (the cheap reference distance); None if it stays open.
fn sampled_toi(kind: Primitives, x: &Points, dx: &Points, offset: f64) -> Option<f64> {
    let at = |t: f64| -> f64 {
        let y: Points = std::array::from_fn(|i| std::array::from_fn(|k| x[i][k] + t * dx[i][k]));
        reference(kind, &y).sqrt() - offset
    };
    let n = 20_000;
    let mut prev = 0.0;
    for s in 1..=n {
        let t = s as f64 / n as f64;
        if at(t) <= 0.0 {
            let (mut a, mut b) = (prev, t);
            for _ in 0..60 {
                let m = 0.5 * (a + b);
                if at(m) <= 0.0 {
                    b = m;
                } else {
                    a = m;
                }
            }
            return Some(b);
        }
        prev = t;
    }
    None
}

/// Hand-made motions: fast ones a test at the step's ends misses, grazing ones at the
/// thickness, rotating edges, a moving triangle over a still point.
fn motions() -> Vec<(&'static str, Primitives, Points, Points, f64)> {
    use Primitives::*;
    let tri = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let z = [0.0; 3];
    vec![
        (
            "point through a face, fast",
            PointTriangle,
            [[0.2, 0.2, 1.0], tri[0], tri[1], tri[2]],
            [[0.0, 0.0, -50.0], z, z, z],
            0.01,
        ),
        (
            "point through a face, slow",
            PointTriangle,
            [[0.2, 0.2, 1.0], tri[0], tri[1], tri[2]],
            [[0.0, 0.0, -1.5], z, z, z],
            0.01,
        ),
        (
            "face through a point",
            PointTriangle,
            [[0.2, 0.2, 0.0], tri[0], tri[1], tri[2]],
            [z, [0.0, 0.0, 9.0], [0.0, 0.0, 9.0], [0.0, 0.0, 9.0]],
            0.0,
        ),
        (
            "point past an edge, fast",
            PointTriangle,
            [[1.0, 1.0, 0.0], tri[0], tri[1], tri[2]],
            [[-30.0, -30.0, 0.0], z, z, z],
            0.001,
        ),
        (
            "point grazing at the thickness",
            PointTriangle,
            [[-0.5, 0.3, 0.0099999], tri[0], tri[1], tri[2]],
            [[2.0, 0.0, 0.0], z, z, z],
            0.01,
        ),
        (
            "point grazing above the thickness",
            PointTriangle,
            [[-0.5, 0.3, 0.0100001], tri[0], tri[1], tri[2]],
            [[2.0, 0.0, 0.0], z, z, z],
            0.01,
        ),
        (
            "edges crossing, fast",
            EdgeEdge,
            [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0]],
            [[0.0, 0.0, -40.0], [0.0, 0.0, -40.0], z, z],
            0.02,
        ),
        (
            "edge rotating through an edge",
            EdgeEdge,
            [[0.0, 0.0, 0.5], [1.0, 0.0, 0.5], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0]],
            [[0.0, 0.0, -1.0], [0.0, 0.0, 1.0], z, z],
            0.0,
        ),
        (
            "parallel edges closing",
            EdgeEdge,
            [[0.0, 0.0, 0.3], [1.0, 0.0, 0.3], [0.2, 0.0, 0.0], [1.2, 0.0, 0.0]],
            [[0.0, 0.0, -0.6], [0.0, 0.0, -0.6], z, z],
            0.05,
        ),
        (
            "edges grazing at the thickness",
            EdgeEdge,
            [[0.0, -1.0, 0.02], [0.0, -0.5, 0.02], [-0.5, 0.0, 0.0], [0.5, 0.0, 0.0]],
            [[0.0, 2.0, 0.0], [0.0, 2.0, 0.0], z, z],
            0.0200001,
        ),
        ("still", PointTriangle, [[0.2, 0.2, 1.0], tri[0], tri[1], tri[2]], [z; 4], 0.01),
    ]
}

#[test]
fn ccd_never_reports_an_impact_later_than_the_true_one() {
    let impacts = std::cell::Cell::new(0);
    let check = |name: &str, kind, x: &Points, dx: &Points, offset: f64| {
        let truth = sampled_toi(kind, x, dx, offset);
        impacts.set(impacts.get() + truth.is_some() as u32);
        let ours = additive_toi(kind, x, dx, offset, 1.0);
        if let Some(t) = truth {
            let toi = ours.unwrap_or_else(|| panic!("{name}: missed the impact at {t}"));
            assert!(toi <= t, "{name}: {toi} after the true {t}");
            assert!(toi >= 0.05 * t, "{name}: {toi} far before the true {t}: the step would stall");
        }
        ours
    };
    for (name, kind, x, dx, offset) in motions() {
        let toi = check(name, kind, &x, &dx, offset);
        if name.contains("fast") {
            // A test at the step's ends sees both sides open: the motion tunnels.
            let end: Points = std::array::from_fn(|i| std::array::from_fn(|k| x[i][k] + dx[i][k]));
            assert!(squared_distance(kind, &end).sqrt() > offset, "{name}: the end is clear");
            assert!(toi.is_some(), "{name}");
        }
        // (a pass above the thickness may still stop the step: the test is conservative)
        if name == "still" {
            assert!(toi.is_none(), "{name}: {toi:?}");
        }
    }
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    for i in 0..300 {
        let kind = if i % 2 == 0 { Primitives::PointTriangle } else { Primitives::EdgeEdge };
        let (x, dx) = (random_points(&mut rng), random_points(&mut rng).map(|p| p.map(|c| 3.0 * c)));
        if squared_distance(kind, &x).sqrt() > 0.05 {
            check("random", kind, &x, &dx, 0.05);
        }
    }
    assert!(impacts.get() >= 25, "the suite meets impacts: {}", impacts.get());
}

/// The pair rules: two stacked layers 0.3 apart touch unless a kernel binds them; on one layer,
/// neighbours within twice the barrier's reach at rest never pair; a body (not moving) pairs
/// with the skin but not with another body.
#[test]
fn the_surface_pairs_what_may_touch() {
    use glam::DVec3;
    // Two 3 x 3 grids of unit cells (16 vertices each), 0.3 apart.
    let grid = |base: u32| -> Vec<[u32; 3]> {
        (0..3u32)
            .flat_map(|i| (0..3u32).map(move |j| (i, j)))
            .flat_map(|(i, j)| {
                let v = |a: u32, b: u32| base + a * 4 + b;
                [[v(i, j), v(i + 1, j), v(i + 1, j + 1)], [v(i, j), v(i + 1, j + 1), v(i, j + 1)]]
            })
            .collect()
    };
    let rest: Vec<DVec3> =
        (0..32u32).map(|k| DVec3::new(((k % 16) / 4) as f64, (k % 4) as f64, if k < 16 { 0.0 } else { 0.3 })).collect();
    let layer = |base, moving| SurfaceLayer { triangles: grid(base), half_thickness: 0.05, moving };
    let across = |s: &Surface| {
        broad::candidates(s, &rest, None, 1.0)
            .iter()
            .filter(|p| p.v.iter().any(|&v| v < 16) && p.v.iter().any(|&v| v >= 16))
            .count()
    };
    let free = Surface::new(&[layer(0, true), layer(16, true)], rest.clone(), 0.1, &[]);
    assert!(across(&free) > 0, "unbound stacked layers pair");
    let bound = Surface::new(&[layer(0, true), layer(16, true)], rest.clone(), 0.1, &[(1, 0), (0, 1)]);
    assert_eq!(across(&bound), 0, "bound layers do not");
    let bodies = Surface::new(&[layer(0, false), layer(16, false)], rest.clone(), 0.1, &[]);
    assert!(broad::candidates(&bodies, &rest, None, 1.0).is_empty(), "two bodies do not");
    // One layer, reach 0.3 + offset 0.1: neighbours within 0.8 at rest excluded, 1 apart kept.
    let one = Surface::new(&[layer(0, true)], rest.clone(), 0.3, &[]);
    for p in broad::candidates(&one, &rest, None, 2.0) {
        let d = squared_distance(p.kind, &gather(&rest, &p.v)).sqrt();
        assert!(d >= 0.8, "{p:?} at {d}");
    }
}

/// The wide list (`ContactState::pairs_near`): over random walks of two crumpled layers, some
/// steps within its extra reach and some beyond, every broad phase at a state finds the same
/// pairs in the same order as building the trees; over a step both hold every pair that comes
/// within its reach along it.
#[test]
fn the_wide_list_finds_what_the_trees_find() {
    use glam::DVec3;
    let n = 8u32;
    let grid = |base: u32| -> Vec<[u32; 3]> {
        (0..n - 1)
            .flat_map(|i| (0..n - 1).map(move |j| (i, j)))
            .flat_map(|(i, j)| {
                let v = |a: u32, b: u32| base + a * n + b;
                [[v(i, j), v(i + 1, j), v(i + 1, j + 1)], [v(i, j), v(i + 1, j + 1), v(i, j + 1)]]
            })
            .collect()
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let rest: Vec<DVec3> = (0..2 * n * n)
        .map(|k| {
            let (l, i, j) = (k / (n * n), (k % (n * n)) / n, k % n);
            DVec3::new(i as f64 * 0.1, j as f64 * 0.1, 0.05 * l as f64)
        })
        .collect();
    let layer = |base| SurfaceLayer { triangles: grid(base), half_thickness: 0.005, moving: true };
    let surface = Surface::new(&[layer(0), layer(n * n)], rest.clone(), 0.01, &[]);
    let mut state = ContactState::new(surface, 0.01);
    let fixed = vec![[false; 3]; rest.len()];
    // (at rest a sheet's points lie on the boxes of triangles they are not part of, 0.07 away,
    // beyond the list's reach of 0.03: by distance, no pair)
    assert!(state.free_pairs(&rest, None, &fixed).is_empty());
    let mut x = rest.clone();
    let (mut reused, mut rebuilt) = (0, 0);
    for step in 0..60 {
        // (small steps reuse the wide list, every tenth is longer than its extra reach)
        let size = if step % 10 == 9 { 0.5 } else { 0.004 };
        let x1: Vec<DVec3> = x
            .iter()
            .map(|p| *p + DVec3::new(rng.random(), rng.random(), rng.random()) * size - DVec3::splat(0.5 * size))
            .collect();
        let before = state.wide_at.clone();
        let key = |p: &Pair| (p.v, p.kind == Primitives::EdgeEdge);
        let keys = |pairs: &[Pair]| pairs.iter().map(key).collect::<Vec<_>>();
        let wide = state.pairs_near(&x, None, &fixed);
        assert_eq!(keys(&wide), keys(&state.free_pairs(&x, None, &fixed)), "step {step}");
        // Over a step the two may differ (each bounds the distance its own way), but both hold
        // every pair that comes within its list reach somewhere along it.
        let (wide, trees) =
            (keys(&state.pairs_near(&x, Some(&x1), &fixed)), keys(&state.free_pairs(&x, Some(&x1), &fixed)));
        let beyond = state.beyond();
        let along: Vec<Vec<DVec3>> =
            (0..=32).map(|k| x.iter().zip(&x1).map(|(a, b)| *a + k as f64 / 32.0 * (*b - *a)).collect()).collect();
        // (a pair that comes within its reach along the step is within it plus twice the
        // longest vertex move at the start)
        let longest = x.iter().zip(&x1).map(|(a, b)| a.distance(*b)).fold(0.0, f64::max);
        for p in broad::candidates(&state.surface, &x, None, beyond + 2.0 * longest) {
            let closest =
                along.iter().map(|y| p.squared_distance(&gather(y, &p.v)).sqrt()).fold(f64::INFINITY, f64::min);
            if closest < p.barrier.offset + beyond {
                assert!(wide.contains(&key(&p)) && trees.contains(&key(&p)), "step {step}: {p:?} at {closest}");
            }
        }
        if state.wide_at == before {
            reused += 1
        } else {
            rebuilt += 1
        }
        x = x1;
    }
    assert!(reused > 10 && rebuilt > 3, "reused {reused}, rebuilt {rebuilt}");
}

/// Lagged friction: the closest points' weights give the brute-force distance, the normal
/// force is the barrier's force along the distance (a central difference of its energy), and
/// the friction energy's gradient and Hessian match central differences, sticking (slip below
/// eps_u) and sliding, with a PSD Hessian.
#[test]
fn friction_pairs_match_central_differences() {
    use glam::DVec3;
    let barrier = Barrier { offset: 0.1, reach: 0.3 };
    let (stiffness, mu) = (2.0, 0.7);
    for (kind, x, expected) in every_type() {
        let eps = if kind == Primitives::EdgeEdge { barrier::mollifier_threshold(1.0, 1.0) * 100.0 } else { 0.0 };
        let pair = Pair { v: [0, 1, 2, 3], kind, barrier, eps };
        let w = distance::closest_weights(kind, &x);
        let offset: [f64; 3] = std::array::from_fn(|k| (0..4).map(|i| w[i] * x[i][k]).sum());
        let d2: f64 = offset.iter().map(|c| c * c).sum();
        assert!((d2 - brute_force(kind, &x)).abs() <= 1e-9, "{expected:?}: weights {w:?}");
        // lambda: the barrier energy's slope when the first primitive moves along the offset
        // (a rigid shift of one primitive changes the distance one for one).
        let n: [f64; 3] = offset.map(|c| c / d2.sqrt());
        let along = |s: f64| {
            let mut y = x;
            for (i, p) in y.iter_mut().enumerate() {
                if w[i] > 0.0 || (w[i] == 0.0 && (i == 0 || (kind == Primitives::EdgeEdge && i == 1))) {
                    (0..3).for_each(|k| p[k] += s * n[k]);
                }
            }
            stiffness * pair.energy(&y)
        };
        let h = 1e-7;
        let slope = (along(h) - along(-h)) / (2.0 * h);
        let xs: Vec<DVec3> = x.iter().map(|p| DVec3::from_array(*p)).collect();
        let f = FrictionPair::lagged(&pair, &xs, stiffness, mu).expect("touching");
        assert!((f.force - mu * slope.abs()).abs() <= 1e-5 * f.force, "{expected:?}: {} vs {}", f.force, mu * slope);
        assert!(f.basis.iter().all(|b| b.dot(DVec3::from_array(n)).abs() < 1e-12));
        // Slips below and beyond the sticking slip eps_u = 0.01, along a tangent.
        for (scale, label) in [(0.004, "sticking"), (0.05, "sliding")] {
            let mut y = xs.clone();
            y[0] += scale * (0.8 * f.basis[0] + 0.6 * f.basis[1]) + DVec3::new(0.001, -0.002, 0.0015);
            y[3] -= DVec3::new(0.002, 0.001, -0.001) * scale;
            let eps_u = 0.01;
            let (e, g, hm) = f.derivatives(&y, eps_u);
            assert!((e - f.energy(&y, eps_u)).abs() <= 1e-14 * e);
            let step = 1e-7;
            for i in 0..12 {
                let shifted = |s: f64| {
                    let mut z = y.clone();
                    z[i / 3][i % 3] += s;
                    z
                };
                let fd = (f.energy(&shifted(step), eps_u) - f.energy(&shifted(-step), eps_u)) / (2.0 * step);
                assert!(
                    (fd - g[i]).abs() <= 1e-6 * (1.0 + g[i].abs()),
                    "{label} {expected:?} g[{i}]: {fd} vs {}",
                    g[i]
                );
                let (gp, gm) = (f.derivatives(&shifted(step), eps_u).1, f.derivatives(&shifted(-step), eps_u).1);
                for j in 0..12 {
                    let fd = (gp[j] - gm[j]) / (2.0 * step);
                    let scale = 1.0 + hm.abs().max();
                    assert!((fd - hm[(j, i)]).abs() <= 1e-5 * scale, "{label} H[{j},{i}]: {fd} vs {}", hm[(j, i)]);
                }
            }
            let min = hm.symmetric_eigenvalues().min();
            assert!(min >= -1e-9 * hm.abs().max(), "{label}: {min}");
            // Sliding, a point with weight 1 feels mu lambda, along the slip.
            if label == "sliding" && w[0] == 1.0 {
                let push = DVec3::new(g[0], g[1], g[2]).length();
                assert!((push - f.force).abs() <= 1e-9 * f.force, "{expected:?}: {push} vs {}", f.force);
            }
        }
    }
}
