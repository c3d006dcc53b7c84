//! Scene and asset errors: each names the file and the line and column or the field.

use std::fmt;
use std::path::PathBuf;

#[derive(Clone, Debug, PartialEq)]
pub struct SceneError {
    pub file: PathBuf,
    /// 1-based line and column, when the error has a position in the file.
    pub position: Option<(usize, usize)>,
    /// Path of the offending field, e.g. `patches[0].layers[1].material.young`.
    pub field: Option<String>,
    pub message: String,
}

impl SceneError {
    pub fn at_field(file: impl Into<PathBuf>, field: impl Into<String>, message: impl Into<String>) -> Self {
        SceneError { file: file.into(), position: None, field: Some(field.into()), message: message.into() }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some((line, col)) = self.position {
            write!(f, ":{line}:{col}")?;
        }
        if let Some(field) = &self.field {
            write!(f, ": {field}")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for SceneError {}
