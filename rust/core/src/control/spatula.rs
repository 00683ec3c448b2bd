//! The seq2seq paper's experiment (Kutsuzawa et al. 2019, Section 5, Fig. 10) as one
//! configuration of the general loop: a task-space controller on the spatula frame, commanded by
//! eq. 23 from the paper's planar poses, the spatula a payload the controller knows, and the
//! pancake ([`PancakeOnSpatula`]) a payload with its own dynamics.
//!
//! # Task and attitude convention
//!
//! A spatula pose of the paper is `p = [y, z, theta]` in the vertical y-z plane; the command is
//! (eq. 23) `q_cmd = [0.5, y, z + 0.35, theta, pi/2, 0]`: position in metres in the robot's base
//! frame, then an attitude `[a, b, c]` read as intrinsic X-Y'-Z'' angles,
//! `R = Rx(a) Ry(b) Rz(c)`. With `b = pi/2` this is the only reading in which `theta` tilts the
//! spatula in the plane of the motion (about the world x axis); the fixed-axis roll-pitch-yaw
//! reading `Rz(c) Ry(b) Rx(a)` is at gimbal lock for `b = pi/2` and would turn `theta` into a
//! rotation about the vertical. So `R_cmd = Rx(theta) Ry(pi/2)`: the spatula frame's z axis points
//! along world +x (away from the robot, the handle direction), its y axis is the blade's in-plane
//! direction `[0, cos theta, sin theta]` and its -x axis the blade normal
//! `[0, -sin theta, cos theta]` (up for `theta = 0`). `theta` is counter-clockwise from +y, as in
//! `genplan.pancake.trajectories`.
//!
//! The spatula frame is the arm's tool flange frame (UR5: `tool0`, z along the flange axis)
//! moved by `spatula_length` along its z axis; its rotation is the flange's. So on the UR5 the
//! tilt `theta` is (up to the arm's small corrections) a rotation of the last wrist joint, and
//! the whole paper region `y, z in [-0.1, 0.1] m` (we check +-0.15), `theta in [-pi, pi]` is
//! reachable away from singularities with no base offset (see the tests).
//!
//! The commands' velocities and accelerations are backward differences of the poses (causal);
//! the paper's loop feeds no acceleration forward ([`ControllerSettings::paper`]).

use nalgebra::{DMatrix, Matrix3, Matrix6, Vector3, Vector6};

use crate::dynamics::{DynWorkspace, Dynamics};
use crate::error::{Error, Result};
use crate::lie::log3;

use super::controllers::TaskCommand;
use super::payloads::{Payload, PancakeOnSpatula, PancakeSettings};
use super::reference::Reference;
use super::run::{Run, SimConfig, Simulation};
use super::settings::{elements, within, ControlSpace, ControllerSettings, Disturbances, JointLimits, LimitPolicy, MAX_MASS, MAX_OFFSET};

/// A UR5 elbow-up posture with the flange pointing forward (world +x), near the paper's start
/// pose: the default first guess of the initial configuration.
const UR5_ELBOW_UP: [f64; 6] = [-0.35, -1.78, 1.94, -0.15, 1.22, -1.571];

/// Where the task lives on the arm (defaults: the paper's eq. 23 on the UR5).
#[derive(Debug, Clone, PartialEq)]
pub struct SpatulaSetup {
    /// The tool flange link.
    pub tool_link: String,
    /// Spatula point = flange frame moved this far along its z axis (m).
    pub spatula_length: f64,
    /// Nominal spatula (known to the controller and present in the plant): mass (kg) and centre
    /// of mass along the flange z axis (m); inertia of a thin rod along z.
    pub spatula_mass: f64,
    /// See `spatula_mass`.
    pub spatula_com: f64,
    /// `q_cmd[0..3] = origin + [0, y, z]` (the paper: [0.5, 0, 0.35]).
    pub origin: [f64; 3],
    /// `q_cmd[4], q_cmd[5]` (the paper: pi/2, 0); `q_cmd[3] = theta`.
    pub attitude: [f64; 2],
    /// First guess of the initial configuration, tried before deterministic restarts (default:
    /// the UR5's elbow-up posture with the flange forward; None: restarts only).
    pub q_seed: Option<Vec<f64>>,
}

impl Default for SpatulaSetup {
    fn default() -> Self {
        SpatulaSetup {
            tool_link: "tool0".into(),
            spatula_length: 0.1,
            spatula_mass: 0.2,
            spatula_com: 0.05,
            origin: [0.5, 0.0, 0.35],
            attitude: [std::f64::consts::FRAC_PI_2, 0.0],
            q_seed: Some(UR5_ELBOW_UP.to_vec()),
        }
    }
}

impl SpatulaSetup {
    /// Lengths and masses within their bounds, finite origin and attitude.
    pub fn validate(&self) -> Result<()> {
        within("setup.spatula_length", self.spatula_length, 0.0, MAX_OFFSET, " m")?;
        within("setup.spatula_mass", self.spatula_mass, 0.0, MAX_MASS, " kg")?;
        within("setup.spatula_com", self.spatula_com, -MAX_OFFSET, MAX_OFFSET, " m")?;
        elements("setup.origin", &self.origin, f64::NEG_INFINITY, f64::INFINITY)?;
        elements("setup.attitude", &self.attitude, f64::NEG_INFINITY, f64::INFINITY)?;
        if let Some(q) = &self.q_seed {
            elements("setup.q_seed", q, f64::NEG_INFINITY, f64::INFINITY)?;
        }
        if self.tool_link.is_empty() {
            return Err(super::settings::setting("setup.tool_link", "must be a link name".into()));
        }
        Ok(())
    }

    /// The controller of `base` made the spatula's: task space on the spatula point, every axis.
    pub fn controller(&self, base: &ControllerSettings) -> ControllerSettings {
        ControllerSettings {
            space: ControlSpace::Task,
            frame: Some(self.tool_link.clone()),
            frame_offset: [0.0, 0.0, self.spatula_length],
            axes: [1.0; 6],
            ..base.clone()
        }
    }

    /// The spatula as a payload the controller knows: a thin rod along the flange's z axis of
    /// length `2 spatula_com`.
    pub fn spatula(&self) -> Payload {
        let l = 2.0 * self.spatula_com.abs();
        let i_rod = self.spatula_mass * l * l / 12.0;
        Payload {
            link: Some(self.tool_link.clone()),
            mass: self.spatula_mass,
            com: [0.0, 0.0, self.spatula_com],
            inertia: [[i_rod, 0.0, 0.0], [0.0, i_rod, 0.0], [0.0, 0.0, 0.0]],
        }
    }

    /// The command pose of a paper pose `[y, z, theta]` (eq. 23).
    pub fn command_pose(&self, p: [f64; 3]) -> (Vector3<f64>, Matrix3<f64>) {
        (
            Vector3::new(self.origin[0], self.origin[1] + p[0], self.origin[2] + p[1]),
            attitude_matrix(p[2], self.attitude[0], self.attitude[1]),
        )
    }
}

/// `Rx(a) Ry(b) Rz(c)`: the attitude convention of `q_cmd` (intrinsic X-Y'-Z'').
pub fn attitude_matrix(a: f64, b: f64, c: f64) -> Matrix3<f64> {
    let rx = nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), a);
    let ry = nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), b);
    let rz = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), c);
    (rx * ry * rz).into_inner()
}

/// The reference plant deviations of genplan's reproduction of the seq2seq paper's experiment
/// (Section 5; they stand in for the unmodelled dynamics of the paper's real arm), for a 6-joint
/// arm: a 0.3 kg payload error at the spatula point (a pancake and a heavier spatula than
/// modelled), Coulomb friction 3/3/2/0.4/0.4/0.2 N m, viscous 2/2/1/0.15/0.15/0.05 N m s/rad, and
/// a constant torque offset 1.5/-2/1/0.3/-0.3/0.2 N m. The wrist values are small because the
/// URDF's wrist links are light (0.017 kg m^2 about the last axis, no rotor inertia).
pub fn reference_disturbances() -> Disturbances {
    Disturbances {
        coulomb: vec![3.0, 3.0, 2.0, 0.4, 0.4, 0.2],
        viscous: vec![2.0, 2.0, 1.0, 0.15, 0.15, 0.05],
        friction_velocity: 0.05,
        offset: vec![1.5, -2.0, 1.0, 0.3, -0.3, 0.2],
        payload: Some(Payload::point(0.3, [0.0; 3])),
    }
}

/// Everything the spatula configuration needs.
#[derive(Debug, Clone, PartialEq)]
pub struct SpatulaConfig {
    /// The controller's gains, observer and period (its frame and axes are the spatula's).
    pub controller: ControllerSettings,
    /// What the plant has that the controller's model lacks (a payload: at the spatula point).
    pub disturbances: Disturbances,
    /// Where the task lives on the arm.
    pub setup: SpatulaSetup,
    /// The pancake.
    pub pancake: PancakeSettings,
    /// RK4 steps per control period.
    pub substeps: usize,
    /// Ticks holding the first pose before the motion.
    pub settle_ticks: usize,
    /// The joint limits every tick is checked against (default: recorded, not enforced).
    pub limits: JointLimits,
}

impl Default for SpatulaConfig {
    /// The paper's loop, no disturbance, one RK4 step a tick, no settle phase; limits logged.
    fn default() -> Self {
        SpatulaConfig {
            controller: ControllerSettings::paper(),
            disturbances: Disturbances::default(),
            setup: SpatulaSetup::default(),
            pancake: PancakeSettings::default(),
            substeps: 1,
            settle_ticks: 0,
            limits: JointLimits { policy: LimitPolicy::Log, ..Default::default() },
        }
    }
}

/// The pancake's verdicts of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct PancakeSummary {
    /// Largest |phi| over the motion window (rad).
    pub max_abs_phi: f64,
    /// The pancake slid or left the spatula during the motion window.
    pub slipped: bool,
    /// Time (s) of the first tick the pancake was not stuck, over the whole run.
    pub first_slip_time: Option<f64>,
    /// Time (s) of the first tick the pancake was off the spatula.
    pub left_time: Option<f64>,
    /// Largest |s| (m) while on the spatula, over the motion window.
    pub max_abs_slide: f64,
}

/// A spatula run: the general loop's run (its log's payload channels are the pancake's:
/// [`PancakeOnSpatula::CHANNELS`]) and the pancake's verdicts.
#[derive(Debug, Clone)]
pub struct SpatulaRun {
    /// The run.
    pub run: Run,
    /// The pancake's verdicts.
    pub pancake: PancakeSummary,
}

/// The simulated arm with the spatula, its controller and the pancake.
pub struct Spatula {
    /// The general loop in the spatula configuration.
    pub sim: Simulation,
    config: SpatulaConfig,
    ws: DynWorkspace,
    jac: DMatrix<f64>,
}

impl Spatula {
    /// Build from the arm's dynamics (6 joints: a square task Jacobian); every setting checked.
    pub fn new(arm: &Dynamics, config: SpatulaConfig) -> Result<Spatula> {
        if arm.nv != 6 || arm.nq != 6 {
            return Err(Error::Invalid(format!(
                "the spatula configuration needs a 6-joint arm of revolute/prismatic joints (square task Jacobian); got nq={}, nv={}",
                arm.nq, arm.nv
            )));
        }
        config.setup.validate()?;
        config.pancake.validate()?;
        let sim_config = SimConfig {
            controller: config.setup.controller(&config.controller),
            disturbances: config.disturbances.clone(),
            payloads: vec![config.setup.spatula()],
            limits: config.limits.clone(),
            substeps: config.substeps,
        };
        let sim = Simulation::new(arm, sim_config)?.with_payload_dynamics(Box::new(PancakeOnSpatula::new(config.pancake, 0.0)));
        Ok(Spatula { ws: sim.controller.nominal.workspace(), jac: DMatrix::zeros(6, 6), sim, config })
    }

    /// The configuration it was built with.
    pub fn config(&self) -> &SpatulaConfig {
        &self.config
    }

    /// The command pose of a paper pose `[y, z, theta]` (eq. 23 with this setup).
    pub fn command_pose(&self, p: [f64; 3]) -> (Vector3<f64>, Matrix3<f64>) {
        self.config.setup.command_pose(p)
    }

    /// World pose of the spatula frame at q (checked).
    pub fn spatula_pose(&mut self, q: &[f64]) -> Result<(Vector3<f64>, Matrix3<f64>)> {
        let n = &self.sim.controller.nominal;
        n.check_state(q, None)?;
        n.update_kinematics_unchecked(q, None, &mut self.ws);
        let (r, p) = n.frame_placement(&self.sim.controller.frame, &self.ws);
        Ok((p, r))
    }

    fn jacobian_at(&mut self, q: &[f64]) -> Matrix6<f64> {
        let c = &self.sim.controller;
        c.nominal.update_kinematics_unchecked(q, None, &mut self.ws);
        c.nominal.frame_jacobians_from_kinematics(&c.frame, &self.ws, &mut self.jac, None);
        Matrix6::from_iterator(self.jac.iter().copied())
    }

    /// |det J| of the spatula frame's task Jacobian at q (0 at a singularity; m^3).
    pub fn jacobian_det(&mut self, q: &[f64]) -> Result<f64> {
        self.sim.controller.nominal.check_state(q, None)?;
        Ok(self.jacobian_at(q).determinant().abs())
    }

    /// Levenberg-Marquardt IK of the spatula frame (damping `lambda^2 = |e|^2 + 1e-12`, Sugihara
    /// 2011: quadratic convergence when reachable, no blow-up near singularities; steps capped
    /// at 0.5 rad so that it does not jump branches). Ok((q, iterations)) once position and
    /// attitude errors are below 1e-10, else an error with the residual.
    pub fn inverse_kinematics(&mut self, pos: &Vector3<f64>, rot: &Matrix3<f64>, seed: &[f64], max_iterations: usize) -> Result<(Vec<f64>, usize)> {
        self.sim.controller.nominal.check_state(seed, None)?;
        let mut q = seed.to_vec();
        let mut err = f64::INFINITY;
        for it in 0..max_iterations {
            let c = &self.sim.controller;
            c.nominal.update_kinematics_unchecked(&q, None, &mut self.ws);
            let (r, p) = c.nominal.frame_placement(&c.frame, &self.ws);
            let (w, _) = log3(&(rot * r.transpose()));
            let dp = pos - p;
            let e = Vector6::new(dp.x, dp.y, dp.z, w.x, w.y, w.z);
            err = dp.norm() + w.norm() * 0.1;
            if dp.norm() < 1e-10 && w.norm() < 1e-10 {
                return Ok((q, it));
            }
            c.nominal.frame_jacobians_from_kinematics(&c.frame, &self.ws, &mut self.jac, None);
            let j = Matrix6::from_iterator(self.jac.iter().copied());
            let lambda2 = dp.norm_squared() + w.norm_squared() + 1e-12;
            let a = j * j.transpose() + Matrix6::identity() * lambda2;
            let dq = match a.cholesky() {
                Some(c) => j.transpose() * c.solve(&e),
                None => break,
            };
            // limit the step so that Newton does not jump branches
            let scale = (0.5 / dq.amax()).min(1.0);
            for i in 0..6 {
                q[i] += dq[i] * scale;
            }
        }
        Err(Error::Invalid(format!(
            "inverse kinematics did not converge (residual {err:.3e} after {max_iterations} iterations)"
        )))
    }

    fn within_limits(&self, q: &[f64]) -> Option<usize> {
        let n = &self.sim.controller.nominal;
        (0..q.len()).find(|&i| q[i] < n.lower[i] - 1e-9 || q[i] > n.upper[i] + 1e-9)
    }

    /// The reference of a paper trajectory `[y, z, theta]` (rows of 3, one per `dt`). Checks
    /// shape, finiteness, and that every pose is reachable (IK along the trajectory,
    /// warm-started, within the joint limits). Returns the reference and the initial
    /// configuration (at rest at the first pose).
    pub fn prepare(&mut self, trajectory: &[f64]) -> Result<(Reference, Vec<f64>)> {
        if trajectory.len() % 3 != 0 || trajectory.len() < 6 {
            return Err(Error::Invalid(format!(
                "trajectory: expected rows [y, z, theta] (K >= 2 rows of 3 values), got {} values",
                trajectory.len()
            )));
        }
        if let Some(i) = trajectory.iter().position(|x| !x.is_finite()) {
            return Err(Error::NonFinite { what: format!("trajectory row {} (column {})", i / 3, i % 3), index: i, value: trajectory[i] });
        }
        let dt = self.sim.controller.settings.dt;
        let rows: Vec<[f64; 3]> = trajectory.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
        let (p0, r0) = self.command_pose(rows[0]);
        let nv = 6;
        let mut seeds: Vec<Vec<f64>> = Vec::new();
        if let Some(s) = self.config.setup.q_seed.clone() {
            crate::error::check_vector("setup.q_seed", &s, nv)?;
            seeds.push(s);
        }
        let mut state: u64 = 0x9E3779B97F4A7C15;
        for _ in 0..16 {
            let n = &self.sim.controller.nominal;
            let q: Vec<f64> = (0..nv)
                .map(|i| {
                    state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    let u = (state >> 11) as f64 / (1u64 << 53) as f64;
                    let (lo, hi) = (n.lower[i].max(-std::f64::consts::PI), n.upper[i].min(std::f64::consts::PI));
                    lo + u * (hi - lo)
                })
                .collect();
            seeds.push(q);
        }
        let mut q_init = None;
        let mut last_err = String::new();
        for s in &seeds {
            match self.inverse_kinematics(&p0, &r0, s, 200) {
                Ok((q, _)) if self.within_limits(&q).is_none() => {
                    q_init = Some(q);
                    break;
                }
                Ok((q, _)) => {
                    let i = self.within_limits(&q).unwrap_or(0);
                    last_err = format!("solution outside the joint limits ({})", self.sim.controller.nominal.joint_names[i]);
                }
                Err(e) => last_err = e.to_string(),
            }
        }
        let q_init = q_init.ok_or_else(|| {
            Error::Invalid(format!(
                "trajectory row 0 (y={:.4}, z={:.4}, theta={:.4}): the spatula pose {:?} is not reachable: {last_err}",
                rows[0][0], rows[0][1], rows[0][2], p0.as_slice()
            ))
        })?;
        // reachability of every sample, tracking the IK solution along the trajectory
        self.track_ik(&rows, &q_init)?;
        // commands with backward differences (causal)
        let mut cmds = Vec::with_capacity(rows.len());
        let mut prev: Option<(Vector3<f64>, Matrix3<f64>, Vector6<f64>)> = None;
        for row in &rows {
            let (p, r) = self.command_pose(*row);
            let (vel, acc) = match prev {
                None => (Vector6::zeros(), Vector6::zeros()),
                Some((pp, rp, vp)) => {
                    let dp = (p - pp) / dt;
                    let (w, _) = log3(&(r * rp.transpose()));
                    let w = w / dt;
                    let vel = Vector6::new(dp.x, dp.y, dp.z, w.x, w.y, w.z);
                    (vel, (vel - vp) / dt)
                }
            };
            cmds.push(TaskCommand { pos: p, rot: r, vel, acc });
            prev = Some((p, r, vel));
        }
        Ok((Reference::from_task(cmds)?, q_init))
    }

    /// IK solutions of every row of a paper trajectory, each warm-started from the previous
    /// one (row 0 from `q_init`); an error names the first row that cannot be reached within
    /// the joint limits.
    pub fn track_ik(&mut self, rows: &[[f64; 3]], q_init: &[f64]) -> Result<Vec<Vec<f64>>> {
        let dt = self.sim.controller.settings.dt;
        let mut q = q_init.to_vec();
        let mut out = Vec::with_capacity(rows.len());
        for (k, row) in rows.iter().enumerate() {
            let (p, r) = self.command_pose(*row);
            match self.inverse_kinematics(&p, &r, &q, 100) {
                Ok((qk, _)) => {
                    if let Some(i) = self.within_limits(&qk) {
                        let n = &self.sim.controller.nominal;
                        return Err(Error::Invalid(format!(
                            "trajectory row {k} (t={:.3} s, y={:.4}, z={:.4}, theta={:.4}): reaching it needs joint '{}' = {:.3} outside its limits [{:.3}, {:.3}]",
                            k as f64 * dt, row[0], row[1], row[2], n.joint_names[i], qk[i], n.lower[i], n.upper[i]
                        )));
                    }
                    q = qk;
                    out.push(q.clone());
                }
                Err(e) => {
                    return Err(Error::Invalid(format!(
                        "trajectory row {k} (t={:.3} s, y={:.4}, z={:.4}, theta={:.4}): the spatula pose {:?} is not reachable: {e}",
                        k as f64 * dt, row[0], row[1], row[2], p.as_slice()
                    )))
                }
            }
        }
        Ok(out)
    }

    /// Execute a paper trajectory (see [`prepare`](Self::prepare)) after the configuration's
    /// settle ticks. `motion_len`: how many rows are the motion proper (the rest is a tail,
    /// e.g. the paper's deceleration; None: all). `paced`: tick on the wall clock.
    pub fn run(&mut self, trajectory: &[f64], motion_len: Option<usize>, paced: bool) -> Result<SpatulaRun> {
        self.run_with(trajectory, motion_len, paced, false, &mut || false)
    }

    /// As [`run`](Self::run), asking `stop` every [`super::STOP_CHECK_TICKS`] ticks whether to
    /// abandon the run (e.g. on Ctrl-C). `stop_at_limit`: end the run after the first tick over
    /// a joint limit (the log ends with that tick).
    pub fn run_with(&mut self, trajectory: &[f64], motion_len: Option<usize>, paced: bool, stop_at_limit: bool, stop: &mut dyn FnMut() -> bool) -> Result<SpatulaRun> {
        let rows = trajectory.len() / 3;
        let settle = self.config.settle_ticks;
        if rows.saturating_add(settle) > super::MAX_TICKS {
            return Err(Error::Invalid(format!(
                "a run is limited to {} ticks; got {rows} trajectory rows + {settle} settle ticks",
                super::MAX_TICKS
            )));
        }
        let (reference, q0) = self.prepare(trajectory)?;
        let initial_tilt = trajectory[2];
        self.sim.payload = Some(Box::new(PancakeOnSpatula::new(self.config.pancake, initial_tilt)));
        let run = self.sim.run_with(&reference, &q0, settle, motion_len, paced, stop_at_limit, stop)?;
        let pancake = pancake_summary(&run);
        Ok(SpatulaRun { run, pancake })
    }
}

/// The pancake's verdicts from a run's payload channels.
fn pancake_summary(run: &Run) -> PancakeSummary {
    let log = &run.log;
    let k = log.channels.len();
    let mut s = PancakeSummary { max_abs_phi: 0.0, slipped: false, first_slip_time: None, left_time: None, max_abs_slide: 0.0 };
    for (tick, row) in log.payload.chunks(k.max(1)).enumerate().take(log.n) {
        let (phi, slide, mode) = (row[1], row[2], row[4]);
        let t = log.t[tick];
        if mode != 0.0 {
            s.first_slip_time.get_or_insert(t);
        }
        if mode == 2.0 {
            s.left_time.get_or_insert(t);
        }
        if tick >= run.motion_start && tick < run.motion_end {
            s.max_abs_phi = s.max_abs_phi.max(phi.abs());
            if mode != 0.0 {
                s.slipped = true;
            }
            if mode != 2.0 {
                s.max_abs_slide = s.max_abs_slide.max(slide.abs());
            }
        }
    }
    s
}
