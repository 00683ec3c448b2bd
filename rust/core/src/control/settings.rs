//! The settings of a run, defined once: the controller ([`ControllerSettings`]), what the true
//! plant has that the controller's model lacks ([`Disturbances`]) and the joint limits every tick
//! is checked against ([`JointLimits`]); the payload type lives in [`super::payloads`].
//!
//! Each struct's `Default` is the value Python's keyword-less constructor gives, and
//! `validate()` checks every value that does not depend on the robot (the error,
//! [`Error::Settings`], names the field as `controller.dt`, `disturbances.coulomb`, ...);
//! `check(nv)` adds the lengths that do.

use crate::error::{Error, Result};

use super::payloads::Payload;

/// Largest mass (kg) of a payload: beyond it an arm model means nothing.
pub const MAX_MASS: f64 = 100.0;

/// Largest distance (m) of a payload's centre of mass, or of the controlled point, from the
/// frame it is given in.
pub const MAX_OFFSET: f64 = 1.0;

/// Largest gain (1/s^2 or 1/s) and largest friction or torque offset (N m) a setting may hold.
pub const MAX_SETTING: f64 = 1e8;

pub(crate) fn setting(field: &'static str, msg: String) -> Error {
    Error::Settings { field, msg }
}

/// `x` finite and > 0.
pub(crate) fn positive(field: &'static str, x: f64) -> Result<()> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(setting(field, format!("must be finite and > 0, got {x}")))
    }
}

/// `x` finite and in `[lo, hi]` (`unit`: of the bounds, for the message).
pub(crate) fn within(field: &'static str, x: f64, lo: f64, hi: f64, unit: &str) -> Result<()> {
    if x.is_finite() && x >= lo && x <= hi {
        Ok(())
    } else if hi.is_finite() {
        Err(setting(field, format!("must be finite and in [{lo}, {hi}]{unit}, got {x}")))
    } else {
        Err(setting(field, format!("must be finite and >= {lo}, got {x}")))
    }
}

/// Every element finite and in `[lo, hi]`.
pub(crate) fn elements(field: &'static str, values: &[f64], lo: f64, hi: f64) -> Result<()> {
    match values.iter().position(|&x| !(x.is_finite() && x >= lo && x <= hi)) {
        None => Ok(()),
        Some(i) if !values[i].is_finite() => Err(setting(field, format!("element {i} must be finite, got {}", values[i]))),
        Some(i) if values[i] < lo => Err(setting(field, format!("element {i} must be >= {lo}, got {}", values[i]))),
        Some(i) => Err(setting(field, format!("element {i} must be <= {hi}, got {}", values[i]))),
    }
}

/// A per-joint vector of length `n`, or (when `broadcast`) of one value for every joint; an
/// empty one when `empty_ok` (zero for every joint).
fn per_joint(field: &'static str, values: &[f64], n: usize, one_ok: bool, empty_ok: bool) -> Result<()> {
    let ok = values.len() == n || (one_ok && values.len() == 1) || (empty_ok && values.is_empty());
    if ok {
        return Ok(());
    }
    let allowed = match (one_ok, empty_ok) {
        (true, _) => format!("1 or {n} values (one per joint)"),
        (false, true) => format!("{n} values (one per joint) or none"),
        (false, false) => format!("{n} values (one per joint)"),
    };
    Err(setting(field, format!("must have {allowed}, got {}", values.len())))
}

/// The value of joint `i` of a per-joint setting (one value: every joint's; none: 0).
pub(crate) fn joint_value(values: &[f64], i: usize) -> f64 {
    match values.len() {
        0 => 0.0,
        1 => values[0],
        _ => values[i],
    }
}

/// What the controller servoes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlSpace {
    /// Every joint to the reference's joint positions: `qdd_ref = qdd_cmd + Kp (q_cmd - q) +
    /// Kv (qd_cmd - qd)`.
    Joint,
    /// A frame (its position and, on the axes not left free, its attitude) to the reference's
    /// pose of that frame: the paper's Fig. 10.
    Task,
}

impl ControlSpace {
    /// The names Python and the CLI use.
    pub const NAMES: [(&'static str, ControlSpace); 2] = [("joint", ControlSpace::Joint), ("task", ControlSpace::Task)];

    /// Its name.
    pub fn name(&self) -> &'static str {
        Self::NAMES.iter().find(|(_, k)| k == self).map_or("task", |(n, _)| n)
    }

    /// The space of a name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::NAMES.iter().find(|(n, _)| *n == name).map(|(_, k)| *k)
    }
}

/// The controller: the P-D law with gains per axis, the disturbance observer and the model
/// compensation of the seq2seq paper's Fig. 10, in the task space of any frame or in joint
/// space. Defaults: the paper's gains, 2 Hz observer, 1 ms period; unlike the paper's loop,
/// the reference's acceleration is fed forward (a planned trajectory carries it; the paper's
/// spatula configuration turns it off: [`ControllerSettings::paper`]). A redundant arm's
/// posture is held as stiffly as joint space holds its joints (400 / 40), and its task solve is
/// damped below a manipulability of 0.01: weaker, the arm swung through its self-motion where
/// Panda shelf plans pass near a singularity (up to 3 rad off the plan's joints under friction).
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerSettings {
    /// Task space (a frame) or joint space.
    pub space: ControlSpace,
    /// The link whose frame is controlled (task space) and whose tracking error is logged
    /// (both spaces); None: the robot's tool frame, which the caller names.
    pub frame: Option<String>,
    /// The controlled point in that link's frame (m): the frame is moved by it, not rotated.
    pub frame_offset: [f64; 3],
    /// Which task axes are servoed: `[x, y, z, rx, ry, rz]` in world axes, 1 servoed, 0 free
    /// (e.g. `[1, 1, 1, 1, 1, 0]`: yaw about the world's vertical free, as the Panda task's
    /// orientation term). Task space only.
    pub axes: [f64; 6],
    /// Stiffness per task axis (1/s^2; the paper's `Kpp` x3, `Kpr` x3).
    pub kp: [f64; 6],
    /// Damping per task axis (1/s; the paper's `Kvp` x3, `Kvr` x3).
    pub kv: [f64; 6],
    /// Joint-space stiffness (1/s^2): one value for every joint, or one per joint.
    pub joint_kp: Vec<f64>,
    /// Joint-space damping (1/s): one value for every joint, or one per joint.
    pub joint_kv: Vec<f64>,
    /// Stiffness (1/s^2) of the posture term towards the reference's joint positions, in the
    /// null space of the servoed task axes (a redundant arm, or free axes).
    pub posture_kp: f64,
    /// Damping (1/s) of that posture term.
    pub posture_kv: f64,
    /// Feed the disturbance estimate back.
    pub dob: bool,
    /// Cut-off frequency of the observer's low-pass filter (Hz).
    pub dob_cutoff_hz: f64,
    /// Add the nominal bias torque `h_n(q, v)` (Coriolis, centrifugal, gravity).
    pub model_compensation: bool,
    /// D term on `v_cmd - v` (true) or on `-v` (false).
    pub velocity_feedforward: bool,
    /// Add the reference's acceleration to the P-D's.
    pub acceleration_feedforward: bool,
    /// Below this `|det J|` (square task Jacobian, m^3) or `sqrt(det(J J^T))` (the servoed rows
    /// of any other), the inverse is damped.
    pub singular_det: f64,
    /// Largest damping `lambda` of the damped least squares near a singularity.
    pub max_damping: f64,
    /// Control period (s).
    pub dt: f64,
}

impl Default for ControllerSettings {
    fn default() -> Self {
        ControllerSettings {
            space: ControlSpace::Task,
            frame: None,
            frame_offset: [0.0; 3],
            axes: [1.0; 6],
            kp: [450.0, 450.0, 450.0, 700.0, 700.0, 700.0],
            kv: [60.0, 60.0, 60.0, 90.0, 90.0, 90.0],
            joint_kp: vec![400.0],
            joint_kv: vec![40.0],
            posture_kp: 400.0,
            posture_kv: 40.0,
            dob: true,
            dob_cutoff_hz: 2.0,
            model_compensation: true,
            velocity_feedforward: true,
            acceleration_feedforward: true,
            singular_det: 1e-2,
            max_damping: 0.05,
            dt: 1e-3,
        }
    }
}

impl ControllerSettings {
    /// The paper's loop (Section 5.1, Fig. 10): the defaults without the acceleration
    /// feed-forward, damped below `|det J| = 1e-3` m^3 (the paper's 6-joint arm, whose task
    /// Jacobian is square).
    pub fn paper() -> Self {
        ControllerSettings { acceleration_feedforward: false, singular_det: 1e-3, ..Default::default() }
    }

    /// Every value that does not depend on the robot.
    pub fn validate(&self) -> Result<()> {
        positive("controller.dt", self.dt)?;
        if self.dt > 1.0 {
            return Err(setting("controller.dt", format!("must be at most 1 s, got {}", self.dt)));
        }
        positive("controller.dob_cutoff_hz", self.dob_cutoff_hz)?;
        within("controller.dob_cutoff_hz", self.dob_cutoff_hz, 0.0, MAX_SETTING, " Hz")?;
        elements("controller.kp", &self.kp, 0.0, MAX_SETTING)?;
        elements("controller.kv", &self.kv, 0.0, MAX_SETTING)?;
        elements("controller.joint_kp", &self.joint_kp, 0.0, MAX_SETTING)?;
        elements("controller.joint_kv", &self.joint_kv, 0.0, MAX_SETTING)?;
        within("controller.posture_kp", self.posture_kp, 0.0, MAX_SETTING, "")?;
        within("controller.posture_kv", self.posture_kv, 0.0, MAX_SETTING, "")?;
        within("controller.singular_det", self.singular_det, 0.0, MAX_SETTING, "")?;
        within("controller.max_damping", self.max_damping, 0.0, MAX_SETTING, "")?;
        elements("controller.frame_offset", &self.frame_offset, -MAX_OFFSET, MAX_OFFSET)?;
        if let Some(i) = self.axes.iter().position(|&a| a != 0.0 && a != 1.0) {
            return Err(setting("controller.axes", format!("element {i} must be 0 (free) or 1 (servoed), got {}", self.axes[i])));
        }
        if self.space == ControlSpace::Task && self.axes.iter().all(|&a| a == 0.0) {
            return Err(setting("controller.axes", "servo at least one axis in task space (or space='joint')".into()));
        }
        if let Some(f) = &self.frame {
            if f.is_empty() {
                return Err(setting("controller.frame", "must be a link name (None: the robot's tool frame)".into()));
            }
        }
        if self.joint_kp.is_empty() || self.joint_kv.is_empty() {
            let field = if self.joint_kp.is_empty() { "controller.joint_kp" } else { "controller.joint_kv" };
            return Err(setting(field, "must have 1 value or one per joint, got none".into()));
        }
        Ok(())
    }

    /// [`validate`](Self::validate) and the lengths of the per-joint gains for an arm of `nv`
    /// joints.
    pub fn check(&self, nv: usize) -> Result<()> {
        self.validate()?;
        per_joint("controller.joint_kp", &self.joint_kp, nv, true, false)?;
        per_joint("controller.joint_kv", &self.joint_kv, nv, true, false)
    }

    /// The number of servoed task axes (task space), or of joints.
    pub fn servoed_axes(&self) -> usize {
        self.axes.iter().filter(|&&a| a != 0.0).count()
    }
}

/// What the true plant has that the controller's model lacks (none by default): joint
/// friction `-(coulomb tanh(v / friction_velocity) + viscous v)`, a constant torque offset added
/// to the commanded torque, and a payload the controller does not know.
#[derive(Debug, Clone, PartialEq)]
pub struct Disturbances {
    /// Coulomb friction per joint (N m, N for a prismatic joint); none: 0.
    pub coulomb: Vec<f64>,
    /// Viscous friction per joint (N m s / rad, N s / m); none: 0.
    pub viscous: Vec<f64>,
    /// Velocity scale of the smoothed Coulomb friction (rad/s).
    pub friction_velocity: f64,
    /// Constant torque added to the commanded one, per joint (N m, N); none: 0.
    pub offset: Vec<f64>,
    /// A payload in the plant that the controller's model does not have (a model error).
    pub payload: Option<Payload>,
}

impl Default for Disturbances {
    fn default() -> Self {
        Disturbances { coulomb: vec![], viscous: vec![], friction_velocity: 0.05, offset: vec![], payload: None }
    }
}

impl Disturbances {
    /// Every value that does not depend on the robot.
    pub fn validate(&self) -> Result<()> {
        elements("disturbances.coulomb", &self.coulomb, 0.0, MAX_SETTING)?;
        elements("disturbances.viscous", &self.viscous, 0.0, MAX_SETTING)?;
        elements("disturbances.offset", &self.offset, -MAX_SETTING, MAX_SETTING)?;
        positive("disturbances.friction_velocity", self.friction_velocity)?;
        if let Some(p) = &self.payload {
            p.validate()?;
        }
        Ok(())
    }

    /// [`validate`](Self::validate) and the per-joint lengths for an arm of `nv` joints.
    pub fn check(&self, nv: usize) -> Result<()> {
        self.validate()?;
        per_joint("disturbances.coulomb", &self.coulomb, nv, false, true)?;
        per_joint("disturbances.viscous", &self.viscous, nv, false, true)?;
        per_joint("disturbances.offset", &self.offset, nv, false, true)
    }
}

/// What a run does at a tick over a joint limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LimitPolicy {
    /// Record it (the log's limit events and first violation); the torque is applied as computed.
    Log,
    /// Clip the torque to the torque limits (as a drive does) and record every tick over a limit.
    Saturate,
    /// End the run at the first tick over a limit (strict).
    Stop,
}

impl LimitPolicy {
    /// The names Python and the CLI use.
    pub const NAMES: [(&'static str, LimitPolicy); 3] =
        [("log", LimitPolicy::Log), ("saturate", LimitPolicy::Saturate), ("stop", LimitPolicy::Stop)];

    /// Its name.
    pub fn name(&self) -> &'static str {
        Self::NAMES.iter().find(|(_, k)| k == self).map_or("saturate", |(n, _)| n)
    }

    /// The policy of a name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::NAMES.iter().find(|(n, _)| *n == name).map(|(_, k)| *k)
    }
}

/// The joint limits a run is checked against: every tick's applied torque, joint speed and
/// joint position, and before the run the reference's positions, speeds and inverse-dynamics
/// torques.
#[derive(Debug, Clone, PartialEq)]
pub struct JointLimits {
    /// Largest |torque| per joint (N m; N for a prismatic joint); None: the robot model's
    /// (the URDF's `<limit effort>`, [`crate::dynamics::Dynamics::effort_limit`]). `inf`
    /// leaves a joint unchecked.
    pub torque: Option<Vec<f64>>,
    /// Largest |speed| per joint (rad/s; m/s); None: the robot model's (the URDF's `<limit
    /// velocity>`). `inf` leaves a joint unchecked.
    pub velocity: Option<Vec<f64>>,
    /// What a tick over a limit does.
    pub policy: LimitPolicy,
}

impl Default for JointLimits {
    fn default() -> Self {
        JointLimits { torque: None, velocity: None, policy: LimitPolicy::Saturate }
    }
}

impl JointLimits {
    /// Every value that does not depend on the robot: each limit > 0 (inf: unchecked).
    pub fn validate(&self) -> Result<()> {
        for (field, v) in [("limits.torque", &self.torque), ("limits.velocity", &self.velocity)] {
            if let Some(v) = v {
                if let Some(i) = v.iter().position(|&x| x.is_nan() || x <= 0.0) {
                    return Err(setting(field, format!("element {i} must be > 0 (inf: unchecked), got {}", v[i])));
                }
            }
        }
        Ok(())
    }

    /// [`validate`](Self::validate) and the lengths for an arm of `nv` joints.
    pub fn check(&self, nv: usize) -> Result<()> {
        self.validate()?;
        for (field, v) in [("limits.torque", &self.torque), ("limits.velocity", &self.velocity)] {
            if let Some(v) = v {
                if v.len() != nv {
                    return Err(setting(field, format!("must have length {nv}, got {}", v.len())));
                }
            }
        }
        Ok(())
    }
}
