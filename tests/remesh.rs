//! Adaptive remeshing in the engine (issue 5): a shell layer coarsens where it is flat and
//! refines where it wrinkles, its entities and relationships stay consistent, every new element
//! gets its rest data, the kernels follow, and the result is deterministic.

mod common;

use std::collections::HashSet;

use bevy_ecs::prelude::*;
use common::*;
use skinsim::model::*;
use skinsim_systems::Simulation;

const SCENE: &str = "lk14/remesh_one_layer_quick.ron";

fn layer(sim: &mut Simulation, name: &str) -> Entity {
    sim.world.query::<(Entity, &Layer)>().iter(&sim.world).find(|(_, l)| l.name == name).unwrap().0
}

/// The layer's entities agree with each other: faces and edges use live vertices of the layer,
/// faces are positive in material space and tile the patch, every face has rest data, every
/// interior edge a hinge, and the masses add up to density x thickness x area.
fn check_layer(sim: &mut Simulation, l: Entity, area: f64) {
    let w = &sim.world;
    let verts: HashSet<Entity> = w.get::<LayerVertices>(l).unwrap().entities().iter().copied().collect();
    let faces = w.get::<LayerFaces>(l).unwrap().entities().to_vec();
    let edges = w.get::<LayerEdges>(l).unwrap().entities().to_vec();
    let report = *w.get::<RemeshReport>(l).unwrap();
    assert_eq!((verts.len(), faces.len()), (report.vertices as usize, report.faces as usize));
    let uv = |v: Entity| w.get::<MaterialPos>(v).unwrap().0;
    let (mut total, mut volume) = (0.0, 0.0);
    let mut face_edges = HashSet::new();
    for &f in &faces {
        let t = w.get::<FaceVerts>(f).unwrap().0;
        assert!(t.iter().all(|v| verts.contains(v)), "a face uses a vertex of its layer");
        let u = t.map(uv);
        let a = 0.5 * (u[1] - u[0]).perp_dot(u[2] - u[0]);
        assert!(a > 0.0, "a face inverted in material space: {a}");
        total += a;
        volume += w.get::<FaceRest>(f).expect("rest data on every face").0.volume;
        for k in 0..3 {
            let mut e = [t[k], t[(k + 1) % 3]];
            e.sort();
            face_edges.insert(e);
        }
    }
    assert!((total / area - 1.0).abs() < 1e-9, "faces tile the patch: {total} against {area}");
    assert_eq!(edges.len(), face_edges.len(), "one edge entity per mesh edge");
    let mut hinges = 0;
    for &e in &edges {
        let mut v = w.get::<EdgeVerts>(e).unwrap().0;
        v.sort();
        assert!(face_edges.contains(&v));
        assert!(w.get::<EdgeOpposite>(e).is_none(), "PropertyResample made every hinge");
        if let Some(h) = w.get::<Hinge>(e) {
            assert!(h.opposite.iter().all(|o| verts.contains(o)));
            hinges += 1;
        }
    }
    let boundary = face_edges.len() * 2 - faces.len() * 3;
    assert_eq!(hinges, face_edges.len() - boundary.min(face_edges.len()), "a hinge on every interior edge");
    let density = w.get::<Material>(l).unwrap().density;
    let mass: f64 = verts.iter().map(|&v| w.get::<Mass>(v).unwrap().0).sum();
    assert!((mass / (density * volume) - 1.0).abs() < 1e-9, "lumped masses: {mass}");
}

#[test]
fn a_remeshed_layer_coarsens_where_flat_refines_where_it_wrinkles_and_converges() {
    let scene = load(SCENE);
    let mut sim = Simulation::new(&scene);
    let dermis = layer(&mut sim, "dermis");
    let start = sim.world.get::<LayerVertices>(dermis).unwrap().entities().len();
    let mut counts = Vec::new();
    for frame in 0..scene.scene.frames {
        let s = sim.step();
        let p = &s.patches[0];
        assert!(p.converged, "frame {frame}: {p:?}");
        assert!(p.constraint_violation < 1e-9, "frame {frame}: {}", p.constraint_violation);
        assert!(s.timing("remesh") > 0.0 && s.timing("property_resample") > 0.0);
        check_layer(&mut sim, dermis, 24e-3 * 12e-3);
        assert!(check_weights(&mut sim) > 0, "kernels resampled and centred on the new mesh");
        counts.push(sim.world.get::<RemeshReport>(dermis).unwrap().vertices);
    }
    println!("dermis vertices: start {start}, per frame {counts:?}");
    assert!((counts[0] as usize) < start / 2, "the flat first frame coarsens: {start} -> {}", counts[0]);
    assert!(counts[5] > 2 * counts[0], "the wrinkles refine: {counts:?}");
}

#[test]
fn remesh_stages_run_only_for_layers_that_ask() {
    let mut scene = load("lk14/fig6_3_one_layer_quick.ron");
    scene.scene.frames = 1;
    let (_, stats) = run(&scene);
    assert_eq!(stats[0].timing("remesh"), 0.0);
    assert_eq!(stats[0].timing("property_resample"), 0.0);
}

#[test]
fn remeshing_is_deterministic() {
    let mut scene = load(SCENE);
    scene.scene.frames = 3;
    let positions = |sim: &mut Simulation| -> Vec<[u64; 3]> {
        let dermis = layer(sim, "dermis");
        let verts = sim.world.get::<LayerVertices>(dermis).unwrap().entities().to_vec();
        verts.iter().map(|&v| sim.world.get::<Position>(v).unwrap().0.to_array().map(f64::to_bits)).collect()
    };
    let (mut a, _) = run(&scene);
    let (mut b, _) = run(&scene);
    assert_eq!(positions(&mut a), positions(&mut b));
}

/// The remesh scene compressed over three frames, then held; remeshed at frames 0 and 4 only,
/// so that frame 4's start (after the remesh, before its solve) differs from frame 3's end only
/// by the remesh.
fn held_then_remeshed(curved: bool, adjust: bool, every: u32) -> (f64, f64) {
    let text = std::fs::read_to_string(scene_path(SCENE))
        .unwrap()
        .replace("weights: [(0, 0.0), (6, 1.0)]", "weights: [(0, 0.0), (3, 1.0)]")
        .replace(
            "refine_compression: 0.2)",
            &format!("refine_compression: 0.2, every: {every}, curved_splits: {curved})"),
        )
        .replace("seed: 1)", &format!("seed: 1, adjust: {adjust})"));
    let scene = skinsim::scene::load_str(&text, &scene_path(SCENE)).unwrap_or_else(|e| panic!("{e}"));
    let (_, stats) = run(&scene);
    let (before, after) = (&stats[3].patches[0], &stats[4].patches[0]);
    assert!(before.converged && after.converged);
    ((after.start_energy - before.energy) / before.energy, after.start_violation)
}

/// Issue 5 points 3 and 4, measured at a remesh of a held patch (the numbers are printed):
/// - the energy jump, with split midpoints on the curved surface against on the straight edge,
///   after four frames without remeshing (measured 0.31 against 2.35 of the energy; remeshing
///   every frame, 0.032 against 0.036: most of that pop is the collapses and flips);
/// - the constraint jump (LK14 4.2): remeshing every frame, with the kernel adjustment the
///   constraints move 6.3e-5 of the patch size, without it 4.3e-4. The adjustment removes the
///   first-order jump (the weights' centroid); what is left is second order, the kernel's
///   second moments over a wrinkled surface.
#[test]
fn remesh_jumps_in_energy_and_constraints() {
    let (pop_curved, _) = held_then_remeshed(true, true, 4);
    let (pop_straight, _) = held_then_remeshed(false, true, 4);
    let (_, jump_adjusted) = held_then_remeshed(true, true, 1);
    let (_, jump_raw) = held_then_remeshed(true, false, 1);
    println!(
        "energy jump at a remesh after 4 frames: curved splits {pop_curved:.3e}, straight {pop_straight:.3e}; \
         constraint jump at an every-frame remesh (relative to the patch size): adjusted {jump_adjusted:.3e}, \
         not adjusted {jump_raw:.3e}"
    );
    assert!(pop_curved.abs() < 0.5 * pop_straight.abs(), "{pop_curved} against {pop_straight}");
    assert!(jump_adjusted < 0.25 * jump_raw, "{jump_adjusted} against {jump_raw}");
}

/// The remesh scene with text replacements, loaded as if it sat in `dir`.
fn variant(dir: &std::path::Path, edits: &[(&str, &str)]) -> skinsim::scene::BuiltScene {
    let mut text = std::fs::read_to_string(scene_path(SCENE)).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{from}");
        text = text.replace(from, to);
    }
    skinsim::scene::load_str(&text, &dir.join("scene.ron")).unwrap_or_else(|e| panic!("{e}"))
}

/// Runs a scene and checks every frame: converged, the constraints held, the layer consistent.
fn run_checked(scene: &skinsim::scene::BuiltScene) -> Simulation {
    let mut sim = Simulation::new(scene);
    let dermis = layer(&mut sim, "dermis");
    for frame in 1..=scene.scene.frames {
        let s = sim.step();
        let p = &s.patches[0];
        assert!(p.converged && p.energy.is_finite(), "frame {frame}: {p:?}");
        assert!(p.constraint_violation < 1e-9, "frame {frame}: {}", p.constraint_violation);
        check_layer(&mut sim, dermis, 24e-3 * 12e-3);
    }
    sim
}

/// Hard case (issue 5 point 8): remeshing while the base is compressed to half its length.
#[test]
fn remeshing_through_compression_to_half() {
    let scene = variant(&scratch_dir("remesh"), &[("strain: 0.1)", "strain: 0.5)")]);
    let mut sim = run_checked(&scene);
    let dermis = layer(&mut sim, "dermis");
    let report = *sim.world.get::<RemeshReport>(dermis).unwrap();
    println!("compressed to 50 %: {report:?}");
    assert!(report.vertices > 1000, "the folds refined: {report:?}");
}

/// Hard case: a property map with a sharp step (Young's modulus x1 on the left half, x8 on the
/// right, across one pixel of 64): new faces sample it, and both sides stay consistent.
#[test]
fn remeshing_over_a_sharp_property_step() {
    let dir = scratch_dir("remesh");
    let step = image::RgbImage::from_fn(64, 4, |x, _| image::Rgb(if x < 32 { [0, 0, 0] } else { [255, 255, 255] }));
    step.save(dir.join("step.png")).unwrap();
    let scene = variant(
        &dir,
        &[(
            "bending: Some((model: Tan)),",
            r#"bending: Some((model: Tan)), properties: Some((map: Png("step.png"), young: Some((1.0, 8.0)))),"#,
        )],
    );
    let mut sim = run_checked(&scene);
    let dermis = layer(&mut sim, "dermis");
    let faces = sim.world.get::<LayerFaces>(dermis).unwrap().entities().to_vec();
    let scales: Vec<f64> = faces.iter().map(|&f| sim.world.get::<ModulusScale>(f).expect("sampled").0).collect();
    let (lo, hi) = scales.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &s| (a.min(s), b.max(s)));
    assert!((lo - 1.0).abs() < 1e-9 && (hi - 8.0).abs() < 1e-9, "both sides sampled: {lo} .. {hi}");
}

/// Hard case: kernels a coarse mesh would leave with fewer than three vertices (radius 1.3 mm
/// under a 2 mm size_max). The remesher caps its edges at half the smallest kernel radius on
/// the layer, so every support can still be adjusted and every frame converges.
#[test]
fn small_kernels_keep_adjustable_supports() {
    let scene = variant(&scratch_dir("remesh"), &[("Constant(8.0)", "Constant(2.2)")]);
    let mut sim = run_checked(&scene);
    let dermis = layer(&mut sim, "dermis");
    let report = *sim.world.get::<RemeshReport>(dermis).unwrap();
    let mut kernels = sim.world.query::<&Kernel>();
    let radius = kernels.iter(&sim.world).map(|k| k.shape.radius).fold(f64::INFINITY, f64::min);
    assert!((report.size_max - 0.5 * radius).abs() < 1e-12, "size_max capped at radius / 2: {report:?}, {radius}");
    let mut q = sim.world.query::<&KernelWeights>();
    let states: Vec<_> = q.iter(&sim.world).map(|w| w.adjusted[0]).collect();
    assert!(states.iter().all(|s| *s == Some(skinsim::coupling::kernels::Adjusted::Centred)), "{states:?}");
}
