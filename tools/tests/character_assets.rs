//! Issue 62 at system level: glTF bodies written by the tests themselves (tests/common/gltf.rs),
//! posed by the `Rig` driver (joints, morph targets, linear blend skinning), carrying patches
//! refined on their Loop limit surface and embedded in them. Every figure has an independent
//! computation beside it. `cargo test --release -p skinsim-cli --test character_assets --
//! --nocapture` prints the figures.
//!
//! That the refined REST vertices lie on the body's Loop limit surface, against an independent
//! evaluation (the box spline of a regular patch), is src/mesh/subdivision_tests.rs's; it is not
//! repeated here. Here the limit surface is followed through the body's motion.

#[allow(dead_code)]
#[path = "../../tests/common/gltf.rs"]
mod gltf;

use std::collections::HashMap;
use std::f32::consts::TAU;
use std::path::PathBuf;
use std::time::Instant;

use glam::{DVec2, DVec3};
use skinsim::mesh::shading::vertex_normals;
use skinsim::mesh::subdivision::{apply_all, refine};
use skinsim::scene;
use skinsim_systems::Simulation;
use skinsim_tools::wrinkles::row_peaks;

/// A scratch folder for one test (the scene file and the asset it loads).
fn scratch(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("skinsim-character-assets-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// glTF (+Y up) to the engine's frame (+Z up): (x, y, z) -> (x, -z, y), exactly.
fn engine(p: [f64; 3]) -> DVec3 {
    DVec3::new(p[0], -p[2], p[1])
}

/// The inverse of [`engine`].
fn gltf_frame(p: DVec3) -> [f64; 3] {
    [p.x, p.z, -p.y]
}

fn widen(p: [f32; 3]) -> [f64; 3] {
    p.map(f64::from)
}

/// One vertex per distinct rest position (bitwise), in order of first occurrence: the loader's
/// welding rule (position and joint influences agree; the influences here are a function of
/// the position). Returns the welded index of every glTF vertex and the first glTF vertex of
/// every welded one.
fn weld(positions: &[[f32; 3]]) -> (Vec<u32>, Vec<usize>) {
    let mut seen: HashMap<[u32; 3], u32> = HashMap::new();
    let mut first = Vec::new();
    let index = positions
        .iter()
        .enumerate()
        .map(|(v, p)| {
            *seen.entry(p.map(f32::to_bits)).or_insert_with(|| {
                first.push(v);
                first.len() as u32 - 1
            })
        })
        .collect();
    (index, first)
}

/// Faces (welded indices) all of whose vertices lie in the box [lo, hi] (engine frame, m), in
/// ascending order: what `region: Box` selects.
fn in_box(rest: &[DVec3], faces: &[[u32; 3]], lo: DVec3, hi: DVec3) -> Vec<u32> {
    let inside = |v: u32| rest[v as usize].cmpge(lo).all() && rest[v as usize].cmple(hi).all();
    (0..faces.len() as u32).filter(|&f| faces[f as usize].iter().all(|&v| inside(v))).collect()
}

fn max_distance(a: &[DVec3], b: &[DVec3]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(p, q)| p.distance(*q)).fold(0.0, f64::max)
}

// ---------------------------------------------------------------------------------------------
// 4 x 4 affine matrices (row-major), independent of glam and of the engine's rig code.

type M4 = [[f64; 4]; 4];

fn mul(a: &M4, b: &M4) -> M4 {
    let mut m = [[0.0; 4]; 4];
    for r in 0..4 {
        for c in 0..4 {
            m[r][c] = (0..4).map(|k| a[r][k] * b[k][c]).sum();
        }
    }
    m
}

fn translation(t: [f64; 3]) -> M4 {
    [[1.0, 0.0, 0.0, t[0]], [0.0, 1.0, 0.0, t[1]], [0.0, 0.0, 1.0, t[2]], [0.0, 0.0, 0.0, 1.0]]
}

/// Rodrigues: a right-handed turn by `degrees` about `axis` (any length).
fn rotation(axis: [f64; 3], degrees: f64) -> M4 {
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let k = axis.map(|a| a / n);
    let (s, c) = degrees.to_radians().sin_cos();
    let cross = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
    let mut m = translation([0.0; 3]);
    for r in 0..3 {
        for col in 0..3 {
            let identity = if r == col { 1.0 } else { 0.0 };
            m[r][col] = c * identity + s * cross[r][col] + (1.0 - c) * k[r] * k[col];
        }
    }
    m
}

fn transform(m: &M4, p: [f64; 3]) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (r, o) in out.iter_mut().enumerate() {
        *o = m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3];
    }
    out
}

// ---------------------------------------------------------------------------------------------
// 1. A refined patch follows rigid, skinned and morphed motion on the limit surface.

/// The tube of test 1 (glTF metres): radius, length, quads around and along.
const TUBE_RADIUS: f32 = 0.010;
const TUBE_LENGTH: f32 = 0.060;
const TUBE_AROUND: u32 = 24;
const TUBE_ALONG: u32 = 12;
/// The root joint's turn of frame 1 (degrees, about this axis of its frame), the child's bend
/// of frame 2 (about glTF z: the far half turns down, so the top, where the patch is, is on the
/// outside of the bend), and the bump's weight at frame 3.
const ROOT_AXIS: [f64; 3] = [1.0, 2.0, 3.0];
const ROOT_TURN: f64 = 30.0;
const CHILD_BEND: f64 = -40.0;

#[test]
fn a_refined_patch_follows_rigid_skinned_and_morphed_motion_on_the_limit_surface() {
    let dir = scratch("follow");
    // The asset: a closed tube (its seam duplicated in glTF, welded by the loader) along glTF x,
    // a root joint at its start (x = -30 mm) and a child at its middle; the child's weight rises
    // linearly across the middle, by rows: 0 up to x = -10 mm, 1/4, 1/2, 3/4, then 1 from
    // x = +10 mm (dyadic weights: exact in f32, summing to one exactly). One morph target: a
    // 2 mm bump along the outward normal on the top at x = +15 mm (sigma 5 mm).
    let (positions, uv, indices) = gltf::cylinder(TUBE_RADIUS, TUBE_LENGTH, TUBE_AROUND, TUBE_ALONG, TAU);
    let row = |v: usize| (v as u32 / (TUBE_AROUND + 1)) as f32;
    let child_weight: Vec<f32> = (0..positions.len()).map(|v| (row(v) - 4.0).clamp(0.0, 4.0) / 4.0).collect();
    let bump: Vec<[f32; 3]> = positions
        .iter()
        .map(|p| {
            let [x, y, z] = widen(*p);
            let rho = (y * y + z * z).sqrt();
            let s = f64::from(TUBE_RADIUS) * z.atan2(y); // arc length from the top
            let a = 0.002 * (-((x - 0.015).powi(2) + s * s) / (2.0 * 0.005f64.powi(2))).exp();
            [0.0, (a * y / rho) as f32, (a * z / rho) as f32]
        })
        .collect();
    let root_at = [-0.5 * TUBE_LENGTH, 0.0, 0.0];
    let child_at = [0.5 * TUBE_LENGTH, 0.0, 0.0];
    let asset = gltf::Asset {
        positions: positions.clone(),
        uv: Some(uv),
        indices: indices.clone(),
        joints: vec![
            gltf::Joint { name: "root".into(), parent: None, translation: root_at },
            gltf::Joint { name: "child".into(), parent: Some(0), translation: child_at },
        ],
        influences: child_weight.iter().map(|&c| ([0, 1, 0, 0], [1.0 - c, c, 0.0, 0.0])).collect(),
        morphs: vec![("bump".into(), bump.clone())],
        ..Default::default()
    };
    gltf::write(&dir, "tube", &asset);
    let scene_path = dir.join("follow.ron");
    std::fs::write(&scene_path, FOLLOW_SCENE).unwrap();
    let built = scene::load(&scene_path).unwrap_or_else(|e| panic!("{e}"));

    // The welded body, in the engine's frame (m), computed here from what was written.
    let (welded, first) = weld(&positions);
    let rest_gltf: Vec<[f64; 3]> = first.iter().map(|&v| widen(positions[v])).collect();
    let rest: Vec<DVec3> = rest_gltf.iter().map(|p| engine(*p)).collect();
    let faces: Vec<[u32; 3]> =
        indices.chunks(3).map(|t| [welded[t[0] as usize], welded[t[1] as usize], welded[t[2] as usize]]).collect();
    // A closed tube: the seam column welds to the first (the writer's full-circle fix).
    assert_eq!(rest.len(), ((TUBE_ALONG + 1) * TUBE_AROUND) as usize, "the seam welds");
    let child: Vec<f64> = first.iter().map(|&v| f64::from(child_weight[v])).collect();
    let bump: Vec<[f64; 3]> = first.iter().map(|&v| widen(bump[v])).collect();
    // Independent linear blend skinning: x' = sum_j w_j G_j B_j^-1 (X + m D), with G the joints'
    // globals (rest rotations the identity, so B_j^-1 is the inverse of the joint's rest
    // translation), the joints' keyed turns in their own frames.
    let (root_t, child_t) = (widen(root_at), widen(child_at));
    let joint_matrices = |root_deg: f64, child_deg: f64| {
        let g_root = mul(&translation(root_t), &rotation(ROOT_AXIS, root_deg));
        let g_child = mul(&g_root, &mul(&translation(child_t), &rotation([0.0, 0.0, 1.0], child_deg)));
        let unbind_root = translation(root_t.map(|t| -t));
        let unbind_child = translation([0, 1, 2].map(|k| -(root_t[k] + child_t[k])));
        (mul(&g_root, &unbind_root), mul(&g_child, &unbind_child))
    };
    let pose = |root_deg: f64, child_deg: f64, morph: f64| -> Vec<DVec3> {
        let (m_root, m_child) = joint_matrices(root_deg, child_deg);
        (0..rest_gltf.len())
            .map(|v| {
                let x: [f64; 3] = [0, 1, 2].map(|k| rest_gltf[v][k] + morph * bump[v][k]);
                let (a, b) = (transform(&m_root, x), transform(&m_child, x));
                engine([0, 1, 2].map(|k| (1.0 - child[v]) * a[k] + child[v] * b[k]))
            })
            .collect()
    };

    // The reference refinement: the top half (engine z >= 0) refined twice, from the welded
    // body computed here (its stencils depend on the connectivity alone: the same for the rest
    // and every posed body; applied below to each frame's posed positions).
    let lo = DVec3::new(-31.0, -11.0, -0.1) * 1e-3;
    let hi = DVec3::new(31.0, 11.0, 11.0) * 1e-3;
    let region = in_box(&rest, &faces, lo, hi);
    assert_eq!(region.len(), 2 * 12 * TUBE_ALONG as usize, "the top half: 12 quads around");
    let reference = refine(&rest, &faces, &region, 2).unwrap();
    let on_limit = |body: &[DVec3]| {
        let mut out = Vec::new();
        apply_all(&reference.stencils, body, &mut out);
        out
    };
    let size = f64::from(TUBE_LENGTH);
    let tolerance = 1e-9 * size;

    let mut sim = Simulation::new(&built);
    // Before any frame: the body is the written tube and the patch its rest limit surface.
    let body = sim.layer_positions("tube", "tube");
    let surface = sim.layer_positions("top", "surface");
    assert_eq!(surface.len(), reference.stencils.len(), "the refined layer's vertices");
    let at_rest = (max_distance(&body, &rest), max_distance(&surface, &on_limit(&rest)));
    println!(
        "follow: body {} welded vertices ({} written), patch {} refined vertices over {} body faces; at rest: \
         body {:.1e} m from the written tube, surface {:.1e} m from its limit surface",
        rest.len(),
        positions.len(),
        surface.len(),
        region.len(),
        at_rest.0,
        at_rest.1
    );
    // Measured 4.7e-18 and 1.4e-17 m (the frame's turn rounds): the welding, the vertex order
    // and the frame are the ones computed here.
    assert!(at_rest.0 <= tolerance && at_rest.1 <= tolerance, "{at_rest:?}");
    let rest_surface = surface;

    // Frame 1: the root turned 30 degrees (rigid); 2: the child bent -40 degrees; 3: the bump.
    let keys = [(ROOT_TURN, 0.0, 0.0), (ROOT_TURN, CHILD_BEND, 0.0), (ROOT_TURN, CHILD_BEND, 1.0)];
    let what = ["rigid root turn", "child bend (skinned)", "bump morph (skinned)"];
    let clock = Instant::now();
    let mut previous = rest_surface.clone();
    for (frame, (&(root_deg, child_deg, morph), name)) in keys.iter().zip(what).enumerate() {
        let s = sim.step();
        assert!(sim.failure().is_none(), "frame {}: {:?}", frame + 1, sim.failure());
        assert!(s.patches.iter().all(|p| p.outcome.converged), "frame {}: {:?}", frame + 1, s.patches);
        let body = sim.layer_positions("tube", "tube");
        let surface = sim.layer_positions("top", "surface");
        let mine = pose(root_deg, child_deg, morph);
        // (a) the engine's posed body against the skinning computed here;
        let body_error = max_distance(&body, &mine);
        // (b) the embedded vertices against the limit surface of the engine's posed body;
        let limit_error = max_distance(&surface, &on_limit(&body));
        // (c) and of the body posed here (independent of the engine's rig and its stencils).
        let independent_error = max_distance(&surface, &on_limit(&mine));
        // What the tolerance is against: how far this frame moved the patch.
        let moved = max_distance(&surface, &previous);
        println!(
            "follow frame {} ({name}): patch moved up to {:.3} mm; body vs own skinning {body_error:.1e} m, \
             embedded vs limit of the posed body {limit_error:.1e} m, vs limit of own posing \
             {independent_error:.1e} m (bound {tolerance:.0e} m)",
            frame + 1,
            1e3 * moved
        );
        // Measured: the patch moved 31.2, 21.6 and 1.7 mm in frames 1-3; the body 1.3-1.6e-17 m
        // from the skinning computed here, the embedded vertices exactly on the limit of the
        // engine's posed body (the same stencils over the same positions) and 1.6e-17 m from the
        // limit of the body posed here, against a bound of 6e-11 m. A carry that read the body
        // before it moved would be off by the frame's motion; a joint turned about a world axis
        // instead of its own (frame 2), or a morph applied after skinning instead of before
        // (frame 3: the bump turned by the joints, about 1 mm), by millimetres.
        assert!(moved > 1e-3, "frame {}: the motion moves the patch ({moved} m)", frame + 1);
        assert!(body_error <= tolerance, "frame {}: body {body_error:e} m from own skinning", frame + 1);
        assert!(limit_error <= tolerance, "frame {}: embedded {limit_error:e} m off the limit surface", frame + 1);
        assert!(independent_error <= tolerance, "frame {}: {independent_error:e} m from own posing", frame + 1);
        if frame == 0 {
            // A rigid motion moves the limit surface rigidly (affine stencils): the rest patch
            // turned by the root's own matrix (measured 2.1e-17 m; a stencil whose weights did
            // not sum to one would show the 30 mm translation).
            let (m_root, _) = joint_matrices(root_deg, 0.0);
            let turned: Vec<DVec3> = rest_surface.iter().map(|p| engine(transform(&m_root, gltf_frame(*p)))).collect();
            let rigid_error = max_distance(&surface, &turned);
            println!("follow frame 1: embedded vs the rest patch turned rigidly {rigid_error:.1e} m");
            assert!(rigid_error <= tolerance, "rigid: {rigid_error:e} m");
        }
        previous = surface;
    }
    println!("follow: {:.2} s/frame", clock.elapsed().as_secs_f64() / keys.len() as f64);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Test 1's scene (millimetres): the tube and its rig's keyframes, a patch on its top half
/// refined twice and embedded, and a thin shell held to it by kernels.
const FOLLOW_SCENE: &str = r#"Scene(
    name: "follow",
    units: (length: Millimetre, stress: MegaPascal),
    frames: 3,
    bodies: [
        Body(
            name: "tube",
            mesh: Gltf(path: "tube.gltf"),
            drivers: [Rig(layer: "tube",
                joints: [JointKeys(joint: "root", axis: (1.0, 2.0, 3.0), keyframes: [(0, 0.0), (1, 30.0)]),
                         JointKeys(joint: "child", axis: (0.0, 0.0, 1.0), keyframes: [(1, 0.0), (2, -40.0)])],
                morphs: [MorphKeys(target: "bump", keyframes: [(2, 0.0), (3, 1.0)])])],
        ),
    ],
    patches: [
        Patch(
            name: "top",
            body: "tube",
            solver: (tolerance: 1e-8, max_iterations: 200, projection: None),
            layers: [
                Layer(name: "surface", kind: Kinematic,
                      mesh: Offset(layer: "tube", distance: 0.0,
                                   region: Box(min: (-31.0, -11.0, -0.1), max: (31.0, 11.0, 11.0)),
                                   refine: Levels(2))),
                Layer(name: "skin", kind: Shell,
                      mesh: Offset(layer: "surface", distance: 0.05),
                      material: (model: BazantHencky, young: 4.0, poisson: 0.45, thickness: 0.1),
                      bending: Some((model: Tan))),
            ],
            couplings: [
                Coupling(upper: "skin", lower: "surface", wavelength: Constant(6.0), seed: 1, distance: Geodesic),
            ],
        ),
    ],
)
"#;

// ---------------------------------------------------------------------------------------------
// 2. Wrinkles keep their length whatever the UV scale.

/// The tube of test 2 (glTF metres): radius, quads around and along; its length is 17/32 of its
/// circumference (50.07 mm), so that its unrolled surface scaled into [0, 1] (by the
/// circumference) has UVs on a dyadic grid: u = i 17/512, v = j / 32. Those, and 1000 times
/// those, are exact in f32, so the two assets differ by the UV scale alone (an f32 UV times
/// 1000 would otherwise be rounded: 6e-8 relative).
const SQUASH_RADIUS: f32 = 0.015;
const SQUASH_AROUND: u32 = 32;
const SQUASH_ALONG: u32 = 16;
/// The coupling's wavelength (mm).
const LAMBDA: f64 = 6.0;

/// What one run of test 2 measured.
struct Squash {
    /// The skin's material coordinates (m), in `layer_surface` order.
    material: Vec<DVec2>,
    /// The dominant wavelength (m) of the skin's heights over the surface along the axis, in 3D
    /// (against the deformed axial coordinate).
    wavelength_3d: f64,
    seconds_per_frame: f64,
}

fn squash(uv_scale: f32) -> Squash {
    let tag = format!("squash-{uv_scale}");
    let dir = scratch(&tag);
    let length = TAU * SQUASH_RADIUS * 17.0 / 32.0;
    let (positions, _, indices) = gltf::cylinder(SQUASH_RADIUS, length, SQUASH_AROUND, SQUASH_ALONG, TAU);
    let w = SQUASH_AROUND + 1;
    let uv: Vec<[f32; 2]> = (0..positions.len() as u32)
        .map(|v| [(v / w * 17) as f32 / 512.0 * uv_scale, (v % w) as f32 / 32.0 * uv_scale])
        .collect();
    // Compressed along the axis: dx = -0.1 x at weight 1 (10 %).
    let squash: Vec<[f32; 3]> = positions.iter().map(|p| [-0.1 * p[0], 0.0, 0.0]).collect();
    let asset =
        gltf::Asset { positions, uv: Some(uv), indices, morphs: vec![("squash".into(), squash)], ..Default::default() };
    gltf::write(&dir, "tube", &asset);
    let scene_path = dir.join("squash.ron");
    std::fs::write(&scene_path, SQUASH_SCENE).unwrap();
    let built = scene::load(&scene_path).unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(&built);
    let clock = Instant::now();
    for frame in 1..=built.scene.frames {
        let s = sim.step();
        assert!(sim.failure().is_none(), "UVs x {uv_scale}, frame {frame}: {:?}", sim.failure());
        assert!(s.patches.iter().all(|p| p.outcome.converged), "UVs x {uv_scale}, frame {frame}: {:?}", s.patches);
    }
    let seconds_per_frame = clock.elapsed().as_secs_f64() / f64::from(built.scene.frames);
    // The skin is the surface's offset, vertex for vertex (the same faces over the same order).
    let (material, skin, skin_faces) = sim.layer_surface("strip", "skin");
    let (surface_material, surface, faces) = sim.layer_surface("strip", "surface");
    assert_eq!((skin_faces.len(), skin.len()), (faces.len(), surface.len()));
    assert!(skin_faces == faces && material == surface_material, "the skin is the surface's offset");
    // Heights of the skin over the surface along the surface's normals.
    let normals = vertex_normals(&surface, &faces);
    let lifted: Vec<DVec3> =
        skin.iter().zip(&surface).zip(&normals).map(|((s, b), n)| DVec3::new(0.0, 0.0, (*s - *b).dot(*n))).collect();
    let (lo, hi) = lifted.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.z), b.max(p.z)));
    // Rows of one material v (around the tube: lines along the axis), profiled against the
    // surface's deformed axial coordinate (engine x), and against the material u.
    let axial: Vec<DVec2> = material.iter().zip(&surface).map(|(m, p)| DVec2::new(p.x, m.y)).collect();
    let wavelength_3d = row_peaks(&lifted, &axial, 0, 0.05)[0].wavelength;
    let wavelength_material = row_peaks(&lifted, &material, 0, 0.05)[0].wavelength;
    // The compression the surface reached: its axial extent against its material extent.
    let extent = |x: &mut dyn Iterator<Item = f64>| {
        let (a, b) = x.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        b - a
    };
    let strain = 1.0 - extent(&mut surface.iter().map(|p| p.x)) / extent(&mut material.iter().map(|m| m.x));
    println!(
        "squash, UVs x {uv_scale}: {} skin vertices, {seconds_per_frame:.2} s/frame; axial compression {:.2} %, \
         height swing {:.3} mm; dominant wavelength {:.3} mm in 3D, {:.3} mm in material space (kernels {LAMBDA} mm)",
        skin.len(),
        100.0 * strain,
        1e3 * (hi - lo),
        1e3 * wavelength_3d,
        1e3 * wavelength_material
    );
    // Wrinkled, or the wavelength would be noise's (measured: a 2.68 mm swing, crests 0.5-1 mm
    // high every 6 mm or so along the middle row).
    assert!(hi - lo > 0.5e-3, "UVs x {uv_scale}: no wrinkles (height swing {} mm)", 1e3 * (hi - lo));
    // The morph compressed the surface 10 % in 3D (measured 9.93 %: length-true material space
    // scales the faceted 32-gon's area, whose perimeter is 0.16 % short of the circle's, so
    // material lengths are 0.08 % short), and the 3D wavelength is the material one compressed
    // alike (measured 5.759 against 6.398 x 0.9007 = 5.763 mm): rows were measured in 3D.
    assert!((strain - 0.1).abs() < 0.002, "UVs x {uv_scale}: compression {strain}");
    let compressed = wavelength_material * (1.0 - strain);
    assert!((wavelength_3d / compressed - 1.0).abs() < 0.01, "UVs x {uv_scale}: {wavelength_3d} vs {compressed}");
    let _ = std::fs::remove_dir_all(&dir);
    Squash { material, wavelength_3d, seconds_per_frame }
}

#[test]
fn wrinkles_keep_their_length_whatever_the_uv_scale() {
    let atlas = squash(1.0);
    let scaled = squash(1000.0);
    // Material space is length-true per UV island: the same coordinates whatever the UV scale.
    let (lo, hi) = skinsim::mesh::bounds(&atlas.material);
    let span = (hi - lo).max_element();
    let off = atlas.material.iter().zip(&scaled.material).map(|(a, b)| a.distance(*b)).fold(0.0, f64::max);
    let (l3, l3s) = (1e3 * atlas.wavelength_3d, 1e3 * scaled.wavelength_3d);
    println!(
        "squash: material coordinates {:.1e} of the patch's {:.2} mm apart between UVs x 1 and x 1000; dominant \
         wavelength in 3D {l3:.3} mm and {l3s:.3} mm ({:+.2} % of lambda, {:.1e} apart); {:.2} s/frame",
        off / span,
        1e3 * span,
        100.0 * (l3 / LAMBDA - 1.0),
        (l3s / l3 - 1.0).abs(),
        0.5 * (atlas.seconds_per_frame + scaled.seconds_per_frame)
    );
    assert_eq!(atlas.material.len(), scaled.material.len());
    // Material coordinates measured 1.9e-16 of the patch apart (UVs scaled by 1000 exactly, see
    // SQUASH_RADIUS); raw UVs taken for metres would be 1000 times apart.
    assert!(off <= 1e-9 * span, "material coordinates {off:e} m apart");
    // The issue's tolerance: the kernels' wavelength to 10 %, measured in 3D. Measured 5.759 mm
    // (-4.0 %). Issue 62's first session, with the shells' predictor: 5.712 mm, and with the
    // perturbation's seed 1, 5, 11 or 12 instead of 3: 6.264, 5.765, 5.989, 6.060 mm (-3.9 to
    // +4.4 %), so the band's edges are about 5 % from every measurement. (In
    // material space the same runs measure 6.35-6.97 mm, up to +16 %: it is in 3D that the
    // wrinkles sit at the kernels' wavelength; finger_quick's 0.9-1.4 band is in material space.)
    assert!((l3 / LAMBDA - 1.0).abs() <= 0.10, "wavelength {l3:.3} mm against {LAMBDA} mm");
    // The same asset with its UVs x 1000: the same material space to round-off (above), so the
    // same kernels; the buckled sheet it reaches then differs as a perturbation's seed makes it
    // differ. Measured 5.832 against 5.759 mm (1.3 % apart; seeds spread the wavelength over
    // 8 %, above). With each frame's shells moved along with their surface before the solve
    // (issue 62's first session; removed, `src/solve/README.md`) the two runs had ended 1.3e-15
    // apart; 3 % here.
    assert!((l3s / LAMBDA - 1.0).abs() <= 0.10, "UVs x 1000: wavelength {l3s:.3} mm against {LAMBDA} mm");
    assert!((l3s / l3 - 1.0).abs() <= 0.03, "UVs x 1000: {l3s:.3} mm against {l3:.3} mm");
}

/// Test 2's scene (millimetres): the tube compressed 10 % along its axis by its morph target in
/// 8 frames; a 112.5-degree strip of its top, 37.5 mm long, refined twice (0.74 x 0.78 mm cells,
/// as finger_quick's), and one thin shell (4 MPa, 0.1 mm: h / lambda = 0.017, thin against its
/// kernels) held to it by geodesic kernels.
const SQUASH_SCENE: &str = r#"Scene(
    name: "squash",
    units: (length: Millimetre, stress: MegaPascal),
    frames: 8,
    bodies: [
        Body(
            name: "tube",
            mesh: Gltf(path: "tube.gltf"),
            drivers: [Rig(layer: "tube", morphs: [MorphKeys(target: "squash", keyframes: [(0, 0.0), (8, 1.0)])])],
        ),
    ],
    patches: [
        Patch(
            name: "strip",
            body: "tube",
            solver: (tolerance: 1e-8, max_iterations: 200, projection: None,
                     perturbation: Some((amplitude: 0.00375, seed: 3))),
            layers: [
                Layer(name: "surface", kind: Kinematic,
                      mesh: Offset(layer: "tube", distance: 0.0,
                                   region: Box(min: (-19.0, -16.0, 7.0), max: (19.0, 16.0, 16.0)),
                                   refine: Levels(2))),
                Layer(name: "skin", kind: Shell,
                      mesh: Offset(layer: "surface", distance: 0.05),
                      material: (model: BazantHencky, young: 4.0, poisson: 0.45, thickness: 0.1),
                      bending: Some((model: Tan))),
            ],
            couplings: [
                Coupling(upper: "skin", lower: "surface", wavelength: Constant(6.0), seed: 1, distance: Geodesic),
            ],
        ),
    ],
)
"#;
