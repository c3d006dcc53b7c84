//! Issue 22: the `skinsim` binary against hostile and careless input. Bad input exits 2 with
//! the file and field named, never panics, writes nothing outside the output folder; a rerun
//! keeps only its own frames; an interrupted run says so, keeps its frames and exits 130.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn skinsim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_skinsim"))
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("skinsim-hostile-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A small film on a base, compressed; `frames` frames; names and solver fields substitutable.
fn scene(scene_name: &str, patch: &str, layer: &str, solver: &str, frames: u32) -> String {
    format!(
        r#"Scene(name: "{scene_name}", frames: {frames}, patches: [Patch(name: "{patch}",
            solver: (projection: Adaptive, perturbation: (amplitude: 0.001, seed: 1){solver}),
            layers: [
                Layer(name: "base", kind: Kinematic, mesh: Grid(size: (8.0, 2.0), cells: (16, 4))),
                Layer(name: "{layer}", kind: Shell, mesh: Grid(size: (8.0, 2.0), cells: (16, 4)),
                      material: (young: 10.0, poisson: 0.3, thickness: 0.1), bending: (model: Tan)),
            ],
            drivers: [
                Compress(layers: ["base", "{layer}"], keyframes: [(0, 0.0), (8, 0.05)]),
                Attach(layer: "{layer}", to: "base", stiffness: 0.0056),
            ],
        )])"#
    )
}

fn good(frames: u32) -> String {
    scene("hostile", "sheet", "film", "", frames)
}

/// Exit status 2, no panic, and every word in stderr.
fn refused(out: &Output, words: &[&str]) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(!err.contains("panicked") && !err.contains("internal error"), "{err}");
    for w in words {
        assert!(err.contains(w), "\"{w}\" not in: {err}");
    }
}

fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut v = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            v.extend(files_under(&p));
        } else {
            v.push(p);
        }
    }
    v.sort();
    v
}

#[test]
fn names_that_would_escape_the_output_folder_are_refused_and_nothing_is_written() {
    let d = scratch("names");
    let bad = [
        ("scene", scene("../../escape", "sheet", "film", "", 2), "name"),
        ("patch", scene("x", "/tmp/abs", "film", "", 2), "patches[0].name"),
        ("layer", scene("x", "sheet", "a/../../b", "", 2), ".name"),
        ("hidden", scene("x", "sheet", "..", "", 2), ".name"),
    ];
    for (tag, text, field) in bad {
        let path = write(&d, &format!("{tag}.ron"), &text);
        let words = [format!("{tag}.ron"), field.to_string(), "not a usable name".to_string()];
        let words: Vec<&str> = words.iter().map(String::as_str).collect();
        refused(&skinsim().arg("check").arg(&path).output().unwrap(), &words);
        refused(&skinsim().arg("run").arg("--out").arg(d.join("out")).arg(&path).output().unwrap(), &words);
    }
    // Only the scene files themselves: no output folder, nothing beside or above it.
    let written: Vec<String> =
        files_under(&d).iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert_eq!(written, ["hidden.ron", "layer.ron", "patch.ron", "scene.ron"]);
    assert!(!d.parent().unwrap().join("escape").exists());
}

#[test]
fn unreadable_scene_files_are_refused_with_the_reason() {
    let d = scratch("files");
    // A byte-order mark is accepted.
    let bom = write(&d, "bom.ron", &format!("\u{feff}{}", good(2)));
    let out = skinsim().arg("check").arg(&bom).output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    // Invalid UTF-8: the line and column of the first bad byte.
    let mut bytes = good(2).into_bytes();
    let second_line = bytes.iter().position(|&b| b == b'\n').unwrap() + 3;
    bytes[second_line] = 0xff;
    let utf8 = d.join("utf8.ron");
    std::fs::write(&utf8, bytes).unwrap();
    refused(&skinsim().arg("check").arg(&utf8).output().unwrap(), &["utf8.ron", "not UTF-8", "line 2, column 3"]);
    // A directory, and a device that never ends.
    refused(&skinsim().arg("check").arg(&d).output().unwrap(), &["is a directory"]);
    if Path::new("/dev/zero").exists() {
        refused(&skinsim().arg("check").arg("/dev/zero").output().unwrap(), &["longer than 16 MiB"]);
    }
}

#[test]
fn numbers_out_of_range_are_refused_at_check() {
    let d = scratch("numbers");
    let cases = [
        ("tolerance", good(2).replace("seed: 1)", "seed: 1), tolerance: inf"), "`inf` (`tolerance`)"),
        ("tolerance_one", good(2).replace("seed: 1)", "seed: 1), tolerance: 1.0"), "solver.tolerance"),
        ("frame_time", good(2).replace("frames: 2,", "frames: 2, frame_time: 1e308,"), "frame_time"),
    ];
    for (tag, text, field) in cases {
        let path = write(&d, &format!("{tag}.ron"), &text);
        refused(&skinsim().arg("check").arg(&path).output().unwrap(), &[field]);
    }
}

#[test]
fn non_finite_obj_coordinates_are_refused_with_their_line() {
    let d = scratch("obj");
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt NaN 0\nvt 0 1\nf 1/1 2/2 3/3\n";
    write(&d, "nan_vt.obj", obj);
    write(&d, "inf_v.obj", &obj.replace("v 1 0 0", "v 1 inf 0"));
    let empty = d.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    write(&empty, "empty.obj", "# nothing\n");
    // Malformed faces, which tobj reports without a line.
    let obj = obj.replace("vt NaN 0", "vt 1 0");
    write(&d, "short.obj", &obj.replace("f 1/1 2/2 3/3", "f 1/1 2/2"));
    write(&d, "corner.obj", &obj.replace("f 1/1 2/2 3/3", "f 1/1 2/x 3/3"));
    write(&d, "range.obj", &obj.replace("f 1/1 2/2 3/3", "f 1/1 2/2 3/3\nf 1 2 9"));
    let cases = [
        ("nan_vt.obj", vec!["nan_vt.obj", "line 5", "vt"]),
        ("inf_v.obj", vec!["inf_v.obj", "line 2"]),
        ("short.obj", vec!["short.obj", "line 7", "at least 3 corners"]),
        ("corner.obj", vec!["corner.obj", "line 7", "`2/x`"]),
        ("range.obj", vec!["range.obj", "line 8", "corner 9 refers to no vertex (the file has 3)"]),
    ];
    for (file, words) in cases {
        let text = good(2).replace(
            "Layer(name: \"base\", kind: Kinematic, mesh: Grid(size: (8.0, 2.0), cells: (16, 4))),",
            &format!("Layer(name: \"base\", kind: Kinematic, mesh: Obj(path: \"{file}\")),"),
        );
        let path = write(&d, &format!("{file}.ron"), &text);
        refused(&skinsim().arg("check").arg(&path).output().unwrap(), &words);
    }
    // `analyze` on a folder whose frame has no face.
    refused(&skinsim().arg("analyze").arg(&empty).output().unwrap(), &["no faces"]);
}

/// Found 1: a remeshed shell with an Attach driver panicked in frame 2. Now the springs follow
/// the remesh: `check` and `run` succeed, in either direction, with a Pin or periodic sides.
#[test]
fn attachment_springs_follow_a_remeshed_layer() {
    let d = scratch("attach");
    let remesh = "bending: (model: Tan), remesh: Some((size_min: 0.1, size_max: 1.0, refine_angle: 0.3, refine_compression: 0.2)))";
    let text = good(3).replace("bending: (model: Tan))", remesh);
    assert!(text.contains("remesh"));
    let attach = r#"Attach(layer: "film", to: "base", stiffness: 0.0056),"#;
    let variants = [
        ("plain", text.clone()),
        ("reversed", text.replace(attach, r#"Attach(layer: "base", to: "film", stiffness: 0.0056),"#)),
        ("pinned", text.replace(attach, &format!(r#"{attach} Pin(layer: "film", select: Sides([XMin])),"#))),
        ("periodic", text.replace(attach, &format!(r#"{attach} Periodic(layers: ["base", "film"], axis: Y),"#))),
    ];
    for (name, text) in variants {
        let path = write(&d, &format!("{name}.ron"), &text);
        let check = skinsim().arg("check").arg(&path).output().unwrap();
        assert_eq!(check.status.code(), Some(0), "{name}: {}", String::from_utf8_lossy(&check.stderr));
        let mut run = skinsim();
        run.args(["run", "--quiet", "--no-rerun", "--export", "obj", "--out"]).arg(d.join(name)).arg(&path);
        let out = run.output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{name}: {err}");
        assert!(d.join(name).join("obj/sheet/film/00003.obj").is_file(), "{name}: every frame written");
    }
}

#[test]
fn command_line_values_out_of_range_exit_2() {
    let d = scratch("args");
    let path = write(&d, "good.ron", &good(2));
    let out_dir = d.join("out");
    let run = |extra: &[&str]| {
        skinsim().args(["run", "--quiet", "--no-rerun", "--out"]).arg(&out_dir).args(extra).arg(&path).output().unwrap()
    };
    refused(&run(&["--frames", "0"]), &["--frames"]);
    refused(&run(&["--threads", "100000000"]), &["--threads"]);
    refused(&skinsim().arg("timing").output().unwrap(), &["at least one scene"]);
    refused(&skinsim().args(["timing", "--rounds", "0"]).arg(&path).output().unwrap(), &["--rounds"]);
    let bake = |extra: &[&str]| {
        skinsim().arg("bake").arg(&path).args(["--out"]).arg(d.join("maps")).args(extra).output().unwrap()
    };
    refused(&bake(&["--frames", "1", "--layer", "nosuch"]), &["nosuch", "film"]);
    refused(&bake(&["--frames", "1", "--blend", "5"]), &["--blend"]);
    refused(&bake(&["--weights", "NaN"]), &["--weights"]);
    refused(&bake(&["--frames", "1", "--layout", "asset"]), &["--layout asset", "no patch on a body"]);
    refused(&bake(&["--frames", "1", "--bits", "12"]), &["--bits"]);
    refused(&bake(&["--frames", "1", "--edge-blend", "-1"]), &["--edge-blend"]);
    refused(&bake(&["--frames", "1", "--height-range", "0"]), &["--height-range"]);
    refused(&bake(&["--frames", "1", "--smooth", "9"]), &["--smooth"]);
    refused(&run(&["--colour-scale", "-1"]), &["--colour-scale"]);
    let asset =
        |extra: &[&str]| skinsim().args(["asset", "hand", "--out"]).arg(d.join("assets")).args(extra).output().unwrap();
    refused(&asset(&["--finger-cells", "100000,100000"]), &["more than 10000000 vertices"]);
    refused(&asset(&["--arm-cells", "5"]), &["two numbers"]);
    refused(&asset(&["--name", "../escape"]), &["plain file name"]);
    assert!(!d.join("assets").exists(), "nothing written");
}

#[test]
fn a_rerun_into_the_same_folder_keeps_only_its_own_frames() {
    let d = scratch("rerun");
    let path = write(&d, "good.ron", &good(3));
    let out_dir = d.join("out");
    // Something of the user's in the output folder stays.
    std::fs::create_dir_all(out_dir.join("obj/sheet/film")).unwrap();
    write(&out_dir, "notes.txt", "mine");
    write(&out_dir.join("obj/sheet/film"), "mine.obj", "# mine");
    let run = |frames: &str, rerun: &[&str]| {
        let out = skinsim()
            .args(["run", "--quiet", "--export", "obj", "--frames", frames])
            .args(rerun)
            .arg("--out")
            .arg(&out_dir)
            .arg(&path)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    };
    run("3", &[]);
    assert!(out_dir.join("recording.rrd").exists());
    run("1", &["--no-rerun"]);
    // (the earlier recording is not this run's: it would show three frames beside one)
    assert!(!out_dir.join("recording.rrd").exists());
    let film: Vec<String> = files_under(&out_dir.join("obj/sheet/film"))
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(film, ["00000.obj", "00001.obj", "mine.obj"], "the rest state and this run's frame");
    assert!(out_dir.join("notes.txt").exists());
    let stats = std::fs::read_to_string(out_dir.join("stats.jsonl")).unwrap();
    assert_eq!(stats.lines().count(), 1);
}

/// `skinsim run --quiet [extra] --out out_dir scene`, started with its stderr piped.
fn spawn_run(extra: &[&str], out_dir: &Path, scene: &Path) -> std::process::Child {
    let mut run = skinsim();
    run.args(["run", "--quiet"]).args(extra).arg("--out").arg(out_dir).arg(scene);
    run.stderr(std::process::Stdio::piped()).spawn().unwrap()
}

#[cfg(unix)]
#[test]
fn an_interrupted_run_says_so_keeps_its_frames_and_exits_130() {
    let d = scratch("interrupt");
    let path = write(&d, "long.ron", &good(5000));
    let out_dir = d.join("out");
    let child = spawn_run(&["--export", "obj"], &out_dir, &path);
    let stats = out_dir.join("stats.jsonl");
    wait_for_frames(&stats, 2);
    let kill = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(kill.success());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted after frame") && err.contains(&out_dir.display().to_string()), "{err}");
    let lines = std::fs::read_to_string(&stats).unwrap().lines().count();
    assert!((2..5000).contains(&lines), "{lines} frames");
    // Every frame in stats.jsonl has its OBJ and its meshes in the recording, which was closed,
    // after the rest state (frame 0).
    assert_eq!(files_under(&out_dir.join("obj/sheet/film")).len(), lines + 1);
    let recorded = recorded_frames(&out_dir.join("recording.rrd"));
    assert_eq!(recorded, (0..=lines as i64).collect::<Vec<_>>());
}

/// Waits (at most 2 minutes) until a running scene's stats.jsonl has `frames` lines.
fn wait_for_frames(stats: &Path, frames: usize) {
    let started = std::time::Instant::now();
    while std::fs::read_to_string(stats).map_or(0, |s| s.lines().count()) < frames {
        assert!(started.elapsed().as_secs() < 120, "fewer than {frames} frames written");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// The frames of the film's mesh in a recording, read back with Rerun's decoder.
fn recorded_frames(path: &Path) -> Vec<i64> {
    let index = skinsim_systems::log_read::read_recording(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    index.frames.get("/patches/sheet/film").map_or(Vec::new(), |f| f.iter().copied().collect())
}

/// A killed run (SIGKILL: no handler runs) still has in its recording every frame stats.jsonl
/// has: the recording is flushed after every frame.
#[cfg(unix)]
#[test]
fn a_killed_run_keeps_every_written_frame_in_its_recording() {
    let d = scratch("kill");
    let path = write(&d, "long.ron", &good(5000));
    let out_dir = d.join("out");
    let mut child = skinsim().args(["run", "--quiet", "--out"]).arg(&out_dir).arg(&path).spawn().unwrap();
    let stats = out_dir.join("stats.jsonl");
    wait_for_frames(&stats, 3);
    child.kill().unwrap();
    child.wait().unwrap();
    let lines = std::fs::read_to_string(&stats).unwrap().lines().count();
    let recorded = recorded_frames(&out_dir.join("recording.rrd"));
    assert!(recorded.len() >= lines, "{lines} frames in stats.jsonl, recorded {recorded:?}");
}

/// Geometry `run` used to panic on: `check` now validates the final geometry (after the offset
/// and the perturbation) and every range, and names the field.
#[test]
fn check_refuses_the_geometry_run_would_fail_on() {
    let d = scratch("geometry");
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let cases = [
        ("examples/volume_slab.ron", "depth: 1.2", "depth: 1e-300", "mesh: tet 0 is degenerate"),
        ("examples/volume_slab.ron", "depth: 1.2", "depth: 1e300", "outside +-1000 m"),
        ("examples/volume_slab.ron", "size: (10.0, 4.0)", "size: (1e300, 4.0)", "outside +-1000 m"),
        (
            "multi_patch.ron",
            "offset: (0.0, 10.0, 0.0)",
            "offset: (0.0, 1e300, 0.0)",
            "patches[1] (\"stiff_foundation\").offset",
        ),
        ("multi_patch.ron", "offset: (0.0, 10.0, 0.0)", "offset: (0.0, inf, 0.0)", "must be finite"),
        ("strip_wrinkles.ron", "amplitude: 0.001", "amplitude: 1e300", "perturbation applied"),
        ("strip_wrinkles.ron", "amplitude: 0.001,", "amplitude: 0.001, cell: Some(1e-300),", "perturbation.cell"),
        ("kck18/elbow_bending_quick.ron", "angle: 150.0", "angle: 1e308", "pose.angle"),
    ];
    for (i, (scene, from, to, words)) in cases.into_iter().enumerate() {
        let text = std::fs::read_to_string(scenes.join(scene)).unwrap();
        assert!(text.contains(from), "{scene}: {from}");
        let path = write(&d, &format!("case{i}.ron"), &text.replacen(from, to, 1));
        refused(&skinsim().arg("check").arg(&path).output().unwrap(), &[&format!("case{i}.ron"), words]);
        let mut run = skinsim();
        run.args(["run", "--quiet", "--no-rerun", "--frames", "1", "--out"]).arg(d.join("out")).arg(&path);
        refused(&run.output().unwrap(), &[words]);
    }
}

/// Resources bounded at `check`: generated meshes, precomputed poses; and a projection ring
/// count far past the body costs no more than one that covers it.
#[test]
fn sizes_past_memory_are_refused_and_ring_counts_past_the_mesh_are_harmless() {
    let d = scratch("resources");
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let read = |s: &str| std::fs::read_to_string(scenes.join(s)).unwrap();
    let grid = good(2).replace("cells: (16, 4))),", "cells: (1000000, 1000000))),");
    let path = write(&d, "grid.ron", &grid);
    refused(&skinsim().arg("check").arg(&path).output().unwrap(), &["layers[0]", "cells", "vertices"]);
    // Within the vertex cap, but 9 M tetrahedral vertices need ~290 GB to solve: refused from
    // the scene's memory estimate, before the mesh is generated.
    let slab = read("examples/volume_slab.ron").replacen("cells: (20, 8)", "cells: (1000, 1000)", 1);
    let slab = slab.replacen("elements: 4", "elements: 8", 1);
    let path = write(&d, "slab.ron", &slab);
    refused(
        &skinsim().arg("check").arg(&path).output().unwrap(),
        &["layers[0]", "mesh.cells", "9018009 vertices", "GB to run", "machine's"],
    );
    let poses = read("kck18/elbow_bending_quick.ron").replacen("frames: 12,", "frames: 1000000000,", 1);
    let path = write(&d, "poses.ron", &poses);
    refused(&skinsim().arg("check").arg(&path).output().unwrap(), &["drivers[0]", "precomputed poses", "GB"]);
    let rings = read("kck18/crease_quick.ron").replacen("method: Walk", "method: ProjectRing(4000000000)", 1);
    let path = write(&d, "rings.ron", &rings);
    let mut run = skinsim();
    run.args(["run", "--quiet", "--no-rerun", "--frames", "1", "--out"]).arg(d.join("out")).arg(&path);
    let out = run.output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    // A directory where a mesh file belongs.
    let text = good(2).replace(
        "Layer(name: \"base\", kind: Kinematic, mesh: Grid(size: (8.0, 2.0), cells: (16, 4))),",
        "Layer(name: \"base\", kind: Kinematic, mesh: Obj(path: \".\")),",
    );
    let path = write(&d, "dir_mesh.ron", &text);
    refused(&skinsim().arg("check").arg(&path).output().unwrap(), &["layers[0]", "is a directory"]);
}

/// Messages a user can act on: RON's bare "Expected comma" explained, numbers kept short, and
/// `--connect` to a port where no viewer listens refused before the run.
#[test]
fn messages_say_what_is_wrong() {
    let d = scratch("messages");
    let decimal = write(&d, "decimal.ron", &good(2).replace("frames: 2,", "frames: 2.0,"));
    refused(&skinsim().arg("check").arg(&decimal).output().unwrap(), &["decimal.ron:1:", "whole number"]);
    let open = write(&d, "open.ron", &good(2).replace("name: \"sheet\",", "name: \"sheet,"));
    refused(&skinsim().arg("check").arg(&open).output().unwrap(), &["the string opened at line 1", "closing quote"]);
    let huge = write(&d, "huge.ron", &good(2).replace("young: 10.0", "young: -1e300"));
    let out = skinsim().arg("check").arg(&huge).output().unwrap();
    refused(&out, &["material.young", "-1e300"]);
    assert!(String::from_utf8_lossy(&out.stderr).len() < 300);
    let path = write(&d, "good.ron", &good(2));
    let mut run = skinsim();
    run.args(["run", "--quiet", "--connect", "rerun+http://127.0.0.1:9/proxy", "--out"]).arg(d.join("out")).arg(&path);
    refused(&run.output().unwrap(), &["no viewer is listening", "127.0.0.1:9"]);
}

/// A full disk (stats.jsonl linked to /dev/full): the run stops, says which file it cannot
/// write and why (the OS error), and exits 1.
#[cfg(target_os = "linux")]
#[test]
fn a_full_disk_is_named_with_the_file_and_the_os_error() {
    let d = scratch("full");
    let path = write(&d, "good.ron", &good(3));
    let out_dir = d.join("out");
    std::fs::create_dir_all(&out_dir).unwrap();
    std::os::unix::fs::symlink("/dev/full", out_dir.join("stats.jsonl")).unwrap();
    let out = skinsim().args(["run", "--quiet", "--no-rerun", "--out"]).arg(&out_dir).arg(&path).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("cannot write") && err.contains("stats.jsonl") && err.contains("No space left"), "{err}");
}

/// Waits at most `secs` for `child`; kills it and fails if it is still running (a hang).
fn finished_within(mut child: std::process::Child, secs: u64) -> Output {
    let started = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if started.elapsed().as_secs() >= secs {
            child.kill().unwrap();
            panic!(
                "still running after {secs} s: {:?}",
                child.wait_with_output().map(|o| String::from_utf8_lossy(&o.stderr).into_owned())
            );
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child.wait_with_output().unwrap()
}

/// Issue 66: a full disk under the recording (recording.rrd linked to /dev/full) ends the run
/// with exit 1 naming the file and the OS error; it used to hang after frame 1.
#[cfg(target_os = "linux")]
#[test]
fn a_full_disk_under_the_recording_ends_the_run_naming_it() {
    let d = scratch("full_rrd");
    let path = write(&d, "good.ron", &good(4));
    let out_dir = d.join("out");
    std::fs::create_dir_all(&out_dir).unwrap();
    std::os::unix::fs::symlink("/dev/full", out_dir.join("recording.rrd")).unwrap();
    let child = spawn_run(&[], &out_dir, &path);
    let out = finished_within(child, 60);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("recording.rrd") && err.contains("No space left"), "{err}");
    // The other outputs hold the frames before it.
    assert!(std::fs::read_to_string(out_dir.join("stats.jsonl")).unwrap().lines().count() <= 1);
}

/// How a fake listener treats the connection it accepts.
type Serve = fn(std::net::TcpStream);

/// Issue 66: `--connect` to a listener that is not a Rerun viewer exits 2 before the run,
/// whether it never answers, closes the connection or speaks another protocol.
#[test]
fn connect_refuses_a_listener_that_is_not_a_viewer() {
    let d = scratch("listener");
    let path = write(&d, "good.ron", &good(2));
    let cases: [(Serve, &str); 3] = [
        (|_s| std::thread::sleep(std::time::Duration::from_secs(5)), "did not answer"),
        (drop, "is not a Rerun viewer"),
        (
            |mut s| {
                use std::io::Write;
                let _ = s.write_all(b"HTTP/1.1 400 Bad Request\r\n\r\n");
                std::thread::sleep(std::time::Duration::from_secs(1));
            },
            "HTTP/1.1",
        ),
    ];
    for (serve, words) in cases {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let url = format!("rerun+http://{}/proxy", listener.local_addr().unwrap());
        std::thread::spawn(move || {
            if let Ok((s, _)) = listener.accept() {
                serve(s);
            }
        });
        let child = spawn_run(&["--connect", &url], &d.join("out"), &path);
        refused(&finished_within(child, 30), &[words, &url]);
    }
}

/// Issue 66: `analyze` reads regular files only: a FIFO named like a frame blocked it for ever,
/// a link to /dev/zero read until memory ran out.
#[cfg(target_os = "linux")]
#[test]
fn analyze_reads_regular_files_only() {
    let d = scratch("analyze");
    let fifo = d.join("fifo");
    std::fs::create_dir_all(&fifo).unwrap();
    assert!(Command::new("mkfifo").arg(fifo.join("00001.obj")).status().unwrap().success());
    let child = skinsim().arg("analyze").arg(&fifo).stderr(std::process::Stdio::piped()).spawn().unwrap();
    refused(&finished_within(child, 30), &["00001.obj", "not a regular file"]);
    let zero = d.join("zero");
    std::fs::create_dir_all(&zero).unwrap();
    std::os::unix::fs::symlink("/dev/zero", zero.join("00001.obj")).unwrap();
    let child = skinsim().arg("analyze").arg(&zero).stderr(std::process::Stdio::piped()).spawn().unwrap();
    refused(&finished_within(child, 30), &["00001.obj", "not a regular file"]);
}

/// Issue 66: one writer per output folder. A second run into a folder a run is writing exits 2
/// naming the holder; once the first ends (killed here: the lock dies with it), runs go on.
#[cfg(unix)]
#[test]
fn a_second_run_into_a_busy_folder_is_refused_naming_the_first() {
    let d = scratch("busy");
    let path = write(&d, "long.ron", &good(5000));
    let out_dir = d.join("out");
    let mut first = skinsim().args(["run", "--quiet", "--out"]).arg(&out_dir).arg(&path).spawn().unwrap();
    wait_for_frames(&out_dir.join("stats.jsonl"), 1);
    let second =
        skinsim().args(["run", "--quiet", "--frames", "1", "--out"]).arg(&out_dir).arg(&path).output().unwrap();
    refused(&second, &["in use by skinsim run", "long.ron", &format!("process {}", first.id())]);
    let bake = skinsim().args(["bake", "--frames", "1", "--out"]).arg(&out_dir).arg(&path).output().unwrap();
    refused(&bake, &["in use by skinsim run"]);
    first.kill().unwrap();
    first.wait().unwrap();
    let third = skinsim().args(["run", "--quiet", "--frames", "1", "--out"]).arg(&out_dir).arg(&path).output().unwrap();
    assert_eq!(third.status.code(), Some(0), "{}", String::from_utf8_lossy(&third.stderr));
    assert_eq!(std::fs::read_to_string(out_dir.join("stats.jsonl")).unwrap().lines().count(), 1);
}

/// Issue 66: numbers that are not finite, or would not stay finite in SI, are refused at
/// `check` with their line and column, wherever they are; `--blend` with one frame is refused
/// before the scene runs.
#[test]
fn numbers_that_overflow_in_si_are_refused_with_their_place() {
    let d = scratch("overflow");
    let multi =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/multi_patch.ron")).unwrap();
    let cases = [
        ("young", good(2).replace("young: 10.0", "young: 1e300"), "`1e300` (`young`)"),
        ("nan", multi.replacen("offset: (0.0, 10.0, 0.0)", "offset: (0.0, NaN, 0.0)", 1), "`NaN` (`offset`)"),
        ("stiffness", good(2).replace("stiffness: 0.0056", "stiffness: 1e300"), "`1e300` (`stiffness`)"),
    ];
    for (tag, text, token) in cases {
        let path = write(&d, &format!("{tag}.ron"), &text);
        refused(&skinsim().arg("check").arg(&path).output().unwrap(), &[&format!("{tag}.ron:"), token, "finite"]);
    }
    let path = write(&d, "good.ron", &good(3));
    let mut bake = skinsim();
    bake.args(["bake", "--frames", "2", "--blend", "0.5", "--out"]).arg(d.join("maps")).arg(&path);
    refused(&bake.output().unwrap(), &["--blend needs two baked frames"]);
}

/// Issue 66: a scene too big to run is refused from its declared sizes before any mesh is made
/// (an 8.1 M-vertex kinematic tube with a shell offset from it was generated first: 44 s and
/// 2.6 GB), within `--budget` when given; `check` prints what a run costs.
#[test]
fn the_budget_is_checked_before_meshes_are_made_and_check_says_what_a_run_costs() {
    let d = scratch("budget");
    let tube = r#"Scene(name: "tube", frames: 2, patches: [Patch(name: "t",
        layers: [
            Layer(name: "bone", kind: Kinematic, mesh: Tube(radius: 8.0, length: 60.0, cells: (2000, 4049))),
            Layer(name: "skin", kind: Shell, mesh: Offset(layer: "bone", distance: 1.0),
                  material: (young: 10.0, poisson: 0.3, thickness: 0.1), bending: (model: Tan)),
        ],
        drivers: [Attach(layer: "skin", to: "bone", stiffness: 0.0056)],
    )])"#;
    let path = write(&d, "tube.ron", tube);
    // (a machine with more than 100 GB would take it: then the budget below decides)
    let out = skinsim().args(["check", "--budget", "20"]).arg(&path).output().unwrap();
    refused(&out, &["layers[1]", "8104050 vertices", "GB to run", "more than the --budget (20.0 GB)"]);
    let path = write(&d, "good.ron", &good(2));
    let out = skinsim().args(["check", "--budget", "0.001"]).arg(&path).output().unwrap();
    refused(&out, &["layers[1]", "more than the --budget (1 MB)"]);
    let mut run = skinsim();
    run.args(["run", "--quiet", "--budget", "0.001", "--out"]).arg(d.join("out")).arg(&path);
    refused(&run.output().unwrap(), &["more than the --budget"]);
    // What a run costs: two layers of 87 vertices (an equilateral grid's odd rows carry one
    // more), the film's all free (the base is kinematic).
    let out = skinsim().arg("check").arg(&path).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(text.contains("sheet: 174 vertices, 261 DOFs; Newton factor about"), "{text}");
    assert!(text.contains("smooth (3 Newton iterations)") && text.contains("buckling (40)"), "{text}");
}

/// Issue 66: `bake` whose recording cannot be written (bake.rrd linked to /dev/full) exits 1
/// naming it; it exited 0.
#[cfg(target_os = "linux")]
#[test]
fn a_bake_whose_recording_cannot_be_written_exits_1() {
    let d = scratch("bake_full");
    let path = write(&d, "good.ron", &good(2));
    let maps = d.join("maps");
    std::fs::create_dir_all(&maps).unwrap();
    std::os::unix::fs::symlink("/dev/full", maps.join("bake.rrd")).unwrap();
    let out = skinsim().args(["bake", "--frames", "1", "--out"]).arg(&maps).arg(&path).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("bake.rrd") && err.contains("No space left"), "{err}");
}

/// Issue 66: SIGTERM (a farm's scheduler) ends a run after the frame being computed, as SIGINT
/// does, keeping every frame written; a second signal ends it at once.
#[cfg(unix)]
#[test]
fn sigterm_ends_a_run_after_its_frame_and_a_second_one_at_once() {
    let d = scratch("sigterm");
    let path = write(&d, "long.ron", &good(5000));
    let out_dir = d.join("out");
    let child = spawn_run(&["--export", "obj"], &out_dir, &path);
    let stats = out_dir.join("stats.jsonl");
    wait_for_frames(&stats, 2);
    assert!(Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap().success());
    let out = finished_within(child, 60);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted after frame"), "{err}");
    let lines = std::fs::read_to_string(&stats).unwrap().lines().count();
    assert_eq!(recorded_frames(&out_dir.join("recording.rrd")), (0..=lines as i64).collect::<Vec<_>>());
    // Two signals in a row: the second ends the run at once, still with a status that says so.
    let child = spawn_run(&[], &d.join("out2"), &path);
    wait_for_frames(&d.join("out2/stats.jsonl"), 1);
    for _ in 0..2 {
        assert!(Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap().success());
    }
    let out = finished_within(child, 60);
    assert_eq!(out.status.code(), Some(130), "{}", String::from_utf8_lossy(&out.stderr));
}
