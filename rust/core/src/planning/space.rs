//! The configuration space the planner works in: the [`Space`] trait (difference, integrate,
//! chart coordinates, input checks), implemented for a robot's [`KinematicModel`] (Lie-group
//! joints, free-flyer base) and for R^n ([`EuclideanSpace`]).

use nalgebra::Matrix3;

use crate::error::check_vector;
use crate::kinematics::{KinematicModel, Motion};
use crate::lie::log3;

/// The configuration space: how configurations are differenced, moved and charted.
pub trait Space: Send + Sync {
    /// Length of a configuration vector.
    fn nq(&self) -> usize;
    /// Dimension of the tangent space (and of the chart used for nearest neighbours).
    fn nv(&self) -> usize;
    /// `out = q1 (-) q0` (tangent vector, length nv).
    fn difference(&self, q0: &[f64], q1: &[f64], out: &mut [f64]);
    /// `out = q (+) v`.
    fn integrate(&self, q: &[f64], v: &[f64], out: &mut [f64]);
    /// Coordinates of q in a chart (length nv) whose Euclidean distance approximates the tangent
    /// distance; the nearest-neighbour index works in it.
    fn coordinates(&self, q: &[f64], out: &mut [f64]);
    /// Check a configuration (length, finite values, ...); the error is a message that starts
    /// with `what` (the caller wraps it in the [`PlanError`](super::PlanError) of its input).
    fn check(&self, q: &[f64], what: &str) -> Result<(), String>;

    /// Tangent distance |q1 (-) q0|.
    fn distance(&self, q0: &[f64], q1: &[f64]) -> f64 {
        tangent_distance(self, q0, q1)
    }

    /// `out = q0 (+) t (q1 (-) q0)`.
    fn interpolate(&self, q0: &[f64], q1: &[f64], t: f64, out: &mut [f64]) {
        tangent_interpolate(self, q0, q1, t, out)
    }
}

/// [`Space::distance`] through the tangent space: |difference(q0, q1)|.
fn tangent_distance<S: Space + ?Sized>(space: &S, q0: &[f64], q1: &[f64]) -> f64 {
    with_tangent(space.nv(), |v| {
        space.difference(q0, q1, v);
        v.iter().map(|x| x * x).sum::<f64>().sqrt()
    })
}

/// [`Space::interpolate`] through the tangent space: integrate(q0, t difference(q0, q1)).
fn tangent_interpolate<S: Space + ?Sized>(space: &S, q0: &[f64], q1: &[f64], t: f64, out: &mut [f64]) {
    with_tangent(space.nv(), |v| {
        space.difference(q0, q1, v);
        v.iter_mut().for_each(|x| *x *= t);
        space.integrate(q0, v, out);
    })
}

/// Tangent vectors up to this length live on the stack in [`Space::distance`] and
/// [`Space::interpolate`] (the planner calls them for every step and edge: no allocation there).
const STACK_TANGENT: usize = 32;

/// `f` on a zeroed tangent buffer of length `nv`: on the stack up to [`STACK_TANGENT`], else on
/// the heap.
#[inline]
fn with_tangent<R>(nv: usize, f: impl FnOnce(&mut [f64]) -> R) -> R {
    if nv <= STACK_TANGENT {
        let mut buf = [0.0; STACK_TANGENT];
        f(&mut buf[..nv])
    } else {
        f(&mut vec![0.0; nv])
    }
}

impl Space for KinematicModel {
    fn nq(&self) -> usize {
        self.nq
    }
    fn nv(&self) -> usize {
        self.nv
    }
    fn difference(&self, q0: &[f64], q1: &[f64], out: &mut [f64]) {
        KinematicModel::difference(self, q0, q1, out)
    }
    fn integrate(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        KinematicModel::integrate(self, q, v, out)
    }
    /// [`Space::distance`]'s numbers; on whole slices when the model is
    /// [`euclidean`](KinematicModel::euclidean) (no tangent buffer, no pass per joint).
    fn distance(&self, q0: &[f64], q1: &[f64]) -> f64 {
        if !self.euclidean() {
            return tangent_distance(self, q0, q1);
        }
        let n = self.nv;
        q0[..n].iter().zip(&q1[..n]).map(|(a, b)| (b - a) * (b - a)).sum::<f64>().sqrt()
    }
    /// [`Space::interpolate`]'s numbers; on whole slices when the model is
    /// [`euclidean`](KinematicModel::euclidean).
    fn interpolate(&self, q0: &[f64], q1: &[f64], t: f64, out: &mut [f64]) {
        if !self.euclidean() {
            return tangent_interpolate(self, q0, q1, t, out);
        }
        let n = self.nq;
        for ((o, a), b) in out[..n].iter_mut().zip(&q0[..n]).zip(&q1[..n]) {
            *o = a + (b - a) * t;
        }
    }
    fn coordinates(&self, q: &[f64], out: &mut [f64]) {
        if self.euclidean() {
            out[..self.nq].copy_from_slice(&q[..self.nq]);
            return;
        }
        let mut iq = 0;
        let mut iv = 0;
        if self.floating_base {
            out[..3].copy_from_slice(&q[..3]);
            // the base quaternion normalised without overflow (a huge finite one is valid)
            let rot = KinematicModel::base_pose(q).rotation;
            let m: Matrix3<f64> = rot.to_rotation_matrix().into_inner();
            let (w, _) = log3(&m);
            out[3..6].copy_from_slice(w.as_slice());
            iq = 7;
            iv = 6;
        }
        for j in self.joints.iter().filter(|j| j.q_index != usize::MAX) {
            debug_assert!(j.q_index >= iq && j.v_index >= iv);
            match j.motion {
                Motion::Continuous { .. } => out[j.v_index] = q[j.q_index + 1].atan2(q[j.q_index]),
                Motion::Fixed => {}
                _ => out[j.v_index] = q[j.q_index],
            }
        }
    }
    fn check(&self, q: &[f64], what: &str) -> Result<(), String> {
        self.check_configuration(q).map_err(|e| format!("{what}: {e}"))
    }
}

/// R^n with the Euclidean metric (tests, benches, toy problems); the field is n.
#[derive(Debug, Clone, Copy)]
pub struct EuclideanSpace(pub usize);

impl Space for EuclideanSpace {
    fn nq(&self) -> usize {
        self.0
    }
    fn nv(&self) -> usize {
        self.0
    }
    fn difference(&self, q0: &[f64], q1: &[f64], out: &mut [f64]) {
        for i in 0..self.0 {
            out[i] = q1[i] - q0[i];
        }
    }
    fn integrate(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        for i in 0..self.0 {
            out[i] = q[i] + v[i];
        }
    }
    fn coordinates(&self, q: &[f64], out: &mut [f64]) {
        out.copy_from_slice(q);
    }
    fn check(&self, q: &[f64], what: &str) -> Result<(), String> {
        check_vector(what, q, self.0).map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::ModelOptions;
    use crate::urdf::Urdf;

    /// The chart of a free-flyer base: a quaternion of any finite size is normalised without
    /// overflow (as `KinematicModel::base_pose` does), so huge components chart like unit ones.
    #[test]
    fn a_huge_base_quaternion_charts_like_its_unit_one() {
        let urdf = Urdf::parse(r#"<robot name="r"><link name="a"/></robot>"#).unwrap();
        let model = KinematicModel::from_urdf(&urdf, &ModelOptions { floating_base: true, ..Default::default() }).unwrap();
        let chart = |quat: [f64; 4]| {
            let q = [1.0, 2.0, 3.0, quat[0], quat[1], quat[2], quat[3]];
            let mut out = [0.0; 6];
            model.coordinates(&q, &mut out);
            out
        };
        let unit = chart([0.5, 0.5, 0.5, 0.5]);
        for big in [1e300, f64::MAX, 1e-300] {
            let c = chart([big; 4]);
            assert!(c.iter().zip(&unit).all(|(a, b)| (a - b).abs() < 1e-12), "{big}: {c:?} != {unit:?}");
        }
        assert_eq!(&unit[..3], &[1.0, 2.0, 3.0]);
    }
}
