//! `run --checkpoint-every N` and `run --resume OUT` (issue 66): the checkpoint file, what it
//! records besides the World's state (the scene file and its hash, the program's build, the
//! run's command line and thread count, and how far each output had got), and the checks that
//! refuse a checkpoint from another scene, another build or a changed scene file.
//!
//! The file is CBOR (every f64 bit-exact), written beside the outputs as `checkpoint.cbor`
//! through a temporary file and a rename, so the one on disk is always complete.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use skinsim::mesh::usd::UsdMark;
use skinsim_systems::checkpoint::Checkpoint;

/// The checkpoint's file name in the output folder.
pub const FILE: &str = "checkpoint.cbor";

/// Bumped when the file's layout changes.
pub const FORMAT: u32 = 1;

/// A checkpoint file.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Saved<A> {
    pub format: u32,
    /// `CARGO_PKG_VERSION` and the build (`build_id`).
    pub version: String,
    pub build: String,
    /// The scene file as the run named it, made absolute, and its SHA-256.
    pub scene_file: PathBuf,
    pub scene_sha256: String,
    pub scene_name: String,
    /// The run's options, paths made absolute (a resume runs with them again).
    pub args: A,
    pub threads: usize,
    /// The frames the run was to compute.
    pub frames: u32,
    /// How far the outputs had got when the state was saved: stats.jsonl's length, the
    /// recording's (file, length, recording id) and the USD stage's mark.
    pub stats_len: Option<u64>,
    pub recording: Option<RecordingMark>,
    pub usd: Option<UsdMark>,
    pub state: Checkpoint,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RecordingMark {
    pub file: Option<PathBuf>,
    pub len: u64,
    pub recording_id: String,
}

/// This program's build: a hash of its executable (a checkpoint resumes bit-identically only
/// under the code that wrote it).
pub fn build_id() -> String {
    static ID: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    ID.get_or_init(|| {
        let bytes = std::env::current_exe().and_then(std::fs::read).unwrap_or_default();
        format!("{:016x}", xxhash_rust::xxh3::xxh3_64(&bytes))
    })
    .clone()
}

/// The SHA-256 of a file's bytes, in hex.
pub fn file_sha256(path: &Path) -> Result<String, String> {
    use sha2::Digest;
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(sha2::Sha256::digest(&bytes).iter().map(|b| format!("{b:02x}")).collect())
}

/// Writes `saved` to `out`/checkpoint.cbor, replacing the last one only once it is whole.
pub fn write<A: Serialize>(out: &Path, saved: &Saved<A>) -> Result<(), String> {
    let path = out.join(FILE);
    let partial = out.join(format!("{FILE}.partial"));
    let fail = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let mut bytes = Vec::new();
    ciborium::into_writer(saved, &mut bytes).map_err(|e| fail(&e))?;
    {
        use std::io::Write;
        let mut f = std::fs::File::create(&partial).map_err(|e| fail(&e))?;
        f.write_all(&bytes).and_then(|_| f.sync_all()).map_err(|e| fail(&e))?;
    }
    std::fs::rename(&partial, &path).map_err(|e| fail(&e))
}

/// Reads `out`/checkpoint.cbor.
pub fn read<A: serde::de::DeserializeOwned>(out: &Path) -> Result<Saved<A>, String> {
    let path = out.join(FILE);
    if !path.is_file() {
        return Err(format!(
            "{} holds no checkpoint ({FILE}): run with --checkpoint-every N to write one",
            out.display()
        ));
    }
    let bytes = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let saved: Saved<A> = ciborium::from_reader(&bytes[..])
        .map_err(|e| format!("{}: not a skinsim checkpoint, or a damaged one ({e})", path.display()))?;
    if saved.format != FORMAT {
        return Err(format!("{}: checkpoint format {}, this skinsim reads {FORMAT}", path.display(), saved.format));
    }
    Ok(saved)
}

/// What differs between the checkpoint and this program and scene file, if anything: each
/// difference in a sentence.
pub fn differences<A>(saved: &Saved<A>, scene_sha256: Option<&str>) -> Vec<String> {
    let mut out = Vec::new();
    let version = env!("CARGO_PKG_VERSION");
    if saved.version != version || saved.build != build_id() {
        out.push(format!(
            "it was written by skinsim {} (build {}), this is skinsim {version} (build {})",
            saved.version,
            saved.build,
            build_id()
        ));
    }
    match scene_sha256 {
        None => out.push(format!("its scene file {} cannot be read", saved.scene_file.display())),
        Some(sha) if sha != saved.scene_sha256 => out.push(format!(
            "its scene file {} changed since (SHA-256 {} then, {} now)",
            saved.scene_file.display(),
            short(&saved.scene_sha256),
            short(sha)
        )),
        Some(_) => {}
    }
    out
}

fn short(sha: &str) -> &str {
    &sha[..sha.len().min(12)]
}

/// stats.jsonl cut back to its first `len` bytes (the frames up to the checkpoint), to append.
pub fn reopen_stats(path: &Path, len: u64) -> Result<std::fs::File, String> {
    use std::io::Seek;
    let fail = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let mut f = std::fs::OpenOptions::new().write(true).open(path).map_err(|e| fail(&e))?;
    let on_disk = f.metadata().map_err(|e| fail(&e))?.len();
    if on_disk < len {
        return Err(format!("{}: {on_disk} bytes, shorter than the checkpoint's {len}", path.display()));
    }
    f.set_len(len).map_err(|e| fail(&e))?;
    f.seek(std::io::SeekFrom::Start(len)).map_err(|e| fail(&e))?;
    Ok(f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_changed_scene_file_and_another_build_are_named() {
        let state =
            Checkpoint { frame: 3, time: 0.1, layers: Vec::new(), patches: Vec::new(), log: (false, Vec::new()) };
        let saved = Saved {
            format: FORMAT,
            version: env!("CARGO_PKG_VERSION").into(),
            build: build_id(),
            scene_file: "scene.ron".into(),
            scene_sha256: "aa".repeat(32),
            scene_name: "s".into(),
            args: (),
            threads: 2,
            frames: 10,
            stats_len: None,
            recording: None,
            usd: None,
            state,
        };
        assert!(differences(&saved, Some(&"aa".repeat(32))).is_empty());
        let changed = differences(&saved, Some(&"bb".repeat(32)));
        assert_eq!(changed.len(), 1);
        assert!(changed[0].contains("scene.ron changed since (SHA-256 aaaaaaaaaaaa then, bbbbbbbbbbbb now)"));
        let other = Saved { build: "0000000000000000".into(), ..saved };
        let d = differences(&other, Some(&"aa".repeat(32)));
        assert!(d[0].contains("(build 0000000000000000), this is skinsim"), "{d:?}");
    }
}
