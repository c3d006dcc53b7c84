//! LK14 constraint kernels in the engine: the constrained solve meets its residual, the two
//! KKT methods agree, and kernels are resampled (and re-centred) when a layer's mesh changes.

mod common;

use bevy_ecs::prelude::*;
use common::*;
use glam::DVec2;
use skinsim::model::*;
use skinsim::scene::load_str;
use skinsim_systems::Simulation;

/// A shell held by kernels over a kinematic base that is compressed (4 %) in two frames.
fn held_sheet(kkt: &str, projection: &str) -> String {
    held_sheet_at(kkt, projection, 0.04)
}

fn held_sheet_at(kkt: &str, projection: &str, strain: f64) -> String {
    format!(
        r#"
Scene(name: "held", frames: 2, patches: [
    Patch(name: "skin",
        solver: (max_iterations: 80, projection: {projection}, kkt: {kkt}, perturbation: Some((amplitude: 0.01, seed: 3))),
        layers: [
            Layer(name: "base", kind: Kinematic, mesh: Grid(size: (8.0, 8.0), cells: (20, 23))),
            Layer(name: "skin", kind: Shell, mesh: Grid(size: (8.0, 8.0), cells: (20, 23), z: 0.15),
                  material: (young: 4.0, poisson: 0.3, thickness: 0.3), bending: Some((model: Tan))),
        ],
        drivers: [Compress(layers: ["base", "skin"], axis: X, keyframes: [(0, 0.0), (2, {strain})])],
        couplings: [Coupling(upper: "skin", lower: "base", wavelength: Constant(3.0), seed: 1)],
    ),
])"#
    )
}

/// A copy of a solved patch with an empty solver cache: a solve from its state as from scratch.
fn without_cache(start: &skinsim::solve::PackedPatch) -> skinsim::solve::PackedPatch {
    skinsim::solve::PackedPatch {
        state: start.state.clone(),
        elements: start.elements.clone(),
        constraints: start.constraints.clone(),
        length_scale: start.length_scale,
        ..Default::default()
    }
}

fn held(kkt: &str, projection: &str) -> (Simulation, Vec<skinsim_systems::FrameStats>) {
    let scene = load_str(&held_sheet(kkt, projection), &scene_path("held.ron")).unwrap_or_else(|e| panic!("{e}"));
    run(&scene)
}

/// PHYSICS.md 2: every frame converges with the constraint residual below 1e-9 of the patch size.
#[test]
fn constrained_frames_converge_with_tiny_constraint_residual() {
    for projection in ["Clamp", "Adaptive"] {
        let (_, stats) = held("Ldlt", projection);
        for s in &stats {
            let p = &s.patches[0];
            println!(
                "{projection}: frame {} iterations {} residual {:.2e} constraints {} violation {:.2e}",
                s.frame,
                p.outcome.iterations,
                p.outcome.residual,
                p.outcome.constraints,
                p.outcome.constraint_violation
            );
            assert!(p.outcome.converged, "{projection}: frame {} did not converge", s.frame);
            assert!(p.outcome.constraints > 0);
            assert!(p.outcome.constraint_violation < 1e-9, "violation {:.2e}", p.outcome.constraint_violation);
        }
    }
}

/// The sparse LDL^T of the KKT matrix and the Schur complement give the same frames (below the
/// buckling strain: past it the two may pick different, equally valid wrinkle patterns), to
/// what the Newton tolerance leaves (1e-6 of the patch size).
#[test]
fn ldlt_and_schur_agree() {
    let run_with = |kkt| {
        let text = held_sheet_at(kkt, "Adaptive", 0.004);
        run(&load_str(&text, &scene_path("held.ron")).unwrap()).0
    };
    let (mut a, mut b) = (run_with("Ldlt"), run_with("Schur"));
    let (pa, pb) = (a.layer_positions("skin", "skin"), b.layer_positions("skin", "skin"));
    let worst = pa.iter().zip(&pb).map(|(x, y)| (*x - *y).length()).fold(0.0, f64::max);
    println!("largest difference {worst:.2e} m");
    assert!(worst < 1e-8, "LDLT and Schur differ by {worst:.2e} m");
}

/// The constraint stages run only when kernels exist, between Motion and Assemble.
#[test]
fn constraint_stages_run_with_kernels() {
    let scene = load_str(&held_sheet("Ldlt", "Clamp"), &scene_path("held.ron")).unwrap();
    let mut sim = Simulation::new(&scene);
    sim.step();
    let s = sim.step();
    assert!(s.timing(Stage::ConstraintResample) > 0.0 && s.timing(Stage::ConstraintAdjust) > 0.0);
}

/// ARCHITECTURE.md 2: a kernel is resampled when one of its layers' meshes changes. Here the
/// upper layer is re-triangulated between frames (every other diagonal flipped, interior
/// material positions jittered) and its epoch bumped, as a remesh would: the weights change,
/// stay affine and centred, and the next frame converges on the new mesh.
#[test]
fn kernels_follow_a_retriangulated_layer() {
    let scene = load_str(&held_sheet("Ldlt", "Clamp"), &scene_path("held.ron")).unwrap();
    let mut sim = Simulation::new(&scene);
    sim.step();
    assert!(check_weights(&mut sim) > 0);
    let before: Vec<KernelWeights> = sim.world.query::<&KernelWeights>().iter(&sim.world).cloned().collect();

    let layer = sim.world.query::<(Entity, &Layer)>().iter(&sim.world).find(|(_, l)| l.name == "skin").unwrap().0;
    let faces: Vec<Entity> = sim.world.get::<LayerFaces>(layer).unwrap().entities().to_vec();
    let verts: Vec<Entity> = sim.world.get::<LayerVertices>(layer).unwrap().entities().to_vec();
    // Flip the shared edge of face pairs (a, b, c) + (c, b, d) -> (a, d, c) + (a, b, d).
    let tris: Vec<[Entity; 3]> = faces.iter().map(|&f| sim.world.get::<FaceVerts>(f).unwrap().0).collect();
    let mut flipped = 0;
    let mut new_tris = tris.clone();
    let mut used = vec![false; tris.len()];
    for i in 0..tris.len() {
        if used[i] || flipped >= 40 {
            continue;
        }
        for j in i + 1..tris.len() {
            if used[j] {
                continue;
            }
            let shared: Vec<Entity> = tris[i].iter().filter(|v| tris[j].contains(v)).copied().collect();
            if shared.len() != 2 {
                continue;
            }
            let a = *tris[i].iter().find(|v| !shared.contains(v)).unwrap();
            let d = *tris[j].iter().find(|v| !shared.contains(v)).unwrap();
            // Keep orientation: in tris[i] the edge runs shared[p] -> shared[q] after a.
            let k = tris[i].iter().position(|v| *v == a).unwrap();
            let (b, c) = (tris[i][(k + 1) % 3], tris[i][(k + 2) % 3]);
            new_tris[i] = [a, b, d];
            new_tris[j] = [a, d, c];
            used[i] = true;
            used[j] = true;
            flipped += 1;
            break;
        }
    }
    assert!(flipped > 0);
    for (f, t) in faces.iter().zip(&new_tris) {
        sim.world.entity_mut(*f).insert(FaceVerts(*t));
    }
    for (i, &v) in verts.iter().enumerate() {
        let mut m = sim.world.get_mut::<MaterialPos>(v).unwrap();
        if m.0.x > 0.0 && m.0.x < 8e-3 && m.0.y > 0.0 && m.0.y < 8e-3 {
            m.0 += DVec2::new(((i * 7919) % 13) as f64 - 6.0, ((i * 104729) % 11) as f64 - 5.0) * 5e-6;
        }
    }
    // Rest shapes follow the new triangulation (what a remesh's PropertyResample does).
    let positions: Vec<(Entity, glam::DVec3)> =
        verts.iter().map(|&v| (v, sim.world.get::<RestPos>(v).unwrap().0)).collect();
    let rest_of = |e: Entity| positions.iter().find(|p| p.0 == e).unwrap().1;
    let thickness = sim.world.get::<Thickness>(layer).unwrap().0;
    for (f, t) in faces.iter().zip(&new_tris) {
        let rest = skinsim::physics::membrane::MembraneRest::from_rest_triangle(
            t.map(rest_of),
            thickness,
            glam::DMat2::IDENTITY,
        )
        .unwrap();
        sim.world.entity_mut(*f).insert(FaceRest(rest));
    }
    sim.world.get_mut::<TopologyEpoch>(layer).unwrap().0 += 1;
    let s = sim.step();
    let after: Vec<KernelWeights> = sim.world.query::<&KernelWeights>().iter(&sim.world).cloned().collect();
    let changed = before.iter().zip(&after).filter(|(a, b)| a.upper != b.upper).count();
    println!("{changed} of {} kernels resampled", after.len());
    assert!(changed > 0);
    assert!(check_weights(&mut sim) > 0);
    assert!(s.patches[0].outcome.converged && s.patches[0].outcome.constraint_violation < 1e-9);
}

/// Issue 21, the trust-region globalization (`globalization: TrustRegion`) on a small buckling
/// problem: the first frame of the stiffness scene (the flat, kernel-held sheet compressed past
/// its critical strain), solved from the same start with both globalizations. Every accepted
/// step lowers the merit function, the frame converges to an energy no higher than the line search's, in at
/// most 1.6x its iterations (measured: 66 against 44; the trust region is kept for comparison,
/// not as the default: `src/solve/README.md`).
#[test]
fn the_trust_region_lowers_the_merit_at_every_step_of_a_buckling_frame() {
    use skinsim::solve::{solve_frame, Globalization, PackedPatch};
    let mut scene = load("lk14/fig6_1_stiffness_quick.ron");
    scene.patches[0].solver.max_iterations = 0;
    let mut sim = Simulation::new(&scene);
    sim.step(); // frame 1's drivers, no Newton iteration: the buckling frame's start
    let dt = sim.world.resource::<SimClock>().dt;
    let mut q = sim.world.query::<&PackedPatch>();
    let start = q.single(&sim.world).unwrap();
    let solve = |globalization| {
        let mut packed = without_cache(start);
        let mut settings = scene.patches[0].solver.clone();
        (settings.max_iterations, settings.globalization) = (200, globalization);
        solve_frame(&mut packed, &settings, dt).unwrap()
    };
    let line_search = solve(Globalization::LineSearch);
    let region = solve(Globalization::TrustRegion);
    assert!(line_search.converged && region.converged);
    assert!(line_search.iterations > 10, "a buckling frame: {} iterations", line_search.iterations);
    assert!(region.merits.len() > 10);
    for w in region.merits.windows(2) {
        // (a step at the round-off floor may keep the merit within its round-off)
        assert!(w[1] <= w[0] + 1e-12 * w[0].abs(), "the merit rose: {} -> {}", w[0], w[1]);
    }
    // (another equilibrium of lower energy is fine, as in the issue's equal-accuracy rule)
    assert!(rel(region.energy, line_search.energy) < 1e-3, "energies {} and {}", region.energy, line_search.energy);
    assert!(region.constraint_violation <= 1e-9);
    assert!(
        region.iterations as f64 <= 1.6 * line_search.iterations as f64,
        "{} iterations against {}",
        region.iterations,
        line_search.iterations
    );
    eprintln!(
        "buckling frame: line search {} iterations / {} factorizations, trust region {} / {}",
        line_search.iterations, line_search.factorizations, region.iterations, region.factorizations
    );
}

/// Issue 26: a frame that starts where the last one was accepted is accepted again without an
/// iteration and leaves the state bitwise unchanged, also when the last one ended above the
/// tolerance (at the round-off floor: with the load held, re-iterating crawled 5-8 iterations a
/// frame), and also on a rebuilt system (a remesh's `invalidate`). A state further from
/// equilibrium than that is solved.
#[test]
fn a_held_frame_accepted_at_its_floor_is_not_solved_again() {
    use skinsim::solve::{solve_frame, PackedPatch};
    let scene = load_str(&held_sheet("Ldlt", "Clamp"), &scene_path("held.ron")).unwrap();
    let mut sim = Simulation::new(&scene);
    sim.step();
    sim.step(); // the full compression, held from here on
    let dt = sim.world.resource::<SimClock>().dt;
    let mut q = sim.world.query::<&PackedPatch>();
    let start = q.single(&sim.world).unwrap();
    let mut packed = without_cache(start);
    let mut settings = scene.patches[0].solver.clone();
    let first = solve_frame(&mut packed, &settings, dt).unwrap();
    assert!(first.converged && first.iterations > 0, "from zero multipliers: {} iterations", first.iterations);
    // The same state, now above a tighter tolerance but at the residual the last frame accepted.
    settings.tolerance = first.residual / 10.0;
    let x = packed.state.x.clone();
    let held = solve_frame(&mut packed, &settings, dt).unwrap();
    assert!(held.converged);
    assert_eq!(held.iterations, 0);
    assert_eq!(held.residual, first.residual);
    assert!(packed.state.x == x, "the held frame moved the state");
    let again = solve_frame(&mut packed, &settings, dt).unwrap();
    assert_eq!(again.iterations, 0, "and again: it stays accepted");
    packed.cache.invalidate(); // as a remesh or new kernels do
    assert_eq!(solve_frame(&mut packed, &settings, dt).unwrap().iterations, 0, "the floor is the load's");
    // One free vertex pushed 1 um along z: the residual rises above the floor.
    let v = (0..packed.state.x.len()).find(|&v| packed.state.fixed[v] == [false; 3]).expect("a free vertex");
    packed.state.x[v].z += 1e-6;
    let floor = first.residual;
    let mut resumed = without_cache(&packed);
    (resumed.cache.accepted, resumed.load_held) = (floor, true);
    let pushed = solve_frame(&mut packed, &settings, dt).unwrap();
    assert!(pushed.iterations > 0, "a disturbed state is solved");
    // (a loading frame: on to the tighter tolerance, here until the stall test, 5 iterations)
    // Under a held load (the drivers unchanged, as after a remesh) the same disturbance is
    // converged once its residual is back within the floor the load was accepted at (1).
    let back = solve_frame(&mut resumed, &settings, dt).unwrap();
    assert!(back.converged && back.residual < floor, "{} not below the floor {floor}", back.residual);
    // The level stays the load's, not this frame's (lower) residual: the next held remesh stops
    // at the same floor. A loading frame's is its own.
    assert_eq!(resumed.cache.accepted, floor);
    assert_eq!(packed.cache.accepted, pushed.residual.min(1e3 * settings.tolerance));
    assert!(
        back.iterations > 0 && back.iterations < pushed.iterations,
        "{} against {}",
        back.iterations,
        pushed.iterations
    );
}

#[test]
fn the_load_is_held_from_the_frame_after_the_last_keyframe() {
    let scene = load_str(&held_sheet("Ldlt", "Clamp"), &scene_path("held.ron")).unwrap();
    let mut sim = Simulation::new(&scene);
    let mut held = Vec::new();
    for _ in 0..4 {
        sim.step();
        held.push(sim.world.query::<&skinsim::model::LoadHeld>().single(&sim.world).unwrap().0);
    }
    assert_eq!(held, [false, false, true, true], "keyframes (0, 0) and (2, strain)");
}
