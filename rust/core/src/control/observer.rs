//! The disturbance observer (Ohnishi's DOB in its pseudo-differentiation form: no acceleration
//! sensor).
//!
//! `tau_dis_hat[k] = a tau_dis_hat[k-1] + (1 - a) d[k]`, `a = exp(-2 pi f_c dt)`: the first-order
//! low-pass `2 pi f_c / (s + 2 pi f_c)` discretised exactly for a piecewise-constant input, where
//! `d[k] = tau[k-1] - h_n[k-1] - M_n[k-1] (v[k] - v[k-1]) / dt` is the torque of the last period
//! that the nominal model does not explain. It always runs (its estimate is logged); the
//! controller's `dob` decides whether it is fed back.

use nalgebra::DMatrix;

use super::controllers::gemv;

/// The observer's state: its estimate and the last period's torque, bias, mass matrix and speed.
pub struct DisturbanceObserver {
    alpha: f64,
    /// The disturbance estimate (nv).
    pub estimate: Vec<f64>,
    prev_tau: Vec<f64>,
    prev_h: Vec<f64>,
    prev_m: DMatrix<f64>,
    prev_v: Vec<f64>,
    has_prev: bool,
    dv: Vec<f64>,
    mdv: Vec<f64>,
}

impl DisturbanceObserver {
    /// An observer of `nv` joints with cut-off `cutoff_hz` at period `dt`.
    pub fn new(nv: usize, cutoff_hz: f64, dt: f64) -> Self {
        DisturbanceObserver {
            alpha: (-2.0 * std::f64::consts::PI * cutoff_hz * dt).exp(),
            estimate: vec![0.0; nv],
            prev_tau: vec![0.0; nv],
            prev_h: vec![0.0; nv],
            prev_m: DMatrix::zeros(nv, nv),
            prev_v: vec![0.0; nv],
            has_prev: false,
            dv: vec![0.0; nv],
            mdv: vec![0.0; nv],
        }
    }

    /// Forget the past: zero estimate, no last period.
    pub fn reset(&mut self) {
        self.estimate.fill(0.0);
        self.prev_tau.fill(0.0);
        self.has_prev = false;
    }

    /// Update the estimate with the speed `v` measured at the start of this period.
    #[inline(always)]
    pub fn update(&mut self, v: &[f64], dt: f64) {
        if !self.has_prev {
            return;
        }
        for i in 0..v.len() {
            self.dv[i] = (v[i] - self.prev_v[i]) / dt;
        }
        gemv(&self.prev_m, &self.dv, &mut self.mdv);
        let a = self.alpha;
        for i in 0..v.len() {
            let d = self.prev_tau[i] - self.prev_h[i] - self.mdv[i];
            self.estimate[i] = self.estimate[i] * a + d * (1.0 - a);
        }
    }

    /// Remember this period's applied torque, the bias the controller added (`h`, or None:
    /// none), the mass matrix and the speed, for the next update.
    #[inline(always)]
    pub fn remember(&mut self, tau: &[f64], h: Option<&[f64]>, m: &DMatrix<f64>, v: &[f64]) {
        self.prev_tau.copy_from_slice(tau);
        match h {
            Some(h) => self.prev_h.copy_from_slice(h),
            None => self.prev_h.fill(0.0),
        }
        // one copy of the storage (both nv x nv, column-major) instead of element by element
        self.prev_m.as_mut_slice().copy_from_slice(m.as_slice());
        self.prev_v.copy_from_slice(v);
        self.has_prev = true;
    }

    /// The torque of a period that the nominal model does not explain, `tau - M_n qdd - h`
    /// with the bias last remembered (what the observer filters), into `out`.
    #[inline(always)]
    pub fn unexplained(&self, tau: &[f64], m: &DMatrix<f64>, qdd: &[f64], scratch: &mut [f64], out: &mut [f64]) {
        gemv(m, qdd, scratch);
        for i in 0..tau.len() {
            out[i] = tau[i] - scratch[i] - self.prev_h[i];
        }
    }
}
