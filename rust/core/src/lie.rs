//! SO(3) and SE(3) maps in Pinocchio's conventions: `log3`, `jlog3`, `log6`, `jlog6`, `exp6`.
//!
//! A motion (twist) is `[v; w]`, linear part first. `jlog3(R)` is the Jacobian of
//! `log3(R exp3(e))` with respect to `e` at 0 (the inverse right Jacobian); `jlog6` likewise for
//! `log6(M exp6(e))`. Cross-checked against Pinocchio in `tests/test_native_projection.py`.
//!
//! [`unit_vector`] and [`unit_quaternion`] normalise without overflow or underflow (a vector
//! `1e200 0 0`, whose squared norm is infinite, normalises to `1 0 0`).

use nalgebra::{Isometry3, Matrix3, Matrix6, Quaternion, Translation3, Unit, UnitQuaternion, Vector3, Vector6};

/// The Euclidean norm of `v`, computed without overflow or underflow (`v` is scaled by its
/// largest magnitude first); NaN if an element is NaN, infinite if one is infinite.
pub fn stable_norm(v: &[f64]) -> f64 {
    if v.iter().any(|x| x.is_nan()) {
        return f64::NAN;
    }
    let m = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if m == 0.0 || m.is_infinite() {
        return m;
    }
    m * v.iter().map(|x| (x / m) * (x / m)).sum::<f64>().sqrt()
}

/// `v / |v|`, computed without overflow or underflow; `None` when an element is not finite or
/// `|v|` is zero or below `min_norm`.
pub fn unit_vector(v: &Vector3<f64>, min_norm: f64) -> Option<Unit<Vector3<f64>>> {
    // |v| may exceed f64::MAX (f64::MAX along two axes): the finite elements are what counts
    let n = stable_norm(v.as_slice());
    if !v.iter().all(|x| x.is_finite()) || n == 0.0 || n < min_norm {
        return None;
    }
    Some(Unit::new_normalize(v / v.amax()))
}

/// The rotation of the quaternion `w + x i + y j + z k` of any finite non-zero norm, normalised
/// without overflow or underflow; `None` when an element is not finite or the norm is zero or
/// below `min_norm`.
pub fn unit_quaternion(w: f64, x: f64, y: f64, z: f64, min_norm: f64) -> Option<UnitQuaternion<f64>> {
    let c = [w, x, y, z];
    let n = stable_norm(&c);
    if !c.iter().all(|v| v.is_finite()) || n == 0.0 || n < min_norm {
        return None;
    }
    let m = c.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    Some(UnitQuaternion::from_quaternion(Quaternion::new(w / m, x / m, y / m, z / m)))
}

/// The skew-symmetric matrix `[v]x` with `[v]x u = v x u`.
#[inline]
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Rotation vector of R (angle in [0, pi]) and the angle.
pub fn log3(r: &Matrix3<f64>) -> (Vector3<f64>, f64) {
    let tr = r.trace();
    let cos = ((tr - 1.0) * 0.5).clamp(-1.0, 1.0);
    let theta = cos.acos();
    let vee = Vector3::new(r[(2, 1)] - r[(1, 2)], r[(0, 2)] - r[(2, 0)], r[(1, 0)] - r[(0, 1)]);
    if theta < 1e-4 {
        // theta / (2 sin theta) ~ 1/2 + theta^2 / 12
        return (vee * (0.5 + theta * theta / 12.0), theta);
    }
    if std::f64::consts::PI - theta < 1e-4 {
        // near pi: use the symmetric part, sign from the skew part
        let mut w = Vector3::zeros();
        for i in 0..3 {
            let v = ((r[(i, i)] - cos) / (1.0 - cos)).max(0.0).sqrt();
            w[i] = if vee[i] < 0.0 { -v } else { v };
        }
        // fix relative signs from the off-diagonal terms of the largest component
        let k = w.iamax();
        let s = w[k].signum();
        for i in 0..3 {
            if i != k {
                let off = (r[(i, k)] + r[(k, i)]) * 0.5 / (1.0 - cos);
                w[i] = off / (w[k].abs().max(1e-12)) * s;
            }
        }
        return (w.normalize() * theta, theta);
    }
    (vee * (theta / (2.0 * theta.sin())), theta)
}

/// Inverse right Jacobian of SO(3) at the rotation vector `w` (angle `theta`).
pub fn jlog3(w: &Vector3<f64>, theta: f64) -> Matrix3<f64> {
    let (alpha, diag_coef) = if theta < 1e-4 {
        (1.0 - theta * theta / 12.0, 1.0 / 12.0 + theta * theta / 720.0)
    } else {
        let alpha = theta * theta.sin() / (2.0 * (1.0 - theta.cos()));
        (alpha, (1.0 - alpha) / (theta * theta))
    };
    Matrix3::identity() * alpha + skew(w) * 0.5 + (w * w.transpose()) * diag_coef
}

/// log of an SE(3) element: `[v; w]`.
pub fn log6(m: &Isometry3<f64>) -> Vector6<f64> {
    let r = m.rotation.to_rotation_matrix().into_inner();
    let p = m.translation.vector;
    let (w, theta) = log3(&r);
    let alpha_coef = if theta < 1e-4 {
        1.0 / 12.0 + theta * theta / 720.0
    } else {
        (1.0 - theta * theta.sin() / (2.0 * (1.0 - theta.cos()))) / (theta * theta)
    };
    let wx = skew(&w);
    let v = p - wx * p * 0.5 + wx * wx * p * alpha_coef;
    Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z)
}

/// Jacobian of `log6(M exp6(e))` with respect to `e` at 0.
pub fn jlog6(m: &Isometry3<f64>) -> Matrix6<f64> {
    let r = m.rotation.to_rotation_matrix().into_inner();
    let p = m.translation.vector;
    let (w, t) = log3(&r);
    let a = jlog3(&w, t);
    let t2 = t * t;
    let (beta, beta_dot_over_theta) = if t < 1e-4 {
        (1.0 / 12.0 + t2 / 720.0, 1.0 / 360.0)
    } else {
        let (st, ct) = t.sin_cos();
        let inv_2_2ct = 1.0 / (2.0 * (1.0 - ct));
        let t2inv = 1.0 / t2;
        (
            t2inv - st / t * inv_2_2ct,
            -2.0 * t2inv * t2inv + (1.0 + st / t) * t2inv * inv_2_2ct,
        )
    };
    let wtp = w.dot(&p);
    let v3 = w * (beta_dot_over_theta * wtp) - p * (t2 * beta_dot_over_theta + 2.0 * beta);
    let mut c = v3 * w.transpose() + (w * p.transpose()) * beta;
    for i in 0..3 {
        c[(i, i)] += wtp * beta;
    }
    c += skew(&(p * 0.5));
    let b = c * a;
    let mut out = Matrix6::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&a);
    out.fixed_view_mut::<3, 3>(0, 3).copy_from(&b);
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&a);
    out
}

/// exp of a twist `[v; w]` as an SE(3) element.
pub fn exp6(nu: &Vector6<f64>) -> Isometry3<f64> {
    let v = Vector3::new(nu[0], nu[1], nu[2]);
    let w = Vector3::new(nu[3], nu[4], nu[5]);
    let theta = w.norm();
    let wx = skew(&w);
    let (b, c) = if theta < 1e-4 {
        (0.5 - theta * theta / 24.0, 1.0 / 6.0 - theta * theta / 120.0)
    } else {
        ((1.0 - theta.cos()) / (theta * theta), (theta - theta.sin()) / (theta * theta * theta))
    };
    let vmat = Matrix3::identity() + wx * b + wx * wx * c;
    Isometry3::from_parts(Translation3::from(vmat * v), UnitQuaternion::from_scaled_axis(w))
}

/// The 6x6 action matrix of M on motions `[v; w]`: `[[R, [p]x R], [0, R]]`.
pub fn action(m: &Isometry3<f64>) -> Matrix6<f64> {
    let r = m.rotation.to_rotation_matrix().into_inner();
    let p = m.translation.vector;
    let mut out = Matrix6::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    out.fixed_view_mut::<3, 3>(0, 3).copy_from(&(skew(&p) * r));
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn numeric_jacobian(m: &Isometry3<f64>) -> Matrix6<f64> {
        let h = 1e-7;
        let mut out = Matrix6::zeros();
        for k in 0..6 {
            let mut e = Vector6::zeros();
            e[k] = h;
            let plus = log6(&(m * exp6(&e)));
            e[k] = -h;
            let minus = log6(&(m * exp6(&e)));
            out.set_column(k, &((plus - minus) / (2.0 * h)));
        }
        out
    }

    #[test]
    fn log_exp_round_trip_and_jlog6_matches_finite_differences() {
        for nu in [
            Vector6::new(0.1, -0.2, 0.3, 0.4, -0.5, 0.6),
            Vector6::new(1.0, 0.0, -1.0, 0.0, 0.0, 1e-6),
            Vector6::new(-0.3, 0.2, 0.1, 2.5, 0.3, -1.2),
            Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        ] {
            let m = exp6(&nu);
            assert!((log6(&m) - nu).amax() < 1e-9, "{nu}");
            let j = jlog6(&m);
            let n = numeric_jacobian(&m);
            assert!((j - n).amax() < 1e-6, "{nu}: {}", (j - n).amax());
        }
    }

    #[test]
    fn normalisation_neither_overflows_nor_underflows() {
        assert_eq!(stable_norm(&[3e300, 4e300]), 5e300);
        assert_eq!(stable_norm(&[3e-300, 4e-300]), 5e-300);
        assert_eq!(stable_norm(&[0.0, 0.0]), 0.0);
        assert!(stable_norm(&[f64::NAN, 1.0]).is_nan() && stable_norm(&[f64::INFINITY, 1.0]).is_infinite());
        let x = unit_vector(&Vector3::new(1e200, 0.0, 0.0), 1e-12).unwrap();
        assert_eq!(x.into_inner(), Vector3::x());
        let d = unit_vector(&Vector3::new(f64::MAX, f64::MAX, 0.0), 1e-12).unwrap();
        assert!((d.into_inner() - Vector3::new(1.0, 1.0, 0.0).normalize()).amax() < 1e-15);
        assert!(unit_vector(&Vector3::new(1e-200, 0.0, 0.0), 1e-12).is_none());
        assert!(unit_vector(&Vector3::zeros(), 0.0).is_none());
        assert!(unit_vector(&Vector3::new(f64::NAN, 1.0, 0.0), 0.0).is_none());
        let q = unit_quaternion(1e300, 1e300, 1e300, 1e300, 0.0).unwrap();
        assert!((q.coords - nalgebra::Vector4::repeat(0.5)).amax() < 1e-15);
        let q = unit_quaternion(f64::MAX, f64::MAX, f64::MAX, f64::MAX, 0.0).unwrap();
        assert!((q.coords - nalgebra::Vector4::repeat(0.5)).amax() < 1e-15);
        assert!(unit_quaternion(0.0, 0.0, 0.0, 0.0, 0.0).is_none());
        assert!(unit_quaternion(f64::INFINITY, 0.0, 0.0, 0.0, 0.0).is_none());
    }

    #[test]
    fn log3_near_pi_keeps_the_axis() {
        let axis = Vector3::new(0.3, -0.4, 0.5).normalize();
        for theta in [std::f64::consts::PI - 1e-6, std::f64::consts::PI - 1e-3, 3.0] {
            let r = UnitQuaternion::from_scaled_axis(axis * theta).to_rotation_matrix().into_inner();
            let (w, t) = log3(&r);
            assert!((t - theta).abs() < 1e-8);
            assert!((w - axis * theta).amax() < 1e-5, "{theta}: {w}");
        }
    }
}
