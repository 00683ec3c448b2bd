//! The controllers of the seq2seq paper's Fig. 10 for any fixed-base robot: a P-D law with gains
//! per axis, in the task space of a frame or in joint space, turned into a torque through the
//! nominal model, `tau = M_n(q) qdd_ref + h_n(q, v) + tau_dis_hat`.
//!
//! # Task space (any frame, free axes)
//!
//! * error `e = [p_cmd - p; log3(R_cmd R^T)]` (world axes), velocity error
//!   `de = [v_cmd - v; w_cmd - w]` (`velocity_feedforward = false`: `-[v; w]`);
//! * `xdd_ref = Kp e + Kv de` per axis (+ the command's acceleration with
//!   `acceleration_feedforward`); only the servoed axes (`axes`) are kept, the others are free;
//! * every axis servoed and as many joints as axes (a square Jacobian: the paper's 6-joint arm):
//!   `qdd_ref = J^-1 (xdd_ref - dJ/dt v)`; near a singularity (`|det J| < singular_det`) damped
//!   least squares `J^T (J J^T + lambda^2 I)^-1` with `lambda^2 = max_damping^2 (1 - |det J| /
//!   singular_det)^2` (Nakamura and Hanafusa);
//! * otherwise (a redundant arm, or free axes) the damped pseudo-inverse of the servoed rows
//!   `J_s`, `J_s^+ = J_s^T (J_s J_s^T + lambda^2 I)^-1` with the same rule on
//!   `w = sqrt(det(J_s J_s^T))` (Yoshikawa's manipulability; `|det J|` for a square one), plus a
//!   posture term in their null space: `qdd_ref += (I - J_s^+ J_s) z`,
//!   `z = posture_kp (q_cmd - q) + posture_kv (qd_cmd - qd)` (+ `qdd_cmd`) towards the
//!   reference's joint motion.
//!
//! # Joint space
//!
//! `qdd_ref = joint_kp (q_cmd - q) + joint_kv (qd_cmd - qd)` (+ `qdd_cmd`), continuous joints'
//! errors taken on their circle.
//!
//! Every buffer is allocated at construction: a tick allocates nothing.

use nalgebra::{DMatrix, Matrix3, Matrix6, Vector3, Vector6};

use crate::dynamics::{cholesky_in_place, cholesky_solve, DynWorkspace, Dynamics, Frame};
use crate::error::{Error, Result};
use crate::lie::log3;

use super::settings::{joint_value, ControlSpace, ControllerSettings};

/// The task-space part of one tick's command: pose, velocity and acceleration of the
/// controller's frame (world axes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaskCommand {
    /// Position of the frame's origin.
    pub pos: Vector3<f64>,
    /// Attitude of the frame.
    pub rot: Matrix3<f64>,
    /// Velocity (linear, angular).
    pub vel: Vector6<f64>,
    /// Acceleration (linear, angular).
    pub acc: Vector6<f64>,
}

impl TaskCommand {
    /// Holding `pos`, `rot` at rest.
    pub fn hold(pos: Vector3<f64>, rot: Matrix3<f64>) -> Self {
        TaskCommand { pos, rot, vel: Vector6::zeros(), acc: Vector6::zeros() }
    }
}

/// The joint-space part of one tick's command.
#[derive(Debug, Clone, Copy)]
pub struct JointCommand<'a> {
    /// Joint positions (nq).
    pub q: &'a [f64],
    /// Joint velocities (nv).
    pub qd: &'a [f64],
    /// Joint accelerations (nv).
    pub qdd: &'a [f64],
}

/// `y = M x` with the summation order of nalgebra's `gemv` (column by column), so that a
/// dynamically sized product gives the same bits as a fixed-size one. `m` is `y.len() x x.len()`.
#[inline(always)]
pub(crate) fn gemv(m: &DMatrix<f64>, x: &[f64], y: &mut [f64]) {
    let (r, c) = m.shape();
    let y = &mut y[..r];
    if r == 0 {
        return;
    }
    // slices zipped to the same length: no bounds check in the inner loop, which vectorises
    let mut cols = m.as_slice().chunks_exact(r).zip(&x[..c]);
    match cols.next() {
        Some((col, &x0)) => {
            for (yi, &a) in y.iter_mut().zip(col) {
                *yi = a * x0;
            }
        }
        None => y.fill(0.0),
    }
    for (col, &xj) in cols {
        for (yi, &a) in y.iter_mut().zip(col) {
            *yi = a * xj + *yi;
        }
    }
}

/// `y = M^T x` (`m` is `x.len() x y.len()`), each entry summed in row order.
#[inline(always)]
fn gemv_transposed(m: &DMatrix<f64>, x: &[f64], y: &mut [f64]) {
    let (r, c) = m.shape();
    let y = &mut y[..c];
    if r == 0 {
        y.fill(0.0);
        return;
    }
    let x = &x[..r];
    for (yj, col) in y.iter_mut().zip(m.as_slice().chunks_exact(r)) {
        *yj = col.iter().zip(x).fold(0.0, |s, (&a, &b)| s + a * b);
    }
}

/// LU factorisation with partial pivoting (the largest |entry| of each column below the
/// diagonal, as nalgebra's `LU`) of a 6 x 6 matrix, on fixed-size rows: `P J = L U` with the unit
/// lower `L` below the diagonal of the returned rows and `U` on and above it, the row order `P`,
/// and `det J`. A zero pivot leaves its column as it is (the determinant is then zero).
#[inline(always)]
fn lu6(j: &Matrix6<f64>) -> ([[f64; 6]; 6], [usize; 6], f64) {
    let mut a = [[0.0; 6]; 6];
    for (r, row) in a.iter_mut().enumerate() {
        for (c, x) in row.iter_mut().enumerate() {
            *x = j[(r, c)];
        }
    }
    let mut perm = [0, 1, 2, 3, 4, 5];
    let mut det = 1.0;
    for k in 0..6 {
        let mut p = k;
        for r in k + 1..6 {
            if a[r][k].abs() > a[p][k].abs() {
                p = r;
            }
        }
        if p != k {
            a.swap(p, k);
            perm.swap(p, k);
            det = -det;
        }
        let pivot = a[k][k];
        det *= pivot;
        if pivot == 0.0 {
            continue;
        }
        let (top, below) = a.split_at_mut(k + 1);
        let row_k = &top[k];
        for row in below.iter_mut() {
            let f = row[k] / pivot;
            row[k] = f;
            for c in k + 1..6 {
                row[c] -= f * row_k[c];
            }
        }
    }
    (a, perm, det)
}

/// `J^-1 b` from [`lu6`]'s factors of `J` (every pivot non-zero).
#[inline(always)]
fn lu6_solve(lu: &[[f64; 6]; 6], perm: &[usize; 6], b: &Vector6<f64>) -> Vector6<f64> {
    let mut x = [0.0; 6];
    for (xr, &p) in x.iter_mut().zip(perm) {
        *xr = b[p];
    }
    for r in 1..6 {
        for c in 0..r {
            x[r] -= lu[r][c] * x[c];
        }
    }
    for r in (0..6).rev() {
        for c in r + 1..6 {
            x[r] -= lu[r][c] * x[c];
        }
        x[r] /= lu[r][r];
    }
    Vector6::from(x)
}

/// The paper's solve of a square task Jacobian: `J^-1 b`, damped near a singularity. Returns
/// (x, det J, damped).
#[inline(always)]
fn damped_solve(j: &Matrix6<f64>, b: &Vector6<f64>, singular_det: f64, max_damping: f64) -> (Vector6<f64>, f64, bool) {
    let (lu, perm, det) = lu6(j);
    let w = det.abs();
    if w >= singular_det && w > 0.0 {
        return (lu6_solve(&lu, &perm, b), det, false);
    }
    let ratio = if singular_det > 0.0 { (w / singular_det).min(1.0) } else { 0.0 };
    let lambda2 = (max_damping * (1.0 - ratio)).powi(2).max(1e-12);
    let a = j * j.transpose() + Matrix6::identity() * lambda2;
    let x = match a.cholesky() {
        Some(c) => j.transpose() * c.solve(b),
        None => Vector6::zeros(),
    };
    (x, det, true)
}

/// The controller's model and law (see the module docs). [`measure`](Self::measure) reads the
/// state; [`control`](Self::control) writes the torque into [`tau`](Self::tau).
pub struct Controller {
    /// Its settings.
    pub settings: ControllerSettings,
    /// The nominal model (the robot and the payloads the controller knows).
    pub nominal: Dynamics,
    /// The controlled (task space) or logged (joint space) frame.
    pub frame: Frame,
    ws: DynWorkspace,
    /// The servoed task rows, in order.
    rows: Vec<usize>,
    /// A square task Jacobian: the paper's inverse.
    square: bool,
    kp_joint: Vec<f64>,
    kv_joint: Vec<f64>,
    /// Bias torque `h_n(q, v)` at the measured state.
    pub h: Vec<f64>,
    /// Jacobian of the frame (6 x nv, world axes) at the measured state.
    pub jac: DMatrix<f64>,
    djac: DMatrix<f64>,
    /// Pose of the frame at the measured state.
    pub pos: Vector3<f64>,
    /// See `pos`.
    pub rot: Matrix3<f64>,
    /// Velocity of the frame (linear, angular).
    pub xd: Vector6<f64>,
    /// `dJ/dt v`: the frame's acceleration at zero joint acceleration.
    pub djv: Vector6<f64>,
    /// The frame's position error `p_cmd - p` of the last [`control`](Self::control).
    pub err_pos: Vector3<f64>,
    /// The frame's attitude error `log3(R_cmd R^T)` of the last [`control`](Self::control).
    pub err_rot: Vector3<f64>,
    /// The reference joint acceleration of the last [`control`](Self::control).
    pub qdd_ref: Vec<f64>,
    /// The torque of the last [`control`](Self::control) (before any limit).
    pub tau: Vec<f64>,
    // the pseudo-inverse's buffers
    js: DMatrix<f64>,
    a: DMatrix<f64>,
    l: DMatrix<f64>,
    b: Vec<f64>,
    z: Vec<f64>,
    jz: Vec<f64>,
    e: Vec<f64>,
}

impl Controller {
    /// The controller of `settings` on `nominal`, servoing (or logging) `frame`.
    pub fn new(settings: ControllerSettings, nominal: Dynamics, frame: Frame) -> Result<Controller> {
        let (nq, nv) = (nominal.nq, nominal.nv);
        settings.check(nv)?;
        if frame.body.is_none() {
            return Err(Error::Settings {
                field: "controller.frame",
                msg: "the frame does not move with any joint (fixed to the world)".into(),
            });
        }
        let rows: Vec<usize> = (0..6).filter(|&r| settings.axes[r] != 0.0).collect();
        let m = rows.len();
        let square = settings.space == ControlSpace::Task && m == 6 && nv == 6 && nq == 6;
        let kp_joint = (0..nv).map(|i| joint_value(&settings.joint_kp, i)).collect();
        let kv_joint = (0..nv).map(|i| joint_value(&settings.joint_kv, i)).collect();
        Ok(Controller {
            ws: nominal.workspace(),
            rows,
            square,
            kp_joint,
            kv_joint,
            h: vec![0.0; nv],
            jac: DMatrix::zeros(6, nv),
            djac: DMatrix::zeros(6, nv),
            pos: Vector3::zeros(),
            rot: Matrix3::identity(),
            xd: Vector6::zeros(),
            djv: Vector6::zeros(),
            err_pos: Vector3::zeros(),
            err_rot: Vector3::zeros(),
            qdd_ref: vec![0.0; nv],
            tau: vec![0.0; nv],
            js: DMatrix::zeros(m, nv),
            a: DMatrix::zeros(m, m),
            l: DMatrix::zeros(m, m),
            b: vec![0.0; m],
            z: vec![0.0; nv],
            jz: vec![0.0; m],
            e: vec![0.0; nv],
            settings,
            nominal,
            frame,
        })
    }

    /// The mass matrix `M_n(q)` of the last [`measure`](Self::measure).
    pub fn mass(&self) -> &DMatrix<f64> {
        &self.ws.mass
    }

    /// The nominal model's workspace: the kinematics of the last [`measure`](Self::measure).
    pub fn workspace(&self) -> &DynWorkspace {
        &self.ws
    }

    /// The nominal model at the measured state (q, v): mass matrix, bias torque, the frame's
    /// pose, Jacobian, velocity and `dJ/dt v`. The inputs are not checked (the loop checks once).
    #[inline(always)]
    pub fn measure(&mut self, q: &[f64], v: &[f64]) {
        let n = &self.nominal;
        n.update_kinematics_unchecked(q, Some(v), &mut self.ws);
        n.mass_matrix_from_kinematics(&mut self.ws);
        n.rnea_from_kinematics(None, true, &mut self.ws, &mut self.h);
        n.frame_jacobians_from_kinematics(&self.frame, &self.ws, &mut self.jac, Some(&mut self.djac));
        let (rot, pos) = n.frame_placement(&self.frame, &self.ws);
        self.rot = rot;
        self.pos = pos;
        gemv(&self.jac, v, self.xd.as_mut_slice());
        gemv(&self.djac, v, self.djv.as_mut_slice());
    }

    /// The tracking error of the frame: `(p_cmd - p, log3(R_cmd R^T))` at the measured state.
    #[inline(always)]
    pub fn frame_error(&self, cmd: &TaskCommand) -> (Vector3<f64>, Vector3<f64>) {
        let (er, _) = log3(&(cmd.rot * self.rot.transpose()));
        (cmd.pos - self.pos, er)
    }

    /// The control law at the measured state (q, v) for the command: writes the frame's error
    /// ([`err_pos`](Self::err_pos), [`err_rot`](Self::err_rot)), [`qdd_ref`](Self::qdd_ref) and
    /// [`tau`](Self::tau) (`M_n qdd_ref`, plus `h_n` with
    /// `model_compensation`, plus `dob_estimate` when given). `joint`: the reference's joint
    /// motion (required in joint space; the posture target of a redundant task). Returns the
    /// singularity measure (`det J` or `sqrt(det(J_s J_s^T))`; NaN in joint space) and whether
    /// the inverse was damped.
    #[inline(always)]
    pub fn control(&mut self, cmd: &TaskCommand, joint: Option<JointCommand<'_>>, q: &[f64], v: &[f64], dob_estimate: Option<&[f64]>) -> Result<(f64, bool)> {
        (self.err_pos, self.err_rot) = self.frame_error(cmd);
        let c = &self.settings;
        let (det, damped) = match c.space {
            ControlSpace::Task => self.task_law(cmd, joint, q, v),
            ControlSpace::Joint => {
                let Some(jc) = joint else {
                    return Err(Error::Invalid("a joint-space controller needs the reference's joint motion".into()));
                };
                self.nominal.difference(q, jc.q, &mut self.e);
                for i in 0..self.e.len() {
                    let de = if c.velocity_feedforward { jc.qd[i] - v[i] } else { -v[i] };
                    let mut a = self.kp_joint[i] * self.e[i] + self.kv_joint[i] * de;
                    if c.acceleration_feedforward {
                        a += jc.qdd[i];
                    }
                    self.qdd_ref[i] = a;
                }
                (f64::NAN, false)
            }
        };
        gemv(&self.ws.mass, &self.qdd_ref, &mut self.tau);
        if self.settings.model_compensation {
            for (t, h) in self.tau.iter_mut().zip(&self.h) {
                *t += h;
            }
        }
        if let Some(d) = dob_estimate {
            for (t, d) in self.tau.iter_mut().zip(d) {
                *t += d;
            }
        }
        Ok((det, damped))
    }

    #[inline(always)]
    fn task_law(&mut self, cmd: &TaskCommand, joint: Option<JointCommand<'_>>, q: &[f64], v: &[f64]) -> (f64, bool) {
        let c = &self.settings;
        let (ep, er) = (self.err_pos, self.err_rot);
        let xd = &self.xd;
        let (dv, dw) = if c.velocity_feedforward {
            (cmd.vel.fixed_rows::<3>(0) - xd.fixed_rows::<3>(0), cmd.vel.fixed_rows::<3>(3) - xd.fixed_rows::<3>(3))
        } else {
            (-xd.fixed_rows::<3>(0), -xd.fixed_rows::<3>(3))
        };
        let mut xdd = Vector6::zeros();
        for k in 0..3 {
            xdd[k] = c.kp[k] * ep[k] + c.kv[k] * dv[k];
            xdd[k + 3] = c.kp[k + 3] * er[k] + c.kv[k + 3] * dw[k];
        }
        if c.acceleration_feedforward {
            xdd += cmd.acc;
        }
        if self.square {
            // the 6 x 6 Jacobian's column-major storage as it is (no element-wise iterator)
            let j = Matrix6::from_column_slice(self.jac.as_slice());
            let (x, det, damped) = damped_solve(&j, &(xdd - self.djv), c.singular_det, c.max_damping);
            self.qdd_ref.copy_from_slice(x.as_slice());
            return (det, damped);
        }
        // the servoed rows: J_s, b = xdd - dJ v
        // column-major storage read through slices: the same sums in the same order as indexing
        // the matrices element by element, without a shape check per element
        let nv = self.qdd_ref.len();
        let m = self.rows.len();
        {
            let (jac, js) = (&self.jac.as_slice()[..6 * nv], &mut self.js.as_mut_slice()[..m * nv]);
            for (k, &r) in self.rows.iter().enumerate() {
                for (dst, src) in js[k..].iter_mut().step_by(m).zip(jac[r..].iter().step_by(6)) {
                    *dst = *src;
                }
                self.b[k] = xdd[r] - self.djv[r];
            }
        }
        {
            let (js, a) = (&self.js.as_slice()[..m * nv], &mut self.a.as_mut_slice()[..m * m]);
            for i in 0..m {
                for k in 0..=i {
                    let s = js[i..].iter().step_by(m).zip(js[k..].iter().step_by(m)).fold(0.0, |s, (&x, &y)| s + x * y);
                    a[i + k * m] = s;
                    a[k + i * m] = s;
                }
            }
        }
        // Yoshikawa's manipulability from the Cholesky factor; damped below singular_det
        let w = match cholesky_in_place(&self.a, &mut self.l) {
            Ok(()) => (0..m).map(|i| self.l[(i, i)]).product::<f64>(),
            Err(_) => 0.0,
        };
        let damped = !(w >= c.singular_det && w > 0.0);
        if damped {
            let ratio = if c.singular_det > 0.0 { (w / c.singular_det).min(1.0) } else { 0.0 };
            let lambda2 = (c.max_damping * (1.0 - ratio)).powi(2).max(1e-12);
            for i in 0..m {
                self.a[(i, i)] += lambda2;
            }
            if cholesky_in_place(&self.a, &mut self.l).is_err() {
                self.qdd_ref.fill(0.0);
                return (w, true);
            }
        }
        // qdd = J_s^+ b
        cholesky_solve(&self.l, &mut self.b);
        gemv_transposed(&self.js, &self.b, &mut self.qdd_ref);
        // + (I - J_s^+ J_s) z, z the posture acceleration towards the reference's joint motion
        if nv > m {
            match joint {
                Some(jc) => {
                    self.nominal.difference(q, jc.q, &mut self.e);
                    for i in 0..nv {
                        let de = if c.velocity_feedforward { jc.qd[i] - v[i] } else { -v[i] };
                        let mut zi = c.posture_kp * self.e[i] + c.posture_kv * de;
                        if c.acceleration_feedforward {
                            zi += jc.qdd[i];
                        }
                        self.z[i] = zi;
                    }
                }
                None => {
                    for i in 0..nv {
                        self.z[i] = -c.posture_kv * v[i];
                    }
                }
            }
            gemv(&self.js, &self.z, &mut self.jz);
            cholesky_solve(&self.l, &mut self.jz);
            gemv_transposed(&self.js, &self.jz, &mut self.e);
            for i in 0..nv {
                self.qdd_ref[i] += self.z[i] - self.e[i];
            }
        }
        (w, damped)
    }
}

#[cfg(test)]
mod tests {
    use super::{lu6, lu6_solve};
    use nalgebra::{Matrix6, Vector6};

    #[test]
    fn lu6_solves_and_gives_the_determinant_of_nalgebras_lu() {
        // a well-conditioned matrix, its rows permuted (pivoting), one with a zero leading entry
        let base = Matrix6::from_fn(|r, c| ((r * 7 + c * 3) % 11) as f64 * 0.1 + if r == c { 2.0 } else { 0.0 });
        let mut permuted = base;
        permuted.swap_rows(0, 4);
        permuted.swap_rows(2, 5);
        let mut zero_lead = base;
        zero_lead[(0, 0)] = 0.0;
        let b = Vector6::new(0.3, -1.2, 0.7, 2.0, -0.4, 0.9);
        for j in [base, permuted, zero_lead] {
            let (lu, perm, det) = lu6(&j);
            let want = j.lu();
            assert!((det - want.determinant()).abs() <= 1e-12 * det.abs(), "{det} {}", want.determinant());
            let x = lu6_solve(&lu, &perm, &b);
            assert!((x - want.solve(&b).unwrap()).amax() < 1e-12);
            assert!((j * x - b).amax() < 1e-12);
        }
        // singular: determinant zero
        let mut singular = base;
        let row = singular.row(1).into_owned();
        singular.set_row(3, &row);
        assert_eq!(lu6(&singular).2, 0.0);
    }
}
