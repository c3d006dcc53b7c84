//! Bad input: every error names the file and the line and column or the field, and none panics.
//! (Exit status 2 for these is tested on the binary in tools/tests/cli.rs.)

mod common;

use common::{mentions, scratch_dir};

use std::path::{Path, PathBuf};

use skinsim::scene::{load, load_str, SceneError};

const GOOD: &str = r#"Scene(
    name: "good",
    frames: 2,
    patches: [
        Patch(
            name: "p",
            layers: [
                Layer(name: "base", kind: Kinematic, mesh: Grid(size: (4.0, 2.0), cells: (4, 2))),
                Layer(name: "film", kind: Shell, mesh: Grid(size: (4.0, 2.0), cells: (4, 2)),
                      material: (young: 1.0, poisson: 0.3, thickness: 0.1), bending: (model: Tan)),
            ],
            drivers: [
                Compress(layers: ["base"], keyframes: [(0, 0.0), (2, 0.01)]),
                Attach(layer: "film", to: "base", stiffness: 0.01),
            ],
        ),
    ],
)"#;

fn dir() -> PathBuf {
    scratch_dir("errors")
}

fn err(text: &str) -> SceneError {
    load_str(text, Path::new("scene.ron")).expect_err("should be refused")
}

#[test]
fn the_reference_scene_is_valid() {
    load_str(GOOD, Path::new("scene.ron")).unwrap();
}

#[test]
fn malformed_ron_names_line_and_column() {
    let e = err(&GOOD.replace("frames: 2,", "frames: 2,,"));
    assert_eq!(e.position.map(|p| p.0), Some(3), "{e}");
    mentions(&e, &["scene.ron:3:"]);
}

#[test]
fn unknown_field_is_refused_with_its_position() {
    let e = err(&GOOD.replace("poisson: 0.3,", "poisson: 0.3, stiffnes: 2.0,"));
    assert!(e.position.is_some());
    mentions(&e, &["stiffnes"]);
}

#[test]
fn empty_scene() {
    let e = err(r#"Scene(name: "e", frames: 1, patches: [])"#);
    mentions(&e, &["patches", "empty"]);
}

#[test]
fn bad_material_values_name_the_field() {
    for (from, to, field) in [
        ("thickness: 0.1", "thickness: 0.0", "material.thickness"),
        ("thickness: 0.1", "thickness: -0.1", "material.thickness"),
        ("young: 1.0", "young: 0.0", "material.young"),
        ("young: 1.0", "young: -3.0", "material.young"),
        ("poisson: 0.3", "poisson: 0.5", "material.poisson"),
        ("poisson: 0.3", "poisson: -1.0", "material.poisson"),
    ] {
        let e = err(&GOOD.replace(from, to));
        mentions(&e, &[field, "\"film\""]);
        assert!(e.field.is_some());
    }
}

#[test]
fn keyframes_out_of_order() {
    let e = err(&GOOD.replace("[(0, 0.0), (2, 0.01)]", "[(2, 0.01), (1, 0.0)]"));
    mentions(&e, &["keyframes[1]", "out of order"]);
}

#[test]
fn unknown_layer_in_a_driver() {
    let e = err(&GOOD.replace("layers: [\"base\"]", "layers: [\"bsae\"]"));
    mentions(&e, &["drivers[0]", "bsae"]);
}

#[test]
fn missing_mesh_file_names_the_file() {
    let e = err(&GOOD.replace(
        "mesh: Grid(size: (4.0, 2.0), cells: (4, 2)),\n                      material",
        "mesh: Obj(path: \"nowhere.obj\"),\n                      material",
    ));
    mentions(&e, &["nowhere.obj", "not found"]);
}

fn obj_scene(name: &str, obj: &str) -> SceneError {
    let d = dir();
    std::fs::write(d.join(format!("{name}.obj")), obj).unwrap();
    let text = format!(
        r#"Scene(name: "{name}", frames: 1, patches: [Patch(name: "p", layers: [
            Layer(name: "skin", kind: Shell, mesh: Obj(path: "{name}.obj"), material: (young: 1.0, poisson: 0.3, thickness: 0.1)),
        ])])"#
    );
    let path = d.join(format!("{name}.ron"));
    std::fs::write(&path, text).unwrap();
    let e = load(&path).expect_err("bad mesh");
    assert!(e.file.ends_with(format!("{name}.obj")), "{e}");
    e
}

const QUAD: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

#[test]
fn bad_meshes_are_refused() {
    mentions(&obj_scene("degenerate", &format!("{QUAD}f 1 2 3\nf 1 3 3\n")), &["degenerate"]);
    mentions(&obj_scene("duplicate", &format!("{QUAD}f 1 2 3\nf 1 3 4\nf 3 1 2\n")), &["same three vertices"]);
    mentions(&obj_scene("nonmanifold", &format!("{QUAD}v 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 3 5\n")), &["non-manifold"]);
    mentions(&obj_scene("unreferenced", &format!("{QUAD}v 5 5 5\nf 1 2 3\nf 1 3 4\n")), &["vertex 4", "not used"]);
    // Issue 24: a curved shell without texture coordinates (a flat one falls back to x, y).
    let folded = "v 0 0 0\nv 1 0 0\nv 1 1 0.5\nv 0 1 0.5\nf 1 2 3\nf 1 3 4\n";
    mentions(
        &obj_scene("no_uvs", folded),
        &["layers[0] (\"skin\").mesh", "curved shell needs texture coordinates", "vt"],
    );
    // A valid OBJ loads.
    let d = dir();
    std::fs::write(d.join("ok.obj"), format!("{QUAD}vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"))
        .unwrap();
    std::fs::write(
        d.join("ok.ron"),
        r#"Scene(name: "ok", frames: 1, patches: [Patch(name: "p", layers: [
            Layer(name: "skin", kind: Shell, mesh: Obj(path: "ok.obj"), material: (young: 1.0, poisson: 0.3, thickness: 0.1)),
        ])])"#,
    )
    .unwrap();
    let s = load(&d.join("ok.ron")).unwrap();
    assert_eq!(s.patches[0].layers[0].mesh.rest().len(), 4);
}

#[test]
fn zero_elements_through_a_thickness() {
    let e = err(r#"Scene(name: "s", frames: 1, patches: [Patch(name: "p", layers: [
        Layer(name: "dermis", kind: Volume, mesh: TetSlab(size: (2.0, 2.0), cells: (2, 2), depth: 1.0, elements: 0),
              material: (young: 0.01, poisson: 0.45)),
    ])])"#);
    mentions(&e, &["mesh.elements", "zero elements"]);
}

#[test]
fn every_shipped_scene_is_valid() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut n = 0;
    let mut stack = vec![root];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(d).unwrap() {
            let p = entry.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "ron") {
                load(&p).unwrap_or_else(|e| panic!("{e}"));
                n += 1;
            }
        }
    }
    assert!(n >= 6);
}

#[test]
fn layers_must_stack_on_an_earlier_volume_slab() {
    let base = r#"Scene(name: "s", frames: 1, patches: [Patch(name: "p", layers: [
        Layer(name: "skin", kind: Shell, mesh: Grid(size: (2.0, 2.0), cells: (2, 2)), material: (young: 1.0, poisson: 0.3, thickness: 0.1)),
        Layer(name: "dermis", kind: Volume, mesh: TetSlab(size: (2.0, 2.0), cells: (2, 2), depth: 1.0, elements: 2), material: (young: 0.01, poisson: 0.45)),
        LAST,
    ])])"#;
    let e = err(&base.replace("LAST", r#"Layer(name: "sc", kind: Shell, mesh: SurfaceOf(layer: "skin"), material: (young: 1.0, poisson: 0.3, thickness: 0.01))"#));
    mentions(&e, &["layers[2]", "mesh.layer", "not a TetSlab or TetOn"]);
    let e = err(&base.replace("LAST", r#"Layer(name: "sc", kind: Shell, mesh: SurfaceOf(layer: "epidermis"), material: (young: 1.0, poisson: 0.3, thickness: 0.01))"#));
    mentions(&e, &["no earlier layer named \"epidermis\""]);
    let e = err(&base.replace("LAST", r#"Layer(name: "hypo", kind: Volume, mesh: TetOn(layer: "dermis", depth: 1.0, elements: 0), material: (young: 0.01, poisson: 0.45))"#));
    mentions(&e, &["mesh.elements", "zero elements"]);
    let ok = base.replace("LAST", r#"Layer(name: "sc", kind: Shell, mesh: SurfaceOf(layer: "dermis"), material: (young: 1.0, poisson: 0.3, thickness: 0.01))"#);
    load_str(&ok, Path::new("scene.ron")).unwrap();
}

const LAYERED: &str = r#"Scene(name: "s", frames: 2, units: (length: Millimetre, stress: KiloPascal), patches: [Patch(name: "p", layers: [
    Layer(name: "hypodermis", kind: Volume, mesh: TetSlab(size: (4.0, 2.0), cells: (4, 2), depth: 1.0, elements: 2, top: -1.0),
          material: (young: 13.0, poisson: 0.4)),
    DERMIS,
    Layer(name: "corneum", kind: Shell, mesh: SurfaceOf(layer: "dermis"),
          material: (young: 1000.0, poisson: 0.495, thickness: 0.02), bending: (model: Tan)SC_EXTRA),
], drivers: [DRIVERS])])"#;

fn layered(dermis: &str, sc_extra: &str, drivers: &str) -> String {
    LAYERED.replace("DERMIS", dermis).replace("SC_EXTRA", sc_extra).replace("DRIVERS", drivers)
}

const DERMIS_ON: &str = r#"Layer(name: "dermis", kind: Volume, mesh: TetOn(layer: "hypodermis", depth: 1.0, elements: 3), material: (young: 1.0, poisson: 0.4))"#;

#[test]
fn layers_whose_interfaces_do_not_match() {
    load_str(&layered(DERMIS_ON, "", ""), Path::new("scene.ron")).unwrap();
    // The dermis as its own slab on the hypodermis' top, with other cells: not connected.
    let loose = r#"Layer(name: "dermis", kind: Volume, mesh: TetSlab(size: (4.0, 2.0), cells: (8, 4), depth: 1.0, elements: 3), material: (young: 1.0, poisson: 0.4))"#;
    let e = err(&layered(loose, "", ""));
    mentions(&e, &["layers[1] (\"dermis\").mesh", "interface", "\"hypodermis\"", "TetOn"]);
    // Same cells but separate vertices: still two unconnected volumes.
    let e = err(&layered(&loose.replace("(8, 4)", "(4, 2)"), "", ""));
    mentions(&e, &["\"dermis\"", "does not match"]);
    // A shell over a layer that is not a volume slab.
    let e = err(&layered(DERMIS_ON, "", "").replace("SurfaceOf(layer: \"dermis\")", "SurfaceOf(layer: \"corneum\")"));
    mentions(&e, &["layers[2] (\"corneum\").mesh.layer", "not a TetSlab or TetOn volume"]);
}

#[test]
fn a_coarsening_slab_names_its_problems() {
    let coarse = |every: &str| {
        layered(DERMIS_ON, "", "").replace("top: -1.0)", &format!("top: -1.0, coarsen: (every: {every}, from: 0.0))"))
    };
    load_str(&coarse("0.6"), Path::new("scene.ron")).unwrap();
    let e = err(&coarse("0.0"));
    mentions(&e, &["layers[0] (\"hypodermis\").mesh.coarsen.every", "must be > 0"]);
    // Two halvings across one element: the dermis' (1 / 3 mm thick) from 2 x 1 to 8 x 4.
    let e = err(&coarse("0.2").replace("cells: (4, 2)", "cells: (16, 8)"));
    mentions(&e, &["layers[1] (\"dermis\").mesh.elements", "halve twice", "from z = -0.6667 to -0.3333"]);
    // The cell element needs hexahedra; the transition cells are not.
    let e =
        err(&coarse("0.6").replace("(young: 13.0, poisson: 0.4)", "(young: 13.0, poisson: 0.4, volume_element: Cell)"));
    mentions(&e, &["layers[0] (\"hypodermis\").material.volume_element", "transition cells", "volume_element: Tet"]);
}

#[test]
fn prestrain_with_a_non_positive_determinant() {
    let e = err(&layered(DERMIS_ON, ", prestrain: (stretch: (1.02, 0.0, 1.0))", ""));
    mentions(&e, &["layers[2] (\"corneum\").prestrain.stretch", "determinant 0"]);
    let e = err(&layered(
        &DERMIS_ON.replace("poisson: 0.4)", "poisson: 0.4), prestrain: (stretch: (1.0, 1.0, -1.0))"),
        "",
        "",
    ));
    mentions(&e, &["layers[1] (\"dermis\").prestrain.stretch", "determinant -1"]);
    // A rest curvature needs hinges.
    let e = err(&layered(DERMIS_ON, "", "").replace("bending: (model: Tan)", "prestrain: (curvature: 0.1)"));
    mentions(&e, &["corneum\").prestrain.curvature", "bending"]);
    // A missing map names the map file.
    let e = err(&layered(DERMIS_ON, ", prestrain: (stretch: (1.02, 1.02, 1.0), map: \"nowhere.png\")", ""));
    mentions(&e, &["nowhere.png", "prestrain.map"]);
}

#[test]
fn randomization_that_makes_a_modulus_negative() {
    let e = err(&layered(DERMIS_ON, ", randomize: (amplitude: 1.2, seed: 1)", ""));
    mentions(&e, &["layers[2] (\"corneum\").randomize.amplitude", "positive", "\"corneum\" reach -200"]);
    load_str(&layered(DERMIS_ON, ", randomize: (amplitude: 0.5, seed: 1)", ""), Path::new("scene.ron")).unwrap();
}

#[test]
fn a_capture_outside_the_run_or_on_a_kinematic_layer() {
    let e = err(&layered(DERMIS_ON, "", r#"Capture(layers: ["corneum"], frame: 9)"#));
    mentions(&e, &["drivers[0].frame", "1 to 2"]);
    let e = err(&layered(DERMIS_ON, "", r#"Capture(layers: ["corneum"], frame: 1, fraction: 1.5)"#));
    mentions(&e, &["drivers[0].fraction"]);
}

/// Issue 5 bad input: remesh thresholds, and remeshing a layer that has no material space.
#[test]
fn bad_remesh_settings_name_the_field() {
    const REMESH: &str = "remesh: Some((size_min: 0.1, size_max: 1.0, refine_compression: 0.01))";
    // (without the attachment springs, which cannot follow a remesh: issue 22)
    let good = GOOD
        .replace("bending: (model: Tan)", &format!("bending: (model: Tan), {REMESH}"))
        .replace(r#"Attach(layer: "film", to: "base", stiffness: 0.01),"#, "");
    load_str(&good, Path::new("scene.ron")).unwrap();
    for (from, to, field) in [
        ("size_min: 0.1", "size_min: 0.0", "remesh.size_min"),
        ("size_min: 0.1", "size_min: -0.1", "remesh.size_min"),
        ("size_min: 0.1", "size_min: 1.0", "remesh.size_min"),
        ("size_min: 0.1", "size_min: 0.1, aspect_min: 0.0", "remesh.aspect_min"),
        ("size_min: 0.1", "size_min: 0.1, aspect_min: 1.5", "remesh.aspect_min"),
        ("size_min: 0.1", "size_min: 0.1, refine_angle: 0.0", "remesh.refine_angle"),
        ("refine_compression: 0.01", "refine_compression: -0.01", "remesh.refine_compression"),
        ("refine_compression: 0.01", "refine_compression: 0.01, refine_velocity: Some(0.0)", "remesh.refine_velocity"),
        ("refine_compression: 0.01", "refine_compression: 0.01, every: 0", "remesh.every"),
        ("refine_compression: 0.01", "refine_compression: 0.01, min_change: -0.1", "remesh.min_change"),
    ] {
        let e = err(&good.replace(from, to));
        mentions(&e, &[field, "\"film\""]);
        assert!(e.field.is_some());
    }
    // Wavelength-aware refinement (issue 26): its numbers, and a coupling to read lambda from.
    let wavelength = good.replace("refine_compression: 0.01", "refine_compression: 0.01, wavelength: Some(())");
    let e = err(&wavelength);
    mentions(&e, &["remesh.wavelength", "needs a coupling", "\"film\" as its upper layer"]);
    let coupling = r#"Coupling(upper: "film", lower: "base", wavelength: Constant(2.5), seed: 1)"#;
    let coupled = wavelength.replace(
        "            ],\n        ),",
        &format!("            ],\n            couplings: [{coupling}],\n        ),"),
    );
    load_str(&coupled, Path::new("scene.ron")).unwrap();
    for (to, field) in [
        ("Some((per_wavelength: 0.5))", "remesh.wavelength.per_wavelength"),
        ("Some((onset: -1.0))", "remesh.wavelength.onset"),
        ("Some((margin: -2.0))", "remesh.wavelength.margin"),
    ] {
        mentions(&err(&coupled.replace("Some(())", to)), &[field, "\"film\""]);
    }
    // Only shells remesh: not a kinematic layer, not a volume.
    let e = err(&GOOD.replace("cells: (4, 2))),", &format!("cells: (4, 2)), {REMESH}),")));
    mentions(&e, &["\"base\"", "remesh", "shell layers", "Kinematic"]);
    let volume = r#"Scene(name: "s", frames: 1, patches: [Patch(name: "p", layers: [
        Layer(name: "dermis", kind: Volume, mesh: TetSlab(size: (2.0, 2.0), cells: (2, 2), depth: 1.0, elements: 2),
              material: (young: 0.01, poisson: 0.45), REMESH),
    ])])"#;
    let e = err(&volume.replace("REMESH", REMESH));
    mentions(&e, &["\"dermis\"", "remesh", "shell layers", "Volume"]);
    // A prestrain is carried across a remesh; a capture's per-element rest state is not.
    load_str(
        &good.replace("thickness: 0.1)", "thickness: 0.1), prestrain: (stretch: (1.02, 1.0, 1.0))"),
        Path::new("s.ron"),
    )
    .unwrap();
    let compress = r#"Compress(layers: ["base"], keyframes: [(0, 0.0), (2, 0.01)]),"#;
    let e = err(&good.replace(compress, &format!(r#"{compress} Capture(layers: ["film"], frame: 1),"#)));
    mentions(&e, &["drivers[1].layers", "\"film\" is remeshed", "captured"]);
}

/// A smooth perturbation's cell must be a positive length.
#[test]
fn a_perturbation_cell_must_be_positive() {
    let with = |cell: &str| {
        GOOD.replace(
            "name: \"p\",",
            &format!("name: \"p\", solver: (perturbation: Some((amplitude: 0.01, seed: 1, cell: {cell}))),"),
        )
    };
    load_str(&with("Some(0.5)"), Path::new("s.ron")).unwrap();
    for bad in ["Some(0.0)", "Some(-1.0)"] {
        mentions(&err(&with(bad)), &["solver.perturbation.cell", "> 0"]);
    }
}

/// Waves add to the smooth field: they need a cell, a positive wavelength, a non-negative
/// amplitude and a material axis.
#[test]
fn perturbation_waves_are_checked() {
    let with = |rest: &str| {
        GOOD.replace(
            "name: \"p\",",
            &format!("name: \"p\", solver: (perturbation: Some((amplitude: 0.01, seed: 1{rest}))),"),
        )
    };
    let wave = |w: &str| with(&format!(", cell: Some(0.5), waves: [(wavelength: 2.0, amplitude: 0.001), {w}]"));
    load_str(&wave("(wavelength: 1.0, amplitude: 0.0, axis: Y)"), Path::new("s.ron")).unwrap();
    for (w, field, says) in [
        ("(wavelength: 0.0, amplitude: 0.001)", "waves[1].wavelength", "> 0"),
        ("(wavelength: 1.0, amplitude: -0.001)", "waves[1].amplitude", ">= 0"),
        ("(wavelength: 1.0, amplitude: 0.001, axis: Z)", "waves[1].axis", "X or Y"),
    ] {
        mentions(&err(&wave(w)), &[&format!("solver.perturbation.{field}"), says]);
    }
    let no_cell = with(", waves: [(wavelength: 2.0, amplitude: 0.001)]");
    mentions(&err(&no_cell), &["solver.perturbation.waves[0]", "cell"]);
}

#[test]
fn quadratic_bending_needs_a_flat_rest() {
    let quadratic = GOOD.replace("bending: (model: Tan)", "bending: (model: Tan, element: Quadratic)");
    load_str(&quadratic, Path::new("scene.ron")).unwrap();
    let curved = quadratic.replace("bending:", "prestrain: (curvature: 0.1), bending:");
    mentions(&err(&curved), &["layers[1] (\"film\").prestrain.curvature", "flat rest", "element: Hinge"]);
    let capture = quadratic.replace("drivers: [", r#"drivers: [Capture(layers: ["film"], frame: 1),"#);
    mentions(&err(&capture), &["drivers[0].layers", "\"film\"", "quadratic", "capture"]);
    let periodic = quadratic.replace("drivers: [", r#"drivers: [Periodic(layers: ["film"], axis: X),"#);
    mentions(&err(&periodic), &["drivers[0].layers", "\"film\"", "periodic seam"]);
    // A rest mesh out of its plane (a folded quad, from an OBJ).
    let d = dir();
    let uvs = "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
    std::fs::write(d.join("folded.obj"), format!("v 0 0 0\nv 1 0 0\nv 1 1 0.5\nv 0 1 0\n{uvs}")).unwrap();
    let text = quadratic
        .replace(
            "Grid(size: (4.0, 2.0), cells: (4, 2)),\n                      material",
            "Obj(path: \"folded.obj\"),\n                      material",
        )
        .replace("Attach(layer: \"film\", to: \"base\", stiffness: 0.01),", "");
    std::fs::write(d.join("folded.ron"), &text).unwrap();
    mentions(
        &load(&d.join("folded.ron")).expect_err("curved rest"),
        &["layers[1] (\"film\").mesh", "flat rest", "leaves its plane"],
    );
}

#[test]
fn a_volume_element_belongs_to_a_volume_layer() {
    let e = err(&GOOD.replace("poisson: 0.3, thickness: 0.1)", "poisson: 0.3, thickness: 0.1, volume_element: Cell)"));
    mentions(&e, &["scene.ron", "layers[1] (\"film\").material.volume_element", "only volume layers"]);
    let e = err(&GOOD.replace("poisson: 0.3, thickness: 0.1)", "poisson: 0.3, thickness: 0.1, volume_element: Hex)"));
    assert!(e.position.is_some(), "{e}");
    mentions(&e, &["Hex"]);
}

#[test]
fn a_joint_needs_a_width_and_two_axes() {
    let with = |joint: &str| GOOD.replace("drivers: [", &format!("drivers: [{joint},"));
    load_str(
        &with(r#"Joint(layers: ["base"], pivot: (2.0, 1.0, 0.0), width: 1.0, keyframes: [(0, 0.0), (2, 30.0)])"#),
        Path::new("scene.ron"),
    )
    .unwrap();
    let e = err(&with(r#"Joint(layers: ["base"], pivot: (2.0, 1.0, 0.0), width: 0.0, keyframes: [(0, 0.0)])"#));
    mentions(&e, &["drivers[0].width", "> 0"]);
    let e = err(&with(
        r#"Joint(layers: ["base"], pivot: (2.0, 1.0, 0.0), axis: X, along: X, width: 1.0, keyframes: [(0, 0.0)])"#,
    ));
    mentions(&e, &["drivers[0].along", "hinge axis"]);
    let e = err(&with(r#"Joint(layers: ["bone"], pivot: (2.0, 1.0, 0.0), width: 1.0, keyframes: [(0, 0.0)])"#));
    mentions(&e, &["drivers[0].layers", "no layer named \"bone\""]);
}

/// A blend shape moves each vertex of a layer as built; on a remeshed layer (new vertices after
/// the first remesh) it is refused at `check`, naming the driver, instead of failing mid-run.
#[test]
fn a_blend_shape_on_a_remeshed_layer_is_refused() {
    let remeshed = GOOD
        .replace(
            "bending: (model: Tan)),",
            "bending: (model: Tan),\n                      remesh: Some((size_min: 0.25, size_max: 2.0, refine_angle: 0.3, \
             refine_compression: 0.2))),",
        )
        .replace(
            "Attach(layer: \"film\", to: \"base\", stiffness: 0.01),",
            "Pin(layer: \"film\", select: Sides([XMin])),\n                BlendShape(layer: \"film\", targets: [Target(shape: \
             Compress(axis: X, strain: 0.1), weights: [(0, 0.0), (2, 1.0)])]),",
        );
    let e = err(&remeshed);
    mentions(&e, &["patches[0] (\"p\").drivers[2].layer", "\"film\" is remeshed"]);
    // (on the kinematic layer below it, the same blend shape is taken)
    load_str(&remeshed.replace("BlendShape(layer: \"film\"", "BlendShape(layer: \"base\""), Path::new("s.ron"))
        .unwrap();
}
