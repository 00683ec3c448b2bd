//! The 1 kHz spatula controller of the seq2seq paper (Kutsuzawa et al. 2019, Section 5, Fig. 10)
//! on a simulated arm, with the pancake's stick/slip on the spatula.
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
//! # Controller (Fig. 10), every `dt` = 1 ms
//!
//! * task error `e = [p_cmd - p; log3(R_cmd R^T)]` (world axes), velocity error
//!   `de = [v_cmd - v; w_cmd - w]` with the command's velocity from a backward difference
//!   (causal; `velocity_feedforward = false` uses `-[v; w]` instead);
//! * `xdd_ref = Kp e + Kv de` (+ the command's backward-difference acceleration when
//!   `acceleration_feedforward`), `Kp = diag(Kpp x3, Kpr x3)`, `Kv = diag(Kvp x3, Kvr x3)`;
//! * `qdd_ref = J^-1 (xdd_ref - dJ/dt v)`; near a singularity (`|det J| < singular_det`) damped
//!   least squares `J^T (J J^T + lambda^2 I)^-1` with `lambda^2 = max_damping^2 (1 - |det J| /
//!   singular_det)^2` (Nakamura and Hanafusa), counted and reported;
//! * `tau_ref = M_n(q) qdd_ref + h_n(q, v) + tau_dis_hat` with the nominal model `M_n`, `h_n`
//!   (URDF arm + spatula; `model_compensation = false` drops `h_n` so the DOB must absorb it);
//! * disturbance observer: `tau_dis_hat[k] = a tau_dis_hat[k-1] + (1 - a) d[k]`,
//!   `a = exp(-2 pi f_c dt)` (the first-order low-pass `2 pi f_c / (s + 2 pi f_c)` discretised
//!   exactly for a piecewise-constant input), where `d[k] = tau[k-1] - h_n[k-1] -
//!   M_n[k-1] (v[k] - v[k-1]) / dt` is the torque of the last period that the nominal model does
//!   not explain (the pseudo-differentiation form of Ohnishi's DOB: no acceleration sensor).
//!   The observer always runs (its estimate is logged); `dob` decides whether it is fed back.
//!
//! # Plant
//!
//! The true arm (URDF + spatula + `payload_mass` the controller does not know) with joint
//! friction `-(coulomb tanh(v / v_s) + viscous v)` and a constant torque offset, integrated with
//! classical RK4 (`substeps` per period) under the zero-order-held torque.
//!
//! # Pancake
//!
//! A point mass on the blade at signed distance `s` from the spatula point, in the y-z plane,
//! with Coulomb friction (`mu_static`, `mu_kinetic`, the paper's `mu = 1`). In the spatula frame
//! (tangent `t = [cos theta, sin theta]`, normal `n = [-sin theta, cos theta]`) with the achieved
//! spatula acceleration `a`, tilt rate `w` and angular acceleration `dw`, per unit mass:
//! normal force `N = (a - g).n + 2 ds w + s dw`; while stuck the needed tangential force is
//! `F = (a - g).t - s w^2` and it stays stuck while `|F| <= mu_static N`; sliding obeys
//! `dds = (g - a).t + s w^2 - mu_kinetic N sign(ds)`. `N <= 0` is a lift-off and `|s|` past the
//! blade's half length a fall: the pancake has left the spatula (the intended end of a flip).
//! At `s = 0` the stick condition is the paper's `|phi| <= arctan(mu)` (eq. 15).
//!
//! # Joint limits
//!
//! Every tick's applied torque and joint speed are checked against the robot's rated limits
//! ([`JointLimits`]; by default the URDF's `<limit effort velocity>`, see
//! [`Dynamics::effort_limit`]). A run that exceeds them is reported
//! ([`Summary::limit_violation`]: the first tick, joint and value); asked to
//! (`stop_at_limit`), the run stops at that tick instead.

use std::time::{Duration, Instant};

use nalgebra::{DMatrix, Isometry3, Matrix3, Matrix6, Translation3, UnitQuaternion, Vector3, Vector6};

use crate::dynamics::{DynWorkspace, Dynamics, Frame};
use crate::error::{Error, Result};
use crate::lie::log3;

/// The paper's gains, Section 5.1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gains {
    /// Position stiffness `Kpp` (1/s^2).
    pub kpp: f64,
    /// Rotation stiffness `Kpr` (1/s^2).
    pub kpr: f64,
    /// Position damping `Kvp` (1/s).
    pub kvp: f64,
    /// Rotation damping `Kvr` (1/s).
    pub kvr: f64,
}

impl Default for Gains {
    fn default() -> Self {
        Gains { kpp: 450.0, kpr: 700.0, kvp: 60.0, kvr: 90.0 }
    }
}

/// Controller settings (defaults: the paper's).
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerConfig {
    /// The P-D gains.
    pub gains: Gains,
    /// Control period (s).
    pub dt: f64,
    /// Feed the disturbance estimate back.
    pub dob: bool,
    /// Cut-off frequency of the DOB's low-pass filter (Hz).
    pub dob_cutoff_hz: f64,
    /// Add the nominal bias torque `h_n(q, v)` (Coriolis, centrifugal, gravity).
    pub model_compensation: bool,
    /// D term on `v_cmd - v` (true) or on `-v` (false).
    pub velocity_feedforward: bool,
    /// Add the command's acceleration to the reference.
    pub acceleration_feedforward: bool,
    /// `|det J|` below which the inverse is damped (m^3; det J does not depend on the point or
    /// the axes it is expressed in).
    pub singular_det: f64,
    /// Largest damping `lambda` of the damped least squares.
    pub max_damping: f64,
    /// Symmetric torque limits per joint (None: unlimited).
    pub torque_limit: Option<Vec<f64>>,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        ControllerConfig {
            gains: Gains::default(),
            dt: 1e-3,
            dob: true,
            dob_cutoff_hz: 2.0,
            model_compensation: true,
            velocity_feedforward: true,
            acceleration_feedforward: false,
            singular_det: 1e-3,
            max_damping: 0.05,
            torque_limit: None,
        }
    }
}

/// Unmodelled effects of the true plant (all zero by default).
#[derive(Debug, Clone, PartialEq)]
pub struct Disturbances {
    /// Coulomb friction per joint (N m), smoothed as `coulomb tanh(v / friction_velocity)`.
    pub coulomb: Vec<f64>,
    /// Viscous friction per joint (N m s / rad).
    pub viscous: Vec<f64>,
    /// Velocity scale of the smoothed Coulomb friction (rad/s).
    pub friction_velocity: f64,
    /// Constant torque added to the commanded one (N m).
    pub offset: Vec<f64>,
    /// Extra mass at the spatula the controller does not know (kg).
    pub payload_mass: f64,
    /// Its centre of mass in the spatula frame (m).
    pub payload_com: [f64; 3],
}

impl Disturbances {
    /// No disturbance on an arm of `nv` joints.
    pub fn none(nv: usize) -> Self {
        Disturbances {
            coulomb: vec![0.0; nv],
            viscous: vec![0.0; nv],
            friction_velocity: 0.05,
            offset: vec![0.0; nv],
            payload_mass: 0.0,
            payload_com: [0.0; 3],
        }
    }

    /// The reference plant deviations of genplan's reproduction of the seq2seq paper's
    /// experiment (Section 5; they stand in for the unmodelled dynamics of the paper's real arm),
    /// for a 6-joint arm: a 0.3 kg payload error at the spatula (a pancake and a heavier spatula
    /// than modelled), Coulomb friction 3/3/2/0.4/0.4/0.2 N m, viscous 2/2/1/0.15/0.15/0.05
    /// N m s/rad, and a constant torque offset 1.5/-2/1/0.3/-0.3/0.2 N m. The wrist values are
    /// small because the URDF's wrist links are light (0.017 kg m^2 about the last axis, no rotor
    /// inertia). Public API, not a test fixture: Python calls it as
    /// `genplan.control.Disturbances.reference()` (`genplan bench control`, the README).
    pub fn reference() -> Self {
        Disturbances {
            coulomb: vec![3.0, 3.0, 2.0, 0.4, 0.4, 0.2],
            viscous: vec![2.0, 2.0, 1.0, 0.15, 0.15, 0.05],
            friction_velocity: 0.05,
            offset: vec![1.5, -2.0, 1.0, 0.3, -0.3, 0.2],
            payload_mass: 0.3,
            payload_com: [0.0, 0.0, 0.0],
        }
    }

    fn check(&self, nv: usize) -> Result<()> {
        setting_vector("disturbances.coulomb", &self.coulomb, nv, 0.0)?;
        setting_vector("disturbances.viscous", &self.viscous, nv, 0.0)?;
        setting_vector("disturbances.offset", &self.offset, nv, f64::NEG_INFINITY)?;
        positive("disturbances.friction_velocity", self.friction_velocity)?;
        within("disturbances.payload_mass", self.payload_mass, 0.0, MAX_MASS, " kg")?;
        setting_vector("disturbances.payload_com", &self.payload_com, 3, f64::NEG_INFINITY)?;
        let d = Vector3::from(self.payload_com).norm();
        if d > MAX_OFFSET {
            return Err(setting("disturbances.payload_com", format!("must lie within {MAX_OFFSET} m of the spatula point, got {d:.3} m")));
        }
        Ok(())
    }
}

/// Largest mass a configuration may give the spatula or the payload (kg): beyond it the arm
/// model (a 5 kg payload UR5) means nothing.
pub const MAX_MASS: f64 = 100.0;

/// Largest distance (m) of the payload's centre of mass from the spatula point, and largest
/// spatula length.
pub const MAX_OFFSET: f64 = 1.0;

fn setting(field: &'static str, msg: String) -> Error {
    Error::Settings { field, msg }
}

/// `x` finite and > 0.
fn positive(field: &'static str, x: f64) -> Result<()> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(setting(field, format!("must be finite and > 0, got {x}")))
    }
}

/// `x` finite and in `[lo, hi]` (`unit`: of the bounds, for the message).
fn within(field: &'static str, x: f64, lo: f64, hi: f64, unit: &str) -> Result<()> {
    if x.is_finite() && x >= lo && x <= hi {
        Ok(())
    } else if hi.is_finite() {
        Err(setting(field, format!("must be finite and in [{lo}, {hi}]{unit}, got {x}")))
    } else {
        Err(setting(field, format!("must be finite and >= {lo}, got {x}")))
    }
}

/// `values` of length `n`, each finite and `>= min`.
fn setting_vector(field: &'static str, values: &[f64], n: usize, min: f64) -> Result<()> {
    if values.len() != n {
        return Err(setting(field, format!("must have length {n}, got {}", values.len())));
    }
    match values.iter().position(|&x| !(x.is_finite() && x >= min)) {
        None => Ok(()),
        Some(i) if values[i].is_finite() => Err(setting(field, format!("element {i} must be >= {min}, got {}", values[i]))),
        Some(i) => Err(setting(field, format!("element {i} must be finite, got {}", values[i]))),
    }
}

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
    /// First guess of the initial configuration (None: the preset's, then deterministic
    /// restarts).
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
            q_seed: None,
        }
    }
}

/// Longest run in ticks (10^7: 2.8 hours at 1 kHz; the log of a run takes ~600 bytes a tick).
pub const MAX_TICKS: usize = 10_000_000;

/// How often [`Simulation::run_with`] asks whether to stop.
pub const STOP_CHECK_TICKS: usize = 250;

/// A UR5 elbow-up posture with the flange pointing forward (world +x), near the paper's start pose.
pub const UR5_SEED: [f64; 6] = [-0.35, -1.78, 1.94, -0.15, 1.22, -1.571];

/// Pancake model settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PancakeConfig {
    /// Static friction coefficient (the paper's mu = 1).
    pub mu_static: f64,
    /// Kinetic friction coefficient.
    pub mu_kinetic: f64,
    /// Half the blade's length along its in-plane direction (m): past it the pancake falls.
    pub blade_half_length: f64,
}

impl Default for PancakeConfig {
    fn default() -> Self {
        PancakeConfig { mu_static: 1.0, mu_kinetic: 1.0, blade_half_length: 0.06 }
    }
}

/// The rated joint limits a run is checked against (see the module docs, "Joint limits").
#[derive(Debug, Clone, PartialEq, Default)]
pub struct JointLimits {
    /// Largest |torque| per joint (N m; N for a prismatic joint); None: the robot model's
    /// ([`Dynamics::effort_limit`]). `inf` leaves a joint unchecked.
    pub torque: Option<Vec<f64>>,
    /// Largest |speed| per joint (rad/s; m/s); None: the robot model's
    /// ([`Dynamics::velocity_limit`]). `inf` leaves a joint unchecked.
    pub velocity: Option<Vec<f64>>,
}

impl JointLimits {
    /// The limits in force on `arm`: the given ones, else the arm's.
    fn resolve(&self, arm: &Dynamics) -> (Vec<f64>, Vec<f64>) {
        (
            self.torque.clone().unwrap_or_else(|| arm.effort_limit.clone()),
            self.velocity.clone().unwrap_or_else(|| arm.velocity_limit.clone()),
        )
    }

    fn check(&self, nv: usize) -> Result<()> {
        for (field, v) in [("limits.torque", &self.torque), ("limits.velocity", &self.velocity)] {
            if let Some(v) = v {
                if v.len() != nv {
                    return Err(setting(field, format!("must have length {nv}, got {}", v.len())));
                }
                if let Some(i) = v.iter().position(|&x| x.is_nan() || x <= 0.0) {
                    return Err(setting(field, format!("element {i} must be > 0 (inf: unchecked), got {}", v[i])));
                }
            }
        }
        Ok(())
    }
}

/// Which limit a tick exceeded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LimitKind {
    /// The applied torque (force).
    Torque,
    /// The joint speed.
    Velocity,
}

/// The first tick of a run that exceeded a joint limit (the joint furthest over its limit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LimitViolation {
    /// Time of the tick from the start of the run (s; the settle phase included).
    pub time: f64,
    /// Index of the tick.
    pub tick: usize,
    /// Index of the joint (v order).
    pub joint: usize,
    /// Torque or speed.
    pub kind: LimitKind,
    /// The signed torque or speed.
    pub value: f64,
    /// The limit it exceeded.
    pub limit: f64,
    /// The unit of both ("N m", "rad/s", "N", "m/s").
    pub unit: &'static str,
}

impl LimitViolation {
    /// "torque" or "velocity".
    pub fn quantity(&self) -> &'static str {
        match self.kind {
            LimitKind::Torque => "torque",
            LimitKind::Velocity => "velocity",
        }
    }

    /// One sentence naming the joint (from `joint_names`), the time, the value and the limit.
    pub fn describe(&self, joint_names: &[String]) -> String {
        let name = joint_names.get(self.joint).map_or("?", String::as_str);
        let (q, u) = (self.quantity(), self.unit);
        let (value, limit) = (self.value.abs(), self.limit);
        // about 3 significant digits, more where the two would print the same
        let mut d: usize = match limit {
            x if x >= 100.0 => 0,
            x if x >= 10.0 => 1,
            x if x >= 1.0 => 2,
            _ => 3,
        };
        while d < 9 && format!("{value:.d$}") == format!("{limit:.d$}") {
            d += 1;
        }
        format!("joint '{name}' exceeds its {q} limit at t = {:.3} s: |{q}| = {value:.d$} {u} > {limit:.d$} {u}", self.time)
    }
}

/// Everything a run needs.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// The controller.
    pub controller: ControllerConfig,
    /// What the plant has that the controller's model lacks.
    pub disturbances: Disturbances,
    /// Where the task lives on the arm.
    pub setup: SpatulaSetup,
    /// The pancake.
    pub pancake: PancakeConfig,
    /// RK4 steps per control period.
    pub substeps: usize,
    /// Ticks holding the first pose before the motion (the DOB settles; the paper's robot
    /// held still for 25 s).
    pub settle_ticks: usize,
    /// The joint limits every tick is checked against.
    pub limits: JointLimits,
}

impl SimConfig {
    /// The defaults for an arm of `nv` joints (no disturbance, one RK4 step a tick, no settle).
    pub fn new(nv: usize) -> Self {
        SimConfig {
            controller: ControllerConfig::default(),
            disturbances: Disturbances::none(nv),
            setup: SpatulaSetup::default(),
            pancake: PancakeConfig::default(),
            substeps: 1,
            settle_ticks: 0,
            limits: JointLimits::default(),
        }
    }

    /// Check every value (the error, [`Error::Settings`], names the field): positive and finite
    /// period, cut-off and blade; non-negative gains, damping, friction; masses in
    /// `[0, MAX_MASS]` kg; vectors of the arm's length; 1..=1000 substeps.
    pub fn check(&self, nv: usize) -> Result<()> {
        let c = &self.controller;
        let nonneg = |field: &'static str, x: f64| within(field, x, 0.0, f64::INFINITY, "");
        positive("controller.dt", c.dt)?;
        positive("controller.dob_cutoff_hz", c.dob_cutoff_hz)?;
        nonneg("controller.gains.kpp", c.gains.kpp)?;
        nonneg("controller.gains.kpr", c.gains.kpr)?;
        nonneg("controller.gains.kvp", c.gains.kvp)?;
        nonneg("controller.gains.kvr", c.gains.kvr)?;
        nonneg("controller.singular_det", c.singular_det)?;
        nonneg("controller.max_damping", c.max_damping)?;
        if let Some(l) = &c.torque_limit {
            setting_vector("controller.torque_limit", l, nv, 0.0)?;
            if let Some(i) = l.iter().position(|&x| x <= 0.0) {
                return Err(setting("controller.torque_limit", format!("element {i} must be > 0, got {}", l[i])));
            }
        }
        self.disturbances.check(nv)?;
        let s = &self.setup;
        within("setup.spatula_length", s.spatula_length, 0.0, MAX_OFFSET, " m")?;
        within("setup.spatula_mass", s.spatula_mass, 0.0, MAX_MASS, " kg")?;
        within("setup.spatula_com", s.spatula_com, -MAX_OFFSET, MAX_OFFSET, " m")?;
        setting_vector("setup.origin", &s.origin, 3, f64::NEG_INFINITY)?;
        setting_vector("setup.attitude", &s.attitude, 2, f64::NEG_INFINITY)?;
        let p = &self.pancake;
        nonneg("pancake.mu_static", p.mu_static)?;
        nonneg("pancake.mu_kinetic", p.mu_kinetic)?;
        positive("pancake.blade_half_length", p.blade_half_length)?;
        if self.substeps == 0 || self.substeps > 1000 {
            return Err(setting("substeps", format!("must be in 1..=1000, got {}", self.substeps)));
        }
        self.limits.check(nv)
    }
}

/// `Rx(a) Ry(b) Rz(c)`: the attitude convention of `q_cmd` (intrinsic X-Y'-Z'').
pub fn attitude_matrix(a: f64, b: f64, c: f64) -> Matrix3<f64> {
    let rx = nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), a);
    let ry = nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), b);
    let rz = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), c);
    (rx * ry * rz).into_inner()
}

/// eq. 16 with the convention of `genplan.pancake.trajectories.phi`:
/// `wrap(atan2(-g - a_z, -a_y) + pi/2 - theta)` in (-pi, pi].
pub fn phi(theta: f64, a_y: f64, a_z: f64, g: f64) -> f64 {
    wrap_angle((-g - a_z).atan2(-a_y) + std::f64::consts::FRAC_PI_2 - theta)
}

/// An angle wrapped to (-pi, pi].
pub fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::PI;
    let w = (a + PI).rem_euclid(2.0 * PI) - PI;
    if w <= -PI {
        w + 2.0 * PI
    } else {
        w
    }
}

/// One sample of the command: pose, velocity, acceleration (world axes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Command {
    /// Position of the spatula point.
    pub pos: Vector3<f64>,
    /// Attitude of the spatula frame.
    pub rot: Matrix3<f64>,
    /// Velocity (linear, angular).
    pub vel: Vector6<f64>,
    /// Acceleration (linear, angular).
    pub acc: Vector6<f64>,
    /// The paper's pose `[y, z, theta]` it came from.
    pub paper: [f64; 3],
}

/// State of the pancake.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PancakeMode {
    /// Moving with the blade.
    Stuck,
    /// Sliding along the blade.
    Sliding,
    /// Lifted off or slid past the blade's end: no longer on the spatula.
    Off,
}

/// The pancake on the blade (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pancake {
    /// Its friction and the blade's length.
    pub config: PancakeConfig,
    /// Stuck, sliding or off.
    pub mode: PancakeMode,
    /// Signed position along the blade from the spatula point (m).
    pub s: f64,
    /// Rate of `s` (m/s).
    pub ds: f64,
    /// Normal force per unit mass of the last step (m/s^2).
    pub normal: f64,
}

/// In-plane motion of the spatula point at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarMotion {
    /// Tilt of the blade, counter-clockwise from +y (rad).
    pub theta: f64,
    /// Tilt rate (rad/s).
    pub w: f64,
    /// Tilt acceleration (rad/s^2).
    pub dw: f64,
    /// Acceleration along y (m/s^2).
    pub a_y: f64,
    /// Acceleration along z (m/s^2).
    pub a_z: f64,
}

impl Pancake {
    /// A pancake stuck at the spatula point.
    pub fn new(config: PancakeConfig) -> Self {
        Pancake { config, mode: PancakeMode::Stuck, s: 0.0, ds: 0.0, normal: 0.0 }
    }

    /// Advance by `dt` under the spatula motion `m`, gravity `g = [g_y, g_z]`.
    pub fn step(&mut self, m: &PlanarMotion, g: [f64; 2], dt: f64) {
        if self.mode == PancakeMode::Off {
            return;
        }
        let (st, ct) = m.theta.sin_cos();
        let t = [ct, st];
        let n = [-st, ct];
        let rel = [m.a_y - g[0], m.a_z - g[1]];
        let rel_n = rel[0] * n[0] + rel[1] * n[1];
        let rel_t = rel[0] * t[0] + rel[1] * t[1];
        let c = &self.config;
        let normal = rel_n + 2.0 * self.ds * m.w + self.s * m.dw;
        self.normal = normal;
        if normal <= 0.0 {
            self.mode = PancakeMode::Off;
            return;
        }
        // tangential force needed to move with the spatula (at the current ds)
        let f_req = rel_t - self.s * m.w * m.w;
        match self.mode {
            PancakeMode::Stuck => {
                if f_req.abs() <= c.mu_static * normal {
                    self.ds = 0.0;
                } else {
                    self.mode = PancakeMode::Sliding;
                    // the pancake tends to move at -f_req relative to the blade; friction opposes it
                    let dds = -f_req + c.mu_kinetic * normal * f_req.signum();
                    self.ds += dds * dt;
                    self.s += self.ds * dt;
                }
            }
            PancakeMode::Sliding => {
                let dir = if self.ds != 0.0 { self.ds.signum() } else { -f_req.signum() };
                let dds = -f_req - c.mu_kinetic * normal * dir;
                let ds_new = self.ds + dds * dt;
                if self.ds != 0.0 && ds_new.signum() != self.ds.signum() && f_req.abs() <= c.mu_static * normal {
                    self.ds = 0.0;
                    self.mode = PancakeMode::Stuck;
                } else {
                    self.ds = ds_new;
                    self.s += self.ds * dt;
                }
            }
            PancakeMode::Off => {}
        }
        if self.s.abs() > c.blade_half_length {
            self.mode = PancakeMode::Off;
        }
    }
}

/// What one tick produced (the state at the tick's start and the torque it applied).
#[derive(Debug, Clone, Copy)]
pub struct TickOutput {
    /// Position of the spatula point.
    pub pos: Vector3<f64>,
    /// Attitude of the spatula frame.
    pub rot: Matrix3<f64>,
    /// The torque applied over the tick (after the limits).
    pub tau: Vector6<f64>,
    /// The DOB's disturbance estimate.
    pub tau_dis_hat: Vector6<f64>,
    /// The torque the nominal model does not explain, `tau - M_n qdd - h_n` (what the DOB sees).
    pub tau_dis: Vector6<f64>,
    /// Achieved spatula acceleration (linear, angular; world axes).
    pub acc: Vector6<f64>,
    /// Spatula velocity (linear, angular; world axes).
    pub vel: Vector6<f64>,
    /// Norm of the position error (m).
    pub err_pos: f64,
    /// Norm of the attitude error (rad).
    pub err_rot: f64,
    /// The paper's phi (eq. 16) of the achieved motion.
    pub phi: f64,
    /// The achieved tilt theta, unwrapped along the run (rad).
    pub tilt: f64,
    /// det J of the task Jacobian (m^3).
    pub det_j: f64,
    /// The inverse of J was damped (near a singularity).
    pub damped: bool,
    /// A torque limit clipped the torque.
    pub saturated: bool,
    /// The pancake after the tick.
    pub pancake: Pancake,
}

/// The simulated arm, its controller and the pancake. The configuration is fixed at
/// construction (the models are built from it): make a new `Simulation` to change it.
pub struct Simulation {
    config: SimConfig,
    /// The controller's model: the arm and the spatula.
    pub nominal: Dynamics,
    /// The true arm: the nominal model plus the payload.
    pub plant: Dynamics,
    /// The spatula frame.
    pub frame: Frame,
    nv: usize,
    ws_n: DynWorkspace,
    ws_p: DynWorkspace,
    /// Plant state: joint positions.
    pub q: [f64; 6],
    /// Plant state: joint velocities.
    pub v: [f64; 6],
    // controller memory
    prev_tau: Vector6<f64>,
    prev_h: Vector6<f64>,
    prev_m: Matrix6<f64>,
    prev_v: Vector6<f64>,
    has_prev: bool,
    /// The DOB's disturbance estimate.
    pub tau_dis_hat: Vector6<f64>,
    /// The pancake.
    pub pancake: Pancake,
    jac: DMatrix<f64>,
    djac: DMatrix<f64>,
    tilt_prev: Option<f64>,
    /// Ticks since the last reset.
    pub ticks: u64,
    torque_limits: Vec<f64>,
    velocity_limits: Vec<f64>,
    limit_units: Vec<(&'static str, &'static str)>,
}

/// Summary numbers of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Ticks run (settle phase included).
    pub ticks: usize,
    /// Wall time of the loop divided by the ticks (us): unpaced, this is the cost of one tick.
    pub us_per_tick: f64,
    /// Largest position error (m) over the executed trajectory (after the settle phase).
    pub max_err_pos: f64,
    /// Largest attitude error (rad), likewise.
    pub max_err_rot: f64,
    /// RMS position error (m), likewise.
    pub rms_err_pos: f64,
    /// RMS attitude error (rad), likewise.
    pub rms_err_rot: f64,
    /// Largest |phi| over the motion window.
    pub max_abs_phi: f64,
    /// The pancake slid or left the spatula during the motion window.
    pub slipped: bool,
    /// Time (s) of the first tick the pancake was not stuck, over the whole run.
    pub first_slip_time: Option<f64>,
    /// Time (s) of the first tick the pancake was off the spatula.
    pub left_time: Option<f64>,
    /// Largest |s| (m) while on the spatula, over the motion window.
    pub max_abs_slide: f64,
    /// Ticks with a damped inverse of J.
    pub damped_ticks: usize,
    /// Time (s) of the first of them.
    pub first_damped_time: Option<f64>,
    /// Smallest |det J| (m^3).
    pub min_abs_det_j: f64,
    /// Ticks where a torque limit clipped the torque.
    pub saturated_ticks: usize,
    /// Largest |torque| per joint (N m).
    pub max_abs_tau: Vec<f64>,
    /// Largest |joint speed| per joint (rad/s).
    pub max_abs_v: Vec<f64>,
    /// The first tick that exceeded a joint limit (None: the run stayed within them).
    pub limit_violation: Option<LimitViolation>,
    /// Ticks that exceeded a joint limit.
    pub limit_ticks: usize,
    /// The run stopped at the first limit violation (`stop_at_limit`): the log ends there.
    pub stopped_at_limit: bool,
}

/// Per-tick log of a run (row-major arrays).
#[derive(Debug, Clone, Default)]
pub struct Log {
    /// Ticks logged (rows).
    pub n: usize,
    /// Joints (columns of the joint arrays).
    pub nv: usize,
    /// Time of each tick (s).
    pub t: Vec<f64>,
    /// The commanded paper pose `[y, z, theta]` (n x 3).
    pub paper_cmd: Vec<f64>,
    /// The achieved paper pose `[y, z, theta]` (n x 3).
    pub paper: Vec<f64>,
    /// Commanded position of the spatula point (n x 3).
    pub pos_cmd: Vec<f64>,
    /// Achieved position of the spatula point (n x 3).
    pub pos: Vec<f64>,
    /// Achieved attitude, row-major (n x 9).
    pub rot: Vec<f64>,
    /// Norm of the position error (m).
    pub err_pos: Vec<f64>,
    /// Norm of the attitude error (rad).
    pub err_rot: Vec<f64>,
    /// Joint positions at the tick's start (n x nv).
    pub q: Vec<f64>,
    /// Joint velocities at the tick's start (n x nv).
    pub v: Vec<f64>,
    /// Applied torques (n x nv).
    pub tau: Vec<f64>,
    /// The DOB's disturbance estimate (n x nv).
    pub tau_dis_hat: Vec<f64>,
    /// The torque the nominal model does not explain (n x nv).
    pub tau_dis: Vec<f64>,
    /// Achieved spatula acceleration, linear then angular (n x 6).
    pub acc: Vec<f64>,
    /// The paper's phi of the achieved motion.
    pub phi: Vec<f64>,
    /// The pancake's position along the blade (m).
    pub slide: Vec<f64>,
    /// The pancake's normal force per unit mass (m/s^2).
    pub normal: Vec<f64>,
    /// 0 stuck, 1 sliding, 2 off the spatula.
    pub pancake_mode: Vec<u8>,
    /// The inverse of J was damped.
    pub damped: Vec<bool>,
    /// det J (m^3).
    pub det_j: Vec<f64>,
    /// Paced runs: how late each tick started after its deadline (s).
    pub lateness: Vec<f64>,
    /// Paced runs: compute time of each tick (s).
    pub compute: Vec<f64>,
}

/// A run: its log, its summary, where the motion window is.
#[derive(Debug, Clone)]
pub struct Run {
    /// Every tick.
    pub log: Log,
    /// The summary numbers.
    pub summary: Summary,
    /// Tick indices: settle phase `[0, motion_start)`, motion `[motion_start, motion_end)`,
    /// then the tail.
    pub motion_start: usize,
    /// See `motion_start`.
    pub motion_end: usize,
}

fn damped_solve(j: &Matrix6<f64>, b: &Vector6<f64>, singular_det: f64, max_damping: f64) -> (Vector6<f64>, f64, bool) {
    let lu = j.lu();
    let det = lu.determinant();
    let w = det.abs();
    if w >= singular_det && w > 0.0 {
        if let Some(x) = lu.solve(b) {
            return (x, det, false);
        }
    }
    let ratio = if singular_det > 0.0 { (w / singular_det).min(1.0) } else { 0.0 };
    let lambda2 = (max_damping * (1.0 - ratio)).powi(2).max(1e-12);
    let a = j * j.transpose() + Matrix6::identity() * lambda2;
    let x = match a.cholesky() {
        Some(c) => j.transpose() * c.solve(b),
        None => Vector6::zeros(),
    };
    (x, det, true)
}

impl Simulation {
    /// Build from the arm's dynamics (used for both the nominal and the true model).
    pub fn new(arm: &Dynamics, config: SimConfig) -> Result<Simulation> {
        let nv = arm.nv;
        if nv != 6 || arm.nq != 6 {
            return Err(Error::Invalid(format!(
                "the spatula controller needs a 6-joint arm of revolute/prismatic joints (square task Jacobian); got nq={}, nv={}",
                arm.nq, arm.nv
            )));
        }
        config.check(nv)?;
        let s = &config.setup;
        let flange = arm.frame(&s.tool_link, &Isometry3::identity())?;
        if flange.body.is_none() {
            return Err(Error::Invalid(format!("tool link '{}' does not move with any joint", s.tool_link)));
        }
        let frame = arm.frame(
            &s.tool_link,
            &Isometry3::from_parts(Translation3::new(0.0, 0.0, s.spatula_length), UnitQuaternion::identity()),
        )?;
        let mut nominal = arm.clone();
        // spatula: a thin rod along the flange z axis, length 2 * spatula_com
        let l = 2.0 * s.spatula_com.abs();
        let i_rod = s.spatula_mass * l * l / 12.0;
        let rod = Matrix3::from_diagonal(&Vector3::new(i_rod, i_rod, 0.0));
        nominal.add_inertia(&flange, s.spatula_mass, Vector3::new(0.0, 0.0, s.spatula_com), rod)?;
        let (torque_limits, velocity_limits) = config.limits.resolve(arm);
        let limit_units = arm
            .bodies
            .iter()
            .map(|b| if b.kind == crate::dynamics::JointKind::Prismatic { ("N", "m/s") } else { ("N m", "rad/s") })
            .collect();
        let mut plant = nominal.clone();
        let d = &config.disturbances;
        if d.payload_mass > 0.0 {
            plant.add_inertia(&frame, d.payload_mass, Vector3::from(d.payload_com), Matrix3::zeros())?;
        }
        Ok(Simulation {
            ws_n: nominal.workspace(),
            ws_p: plant.workspace(),
            nominal,
            plant,
            frame,
            nv,
            q: [0.0; 6],
            v: [0.0; 6],
            prev_tau: Vector6::zeros(),
            prev_h: Vector6::zeros(),
            prev_m: Matrix6::zeros(),
            prev_v: Vector6::zeros(),
            has_prev: false,
            tau_dis_hat: Vector6::zeros(),
            pancake: Pancake::new(config.pancake),
            jac: DMatrix::zeros(6, nv),
            djac: DMatrix::zeros(6, nv),
            tilt_prev: None,
            ticks: 0,
            torque_limits,
            velocity_limits,
            limit_units,
            config,
        })
    }

    /// The configuration this simulation was built with.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// The joint limits in force (torque, speed per joint): the configuration's, else the robot
    /// model's.
    pub fn limits(&self) -> (&[f64], &[f64]) {
        (&self.torque_limits, &self.velocity_limits)
    }

    /// The joint furthest over its limit (relative to the limit) at tick `k` with applied torque
    /// `tau` and joint speeds `v`; None when every joint is within its limits.
    fn limit_violation(&self, k: usize, tau: &Vector6<f64>, v: &[f64; 6]) -> Option<LimitViolation> {
        let mut worst: Option<(f64, LimitViolation)> = None;
        for i in 0..self.nv {
            for (kind, value, limit) in
                [(LimitKind::Torque, tau[i], self.torque_limits[i]), (LimitKind::Velocity, v[i], self.velocity_limits[i])]
            {
                let ratio = value.abs() / limit;
                if ratio > 1.0 && worst.as_ref().is_none_or(|(r, _)| ratio > *r) {
                    let unit = if kind == LimitKind::Torque { self.limit_units[i].0 } else { self.limit_units[i].1 };
                    let time = k as f64 * self.config.controller.dt;
                    worst = Some((ratio, LimitViolation { time, tick: k, joint: i, kind, value, limit, unit }));
                }
            }
        }
        worst.map(|(_, v)| v)
    }

    /// The command pose of a paper pose `[y, z, theta]` (eq. 23 with this setup).
    pub fn command_pose(&self, p: [f64; 3]) -> (Vector3<f64>, Matrix3<f64>) {
        let s = &self.config.setup;
        (
            Vector3::new(s.origin[0], s.origin[1] + p[0], s.origin[2] + p[1]),
            attitude_matrix(p[2], s.attitude[0], s.attitude[1]),
        )
    }

    /// World pose of the spatula frame at q (checked).
    pub fn spatula_pose(&mut self, q: &[f64]) -> Result<(Vector3<f64>, Matrix3<f64>)> {
        self.nominal.check_state(q, None)?;
        self.nominal.update_kinematics_unchecked(q, None, &mut self.ws_n);
        let (r, p) = self.nominal.frame_placement(&self.frame, &self.ws_n);
        Ok((p, r))
    }

    /// Levenberg-Marquardt IK of the spatula frame (damping `lambda^2 = |e|^2 + 1e-12`, Sugihara
    /// 2011: quadratic convergence when reachable, no blow-up near singularities; steps capped
    /// at 0.5 rad so that it does not jump branches). Ok((q, iterations)) once position and
    /// attitude errors are below 1e-10, else an error with the residual.
    pub fn inverse_kinematics(&mut self, pos: &Vector3<f64>, rot: &Matrix3<f64>, seed: &[f64], max_iterations: usize) -> Result<(Vec<f64>, usize)> {
        self.nominal.check_state(seed, None)?;
        let mut q = seed.to_vec();
        let mut err = f64::INFINITY;
        for it in 0..max_iterations {
            self.nominal.update_kinematics_unchecked(&q, None, &mut self.ws_n);
            let (r, p) = self.nominal.frame_placement(&self.frame, &self.ws_n);
            let (w, _) = log3(&(rot * r.transpose()));
            let dp = pos - p;
            let e = Vector6::new(dp.x, dp.y, dp.z, w.x, w.y, w.z);
            err = dp.norm() + w.norm() * 0.1;
            if dp.norm() < 1e-10 && w.norm() < 1e-10 {
                return Ok((q, it));
            }
            self.nominal.frame_jacobians_from_kinematics(&self.frame, &self.ws_n, &mut self.jac, None);
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
        (0..q.len()).find(|&i| q[i] < self.nominal.lower[i] - 1e-9 || q[i] > self.nominal.upper[i] + 1e-9)
    }

    /// The commands of a paper trajectory `[y, z, theta]` (rows of 3, one per `dt`): settle
    /// ticks first. Checks shape, finiteness, and that every pose is reachable (IK along the
    /// trajectory, warm-started, within the joint limits). Returns the commands and the initial
    /// configuration (at rest at the first pose).
    pub fn prepare(&mut self, trajectory: &[f64]) -> Result<(Vec<Command>, Vec<f64>)> {
        if trajectory.len() % 3 != 0 || trajectory.len() < 6 {
            return Err(Error::Invalid(format!(
                "trajectory: expected rows [y, z, theta] (K >= 2 rows of 3 values), got {} values",
                trajectory.len()
            )));
        }
        if let Some(i) = trajectory.iter().position(|x| !x.is_finite()) {
            return Err(Error::NonFinite {
                what: format!("trajectory row {} (column {})", i / 3, i % 3),
                index: i,
                value: trajectory[i],
            });
        }
        let dt = self.config.controller.dt;
        let rows: Vec<[f64; 3]> = trajectory.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
        let user_seed = self.config.setup.q_seed.clone();
        // initial configuration
        let (p0, r0) = self.command_pose(rows[0]);
        let mut seeds: Vec<Vec<f64>> = Vec::new();
        if let Some(s) = user_seed {
            crate::error::check_vector("setup.q_seed", &s, self.nv)?;
            seeds.push(s);
        }
        seeds.push(UR5_SEED.to_vec());
        let mut state: u64 = 0x9E3779B97F4A7C15;
        for _ in 0..16 {
            let q: Vec<f64> = (0..self.nv)
                .map(|i| {
                    state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    let u = (state >> 11) as f64 / (1u64 << 53) as f64;
                    let (lo, hi) = (self.nominal.lower[i].max(-std::f64::consts::PI), self.nominal.upper[i].min(std::f64::consts::PI));
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
                Ok((q, _)) => last_err = format!("solution outside the joint limits ({})", self.nominal.joint_names[self.within_limits(&q).unwrap_or(0)]),
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
        let n_settle = self.config.settle_ticks;
        let mut cmds = Vec::with_capacity(rows.len() + n_settle);
        for _ in 0..n_settle {
            cmds.push(Command { pos: p0, rot: r0, vel: Vector6::zeros(), acc: Vector6::zeros(), paper: rows[0] });
        }
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
            cmds.push(Command { pos: p, rot: r, vel, acc, paper: *row });
            prev = Some((p, r, vel));
        }
        Ok((cmds, q_init))
    }

    /// IK solutions of every row of a paper trajectory, each warm-started from the previous
    /// one (row 0 from `q_init`); an error names the first row that cannot be reached within
    /// the joint limits.
    pub fn track_ik(&mut self, rows: &[[f64; 3]], q_init: &[f64]) -> Result<Vec<Vec<f64>>> {
        let dt = self.config.controller.dt;
        let mut q = q_init.to_vec();
        let mut out = Vec::with_capacity(rows.len());
        for (k, row) in rows.iter().enumerate() {
            let (p, r) = self.command_pose(*row);
            match self.inverse_kinematics(&p, &r, &q, 100) {
                Ok((qk, _)) => {
                    if let Some(i) = self.within_limits(&qk) {
                        return Err(Error::Invalid(format!(
                            "trajectory row {k} (t={:.3} s, y={:.4}, z={:.4}, theta={:.4}): reaching it needs joint '{}' = {:.3} outside its limits [{:.3}, {:.3}]",
                            k as f64 * dt, row[0], row[1], row[2], self.nominal.joint_names[i], qk[i], self.nominal.lower[i], self.nominal.upper[i]
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

    /// |det J| of the spatula frame's task Jacobian at q (0 at a singularity; m^3).
    pub fn jacobian_det(&mut self, q: &[f64]) -> Result<f64> {
        self.nominal.check_state(q, None)?;
        self.nominal.update_kinematics_unchecked(q, None, &mut self.ws_n);
        self.nominal.frame_jacobians_from_kinematics(&self.frame, &self.ws_n, &mut self.jac, None);
        Ok(Matrix6::from_iterator(self.jac.iter().copied()).determinant().abs())
    }

    /// Put the arm at rest at `q` and reset the controller and the pancake.
    pub fn reset(&mut self, q: &[f64]) -> Result<()> {
        self.nominal.check_state(q, None)?;
        self.q.copy_from_slice(q);
        self.v = [0.0; 6];
        self.has_prev = false;
        self.tau_dis_hat = Vector6::zeros();
        self.prev_tau = Vector6::zeros();
        self.pancake = Pancake::new(self.config.pancake);
        self.tilt_prev = None;
        self.ticks = 0;
        Ok(())
    }

    /// Advance the plant alone by one period under the held torque `tau` (RK4, `substeps`);
    /// returns the joint acceleration at the period's start. The controller is not involved.
    pub fn integrate_plant(&mut self, tau: &Vector6<f64>) -> Result<Vector6<f64>> {
        let substeps = self.config.substeps;
        let h = self.config.controller.dt / substeps as f64;
        let d = &self.config.disturbances;
        let plant = &self.plant;
        let ws = &mut self.ws_p;
        let mut accel = |q: &[f64; 6], v: &[f64; 6], out: &mut [f64; 6]| -> Result<()> {
            let mut t = [0.0; 6];
            for i in 0..6 {
                let fr = d.coulomb[i] * (v[i] / d.friction_velocity).tanh() + d.viscous[i] * v[i];
                t[i] = tau[i] + d.offset[i] - fr;
            }
            plant.update_local_kinematics_unchecked(q, Some(v), ws);
            plant.forward_dynamics_from_kinematics(&t, ws, out)
        };
        let mut q = self.q;
        let mut v = self.v;
        let mut qdd0 = [0.0; 6];
        let (mut k1, mut k2, mut k3, mut k4) = ([0.0; 6], [0.0; 6], [0.0; 6], [0.0; 6]);
        for sub in 0..substeps {
            accel(&q, &v, &mut k1)?;
            if sub == 0 {
                qdd0 = k1;
            }
            let (mut qt, mut vt) = ([0.0; 6], [0.0; 6]);
            for i in 0..6 {
                qt[i] = q[i] + 0.5 * h * v[i];
                vt[i] = v[i] + 0.5 * h * k1[i];
            }
            let v2 = vt;
            accel(&qt, &vt, &mut k2)?;
            for i in 0..6 {
                qt[i] = q[i] + 0.5 * h * v2[i];
                vt[i] = v[i] + 0.5 * h * k2[i];
            }
            let v3 = vt;
            accel(&qt, &vt, &mut k3)?;
            for i in 0..6 {
                qt[i] = q[i] + h * v3[i];
                vt[i] = v[i] + h * k3[i];
            }
            let v4 = vt;
            accel(&qt, &vt, &mut k4)?;
            for i in 0..6 {
                q[i] += h / 6.0 * (v[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i]);
                v[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
        }
        if !(q.iter().chain(&v).all(|x| x.is_finite())) {
            return Err(Error::Invalid(format!("the plant diverged (non-finite state) at tick {}", self.ticks)));
        }
        self.q = q;
        self.v = v;
        Ok(Vector6::from(qdd0))
    }

    /// One control period: measure, control, let the plant run `dt` under the held torque,
    /// step the pancake. The output describes the state at the start of the tick.
    pub fn tick(&mut self, cmd: &Command) -> Result<TickOutput> {
        let c = &self.config.controller;
        let (dt, g) = (c.dt, c.gains);
        let nv = self.nv;
        // --- controller: nominal model at the measured state
        self.nominal.update_kinematics_unchecked(&self.q, Some(&self.v), &mut self.ws_n);
        self.nominal.mass_matrix_from_kinematics(&mut self.ws_n);
        let mut h = [0.0; 6];
        self.nominal.rnea_from_kinematics(None, true, &mut self.ws_n, &mut h);
        self.nominal.frame_jacobians_from_kinematics(&self.frame, &self.ws_n, &mut self.jac, Some(&mut self.djac));
        let (rot, pos) = self.nominal.frame_placement(&self.frame, &self.ws_n);
        let m = Matrix6::from_iterator(self.ws_n.mass.iter().copied());
        let j = Matrix6::from_iterator(self.jac.iter().copied());
        let dj = Matrix6::from_iterator(self.djac.iter().copied());
        let v = Vector6::from_column_slice(&self.v);
        let h = Vector6::from(h);
        let xd = j * v;
        let djv = dj * v;

        // disturbance observer (uses the last period)
        if self.has_prev {
            let alpha = (-2.0 * std::f64::consts::PI * c.dob_cutoff_hz * dt).exp();
            let d = self.prev_tau - self.prev_h - self.prev_m * ((v - self.prev_v) / dt);
            self.tau_dis_hat = self.tau_dis_hat * alpha + d * (1.0 - alpha);
        }

        let ep = cmd.pos - pos;
        let (er, _) = log3(&(cmd.rot * rot.transpose()));
        let (dv, dw) = if c.velocity_feedforward {
            (cmd.vel.fixed_rows::<3>(0) - xd.fixed_rows::<3>(0), cmd.vel.fixed_rows::<3>(3) - xd.fixed_rows::<3>(3))
        } else {
            (-xd.fixed_rows::<3>(0), -xd.fixed_rows::<3>(3))
        };
        let mut xdd = Vector6::zeros();
        for k in 0..3 {
            xdd[k] = g.kpp * ep[k] + g.kvp * dv[k];
            xdd[k + 3] = g.kpr * er[k] + g.kvr * dw[k];
        }
        if c.acceleration_feedforward {
            xdd += cmd.acc;
        }
        let (qdd_ref, det, damped) = damped_solve(&j, &(xdd - djv), c.singular_det, c.max_damping);
        let mut tau = m * qdd_ref;
        if c.model_compensation {
            tau += h;
        }
        if c.dob {
            tau += self.tau_dis_hat;
        }
        let mut saturated = false;
        if let Some(lim) = &c.torque_limit {
            for i in 0..nv {
                if tau[i].abs() > lim[i] {
                    tau[i] = tau[i].clamp(-lim[i], lim[i]);
                    saturated = true;
                }
            }
        }
        if !tau.iter().all(|x| x.is_finite()) {
            return Err(Error::Invalid(format!("controller produced a non-finite torque at tick {}", self.ticks)));
        }
        self.prev_tau = tau;
        self.prev_h = if c.model_compensation { h } else { Vector6::zeros() };
        self.prev_m = m;
        self.prev_v = v;
        self.has_prev = true;

        // --- plant: RK4 under the held torque
        let qdd0 = self.integrate_plant(&tau)?;

        // --- achieved spatula motion at the tick's start, phi, pancake
        let acc = j * qdd0 + djv;
        let tau_dis = tau - m * qdd0 - self.prev_h;
        let tangent = rot.column(1);
        let raw_tilt = tangent[2].atan2(tangent[1]);
        let reference = self.tilt_prev.unwrap_or(cmd.paper[2]);
        let tilt = reference + wrap_angle(raw_tilt - reference);
        self.tilt_prev = Some(tilt);
        let gz = -self.plant.gravity.z;
        let phi_val = phi(tilt, acc[1], acc[2], gz);
        let motion = PlanarMotion { theta: tilt, w: xd[3], dw: acc[3], a_y: acc[1], a_z: acc[2] };
        self.pancake.step(&motion, [self.plant.gravity.y, self.plant.gravity.z], dt);
        self.ticks += 1;
        Ok(TickOutput {
            pos,
            rot,
            tau,
            tau_dis_hat: self.tau_dis_hat,
            tau_dis,
            acc,
            vel: xd,
            err_pos: ep.norm(),
            err_rot: er.norm(),
            phi: phi_val,
            tilt,
            det_j: det,
            damped,
            saturated,
            pancake: self.pancake,
        })
    }

    /// Execute a paper trajectory (see [`prepare`](Self::prepare)). `motion_len`: how many rows
    /// are the motion proper (the rest is a tail, e.g. the paper's deceleration; None: all).
    /// `paced`: tick on the wall clock every `dt` and record the lateness of each tick. Ticks
    /// over the joint limits are reported in the summary ([`Summary::limit_violation`]).
    pub fn run(&mut self, trajectory: &[f64], motion_len: Option<usize>, paced: bool) -> Result<Run> {
        self.run_with(trajectory, motion_len, paced, false, &mut || false)
    }

    /// As [`run`](Self::run), asking `stop` every [`STOP_CHECK_TICKS`] ticks whether to abandon
    /// the run (e.g. on Ctrl-C); a stop is the error [`Error::Invalid`] "run interrupted".
    /// `stop_at_limit`: end the run after the first tick over a joint limit
    /// ([`Summary::stopped_at_limit`]; the log ends with that tick).
    pub fn run_with(
        &mut self,
        trajectory: &[f64],
        motion_len: Option<usize>,
        paced: bool,
        stop_at_limit: bool,
        stop: &mut dyn FnMut() -> bool,
    ) -> Result<Run> {
        let rows = trajectory.len() / 3;
        if rows.saturating_add(self.config.settle_ticks) > MAX_TICKS {
            return Err(Error::Invalid(format!(
                "a run is limited to {MAX_TICKS} ticks; got {rows} trajectory rows + {} settle ticks",
                self.config.settle_ticks
            )));
        }
        let (cmds, q0) = self.prepare(trajectory)?;
        let motion_len = motion_len.unwrap_or(rows);
        if motion_len == 0 || motion_len > rows {
            return Err(Error::Invalid(format!("motion_len must be in 1..={rows}, got {motion_len}")));
        }
        self.reset(&q0)?;
        let n = cmds.len();
        let nv = self.nv;
        let dt = self.config.controller.dt;
        let motion_start = self.config.settle_ticks;
        let motion_end = motion_start + motion_len;
        let mut log = Log { n, nv, ..Default::default() };
        let reserve = |v: &mut Vec<f64>, k: usize| v.reserve_exact(n * k);
        reserve(&mut log.t, 1);
        for (v, k) in [
            (&mut log.paper_cmd, 3),
            (&mut log.paper, 3),
            (&mut log.pos_cmd, 3),
            (&mut log.pos, 3),
            (&mut log.rot, 9),
            (&mut log.q, nv),
            (&mut log.v, nv),
            (&mut log.tau, nv),
            (&mut log.tau_dis_hat, nv),
            (&mut log.tau_dis, nv),
            (&mut log.acc, 6),
        ] {
            reserve(v, k);
        }
        let mut summary = Summary {
            ticks: n,
            us_per_tick: 0.0,
            max_err_pos: 0.0,
            max_err_rot: 0.0,
            rms_err_pos: 0.0,
            rms_err_rot: 0.0,
            max_abs_phi: 0.0,
            slipped: false,
            first_slip_time: None,
            left_time: None,
            max_abs_slide: 0.0,
            damped_ticks: 0,
            first_damped_time: None,
            min_abs_det_j: f64::INFINITY,
            saturated_ticks: 0,
            max_abs_tau: vec![0.0; nv],
            max_abs_v: vec![0.0; nv],
            limit_violation: None,
            limit_ticks: 0,
            stopped_at_limit: false,
        };
        let mut outs: Vec<TickOutput> = Vec::with_capacity(n);
        let mut states: Vec<([f64; 6], [f64; 6])> = Vec::with_capacity(n);
        let period = Duration::from_secs_f64(dt);
        let start = Instant::now();
        for (k, cmd) in cmds.iter().enumerate() {
            if k % STOP_CHECK_TICKS == STOP_CHECK_TICKS - 1 && stop() {
                return Err(Error::Invalid(format!("run interrupted at t = {:.3} s", k as f64 * dt)));
            }
            if paced {
                let deadline = start + period.mul_f64(k as f64);
                wait_until(deadline);
                let now = Instant::now();
                log.lateness.push(now.saturating_duration_since(deadline).as_secs_f64());
            }
            let t0 = if paced { Some(Instant::now()) } else { None };
            let v0 = self.v;
            states.push((self.q, v0));
            let out = match self.tick(cmd) {
                Ok(out) => out,
                Err(Error::Invalid(msg)) => {
                    let t = k as f64 * dt;
                    return Err(Error::Invalid(match &summary.limit_violation {
                        Some(v) => format!("{msg} (t = {t:.3} s), after exceeding a limit: {}", v.describe(&self.nominal.joint_names)),
                        None => format!("{msg} (t = {t:.3} s)"),
                    }));
                }
                Err(e) => return Err(e),
            };
            if let Some(t0) = t0 {
                log.compute.push(t0.elapsed().as_secs_f64());
            }
            let over = self.limit_violation(k, &out.tau, &v0);
            outs.push(out);
            if let Some(v) = over {
                summary.limit_ticks += 1;
                summary.limit_violation.get_or_insert(v);
                if stop_at_limit {
                    summary.stopped_at_limit = true;
                    break;
                }
            }
        }
        let elapsed = start.elapsed().as_secs_f64();
        let n = outs.len();
        log.n = n;
        summary.ticks = n;
        summary.us_per_tick = elapsed / n as f64 * 1e6;
        // fill the log outside the timed loop
        let (mut se_p, mut se_r, mut cnt) = (0.0, 0.0, 0usize);
        for (k, (out, (q, v))) in outs.iter().zip(&states).enumerate() {
            let cmd = &cmds[k];
            let t = k as f64 * dt;
            log.t.push(t);
            log.paper_cmd.extend_from_slice(&cmd.paper);
            let s = &self.config.setup;
            log.paper.extend_from_slice(&[out.pos.y - s.origin[1], out.pos.z - s.origin[2], out.tilt]);
            log.pos_cmd.extend_from_slice(cmd.pos.as_slice());
            log.pos.extend_from_slice(out.pos.as_slice());
            for r in 0..3 {
                for cc in 0..3 {
                    log.rot.push(out.rot[(r, cc)]);
                }
            }
            log.err_pos.push(out.err_pos);
            log.err_rot.push(out.err_rot);
            log.q.extend_from_slice(q);
            log.v.extend_from_slice(v);
            log.tau.extend_from_slice(out.tau.as_slice());
            log.tau_dis_hat.extend_from_slice(out.tau_dis_hat.as_slice());
            log.tau_dis.extend_from_slice(out.tau_dis.as_slice());
            log.acc.extend_from_slice(out.acc.as_slice());
            log.phi.push(out.phi);
            log.slide.push(out.pancake.s);
            log.normal.push(out.pancake.normal);
            let mode = match out.pancake.mode {
                PancakeMode::Stuck => 0u8,
                PancakeMode::Sliding => 1,
                PancakeMode::Off => 2,
            };
            log.pancake_mode.push(mode);
            log.damped.push(out.damped);
            log.det_j.push(out.det_j);
            if out.damped {
                summary.damped_ticks += 1;
                summary.first_damped_time.get_or_insert(t);
            }
            if out.saturated {
                summary.saturated_ticks += 1;
            }
            summary.min_abs_det_j = summary.min_abs_det_j.min(out.det_j.abs());
            for (i, (tau_i, v_i)) in summary.max_abs_tau.iter_mut().zip(&mut summary.max_abs_v).enumerate() {
                *tau_i = tau_i.max(out.tau[i].abs());
                *v_i = v_i.max(v[i].abs());
            }
            if mode != 0 {
                summary.first_slip_time.get_or_insert(t);
            }
            if mode == 2 {
                summary.left_time.get_or_insert(t);
            }
            if k >= motion_start {
                summary.max_err_pos = summary.max_err_pos.max(out.err_pos);
                summary.max_err_rot = summary.max_err_rot.max(out.err_rot);
                se_p += out.err_pos * out.err_pos;
                se_r += out.err_rot * out.err_rot;
                cnt += 1;
            }
            if k >= motion_start && k < motion_end {
                summary.max_abs_phi = summary.max_abs_phi.max(out.phi.abs());
                if mode != 0 {
                    summary.slipped = true;
                }
                if mode != 2 {
                    summary.max_abs_slide = summary.max_abs_slide.max(out.pancake.s.abs());
                }
            }
        }
        if cnt > 0 {
            summary.rms_err_pos = (se_p / cnt as f64).sqrt();
            summary.rms_err_rot = (se_r / cnt as f64).sqrt();
        }
        Ok(Run { log, summary, motion_start, motion_end })
    }
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
