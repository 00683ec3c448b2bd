//! Jerk-limited timing of straight joint-space motions: each segment of a piecewise-linear path
//! timed from rest to rest by a 7-segment S-curve under joint velocity, acceleration and jerk
//! limits, phase-synchronised (every joint follows one normalised profile, so the motion stays
//! on the segment's straight line, the line the planner checked).
//!
//! A segment from `q0` to `q1` is `q(t) = q0 + (q1 - q0) s(t)` with `s` going from 0 to 1 at
//! rest at both ends. Joint `j`'s limits bound the profile by `|dq_j| s' <= v_j`,
//! `|dq_j| s'' <= a_j` and `|dq_j| s''' <= j_j`, so `s` has the limits `v_s = min_j v_j / |dq_j|`
//! (likewise `a_s`, `j_s`; a joint that does not move bounds nothing) and its time-optimal
//! profile under them is the classic S-curve ([`SCurve`]): jerk `+j_s`, 0, `-j_s` up to the peak
//! speed, a cruise, and the mirror image down. That is the least duration of any straight-line
//! rest-to-rest motion: whichever joint's limit binds (one joint's velocity, another's jerk)
//! sets it, and every other joint is time-scaled to it.
//!
//! A path of several states ([`JerkPath`]) stops at each of them: every segment is its own
//! rest-to-rest motion (the simple, honest timing of a plan's waypoints; it never cuts a corner
//! the planner did not check, at the price of stopping).
//!
//! The limits the profile is built for are the given ones times `1 - MARGIN`, so that the
//! samples' rounding (the products `dq_j s'`) can never take a sample beyond a given limit: the
//! samples are checked against the given limits with no tolerance by the caller.

use crate::error::{check_finite, Error, Result};
use crate::timing::{sample_bytes, MAX_SAMPLE_BYTES};

/// Relative margin under the limits the profiles are built for (their duration grows by about
/// as much): covers the rounding of the samples' products.
pub const MARGIN: f64 = 1e-9;

/// The time-optimal rest-to-rest S-curve of a scalar `s` from 0 to 1 under the limits `v`, `a`,
/// `j` on `|s'|`, `|s''|`, `|s'''|`: the jerk phases `tj` long, the constant-acceleration phases
/// `ta` long (0 when the peak acceleration `peak_a` is below `a`), the cruise `tv` long at the
/// peak speed `peak_v`. The profile is symmetric: the second half is the first mirrored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SCurve {
    /// The jerk bound used, `|s'''|`.
    pub jerk: f64,
    /// The duration of each of the four jerk phases.
    pub tj: f64,
    /// The duration of each of the two constant-acceleration phases.
    pub ta: f64,
    /// The duration of the cruise at `peak_v`.
    pub tv: f64,
    /// The largest `|s''|` reached (`jerk * tj`).
    pub peak_a: f64,
    /// The largest `s'` reached.
    pub peak_v: f64,
}

impl SCurve {
    /// The time-optimal profile from 0 to 1 under the positive, finite limits `v`, `a`, `j`
    /// (not checked here: [`JerkPath::new`] checks its inputs before it builds one).
    pub fn new(v: f64, a: f64, j: f64) -> SCurve {
        // the accelerating half's duration at peak speed vp (peak acceleration min(a, sqrt(vp j)))
        // and the distance covered accelerating and decelerating: vp * accel_time(vp)
        let accel_time = |vp: f64| if vp * j >= a * a { vp / a + a / j } else { 2.0 * (vp / j).sqrt() };
        let vp = if v * accel_time(v) <= 1.0 {
            v
        } else {
            // no cruise: the peak speed at which accelerating and decelerating cover 1
            let without_a = (j / 4.0).cbrt(); // vp * 2 sqrt(vp / j) = 1
            let vp = if without_a * j <= a * a {
                without_a
            } else {
                // vp (vp / a + a / j) = 1
                let b = a / j;
                0.5 * a * (-b + (b * b + 4.0 / a).sqrt())
            };
            vp.min(v)
        };
        let peak_a = a.min((vp * j).sqrt());
        let tj = peak_a / j;
        let ta = (vp / peak_a - tj).max(0.0);
        let tv = (1.0 / vp - (2.0 * tj + ta)).max(0.0);
        SCurve { jerk: j, tj, ta, tv, peak_a, peak_v: vp }
    }

    /// Its duration: four jerk phases, two constant-acceleration phases and the cruise.
    pub fn duration(&self) -> f64 {
        4.0 * self.tj + 2.0 * self.ta + self.tv
    }

    /// `(s, s', s'', s''')` at time `t` of the first half (`0 <= t`, accelerating then cruising),
    /// each within its bound: `s` in [0, 1], `s'` in [0, peak_v], `|s''| <= peak_a`.
    fn rising(&self, t: f64) -> (f64, f64, f64, f64) {
        let (j, tj, ta) = (self.jerk, self.tj, self.ta);
        let (t1, t2, t3) = (tj, tj + ta, 2.0 * tj + ta);
        let (s, v, a, jk) = if t <= t1 {
            (j * t * t * t / 6.0, 0.5 * j * t * t, j * t, j)
        } else {
            // the end of the first jerk phase
            let (s1, v1, a1) = (j * t1 * t1 * t1 / 6.0, 0.5 * j * t1 * t1, self.peak_a);
            if t <= t2 {
                let d = t - t1;
                (s1 + v1 * d + 0.5 * a1 * d * d, v1 + a1 * d, a1, 0.0)
            } else {
                let (s2, v2) = (s1 + v1 * ta + 0.5 * a1 * ta * ta, v1 + a1 * ta);
                if t <= t3 {
                    let d = t - t2;
                    (s2 + v2 * d + 0.5 * a1 * d * d - j * d * d * d / 6.0, v2 + a1 * d - 0.5 * j * d * d, a1 - j * d, -j)
                } else {
                    // cruising: measured from the middle, where s = 1/2 by symmetry
                    let mid = t3 + 0.5 * self.tv;
                    (0.5 + self.peak_v * (t - mid), self.peak_v, 0.0, 0.0)
                }
            }
        };
        (s.clamp(0.0, 1.0), v.clamp(0.0, self.peak_v), a.clamp(-self.peak_a, self.peak_a), jk)
    }

    /// `(s, s', s'', s''')` at time `t` (clamped to [0, duration]); exactly `(0, 0, 0, j)` at 0
    /// and `(1, 0, 0, j)` at the end: the second half is evaluated as the first mirrored
    /// (`s(T - t) = 1 - s(t)`), so both ends are exact.
    pub fn at(&self, t: f64) -> (f64, f64, f64, f64) {
        let total = self.duration();
        let t = t.clamp(0.0, total);
        if t <= 0.5 * total {
            self.rising(t)
        } else {
            let (s, v, a, jk) = self.rising(total - t);
            (1.0 - s, v, -a, jk)
        }
    }
}

/// Times, then `q`, `qd`, `qdd`, `qddd` (rows of n), of [`JerkPath::sample`].
pub type JerkSamples = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

/// A piecewise-linear joint path timed with jerk limits, stopping at each of its states: one
/// phase-synchronised [`SCurve`] per segment (see the module's documentation).
#[derive(Debug, Clone)]
pub struct JerkPath {
    /// Joints per state.
    pub n: usize,
    /// The states (m x n, row-major), consecutive ones distinct.
    pub states: Vec<f64>,
    /// Each segment's profile (m - 1).
    pub profiles: Vec<SCurve>,
    /// The time each state is reached (m, from 0).
    pub times: Vec<f64>,
}

impl JerkPath {
    /// Time the path through `states` (m x n, row-major, m >= 2, no two consecutive rows equal)
    /// under the joint limits `vlim`, `alim`, `jlim` (n positive finite numbers each).
    /// Errors (naming the argument): bad shapes, non-finite values, non-positive limits, two
    /// equal consecutive states.
    pub fn new(states: &[f64], vlim: &[f64], alim: &[f64], jlim: &[f64]) -> Result<JerkPath> {
        let n = vlim.len();
        if n == 0 {
            return Err(Error::Invalid("vlim: at least one joint".into()));
        }
        for (what, v) in [("alim", alim), ("jlim", jlim)] {
            if v.len() != n {
                return Err(Error::Shape { what: what.into(), expected: n, got: v.len() });
            }
        }
        for (what, v) in [("states", states), ("vlim", vlim), ("alim", alim), ("jlim", jlim)] {
            check_finite(what, v)?;
        }
        for (what, v) in [("vlim", vlim), ("alim", alim), ("jlim", jlim)] {
            if let Some(k) = v.iter().position(|&x| x <= 0.0) {
                return Err(Error::Invalid(format!("{what}: limits must be positive, joint {k} has {}", v[k])));
            }
        }
        if states.len() % n != 0 || states.len() < 2 * n {
            return Err(Error::Invalid(format!("states: expected m x {n} values with m >= 2, got {}", states.len())));
        }
        let m = states.len() / n;
        let keep = 1.0 - MARGIN;
        let mut profiles = Vec::with_capacity(m - 1);
        let mut times = Vec::with_capacity(m);
        times.push(0.0);
        for i in 0..m - 1 {
            let (q0, q1) = (&states[i * n..(i + 1) * n], &states[(i + 1) * n..(i + 2) * n]);
            let (mut v, mut a, mut j) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
            for k in 0..n {
                let d = (q1[k] - q0[k]).abs();
                if d > 0.0 {
                    v = v.min(keep * vlim[k] / d);
                    a = a.min(keep * alim[k] / d);
                    j = j.min(keep * jlim[k] / d);
                }
            }
            if !v.is_finite() {
                return Err(Error::Invalid(format!("states: rows {i} and {} are equal (a segment that does not move)", i + 1)));
            }
            let p = SCurve::new(v, a, j);
            if !(p.duration().is_finite() && p.duration() > 0.0) {
                return Err(Error::Invalid(format!(
                    "states: segment {i} cannot be timed (its limits v {v}, a {a}, j {j} give duration {})",
                    p.duration()
                )));
            }
            times.push(times[i] + p.duration());
            profiles.push(p);
        }
        Ok(JerkPath { n, states: states.to_vec(), profiles, times })
    }

    /// Its duration, seconds.
    pub fn duration(&self) -> f64 {
        self.times[self.times.len() - 1]
    }

    /// Position, velocity, acceleration and jerk at time `t` (clamped to [0, duration]) into the
    /// four rows of n. Each joint's position stays between its two states' values (the segment),
    /// each state is reached exactly at its time, at rest.
    pub fn at(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64], qddd: &mut [f64]) {
        let n = self.n;
        let t = t.clamp(0.0, self.duration());
        // the segment holding t (the last one whose start is <= t)
        let i = match self.times.partition_point(|&x| x <= t) {
            0 => 0,
            k => (k - 1).min(self.profiles.len() - 1),
        };
        let (s, v, a, jk) = self.profiles[i].at(t - self.times[i]);
        let (q0, q1) = (&self.states[i * n..(i + 1) * n], &self.states[(i + 1) * n..(i + 2) * n]);
        for k in 0..n {
            let d = q1[k] - q0[k];
            q[k] = if s >= 1.0 { q1[k] } else { (q0[k] + d * s).clamp(q0[k].min(q1[k]), q0[k].max(q1[k])) };
            qd[k] = d * v;
            qdd[k] = d * a;
            qddd[k] = d * jk;
        }
    }

    /// The samples at `rate` Hz from 0 to the end (the end appended when it falls between two
    /// ticks): times, then `q`, `qd`, `qdd`, `qddd` (rows of n). Refused ([`Error::Settings`]
    /// naming `rate`) before anything is allocated when the samples would take more than
    /// [`MAX_SAMPLE_BYTES`]; an allocation that fails is the same error, never an abort.
    pub fn sample(&self, rate: f64) -> Result<JerkSamples> {
        if !(rate.is_finite() && rate > 0.0) {
            return Err(Error::Settings { field: "rate", msg: format!("must be positive and finite, got {rate}") });
        }
        let (n, total) = (self.n, self.duration());
        // sample_bytes counts q, qd, qdd: the jerk is one more row of n per sample
        let bytes = sample_bytes(total, rate, n) * (1 + 4 * n) as f64 / (1 + 3 * n) as f64;
        let gib = |b: f64| b / (1u64 << 30) as f64;
        let what = || format!("{total} s at {rate} Hz with {n} joints, {:.2} GiB,", gib(bytes));
        if !(bytes <= MAX_SAMPLE_BYTES as f64) {
            return Err(Error::Settings {
                field: "rate",
                msg: format!("{} more than the {:.2} GiB the samples of a trajectory may take", what(), gib(MAX_SAMPLE_BYTES as f64)),
            });
        }
        let ticks = (total * rate + 1e-9).floor() as usize;
        let alloc = |len: usize| -> Result<Vec<f64>> {
            let mut v = Vec::new();
            v.try_reserve_exact(len)
                .map_err(|_| Error::Settings { field: "rate", msg: format!("{} could not be allocated (out of memory)", what()) })?;
            v.resize(len, 0.0);
            Ok(v)
        };
        let mut t = alloc(ticks + 2)?;
        t.truncate(ticks + 1);
        for (k, x) in t.iter_mut().enumerate() {
            *x = (k as f64 / rate).min(total);
        }
        if total - t[ticks] > 1e-9 {
            t.push(total);
        }
        let rows = t.len() * n;
        let (mut q, mut qd, mut qdd, mut qddd) = (alloc(rows)?, alloc(rows)?, alloc(rows)?, alloc(rows)?);
        for (k, &tk) in t.iter().enumerate() {
            let r = k * n..(k + 1) * n;
            self.at(tk, &mut q[r.clone()], &mut qd[r.clone()], &mut qdd[r.clone()], &mut qddd[r]);
        }
        Ok((t, q, qd, qdd, qddd))
    }
}
