//! The damped Gauss-Newton solver: its [`Settings`], a solve's [`Outcome`], the [`Projector`]
//! (built and retargeted with its terms checked) and the solve itself.

use std::time::Instant;

use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Vector3};

use super::linalg::{sparse_mul, DampedPinv};
use super::terms::{nominals, within_margin, State};
use super::validate::{check_rotation, validate};
use super::{residual_size, SolveError, Term, TermKind, TermResult, MAX_MAGNITUDE};
#[cfg(doc)]
use super::{TermFailure, ROTATION_TOLERANCE};
use crate::error::{check_finite, check_vector, Error, Result};
use crate::kinematics::KinematicModel;

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
    pub(super) bounded: Vec<(usize, usize, f64, f64)>,
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

    /// The terms' unweighted residuals and, when `with_jac`, their weighted Jacobians stacked.
    pub(super) fn stack(&self, terms: &[Term], s: &State, noms: &[Vec<f64>], with_jac: bool) -> TermResult<Stacked> {
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

    pub(super) fn weighted(terms: &[Term], raws: &[DVector<f64>]) -> DVector<f64> {
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

    /// The task holds a [`TermKind::Custom`] term (primary or secondary).
    pub fn has_custom_terms(&self) -> bool {
        self.primary.iter().chain(&self.secondary).any(|t| matches!(t.kind, TermKind::Custom(_)))
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

/// Terms' unweighted residuals, and their weighted Jacobians stacked when asked for.
type Stacked = (Vec<DVector<f64>>, Option<DMatrix<f64>>);

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
}
