//! Layered volumetric patches (the groundwork of H15's construction): tetrahedral layers stacked
//! with shared interface vertices, a shell that is the top surface of a volume layer, the bottom
//! attached by springs, periodic and plane-strain ties.

mod common;

use bevy_ecs::prelude::*;
use common::*;
use skinsim::model::PackedIndex;
use skinsim::model::{Mass, Position, Spring};
use skinsim::scene::load_str;
use skinsim::solve::PackedPatch;
use skinsim_systems::Simulation;

const STACK: &str = r#"Scene(name: "stack", frames: 2, units: (length: Millimetre, stress: KiloPascal), patches: [
    Patch(name: "skin", solver: (projection: Adaptive), layers: [
        Layer(name: "body", kind: Kinematic, mesh: Grid(size: (4.0, 2.0), cells: (4, 2), pattern: RightTriangle, z: -3.0)),
        Layer(name: "hypodermis", kind: Volume,
              mesh: TetSlab(size: (4.0, 2.0), cells: (4, 2), depth: 1.5, elements: 2, top: -1.0),
              material: (young: 13.0, poisson: 0.45, density: 1000.0)),
        Layer(name: "dermis", kind: Volume, mesh: TetOn(layer: "hypodermis", depth: 1.0, elements: 3),
              material: (young: 1.0, poisson: 0.45, density: 1200.0)),
        Layer(name: "corneum", kind: Shell, mesh: SurfaceOf(layer: "dermis"),
              material: (young: 1000.0, poisson: 0.45, density: 1500.0, thickness: 0.02), bending: (model: Tan)),
    ], drivers: [
        Attach(layer: "hypodermis", to: "body", stiffness: 10.0),
        Compress(layers: ["body", "hypodermis", "dermis"], keyframes: [(0, 0.0), (2, 0.05)]),
    ]),
])"#;

#[test]
fn stacked_layers_share_their_interfaces() {
    let scene = load_str(STACK, &scene_path("stack.ron")).unwrap();
    let dermis = &scene.patches[0].layers[2];
    assert_eq!(dermis.mesh.rest()[0].z, -1.0e-3, "the dermis starts on the hypodermis' top");
    let mut sim = Simulation::new(&scene);
    let plane = 5 * 3;
    // body + hypodermis (3 planes) + dermis (3 new planes); the corneum owns no vertex.
    let unique = plane + 3 * plane + 3 * plane;
    let stats = sim.step();
    assert_eq!(stats.patches[0].vertices, unique);
    assert!(stats.patches[0].outcome.converged, "{:?}", stats.patches[0]);
    // Springs from the hypodermis' bottom plane only.
    let springs = sim.world.query::<&Spring>().iter(&sim.world).count();
    assert_eq!(springs, plane);
    // Lumped masses: every layer's density x volume, shared vertices counted once.
    let total: f64 = sim.world.query::<&Mass>().iter(&sim.world).map(|m| m.0).sum();
    let volume = |depth: f64| 4e-3 * 2e-3 * depth;
    let expected = 1000.0 * volume(1.5e-3) + 1200.0 * volume(1.0e-3) + 1500.0 * 4e-3 * 2e-3 * 0.02e-3;
    assert!((total / expected - 1.0).abs() < 1e-12, "{total} vs {expected}");
    // The corneum's faces use the dermis' own top vertices (shared, not copied).
    let mut layers = sim.world.query::<(Entity, &skinsim::model::Layer)>();
    let id = |name: &str, w: &World, q: &mut QueryState<(Entity, &skinsim::model::Layer)>| {
        q.iter(w).find(|(_, l)| l.name == name).unwrap().0
    };
    let (dermis, corneum) = (id("dermis", &sim.world, &mut layers), id("corneum", &sim.world, &mut layers));
    let mut faces = sim.world.query::<(&skinsim::model::FaceVerts, &skinsim::model::FaceOf)>();
    let corneum_faces: Vec<[Entity; 3]> =
        faces.iter(&sim.world).filter(|(_, of)| of.0 == corneum).map(|(f, _)| f.0).collect();
    assert_eq!(corneum_faces.len(), 2 * 4 * 2);
    for f in corneum_faces {
        for v in f {
            assert_eq!(sim.world.get::<skinsim::model::VertexOf>(v).unwrap().0, dermis);
            assert!((sim.world.get::<skinsim::model::RestPos>(v).unwrap().0.z).abs() < 1e-12, "top plane z = 0");
        }
    }
}

#[test]
fn a_coarsening_stack_shares_its_interfaces_and_solves() {
    // Issue 25 item 3: the grid halves every 0.6 mm below the skin (z = 0). Planes from the
    // top: z = 0 and -0.5 (8 x 4), -1 (4 x 2; the dermis' bottom is the hypodermis' top), -1.5
    // (2 x 1), -2 (1 x 1).
    let text = STACK
        .replace(
            "cells: (4, 2), depth: 1.5, elements: 2, top: -1.0)",
            "cells: (8, 4), depth: 1.0, elements: 2, top: -1.0, coarsen: (every: 0.6, from: 0.0))",
        )
        .replace("depth: 1.0, elements: 3)", "depth: 1.0, elements: 2)")
        .replace(
            "Attach(layer: \"hypodermis\", to: \"body\", stiffness: 10.0),",
            "Pin(layer: \"hypodermis\", select: Sides([ZMin])),",
        );
    let scene = load_str(&text, &scene_path("coarse.ron")).unwrap();
    let mut sim = Simulation::new(&scene);
    let stats = sim.step();
    let body = 5 * 3;
    assert_eq!(stats.patches[0].vertices, body + 4 + 6 + 15 + 45 + 45);
    assert!(stats.patches[0].outcome.converged, "{:?}", stats.patches[0]);
    let total: f64 = sim.world.query::<&Mass>().iter(&sim.world).map(|m| m.0).sum();
    let expected = (1000.0 * 1.0e-3 + 1200.0 * 1.0e-3 + 1500.0 * 0.02e-3) * 4e-3 * 2e-3;
    assert!((total / expected - 1.0).abs() < 1e-12, "{total} vs {expected}");
    let mut layers = sim.world.query::<(Entity, &skinsim::model::Layer)>();
    let dermis = layers.iter(&sim.world).find(|(_, l)| l.name == "dermis").unwrap().0;
    let corneum = layers.iter(&sim.world).find(|(_, l)| l.name == "corneum").unwrap().0;
    let mut faces = sim.world.query::<(&skinsim::model::FaceVerts, &skinsim::model::FaceOf)>();
    let corneum_faces: Vec<[Entity; 3]> =
        faces.iter(&sim.world).filter(|(_, of)| of.0 == corneum).map(|(f, _)| f.0).collect();
    assert_eq!(corneum_faces.len(), 2 * 8 * 4, "the skin keeps the finest grid");
    for v in corneum_faces.into_iter().flatten() {
        assert_eq!(sim.world.get::<skinsim::model::VertexOf>(v).unwrap().0, dermis);
    }
}

const STRIP: &str = r#"Scene(name: "periodic", frames: 4, patches: [
    Patch(name: "bilayer", solver: (projection: Adaptive, max_iterations: 150, perturbation: (amplitude: 0.01, seed: 2)), layers: [
        Layer(name: "substrate", kind: Volume, mesh: TetSlab(size: (20.0, 1.0), cells: (20, 1), depth: 10.0, elements: 5),
              material: (young: 0.01, poisson: 0.3)),
        Layer(name: "film", kind: Shell, mesh: SurfaceOf(layer: "substrate"),
              material: (young: 10.0, poisson: 0.3, thickness: 0.1), bending: (model: Tan)),
    ], drivers: [
        PlaneStrain(layers: ["substrate", "film"], axis: Y),
        Periodic(layers: ["substrate", "film"], axis: X),
        Pin(layer: "substrate", select: Sides([ZMin])),
        Pin(layer: "substrate", select: Sides([XMin, XMax]), dofs: (x: true, y: false, z: false)),
        Compress(layers: ["substrate"], keyframes: [(0, 0.0), (4, 0.02)]),
    ]),
])"#;

#[test]
fn periodic_and_plane_strain_ties_hold_after_solving() {
    let scene = load_str(STRIP, &scene_path("periodic.ron")).unwrap();
    let mut sim = Simulation::new(&scene);
    let seam = sim.world.query::<&skinsim::model::Hinge>().iter(&sim.world).filter(|h| h.image.is_some()).count();
    assert_eq!(seam, 1);
    for _ in 0..4 {
        let s = sim.step();
        assert!(s.patches[0].outcome.converged, "{:?}", s.patches[0]);
    }
    let mut q = sim.world.query::<(&PackedPatch, &PackedIndex)>();
    let (body, index) = q.single(&sim.world).unwrap();
    let rest: Vec<glam::DVec3> =
        index.vertices.iter().map(|e| sim.world.get::<skinsim::model::RestPos>(*e).unwrap().0).collect();
    let pos = |e: Entity| sim.world.get::<Position>(e).unwrap().0;
    let mut checked = 0;
    for (i, a) in rest.iter().enumerate() {
        for (j, b) in rest.iter().enumerate() {
            let same_column = (a.x - b.x).abs() < 1e-12 && (a.z - b.z).abs() < 1e-12 && i != j;
            let across = (a.x - 0.0).abs() < 1e-12
                && (b.x - 0.02).abs() < 1e-12
                && (a.y - b.y).abs() < 1e-12
                && (a.z - b.z).abs() < 1e-12;
            let (pa, pb) = (pos(index.vertices[i]), pos(index.vertices[j]));
            if same_column {
                assert_eq!((pa.x, pa.z), (pb.x, pb.z), "plane strain");
                checked += 1;
            }
            if across {
                assert_eq!(pa.z, pb.z, "periodic in z");
                checked += 1;
            }
        }
    }
    assert!(checked > 100);
    // One hinge joins the film across the seam (one cell row), placed at its periodic image.
    let imaged: Vec<_> = body.elements.hinges.iter().filter(|h| h.image.is_some()).collect();
    assert_eq!(imaged.len(), 1);
    // Across the seam the four positions form an ordinary hinge (opposite vertices on both sides).
    let p = imaged[0].positions(&body.state.x);
    assert!(p[2].x < p[0].x && p[3].x > p[0].x, "{p:?}");
    // The compression really deformed the strip.
    assert!(body.state.x.iter().any(|p| p.z.abs() > 1e-7));
}

/// Issue 27: a volume layer at Poisson's ratio 0.495 evaluates its lambda term once per
/// hexahedral cell (six tets) by default, one at 0.45 or with `volume_element: Tet` per tet.
#[test]
fn nearly_incompressible_layers_share_one_dilatation_per_cell() {
    let packed = |text: &str| {
        let scene = load_str(text, &scene_path("cells.ron")).unwrap();
        let mut sim = Simulation::new(&scene);
        let s = sim.step();
        assert!(s.patches[0].outcome.converged, "{:?}", s.patches[0]);
        let mut q = sim.world.query::<&PackedPatch>();
        let el = q.single(&sim.world).unwrap().elements.clone();
        (el, s.patches[0].outcome.energy)
    };
    let stiff = STACK
        .replace("poisson: 0.45, density: 1000.0", "poisson: 0.495, density: 1000.0")
        .replace("poisson: 0.45, density: 1200.0", "poisson: 0.495, density: 1200.0");
    let (cells, e_cell) = packed(&stiff);
    // 4 x 2 grid cells through 2 + 3 levels.
    assert_eq!(cells.cells.len(), 4 * 2 * 5);
    assert_eq!(cells.tets.len(), 6 * 4 * 2 * 5);
    assert!(cells.tets.iter().all(|t| t.lame.lambda == 0.0));
    let bulk: f64 = cells.cells.iter().map(|c| c.rest.bulk).sum();
    let lambda = |young: f64| young * 0.495 / (1.495 * 0.01);
    let expected = lambda(13e3) * 4e-3 * 2e-3 * 1.5e-3 + lambda(1e3) * 4e-3 * 2e-3 * 1e-3;
    assert!((bulk / expected - 1.0).abs() < 1e-12, "{bulk} vs {expected}");
    let per_tet =
        stiff.replace("poisson: 0.495, density: 1000.0", "poisson: 0.495, density: 1000.0, volume_element: Tet");
    let (tets, e_tet) = packed(
        &per_tet.replace("poisson: 0.495, density: 1200.0", "poisson: 0.495, density: 1200.0, volume_element: Tet"),
    );
    assert!(tets.cells.is_empty() && tets.tets.iter().all(|t| t.lame.lambda > 0.0));
    // One constraint per cell instead of per tet: the same load finds a softer state.
    assert!(e_cell < e_tet, "{e_cell} vs {e_tet}");
    let (soft, _) = packed(STACK);
    assert!(soft.cells.is_empty(), "0.45: per tet by default");
}
