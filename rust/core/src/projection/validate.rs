//! The checks of a term's numbers, made when a projector is built or retargeted: finite, bounded
//! by [`MAX_MAGNITUDE`], rotations orthonormal and axes of unit length within
//! [`ROTATION_TOLERANCE`], indices and sizes the model's.

use nalgebra::{Isometry3, Matrix3, Vector3};

use super::{Term, TermKind};
#[cfg(doc)]
use super::CustomTerm;
use crate::error::{check_finite, check_vector, Error, Result};
use crate::kinematics::KinematicModel;

/// The largest absolute value of a term's numbers (target and box coordinates in m, weights,
/// masks, tolerances, margins, posture weights and values) and of the damping settings: 1e6.
/// Squared residuals of such terms, weighted, stay far from overflow.
pub const MAX_MAGNITUDE: f64 = 1e6;

/// How far a term's rotation matrix may be from orthonormal (largest entry of `R^T R - I`), as
/// `genplan.projection` checks it in Python.
pub const ROTATION_TOLERANCE: f64 = 1e-6;

/// Check a term against the model (see the module doc): the link index; every number finite
/// and at most [`MAX_MAGNITUDE`] in absolute value (`weight` and `tolerance` positive, margins
/// not negative); rotations orthonormal and axes or normals of unit length within
/// [`ROTATION_TOLERANCE`]; a relative term's two links distinct; a box's lower corner
/// below its upper one; posture vectors of the model's sizes. The error names the term and the
/// field.
pub(super) fn validate(model: &KinematicModel, t: &Term) -> Result<()> {
    let name = &t.name;
    let bad = |msg: String| Err(Error::Invalid(format!("term '{name}': {msg}")));
    for (field, v) in [("weight", t.weight), ("tolerance", t.tolerance)] {
        if !(v.is_finite() && v > 0.0 && v <= MAX_MAGNITUDE) {
            return bad(format!("{field} must be in (0, {MAX_MAGNITUDE:e}], got {v:?}"));
        }
    }
    let link_ok = |l: usize| l < model.n_links();
    // a relative term's links: both in range, and two of them
    let link_pair_ok = |link: usize, relative_to: usize| -> Result<()> {
        if let Some(l) = [link, relative_to].into_iter().find(|&l| !link_ok(l)) {
            return bad(format!("link index {l} out of range"));
        }
        if link == relative_to {
            return bad(format!("relative_to is the link itself (index {link}): its pose in its own frame never changes"));
        }
        Ok(())
    };
    match &t.kind {
        TermKind::FramePose { link, .. }
        | TermKind::FramePosition { link, .. }
        | TermKind::FrameOrientation { link, .. }
        | TermKind::PointAt { link, .. }
        | TermKind::Plane { link, .. }
            if !link_ok(*link) =>
        {
            bad(format!("link index {link} out of range"))
        }
        TermKind::RelativePose { link, relative_to, target, mask } => {
            link_pair_ok(*link, *relative_to)?;
            check_pose(name, target)?;
            bounded(name, "mask", mask)
        }
        TermKind::RelativePosition { link, relative_to, target, mask } => {
            link_pair_ok(*link, *relative_to)?;
            bounded(name, "target", target.as_slice())?;
            bounded(name, "mask", mask)
        }
        TermKind::PointAt { axis, point, .. } => {
            check_unit(name, "axis", axis)?;
            bounded(name, "point", point.as_slice())
        }
        TermKind::Plane { normal, offset, .. } => {
            check_unit(name, "normal", normal)?;
            bounded(name, "offset", &[*offset])
        }
        TermKind::FramePose { target, mask, .. } => {
            check_pose(name, target)?;
            bounded(name, "mask", mask)
        }
        TermKind::FramePosition { target, mask, .. } => {
            bounded(name, "target", target.as_slice())?;
            bounded(name, "mask", mask)
        }
        TermKind::FrameOrientation { target, offset, mask, .. } => {
            check_rotation(name, "target", target)?;
            check_rotation(name, "offset", offset)?;
            bounded(name, "mask", mask)
        }
        TermKind::JointLimits { margin } => margin_ok(name, *margin),
        TermKind::ComBox { lower, upper, margin } => {
            bounded(name, "lower", lower.as_slice())?;
            bounded(name, "upper", upper.as_slice())?;
            if (0..3).any(|k| lower[k] > upper[k]) {
                return bad("lower exceeds upper".into());
            }
            margin_ok(name, *margin)
        }
        TermKind::Posture { q_nom, weights, overrides } => {
            if weights.len() != model.nv {
                return bad(format!("posture weights: expected {} numbers, got {}", model.nv, weights.len()));
            }
            bounded(name, "posture weights", weights)?;
            if let Some(n) = q_nom {
                check_vector(&format!("term '{name}' posture q_nom"), n, model.nq)?;
                bounded(name, "posture q_nom", n)?;
            }
            if let Some(&(iq, v)) = overrides.iter().find(|&&(iq, v)| iq >= model.nq || !(v.is_finite() && v.abs() <= MAX_MAGNITUDE)) {
                return bad(format!(
                    "posture override (q index {iq}, value {v:?}) out of range: the index must be below nq = {}, the value finite and at most {MAX_MAGNITUDE:e} in absolute value",
                    model.nq
                ));
            }
            Ok(())
        }
        TermKind::Custom(c) => match c.dim() {
            0 => bad("a custom term needs at least one residual component (dim >= 1)".into()),
            d if d > MAX_CUSTOM_DIM => bad(format!("dim {d} exceeds {MAX_CUSTOM_DIM}")),
            _ => Ok(()),
        },
    }
}

/// The largest residual size of a [`CustomTerm`] (its Jacobian is `dim x nv` numbers per call).
pub const MAX_CUSTOM_DIM: usize = 10_000;

/// Every element of `values` (field `field` of term `term`) finite (else [`Error::NonFinite`])
/// and at most [`MAX_MAGNITUDE`] in absolute value (else [`Error::Invalid`]).
fn bounded(term: &str, field: &str, values: &[f64]) -> Result<()> {
    check_finite(&format!("term '{term}' {field}"), values)?;
    match values.iter().position(|v| v.abs() > MAX_MAGNITUDE) {
        Some(i) => Err(Error::Invalid(format!(
            "term '{term}': {field} element {i} is {:?}, beyond the bound {MAX_MAGNITUDE:e} on a term's numbers",
            values[i]
        ))),
        None => Ok(()),
    }
}

/// A target pose: its translation bounded ([`bounded`]), its rotation a unit quaternion within
/// [`ROTATION_TOLERANCE`].
fn check_pose(term: &str, target: &Isometry3<f64>) -> Result<()> {
    bounded(term, "target translation", target.translation.vector.as_slice())?;
    let r = target.rotation.coords;
    check_finite(&format!("term '{term}' target rotation"), r.as_slice())?;
    let norm = crate::lie::stable_norm(r.as_slice()); // huge components do not overflow
    if (norm - 1.0).abs() > ROTATION_TOLERANCE {
        return Err(Error::Invalid(format!("term '{term}': target rotation: not a unit quaternion (norm {norm:?})")));
    }
    Ok(())
}

/// A unit vector: finite, of norm 1 within [`ROTATION_TOLERANCE`].
fn check_unit(term: &str, field: &str, v: &Vector3<f64>) -> Result<()> {
    check_finite(&format!("term '{term}' {field}"), v.as_slice())?;
    let norm = crate::lie::stable_norm(v.as_slice());
    if (norm - 1.0).abs() > ROTATION_TOLERANCE {
        return Err(Error::Invalid(format!("term '{term}': {field} must be a unit vector, got norm {norm:?}")));
    }
    Ok(())
}

/// A margin: finite, in [0, [`MAX_MAGNITUDE`]].
fn margin_ok(term: &str, margin: f64) -> Result<()> {
    if margin.is_finite() && (0.0..=MAX_MAGNITUDE).contains(&margin) {
        Ok(())
    } else {
        Err(Error::Invalid(format!("term '{term}': margin must be in [0, {MAX_MAGNITUDE:e}], got {margin:?}")))
    }
}

/// A rotation matrix: finite, orthonormal within [`ROTATION_TOLERANCE`].
pub(super) fn check_rotation(term: &str, field: &str, r: &Matrix3<f64>) -> Result<()> {
    check_finite(&format!("term '{term}' {field}"), r.as_slice())?;
    let err = (r.transpose() * r - Matrix3::identity()).amax();
    if err > ROTATION_TOLERANCE {
        return Err(Error::Invalid(format!(
            "term '{term}': {field} is not a rotation matrix (R^T R differs from the identity by {err:?}, more than {ROTATION_TOLERANCE:e})"
        )));
    }
    Ok(())
}
