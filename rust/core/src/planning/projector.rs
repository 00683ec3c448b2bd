//! Projectors: the [`Projector`] trait (batches of configurations onto the constraint
//! manifold, each around its own nominal posture), what one projection reports
//! ([`Projection`]), and the adapter of the native damped Gauss-Newton solver
//! ([`GaussNewtonProjector`] around [`crate::projection::Projector`]).

use std::sync::Arc;

use rayon::prelude::*;

use super::PlanResult;

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
}

/// The native damped Gauss-Newton projector; a batch runs on rayon's threads when `parallel`.
pub struct GaussNewtonProjector {
    /// The solver and its task.
    pub inner: Arc<crate::projection::Projector>,
    /// Project the configurations of a batch on rayon's threads.
    pub parallel: bool,
}

impl Projector for GaussNewtonProjector {
    fn project(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        let nq = self.inner.model.nq;
        let solve = |(q, nom): (&[f64], &[f64])| {
            let o = self.inner.solve_unchecked(q, Some(nom));
            (o.q, Projection { success: o.success, iterations: o.iterations })
        };
        let results: Vec<(Vec<f64>, Projection)> = if self.parallel && reports.len() > 1 {
            qs.par_chunks(nq).zip(q_noms.par_chunks(nq)).map(solve).collect()
        } else {
            qs.chunks(nq).zip(q_noms.chunks(nq)).map(solve).collect()
        };
        for ((q, rep), (row, slot)) in results.into_iter().zip(out.chunks_mut(nq).zip(reports.iter_mut())) {
            row.copy_from_slice(&q);
            *slot = rep;
        }
        Ok(())
    }
}
