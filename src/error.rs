//! One error type for the crate: every message names the field (or cell) at fault.

use thiserror::Error;

/// What can go wrong between reading a scene and writing the last output.
#[derive(Debug, Error)]
pub enum Error {
    /// A scene value is missing, unknown or out of its allowed range; `field` is the JSON path,
    /// or the command-line option (`--steps`), which the message calls an option.
    #[error("{} `{field}`: {message}", if field.starts_with("--") { "option" } else { "scene:" })]
    Scene {
        /// The JSON path of the value, e.g. `bodies[0].mesh.cells`.
        field: String,
        /// What is wrong and the allowed range.
        message: String,
    },
    /// A mesh cell is degenerate, clockwise, overlapping or non-conforming.
    #[error("mesh `{body}`: cell {cell}: {message}")]
    Mesh {
        /// The body's name.
        body: String,
        /// The cell's index within the body.
        cell: usize,
        /// What is wrong with it.
        message: String,
    },
    /// The scene is not JSON, or not a JSON object (a key at fault in well-formed JSON is a
    /// [`Error::Scene`] at its path).
    #[error("scene {path}: {message}")]
    Parse {
        /// The scene file (or `<string>`).
        path: String,
        /// The parser's message, with the line and column.
        message: String,
    },
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file or directory.
        path: String,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
}

/// The longest message (in characters) an error keeps: a value echoed whole, or the rest of a
/// file a reader quotes, is cut past it.
pub const MAX_MESSAGE: usize = 400;

/// `text` cut to [`MAX_MESSAGE`] characters, with how much was left out.
pub fn cut(text: impl Into<String>) -> String {
    let text = text.into();
    match text.char_indices().nth(MAX_MESSAGE) {
        None => text,
        Some((end, _)) => format!(
            "{}… ({} more characters)",
            &text[..end],
            text[end..].chars().count()
        ),
    }
}

impl Error {
    /// The error as `(kind, key, message)`: `kind` is `scene`, `mesh`, `parse` or `io`, and
    /// `key` the scene key, the mesh's body and cell, or the file at fault. `rbsm --json` and
    /// the Python package report errors so.
    pub fn parts(&self) -> (&'static str, String, String) {
        match self {
            Error::Scene { field, message } => ("scene", field.clone(), message.clone()),
            Error::Mesh {
                body,
                cell,
                message,
            } => ("mesh", format!("{body}, cell {cell}"), message.clone()),
            Error::Parse { path, message } => ("parse", path.clone(), message.clone()),
            Error::Io { path, source } => ("io", path.clone(), source.to_string()),
        }
    }

    /// A scene error for `field` with an explanation of the allowed values.
    pub fn scene(field: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Scene {
            field: cut(field),
            message: cut(message),
        }
    }
    /// A mesh error that names the body and the cell.
    pub fn mesh(body: &str, cell: usize, message: impl Into<String>) -> Self {
        Error::Mesh {
            body: cut(body),
            cell,
            message: cut(message),
        }
    }
    /// A parse error in the file `path`.
    pub fn parse(path: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Parse {
            path: cut(path),
            message: cut(message),
        }
    }
    /// An I/O error that names the path.
    pub fn io(path: impl AsRef<std::path::Path>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.as_ref().display().to_string(),
            source,
        }
    }
}

/// The crate's result type.
pub type Result<T> = std::result::Result<T, Error>;
