//! Typed Python errors raised from Rust. The classes are defined once, in Python
//! (`python/genplan/errors.py`), and looked up here when an error is raised, so an error has
//! one type whichever layer found it (docs/ARCHITECTURE.md, "Errors").

use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyType;

use genplan_core::Error;

/// The kinds of caller error, one per class of `genplan.errors`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    Generic,
    Shape,
    NonFinite,
    UnknownName,
    Settings,
    RobotFile,
    InvalidStart,
    InvalidGoal,
    InvalidTrajectory,
    LimitExceeded,
    Callback,
}

impl Kind {
    fn class_name(self) -> &'static str {
        match self {
            Kind::Generic => "GenplanError",
            Kind::Shape => "ShapeError",
            Kind::NonFinite => "NonFiniteError",
            Kind::UnknownName => "UnknownNameError",
            Kind::Settings => "SettingsError",
            Kind::RobotFile => "RobotFileError",
            Kind::InvalidStart => "InvalidStartError",
            Kind::InvalidGoal => "InvalidGoalError",
            Kind::InvalidTrajectory => "InvalidTrajectoryError",
            Kind::LimitExceeded => "LimitExceededError",
            Kind::Callback => "CallbackError",
        }
    }
}

/// A `genplan.errors` exception of the given kind (a plain ValueError if that module cannot be
/// imported, which only happens when the extension is used without its Python package).
pub(crate) fn err(kind: Kind, msg: impl Into<String>) -> PyErr {
    let msg: String = msg.into();
    Python::attach(|py| {
        let cls = py
            .import("genplan.errors")
            .and_then(|m| m.getattr(kind.class_name()))
            .and_then(|c| c.cast_into::<PyType>().map_err(PyErr::from));
        match cls {
            Ok(cls) => PyErr::from_type(cls, msg),
            Err(_) => PyValueError::new_err(msg),
        }
    })
}

/// The Python error of a core error: missing files are FileNotFoundError, unreadable ones
/// OSError, everything else the `genplan.errors` class of its kind.
pub(crate) fn to_py(e: Error) -> PyErr {
    let msg = e.to_string();
    raise_as(&e, msg)
}

/// [`to_py`] with the message prefixed by `what` (the argument or row at fault), same class.
pub(crate) fn to_py_in(what: &str, e: Error) -> PyErr {
    let msg = format!("{what}: {e}");
    raise_as(&e, msg)
}

fn raise_as(e: &Error, msg: String) -> PyErr {
    let kind = match e {
        Error::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            return PyFileNotFoundError::new_err(msg)
        }
        Error::Io { .. } => return PyOSError::new_err(msg),
        Error::Parse { .. } | Error::Mesh { .. } => Kind::RobotFile,
        Error::UnknownName { .. } => Kind::UnknownName,
        Error::Shape { .. } => Kind::Shape,
        Error::NonFinite { .. } => Kind::NonFinite,
        Error::Settings { .. } => Kind::Settings,
        Error::Invalid(_) => Kind::Generic,
    };
    err(kind, msg)
}
