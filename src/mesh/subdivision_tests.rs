use std::collections::{BTreeSet, HashMap, HashSet};

use glam::{DQuat, DVec2, DVec3};

use super::*;
// (the same subdivided icosahedron as the creature body's)
use crate::mesh::bodies::icosphere;

use crate::mesh::test_rng::Rng;

/// Flips up to `count` random interior edges (keeping valences >= 3 and no doubled edge), so
/// that the mesh has irregular vertices of many valences.
fn flip_edges(faces: &mut [[u32; 3]], rng: &mut Rng, count: usize) {
    let mut flipped = 0;
    for _ in 0..count * 20 {
        if flipped == count {
            break;
        }
        let mut edge_faces: HashMap<(u32, u32), Vec<(usize, usize)>> = HashMap::new();
        let mut valence: HashMap<u32, usize> = HashMap::new();
        for (fi, f) in faces.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                edge_faces.entry((a.min(b), a.max(b))).or_default().push((fi, k));
                if a < b {
                    *valence.entry(a).or_default() += 1;
                    *valence.entry(b).or_default() += 1;
                }
            }
        }
        for f in faces.iter() {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                if a > b && edge_faces[&(b, a)].len() == 1 {
                    *valence.entry(a).or_default() += 1;
                    *valence.entry(b).or_default() += 1;
                }
            }
        }
        let (f1, k1) = (rng.below(faces.len()), rng.below(3));
        let (a, b, c) = (faces[f1][k1], faces[f1][(k1 + 1) % 3], faces[f1][(k1 + 2) % 3]);
        let Some(&(f2, k2)) = edge_faces[&(a.min(b), a.max(b))].iter().find(|&&(fi, _)| fi != f1) else { continue };
        let d = faces[f2][(k2 + 2) % 3];
        if faces[f2][k2] != b || edge_faces.contains_key(&(c.min(d), c.max(d))) || valence[&a] <= 4 || valence[&b] <= 4
        {
            continue;
        }
        faces[f1] = [a, d, c];
        faces[f2] = [d, b, c];
        flipped += 1;
    }
}

/// A grid of `n` x `n` quads of size `h` in the xy plane, vertex (i, j) = j (n + 1) + i. Each quad
/// is split along (i, j)-(i+1, j+1), or, with `mixed`, along a random diagonal.
fn grid(n: u32, h: f64, mixed: Option<&mut Rng>) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let v = |i: u32, j: u32| j * (n + 1) + i;
    let p = (0..=n).flat_map(|j| (0..=n).map(move |i| DVec3::new(i as f64 * h, j as f64 * h, 0.0))).collect();
    let mut f = Vec::new();
    let mut rng = mixed;
    for j in 0..n {
        for i in 0..n {
            let other = rng.as_mut().is_some_and(|r| r.below(2) == 1);
            if other {
                f.push([v(i, j), v(i + 1, j), v(i, j + 1)]);
                f.push([v(i + 1, j), v(i + 1, j + 1), v(i, j + 1)]);
            } else {
                f.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
                f.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
            }
        }
    }
    (p, f)
}

/// A connected patch of `count` faces grown breadth-first (across edges) from `seed`.
fn patch(faces: &[[u32; 3]], seed: u32, count: usize) -> Vec<u32> {
    let mut by_edge: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
    for (fi, f) in faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            by_edge.entry((a.min(b), a.max(b))).or_default().push(fi as u32);
        }
    }
    let mut out = vec![seed];
    let mut i = 0;
    while out.len() < count && i < out.len() {
        let f = faces[out[i] as usize];
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            for &g in &by_edge[&(a.min(b), a.max(b))] {
                if out.len() < count && !out.contains(&g) {
                    out.push(g);
                }
            }
        }
        i += 1;
    }
    out
}

/// A refined vertex's point of the coarse parametric domain: coarse vertices with numerators
/// over 2^levels, ascending.
type Key = Vec<(u32, u64)>;

fn key_of(faces: &[[u32; 3]], parent: (u32, DVec3), levels: u32) -> Key {
    let f = faces[parent.0 as usize];
    let scale = f64::from(1u32 << levels);
    let mut k: Key = (0..3)
        .filter(|&i| parent.1[i] != 0.0)
        .map(|i| {
            let n = parent.1[i] * scale;
            assert_eq!(n, n.round(), "barycentric {} is not a multiple of 2^-{levels}", parent.1[i]);
            (f[i], n as u64)
        })
        .collect();
    k.sort_unstable();
    k
}

fn canonical(f: [usize; 3]) -> [usize; 3] {
    let r = (0..3).min_by_key(|&k| f[k]).unwrap_or(0);
    [f[r], f[(r + 1) % 3], f[(r + 2) % 3]]
}

/// The reference: Loop subdivision of the WHOLE mesh, written without the module's code, with
/// dense rows over all coarse vertices. Per level 0..=levels: each vertex's key, its limit row,
/// and the level's faces (canonical rotation).
struct RefLevel {
    index: HashMap<Key, usize>,
    pos: Vec<f64>,
    limit: Vec<f64>,
    faces: HashSet<[usize; 3]>,
}

fn reference(nc: usize, coarse: &[[u32; 3]], levels: u32) -> Vec<RefLevel> {
    let beta = |n: usize| {
        let c = 3.0 / 8.0 + 0.25 * (2.0 * std::f64::consts::PI / n as f64).cos();
        (5.0 / 8.0 - c * c) / n as f64
    };
    let mut faces: Vec<[usize; 3]> = coarse.iter().map(|f| f.map(|v| v as usize)).collect();
    let mut pos = vec![0.0; nc * nc];
    (0..nc).for_each(|v| pos[v * nc + v] = 1.0);
    let mut keys: Vec<Key> = (0..nc as u32).map(|v| vec![(v, 1)]).collect();
    let mut out = Vec::new();
    for level in 0..=levels {
        let n = keys.len();
        let mut edge_faces: HashMap<(usize, usize), Vec<usize>> = HashMap::new();
        for (fi, f) in faces.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                edge_faces.entry((a.min(b), a.max(b))).or_default().push(fi);
            }
        }
        let mut nbrs: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); n];
        let mut bnbrs: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); n];
        for (&(a, b), fs) in &edge_faces {
            nbrs[a].insert(b);
            nbrs[b].insert(a);
            if fs.len() == 1 {
                bnbrs[a].insert(b);
                bnbrs[b].insert(a);
            }
        }
        let combine = |pos: &[f64], terms: &[(usize, f64)], row: &mut [f64]| {
            for &(u, c) in terms {
                for (r, &p) in row.iter_mut().zip(&pos[u * nc..(u + 1) * nc]) {
                    *r += c * p;
                }
            }
        };
        let mut limit = vec![0.0; n * nc];
        for v in 0..n {
            let terms: Vec<(usize, f64)> = if bnbrs[v].is_empty() {
                let m = nbrs[v].len() as f64;
                let chi = 1.0 / (3.0 / (8.0 * beta(nbrs[v].len())) + m);
                std::iter::once((v, 1.0 - m * chi)).chain(nbrs[v].iter().map(|&u| (u, chi))).collect()
            } else {
                assert_eq!(bnbrs[v].len(), 2);
                std::iter::once((v, 2.0 / 3.0)).chain(bnbrs[v].iter().map(|&u| (u, 1.0 / 6.0))).collect()
            };
            combine(&pos, &terms, &mut limit[v * nc..(v + 1) * nc]);
        }
        out.push(RefLevel {
            index: keys.iter().enumerate().map(|(i, k)| (k.clone(), i)).collect(),
            pos: pos.clone(),
            limit,
            faces: faces.iter().map(|&f| canonical(f)).collect(),
        });
        if level == levels {
            break;
        }
        let mut edge_vertex: HashMap<(usize, usize), usize> = HashMap::new();
        let mut edge_list = Vec::new();
        for f in &faces {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                edge_vertex.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    edge_list.push((a.min(b), a.max(b)));
                    n + edge_list.len() - 1
                });
            }
        }
        let n2 = n + edge_list.len();
        let mut next = vec![0.0; n2 * nc];
        let mut next_keys = Vec::with_capacity(n2);
        for v in 0..n {
            let terms: Vec<(usize, f64)> = if bnbrs[v].is_empty() {
                let b = beta(nbrs[v].len());
                std::iter::once((v, 1.0 - nbrs[v].len() as f64 * b)).chain(nbrs[v].iter().map(|&u| (u, b))).collect()
            } else {
                std::iter::once((v, 0.75)).chain(bnbrs[v].iter().map(|&u| (u, 0.125))).collect()
            };
            combine(&pos, &terms, &mut next[v * nc..(v + 1) * nc]);
            next_keys.push(keys[v].iter().map(|&(i, w)| (i, 2 * w)).collect::<Key>());
        }
        for (e, &(a, b)) in edge_list.iter().enumerate() {
            let fs = &edge_faces[&(a, b)];
            let terms: Vec<(usize, f64)> = if fs.len() == 1 {
                vec![(a, 0.5), (b, 0.5)]
            } else {
                let opp = fs.iter().map(|&fi| faces[fi].into_iter().find(|&x| x != a && x != b).unwrap_or(a));
                [(a, 0.375), (b, 0.375)].into_iter().chain(opp.map(|o| (o, 0.125))).collect()
            };
            let v = n + e;
            combine(&pos, &terms, &mut next[v * nc..(v + 1) * nc]);
            let mut k: HashMap<u32, u64> = HashMap::new();
            for &(i, w) in keys[a].iter().chain(&keys[b]) {
                *k.entry(i).or_default() += w;
            }
            let mut k: Key = k.into_iter().collect();
            k.sort_unstable();
            next_keys.push(k);
        }
        let mut next_faces = Vec::with_capacity(faces.len() * 4);
        for f in &faces {
            let m = |a: usize, b: usize| edge_vertex[&(a.min(b), a.max(b))];
            let (m0, m1, m2) = (m(f[0], f[1]), m(f[1], f[2]), m(f[2], f[0]));
            next_faces.extend([[f[0], m0, m2], [m0, f[1], m1], [m2, m1, f[2]], [m0, m1, m2]]);
        }
        faces = next_faces;
        pos = next;
        keys = next_keys;
    }
    out
}

/// Compares `refine` on `region` at `levels` with the whole-mesh reference; returns the largest
/// weight difference. Also checks faces, parents and the lowest-face tie rule.
fn compare_with_reference(
    rest: &[DVec3],
    faces: &[[u32; 3]],
    region: &[u32],
    levels: u32,
    reference: &[RefLevel],
) -> f64 {
    let nc = rest.len();
    let r = refine(rest, faces, region, levels).expect("refine");
    let lv = &reference[levels as usize];
    assert_eq!(r.levels, levels);
    assert_eq!(r.faces.len(), region.len() << (2 * levels));
    assert_eq!(r.stencils.len(), r.parent.len());
    let mut worst = 0.0f64;
    let mut ref_ids = Vec::with_capacity(r.stencils.len());
    let mut seen = HashSet::new();
    for (s, &p) in r.stencils.iter().zip(&r.parent) {
        assert!(region.contains(&p.0), "parent face {} not in the region", p.0);
        assert!((p.1.element_sum() - 1.0).abs() == 0.0 && p.1.min_element() >= 0.0);
        let key = key_of(faces, p, levels);
        // The lowest region face whose closure holds the point.
        let lowest = region
            .iter()
            .copied()
            .filter(|&g| key.iter().all(|&(v, _)| faces[g as usize].contains(&v)))
            .min()
            .expect("a region face holds the vertex");
        assert_eq!(p.0, lowest, "tie rule");
        assert!(seen.insert(key.clone()), "vertex {key:?} twice");
        let id = *lv.index.get(&key).expect("vertex in the reference");
        ref_ids.push(id);
        assert!(s.vertices.windows(2).all(|w| w[0] < w[1]), "ascending, unique");
        assert!(s.weights.iter().all(|&w| w != 0.0), "no stored zeros");
        let mut dense = vec![0.0; nc];
        s.vertices.iter().zip(&s.weights).for_each(|(&v, &w)| dense[v as usize] = w);
        for (a, b) in dense.iter().zip(&lv.limit[id * nc..(id + 1) * nc]) {
            worst = worst.max((a - b).abs());
        }
    }
    for f in &r.faces {
        let g = canonical(f.map(|v| ref_ids[v as usize]));
        assert!(lv.faces.contains(&g), "face {f:?} is not a face of the whole-mesh subdivision");
    }
    worst
}

/// Test 1: on irregular closed and open meshes, the stencils of a region refined 1-4 levels
/// with one ring of neighbours equal those of subdividing the whole mesh.
#[test]
fn cut_is_exact() {
    let mut rng = Rng::new(7);
    let (mut sphere, mut sphere_faces) = icosphere(2);
    flip_edges(&mut sphere_faces, &mut rng, 40);
    sphere.iter_mut().for_each(|p| *p *= rng.range(0.9, 1.1));
    let valences: BTreeSet<usize> =
        (0..sphere.len() as u32).map(|v| sphere_faces.iter().filter(|f| f.contains(&v)).count()).collect();
    assert!(valences.len() >= 4, "irregular valences {valences:?}");
    let (mut plane, plane_faces) = grid(12, 0.1, Some(&mut rng));
    plane
        .iter_mut()
        .for_each(|p| *p += DVec3::new(rng.range(-0.02, 0.02), rng.range(-0.02, 0.02), rng.range(-0.05, 0.05)));
    let sphere_regions = vec![
        patch(&sphere_faces, 17, 9),
        vec![200],
        [patch(&sphere_faces, 3, 4), patch(&sphere_faces, 250, 5)].concat(),
        patch(&sphere_faces, 101, 30),
    ];
    // Quads (i, j) hold faces 2 (12 j + i) and +1: a corner, a border, the middle, a strip.
    let plane_regions = vec![
        patch(&plane_faces, 0, 6),
        patch(&plane_faces, 2 * 5 + 1, 10),
        patch(&plane_faces, 2 * (12 * 6 + 6), 12),
        (0..24).map(|i| 2 * 12 * 11 + i).collect(),
    ];
    let mut report = Vec::new();
    for (name, rest, faces, regions) in
        [("sphere", &sphere, &sphere_faces, &sphere_regions), ("grid", &plane, &plane_faces, &plane_regions)]
    {
        let reference = reference(rest.len(), faces, 4);
        for (ri, region) in regions.iter().enumerate() {
            let top = if region.len() > 20 { 3 } else { 4 };
            for levels in 0..=top {
                let worst = compare_with_reference(rest, faces, region, levels, &reference);
                assert!(worst <= 1e-14, "{name} region {ri} level {levels}: {worst:e}");
                report.push(worst);
            }
        }
    }
    println!(
        "cut vs whole mesh: {} cases, largest weight difference {:.1e}",
        report.len(),
        report.iter().fold(0.0f64, |a, &b| a.max(b))
    );
}

/// The safety net: with no ring of neighbours the cut reaches the region and is reported; with
/// more rings than one the result is the same.
#[test]
fn rings_are_enough_and_a_short_cut_is_detected() {
    let (rest, faces) = icosphere(2);
    let region = patch(&faces, 40, 12);
    let short = refine_with_rings(rest.len(), &faces, &region, 2, 0);
    assert!(matches!(short, Err(SubdivisionError::Incomplete { .. })), "{short:?}");
    let one = refine_with_rings(rest.len(), &faces, &region, 3, 1).expect("one ring");
    for rings in [2, 3] {
        let more = refine_with_rings(rest.len(), &faces, &region, 3, rings).expect("more rings");
        assert_eq!(one.faces, more.faces);
        assert_eq!(one.parent, more.parent);
        for (a, b) in one.stencils.iter().zip(&more.stencils) {
            assert_eq!(a.vertices, b.vertices);
            let d = a.weights.iter().zip(&b.weights).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
            assert!(d <= 1e-15, "{d:e}");
        }
    }
}

/// The flags behind the safety net are sound: wherever a level's vertex is flagged valid its
/// row is that of subdividing the whole mesh, and where it is also flagged complete its fan is
/// the whole mesh's; with no ring around the region some vertices are (rightly) not valid.
#[test]
fn validity_flags_are_sound() {
    let mut rng = Rng::new(31);
    let (rest, mut faces) = icosphere(2);
    flip_edges(&mut faces, &mut rng, 40);
    let nc = rest.len();
    let reference = reference(nc, &faces, 3);
    for rings in [0, 1] {
        for region in [patch(&faces, 12, 10), patch(&faces, 150, 3)] {
            let (sub_faces, sub_verts, mut lv) = neighbourhood(nc, &faces, &region, rings).expect("neighbourhood");
            let mut acc = Acc::new(sub_verts.len());
            let mut invalid = 0;
            for level in 1..=3u32 {
                lv = step(lv, region.len() as u32, &mut acc);
                let rl = &reference[level as usize];
                let mut keys: Vec<Option<Key>> = vec![None; lv.valid.len()];
                let mut fan = vec![0usize; lv.valid.len()];
                for ((f, &a), b) in lv.faces.iter().zip(&lv.anc).zip(&lv.bary) {
                    for k in 0..3 {
                        keys[f[k] as usize] = Some(key_of(&faces, (sub_faces[a as usize], b[k]), level));
                        fan[f[k] as usize] += 1;
                    }
                }
                let mut ref_fan: HashMap<usize, usize> = HashMap::new();
                rl.faces.iter().flatten().for_each(|&v| *ref_fan.entry(v).or_default() += 1);
                for v in 0..lv.valid.len() {
                    let id = rl.index[keys[v].as_ref().expect("every kept vertex is on a kept face")];
                    if !lv.valid[v] {
                        invalid += 1;
                        continue;
                    }
                    let mut dense = vec![0.0; nc];
                    let (idx, w) = lv.rows.row(v);
                    idx.iter().zip(w).for_each(|(&j, &w)| dense[sub_verts[j as usize] as usize] = w);
                    let d = dense
                        .iter()
                        .zip(&rl.pos[id * nc..(id + 1) * nc])
                        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
                    assert!(d <= 1e-14, "rings {rings} level {level}: vertex {v} flagged valid is off by {d:e}");
                    if lv.complete[v] {
                        assert_eq!(fan[v], ref_fan[&id], "rings {rings} level {level}: vertex {v} flagged complete");
                    }
                }
            }
            assert_eq!(invalid > 0, rings == 0, "rings {rings}: {invalid} vertices not valid");
        }
    }
}

// ---- Test 2: the quartic three-direction box spline, evaluated independently ----

fn cross2(a: DVec2, b: DVec2) -> f64 {
    a.x * b.y - a.y * b.x
}

/// The six triangles of the Courant hat M_111 centred at `c`, counter-clockwise, centre first.
fn hat_triangles(c: DVec2) -> [[DVec2; 3]; 6] {
    let d = [(1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (-1.0, 0.0), (-1.0, -1.0), (0.0, -1.0)].map(|(x, y)| DVec2::new(x, y));
    std::array::from_fn(|k| [c, c + d[k], c + d[(k + 1) % 6]])
}

/// The hat's value on triangle `t` (1 at its centre corner, 0 at the others, linear).
fn hat_on(t: &[DVec2; 3], y: DVec2) -> f64 {
    cross2(t[1] - y, t[2] - y) / cross2(t[1] - t[0], t[2] - t[0])
}

/// Sutherland-Hodgman: the part of convex polygon `poly` inside the counter-clockwise triangle `t`.
fn clip(mut poly: Vec<DVec2>, t: &[DVec2; 3]) -> Vec<DVec2> {
    for k in 0..3 {
        let (p, q) = (t[k], t[(k + 1) % 3]);
        let side = |x: DVec2| cross2(q - p, x - p);
        let mut out = Vec::with_capacity(poly.len() + 1);
        for i in 0..poly.len() {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            let (sa, sb) = (side(a), side(b));
            if sa >= 0.0 {
                out.push(a);
            }
            if (sa > 0.0 && sb < 0.0) || (sa < 0.0 && sb > 0.0) {
                out.push(a + (b - a) * (sa / (sa - sb)));
            }
        }
        poly = out;
        if poly.len() < 3 {
            return Vec::new();
        }
    }
    poly
}

/// The three-direction quartic box spline M_222 (directions (1,0), (0,1), (1,1), each twice) as
/// the convolution M_111 * M_111 of two Courant hats, integrated exactly: the product of two
/// linear functions over each convex overlap of their triangles, by the edge-midpoint rule
/// (exact for quadratics). Support: the hexagon around (2, 2).
fn box_spline(x: DVec2) -> f64 {
    if x.x <= 0.0 || x.y <= 0.0 || x.x >= 4.0 || x.y >= 4.0 || (x.x - x.y).abs() >= 2.0 {
        return 0.0;
    }
    let a = hat_triangles(DVec2::ONE);
    let b = hat_triangles(x - DVec2::ONE);
    let mut sum = 0.0;
    for ta in &a {
        for tb in &b {
            let poly = clip(ta.to_vec(), tb);
            for i in 1..poly.len().saturating_sub(1) {
                let (p0, p1, p2) = (poly[0], poly[i], poly[i + 1]);
                let area = 0.5 * cross2(p1 - p0, p2 - p0);
                let f = |y: DVec2| hat_on(ta, y) * hat_on(tb, y);
                sum += area / 3.0 * (f(0.5 * (p0 + p1)) + f(0.5 * (p1 + p2)) + f(0.5 * (p2 + p0)));
            }
        }
    }
    sum
}

/// The limit surface of a regular grid at lattice point `p`: sum of P_ij M_222(p - (i, j) + (2, 2)).
fn box_spline_surface(rest: &[DVec3], n: u32, p: DVec2) -> DVec3 {
    let mut s = DVec3::ZERO;
    let (i0, j0) = ((p.x - 2.0).floor().max(0.0) as u32, (p.y - 2.0).floor().max(0.0) as u32);
    for j in j0..=(j0 + 5).min(n) {
        for i in i0..=(i0 + 5).min(n) {
            let w = box_spline(p - DVec2::new(i as f64, j as f64) + DVec2::splat(2.0));
            s += w * rest[(j * (n + 1) + i) as usize];
        }
    }
    s
}

#[test]
fn box_spline_reference_is_sane() {
    let at = |x: f64, y: f64| box_spline(DVec2::new(x, y));
    assert!((at(2.0, 2.0) - 0.5).abs() < 1e-15);
    for (x, y) in [(3.0, 2.0), (1.0, 2.0), (2.0, 3.0), (2.0, 1.0), (3.0, 3.0), (1.0, 1.0)] {
        assert!((at(x, y) - 1.0 / 12.0).abs() < 1e-15, "({x}, {y}): {}", at(x, y));
    }
    assert_eq!(at(3.0, 1.0), 0.0);
    // Partition of unity at random points.
    let mut rng = Rng::new(3);
    for _ in 0..20 {
        let p = DVec2::new(rng.range(0.0, 1.0), rng.range(0.0, 1.0));
        let mut s = 0.0;
        for j in -3..=3 {
            for i in -3..=3 {
                s += box_spline(p - DVec2::new(i as f64, j as f64) + DVec2::splat(2.0));
            }
        }
        assert!((s - 1.0).abs() < 1e-14, "{s}");
    }
}

/// Test 2: on a regular part of a grid, refined vertices lie on the quartic box spline surface
/// of the control points, evaluated by `box_spline_surface` at each vertex's parametric point.
#[test]
fn limit_points_lie_on_the_box_spline() {
    let (n, h) = (12u32, 0.013);
    let (mut rest, faces) = grid(n, h, None);
    let mut rng = Rng::new(11);
    for p in &mut rest {
        let (x, y) = (p.x, p.y);
        p.z = 0.01 * (x / 0.03).sin() * (y / 0.05).cos() + 0.3 * x * y;
        p.x += rng.range(-0.2, 0.2) * h;
        p.y += rng.range(-0.2, 0.2) * h;
    }
    // Quads 4..8 x 4..8: every vertex within a ring of them is interior, of valence 6.
    let region: Vec<u32> =
        (4..8).flat_map(|j| (4..8).flat_map(move |i| [2 * (j * n + i), 2 * (j * n + i) + 1])).collect();
    let lattice = |v: u32| DVec2::new((v % (n + 1)) as f64, (v / (n + 1)) as f64);
    let mut worst = 0.0f64;
    for levels in 1..=4 {
        let r = refine(&rest, &faces, &region, levels).expect("refine");
        let mut y = Vec::new();
        apply_all(&r.stencils, &rest, &mut y);
        for (q, &(f, b)) in y.iter().zip(&r.parent) {
            let c = faces[f as usize].map(lattice);
            let p = b.x * c[0] + b.y * c[1] + b.z * c[2];
            worst = worst.max(q.distance(box_spline_surface(&rest, n, p)) / h);
        }
    }
    println!("refined points vs box spline surface: largest distance {worst:.1e} mesh sizes");
    assert!(worst <= 1e-12, "{worst:e}");
}

/// Test 3: affine invariance.
#[test]
fn stencils_are_affine() {
    let mut rng = Rng::new(5);
    let (mut rest, mut faces) = icosphere(2);
    flip_edges(&mut faces, &mut rng, 30);
    rest.iter_mut().for_each(|p| *p *= rng.range(0.9, 1.1));
    let region = patch(&faces, 60, 20);
    let r = refine(&rest, &faces, &region, 4).expect("refine");
    let sum_err = r.stencils.iter().map(|s| (s.weights.iter().sum::<f64>() - 1.0).abs()).fold(0.0, f64::max);
    assert!(sum_err <= 1e-14, "{sum_err:e}");
    // A rigid motion of the coarse mesh moves the refined points by the same motion.
    let q = DQuat::from_xyzw(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0))
        .normalize();
    let t = DVec3::new(0.3, -1.2, 2.5);
    let moved: Vec<DVec3> = rest.iter().map(|&p| q * p + t).collect();
    let (mut y, mut ym) = (Vec::new(), Vec::new());
    apply_all(&r.stencils, &rest, &mut y);
    apply_all(&r.stencils, &moved, &mut ym);
    let rigid = y.iter().zip(&ym).map(|(&a, &b)| (q * a + t).distance(b)).fold(0.0, f64::max);
    assert!(rigid <= 1e-12, "{rigid:e}");
    // A planar region of a planar mesh stays in its plane.
    let (mut flat, flat_faces) = grid(10, 0.05, Some(&mut rng));
    let tilt = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 0.7);
    for p in &mut flat {
        *p = tilt * (*p + DVec3::new(rng.range(-0.01, 0.01), rng.range(-0.01, 0.01), 0.0)) + t;
    }
    let normal = tilt * DVec3::Z;
    let region = patch(&flat_faces, 2 * (10 * 4 + 4), 25);
    let r = refine(&flat, &flat_faces, &region, 3).expect("refine");
    apply_all(&r.stencils, &flat, &mut y);
    let off = y.iter().map(|&p| (p - t).dot(normal).abs()).fold(0.0, f64::max);
    assert!(off <= 1e-12, "{off:e}");
    println!("affine: weight sums within {sum_err:.1e}, rigid motion {rigid:.1e}, off the plane {off:.1e}");
}

/// The largest angle between the normals of two faces sharing an edge.
fn max_dihedral(p: &[DVec3], faces: &[[u32; 3]]) -> f64 {
    let normal =
        |f: &[u32; 3]| (p[f[1] as usize] - p[f[0] as usize]).cross(p[f[2] as usize] - p[f[0] as usize]).normalize();
    let mut by_edge: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (fi, f) in faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            by_edge.entry((a.min(b), a.max(b))).or_default().push(fi);
        }
    }
    by_edge
        .values()
        .filter(|fs| fs.len() == 2)
        .map(|fs| normal(&faces[fs[0]]).dot(normal(&faces[fs[1]])).clamp(-1.0, 1.0).acos())
        .fold(0.0, f64::max)
}

/// A forehead-like open cylinder: radius 60 mm, rows of `around` vertices 12.5 mm apart, every
/// other row turned by half a step (near-equilateral triangles of 12-17 mm with the jitter).
fn forehead(around: u32, rows: u32, rng: &mut Rng) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let radius = 0.060;
    let mut p = Vec::new();
    for j in 0..rows {
        for i in 0..around {
            let a = (i as f64 + 0.5 * (j % 2) as f64 + rng.range(-0.08, 0.08)) * std::f64::consts::TAU / around as f64;
            let z = j as f64 * 0.0125 + rng.range(-0.001, 0.001);
            p.push(DVec3::new(radius * a.cos(), radius * a.sin(), z));
        }
    }
    let v = |i: u32, j: u32| j * around + i % around;
    let mut f = Vec::new();
    for j in 0..rows - 1 {
        for i in 0..around {
            if j % 2 == 0 {
                f.push([v(i, j), v(i + 1, j), v(i, j + 1)]);
                f.push([v(i + 1, j), v(i + 1, j + 1), v(i, j + 1)]);
            } else {
                f.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
                f.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            }
        }
    }
    (p, f)
}

/// The forehead case: 120 faces of the cylinder (10 columns of quads x 6 rows, away from its ends).
fn forehead_region(around: u32) -> Vec<u32> {
    (2..8).flat_map(|j| (3..13).flat_map(move |i| [2 * (j * around + i), 2 * (j * around + i) + 1])).collect()
}

/// Test 4a: on an icosphere (`splits` times split icosahedron, unit radius), refined limit points.
fn sphere_convergence(splits: u32) {
    let (rest, faces) = icosphere(splits);
    let region = patch(&faces, 0, 40);
    let sagitta = region
        .iter()
        .map(|&fi| {
            let [a, b, c] = faces[fi as usize].map(|v| rest[v as usize]);
            1.0 - (b - a).cross(c - a).normalize().dot(a).abs()
        })
        .fold(0.0, f64::max);
    let r = refine(&rest, &faces, &region, 4).expect("refine");
    let mut y = Vec::new();
    apply_all(&r.stencils, &rest, &mut y);
    let off = |y: &[DVec3]| y.iter().map(|p| (1.0 - p.length()).abs()).fold(0.0, f64::max);
    let raw = off(&y);
    // Loop approximates: with the control points on the sphere the limit surface lies inside it.
    // Control points whose limit points are on the sphere (radial fixed point on the coarse
    // vertices' limit stencils) give the surface the sphere's own size.
    let all: Vec<u32> = (0..faces.len() as u32).collect();
    let coarse_limit = refine(&rest, &faces, &all, 0).expect("limit stencils");
    let mut fitted = rest.clone();
    let mut at = Vec::new();
    for _ in 0..40 {
        apply_all(&coarse_limit.stencils, &fitted, &mut at);
        for (s, q) in coarse_limit.stencils.iter().zip(&at) {
            let v = s.vertices[s.weights.iter().enumerate().fold(0, |m, (i, &w)| if w > s.weights[m] { i } else { m })];
            fitted[v as usize] /= q.length();
        }
    }
    apply_all(&r.stencils, &fitted, &mut y);
    let fit = off(&y);
    println!(
        "sphere {}: coarse sagitta {sagitta:.2e}; refined limit points off the unit sphere: {raw:.2e} with the control \
         points on it (Loop shrinks), {fit:.2e} ({:.0}x below the sagitta) with control points fitted",
        faces.len(),
        sagitta / fit
    );
    assert!(raw < 2.0 * sagitta, "{raw:e}");
    assert!(fit < sagitta / 10.0, "{fit:e} vs sagitta {sagitta:e}");
}

/// Test 4: convergence on a sphere and smoothness on a forehead-like cylinder.
#[test]
fn refined_surface_is_smooth() {
    for splits in [2, 3] {
        sphere_convergence(splits);
    }

    let mut rng = Rng::new(13);
    let (rest, faces) = forehead(26, 10, &mut rng);
    let region = forehead_region(26);
    assert_eq!(region.len(), 120);
    let edges: Vec<f64> = region
        .iter()
        .flat_map(|&fi| {
            let f = faces[fi as usize];
            (0..3).map(move |k| (f[k], f[(k + 1) % 3]))
        })
        .map(|(a, b)| rest[a as usize].distance(rest[b as usize]))
        .collect();
    let (emin, emax) = edges.iter().fold((f64::MAX, 0.0f64), |(lo, hi), &e| (lo.min(e), hi.max(e)));
    assert!(emin > 0.011 && emax < 0.018, "{emin} {emax}");
    let levels = levels_for(&rest, &faces, &region, 0.0012).expect("levels");
    assert_eq!(levels, 4);
    let r = refine(&rest, &faces, &region, levels).expect("refine");
    let mut y = Vec::new();
    apply_all(&r.stencils, &rest, &mut y);
    let coarse_faces: Vec<[u32; 3]> = region.iter().map(|&fi| faces[fi as usize]).collect();
    let coarse = max_dihedral(&rest, &coarse_faces);
    let fine = max_dihedral(&y, &r.faces);
    // How far inside the body's vertices (on the 60 mm cylinder) the limit surface lies, against
    // the coarse facets' sagitta.
    let radial = |p: DVec3| 0.060 - p.truncate().length();
    let sagitta = coarse_faces
        .iter()
        .map(|f| radial((rest[f[0] as usize] + rest[f[1] as usize] + rest[f[2] as usize]) / 3.0))
        .fold(0.0, f64::max);
    let inside = y.iter().map(|&p| radial(p)).fold(0.0, f64::max);
    println!(
        "forehead: edges {:.1}..{:.1} mm, {levels} levels, {} faces; largest dihedral angle coarse {:.2} deg, \
         refined {:.3} deg; refined points up to {:.2} mm inside the cylinder (coarse facet centroids {:.2} mm)",
        emin * 1e3,
        emax * 1e3,
        r.faces.len(),
        coarse.to_degrees(),
        fine.to_degrees(),
        inside * 1e3,
        sagitta * 1e3
    );
    assert!(fine < coarse / 8.0, "{fine} vs {coarse}");
    assert!(inside > 0.0 && inside < 2.0 * sagitta, "{inside} vs {sagitta}");
}

/// Test 5: at a border, limit points lie on the border's cubic B-spline curve: a straight border
/// stays straight; a curved one matches the curve evaluated here.
#[test]
fn border_follows_the_b_spline() {
    let n = 10u32;
    let mut rng = Rng::new(17);
    let (mut rest, faces) = grid(n, 0.01, Some(&mut rng));
    for (v, p) in rest.iter_mut().enumerate() {
        let j = v as u32 / (n + 1);
        p.x += rng.range(-0.003, 0.003);
        if j > 0 {
            p.y += rng.range(-0.003, 0.003);
            p.z = rng.range(-0.004, 0.004);
        }
    }
    // The faces of quads 3..7 of the bottom row and the row above: the region touches the border.
    let region: Vec<u32> =
        (0..2).flat_map(|j| (3..7).flat_map(move |i| [2 * (j * n + i), 2 * (j * n + i) + 1])).collect();
    let border = |r: &Refinement| -> Vec<(usize, u32, f64)> {
        // Refined vertices on the bottom row: (index, left coarse vertex i, parameter u in [0, 1)).
        r.parent
            .iter()
            .enumerate()
            .filter_map(|(k, &(f, b))| {
                let f = faces[f as usize];
                let on: Vec<(u32, f64)> = (0..3).filter(|&c| b[c] != 0.0).map(|c| (f[c], b[c])).collect();
                if !on.iter().all(|&(v, _)| v <= n) {
                    return None;
                }
                let t: f64 = on.iter().map(|&(v, w)| v as f64 * w).sum();
                Some((k, t.floor() as u32, t - t.floor()))
            })
            .collect()
    };
    let r = refine(&rest, &faces, &region, 3).expect("refine");
    let mut y = Vec::new();
    apply_all(&r.stencils, &rest, &mut y);
    let on_border = border(&r);
    assert_eq!(on_border.len(), 4 * 8 + 1);
    let straight = on_border.iter().map(|&(k, _, _)| y[k].y.abs().max(y[k].z.abs())).fold(0.0, f64::max);
    assert!(straight <= 1e-15, "{straight:e}");
    // Bend the border (z and y along a curve) and compare with the uniform cubic B-spline.
    for p in &mut rest[..=n as usize] {
        p.y = 0.2 * p.x * p.x;
        p.z = 0.01 * (p.x / 0.02).sin();
    }
    apply_all(&r.stencils, &rest, &mut y);
    let mut worst = 0.0f64;
    for &(k, i, u) in &on_border {
        let c = |d: i64| rest[(i as i64 + d) as usize];
        let b = [
            (1.0 - u).powi(3),
            3.0 * u.powi(3) - 6.0 * u * u + 4.0,
            -3.0 * u.powi(3) + 3.0 * u * u + 3.0 * u + 1.0,
            u.powi(3),
        ];
        let curve = (b[0] * c(-1) + b[1] * c(0) + b[2] * c(1) + b[3] * c(2)) / 6.0;
        worst = worst.max(curve.distance(y[k]));
    }
    println!("border: straight border off its line {straight:.1e}; curved border vs B-spline {worst:.1e}");
    assert!(worst <= 1e-15, "{worst:e}");
}

/// Test 6: bad input gives errors naming the element.
#[test]
fn bad_input_is_reported() {
    let (rest, faces) = grid(4, 1.0, None);
    assert_eq!(refine(&rest, &faces, &[], 1), Err(SubdivisionError::EmptyRegion));
    assert_eq!(
        refine(&rest, &faces, &[3, 99], 1),
        Err(SubdivisionError::RegionFaceOutOfRange { index: 1, face: 99, count: 32 })
    );
    assert_eq!(refine(&rest, &faces, &[3, 4, 3], 1), Err(SubdivisionError::DuplicateRegionFace { face: 3 }));
    assert_eq!(refine(&rest, &faces, &[3], 9), Err(SubdivisionError::TooManyLevels { levels: 9, max: MAX_LEVELS }));
    // A third face on edge (6, 12), inside the region.
    let mut extra_rest = rest.clone();
    extra_rest.push(DVec3::new(1.5, 1.5, 1.0));
    let mut extra = faces.clone();
    extra.push([6, 12, 25]);
    assert_eq!(
        refine(&extra_rest, &extra, &[10, 11], 1),
        Err(SubdivisionError::NonManifoldEdge { a: 6, b: 12, count: 3 })
    );
    // Two tetrahedra sharing vertex 0: two closed fans around it.
    let tets = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], [0, 5, 4], [0, 4, 6], [0, 6, 5], [4, 5, 6]];
    let tet_rest = vec![DVec3::ZERO; 7];
    assert_eq!(refine(&tet_rest, &tets, &[0], 1), Err(SubdivisionError::NonManifoldVertex { vertex: 0 }));
    assert!(refine(&tet_rest[..4], &tets[..4], &[3], 2).is_ok(), "one tetrahedron is fine");
    // A bowtie: two triangles meeting at a vertex.
    let bowtie = vec![[0, 1, 2], [0, 3, 4]];
    assert_eq!(refine(&tet_rest, &bowtie, &[1], 1), Err(SubdivisionError::NonManifoldVertex { vertex: 0 }));
    let mut bad = faces.clone();
    bad[20] = [1, 2, 40];
    assert_eq!(refine(&rest, &bad, &[0], 1), Err(SubdivisionError::BadVertex { face: 20, vertex: 40, count: 25 }));
    bad[20] = [1, 2, 1];
    assert_eq!(refine(&rest, &bad, &[0], 1), Err(SubdivisionError::DegenerateFace { face: 20 }));
    // levels_for: longest region edge sqrt(2).
    assert_eq!(levels_for(&rest, &faces, &[0], 2.0), Ok(0));
    assert_eq!(levels_for(&rest, &faces, &[0], 1.0), Ok(1));
    assert_eq!(levels_for(&rest, &faces, &[0], 0.7), Ok(2));
    assert_eq!(levels_for(&rest, &faces, &[0], 2f64.sqrt() / 256.0), Ok(8));
    assert!(matches!(levels_for(&rest, &faces, &[0], 0.005), Err(SubdivisionError::TargetTooFine { max: 8, .. })));
    assert!(matches!(levels_for(&rest, &faces, &[0], 0.0), Err(SubdivisionError::BadTarget { .. })));
    assert!(matches!(levels_for(&rest, &faces, &[0], f64::NAN), Err(SubdivisionError::BadTarget { .. })));
    assert_eq!(levels_for(&rest, &faces, &[], 1.0), Err(SubdivisionError::EmptyRegion));
    let mut nan = rest.clone();
    nan[1].x = f64::NAN;
    assert_eq!(levels_for(&nan, &faces, &[0], 1.0), Err(SubdivisionError::NonFinite { vertex: 1 }));
    // Apply: a missing coarse vertex gives NaN, not a panic.
    let s = Stencil { vertices: vec![0, 7], weights: vec![0.5, 0.5] };
    assert!(s.apply(&rest[..3]).is_nan());
}

/// `estimate` bounds the real sizes; faces are exact.
#[test]
fn estimate_bounds_the_sizes() {
    let mut rng = Rng::new(23);
    let (rest, faces) = forehead(26, 10, &mut rng);
    for (region, levels) in [(forehead_region(26), 3), (vec![5, 77, 130], 4), (vec![9], 0)] {
        let r = refine(&rest, &faces, &region, levels).expect("refine");
        let (v, f) = estimate(region.len(), levels);
        assert_eq!(f, r.faces.len());
        assert!(v >= r.stencils.len() && r.stencils.len() >= f / 2, "{v} {}", r.stencils.len());
    }
    assert_eq!(estimate(usize::MAX, 8).1, usize::MAX);
}

/// Test 7: the forehead case (120 faces, 4 levels, 30720 faces) is fast.
#[test]
fn forehead_case_is_fast() {
    let mut rng = Rng::new(29);
    let (rest, faces) = forehead(26, 10, &mut rng);
    let region = forehead_region(26);
    let start = std::time::Instant::now();
    let r = refine(&rest, &faces, &region, 4).expect("refine");
    let seconds = start.elapsed().as_secs_f64();
    let entries: usize = r.stencils.iter().map(|s| s.vertices.len()).sum();
    println!(
        "forehead: 120 faces x 4 levels -> {} faces, {} vertices, {:.1} coarse vertices per stencil, {:.3} s",
        r.faces.len(),
        r.stencils.len(),
        entries as f64 / r.stencils.len() as f64,
        seconds
    );
    assert_eq!(r.faces.len(), 120 * 256);
    assert!(seconds < 2.0, "{seconds} s");
}
