//! Time-optimal path parameterisation under joint velocity and acceleration limits: TOPP-RA
//! (Pham and Pham, "A new approach to time-optimal path parameterization based on reachability
//! analysis", IEEE T-RO 2018) for box limits, the model of the `toppra` package's
//! `TOPPRA` with `JointVelocityConstraint` and `JointAccelerationConstraint` (interpolation
//! discretisation) that `python/genplan/trajectory.py` used before this module.
//!
//! The path `q(s)` is given at grid points `s_0 < ... < s_N` by its derivatives `q'(s_i)` and
//! `q''(s_i)`. Per stage the unknowns are `x_i = s'^2` and a constant `u_i = s''` over
//! `[s_i, s_{i+1}]` (so `x_{i+1} = x_i + 2 (s_{i+1} - s_i) u_i`); every limit is linear in
//! `(x, u)`:
//!
//! * velocity: `x_i <= min_j (v_j / |q'_j(s_i)|)^2`;
//! * acceleration `q' u + q'' x` within `+-a` at `s_i`, and at `s_{i+1}` with `x_{i+1}`
//!   (the interpolation scheme: the limits hold at both ends of each interval).
//!
//! The backward pass computes each stage's controllable set `[lo_i, hi_i]` (the `x_i` from which
//! the rest of the path can be followed to rest at the end): a two-variable linear programme,
//! solved exactly by eliminating `u` (Fourier-Motzkin on the stage's few constraints). The
//! forward pass then takes, from `x_0 = 0`, the largest `u_i` that keeps `x_{i+1}` controllable.
//!
//! [`sample`] evaluates the timed spline at a fixed rate (positions, velocities, accelerations).

use crate::error::{check_finite, Error, Result};

/// `|a| below this` counts as 0 in a constraint on `u` (a joint at rest along the path there).
const ZERO: f64 = 1e-12;

/// One linear constraint `a u + b x <= c`.
#[derive(Debug, Clone, Copy)]
struct Row {
    a: f64,
    b: f64,
    c: f64,
}

/// `x = s'^2` at every grid point of the time-optimal parameterisation from rest to rest.
///
/// `grid`: N + 1 increasing path parameters; `d1`, `d2`: `q'` and `q''` at them (row-major,
/// (N + 1) x n); `vlim`, `alim`: the n positive velocity and acceleration limits. Errors: bad
/// shapes, non-finite values, a grid that does not increase, non-positive limits, or no
/// parameterisation (a stage whose controllable set is empty).
pub fn time_optimal(grid: &[f64], d1: &[f64], d2: &[f64], vlim: &[f64], alim: &[f64]) -> Result<Vec<f64>> {
    let n = vlim.len();
    let points = grid.len();
    if n == 0 || alim.len() != n {
        return Err(Error::Invalid(format!("vlim and alim: one limit per joint (got {} and {})", n, alim.len())));
    }
    if points < 2 {
        return Err(Error::Invalid(format!("grid: at least 2 points, got {points}")));
    }
    if d1.len() != points * n || d2.len() != points * n {
        return Err(Error::Invalid(format!(
            "d1 and d2: {points} x {n} values (the grid's points x the joints), got {} and {}",
            d1.len(),
            d2.len()
        )));
    }
    for (what, v) in [("grid", grid), ("d1", d1), ("d2", d2), ("vlim", vlim), ("alim", alim)] {
        check_finite(what, v)?;
    }
    if let Some(i) = (1..points).find(|&i| grid[i] <= grid[i - 1]) {
        return Err(Error::Invalid(format!("grid: must increase, but grid[{i}] = {} <= grid[{}] = {}", grid[i], i - 1, grid[i - 1])));
    }
    if let Some(j) = (0..n).find(|&j| vlim[j] <= 0.0 || alim[j] <= 0.0) {
        return Err(Error::Invalid(format!("limits: must be positive, joint {j} has vlim {} and alim {}", vlim[j], alim[j])));
    }
    let row = |i: usize| (&d1[i * n..(i + 1) * n], &d2[i * n..(i + 1) * n]);
    // velocity bound on x at each grid point
    let xv: Vec<f64> = (0..points)
        .map(|i| {
            let (p, _) = row(i);
            (0..n).map(|j| if p[j].abs() > ZERO { (vlim[j] / p[j].abs()).powi(2) } else { f64::INFINITY }).fold(f64::INFINITY, f64::min)
        })
        .collect();
    // the stage's constraints in (x, u), given the next stage's controllable set
    let mut rows: Vec<Row> = Vec::with_capacity(4 * n + 2);
    let stage = |i: usize, next: (f64, f64), rows: &mut Vec<Row>| {
        rows.clear();
        let delta = grid[i + 1] - grid[i];
        let ((p0, pp0), (p1, pp1)) = (row(i), row(i + 1));
        for j in 0..n {
            for (a, b) in [(p0[j], pp0[j]), (p1[j] + 2.0 * delta * pp1[j], pp1[j])] {
                rows.push(Row { a, b, c: alim[j] });
                rows.push(Row { a: -a, b: -b, c: alim[j] });
            }
        }
        rows.push(Row { a: 2.0 * delta, b: 1.0, c: next.1 });
        rows.push(Row { a: -2.0 * delta, b: -1.0, c: -next.0 });
    };
    // backward pass: the controllable sets
    let mut sets = vec![(0.0, 0.0); points];
    for i in (0..points - 1).rev() {
        stage(i, sets[i + 1], &mut rows);
        let (lo, hi) = x_range(&rows, xv[i]);
        if !(lo <= hi + 1e-9 * hi.abs().max(1.0)) {
            return Err(Error::Invalid(format!(
                "no parameterisation within the limits: stage {i} (s = {}) cannot be followed to rest at the end",
                grid[i]
            )));
        }
        sets[i] = (lo, hi.max(lo));
    }
    if sets[0].0 > 1e-9 {
        return Err(Error::Invalid("no parameterisation within the limits from rest at the start".into()));
    }
    // forward pass: the largest admissible s'' at each stage
    let mut x = vec![0.0; points];
    for i in 0..points - 1 {
        stage(i, sets[i + 1], &mut rows);
        let (mut u_lo, mut u_hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for r in &rows {
            let rhs = r.c - r.b * x[i];
            if r.a > ZERO {
                u_hi = u_hi.min(rhs / r.a);
            } else if r.a < -ZERO {
                u_lo = u_lo.max(rhs / r.a);
            }
        }
        // round-off may leave the interval a hair empty: stay within the next controllable set
        let u = if u_hi >= u_lo { u_hi } else { u_lo };
        let delta = grid[i + 1] - grid[i];
        x[i + 1] = (x[i] + 2.0 * delta * u).clamp(sets[i + 1].0.max(0.0), sets[i + 1].1);
    }
    x[points - 1] = 0.0;
    Ok(x)
}

/// The range of `x` in [0, `x_max`] for which some `u` satisfies every row (Fourier-Motzkin
/// elimination of `u`); (lo, hi) with lo > hi when there is none.
fn x_range(rows: &[Row], x_max: f64) -> (f64, f64) {
    let (mut lo, mut hi) = (0.0f64, x_max);
    let bound = |alpha: f64, beta: f64, lo: &mut f64, hi: &mut f64| {
        // alpha x >= beta
        if alpha > ZERO {
            *lo = lo.max(beta / alpha);
        } else if alpha < -ZERO {
            *hi = hi.min(beta / alpha);
        } else if beta > 1e-12 {
            *hi = f64::NEG_INFINITY;
        }
    };
    for r in rows.iter().filter(|r| r.a.abs() <= ZERO) {
        // b x <= c
        bound(-r.b, -r.c, &mut lo, &mut hi);
    }
    for up in rows.iter().filter(|r| r.a > ZERO) {
        for down in rows.iter().filter(|r| r.a < -ZERO) {
            // u <= (c_up - b_up x) / a_up and u >= (c_down - b_down x) / a_down
            let alpha = down.b / down.a - up.b / up.a;
            let beta = down.c / down.a - up.c / up.a;
            bound(alpha, beta, &mut lo, &mut hi);
        }
    }
    (lo, hi)
}

/// A timed path: a cubic spline `q(s)` (breakpoints `x`, m intervals, coefficients `c`:
/// m x 4 x n, `c[i][k]` multiplying `(s - x_i)^(3 - k)`, scipy's `CubicSpline.c` with its first
/// two axes swapped) and a timing `s(t)` that is piecewise quadratic between the times `knots`
/// of the grid points `grid` (speed `sdot` at each, constant `sdd` after each).
#[derive(Debug, Clone, Copy)]
pub struct TimedSpline<'a> {
    /// The spline's breakpoints (m + 1, increasing).
    pub x: &'a [f64],
    /// Its coefficients (m x 4 x n).
    pub c: &'a [f64],
    /// Grid points (N + 1) in s.
    pub grid: &'a [f64],
    /// Their times (N + 1, increasing from 0).
    pub knots: &'a [f64],
    /// s' at each grid point (N + 1).
    pub sdot: &'a [f64],
    /// s'' on each interval (N).
    pub sdd: &'a [f64],
}

/// Sample times, then `q`, `qd`, `qdd` (rows of n), of [`sample`].
pub type Samples = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

/// The most memory the samples of one timed path may take ([`sample`]: times, `q`, `qd`, `qdd`,
/// 8 bytes each): 1 GiB, 1.7 hours of a 7-joint arm at 1 kHz.
pub const MAX_SAMPLE_BYTES: usize = 1 << 30;

/// The bytes the samples of a timed path `total` seconds long take at `rate` Hz with `n`
/// joints, at most (every tick from 0, and the end when it falls between two): the bound
/// [`sample`] checks against [`MAX_SAMPLE_BYTES`] before it allocates anything. Not finite when
/// the count is not.
pub fn sample_bytes(total: f64, rate: f64, n: usize) -> f64 {
    ((total * rate + 1e-9).floor() + 2.0) * ((1 + 3 * n) * 8) as f64
}

/// `len` zeros, allocated fallibly: an allocation that fails is an error naming what it was
/// for, not an abort.
fn zeros(len: usize, what: &dyn Fn() -> String) -> Result<Vec<f64>> {
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| Error::Settings { field: "rate", msg: format!("{}: could not be allocated (out of memory)", what()) })?;
    v.resize(len, 0.0);
    Ok(v)
}

/// The samples of a timed path at `rate` Hz, its timing stretched by `scale` (`t -> scale t`),
/// from 0 to the end (the end itself appended when it falls between two ticks): times, then
/// `q`, `qd`, `qdd` (rows of n): the samples of `python/genplan/trajectory.py`. Samples that
/// would take more than [`MAX_SAMPLE_BYTES`] ([`sample_bytes`]) are refused before anything is
/// allocated, and an allocation that fails is an error ([`Error::Settings`] naming `rate`
/// either way), never an abort.
pub fn sample(p: &TimedSpline<'_>, n: usize, rate: f64, scale: f64) -> Result<Samples> {
    let (m, points) = (p.x.len().saturating_sub(1), p.grid.len());
    if m == 0 || n == 0 || p.c.len() != m * 4 * n {
        return Err(Error::Invalid(format!("spline: {} breakpoints need {} x 4 x {n} coefficients, got {}", p.x.len(), m, p.c.len())));
    }
    if points < 2 || p.knots.len() != points || p.sdot.len() != points || p.sdd.len() != points - 1 {
        return Err(Error::Invalid(format!(
            "timing: {points} grid points need as many knots and speeds and one s'' fewer, got {}, {} and {}",
            p.knots.len(),
            p.sdot.len(),
            p.sdd.len()
        )));
    }
    for (what, v) in [("x", p.x), ("c", p.c), ("grid", p.grid), ("knots", p.knots), ("sdot", p.sdot), ("sdd", p.sdd)] {
        check_finite(what, v)?;
    }
    if !(rate.is_finite() && rate > 0.0 && scale.is_finite() && scale > 0.0) {
        return Err(Error::Invalid(format!("rate and scale must be positive and finite, got {rate} and {scale}")));
    }
    let end = p.knots[points - 1];
    let total = end * scale;
    let bytes = sample_bytes(total, rate, n);
    let ticks = (total * rate + 1e-9).floor();
    let gib = |b: f64| b / (1u64 << 30) as f64;
    let what = || format!("{total} s at {rate} Hz: {} samples of {n} joints, {:.2} GiB,", ticks + 1.0, gib(bytes));
    if !(bytes <= MAX_SAMPLE_BYTES as f64) {
        return Err(Error::Settings {
            field: "rate",
            msg: format!("{} more than the {:.2} GiB the samples of a trajectory may take", what(), gib(MAX_SAMPLE_BYTES as f64)),
        });
    }
    // within MAX_SAMPLE_BYTES: the counts fit a usize
    let ticks = ticks as usize;
    let mut t = zeros(ticks + 2, &what)?;
    t.truncate(ticks + 1);
    for (k, x) in t.iter_mut().enumerate() {
        *x = k as f64 / rate;
    }
    if total - t[ticks] > 1e-9 {
        t.push(total);
    }
    let s_end = p.x[m];
    let (mut q, mut qd, mut qdd) = (zeros(t.len() * n, &what)?, zeros(t.len() * n, &what)?, zeros(t.len() * n, &what)?);
    let (mut i, mut j) = (0usize, 0usize);
    for (k, &tk) in t.iter().enumerate() {
        let tu = (tk / scale).min(end);
        // times and s only grow: walk the intervals forward
        while i + 1 < points - 1 && p.knots[i + 1] <= tu {
            i += 1;
        }
        let tau = tu - p.knots[i];
        let s = (p.grid[i] + p.sdot[i] * tau + 0.5 * p.sdd[i] * tau * tau).clamp(0.0, s_end);
        let sv = (p.sdot[i] + p.sdd[i] * tau).max(0.0);
        while j + 1 < m && p.x[j + 1] <= s {
            j += 1;
        }
        while j > 0 && p.x[j] > s {
            j -= 1;
        }
        let dx = s - p.x[j];
        let c = &p.c[j * 4 * n..(j + 1) * 4 * n];
        for a in 0..n {
            let (c0, c1, c2, c3) = (c[a], c[n + a], c[2 * n + a], c[3 * n + a]);
            let d1 = (3.0 * c0 * dx + 2.0 * c1) * dx + c2;
            let d2 = 6.0 * c0 * dx + 2.0 * c1;
            q[k * n + a] = ((c0 * dx + c1) * dx + c2) * dx + c3;
            qd[k * n + a] = d1 * sv / scale;
            qdd[k * n + a] = (d1 * p.sdd[i] + d2 * sv * sv) / (scale * scale);
        }
    }
    Ok((t, q, qd, qdd))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A straight line of length L for one joint at unit speed along s: the optimum is the
    /// bang-bang profile (accelerate at a, cruise at v, brake at a); the grid's x follows it.
    #[test]
    fn a_straight_line_is_bang_coast_bang() {
        let (v, a, len) = (1.0, 2.0, 2.0);
        let points = 401;
        let grid: Vec<f64> = (0..points).map(|i| len * i as f64 / (points - 1) as f64).collect();
        let d1 = vec![1.0; points];
        let d2 = vec![0.0; points];
        let x = time_optimal(&grid, &d1, &d2, &[v], &[a]).unwrap();
        for (s, x) in grid.iter().zip(&x) {
            // s'^2 = min(2 a s, v^2, 2 a (L - s))
            let want = (2.0 * a * s).min(v * v).min(2.0 * a * (len - s));
            assert!((x - want).abs() < 1e-9, "s = {s}: x = {x}, want {want}");
        }
    }

    /// q(s) = s^3 timed s(t) = t, stretched by 2: the samples are the closed form's; the end is
    /// included; bad shapes are refused.
    #[test]
    fn samples_follow_the_closed_form() {
        let (x, c) = ([0.0, 1.0], [1.0, 0.0, 0.0, 0.0]);
        let p = TimedSpline { x: &x, c: &c, grid: &[0.0, 1.0], knots: &[0.0, 1.0], sdot: &[1.0, 1.0], sdd: &[0.0] };
        let (t, q, qd, qdd) = sample(&p, 1, 4.0, 2.0).unwrap();
        assert_eq!(t.len(), 9);
        assert_eq!(t[8], 2.0);
        for k in 0..t.len() {
            let u = t[k] / 2.0;
            assert!((q[k] - u.powi(3)).abs() < 1e-12);
            assert!((qd[k] - 3.0 * u * u / 2.0).abs() < 1e-12);
            assert!((qdd[k] - 6.0 * u / 4.0).abs() < 1e-12);
        }
        let bad = TimedSpline { sdd: &[0.0, 0.0], ..p };
        assert!(sample(&bad, 1, 4.0, 1.0).unwrap_err().to_string().contains("one s'' fewer"));
        assert!(sample(&p, 2, 4.0, 1.0).unwrap_err().to_string().contains("coefficients"));
        assert!(sample(&p, 1, 0.0, 1.0).unwrap_err().to_string().contains("positive"));
    }

    /// A sample count whose samples would take more than MAX_SAMPLE_BYTES is refused before
    /// anything is allocated (2.8 GiB aborted the process), naming the rate and the size.
    #[test]
    fn integrity_6_samples_beyond_the_memory_bound_are_refused_before_allocating() {
        let (x, c) = ([0.0, 1.0], [0.0; 4 * 7]);
        let p = TimedSpline { x: &x, c: &c, grid: &[0.0, 1.0], knots: &[0.0, 1.0], sdot: &[1.0, 1.0], sdd: &[0.0] };
        let per_sample = sample_bytes(0.0, 1.0, 7) / 2.0; // t, q, qd, qdd: 176 bytes
        let rate = 2.8 * (1u64 << 30) as f64 / per_sample;
        match sample(&p, 7, rate, 1.0) {
            Err(Error::Settings { field: "rate", msg }) => {
                assert!(msg.contains("2.80 GiB") && msg.contains("more than the 1.00 GiB"), "{msg}")
            }
            other => panic!("expected a settings error, got {:?}", other.map(|s| s.0.len())),
        }
        for bad in [f64::MAX, 1e300] {
            assert!(matches!(sample(&p, 7, bad, 1.0), Err(Error::Settings { field: "rate", .. })));
        }
        assert!(matches!(sample(&p, 7, 1e3, 1e300), Err(Error::Settings { field: "rate", .. })));
        // 1.01 x the bound: refused; 1e5 samples: made
        assert!(sample(&p, 7, 1.01 * MAX_SAMPLE_BYTES as f64 / per_sample, 1.0).is_err());
        let (t, q, _, _) = sample(&p, 7, 1e5, 1.0).unwrap();
        assert_eq!((t.len(), q.len()), (100_001, 700_007));
    }

    /// Curved paths of several joints: every grid point keeps the velocity limits and each
    /// interval's constant s'' keeps the acceleration limits at both of its ends; the end is at
    /// rest; a limit that cannot be met is an error naming it.
    #[test]
    fn limits_hold_at_the_grid_and_bad_input_is_refused() {
        let n = 3;
        let points = 200;
        let grid: Vec<f64> = (0..points).map(|i| 3.0 * i as f64 / (points - 1) as f64).collect();
        let (mut d1, mut d2) = (Vec::new(), Vec::new());
        for &s in &grid {
            for j in 0..n {
                let w = 1.0 + j as f64;
                d1.push((w * s).cos());
                d2.push(-w * (w * s).sin());
            }
        }
        let (vlim, alim) = ([1.0, 0.8, 1.5], [2.0, 3.0, 1.0]);
        let x = time_optimal(&grid, &d1, &d2, &vlim, &alim).unwrap();
        assert_eq!((x[0], x[points - 1]), (0.0, 0.0));
        assert!(x.iter().any(|&v| v > 0.1), "it moves");
        for i in 0..points - 1 {
            let u = (x[i + 1] - x[i]) / (2.0 * (grid[i + 1] - grid[i]));
            for (k, xk) in [(i, x[i]), (i + 1, x[i + 1])] {
                for j in 0..n {
                    let (p, pp) = (d1[k * n + j], d2[k * n + j]);
                    assert!(p.abs() * xk.sqrt() <= vlim[j] * (1.0 + 1e-9), "velocity at {k}");
                    assert!((p * u + pp * xk).abs() <= alim[j] * (1.0 + 1e-6) + 1e-9, "acceleration at {k}: {}", p * u + pp * xk);
                }
            }
        }
        let err = |r: Result<Vec<f64>>| r.unwrap_err().to_string();
        assert!(err(time_optimal(&grid, &d1, &d2, &vlim, &[1.0])).contains("one limit per joint"));
        assert!(err(time_optimal(&grid, &d1[1..], &d2, &vlim, &alim)).contains("d1 and d2"));
        assert!(err(time_optimal(&grid, &d1, &d2, &[1.0, 0.0, 1.0], &alim)).contains("must be positive"));
        let mut g = grid.clone();
        g[5] = g[4];
        assert!(err(time_optimal(&g, &d1, &d2, &vlim, &alim)).contains("must increase"));
        let mut bad = d1.clone();
        bad[7] = f64::NAN;
        assert!(err(time_optimal(&grid, &bad, &d2, &vlim, &alim)).contains("d1"));
    }
}
