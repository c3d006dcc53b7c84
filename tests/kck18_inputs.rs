//! KCK18 bad input (issue 6): body meshes with non-manifold edges or degenerate faces, OBJ
//! sequences whose vertex count changes, and skin that starts far from the body. Each is refused
//! at load with the file and the problem (status 2 from the binary: tools/tests/cli.rs).

mod common;

use common::{mentions, scratch_dir};

use std::path::PathBuf;

use skinsim::scene::{load, SceneError};

const SCENE: &str = r#"Scene(
    name: "kck18",
    units: (length: Millimetre, stress: MegaPascal),
    frames: 2,
    patches: [
        Patch(
            name: "p",
            layers: [
                Layer(name: "body", kind: Kinematic, mesh: {body}),
                Layer(name: "skin", kind: Shell, mesh: Offset(layer: "body", distance: {gap}),
                      material: (model: StableNeoHookean, young: 0.1, poisson: 0.45, thickness: 1.0)),
            ],
            drivers: [{drivers}],
            anchors: (skin: "skin", body: "body", stiffness: 0.002, max_distance: 1.0),
        ),
    ],
)"#;

/// Two triangles of a unit square, and a third sharing their diagonal (non-manifold) or
/// repeating a vertex (degenerate), as OBJ text.
const SQUARE: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n";

fn dir() -> PathBuf {
    scratch_dir("kck18-inputs")
}

fn load_with(name: &str, body: &str, gap: f64, drivers: &str, files: &[(&str, &str)]) -> Result<(), SceneError> {
    let d = dir();
    for (f, text) in files {
        std::fs::write(d.join(f), text).unwrap();
    }
    let text = SCENE.replace("{body}", body).replace("{gap}", &gap.to_string()).replace("{drivers}", drivers);
    let path = d.join(name);
    std::fs::write(&path, text).unwrap();
    load(&path).map(|_| ())
}

#[test]
fn a_good_body_loads_and_reports_its_binding() {
    load_with("good.ron", r#"Obj(path: "square.obj")"#, 0.0, "", &[("square.obj", SQUARE)]).unwrap();
}

#[test]
fn a_body_with_a_non_manifold_edge_is_refused() {
    let obj = format!("{SQUARE}v 0.5 0.5 1\nf 1 3 5\n");
    let e = load_with("nm.ron", r#"Obj(path: "nm.obj")"#, 0.0, "", &[("nm.obj", &obj)]).unwrap_err();
    mentions(&e, &["nm.obj", "non-manifold", "layers[0]"]);
}

#[test]
fn a_body_with_a_degenerate_face_is_refused() {
    let obj = format!("{SQUARE}v 2 0 0\nf 2 5 2\n");
    let e = load_with("deg.ron", r#"Obj(path: "deg.obj")"#, 0.0, "", &[("deg.obj", &obj)]).unwrap_err();
    mentions(&e, &["deg.obj", "degenerate"]);
}

#[test]
fn an_obj_sequence_that_changes_vertex_count_is_refused() {
    let longer = format!("{SQUARE}v 2 0 0\nf 2 5 3\n");
    let drivers = r#"ObjSequence(layer: "body", files: ["f0.obj", "f1.obj"])"#;
    let files = [("sq.obj", SQUARE), ("f0.obj", SQUARE), ("f1.obj", longer.as_str())];
    let e = load_with("seq.ron", r#"Obj(path: "sq.obj")"#, 0.0, drivers, &files).unwrap_err();
    mentions(&e, &["f1.obj", "drivers[0].files[1]", "5 vertices", "has 4"]);
}

#[test]
fn skin_far_from_the_body_is_refused_with_the_distance() {
    let e = load_with("far.ron", r#"Obj(path: "square.obj")"#, 3.0, "", &[("square.obj", SQUARE)]).unwrap_err();
    mentions(&e, &["far.ron", "anchors.max_distance", "skin vertex 0", "3.0000", "limit 1.0000"]);
}

/// A painted stiffness: the red channel ramps 0 -> 1 across x and maps to 1x -> 3x, so face
/// anchors on the right hold about three times as hard per unit area as those on the left; a
/// range that maps a present colour to zero is refused.
#[test]
fn a_stiffness_map_paints_the_anchors_and_a_non_positive_factor_is_refused() {
    let body = r#"Grid(size: (10.0, 10.0), cells: (10, 10), pattern: Alternating)"#;
    let map = r#"stiffness_map: (map: Ramp(axis: X, from: (0.0, 0.0, 0.0), to: (1.0, 0.0, 0.0)), range: {range}),"#;
    let text = |range: &str| {
        SCENE.replace("{body}", body).replace("{gap}", "0.0").replace("{drivers}", "").replace(
            "max_distance: 1.0)",
            &format!("max_distance: 1.0, {})", map.replace("{range}", range)).replace(",)", ")"),
        )
    };
    let path = dir().join("painted.ron");
    std::fs::write(&path, text("(1.0, 3.0)")).unwrap();
    let built = load(&path).unwrap_or_else(|e| panic!("{e}"));
    let a = built.patches[0].anchors.as_ref().unwrap();
    let per_area: Vec<f64> = a.face.iter().map(|&(_, _, k)| k).collect();
    let (lo, hi) = per_area.iter().fold((f64::INFINITY, 0.0f64), |(l, h), k| (l.min(*k), h.max(*k)));
    assert!(hi / lo > 2.5 && hi / lo < 3.0, "stiffest / softest face anchor: {}", hi / lo);
    std::fs::write(&path, text("(0.0, 1.0)")).unwrap();
    let e = load(&path).unwrap_err();
    mentions(&e, &["painted.ron", "anchors.stiffness_map.range", "must be > 0"]);
}

/// KCK18 section 3: the skin under anchors is Stable Neo-Hookean unless the scene says otherwise.
#[test]
fn an_anchored_skin_defaults_to_stable_neo_hookean() {
    use skinsim::physics::ConstitutiveModel;
    let text = SCENE
        .replace("{body}", r#"Obj(path: "square.obj")"#)
        .replace("{gap}", "0.0")
        .replace("{drivers}", "")
        .replace("model: StableNeoHookean, ", "");
    let d = dir();
    std::fs::write(d.join("square.obj"), SQUARE).unwrap();
    std::fs::write(d.join("default.ron"), &text).unwrap();
    let built = load(&d.join("default.ron")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(built.patches[0].layers[1].material.unwrap().model, ConstitutiveModel::StableNeoHookean);
    let stated = text.replace("young: 0.1", "model: BazantHencky, young: 0.1");
    std::fs::write(d.join("stated.ron"), stated).unwrap();
    let built = load(&d.join("stated.ron")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(built.patches[0].layers[1].material.unwrap().model, ConstitutiveModel::BazantHencky);
}

/// An OBJ sequence animates the body: frame start + i takes file i's positions, the last file
/// holds after, and the anchored skin follows.
#[test]
fn an_obj_sequence_drives_the_body_frame_by_frame() {
    let lifted = |z: f64| SQUARE.replace(" 0\nv", &format!(" {z}\nv")).replacen("v 0 1 0", &format!("v 0 1 {z}"), 1);
    let files = [("base.obj", SQUARE.to_string()), ("a.obj", lifted(0.1)), ("b.obj", lifted(0.2))];
    let d = dir();
    for (f, t) in &files {
        std::fs::write(d.join(f), t).unwrap();
    }
    let drivers = r#"ObjSequence(layer: "body", files: ["a.obj", "b.obj"], start: 1)"#;
    let text = SCENE
        .replace("{body}", r#"Obj(path: "base.obj")"#)
        .replace("{gap}", "0.0")
        .replace("{drivers}", drivers)
        .replace("frames: 2", "frames: 3");
    std::fs::write(d.join("sequence.ron"), text).unwrap();
    let built = load(&d.join("sequence.ron")).unwrap_or_else(|e| panic!("{e}"));
    let mut sim = skinsim_systems::Simulation::new(&built);
    for (frame, z) in [(1, 0.1e-3), (2, 0.2e-3), (3, 0.2e-3)] {
        sim.step();
        assert!(sim.failure().is_none(), "{:?}", sim.failure());
        let body = sim.layer_positions("p", "body");
        assert!(body.iter().all(|p| (p.z - z).abs() < 1e-15), "frame {frame}: {body:?}");
        let skin = sim.layer_positions("p", "skin");
        assert!(skin.iter().all(|p| (p.z - z).abs() < 1e-9), "frame {frame}: the skin follows: {skin:?}");
    }
}
