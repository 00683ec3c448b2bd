//! Projectors: the [`Projector`] trait (batches of configurations onto the constraint
//! manifold, each around its own nominal posture), what one projection reports
//! ([`Projection`]), and the adapter of the native damped Gauss-Newton solver
//! ([`GaussNewtonProjector`] around [`crate::projection::Projector`]).
//!
//! States between two tree nodes (a validated tree edge) are projected with
//! [`Projector::project_edge`]: only whether each lands on the manifold, near its interpolation,
//! matters there. The native projector drops its secondary (posture) step for them: the primary
//! step is already the minimum-norm correction for states so near the manifold, and the posture
//! step cost a third of the time of a projected edge state (issue 17: 51 us with it, 33 us
//! without), for the same plans (rust/core/tests/planning.rs). A shortcut's states, farther off,
//! keep it (`ConstrainedSpace::geodesic`).

use std::sync::Arc;

use rayon::prelude::*;

use super::{PlanError, PlanResult};
use crate::projection::TermFailure;

/// What one projection did.
#[derive(Debug, Clone, Copy, Default)]
pub struct Projection {
    /// The projected configuration satisfies the constraints (within their tolerances).
    pub success: bool,
    /// Optimisation steps (Gauss-Newton iterations) spent.
    pub iterations: usize,
}

/// Projects configurations onto the constraint manifold.
pub trait Projector: Send {
    /// Project the rows of `qs` (n x nq), row i with a posture task around row i of `q_noms`;
    /// write the projected rows to `out` and what happened to `reports` (length n).
    fn project(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()>;

    /// Project the states of an edge (interpolations between two states on the manifold), as
    /// [`project`](Self::project) does; only the constraint matters for them, so a projector may
    /// skip work that serves the posture alone. Default: [`project`](Self::project).
    fn project_edge(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        self.project(qs, q_noms, out, reports)
    }

    /// The chord check: `ok[i]` says whether row i of `qs` (the midpoint of the straight chord
    /// between two consecutive states of an edge) satisfies the constraint within the tolerance
    /// the chords of a path are held to. Returns false, leaving `ok` alone, when this projector
    /// holds the chords to no tolerance (the default): they are then not checked.
    fn check_chords(&mut self, _qs: &[f64], _ok: &mut [bool]) -> PlanResult<bool> {
        Ok(false)
    }
}

/// The native damped Gauss-Newton projector; a batch runs on rayon's threads when `parallel`.
/// Edge states ([`Projector::project_edge`]) are projected without the secondary terms (the
/// posture step). With [`with_chord_tolerance`](Self::with_chord_tolerance) it also checks the
/// chords between consecutive states ([`Projector::check_chords`]).
pub struct GaussNewtonProjector {
    inner: Arc<crate::projection::Projector>,
    /// `inner` without its secondary terms.
    primary_only: Arc<crate::projection::Projector>,
    /// The chord check: the primary terms at their tolerances times the chord tolerance, no
    /// iteration (an evaluation), or None.
    chords: Option<Arc<crate::projection::Projector>>,
    /// Project the configurations of a batch on rayon's threads.
    pub parallel: bool,
}

impl GaussNewtonProjector {
    /// The planner's projector around the solver `inner` (its task and settings).
    pub fn new(inner: Arc<crate::projection::Projector>, parallel: bool) -> GaussNewtonProjector {
        let primary_only = if inner.secondary.is_empty() {
            inner.clone()
        } else {
            let mut p = (*inner).clone();
            p.secondary.clear();
            Arc::new(p)
        };
        GaussNewtonProjector { inner, primary_only, chords: None, parallel }
    }

    /// This projector, holding the chords between consecutive states of every edge to its
    /// primary terms' tolerances times `scale` ([`Projector::check_chords`]). A planner whose
    /// projector solves a task with its tolerances tightened by a factor f (as
    /// `genplan.planning.Planner` does, f = 0.1) passes 1 / f: every chord of the path then
    /// satisfies the task at its own tolerances. `scale` must be positive and finite
    /// ([`PlanError::Settings`] naming `chord_tolerance`).
    pub fn with_chord_tolerance(mut self, scale: f64) -> PlanResult<GaussNewtonProjector> {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(PlanError::Settings { field: "chord_tolerance", msg: format!("chord_tolerance must be positive and finite, got {scale}") });
        }
        let mut p = (*self.primary_only).clone();
        for t in &mut p.primary {
            t.tolerance *= scale;
        }
        // an evaluation where the configuration stands: no iteration, no clipping
        p.settings.max_iterations = 0;
        p.settings.clip_to_limits = false;
        self.chords = Some(Arc::new(p));
        Ok(self)
    }

    /// The solver and its task.
    pub fn inner(&self) -> &Arc<crate::projection::Projector> {
        &self.inner
    }
}

impl Projector for GaussNewtonProjector {
    /// A custom term's failure ends the batch: the first one is returned as
    /// [`PlanError::Component`] holding the term's own error (e.g. a Python exception, which the
    /// bindings give back unchanged), or the core error naming the term (a non-finite or
    /// misshapen output). A task with a custom term is solved one row after the other (a custom
    /// term may call back into an interpreter that runs one call at a time).
    fn project(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        solve_batch(&self.inner, self.parallel, qs, q_noms, out, reports)
    }

    /// [`project`](Projector::project) with the primary terms only (no posture step).
    fn project_edge(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        solve_batch(&self.primary_only, self.parallel, qs, q_noms, out, reports)
    }

    /// Each point's primary residuals against the tolerances times the chord tolerance (one
    /// forward kinematics per point, no solver step), when the projector has one.
    fn check_chords(&mut self, qs: &[f64], ok: &mut [bool]) -> PlanResult<bool> {
        let Some(chords) = &self.chords else {
            return Ok(false);
        };
        let mut out = vec![0.0; qs.len()];
        let mut reports = vec![Projection::default(); ok.len()];
        solve_batch(chords, self.parallel, qs, qs, &mut out, &mut reports)?;
        for (o, r) in ok.iter_mut().zip(&reports) {
            *o = r.success;
        }
        Ok(true)
    }
}

/// Solve the rows of `qs` (each around its row of `q_noms`) with `solver`, on rayon's threads
/// when `parallel` (and no custom term).
fn solve_batch(
    solver: &crate::projection::Projector,
    parallel: bool,
    qs: &[f64],
    q_noms: &[f64],
    out: &mut [f64],
    reports: &mut [Projection],
) -> PlanResult<()> {
        let nq = solver.model.nq;
        let solve = |(q, nom): (&[f64], &[f64])| {
            solver
                .try_solve_unchecked(q, Some(nom))
                .map(|o| (o.q, Projection { success: o.success, iterations: o.iterations }))
        };
        let custom = solver.has_custom_terms();
        let results: Vec<Result<(Vec<f64>, Projection), TermFailure>> = if parallel && !custom && reports.len() > 1 {
            qs.par_chunks(nq).zip(q_noms.par_chunks(nq)).map(solve).collect()
        } else {
            // sequential: stop at the first failure
            let mut v = Vec::with_capacity(reports.len());
            for pair in qs.chunks(nq).zip(q_noms.chunks(nq)) {
                let r = solve(pair);
                let failed = r.is_err();
                v.push(r);
                if failed {
                    break;
                }
            }
            v
        };
        for (r, (row, slot)) in results.into_iter().zip(out.chunks_mut(nq).zip(reports.iter_mut())) {
            let (q, rep) = r.map_err(term_failure)?;
            row.copy_from_slice(&q);
            *slot = rep;
        }
        Ok(())
}

/// A custom term's failure as the planner's component error: the term's own error unchanged,
/// or (for a core error such as a non-finite output) the core error naming the term.
fn term_failure(f: TermFailure) -> PlanError {
    if f.source.is::<crate::error::Error>() {
        PlanError::Component(Box::new(f.into_error()))
    } else {
        PlanError::Component(f.source)
    }
}
