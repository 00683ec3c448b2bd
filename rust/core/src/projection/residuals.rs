//! The primary terms' residuals without a solve: stacked at one configuration (with their
//! Jacobian), and the residual-only check of many configurations.

use nalgebra::{DMatrix, DVector};

use super::terms::{largest_abs, nominal_of, nominals, State};
use super::{residual_size, Projector, SolveError, Term, TermKind, TermResult};
#[cfg(doc)]
use super::{Outcome, TermFailure};
use crate::error::{Error, Result};
#[cfg(doc)]
use crate::kinematics::KinematicModel;

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
    /// and no Jacobian. Each row computes only the forward kinematics its terms read (the joints
    /// placing their links: [`KinematicModel::joints_placing`]; every link for a centre of mass;
    /// none for joint, posture and custom terms) and evaluates the built-in terms into buffers
    /// kept across rows, allocating nothing per row; the sizes are those of
    /// [`primary_residuals`](Self::primary_residuals), bit for bit. Every row is checked like
    /// [`solve`](Self::solve) before any is evaluated. Rows run on rayon's threads when
    /// `parallel`; a failing custom term's error is returned intact (the first one met).
    pub fn try_residual_sizes(&self, qs: &[f64], parallel: bool) -> std::result::Result<Vec<f64>, SolveError> {
        let nq = self.model.nq.max(1);
        if qs.len() % nq != 0 {
            return Err(Error::Invalid(format!("q: {} numbers are not rows of {nq}", qs.len())).into());
        }
        for q in qs.chunks(nq) {
            self.model.check_configuration(q)?;
        }
        self.try_residual_sizes_unchecked(qs, parallel)
    }

    /// [`try_residual_sizes`](Self::try_residual_sizes) of rows already checked by
    /// [`KinematicModel::check_configuration`] (the bindings check a batch once, up front,
    /// naming the bad row; the midpoints of checked rows need none). A length that is not rows
    /// of `nq` is still refused; a non-finite row gives +inf sizes, never a panic.
    pub fn try_residual_sizes_unchecked(&self, qs: &[f64], parallel: bool) -> std::result::Result<Vec<f64>, SolveError> {
        use rayon::prelude::*;
        let nq = self.model.nq.max(1);
        if qs.len() % nq != 0 {
            return Err(Error::Invalid(format!("q: {} numbers are not rows of {nq}", qs.len())).into());
        }
        let terms = self.primary.len();
        let mut out = vec![0.0; qs.len() / nq * terms];
        if terms == 0 {
            return Ok(out);
        }
        let joints = self.joints_read(&self.primary);
        // the longest built-in residual (a custom term's comes from its own call)
        let rows = self.primary.iter().filter(|t| !matches!(t.kind, TermKind::Custom(_))).map(|t| self.dim(t)).max().unwrap_or(0);
        let empty = || Row { s: State { q: Vec::with_capacity(nq), poses: Vec::new() }, nominal: Vec::new(), r: vec![0.0; rows] };
        // one row, in buffers kept across rows, each term's size into `sizes`
        let row = |b: &mut Row, q: &[f64], sizes: &mut [f64]| -> TermResult<()> {
            b.s.q.clear();
            b.s.q.extend_from_slice(q);
            if let Some(joints) = joints {
                self.model.forward_kinematics_prefix(q, &mut b.s.poses, joints);
            }
            for (t, size) in self.primary.iter().zip(sizes.iter_mut()) {
                // a Posture term reads its nominal (the row itself, or its own); the others the row
                let n = nominal_of(t, q, &mut b.nominal);
                *size = if let TermKind::Custom(_) = t.kind {
                    let mut no_jacobian = DMatrix::zeros(0, 0);
                    residual_size(&self.eval(t, &b.s, n, false, &mut no_jacobian)?.0)
                } else {
                    let r = &mut b.r[..self.dim(t)];
                    self.residual_into(t, &b.s, n, r);
                    largest_abs(r)
                };
            }
            Ok(())
        };
        if parallel {
            out.par_chunks_mut(terms).zip(qs.par_chunks(nq)).try_for_each_init(empty, |b, (sizes, q)| row(b, q, sizes))?;
        } else {
            let mut b = empty();
            for (sizes, q) in out.chunks_mut(terms).zip(qs.chunks(nq)) {
                row(&mut b, q, sizes)?;
            }
        }
        Ok(out)
    }

    /// How many leading joints [`forward_kinematics_prefix`](KinematicModel::forward_kinematics_prefix)
    /// needs for `terms` to read every link pose they read: None when they read none (joint
    /// limits, postures, custom terms, which see the configuration alone), every joint for a
    /// centre of mass (every link's pose), else the joints placing the terms' links
    /// ([`KinematicModel::joints_placing`]).
    pub(super) fn joints_read(&self, terms: &[Term]) -> Option<usize> {
        let mut links = Vec::new();
        for t in terms {
            match &t.kind {
                TermKind::FramePose { link, .. }
                | TermKind::FramePosition { link, .. }
                | TermKind::FrameOrientation { link, .. }
                | TermKind::PointAt { link, .. }
                | TermKind::Plane { link, .. } => links.push(*link),
                TermKind::RelativePose { link, relative_to, .. } | TermKind::RelativePosition { link, relative_to, .. } => {
                    links.extend([*link, *relative_to])
                }
                TermKind::ComBox { .. } => return Some(self.model.joints.len()),
                TermKind::JointLimits { .. } | TermKind::Posture { .. } | TermKind::Custom(_) => {}
            }
        }
        (!links.is_empty()).then(|| self.model.joints_placing(&links))
    }
}

/// A row's buffers in the residual-only check, kept across the rows one thread evaluates.
struct Row {
    /// The row's configuration and the link poses its terms read.
    s: State,
    /// A Posture term's nominal with its overrides.
    nominal: Vec<f64>,
    /// A built-in term's residual.
    r: Vec<f64>,
}
