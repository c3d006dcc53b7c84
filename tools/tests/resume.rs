//! Issue 66: a run killed at a frame and resumed (`run --resume OUT`) from its last checkpoint
//! (`run --checkpoint-every N`) writes every stats line (timings aside), every OBJ frame, its
//! USD stage and its recording as the uninterrupted run does, on a remeshing, a kernel and an
//! anchor scene. A checkpoint of a changed scene file, from another thread count, a damaged one
//! or none at all is refused with exit 2.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn skinsim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_skinsim"))
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("skinsim-resume-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn scene(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(rel)
}

fn run(args: &[&str], kill_after: Option<u32>) -> Output {
    let mut c = skinsim();
    c.args(args);
    if let Some(k) = kill_after {
        c.env("SKINSIM_TEST_KILL_AFTER_FRAME", k.to_string());
    }
    c.output().unwrap()
}

fn ok(out: &Output) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
}

fn refused(out: &Output, words: &[&str]) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(!err.contains("panicked") && !err.contains("internal error"), "{err}");
    for w in words {
        assert!(err.contains(w), "\"{w}\" not in: {err}");
    }
}

fn stats(out: &Path) -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(out.join("stats.jsonl")).unwrap();
    text.lines().map(|l| skinsim_systems::without_timings(serde_json::from_str(l).unwrap())).collect()
}

/// Every OBJ frame under `out`/obj, by its path below it.
fn obj_frames(out: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(root: &Path, dir: &Path, into: &mut BTreeMap<PathBuf, Vec<u8>>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, into);
            } else {
                into.insert(p.strip_prefix(root).unwrap().to_path_buf(), std::fs::read(&p).unwrap());
            }
        }
    }
    let mut m = BTreeMap::new();
    walk(&out.join("obj"), &out.join("obj"), &mut m);
    m
}

/// Runs `rel` uninterrupted and again with a checkpoint every `every` frames, killed (SIGKILL)
/// after frame `kill`, then resumed; the two runs' outputs must agree.
fn killed_run_resumes_bit_identically(name: &str, rel: &str, frames: u32, every: u32, kill: u32, extra: &[&str]) {
    let d = scratch(name);
    let s = scene(rel);
    let (whole, cut) = (d.join("whole"), d.join("cut"));
    let frames_arg = frames.to_string();
    let base = |out: &Path| -> Vec<String> {
        let mut a: Vec<String> = ["run", s.to_str().unwrap(), "--quiet", "--threads", "2", "--frames", &frames_arg]
            .iter()
            .map(|x| x.to_string())
            .collect();
        a.extend(["--out".to_string(), out.display().to_string()]);
        a.extend(extra.iter().map(|x| x.to_string()));
        a
    };
    let strs = |v: &[String]| v.to_vec();
    let whole_args = strs(&base(&whole));
    ok(&run(&whole_args.iter().map(String::as_str).collect::<Vec<_>>(), None));
    let mut cut_args = base(&cut);
    cut_args.extend(["--checkpoint-every".to_string(), every.to_string()]);
    let killed = run(&cut_args.iter().map(String::as_str).collect::<Vec<_>>(), Some(kill));
    assert!(!killed.status.success(), "{name}: the run was to be killed");
    assert_eq!(stats(&cut).len(), kill as usize, "{name}: frames written before the kill");
    let saved = kill / every * every;
    let resumed = run(&["run", "--resume", cut.to_str().unwrap(), "--quiet"], None);
    ok(&resumed);
    let (a, b) = (stats(&whole), stats(&cut));
    assert_eq!(a.len(), b.len(), "{name}: stats lines");
    for (f, (x, y)) in a.iter().zip(&b).enumerate() {
        assert_eq!(x, y, "{name}: frame {}'s stats line differs after a resume at {saved}", f + 1);
    }
    let (a, b) = (obj_frames(&whole), obj_frames(&cut));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>(), "{name}: OBJ frames");
    assert!(a.len() > (frames as usize), "{name}: OBJ frames are written");
    for (path, bytes) in &a {
        assert!(*bytes == b[path], "{name}: {} differs after a resume at {saved}", path.display());
    }
    // The recording decodes to its end as one recording (the resumed frames appended).
    let index = skinsim_systems::log_read::read_recording(&cut.join("recording.rrd")).unwrap();
    assert_eq!(index.recording_ids.len(), 1, "{name}: one recording");
}

/// The scratch folder of a test that passed, removed (a kernel run's outputs are 50-80 MB).
fn clean(name: &str) {
    let _ = std::fs::remove_dir_all(std::env::temp_dir().join(format!("skinsim-resume-{}-{name}", std::process::id())));
}

#[test]
fn a_killed_remeshing_run_resumes_bit_identically() {
    killed_run_resumes_bit_identically("remesh", "lk14/remesh_one_layer_quick.ron", 8, 2, 5, &[]);
    clean("remesh");
}

#[test]
fn a_killed_anchor_run_resumes_bit_identically() {
    killed_run_resumes_bit_identically("anchor", "kck18/crease_quick.ron", 12, 3, 7, &["--export", "obj"]);
    clean("anchor");
}

/// The kernel scene also exports USD: the resumed stage is the uninterrupted one, byte for byte.
#[test]
fn a_killed_kernel_run_resumes_bit_identically_with_its_usd_stage() {
    let name = "kernel";
    killed_run_resumes_bit_identically(name, "character/hand_quick.ron", 6, 2, 3, &["--export", "usd"]);
    let d = std::env::temp_dir().join(format!("skinsim-resume-{}-{name}", std::process::id()));
    let stage = |run: &str| std::fs::read(d.join(run).join("skinsim.usdc")).unwrap();
    assert!(stage("whole") == stage("cut"), "the resumed USD stage differs");
    assert!(!d.join("cut/.skinsim.usdc.spool").exists(), "the finished run leaves no spool");
    clean(name);
}

#[test]
fn a_resume_is_refused_on_a_changed_scene_another_thread_count_or_a_bad_checkpoint() {
    let d = scratch("refused");
    let s = d.join("scene.ron");
    std::fs::copy(scene("lk14/remesh_one_layer_quick.ron"), &s).unwrap();
    let out = d.join("out");
    let (s_str, out_str) = (s.to_str().unwrap(), out.to_str().unwrap());
    let args = ["run", s_str, "--out", out_str, "--quiet", "--threads", "2", "--no-rerun", "--checkpoint-every", "2"];
    let killed = run(&args, Some(3));
    assert!(!killed.status.success());
    refused(&run(&["run", "--resume", out_str, "--threads", "1"], None), &["the run used 2 threads", "--threads 2"]);
    refused(&run(&["run", "--resume", out_str, "--out", "x"], None), &["--out"]);
    let mut text = std::fs::read_to_string(&s).unwrap();
    text.push_str("\n// a later edit\n");
    std::fs::write(&s, &text).unwrap();
    refused(&run(&["run", "--resume", out_str], None), &["scene.ron changed since", "SHA-256"]);
    let empty = d.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    refused(&run(&["run", "--resume", empty.to_str().unwrap()], None), &["holds no checkpoint", "--checkpoint-every"]);
    std::fs::write(out.join("checkpoint.cbor"), b"not cbor at all").unwrap();
    refused(&run(&["run", "--resume", out_str], None), &["checkpoint.cbor", "not a skinsim checkpoint"]);
    // A checkpoint that cannot be written ends the run with exit 1, naming it.
    let blocked = d.join("blocked");
    std::fs::create_dir_all(blocked.join("checkpoint.cbor.partial")).unwrap();
    let b = blocked.to_str().unwrap();
    let failed = run(&["run", s_str, "--out", b, "--quiet", "--no-rerun", "--checkpoint-every", "2"], None);
    let err = String::from_utf8_lossy(&failed.stderr);
    assert_eq!(failed.status.code(), Some(1), "{err}");
    assert!(err.contains("cannot write the checkpoint") && err.contains("checkpoint.cbor"), "{err}");
    assert!(err.contains("frames 1-2 are complete"), "{err}");
    clean("refused");
}

/// SIGTERM (a farm's preemption) with checkpoints on: the run saves the frame it finished, and
/// the resume goes on from there, losing none.
#[cfg(unix)]
#[test]
fn a_terminated_run_checkpoints_the_frame_it_finished() {
    let d = scratch("term");
    // The remesh scene held for many frames after its compression: long enough to signal.
    let out = d.join("out");
    let s = scene("lk14/remesh_one_layer_quick.ron");
    let mut child = skinsim()
        .args(["run", "--quiet", "--no-rerun", "--frames", "5000", "--checkpoint-every", "1000", "--out"])
        .arg(&out)
        .arg(&s)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let stats_path = out.join("stats.jsonl");
    let started = std::time::Instant::now();
    while std::fs::read_to_string(&stats_path).map_or(0, |t| t.lines().count()) < 3 {
        assert!(started.elapsed().as_secs() < 120, "fewer than 3 frames written");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    // One signal, in the run's first frames: it used to be lost when it came while METIS
    // ordered a matrix (skinsim_tools::signals). The bound only keeps a lost one from hanging
    // the suite; a frame of this scene takes milliseconds.
    assert!(Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap().success());
    let asked = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() && asked.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    if child.try_wait().unwrap().is_none() {
        let _ = child.kill();
        panic!("the run went on 60 s after SIGTERM");
    }
    let stopped = child.wait_with_output().unwrap();
    assert_eq!(stopped.status.code(), Some(130), "{}", String::from_utf8_lossy(&stopped.stderr));
    let written = stats(&out).len() as u32;
    let resumed = run(&["run", "--resume", out.to_str().unwrap(), "--frames", &(written + 1).to_string()], None);
    ok(&resumed);
    let err = String::from_utf8_lossy(&resumed.stderr);
    assert!(err.contains(&format!("1 frames (resumed after frame {written})")), "{err}");
    assert_eq!(stats(&out).len() as u32, written + 1);
    clean("term");
}
