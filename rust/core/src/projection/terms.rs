//! The built-in residual terms ([`TermKind`], [`Term`]): what each measures, its residual and its
//! analytic Jacobian, and the kinematic state they are evaluated at.

use std::sync::Arc;

use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Matrix6, SMatrix, Vector3};

use super::{CustomTerm, Projector, TermError, TermFailure, TermResult};
use crate::error::check_finite;
use crate::lie::{action, jlog3, jlog6, log3, log6, skew};

/// What a residual term measures.
#[derive(Debug, Clone)]
pub enum TermKind {
    /// r = mask * log6(T_ref^-1 T(q)).
    FramePose {
        /// Index of the link.
        link: usize,
        /// T_ref, in the world.
        target: Isometry3<f64>,
        /// Per component of the residual (linear, then angular); 0 drops it.
        mask: [f64; 6],
    },
    /// r = mask * (p(q) - p_ref).
    FramePosition {
        /// Index of the link.
        link: usize,
        /// p_ref, in the world.
        target: Vector3<f64>,
        /// Per component of the residual; 0 drops it.
        mask: [f64; 3],
    },
    /// r = mask * log3(R_ref^T R(q) R_offset).
    FrameOrientation {
        /// Index of the link.
        link: usize,
        /// R_ref, in the world.
        target: Matrix3<f64>,
        /// R_offset, in the link frame.
        offset: Matrix3<f64>,
        /// Per component of the residual; 0 drops it.
        mask: [f64; 3],
    },
    /// The pose of one link in another's frame: r = mask * log6(T_ref^-1 T_B(q)^-1 T_A(q)), A
    /// the link, B `relative_to` (the error convention of [`FramePose`](Self::FramePose), with
    /// `T_B^-1 T_A` for the link's pose in the world; a mask on the linear part alone leaves an
    /// orientation with free axes).
    RelativePose {
        /// Index of the link (A).
        link: usize,
        /// Index of the link whose frame the pose is measured in (B), not `link`.
        relative_to: usize,
        /// T_ref, the pose of A in B's frame.
        target: Isometry3<f64>,
        /// Per component of the residual (linear, then angular); 0 drops it.
        mask: [f64; 6],
    },
    /// The position of one link's origin in another's frame: r = mask * (R_B^T (p_A - p_B) - p_ref).
    RelativePosition {
        /// Index of the link (A).
        link: usize,
        /// Index of the link whose frame the position is measured in (B), not `link`.
        relative_to: usize,
        /// p_ref, in B's frame.
        target: Vector3<f64>,
        /// Per component of the residual (B's axes); 0 drops it.
        mask: [f64; 3],
    },
    /// An axis of a link pointing through a point: r = E^T R^T (c - p), the part of the point's
    /// offset from the link's origin (in the link's frame) orthogonal to the axis, in the
    /// orthonormal basis E (3 x 2) of the plane orthogonal to the axis that [`axis_complement`]
    /// gives. Two rows, each with a Jacobian of full rank (a third row along the axis would be
    /// zero to first order); their norm is the point's distance from the axis's line. The point
    /// may lie on either side of the origin along the axis.
    PointAt {
        /// Index of the link.
        link: usize,
        /// The axis, a unit vector in the link's frame.
        axis: Vector3<f64>,
        /// c, the point, in the world.
        point: Vector3<f64>,
    },
    /// A link's origin on a plane: r = n . p - d (one row, the signed distance from the plane).
    Plane {
        /// Index of the link.
        link: usize,
        /// n, the plane's unit normal, in the world.
        normal: Vector3<f64>,
        /// d, the plane's offset along the normal from the world's origin.
        offset: f64,
    },
    /// r = min(q - lower, 0) + max(q - upper, 0) over the bounded joints.
    JointLimits {
        /// A joint's Jacobian row is active within this distance of a limit.
        margin: f64,
    },
    /// r = min(c - lower, 0) + max(c - upper, 0), c the centre of mass.
    ComBox {
        /// Lower corner of the box, in the world.
        lower: Vector3<f64>,
        /// Upper corner of the box, in the world.
        upper: Vector3<f64>,
        /// A coordinate's Jacobian row is active within this distance of a face.
        margin: f64,
    },
    /// r = weights * (q (-) q_nom); `q_nom` None: the solve's nominal posture, with `overrides`
    /// (q index, value) applied.
    Posture {
        /// A fixed nominal posture (length nq), or None.
        q_nom: Option<Vec<f64>>,
        /// Per tangent component (length nv).
        weights: Vec<f64>,
        /// (q index, value) pairs that replace the solve's nominal posture there.
        overrides: Vec<(usize, f64)>,
    },
    /// r = the caller's own ([`CustomTerm::evaluate`]).
    Custom(Arc<dyn CustomTerm>),
}

/// A weighted residual term with its tolerance.
#[derive(Debug, Clone)]
pub struct Term {
    /// Its name, in error messages.
    pub name: String,
    /// What it measures.
    pub kind: TermKind,
    /// Multiplies its residual and Jacobian.
    pub weight: f64,
    /// A primary term is satisfied when its largest absolute unweighted residual component is
    /// below this.
    pub tolerance: f64,
}

/// Kinematic state at one q: link poses, and lazily the centre of mass.
pub(super) struct State {
    pub(super) q: Vec<f64>,
    pub(super) poses: Vec<Isometry3<f64>>,
}

impl Projector {
    pub(super) fn state(&self, q: Vec<f64>) -> State {
        let mut poses = Vec::new();
        self.model.forward_kinematics_unchecked(&q, &mut poses);
        State { q, poses }
    }

    pub(super) fn dim(&self, t: &Term) -> usize {
        match &t.kind {
            TermKind::FramePose { .. } | TermKind::RelativePose { .. } => 6,
            TermKind::FramePosition { .. } | TermKind::FrameOrientation { .. } | TermKind::ComBox { .. } | TermKind::RelativePosition { .. } => 3,
            TermKind::PointAt { .. } => 2,
            TermKind::Plane { .. } => 1,
            TermKind::JointLimits { .. } => self.bounded.len(),
            TermKind::Posture { .. } => self.model.nv,
            TermKind::Custom(c) => c.dim(),
        }
    }

    /// A custom term's residual and, when `with_jac`, its Jacobian (dim x nv), checked finite.
    fn custom(&self, t: &Term, c: &dyn CustomTerm, s: &State, with_jac: bool) -> TermResult<(DVector<f64>, Option<DMatrix<f64>>)> {
        let (d, nv) = (c.dim(), self.model.nv);
        let fail = |source: TermError| TermFailure { term: t.name.clone(), source };
        let mut r = vec![0.0; d];
        let mut j = if with_jac { vec![0.0; d * nv] } else { Vec::new() };
        c.evaluate(&s.q, &mut r, if with_jac { Some(&mut j) } else { None }).map_err(fail)?;
        check_finite("residual", &r).map_err(|e| fail(e.into()))?;
        check_finite("Jacobian (row-major)", &j).map_err(|e| fail(e.into()))?;
        Ok((DVector::from_vec(r), with_jac.then(|| DMatrix::from_row_slice(d, nv, &j))))
    }

    /// Unweighted residual and, when `with_jac`, Jacobian of a term: one evaluation of a custom term.
    pub(super) fn eval(&self, t: &Term, s: &State, q_nom: &[f64], with_jac: bool, frame_jac: &mut DMatrix<f64>) -> TermResult<(DVector<f64>, Option<DMatrix<f64>>)> {
        if let TermKind::Custom(c) = &t.kind {
            return self.custom(t, c.as_ref(), s, with_jac);
        }
        let r = self.residual(t, s, q_nom);
        Ok((r, with_jac.then(|| self.jacobian(t, s, q_nom, frame_jac))))
    }

    /// Unweighted residual of a built-in term (a custom one goes through [`eval`](Self::eval)).
    fn residual(&self, t: &Term, s: &State, q_nom: &[f64]) -> DVector<f64> {
        let mut r = DVector::zeros(self.dim(t));
        self.residual_into(t, s, q_nom, r.as_mut_slice());
        r
    }

    /// [`residual`](Self::residual) written into `out` (length [`dim`](Self::dim)), allocating
    /// nothing: the one definition of the built-in residuals, which the residual-only check of
    /// many configurations evaluates into a buffer kept across rows.
    pub(super) fn residual_into(&self, t: &Term, s: &State, q_nom: &[f64], out: &mut [f64]) {
        // out[k] = mask[k] * r[k] over the mask's components
        fn masked(out: &mut [f64], mask: &[f64], r: &[f64]) {
            out.iter_mut().zip(mask.iter().zip(r)).for_each(|(o, (m, x))| *o = m * x);
        }
        match &t.kind {
            TermKind::FramePose { link, target, mask } => masked(out, mask, log6(&(target.inverse() * s.poses[*link])).as_slice()),
            TermKind::FramePosition { link, target, mask } => masked(out, mask, (s.poses[*link].translation.vector - target).as_slice()),
            TermKind::FrameOrientation { link, target, offset, mask } => {
                let rel = target.transpose() * s.poses[*link].rotation.to_rotation_matrix().into_inner() * offset;
                let (w, _) = log3(&rel);
                masked(out, mask, w.as_slice())
            }
            TermKind::RelativePose { link, relative_to, target, mask } => {
                masked(out, mask, log6(&(target.inverse() * s.poses[*relative_to].inverse() * s.poses[*link])).as_slice())
            }
            TermKind::RelativePosition { link, relative_to, target, mask } => {
                masked(out, mask, (relative_position(&s.poses[*link], &s.poses[*relative_to]) - target).as_slice())
            }
            TermKind::PointAt { link, axis, point } => {
                let d = s.poses[*link].rotation.inverse_transform_vector(&(point - s.poses[*link].translation.vector));
                let (e1, e2) = axis_complement(axis);
                out[0] = e1.dot(&d);
                out[1] = e2.dot(&d);
            }
            TermKind::Plane { link, normal, offset } => out[0] = normal.dot(&s.poses[*link].translation.vector) - offset,
            TermKind::JointLimits { .. } => {
                for (o, &(iq, _, lo, hi)) in out.iter_mut().zip(&self.bounded) {
                    *o = (s.q[iq] - lo).min(0.0) + (s.q[iq] - hi).max(0.0);
                }
            }
            TermKind::ComBox { lower, upper, .. } => {
                let c = self.model.center_of_mass(&s.poses, None);
                for (k, o) in out.iter_mut().enumerate() {
                    *o = (c[k] - lower[k]).min(0.0) + (c[k] - upper[k]).max(0.0);
                }
            }
            TermKind::Posture { weights, .. } => {
                // `difference` writes every tangent component but those of no joint (zero)
                out.fill(0.0);
                self.model.difference(q_nom, &s.q, out);
                out.iter_mut().zip(weights).for_each(|(o, w)| *o *= w);
            }
            TermKind::Custom(_) => unreachable!("custom terms are evaluated by Projector::custom"),
        }
    }

    /// Jacobian (dim x nv) of a built-in term's unweighted residual.
    pub(super) fn jacobian(&self, t: &Term, s: &State, q_nom: &[f64], frame_jac: &mut DMatrix<f64>) -> DMatrix<f64> {
        let nv = self.model.nv;
        match &t.kind {
            TermKind::FramePose { link, target, mask } => {
                self.model.frame_jacobian_local(&s.poses, *link, frame_jac);
                let jl = jlog6(&(target.inverse() * s.poses[*link]));
                let m = Matrix6::from_fn(|r, c| jl[(r, c)] * mask[r]);
                small_times_columns(&m, frame_jac, 0)
            }
            TermKind::FramePosition { link, mask, .. } => {
                self.model.frame_jacobian_local(&s.poses, *link, frame_jac);
                let rot = s.poses[*link].rotation.to_rotation_matrix().into_inner();
                let m = Matrix3::from_fn(|r, c| rot[(r, c)] * mask[r]);
                small_times_columns(&m, frame_jac, 0)
            }
            TermKind::FrameOrientation { link, target, offset, mask } => {
                self.model.frame_jacobian_local(&s.poses, *link, frame_jac);
                let rel = target.transpose() * s.poses[*link].rotation.to_rotation_matrix().into_inner() * offset;
                let (w, theta) = log3(&rel);
                let m = jlog3(&w, theta) * offset.transpose();
                let m = Matrix3::from_fn(|r, c| m[(r, c)] * mask[r]);
                small_times_columns(&m, frame_jac, 3)
            }
            TermKind::RelativePose { link, relative_to, target, mask } => {
                // the body velocity of T_rel = T_B^-1 T_A is V_A - Ad(T_rel^-1) V_B (V_A, V_B the
                // links' body velocities, `frame_jacobian_local`); log6's derivative maps it
                let rel = s.poses[*relative_to].inverse() * s.poses[*link];
                let jl = jlog6(&(target.inverse() * rel));
                let ma = Matrix6::from_fn(|r, c| jl[(r, c)] * mask[r]);
                let mb = -ma * action(&rel.inverse());
                self.two_frames(s, *link, &ma, *relative_to, &mb, frame_jac)
            }
            TermKind::RelativePosition { link, relative_to, mask, .. } => {
                // d/dt R_B^T (p_A - p_B) = R_rel v_A - v_B + [p_rel]x w_B (body velocities)
                let rel = s.poses[*relative_to].inverse() * s.poses[*link];
                let r_rel = rel.rotation.to_rotation_matrix().into_inner();
                let px = skew(&rel.translation.vector);
                let ma = SMatrix::<f64, 3, 6>::from_fn(|r, c| if c < 3 { r_rel[(r, c)] * mask[r] } else { 0.0 });
                let mb = SMatrix::<f64, 3, 6>::from_fn(|r, c| mask[r] * if c >= 3 { px[(r, c - 3)] } else if r == c { -1.0 } else { 0.0 });
                self.two_frames(s, *link, &ma, *relative_to, &mb, frame_jac)
            }
            TermKind::PointAt { link, axis, point } => {
                // d = R^T (c - p) moves as [d]x w - v (the link's body velocity)
                self.model.frame_jacobian_local(&s.poses, *link, frame_jac);
                let d = s.poses[*link].rotation.inverse_transform_vector(&(point - s.poses[*link].translation.vector));
                let dx = skew(&d);
                let (e1, e2) = axis_complement(axis);
                let m = SMatrix::<f64, 2, 6>::from_fn(|r, c| {
                    let e = if r == 0 { &e1 } else { &e2 };
                    if c < 3 { -e[c] } else { (0..3).map(|k| e[k] * dx[(k, c - 3)]).sum() }
                });
                rows_times_columns(&m, frame_jac, None)
            }
            TermKind::Plane { link, normal, .. } => {
                // d/dt n . p = n^T R v
                self.model.frame_jacobian_local(&s.poses, *link, frame_jac);
                let nr = s.poses[*link].rotation.inverse_transform_vector(normal);
                let m = SMatrix::<f64, 1, 6>::from_fn(|_, c| if c < 3 { nr[c] } else { 0.0 });
                rows_times_columns(&m, frame_jac, None)
            }
            TermKind::JointLimits { margin } => {
                let mut j = DMatrix::zeros(self.bounded.len(), nv);
                for (row, &(iq, iv, lo, hi)) in self.bounded.iter().enumerate() {
                    if within_margin(s.q[iq], *margin, lo, hi) {
                        j[(row, iv)] = 1.0;
                    }
                }
                j
            }
            TermKind::ComBox { lower, upper, margin } => {
                let mut jc = DMatrix::zeros(3, nv);
                let c = self.model.center_of_mass(&s.poses, Some(&mut jc));
                for k in 0..3 {
                    if !(c[k] - margin < lower[k] || c[k] + margin > upper[k]) {
                        jc.row_mut(k).fill(0.0);
                    }
                }
                jc
            }
            TermKind::Posture { weights, .. } => {
                let mut j = self.model.difference_jacobian(q_nom, &s.q);
                for (r, w) in weights.iter().enumerate() {
                    j.row_mut(r).scale_mut(*w);
                }
                j
            }
            TermKind::Custom(_) => unreachable!("custom terms are evaluated by Projector::custom"),
        }
    }

    /// `ma J_A + mb J_B`, `J_A`, `J_B` the local frame Jacobians (6 x nv) of links `a` and `b`
    /// (`frame_jac`, the caller's buffer, holds `J_A`).
    fn two_frames<const D: usize>(
        &self,
        s: &State,
        a: usize,
        ma: &SMatrix<f64, D, 6>,
        b: usize,
        mb: &SMatrix<f64, D, 6>,
        frame_jac: &mut DMatrix<f64>,
    ) -> DMatrix<f64> {
        let mut jb = DMatrix::zeros(6, self.model.nv);
        self.model.frame_jacobian_local(&s.poses, b, &mut jb);
        self.model.frame_jacobian_local(&s.poses, a, frame_jac);
        rows_times_columns(ma, frame_jac, Some((mb, &jb)))
    }
}

/// A term's residual size: the largest absolute component of its unweighted residual `r` (0
/// for a term of no rows, +inf when a component is NaN), the measure its tolerance bounds.
pub fn residual_size(r: &DVector<f64>) -> f64 {
    largest_abs(r.as_slice())
}

/// [`residual_size`] of a residual held in a slice (0 when empty, +inf with a NaN, else the
/// largest absolute component: a maximum, exact in any order).
pub(super) fn largest_abs(r: &[f64]) -> f64 {
    if r.iter().any(|x| x.is_nan()) {
        return f64::INFINITY;
    }
    r.iter().fold(0.0, |m: f64, x| m.max(x.abs()))
}

/// The nominal posture of each term: a Posture's own `q_nom`, else the solve's nominal with
/// the term's overrides applied.
pub(super) fn nominals(terms: &[Term], nominal: &[f64]) -> Vec<Vec<f64>> {
    let mut buf = Vec::new();
    terms.iter().map(|t| nominal_of(t, nominal, &mut buf).to_vec()).collect()
}

/// The nominal posture of one term ([`nominals`]), without a copy when it is `nominal` or the
/// term's own; with overrides, written into `buf` (kept by the caller across calls).
pub(super) fn nominal_of<'a>(t: &'a Term, nominal: &'a [f64], buf: &'a mut Vec<f64>) -> &'a [f64] {
    match &t.kind {
        TermKind::Posture { q_nom: Some(n), .. } => n,
        TermKind::Posture { q_nom: None, overrides, .. } if !overrides.is_empty() => {
            buf.clear();
            buf.extend_from_slice(nominal);
            for &(iq, v) in overrides {
                buf[iq] = v;
            }
            buf
        }
        _ => nominal,
    }
}

/// A joint at `q` is within `margin` of a limit of `[lo, hi]`: its `JointLimits` row is active
/// (a Jacobian entry of 1; the residual is non-zero only beyond the limit).
#[inline]
pub(super) fn within_margin(q: f64, margin: f64, lo: f64, hi: f64) -> bool {
    q - margin < lo || q + margin > hi
}

/// `m * rows(r0 .. r0 + D)` of the 6 x nv `frame_jac`, column by column with fixed-size
/// products (a general matrix product of such small factors spent most of its time packing).
fn small_times_columns<const D: usize>(m: &SMatrix<f64, D, D>, frame_jac: &DMatrix<f64>, r0: usize) -> DMatrix<f64> {
    let nv = frame_jac.ncols();
    let mut out = DMatrix::zeros(D, nv);
    for c in 0..nv {
        let col = frame_jac.fixed_view::<D, 1>(r0, c);
        out.fixed_view_mut::<D, 1>(0, c).copy_from(&(m * col));
    }
    out
}

/// `ma * ja` (+ `mb * jb`), `ja`, `jb` 6 x nv frame Jacobians, column by column with fixed-size
/// products (as [`small_times_columns`]).
fn rows_times_columns<const D: usize>(ma: &SMatrix<f64, D, 6>, ja: &DMatrix<f64>, b: Option<(&SMatrix<f64, D, 6>, &DMatrix<f64>)>) -> DMatrix<f64> {
    let nv = ja.ncols();
    let mut out = DMatrix::zeros(D, nv);
    for c in 0..nv {
        let mut col = ma * ja.fixed_view::<6, 1>(0, c);
        if let Some((mb, jb)) = b {
            col += mb * jb.fixed_view::<6, 1>(0, c);
        }
        out.fixed_view_mut::<D, 1>(0, c).copy_from(&col);
    }
    out
}

/// The position of `a`'s origin in `b`'s frame, `R_B^T (p_A - p_B)`.
fn relative_position(a: &Isometry3<f64>, b: &Isometry3<f64>) -> Vector3<f64> {
    b.rotation.inverse_transform_vector(&(a.translation.vector - b.translation.vector))
}

/// An orthonormal basis `(e1, e2)` of the plane orthogonal to the unit vector `axis`, the rows of
/// a [`TermKind::PointAt`] residual: `e1` is `axis x e_k` normalised, `e_k` the coordinate axis
/// least aligned with `axis` (the first of equals), and `e2 = axis x e1`. `genplan.projection`'s
/// `PointAt` uses the same rule.
pub fn axis_complement(axis: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let k = (0..3).fold(0, |best, i| if axis[i].abs() < axis[best].abs() { i } else { best });
    let e1 = axis.cross(&Vector3::ith(k, 1.0)).normalize();
    (e1, axis.cross(&e1))
}
