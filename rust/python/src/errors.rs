//! The typed Python errors of genplan, defined once: `error_classes!` below is the one table
//! of the classes the native core raises. Each is created here (`create_exception!`), registered
//! on `genplan._core` and re-exported by `genplan.errors` (where the errors only Python raises
//! subclass them), so an error has one type whichever layer found it (docs/ARCHITECTURE.md,
//! "Errors"). Their `__module__` is `genplan.errors`, the module users import them from: what a
//! traceback shows, and where pickle finds them again.

use pyo3::create_exception;
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyTuple, PyType};

use genplan_core::Error;

/// The table of error classes: for each, its [`Kind`] variant, its class and base, and its
/// docstring. Makes the classes, [`Kind`], [`Kind::new_err`] (a kind's class raised directly,
/// without a lookup) and [`register`].
macro_rules! error_classes {
    ($($(#[$meta:meta])* $kind:ident => $name:ident($base:ty), $doc:literal;)+) => {
        $(create_exception!(genplan.errors, $name, $base, $doc);)+

        /// The kinds of caller error, one per class of the table.
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        pub(crate) enum Kind {
            $($(#[$meta])* $kind,)+
        }

        impl Kind {
            /// An exception of this kind's class carrying `msg`.
            fn new_err(self, msg: String) -> PyErr {
                match self {
                    $(Kind::$kind => $name::new_err(msg),)+
                }
            }
        }

        /// Add every class of the table to `m` under its name, and the tuple `ERRORS` of them all
        /// (in the table's order), which `genplan.errors` re-exports and the tests check.
        pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
            let py = m.py();
            let classes: Vec<Bound<'_, PyType>> = vec![$(py.get_type::<$name>()),+];
            for cls in &classes {
                m.add(cls.name()?, cls)?;
            }
            m.add("ERRORS", PyTuple::new(py, classes)?)
        }
    };
}

error_classes! {
    /// Any other bad argument.
    Generic => GenplanError(PyValueError),
        "An argument genplan cannot use; the message names the argument and the problem.";
    Shape => ShapeError(GenplanError),
        "An array or vector of the wrong shape or length (or not readable as numbers).";
    NonFinite => NonFiniteError(GenplanError),
        "A NaN or infinity where a finite number is needed; the message gives the first one.";
    UnknownName => UnknownNameError(GenplanError),
        "A name (robot, link, joint, frame, term, sampler, environment, ...) that is not known;
the message lists the known ones.";
    Settings => SettingsError(GenplanError),
        "A setting with a bad value, of the wrong type, or not known; the message names the field.";
    RobotFile => RobotFileError(GenplanError),
        "A robot description (URDF, SRDF, mesh) that exists but cannot be read into a model.";
    InvalidStart => InvalidStartError(GenplanError),
        "A planning start that the result's guarantee cannot rest on (e.g. in collision).";
    InvalidGoal => InvalidGoalError(GenplanError),
        "Planning goals that the result's guarantee cannot rest on (e.g. none of them valid).";
    InvalidTrajectory => InvalidTrajectoryError(GenplanError),
        "A path that cannot be timed (a state outside the joint limits, no parameterisation within
the velocity and acceleration limits) or a trajectory that fails its own check (a sample
outside the joint limits, in collision, or off the task's manifold); the message names the
first bad state or sample (index, time) and the limit, pair or term it breaks.";
    LimitExceeded => LimitExceededError(GenplanError),
        "A trajectory whose execution exceeds the robot's rated joint limits (torque or speed),
refused under strict checking (``genplan.control.execute(..., strict=True)``); the message
names the joint, the time, the value and the limit.";
    Callback => CallbackError(GenplanError),
        "A Python sampler, projector or checker called back from the native core returned a value
of the wrong shape or type. An exception the callback raises itself reaches the caller
unchanged.";
}

/// An exception of `kind`'s class (from the table above) carrying `msg`.
pub(crate) fn err(kind: Kind, msg: impl Into<String>) -> PyErr {
    kind.new_err(msg.into())
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
