//! Joint limits in force during a run: the robot model's (the URDF's `<limit effort velocity
//! lower upper>`) or the caller's ([`JointLimits`]): every tick's applied torque and joint speed
//! are checked against them; before the run, the reference's positions, speeds and
//! inverse-dynamics torques ([`super::reference`](mod@super::reference)).

use crate::dynamics::{Dynamics, JointKind};

use super::settings::{JointLimits, LimitPolicy};

/// Which limit a tick exceeded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LimitKind {
    /// The applied torque (force).
    Torque,
    /// The joint speed.
    Velocity,
}

impl LimitKind {
    /// "torque" or "velocity".
    pub fn name(&self) -> &'static str {
        match self {
            LimitKind::Torque => "torque",
            LimitKind::Velocity => "velocity",
        }
    }
}

/// A tick over a joint limit (the joint furthest over its limit).
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
        self.kind.name()
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

/// The limits in force on a robot, per joint (v order), and the policy.
#[derive(Debug, Clone)]
pub struct Limits {
    /// Largest |torque|.
    pub torque: Vec<f64>,
    /// Largest |speed|.
    pub velocity: Vec<f64>,
    /// Position range per joint (v order; infinite for a continuous joint).
    pub lower: Vec<f64>,
    /// See `lower`.
    pub upper: Vec<f64>,
    /// What a tick over a limit does.
    pub policy: LimitPolicy,
    units: Vec<[&'static str; 2]>,
}

impl Limits {
    /// The limits of `settings` on `model` (checked for its joints): the given ones, else the
    /// model's.
    pub fn new(settings: &JointLimits, model: &Dynamics) -> crate::error::Result<Limits> {
        settings.check(model.nv)?;
        let nv = model.nv;
        let (mut lower, mut upper) = (vec![f64::NEG_INFINITY; nv], vec![f64::INFINITY; nv]);
        let mut units = vec![["N m", "rad/s"]; nv];
        for b in &model.bodies {
            match b.kind {
                JointKind::Continuous => {}
                JointKind::Revolute | JointKind::Prismatic => {
                    lower[b.v_index] = model.lower[b.q_index];
                    upper[b.v_index] = model.upper[b.q_index];
                }
            }
            if b.kind == JointKind::Prismatic {
                units[b.v_index] = ["N", "m/s"];
            }
        }
        Ok(Limits {
            torque: settings.torque.clone().unwrap_or_else(|| model.effort_limit.clone()),
            velocity: settings.velocity.clone().unwrap_or_else(|| model.velocity_limit.clone()),
            lower,
            upper,
            policy: settings.policy,
            units,
        })
    }

    /// The unit of a quantity of joint `i`.
    pub fn unit(&self, i: usize, kind: LimitKind) -> &'static str {
        self.units[i][kind as usize]
    }

    /// Clip `tau` to the torque limits; true if it clipped any joint.
    #[inline(always)]
    pub fn saturate(&self, tau: &mut [f64]) -> bool {
        let mut clipped = false;
        for (t, &l) in tau.iter_mut().zip(&self.torque) {
            if t.abs() > l {
                *t = t.clamp(-l, l);
                clipped = true;
            }
        }
        clipped
    }

    /// The largest |torque| / limit and |speed| / limit over the joints.
    #[inline(always)]
    pub fn ratios(&self, tau: &[f64], v: &[f64]) -> (f64, f64) {
        let r = |x: &[f64], l: &[f64]| x.iter().zip(l).map(|(x, l)| x.abs() / l).fold(0.0, f64::max);
        (r(tau, &self.torque), r(v, &self.velocity))
    }

    /// The joint furthest over its torque or speed limit (relative to the limit) with applied
    /// torque `tau` and speed `v`; None within every limit.
    pub fn violation(&self, tick: usize, time: f64, tau: &[f64], v: &[f64]) -> Option<LimitViolation> {
        let mut worst: Option<(f64, LimitViolation)> = None;
        for i in 0..tau.len() {
            for (kind, value, limit) in [(LimitKind::Torque, tau[i], self.torque[i]), (LimitKind::Velocity, v[i], self.velocity[i])] {
                let ratio = value.abs() / limit;
                if ratio > 1.0 && worst.as_ref().is_none_or(|(r, _)| ratio > *r) {
                    let unit = self.unit(i, kind);
                    worst = Some((ratio, LimitViolation { time, tick, joint: i, kind, value, limit, unit }));
                }
            }
        }
        worst.map(|(_, v)| v)
    }
}
