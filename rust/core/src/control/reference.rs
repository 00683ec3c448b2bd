//! What a run follows: one command per tick, the controller frame's pose, velocity and
//! acceleration ([`TaskCommand`]) and, for a joint trajectory, its joint positions, velocities
//! and accelerations.
//!
//! A joint trajectory is checked before anything runs ([`Reference::from_joints`]): its shape,
//! finite values, unit `[cos, sin]` of continuous joints, positions within the joint range,
//! speeds within the velocity limits, and no step between samples longer than one tick at the
//! velocity limit can follow (`|q[k+1] (-) q[k]| <= v_max dt`); the inverse-dynamics torques of
//! the nominal model along it are compared with the torque limits ([`ReferenceCheck`]).

use nalgebra::DMatrix;

use crate::dynamics::{Dynamics, Frame};
use crate::error::{Error, Result};

use super::controllers::{gemv, JointCommand, TaskCommand};
use super::limits::{LimitKind, LimitViolation, Limits};

/// How often [`Reference::from_joints_with`] asks whether to stop (samples).
pub const STOP_CHECK_SAMPLES: usize = 1000;

/// Why a trajectory cannot be followed (before the run).
#[derive(Debug)]
pub enum ReferenceError {
    /// A shape or value error of the input (the error names the field).
    Input(Error),
    /// A trajectory the robot cannot follow: outside the joint range, over the velocity limits,
    /// or a jump between samples (the message names the field, the sample and the joint).
    Trajectory(String),
}

impl std::fmt::Display for ReferenceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ReferenceError::Input(e) => write!(f, "{e}"),
            ReferenceError::Trajectory(m) => write!(f, "{m}"),
        }
    }
}

impl std::error::Error for ReferenceError {}

impl From<Error> for ReferenceError {
    fn from(e: Error) -> Self {
        ReferenceError::Input(e)
    }
}

impl From<ReferenceError> for Error {
    fn from(e: ReferenceError) -> Self {
        match e {
            ReferenceError::Input(e) => e,
            ReferenceError::Trajectory(m) => Error::Invalid(m),
        }
    }
}

/// The joint motion of a reference, row-major: `q` (n x nq), `qd` and `qdd` (n x nv).
#[derive(Debug, Clone, PartialEq)]
pub struct JointReference {
    /// Positions.
    pub q: Vec<f64>,
    /// Velocities.
    pub qd: Vec<f64>,
    /// Accelerations.
    pub qdd: Vec<f64>,
}

/// How the reference's inverse-dynamics torques (nominal model) compare with the torque limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceCheck {
    /// The largest |torque| / limit over the samples and joints.
    pub max_torque_ratio: f64,
    /// The first sample over a torque limit (its `time` from the trajectory's start).
    pub torque_over: Option<LimitViolation>,
}

/// One command per tick.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// The frame's commands.
    pub task: Vec<TaskCommand>,
    /// The joint motion (a joint trajectory), or None (task commands only).
    pub joint: Option<JointReference>,
    nq: usize,
    nv: usize,
}

impl Reference {
    /// Task commands only (e.g. the spatula's eq. 23); at least one.
    pub fn from_task(task: Vec<TaskCommand>) -> Result<Reference> {
        if task.is_empty() {
            return Err(Error::Invalid("reference: no command".into()));
        }
        Ok(Reference { task, joint: None, nq: 0, nv: 0 })
    }

    /// The reference of a joint trajectory sampled every `dt` (row-major `q` n x nq, `qd` and
    /// `qdd` n x nv), checked (see the module docs; errors name `trajectory.q`,
    /// `trajectory.qd`, `trajectory.qdd` with the sample and the joint), with the commands of
    /// `frame` (its pose, `J qd`, `J qdd + dJ/dt qd` on `model`) and the comparison of its
    /// inverse-dynamics torques on `model` with the torque limits.
    pub fn from_joints(model: &Dynamics, frame: &Frame, limits: &Limits, q: Vec<f64>, qd: Vec<f64>, qdd: Vec<f64>, dt: f64) -> std::result::Result<(Reference, ReferenceCheck), ReferenceError> {
        Self::from_joints_with(model, frame, limits, q, qd, qdd, dt, &mut || false)
    }

    /// As [`from_joints`](Self::from_joints), asking `stop` every [`STOP_CHECK_SAMPLES`]
    /// samples whether to abandon (e.g. on Ctrl-C): the error [`Error::Invalid`] "interrupted".
    #[allow(clippy::too_many_arguments)]
    pub fn from_joints_with(
        model: &Dynamics,
        frame: &Frame,
        limits: &Limits,
        q: Vec<f64>,
        qd: Vec<f64>,
        qdd: Vec<f64>,
        dt: f64,
        stop: &mut dyn FnMut() -> bool,
    ) -> std::result::Result<(Reference, ReferenceCheck), ReferenceError> {
        let (nq, nv) = (model.nq, model.nv);
        if nq == 0 || q.len() % nq != 0 || q.is_empty() {
            return Err(Error::Invalid(format!("trajectory.q: expected rows of {nq} joint positions (n >= 1), got {} values", q.len())).into());
        }
        let n = q.len() / nq;
        for (what, values) in [("trajectory.qd", &qd), ("trajectory.qdd", &qdd)] {
            if values.len() != n * nv {
                return Err(Error::Invalid(format!("{what}: expected {n} rows of {nv} (as trajectory.q), got {} values", values.len())).into());
            }
        }
        for (what, values, width) in [("trajectory.q", &q, nq), ("trajectory.qd", &qd, nv), ("trajectory.qdd", &qdd, nv)] {
            if let Some(i) = values.iter().position(|x| !x.is_finite()) {
                return Err(Error::NonFinite { what: format!("{what} row {} (column {})", i / width, i % width), index: i, value: values[i] }.into());
            }
        }
        let names = &model.joint_names;
        let time = |k: usize| k as f64 * dt;
        for b in &model.bodies {
            let (i, k) = (b.q_index, b.v_index);
            for row in 0..n {
                let qr = &q[row * nq..(row + 1) * nq];
                if model.is_continuous(k) {
                    let norm = qr[i].hypot(qr[i + 1]);
                    if (norm - 1.0).abs() > 1e-6 {
                        return Err(ReferenceError::Trajectory(format!(
                            "trajectory.q: sample {row} (t = {:.3} s): continuous joint '{}' has [cos, sin] = [{}, {}] of norm {norm:.6}, not 1",
                            time(row), names[k], qr[i], qr[i + 1]
                        )));
                    }
                } else if qr[i] < model.lower[i] - 1e-9 || qr[i] > model.upper[i] + 1e-9 {
                    return Err(ReferenceError::Trajectory(format!(
                        "trajectory.q: sample {row} (t = {:.3} s): joint '{}' at {:.6} is outside its range [{:.6}, {:.6}]",
                        time(row), names[k], qr[i], model.lower[i], model.upper[i]
                    )));
                }
                let speed = qd[row * nv + k];
                if speed.abs() > limits.velocity[k] * (1.0 + 1e-6) {
                    return Err(ReferenceError::Trajectory(format!(
                        "trajectory.qd: sample {row} (t = {:.3} s): joint '{}' at {:.4} {} is over its velocity limit {:.4}",
                        time(row), names[k], speed, limits.unit(k, LimitKind::Velocity), limits.velocity[k]
                    )));
                }
            }
        }
        let mut step = vec![0.0; nv];
        for row in 1..n {
            model.difference(&q[(row - 1) * nq..row * nq], &q[row * nq..(row + 1) * nq], &mut step);
            for k in 0..nv {
                let most = limits.velocity[k] * dt;
                if step[k].abs() > most * (1.0 + 1e-6) + 1e-12 {
                    return Err(ReferenceError::Trajectory(format!(
                        "trajectory.q: sample {row} (t = {:.3} s): joint '{}' moves {:.4} in one tick of {dt} s, more than its velocity limit allows ({:.4} x {dt} = {:.4}): a jump the robot cannot follow",
                        time(row), names[k], step[k].abs(), limits.velocity[k], most
                    )));
                }
            }
        }
        // the frame's commands and the inverse-dynamics torques
        let mut ws = model.workspace();
        let (mut jac, mut djac) = (DMatrix::zeros(6, nv), DMatrix::zeros(6, nv));
        let (mut tau, mut jqdd, at_rest) = (vec![0.0; nv], [0.0; 6], vec![0.0; nv]);
        let mut task = Vec::with_capacity(n);
        let mut check = ReferenceCheck { max_torque_ratio: 0.0, torque_over: None };
        for row in 0..n {
            if row % STOP_CHECK_SAMPLES == STOP_CHECK_SAMPLES - 1 && stop() {
                return Err(Error::Invalid(format!("interrupted while checking the trajectory (sample {row} of {n})")).into());
            }
            let (qr, qdr, qddr) = (&q[row * nq..(row + 1) * nq], &qd[row * nv..(row + 1) * nv], &qdd[row * nv..(row + 1) * nv]);
            model.update_kinematics_unchecked(qr, Some(qdr), &mut ws);
            model.frame_jacobians_from_kinematics(frame, &ws, &mut jac, Some(&mut djac));
            let (rot, pos) = model.frame_placement(frame, &ws);
            let mut cmd = TaskCommand::hold(pos, rot);
            gemv(&jac, qdr, cmd.vel.as_mut_slice());
            gemv(&djac, qdr, cmd.acc.as_mut_slice());
            gemv(&jac, qddr, &mut jqdd);
            for r in 0..6 {
                cmd.acc[r] += jqdd[r];
            }
            task.push(cmd);
            model.rnea_from_kinematics(Some(qddr), true, &mut ws, &mut tau);
            let (ratio, _) = limits.ratios(&tau, &at_rest);
            check.max_torque_ratio = check.max_torque_ratio.max(ratio);
            if check.torque_over.is_none() {
                check.torque_over = limits.violation(row, time(row), &tau, &at_rest);
            }
        }
        Ok((Reference { task, joint: Some(JointReference { q, qd, qdd }), nq, nv }, check))
    }

    /// Commands (ticks) in the reference.
    pub fn len(&self) -> usize {
        self.task.len()
    }

    /// Whether it holds no command (never, once built).
    pub fn is_empty(&self) -> bool {
        self.task.is_empty()
    }

    /// The joint motion of command `k`.
    pub fn joint_command(&self, k: usize) -> Option<JointCommand<'_>> {
        self.joint.as_ref().map(|j| JointCommand {
            q: &j.q[k * self.nq..(k + 1) * self.nq],
            qd: &j.qd[k * self.nv..(k + 1) * self.nv],
            qdd: &j.qdd[k * self.nv..(k + 1) * self.nv],
        })
    }
}
