//! Load-time diagnostics: one `file:line:column: message` per problem found in a level or
//! glTF file, with a JSON pointer naming the place inside the document.
//!
//! Loaders collect every problem they can find (not just the first) so `gloam check` can
//! list them all; `LoadError` carries the list through `anyhow` to the command line.

use std::fmt;
use std::path::{Path, PathBuf};

use super::source_map;

/// One step of a path into a JSON or RON document.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Segment {
    Key(String),
    Index(usize),
}

/// A path into a document, written as an RFC 6901 JSON pointer (`/meshes/0/primitives/1`).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Pointer(pub Vec<Segment>);

impl Pointer {
    pub fn root() -> Self {
        Pointer(Vec::new())
    }

    pub fn key(&self, key: &str) -> Self {
        let mut segments = self.0.clone();
        segments.push(Segment::Key(key.to_owned()));
        Pointer(segments)
    }

    pub fn index(&self, index: usize) -> Self {
        let mut segments = self.0.clone();
        segments.push(Segment::Index(index));
        Pointer(segments)
    }

    /// Builds a pointer from `"/a/0/b"` (segments that parse as numbers become indices).
    pub fn parse(text: &str) -> Self {
        Pointer(
            text.split('/')
                .skip(1)
                .map(|part| match part.parse::<usize>() {
                    Ok(index) => Segment::Index(index),
                    Err(_) => Segment::Key(part.replace("~1", "/").replace("~0", "~")),
                })
                .collect(),
        )
    }

    /// Converts a gltf-json validation path (`meshes[0].attributes["POSITION"]`).
    pub fn from_gltf_path(path: &str) -> Self {
        let mut segments = Vec::new();
        let mut rest = path;
        while !rest.is_empty() {
            if let Some(after) = rest.strip_prefix('.') {
                rest = after;
            } else if let Some(after) = rest.strip_prefix("[\"") {
                let end = after.find("\"]").unwrap_or(after.len());
                segments.push(Segment::Key(after[..end].to_owned()));
                rest = after.get(end + 2..).unwrap_or("");
            } else if let Some(after) = rest.strip_prefix('[') {
                let end = after.find(']').unwrap_or(after.len());
                match after[..end].parse::<usize>() {
                    Ok(index) => segments.push(Segment::Index(index)),
                    Err(_) => segments.push(Segment::Key(after[..end].to_owned())),
                }
                rest = after.get(end + 1..).unwrap_or("");
            } else {
                let end = rest.find(['.', '[']).unwrap_or(rest.len());
                segments.push(Segment::Key(rest[..end].to_owned()));
                rest = &rest[end..];
            }
        }
        Pointer(segments)
    }
}

impl fmt::Display for Pointer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.is_empty() {
            return f.write_str("/");
        }
        for segment in &self.0 {
            match segment {
                Segment::Key(key) => write!(f, "/{}", key.replace('~', "~0").replace('/', "~1"))?,
                Segment::Index(index) => write!(f, "/{index}")?,
            }
        }
        Ok(())
    }
}

/// A problem at a place in a file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Diagnostic {
    pub file: PathBuf,
    /// 1-based line and column of the offending value (1:1 when the file has no text).
    pub line: usize,
    pub column: usize,
    pub message: String,
}

impl Diagnostic {
    /// A problem with the file as a whole (it cannot be read, or is not text).
    pub fn whole_file(file: &Path, message: impl Into<String>) -> Self {
        Diagnostic {
            file: file.to_owned(),
            line: 1,
            column: 1,
            message: message.into(),
        }
    }

    /// A problem at `pointer` inside `text`; the message ends with the pointer so the place
    /// is unambiguous even where line:column is approximate (binary glTF's JSON chunk).
    pub fn at_pointer(
        file: &Path,
        text: &str,
        pointer: &Pointer,
        message: impl Into<String>,
    ) -> Self {
        let position = source_map::locate(text, pointer);
        Diagnostic {
            file: file.to_owned(),
            line: position.line,
            column: position.column,
            message: format!("{} (at {pointer})", message.into()),
        }
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}: {}",
            self.file.display(),
            self.line,
            self.column,
            self.message
        )
    }
}

/// Every problem found while loading one file (never empty).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LoadError {
    pub diagnostics: Vec<Diagnostic>,
}

impl LoadError {
    pub fn single(diagnostic: Diagnostic) -> Self {
        LoadError {
            diagnostics: vec![diagnostic],
        }
    }
}

impl From<Diagnostic> for LoadError {
    fn from(diagnostic: Diagnostic) -> Self {
        LoadError::single(diagnostic)
    }
}

impl fmt::Display for LoadError {
    /// The first problem, and how many more there are: one line, for error chains.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.diagnostics.as_slice() {
            [] => f.write_str("unknown load error"),
            [only] => write!(f, "{only}"),
            [first, rest @ ..] => {
                write!(
                    f,
                    "{first} (and {} more; `gloam check` lists them)",
                    rest.len()
                )
            }
        }
    }
}

impl std::error::Error for LoadError {}
