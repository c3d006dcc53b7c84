//! LK14 bad input (issue 4): property maps, kernel wavelengths and blend shapes. Every error
//! names the file and the field; exit status 2 for scene errors is tested on the binary in
//! tools/tests/cli.rs.

mod common;

use common::{mentions, scratch_dir};

use std::path::{Path, PathBuf};

use skinsim::scene::{load, load_str, SceneError};

/// A one-shell LK14 patch over a kinematic base; `{props}`, `{wavelength}` and `{targets}` are
/// filled in by each test.
const TEMPLATE: &str = r#"Scene(
    name: "lk14",
    units: (length: Millimetre, stress: MegaPascal),
    frames: 4,
    patches: [
        Patch(
            name: "p",
            layers: [
                Layer(name: "base", kind: Kinematic, mesh: Grid(size: (20.0, 10.0), cells: (40, 23))),
                Layer(name: "skin", kind: Shell, mesh: Grid(size: (20.0, 10.0), cells: (40, 23)),
                      material: (preset: Lk14Dermis, thickness: 0.1), bending: (model: Tan),
                      properties: {props}),
            ],
            drivers: [
                BlendShape(layer: "base", targets: [{targets}]),
            ],
            couplings: [Coupling(upper: "skin", lower: "base", wavelength: {wavelength})],
        ),
    ],
)"#;

const TARGET: &str = "Target(shape: Compress(axis: X, strain: 0.1), weights: [(0, 0.0), (4, 1.0)])";

fn scene(props: &str, wavelength: &str, targets: &str) -> String {
    TEMPLATE.replace("{props}", props).replace("{wavelength}", wavelength).replace("{targets}", targets)
}

fn dir() -> PathBuf {
    scratch_dir("lk14-inputs")
}

/// Writes the scene into the temp folder (so relative asset paths resolve there) and loads it.
fn load_in_dir(name: &str, text: &str) -> Result<skinsim::scene::BuiltScene, SceneError> {
    let path = dir().join(name);
    std::fs::write(&path, text).unwrap();
    load(&path)
}

fn refused(text: &str) -> SceneError {
    load_str(text, Path::new("lk14.ron")).expect_err("should be refused")
}

#[test]
fn the_template_is_valid_with_procedural_maps_and_targets() {
    for map in [
        "None",
        "Some((map: Constant((0.5, 0.5, 0.5)), young: Some((0.5, 1.5))))",
        "Some((map: Ramp(axis: X, from: (0.0, 0.0, 0.0), to: (1.0, 1.0, 1.0)), thickness: Some((0.5, 1.0))))",
        "Some((map: Radial(inner: (1.0, 1.0, 1.0), outer: (0.0, 0.0, 0.0)), wavelength: Some((0.8, 1.2))))",
        "Some((map: Noise(seed: 3, cells: 4, low: (0.2, 0.2, 0.2), high: (0.8, 0.8, 0.8)), young: Some((1.0, 2.0))))",
    ] {
        let twist = "Target(shape: Twist(angle: 20.0), weights: [(0, 0.0), (4, 1.0)])";
        let pinch = "Target(shape: Pinch(radius: 4.0, squeeze: 0.2, lift: 1.0), weights: [(0, 0.0), (4, 0.5)])";
        let targets = format!("{TARGET}, {twist}, {pinch}");
        load_str(&scene(map, "Constant(4.0)", &targets), Path::new("lk14.ron"))
            .unwrap_or_else(|e| panic!("{map}: {e}"));
    }
}

/// A pinch between two fingers may squeeze past 1 (it folds the skin over itself), up to 4;
/// from all sides it may not, and the fingers lie in the plane.
#[test]
fn a_pinch_between_fingers_is_checked() {
    let with = |shape: &str| {
        let pinch = format!("Target(shape: {shape}, weights: [(0, 0.0), (4, 1.0)])");
        load_str(&scene("None", "Constant(4.0)", &format!("{TARGET}, {pinch}")), Path::new("lk14.ron"))
    };
    with("Pinch(radius: 4.0, squeeze: 1.6, lift: 1.0, between: Some(Y))").unwrap_or_else(|e| panic!("{e}"));
    for (shape, words) in [
        ("Pinch(radius: 4.0, squeeze: 1.6, lift: 1.0)", &["targets[1].shape.squeeze", "[0, 1)"][..]),
        ("Pinch(radius: 4.0, squeeze: 4.0, lift: 1.0, between: Some(X))", &["targets[1].shape.squeeze", "[0, 4)"]),
        ("Pinch(radius: 4.0, squeeze: 1.0, lift: 1.0, between: Some(Z))", &["targets[1].shape.between", "X or Y"]),
    ] {
        mentions(&with(shape).expect_err(shape), words);
    }
}

#[test]
fn a_missing_property_map_names_the_file() {
    let text = scene(r#"Some((map: Png("nowhere.png"), young: Some((1.0, 2.0))))"#, "Constant(4.0)", TARGET);
    let e = load_in_dir("missing_map.ron", &text).expect_err("missing map");
    mentions(&e, &["nowhere.png", "properties.map", "cannot read"]);
}

#[test]
fn a_greyscale_or_empty_map_is_refused() {
    let d = dir();
    image::GrayImage::from_pixel(4, 4, image::Luma([128])).save(d.join("grey.png")).unwrap();
    let text = scene(r#"Some((map: Png("grey.png"), young: Some((1.0, 2.0))))"#, "Constant(4.0)", TARGET);
    let e = load_in_dir("grey_map.ron", &text).expect_err("greyscale");
    mentions(&e, &["grey.png", "must be RGB"]);
    // A PNG of zero pixels cannot be encoded: an empty file stands for it.
    std::fs::write(d.join("empty.png"), b"").unwrap();
    let text = scene(r#"Some((map: Png("empty.png"), young: Some((1.0, 2.0))))"#, "Constant(4.0)", TARGET);
    let e = load_in_dir("empty_map.ron", &text).expect_err("empty");
    mentions(&e, &["empty.png", "properties.map"]);
}

#[test]
fn an_rgb_png_map_scales_the_modulus() {
    let d = dir();
    image::RgbImage::from_fn(8, 8, |x, _| image::Rgb([0, if x < 4 { 0 } else { 255 }, 0]))
        .save(d.join("rgb.png"))
        .unwrap();
    let text = scene(r#"Some((map: Png("rgb.png"), young: Some((1.0, 4.0))))"#, "Constant(4.0)", TARGET);
    let built = load_in_dir("rgb_map.ron", &text).unwrap();
    let props = built.patches[0].layers[1].properties.as_ref().unwrap();
    let f = |x: f64| props.at(glam::DVec2::new(x, 0.005)).young;
    assert_eq!((f(0.0), f(0.02)), (1.0, 4.0), "green 0 at the left edge, 1 at the right");
}

#[test]
fn a_map_that_makes_a_modulus_or_thickness_non_positive_is_refused() {
    let e =
        refused(&scene("Some((map: Constant((0.5, 1.0, 0.5)), young: Some((1.0, -1.0))))", "Constant(4.0)", TARGET));
    mentions(&e, &["properties.young", "green", "must be > 0"]);
    let e =
        refused(&scene("Some((map: Constant((0.5, 0.5, 0.0)), thickness: Some((0.0, 1.0))))", "Constant(4.0)", TARGET));
    mentions(&e, &["properties.thickness", "blue"]);
    let e = refused(&scene("Some((map: Constant((0.5, 0.5, 1.5))))", "Constant(4.0)", TARGET));
    mentions(&e, &["properties.map", "[0, 1]"]);
}

#[test]
fn kernel_wavelengths_outside_the_mesh_and_patch_are_refused() {
    let e = refused(&scene("None", "Constant(40.0)", TARGET));
    mentions(&e, &["couplings[0].wavelength", "larger than the patch"]);
    let e = refused(&scene("None", "Constant(0.5)", TARGET));
    mentions(&e, &["couplings[0].wavelength", "below the mesh spacing"]);
}

#[test]
fn blend_targets_with_another_vertex_count_name_the_file() {
    let d = dir();
    std::fs::write(d.join("tri.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let targets = r#"Target(shape: Obj("tri.obj"), weights: [(0, 0.0), (4, 1.0)])"#;
    let e = load_in_dir("obj_target.ron", &scene("None", "Constant(4.0)", targets)).expect_err("3 vertices");
    mentions(&e, &["tri.obj", "targets[0].shape", "3 vertices"]);
}

#[test]
fn weights_outside_the_declared_range_name_the_keyframe() {
    let targets = "Target(shape: Compress(axis: X, strain: 0.1), weights: [(0, 0.0), (4, 1.5)])";
    let e = refused(&scene("None", "Constant(4.0)", targets));
    mentions(&e, &["targets[0].weights[1]", "outside the declared range [0, 1]"]);
    let ranged = TEMPLATE
        .replace("{props}", "None")
        .replace("{wavelength}", "Constant(4.0)")
        .replace("targets: [{targets}])", &format!("targets: [{}], range: (0.0, 2.0))", targets));
    load_str(&ranged, Path::new("lk14.ron")).unwrap();
}
