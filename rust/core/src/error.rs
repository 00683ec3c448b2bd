//! Errors of the core crate. Every fallible entry point returns [`Error`];
//! the core never panics on user input.

use std::path::PathBuf;

/// Everything that can go wrong when loading a robot or answering a query.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file named by the caller (URDF, SRDF, mesh) does not exist or cannot be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why it cannot be read.
        #[source]
        source: std::io::Error,
    },
    /// A URDF or SRDF file is not well-formed XML, or misses a required element.
    #[error("cannot parse {what}: {msg}")]
    Parse {
        /// Which file (e.g. `URDF`, `SRDF <path>`).
        what: String,
        /// What is wrong with it.
        msg: String,
    },
    /// A mesh file could not be turned into a collision shape.
    #[error("bad mesh {path}: {msg}")]
    Mesh {
        /// The mesh file.
        path: PathBuf,
        /// What is wrong with it.
        msg: String,
    },
    /// A joint, link or obstacle name that the model does not have.
    #[error("unknown {kind} '{name}'{hint}")]
    UnknownName {
        /// What was looked up ("link", "obstacle", "robot", ...).
        kind: &'static str,
        /// The name given.
        name: String,
        /// The known names, as " (known: ...)", or empty.
        hint: String,
    },
    /// An input vector or array of the wrong length.
    #[error("{what}: expected length {expected}, got {got}")]
    Shape {
        /// Which input.
        what: String,
        /// The length it must have.
        expected: usize,
        /// The length it has.
        got: usize,
    },
    /// A NaN or infinity in an input.
    #[error("{what}: element {index} is not finite ({value})")]
    NonFinite {
        /// Which input.
        what: String,
        /// Index of the first non-finite element.
        index: usize,
        /// Its value.
        value: f64,
    },
    /// A setting with a bad value; the message names the field.
    #[error("settings: {field} {msg}")]
    Settings {
        /// The setting's name.
        field: &'static str,
        /// What is wrong with its value.
        msg: String,
    },
    /// Any other invalid argument, with a message that names it.
    #[error("{0}")]
    Invalid(String),
}

/// The result of the core's fallible functions.
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
