//! KCK18 sliding skin (VALIDATION.md D): anchors stay on the body (case 13), the walk moves them
//! continuously where projection jumps across folds (case 14), and the walk's share of the frame
//! is reported (case 15). Quick scenes; the full ones belong to `skinsim timing`.

mod common;

use common::*;
use glam::DVec3;
use parry3d_f64::math::Vector;
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::TriMesh;
use skinsim::model::{AnchorReport, Stage};
use skinsim_systems::{FrameStats, Simulation};

fn report(stats: &FrameStats, patch: &str) -> AnchorReport {
    let p = stats.patches.iter().find(|p| p.name == patch).expect("patch");
    p.anchors.expect("anchor report")
}

/// Case 13: after every frame, each anchor is on its body's current surface (distance below
/// 1e-12 of the body size) inside its triangle.
#[test]
fn case_13_anchors_never_leave_the_body_surface() {
    for scene in ["kck18/crease_quick.ron", "kck18/elbow_quick.ron"] {
        let built = load(scene);
        let mut sim = Simulation::new(&built);
        let mut worst = 0.0f64;
        for _ in 0..built.scene.frames {
            sim.step();
            assert!(sim.failure().is_none(), "{scene}: {:?}", sim.failure());
            for patch in ["walk", "project", "ring"] {
                let (_, x, faces) = sim.layer_surface(patch, "body");
                let (lo, hi) =
                    x.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
                let size = (hi - lo).length();
                let mesh = TriMesh::new(x.iter().map(|p| Vector::new(p.x, p.y, p.z)).collect(), faces).unwrap();
                for (point, state) in sim.anchors(patch) {
                    let st = point.st;
                    assert!(st.x >= 0.0 && st.y >= 0.0 && st.x + st.y <= 1.0 + 1e-15, "{st:?}");
                    let p = state.position;
                    let d = mesh.distance_to_local_point(Vector::new(p.x, p.y, p.z), false);
                    worst = worst.max(d / size);
                }
            }
        }
        println!("case 13 {scene}: farthest anchor from the body {worst:.2e} of the body size");
        assert!(worst < 1e-12, "{scene}: {worst:e}");
    }
}

/// Case 14: on the crease closing to zero width and on the self-intersecting fold, no walked
/// anchor jumps farther over the body than its own step (the body folds isometrically, so the
/// jump is measured exactly on its rest surface), while projection springs jump across the fold.
#[test]
fn case_14_the_walk_is_continuous_where_projection_jumps() {
    for (scene, projected_at_least) in [("kck18/crease_quick.ron", 5e-3), ("kck18/self_intersect_quick.ron", 1e-3)] {
        let built = load(scene);
        let (sim, stats) = run(&built);
        assert!(sim.failure().is_none(), "{scene}: {:?}", sim.failure());
        let max = |patch: &str, f: fn(&AnchorReport) -> f64| {
            stats.iter().map(|s| f(&report(s, patch))).fold(0.0f64, f64::max)
        };
        let walk_excess = max("walk", |r| r.max_excess);
        let walked = max("walk", |r| r.max_walked);
        let (project, ring) = (max("project", |r| r.max_jump), max("ring", |r| r.max_jump));
        println!(
            "case 14 {scene}: largest jump over the step: walk {:.3} mm (walked {:.3} mm); largest jump: \
             projection {:.2} mm, 2-ring projection {:.2} mm",
            walk_excess * 1e3,
            walked * 1e3,
            project * 1e3,
            ring * 1e3
        );
        assert!(walk_excess <= 1e-9, "{scene}: a walked anchor jumped {walk_excess:e} m beyond its step");
        for s in &stats {
            let r = report(s, "walk");
            assert!(r.max_walked <= r.max_step * (1.0 + 1e-12) + 1e-15, "{scene} frame {}: {r:?}", s.frame);
        }
        assert!(project > projected_at_least, "{scene}: projection jumped only {project:e} m");
    }
}

/// Case 15, reported (a test asserts no time): the walk's share of the frame on the quick
/// creature; the full-size figure comes from `skinsim timing scenes/kck18/creature.ron`.
#[test]
fn case_15_walk_share_is_reported() {
    let built = load("kck18/creature_quick.ron");
    let (sim, stats) = run(&built);
    assert!(sim.failure().is_none(), "{:?}", sim.failure());
    let walk: f64 = stats.iter().map(|s| s.timing(Stage::AnchorWalk)).sum();
    let total: f64 = stats.iter().map(|s| s.total_ms()).sum();
    println!("case 15 creature_quick: walk {:.1} ms of {:.0} ms ({:.2} %)", walk, total, 100.0 * walk / total);
    assert!(stats.iter().all(|s| s.patches[0].outcome.converged), "every frame converges");
    // (No time is asserted: the share is reported.) Every anchor took part in every walk.
    assert!(stats.iter().all(|s| report(s, "creature").anchors == 642 + 1280));
}

/// KCK18 fig. 2: bending is off by default and on as an option; with it the squeezed skin of
/// the elbow bends (and the solve still converges every frame).
#[test]
fn bending_is_an_option_on_the_anchored_skin() {
    let (sim, stats) = run(&load("kck18/elbow_bending_quick.ron"));
    assert!(sim.failure().is_none(), "{:?}", sim.failure());
    assert!(stats.iter().all(|s| s.patches[0].outcome.converged));
    let last = &stats.last().unwrap().patches[0];
    assert!(
        last.outcome.parts.bending > 0.01 * last.outcome.parts.membrane,
        "{} J vs {} J",
        last.outcome.parts.bending,
        last.outcome.parts.membrane
    );
    let (_, plain) = run(&load("kck18/elbow_quick.ron"));
    assert_eq!(plain.last().unwrap().patches[0].outcome.parts.bending, 0.0, "off by default");
}
