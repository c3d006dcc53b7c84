use glam::{DQuat, DVec2, DVec3};

use super::*;

use crate::mesh::test_rng::Rng;

/// A test asset: welded rest positions (m), faces, per-corner UVs.
struct Asset {
    rest: Vec<DVec3>,
    faces: Vec<[u32; 3]>,
    uv: Vec<[DVec2; 3]>,
}

const RADIUS: f64 = 0.05;
const LENGTH: f64 = 0.1;
const AROUND: usize = 48;
const ALONG: usize = 12;

/// A cylinder (radius 50 mm, length 100 mm, `AROUND` x `ALONG` quads split along a random
/// diagonal, outward normals) whose UVs are its development (the prism's strips of chord width,
/// unrolled from angle 0) times `uv_per_metre` plus `shift`. Columns in `cuts` (besides column 0,
/// always a seam) start a new strip `gap` further along u. Also the seam edges expected.
fn cylinder(uv_per_metre: f64, shift: DVec2, cuts: &[usize], gap: f64, seed: u64) -> (Asset, Vec<[u32; 2]>) {
    let mut rng = Rng::new(seed);
    let at = |k: usize, j: usize| (j * AROUND + k % AROUND) as u32;
    let mut rest = Vec::new();
    for j in 0..=ALONG {
        for k in 0..AROUND {
            let theta = std::f64::consts::TAU * k as f64 / AROUND as f64;
            let z = -0.5 * LENGTH + LENGTH * j as f64 / ALONG as f64;
            rest.push(DVec3::new(RADIUS * theta.cos(), RADIUS * theta.sin(), z));
        }
    }
    let chord = 2.0 * RADIUS * (std::f64::consts::PI / AROUND as f64).sin();
    let (mut faces, mut uv) = (Vec::new(), Vec::new());
    for j in 0..ALONG {
        for k in 0..AROUND {
            let offset = gap * cuts.iter().filter(|&&c| c != 0 && c <= k).count() as f64;
            let dev = |kk: usize, jj: usize| {
                let z = -0.5 * LENGTH + LENGTH * jj as f64 / ALONG as f64;
                DVec2::new(kk as f64 * chord + offset, z + 0.5 * LENGTH) * uv_per_metre + shift
            };
            let (a, b, c, d) = ((k, j), (k + 1, j), (k + 1, j + 1), (k, j + 1));
            let tris = if rng.coin() { [[a, b, c], [a, c, d]] } else { [[a, b, d], [b, c, d]] };
            for t in tris {
                faces.push(t.map(|(kk, jj)| at(kk, jj)));
                uv.push(t.map(|(kk, jj)| dev(kk, jj)));
            }
        }
    }
    let mut columns: Vec<usize> = cuts.to_vec();
    columns.push(0);
    columns.sort_unstable();
    columns.dedup();
    let mut seams: Vec<[u32; 2]> =
        columns.iter().flat_map(|&c| (0..ALONG).map(move |j| [at(c, j), at(c, j + 1)])).collect();
    seams.iter_mut().for_each(|e| e.sort_unstable());
    seams.sort_unstable();
    (Asset { rest, faces, uv }, seams)
}

/// A jittered grid over [0, w] x [0, h] (in its own plane: `local`), rotated and moved into 3D
/// by a seeded random rigid motion; vertices on x = `keep_x` keep that x. Split quads.
fn plane(w: f64, h: f64, nx: usize, ny: usize, keep_x: f64, seed: u64) -> (Vec<DVec2>, Vec<DVec3>, Vec<[u32; 3]>) {
    let mut rng = Rng::new(seed);
    let (dx, dy) = (w / nx as f64, h / ny as f64);
    let mut local = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            let mut p = DVec2::new(i as f64 * dx, j as f64 * dy);
            let inner_x = i > 0 && i < nx && (p.x - keep_x).abs() > 1e-12;
            if inner_x {
                p.x += rng.range(-0.25, 0.25) * dx;
            }
            if j > 0 && j < ny {
                p.y += rng.range(-0.25, 0.25) * dy;
            }
            local.push(p);
        }
    }
    let axis = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)).normalize();
    let rot = DQuat::from_axis_angle(axis, rng.range(0.0, std::f64::consts::TAU));
    let offset = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
    let rest = local.iter().map(|p| rot * p.extend(0.0) + offset).collect();
    let at = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let mut faces = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            faces.extend(if rng.coin() { [[a, b, c], [a, c, d]] } else { [[a, b, d], [b, c, d]] });
        }
    }
    (local, rest, faces)
}

/// A spherical cap (radius 100 mm, polar angle up to `max_deg`), pole up, outward normals:
/// a pole and `rings` rings of `segments` vertices, quads split along a random diagonal.
fn cap(rings: usize, segments: usize, max_deg: f64, seed: u64) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let r = 0.1;
    let mut rng = Rng::new(seed);
    let mut rest = vec![DVec3::new(0.0, 0.0, r)];
    for i in 1..=rings {
        let theta = max_deg.to_radians() * i as f64 / rings as f64;
        for k in 0..segments {
            let phi = std::f64::consts::TAU * (k as f64 + 0.5 * i as f64) / segments as f64;
            rest.push(r * DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()));
        }
    }
    let at = |i: usize, k: usize| (1 + (i - 1) * segments + k % segments) as u32;
    let mut faces = Vec::new();
    for k in 0..segments {
        faces.push([0, at(1, k), at(1, k + 1)]);
    }
    for i in 1..rings {
        for k in 0..segments {
            let (a, b, c, d) = (at(i, k), at(i, k + 1), at(i + 1, k + 1), at(i + 1, k));
            faces.extend(if rng.coin() { [[a, d, c], [a, c, b]] } else { [[a, d, b], [b, d, c]] });
        }
    }
    (rest, faces)
}

/// The largest relative difference between each face edge's rest length and its length in the
/// per-corner coordinates, over `set` (all faces when None).
fn edge_error(rest: &[DVec3], faces: &[[u32; 3]], corners: &[[DVec2; 3]], set: Option<&[u32]>) -> f64 {
    let all: Vec<u32> = (0..faces.len() as u32).collect();
    let mut worst = 0.0f64;
    for &f in set.unwrap_or(&all) {
        let (t, c) = (faces[f as usize], corners[f as usize]);
        for k in 0..3 {
            let l3 = rest[t[k] as usize].distance(rest[t[(k + 1) % 3] as usize]);
            let l2 = c[k].distance(c[(k + 1) % 3]);
            worst = worst.max((l2 - l3).abs() / l3);
        }
    }
    worst
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

// ------------------------------------------------------------------------ 1. the cylinder

#[test]
fn cylinder_is_one_island_at_scale_1000_and_length_true() {
    // UV = development / 1000, shifted so that it starts at (0, 0): in [0, 3.2e-4] x [0, 1e-4].
    let (a, seams) = cylinder(1e-3, DVec2::ZERO, &[], 0.0, 1);
    let isl = islands(&a.faces, &a.uv);
    assert_eq!(isl.count, 1);
    assert_eq!(isl.seams, seams, "the seam is exactly the column at angle 0");
    assert!(isl.of_face.iter().all(|&i| i == 0));
    let (corners, reports) = length_true(&a.rest, &a.faces, &a.uv, &isl).unwrap();
    let r = reports[0];
    let edges = edge_error(&a.rest, &a.faces, &corners, None);
    println!(
        "cylinder: scale {:.15} (rel err {:.1e}), stretch mean - 1 {:.1e}, max - 1 {:.1e}, area ratio [{:.1e}, {:.1e}] \
         from 1, edge lengths rel err {edges:.1e}",
        r.scale,
        rel(r.scale, 1000.0),
        r.stretch_mean - 1.0,
        r.stretch_max - 1.0,
        r.area_ratio_min - 1.0,
        r.area_ratio_max - 1.0
    );
    assert_eq!((r.faces, r.first_face, r.flipped, r.degenerate, r.mirrored), (a.faces.len(), 0, 0, 0, false));
    assert!(rel(r.scale, 1000.0) < 1e-12);
    assert!((r.stretch_mean - 1.0).abs() < 1e-9 && (r.stretch_max - 1.0).abs() < 1e-9);
    assert!((r.area_ratio_min - 1.0).abs() < 1e-9 && (r.area_ratio_max - 1.0).abs() < 1e-9);
    assert!(rel(r.area_3d, 1e6 * r.area_uv) < 1e-12);
    assert!(edges < 1e-9, "{edges}");
    // The area-weighted UV centroid lands at the origin.
    let centre: DVec2 = corners.iter().flatten().sum::<DVec2>() / (3 * corners.len()) as f64;
    assert!(centre.length() < 1e-12, "{centre}");
}

#[test]
fn cylinder_cut_twice_is_two_islands_split_at_the_cuts() {
    let (a, seams) = cylinder(1e-3, DVec2::ZERO, &[AROUND / 2], 1e-5, 2);
    let isl = islands(&a.faces, &a.uv);
    assert_eq!(isl.count, 2);
    assert_eq!(isl.seams, seams);
    // Faces are made column by column, two per quad: the first half of each ring is island 0.
    for (f, &i) in isl.of_face.iter().enumerate() {
        let column = (f / 2) % AROUND;
        assert_eq!(i, u32::from(column >= AROUND / 2), "face {f}");
    }
    let (corners, reports) = length_true(&a.rest, &a.faces, &a.uv, &isl).unwrap();
    assert!(reports.iter().all(|r| rel(r.scale, 1000.0) < 1e-12 && (r.stretch_max - 1.0).abs() < 1e-9));
    assert!(edge_error(&a.rest, &a.faces, &corners, None) < 1e-9);
}

#[test]
fn near_equal_uvs_join_and_distinct_ones_split() {
    let (mut a, seams) = cylinder(1e-3, DVec2::ZERO, &[], 0.0, 3);
    // The extent is 2 pi r / 1000 ~ 3.1e-4: nudges of 1e-17 (3e-14 of it) still agree, a nudge of
    // 1e-15 (3e-12 of it) opens a seam along the edges of that corner's vertex.
    a.uv[100][0].x += 1e-17;
    assert_eq!(islands(&a.faces, &a.uv).seams, seams);
    a.uv[100][0].x += 1e-15;
    let cut = islands(&a.faces, &a.uv);
    assert!(cut.seams.len() > seams.len());
    let v = a.faces[100][0];
    assert!(cut.seams.iter().filter(|e| !seams.contains(e)).all(|e| e.contains(&v)));
}

// ---------------------------------------------------------------- 2. scale invariance

#[test]
fn uvs_scaled_by_1000_give_the_same_length_true_coordinates() {
    let (a, _) = cylinder(1e-3, DVec2::ZERO, &[], 0.0, 4);
    let b_uv: Vec<[DVec2; 3]> = a.uv.iter().map(|c| c.map(|p| p * 1000.0)).collect();
    let (ca, ra) = length_true(&a.rest, &a.faces, &a.uv, &islands(&a.faces, &a.uv)).unwrap();
    let (cb, rb) = length_true(&a.rest, &a.faces, &b_uv, &islands(&a.faces, &b_uv)).unwrap();
    let size = ca.iter().flatten().map(|p| p.abs().max_element()).fold(0.0, f64::max);
    let diff =
        ca.iter().flatten().zip(cb.iter().flatten()).map(|(p, q)| (*p - *q).abs().max_element()).fold(0.0, f64::max);
    let same = ca.iter().flatten().zip(cb.iter().flatten()).filter(|(p, q)| p == q).count();
    println!(
        "UVs x 1000: max difference {:.1e} of the extent ({same} of {} corners bit-identical), scale ratio - 1e-3 \
         {:.1e}",
        diff / size,
        3 * ca.len(),
        rb[0].scale / ra[0].scale * 1000.0 - 1.0
    );
    assert!(diff <= 1e-15 * size, "{}", diff / size);
    assert!(rel(rb[0].scale * 1000.0, ra[0].scale) < 1e-15);
    assert!((ra[0].stretch_mean - rb[0].stretch_mean).abs() < 1e-15);

    // With an atlas offset the inputs themselves only hold ~1e-16 x the offset: the outputs agree
    // to that, not better (a translation changes nothing else).
    let offset = DVec2::new(0.25, 0.5);
    let c_uv: Vec<[DVec2; 3]> = a.uv.iter().map(|c| c.map(|p| p + offset)).collect();
    let (cc, _) = length_true(&a.rest, &a.faces, &c_uv, &islands(&a.faces, &c_uv)).unwrap();
    let shifted =
        ca.iter().flatten().zip(cc.iter().flatten()).map(|(p, q)| (*p - *q).abs().max_element()).fold(0.0, f64::max);
    let bound = 4.0 * f64::EPSILON * offset.max_element() * ra[0].scale;
    println!("UVs + (0.25, 0.5): max difference {:.1e} of the extent (bound {:.1e})", shifted / size, bound / size);
    assert!(shifted <= bound);
}

// ------------------------------------------------------------ 3. two texel densities

/// A flat 200 x 100 mm sheet cut at x = 100 mm: left half at 0.5 m per UV unit placed at
/// (0.05, 0.05), right half at 0.25 m per UV unit placed at (0.5, 0.2).
fn two_densities(seed: u64) -> (Asset, Vec<DVec2>) {
    let (local, rest, faces) = plane(0.2, 0.1, 16, 8, 0.1, seed);
    let uv = faces
        .iter()
        .map(|t| {
            let left = t.iter().all(|&v| local[v as usize].x <= 0.1 + 1e-12);
            t.map(|v| {
                let p = local[v as usize];
                if left {
                    p / 0.5 + DVec2::splat(0.05)
                } else {
                    (p - DVec2::new(0.1, 0.0)) / 0.25 + DVec2::new(0.5, 0.2)
                }
            })
        })
        .collect();
    (Asset { rest, faces, uv }, local)
}

#[test]
fn two_islands_at_different_texel_densities_get_their_own_scales() {
    let (a, local) = two_densities(5);
    let isl = islands(&a.faces, &a.uv);
    assert_eq!(isl.count, 2);
    // The seam is the column x = 0.1, all of it and nothing else.
    let on_cut = |v: u32| (local[v as usize].x - 0.1).abs() < 1e-12;
    assert_eq!(isl.seams.len(), 8);
    assert!(isl.seams.iter().all(|e| on_cut(e[0]) && on_cut(e[1])));
    let (corners, reports) = length_true(&a.rest, &a.faces, &a.uv, &isl).unwrap();
    let left = isl.of_face[0] as usize;
    let (sl, sr) = (reports[left].scale, reports[1 - left].scale);
    let edges = edge_error(&a.rest, &a.faces, &corners, None);
    println!(
        "two densities: scales {sl:.15} and {sr:.15} (rel err {:.1e}, {:.1e}), stretch max - 1 {:.1e} and {:.1e}, \
         edge lengths rel err {edges:.1e}",
        rel(sl, 0.5),
        rel(sr, 0.25),
        reports[left].stretch_max - 1.0,
        reports[1 - left].stretch_max - 1.0
    );
    assert!(rel(sl, 0.5) < 1e-12 && rel(sr, 0.25) < 1e-12);
    assert!(reports.iter().all(|r| (r.stretch_max - 1.0).abs() < 1e-9 && r.flipped == 0 && !r.mirrored));
    assert_eq!(reports.iter().map(|r| r.faces).sum::<usize>(), a.faces.len());
    assert!(edges < 1e-9, "{edges}");
}

#[test]
fn a_mirrored_island_is_mirrored_back_and_a_flipped_face_counted() {
    let (mut a, _) = two_densities(6);
    let isl = islands(&a.faces, &a.uv);
    let right = 1 - isl.of_face[0];
    for (f, c) in a.uv.iter_mut().enumerate() {
        if isl.of_face[f] == right {
            c.iter_mut().for_each(|p| p.x = 2.0 - p.x);
        }
    }
    let (corners, reports) = length_true(&a.rest, &a.faces, &a.uv, &isl).unwrap();
    assert!(reports[right as usize].mirrored && !reports[1 - right as usize].mirrored);
    assert!(edge_error(&a.rest, &a.faces, &corners, None) < 1e-9);
    // Every material triangle now winds as its face: positive signed area.
    assert!(corners.iter().all(|q| (q[1] - q[0]).perp_dot(q[2] - q[0]) > 0.0));
    // An interior vertex's UV moved (in all its corners) past its neighbours: the faces folded
    // over are flipped, and counted.
    let isl = islands(&a.faces, &a.uv);
    let left = isl.of_face[0];
    let v = a.faces[isl.faces(left)[40] as usize][0];
    for (t, c) in a.faces.iter().zip(a.uv.iter_mut()) {
        for (&w, p) in t.iter().zip(c.iter_mut()) {
            if w == v {
                p.x += 0.05;
            }
        }
    }
    let isl = islands(&a.faces, &a.uv);
    assert_eq!(isl.count, 2);
    let (_, reports) = length_true(&a.rest, &a.faces, &a.uv, &isl).unwrap();
    let negative = isl
        .faces(left)
        .iter()
        .filter(|&&f| {
            let q = a.uv[f as usize];
            (q[1] - q[0]).perp_dot(q[2] - q[0]) < 0.0
        })
        .count();
    println!("a vertex moved by 0.05 UV: {negative} faces fold over");
    assert!(negative > 0);
    assert_eq!(reports[left as usize].flipped, negative);
    assert_eq!(reports[1 - left as usize].flipped, 0);
}

// ---------------------------------------------------------- 4. a distorted island, charts

#[test]
fn an_orthographic_cap_is_stretched_and_its_conformal_chart_is_not() {
    let (rest, faces) = cap(16, 64, 60.0, 7);
    let uv: Vec<[DVec2; 3]> = faces.iter().map(|t| t.map(|v| rest[v as usize].truncate() * 4.0 + 0.5)).collect();
    let isl = islands(&faces, &uv);
    assert_eq!((isl.count, isl.seams.len()), (1, 0));
    let (corners, reports) = length_true(&rest, &faces, &uv, &isl).unwrap();
    let r = reports[0];
    let all: Vec<u32> = (0..faces.len() as u32).collect();
    let (stretch, ratio) = region_distortion(&rest, &faces, &corners, &all);
    assert_eq!(stretch, r.stretch_mean);
    assert!((ratio - 1.0).abs() < 1e-12, "length-true coordinates keep the island's area");

    let chart = conformal_chart(&rest, &faces, &all).unwrap();
    let c = chart.report;
    println!(
        "cap 60 deg: orthographic UV stretch mean {:.4} max {:.4}; conformal chart stretch mean {:.6} max {:.6}, \
         area ratio {:.3}..{:.3} (spread x{:.3}), area rel err {:.1e}, flipped {}",
        r.stretch_mean,
        r.stretch_max,
        c.stretch_mean,
        c.stretch_max,
        c.area_ratio_min,
        c.area_ratio_max,
        c.area_ratio_max / c.area_ratio_min,
        rel(c.area_material, c.area_3d),
        c.flipped
    );
    // Continuum: the mean of 1 / cos(theta) over the cap's area is ln 2 / (1 - cos 60) = 1.386.
    assert!(r.stretch_mean > 1.1 && (r.stretch_mean - 2f64.ln() / 0.5).abs() < 0.02);
    // The exact conformal map (stereographic projection) sampled at the vertices, as a yardstick:
    // on flat triangles neither is conformal face by face (the error halves with the ring's
    // segments); LSCM does at least as well.
    let stereo: Vec<[DVec2; 3]> =
        faces.iter().map(|t| t.map(|v| rest[v as usize].truncate() / (0.1 + rest[v as usize].z))).collect();
    let s = distortion(&rest, &faces, &stereo, &all).unwrap();
    println!("  stereographic projection at the vertices: stretch mean {:.6} max {:.6}", s.stretch_mean, s.stretch_max);
    assert!(c.stretch_mean <= s.stretch_mean && c.stretch_mean < 1.03);
    assert!(rel(c.area_material, c.area_3d) < 1e-9 && (c.area_ratio - 1.0).abs() < 1e-9);
    assert_eq!((c.flipped, c.degenerate, c.faces), (0, 0, faces.len()));
    // Pinned: the first at the origin, the second on +x.
    let [p0, p1] = chart.pins;
    assert!(p0 < p1);
    assert_eq!(chart[p0 as usize], DVec2::ZERO);
    assert!(chart[p1 as usize].y == 0.0 && chart[p1 as usize].x > 0.0);
    assert_eq!(chart.vertices.len(), rest.len());
}

/// The LSCM energy of a face: rest area x |J - cof J|^2 / 2 = A ((a - d)^2 + (b + c)^2) / 2, J
/// the 2x2 map from the rest triangle (in an orthonormal frame of its plane) to the chart.
fn conformal_energy(rest: [DVec3; 3], q: [DVec2; 3]) -> f64 {
    let (e1, e2) = (rest[1] - rest[0], rest[2] - rest[0]);
    let x = e1.normalize();
    let y = e1.cross(e2).cross(e1).normalize();
    let frame = glam::DMat2::from_cols(DVec2::new(x.dot(e1), y.dot(e1)), DVec2::new(x.dot(e2), y.dot(e2)));
    let j = glam::DMat2::from_cols(q[1] - q[0], q[2] - q[0]) * frame.inverse();
    let (a, b, c, d) = (j.x_axis.x, j.y_axis.x, j.x_axis.y, j.y_axis.y);
    0.5 * e1.cross(e2).length() * 0.5 * ((a - d).powi(2) + (b + c).powi(2))
}

#[test]
fn the_chart_minimizes_the_conformal_energy() {
    // No move of one unpinned vertex lowers the energy (computed here from the Jacobian, not
    // from the module's least squares rows): the gradient vanishes.
    let (rest, faces) = cap(8, 32, 70.0, 15);
    let all: Vec<u32> = (0..faces.len() as u32).collect();
    let chart = conformal_chart(&rest, &faces, &all).unwrap();
    let mut around = vec![Vec::new(); rest.len()];
    for (f, t) in faces.iter().enumerate() {
        t.iter().for_each(|&v| around[v as usize].push(f));
    }
    let mut coords = chart.coords.clone();
    let energy = |coords: &[DVec2], v: usize| -> f64 {
        around[v]
            .iter()
            .map(|&f| conformal_energy(faces[f].map(|i| rest[i as usize]), faces[f].map(|i| coords[i as usize])))
            .sum()
    };
    // Per vertex and axis, the moves +s and -s raise the energy by g s + H s^2 and -g s + H s^2:
    // the first-order share |g s| / (H s^2) is ~0 at a minimum.
    let mut worst = 0.0f64;
    for v in 0..rest.len() {
        if chart.pins.contains(&(v as u32)) {
            continue;
        }
        let base = energy(&coords, v);
        let h = around[v]
            .iter()
            .map(|&f| rest[faces[f][0] as usize].distance(rest[faces[f][1] as usize]))
            .fold(f64::INFINITY, f64::min);
        for axis in [DVec2::X, DVec2::Y] {
            let keep = coords[v];
            let mut rise = [0.0; 2];
            for (r, sign) in rise.iter_mut().zip([1.0, -1.0]) {
                coords[v] = keep + sign * 1e-4 * h * axis;
                *r = energy(&coords, v) - base;
            }
            coords[v] = keep;
            worst = worst.max((rise[0] - rise[1]).abs() / (rise[0] + rise[1]));
        }
    }
    println!("chart optimality: largest first-order share of the energy change of a vertex move {worst:.1e}");
    assert!(worst < 1e-6, "{worst}");
}

#[test]
fn a_flat_region_charts_isometrically() {
    let (local, rest, faces) = plane(0.12, 0.08, 12, 9, -1.0, 8);
    // The faces whose centroid is within 45 mm of the sheet's centre: a disk inside the sheet.
    let region: Vec<u32> = (0..faces.len() as u32)
        .filter(|&f| {
            let c = faces[f as usize].iter().map(|&v| local[v as usize]).sum::<DVec2>() / 3.0;
            c.distance(DVec2::new(0.06, 0.04)) < 0.045
        })
        .collect();
    assert!(region.len() < faces.len());
    let chart = conformal_chart(&rest, &faces, &region).unwrap();
    let corners: Vec<[DVec2; 3]> = faces.iter().map(|t| t.map(|v| chart[v as usize])).collect();
    let edges = edge_error(&rest, &faces, &corners, Some(&region));
    // Beyond edges: every pair of region vertices keeps its distance.
    let mut pairs = 0.0f64;
    for &a in &chart.vertices {
        for &b in &chart.vertices {
            if a < b {
                let (d3, d2) =
                    (rest[a as usize].distance(rest[b as usize]), chart[a as usize].distance(chart[b as usize]));
                pairs = pairs.max(rel(d2, d3));
            }
        }
    }
    let c = chart.report;
    println!(
        "flat region ({} faces): edge lengths rel err {edges:.1e}, all pairwise distances {pairs:.1e}, stretch max - 1 \
         {:.1e}, area ratio - 1 in [{:.1e}, {:.1e}]",
        region.len(),
        c.stretch_max - 1.0,
        c.area_ratio_min - 1.0,
        c.area_ratio_max - 1.0
    );
    assert!(edges < 1e-9 && pairs < 1e-9);
    assert!((c.stretch_max - 1.0).abs() < 1e-9 && (c.area_ratio_min - 1.0).abs() < 1e-9);
    assert!((c.area_ratio_max - 1.0).abs() < 1e-9);
    // Vertices outside the region are NaN.
    let inside: Vec<bool> = (0..rest.len() as u32).map(|v| chart.vertices.binary_search(&v).is_ok()).collect();
    assert!(chart.coords.iter().zip(&inside).all(|(p, &i)| i == p.is_finite()));
}

// ------------------------------------------------------------------------- 5. errors

#[test]
fn an_island_of_zero_uv_area_is_named() {
    let (mut a, _) = two_densities(9);
    let isl = islands(&a.faces, &a.uv);
    let right = 1 - isl.of_face[0];
    let first = isl.faces(right)[0];
    // Collapsed to a point: still one island (all its corners agree).
    for (f, c) in a.uv.iter_mut().enumerate() {
        if isl.of_face[f] == right {
            *c = [DVec2::splat(0.7); 3];
        }
    }
    let isl = islands(&a.faces, &a.uv);
    assert_eq!(isl.count, 2);
    let e = length_true(&a.rest, &a.faces, &a.uv, &isl).unwrap_err();
    assert_eq!(e, UvError::ZeroUvArea { island: right, face: first });
    assert!(e.to_string().contains(&format!("island {right} (face {first})")), "{e}");
    // Collapsed onto a line: zero area too.
    let mut b = two_densities(9).0;
    for (f, c) in b.uv.iter_mut().enumerate() {
        if isl.of_face[f] == right {
            c.iter_mut().for_each(|p| p.y = 0.3 + 0.1 * p.x);
        }
    }
    let isl = islands(&b.faces, &b.uv);
    assert_eq!(length_true(&b.rest, &b.faces, &b.uv, &isl), Err(UvError::ZeroUvArea { island: right, face: first }));
}

#[test]
fn an_island_of_zero_rest_area_is_named() {
    let (mut a, _) = two_densities(10);
    // A separate face whose rest vertices lie on a line, with UVs of its own.
    let n = a.rest.len() as u32;
    let p = a.rest[0];
    a.rest.extend([p, p + DVec3::X * 0.01, p + DVec3::X * 0.02]);
    a.faces.push([n, n + 1, n + 2]);
    a.uv.push([DVec2::new(0.9, 0.9), DVec2::new(0.95, 0.9), DVec2::new(0.9, 0.95)]);
    let isl = islands(&a.faces, &a.uv);
    assert_eq!(isl.count, 3);
    let face = a.faces.len() as u32 - 1;
    assert_eq!(length_true(&a.rest, &a.faces, &a.uv, &isl), Err(UvError::ZeroRestArea { island: 2, face }));
}

#[test]
fn a_nan_uv_is_named() {
    let (mut a, _) = two_densities(11);
    a.uv[7][1].x = f64::NAN;
    let isl = islands(&a.faces, &a.uv);
    assert_eq!(length_true(&a.rest, &a.faces, &a.uv, &isl), Err(UvError::NonFiniteUv { face: 7 }));
    a.uv[7][1].x = 0.1;
    a.uv[3][0].y = f64::INFINITY;
    assert_eq!(length_true(&a.rest, &a.faces, &a.uv, &isl), Err(UvError::NonFiniteUv { face: 3 }));
}

#[test]
fn a_region_straddling_a_seam_charts_conformally() {
    let (a, _) = two_densities(12);
    let all: Vec<u32> = (0..a.faces.len() as u32).collect();
    // Across the cut the islands' corners do not collapse to per-vertex coordinates: a conformal
    // chart of the region does (flat here: an isometry).
    let chart = conformal_chart(&a.rest, &a.faces, &all).unwrap();
    let corners: Vec<[DVec2; 3]> = a.faces.iter().map(|t| t.map(|v| chart[v as usize])).collect();
    assert!(edge_error(&a.rest, &a.faces, &corners, None) < 1e-9);
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let (a, _) = two_densities(13);
    let isl = islands(&a.faces, &a.uv);
    assert_eq!(
        length_true(&a.rest, &a.faces, &a.uv[1..], &isl),
        Err(UvError::CornerCount { faces: a.faces.len(), corners: a.faces.len() - 1 })
    );
    let mut faces = a.faces.clone();
    faces[5][2] = 10_000;
    assert_eq!(
        length_true(&a.rest, &faces, &a.uv, &isl),
        Err(UvError::VertexOutOfRange { face: 5, vertex: 10_000, vertices: a.rest.len() })
    );
    let mut rest = a.rest.clone();
    rest[4].z = f64::NAN;
    assert_eq!(length_true(&rest, &a.faces, &a.uv, &isl), Err(UvError::NonFinitePosition { vertex: 4 }));
    let mut labels = isl.clone();
    labels.of_face[3] = 2;
    assert_eq!(
        length_true(&a.rest, &a.faces, &a.uv, &labels),
        Err(UvError::LabelOutOfRange { face: 3, island: 2, count: 2 })
    );
    let mut labels = isl.clone();
    labels.count = 3;
    assert_eq!(length_true(&a.rest, &a.faces, &a.uv, &labels), Err(UvError::EmptyIsland { island: 2 }));
    // Fewer UV triples than faces: islands still labels every face.
    assert_eq!(islands(&a.faces, &a.uv[..10]).of_face.len(), a.faces.len());
    assert!(islands(&[], &[]).of_face.is_empty());

    // Charts: not a disk (the uncut cylinder is an annulus), not connected, empty, out of range.
    let (c, _) = cylinder(1e-3, DVec2::ZERO, &[], 0.0, 14);
    let all: Vec<u32> = (0..c.faces.len() as u32).collect();
    assert_eq!(conformal_chart(&c.rest, &c.faces, &all), Err(UvError::NotDisk { euler: 0, boundary_loops: 2 }));
    let far = c.faces.len() as u32 - 1;
    assert_eq!(conformal_chart(&c.rest, &c.faces, &[0, far]), Err(UvError::NotConnected { face: far, first: 0 }));
    assert_eq!(conformal_chart(&c.rest, &c.faces, &[]), Err(UvError::EmptyRegion));
    assert_eq!(
        conformal_chart(&c.rest, &c.faces, &[0, 1_000_000]),
        Err(UvError::FaceOutOfRange { face: 1_000_000, faces: c.faces.len() })
    );
    assert!(region_distortion(&c.rest, &c.faces, &c.uv, &[1_000_000]).0.is_nan());
    // A region with a face wound against its neighbours.
    let mut flipped = a.faces.clone();
    flipped[20].swap(0, 1);
    let all: Vec<u32> = (0..a.faces.len() as u32).collect();
    assert!(matches!(conformal_chart(&a.rest, &flipped, &all), Err(UvError::InconsistentWinding { .. })));
}
