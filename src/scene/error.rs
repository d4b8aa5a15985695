//! Scene errors that name the file, line, column and key, and say what would be valid.

use std::fmt;
use std::path::PathBuf;

/// One problem found in a scene file, located in its source text.
#[derive(Clone, Debug, PartialEq)]
pub struct Diagnostic {
    /// The file (or `builtin:NAME`).
    pub file: String,
    /// 1-based line and column of the offending key or value.
    pub line: usize,
    pub column: usize,
    /// Where in the scene: `[[sphere]] #2 key `radius``, `[camera]`, ….
    pub key: String,
    pub message: String,
    /// A suggestion ("did you mean `color`?", "valid range is 0 to 1").
    pub help: Option<String>,
    /// The source line, for the snippet under the message.
    pub source_line: String,
}

impl Diagnostic {
    /// Locates `span` (byte offsets) in `src` and builds the diagnostic.
    pub(crate) fn at(
        file: &str,
        src: &str,
        span: std::ops::Range<usize>,
        key: String,
        message: String,
        help: Option<String>,
    ) -> Diagnostic {
        let start = span.start.min(src.len());
        let before = &src[..start];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = src[line_start..start].chars().count() + 1;
        let source_line = src[line_start..]
            .lines()
            .next()
            .unwrap_or_default()
            .to_string();
        Diagnostic {
            file: file.to_string(),
            line,
            column,
            key,
            message,
            help,
            source_line,
        }
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}: ", self.file, self.line, self.column)?;
        if !self.key.is_empty() {
            write!(f, "{}: ", self.key)?;
        }
        writeln!(f, "{}", self.message)?;
        let gutter = self.line.to_string().len();
        writeln!(f, "{:gutter$} |", "")?;
        writeln!(f, "{} | {}", self.line, self.source_line)?;
        let pad: String = self
            .source_line
            .chars()
            .take(self.column.saturating_sub(1))
            .map(|c| if c == '\t' { '\t' } else { ' ' })
            .collect();
        write!(f, "{:gutter$} | {pad}^", "")?;
        if let Some(h) = &self.help {
            write!(f, "\n{:gutter$} = help: {h}", "")?;
        }
        Ok(())
    }
}

crate::message_error!(
    /// What is wrong inside a model, mesh or image file, as the user reads it ("accessor 3
    /// has no buffer view"), before the caller ties it to the file's path
    /// ([`super::gltf::GltfError`], [`Diagnostic`]).
    Malformed
);

/// An error reading a glTF (or OBJ) file: what went wrong, naming the part of the file.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct GltfError {
    pub path: String,
    pub message: String,
}

/// Why a scene could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("cannot read scene file {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("no scene file `{name}`, and it is not a built-in scene (built-in: {})", builtins.join(", "))]
    NotFound { name: String, builtins: Vec<String> },
    #[error("invalid scene\n{}", format_all(.0))]
    Invalid(Vec<Diagnostic>),
    /// The sky map given beside the scene (the command line's) cannot be used.
    #[error("sky map {0}")]
    Sky(#[from] super::envmap::EnvMapError),
    /// A glTF file that cannot be opened (what is wrong, naming the file and its part).
    #[error("invalid glTF scene: {0}")]
    Gltf(#[from] GltfError),
}

impl SceneError {
    /// The located problems, when the file was read but is not a valid scene.
    pub fn diagnostics(&self) -> &[Diagnostic] {
        match self {
            SceneError::Invalid(d) => d,
            _ => &[],
        }
    }
}

fn format_all(diags: &[Diagnostic]) -> String {
    let mut s = String::new();
    for (i, d) in diags.iter().enumerate() {
        if i > 0 {
            s.push_str("\n\n");
        }
        s.push_str(&d.to_string());
    }
    if diags.len() > 1 {
        s.push_str(&format!("\n\n{} errors in this scene", diags.len()));
    }
    s
}
