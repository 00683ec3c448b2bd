//! Payloads: what a robot holds.
//!
//! * [`Payload`]: a rigid body (mass, centre of mass, inertia) attached to a link: the physical
//!   part of an object the robot holds. Known to the controller (in its nominal model and in the
//!   plant) or not (in the plant only: [`super::Disturbances::payload`]).
//! * [`PayloadDynamics`]: a payload with dynamics of its own, driven by the motion of the frame
//!   it rides on, e.g. [`PancakeOnSpatula`]: the seq2seq paper's pancake on the spatula
//!   (Coulomb stick/slip; Section 4.1, eqs. 15-16).
//!
//! # The pancake
//!
//! A point mass on the blade at signed distance `s` from the spatula point, in the y-z plane,
//! with Coulomb friction (`mu_static`, `mu_kinetic`, the paper's `mu = 1`). In the spatula frame
//! (tangent `t = [cos theta, sin theta]`, normal `n = [-sin theta, cos theta]`) with the achieved
//! spatula acceleration `a`, tilt rate `w` and angular acceleration `dw`, per unit mass:
//! normal force `N = (a - g).n + 2 ds w + s dw`; while stuck the needed tangential force is
//! `F = (a - g).t - s w^2` and it stays stuck while `|F| <= mu_static N`; sliding obeys
//! `dds = (g - a).t + s w^2 - mu_kinetic N sign(ds)`. `N <= 0` is a lift-off and `|s|` past the
//! blade's half length a fall: the pancake has left the spatula (the intended end of a flip).
//! At `s = 0` the stick condition is the paper's `|phi| <= arctan(mu)` (eq. 15). The pancake's
//! mass is not fed back to the arm (the spatula's payload error stands for it).

use nalgebra::{Matrix3, Vector3, Vector6};

use crate::error::Result;

use super::settings::{elements, setting, within, MAX_MASS, MAX_OFFSET};

/// A rigid body attached to a link: mass, centre of mass and rotational inertia about it.
#[derive(Debug, Clone, PartialEq)]
pub struct Payload {
    /// The link it is attached to; None: the controller's frame (its link moved by the
    /// controller's `frame_offset`).
    pub link: Option<String>,
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the frame it is attached to (m).
    pub com: [f64; 3],
    /// Rotational inertia about the centre of mass, in that frame's axes (kg m^2; symmetric,
    /// positive semi-definite).
    pub inertia: [[f64; 3]; 3],
}

impl Default for Payload {
    fn default() -> Self {
        Payload { link: None, mass: 0.0, com: [0.0; 3], inertia: [[0.0; 3]; 3] }
    }
}

impl Payload {
    /// A point mass at `com` of the controller's frame.
    pub fn point(mass: f64, com: [f64; 3]) -> Self {
        Payload { mass, com, ..Default::default() }
    }

    /// Mass in `[0, MAX_MASS]` kg, centre of mass within `MAX_OFFSET` m, a finite, symmetric,
    /// positive semi-definite inertia; a link name, if given, not empty.
    pub fn validate(&self) -> Result<()> {
        within("payload.mass", self.mass, 0.0, MAX_MASS, " kg")?;
        elements("payload.com", &self.com, f64::NEG_INFINITY, f64::INFINITY)?;
        let d = Vector3::from(self.com).norm();
        if d > MAX_OFFSET {
            return Err(setting("payload.com", format!("must lie within {MAX_OFFSET} m of its frame's origin, got {d:.3} m")));
        }
        let i = self.inertia_matrix();
        if !i.iter().all(|x| x.is_finite()) {
            return Err(setting("payload.inertia", "must be finite".into()));
        }
        if (i - i.transpose()).amax() > 1e-12 * (1.0 + i.amax()) {
            return Err(setting("payload.inertia", "must be symmetric".into()));
        }
        let smallest = i.symmetric_eigenvalues().min();
        if smallest < -1e-12 * (1.0 + i.amax()) {
            return Err(setting("payload.inertia", format!("must be positive semi-definite, has the eigenvalue {smallest:.3e}")));
        }
        if let Some(l) = &self.link {
            if l.is_empty() {
                return Err(setting("payload.link", "must be a link name (None: the controller's frame)".into()));
            }
        }
        Ok(())
    }

    /// The inertia as a matrix.
    pub fn inertia_matrix(&self) -> Matrix3<f64> {
        Matrix3::from_fn(|r, c| self.inertia[r][c])
    }
}

/// The motion of the frame a payload rides on at one instant (world axes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameMotion {
    /// Position of the frame's origin.
    pub pos: Vector3<f64>,
    /// Rotation of the frame.
    pub rot: Matrix3<f64>,
    /// Velocity (linear, angular).
    pub vel: Vector6<f64>,
    /// Acceleration (linear, angular).
    pub acc: Vector6<f64>,
}

/// A payload with dynamics of its own, driven by the motion of the frame it rides on (the
/// controller's frame), stepped once a tick after the plant; its state at the tick's start is
/// logged as [`channels`](Self::channels) values.
pub trait PayloadDynamics: Send + Sync {
    /// The names of the values it logs each tick.
    fn channels(&self) -> &'static [&'static str];
    /// Back to its initial state.
    fn reset(&mut self);
    /// Advance by `dt` under the frame's motion `m` with `gravity` (world), writing this tick's
    /// channel values into `out`.
    fn step(&mut self, m: &FrameMotion, gravity: &Vector3<f64>, dt: f64, out: &mut [f64]);
}

/// Pancake model settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PancakeSettings {
    /// Static friction coefficient (the paper's mu = 1).
    pub mu_static: f64,
    /// Kinetic friction coefficient.
    pub mu_kinetic: f64,
    /// Half the blade's length along its in-plane direction (m): past it the pancake falls.
    pub blade_half_length: f64,
}

impl Default for PancakeSettings {
    fn default() -> Self {
        PancakeSettings { mu_static: 1.0, mu_kinetic: 1.0, blade_half_length: 0.06 }
    }
}

impl PancakeSettings {
    /// Friction coefficients finite and >= 0, the blade's half length finite and > 0.
    pub fn validate(&self) -> Result<()> {
        within("pancake.mu_static", self.mu_static, 0.0, f64::INFINITY, "")?;
        within("pancake.mu_kinetic", self.mu_kinetic, 0.0, f64::INFINITY, "")?;
        super::settings::positive("pancake.blade_half_length", self.blade_half_length)
    }
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

impl PancakeMode {
    /// 0 stuck, 1 sliding, 2 off (the log's code).
    pub fn code(&self) -> u8 {
        match self {
            PancakeMode::Stuck => 0,
            PancakeMode::Sliding => 1,
            PancakeMode::Off => 2,
        }
    }
}

/// The pancake on the blade (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pancake {
    /// Its friction and the blade's length.
    pub config: PancakeSettings,
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
    pub fn new(config: PancakeSettings) -> Self {
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

/// The pancake riding on the spatula frame: the blade lies along the frame's y axis, in the
/// world's y-z plane (the spatula configuration's eq. 23 attitude). Each tick it reads the
/// blade's tilt `theta` from the frame (unwrapped along the run, from `initial_tilt`), the
/// paper's `phi` (eq. 16) of the achieved motion, and steps the [`Pancake`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PancakeOnSpatula {
    /// The pancake.
    pub pancake: Pancake,
    /// The tilt the first tick unwraps around (the command's first `theta`).
    pub initial_tilt: f64,
    tilt_prev: Option<f64>,
}

impl PancakeOnSpatula {
    /// Channels: the tilt (rad, unwrapped), phi (rad), the position along the blade (m), the
    /// normal force per unit mass (m/s^2) and the mode (0 stuck, 1 sliding, 2 off).
    pub const CHANNELS: [&'static str; 5] = ["tilt", "phi", "slide", "normal", "mode"];

    /// A pancake stuck at the spatula point.
    pub fn new(config: PancakeSettings, initial_tilt: f64) -> Self {
        PancakeOnSpatula { pancake: Pancake::new(config), initial_tilt, tilt_prev: None }
    }
}

impl PayloadDynamics for PancakeOnSpatula {
    fn channels(&self) -> &'static [&'static str] {
        &Self::CHANNELS
    }

    fn reset(&mut self) {
        self.pancake = Pancake::new(self.pancake.config);
        self.tilt_prev = None;
    }

    fn step(&mut self, m: &FrameMotion, gravity: &Vector3<f64>, dt: f64, out: &mut [f64]) {
        let tangent = m.rot.column(1);
        let raw_tilt = tangent[2].atan2(tangent[1]);
        let reference = self.tilt_prev.unwrap_or(self.initial_tilt);
        let tilt = reference + wrap_angle(raw_tilt - reference);
        self.tilt_prev = Some(tilt);
        let phi_val = phi(tilt, m.acc[1], m.acc[2], -gravity.z);
        let motion = PlanarMotion { theta: tilt, w: m.vel[3], dw: m.acc[3], a_y: m.acc[1], a_z: m.acc[2] };
        self.pancake.step(&motion, [gravity.y, gravity.z], dt);
        let p = &self.pancake;
        out.copy_from_slice(&[tilt, phi_val, p.s, p.normal, p.mode.code() as f64]);
    }
}
