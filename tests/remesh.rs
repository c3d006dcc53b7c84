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
