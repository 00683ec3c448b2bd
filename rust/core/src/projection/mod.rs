//! Constraint projection / inverse kinematics: damped Gauss-Newton with a null-space posture task
//! (the GAN paper's Section III-B), natively.
//!
//! The same algorithm as `genplan.projection.GaussNewtonProjector` (Pinocchio, Python), step for
//! step, so the two are cross-checked against each other in the tests: primary step
//! `dq1 = J1^+ r1` with damping `lambda = mu r^T r + mu_bar` and Armijo backtracking, then a
//! secondary (posture) step `dq2 = N1 (J2 N1)^+ (r2 - alpha J2 dq1)` kept only while it does not
//! make the primary cost worse; clipping to the joint limits after every step. Success: every
//! primary term's largest absolute (unweighted) residual component is below its tolerance.
//!
//! Every number of a term is checked when the projector is built ([`Projector::new`],
//! [`Projector::retargeted`]): finite, and at most [`MAX_MAGNITUDE`] in absolute value
//! (positions in m, weights, masks, tolerances, margins, posture values), rotations orthonormal;
//! the settings' ranges are closed ([`Settings::validate`]). With such inputs the solver's sums
//! of squares cannot overflow; should an iterate still stop being finite (an extreme start or
//! nominal configuration), the solve ends there, unsuccessful, with the last finite
//! configuration ([`Projector::solve_unchecked`]): the answer from a finite start is finite.
//!
//! A term of the caller's own ([`CustomTerm`], held by [`TermKind::Custom`]: in the bindings, a
//! Python object) runs inside the same solver. Its evaluation may fail: the error, kept intact,
//! stops the solve and is returned by [`Projector::try_solve`] (and
//! [`Projector::try_solve_unchecked`], [`Projector::try_primary_residuals`]) as a
//! [`TermFailure`] naming the term; its outputs are checked (finite) after every call.
//!
//! One concept per file: the terms, their residuals and analytic Jacobians (`terms.rs`), their
//! checks (`validate.rs`), the caller's own terms (`custom.rs`), the solver (`solver.rs`:
//! [`Settings`], [`Outcome`], [`Projector`], solving and retargeting), its linear algebra
//! (`linalg.rs`), the residuals without a solve (`residuals.rs`), dense paths on the manifold
//! (`dense.rs`) and the errors (`error.rs`).

mod custom;
mod dense;
mod error;
mod linalg;
mod residuals;
mod solver;
mod terms;
mod validate;

pub use custom::{CustomTerm, TermError};
pub use dense::{dense_path, densify, hold_chords, Dense, DenseFailure, DenseSettings, MAX_DENSE_STATES};
pub use error::{SolveError, TermFailure, TermResult};
pub use solver::{Outcome, Projector, Settings};
pub use terms::{axis_complement, residual_size, Term, TermKind};
pub use validate::{MAX_CUSTOM_DIM, MAX_MAGNITUDE, ROTATION_TOLERANCE};
