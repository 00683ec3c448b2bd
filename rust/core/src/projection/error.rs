//! The projection's errors: a custom term's failure ([`TermFailure`]) and why a solve returned no
//! outcome ([`SolveError`]).

use super::TermError;
#[cfg(doc)]
use super::{CustomTerm, Projector};
use crate::error::Error;

/// A [`CustomTerm`] that failed: its evaluation returned an error, or wrote a number that is not
/// finite (the source is then an [`Error::NonFinite`] naming the residual or the Jacobian).
#[derive(Debug, thiserror::Error)]
#[error("term '{term}': {source}")]
pub struct TermFailure {
    /// The term's name.
    pub term: String,
    /// What went wrong, as the term returned it.
    #[source]
    pub source: TermError,
}

impl TermFailure {
    /// The failure as a core [`Error`]: a core error from the term (e.g. a non-finite output)
    /// keeps its variant, its subject prefixed with the term's name; anything else becomes
    /// [`Error::Invalid`] with the failure's message.
    pub fn into_error(self) -> Error {
        let term = self.term;
        match self.source.downcast::<Error>() {
            Ok(e) => match *e {
                Error::NonFinite { what, index, value } => Error::NonFinite { what: format!("term '{term}' {what}"), index, value },
                Error::Shape { what, expected, got } => Error::Shape { what: format!("term '{term}' {what}"), expected, got },
                Error::UnknownName { kind, name, hint } => Error::UnknownName { kind, name, hint },
                other => Error::Invalid(format!("term '{term}': {other}")),
            },
            Err(source) => Error::Invalid(format!("term '{term}': {source}")),
        }
    }
}

/// Why [`Projector::try_solve`] returned no outcome.
#[derive(Debug, thiserror::Error)]
pub enum SolveError {
    /// A bad input (configuration, nominal posture), as [`Projector::solve`] refuses it.
    #[error(transparent)]
    Input(#[from] Error),
    /// A custom term failed during the solve.
    #[error(transparent)]
    Term(#[from] TermFailure),
}

impl From<SolveError> for Error {
    fn from(e: SolveError) -> Error {
        match e {
            SolveError::Input(e) => e,
            SolveError::Term(f) => f.into_error(),
        }
    }
}

/// The result of a step that evaluates terms: a custom term may fail.
pub type TermResult<T> = std::result::Result<T, TermFailure>;
