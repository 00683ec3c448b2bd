//! The primary terms' residuals without a solve: stacked at one configuration (with their
//! Jacobian), and the residual-only check of many configurations.

use nalgebra::{DMatrix, DVector};

use super::terms::{nominals, State};
use super::{residual_size, Projector, SolveError, TermKind, TermResult};
#[cfg(doc)]
use super::{Outcome, TermFailure};
use crate::error::{Error, Result};

impl Projector {
    /// The primary terms' weighted residuals stacked (length [`primary_dim`](Self::primary_dim))
    /// and, when `with_jacobian`, their weighted Jacobian (rows x nv, tangent space), at `q`
    /// (checked like [`solve`](Self::solve)); a Posture term's nominal is `q` itself. The costs a
    /// learned sampler is trained with (`genplan.gan.costs`) are these residuals.
    /// A failing custom term's error becomes a core [`Error`] ([`TermFailure::into_error`]);
    /// [`try_primary_residuals`](Self::try_primary_residuals) returns it intact.
    pub fn primary_residuals(&self, q: &[f64], with_jacobian: bool) -> Result<(DVector<f64>, Option<DMatrix<f64>>)> {
        self.try_primary_residuals(q, with_jacobian).map_err(Error::from)
    }

    /// [`primary_residuals`](Self::primary_residuals), a custom term's failure returned intact.
    pub fn try_primary_residuals(&self, q: &[f64], with_jacobian: bool) -> std::result::Result<(DVector<f64>, Option<DMatrix<f64>>), SolveError> {
        self.model.check_configuration(q)?;
        let nominal = nominals(&self.primary, q);
        let s = self.state(q.to_vec());
        let (raws, j) = self.stack(&self.primary, &s, &nominal, with_jacobian)?;
        Ok((Self::weighted(&self.primary, &raws), j))
    }

    /// Rows of [`primary_residuals`](Self::primary_residuals): the primary terms' residual sizes summed.
    pub fn primary_dim(&self) -> usize {
        self.primary.iter().map(|t| self.dim(t)).sum()
    }

    /// Per row of `qs` (rows of `nq` numbers) and primary term, the term's residual size at that
    /// row ([`residual_size`]: what [`Outcome::residuals`] reports and the terms' tolerances
    /// bound), row after row (rows x primary terms): the residual-only check of many
    /// configurations, such as a timed trajectory's samples, with no solver step, no clipping
    /// and no Jacobian (one forward kinematics a row). Every row is checked like
    /// [`solve`](Self::solve) before any is evaluated. Rows run on rayon's threads when
    /// `parallel`; a failing custom term's error is returned intact (the first one met).
    pub fn try_residual_sizes(&self, qs: &[f64], parallel: bool) -> std::result::Result<Vec<f64>, SolveError> {
        use rayon::prelude::*;
        let nq = self.model.nq.max(1);
        if qs.len() % nq != 0 {
            return Err(Error::Invalid(format!("q: {} numbers are not rows of {nq}", qs.len())).into());
        }
        for q in qs.chunks(nq) {
            self.model.check_configuration(q)?;
        }
        let terms = self.primary.len();
        let mut out = vec![0.0; qs.len() / nq * terms];
        if terms == 0 {
            return Ok(out);
        }
        // only a Posture term reads its nominal (the row itself, or its own): the others are
        // given the row, with no copy per term
        let postures = self.primary.iter().any(|t| matches!(t.kind, TermKind::Posture { .. }));
        let empty = || State { q: Vec::with_capacity(nq), poses: Vec::new() };
        // one row, in a state kept across rows (no allocation for q and the poses), each term's
        // size into `sizes`
        let row = |s: &mut State, q: &[f64], sizes: &mut [f64]| -> TermResult<()> {
            s.q.clear();
            s.q.extend_from_slice(q);
            self.model.forward_kinematics_unchecked(q, &mut s.poses);
            let nominal = if postures { nominals(&self.primary, q) } else { Vec::new() };
            let mut no_jacobian = DMatrix::zeros(0, 0);
            for (i, (t, size)) in self.primary.iter().zip(sizes.iter_mut()).enumerate() {
                let n = nominal.get(i).map_or(q, Vec::as_slice);
                *size = residual_size(&self.eval(t, s, n, false, &mut no_jacobian)?.0);
            }
            Ok(())
        };
        if parallel {
            out.par_chunks_mut(terms).zip(qs.par_chunks(nq)).try_for_each_init(empty, |s, (sizes, q)| row(s, q, sizes))?;
        } else {
            let mut s = empty();
            for (sizes, q) in out.chunks_mut(terms).zip(qs.chunks(nq)) {
                row(&mut s, q, sizes)?;
            }
        }
        Ok(out)
    }
}
