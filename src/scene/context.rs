//! What every part of a scene's build reads: the builder (the file, its errors and notes, the
//! memory estimate) and a patch's context (its layers by name, units and offset).

use std::collections::HashMap;
use std::path::PathBuf;

use glam::DVec3;

use super::built::BuiltLayer;
use super::error::SceneError;
use super::schema::Scene;

/// The longest name of a scene, patch or layer.
const MAX_NAME: usize = 64;

pub(super) struct Builder {
    pub(super) file: PathBuf,
    pub(super) dir: PathBuf,
    /// The memory the layers built so far need to run (bytes, estimated: `meshes.rs`).
    pub(super) memory: std::cell::Cell<f64>,
    /// The memory budget (bytes) and whose it is ("--budget", "the scene's `memory` budget"),
    /// if one is stated; else the machine's memory bounds the run.
    pub(super) budget: std::cell::Cell<Option<(f64, &'static str)>>,
    /// What `check` and `run` tell the user beyond errors (`BuiltScene::notes`).
    pub(super) notes: std::cell::RefCell<Vec<String>>,
}

impl Builder {
    pub(super) fn err(&self, field: impl Into<String>, message: impl Into<String>) -> SceneError {
        SceneError::at_field(&self.file, field, message)
    }

    /// A line for the user: an estimate, a measured distortion, input fixed with a warning.
    pub(super) fn note(&self, line: String) {
        self.notes.borrow_mut().push(line);
    }

    pub(super) fn check_name(&self, field: impl Into<String>, name: &str) -> Result<(), SceneError> {
        let safe = |c: char| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.');
        let ok = (1..=MAX_NAME).contains(&name.len())
            && name.chars().all(safe)
            && !name.starts_with(['.', '-'])
            && !name.contains("..");
        if ok {
            return Ok(());
        }
        Err(self.err(
            field,
            format!(
                "\"{}\" is not a usable name: it names output folders and files, so it must be 1-{MAX_NAME} \
                 letters, digits, '_', '-' or '.', not starting with '.' or '-'",
                name.escape_debug()
            ),
        ))
    }
}

/// What a patch's drivers are built against: its layers (by name too), units and offset.
pub(super) struct PatchContext<'a> {
    pub scene: &'a Scene,
    pub layers: &'a [BuiltLayer],
    pub index: &'a HashMap<String, usize>,
    /// Metres and pascals per scene unit.
    pub len: f64,
    pub stress: f64,
    /// Where the patch sits (m).
    pub offset: DVec3,
}

impl PatchContext<'_> {
    /// The index of the layer named `name`, or an error at `field`.
    pub(super) fn find(&self, builder: &Builder, field: String, name: &str) -> Result<usize, SceneError> {
        let missing = || builder.err(field, format!("no layer named \"{name}\" in this patch"));
        self.index.get(name).copied().ok_or_else(missing)
    }
}

/// Why an asset path is not a readable file (None when it is one): not found, a directory, or
/// not a regular file (a device or a pipe).
pub(super) fn not_a_file(path: &std::path::Path) -> Option<String> {
    match std::fs::metadata(path) {
        Err(_) => Some(format!("not found: {}", path.display())),
        Ok(m) if m.is_dir() => Some(format!("{} is a directory", path.display())),
        Ok(m) if !m.is_file() => Some(format!("{} is not a regular file", path.display())),
        Ok(_) => None,
    }
}
