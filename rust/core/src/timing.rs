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
//!
//! [`TimedPath`] does all of it for a path given by its states: the not-a-knot cubic spline
//! through them ([`Spline`], scipy's `CubicSpline`), TOPP-RA's grid on it ([`gridpoints`]), the
//! speed profile, the uniform stretch that keeps every sample within the limits
//! ([`TimedPath::stretch`]) and the samples: what `python/genplan/trajectory.py` times a path
//! with, in one call instead of a scipy spline, numpy passes and a resampling per stretch.

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
    let (mut ups, mut downs) = (Vec::with_capacity(2 * n + 1), Vec::with_capacity(2 * n + 1));
    for i in (0..points - 1).rev() {
        stage(i, sets[i + 1], &mut rows);
        let (lo, hi) = x_range(&rows, xv[i], &mut ups, &mut downs);
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
/// elimination of `u`); (lo, hi) with lo > hi when there is none. `ups`, `downs`: scratch.
fn x_range(rows: &[Row], x_max: f64, ups: &mut Vec<(f64, f64)>, downs: &mut Vec<(f64, f64)>) -> (f64, f64) {
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
    // u <= (c_up - b_up x) / a_up and u >= (c_down - b_down x) / a_down: each row's b / a and
    // c / a divided once, not once per pair
    ups.clear();
    downs.clear();
    for r in rows {
        if r.a > ZERO {
            ups.push((r.b / r.a, r.c / r.a));
        } else if r.a < -ZERO {
            downs.push((r.b / r.a, r.c / r.a));
        }
    }
    for &(bu, cu) in ups.iter() {
        for &(bd, cd) in downs.iter() {
            bound(bd - bu, cd - cu, &mut lo, &mut hi);
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
    check_timed(p, n)?;
    if !(rate.is_finite() && rate > 0.0 && scale.is_finite() && scale > 0.0) {
        return Err(Error::Invalid(format!("rate and scale must be positive and finite, got {rate} and {scale}")));
    }
    let total = p.knots[p.knots.len() - 1] * scale;
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
    let (mut q, mut qd, mut qdd) = (zeros(t.len() * n, &what)?, zeros(t.len() * n, &what)?, zeros(t.len() * n, &what)?);
    let mut walk = Walk::new(p, n, scale);
    for (k, &tk) in t.iter().enumerate() {
        let rows = k * n..(k + 1) * n;
        walk.at(tk, &mut q[rows.clone()], &mut qd[rows.clone()], &mut qdd[rows]);
    }
    Ok((t, q, qd, qdd))
}

/// A [`TimedSpline`]'s shapes and values checked (what [`sample`] refuses before any work).
fn check_timed(p: &TimedSpline<'_>, n: usize) -> Result<()> {
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
    Ok(())
}

/// The evaluation of a (checked) timed spline at increasing times: the grid interval and the
/// spline interval of the last time, walked forward (times and s only grow). One definition of
/// a sample for [`sample`] and for [`TimedPath::stretch`]'s passes, so both see the same values.
struct Walk<'p, 'a> {
    p: &'p TimedSpline<'a>,
    n: usize,
    scale: f64,
    /// The grid interval and the spline interval of the last time.
    i: usize,
    j: usize,
}

impl<'p, 'a> Walk<'p, 'a> {
    fn new(p: &'p TimedSpline<'a>, n: usize, scale: f64) -> Self {
        Walk { p, n, scale, i: 0, j: 0 }
    }

    /// `q`, `qd`, `qdd` (n each) at time `tk` of the stretched timing: q = p(s(t)),
    /// qd = p'(s) s', qdd = p'(s) s'' + p''(s) s'^2, the timing's derivatives divided by the
    /// scale (once and twice).
    #[inline]
    fn at(&mut self, tk: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        let (p, n, scale) = (self.p, self.n, self.scale);
        let (m, points) = (p.x.len() - 1, p.grid.len());
        let end = p.knots[points - 1];
        let tu = (tk / scale).min(end);
        while self.i + 1 < points - 1 && p.knots[self.i + 1] <= tu {
            self.i += 1;
        }
        let i = self.i;
        let tau = tu - p.knots[i];
        let s = (p.grid[i] + p.sdot[i] * tau + 0.5 * p.sdd[i] * tau * tau).clamp(0.0, p.x[m]);
        let sv = (p.sdot[i] + p.sdd[i] * tau).max(0.0);
        while self.j + 1 < m && p.x[self.j + 1] <= s {
            self.j += 1;
        }
        while self.j > 0 && p.x[self.j] > s {
            self.j -= 1;
        }
        let dx = s - p.x[self.j];
        let c = &p.c[self.j * 4 * n..(self.j + 1) * 4 * n];
        for a in 0..n {
            let (c0, c1, c2, c3) = (c[a], c[n + a], c[2 * n + a], c[3 * n + a]);
            let d1 = (3.0 * c0 * dx + 2.0 * c1) * dx + c2;
            let d2 = 6.0 * c0 * dx + 2.0 * c1;
            q[a] = ((c0 * dx + c1) * dx + c2) * dx + c3;
            qd[a] = d1 * sv / scale;
            qdd[a] = (d1 * p.sdd[i] + d2 * sv * sv) / (scale * scale);
        }
    }
}

/// How [`gridpoints`] picks TOPP-RA's grid along a path (`python/genplan/trajectory.py`'s
/// `GRID_BASE` and `GRID_CRITICAL`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridRule {
    /// At most this many grid points spread evenly over the path's states (at least 2).
    pub base: usize,
    /// A state whose curvature could demand this fraction of an acceleration limit is a grid
    /// point; four times as much and its intervals are split in four.
    pub critical: f64,
}

/// A piecewise cubic through `n`-dimensional states: breakpoints `x` (m + 1, increasing) and
/// coefficients `c` (m x 4 x n, `c[i][k]` multiplying `(s - x_i)^(3 - k)`): the layout of
/// [`TimedSpline`].
#[derive(Debug, Clone, PartialEq)]
pub struct Spline {
    /// The breakpoints (m + 1, increasing).
    pub x: Vec<f64>,
    /// The coefficients (m x 4 x n).
    pub c: Vec<f64>,
    /// The dimension of a state.
    pub n: usize,
}

impl Spline {
    /// The not-a-knot cubic spline through the states `y` (rows of `n`) at the increasing
    /// parameters `x`: scipy's `CubicSpline(x, y)` (its default boundary condition, which
    /// `toppra`'s `SplineInterpolator` uses too), the same cases: two states a straight line,
    /// three the parabola through them, more the tridiagonal system of the breakpoints'
    /// derivatives (solved by elimination without pivoting: after its first row, which the
    /// second makes diagonally dominant, every row is). Errors: bad shapes, non-finite values,
    /// parameters that do not increase.
    pub fn not_a_knot(x: &[f64], y: &[f64], n: usize) -> Result<Spline> {
        let points = x.len();
        if points < 2 || n == 0 || y.len() != points * n {
            return Err(Error::Invalid(format!(
                "spline: at least 2 parameters and as many rows of n >= 1 states, got {points} parameters, {} values and n = {n}",
                y.len()
            )));
        }
        check_finite("x", x)?;
        check_finite("y", y)?;
        if let Some(i) = (1..points).find(|&i| x[i] <= x[i - 1]) {
            return Err(Error::Invalid(format!("x: must increase, but x[{i}] = {} <= x[{}] = {}", x[i], i - 1, x[i - 1])));
        }
        let m = points - 1;
        let dx: Vec<f64> = (0..m).map(|i| x[i + 1] - x[i]).collect();
        let slope: Vec<f64> = (0..m * n).map(|k| (y[k + n] - y[k]) / dx[k / n]).collect();
        // the derivatives at the breakpoints (points x n)
        let mut d = vec![0.0; points * n];
        if points == 2 {
            d[..n].copy_from_slice(&slope);
            d[n..].copy_from_slice(&slope);
        } else if points == 3 {
            // the parabola through the three states (scipy's 3 x 3 system, solved in closed form)
            for a in 0..n {
                let (s0, s1) = (slope[a], slope[n + a]);
                let mid = (dx[0] * s1 + dx[1] * s0) / (dx[0] + dx[1]);
                d[a] = 2.0 * s0 - mid;
                d[n + a] = mid;
                d[2 * n + a] = 2.0 * s1 - mid;
            }
        } else {
            // rows: lower * d[i-1] + diag * d[i] + upper * d[i+1] = rhs (scipy's banded matrix)
            let row = |i: usize| -> (f64, f64, f64) {
                if i == 0 {
                    (0.0, dx[1], x[2] - x[0])
                } else if i == m {
                    (x[m] - x[m - 2], dx[m - 2], 0.0)
                } else {
                    (dx[i], 2.0 * (dx[i - 1] + dx[i]), dx[i - 1])
                }
            };
            let rhs = |i: usize, a: usize| -> f64 {
                if i == 0 {
                    let w = x[2] - x[0];
                    ((dx[0] + 2.0 * w) * dx[1] * slope[a] + dx[0] * dx[0] * slope[n + a]) / w
                } else if i == m {
                    let w = x[m] - x[m - 2];
                    (dx[m - 1] * dx[m - 1] * slope[(m - 2) * n + a] + (2.0 * w + dx[m - 1]) * dx[m - 2] * slope[(m - 1) * n + a]) / w
                } else {
                    3.0 * (dx[i] * slope[(i - 1) * n + a] + dx[i - 1] * slope[i * n + a])
                }
            };
            // forward elimination (the matrix is the same for every joint), then back substitution
            let mut upper = vec![0.0; points];
            for i in 0..points {
                let (lo, diag, up) = row(i);
                let pivot = if i == 0 { diag } else { diag - lo * upper[i - 1] };
                upper[i] = up / pivot;
                for a in 0..n {
                    let before = if i == 0 { 0.0 } else { lo * d[(i - 1) * n + a] };
                    d[i * n + a] = (rhs(i, a) - before) / pivot;
                }
            }
            for i in (0..m).rev() {
                for a in 0..n {
                    d[i * n + a] -= upper[i] * d[(i + 1) * n + a];
                }
            }
        }
        // scipy's CubicHermiteSpline coefficients from the values and derivatives
        let mut c = vec![0.0; m * 4 * n];
        for i in 0..m {
            for a in 0..n {
                let (s, d0, d1) = (slope[i * n + a], d[i * n + a], d[(i + 1) * n + a]);
                let t = (d0 + d1 - 2.0 * s) / dx[i];
                let row = &mut c[i * 4 * n..(i + 1) * 4 * n];
                row[a] = t / dx[i];
                row[n + a] = (s - d0) / dx[i] - t;
                row[2 * n + a] = d0;
                row[3 * n + a] = y[i * n + a];
            }
        }
        Ok(Spline { x: x.to_vec(), c, n })
    }

    /// The first and second derivatives (n each) at `s`, in the interval `x_i <= s < x_{i+1}`
    /// (the last one from its start on, the first one before it), as scipy's `PPoly` evaluates.
    pub fn derivatives(&self, s: f64, d1: &mut [f64], d2: &mut [f64]) {
        let (n, m) = (self.n, self.x.len() - 1);
        let i = self.x.partition_point(|&b| b <= s).saturating_sub(1).min(m - 1);
        let dx = s - self.x[i];
        let c = &self.c[i * 4 * n..(i + 1) * 4 * n];
        for a in 0..n {
            let (c0, c1, c2) = (c[a], c[n + a], c[2 * n + a]);
            d1[a] = (3.0 * c0 * dx + 2.0 * c1) * dx + c2;
            d2[a] = 6.0 * c0 * dx + 2.0 * c1;
        }
    }
}

/// `num` numbers evenly spaced from `start` to `stop` (both included), computed as numpy's
/// `linspace` does (`start + k * step`, the last `stop` itself).
fn linspace(start: f64, stop: f64, num: usize) -> impl Iterator<Item = f64> {
    let step = if num > 1 { (stop - start) / (num - 1) as f64 } else { 0.0 };
    (0..num).map(move |k| if k + 1 == num && num > 1 { stop } else { k as f64 * step + start })
}

/// TOPP-RA's grid on `spline` (through a path's states at its breakpoints), increasing: an even
/// base of the breakpoints (`rule.base` of them; a path of fewer breakpoints: all of them and
/// `rule.base` points evenly spread in s, so that even two states leave TOPP-RA room to speed up
/// and slow down) plus the breakpoints (and, where it is four times larger still, their
/// intervals' quarters) whose curvature could call for more than `rule.critical` of an
/// acceleration limit at the fastest speed the velocity limits allow there.
pub fn gridpoints(spline: &Spline, vlim: &[f64], alim: &[f64], rule: GridRule) -> Vec<f64> {
    let (ss, n) = (&spline.x, spline.n);
    let points = ss.len();
    let (mut d1, mut d2) = (vec![0.0; n], vec![0.0; n]);
    let need: Vec<f64> = ss
        .iter()
        .map(|&s| {
            spline.derivatives(s, &mut d1, &mut d2);
            let speed = (0..n).map(|a| vlim[a] / d1[a].abs().max(1e-12)).fold(f64::INFINITY, f64::min);
            let s_max2 = speed * speed;
            (0..n).map(|a| d2[a].abs() * s_max2 / alim[a]).fold(f64::NEG_INFINITY, f64::max)
        })
        .collect();
    let mut grid: Vec<f64> = linspace(0.0, (points - 1) as f64, rule.base.min(points)).map(|k| ss[k.round_ties_even() as usize]).collect();
    grid.extend((0..points).filter(|&i| need[i] > rule.critical).map(|i| ss[i]));
    for i in (0..points - 1).filter(|&i| need[i].max(need[i + 1]) > 4.0 * rule.critical) {
        grid.extend([0.25, 0.5, 0.75].map(|f| ss[i] + (ss[i + 1] - ss[i]) * f));
    }
    if points < rule.base {
        grid.extend(linspace(0.0, ss[points - 1], rule.base));
    }
    grid.sort_by(f64::total_cmp);
    grid.dedup();
    grid
}

/// A path timed by TOPP-RA from rest to rest: the not-a-knot spline through its states, the
/// grid, and the speed profile (`x = s'^2` at the grid points from [`time_optimal`], `s''`
/// constant on each interval, the times of the grid points): a [`TimedSpline`] that owns its
/// arrays, with the limits it was timed for.
#[derive(Debug, Clone)]
pub struct TimedPath {
    /// The spline through the states.
    pub spline: Spline,
    /// TOPP-RA's grid ([`gridpoints`]).
    pub grid: Vec<f64>,
    /// The times of the grid points (from 0, increasing).
    pub knots: Vec<f64>,
    /// s' at each grid point.
    pub sdot: Vec<f64>,
    /// s'' on each grid interval.
    pub sdd: Vec<f64>,
    /// The joint velocity limits.
    pub vlim: Vec<f64>,
    /// The joint acceleration limits.
    pub alim: Vec<f64>,
}

/// The largest number of uniform stretches [`TimedPath::stretch`] tries.
pub const STRETCH_ATTEMPTS: i32 = 10;

impl TimedPath {
    /// The path through `states` (rows of n, distinct consecutive states) at the path
    /// parameters `s` (increasing, usually the cumulative joint-space distance) timed under
    /// the velocity and acceleration limits `vlim`, `alim` (n each, positive) on the grid of
    /// `rule`. Errors: bad shapes or values; no parameterisation within the limits (including
    /// a speed profile that stops inside the path).
    pub fn new(s: &[f64], states: &[f64], vlim: &[f64], alim: &[f64], rule: GridRule) -> Result<TimedPath> {
        let n = vlim.len();
        if n == 0 || alim.len() != n {
            return Err(Error::Invalid(format!("vlim and alim: one limit per joint (got {} and {})", n, alim.len())));
        }
        check_finite("vlim", vlim)?;
        check_finite("alim", alim)?;
        if let Some(j) = (0..n).find(|&j| vlim[j] <= 0.0 || alim[j] <= 0.0) {
            return Err(Error::Invalid(format!("limits: must be positive, joint {j} has vlim {} and alim {}", vlim[j], alim[j])));
        }
        if rule.base < 2 || !(rule.critical.is_finite() && rule.critical > 0.0) {
            return Err(Error::Invalid(format!("grid rule: base must be at least 2 and critical positive, got {rule:?}")));
        }
        let spline = Spline::not_a_knot(s, states, n)?;
        let grid = gridpoints(&spline, vlim, alim, rule);
        let points = grid.len();
        let (mut d1, mut d2) = (vec![0.0; points * n], vec![0.0; points * n]);
        for (k, &g) in grid.iter().enumerate() {
            spline.derivatives(g, &mut d1[k * n..(k + 1) * n], &mut d2[k * n..(k + 1) * n]);
        }
        let mut x = time_optimal(&grid, &d1, &d2, vlim, alim)?;
        for v in x.iter_mut() {
            *v = v.max(0.0);
        }
        x[0] = 0.0;
        x[points - 1] = 0.0;
        let sdot: Vec<f64> = x.iter().map(|v| v.sqrt()).collect();
        let mut sdd = Vec::with_capacity(points - 1);
        let mut knots = Vec::with_capacity(points);
        knots.push(0.0);
        for i in 0..points - 1 {
            let ds = grid[i + 1] - grid[i];
            // constant s'' per interval, consistent with x = s'^2
            sdd.push((x[i + 1] - x[i]) / (2.0 * ds));
            let speed = sdot[i] + sdot[i + 1];
            if !(speed > 0.0) {
                return Err(Error::Invalid(format!(
                    "the speed profile stops inside the path (grid interval {i} of {}, s = {:.4})",
                    points - 1,
                    grid[i]
                )));
            }
            knots.push(knots[i] + 2.0 * ds / speed);
        }
        Ok(TimedPath { spline, grid, knots, sdot, sdd, vlim: vlim.to_vec(), alim: alim.to_vec() })
    }

    /// Its duration at the time-optimal speed (no stretch), seconds.
    pub fn duration(&self) -> f64 {
        self.knots[self.knots.len() - 1]
    }

    /// The timed spline, borrowed ([`sample`]'s input).
    pub fn timed(&self) -> TimedSpline<'_> {
        TimedSpline { x: &self.spline.x, c: &self.spline.c, grid: &self.grid, knots: &self.knots, sdot: &self.sdot, sdd: &self.sdd }
    }

    /// The samples at `rate` Hz with the timing stretched by `scale` ([`sample`]).
    pub fn sample(&self, rate: f64, scale: f64) -> Result<Samples> {
        sample(&self.timed(), self.spline.n, rate, scale)
    }

    /// The least uniform stretch `scale` (`t -> scale t`) found that keeps every sample at
    /// `rate` Hz within the velocity and acceleration limits, with no tolerance: TOPP-RA holds
    /// them at its grid points only, and between them (and within its numerical tolerance) a
    /// sample may exceed them a little. From 1, while a sample exceeds a limit (at most
    /// [`STRETCH_ATTEMPTS`] times), the scale is multiplied by the largest excess (velocity
    /// ratio, or the square root of the acceleration ratio) times `1 + 1e-6 x 10^attempt` (a
    /// ratio may round to 1 a hair beyond its limit, and a stretch moves the ticks along the
    /// profile), and the samples are evaluated again, without being stored. The caller checks
    /// the samples it then takes (the scale after the last attempt is not certified). A scale
    /// whose samples would take more than [`MAX_SAMPLE_BYTES`] ends the search unevaluated
    /// ([`sample`] refuses it).
    pub fn stretch(&self, rate: f64) -> Result<f64> {
        if !(rate.is_finite() && rate > 0.0) {
            return Err(Error::Invalid(format!("rate must be positive and finite, got {rate}")));
        }
        let (p, n) = (self.timed(), self.spline.n);
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut scale = 1.0;
        for attempt in 0..STRETCH_ATTEMPTS {
            let total = self.duration() * scale;
            if !(sample_bytes(total, rate, n) <= MAX_SAMPLE_BYTES as f64) {
                break;
            }
            // every tick from 0 and the end when it falls between two, as `sample` takes them
            let ticks = (total * rate + 1e-9).floor() as usize;
            let last = ticks as f64 / rate;
            let times = (0..=ticks).map(|k| k as f64 / rate).chain((total - last > 1e-9).then_some(total));
            let mut walk = Walk::new(&p, n, scale);
            let (mut within, mut over_v, mut over_a) = (true, f64::NEG_INFINITY, f64::NEG_INFINITY);
            for tk in times {
                walk.at(tk, &mut q, &mut qd, &mut qdd);
                for a in 0..n {
                    let (v, acc) = (qd[a].abs(), qdd[a].abs());
                    within &= v <= self.vlim[a] && acc <= self.alim[a];
                    over_v = over_v.max(v / self.vlim[a]);
                    over_a = over_a.max(acc / self.alim[a]);
                }
            }
            if within {
                break;
            }
            let over = over_v.max(over_a.sqrt()).max(1.0);
            scale *= over * (1.0 + 1e-6 * 10f64.powi(attempt));
        }
        Ok(scale)
    }
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

    /// The not-a-knot spline is exact on a cubic (its third derivative is continuous at the
    /// first and last inner breakpoints, and a cubic satisfies every condition), on a parabola
    /// through three states and on a line through two, at uneven breakpoints (its derivatives
    /// those of the polynomial everywhere), and passes through its states.
    #[test]
    fn the_not_a_knot_spline_is_exact_on_polynomials_of_its_degree() {
        // per case: values, first and second derivatives of the two coordinates at s
        type Poly = fn(f64) -> [[f64; 2]; 3];
        let line: Poly = |s| [[1.0 + 2.0 * s, -s], [2.0, -1.0], [0.0, 0.0]];
        let parabola: Poly = |s| [[s * s - s, 2.0 - 0.5 * s * s], [2.0 * s - 1.0, -s], [2.0, -1.0]];
        let cubic: Poly = |s| {
            [[0.5 * s * s * s - s * s + 2.0 * s - 1.0, -0.25 * s * s * s + 3.0 * s], [1.5 * s * s - 2.0 * s + 2.0, -0.75 * s * s + 3.0], [3.0 * s - 2.0, -1.5 * s]]
        };
        for (points, f) in [(2usize, line), (3, parabola), (4, cubic), (7, cubic), (30, cubic)] {
            let x: Vec<f64> = (0..points).map(|i| (i as f64).powf(1.3) * 0.7 + 0.1 * (i % 3) as f64).collect();
            let y: Vec<f64> = x.iter().flat_map(|&s| f(s)[0]).collect();
            let sp = Spline::not_a_knot(&x, &y, 2).unwrap();
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-10 * b.abs().max(1.0);
            let (mut d1, mut d2) = ([0.0; 2], [0.0; 2]);
            for k in 0..=20 * (points - 1) {
                let s = x[0] + (x[points - 1] - x[0]) * k as f64 / (20 * (points - 1)) as f64;
                sp.derivatives(s, &mut d1, &mut d2);
                let want = f(s);
                for a in 0..2 {
                    assert!(close(d1[a], want[1][a]) && close(d2[a], want[2][a]), "{points} points, s = {s}: {d1:?} {d2:?} != {want:?}");
                }
            }
            // through the states
            for i in 0..points - 1 {
                for a in 0..2 {
                    assert_eq!(sp.c[i * 8 + 6 + a], y[i * 2 + a]);
                }
            }
        }
        let err = |r: Result<Spline>| r.unwrap_err().to_string();
        assert!(err(Spline::not_a_knot(&[0.0], &[1.0], 1)).contains("at least 2"));
        assert!(err(Spline::not_a_knot(&[0.0, 1.0], &[1.0, 2.0, 3.0], 1)).contains("at least 2"));
        assert!(err(Spline::not_a_knot(&[0.0, 0.0], &[1.0, 2.0], 1)).contains("must increase"));
        assert!(err(Spline::not_a_knot(&[0.0, 1.0], &[1.0, f64::NAN], 1)).contains("y"));
    }

    /// The grid: increasing, distinct, the ends and the even base among its points; a sharp
    /// corner (a state where the path turns) adds its state and its intervals' quarters; a
    /// short path gets the even points in s.
    #[test]
    fn the_grid_holds_the_base_and_the_corners() {
        let rule = GridRule { base: 5, critical: 1.0 };
        // 21 states along joint 0, then a corner at state 10 into joint 1
        let x: Vec<f64> = (0..21).map(|i| 0.05 * i as f64).collect();
        let y: Vec<f64> = (0..21).flat_map(|i| if i <= 10 { [0.05 * i as f64, 0.0] } else { [0.5, 0.05 * (i - 10) as f64] }).collect();
        let sp = Spline::not_a_knot(&x, &y, 2).unwrap();
        let grid = gridpoints(&sp, &[1.0, 1.0], &[1.0, 1.0], rule);
        assert!(grid.windows(2).all(|w| w[0] < w[1]));
        for i in [0, 5, 10, 15, 20] {
            assert!(grid.contains(&x[i]), "x[{i}] in {grid:?}");
        }
        let quarter = |i: usize| x[i] + (x[i + 1] - x[i]) * 0.25;
        assert!((8..12).any(|i| grid.contains(&quarter(i))) && grid.len() >= 9, "the corner subdivided: {grid:?}");
        // a straight, slow path: the base alone
        let flat: Vec<f64> = (0..21).flat_map(|i| [0.001 * i as f64, 0.0]).collect();
        let sp = Spline::not_a_knot(&x, &flat, 2).unwrap();
        assert_eq!(gridpoints(&sp, &[1.0, 1.0], &[1.0, 1.0], rule).len(), 5);
        // two states: both and the even points between them
        let sp = Spline::not_a_knot(&[0.0, 2.0], &[0.0, 1.0], 1).unwrap();
        assert_eq!(gridpoints(&sp, &[1.0], &[1.0], rule), vec![0.0, 0.5, 1.0, 1.5, 2.0]);
    }

    /// A timed path: at rest at both ends, its duration the last knot; the stretch it finds
    /// keeps every sample within the limits, exactly, and is 1.0 when nothing exceeds them
    /// (else some sample at 1.0 does); bad input is refused, naming it.
    #[test]
    fn a_timed_path_is_stretched_until_every_sample_is_within_the_limits() {
        let rule = GridRule { base: 40, critical: 1.0 };
        let n = 3;
        let states = 60;
        let s: Vec<f64> = (0..states).map(|i| 0.05 * i as f64).collect();
        let y: Vec<f64> = s.iter().flat_map(|&u| (0..n).map(move |j| (u * (1.0 + j as f64)).sin() / (1.0 + j as f64))).collect();
        let (vlim, alim) = ([1.0, 0.8, 1.5], [2.0, 3.0, 1.0]);
        let path = TimedPath::new(&s, &y, &vlim, &alim, rule).unwrap();
        assert!(path.duration() > 0.0 && path.sdot[0] == 0.0 && path.sdot[path.sdot.len() - 1] == 0.0);
        let within = |scale: f64| {
            let (_, _, qd, qdd) = path.sample(1000.0, scale).unwrap();
            qd.iter().zip(qdd.iter()).enumerate().all(|(k, (v, a))| v.abs() <= vlim[k % n] && a.abs() <= alim[k % n])
        };
        let scale = path.stretch(1000.0).unwrap();
        assert!(scale >= 1.0 && within(scale), "scale {scale}");
        if scale > 1.0 {
            assert!(!within(1.0), "a stretch only where a sample exceeds a limit");
        }
        let (t, q, _, _) = path.sample(1000.0, scale).unwrap();
        assert!((t[t.len() - 1] - path.duration() * scale).abs() < 1e-12);
        for a in 0..n {
            assert!((q[a] - y[a]).abs() < 1e-15 && (q[q.len() - n + a] - y[y.len() - n + a]).abs() < 1e-12);
        }
        // a straight line (bang-coast-bang, on the limits only at the grid's points): at most a
        // hair of stretch
        let line: Vec<f64> = s.iter().flat_map(|&u| [0.5 * u, 0.0, 0.0]).collect();
        let k = TimedPath::new(&s, &line, &vlim, &alim, rule).unwrap().stretch(1000.0).unwrap();
        assert!((1.0..1.0 + 1e-4).contains(&k), "{k}");
        let err = |r: Result<TimedPath>| r.unwrap_err().to_string();
        assert!(err(TimedPath::new(&s, &y, &vlim, &alim[..2], rule)).contains("one limit per joint"));
        assert!(err(TimedPath::new(&s, &y, &[1.0, 0.0, 1.0], &alim, rule)).contains("must be positive"));
        assert!(err(TimedPath::new(&s, &y, &vlim, &alim, GridRule { base: 1, critical: 1.0 })).contains("grid rule"));
        assert!(err(TimedPath::new(&s[1..], &y, &vlim, &alim, rule)).contains("spline"));
        assert!(path.stretch(0.0).unwrap_err().to_string().contains("rate"));
    }
}
