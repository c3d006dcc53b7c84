//! Resume (issue 66): a run continued from a checkpoint computes the frames after it bit for bit
//! as the uninterrupted run did, on remeshing (kernels on a remeshed layer), anchor, volume and
//! contact scenes. The character hand (kernels, anchors, a shared body) is resumed through the
//! binary in `tools/tests/resume.rs`.

mod common;

use bevy_ecs::prelude::*;
use skinsim::model::*;
use skinsim_systems::checkpoint::Checkpoint;
use skinsim_systems::{FrameStats, Simulation};

/// A frame's stats line without its timings, and every vertex position's bits by layer order.
fn frame_record(sim: &mut Simulation, stats: &FrameStats) -> (String, Vec<[u64; 3]>) {
    let line = skinsim_systems::without_timings(serde_json::to_value(stats).unwrap());
    let mut layers: Vec<Entity> = sim.world.query_filtered::<Entity, With<Layer>>().iter(&sim.world).collect();
    layers.sort_by_key(|e| e.to_bits());
    let mut x = Vec::new();
    for l in layers {
        let Some(verts) = sim.world.get::<LayerVertices>(l) else { continue };
        for &v in verts.entities() {
            x.push(sim.world.get::<Position>(v).unwrap().0.to_array().map(f64::to_bits));
        }
    }
    (line.to_string(), x)
}

/// Runs `frames` frames of `scene` uninterrupted and again with a checkpoint after frame `at`
/// (round-tripped through serde) restored into a fresh World; asserts the frames after it match.
fn resumes_bit_identically(rel: &str, frames: u32, at: u32) -> Checkpoint {
    resumes_built(rel, &common::load(rel), frames, at)
}

fn resumes_built(rel: &str, built: &skinsim::scene::BuiltScene, frames: u32, at: u32) -> Checkpoint {
    let mut whole = Simulation::new(built);
    let mut expected = Vec::new();
    let mut saved = None;
    for f in 1..=frames {
        let stats = whole.step();
        assert!(whole.failure().is_none(), "{rel}: frame {f} failed");
        expected.push(frame_record(&mut whole, &stats));
        if f == at {
            saved = Some(whole.checkpoint());
        }
    }
    let saved = saved.unwrap();
    let read = Checkpoint::from_bytes(&saved.to_bytes()).unwrap();
    assert!(read == saved, "{rel}: the checkpoint does not round-trip");
    let mut resumed = Simulation::resume(built, &read).unwrap_or_else(|e| panic!("{rel}: {e}"));
    for f in at + 1..=frames {
        let stats = resumed.step();
        let got = frame_record(&mut resumed, &stats);
        let want = &expected[(f - 1) as usize];
        assert_eq!(got.0, want.0, "{rel}: frame {f}'s stats differ after a resume at {at}");
        let diff = got
            .1
            .iter()
            .zip(&want.1)
            .flat_map(|(a, b)| (0..3).map(move |k| (f64::from_bits(a[k]) - f64::from_bits(b[k])).abs()))
            .fold(0.0, f64::max);
        assert!(got.1 == want.1, "{rel}: frame {f}'s positions differ after a resume at {at} (by up to {diff:e} m)");
    }
    saved
}

#[test]
fn a_remeshing_scene_resumes_bit_identically() {
    let saved = resumes_bit_identically("lk14/remesh_one_layer_quick.ron", 6, 3);
    let dermis = saved.layers.iter().find(|l| l.name == "dermis").unwrap();
    assert!(dermis.epoch > 0, "the dermis was remeshed before the checkpoint");
}

/// Remeshed every second frame (2, 4, 6) and saved after the remesh of frame 2: frame 3 keeps
/// the remeshed topology, so the resumed run takes up the whole solver carry (the KKT memory
/// included) on a mesh the remesher made; frame 4 remeshes again.
#[test]
fn a_layer_remeshed_before_the_checkpoint_resumes_bit_identically_between_remeshes() {
    let rel = "lk14/remesh_one_layer_quick.ron";
    let built = common::variant(rel, &[("refine_compression: 0.2))", "refine_compression: 0.2, every: 2))")]);
    let saved = resumes_built(rel, &built, 5, 2);
    let dermis = saved.layers.iter().find(|l| l.name == "dermis").unwrap();
    assert_eq!(dermis.remesh.map(|r| r.frame), Some(2));
    let mut fresh = Simulation::new(&built);
    let spawned: std::collections::HashSet<u64> =
        fresh.world.query::<(Entity, &FaceOf)>().iter(&fresh.world).map(|(e, _)| e.to_bits()).collect();
    let made = dermis.faces.iter().filter(|f| !spawned.contains(&f.id)).count();
    assert!(made > 0, "the dermis holds faces the remesh made");
}

#[test]
fn a_volume_scene_resumes_bit_identically() {
    resumes_bit_identically("examples/volume_slab.ron", 5, 2);
}

#[test]
fn an_anchor_scene_resumes_bit_identically() {
    resumes_bit_identically("kck18/crease_quick.ron", 5, 2);
}

#[test]
fn a_contact_scene_resumes_bit_identically() {
    resumes_bit_identically("examples/fold_strip.ron", 6, 3);
}
