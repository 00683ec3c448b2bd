//! Errors of the core crate. Every fallible entry point returns [`Error`];
//! the core never panics on user input.

use std::path::PathBuf;

/// Everything that can go wrong when loading a robot or answering a query.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file named by the caller (URDF, SRDF, mesh) does not exist or cannot be read.
    #[error("cannot read {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A URDF or SRDF file is not well-formed XML, or misses a required element.
    #[error("cannot parse {what}: {msg}")]
    Parse { what: String, msg: String },
    /// A mesh file could not be turned into a collision shape.
    #[error("bad mesh {path}: {msg}")]
    Mesh { path: PathBuf, msg: String },
    /// A joint, link or obstacle name that the model does not have.
    #[error("unknown {kind} '{name}'{hint}")]
    UnknownName {
        kind: &'static str,
        name: String,
        hint: String,
    },
    /// An input vector or array of the wrong length.
    #[error("{what}: expected length {expected}, got {got}")]
    Shape {
        what: String,
        expected: usize,
        got: usize,
    },
    /// A NaN or infinity in an input.
    #[error("{what}: element {index} is not finite ({value})")]
    NonFinite {
        what: String,
        index: usize,
        value: f64,
    },
    /// Any other invalid argument, with a message that names it.
    #[error("{0}")]
    Invalid(String),
}

pub type Result<T> = std::result::Result<T, Error>;

/// Check that `values` has `expected` elements, all finite.
pub fn check_vector(what: &str, values: &[f64], expected: usize) -> Result<()> {
    if values.len() != expected {
        return Err(Error::Shape {
            what: what.to_string(),
            expected,
            got: values.len(),
        });
    }
    check_finite(what, values)
}

/// Check that every element of `values` is finite.
pub fn check_finite(what: &str, values: &[f64]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(Error::NonFinite {
            what: what.to_string(),
            index,
            value: values[index],
        }),
        None => Ok(()),
    }
}

pub(crate) fn unknown(kind: &'static str, name: &str, known: &[&str]) -> Error {
    const SHOWN: usize = 12;
    let mut hint = String::new();
    if !known.is_empty() {
        let shown: Vec<&str> = known.iter().take(SHOWN).copied().collect();
        hint = format!(
            " (known: {}{})",
            shown.join(", "),
            if known.len() > SHOWN { ", ..." } else { "" }
        );
    }
    Error::UnknownName {
        kind,
        name: name.to_string(),
        hint,
    }
}
