//! The 1 kHz loop: every tick the controller measures the plant's state, computes its torque
//! (limits applied by the policy), the plant runs one period under it, and a payload with
//! dynamics steps with the achieved motion of the controller's frame. A run follows a
//! [`Reference`] after `settle` ticks holding its first command; its log is allocated before the
//! loop and written in place (no allocation per tick); the caller is asked every
//! [`STOP_CHECK_TICKS`] ticks whether to stop (Ctrl-C); a paced run ticks on the wall clock.

use std::time::{Duration, Instant};

use nalgebra::{DMatrix, Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3, Vector6};

use crate::dynamics::{cholesky_in_place, cholesky_solve, Dynamics, Frame};
use crate::error::{Error, Result};

use super::controllers::{gemv, Controller, JointCommand, TaskCommand};
use super::limits::{LimitViolation, Limits};
use super::observer::DisturbanceObserver;
use super::payloads::{FrameMotion, Payload, PayloadDynamics};
use super::plant::Plant;
use super::reference::Reference;
use super::settings::{setting, ControllerSettings, Disturbances, JointLimits, LimitPolicy};

/// Longest run in ticks (10^7: 2.8 hours at 1 kHz).
pub const MAX_TICKS: usize = 10_000_000;

/// How often [`Simulation::run_with`] asks whether to stop.
pub const STOP_CHECK_TICKS: usize = 250;

/// Everything a simulation is built from.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// The controller.
    pub controller: ControllerSettings,
    /// What the plant has that the controller's model lacks.
    pub disturbances: Disturbances,
    /// The payloads the robot holds and the controller knows (in its model and in the plant).
    pub payloads: Vec<Payload>,
    /// The joint limits and what a tick over one does.
    pub limits: JointLimits,
    /// RK4 steps of the plant per control period.
    pub substeps: usize,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            controller: ControllerSettings::default(),
            disturbances: Disturbances::default(),
            payloads: vec![],
            limits: JointLimits::default(),
            substeps: 1,
        }
    }
}

/// What one tick did (its state at the start is in the simulation's fields).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TickOutput {
    /// Norm of the frame's position error (m).
    pub err_pos: f64,
    /// Angle of the frame's attitude error (rad).
    pub err_rot: f64,
    /// The singularity measure of the task solve (NaN in joint space).
    pub det: f64,
    /// The task inverse was damped.
    pub damped: bool,
    /// The torque was clipped to its limits (policy `saturate`).
    pub saturated: bool,
    /// Largest |commanded torque| / limit over the joints.
    pub torque_ratio: f64,
    /// Largest |joint speed| / limit over the joints (at the tick's start).
    pub velocity_ratio: f64,
}

/// Summary numbers of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Ticks run (settle phase included).
    pub ticks: usize,
    /// Wall time of the loop divided by the ticks (us): unpaced, the cost of one tick.
    pub us_per_tick: f64,
    /// Largest position error of the frame (m) after the settle phase.
    pub max_error_position: f64,
    /// Largest attitude error of the frame (rad), likewise.
    pub max_error_rotation: f64,
    /// RMS position error (m), likewise.
    pub rms_error_position: f64,
    /// RMS attitude error (rad), likewise.
    pub rms_error_rotation: f64,
    /// Largest |joint error| (rad or m) after the settle phase (a joint reference; else NaN).
    pub max_error_joint: f64,
    /// Ticks with a damped task inverse.
    pub damped_ticks: usize,
    /// Time (s) of the first of them.
    pub first_damped_time: Option<f64>,
    /// Smallest singularity measure (`|det J|` or `sqrt(det(J_s J_s^T))`).
    pub min_abs_det_j: f64,
    /// Ticks whose torque was clipped to the limits.
    pub saturated_ticks: usize,
    /// Largest |applied torque| per joint.
    pub max_abs_tau: Vec<f64>,
    /// Largest |joint speed| per joint.
    pub max_abs_v: Vec<f64>,
    /// Largest |commanded torque| / limit over the run.
    pub max_torque_ratio: f64,
    /// Largest |joint speed| / limit over the run.
    pub max_velocity_ratio: f64,
    /// Ticks over a joint limit.
    pub limit_ticks: usize,
    /// The run stopped at the first tick over a limit (the log ends there).
    pub stopped_at_limit: bool,
}

/// Per-tick log of a run (row-major arrays; the state at the tick's start and what it applied).
#[derive(Debug, Clone, Default)]
pub struct Log {
    /// Ticks logged (rows).
    pub n: usize,
    /// Length of q.
    pub nq: usize,
    /// Joints.
    pub nv: usize,
    /// Time of each tick (s).
    pub t: Vec<f64>,
    /// Joint positions (n x nq).
    pub q: Vec<f64>,
    /// Joint velocities (n x nv).
    pub v: Vec<f64>,
    /// Applied torques (n x nv).
    pub tau: Vec<f64>,
    /// The observer's estimate (n x nv).
    pub tau_dis_hat: Vec<f64>,
    /// The torque the nominal model does not explain (n x nv).
    pub tau_dis: Vec<f64>,
    /// `q_ref (-) q` (n x nv; empty without a joint reference).
    pub err_joint: Vec<f64>,
    /// Commanded position of the frame (n x 3).
    pub pos_cmd: Vec<f64>,
    /// Achieved position (n x 3).
    pub pos: Vec<f64>,
    /// Achieved attitude, row-major (n x 9).
    pub rot: Vec<f64>,
    /// Norm of the position error (m).
    pub err_pos: Vec<f64>,
    /// Angle of the attitude error (rad).
    pub err_rot: Vec<f64>,
    /// The frame's velocity, linear then angular (n x 6).
    pub vel: Vec<f64>,
    /// The frame's achieved acceleration, linear then angular (n x 6).
    pub acc: Vec<f64>,
    /// The singularity measure (NaN in joint space).
    pub det_j: Vec<f64>,
    /// The task inverse was damped.
    pub damped: Vec<bool>,
    /// The torque was clipped.
    pub saturated: Vec<bool>,
    /// Largest |commanded torque| / limit.
    pub torque_ratio: Vec<f64>,
    /// Largest |joint speed| / limit.
    pub velocity_ratio: Vec<f64>,
    /// Compute time of each tick (s).
    pub compute: Vec<f64>,
    /// Paced runs: how late each tick started after its deadline (s).
    pub lateness: Vec<f64>,
    /// Names of the payload's channels.
    pub channels: Vec<&'static str>,
    /// The payload's channels (n x channels).
    pub payload: Vec<f64>,
}

/// Reserve `n` more elements, or an error naming the log (no abort on a failed allocation), and
/// touch each page of the reserved memory once: the loop then writes its log without a page
/// fault (a first touch of fresh memory costs microseconds on a virtual machine, the compute of
/// a tick, and in a paced run would show as a late tick).
fn reserve<T: Copy + Default>(v: &mut Vec<T>, n: usize) -> Result<()> {
    v.try_reserve_exact(n).map_err(|_| Error::Invalid(format!("cannot allocate the run's log ({n} values)")))?;
    let per_page = (4096 / std::mem::size_of::<T>().max(1)).max(1);
    let spare = v.spare_capacity_mut();
    for slot in spare.iter_mut().step_by(per_page) {
        slot.write(T::default());
    }
    // the writes must happen although nothing reads them before the log's own
    std::hint::black_box(spare.as_mut_ptr());
    Ok(())
}

impl Log {
    fn with_capacity(n: usize, nq: usize, nv: usize, joint_errors: bool, channels: &[&'static str], paced: bool) -> Result<Log> {
        let mut log = Log { nq, nv, channels: channels.to_vec(), ..Default::default() };
        for (v, k) in [
            (&mut log.t, 1),
            (&mut log.q, nq),
            (&mut log.v, nv),
            (&mut log.tau, nv),
            (&mut log.tau_dis_hat, nv),
            (&mut log.tau_dis, nv),
            (&mut log.err_joint, if joint_errors { nv } else { 0 }),
            (&mut log.pos_cmd, 3),
            (&mut log.pos, 3),
            (&mut log.rot, 9),
            (&mut log.err_pos, 1),
            (&mut log.err_rot, 1),
            (&mut log.vel, 6),
            (&mut log.acc, 6),
            (&mut log.det_j, 1),
            (&mut log.torque_ratio, 1),
            (&mut log.velocity_ratio, 1),
            (&mut log.compute, 1),
            (&mut log.lateness, if paced { 1 } else { 0 }),
            (&mut log.payload, channels.len()),
        ] {
            reserve(v, n.checked_mul(k).ok_or_else(|| Error::Invalid("the run's log is too large".into()))?)?;
        }
        reserve(&mut log.damped, n)?;
        reserve(&mut log.saturated, n)?;
        Ok(log)
    }
}

/// A run: its log, its summary, the first tick over a joint limit, where the motion is.
#[derive(Debug, Clone)]
pub struct Run {
    /// Every tick.
    pub log: Log,
    /// The summary numbers.
    pub summary: Summary,
    /// The first tick over a joint limit (None: the run stayed within them).
    pub limit_violation: Option<LimitViolation>,
    /// Tick indices: settle phase `[0, motion_start)`, motion `[motion_start, motion_end)`,
    /// then the tail.
    pub motion_start: usize,
    /// See `motion_start`.
    pub motion_end: usize,
}

/// The robot, its controller, the plant, the observer and a payload's dynamics. The
/// configuration is fixed at construction (the models are built from it).
pub struct Simulation {
    config: SimConfig,
    /// The controller and its nominal model.
    pub controller: Controller,
    /// The true robot.
    pub plant: Plant,
    /// The disturbance observer.
    pub observer: DisturbanceObserver,
    /// The limits in force.
    pub limits: Limits,
    /// A payload with dynamics of its own riding on the controller's frame.
    pub payload: Option<Box<dyn PayloadDynamics>>,
    /// Ticks since the last reset.
    pub ticks: u64,
    /// The torque applied by the last tick.
    pub tau: Vec<f64>,
    /// The torque the nominal model did not explain in the last tick.
    pub tau_dis: Vec<f64>,
    /// The frame's achieved acceleration in the last tick (linear, angular).
    pub acc: Vector6<f64>,
    /// The payload's channel values of the last tick.
    pub payload_state: Vec<f64>,
    qdd0: Vec<f64>,
    scratch: Vec<f64>,
    /// The plant's robot has the controller's kinematics (payloads change inertias only): the
    /// plant's first stage takes the kinematics the controller measured.
    share_kinematics: bool,
    /// Tick with the build compiled for AVX2 and FMA (chosen once, where the processor has them).
    avx2: bool,
    /// The plant is the nominal model plus one rigid payload on the controller frame's body: its
    /// first RK stage from the controller's mass matrix and bias plus the payload's terms.
    first_stage: Option<PayloadStage>,
}

/// The plant's joint acceleration at the state the controller has just measured, when the plant
/// is the controller's nominal model plus one rigid payload on the controller frame's body:
/// `(M_n + M_p) qdd = tau_net - h_n - h_p`, the payload's terms through the Jacobian of its
/// centre of mass (the frame's, its linear rows moved to the centre of mass):
/// `M_p = m J_c^T J_c + J_w^T I J_w` and `h_p = m J_c^T (b_c - g) + J_w^T (I b_w + w x I w)`,
/// `b` the accelerations at zero joint acceleration (`dJ/dt v` moved to the centre of mass), `I`
/// the payload's inertia about its centre of mass in world axes. One Cholesky solve of nv x nv
/// instead of the articulated-body algorithm; equal to it up to rounding.
struct PayloadStage {
    /// The body the payload and the controller's frame move with.
    body: usize,
    mass: f64,
    /// Centre of mass in the body's frame.
    com: Vector3<f64>,
    /// Rotational inertia about the centre of mass, the body's axes.
    inertia: Matrix3<f64>,
    /// Per joint: the centre of mass's linear Jacobian column, the angular one and `I` times it.
    cols: Vec<[Vector3<f64>; 3]>,
    a: DMatrix<f64>,
    l: DMatrix<f64>,
    rhs: Vec<f64>,
}

impl PayloadStage {
    /// The stage for `payload` (the plant's unknown one) when it rides on the controller frame's
    /// body and carries mass or inertia; else None (the plant computes its first stage).
    fn new(robot: &Dynamics, payload: &Payload, frame: &Frame) -> Result<Option<PayloadStage>> {
        if payload.mass == 0.0 && payload.inertia.iter().flatten().all(|&x| x == 0.0) {
            return Ok(None);
        }
        let at = payload_frame(robot, payload, frame)?;
        let (Some(body), true) = (at.body, at.body == frame.body) else { return Ok(None) };
        let nv = robot.nv;
        Ok(Some(PayloadStage {
            body,
            mass: payload.mass,
            com: at.r * Vector3::from(payload.com) + at.p,
            inertia: at.r * payload.inertia_matrix() * at.r.transpose(),
            cols: vec![[Vector3::zeros(); 3]; nv],
            a: DMatrix::zeros(nv, nv),
            l: DMatrix::zeros(nv, nv),
            rhs: vec![0.0; nv],
        }))
    }

    /// The plant's joint acceleration under the net joint torque `torque` (applied plus offset
    /// minus friction) at the state `c` measured, into `out`.
    #[inline(always)]
    fn acceleration(&mut self, c: &Controller, gravity: &Vector3<f64>, torque: &[f64], out: &mut [f64]) -> Result<()> {
        let ws = c.workspace();
        let (rw, pw) = (ws.rw[self.body], ws.pw[self.body]);
        // from the frame's origin to the centre of mass; the inertia in world axes
        let rc = pw + rw * self.com - c.pos;
        let iw = rw * self.inertia * rw.transpose();
        let w = Vector3::new(c.xd[3], c.xd[4], c.xd[5]);
        let bw = Vector3::new(c.djv[3], c.djv[4], c.djv[5]);
        let bc = Vector3::new(c.djv[0], c.djv[1], c.djv[2]) + bw.cross(&rc) + w.cross(&w.cross(&rc));
        let f = (bc - gravity) * self.mass;
        let n = iw * bw + w.cross(&(iw * w));
        // the matrices' column-major storage through slices (no shape check per element)
        let nv = self.cols.len();
        let m = &c.mass().as_slice()[..nv * nv];
        for ((k, col), jk) in self.cols.iter_mut().enumerate().zip(c.jac.as_slice().chunks_exact(6)) {
            let jw = Vector3::new(jk[3], jk[4], jk[5]);
            let jc = Vector3::new(jk[0], jk[1], jk[2]) + jw.cross(&rc);
            *col = [jc, jw, iw * jw];
            self.rhs[k] = torque[k] - c.h[k] - jc.dot(&f) - jw.dot(&n);
        }
        // the lower triangle (what the factorisation reads)
        let a = &mut self.a.as_mut_slice()[..nv * nv];
        for (i, ci) in self.cols.iter().enumerate() {
            for (k, ck) in self.cols.iter().enumerate().skip(i) {
                a[k + i * nv] = m[k + i * nv] + self.mass * ck[0].dot(&ci[0]) + ck[1].dot(&ci[2]);
            }
        }
        cholesky_in_place(&self.a, &mut self.l).map_err(|k| {
            Error::Invalid(format!("dynamics: the plant's mass matrix is not positive definite (pivot {k})"))
        })?;
        cholesky_solve(&self.l, &mut self.rhs);
        out.copy_from_slice(&self.rhs);
        Ok(())
    }
}

/// The frame a payload is attached to: its link's frame, or the controller's frame.
fn payload_frame(robot: &Dynamics, payload: &Payload, controller_frame: &Frame) -> Result<Frame> {
    match &payload.link {
        Some(link) => robot.frame(link, &Isometry3::identity()),
        None => Ok(*controller_frame),
    }
}

fn attach(model: &mut Dynamics, robot: &Dynamics, payload: &Payload, controller_frame: &Frame) -> Result<()> {
    payload.validate()?;
    if payload.mass == 0.0 && payload.inertia.iter().flatten().all(|&x| x == 0.0) {
        return Ok(());
    }
    let frame = payload_frame(robot, payload, controller_frame)?;
    if frame.body.is_none() {
        return Err(setting("payload.link", format!("'{}' does not move with any joint", payload.link.as_deref().unwrap_or("?"))));
    }
    model.add_inertia(&frame, payload.mass, Vector3::from(payload.com), payload.inertia_matrix())
}

impl Simulation {
    /// Build from the robot's dynamics: the nominal model is the robot with `config.payloads`,
    /// the plant that plus the disturbances' payload. The controller's frame must be named
    /// (`controller.frame`). Every setting is checked (the error names the field).
    pub fn new(robot: &Dynamics, config: SimConfig) -> Result<Simulation> {
        let nv = robot.nv;
        let c = &config.controller;
        c.check(nv)?;
        config.disturbances.check(nv)?;
        let Some(link) = c.frame.as_deref() else {
            return Err(setting("controller.frame", "no frame given: name the link to control (or log)".into()));
        };
        let o = c.frame_offset;
        let frame = robot.frame(link, &Isometry3::from_parts(Translation3::new(o[0], o[1], o[2]), UnitQuaternion::identity()))?;
        let mut nominal = robot.clone();
        for p in &config.payloads {
            attach(&mut nominal, robot, p, &frame)?;
        }
        let mut true_model = nominal.clone();
        if let Some(p) = &config.disturbances.payload {
            attach(&mut true_model, robot, p, &frame)?;
        }
        let limits = Limits::new(&config.limits, robot)?;
        let plant = Plant::new(true_model, &config.disturbances, config.substeps)?;
        let controller = Controller::new(c.clone(), nominal, frame)?;
        let observer = DisturbanceObserver::new(nv, c.dob_cutoff_hz, c.dt);
        let share_kinematics = plant.shares_kinematics_with(&controller.nominal);
        let first_stage = match (&config.disturbances.payload, share_kinematics) {
            (Some(p), true) => PayloadStage::new(robot, p, &controller.frame)?,
            _ => None,
        };
        Ok(Simulation {
            share_kinematics,
            controller,
            plant,
            observer,
            limits,
            payload: None,
            ticks: 0,
            tau: vec![0.0; nv],
            tau_dis: vec![0.0; nv],
            acc: Vector6::zeros(),
            payload_state: vec![],
            qdd0: vec![0.0; nv],
            scratch: vec![0.0; nv],
            avx2: crate::cpu::avx2_fma(),
            first_stage,
            config,
        })
    }

    /// With a payload whose dynamics ride on the controller's frame.
    pub fn with_payload_dynamics(mut self, payload: Box<dyn PayloadDynamics>) -> Self {
        self.payload_state = vec![0.0; payload.channels().len()];
        self.payload = Some(payload);
        self
    }

    /// The configuration this simulation was built with.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// Put the robot at rest at `q` and reset the observer and the payload.
    pub fn reset(&mut self, q: &[f64]) -> Result<()> {
        self.plant.reset(q)?;
        self.observer.reset();
        if let Some(p) = &mut self.payload {
            p.reset();
        }
        self.ticks = 0;
        Ok(())
    }

    /// Whether ticks run the build compiled for AVX2 and FMA: asked for (`on`, the default) and
    /// the processor has them; else the baseline build. The two give the same bits: Rust neither
    /// fuses a multiply and an add on its own nor reorders a sum, so the wider registers change
    /// the instructions, not the arithmetic. Returns the choice in force.
    pub fn set_avx2(&mut self, on: bool) -> bool {
        self.avx2 = on && crate::cpu::avx2_fma();
        self.avx2
    }

    /// Whether the plant's first RK stage comes from the controller's mass matrix and bias plus
    /// the unknown payload's terms (the plant is the nominal model plus one rigid payload on the
    /// controller frame's body) instead of the plant's own articulated-body algorithm.
    pub fn first_stage_from_controller(&self) -> bool {
        self.first_stage.is_some()
    }

    /// One control period: measure, control (limits by the policy), let the plant run `dt`
    /// under the held torque, step the payload. The frame's state at the tick's start is in
    /// `self.controller` (`pos`, `rot`, `xd`), the applied torque in `self.tau`. The whole
    /// tick (controller, observer and plant, inlined into one function) is compiled twice, for
    /// the baseline processor and with AVX2 and FMA; the second runs where the processor has them
    /// (see [`set_avx2`](Self::set_avx2)).
    pub fn tick(&mut self, cmd: &TaskCommand, joint: Option<JointCommand<'_>>) -> Result<TickOutput> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            #[target_feature(enable = "avx2,fma")]
            fn tick_avx2(s: &mut Simulation, cmd: &TaskCommand, joint: Option<JointCommand<'_>>) -> Result<TickOutput> {
                s.tick_inlined(cmd, joint)
            }
            // SAFETY: `avx2` is true only where the processor has AVX2 and FMA (crate::cpu)
            return unsafe { tick_avx2(self, cmd, joint) };
        }
        self.tick_inlined(cmd, joint)
    }

    /// The body of [`tick`](Self::tick), inlined (with everything it calls in the core) into
    /// each of its two builds.
    #[inline(always)]
    fn tick_inlined(&mut self, cmd: &TaskCommand, joint: Option<JointCommand<'_>>) -> Result<TickOutput> {
        let dt = self.controller.settings.dt;
        let (dob, mc) = (self.controller.settings.dob, self.controller.settings.model_compensation);
        let (q, v) = (&self.plant.q, &self.plant.v);
        self.controller.measure(q, v);
        self.observer.update(v, dt);
        let estimate = if dob { Some(self.observer.estimate.as_slice()) } else { None };
        let (det, damped) = self.controller.control(cmd, joint, q, v, estimate)?;
        self.tau.copy_from_slice(&self.controller.tau);
        let (torque_ratio, velocity_ratio) = self.limits.ratios(&self.tau, v);
        let saturated = self.limits.policy == LimitPolicy::Saturate && self.limits.saturate(&mut self.tau);
        if !self.tau.iter().all(|x| x.is_finite()) {
            return Err(Error::Invalid(format!("controller produced a non-finite torque at tick {}", self.ticks)));
        }
        let h = if mc { Some(self.controller.h.as_slice()) } else { None };
        self.observer.remember(&self.tau, h, self.controller.mass(), v);
        let (ep, er) = (self.controller.err_pos.norm(), self.controller.err_rot.norm());
        // the plant: RK4 under the held torque, from the kinematics the controller measured (and
        // the first stage from its mass matrix and bias when only a payload on its frame's body
        // tells the plant from the nominal model)
        match &mut self.first_stage {
            Some(stage) => {
                self.plant.net_torque(&self.tau, v, &mut self.scratch);
                stage.acceleration(&self.controller, &self.plant.model().gravity, &self.scratch, &mut self.qdd0)?;
                self.plant.step_from_acceleration(&self.tau, dt, self.ticks, self.controller.workspace(), &self.qdd0)?;
            }
            None => {
                let start = if self.share_kinematics { Some(self.controller.workspace()) } else { None };
                self.plant.step(&self.tau, dt, self.ticks, start, &mut self.qdd0)?;
            }
        }
        // the frame's achieved motion at the tick's start, the unexplained torque, the payload
        let c = &self.controller;
        gemv(&c.jac, &self.qdd0, self.acc.as_mut_slice());
        self.acc += c.djv;
        self.observer.unexplained(&self.tau, c.mass(), &self.qdd0, &mut self.scratch, &mut self.tau_dis);
        if let Some(p) = &mut self.payload {
            let m = FrameMotion { pos: c.pos, rot: c.rot, vel: c.xd, acc: self.acc };
            p.step(&m, &self.plant.model().gravity, dt, &mut self.payload_state);
        }
        self.ticks += 1;
        Ok(TickOutput { err_pos: ep, err_rot: er, det, damped, saturated, torque_ratio, velocity_ratio })
    }

    /// Follow `reference` from rest at `q0`: `settle` ticks holding its first command (the
    /// observer converges; the paper's robot held still for 25 s), then one tick per command.
    /// `motion_len`: how many commands are the motion proper (the rest is a tail; None: all).
    /// `paced`: tick on the wall clock every `dt` and record the lateness of each tick.
    /// `stop_at_limit` (or the policy `stop`): end the run after the first tick over a joint
    /// limit. `stop` is asked every [`STOP_CHECK_TICKS`] ticks whether to abandon the run (e.g.
    /// on Ctrl-C); a stop is the error [`Error::Invalid`] "run interrupted".
    pub fn run_with(
        &mut self,
        reference: &Reference,
        q0: &[f64],
        settle: usize,
        motion_len: Option<usize>,
        paced: bool,
        stop_at_limit: bool,
        stop: &mut dyn FnMut() -> bool,
    ) -> Result<Run> {
        let rows = reference.len();
        if rows.saturating_add(settle) > MAX_TICKS {
            return Err(Error::Invalid(format!(
                "a run is limited to {MAX_TICKS} ticks; got {rows} trajectory rows + {settle} settle ticks"
            )));
        }
        let motion_len = motion_len.unwrap_or(rows);
        if motion_len == 0 || motion_len > rows {
            return Err(Error::Invalid(format!("motion_len must be in 1..={rows}, got {motion_len}")));
        }
        if let Some(j) = &reference.joint {
            let nq = self.plant.q.len();
            if j.q.len() != rows * nq {
                return Err(Error::Invalid(format!("reference: {} joint positions for {rows} commands of {nq}", j.q.len())));
            }
        }
        self.reset(q0)?;
        let stop_at_limit = stop_at_limit || self.limits.policy == LimitPolicy::Stop;
        let n = rows + settle;
        let (nq, nv) = (self.plant.q.len(), self.plant.v.len());
        let dt = self.controller.settings.dt;
        let channels: Vec<&'static str> = self.payload.as_ref().map_or(vec![], |p| p.channels().to_vec());
        let joint_errors = reference.joint.is_some();
        let mut log = Log::with_capacity(n, nq, nv, joint_errors, &channels, paced)?;
        let (mut err_joint, at_rest) = (vec![0.0; nv], vec![0.0; nv]);
        let hold = TaskCommand::hold(reference.task[0].pos, reference.task[0].rot);
        let mut violation: Option<LimitViolation> = None;
        let (mut limit_ticks, mut stopped) = (0usize, false);
        let period = Duration::from_secs_f64(dt);
        let start = Instant::now();
        for k in 0..n {
            if k % STOP_CHECK_TICKS == STOP_CHECK_TICKS - 1 && stop() {
                return Err(Error::Invalid(format!("run interrupted at t = {:.3} s", k as f64 * dt)));
            }
            if paced {
                let deadline = start + period.mul_f64(k as f64);
                wait_until(deadline);
                log.lateness.push(Instant::now().saturating_duration_since(deadline).as_secs_f64());
            }
            let (cmd, joint) = if k < settle {
                let joint = reference.joint_command(0).map(|j| JointCommand { q: j.q, qd: &at_rest, qdd: &at_rest });
                (&hold, joint)
            } else {
                (&reference.task[k - settle], reference.joint_command(k - settle))
            };
            // the state at the tick's start
            log.t.push(k as f64 * dt);
            log.q.extend_from_slice(&self.plant.q);
            log.v.extend_from_slice(&self.plant.v);
            if let Some(j) = joint {
                self.plant.model().difference(&self.plant.q, j.q, &mut err_joint);
                log.err_joint.extend_from_slice(&err_joint);
            }
            let t0 = Instant::now();
            let out = match self.tick(cmd, joint) {
                Ok(out) => out,
                Err(Error::Invalid(msg)) => {
                    let t = k as f64 * dt;
                    let names = &self.controller.nominal.joint_names;
                    return Err(Error::Invalid(match &violation {
                        Some(v) => format!("{msg} (t = {t:.3} s), after exceeding a limit: {}", v.describe(names)),
                        None => format!("{msg} (t = {t:.3} s)"),
                    }));
                }
                Err(e) => return Err(e),
            };
            log.compute.push(t0.elapsed().as_secs_f64());
            let c = &self.controller;
            log.tau.extend_from_slice(&self.tau);
            log.tau_dis_hat.extend_from_slice(&self.observer.estimate);
            log.tau_dis.extend_from_slice(&self.tau_dis);
            log.pos_cmd.extend_from_slice(cmd.pos.as_slice());
            log.pos.extend_from_slice(c.pos.as_slice());
            for r in 0..3 {
                for cc in 0..3 {
                    log.rot.push(c.rot[(r, cc)]);
                }
            }
            log.err_pos.push(out.err_pos);
            log.err_rot.push(out.err_rot);
            log.vel.extend_from_slice(c.xd.as_slice());
            log.acc.extend_from_slice(self.acc.as_slice());
            log.det_j.push(out.det);
            log.damped.push(out.damped);
            log.saturated.push(out.saturated);
            log.torque_ratio.push(out.torque_ratio);
            log.velocity_ratio.push(out.velocity_ratio);
            log.payload.extend_from_slice(&self.payload_state);
            // the commanded torque (before a clip) and the speed at the tick's start
            let over = if out.torque_ratio > 1.0 || out.velocity_ratio > 1.0 {
                let v0 = &log.v[k * nv..(k + 1) * nv];
                self.limits.violation(k, k as f64 * dt, &self.controller.tau, v0)
            } else {
                None
            };
            if let Some(v) = over {
                limit_ticks += 1;
                violation.get_or_insert(v);
                if stop_at_limit {
                    stopped = true;
                    break;
                }
            }
        }
        let elapsed = start.elapsed().as_secs_f64();
        let n = log.t.len();
        log.n = n;
        let summary = summarize(&log, settle, elapsed, limit_ticks, stopped);
        Ok(Run { log, summary, limit_violation: violation, motion_start: settle, motion_end: settle + motion_len })
    }
}

/// The summary of a log (errors after `settle` ticks).
fn summarize(log: &Log, settle: usize, elapsed: f64, limit_ticks: usize, stopped: bool) -> Summary {
    let (n, nv) = (log.n, log.nv);
    let dt_of = |k: usize| log.t[k];
    let mut s = Summary {
        ticks: n,
        us_per_tick: elapsed / n.max(1) as f64 * 1e6,
        max_error_position: 0.0,
        max_error_rotation: 0.0,
        rms_error_position: 0.0,
        rms_error_rotation: 0.0,
        max_error_joint: if log.err_joint.is_empty() { f64::NAN } else { 0.0 },
        damped_ticks: 0,
        first_damped_time: None,
        min_abs_det_j: f64::INFINITY,
        saturated_ticks: 0,
        max_abs_tau: vec![0.0; nv],
        max_abs_v: vec![0.0; nv],
        max_torque_ratio: 0.0,
        max_velocity_ratio: 0.0,
        limit_ticks,
        stopped_at_limit: stopped,
    };
    let (mut se_p, mut se_r, mut cnt) = (0.0, 0.0, 0usize);
    for k in 0..n {
        if log.damped[k] {
            s.damped_ticks += 1;
            s.first_damped_time.get_or_insert(dt_of(k));
        }
        if log.saturated[k] {
            s.saturated_ticks += 1;
        }
        s.min_abs_det_j = s.min_abs_det_j.min(log.det_j[k].abs());
        for i in 0..nv {
            s.max_abs_tau[i] = s.max_abs_tau[i].max(log.tau[k * nv + i].abs());
            s.max_abs_v[i] = s.max_abs_v[i].max(log.v[k * nv + i].abs());
        }
        s.max_torque_ratio = s.max_torque_ratio.max(log.torque_ratio[k]);
        s.max_velocity_ratio = s.max_velocity_ratio.max(log.velocity_ratio[k]);
        if k >= settle {
            let (ep, er) = (log.err_pos[k], log.err_rot[k]);
            s.max_error_position = s.max_error_position.max(ep);
            s.max_error_rotation = s.max_error_rotation.max(er);
            se_p += ep * ep;
            se_r += er * er;
            cnt += 1;
            if !log.err_joint.is_empty() {
                for i in 0..nv {
                    s.max_error_joint = s.max_error_joint.max(log.err_joint[k * nv + i].abs());
                }
            }
        }
    }
    if cnt > 0 {
        s.rms_error_position = (se_p / cnt as f64).sqrt();
        s.rms_error_rotation = (se_r / cnt as f64).sqrt();
    }
    s
}

/// Wait for `deadline`: sleep while more than 2 ms are left, then spin. At 1 kHz this always
/// spins: waking from a sleep costs 0.1 ms or more on a loaded machine.
fn wait_until(deadline: Instant) {
    const SPIN: Duration = Duration::from_millis(2);
    loop {
        let now = Instant::now();
        if now >= deadline {
            return;
        }
        let left = deadline - now;
        if left > SPIN {
            std::thread::sleep(left - SPIN);
        } else {
            std::hint::spin_loop();
        }
    }
}

/// Percentile (0..=100) of a sample by linear interpolation (NaN for an empty one).
pub fn percentile(values: &[f64], pct: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut v = values.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    let x = pct.clamp(0.0, 100.0) / 100.0 * (v.len() - 1) as f64;
    let (i, f) = (x.floor() as usize, x - x.floor());
    if i + 1 < v.len() {
        v[i] * (1.0 - f) + v[i + 1] * f
    } else {
        v[i]
    }
}
