//! Procedural kinematic bodies and their poses for the KCK18 scenes: a tube that bends at an
//! elbow, a sheet that folds shut along a crease, a lumpy creature, and a skin offset from any
//! of them.

use std::collections::HashMap;
use std::f64::consts::{PI, TAU};

use glam::{DVec2, DVec3};

use super::SurfaceMesh;

/// An open tube along x, centred on the origin: `around` vertices per ring, `along` cells.
/// Material coordinates (x, arc length from the top).
pub fn tube(radius: f64, length: f64, around: u32, along: u32) -> SurfaceMesh {
    tube_arc(radius, length, around, along, TAU)
}

/// A tube (`arc` = 2 pi, closed) or an open part of one `arc` radians wide, centred on +z, its
/// material coordinates (x, radius x angle) continuous over it.
pub(crate) fn tube_arc(radius: f64, length: f64, around: u32, along: u32, arc: f64) -> SurfaceMesh {
    let closed = arc >= TAU;
    let columns = if closed { around } else { around + 1 };
    let start = if closed { 0.0 } else { -0.5 * arc };
    let mut m = SurfaceMesh::default();
    for i in 0..=along {
        let x = -0.5 * length + length * i as f64 / along as f64;
        for j in 0..columns {
            let theta = start + arc.min(TAU) * j as f64 / around as f64;
            m.rest.push(DVec3::new(x, radius * theta.sin(), radius * theta.cos()));
            m.uv.push(DVec2::new(x, radius * theta));
        }
    }
    tube_faces(&mut m.faces, 0, columns, around, along);
    m
}

/// The triangles of a tube whose rings of `columns` vertices start at vertex `base`: `around`
/// quads per ring (the last one closing the ring when `around == columns`), `along` rings of
/// quads.
pub(crate) fn tube_faces(faces: &mut Vec<[u32; 3]>, base: u32, columns: u32, around: u32, along: u32) {
    for i in 0..along {
        for j in 0..around {
            let v = |di: u32, dj: u32| base + (i + di) * columns + (j + dj) % columns;
            // Alternate the diagonals so the tube has no handedness.
            if (i + j) % 2 == 0 {
                faces.push([v(0, 0), v(1, 0), v(1, 1)]);
                faces.push([v(0, 0), v(1, 1), v(0, 1)]);
            } else {
                faces.push([v(0, 0), v(1, 0), v(0, 1)]);
                faces.push([v(1, 0), v(1, 1), v(0, 1)]);
            }
        }
    }
}

/// A closed creature-like body of about 20 x 4^subdivisions triangles: a subdivided
/// icosahedron of radius `radius` with lumps for four legs, a head and a tail. The creases
/// where the lumps meet the torso are where projected anchors snag.
pub fn creature(radius: f64, subdivisions: u32) -> SurfaceMesh {
    let (dirs, faces) = icosphere(subdivisions);
    // (direction, height, angular width): legs below, head in front, tail behind.
    let lumps: [(DVec3, f64, f64); 6] = [
        (DVec3::new(0.5, 0.45, -0.75), 0.55, 0.30),
        (DVec3::new(0.5, -0.45, -0.75), 0.55, 0.30),
        (DVec3::new(-0.5, 0.45, -0.75), 0.55, 0.30),
        (DVec3::new(-0.5, -0.45, -0.75), 0.55, 0.30),
        (DVec3::new(1.0, 0.0, 0.35), 0.45, 0.40),
        (DVec3::new(-1.0, 0.0, 0.1), 0.35, 0.22),
    ];
    let rest: Vec<DVec3> = dirs
        .iter()
        .map(|d| {
            let bump: f64 =
                lumps.iter().map(|(c, h, w)| h * (-(1.0 - d.dot(c.normalize())) / (w * w)).exp()).sum::<f64>();
            // An elongated torso (1.4 : 1 : 0.9) carrying the lumps.
            let torso = DVec3::new(1.4, 1.0, 0.9) * *d;
            radius * (torso + bump * *d)
        })
        .collect();
    let uv = dirs.iter().map(|d| DVec2::new(d.y.atan2(d.x) * radius, d.z.clamp(-1.0, 1.0).acos() * radius)).collect();
    SurfaceMesh { rest, uv, faces }
}

/// Unit sphere directions and outward triangles of an icosahedron subdivided `n` times.
pub(crate) fn icosphere(n: u32) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<DVec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..n {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut split = |a: u32, b: u32, v: &mut Vec<DVec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                v.push((v[a as usize] + v[b as usize]).normalize());
                (v.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(f.len() * 4);
        for [a, b, c] in f {
            let (ab, bc, ca) = (split(a, b, &mut v), split(b, c, &mut v), split(c, a, &mut v));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    (v, f)
}

/// `mesh` moved by `distance` along its area-weighted vertex normals (a skin over a body).
pub fn offset(mesh: &SurfaceMesh, distance: f64) -> SurfaceMesh {
    let normals = super::shading::vertex_normals(&mesh.rest, &mesh.faces);
    let rest = mesh.rest.iter().zip(&normals).map(|(p, n)| *p + distance * *n).collect();
    SurfaceMesh { rest, uv: mesh.uv.clone(), faces: mesh.faces.clone() }
}

/// An elbow: from `centre` on, the tube axis (x) bends upwards (+z; downwards for a negative
/// angle) by `angle` (radians) along
/// an arc of radius `bend_radius`; the part before stays, the part after turns rigidly. A bend
/// radius below the tube radius pinches the inside of the elbow and then folds it through
/// itself.
pub fn elbow(p: DVec3, centre: DVec3, angle: f64, bend_radius: f64) -> DVec3 {
    if angle < 0.0 {
        // Bending downwards: the mirror image (in z about the centre) of bending upwards.
        let mirror = |v: DVec3| DVec3::new(v.x, v.y, 2.0 * centre.z - v.z);
        return mirror(elbow(mirror(p), centre, -angle, bend_radius));
    }
    let q = p - centre;
    if angle == 0.0 {
        return p;
    }
    let u = q.x.clamp(0.0, angle * bend_radius);
    let theta = u / bend_radius;
    let (s, c) = theta.sin_cos();
    let axis = DVec3::new(bend_radius * s, 0.0, bend_radius * (1.0 - c));
    let tangent = DVec3::new(c, 0.0, s);
    let normal = DVec3::new(-s, 0.0, c);
    centre + axis + (q.x - u) * tangent + q.y * DVec3::Y + q.z * normal
}

/// A fold along the line through `centre` parallel to y: the part with x > centre.x turns
/// upwards about it by `angle` (radians). At pi the two halves lie on each other (a crease of
/// zero width); past pi they pass through each other.
pub fn fold(p: DVec3, centre: DVec3, angle: f64) -> DVec3 {
    let q = p - centre;
    if q.x <= 0.0 {
        return p;
    }
    let (s, c) = angle.sin_cos();
    centre + DVec3::new(q.x * c - q.z * s, q.y, q.x * s + q.z * c)
}

/// Degrees to radians for scene values.
pub fn radians(degrees: f64) -> f64 {
    degrees * PI / 180.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::check_surface;

    #[test]
    fn generated_bodies_are_valid_surfaces_of_the_expected_size() {
        let t = tube(1.0, 4.0, 24, 16);
        assert_eq!((t.rest.len(), t.faces.len()), (17 * 24, 2 * 24 * 16));
        check_surface(&t).unwrap();
        let c = creature(1.0, 5);
        assert_eq!(c.faces.len(), 20 * 4usize.pow(5));
        check_surface(&c).unwrap();
        // Outward faces: a positive enclosed volume.
        let volume: f64 = c
            .faces
            .iter()
            .map(|f| c.rest[f[0] as usize].dot(c.rest[f[1] as usize].cross(c.rest[f[2] as usize])) / 6.0)
            .sum();
        assert!(volume > 4.0, "{volume}");
    }

    #[test]
    fn poses_are_rigid_away_from_the_joint_and_close_the_fold() {
        let c = DVec3::ZERO;
        // An elbow at 90 degrees turns the far end of the axis to point up.
        let far = elbow(DVec3::new(10.0, 0.0, 0.0), c, PI / 2.0, 1.0);
        assert!((far - DVec3::new(1.0, 0.0, 1.0 + 10.0 - PI / 2.0)).length() < 1e-12, "{far}");
        assert_eq!(elbow(DVec3::new(0.3, 0.2, 0.1), c, 0.0, 1.0), DVec3::new(0.3, 0.2, 0.1));
        // Folded shut, the right half lies on the left one.
        let p = fold(DVec3::new(2.0, 1.0, 0.0), c, PI);
        assert!((p - DVec3::new(-2.0, 1.0, 0.0)).length() < 1e-12);
        assert_eq!(fold(DVec3::new(-2.0, 1.0, 0.0), c, PI), DVec3::new(-2.0, 1.0, 0.0));
    }
}
