//! Residual terms of the caller's own ([`CustomTerm`]), evaluated inside the solver like the
//! built-in ones.

#[cfg(doc)]
use super::{Term, TermFailure};
#[cfg(doc)]
use crate::kinematics::KinematicModel;

/// The error a [`CustomTerm`] returns: anything, kept intact (the bindings box a Python
/// exception and raise it again unchanged).
pub type TermError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// A residual term of the caller's own, evaluated inside the solver like the built-in ones.
///
/// Its residual has [`dim`](Self::dim) components; its Jacobian is `dim x nv`, row-major, with
/// respect to the tangent space (the same `v` as the other terms: for a free-flyer base, the
/// base's twist in its own frame, as [`KinematicModel::integrate`] steps it). The solver weights
/// both by the term's [`Term::weight`] and checks that every number written is finite.
pub trait CustomTerm: Send + Sync + std::fmt::Debug {
    /// Number of residual components (at least 1), the same at every q.
    fn dim(&self) -> usize;
    /// Write the unweighted residual at `q` (length nq) to `residual` (length `dim`) and, when
    /// `jacobian` is given, its Jacobian (length `dim * nv`, row-major). An error stops the solve
    /// ([`TermFailure`]).
    fn evaluate(&self, q: &[f64], residual: &mut [f64], jacobian: Option<&mut [f64]>) -> std::result::Result<(), TermError>;
}
