//! Dense paths on a task's manifold: a path's states interpolated wherever two consecutive ones
//! are more than a resolution apart, and projected ([`densify`]); the chords between consecutive
//! states held to the task's tolerance ([`hold_chords`]). What `genplan.seq2seq.finish` makes of
//! a decoded trajectory before it checks and times it, one path at a time with no allocation per
//! state beyond the path itself (the bindings run the paths of a batch on rayon's threads).
//!
//! Steps between states are measured as the largest joint difference (max over the joints).

use super::{Projector, SolveError};
use crate::error::{Error, Result};

/// How [`densify`] and [`hold_chords`] work (`genplan.seq2seq.finish`'s constants).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DenseSettings {
    /// The largest joint step (rad, max over the joints) between consecutive dense states.
    pub resolution: f64,
    /// A projected interpolated state more than this many resolutions from its interpolation
    /// is a change of branch ([`DenseFailure::Jump`]).
    pub max_jump: f64,
    /// Rounds of interpolation and projection (each at most halves the largest step).
    pub max_rounds: usize,
    /// Rounds of chord splitting.
    pub chord_rounds: usize,
    /// A chord strays when, at its midpoint, a primary term of the chord projector exceeds this
    /// fraction of its tolerance.
    pub chord_fraction: f64,
}

impl DenseSettings {
    /// Refuses a resolution, jump or chord fraction that is not positive and finite.
    pub fn validate(&self) -> Result<()> {
        for (field, v) in [("resolution", self.resolution), ("max_jump", self.max_jump), ("chord_fraction", self.chord_fraction)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::Settings { field, msg: format!("{field} must be positive and finite, got {v}") });
            }
        }
        Ok(())
    }
}

/// The most states a dense path may have: a path that would need more (a step of thousands of
/// resolutions) fails with [`DenseFailure::Steps`] instead of allocating them.
pub const MAX_DENSE_STATES: usize = 1 << 20;

/// Why a path could not be made dense (the path returned with it is the one before the step
/// that failed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DenseFailure {
    /// An interpolated state could not be projected onto the manifold.
    Projection,
    /// A projected interpolated state moved this far (rad, max over the joints; the largest of
    /// its round) from its interpolation: a change of branch.
    Jump(f64),
    /// After the rounds the largest step (rad) is still more than 1.5 resolutions (or the path
    /// would need more than [`MAX_DENSE_STATES`] states).
    Steps(f64),
    /// A chord strays off the manifold though it is shorter than an eighth of the resolution.
    ChordTooShort,
    /// A straying chord's midpoint could not be projected onto the manifold.
    ChordProjection,
}

impl DenseFailure {
    /// Its name (`"projection"`, `"jump"`, `"steps"`, `"chord_too_short"`, `"chord_projection"`)
    /// and its number (NaN for the kinds without one).
    pub fn parts(&self) -> (&'static str, f64) {
        match *self {
            DenseFailure::Projection => ("projection", f64::NAN),
            DenseFailure::Jump(v) => ("jump", v),
            DenseFailure::Steps(v) => ("steps", v),
            DenseFailure::ChordTooShort => ("chord_too_short", f64::NAN),
            DenseFailure::ChordProjection => ("chord_projection", f64::NAN),
        }
    }
}

/// A path (rows of n) and, when it could not be made dense, why.
#[derive(Debug, Clone, PartialEq)]
pub struct Dense {
    /// The states, rows of n.
    pub path: Vec<f64>,
    /// None, or why the path is not dense.
    pub failure: Option<DenseFailure>,
}

/// The larger of `a` and `b`, NaN when either is (numpy's `max`: a NaN is never a step within
/// the resolution).
fn larger(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else {
        a.max(b)
    }
}

/// The largest joint difference between `a` and `b`.
fn step(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (y - x).abs()).fold(f64::NEG_INFINITY, larger)
}

/// The steps between consecutive rows of `path` (rows of n).
fn steps(path: &[f64], n: usize) -> Vec<f64> {
    path.chunks_exact(n).zip(path.chunks_exact(n).skip(1)).map(|(a, b)| step(a, b)).collect()
}

/// Project `rows` (rows of n, in place) with `project`, each around itself; false as soon as one
/// does not reach the manifold.
fn project_rows(project: &Projector, rows: &mut [f64], n: usize) -> std::result::Result<bool, SolveError> {
    for row in rows.chunks_exact_mut(n) {
        let out = project.try_solve_unchecked(row, Some(row))?;
        if !out.success {
            return Ok(false);
        }
        row.copy_from_slice(&out.q);
    }
    Ok(true)
}

fn check_shape(q: &[f64], n: usize, project: Option<&Projector>) -> Result<()> {
    if n == 0 || q.len() % n != 0 {
        return Err(Error::Invalid(format!("path: {} numbers are not rows of {n}", q.len())));
    }
    if let Some(p) = project {
        if p.model.nq != n {
            return Err(Error::Invalid(format!("path: rows of {n}, but the projector's robot has {} joints", p.model.nq)));
        }
    }
    Ok(())
}

/// The path through the states `q` (rows of n) with every step at most `settings.resolution`:
/// in rounds (at most `max_rounds`), every pair of consecutive states `m > 1` resolutions apart
/// (`m` = the step over the resolution, rounded up) gets the `m - 1` states evenly spaced on
/// their straight line between them, projected with `project` (each around itself; None: kept
/// as interpolated). A projection that fails ([`DenseFailure::Projection`]) or a projected state
/// more than `max_jump` resolutions from its interpolation ([`DenseFailure::Jump`]) ends it;
/// after the rounds, steps of up to 1.5 resolutions are accepted ([`DenseFailure::Steps`]
/// beyond). The rows are not checked here (the bindings check each once, up front); a
/// non-finite one ends as a failure, never a panic. Errors: shapes, settings, a custom term's
/// failure.
pub fn densify(q: &[f64], n: usize, settings: &DenseSettings, project: Option<&Projector>) -> std::result::Result<Dense, SolveError> {
    check_shape(q, n, project)?;
    settings.validate()?;
    let res = settings.resolution;
    let mut path = q.to_vec();
    for _ in 0..settings.max_rounds {
        let steps = steps(&path, n);
        if steps.iter().all(|&s| s <= res * (1.0 + 1e-9)) {
            return Ok(Dense { path, failure: None });
        }
        // the states each step is cut into (NaN: none; the count bounded before allocating)
        let cuts: Vec<f64> = steps.iter().map(|&s| (s / res).ceil()).collect();
        let total: f64 = path.len() as f64 / n as f64 + cuts.iter().filter(|&&m| m > 1.0).map(|m| m - 1.0).sum::<f64>();
        if !(total <= MAX_DENSE_STATES as f64) {
            let largest = steps.iter().copied().fold(f64::NEG_INFINITY, larger);
            return Ok(Dense { path, failure: Some(DenseFailure::Steps(largest)) });
        }
        let mut rows = Vec::new();
        for (s, &m) in cuts.iter().enumerate() {
            if m > 1.0 {
                let (a, b) = (&path[s * n..(s + 1) * n], &path[(s + 1) * n..(s + 2) * n]);
                let m = m as usize;
                for k in 1..m {
                    let f = k as f64 / m as f64;
                    rows.extend(a.iter().zip(b).map(|(x, y)| x + f * (y - x)));
                }
            }
        }
        if let Some(p) = project {
            let mut projected = rows.clone();
            if !project_rows(p, &mut projected, n)? {
                return Ok(Dense { path, failure: Some(DenseFailure::Projection) });
            }
            let moved = projected.chunks_exact(n).zip(rows.chunks_exact(n)).map(|(a, b)| step(b, a)).fold(f64::NEG_INFINITY, larger);
            if moved > settings.max_jump * res {
                return Ok(Dense { path, failure: Some(DenseFailure::Jump(moved)) });
            }
            rows = projected;
        }
        let mut out = Vec::with_capacity(path.len() + rows.len());
        out.extend_from_slice(&path[..n]);
        let mut next = rows.chunks_exact(n);
        for (s, &m) in cuts.iter().enumerate() {
            if m > 1.0 {
                for _ in 1..m as usize {
                    out.extend_from_slice(next.next().expect("one interpolated row per cut"));
                }
            }
            out.extend_from_slice(&path[(s + 1) * n..(s + 2) * n]);
        }
        path = out;
    }
    let largest = steps(&path, n).into_iter().fold(f64::NEG_INFINITY, larger);
    let failure = (!steps(&path, n).iter().all(|&s| s <= 1.5 * res)).then_some(DenseFailure::Steps(largest));
    Ok(Dense { path, failure })
}

/// The planner's chord rule on a dense path (rows of n): in rounds (at most `chord_rounds`),
/// the midpoint of every chord between consecutive states is evaluated on the primary terms of
/// `chords` (no solver step: [`Projector::try_residual_sizes`]), and a chord whose midpoint
/// exceeds `chord_fraction` of a term's tolerance is split at its midpoint projected with
/// `project` (around itself). A straying chord shorter than an eighth of the resolution
/// ([`DenseFailure::ChordTooShort`]) or a midpoint that cannot be projected
/// ([`DenseFailure::ChordProjection`]) ends it. The rows are not checked (as in [`densify`]).
pub fn hold_chords(
    path: &[f64],
    n: usize,
    settings: &DenseSettings,
    project: &Projector,
    chords: &Projector,
) -> std::result::Result<Dense, SolveError> {
    check_shape(path, n, Some(project))?;
    check_shape(path, n, Some(chords))?;
    settings.validate()?;
    let limits: Vec<f64> = chords.primary.iter().map(|t| settings.chord_fraction * t.tolerance).collect();
    let terms = limits.len();
    let mut path = path.to_vec();
    for _ in 0..settings.chord_rounds {
        let mids: Vec<f64> =
            path.chunks_exact(n).zip(path.chunks_exact(n).skip(1)).flat_map(|(a, b)| b.iter().zip(a).map(|(y, x)| 0.5 * (y + x))).collect();
        let sizes = chords.try_residual_sizes_unchecked(&mids, false)?;
        let bad: Vec<bool> = (0..mids.len() / n).map(|i| (0..terms).any(|t| sizes[i * terms + t] > limits[t])).collect();
        if !bad.iter().any(|&b| b) {
            return Ok(Dense { path, failure: None });
        }
        let short = |i: usize| step(&path[i * n..(i + 1) * n], &path[(i + 1) * n..(i + 2) * n]) < settings.resolution / 8.0;
        if (0..bad.len()).any(|i| bad[i] && short(i)) {
            return Ok(Dense { path, failure: Some(DenseFailure::ChordTooShort) });
        }
        let mut split: Vec<f64> = (0..bad.len()).filter(|&i| bad[i]).flat_map(|i| mids[i * n..(i + 1) * n].iter().copied()).collect();
        if !project_rows(project, &mut split, n)? {
            return Ok(Dense { path, failure: Some(DenseFailure::ChordProjection) });
        }
        let mut out = Vec::with_capacity(path.len() + split.len());
        out.extend_from_slice(&path[..n]);
        let mut next = split.chunks_exact(n);
        for (i, &b) in bad.iter().enumerate() {
            if b {
                out.extend_from_slice(next.next().expect("one projected midpoint per straying chord"));
            }
            out.extend_from_slice(&path[(i + 1) * n..(i + 2) * n]);
        }
        path = out;
    }
    Ok(Dense { path, failure: None })
}

/// [`densify`] (when `densify`) and then, when it succeeded and both projectors are given,
/// [`hold_chords`]: a dense path whose chords stay on the manifold.
pub fn dense_path(
    q: &[f64],
    n: usize,
    settings: &DenseSettings,
    project: Option<&Projector>,
    chords: Option<&Projector>,
    densify_first: bool,
) -> std::result::Result<Dense, SolveError> {
    let d = if densify_first {
        densify(q, n, settings, project)?
    } else {
        check_shape(q, n, project)?;
        Dense { path: q.to_vec(), failure: None }
    };
    match (d.failure, project, chords) {
        (None, Some(p), Some(c)) => hold_chords(&d.path, n, settings, p, c),
        _ => Ok(d),
    }
}
