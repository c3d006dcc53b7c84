//! System-level tests of the engine: the schedule, several patches in one world, determinism,
//! failure handling and the Rerun recording. Each builds a World from a scene.

mod common;

use std::collections::BTreeSet;
use std::hash::{Hash, Hasher};

use bevy_ecs::prelude::*;
use common::*;
use skinsim::model::{Failure, PatchReport, Position, Stage};
use skinsim::scene::{load_str, BuiltScene};
use skinsim_systems::log::{ObjExport, RerunSink};
use skinsim_systems::log_read::RecordingIndex;
use skinsim_systems::{Simulation, StageSet};

/// Records which stage sets ran, in order (the bevy_ecs schedule-test pattern).
#[derive(Resource, Default)]
struct Ran(Vec<Stage>);

fn record_stages(sim: &mut Simulation) {
    sim.world.init_resource::<Ran>();
    for stage in Stage::ALL {
        sim.schedule.add_systems((move |mut ran: ResMut<Ran>| ran.0.push(stage)).in_set(StageSet(stage)));
    }
}

const SHEET_WITHOUT_DRIVERS: &str = r#"
Scene(name: "still", frames: 1, patches: [
    Patch(name: "sheet", layers: [
        Layer(name: "sheet", kind: Shell, mesh: Grid(size: (4.0, 4.0), cells: (4, 4)),
              material: (young: 1.0, poisson: 0.3, thickness: 0.1)),
    ]),
])"#;

#[test]
fn stages_run_in_order_and_only_what_a_scene_declares() {
    let mut sim = Simulation::new(&load("strip_wrinkles.ron"));
    record_stages(&mut sim);
    sim.step();
    let skipped = [
        Stage::Remesh,
        Stage::PropertyResample,
        Stage::Log,
        Stage::ConstraintResample,
        Stage::ConstraintAdjust,
        Stage::AnchorWalk,
        Stage::Settle,
    ];
    let all: Vec<Stage> = Stage::ALL.iter().copied().filter(|s| !skipped.contains(s)).collect();
    assert_eq!(
        sim.world.resource::<Ran>().0,
        all,
        "drivers, no remeshing, no kernels, no anchors and no sink: no Log, no remesh, constraint stages or walk"
    );

    // Remeshing with kernels: Remesh and PropertyResample run after the drivers, before the
    // kernels are resampled.
    let mut sim = Simulation::new(&load("lk14/remesh_one_layer_quick.ron"));
    record_stages(&mut sim);
    sim.step();
    let ran = &sim.world.resource::<Ran>().0;
    let order = [Stage::Motion, Stage::Remesh, Stage::PropertyResample, Stage::ConstraintResample];
    assert_eq!(ran[..4], order, "{ran:?}");
    // Settle only in a frame whose remesh changed a face (the first frame keeps the scene's
    // mesh), between Assemble and Solve.
    assert!(!ran.contains(&Stage::Settle), "{ran:?}");
    sim.world.resource_mut::<Ran>().0.clear();
    sim.step();
    let ran = &sim.world.resource::<Ran>().0;
    let at = |s: Stage| ran.iter().position(|r| *r == s).unwrap_or_else(|| panic!("{s:?} in {ran:?}"));
    assert_eq!((at(Stage::Assemble) + 1, at(Stage::Settle) + 1), (at(Stage::Settle), at(Stage::Solve)), "{ran:?}");

    // Anchors: the walk runs, between the constraint stages and Assemble.
    let mut sim = Simulation::new(&load("kck18/crease_quick.ron"));
    record_stages(&mut sim);
    sim.step();
    let ran = &sim.world.resource::<Ran>().0;
    let at = |s: Stage| ran.iter().position(|r| *r == s);
    assert!(at(Stage::AnchorWalk).is_some() && at(Stage::AnchorWalk) < at(Stage::Assemble), "{ran:?}");
    assert!(at(Stage::ConstraintResample).is_none(), "{ran:?}");

    // No drivers: no Motion work. A sink: the Log stage runs, last.
    let scene = load_str(SHEET_WITHOUT_DRIVERS, &scene_path("still.ron")).unwrap();
    let mut sim = Simulation::new(&scene);
    record_stages(&mut sim);
    let dir = std::env::temp_dir().join(format!("skinsim-stages-{}", std::process::id()));
    sim.world.insert_resource(ObjExport(dir.clone()));
    sim.step();
    let ran = &sim.world.resource::<Ran>().0;
    assert!(!ran.contains(&Stage::Motion));
    assert_eq!(ran.last(), Some(&Stage::Log));
    assert!(dir.join("obj/sheet/sheet/00001.obj").is_file());
    let _ = std::fs::remove_dir_all(dir);
}

/// Stage timings are read by stage, not by a string key: every stage and the total are in a
/// frame's stats, and a timing that is missing is an error, not a zero.
#[test]
fn every_stage_is_timed_and_a_missing_timing_is_an_error() {
    let mut sim = Simulation::new(&load("strip_wrinkles.ron"));
    let s = sim.step();
    assert_eq!(s.timings_ms.len(), Stage::ALL.len() + 1, "{:?}", s.timings_ms);
    assert!(Stage::ALL.iter().all(|&stage| s.timing(stage) >= 0.0) && s.total_ms() > 0.0);
    assert!(s.timing(Stage::Solve) > 0.0 && s.timing(Stage::Remesh) == 0.0, "{:?}", s.timings_ms);
    let mut without = s.clone();
    without.timings_ms.remove(Stage::Solve.key());
    assert!(std::panic::catch_unwind(|| without.timing(Stage::Solve)).is_err());
}

fn positions_hash(sim: &mut Simulation) -> u64 {
    let mut q = sim.world.query::<(Entity, &Position)>();
    let mut all: Vec<_> = q.iter(&sim.world).map(|(e, p)| (e.to_bits(), p.0.to_array().map(f64::to_bits))).collect();
    all.sort();
    let mut h = std::collections::hash_map::DefaultHasher::new();
    all.hash(&mut h);
    h.finish()
}

fn run_frames(scene: &BuiltScene, frames: u32) -> Simulation {
    let mut sim = Simulation::new(scene);
    for _ in 0..frames {
        sim.step();
        assert!(sim.failure().is_none());
    }
    sim
}

#[test]
fn same_scene_same_bits_whatever_the_thread_count() {
    let scene = load("strip_wrinkles.ron");
    let hashes: Vec<u64> = [1, 2, 2]
        .iter()
        .map(|&n| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
            pool.install(|| positions_hash(&mut run_frames(&scene, 10)))
        })
        .collect();
    assert_eq!(hashes[1], hashes[2], "two runs with 2 threads differ");
    assert_eq!(hashes[0], hashes[1], "1 and 2 threads differ");

    // Anchors walk in parallel, each on its own: the same bits too (KCK18 crease, 6 frames).
    let scene = load("kck18/crease_quick.ron");
    let hashes: Vec<u64> = [1, 2]
        .iter()
        .map(|&n| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
            pool.install(|| positions_hash(&mut run_frames(&scene, 6)))
        })
        .collect();
    assert_eq!(hashes[0], hashes[1], "KCK18 anchors: 1 and 2 threads differ");
}

#[test]
fn a_patch_gives_the_same_result_alone_and_beside_others() {
    let mut both = load("multi_patch.ron");
    both.scene.frames = 10;
    assert!(both.patches.len() >= 2);
    let mut together = run_frames(&both, 10);
    for p in &both.patches {
        let mut alone_scene = both.clone();
        alone_scene.patches.retain(|q| q.name == p.name);
        let mut alone = run_frames(&alone_scene, 10);
        for layer in &p.layers {
            let a = alone.layer_positions(&p.name, &layer.name);
            let b = together.layer_positions(&p.name, &layer.name);
            assert!(!a.is_empty());
            assert_eq!(a, b, "patch {} layer {} differs beside other patches", p.name, layer.name);
        }
    }
    // The two patches really wrinkled (they are not trivially equal to their rest state).
    let film = together.layer_positions("stiff_foundation", "film");
    assert!(film.iter().any(|p| p.z.abs() > 1e-5), "no wrinkles");
}

#[test]
fn a_non_finite_state_stops_the_run_and_names_the_frame_and_patch() {
    let mut sim = Simulation::new(&load("strip_wrinkles.ron"));
    sim.step();
    assert!(sim.failure().is_none());
    let mut q = sim.world.query::<&mut Position>();
    if let Some(mut p) = q.iter_mut(&mut sim.world).nth(1000) {
        p.0.z = f64::NAN;
    }
    let stats = sim.step();
    let failure = sim.failure().expect("the NaN is reported");
    let Failure::Solve { frame, patch, error } = &failure else { panic!("{failure}") };
    assert_eq!((*frame, patch.as_str()), (2, "strip"), "{failure}");
    assert!(matches!(error, skinsim::solve::SolveError::NonFinite { .. }), "{error}");
    // (the CLI's line, as before)
    let line = failure.to_string();
    assert!(line.starts_with("frame 2: patch \"strip\": non-finite"), "{line}");
    assert!(!stats.patches[0].outcome.converged);
}

#[test]
fn the_recording_holds_every_layer_and_frame() {
    let mut scene = load("strip_wrinkles.ron");
    scene.scene.frames = 3;
    let RecordingIndex { frames, sim_time, .. } = record(&scene, "strip");
    // sim_time in nanoseconds: the rest state at 0 (issue 65), frames 1..3 at 1/30 s.
    let expected: BTreeSet<i64> = (0..=3).map(|f| (f as f64 / 30.0 * 1e9).round() as i64).collect();
    assert_eq!(sim_time, expected);
    // The layers from the rest state (frame 0), the solve's figures from frame 1; the stage
    // timings from frame 2, frame 1's (the set-up) apart.
    let logged = [
        ("/patches/strip/film", 0..=3),
        ("/patches/strip/base", 0..=3),
        ("/stats/strip/energy", 1..=3),
        ("/stats/strip/log10_residual", 1..=3),
        ("/timings/solve", 2..=3),
        ("/setup_timings/solve", 1..=1),
    ];
    for (entity, range) in logged {
        let f = frames.get(entity).unwrap_or_else(|| panic!("{entity} missing from {:?}", frames.keys()));
        assert_eq!(f.iter().copied().collect::<Vec<_>>(), range.collect::<Vec<i64>>(), "{entity}");
    }
}

/// Issue 5: a remeshed layer is also logged in material space (faces and edges) every frame,
/// with its triangles on the timeline (they change); a layer that is not remeshed is not.
#[test]
fn the_recording_holds_the_material_space_mesh_of_a_remeshed_layer() {
    let mut scene = load("lk14/remesh_one_layer_quick.ron");
    scene.scene.frames = 2;
    let frames = record(&scene, "remesh").frames;
    for entity in ["/patches/skin/dermis", "/material/skin/dermis", "/material/skin/dermis/edges"] {
        let f = frames.get(entity).unwrap_or_else(|| panic!("{entity} missing from {:?}", frames.keys()));
        assert_eq!(f.iter().copied().collect::<Vec<_>>(), vec![0, 1, 2], "{entity}");
    }
    assert!(!frames.contains_key("/material/skin/base"));
}

/// KCK18: body, skin, anchors (points and springs) and the largest jump of each method; the
/// anchors are screen-sized dots (a radius in metres at every vertex and face centre hid the
/// skin), with a legend of their own. Issue 65: the body and skin from the rest state (frame
/// 0), the body a neutral grey whatever the colouring, the skin's colour scale in the
/// recording's properties.
#[test]
fn the_recording_holds_the_anchors_of_each_method() {
    let mut scene = load("kck18/crease_quick.ron");
    scene.scene.frames = 2;
    let index = record(&scene, "kck18");
    let frames = &index.frames;
    for patch in ["walk", "project", "ring"] {
        for (entity, first) in [
            (format!("/patches/{patch}/body"), 0),
            (format!("/patches/{patch}/skin"), 0),
            (format!("/patches/{patch}/skin/anchors/points"), 1),
            (format!("/patches/{patch}/skin/anchors/springs"), 1),
            (format!("/stats/{patch}/anchors/max_jump"), 1),
        ] {
            let f = frames.get(&entity).unwrap_or_else(|| panic!("{entity} missing from {:?}", frames.keys()));
            assert_eq!(f.iter().copied().collect::<Vec<_>>(), (first..=2).collect::<Vec<i64>>(), "{entity}");
        }
        let body = &index.colours[&format!("/patches/{patch}/body")];
        assert!(!body.is_empty() && body.iter().all(|c| *c == 0xB2B2B2FF), "{patch}: the body's colours");
        let key = format!("/__properties/colour_scale/patches/{patch}/skin:");
        let scale = index.property_numbers.iter().find(|(k, _)| k.starts_with(&key)).map(|(_, v)| v);
        assert_eq!(scale, Some(&vec![0.1]), "{patch}: strain saturates at 10 %: {:?}", index.property_numbers);
        let legend = &index.documents[&format!("/anchor_legend/{patch}/skin")];
        assert!(legend.contains("dark violet"), "{legend}");
        let radii = &index.radii[&format!("/patches/{patch}/skin/anchors/points")];
        assert!(
            !radii.is_empty() && radii.iter().all(|r| *r < 0.0),
            "{patch}: anchor radii {radii:?} not in UI points"
        );
    }
}

/// Runs a scene into an .rrd file and reads it back with Rerun's own decoder: the frames each
/// entity was logged at, every sim_time, radii.
fn record(scene: &BuiltScene, tag: &str) -> RecordingIndex {
    let path = std::env::temp_dir().join(format!("skinsim-rec-{tag}-{}.rrd", std::process::id()));
    {
        let rec = rerun::RecordingStreamBuilder::new("skinsim").recording_id("test").save(&path).unwrap();
        let mut sim = Simulation::new(scene);
        sim.world.insert_resource(RerunSink(rec.clone()));
        for _ in 0..scene.scene.frames {
            sim.step();
        }
        rec.flush_blocking().unwrap();
    }
    let index = skinsim_systems::log_read::read_recording(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    index
}

/// Implicit Euler with no forces moves every free vertex by h v exactly (the inertia term of the
/// incremental potential, LK14 eq. 5.2), and a frame-to-frame velocity is recovered.
#[test]
fn implicit_euler_keeps_a_free_sheet_in_uniform_motion() {
    let text = r#"Scene(name: "drift", frames: 3, frame_time: 0.01, patches: [
        Patch(name: "sheet", solver: (mode: ImplicitEuler), layers: [
            Layer(name: "sheet", kind: Shell, mesh: Grid(size: (4.0, 4.0), cells: (4, 4)),
                  material: (young: 1.0, poisson: 0.3, thickness: 0.1), bending: (model: Tan)),
        ]),
    ])"#;
    let scene = load_str(text, &scene_path("drift.ron")).unwrap();
    let mut sim = Simulation::new(&scene);
    let velocity = glam::DVec3::new(0.1, -0.2, 0.3);
    let mut q = sim.world.query::<&mut skinsim::model::Velocity>();
    for mut v in q.iter_mut(&mut sim.world) {
        v.0 = velocity;
    }
    let start = sim.layer_positions("sheet", "sheet");
    for _ in 0..3 {
        let s = sim.step();
        assert!(s.patches[0].outcome.converged, "{:?}", s.patches[0]);
    }
    let end = sim.layer_positions("sheet", "sheet");
    for (a, b) in start.iter().zip(&end) {
        let moved = *b - *a - velocity * 0.03;
        assert!(moved.length() < 1e-12, "{moved:?}");
    }
}

/// Implicit Euler's predictor is x_n + h v_n (LK14 eq. 5.2), not the compression driver's guess:
/// in a step far shorter than a wave's travel time (h = 0.1 ms; c = sqrt(E / rho) ~ 32 m/s, a
/// quarter width away ~ 30 ms) a sheet at rest lags its driven edges, and its interior barely
/// moves. With the driver's incremental map in x_hat it moved with the map (the whole increment).
#[test]
fn an_implicit_euler_step_lags_the_driven_edges() {
    let text = r#"Scene(name: "lag", frames: 1, frame_time: 1e-4, units: (length: Millimetre, stress: MegaPascal),
        patches: [Patch(name: "sheet", solver: (mode: ImplicitEuler, tolerance: 1e-9), layers: [
            Layer(name: "sheet", kind: Shell, mesh: Grid(size: (1000.0, 100.0), cells: (40, 4)),
                  material: (young: 1.0, poisson: 0.3, density: 1000.0, thickness: 0.5), bending: (model: Tan)),
        ], drivers: [
            Pin(layer: "sheet", select: Sides([XMin, XMax]), dofs: (x: true, y: true, z: true)),
            Compress(layers: ["sheet"], keyframes: [(0, 0.0), (1, 0.01)]),
        ])])"#;
    let scene = load_str(text, &scene_path("lag.ron")).unwrap();
    let mut sim = Simulation::new(&scene);
    let start = sim.layer_positions("sheet", "sheet");
    let s = sim.step();
    assert!(s.patches[0].outcome.converged, "{:?}", s.patches[0]);
    let end = sim.layer_positions("sheet", "sheet");
    // The driven edge moved by 1 % of the half width, 5 mm; the affine map moves x = 250 mm
    // by 2.5 mm (the grid spans x = 0 to 1 m).
    let (edge, quarter) = (end[0].x - start[0].x, end[10].x - start[10].x);
    assert!((start[10].x - 0.25).abs() < 1e-9, "{:?}", start[10]);
    assert!((edge - 0.005).abs() < 1e-9, "edge moved {edge}");
    assert!(quarter.abs() < 1e-3 * 0.0025, "a quarter width in moved {quarter} m");
}

/// Runs `frames` frames of a one-patch scene, each asserted converged: the layer's final
/// positions, and `count` of the patch's reports summed over the frames.
fn converged_run(
    scene: &BuiltScene,
    frames: usize,
    (patch, layer): (&str, &str),
    count: impl Fn(&PatchReport) -> u32,
) -> (Vec<glam::DVec3>, u32) {
    let mut sim = Simulation::new(scene);
    let mut total = 0;
    for _ in 0..frames {
        let s = sim.step();
        assert!(s.patches[0].outcome.converged, "{:?}", s.patches[0]);
        total += count(&s.patches[0]);
    }
    (sim.layer_positions(patch, layer), total)
}

fn largest_difference(a: &[glam::DVec3], b: &[glam::DVec3]) -> f64 {
    a.iter().zip(b).map(|(p, q)| (*p - *q).length()).fold(0.0f64, f64::max)
}

#[test]
fn krylov_newton_reaches_the_direct_solution_with_fewer_factorizations() {
    let direct = load("strip_wrinkles.ron");
    let text = std::fs::read_to_string(scene_path("strip_wrinkles.ron")).unwrap();
    let text = text.replace("max_iterations: 60,", "max_iterations: 60, linear: Krylov(max_iterations: 30),");
    let krylov = load_str(&text, &scene_path("strip_wrinkles.ron")).unwrap();
    let run = |scene: &BuiltScene| converged_run(scene, 12, ("strip", "film"), |p| p.outcome.factorizations);
    let ((a, fa), (b, fb)) = (run(&direct), run(&krylov));
    let worst = largest_difference(&a, &b);
    println!("factorizations: direct {fa}, Krylov {fb}; largest position difference {worst:.3e} m");
    assert!(worst < 1e-6 * 0.04, "the same equilibrium: {worst} m");
    assert!(fb < fa, "Krylov {fb} vs direct {fa}");
}

/// Issue 25 item 2: mixed precision (the factor in f32, each step refined in f64 by CG) reaches
/// the f64 solve's equilibrium on a squeezed volume slab, and refines every step.
#[test]
fn mixed_precision_newton_reaches_the_f64_solution() {
    let text = std::fs::read_to_string(scene_path("examples/volume_slab.ron")).unwrap();
    let f32_text = text.replace("solver: (projection: Adaptive)", "solver: (projection: Adaptive, precision: F32)");
    assert_ne!(text, f32_text);
    let run = |text: &str| {
        let scene = load_str(text, &scene_path("examples/volume_slab.ron")).unwrap();
        converged_run(&scene, 5, ("slab", "dermis"), |p| p.outcome.cg_iterations)
    };
    let ((a, cg64), (b, cg32)) = (run(&text), run(&f32_text));
    let worst = largest_difference(&a, &b);
    println!("largest position difference {worst:.3e} m; CG refinements {cg32}");
    assert!(worst < 1e-6 * 0.01, "the same equilibrium: {worst} m");
    assert_eq!(cg64, 0);
    assert!(cg32 > 0, "every f32 step is refined");
}

/// Issue 21 item 6: LK14's velocity-based scheme (one linearized implicit-Euler step per frame,
/// `LinearizedEuler`) is a supported mode: every frame one iteration and one factorization,
/// reported converged, and on the ringing film (examples/dynamic_strip.ron, 40 steps of 1 ms)
/// its final wrinkle amplitude is within 10 % of the fully converged implicit Euler's.
#[test]
fn the_linearized_euler_step_takes_one_factorization_per_frame() {
    let text = std::fs::read_to_string(scene_path("examples/dynamic_strip.ron")).unwrap();
    let linear = text.replace("mode: ImplicitEuler", "mode: LinearizedEuler");
    assert_ne!(linear, text);
    let amplitude = |text: &str, one_step: bool| {
        let scene = load_str(text, &scene_path("examples/dynamic_strip.ron")).unwrap();
        let mut sim = Simulation::new(&scene);
        for frame in 1..=scene.scene.frames {
            let s = sim.step();
            let p = &s.patches[0];
            assert!(p.outcome.converged, "frame {frame}: {p:?}");
            if one_step {
                assert_eq!((p.outcome.iterations, p.outcome.factorizations), (1, 1), "frame {frame}");
            }
        }
        sim.layer_positions("strip", "film").iter().map(|p| p.z.abs()).fold(0.0, f64::max)
    };
    let (full, linearized) = (amplitude(&text, false), amplitude(&linear, true));
    println!("final amplitude: implicit Euler {full:.4e} m, linearized {linearized:.4e} m");
    assert!(full > 1e-4, "the film wrinkles: {full}");
    assert!((linearized - full).abs() < 0.1 * full, "{linearized} vs {full}");
}

/// Issue 24: a procedural joint bends a kinematic tube (a finger) at its middle; the skin held
/// to it by KCK18 anchors follows, and every frame converges. The body's vertices are exactly the
/// joint's map of their rest positions at the keyframed angle.
#[test]
fn a_joint_bends_a_finger_and_its_skin_follows() {
    let text = r#"Scene(name: "finger", units: (length: Millimetre, stress: MegaPascal), frames: 2, patches: [
        Patch(name: "finger", solver: (projection: Adaptive, max_iterations: 100), layers: [
            Layer(name: "bone", kind: Kinematic, mesh: Tube(radius: 8.0, length: 80.0, cells: (24, 32))),
            Layer(name: "skin", kind: Shell, mesh: Offset(layer: "bone", distance: 0.5),
                  material: (young: 1.0, poisson: 0.45, thickness: 0.5), bending: (model: Tan)),
        ], drivers: [
            Joint(layers: ["bone"], pivot: (0.0, 0.0, 0.0), axis: Y, along: X, width: 16.0, keyframes: [(0, 0.0), (2, 60.0)]),
        ], anchors: Anchors(skin: "skin", body: "bone", stiffness: 0.01)),
    ])"#;
    let scene = load_str(text, &scene_path("finger.ron")).unwrap();
    let rest = scene.patches[0].layers[0].mesh.rest().to_vec();
    let joint =
        skinsim::model::Joint { pivot: glam::DVec3::ZERO, axis: glam::DVec3::Y, along: glam::DVec3::X, width: 0.016 };
    let mut sim = Simulation::new(&scene);
    for frame in 1..=2 {
        let s = sim.step();
        assert!(s.patches[0].outcome.converged, "frame {frame}: {:?}", s.patches[0]);
        let angle = (30.0 * frame as f64).to_radians();
        let bone: Vec<glam::DVec3> = sim.layer_points("finger", "bone").into_iter().map(|p| p.1).collect();
        for (p, r) in bone.iter().zip(&rest) {
            assert!((*p - joint.bend(*r, angle)).length() < 1e-12, "frame {frame}: {p} vs {r}");
        }
    }
    // The fingertip turned by 60 degrees, and the skin over it came along (within the offset
    // and the springs' sag).
    let tip = |layer: &str, sim: &mut Simulation| {
        let pts: Vec<glam::DVec3> = sim.layer_points("finger", layer).into_iter().map(|p| p.1).collect();
        pts.iter().copied().sum::<glam::DVec3>() / pts.len() as f64
    };
    let (bone, skin) = (tip("bone", &mut sim), tip("skin", &mut sim));
    assert!(bone.z < -0.005, "the far half went down: {bone}");
    assert!((skin - bone).length() < 0.002, "skin {skin} vs bone {bone}");
}

#[test]
fn a_load_is_held_only_while_every_motion_holds_and_no_capture_ran() {
    use bevy_ecs::system::RunSystemOnce;
    use skinsim::model::{Capture, Keyframes, LoadHeld, Motion, MotionKind, PatchCaptures, PatchMotion, SimClock};
    let mut world = World::new();
    let motion = |keys: Vec<(u32, f64)>| Motion {
        layers: vec![],
        kind: MotionKind::Compress { axis: 0, predict: false },
        keyframes: Keyframes(keys),
    };
    let capture = Capture { layers: vec![], frame: 5, fraction: 1.0, map: None };
    let patch = world
        .spawn((
            PatchMotion {
                motions: vec![motion(vec![(0, 0.0), (3, 0.1)]), motion(vec![(0, 0.0)])],
                ..Default::default()
            },
            PatchCaptures(vec![capture]),
            LoadHeld::default(),
        ))
        .id();
    let mut held = Vec::new();
    for frame in 1..=7 {
        world.insert_resource(SimClock { frame, time: 0.0, dt: 1.0 });
        world.run_system_once(skinsim_systems::motion::apply_motions).unwrap();
        held.push(world.get::<LoadHeld>(patch).unwrap().0);
    }
    // Frames 1-3 load, 4 and 5 hold, 6 follows frame 5's capture (a new rest state), 7 holds.
    assert_eq!(held, [false, false, false, true, true, false, true]);
}
