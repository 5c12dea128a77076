//! Where things are in scene files, and what went wrong there.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A position in a scene file: the file and a 1-based line.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Loc {
    pub file: Arc<PathBuf>,
    pub line: u32,
}

impl Loc {
    pub fn new(file: &Arc<PathBuf>, line: u32) -> Loc {
        Loc {
            file: Arc::clone(file),
            line,
        }
    }

    /// A location for values that do not come from a file (defaults, tests).
    pub fn synthetic(what: &str) -> Loc {
        Loc {
            file: Arc::new(PathBuf::from(format!("<{what}>"))),
            line: 0,
        }
    }

    pub fn path(&self) -> &Path {
        &self.file
    }
}

impl fmt::Display for Loc {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.file.display(), self.line)
    }
}

/// How bad a diagnostic is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Severity {
    /// Kiln ignored something that does not change the image (or changes it in a documented way).
    Warning,
    /// Kiln cannot render the scene faithfully.
    Error,
}

/// One message about a scene file, with its location.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnostic {
    pub severity: Severity,
    pub loc: Loc,
    pub message: String,
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let level = match self.severity {
            Severity::Warning => "warning",
            Severity::Error => "error",
        };
        write!(f, "{}: {level}: {}", self.loc, self.message)
    }
}

/// Why a scene could not be loaded. Every variant names the file and line it comes from.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene (or a file it includes) could not be read.
    /// (The OS error is in the message and not a `source`, so that a chain of causes does
    /// not print it twice.)
    #[error("{loc}: cannot read '{path}': {cause}")]
    Io {
        loc: Loc,
        path: PathBuf,
        cause: std::io::Error,
    },
    /// A syntax or semantic error at one place.
    #[error("{loc}: {message}")]
    At { loc: Loc, message: String },
    /// Several errors found in one pass; the first few are listed.
    #[error("{}", format_many(.0))]
    Many(Vec<Diagnostic>),
}

fn format_many(diags: &[Diagnostic]) -> String {
    let shown: Vec<String> = diags.iter().take(20).map(|d| d.to_string()).collect();
    let mut text = shown.join("\n");
    if diags.len() > 20 {
        text.push_str(&format!("\n... and {} more errors", diags.len() - 20));
    }
    text
}

impl SceneError {
    pub fn at(loc: &Loc, message: impl Into<String>) -> SceneError {
        SceneError::At {
            loc: loc.clone(),
            message: message.into(),
        }
    }
}

pub type Result<T, E = SceneError> = std::result::Result<T, E>;
