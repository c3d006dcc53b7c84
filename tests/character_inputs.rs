//! Bad input of a real rigged character (issue 62): glTF bodies, refined regions, the `Rig`
//! driver and the scene's `memory` budget. Each test writes its own small asset (a half
//! cylinder along the glTF x axis with a star of six joints, a morph target and a clip) beside
//! its scene in a scratch folder, loads the scene with `skinsim::scene::load`, and checks that
//! the error names the file and the field or the glTF accessor. (The binary's exit status for
//! scene errors is tested in tools/tests/hostile_input.rs.)

mod common;

use std::path::{Path, PathBuf};

use glam::DVec3;
use serde_json::Value;
use skinsim::scene::built::BuiltDriver;
use skinsim::scene::{load, BuiltScene, SceneError};

use common::gltf::{self, Asset, Clip, Joint};
use common::{mentions, scratch_dir};

/// The half cylinder: radius and length (m), quads around and along.
const RADIUS: f32 = 0.03;
const LENGTH: f32 = 0.12;
const AROUND: u32 = 8;
const ALONG: u32 = 12;

/// A Box over the middle of the top of the cylinder (mm; the engine frame, +Z up: the glTF +Y
/// top of the cylinder faces +Z).
const REGION: &str = "Box(min: (-20.0, -15.0, 0.0), max: (20.0, 15.0, 40.0))";

/// One folder per test (they run in parallel and write files of the same names).
fn dir(tag: &str) -> PathBuf {
    scratch_dir(&format!("character-inputs-{tag}"))
}

/// The asset: joint 0 "root" at the origin and "j1" to "j6" its children spread along x; every
/// vertex weighted to j1 and j2 (linear along x, summing to one), a morph target "bulge" lifting
/// the top, and a clip "bend" turning j1 about glTF z.
fn arm() -> Asset {
    let (positions, uv, indices) = gltf::cylinder(RADIUS, LENGTH, AROUND, ALONG, std::f32::consts::PI);
    let mut joints = vec![Joint { name: "root".into(), parent: None, translation: [0.0; 3] }];
    for k in 1..=6 {
        let x = -0.05 + 0.02 * (k - 1) as f32;
        joints.push(Joint { name: format!("j{k}"), parent: Some(0), translation: [x, 0.0, 0.0] });
    }
    let influences = positions
        .iter()
        .map(|p| {
            let a = 0.5 + p[0] / LENGTH; // 0 to 1 along the cylinder
            ([1, 2, 0, 0], [1.0 - a, a, 0.0, 0.0])
        })
        .collect();
    let bulge = positions.iter().map(|p| [0.0, 0.002 * p[1] / RADIUS, 0.0]).collect();
    let (s, c) = (0.2f32.sin(), 0.2f32.cos()); // 0.4 rad about z
    let clip = Clip {
        name: "bend".into(),
        joint: 1,
        times: vec![0.0, 0.1],
        rotations: vec![[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, s, c]],
    };
    Asset {
        positions,
        uv: Some(uv),
        indices,
        joints,
        influences,
        morphs: vec![("bulge".into(), bulge)],
        clips: vec![clip],
        ..Default::default()
    }
}

/// A scene with the glTF `asset` as its body (moved by `drivers`) and one patch on it whose
/// kinematic layer has the mesh `surface` (default: the REGION refined one level).
struct SceneText<'a> {
    asset: &'a str,
    drivers: &'a str,
    surface: String,
    memory: &'a str,
}

impl Default for SceneText<'_> {
    fn default() -> Self {
        SceneText { asset: "arm.gltf", drivers: "", surface: refined(REGION, "Levels(1)"), memory: "None" }
    }
}

fn refined(region: &str, refine: &str) -> String {
    format!("Offset(layer: \"body\", distance: 0.0, region: {region}, refine: {refine})")
}

impl SceneText<'_> {
    fn text(&self) -> String {
        format!(
            r#"Scene(
    name: "character_inputs",
    units: (length: Millimetre, stress: MegaPascal),
    frames: 4,
    memory: {memory},
    bodies: [
        Body(name: "body", mesh: Gltf(path: "{asset}"), drivers: [{drivers}]),
    ],
    patches: [
        Patch(
            name: "p",
            body: "body",
            layers: [
                Layer(name: "surface", kind: Kinematic, mesh: {surface}),
            ],
        ),
    ],
)"#,
            memory = self.memory,
            asset = self.asset,
            drivers = self.drivers,
            surface = self.surface
        )
    }

    /// Writes the scene into `d` (beside its asset) and loads it.
    fn load(&self, d: &Path, name: &str) -> Result<BuiltScene, SceneError> {
        let path = d.join(name);
        std::fs::write(&path, self.text()).unwrap();
        load(&path)
    }
}

/// The error, with its file and field checked: `file` ends the error's file name, `field` is
/// the field path's tail.
fn refused(r: Result<BuiltScene, SceneError>, file: &str, field: &str) -> SceneError {
    let e = r.map(|_| ()).expect_err("should be refused");
    assert!(e.file.to_string_lossy().ends_with(file), "{e}: the file is not {file}");
    let f = e.field.as_deref().unwrap_or_else(|| panic!("{e}: no field"));
    assert!(f.ends_with(field), "{e}: the field is not {field}");
    mentions(&e, &[file, field]);
    e
}

/// Rewrites the .gltf JSON written by `gltf::write`.
fn edit_json(path: &Path, edit: impl FnOnce(&mut Value)) {
    let mut doc: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    edit(&mut doc);
    std::fs::write(path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
}

const BODY_MESH: &str = "bodies[0] (\"body\").mesh";
const SURFACE: &str = "patches[0] (\"p\").layers[0] (\"surface\").mesh";

#[test]
fn the_reference_character_loads_with_its_notes() {
    let d = dir("reference");
    gltf::write(&d, "arm", &arm());
    let text = SceneText {
        drivers: r#"Rig(layer: "body", clip: Some("bend"), joints: [JointKeys(joint: "j2", axis: (0.0, 0.0, 1.0),
                     keyframes: [(0, 0.0), (4, 10.0)])], morphs: [MorphKeys(target: "bulge", keyframes: [(0, 0.0), (4, 1.0)])])"#,
        ..Default::default()
    };
    let built = text.load(&d, "reference.ron").unwrap_or_else(|e| panic!("{e}"));
    let notes = built.notes.join("\n");
    assert!(!notes.contains("warning"), "{notes}");
    assert!(notes.contains("arm.gltf: UV island 0"), "{notes}");
    assert!(notes.contains(&format!("{SURFACE}.refine: 1 subdivision levels: about")), "{notes}");
    assert!(built.patches[0].layers[1].embedding.is_some(), "the refined layer rides on the body");
}

/// (1) A refined region needs the body's UVs (its material space).
#[test]
fn a_refined_region_on_a_body_without_uvs_names_texcoord_0() {
    let d = dir("no-uv");
    gltf::write(&d, "bare", &Asset { uv: None, ..arm() });
    let text = SceneText { asset: "bare.gltf", ..Default::default() };
    let e = refused(text.load(&d, "no_uv.ron"), "bare.gltf", &format!("{SURFACE}.region"));
    mentions(&e, &["TEXCOORD_0", "no UVs", "\"body\""]);
    // Without a region that needs a material space the body itself is fine: it moves.
    let text = SceneText {
        asset: "bare.gltf",
        surface: "Offset(layer: \"body\", distance: 0.0)".into(),
        ..Default::default()
    };
    text.load(&d, "no_uv_whole.ron").unwrap_or_else(|e| panic!("{e}"));
}

/// (2) Weights that do not sum to one are normalised, with a warning naming the file.
#[test]
fn weights_not_summing_to_one_load_normalised_with_a_warning() {
    let d = dir("weights");
    let mut a = arm();
    a.influences.iter_mut().for_each(|i| *i = ([1, 2, 0, 0], [0.5, 0.4, 0.0, 0.0]));
    gltf::write(&d, "light", &a);
    let built = SceneText { asset: "light.gltf", ..Default::default() }
        .load(&d, "weights.ron")
        .unwrap_or_else(|e| panic!("{e}"));
    let warning = built
        .notes
        .iter()
        .find(|n| n.starts_with("warning") && n.contains("not summing to one"))
        .unwrap_or_else(|| panic!("no warning in {:#?}", built.notes));
    for word in ["light.gltf", BODY_MESH, "weights of mesh \"light\", primitive 0", "sum 0.9000000", "normalised"] {
        assert!(warning.contains(word), "{warning:?} does not mention {word:?}");
    }
    let asset = &built.bodies[0].layers[0].asset.as_ref().unwrap().asset;
    for v in 0..asset.rest.len() {
        let (j, w) = asset.influences.of(v);
        assert_eq!(j, [1, 2]);
        let sum = 0.5f32 as f64 + 0.4f32 as f64;
        let (w1, w2) = (0.5f32 as f64 / sum, 0.4f32 as f64 / sum);
        assert!((w[0] - w1).abs() < 1e-12 && (w[1] - w2).abs() < 1e-12, "vertex {v}: {w:?}");
    }
}

/// (3) Six influences (JOINTS_1 / WEIGHTS_1) are read and skin: a vertex of a Rig driver turning
/// the joint that only WEIGHTS_1 names moves by its weight of that joint's rotation.
#[test]
fn more_than_four_influences_are_used_by_the_rig() {
    let d = dir("eight");
    let mut a = arm();
    // Per vertex: j1-j4 in set 0, j5 and j6 in set 1, the weight of j5 varying along x.
    let set = |p: &[f32; 3]| {
        let s = 0.5 + p[0] / LENGTH;
        (([1u16, 2, 3, 4], [0.1 + 0.1 * s, 0.2, 0.1, 0.1]), ([5u16, 6, 0, 0], [0.3 - 0.1 * s, 0.2, 0.0, 0.0]))
    };
    a.influences = a.positions.iter().map(|p| set(p).0).collect();
    a.influences_1 = a.positions.iter().map(|p| set(p).1).collect();
    gltf::write(&d, "six", &a);
    let text = SceneText {
        asset: "six.gltf",
        drivers: r#"Rig(layer: "body", joints: [JointKeys(joint: "j5", axis: (0.0, 0.0, 1.0), keyframes: [(0, 0.0), (4, 40.0)])])"#,
        ..Default::default()
    };
    let built = text.load(&d, "six.ron").unwrap_or_else(|e| panic!("{e}"));
    assert!(!built.notes.iter().any(|n| n.starts_with("warning")), "{:#?}", built.notes);
    let BuiltDriver::Rig { rig, .. } = &built.bodies[0].drivers[0] else { panic!("not a Rig driver") };
    let asset = &built.bodies[0].layers[0].asset.as_ref().unwrap().asset;
    let posed = rig.positions(4.0);
    // The independent figure: joint j5 sits at c (rest rotations are the identity), its skinning
    // matrix turns about c by 40 degrees about glTF z; the other joints stay. A vertex moves by
    // its normalised weight of j5 times that turn's displacement, then (x, y, z)_gltf lands at
    // (x, -z, y) in the engine frame.
    let c = DVec3::new(a.joints[5].translation[0] as f64, 0.0, 0.0);
    let (sin, cos) = 40f64.to_radians().sin_cos();
    let (mut largest, mut worst) = (0.0f64, 0.0f64);
    for (v, p) in a.positions.iter().enumerate() {
        let ((j0, w0), (j1, w1)) = set(p);
        let weights: Vec<f64> = w0.iter().chain(&w1).map(|&w| w as f64).collect();
        let sum: f64 = weights.iter().sum();
        let w5 = weights[4] / sum;
        let welded = asset.weld[v] as usize;
        let (joints, w) = asset.influences.of(welded);
        assert_eq!(joints, [1, 2, 3, 4, 5, 6], "vertex {v}: {j0:?} + {j1:?}");
        assert!((w[4] - w5).abs() < 1e-15, "vertex {v}: weight of j5 {} against {w5}", w[4]);
        let p = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        let r = p - c;
        let turned = c + DVec3::new(cos * r.x - sin * r.y, sin * r.x + cos * r.y, r.z);
        let g = p + w5 * (turned - p);
        let expected = DVec3::new(g.x, -g.z, g.y);
        let off = (posed[welded] - expected).length();
        worst = worst.max(off);
        assert!(off < 1e-9, "vertex {v}: {} against {expected} (off by {off:e})", posed[welded]);
        largest = largest.max((expected - DVec3::new(p.x, -p.z, p.y)).length());
    }
    assert!(largest > 5e-3, "the turn moves the vertices (largest {largest} m)");
    eprintln!("six influences: largest move {largest:.4} m, off the independent figure by at most {worst:.1e} m");
}

/// (4) A name in a Rig driver that the asset lacks: the field and the asset's names.
#[test]
fn unknown_clip_joint_or_morph_names_the_field_and_lists_the_known_names() {
    let d = dir("names");
    gltf::write(&d, "arm", &arm());
    let field = "bodies[0] (\"body\").drivers[0]";
    for (driver, tail, words) in [
        (
            r#"Rig(layer: "body", clip: Some("wave"))"#,
            "clip",
            vec!["no animation clip named \"wave\"", "known clips: \"bend\""],
        ),
        (
            r#"Rig(layer: "body", joints: [JointKeys(joint: "elbow", axis: (0.0, 0.0, 1.0), keyframes: [(0, 0.0)])])"#,
            "joints[0].joint",
            vec!["no joint named \"elbow\"", "known joints: \"root\", \"j1\", \"j2\", \"j3\", \"j4\", \"j5\", \"j6\""],
        ),
        (
            r#"Rig(layer: "body", morphs: [MorphKeys(target: "smile", keyframes: [(0, 1.0)])])"#,
            "morphs[0].target",
            vec!["no morph target named \"smile\"", "known morph targets: \"bulge\""],
        ),
    ] {
        let text = SceneText { drivers: driver, ..Default::default() };
        // (a name the scene gives: the scene's field, the asset named in the message)
        let e = refused(text.load(&d, "names.ron"), "names.ron", &format!("{field}.{tail}"));
        mentions(&e, &words);
        mentions(&e, &["arm.gltf"]);
    }
}

/// (5) A missing external buffer file is named.
#[test]
fn a_missing_buffer_file_is_named() {
    let d = dir("bin");
    gltf::write(&d, "hollow", &arm());
    std::fs::remove_file(d.join("hollow.bin")).unwrap();
    let e =
        refused(SceneText { asset: "hollow.gltf", ..Default::default() }.load(&d, "bin.ron"), "hollow.gltf", BODY_MESH);
    mentions(&e, &["buffer 0", "hollow.bin", "does not exist"]);
}

/// (6) NaN or infinity in an accessor: the accessor by index and role.
#[test]
fn non_finite_values_name_the_accessor() {
    let d = dir("nan");
    let mut a = arm();
    a.positions[5][1] = f32::NAN;
    gltf::write(&d, "nan", &a);
    let e = refused(SceneText { asset: "nan.gltf", ..Default::default() }.load(&d, "nan.ron"), "nan.gltf", BODY_MESH);
    // (POSITION is the writer's first accessor)
    mentions(&e, &["accessor 0 (POSITION of mesh \"nan\", primitive 0)", "element 5", "non-finite", "NaN"]);

    let mut a = arm();
    a.morphs[0].1[7][0] = f32::INFINITY;
    gltf::write(&d, "inf", &a);
    let e = refused(SceneText { asset: "inf.gltf", ..Default::default() }.load(&d, "inf.ron"), "inf.gltf", BODY_MESH);
    mentions(&e, &["(POSITION of morph target 0 of mesh \"inf\", primitive 0)", "element 7", "non-finite", "inf"]);
}

/// (7) A region that selects no face, or an empty box.
#[test]
fn a_region_that_selects_nothing_names_the_region() {
    let d = dir("region");
    gltf::write(&d, "arm", &arm());
    let field = format!("{SURFACE}.region");
    for (region, words) in [
        ("Box(min: (500.0, 500.0, 500.0), max: (600.0, 600.0, 600.0))", vec!["selects no face of \"body\""]),
        // Only the line of vertices along the top (y = 0, z = 30 mm): no whole face.
        ("Box(min: (-100.0, -1.0, 29.0), max: (100.0, 1.0, 31.0))", vec!["selects no face of \"body\""]),
        ("Box(min: (20.0, -15.0, 0.0), max: (-20.0, 15.0, 40.0))", vec!["finite min < max"]),
    ] {
        for refine in ["Levels(1)", "None"] {
            let text = SceneText { surface: refined(region, refine), ..Default::default() };
            let r = text.load(&d, "region.ron");
            assert!(r.is_err(), "{region} (refine {refine}) loads");
            let e = refused(r, "region.ron", &field);
            mentions(&e, &words);
        }
    }
}

/// (8) An island of zero UV area (every UV the same) cannot be made length-true.
#[test]
fn a_uv_island_of_zero_area_is_named() {
    let d = dir("flat-uv");
    let mut a = arm();
    a.uv = Some(vec![[0.5, 0.5]; a.positions.len()]);
    gltf::write(&d, "dot", &a);
    let e = refused(SceneText { asset: "dot.gltf", ..Default::default() }.load(&d, "dot.ron"), "dot.gltf", BODY_MESH);
    mentions(&e, &["UV island 0", "zero UV area"]);
}

/// (9) A refinement past the scene's `memory` budget is refused before it is built, with the
/// estimate.
#[test]
fn a_refinement_past_the_memory_budget_names_refine_and_the_estimate() {
    let d = dir("memory");
    gltf::write(&d, "arm", &arm());
    // Every face (2 x 8 x 12 = 192), 7 levels: 192 x 4^7 = 3.1 M faces; the estimate counts
    // faces / 2 + half of every face's edges refined (3 x 192 x 2^7 / 2) + the faces: 1,609,920
    // vertices at 1 KB each (kinematic), 1.6 GB against 1 GB.
    let all = "Box(min: (-100.0, -100.0, -100.0), max: (100.0, 100.0, 100.0))";
    let text = SceneText { surface: refined(all, "Levels(7)"), memory: "Some(1.0)", ..Default::default() };
    let start = std::time::Instant::now();
    let e = refused(text.load(&d, "memory.ron"), "memory.ron", &format!("{SURFACE}.refine"));
    assert!(start.elapsed().as_secs_f64() < 2.0, "refused before refining ({:?})", start.elapsed());
    let faces = 2 * AROUND as usize * ALONG as usize;
    let vertices = faces * 4usize.pow(7) / 2 + 3 * faces * 2usize.pow(7) / 2 + faces;
    mentions(&e, &["7 levels", &format!("about {vertices} vertices"), "about 1.6 GB", "`memory` budget", "1.0 GB"]);
    // Within the budget the same region refined once loads.
    let text = SceneText { surface: refined(all, "Levels(1)"), memory: "Some(1.0)", ..Default::default() };
    text.load(&d, "memory_ok.ron").unwrap_or_else(|e| panic!("{e}"));
}

/// (10) Dual quaternions take rigid joints only; a glTF mesh is a body, not a shell.
#[test]
fn dual_quaternions_refuse_a_scaled_joint_and_a_shell_refuses_gltf() {
    let d = dir("refusals");
    let path = gltf::write(&d, "scaled", &arm());
    edit_json(&path, |doc| doc["nodes"][2]["scale"] = serde_json::json!([1.5, 1.5, 1.5]));
    let rig = |skinning: &str| {
        format!(
            r#"Rig(layer: "body", skinning: {skinning}, joints: [JointKeys(joint: "j1", axis: (0.0, 0.0, 1.0),
               keyframes: [(0, 0.0), (4, 30.0)])])"#
        )
    };
    let dq = rig("DualQuaternion");
    let text = SceneText { asset: "scaled.gltf", drivers: &dq, ..Default::default() };
    let e = refused(text.load(&d, "dq.ron"), "dq.ron", "bodies[0] (\"body\").drivers[0].skinning");
    mentions(&e, &["scaled.gltf", "dual quaternion", "rigid", "joint \"j2\"", "scale or shear", "at frame"]);
    let linear = rig("Linear");
    SceneText { asset: "scaled.gltf", drivers: &linear, ..Default::default() }
        .load(&d, "linear.ron")
        .unwrap_or_else(|e| panic!("linear skinning takes a scaled joint: {e}"));

    gltf::write(&d, "arm", &arm());
    let shell = r#"Scene(
    name: "shell",
    frames: 2,
    patches: [
        Patch(name: "p", layers: [
            Layer(name: "skin", kind: Shell, mesh: Gltf(path: "arm.gltf"),
                  material: (young: 4.0, poisson: 0.45, thickness: 0.1)),
        ]),
    ],
)"#;
    let path = d.join("shell.ron");
    std::fs::write(&path, shell).unwrap();
    let e = refused(load(&path), "shell.ron", "patches[0] (\"p\").layers[0] (\"skin\").mesh");
    mentions(&e, &["a glTF mesh is a body", "kinematic"]);
}
