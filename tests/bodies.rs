//! Issue 24, item 3: one kinematic body shared by several patches. The body is one entity moved
//! by its own drivers; each patch on it is its own solve, and its result does not depend on the
//! other patches on the body. Regions (`Offset(region: ...)`) cut a patch out of the body.

mod common;

use std::path::Path;

use bevy_ecs::prelude::*;
use common::mentions;
use skinsim::model::{Layer, LayerOf, Patch, Position};
use skinsim::scene::{load_str, SceneError};
use skinsim_systems::Simulation;

/// A closed tube (radius 8 mm, 60 mm) bending at x = 0, and a skin patch over its bend on the
/// -z side (material v = 8 pi mm there) for each `(name, u range)`, held by geodesic kernels.
fn scene(patches: &[(&str, (f64, f64))]) -> String {
    let patch = |(name, (u0, u1)): &(&str, (f64, f64))| {
        format!(
            r#"Patch(name: "{name}", body: "arm",
                solver: (tolerance: 1e-8, max_iterations: 300, projection: None,
                         perturbation: Some((amplitude: 0.00375, seed: 3))),
                layers: [Layer(name: "skin", kind: Shell,
                    mesh: Offset(layer: "arm", distance: 0.01875, region: Uv(min: ({u0:.1}, 16.0), max: ({u1:.1}, 34.0))),
                    material: (young: 4.0, poisson: 0.45, thickness: 0.0375), bending: Some((model: Tan)))],
                couplings: [Coupling(upper: "skin", lower: "arm", wavelength: Eq31(constant: 5.657, lower: Some((0.5, 15.0))),
                                     seed: 1, distance: Geodesic)])"#
        )
    };
    let list: Vec<String> = patches.iter().map(patch).collect();
    format!(
        r#"Scene(name: "shared", units: (length: Millimetre, stress: MegaPascal), frames: 3,
        bodies: [Body(name: "arm", mesh: Tube(radius: 8.0, length: 60.0, cells: (64, 60)),
                      drivers: [Joint(layers: ["arm"], pivot: (0.0, 0.0, 0.0), axis: Y, along: X, width: 20.0,
                                      keyframes: [(0, 0.0), (3, 12.0)])])],
        patches: [{}])"#,
        list.join(",\n")
    )
}

fn run(text: &str) -> Simulation {
    let built = load_str(text, Path::new("shared.ron")).unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(&built);
    for frame in 1..=built.scene.frames {
        let s = sim.step();
        assert!(sim.failure().is_none(), "frame {frame}: {:?}", sim.failure());
        assert!(s.patches.iter().all(|p| p.outcome.converged), "frame {frame}: {:?}", s.patches);
    }
    sim
}

/// Every (patch, layer) name pair and the number of layer entities of that name.
fn layer_owners(sim: &mut Simulation) -> Vec<(String, String)> {
    let mut q = sim.world.query::<(&Layer, &LayerOf)>();
    let pairs: Vec<(Entity, String)> = q.iter(&sim.world).map(|(l, of)| (of.0, l.name.clone())).collect();
    let mut out: Vec<(String, String)> =
        pairs.into_iter().map(|(p, l)| (sim.world.get::<Patch>(p).unwrap().name.clone(), l)).collect();
    out.sort();
    out
}

#[test]
fn a_patch_on_a_shared_body_is_the_same_alone_and_beside_others() {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let (mut alone, mut together) = pool.install(|| {
        (run(&scene(&[("near", (-12.0, 12.0))])), run(&scene(&[("far", (14.0, 28.0)), ("near", (-12.0, 12.0))])))
    });
    let bits = |v: Vec<glam::DVec3>| -> Vec<[u64; 3]> { v.iter().map(|p| p.to_array().map(f64::to_bits)).collect() };
    let a = bits(alone.layer_positions("near", "skin"));
    let b = bits(together.layer_positions("near", "skin"));
    assert!(!a.is_empty());
    assert_eq!(a, b, "the patch's skin, alone and beside another patch on the body");
    // One body entity for both patches (not a copy each), moved by its joint.
    let owners = layer_owners(&mut together);
    let arm = owners.iter().filter(|(_, l)| l == "arm").count();
    assert_eq!(arm, 1, "{owners:?}");
    let body = together.layer_positions("arm", "arm");
    let moved = body.iter().filter(|p| p.x > 0.015).all(|p| p.z.abs() > 1e-6 || p.y.abs() > 7.9e-3);
    assert!(moved && body.iter().any(|p| p.x > 0.015), "the body follows its joint");
    // The near patch wrinkled (the bend compresses its -z side): it is not its rest offset.
    let near = together.layer_positions("near", "skin");
    assert!(near.len() > 100);
    let mut q = together.world.query::<&Position>();
    assert!(q.iter(&together.world).all(|p| p.0.is_finite()));
}

fn err(text: &str) -> SceneError {
    match load_str(text, Path::new("scene.ron")) {
        Ok(_) => panic!("should be refused:\n{text}"),
        Err(e) => e,
    }
}

#[test]
fn a_patch_naming_no_body_is_refused() {
    let good = scene(&[("near", (-12.0, 12.0))]);
    let e = err(&good.replace(r#"body: "arm""#, r#"body: "leg""#));
    mentions(&e, &["patches[0]", ".body", "no body named \"leg\"", "\"arm\""]);
    let e = err(&good.replace(r#"Patch(name: "near""#, r#"Patch(name: "arm""#));
    mentions(&e, &["patches[0].name", "also the name of bodies[0]"]);
}

#[test]
fn a_region_that_selects_no_face_is_refused() {
    let good = scene(&[("near", (-12.0, 12.0))]);
    let e = err(&good.replace("min: (-12.0, 16.0), max: (12.0, 34.0)", "min: (100.0, 16.0), max: (120.0, 34.0)"));
    mentions(&e, &["patches[0]", "layers[0] (\"skin\").mesh.region", "selects no face of \"arm\""]);
    let e = err(&good.replace("min: (-12.0, 16.0), max: (12.0, 34.0)", "min: (12.0, 16.0), max: (-12.0, 34.0)"));
    mentions(&e, &["mesh.region", "min < max"]);
    let e = err(&good.replace(
        "region: Uv(min: (-12.0, 16.0), max: (12.0, 34.0))",
        r#"region: Mask(image: "nowhere.png", threshold: 0.5)"#,
    ));
    mentions(&e, &["nowhere.png", "region.image", "cannot read"]);
}

#[test]
fn a_body_moves_by_its_own_drivers_only() {
    let good = scene(&[("near", (-12.0, 12.0))]);
    let patch_drives_body = good.replace(
        r#"seed: 1, distance: Geodesic)])"#,
        r#"seed: 1, distance: Geodesic)],
           drivers: [Bend(layers: ["arm"], axis: Y, keyframes: [(0, 0.0), (3, 1.0)])])"#,
    );
    let e = err(&patch_drives_body);
    mentions(&e, &["patches[0]", "drivers[0]", "the body \"arm\" moves by its own drivers", "bodies[0].drivers"]);
    let body_pins = good.replace(
        r#"drivers: [Joint(layers: ["arm"]"#,
        r#"drivers: [Pin(layer: "arm", select: All), Joint(layers: ["arm"]"#,
    );
    let e = err(&body_pins);
    mentions(&e, &["bodies[0] (\"arm\").drivers[0]", "motions only"]);
    let e = err(&good.replace(
        r#"Patch(name: "near", body: "arm","#,
        r#"Patch(name: "near", body: "arm", offset: (1.0, 0.0, 0.0),"#,
    ));
    mentions(&e, &["patches[0] (\"near\").offset", "sits where the body is"]);
}

#[test]
fn a_region_can_be_an_obj_group() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/character");
    let text = |region: &str| {
        format!(
            r#"Scene(name: "groups", frames: 1,
            bodies: [Body(name: "hand", mesh: Obj(path: "assets/hand_quick.obj"))],
            patches: [Patch(name: "p", body: "hand", layers: [
                Layer(name: "skin", kind: Shell, mesh: Offset(layer: "hand", distance: 0.02, region: {region}),
                      material: (young: 4.0, poisson: 0.45, thickness: 0.04))])])"#
        )
    };
    let built = load_str(&text(r#"Group("finger_a")"#), &dir.join("groups.ron")).unwrap_or_else(|e| panic!("{e}"));
    let skinsim::scene::built::LayerMesh::Surface(m) = &built.patches[0].layers[1].mesh else { panic!("a surface") };
    // `skinsim asset hand --finger-cells 40,96`: one finger is 40 x 96 quads.
    assert_eq!((m.faces.len(), m.rest.len()), (2 * 40 * 96, 40 * 97));
    assert!(m.rest.iter().all(|p| p.y < 0.0), "finger a lies at y = -10 mm");
    let e = load_str(&text(r#"Group("thumb")"#), &dir.join("groups.ron")).unwrap_err();
    mentions(&e, &["mesh.region", "no group \"thumb\"", "\"arm\", \"finger_a\", \"finger_b\""]);
    let tube = scene(&[("near", (-12.0, 12.0))])
        .replace("region: Uv(min: (-12.0, 16.0), max: (12.0, 34.0))", r#"region: Group("finger_a")"#);
    let e = err(&tube);
    mentions(&e, &["mesh.region", "\"arm\" is not an OBJ mesh"]);
}

#[test]
fn a_region_can_be_a_painted_mask() {
    // A mask over the arm's material rectangle (u = x from -30 to 30 mm, v = arc length), white
    // on its left half (u < 0) only.
    let dir = common::scratch_dir("bodies-mask");
    let mask = image::GrayImage::from_fn(64, 64, |x, _| image::Luma([if x < 32 { 255 } else { 0 }]));
    mask.save(dir.join("left.png")).unwrap();
    let text = |threshold: f64| {
        format!(
            r#"Scene(name: "mask", frames: 1,
            bodies: [Body(name: "arm", mesh: Tube(radius: 8.0, length: 60.0, cells: (64, 60)))],
            patches: [Patch(name: "p", body: "arm", layers: [
                Layer(name: "skin", kind: Shell,
                      mesh: Offset(layer: "arm", distance: 0.02, region: Mask(image: "left.png", threshold: {threshold:.1})),
                      material: (young: 4.0, poisson: 0.45, thickness: 0.04))])])"#
        )
    };
    let built = load_str(&text(0.5), &dir.join("mask.ron")).unwrap_or_else(|e| panic!("{e}"));
    let skinsim::scene::built::LayerMesh::Surface(m) = &built.patches[0].layers[1].mesh else { panic!("a surface") };
    // The left half of the tube: 30 of its 60 rings of quads (the painted edge is at u = 0).
    assert_eq!(m.faces.len(), 2 * 64 * 30, "faces");
    assert!(m.uv.iter().all(|u| u.x <= 1e-9), "only the painted (left) half");
    let e = load_str(&text(1.5), &dir.join("mask.ron")).unwrap_err();
    mentions(&e, &["region.threshold", "[0, 1]"]);
}
