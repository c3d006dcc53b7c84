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
    pub(crate) fn at_field(file: impl Into<PathBuf>, field: impl Into<String>, message: impl Into<String>) -> Self {
        let message = compact_numbers(&message.into());
        SceneError { file: file.into(), position: None, field: Some(field.into()), message }
    }
}

/// A number printed with more than this many characters is shown in scientific notation (an
/// f64 such as 1e300 prints with 301 digits).
const LONG_NUMBER: usize = 16;

/// The message with every overlong decimal number written as, e.g., 1e300.
fn compact_numbers(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(start) = rest.find(|c: char| c.is_ascii_digit()) {
        out.push_str(&rest[..start]);
        let tail = &rest[start..];
        let end = tail.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(tail.len());
        let token = &tail[..end];
        match token.parse::<f64>() {
            Ok(v) if token.len() > LONG_NUMBER => out.push_str(&format!("{v:e}")),
            _ => out.push_str(token),
        }
        rest = &tail[end..];
    }
    out.push_str(rest);
    out
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

#[cfg(test)]
mod tests {
    #[test]
    fn overlong_numbers_are_compacted() {
        let long = format!("must be > 0 (got -{})", 1e300);
        assert_eq!(super::compact_numbers(&long), "must be > 0 (got -1e300)");
        let short = "vertex 12 at 0.25 m, 1234567890123456 cells";
        assert_eq!(super::compact_numbers(short), short);
    }
}
