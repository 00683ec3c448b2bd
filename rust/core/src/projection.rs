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

use std::sync::Arc;
use std::time::Instant;

use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Matrix6, SMatrix, Vector3};

use crate::error::{check_finite, check_vector, Error, Result};
use crate::kinematics::KinematicModel;
use crate::lie::{action, jlog3, jlog6, log3, log6, skew};

/// The largest absolute value of a term's numbers (target and box coordinates in m, weights,
/// masks, tolerances, margins, posture weights and values) and of the damping settings: 1e6.
/// Squared residuals of such terms, weighted, stay far from overflow.
pub const MAX_MAGNITUDE: f64 = 1e6;

/// How far a term's rotation matrix may be from orthonormal (largest entry of `R^T R - I`), as
/// `genplan.projection` checks it in Python.
pub const ROTATION_TOLERANCE: f64 = 1e-6;

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

/// What a residual term measures.
#[derive(Debug, Clone)]
pub enum TermKind {
    /// r = mask * log6(T_ref^-1 T(q)).
    FramePose {
        /// Index of the link.
        link: usize,
        /// T_ref, in the world.
        target: Isometry3<f64>,
        /// Per component of the residual (linear, then angular); 0 drops it.
        mask: [f64; 6],
    },
    /// r = mask * (p(q) - p_ref).
    FramePosition {
        /// Index of the link.
        link: usize,
        /// p_ref, in the world.
        target: Vector3<f64>,
        /// Per component of the residual; 0 drops it.
        mask: [f64; 3],
    },
    /// r = mask * log3(R_ref^T R(q) R_offset).
    FrameOrientation {
        /// Index of the link.
        link: usize,
        /// R_ref, in the world.
        target: Matrix3<f64>,
        /// R_offset, in the link frame.
        offset: Matrix3<f64>,
        /// Per component of the residual; 0 drops it.
        mask: [f64; 3],
    },
    /// The pose of one link in another's frame: r = mask * log6(T_ref^-1 T_B(q)^-1 T_A(q)), A
    /// the link, B `relative_to` (the error convention of [`FramePose`](Self::FramePose), with
    /// `T_B^-1 T_A` for the link's pose in the world; a mask on the linear part alone leaves an
    /// orientation with free axes).
    RelativePose {
        /// Index of the link (A).
        link: usize,
        /// Index of the link whose frame the pose is measured in (B), not `link`.
        relative_to: usize,
        /// T_ref, the pose of A in B's frame.
        target: Isometry3<f64>,
        /// Per component of the residual (linear, then angular); 0 drops it.
        mask: [f64; 6],
    },
    /// The position of one link's origin in another's frame: r = mask * (R_B^T (p_A - p_B) - p_ref).
    RelativePosition {
        /// Index of the link (A).
        link: usize,
        /// Index of the link whose frame the position is measured in (B), not `link`.
        relative_to: usize,
        /// p_ref, in B's frame.
        target: Vector3<f64>,
        /// Per component of the residual (B's axes); 0 drops it.
        mask: [f64; 3],
    },
    /// An axis of a link pointing through a point: r = E^T R^T (c - p), the part of the point's
    /// offset from the link's origin (in the link's frame) orthogonal to the axis, in the
    /// orthonormal basis E (3 x 2) of the plane orthogonal to the axis that [`axis_complement`]
    /// gives. Two rows, each with a Jacobian of full rank (a third row along the axis would be
    /// zero to first order); their norm is the point's distance from the axis's line. The point
    /// may lie on either side of the origin along the axis.
    PointAt {
        /// Index of the link.
        link: usize,
        /// The axis, a unit vector in the link's frame.
        axis: Vector3<f64>,
        /// c, the point, in the world.
        point: Vector3<f64>,
    },
    /// A link's origin on a plane: r = n . p - d (one row, the signed distance from the plane).
    Plane {
        /// Index of the link.
        link: usize,
        /// n, the plane's unit normal, in the world.
        normal: Vector3<f64>,
        /// d, the plane's offset along the normal from the world's origin.
        offset: f64,
    },
    /// r = min(q - lower, 0) + max(q - upper, 0) over the bounded joints.
    JointLimits {
        /// A joint's Jacobian row is active within this distance of a limit.
        margin: f64,
    },
    /// r = min(c - lower, 0) + max(c - upper, 0), c the centre of mass.
    ComBox {
        /// Lower corner of the box, in the world.
        lower: Vector3<f64>,
        /// Upper corner of the box, in the world.
        upper: Vector3<f64>,
        /// A coordinate's Jacobian row is active within this distance of a face.
        margin: f64,
    },
    /// r = weights * (q (-) q_nom); `q_nom` None: the solve's nominal posture, with `overrides`
    /// (q index, value) applied.
    Posture {
        /// A fixed nominal posture (length nq), or None.
        q_nom: Option<Vec<f64>>,
        /// Per tangent component (length nv).
        weights: Vec<f64>,
        /// (q index, value) pairs that replace the solve's nominal posture there.
        overrides: Vec<(usize, f64)>,
    },
    /// r = the caller's own ([`CustomTerm::evaluate`]).
    Custom(Arc<dyn CustomTerm>),
}

/// A weighted residual term with its tolerance.
#[derive(Debug, Clone)]
pub struct Term {
    /// Its name, in error messages.
    pub name: String,
    /// What it measures.
    pub kind: TermKind,
    /// Multiplies its residual and Jacobian.
    pub weight: f64,
    /// A primary term is satisfied when its largest absolute unweighted residual component is
    /// below this.
    pub tolerance: f64,
}

/// Solver settings (defaults: the GAN paper and its public code).
#[derive(Debug, Clone)]
pub struct Settings {
    /// Gauss-Newton iterations at most.
    pub max_iterations: usize,
    /// Damping `lambda = mu r^T r + mu_bar` of the primary step, in [0, 1e6].
    pub mu: f64,
    /// Constant part of the damping (the secondary step's whole damping), in [0, 1e6].
    pub mu_bar: f64,
    /// Armijo's sufficient-decrease constant for the primary step.
    pub armijo_c1: f64,
    /// Factor that shrinks a step on each backtrack.
    pub backtrack: f64,
    /// Backtracks of the primary step at most.
    pub max_backtracks: usize,
    /// Clip q to the joint limits at the start and after every step.
    pub clip_to_limits: bool,
    /// Joint limits as bounds of the step (an active set), beyond the paper: a bounded joint at
    /// a limit whose step points out of its range is held there and the step is solved again
    /// over the other joints (primary and posture steps), until no held joint is left out, so
    /// the other joints do the work instead of losing it to the clipping. `false` (default):
    /// the paper's step, clipped (its Table I is reproduced with it).
    pub active_set: bool,
    /// Tries of the secondary step at most.
    pub secondary_backtracks: usize,
    /// The secondary step is kept when the primary cost grows by at most this, in [0, 1e6].
    pub secondary_slack: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            max_iterations: 50,
            mu: 1e-4,
            mu_bar: 1e-6,
            armijo_c1: 1e-4,
            backtrack: 0.2,
            max_backtracks: 20,
            clip_to_limits: true,
            active_set: false,
            secondary_backtracks: 3,
            secondary_slack: 1e-6,
        }
    }
}

impl Settings {
    /// Check every field's range; the error names the first bad field, its value and the range:
    /// `mu`, `mu_bar`, `secondary_slack` in [0, [`MAX_MAGNITUDE`]] (so that the damping
    /// `mu r^T r + mu_bar` stays finite), `armijo_c1`, `backtrack` in (0, 1), any counts and flag
    /// (the counts bound loops that allocate nothing).
    pub fn validate(&self) -> Result<()> {
        let bad = |field: &'static str, msg: String| Err(Error::Settings { field, msg });
        for (field, v) in [("mu", self.mu), ("mu_bar", self.mu_bar), ("secondary_slack", self.secondary_slack)] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(field, format!("must be >= 0 and finite, got {v}"));
            }
            if v > MAX_MAGNITUDE {
                return bad(field, format!("must be at most {MAX_MAGNITUDE:e}, got {v:?}"));
            }
        }
        for (field, v) in [("armijo_c1", self.armijo_c1), ("backtrack", self.backtrack)] {
            if !(v > 0.0 && v < 1.0) {
                return bad(field, format!("must be in (0, 1), got {v}"));
            }
        }
        Ok(())
    }
}

/// The outcome of one solve.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The final configuration.
    pub q: Vec<f64>,
    /// Every primary term is satisfied.
    pub success: bool,
    /// Gauss-Newton iterations spent.
    pub iterations: usize,
    /// Per primary term: largest absolute component of the unweighted residual.
    pub residuals: Vec<f64>,
    /// Wall time of the solve, in seconds.
    pub time_s: f64,
}

/// Kinematic state at one q: link poses, and lazily the centre of mass.
struct State {
    q: Vec<f64>,
    poses: Vec<Isometry3<f64>>,
}

/// A damped Gauss-Newton projector for one task on one robot.
#[derive(Debug, Clone)]
pub struct Projector {
    /// The robot.
    pub model: std::sync::Arc<KinematicModel>,
    /// The constraints, solved together.
    pub primary: Vec<Term>,
    /// Tasks solved in the primary terms' null space (e.g. the posture).
    pub secondary: Vec<Term>,
    /// Solver settings.
    pub settings: Settings,
    /// (q index, v index, lower, upper) of each bounded 1-dof joint.
    bounded: Vec<(usize, usize, f64, f64)>,
}

impl Projector {
    /// A projector, its terms and settings checked against the model. A model whose finite
    /// limits are reversed (lower above upper: only possible by editing its public fields) is
    /// refused ([`Error::Invalid`] naming the joint).
    pub fn new(
        model: std::sync::Arc<KinematicModel>,
        primary: Vec<Term>,
        secondary: Vec<Term>,
        settings: Settings,
    ) -> Result<Projector> {
        if primary.is_empty() {
            return Err(Error::Invalid("a task needs at least one primary term".into()));
        }
        settings.validate()?;
        for t in primary.iter().chain(&secondary) {
            validate(&model, t)?;
        }
        let bounded_joints = model
            .joints
            .iter()
            .filter(|j| j.q_index != usize::MAX && !matches!(j.motion, crate::kinematics::Motion::Continuous { .. } | crate::kinematics::Motion::Fixed))
            .filter(|j| model.lower[j.q_index].is_finite() && model.upper[j.q_index].is_finite());
        let mut bounded = Vec::new();
        for j in bounded_joints {
            let (lo, hi) = (model.lower[j.q_index], model.upper[j.q_index]);
            // a model read from a URDF never has reversed limits, but its fields are public: the
            // clipping (f64::clamp) needs lower <= upper
            if lo > hi {
                return Err(Error::Invalid(format!(
                    "joint '{}': its lower limit {lo:?} is above its upper limit {hi:?} (q index {})",
                    j.name, j.q_index
                )));
            }
            bounded.push((j.q_index, j.v_index, lo, hi));
        }
        Ok(Projector { model, primary, secondary, settings, bounded })
    }

    /// Aim primary term `term` at `target`: 3 numbers for a FramePosition or a RelativePosition,
    /// a row-major 4x4 pose (16 numbers) for a FramePose or a RelativePose. The new target is
    /// checked like [`new`](Self::new) checks terms: finite, a position within [`MAX_MAGNITUDE`], a rotation block orthonormal within
    /// [`ROTATION_TOLERANCE`]; on an error the projector is unchanged.
    pub fn retarget(&mut self, term: usize, target: &[f64]) -> Result<()> {
        check_finite("target", target)?;
        let mut t = self.primary.get(term).ok_or_else(|| Error::Invalid(format!("no primary term {term}")))?.clone();
        if target.len() == 16 {
            let r = Matrix3::from_fn(|i, j| target[4 * i + j]);
            check_rotation(&t.name, "target rotation", &r)?;
        }
        match (&mut t.kind, target.len()) {
            (TermKind::FramePosition { target: tg, .. } | TermKind::RelativePosition { target: tg, .. }, 3) => {
                *tg = Vector3::new(target[0], target[1], target[2])
            }
            (TermKind::FramePose { target: tg, .. } | TermKind::RelativePose { target: tg, .. }, 16) => {
                let r = Matrix3::from_fn(|i, j| target[4 * i + j]);
                *tg = Isometry3::from_parts(
                    nalgebra::Translation3::new(target[3], target[7], target[11]),
                    nalgebra::UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(r)),
                );
            }
            _ => {
                return Err(Error::Invalid(format!(
                    "term '{}' takes no target of {} numbers (FramePosition, RelativePosition: 3; FramePose, RelativePose: 16)",
                    t.name,
                    target.len()
                )))
            }
        }
        validate(&self.model, &t)?;
        self.primary[term] = t;
        Ok(())
    }

    /// A copy of this projector with [`retarget`](Self::retarget) applied.
    pub fn retargeted(&self, term: usize, target: &[f64]) -> Result<Projector> {
        let mut out = self.clone();
        out.retarget(term, target)?;
        Ok(out)
    }

    fn state(&self, q: Vec<f64>) -> State {
        let mut poses = Vec::new();
        self.model.forward_kinematics_unchecked(&q, &mut poses);
        State { q, poses }
    }

    fn dim(&self, t: &Term) -> usize {
        match &t.kind {
            TermKind::FramePose { .. } | TermKind::RelativePose { .. } => 6,
            TermKind::FramePosition { .. } | TermKind::FrameOrientation { .. } | TermKind::ComBox { .. } | TermKind::RelativePosition { .. } => 3,
            TermKind::PointAt { .. } => 2,
            TermKind::Plane { .. } => 1,
            TermKind::JointLimits { .. } => self.bounded.len(),
            TermKind::Posture { .. } => self.model.nv,
            TermKind::Custom(c) => c.dim(),
        }
    }

    /// A custom term's residual and, when `with_jac`, its Jacobian (dim x nv), checked finite.
    fn custom(&self, t: &Term, c: &dyn CustomTerm, s: &State, with_jac: bool) -> TermResult<(DVector<f64>, Option<DMatrix<f64>>)> {
        let (d, nv) = (c.dim(), self.model.nv);
        let fail = |source: TermError| TermFailure { term: t.name.clone(), source };
        let mut r = vec![0.0; d];
        let mut j = if with_jac { vec![0.0; d * nv] } else { Vec::new() };
        c.evaluate(&s.q, &mut r, if with_jac { Some(&mut j) } else { None }).map_err(fail)?;
        check_finite("residual", &r).map_err(|e| fail(e.into()))?;
        check_finite("Jacobian (row-major)", &j).map_err(|e| fail(e.into()))?;
        Ok((DVector::from_vec(r), with_jac.then(|| DMatrix::from_row_slice(d, nv, &j))))
    }

    /// Unweighted residual and, when `with_jac`, Jacobian of a term: one evaluation of a custom term.
    fn eval(&self, t: &Term, s: &State, q_nom: &[f64], with_jac: bool, frame_jac: &mut DMatrix<f64>) -> TermResult<(DVector<f64>, Option<DMatrix<f64>>)> {
        if let TermKind::Custom(c) = &t.kind {
            return self.custom(t, c.as_ref(), s, with_jac);
        }
        let r = self.residual(t, s, q_nom);
        Ok((r, with_jac.then(|| self.jacobian(t, s, q_nom, frame_jac))))
    }

    /// Unweighted residual of a built-in term (a custom one goes through [`eval`](Self::eval)).
    fn residual(&self, t: &Term, s: &State, q_nom: &[f64]) -> DVector<f64> {
        match &t.kind {
            TermKind::FramePose { link, target, mask } => {
                let r = log6(&(target.inverse() * s.poses[*link]));
                DVector::from_iterator(6, (0..6).map(|k| mask[k] * r[k]))
            }
            TermKind::FramePosition { link, target, mask } => {
                let d = s.poses[*link].translation.vector - target;
                DVector::from_iterator(3, (0..3).map(|k| mask[k] * d[k]))
            }
            TermKind::FrameOrientation { link, target, offset, mask } => {
                let rel = target.transpose() * s.poses[*link].rotation.to_rotation_matrix().into_inner() * offset;
                let (w, _) = log3(&rel);
                DVector::from_iterator(3, (0..3).map(|k| mask[k] * w[k]))
            }
            TermKind::RelativePose { link, relative_to, target, mask } => {
                let r = log6(&(target.inverse() * s.poses[*relative_to].inverse() * s.poses[*link]));
                DVector::from_iterator(6, (0..6).map(|k| mask[k] * r[k]))
            }
            TermKind::RelativePosition { link, relative_to, target, mask } => {
                let d = relative_position(&s.poses[*link], &s.poses[*relative_to]) - target;
                DVector::from_iterator(3, (0..3).map(|k| mask[k] * d[k]))
            }
            TermKind::PointAt { link, axis, point } => {
                let d = s.poses[*link].rotation.inverse_transform_vector(&(point - s.poses[*link].translation.vector));
                let (e1, e2) = axis_complement(axis);
                DVector::from_vec(vec![e1.dot(&d), e2.dot(&d)])
            }
            TermKind::Plane { link, normal, offset } => DVector::from_element(1, normal.dot(&s.poses[*link].translation.vector) - offset),
            TermKind::JointLimits { .. } => DVector::from_iterator(
                self.bounded.len(),
                self.bounded.iter().map(|&(iq, _, lo, hi)| (s.q[iq] - lo).min(0.0) + (s.q[iq] - hi).max(0.0)),
            ),
            TermKind::ComBox { lower, upper, .. } => {
                let c = self.model.center_of_mass(&s.poses, None);
                DVector::from_iterator(3, (0..3).map(|k| (c[k] - lower[k]).min(0.0) + (c[k] - upper[k]).max(0.0)))
            }
            TermKind::Posture { weights, .. } => {
                let mut d = vec![0.0; self.model.nv];
                self.model.difference(q_nom, &s.q, &mut d);
                DVector::from_iterator(self.model.nv, d.iter().zip(weights).map(|(a, w)| a * w))
            }
            TermKind::Custom(_) => unreachable!("custom terms are evaluated by Projector::custom"),
        }
    }

    /// Jacobian (dim x nv) of a built-in term's unweighted residual.
    fn jacobian(&self, t: &Term, s: &State, q_nom: &[f64], frame_jac: &mut DMatrix<f64>) -> DMatrix<f64> {
        let nv = self.model.nv;
        match &t.kind {
            TermKind::FramePose { link, target, mask } => {
                self.model.frame_jacobian_local(&s.poses, *link, frame_jac);
                let jl = jlog6(&(target.inverse() * s.poses[*link]));
                let m = Matrix6::from_fn(|r, c| jl[(r, c)] * mask[r]);
                small_times_columns(&m, frame_jac, 0)
            }
            TermKind::FramePosition { link, mask, .. } => {
                self.model.frame_jacobian_local(&s.poses, *link, frame_jac);
                let rot = s.poses[*link].rotation.to_rotation_matrix().into_inner();
                let m = Matrix3::from_fn(|r, c| rot[(r, c)] * mask[r]);
                small_times_columns(&m, frame_jac, 0)
            }
            TermKind::FrameOrientation { link, target, offset, mask } => {
                self.model.frame_jacobian_local(&s.poses, *link, frame_jac);
                let rel = target.transpose() * s.poses[*link].rotation.to_rotation_matrix().into_inner() * offset;
                let (w, theta) = log3(&rel);
                let m = jlog3(&w, theta) * offset.transpose();
                let m = Matrix3::from_fn(|r, c| m[(r, c)] * mask[r]);
                small_times_columns(&m, frame_jac, 3)
            }
            TermKind::RelativePose { link, relative_to, target, mask } => {
                // the body velocity of T_rel = T_B^-1 T_A is V_A - Ad(T_rel^-1) V_B (V_A, V_B the
                // links' body velocities, `frame_jacobian_local`); log6's derivative maps it
                let rel = s.poses[*relative_to].inverse() * s.poses[*link];
                let jl = jlog6(&(target.inverse() * rel));
                let ma = Matrix6::from_fn(|r, c| jl[(r, c)] * mask[r]);
                let mb = -ma * action(&rel.inverse());
                self.two_frames(s, *link, &ma, *relative_to, &mb, frame_jac)
            }
            TermKind::RelativePosition { link, relative_to, mask, .. } => {
                // d/dt R_B^T (p_A - p_B) = R_rel v_A - v_B + [p_rel]x w_B (body velocities)
                let rel = s.poses[*relative_to].inverse() * s.poses[*link];
                let r_rel = rel.rotation.to_rotation_matrix().into_inner();
                let px = skew(&rel.translation.vector);
                let ma = SMatrix::<f64, 3, 6>::from_fn(|r, c| if c < 3 { r_rel[(r, c)] * mask[r] } else { 0.0 });
                let mb = SMatrix::<f64, 3, 6>::from_fn(|r, c| mask[r] * if c >= 3 { px[(r, c - 3)] } else if r == c { -1.0 } else { 0.0 });
                self.two_frames(s, *link, &ma, *relative_to, &mb, frame_jac)
            }
            TermKind::PointAt { link, axis, point } => {
                // d = R^T (c - p) moves as [d]x w - v (the link's body velocity)
                self.model.frame_jacobian_local(&s.poses, *link, frame_jac);
                let d = s.poses[*link].rotation.inverse_transform_vector(&(point - s.poses[*link].translation.vector));
                let dx = skew(&d);
                let (e1, e2) = axis_complement(axis);
                let m = SMatrix::<f64, 2, 6>::from_fn(|r, c| {
                    let e = if r == 0 { &e1 } else { &e2 };
                    if c < 3 { -e[c] } else { (0..3).map(|k| e[k] * dx[(k, c - 3)]).sum() }
                });
                rows_times_columns(&m, frame_jac, None)
            }
            TermKind::Plane { link, normal, .. } => {
                // d/dt n . p = n^T R v
                self.model.frame_jacobian_local(&s.poses, *link, frame_jac);
                let nr = s.poses[*link].rotation.inverse_transform_vector(normal);
                let m = SMatrix::<f64, 1, 6>::from_fn(|_, c| if c < 3 { nr[c] } else { 0.0 });
                rows_times_columns(&m, frame_jac, None)
            }
            TermKind::JointLimits { margin } => {
                let mut j = DMatrix::zeros(self.bounded.len(), nv);
                for (row, &(iq, iv, lo, hi)) in self.bounded.iter().enumerate() {
                    if within_margin(s.q[iq], *margin, lo, hi) {
                        j[(row, iv)] = 1.0;
                    }
                }
                j
            }
            TermKind::ComBox { lower, upper, margin } => {
                let mut jc = DMatrix::zeros(3, nv);
                let c = self.model.center_of_mass(&s.poses, Some(&mut jc));
                for k in 0..3 {
                    if !(c[k] - margin < lower[k] || c[k] + margin > upper[k]) {
                        jc.row_mut(k).fill(0.0);
                    }
                }
                jc
            }
            TermKind::Posture { weights, .. } => {
                let mut j = self.model.difference_jacobian(q_nom, &s.q);
                for (r, w) in weights.iter().enumerate() {
                    j.row_mut(r).scale_mut(*w);
                }
                j
            }
            TermKind::Custom(_) => unreachable!("custom terms are evaluated by Projector::custom"),
        }
    }

    /// `ma J_A + mb J_B`, `J_A`, `J_B` the local frame Jacobians (6 x nv) of links `a` and `b`
    /// (`frame_jac`, the caller's buffer, holds `J_A`).
    fn two_frames<const D: usize>(
        &self,
        s: &State,
        a: usize,
        ma: &SMatrix<f64, D, 6>,
        b: usize,
        mb: &SMatrix<f64, D, 6>,
        frame_jac: &mut DMatrix<f64>,
    ) -> DMatrix<f64> {
        let mut jb = DMatrix::zeros(6, self.model.nv);
        self.model.frame_jacobian_local(&s.poses, b, &mut jb);
        self.model.frame_jacobian_local(&s.poses, a, frame_jac);
        rows_times_columns(ma, frame_jac, Some((mb, &jb)))
    }

    /// The terms' unweighted residuals and, when `with_jac`, their weighted Jacobians stacked.
    fn stack(&self, terms: &[Term], s: &State, noms: &[Vec<f64>], with_jac: bool) -> TermResult<Stacked> {
        let nv = self.model.nv;
        // only a Jacobian needs the frame Jacobian's buffer (an empty matrix allocates nothing)
        let mut frame_jac = if with_jac { DMatrix::zeros(6, nv) } else { DMatrix::zeros(0, 0) };
        let mut raws = Vec::with_capacity(terms.len());
        let mut jacs = Vec::new();
        for (t, n) in terms.iter().zip(noms) {
            let (r, j) = self.eval(t, s, n, with_jac, &mut frame_jac)?;
            raws.push(r);
            jacs.extend(j);
        }
        if !with_jac {
            return Ok((raws, None));
        }
        let rows: usize = jacs.iter().map(|j| j.nrows()).sum();
        let mut j = DMatrix::zeros(rows, nv);
        let mut r0 = 0;
        for (t, jt) in terms.iter().zip(jacs) {
            let d = jt.nrows();
            j.view_mut((r0, 0), (d, nv)).copy_from(&(jt * t.weight));
            r0 += d;
        }
        Ok((raws, Some(j)))
    }

    /// The weighted residual rows (of `raws`, the terms' residuals at `s`) and weighted Jacobian
    /// rows of `terms` at `s`, without the rows whose residual and Jacobian row are both zero
    /// (they change nothing in a least-squares step).
    fn active_rows(
        &self,
        terms: &[Term],
        s: &State,
        noms: &[Vec<f64>],
        raws: &[DVector<f64>],
        frame_jac: &mut DMatrix<f64>,
    ) -> TermResult<(DVector<f64>, DMatrix<f64>)> {
        let nv = self.model.nv;
        let mut jacs = Vec::with_capacity(terms.len());
        // per term, the indices of the rows kept (a column-major scan of its Jacobian)
        let mut kept: Vec<Vec<usize>> = Vec::with_capacity(terms.len());
        for ((t, n), r) in terms.iter().zip(noms).zip(raws) {
            if let TermKind::JointLimits { margin } = t.kind {
                // one unit entry per row at most: the rows kept are listed without the dense
                // Jacobian (bounded joints x nv, nearly all zero), which the copy below writes
                let rows = self.bounded.iter().enumerate().filter(|&(row, &(iq, _, lo, hi))| {
                    r[row] != 0.0 || within_margin(s.q[iq], margin, lo, hi)
                });
                kept.push(rows.map(|(row, _)| row).collect());
                jacs.push(DMatrix::zeros(0, 0));
                continue;
            }
            if let TermKind::Posture { weights, .. } = &t.kind {
                // row i of its Jacobian is weights[i] times row i of the difference Jacobian (a
                // unit row, or a row of the free-flyer's invertible block), zero exactly when
                // weights[i] is: the rows kept are listed, and written by the copy below, without
                // the dense nv x nv Jacobian (a residual that is not finite is kept, as below)
                kept.push((0..r.len()).filter(|&i| weights[i] != 0.0 || r[i] != 0.0).collect());
                jacs.push(DMatrix::zeros(0, 0));
                continue;
            }
            let j = match &t.kind {
                TermKind::Custom(_) => self.eval(t, s, n, true, frame_jac)?.1.unwrap_or_else(|| unreachable!("eval with_jac returns a Jacobian")),
                _ => self.jacobian(t, s, n, frame_jac),
            };
            // the sum of a row's absolute values is 0 exactly when the row is (NaN stays NaN,
            // kept); summed over the contiguous columns, which vectorises
            let mut mass: Vec<f64> = r.iter().map(|x| x.abs()).collect();
            if !mass.is_empty() {
                for col in j.as_slice().chunks_exact(mass.len()) {
                    mass.iter_mut().zip(col).for_each(|(m, x)| *m += x.abs());
                }
            }
            jacs.push(j);
            kept.push((0..mass.len()).filter(|&i| mass[i] != 0.0).collect());
        }
        let rows = kept.iter().map(Vec::len).sum();
        let mut r1 = DVector::zeros(rows);
        let mut j1 = DMatrix::zeros(rows, nv);
        let mut k0 = 0;
        for ((((t, n), r), j), kept) in terms.iter().zip(noms).zip(raws).zip(&jacs).zip(&kept) {
            for (dst, &i) in r1.as_mut_slice()[k0..k0 + kept.len()].iter_mut().zip(kept) {
                *dst = t.weight * r[i];
            }
            if let TermKind::JointLimits { margin } = t.kind {
                // the row's entry is 1 at the joint's column when it is within the margin (as
                // `jacobian` writes it), else the row is kept for its residual alone
                for (k, &i) in kept.iter().enumerate() {
                    let (iq, iv, lo, hi) = self.bounded[i];
                    if within_margin(s.q[iq], margin, lo, hi) {
                        j1[(k0 + k, iv)] = t.weight;
                    }
                }
                k0 += kept.len();
                continue;
            }
            if let TermKind::Posture { weights, .. } = &t.kind {
                // the entries `jacobian` writes for these rows: weights[i] on the diagonal, or
                // weights[i] times the free-flyer block's row
                let base = if kept.first().is_some_and(|&i| i < 6) { self.model.difference_jacobian_base(n, &s.q) } else { None };
                for (k, &i) in kept.iter().enumerate() {
                    match &base {
                        Some(jb) if i < 6 => (0..6).for_each(|c| j1[(k0 + k, c)] = t.weight * (jb[(i, c)] * weights[i])),
                        _ => j1[(k0 + k, i)] = t.weight * weights[i],
                    }
                }
                k0 += kept.len();
                continue;
            }
            for c in 0..nv {
                let (src, col) = (j.column(c), &mut j1.as_mut_slice()[c * rows..(c + 1) * rows]);
                for (dst, &i) in col[k0..k0 + kept.len()].iter_mut().zip(kept) {
                    *dst = t.weight * src[i];
                }
            }
            k0 += kept.len();
        }
        Ok((r1, j1))
    }

    fn weighted(terms: &[Term], raws: &[DVector<f64>]) -> DVector<f64> {
        let n: usize = raws.iter().map(|r| r.len()).sum();
        let mut out = DVector::zeros(n);
        let mut i = 0;
        for (t, r) in terms.iter().zip(raws) {
            for x in r.iter() {
                out[i] = t.weight * x;
                i += 1;
            }
        }
        out
    }

    fn cost(&self, raws: &[DVector<f64>]) -> f64 {
        self.primary.iter().zip(raws).map(|(t, r)| t.weight * t.weight * r.norm_squared()).sum()
    }

    fn satisfied(&self, raws: &[DVector<f64>]) -> bool {
        self.primary.iter().zip(raws).all(|(t, r)| r.len() == 0 || (r.iter().all(|x| x.is_finite()) && r.amax() < t.tolerance))
    }

    /// The active set of [`Settings::active_set`]: while the step `-dq1` moves a bounded joint
    /// that sits at a limit out of its range, hold that joint (zero its Jacobian column, so its
    /// step component is 0) and solve the step again over the others. Returns the held joints'
    /// tangent indices (at most one round per bounded joint).
    fn hold_at_limits(&self, q: &[f64], lam: f64, r1: &DVector<f64>, j1: &mut DMatrix<f64>, pinv: &mut DampedPinv, dq1: &mut DVector<f64>) -> Vec<usize> {
        let mut held: Vec<usize> = Vec::new();
        loop {
            let before = held.len();
            for &(iq, iv, lo, hi) in &self.bounded {
                let v = -dq1[iv];
                let out = (q[iq] <= lo + AT_LIMIT && v < 0.0) || (q[iq] >= hi - AT_LIMIT && v > 0.0);
                if out && !held.contains(&iv) {
                    held.push(iv);
                    j1.column_mut(iv).fill(0.0);
                }
            }
            if held.len() == before {
                return held;
            }
            *pinv = DampedPinv::new(j1, lam);
            *dq1 = pinv.apply(j1, r1);
        }
    }

    fn step(&self, q: &[f64], dq: &DVector<f64>, alpha: f64) -> Vec<f64> {
        let v: Vec<f64> = dq.iter().map(|x| -alpha * x).collect();
        let mut out = vec![0.0; q.len()];
        self.model.integrate(q, &v, &mut out);
        if self.settings.clip_to_limits {
            for &(iq, _, lo, hi) in &self.bounded {
                out[iq] = out[iq].clamp(lo, hi);
            }
        }
        out
    }

    /// The primary terms' weighted residuals stacked (length [`primary_dim`](Self::primary_dim))
    /// and, when `with_jacobian`, their weighted Jacobian (rows x nv, tangent space), at `q`
    /// (checked like [`solve`](Self::solve)); a Posture term's nominal is `q` itself. The costs a
    /// learned sampler is trained with (`genplan.gan.costs`) are these residuals.
    /// A failing custom term's error becomes a core [`Error`] ([`TermFailure::into_error`]);
    /// [`try_primary_residuals`](Self::try_primary_residuals) returns it intact.
    pub fn primary_residuals(&self, q: &[f64], with_jacobian: bool) -> Result<(DVector<f64>, Option<DMatrix<f64>>)> {
        self.try_primary_residuals(q, with_jacobian).map_err(Error::from)
    }

    /// [`primary_residuals`](Self::primary_residuals), a custom term's failure returned intact.
    pub fn try_primary_residuals(&self, q: &[f64], with_jacobian: bool) -> std::result::Result<(DVector<f64>, Option<DMatrix<f64>>), SolveError> {
        self.model.check_configuration(q)?;
        let nominal = nominals(&self.primary, q);
        let s = self.state(q.to_vec());
        let (raws, j) = self.stack(&self.primary, &s, &nominal, with_jacobian)?;
        Ok((Self::weighted(&self.primary, &raws), j))
    }

    /// The task holds a [`TermKind::Custom`] term (primary or secondary).
    pub fn has_custom_terms(&self) -> bool {
        self.primary.iter().chain(&self.secondary).any(|t| matches!(t.kind, TermKind::Custom(_)))
    }

    /// Rows of [`primary_residuals`](Self::primary_residuals): the primary terms' residual sizes summed.
    pub fn primary_dim(&self) -> usize {
        self.primary.iter().map(|t| self.dim(t)).sum()
    }

    /// Per row of `qs` (rows of `nq` numbers) and primary term, the term's residual size at that
    /// row ([`residual_size`]: what [`Outcome::residuals`] reports and the terms' tolerances
    /// bound), row after row (rows x primary terms): the residual-only check of many
    /// configurations, such as a timed trajectory's samples, with no solver step, no clipping
    /// and no Jacobian (one forward kinematics a row). Every row is checked like
    /// [`solve`](Self::solve) before any is evaluated. Rows run on rayon's threads when
    /// `parallel`; a failing custom term's error is returned intact (the first one met).
    pub fn try_residual_sizes(&self, qs: &[f64], parallel: bool) -> std::result::Result<Vec<f64>, SolveError> {
        use rayon::prelude::*;
        let nq = self.model.nq.max(1);
        if qs.len() % nq != 0 {
            return Err(Error::Invalid(format!("q: {} numbers are not rows of {nq}", qs.len())).into());
        }
        for q in qs.chunks(nq) {
            self.model.check_configuration(q)?;
        }
        let terms = self.primary.len();
        let mut out = vec![0.0; qs.len() / nq * terms];
        if terms == 0 {
            return Ok(out);
        }
        // only a Posture term reads its nominal (the row itself, or its own): the others are
        // given the row, with no copy per term
        let postures = self.primary.iter().any(|t| matches!(t.kind, TermKind::Posture { .. }));
        let empty = || State { q: Vec::with_capacity(nq), poses: Vec::new() };
        // one row, in a state kept across rows (no allocation for q and the poses), each term's
        // size into `sizes`
        let row = |s: &mut State, q: &[f64], sizes: &mut [f64]| -> TermResult<()> {
            s.q.clear();
            s.q.extend_from_slice(q);
            self.model.forward_kinematics_unchecked(q, &mut s.poses);
            let nominal = if postures { nominals(&self.primary, q) } else { Vec::new() };
            let mut no_jacobian = DMatrix::zeros(0, 0);
            for (i, (t, size)) in self.primary.iter().zip(sizes.iter_mut()).enumerate() {
                let n = nominal.get(i).map_or(q, Vec::as_slice);
                *size = residual_size(&self.eval(t, s, n, false, &mut no_jacobian)?.0);
            }
            Ok(())
        };
        if parallel {
            out.par_chunks_mut(terms).zip(qs.par_chunks(nq)).try_for_each_init(empty, |s, (sizes, q)| row(s, q, sizes))?;
        } else {
            let mut s = empty();
            for (sizes, q) in out.chunks_mut(terms).zip(qs.chunks(nq)) {
                row(&mut s, q, sizes)?;
            }
        }
        Ok(out)
    }

    /// Project `q0`; the posture task regularises around `q_nom` (default: `q0`). The answer is
    /// finite ([`solve_unchecked`](Self::solve_unchecked)). A failing custom term's error becomes
    /// a core [`Error`] ([`TermFailure::into_error`]); [`try_solve`](Self::try_solve) returns it
    /// intact.
    pub fn solve(&self, q0: &[f64], q_nom: Option<&[f64]>) -> Result<Outcome> {
        self.try_solve(q0, q_nom).map_err(Error::from)
    }

    /// [`solve`](Self::solve), a custom term's failure returned intact ([`SolveError::Term`]).
    pub fn try_solve(&self, q0: &[f64], q_nom: Option<&[f64]>) -> std::result::Result<Outcome, SolveError> {
        self.model.check_configuration(q0)?;
        if let Some(n) = q_nom {
            check_vector("q_nom", n, self.model.nq)?;
            // a configuration like q0 (joint values bounded: finding URDF-7)
            self.model.check_configuration(n).map_err(|e| Error::Invalid(format!("q_nom: {e}")))?;
        }
        Ok(self.try_solve_unchecked(q0, q_nom)?)
    }

    /// [`solve`](Self::solve) without input checks. Every iterate is checked: should one not be
    /// finite (the arithmetic overflowed, e.g. from an extreme start or nominal configuration),
    /// the solve stops there and answers the last finite configuration, unsuccessful; a residual
    /// that cannot be computed is reported as +inf. So the answer is finite whenever `q0` is.
    /// Should a custom term fail, the answer is `q0` (clipped to the limits), unsuccessful, every
    /// residual +inf, and the error is dropped: a task with custom terms is better solved with
    /// [`try_solve_unchecked`](Self::try_solve_unchecked).
    pub fn solve_unchecked(&self, q0: &[f64], q_nom: Option<&[f64]>) -> Outcome {
        let t0 = Instant::now();
        self.try_solve_unchecked(q0, q_nom).unwrap_or_else(|_| {
            let mut q = q0.to_vec();
            if self.settings.clip_to_limits {
                for &(iq, _, lo, hi) in &self.bounded {
                    q[iq] = q[iq].clamp(lo, hi);
                }
            }
            Outcome {
                q,
                success: false,
                iterations: 0,
                residuals: vec![f64::INFINITY; self.primary.len()],
                time_s: t0.elapsed().as_secs_f64(),
            }
        })
    }

    /// [`solve_unchecked`](Self::solve_unchecked), except that a custom term's failure stops the
    /// solve and is returned (the first one; no outcome).
    pub fn try_solve_unchecked(&self, q0: &[f64], q_nom: Option<&[f64]>) -> TermResult<Outcome> {
        let t0 = Instant::now();
        let st = &self.settings;
        let nv = self.model.nv;
        let mut q = q0.to_vec();
        if st.clip_to_limits {
            for &(iq, _, lo, hi) in &self.bounded {
                q[iq] = q[iq].clamp(lo, hi);
            }
        }
        let nominal: Vec<f64> = q_nom.map(<[f64]>::to_vec).unwrap_or_else(|| q.clone());
        let primary_nominal = nominals(&self.primary, &nominal);
        let secondary_nominal = nominals(&self.secondary, &nominal);
        let mut iterations = 0;
        // the iterate: its configuration (`s.q`) and link poses
        let mut s = self.state(q);
        // Residuals first: a configuration already on the manifold (most states along a planner's
        // edge) costs one forward kinematics, no Jacobian.
        let (mut raws, _) = self.stack(&self.primary, &s, &primary_nominal, false)?;
        let mut frame_jac = DMatrix::zeros(6, nv);
        while !self.satisfied(&raws) && iterations < st.max_iterations {
            // Rows with a zero residual and a zero Jacobian (inactive limits, CoM inside its box,
            // posture rows of weight 0) change nothing in the step: only the others are stacked.
            let (r1, mut j1m) = self.active_rows(&self.primary, &s, &primary_nominal, &raws, &mut frame_jac)?;
            let c0 = r1.norm_squared();
            let lam = st.mu * c0 + st.mu_bar;
            let mut pinv = DampedPinv::new(&j1m, lam);
            let mut dq1 = pinv.apply(&j1m, &r1);
            let held = if st.active_set { self.hold_at_limits(&s.q, lam, &r1, &mut j1m, &mut pinv, &mut dq1) } else { Vec::new() };
            let slope = 2.0 * r1.dot(&(&j1m * &dq1));
            let mut alpha = 1.0;
            // the iterate after the step, its state and residuals (those of the last try)
            let mut next = None;
            let mut c = f64::INFINITY;
            for _ in 0..st.max_backtracks {
                let q_try = self.step(&s.q, &dq1, alpha);
                let sn = self.state(q_try);
                let (rn, _) = self.stack(&self.primary, &sn, &primary_nominal, false)?;
                c = self.cost(&rn);
                next = Some((sn, rn));
                if c <= c0 - st.armijo_c1 * alpha * slope {
                    break;
                }
                alpha *= st.backtrack;
            }
            let (mut s_new, mut raws_new) = match next {
                Some(n) => n,
                // no backtrack allowed: the step is not taken
                None => {
                    let sn = self.state(s.q.clone());
                    let rn = raws.clone();
                    (sn, rn)
                }
            };
            if !self.secondary.is_empty() {
                let mut r2_parts = Vec::new();
                let mut j2 = DMatrix::zeros(0, nv);
                for (t, nom) in self.secondary.iter().zip(&secondary_nominal) {
                    let (r, jt) = self.eval(t, &s, nom, true, &mut frame_jac)?;
                    r2_parts.push(r * t.weight);
                    let Some(jt) = jt else { unreachable!("eval with_jac returns a Jacobian") };
                    let mut jt = jt * t.weight;
                    for &iv in &held {
                        jt.column_mut(iv).fill(0.0);
                    }
                    let rows = j2.nrows();
                    j2 = j2.insert_rows(rows, jt.nrows(), 0.0);
                    j2.view_mut((rows, 0), (jt.nrows(), nv)).copy_from(&jt);
                }
                let r2 = DVector::from_iterator(
                    r2_parts.iter().map(|r| r.len()).sum(),
                    r2_parts.iter().flat_map(|r| r.iter().copied()),
                );
                let n1 = pinv.null_space(&j1m);
                let j2n = sparse_mul(&j2, &n1);
                let rhs = r2 - &j2 * (&dq1 * alpha);
                let dq2 = &n1 * DampedPinv::new(&j2n, st.mu_bar).apply(&j2n, &rhs);
                let mut alpha2 = 1.0;
                for _ in 0..st.secondary_backtracks {
                    let q_try = self.step(&s_new.q, &dq2, alpha2);
                    let sn = self.state(q_try);
                    let (rn, _) = self.stack(&self.primary, &sn, &primary_nominal, false)?;
                    if self.cost(&rn) <= c + st.secondary_slack {
                        (s_new, raws_new) = (sn, rn);
                        break;
                    }
                    alpha2 *= st.backtrack;
                }
            }
            iterations += 1;
            if s_new.q.iter().any(|x| !x.is_finite()) {
                // the step overflowed: stop at the last finite iterate (`s`, `raws`), unsuccessful
                break;
            }
            s = s_new;
            raws = raws_new;
        }
        let residuals = raws.iter().map(residual_size).collect();
        Ok(Outcome {
            success: self.satisfied(&raws),
            q: s.q,
            iterations,
            residuals,
            time_s: t0.elapsed().as_secs_f64(),
        })
    }
}

/// A bounded joint within this of a limit (rad or m) is at it, for [`Settings::active_set`]
/// (the clipping puts it exactly there).
const AT_LIMIT: f64 = 1e-9;

/// The result of a step that evaluates terms: a custom term may fail.
pub type TermResult<T> = std::result::Result<T, TermFailure>;

/// Terms' unweighted residuals, and their weighted Jacobians stacked when asked for.
type Stacked = (Vec<DVector<f64>>, Option<DMatrix<f64>>);

/// The nominal posture of each term: a Posture's own `q_nom`, else the solve's nominal with
/// the term's overrides applied.
/// A term's residual size: the largest absolute component of its unweighted residual `r` (0
/// for a term of no rows, +inf when a component is NaN), the measure its tolerance bounds.
pub fn residual_size(r: &DVector<f64>) -> f64 {
    match r.len() {
        0 => 0.0,
        _ if r.iter().any(|x| x.is_nan()) => f64::INFINITY,
        _ => r.amax(),
    }
}

fn nominals(terms: &[Term], nominal: &[f64]) -> Vec<Vec<f64>> {
    terms
        .iter()
        .map(|t| match &t.kind {
            TermKind::Posture { q_nom: Some(n), .. } => n.clone(),
            TermKind::Posture { q_nom: None, overrides, .. } => {
                let mut n = nominal.to_vec();
                for &(iq, v) in overrides {
                    n[iq] = v;
                }
                n
            }
            _ => nominal.to_vec(),
        })
        .collect()
}

/// The damped pseudo-inverse of a Jacobian J, `J^+ = J^T (J J^T + lambda I)^-1` (the
/// normal-equation form `(J^T J + lambda I)^-1 J^T` when J is tall), by one Cholesky factorisation
/// of the smaller damped Gram matrix, shared by the step ([`apply`](Self::apply)) and the null
/// space ([`null_space`](Self::null_space)). The pseudo-inverse itself is never formed (a solve
/// with one right-hand side per joint cost a fifth of a Talos iteration). When the damped matrix
/// is not positive definite (lambda = 0 and J rank-deficient), `J^+` is 0.
struct DampedPinv {
    ch: Option<nalgebra::linalg::Cholesky<f64, nalgebra::Dyn>>,
    wide: bool,
}

impl DampedPinv {
    fn new(j: &DMatrix<f64>, lam: f64) -> DampedPinv {
        let wide = j.nrows() <= j.ncols();
        DampedPinv { ch: damped_gram(j, lam, wide).cholesky(), wide }
    }

    /// `J^+ v` (`j` the matrix this was made from).
    fn apply(&self, j: &DMatrix<f64>, v: &DVector<f64>) -> DVector<f64> {
        match (&self.ch, self.wide) {
            (Some(ch), true) => j.tr_mul(&ch.solve(v)),
            (Some(ch), false) => ch.solve(&j.tr_mul(v)),
            (None, _) => DVector::zeros(j.ncols()),
        }
    }

    /// `I - J^+ J`, the secondary step's null-space projector (`j` the matrix this was made
    /// from). For a wide J it is `I - B^T B` with `B = L^-1 J`, `L` the Cholesky factor, by
    /// forward substitution on the columns of `J^T` (contiguous).
    fn null_space(&self, j: &DMatrix<f64>) -> DMatrix<f64> {
        let (m, n) = j.shape();
        let Some(ch) = &self.ch else { return DMatrix::identity(n, n) };
        if !self.wide {
            return DMatrix::identity(n, n) - ch.solve(&j.transpose()) * j;
        }
        let l = ch.l_dirty();
        // column i of bt = (row i of J - sum over k < i of L[i, k] row k of B) / L[i, i]
        let mut bt = j.transpose();
        for i in 0..m {
            for k in 0..i {
                let lik = l[(i, k)];
                if lik != 0.0 {
                    let (done, rest) = bt.as_mut_slice().split_at_mut(i * n);
                    let (bk, bi) = (&done[k * n..(k + 1) * n], &mut rest[..n]);
                    bi.iter_mut().zip(bk).for_each(|(x, y)| *x -= lik * y);
                }
            }
            let d = l[(i, i)];
            bt.column_mut(i).iter_mut().for_each(|x| *x /= d);
        }
        let mut out = DMatrix::identity(n, n);
        out.gemm(-1.0, &bt, &bt.transpose(), 1.0);
        out
    }
}

/// The damped Gram matrix of `j`: `J J^T + lambda I` when `wide`, else `J^T J + lambda I`.
/// A primary step's J is small and mostly zeros (Talos: about 20 x 34, a sole's rows touching
/// the base and one leg, a posture row one joint), and a general matrix product spent its time
/// packing and allocating there (with the posture rows of `active_rows`, a Talos edge state went
/// from 43.4 to 33.2 us: benches/results/criterion_ab_gram.json): a wide J with at most a quarter
/// of its entries non-zero adds, per column, the outer product of that column's non-zero entries
/// (the lower triangle, then mirrored). A denser J (the posture step's, nv x nv) goes through
/// the general product, whose vectorised kernel wins there.
fn damped_gram(j: &DMatrix<f64>, lam: f64, wide: bool) -> DMatrix<f64> {
    let (m, n) = j.shape();
    let js = j.as_slice();
    let sparse = wide && 4 * js.iter().filter(|&&x| x != 0.0).count() <= m * n;
    if !sparse {
        let mut a = if wide { j * j.transpose() } else { j.tr_mul(j) };
        for k in 0..a.nrows() {
            a[(k, k)] += lam;
        }
        return a;
    }
    let mut a = DMatrix::zeros(m, m);
    let out = a.as_mut_slice();
    // the non-zero entries of one column: (row, value), rows ascending
    let mut nz: Vec<(usize, f64)> = Vec::with_capacity(m);
    for col in js.chunks_exact(m.max(1)).take(n) {
        nz.clear();
        nz.extend(col.iter().enumerate().filter(|&(_, &x)| x != 0.0).map(|(i, &x)| (i, x)));
        for (p, &(k, xk)) in nz.iter().enumerate() {
            // column k of the lower triangle: rows i >= k gain J[i, c] J[k, c]
            for &(i, xi) in &nz[p..] {
                out[k * m + i] += xi * xk;
            }
        }
    }
    for k in 0..m {
        out[k * m + k] += lam;
        for i in k + 1..m {
            out[i * m + k] = out[k * m + i];
        }
    }
    a
}

/// A joint at `q` is within `margin` of a limit of `[lo, hi]`: its `JointLimits` row is active
/// (a Jacobian entry of 1; the residual is non-zero only beyond the limit).
#[inline]
fn within_margin(q: f64, margin: f64, lo: f64, hi: f64) -> bool {
    q - margin < lo || q + margin > hi
}

/// `m * rows(r0 .. r0 + D)` of the 6 x nv `frame_jac`, column by column with fixed-size
/// products (a general matrix product of such small factors spent most of its time packing).
fn small_times_columns<const D: usize>(m: &SMatrix<f64, D, D>, frame_jac: &DMatrix<f64>, r0: usize) -> DMatrix<f64> {
    let nv = frame_jac.ncols();
    let mut out = DMatrix::zeros(D, nv);
    for c in 0..nv {
        let col = frame_jac.fixed_view::<D, 1>(r0, c);
        out.fixed_view_mut::<D, 1>(0, c).copy_from(&(m * col));
    }
    out
}

/// `ma * ja` (+ `mb * jb`), `ja`, `jb` 6 x nv frame Jacobians, column by column with fixed-size
/// products (as [`small_times_columns`]).
fn rows_times_columns<const D: usize>(ma: &SMatrix<f64, D, 6>, ja: &DMatrix<f64>, b: Option<(&SMatrix<f64, D, 6>, &DMatrix<f64>)>) -> DMatrix<f64> {
    let nv = ja.ncols();
    let mut out = DMatrix::zeros(D, nv);
    for c in 0..nv {
        let mut col = ma * ja.fixed_view::<6, 1>(0, c);
        if let Some((mb, jb)) = b {
            col += mb * jb.fixed_view::<6, 1>(0, c);
        }
        out.fixed_view_mut::<D, 1>(0, c).copy_from(&col);
    }
    out
}

/// The position of `a`'s origin in `b`'s frame, `R_B^T (p_A - p_B)`.
fn relative_position(a: &Isometry3<f64>, b: &Isometry3<f64>) -> Vector3<f64> {
    b.rotation.inverse_transform_vector(&(a.translation.vector - b.translation.vector))
}

/// An orthonormal basis `(e1, e2)` of the plane orthogonal to the unit vector `axis`, the rows of
/// a [`TermKind::PointAt`] residual: `e1` is `axis x e_k` normalised, `e_k` the coordinate axis
/// least aligned with `axis` (the first of equals), and `e2 = axis x e1`. `genplan.projection`'s
/// `PointAt` uses the same rule.
pub fn axis_complement(axis: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let k = (0..3).fold(0, |best, i| if axis[i].abs() < axis[best].abs() { i } else { best });
    let e1 = axis.cross(&Vector3::ith(k, 1.0)).normalize();
    (e1, axis.cross(&e1))
}

/// `a * b` for a sparse `a` (a posture Jacobian: diagonal but for the free-flyer's block): each
/// non-zero of `a` adds a multiple of a row of `b` (a column of `b^T`, contiguous).
fn sparse_mul(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let bt = b.transpose();
    let mut out_t = DMatrix::zeros(b.ncols(), a.nrows());
    for i in 0..a.nrows() {
        for k in 0..a.ncols() {
            let x = a[(i, k)];
            if x != 0.0 {
                out_t.column_mut(i).axpy(x, &bt.column(k), 1.0);
            }
        }
    }
    out_t.transpose()
}

/// Check a term against the model (see the module doc): the link index; every number finite
/// and at most [`MAX_MAGNITUDE`] in absolute value (`weight` and `tolerance` positive, margins
/// not negative); rotations orthonormal and axes or normals of unit length within
/// [`ROTATION_TOLERANCE`]; a relative term's two links distinct; a box's lower corner
/// below its upper one; posture vectors of the model's sizes. The error names the term and the
/// field.
fn validate(model: &KinematicModel, t: &Term) -> Result<()> {
    let name = &t.name;
    let bad = |msg: String| Err(Error::Invalid(format!("term '{name}': {msg}")));
    for (field, v) in [("weight", t.weight), ("tolerance", t.tolerance)] {
        if !(v.is_finite() && v > 0.0 && v <= MAX_MAGNITUDE) {
            return bad(format!("{field} must be in (0, {MAX_MAGNITUDE:e}], got {v:?}"));
        }
    }
    let link_ok = |l: usize| l < model.n_links();
    // a relative term's links: both in range, and two of them
    let link_pair_ok = |link: usize, relative_to: usize| -> Result<()> {
        if let Some(l) = [link, relative_to].into_iter().find(|&l| !link_ok(l)) {
            return bad(format!("link index {l} out of range"));
        }
        if link == relative_to {
            return bad(format!("relative_to is the link itself (index {link}): its pose in its own frame never changes"));
        }
        Ok(())
    };
    match &t.kind {
        TermKind::FramePose { link, .. }
        | TermKind::FramePosition { link, .. }
        | TermKind::FrameOrientation { link, .. }
        | TermKind::PointAt { link, .. }
        | TermKind::Plane { link, .. }
            if !link_ok(*link) =>
        {
            bad(format!("link index {link} out of range"))
        }
        TermKind::RelativePose { link, relative_to, target, mask } => {
            link_pair_ok(*link, *relative_to)?;
            check_pose(name, target)?;
            bounded(name, "mask", mask)
        }
        TermKind::RelativePosition { link, relative_to, target, mask } => {
            link_pair_ok(*link, *relative_to)?;
            bounded(name, "target", target.as_slice())?;
            bounded(name, "mask", mask)
        }
        TermKind::PointAt { axis, point, .. } => {
            check_unit(name, "axis", axis)?;
            bounded(name, "point", point.as_slice())
        }
        TermKind::Plane { normal, offset, .. } => {
            check_unit(name, "normal", normal)?;
            bounded(name, "offset", &[*offset])
        }
        TermKind::FramePose { target, mask, .. } => {
            check_pose(name, target)?;
            bounded(name, "mask", mask)
        }
        TermKind::FramePosition { target, mask, .. } => {
            bounded(name, "target", target.as_slice())?;
            bounded(name, "mask", mask)
        }
        TermKind::FrameOrientation { target, offset, mask, .. } => {
            check_rotation(name, "target", target)?;
            check_rotation(name, "offset", offset)?;
            bounded(name, "mask", mask)
        }
        TermKind::JointLimits { margin } => margin_ok(name, *margin),
        TermKind::ComBox { lower, upper, margin } => {
            bounded(name, "lower", lower.as_slice())?;
            bounded(name, "upper", upper.as_slice())?;
            if (0..3).any(|k| lower[k] > upper[k]) {
                return bad("lower exceeds upper".into());
            }
            margin_ok(name, *margin)
        }
        TermKind::Posture { q_nom, weights, overrides } => {
            if weights.len() != model.nv {
                return bad(format!("posture weights: expected {} numbers, got {}", model.nv, weights.len()));
            }
            bounded(name, "posture weights", weights)?;
            if let Some(n) = q_nom {
                check_vector(&format!("term '{name}' posture q_nom"), n, model.nq)?;
                bounded(name, "posture q_nom", n)?;
            }
            if let Some(&(iq, v)) = overrides.iter().find(|&&(iq, v)| iq >= model.nq || !(v.is_finite() && v.abs() <= MAX_MAGNITUDE)) {
                return bad(format!(
                    "posture override (q index {iq}, value {v:?}) out of range: the index must be below nq = {}, the value finite and at most {MAX_MAGNITUDE:e} in absolute value",
                    model.nq
                ));
            }
            Ok(())
        }
        TermKind::Custom(c) => match c.dim() {
            0 => bad("a custom term needs at least one residual component (dim >= 1)".into()),
            d if d > MAX_CUSTOM_DIM => bad(format!("dim {d} exceeds {MAX_CUSTOM_DIM}")),
            _ => Ok(()),
        },
    }
}

/// The largest residual size of a [`CustomTerm`] (its Jacobian is `dim x nv` numbers per call).
pub const MAX_CUSTOM_DIM: usize = 10_000;

/// Every element of `values` (field `field` of term `term`) finite (else [`Error::NonFinite`])
/// and at most [`MAX_MAGNITUDE`] in absolute value (else [`Error::Invalid`]).
fn bounded(term: &str, field: &str, values: &[f64]) -> Result<()> {
    check_finite(&format!("term '{term}' {field}"), values)?;
    match values.iter().position(|v| v.abs() > MAX_MAGNITUDE) {
        Some(i) => Err(Error::Invalid(format!(
            "term '{term}': {field} element {i} is {:?}, beyond the bound {MAX_MAGNITUDE:e} on a term's numbers",
            values[i]
        ))),
        None => Ok(()),
    }
}

/// A target pose: its translation bounded ([`bounded`]), its rotation a unit quaternion within
/// [`ROTATION_TOLERANCE`].
fn check_pose(term: &str, target: &Isometry3<f64>) -> Result<()> {
    bounded(term, "target translation", target.translation.vector.as_slice())?;
    let r = target.rotation.coords;
    check_finite(&format!("term '{term}' target rotation"), r.as_slice())?;
    let norm = crate::lie::stable_norm(r.as_slice()); // huge components do not overflow
    if (norm - 1.0).abs() > ROTATION_TOLERANCE {
        return Err(Error::Invalid(format!("term '{term}': target rotation: not a unit quaternion (norm {norm:?})")));
    }
    Ok(())
}

/// A unit vector: finite, of norm 1 within [`ROTATION_TOLERANCE`].
fn check_unit(term: &str, field: &str, v: &Vector3<f64>) -> Result<()> {
    check_finite(&format!("term '{term}' {field}"), v.as_slice())?;
    let norm = crate::lie::stable_norm(v.as_slice());
    if (norm - 1.0).abs() > ROTATION_TOLERANCE {
        return Err(Error::Invalid(format!("term '{term}': {field} must be a unit vector, got norm {norm:?}")));
    }
    Ok(())
}

/// A margin: finite, in [0, [`MAX_MAGNITUDE`]].
fn margin_ok(term: &str, margin: f64) -> Result<()> {
    if margin.is_finite() && (0.0..=MAX_MAGNITUDE).contains(&margin) {
        Ok(())
    } else {
        Err(Error::Invalid(format!("term '{term}': margin must be in [0, {MAX_MAGNITUDE:e}], got {margin:?}")))
    }
}

/// A rotation matrix: finite, orthonormal within [`ROTATION_TOLERANCE`].
fn check_rotation(term: &str, field: &str, r: &Matrix3<f64>) -> Result<()> {
    check_finite(&format!("term '{term}' {field}"), r.as_slice())?;
    let err = (r.transpose() * r - Matrix3::identity()).amax();
    if err > ROTATION_TOLERANCE {
        return Err(Error::Invalid(format!(
            "term '{term}': {field} is not a rotation matrix (R^T R differs from the identity by {err:?}, more than {ROTATION_TOLERANCE:e})"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::kinematics::ModelOptions;
    use crate::urdf::Urdf;

    /// A model whose public limits were edited to be reversed is refused when the projector is
    /// built, instead of the clipping (`f64::clamp`) panicking in a solve.
    #[test]
    fn reversed_limits_are_refused_not_a_panic() {
        let urdf = Urdf::parse(
            r#"<robot name="r"><link name="a"/><link name="b"/>
              <joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
                <limit lower="-1" upper="1"/></joint></robot>"#,
        )
        .unwrap();
        let mut model = KinematicModel::from_urdf(&urdf, &ModelOptions::default()).unwrap();
        let terms = || vec![Term { name: "limits".into(), kind: TermKind::JointLimits { margin: 0.0 }, weight: 1.0, tolerance: 1e-6 }];
        let p = Projector::new(Arc::new(model.clone()), terms(), Vec::new(), Settings::default()).unwrap();
        assert_eq!(p.solve(&[3.0], None).unwrap().q, vec![1.0]);
        (model.lower[0], model.upper[0]) = (1.0, -1.0);
        let e = Projector::new(Arc::new(model), terms(), Vec::new(), Settings::default()).unwrap_err().to_string();
        assert!(e.contains("joint 'j'") && e.contains("lower limit 1.0 is above its upper limit -1.0"), "{e}");
    }

    /// The damped pseudo-inverse written out: J^T (J J^T + lambda I)^-1.
    fn explicit_pinv(j: &DMatrix<f64>, lam: f64) -> DMatrix<f64> {
        let m = j.nrows();
        j.transpose() * (j * j.transpose() + DMatrix::identity(m, m) * lam).try_inverse().unwrap()
    }

    fn random_matrix(rows: usize, cols: usize, seed: u64) -> DMatrix<f64> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        DMatrix::from_fn(rows, cols, |_, _| rng.random_range(-1.0..1.0))
    }

    /// The factorised step and null space (no pseudo-inverse formed) against the formulas written
    /// out, for wide and tall Jacobians, with and without damping, with a rank-deficient one.
    #[test]
    fn damped_pinv_matches_the_explicit_formula() {
        for (rows, cols, lam, seed) in [(20, 34, 1e-3, 1), (3, 7, 0.0, 2), (7, 7, 1e-6, 3), (12, 5, 0.1, 4), (1, 6, 0.0, 5)] {
            let j = random_matrix(rows, cols, seed);
            let v = random_matrix(rows, 1, seed + 100).column(0).into_owned();
            let pinv = if rows <= cols {
                explicit_pinv(&j, lam)
            } else {
                (j.transpose() * &j + DMatrix::identity(cols, cols) * lam).try_inverse().unwrap() * j.transpose()
            };
            let d = DampedPinv::new(&j, lam);
            assert!((d.apply(&j, &v) - &pinv * &v).amax() < 1e-9, "{rows}x{cols}: step");
            let n1 = DMatrix::identity(cols, cols) - &pinv * &j;
            assert!((d.null_space(&j) - n1).amax() < 1e-9, "{rows}x{cols}: null space");
        }
        // rank-deficient (a zero row) without damping: J J^T is singular, J^+ = 0, as before
        let mut j = random_matrix(4, 6, 9);
        j.row_mut(1).fill(0.0);
        let d = DampedPinv::new(&j, 0.0);
        assert!(d.ch.is_none());
        assert_eq!(d.apply(&j, &DVector::from_element(4, 1.0)), DVector::zeros(6));
        assert_eq!(d.null_space(&j), DMatrix::identity(6, 6));
    }

    /// The rows `active_rows` writes without the dense Jacobian (posture and joint limits) are
    /// the dense Jacobian's rows (`jacobian`), weighted, and every row it drops is zero in both
    /// the residual and the dense Jacobian: on a free-flyer (its block's rows and the joints'),
    /// with posture weights of 0, a joint within the limits' margin and one outside it, beside a
    /// frame term.
    #[test]
    fn rows_written_without_the_dense_jacobian_are_its_rows() {
        let urdf = Urdf::parse(
            r#"<robot name="r"><link name="a"/><link name="b"/><link name="c"/>
              <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
                <origin xyz="0.1 0 0.2"/><limit lower="-2" upper="2"/></joint>
              <joint name="j2" type="revolute"><parent link="b"/><child link="c"/><axis xyz="0 1 0"/>
                <origin xyz="0 0.3 0"/><limit lower="-2" upper="2"/></joint></robot>"#,
        )
        .unwrap();
        let model = Arc::new(KinematicModel::from_urdf(&urdf, &ModelOptions { floating_base: true, ..Default::default() }).unwrap());
        let c = model.link_index("c").unwrap();
        // j1 = 0.4 is 1.6 from its limits, j2 = -0.7 1.3: with a margin of 1.5 only j2's row is active
        let q = [0.1, -0.2, 0.3, 0.2, -0.1, 0.3, 0.9273618495495703, 0.4, -0.7];
        let q_nom = [0.0, 0.1, 0.2, 0.0, 0.0, 0.0, 1.0, 0.0, 0.2];
        for weights in [vec![1.0, 0.5, 2.0, 1.0, 1.0, 3.0, 0.7, 1.5], vec![0.0, 2.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.5]] {
            let posture = Term {
                name: "posture".into(),
                kind: TermKind::Posture { q_nom: Some(q_nom.to_vec()), weights: weights.clone(), overrides: vec![] },
                weight: 3.0,
                tolerance: 1e-3,
            };
            let frame = Term {
                name: "c".into(),
                kind: TermKind::FramePosition { link: c, target: Vector3::new(0.5, 0.0, 1.0), mask: [1.0; 3] },
                weight: 2.0,
                tolerance: 1e-4,
            };
            let limits = Term { name: "limits".into(), kind: TermKind::JointLimits { margin: 1.5 }, weight: 4.0, tolerance: 1e-3 };
            let p = Projector::new(model.clone(), vec![frame, limits, posture], Vec::new(), Settings::default()).unwrap();
            let s = p.state(q.to_vec());
            let noms = nominals(&p.primary, &q);
            let (raws, dense) = p.stack(&p.primary, &s, &noms, true).unwrap();
            let dense = dense.unwrap();
            let mut frame_jac = DMatrix::zeros(6, model.nv);
            let (r1, j1) = p.active_rows(&p.primary, &s, &noms, &raws, &mut frame_jac).unwrap();
            // rows of the stack: 3 frame, 2 limits (j1, j2), 8 posture
            let kept: Vec<usize> = (0..3).chain([4]).chain((0..8).filter(|&i| weights[i] != 0.0).map(|i| 5 + i)).collect();
            assert_eq!(j1.nrows(), kept.len());
            let weighted = Projector::weighted(&p.primary, &raws);
            for (k, &i) in kept.iter().enumerate() {
                assert_eq!(r1[k], weighted[i], "residual row {i}");
                assert_eq!(j1.row(k), dense.row(i), "Jacobian row {i}");
            }
            for i in (0..dense.nrows()).filter(|i| !kept.contains(i)) {
                assert!(weighted[i] == 0.0 && dense.row(i).iter().all(|&x| x == 0.0), "dropped row {i} is not zero");
            }
        }
    }

    #[test]
    fn damped_gram_is_the_product() {
        // wide and tall; dense, a third non-zero (the general product) and a seventh non-zero
        // (the sparse sum), with a row and a column of zeros, as a step's J has
        let cases = [(19, 38, 1e-4, 1), (38, 19, 1e-4, 2), (6, 6, 0.0, 3), (1, 4, 0.5, 4), (0, 5, 0.1, 5), (38, 38, 1e-6, 6)];
        for ((rows, cols, lam, seed), keep) in cases.into_iter().flat_map(|c| [1, 3, 7].map(|k| (c, k))) {
            let mut j = random_matrix(rows, cols, seed);
            for (k, x) in j.iter_mut().enumerate() {
                if k % keep != 0 {
                    *x = 0.0;
                }
            }
            if rows > 2 && cols > 2 {
                j.row_mut(1).fill(0.0);
                j.column_mut(2).fill(0.0);
            }
            let wide = rows <= cols;
            let expected = if wide { &j * j.transpose() + DMatrix::identity(rows, rows) * lam } else { j.transpose() * &j + DMatrix::identity(cols, cols) * lam };
            let got = damped_gram(&j, lam, wide);
            assert_eq!(got.shape(), expected.shape(), "{rows}x{cols}, 1 in {keep}");
            assert!(got.iter().zip(expected.iter()).all(|(a, b)| (a - b).abs() <= 1e-12 * (1.0 + b.abs())), "{rows}x{cols}, 1 in {keep}");
            assert_eq!(got, got.transpose(), "{rows}x{cols}, 1 in {keep}: symmetric");
        }
    }

    #[test]
    fn sparse_mul_is_the_product() {
        let mut a = DMatrix::zeros(9, 9);
        a.view_mut((0, 0), (3, 3)).copy_from(&random_matrix(3, 3, 11));
        for i in 3..9 {
            a[(i, i)] = 0.5 + i as f64;
        }
        let b = random_matrix(9, 9, 12);
        assert!((sparse_mul(&a, &b) - &a * &b).amax() < 1e-12);
        let wide = random_matrix(4, 9, 13);
        assert!((sparse_mul(&wide, &b) - &wide * &b).amax() < 1e-12);
    }
}
