//! Issue 62: skin on a real character (the MakeHuman hm08 head and arm, `scenes/character/
//! assets/README-hm08.md`). `forehead_quick`: the brows rise by the asset's own clip and
//! horizontal lines form across a refined, embedded forehead; `fist_quick`: the hand closes by
//! the rig's finger joints and creases form across each finger's bend. `cargo test --release -p
//! skinsim-cli --test character_scenes -- --nocapture` prints the figures.

use std::path::Path;

use glam::{DVec2, DVec3};
use skinsim::mesh::shading::vertex_normals;
use skinsim::scene::{self, built::LayerMesh, BuiltScene};
use skinsim_systems::Simulation;
use skinsim_tools::wrinkles::dominant_wave;

fn load(name: &str) -> BuiltScene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/character").join(name);
    scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// Runs every frame, asserting that every patch converges; returns the simulation and s/frame.
fn run_converged(built: &BuiltScene) -> (Simulation, f64) {
    let mut sim = Simulation::new(built);
    let clock = std::time::Instant::now();
    for frame in 1..=built.scene.frames {
        let s = sim.step();
        assert!(sim.failure().is_none(), "frame {frame}: {:?}", sim.failure());
        for p in &s.patches {
            assert!(p.outcome.converged, "frame {frame}, patch {}: {} iterations", p.name, p.outcome.iterations);
        }
    }
    (sim, clock.elapsed().as_secs_f64() / built.scene.frames as f64)
}

/// A shell's height over the surface it is offset from (the same vertices in the same order),
/// along the surface's normals, mean removed; with the shell's material positions and faces.
fn heights(sim: &mut Simulation, patch: &str, surface: &str, skin: &str) -> (Vec<DVec2>, Vec<f64>, Vec<[u32; 3]>) {
    let (_, base, faces) = sim.layer_mesh(patch, surface);
    let (uv, top, _) = sim.layer_mesh(patch, skin);
    let normals = vertex_normals(&base, &faces);
    let h: Vec<f64> = top.iter().zip(&base).zip(&normals).map(|((s, b), n)| (*s - *b).dot(*n)).collect();
    let mean = h.iter().sum::<f64>() / h.len() as f64;
    (uv, h.iter().map(|x| x - mean).collect(), faces)
}

/// The direction (radians, in [0, pi)) in material space along which the world's height (z)
/// grows fastest: a least-squares fit of z over the material positions.
fn up_in_material(uv: &[DVec2], x: &[DVec3]) -> f64 {
    let n = uv.len() as f64;
    let (cu, cz) = (uv.iter().sum::<DVec2>() / n, x.iter().map(|p| p.z).sum::<f64>() / n);
    let (mut a, mut b) = (glam::DMat2::ZERO, DVec2::ZERO);
    for (u, p) in uv.iter().zip(x) {
        let d = *u - cu;
        a += glam::DMat2::from_cols(d * d.x, d * d.y);
        b += d * (p.z - cz);
    }
    let g = a.inverse() * b;
    g.y.atan2(g.x).rem_euclid(std::f64::consts::PI)
}

/// The umbrella operator's size at each vertex (|x_i - mean of its neighbours|): curvature, up
/// to the local edge length.
fn umbrella(x: &[DVec3], faces: &[[u32; 3]]) -> Vec<f64> {
    let mut sum = vec![DVec3::ZERO; x.len()];
    let mut count = vec![0.0; x.len()];
    let mut seen = std::collections::HashSet::new();
    for f in faces {
        for k in 0..3 {
            let (a, b) = (f[k].min(f[(k + 1) % 3]), f[k].max(f[(k + 1) % 3]));
            if seen.insert((a, b)) {
                sum[a as usize] += x[b as usize];
                sum[b as usize] += x[a as usize];
                count[a as usize] += 1.0;
                count[b as usize] += 1.0;
            }
        }
    }
    x.iter().zip(sum.iter().zip(&count)).map(|(p, (s, c))| (*p - *s / *c).length()).collect()
}

/// Mean of `values` over the vertices that lie on an edge of the body's coarse mesh (a zero
/// barycentric coordinate in their parent face) over the mean over the others, interior
/// vertices of the patch only (a boundary vertex's umbrella is its boundary's, not a fold's).
fn on_coarse_edges_over_inside(values: &[f64], parents: &[(u32, DVec3)], interior: &[bool]) -> f64 {
    let (mut on, mut off) = ((0.0, 0.0), (0.0, 0.0));
    for ((v, (_, b)), inside) in values.iter().zip(parents).zip(interior) {
        if !inside {
            continue;
        }
        let slot = if b.min_element() == 0.0 { &mut on } else { &mut off };
        slot.0 += v;
        slot.1 += 1.0;
    }
    (on.0 / on.1) / (off.0 / off.1)
}

/// Issue 62 (VALIDATION.md case 16): the brows rise and the forehead's lines run horizontally,
/// at the kernels' wavelength, and no fold follows the head's coarse (4-16 mm) edges.
#[test]
fn the_forehead_wrinkles_in_horizontal_lines_when_the_brows_rise() {
    let built = load("forehead_quick.ron");
    let (mut sim, per_frame) = run_converged(&built);
    let (uv, h, faces) = heights(&mut sim, "forehead", "surface", "dermis");
    let (_, surface, _) = sim.layer_mesh("forehead", "surface");
    let wave = dominant_wave(&uv, &h, &faces, 0.5e-3).expect("a wave");
    let up = up_in_material(&uv, &surface);
    // The angle between the wave vector and the world's vertical, seen in material space (lines
    // run horizontally when the wave vector points up).
    let from_vertical = |angle: f64| {
        let off = (angle - up).rem_euclid(std::f64::consts::PI);
        off.min(std::f64::consts::PI - off).to_degrees()
    };
    let off = from_vertical(wave.angle);
    // The outer layer, the epidermis (LK14's second layer), shows the same lines.
    let (euv, eh, efaces) = heights(&mut sim, "forehead", "surface", "epidermis");
    let outer = dominant_wave(&euv, &eh, &efaces, 0.5e-3).expect("a wave");
    let outer_off = from_vertical(outer.angle);
    let swing = h.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    // Folds along the coarse edges would put the curvature there: compare it with the
    // curvature inside the coarse faces, for the embedded surface, for the wrinkled dermis, and
    // for the same refined vertices on the head's flat facets (where every fold is on an edge).
    let patch = &built.patches[0];
    let layer = patch.layers.iter().find(|l| l.name == "surface").unwrap();
    let parents = layer.parents.as_ref().expect("a refined layer");
    let LayerMesh::Surface(head) = &patch.layers[0].mesh else { panic!("the head is a surface") };
    let faceted: Vec<DVec3> = parents
        .iter()
        .map(|&(f, b)| {
            let c = head.faces[f as usize].map(|v| head.rest[v as usize]);
            b.x * c[0] + b.y * c[1] + b.z * c[2]
        })
        .collect();
    let interior: Vec<bool> = skinsim::mesh::boundary_vertices(&faces, faceted.len()).iter().map(|b| !b).collect();
    let (_, dermis, _) = sim.layer_mesh("forehead", "dermis");
    let ratio = |x: &[DVec3]| on_coarse_edges_over_inside(&umbrella(x, &faces), parents, &interior);
    let (faceted_ratio, surface_ratio, dermis_ratio) = (ratio(&faceted), ratio(&surface), ratio(&dermis));
    println!(
        "forehead_quick: {per_frame:.2} s/frame; dominant wavelength {:.2} mm (kernels 10 mm), wave vector {off:.1} \
         degrees from vertical; epidermis {:.2} mm, {outer_off:.1} degrees; height swing {:.3} mm; curvature on \
         coarse edges / inside coarse faces: flat facets {faceted_ratio:.1}, embedded surface {surface_ratio:.3}, \
         dermis {dermis_ratio:.3}",
        1e3 * wave.wavelength,
        1e3 * outer.wavelength,
        1e3 * swing
    );
    assert!(swing > 0.2e-3, "the forehead wrinkles: {swing}");
    // Measured 12.1 degrees, the epidermis 4.7 (the full scene: 6.9, `forehead.ron`).
    assert!(off < 20.0, "lines within 20 degrees of horizontal: {off:.1}");
    assert!(outer_off < 20.0, "the epidermis's lines within 20 degrees of horizontal: {outer_off:.1}");
    assert!((wave.wavelength / outer.wavelength - 1.0).abs() < 0.1, "{} {}", wave.wavelength, outer.wavelength);
    // Measured 12.35 mm, the epidermis 13.25 (the full scene 9.8): the kernels' band
    // (coupling::kernels::KERNEL_SCALE, 0.9-1.4 lambda on the finger) widened below for this
    // 45 mm tall patch, whose 4.5 waves put the spectrum's bins 10-20 % apart.
    assert!((0.75..=1.4).contains(&(wave.wavelength / 10e-3)), "{}", wave.wavelength);
    // Measured: flat facets put all curvature on the coarse edges (ratio 4.8e12); the limit
    // surface 1.18, the dermis 1.06: no fold follows them.
    assert!(faceted_ratio > 10.0, "the measure sees folds on coarse edges: {faceted_ratio}");
    assert!(surface_ratio < 1.5 && dermis_ratio < 1.5, "{surface_ratio} {dermis_ratio}");
}

/// Issue 62: the hand closes by the rig's finger joints (the asset's `fist` clip); two patches
/// on the one arm, the palm sides of the index and middle fingers, converge every frame and
/// crease across each finger's bend: their crests run across the finger (the wave vector along
/// it).
#[test]
fn the_fingers_crease_across_their_bends_as_the_hand_closes() {
    let built = load("fist_quick.ron");
    let (mut sim, per_frame) = run_converged(&built);
    let mut measured = Vec::new();
    for finger in ["index", "middle"] {
        let (uv, h, faces) = heights(&mut sim, finger, "surface", "skin");
        let wave = dominant_wave(&uv, &h, &faces, 0.25e-3).expect("a wave");
        // Along the finger: the material direction in which the rest surface runs longest.
        let along = finger_axis(&uv, &rest_of(&built, finger));
        let off = (wave.angle - along).rem_euclid(std::f64::consts::PI);
        let off = off.min(std::f64::consts::PI - off).to_degrees();
        let swing = h.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        println!(
            "fist_quick {finger}: dominant wavelength {:.2} mm, wave vector {off:.1} degrees from the finger's axis, \
             height swing {:.3} mm",
            1e3 * wave.wavelength,
            1e3 * swing
        );
        measured.push((finger, swing, off));
    }
    println!("fist_quick: {per_frame:.2} s/frame");
    for (finger, swing, off) in measured {
        assert!(swing > 0.1e-3, "{finger} creases: {swing}");
        // Measured 4.1 (index) and 19.2 (middle) degrees: the creases run across the finger,
        // the middle one slanted where the skinning twists its joint as it closes. (With the
        // shells moved along with their surface before each solve, issue 62's first session:
        // 37.7 and 20.1.)
        assert!(off < 30.0, "{finger}: crests across the finger: {off:.1}");
    }
}

/// The rest positions of a patch's refined surface, in its mesh's order.
fn rest_of(built: &BuiltScene, patch: &str) -> Vec<DVec3> {
    let p = built.patches.iter().find(|p| p.name == patch).unwrap();
    p.layers.iter().find(|l| l.name == "surface").unwrap().mesh.rest().to_vec()
}

/// The material direction (radians, [0, pi)) of the rest surface's longest extent: the
/// principal axis of the 3D rest positions, expressed in material space by a least-squares fit.
fn finger_axis(uv: &[DVec2], rest: &[DVec3]) -> f64 {
    let n = rest.len() as f64;
    let c = rest.iter().sum::<DVec3>() / n;
    let cov = rest.iter().fold(glam::DMat3::ZERO, |m, p| {
        let d = *p - c;
        m + glam::DMat3::from_cols(d * d.x, d * d.y, d * d.z)
    });
    // Power iteration for the principal axis.
    let mut a = DVec3::ONE.normalize();
    for _ in 0..100 {
        a = (cov * a).normalize();
    }
    let along: Vec<DVec3> = rest.iter().map(|p| DVec3::new(0.0, 0.0, (*p - c).dot(a))).collect();
    up_in_material(uv, &along)
}
