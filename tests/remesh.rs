//! Adaptive remeshing in the engine (issue 5): a shell layer coarsens where it is flat and
//! refines where it wrinkles, its entities and relationships stay consistent, every new element
//! gets its rest data, the kernels follow, and the result is deterministic.

mod common;

use std::collections::HashSet;

use bevy_ecs::prelude::*;
use common::*;
use skinsim::model::*;
use skinsim::solve::PackedPatch;
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
    if report.frame > 0 {
        assert_eq!((verts.len(), faces.len()), (report.vertices as usize, report.faces as usize));
    }
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
    // (as PropertyResample lumps them; spawn lumps over the flat material area)
    if report.frame > 0 {
        assert!((mass / (density * volume) - 1.0).abs() < 1e-9, "lumped masses: {mass}");
    }
}

/// The first frame runs on the scene's mesh; the remeshes after it coarsen the flat parts and
/// refine the wrinkles (measured: the largest face 2.0x the start's mean area, the smallest 0.26x).
#[test]
fn a_remeshed_layer_coarsens_where_flat_refines_where_it_wrinkles_and_converges() {
    let scene = load(SCENE);
    let mut sim = Simulation::new(&scene);
    let dermis = layer(&mut sim, "dermis");
    let start = sim.world.get::<LayerVertices>(dermis).unwrap().entities().len();
    let areas = |sim: &Simulation| -> Vec<f64> {
        let w = &sim.world;
        let uv = |v: Entity| w.get::<MaterialPos>(v).unwrap().0;
        let faces = w.get::<LayerFaces>(dermis).unwrap().entities();
        let area = |t: [Entity; 3]| 0.5 * (uv(t[1]) - uv(t[0])).perp_dot(uv(t[2]) - uv(t[0]));
        faces.iter().map(|&f| area(w.get::<FaceVerts>(f).unwrap().0)).collect()
    };
    let mean_start = areas(&sim).iter().sum::<f64>() / areas(&sim).len() as f64;
    let mut counts = Vec::new();
    for frame in 1..=scene.scene.frames {
        let s = sim.step();
        let p = &s.patches[0];
        assert!(p.outcome.converged, "frame {frame}: {p:?}");
        assert!(p.outcome.constraint_violation < 1e-9, "frame {frame}: {}", p.outcome.constraint_violation);
        check_layer(&mut sim, dermis, 24e-3 * 12e-3);
        assert!(check_weights(&mut sim) > 0, "kernels resampled and centred on the new mesh");
        let report = *sim.world.get::<RemeshReport>(dermis).unwrap();
        // The first frame is solved on the scene's mesh; every later one is remeshed first.
        assert_eq!(report.frame, if frame == 1 { 0 } else { frame as u64 }, "{report:?}");
        assert!(frame == 1 || s.timing(Stage::Remesh) > 0.0 && s.timing(Stage::PropertyResample) > 0.0);
        counts.push(sim.world.get::<LayerVertices>(dermis).unwrap().entities().len());
    }
    let a = areas(&sim);
    let (small, large) = a.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &x| (lo.min(x), hi.max(x)));
    println!("dermis vertices: start {start}, per frame {counts:?}; face areas {small:.3e} .. {large:.3e} (start mean {mean_start:.3e})");
    assert_eq!(counts[0], start, "frame 1 on the scene's mesh");
    assert!(large > 1.5 * mean_start, "flat parts coarsened: {large:.3e} against {mean_start:.3e}");
    assert!(small < 0.5 * mean_start, "the wrinkles refined: {small:.3e} against {mean_start:.3e}");
}

#[test]
fn remesh_stages_run_only_for_layers_that_ask() {
    let mut scene = load("lk14/fig6_3_one_layer_quick.ron");
    scene.scene.frames = 1;
    let (_, stats) = run(&scene);
    assert_eq!(stats[0].timing(Stage::Remesh), 0.0);
    assert_eq!(stats[0].timing(Stage::PropertyResample), 0.0);
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

/// The remesh scene with `edits`, run to frame `at`: the jumps, in energy (relative) and in the
/// constraints (relative to the patch size), from frame `at - 1`'s solution to frame `at`'s start
/// (after its remesh, before its solve). The edits hold the base still over those frames, so the
/// remesh is all that moves.
fn jump_at_remesh(edits: &[(&str, &str)], at: usize) -> (f64, f64) {
    let mut scene = variant(&scratch_dir("remesh"), edits);
    scene.scene.frames = at as u32;
    let (_, stats) = run(&scene);
    let (before, after) = (&stats[at - 2].patches[0], &stats[at - 1].patches[0]);
    assert!(before.outcome.converged && after.outcome.converged);
    ((after.outcome.start_energy - before.outcome.energy) / before.outcome.energy, after.outcome.start_violation)
}

/// Issue 5 points 3 and 4, measured at a remesh of a held patch (the numbers are printed):
/// - the energy jump right after the first remesh of a 12 x 7 start wrinkled by the whole
///   compression in frame 1, refined at frame 2: split midpoints on the straight edge, on the
///   curved surface, and on the curved surface then settled (the default). Measured +1.68,
///   +0.069 and -0.12 of the energy: settling starts the solve below the last frame's energy;
/// - the constraint jump (LK14 4.2): compressed over three frames and held, remeshed every
///   frame, at frame 5: with the kernel adjustment the constraints move 3.0e-5 of the patch
///   size, without it 3.8e-4. The adjustment removes the first-order jump (the weights'
///   centroid); what is left is second order, the kernel's second moments over a wrinkled
///   surface. The settle keeps the kernels' values (without that: 6.8e-5, 0.16 of the raw
///   jump; the bound below is 0.12).
#[test]
fn remesh_jumps_in_energy_and_constraints() {
    let pop = |placement: &str| {
        let splits = format!("refine_compression: 0.2, {placement})");
        let edits = [
            ("weights: [(0, 0.0), (6, 1.0)]", "weights: [(0, 0.0), (1, 1.0)]"),
            ("cells: (24, 14), pattern: Equilateral, z: 0.5", "cells: (12, 7), pattern: Equilateral, z: 0.5"),
            ("refine_compression: 0.2)", splits.as_str()),
        ];
        jump_at_remesh(&edits, 2).0
    };
    let pop_straight = pop("curved_splits: false, settle: false");
    let pop_curved = pop("settle: false");
    let pop_settled = pop("settle: true");
    let jump = |adjust: &str| {
        let adjusted = format!("seed: 1, adjust: {adjust})");
        let edits =
            [("weights: [(0, 0.0), (6, 1.0)]", "weights: [(0, 0.0), (3, 1.0)]"), ("seed: 1)", adjusted.as_str())];
        jump_at_remesh(&edits, 5).1
    };
    let (jump_adjusted, jump_raw) = (jump("true"), jump("false"));
    println!(
        "energy jump at the first remesh of a coarse wrinkled start: straight splits {pop_straight:.3e}, curved \
         {pop_curved:.3e}, curved and settled {pop_settled:.3e}; constraint jump at an every-frame remesh (relative \
         to the patch size): adjusted {jump_adjusted:.3e}, not adjusted {jump_raw:.3e}"
    );
    assert!(pop_curved.abs() < 0.2 * pop_straight.abs(), "{pop_curved} against {pop_straight}");
    assert!(pop_settled <= 0.0 && pop_settled < pop_curved, "{pop_settled} against {pop_curved}");
    assert!(jump_adjusted < 0.12 * jump_raw, "{jump_adjusted} against {jump_raw}");
}

/// Hard case (issue 5 points 3 and 8): the LK14 fig. 3-3 strip (case 10) solved on 4 elements
/// per wavelength to 8 % compression, then refined about fourfold. Without settling, the
/// curved midpoints raised the energy 6x and the solve ended in a folded state (dihedral
/// angles up to 2.45 rad, energy 7x the uniform 192 x 27 run's, 174 Newton iterations in that
/// frame). Settled: energy x1.26 at the remesh, no fold (largest dihedral angle 0.38 rad, the
/// uniform run's 0.51).
#[test]
fn refining_a_coarse_wrinkled_strip_does_not_fold_it() {
    let mut text = std::fs::read_to_string(scene_path("lk14/fig3_3_e1_h1_quick.ron")).unwrap();
    for (from, to) in [
        ("seed: 3))", "seed: 3, cell: 3.0))"),
        ("cells: (128, 18), pattern: Equilateral, z: 0.01875", "cells: (64, 9), pattern: Equilateral, z: 0.01875"),
        (
            "bending: Some((model: Tan))),",
            "bending: Some((model: Tan)), remesh: Some((size_min: 0.25, size_max: 3, refine_angle: 0.2, \
             refine_compression: 0.02, every: 3))),",
        ),
    ] {
        assert!(text.contains(from), "{from}");
        text = text.replace(from, to);
    }
    let scene = skinsim::scene::load_str(&text, &scratch_dir("remesh").join("strip.ron")).unwrap();
    let (mut sim, stats) = run(&scene);
    let p: Vec<_> = stats.iter().map(|s| &s.patches[0]).collect();
    assert!(p.iter().all(|p| p.outcome.converged), "{p:?}");
    let (uv, x, faces) = sim.layer_mesh("skin", "skin");
    assert!(uv.len() > 4 * 655, "refined about fourfold from 655 vertices: {}", uv.len());
    let normal = |f: &[u32; 3]| {
        let [a, b, c] = f.map(|i| x[i as usize]);
        (b - a).cross(c - a).normalize()
    };
    let dihedral = skinsim::mesh::edges(&faces)
        .iter()
        .filter(|e| e.is_interior())
        .map(|e| normal(&faces[e.faces[0] as usize]).angle_between(normal(&faces[e.faces[1] as usize])))
        .fold(0.0f64, f64::max);
    // The remesh before frame 5 refines the wrinkled strip.
    let pop = p[4].outcome.start_energy / p[3].outcome.energy;
    println!("coarse to fine: energy at the remesh x{pop:.2}, largest dihedral angle {dihedral:.3} rad");
    assert!(pop < 1.5, "no pop: x{pop}");
    assert!(dihedral < 0.6, "no fold: {dihedral} rad");
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

/// Runs a scene and checks every frame (`step_checked`).
fn run_checked(scene: &skinsim::scene::BuiltScene) -> Simulation {
    let mut sim = Simulation::new(scene);
    let dermis = layer(&mut sim, "dermis");
    for frame in 1..=scene.scene.frames {
        step_checked(&mut sim, frame, dermis);
    }
    sim
}

/// One frame of the remesh scene, checked: converged, the constraints held, the layer
/// consistent.
fn step_checked(sim: &mut Simulation, frame: u32, dermis: Entity) -> PatchReport {
    let s = sim.step();
    let p = s.patches[0].clone();
    assert!(p.outcome.converged && p.outcome.energy.is_finite(), "frame {frame}: {p:?}");
    assert!(p.outcome.constraint_violation < 1e-9, "frame {frame}: {}", p.outcome.constraint_violation);
    check_layer(sim, dermis, 24e-3 * 12e-3);
    p
}

/// Hard case (issue 5 point 8): remeshing while the base is compressed to half its length.
/// The quadratic bending element on a remeshed layer: its per-vertex elements are rebuilt from
/// the new mesh (one per interior vertex, no hinges), and every frame converges with the
/// constraints held and the layer consistent.
#[test]
fn a_remeshed_layer_bends_with_quadratic_elements() {
    let quadratic = "bending: Some((model: Tan, element: Quadratic)),";
    let scene = variant(&scratch_dir("remesh"), &[("bending: Some((model: Tan)),", quadratic)]);
    let mut sim = run_checked(&scene);
    let (_, _, faces) = sim.layer_mesh("skin", "dermis");
    let mut interior: HashSet<u32> = faces.iter().flatten().copied().collect();
    for e in skinsim::mesh::edges(&faces).iter().filter(|e| !e.is_interior()) {
        interior.remove(&e.v[0]);
        interior.remove(&e.v[1]);
    }
    let mut q = sim.world.query::<&PackedPatch>();
    let body = q.single(&sim.world).unwrap();
    println!(
        "quadratic elements after remeshing: {} ({} interior vertices)",
        body.elements.quadratic.len(),
        interior.len()
    );
    assert!(body.elements.hinges.is_empty());
    assert_eq!(body.elements.quadratic.len(), interior.len());
    // and its Gaussian term on every face with an interior corner
    let touching = faces.iter().filter(|f| f.iter().any(|v| interior.contains(v))).count();
    assert_eq!(body.elements.gaussian.len(), touching);
    let dermis = layer(&mut sim, "dermis");
    assert!(sim.world.get::<RemeshReport>(dermis).unwrap().frame > 0);
}

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

/// Issue 5 point 3: a prestrain is carried across remeshes. After every frame each face of the
/// remeshed layer, spawned with the scene or made by a remesh, holds the layer's prestrain in
/// its own rest frame (an anisotropic stretch, so the frame matters), and each hinge the
/// prestrain's rest curvature.
#[test]
fn a_remeshed_layer_keeps_its_prestrain() {
    use skinsim::physics::prestrain::hinge_with_curvature;
    let prestrain = "thickness: 1.0), prestrain: (stretch: (1.03, 0.99, 1.0), curvature: 0.02, curvature_along: Y),";
    let scene = variant(&scratch_dir("remesh"), &[("thickness: 1.0),", prestrain)]);
    let mut sim = Simulation::new(&scene);
    let dermis = layer(&mut sim, "dermis");
    let p = sim.world.get::<LayerPrestrain>(dermis).expect("kept on a remeshed layer").clone();
    let bending = *sim.world.get::<Bending>(dermis).unwrap();
    for frame in 1..=3 {
        let s = sim.step();
        assert!(s.patches[0].outcome.converged, "frame {frame}: {:?}", s.patches[0]);
        let w = &sim.world;
        let rest = |v: Entity| w.get::<RestPos>(v).unwrap().0;
        let uv = |v: Entity| w.get::<MaterialPos>(v).unwrap().0;
        let faces = w.get::<LayerFaces>(dermis).unwrap().entities().to_vec();
        for &f in &faces {
            let tri = w.get::<FaceVerts>(f).unwrap().0;
            let f0 = w.get::<FacePrestrain>(f).expect("every face prestrained").0;
            let expected = p.face_f0(tri.map(rest), tri.map(uv).iter().sum::<glam::DVec2>() / 3.0);
            assert!(f0.abs_diff_eq(expected, 1e-12), "frame {frame}: {f0:?} against {expected:?}");
        }
        let mut hinges = 0;
        for &e in w.get::<LayerEdges>(dermis).unwrap().entities() {
            let (Some(ends), Some(h)) = (w.get::<EdgeVerts>(e), w.get::<Hinge>(e)) else { continue };
            let q = [ends.0[0], ends.0[1], h.opposite[0], h.opposite[1]].map(rest);
            let stiffness = h.rest.weight / hinge_with_curvature(bending.model, 1.0, q, 0.0, 0).weight;
            let expected = hinge_with_curvature(bending.model, stiffness, q, p.curvature, p.along);
            assert!((h.rest.rest_phi - expected.rest_phi).abs() < 1e-9, "frame {frame}: hinge rest {:?}", h.rest);
            hinges += 1;
        }
        let report = *w.get::<RemeshReport>(dermis).unwrap();
        assert!(frame == 1 || report.stats.splits + report.stats.collapses > 0, "frame {frame} remeshed: {report:?}");
        assert!(hinges > 0);
    }
}

/// A smooth perturbation (`cell`) depends on the material point, not on the mesh: a grid and its
/// 2x refinement put the same imperfection at the points they share.
#[test]
fn a_smooth_perturbation_is_the_same_on_every_mesh() {
    let dir = scratch_dir("remesh");
    let smooth = |cells: &str| {
        variant(
            &dir,
            &[("seed: 3))", "seed: 3, cell: 3.3))"), ("cells: (24, 14), pattern: Equilateral, z: 0.5", cells)],
        )
    };
    let heights = |cells: &str| -> Vec<(glam::DVec2, f64)> {
        let sim = Simulation::new(&smooth(cells));
        let mut w = sim.world;
        let dermis = w.query::<(Entity, &Layer)>().iter(&w).find(|(_, l)| l.name == "dermis").unwrap().0;
        let verts = w.get::<LayerVertices>(dermis).unwrap().entities().to_vec();
        verts.iter().map(|&v| (w.get::<MaterialPos>(v).unwrap().0, w.get::<RestPos>(v).unwrap().0.z)).collect()
    };
    let coarse = heights("cells: (12, 6), z: 0.5");
    let fine = heights("cells: (24, 12), z: 0.5");
    let mut shared = 0;
    let spread = coarse.iter().map(|c| (c.1 - 0.5e-3).abs()).fold(0.0, f64::max);
    for (uv, z) in &coarse {
        let Some((_, zf)) = fine.iter().find(|f| f.0.distance(*uv) < 1e-12) else { continue };
        assert!((z - zf).abs() < 1e-15 * (1.0 + z.abs()), "at {uv}: {z} against {zf}");
        shared += 1;
    }
    assert_eq!(shared, coarse.len(), "every coarse vertex is a fine one");
    assert!(spread > 2e-7, "the field perturbs: {spread}");

    // A remesh gives its new vertices the field at their own material point.
    let mut sim = Simulation::new(&smooth("cells: (24, 14), pattern: Equilateral, z: 0.5"));
    let dermis = layer(&mut sim, "dermis");
    let imperfection = sim.world.get::<LayerImperfection>(dermis).expect("kept on a remeshed layer").0.clone();
    let before: HashSet<Entity> = sim.world.get::<LayerVertices>(dermis).unwrap().entities().iter().copied().collect();
    for _ in 0..4 {
        sim.step();
    }
    let w = &sim.world;
    let verts = w.get::<LayerVertices>(dermis).unwrap().entities().to_vec();
    let new: Vec<Entity> = verts.into_iter().filter(|v| !before.contains(v)).collect();
    for &v in &new {
        let (uv, z) = (w.get::<MaterialPos>(v).unwrap().0, w.get::<RestPos>(v).unwrap().0.z);
        assert!((z - 0.5e-3 - imperfection.at(uv)).abs() < 1e-12, "at {uv}: {z} against {}", imperfection.at(uv));
    }
    assert!(new.len() > 10, "{} new vertices", new.len());
}

/// A film on a base, joined by an Attach driver, one of them remeshed (issue 22): `attached`
/// holds the springs, `to` is the other layer.
fn attached_scene(attached: &str, to: &str, pin: bool) -> String {
    let remesh = "remesh: Some((size_min: 0.1, size_max: 1.0, refine_compression: 0.01))";
    let pin = if pin { r#"Pin(layer: "film", select: Sides([XMin])),"# } else { "" };
    format!(
        r#"Scene(name: "attach", frames: 5, patches: [Patch(name: "sheet",
            solver: (projection: Adaptive, perturbation: (amplitude: 0.001, seed: 1)),
            layers: [
                Layer(name: "base", kind: Kinematic, mesh: Grid(size: (8.0, 2.0), cells: (16, 4))),
                Layer(name: "film", kind: Shell, mesh: Grid(size: (8.0, 2.0), cells: (16, 4)),
                      material: (young: 10.0, poisson: 0.3, thickness: 0.1), bending: (model: Tan), {remesh}),
            ],
            drivers: [
                Compress(layers: ["base", "film"], keyframes: [(2, 0.0), (5, 0.05)]),
                Attach(layer: "{attached}", to: "{to}", stiffness: 0.0056),
                {pin}
            ],
        )])"#
    )
}

/// Attach with a remeshed layer, either way round, with and without a Pin: every frame
/// converges; after each remesh every spring is a face spring whose point on the other layer
/// sits at its vertex's rest (x, y), on live vertices; the remeshed film gets one spring per
/// vertex, a kept layer keeps its springs' count and stiffness; and the film stays on the base.
#[test]
fn attachments_follow_a_remesh_of_either_layer() {
    for (attached, to, pin) in [("film", "base", false), ("film", "base", true), ("base", "film", false)] {
        let text = attached_scene(attached, to, pin);
        let scene =
            skinsim::scene::load_str(&text, std::path::Path::new("attach.ron")).unwrap_or_else(|e| panic!("{e}"));
        let mut sim = Simulation::new(&scene);
        let (a_layer, b_layer) = (layer(&mut sim, attached), layer(&mut sim, to));
        let stiffness = |sim: &Simulation| -> f64 {
            let springs = sim.world.get::<LayerSprings>(a_layer).unwrap().entities().to_vec();
            springs
                .iter()
                .map(|&s| {
                    let e = sim.world.entity(s);
                    e.get::<Spring>()
                        .map(|s| s.stiffness)
                        .or_else(|| e.get::<FaceSpring>().map(|s| s.stiffness))
                        .unwrap()
                })
                .sum()
        };
        let k_start = stiffness(&sim);
        let n_start = sim.world.get::<LayerSprings>(a_layer).unwrap().entities().len();
        let mut worst_gap = 0.0f64;
        for frame in 1..=scene.scene.frames {
            let s = sim.step();
            assert!(s.patches[0].outcome.converged, "{attached} -> {to}, frame {frame}: {:?}", s.patches[0]);
            let w = &sim.world;
            let springs = w.get::<LayerSprings>(a_layer).unwrap().entities().to_vec();
            let a_verts: HashSet<Entity> =
                w.get::<LayerVertices>(a_layer).unwrap().entities().iter().copied().collect();
            let b_verts: HashSet<Entity> =
                w.get::<LayerVertices>(b_layer).unwrap().entities().iter().copied().collect();
            if frame == 1 {
                assert!(springs.iter().all(|&s| w.get::<Spring>(s).is_some()), "vertex pairs before any remesh");
                continue;
            }
            for &s in &springs {
                let sp = w.get::<FaceSpring>(s).expect("a face spring after a remesh");
                assert!(a_verts.contains(&sp.a) && sp.b.iter().all(|b| b_verts.contains(b)), "live vertices");
                let rest = |v: Entity| w.get::<RestPos>(v).unwrap().0;
                let on_b: glam::DVec3 = (0..3).map(|k| sp.w[k] * rest(sp.b[k])).sum();
                assert!(on_b.truncate().distance(rest(sp.a).truncate()) < 1e-9, "the point under the vertex");
                let pos = |v: Entity| w.get::<Position>(v).unwrap().0;
                let now: glam::DVec3 = (0..3).map(|k| sp.w[k] * pos(sp.b[k])).sum();
                worst_gap = worst_gap.max(now.distance(pos(sp.a)));
            }
            if attached == "film" {
                assert_eq!(springs.len(), a_verts.len(), "one spring per film vertex");
            } else {
                assert_eq!(springs.len(), n_start, "the kept layer's springs");
                assert!((stiffness(&sim) / k_start - 1.0).abs() < 1e-12);
            }
        }
        // (the film, 0.1 thick, wrinkles on its springs by a few hundredths)
        println!("{attached} -> {to} (pin {pin}): largest spring length {worst_gap:.3e}");
        assert!(worst_gap < 0.1, "{attached} -> {to}: the film left the base ({worst_gap})");
    }
}

/// Issue 26 item 1: with the wavelength term, the LK14 fig. 3-3 strip (case 10, lambda 6 mm)
/// started on 4 elements per wavelength is refined before its first solve, to at most lambda / 8
/// across the compression wherever the driver compresses it (all of it, at 0.1 % in frame 1),
/// and the solve on the refined mesh converges. Without the term the first frame runs on the
/// scene's mesh.
#[test]
fn the_wavelength_term_refines_before_the_first_solve() {
    let refine = |wavelength: &str| {
        let remesh = format!(
            "bending: Some((model: Tan)),\n                      remesh: Some((size_min: 0.25, size_max: 3.0, \
             refine_angle: 0.4, refine_compression: 0.05{wavelength}))),"
        );
        let edits = [
            ("cells: (128, 18), pattern: Equilateral, z: 0.01875", "cells: (64, 9), pattern: Equilateral, z: 0.01875"),
            ("bending: Some((model: Tan))),", remesh.as_str()),
        ];
        let mut text = std::fs::read_to_string(scene_path("lk14/fig3_3_e1_h1_quick.ron")).unwrap();
        for (from, to) in edits {
            assert!(text.contains(from), "{from}");
            text = text.replace(from, to);
        }
        let path = scratch_dir("wavelength").join("scene.ron");
        let mut scene = skinsim::scene::load_str(&text, &path).unwrap_or_else(|e| panic!("{e}"));
        scene.scene.frames = 1;
        let (mut sim, stats) = run(&scene);
        assert!(stats[0].patches[0].outcome.converged, "{:?}", stats[0].patches[0]);
        let skin = layer(&mut sim, "skin");
        let report = *sim.world.get::<RemeshReport>(skin).unwrap();
        let w = &sim.world;
        let uv = |v: Entity| w.get::<MaterialPos>(v).unwrap().0;
        let widest = w
            .get::<LayerEdges>(skin)
            .unwrap()
            .entities()
            .iter()
            .map(|&e| w.get::<EdgeVerts>(e).unwrap().0.map(uv))
            .map(|[a, b]| (a.x - b.x).abs())
            .fold(0.0f64, f64::max);
        (report, widest, stats[0].clone())
    };
    let (report, widest, first) = refine(", wavelength: Some((per_wavelength: 8, onset: 0.5))");
    println!("frame 1 remeshed: {report:?}; widest edge across the compression {widest:.3e} m");
    assert_eq!(report.frame, 1, "{report:?}");
    assert!(widest <= 6e-3 / 8.0 * (1.0 + 1e-9), "{widest}");
    // The layer was at rest: its new vertices start at their rest positions (no strain, so no
    // energy but round-off), and nothing is settled. (With the curved midpoints and the settle,
    // 1.9e-12 J here.)
    let start = first.patches[0].outcome.start_energy;
    assert!(start.abs() < 1e-15, "the refined strip starts strained: {start:e} J");
    assert_eq!(first.timing(Stage::Settle), 0.0, "a layer at rest was settled");
    let (report, widest, _) = refine("");
    assert_eq!(report.frame, 0, "no remesh before the first solve without the term");
    assert!(widest > 1.4e-3, "{widest}");
}

/// The LK14 fig. 6-4 pinch (quick) with its epidermis started at 48 x 28 cells and remeshed with
/// `remesh` (the fields of its `remesh: Some((..))`), in a scratch directory named `dir`.
fn pinch_with_remeshed_epidermis(dir: &str, remesh: &str) -> Simulation {
    let layer = format!(
        "cells: (48, 28), pattern: Equilateral, z: 1.0125),\n                      \
         material: (model: BazantHencky, young: 64.0, poisson: 0.45, thickness: 0.025),\n                      \
         bending: Some((model: Tan)), remesh: Some(({remesh})))"
    );
    let text = std::fs::read_to_string(scene_path("lk14/fig6_4_pinch_quick.ron")).unwrap();
    let from = "cells: (80, 46), pattern: Equilateral, z: 1.0125),\n                      \
                material: (model: BazantHencky, young: 64.0, poisson: 0.45, thickness: 0.025),\n                      \
                bending: Some((model: Tan)))";
    assert!(text.contains(from));
    let path = scratch_dir(dir).join("scene.ron");
    let scene = skinsim::scene::load_str(&text.replace(from, &layer), &path).unwrap_or_else(|e| panic!("{e}"));
    Simulation::new(&scene)
}

/// Issue 26 item 1, ahead of the load: with `lookahead` the first remesh (frame 1, before any
/// solve) reads the compression the kinematic base reaches at its blend shape's last keyframe
/// (the LK14 fig. 6-4 pinch, full at frame 6), so the epidermis is refined to lambda_2 / 8 in
/// every direction over the pinched disc and nowhere far from it; without it, the base is not
/// yet compressed and nothing is refined.
#[test]
fn the_lookahead_refines_where_the_driver_will_compress_before_the_load_gets_there() {
    let refine = |options: &str| {
        let mut sim = pinch_with_remeshed_epidermis(
            "lookahead",
            &format!(
                "size_min: 0.1, size_max: 1.0, refine_angle: 0.6, refine_compression: 0.05, \
                 wavelength: Some((per_wavelength: 8, onset: 0.5, isotropic: true{options}))"
            ),
        );
        // The Remesh stage alone, as in frame 1 (before the Motion stage moves the base).
        sim.world.resource_mut::<SimClock>().frame = 1;
        skinsim_systems::remesh::remesh_layers(&mut sim.world);
        let epidermis = layer(&mut sim, "epidermis");
        let w = &sim.world;
        let uv = |v: Entity| w.get::<MaterialPos>(v).unwrap().0;
        let centre = glam::DVec2::new(12e-3, 6e-3);
        // The longest edge (material length) with its midpoint within 4 mm of the pinch's
        // centre, and the shortest 8-10 mm from it (the disc's radius is 6 mm).
        let (mut inside, mut outside) = (0.0f64, f64::INFINITY);
        for &e in w.get::<LayerEdges>(epidermis).unwrap().entities() {
            let [a, b] = w.get::<EdgeVerts>(e).unwrap().0.map(uv);
            let d = ((a + b) / 2.0).distance(centre);
            if d < 4e-3 {
                inside = inside.max(a.distance(b));
            } else if (8e-3..10e-3).contains(&d) {
                outside = outside.min(a.distance(b));
            }
        }
        (inside, outside)
    };
    let (inside, outside) = refine(", lookahead: true");
    println!("lookahead: longest edge in the disc {inside:.3e} m, shortest far from it {outside:.3e} m");
    assert!(inside <= 2e-3 / 8.0 * (1.0 + 1e-9), "{inside}");
    assert!(outside > 0.45e-3, "{outside}");
    let (inside, _) = refine("");
    println!("without: longest edge in the disc {inside:.3e} m");
    assert!(inside > 0.45e-3, "nothing refined before the load: {inside}");
}

/// Under `lookahead` the term reads the kinematic layers below only: with the dermis squeezed
/// by 10 % along x (far past the epidermis' critical strain, 5.1e-4) and the base at rest, the
/// first remesh refines the whole epidermis across the squeeze without it, and with it leaves
/// the start mesh's 0.5 mm beyond the disc the pinch will compress (the compression the layers
/// between take once wrinkled must not refine a mesh held to the driver's).
#[test]
fn the_lookahead_reads_the_kinematic_layers_only() {
    let longest_across = |options: &str| {
        let mut sim = pinch_with_remeshed_epidermis(
            "lookahead_kinematic",
            &format!(
                "size_min: 0.1, size_max: 1.0, refine_angle: 0.6, refine_compression: 0.05, \
                 wavelength: Some((per_wavelength: 8, onset: 0.5{options}))"
            ),
        );
        let dermis = layer(&mut sim, "dermis");
        let verts = sim.world.get::<LayerVertices>(dermis).unwrap().entities().to_vec();
        for v in verts {
            sim.world.get_mut::<Position>(v).unwrap().0.x *= 0.9;
        }
        sim.world.resource_mut::<SimClock>().frame = 1;
        skinsim_systems::remesh::remesh_layers(&mut sim.world);
        let epidermis = layer(&mut sim, "epidermis");
        let w = &sim.world;
        let uv = |v: Entity| w.get::<MaterialPos>(v).unwrap().0;
        let edges = w.get::<LayerEdges>(epidermis).unwrap().entities().iter();
        edges.map(|&e| w.get::<EdgeVerts>(e).unwrap().0.map(uv)).map(|[a, b]| (a.x - b.x).abs()).fold(0.0f64, f64::max)
    };
    let without = longest_across("");
    let with = longest_across(", lookahead: true");
    println!("longest extent across the squeeze: {without:.3e} m without lookahead, {with:.3e} m with it");
    assert!(without <= 2e-3 / 8.0 * (1.0 + 1e-9), "{without}");
    assert!(with > 0.45e-3, "{with}");
}

/// Issue 26 item 2: with `local_solve`, each remesh's changed region is solved to equilibrium
/// (the rest held) before the frame's solve; the frames still converge with the constraints
/// held and the layer consistent, and every frame after a changing remesh reports a converged
/// region solve over its vertices.
#[test]
fn a_region_solve_after_each_remesh_converges_and_is_reported() {
    let edits = [("refine_compression: 0.2)", "refine_compression: 0.2, local_solve: true)")];
    let mut scene = variant(&scratch_dir("local_solve"), &edits);
    scene.scene.frames = 4;
    let mut sim = Simulation::new(&scene);
    let dermis = layer(&mut sim, "dermis");
    let mut solved = 0;
    for frame in 1..=scene.scene.frames {
        let p = step_checked(&mut sim, frame, dermis);
        let changed = sim
            .world
            .get::<RemeshReport>(dermis)
            .is_some_and(|r| r.frame == u64::from(frame) && r.stats.splits + r.stats.collapses + r.stats.flips > 0);
        println!("frame {frame}: {} Newton iterations, region solve {:?}", p.outcome.iterations, p.local_solve);
        assert_eq!(p.local_solve.is_some(), changed, "frame {frame}");
        if let Some(r) = p.local_solve {
            assert!(r.converged && r.vertices > 0 && r.iterations > 0, "frame {frame}: {r:?}");
            solved += 1;
        }
    }
    assert!(solved >= 2, "{solved} region solves");
}

/// Issue 26 items 2 and 3: with `hold`, a remesh after the one that refined ahead of the load
/// leaves the faces it refined as they were, though the sheet has wrinkled since (the fig. 6-4
/// pinch's epidermis, refined to lambda_2 / 8 over the disc before any solve, then given
/// wrinkles the curvature term asks to refine); without it that remesh changes them. (The
/// wrinkles stop short of the held region's rim: a held face that a free one meets across an
/// edge the metric wants split is released, `a_held_face_the_metric_wants_split_is_released`.)
#[test]
fn held_faces_survive_a_later_remesh() {
    let faces_changed = |hold: bool| {
        let mut sim = pinch_with_remeshed_epidermis(
            "hold",
            &format!(
                "size_min: 0.05, size_max: 1.0, refine_angle: 0.6, refine_compression: 0.05, every: 1, \
                 wavelength: Some((per_wavelength: 8, onset: 0.5, isotropic: true, lookahead: true, hold: {hold}))"
            ),
        );
        let epidermis = layer(&mut sim, "epidermis");
        let triples = |w: &World| -> HashSet<[Entity; 3]> {
            let uv = |v: Entity| w.get::<MaterialPos>(v).unwrap().0;
            let faces = w.get::<LayerFaces>(epidermis).unwrap().entities().to_vec();
            let verts = faces.iter().map(|&f| w.get::<FaceVerts>(f).unwrap().0);
            // (the disc, 6 mm around the pinch's centre, less a margin of a few elements)
            verts
                .filter(|t| {
                    (t.map(uv).iter().sum::<glam::DVec2>() / 3.0).distance(glam::DVec2::new(12e-3, 6e-3)) < 5e-3
                })
                .collect()
        };
        // The Remesh stage alone, in frame 1 (before the Motion stage moves the base), then in
        // frame 2 after wrinkles of 2 mm, 0.6 mm high, within 4.5 mm of the centre and beyond
        // 8 mm, none from 5.5 to 7 mm (the held region's rim, about 6 mm).
        sim.world.resource_mut::<SimClock>().frame = 1;
        skinsim_systems::remesh::remesh_layers(&mut sim.world);
        let before = triples(&sim.world);
        let verts = sim.world.get::<LayerVertices>(epidermis).unwrap().entities().to_vec();
        let window = |r: f64| {
            let step = |t: f64| {
                let t = t.clamp(0.0, 1.0);
                t * t * (3.0 - 2.0 * t)
            };
            1.0 - step((r - 4.5e-3) / 1e-3) + step((r - 7e-3) / 1e-3)
        };
        for v in verts {
            let u = sim.world.get::<MaterialPos>(v).unwrap().0;
            let r = u.distance(glam::DVec2::new(12e-3, 6e-3));
            sim.world.get_mut::<Position>(v).unwrap().0.z +=
                0.6e-3 * window(r) * (std::f64::consts::TAU * u.x / 2e-3).sin();
        }
        sim.world.resource_mut::<SimClock>().frame = 2;
        skinsim_systems::remesh::remesh_layers(&mut sim.world);
        let report = *sim.world.get::<RemeshReport>(epidermis).unwrap();
        assert_eq!(report.frame, 2);
        assert!(report.stats.splits > 0, "the wrinkles ask for splits: {report:?}");
        assert_eq!(report.stats.released, 0, "{report:?}");
        let after = triples(&sim.world);
        (before.len(), before.difference(&after).count())
    };
    let (held, changed) = faces_changed(true);
    println!("hold: {changed} of the disc's {held} faces changed");
    assert!(held > 1000 && changed == 0, "{changed} of {held}");
    let (free, changed) = faces_changed(false);
    println!("without: {changed} of the disc's {free} faces changed");
    assert!(changed > free / 2, "{changed} of {free}");
}

/// `hold` holds nothing at a layer's first remesh: the pinch's start edges (0.5 mm) are within
/// its slack of lambda_2 / 5 = 0.4 mm, and the first remesh still refines them to the bound, as
/// it does without `hold`.
#[test]
fn hold_leaves_the_first_remesh_free() {
    let vertices_after_the_first_remesh = |hold: bool| {
        let mut sim = pinch_with_remeshed_epidermis(
            &format!("hold_first_{hold}"),
            &format!(
                "size_min: 0.05, size_max: 1.0, refine_angle: 0.6, refine_compression: 0.05, every: 1, \
                 wavelength: Some((per_wavelength: 5, onset: 0.5, isotropic: true, lookahead: true, hold: {hold}))"
            ),
        );
        let epidermis = layer(&mut sim, "epidermis");
        let count = |w: &World| w.get::<LayerVertices>(epidermis).unwrap().entities().len();
        let start = count(&sim.world);
        sim.world.resource_mut::<SimClock>().frame = 1;
        skinsim_systems::remesh::remesh_layers(&mut sim.world);
        (start, count(&sim.world))
    };
    let (start, held) = vertices_after_the_first_remesh(true);
    let (_, free) = vertices_after_the_first_remesh(false);
    println!("epidermis vertices {start} -> {held} with hold, {free} without");
    assert!(held > start + 100 && held == free, "{start} -> {held} with hold, {free} without");
}

/// The report's fig. 6-4 pinch, adaptive at lambda_2 / 6 with a 4 mm margin (`report --only
/// lk14 --cases pinch`, its scene as the report writes it).
const HELD_PINCH: &str = r#"
Scene(
    name: "lk14_fig6_4_pinch", units: (length: Millimetre, stress: MegaPascal), frames: 10,
    patches: [Patch(
        name: "skin",
        solver: (tolerance: 1e-8, max_iterations: 1000, projection: None,
                 perturbation: Some((amplitude: 0.002, seed: 3, cell: 1))),
        layers: [
            Layer(name: "base", kind: Kinematic, mesh: Grid(size: (32.0, 16.0), cells: (32, 18), pattern: Equilateral)),
            Layer(name: "dermis", kind: Shell, mesh: Grid(size: (32.0, 16.0), cells: (53, 31), pattern: Equilateral, z: 0.5),
                  material: (model: BazantHencky, young: 4.0, poisson: 0.45, thickness: 1.0),
                  bending: Some((model: Tan, element: Hinge))),
            Layer(name: "epidermis", kind: Shell, mesh: Grid(size: (32.0, 16.0), cells: (64, 37), pattern: Equilateral, z: 1.0125),
                  material: (model: BazantHencky, young: 64.0, poisson: 0.45, thickness: 0.025),
                  bending: Some((model: Tan, element: Hinge)),
                  remesh: Some((size_min: 0.1, size_max: 1, refine_angle: 0.4, refine_compression: 0.02, every: 10,
                                wavelength: Some((per_wavelength: 6, onset: 0.5, isotropic: true, lookahead: true, margin: 4, hold: true))))),
        ],
        drivers: [BlendShape(layer: "base", interpolation: Smooth, targets: [
            Target(shape: Pinch(radius: 8.0, squeeze: 0.25, lift: 2.0), weights: [(0, 0.0), (10, 1.0)]),
        ])],
        couplings: [
            Coupling(upper: "dermis", lower: "base", wavelength: Constant(8.0), seed: 1),
            Coupling(upper: "epidermis", lower: "dermis", wavelength: Constant(2.0), seed: 2),
        ],
    )],
    output: (stats: false, rerun: false, obj: false),
)"#;

/// Issue 26 item 2, under a held load: a remesh resamples the kernels' sums, and a full step
/// that meets them again can leave along negative curvature off their null space, far outside
/// its quadratic model (the l1 merit still falls). Such a step is taken back and tried stiffer
/// (`solve::constrained`, HELD_MODEL_ERROR). The report's held remeshes on this pinch (after a
/// held frame that takes no iteration, three frames remeshed every frame) took 2, 12 and 3
/// Newton iterations without the rule, and 2, 2 and 2 with it, one step taken back. The load
/// ends at the round-off floor (the stall test); a held frame back within that test's band of
/// it (twice its residual) is at the floor too (`held_level`): the third remesh then takes 1.
#[test]
fn a_held_remesh_takes_back_a_step_its_model_did_not_predict() {
    let scene = skinsim::scene::load_str(HELD_PINCH, &scratch_dir("held-pinch").join("scene.ron"))
        .unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(&scene);
    let every = |sim: &mut Simulation, every: u32| {
        let mut q = sim.world.query::<(&Layer, &mut RemeshSettings)>();
        q.iter_mut(&mut sim.world).filter(|(l, _)| l.name == "epidermis").for_each(|(_, mut r)| r.every = every);
    };
    let mut level = 0.0;
    for _ in 0..10 {
        level = sim.step().patches[0].outcome.residual;
    }
    assert!(level > 1e-8, "the load ends at the round-off floor, above the tolerance: {level:e}");
    every(&mut sim, u32::MAX);
    assert_eq!(sim.step().patches[0].outcome.iterations, 0, "the held load's first frame starts converged");
    every(&mut sim, 1);
    let (mut iterations, mut taken_back, mut in_band) = (Vec::new(), 0, 0);
    for _ in 0..3 {
        let p = sim.step().patches[0].clone();
        assert!(p.outcome.converged && sim.failure().is_none());
        iterations.push(p.outcome.iterations);
        taken_back += p.outcome.unmodelled_steps;
        in_band += u32::from(p.outcome.residual > level && p.outcome.residual <= 2.0 * level);
    }
    println!("held remeshes: {iterations:?} Newton iterations, {taken_back} step(s) taken back, {in_band} in the band");
    assert!(taken_back >= 1, "no step was taken back: {iterations:?}");
    assert!(in_band >= 1, "no held frame was accepted within the floor's band: {iterations:?}");
    assert!(
        iterations.iter().sum::<u32>() <= 5,
        "{iterations:?} (2, 12, 3 without the rule; 2, 2, 2 without the band)"
    );
}
