//! The true plant: the robot's rigid-body dynamics with what the controller's model lacks
//! (joint friction, a torque offset, an unknown payload), integrated with classical RK4
//! (`substeps` per control period) under the zero-order-held torque. Continuous joints are
//! integrated on their circle (their `[cos, sin]` rotated by the step's angle).
//!
//! Each RK stage's joint acceleration comes from the articulated-body algorithm
//! ([`Dynamics::aba_from_kinematics`]); the first stage takes the kinematics the controller has
//! just measured at the same state (or its acceleration, given: [`Plant::step_from_acceleration`]),
//! the three others rotate each joint from the step's start by angle addition (no `sin_cos` of
//! the whole angle). Both give the CRBA + Cholesky solve and the kinematics at the integrated q
//! up to rounding.

use crate::dynamics::{DynWorkspace, Dynamics};
use crate::error::{Error, Result};

use super::settings::{joint_value, Disturbances};

/// The forces on the true robot: its dynamics, joint friction and the torque offset.
struct Forces {
    model: Dynamics,
    ws: DynWorkspace,
    coulomb: Vec<f64>,
    viscous: Vec<f64>,
    offset: Vec<f64>,
    friction_velocity: f64,
    torque: Vec<f64>,
}

impl Forces {
    /// The joint acceleration at the state whose kinematics (world placements and velocities
    /// included) `self.ws` holds (speed `v`) under the applied torque `tau` plus the offset minus
    /// the friction `coulomb tanh(v / friction_velocity) + viscous v`, by the articulated-body
    /// algorithm (the result of CRBA + RNEA + Cholesky up to rounding).
    #[inline(always)]
    fn accel_from_kinematics(&mut self, tau: &[f64], v: &[f64], out: &mut [f64]) -> Result<()> {
        self.set_torque(tau, v);
        self.model.aba_from_kinematics(&self.torque, &mut self.ws, out)
    }

    /// As [`accel_from_kinematics`](Self::accel_from_kinematics) at the state `q (+) factor dq`
    /// (speed `v`), its kinematics taken from `angles` (each joint's `[cos, sin]` at `q`) in the
    /// articulated-body algorithm's first pass
    /// ([`Dynamics::aba_moved_unchecked`]).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn accel_moved(&mut self, angles: &[[f64; 2]], q: &[f64], dq: &[f64], factor: f64, tau: &[f64], v: &[f64], out: &mut [f64]) -> Result<()> {
        self.set_torque(tau, v);
        self.model.aba_moved_unchecked(angles, q, dq, factor, v, &self.torque, &mut self.ws, out)
    }

    /// `self.torque`: the applied torque `tau` plus the offset minus the friction at speed `v`.
    #[inline(always)]
    fn set_torque(&mut self, tau: &[f64], v: &[f64]) {
        let mut torque = std::mem::take(&mut self.torque);
        self.net_torque(tau, v, &mut torque);
        self.torque = torque;
    }

    /// The applied torque `tau` plus the offset minus the friction at speed `v`, into `out`.
    #[inline(always)]
    fn net_torque(&self, tau: &[f64], v: &[f64], out: &mut [f64]) {
        for i in 0..tau.len() {
            let fr = self.coulomb[i] * tanh(v[i] / self.friction_velocity) + self.viscous[i] * v[i];
            out[i] = tau[i] + self.offset[i] - fr;
        }
    }
}

/// `tanh(x)` to 4e-15 relative of the library's, in one `exp` (the library's goes through
/// `expm1`: 7 % of a tick's profile against 2 % for this one, the friction of every joint taking
/// one per RK stage): `(1 - e) / (1 + e)` with `e = exp(-2 |x|)` for
/// `|x| >= 1/32`, where `1 - e > 0.06` keeps the cancellation below 2e-15 relative; below, the
/// odd Taylor series to `x^9`, whose first omitted term is under 1e-17 relative there.
#[inline(always)]
pub(crate) fn tanh(x: f64) -> f64 {
    let a = x.abs();
    if a < 0.03125 {
        let x2 = x * x;
        // x - x^3/3 + 2x^5/15 - 17x^7/315 + 62x^9/2835
        x * (1.0 + x2 * (-1.0 / 3.0 + x2 * (2.0 / 15.0 + x2 * (-17.0 / 315.0 + x2 * (62.0 / 2835.0)))))
    } else if a < 20.0 {
        let e = (-2.0 * a).exp();
        ((1.0 - e) / (1.0 + e)).copysign(x)
    } else if a.is_nan() {
        x
    } else {
        1.0f64.copysign(x)
    }
}

/// Where an RK4 step's first stage comes from.
#[derive(Clone, Copy)]
enum First<'a> {
    /// The plant's own kinematics and articulated-body algorithm.
    Compute,
    /// The kinematics of the current state (another model's, the same joints), then the ABA.
    Kinematics(&'a DynWorkspace),
    /// The kinematics of the current state and the joint acceleration, both known.
    Acceleration(&'a DynWorkspace, &'a [f64]),
}

/// The simulated robot: its model (the controller's nominal model plus the unknown payloads),
/// friction and offsets, its state, and the buffers of one RK4 step (no allocation per tick).
pub struct Plant {
    forces: Forces,
    substeps: usize,
    /// Joint positions (nq).
    pub q: Vec<f64>,
    /// Joint velocities (nv).
    pub v: Vec<f64>,
    // the state within a period, and the stages of one RK4 step
    q_step: Vec<f64>,
    v_step: Vec<f64>,
    qt: Vec<f64>,
    k1: Vec<f64>,
    k2: Vec<f64>,
    k3: Vec<f64>,
    k4: Vec<f64>,
    v2: Vec<f64>,
    v3: Vec<f64>,
    v4: Vec<f64>,
    sum: Vec<f64>,
    /// Each body's joint `[cos, sin]` at the start of the RK step.
    angles: Vec<[f64; 2]>,
}

impl Plant {
    /// The plant of `model` (which already holds every payload) with `disturbances`' friction
    /// and offsets (checked for `model.nv` joints), at rest at the model's neutral
    /// configuration (see [`reset`](Self::reset)); `substeps` RK4 steps per period (1..=1000).
    pub fn new(model: Dynamics, disturbances: &Disturbances, substeps: usize) -> Result<Plant> {
        let nv = model.nv;
        disturbances.check(nv)?;
        if substeps == 0 || substeps > 1000 {
            return Err(Error::Settings { field: "substeps", msg: format!("must be in 1..=1000, got {substeps}") });
        }
        let per_joint = |values: &[f64]| (0..nv).map(|i| joint_value(values, i)).collect::<Vec<f64>>();
        let z = vec![0.0; nv];
        let q = model.neutral();
        let n_bodies = model.n_bodies();
        Ok(Plant {
            forces: Forces {
                ws: model.workspace(),
                coulomb: per_joint(&disturbances.coulomb),
                viscous: per_joint(&disturbances.viscous),
                offset: per_joint(&disturbances.offset),
                friction_velocity: disturbances.friction_velocity,
                torque: z.clone(),
                model,
            },
            substeps,
            q_step: q.clone(),
            qt: q.clone(),
            q,
            v: z.clone(),
            v_step: z.clone(),
            k1: z.clone(),
            k2: z.clone(),
            k3: z.clone(),
            k4: z.clone(),
            v2: z.clone(),
            v3: z.clone(),
            v4: z.clone(),
            sum: z,
            angles: vec![[1.0, 0.0]; n_bodies],
        })
    }

    /// The true dynamics (the robot with every payload).
    pub fn model(&self) -> &Dynamics {
        &self.forces.model
    }

    /// At rest at `q` (checked: length nq, finite).
    pub fn reset(&mut self, q: &[f64]) -> Result<()> {
        self.forces.model.check_state(q, None)?;
        self.q.copy_from_slice(q);
        self.v.fill(0.0);
        Ok(())
    }

    /// Whether [`step`](Self::step) can take its first stage's kinematics from a workspace of
    /// `model` (the same joints and placements as the plant's robot; see
    /// [`Dynamics::same_kinematics`]).
    pub fn shares_kinematics_with(&self, model: &Dynamics) -> bool {
        self.forces.model.same_kinematics(model)
    }

    /// The joint torque the plant's dynamics see under the applied torque `tau` at speed `v`:
    /// `tau` plus the offset minus the friction, into `out` (nv).
    #[inline(always)]
    pub fn net_torque(&self, tau: &[f64], v: &[f64], out: &mut [f64]) {
        self.forces.net_torque(tau, v, out);
    }

    /// Advance by one period `dt` under the held torque `tau` (RK4, `substeps`); `qdd0` gets the
    /// joint acceleration at the period's start. `start`: the kinematics of the current state
    /// (q, v) already computed on a model for which
    /// [`shares_kinematics_with`](Self::shares_kinematics_with) holds (the controller's, which
    /// has just measured this state), copied instead of recomputed; None: computed here. The
    /// state changes only when the whole period succeeds; `tick` names the tick in the error of
    /// a non-finite state (the plant diverged).
    #[inline(always)]
    pub fn step(&mut self, tau: &[f64], dt: f64, tick: u64, start: Option<&DynWorkspace>, qdd0: &mut [f64]) -> Result<()> {
        self.rk4(tau, dt, tick, start.map_or(First::Compute, First::Kinematics), Some(qdd0))
    }

    /// As [`step`](Self::step) with the joint acceleration at the period's start already known
    /// (`k1`: the plant's dynamics at the current state under `tau`, e.g. from the controller's
    /// mass matrix and bias plus the terms of what the plant has more), so that the first RK
    /// stage only takes each joint's `[cos, sin]` from `start` (the current state's kinematics,
    /// as for `step`). With `substeps` > 1 the later substeps' first stages are computed.
    #[inline(always)]
    pub fn step_from_acceleration(&mut self, tau: &[f64], dt: f64, tick: u64, start: &DynWorkspace, k1: &[f64]) -> Result<()> {
        self.rk4(tau, dt, tick, First::Acceleration(start, k1), None)
    }

    #[inline(always)]
    fn rk4(&mut self, tau: &[f64], dt: f64, tick: u64, first: First<'_>, mut qdd0: Option<&mut [f64]>) -> Result<()> {
        let h = dt / self.substeps as f64;
        let nv = self.v.len();
        let f = &mut self.forces;
        self.q_step.copy_from_slice(&self.q);
        self.v_step.copy_from_slice(&self.v);
        let (q, v) = (&mut self.q_step, &mut self.v_step);
        for sub in 0..self.substeps {
            match first {
                First::Acceleration(ws, k1) if sub == 0 => {
                    self.k1.copy_from_slice(k1);
                    self.angles.copy_from_slice(&ws.angles);
                }
                First::Kinematics(ws) if sub == 0 => {
                    f.model.copy_kinematics(ws, &mut f.ws);
                    f.accel_from_kinematics(tau, v, &mut self.k1)?;
                    self.angles.copy_from_slice(&f.ws.angles);
                }
                _ => {
                    f.model.update_kinematics_unchecked(q, Some(v), &mut f.ws);
                    f.accel_from_kinematics(tau, v, &mut self.k1)?;
                    self.angles.copy_from_slice(&f.ws.angles);
                }
            }
            if let Some(out) = qdd0.take() {
                out.copy_from_slice(&self.k1);
            }
            // the later stages' joint rotations from this state's by angle addition
            // each stage's speed written once where the next stages read it (no copies)
            for i in 0..nv {
                self.v2[i] = v[i] + 0.5 * h * self.k1[i];
            }
            f.accel_moved(&self.angles, q, v, 0.5 * h, tau, &self.v2, &mut self.k2)?;
            for i in 0..nv {
                self.v3[i] = v[i] + 0.5 * h * self.k2[i];
            }
            f.accel_moved(&self.angles, q, &self.v2, 0.5 * h, tau, &self.v3, &mut self.k3)?;
            for i in 0..nv {
                self.v4[i] = v[i] + h * self.k3[i];
            }
            f.accel_moved(&self.angles, q, &self.v3, h, tau, &self.v4, &mut self.k4)?;
            for i in 0..nv {
                self.sum[i] = v[i] + 2.0 * self.v2[i] + 2.0 * self.v3[i] + self.v4[i];
            }
            f.model.integrate_scaled(q, &self.sum, h / 6.0, &mut self.qt);
            q.copy_from_slice(&self.qt);
            for i in 0..nv {
                v[i] += h / 6.0 * (self.k1[i] + 2.0 * self.k2[i] + 2.0 * self.k3[i] + self.k4[i]);
            }
        }
        if !q.iter().chain(v.iter()).all(|x| x.is_finite()) {
            return Err(Error::Invalid(format!("the plant diverged (non-finite state) at tick {tick}")));
        }
        f.model.normalize_circles(q);
        self.q.copy_from_slice(q);
        self.v.copy_from_slice(v);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::tanh;

    #[test]
    fn tanh_is_the_library_tanh_to_rounding() {
        // both branches, their boundaries, the saturation and the signs
        let mut worst: f64 = 0.0;
        let mut x = 1e-300;
        while x < 40.0 {
            for y in [x, -x, x * (1.0 + 1e-3), 0.03125 * (1.0 - 1e-12), 0.03125] {
                let (got, want) = (tanh(y), y.tanh());
                assert_eq!(got.signum(), want.signum(), "{y}");
                worst = worst.max(((got - want) / want).abs());
            }
            x *= 1.01;
        }
        assert!(worst < 4e-15, "largest relative error {worst:e}");
        assert_eq!(tanh(0.0), 0.0);
        assert_eq!(tanh(f64::INFINITY), 1.0);
        assert_eq!(tanh(f64::NEG_INFINITY), -1.0);
        assert!(tanh(f64::NAN).is_nan());
    }
}
