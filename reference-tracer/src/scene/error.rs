//! Scene errors: the file, the place inside it, and what was wrong.

use std::fmt;
use std::path::{Path, PathBuf};

/// A scene that cannot be rendered as written.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    /// The file at fault (the scene file, or a mesh or image it names).
    pub file: PathBuf,
    /// Where in the scene file: a JSON path such as `materials.lamp.emission` or
    /// `shapes[2].file`, with the line and column when the JSON itself is malformed.
    pub location: String,
    /// What is wrong.
    pub message: String,
}

impl SceneError {
    /// An error at `location` of `file`.
    pub fn new(file: &Path, location: impl Into<String>, message: impl Into<String>) -> Self {
        Self { file: file.to_path_buf(), location: location.into(), message: message.into() }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.location.is_empty() {
            write!(f, "{}: {}", self.file.display(), self.message)
        } else {
            write!(f, "{}: {}: {}", self.file.display(), self.location, self.message)
        }
    }
}

impl std::error::Error for SceneError {}
