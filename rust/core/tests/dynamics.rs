//! Rigid-body dynamics: closed forms on a planar 2R arm, internal consistency on small URDFs
//! with every joint kind (CRBA vs RNEA columns, energy, power, finite differences of the
//! kinematics for J and dJ/dt, Christoffel property, the articulated-body algorithm against
//! CRBA + Cholesky), and on the presets (those need example-robot-data: ignored by a bare
//! `cargo test`, run by `--include-ignored`).
//! The cross-check against Pinocchio is tests/test_dynamics.py.

use genplan_core::dynamics::{cholesky_in_place, Dynamics, Frame};
use genplan_core::kinematics::{KinematicModel, ModelOptions};
use genplan_core::robot::{find_robots_dir, preset};
use genplan_core::urdf::Urdf;
use genplan_core::Error;
use nalgebra::{DMatrix, Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};
use rand::{rngs::StdRng, Rng, SeedableRng};

/// Planar 2R arm in the vertical x-z plane (axes y), links along x.
const L1: f64 = 0.7;
const LC1: f64 = 0.3;
const LC2: f64 = 0.25;
const M1: f64 = 2.0;
const M2: f64 = 1.5;
const I1: f64 = 0.05;
const I2: f64 = 0.03;

fn planar() -> String {
    format!(
        r#"<robot name="planar2r">
  <link name="world"/>
  <link name="l1"><inertial><mass value="{M1}"/><origin xyz="{LC1} 0 0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="{I1}" iyz="0" izz="0.02"/></inertial></link>
  <link name="l2"><inertial><mass value="{M2}"/><origin xyz="{LC2} 0 0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="{I2}" iyz="0" izz="0.02"/></inertial></link>
  <link name="tool"/>
  <joint name="j1" type="revolute"><parent link="world"/><child link="l1"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="{L1} 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
  <joint name="jt" type="fixed"><parent link="l2"/><child link="tool"/><origin xyz="0.5 0 0"/></joint>
</robot>"#
    )
}

/// Every joint kind, off-axis origins, rotated inertias, a link lumped through a fixed joint (the
/// same file the Python cross-check against Pinocchio reads).
const MIXED: &str = include_str!("../../../tests/data/mixed.urdf");

fn dynamics(text: &str) -> Dynamics {
    Dynamics::from_urdf(&Urdf::parse(text).unwrap(), &ModelOptions::default()).unwrap()
}

fn rel(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    (a - b).norm() / b.norm().max(1.0)
}

fn mass(d: &Dynamics, q: &[f64]) -> DMatrix<f64> {
    let mut ws = d.workspace();
    let mut m = DMatrix::zeros(d.nv, d.nv);
    d.mass_matrix(q, &mut ws, &mut m).unwrap();
    m
}

fn rnea(d: &Dynamics, q: &[f64], v: &[f64], a: &[f64]) -> Vec<f64> {
    let mut ws = d.workspace();
    let mut t = vec![0.0; d.nv];
    d.rnea(q, v, a, &mut ws, &mut t).unwrap();
    t
}

fn nle(d: &Dynamics, q: &[f64], v: &[f64]) -> Vec<f64> {
    let mut ws = d.workspace();
    let mut t = vec![0.0; d.nv];
    d.nonlinear_effects(q, v, &mut ws, &mut t).unwrap();
    t
}

fn jac(d: &Dynamics, q: &[f64], f: &Frame) -> DMatrix<f64> {
    let mut ws = d.workspace();
    let mut j = DMatrix::zeros(6, d.nv);
    d.frame_jacobian(q, f, &mut ws, &mut j).unwrap();
    j
}

fn pose(d: &Dynamics, q: &[f64], f: &Frame) -> Isometry3<f64> {
    let mut ws = d.workspace();
    d.update_kinematics_unchecked(q, None, &mut ws);
    d.frame_isometry(f, &ws)
}

/// q (+) v h in Pinocchio's convention (a continuous joint's angle moves, [cos, sin] follow).
fn integrate(d: &Dynamics, q: &[f64], v: &[f64], h: f64) -> Vec<f64> {
    let mut out = q.to_vec();
    for b in &d.bodies {
        match b.kind {
            genplan_core::dynamics::JointKind::Continuous => {
                let a = q[b.q_index + 1].atan2(q[b.q_index]) + v[b.v_index] * h;
                out[b.q_index] = a.cos();
                out[b.q_index + 1] = a.sin();
            }
            _ => out[b.q_index] += v[b.v_index] * h,
        }
    }
    out
}

fn random_state(d: &Dynamics, rng: &mut StdRng) -> (Vec<f64>, Vec<f64>) {
    let mut q = vec![0.0; d.nq];
    for b in &d.bodies {
        match b.kind {
            genplan_core::dynamics::JointKind::Continuous => {
                let a: f64 = rng.random_range(-3.0..3.0);
                q[b.q_index] = a.cos();
                q[b.q_index + 1] = a.sin();
            }
            _ => q[b.q_index] = rng.random_range(-1.5..1.5),
        }
    }
    let v = (0..d.nv).map(|_| rng.random_range(-2.0..2.0)).collect();
    (q, v)
}

#[test]
fn planar_2r_matches_closed_form() {
    let d = dynamics(&planar());
    let g = 9.81;
    let mut rng = StdRng::seed_from_u64(1);
    for _ in 0..20 {
        let (q1, q2): (f64, f64) = (rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0));
        let (v1, v2): (f64, f64) = (rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0));
        let c2 = q2.cos();
        let m11 = I1 + I2 + M1 * LC1 * LC1 + M2 * (L1 * L1 + LC2 * LC2 + 2.0 * L1 * LC2 * c2);
        let m12 = I2 + M2 * (LC2 * LC2 + L1 * LC2 * c2);
        let m22 = I2 + M2 * LC2 * LC2;
        let expected = DMatrix::from_row_slice(2, 2, &[m11, m12, m12, m22]);
        assert!(rel(&mass(&d, &[q1, q2]), &expected) < 1e-14);
        // rotation about +y takes x to (cos q, 0, -sin q): heights -l sin q
        let h = -M2 * L1 * LC2 * q2.sin();
        let g1 = -g * ((M1 * LC1 + M2 * L1) * q1.cos() + M2 * LC2 * (q1 + q2).cos());
        let g2 = -g * M2 * LC2 * (q1 + q2).cos();
        let c1 = h * (2.0 * v1 * v2 + v2 * v2);
        let c2t = -h * v1 * v1;
        let got = nle(&d, &[q1, q2], &[v1, v2]);
        assert!((got[0] - (c1 + g1)).abs() < 1e-12 && (got[1] - (c2t + g2)).abs() < 1e-12, "{got:?}");
    }
}

#[test]
fn crba_equals_rnea_columns_and_forward_dynamics_inverts_rnea() {
    for text in [planar(), MIXED.to_string()] {
        let d = dynamics(&text);
        let mut rng = StdRng::seed_from_u64(2);
        for _ in 0..20 {
            let (q, v) = random_state(&d, &mut rng);
            let zero = vec![0.0; d.nv];
            let g = rnea(&d, &q, &zero, &zero);
            let m = mass(&d, &q);
            for i in 0..d.nv {
                let mut e = zero.clone();
                e[i] = 1.0;
                let col = rnea(&d, &q, &zero, &e);
                for k in 0..d.nv {
                    assert!((col[k] - g[k] - m[(k, i)]).abs() < 1e-12 * m.norm().max(1.0));
                }
            }
            assert!((&m - m.transpose()).amax() < 1e-14 * m.norm());
            let mut l = DMatrix::zeros(d.nv, d.nv);
            assert!(cholesky_in_place(&m, &mut l).is_ok(), "M must be positive definite");
            // rnea(q, v, fd(q, v, tau)) = tau
            let tau: Vec<f64> = (0..d.nv).map(|_| rng.random_range(-5.0..5.0)).collect();
            let mut ws = d.workspace();
            let mut qdd = vec![0.0; d.nv];
            d.forward_dynamics(&q, &v, &tau, &mut ws, &mut qdd).unwrap();
            let back = rnea(&d, &q, &v, &qdd);
            for k in 0..d.nv {
                assert!((back[k] - tau[k]).abs() < 1e-10, "{back:?} {tau:?}");
            }
        }
    }
}

/// The articulated-body algorithm against CRBA + RNEA + Cholesky at random states and torques,
/// at rest and moving, with a payload added off the last body's axes: the largest difference
/// relative to `1 + |qdd|_inf`.
fn aba_versus_crba(d: &Dynamics, seed: u64, n: usize) -> f64 {
    let mut with_payload = d.clone();
    let last = d.frame(&d.bodies[d.n_bodies() - 1].link, &Isometry3::translation(0.05, -0.02, 0.1)).unwrap();
    let inertia = Matrix3::new(0.02, 0.001, 0.0, 0.001, 0.03, 0.002, 0.0, 0.002, 0.01);
    with_payload.add_inertia(&last, 0.8, Vector3::new(0.01, 0.02, 0.03), inertia).unwrap();
    let mut rng = StdRng::seed_from_u64(seed);
    let mut worst = 0.0_f64;
    for model in [d, &with_payload] {
        let mut ws = model.workspace();
        let (mut expected, mut got) = (vec![0.0; model.nv], vec![0.0; model.nv]);
        for k in 0..n {
            let (q, mut v) = random_state(model, &mut rng);
            if k % 4 == 0 {
                v.fill(0.0);
            }
            let tau: Vec<f64> = (0..model.nv).map(|_| rng.random_range(-20.0..20.0)).collect();
            model.forward_dynamics(&q, &v, &tau, &mut ws, &mut expected).unwrap();
            let mut fresh = model.workspace();
            model.update_kinematics_unchecked(&q, Some(&v), &mut fresh);
            model.aba_from_kinematics(&tau, &mut fresh, &mut got).unwrap();
            let scale = 1.0 + expected.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
            for i in 0..model.nv {
                worst = worst.max((got[i] - expected[i]).abs() / scale);
            }
        }
    }
    worst
}

#[test]
fn aba_equals_crba_and_cholesky() {
    for text in [planar(), MIXED.to_string()] {
        let d = dynamics(&text);
        let err = aba_versus_crba(&d, 21, 200);
        assert!(err < 1e-9, "{}: ABA differs from CRBA + Cholesky by {err:e}", d.joint_names.join(","));
    }
    // a body without inertia fails as the Cholesky factor does, naming the joint
    let massless = MIXED.replace("<mass value=\"0.9\"/>", "<mass value=\"0\"/>").replace(
        "ixx=\"0.004\" ixy=\"0\" ixz=\"0\" iyy=\"0.02\" iyz=\"0\" izz=\"0.021\"",
        "ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"",
    );
    let d = dynamics(&massless);
    let mut ws = d.workspace();
    d.update_kinematics_unchecked(&[0.0, 1.0, 0.0, 0.0], Some(&[0.0; 3]), &mut ws);
    let e = d.aba_from_kinematics(&[0.0; 3], &mut ws, &mut [0.0; 3]).unwrap_err();
    assert!(e.to_string().contains("not positive definite") && e.to_string().contains("elbow"), "{e}");
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn aba_equals_crba_and_cholesky_on_the_presets() {
    for name in ["ur3", "ur5", "ur10", "panda", "kinova"] {
        let d = Dynamics::from_description(&preset(name).unwrap()).unwrap();
        let err = aba_versus_crba(&d, 22, 200);
        assert!(err < 1e-9, "{name}: ABA differs from CRBA + Cholesky by {err:e}");
    }
}

/// The kinematics at `q (+) h dq` by angle addition from the angles at q, against a fresh
/// update at the integrated configuration: every placement and velocity to rounding, for steps
/// of an RK stage and for steps beyond the small-angle series (`|h dq| > 1/16`).
#[test]
fn moved_kinematics_equal_the_kinematics_at_the_integrated_q() {
    for text in [planar(), MIXED.to_string()] {
        let d = dynamics(&text);
        let mut rng = StdRng::seed_from_u64(23);
        let (mut base, mut moved, mut fresh) = (d.workspace(), d.workspace(), d.workspace());
        let mut worst = 0.0_f64;
        for k in 0..200 {
            let (q, v) = random_state(&d, &mut rng);
            let (_, dq) = random_state(&d, &mut rng);
            let h = [5e-4, 1e-3, 0.02, 0.3][k % 4];
            d.update_kinematics_unchecked(&q, None, &mut base);
            d.update_kinematics_moved_unchecked(&base.angles, &q, &dq, h, &v, &mut moved);
            let mut qh = vec![0.0; d.nq];
            d.integrate_scaled(&q, &dq, h, &mut qh);
            d.update_kinematics_unchecked(&qh, Some(&v), &mut fresh);
            for i in 0..d.n_bodies() {
                for (a, b) in [(&moved.rw[i], &fresh.rw[i]), (&moved.r[i], &fresh.r[i])] {
                    worst = worst.max((a - b).amax());
                }
                for (a, b) in [(&moved.pw[i], &fresh.pw[i]), (&moved.vw[i], &fresh.vw[i]), (&moved.ww[i], &fresh.ww[i])] {
                    worst = worst.max((a - b).amax());
                }
                let (c, s) = (fresh.angles[i][0], fresh.angles[i][1]);
                worst = worst.max((moved.angles[i][0] - c).abs()).max((moved.angles[i][1] - s).abs());
            }
            assert_eq!(moved.qd, v);
        }
        assert!(worst < 1e-13, "{}: moved kinematics differ by {worst:e}", d.joint_names.join(","));
    }
}

/// The fused moved kinematics and articulated-body algorithm of the plant's RK stages against
/// the two calls it replaces: the same bits in qdd and in every placement and velocity.
#[test]
fn aba_moved_equals_moved_kinematics_then_aba_bit_for_bit() {
    for text in [planar(), MIXED.to_string()] {
        let d = dynamics(&text);
        let mut rng = StdRng::seed_from_u64(24);
        let (mut base, mut two, mut fused) = (d.workspace(), d.workspace(), d.workspace());
        let (mut want, mut got) = (vec![0.0; d.nv], vec![0.0; d.nv]);
        for k in 0..100 {
            let (q, v) = random_state(&d, &mut rng);
            let (_, dq) = random_state(&d, &mut rng);
            let tau: Vec<f64> = (0..d.nv).map(|_| rng.random_range(-20.0..20.0)).collect();
            let h = [5e-4, 1e-3, 0.3][k % 3];
            d.update_kinematics_unchecked(&q, None, &mut base);
            d.update_kinematics_moved_unchecked(&base.angles, &q, &dq, h, &v, &mut two);
            d.aba_from_kinematics(&tau, &mut two, &mut want).unwrap();
            d.aba_moved_unchecked(&base.angles, &q, &dq, h, &v, &tau, &mut fused, &mut got).unwrap();
            assert_eq!(got, want);
            assert!(want.iter().any(|x| *x != 0.0));
            assert_eq!((&fused.rw, &fused.pw, &fused.r, &fused.p), (&two.rw, &two.pw, &two.r, &two.p));
            assert_eq!((&fused.vw, &fused.ww, &fused.qd, &fused.angles), (&two.vw, &two.ww, &two.qd, &two.angles));
        }
    }
}

#[test]
fn kinetic_energy_is_half_vmv_and_power_balances() {
    let d = dynamics(MIXED);
    let mut rng = StdRng::seed_from_u64(3);
    for _ in 0..10 {
        let (q, v) = random_state(&d, &mut rng);
        let mut ws = d.workspace();
        d.update_kinematics_unchecked(&q, Some(&v), &mut ws);
        let ke = d.kinetic_energy_from_kinematics(&ws);
        let m = mass(&d, &q);
        let vv = nalgebra::DVector::from_column_slice(&v);
        assert!((ke - 0.5 * vv.dot(&(&m * &vv))).abs() < 1e-12);
        // with tau = 0 the total energy is constant: d/dt (T + V) = v^T tau = 0, by central
        // differences along the flow q' = v, v' = fd(q, v, 0)
        let zero = vec![0.0; d.nv];
        let energy = |q: &[f64], v: &[f64]| {
            let mut ws = d.workspace();
            d.update_kinematics_unchecked(q, Some(v), &mut ws);
            d.kinetic_energy_from_kinematics(&ws) + d.potential_energy_from_kinematics(&ws)
        };
        let mut qdd = vec![0.0; d.nv];
        d.forward_dynamics(&q, &v, &zero, &mut ws, &mut qdd).unwrap();
        let h = 1e-6;
        let vp: Vec<f64> = v.iter().zip(&qdd).map(|(a, b)| a + b * h).collect();
        let vm: Vec<f64> = v.iter().zip(&qdd).map(|(a, b)| a - b * h).collect();
        let de = (energy(&integrate(&d, &q, &v, h), &vp) - energy(&integrate(&d, &q, &v, -h), &vm)) / (2.0 * h);
        assert!(de.abs() < 1e-6 * (1.0 + energy(&q, &v).abs()), "dE/dt = {de}");
    }
}

/// d/dt M along v, by central differences.
fn mdot(d: &Dynamics, q: &[f64], v: &[f64]) -> DMatrix<f64> {
    let h = 1e-6;
    (mass(d, &integrate(d, q, v, h)) - mass(d, &integrate(d, q, v, -h))) / (2.0 * h)
}

#[test]
fn coriolis_satisfies_the_skew_symmetry_property() {
    // v^T (dM/dt - 2 C) v = 0, with C v = nle(q, v) - g(q)
    let d = dynamics(MIXED);
    let mut rng = StdRng::seed_from_u64(4);
    for _ in 0..10 {
        let (q, v) = random_state(&d, &mut rng);
        let zero = vec![0.0; d.nv];
        let g = nle(&d, &q, &zero);
        let cv: Vec<f64> = nle(&d, &q, &v).iter().zip(&g).map(|(a, b)| a - b).collect();
        let vv = nalgebra::DVector::from_column_slice(&v);
        let lhs = vv.dot(&(mdot(&d, &q, &v) * &vv));
        let rhs = 2.0 * vv.dot(&nalgebra::DVector::from_column_slice(&cv));
        assert!((lhs - rhs).abs() < 1e-6 * (1.0 + lhs.abs()), "{lhs} vs {rhs}");
    }
}

fn check_jacobians_by_finite_differences(d: &Dynamics, frame: &Frame, seed: u64, n: usize) {
    let mut rng = StdRng::seed_from_u64(seed);
    for _ in 0..n {
        let (q, v) = random_state(d, &mut rng);
        let j = jac(d, &q, frame);
        // J v = d/dt of the frame's pose: linear part = d p / dt, angular from the rotations
        let h = 1e-6;
        let (pp, pm) = (pose(d, &integrate(d, &q, &v, h), frame), pose(d, &integrate(d, &q, &v, -h), frame));
        let lin = (pp.translation.vector - pm.translation.vector) / (2.0 * h);
        let ang = (pp.rotation * pm.rotation.inverse()).scaled_axis() / (2.0 * h);
        let jv = &j * nalgebra::DVector::from_column_slice(&v);
        for k in 0..3 {
            assert!((jv[k] - lin[k]).abs() < 1e-7 && (jv[k + 3] - ang[k]).abs() < 1e-7, "J v {jv} vs {lin} {ang}");
        }
        // dJ/dt = (J(q + v h) - J(q - v h)) / 2h
        let mut ws = d.workspace();
        let mut dj = DMatrix::zeros(6, d.nv);
        d.frame_jacobian_time_variation(&q, &v, frame, &mut ws, &mut dj).unwrap();
        let fd = (jac(d, &integrate(d, &q, &v, h), frame) - jac(d, &integrate(d, &q, &v, -h), frame)) / (2.0 * h);
        assert!((&dj - &fd).amax() < 1e-7 * (1.0 + dj.amax()), "dJ {dj} vs {fd}");
    }
}

#[test]
fn jacobian_and_its_time_derivative_match_finite_differences() {
    let d = dynamics(MIXED);
    let offset = Isometry3::from_parts(Translation3::new(0.05, -0.02, 0.1), UnitQuaternion::from_euler_angles(0.3, -0.2, 0.1));
    for (link, off) in [("tip", Isometry3::identity()), ("bracket", offset), ("slider", offset)] {
        check_jacobians_by_finite_differences(&d, &d.frame(link, &off).unwrap(), 5, 10);
    }
    let d = dynamics(&planar());
    check_jacobians_by_finite_differences(&d, &d.frame("tool", &Isometry3::identity()).unwrap(), 6, 10);
}

#[test]
fn frames_agree_with_the_kinematic_model() {
    let urdf = Urdf::parse(MIXED).unwrap();
    let model = KinematicModel::from_urdf(&urdf, &ModelOptions::default()).unwrap();
    let d = Dynamics::from_model(&model, &urdf).unwrap();
    let mut rng = StdRng::seed_from_u64(7);
    let mut poses = Vec::new();
    for _ in 0..10 {
        let (q, _) = random_state(&d, &mut rng);
        model.forward_kinematics(&q, &mut poses).unwrap();
        for (l, name) in model.link_names.iter().enumerate() {
            let p = pose(&d, &q, &d.frame(name, &Isometry3::identity()).unwrap());
            assert!((p.to_homogeneous() - poses[l].to_homogeneous()).amax() < 1e-12, "{name}");
        }
    }
}

#[test]
fn added_point_mass_changes_m_and_g_by_its_jacobian() {
    let base = dynamics(MIXED);
    let mut with = base.clone();
    let f = base.frame("arm", &Isometry3::translation(0.3, 0.01, 0.02)).unwrap();
    let m = 0.7;
    with.add_inertia(&f, m, Vector3::zeros(), Matrix3::zeros()).unwrap();
    let mut rng = StdRng::seed_from_u64(8);
    for _ in 0..10 {
        let (q, _) = random_state(&base, &mut rng);
        let j = jac(&base, &q, &f);
        let jp = j.rows(0, 3).into_owned();
        let dm = mass(&with, &q) - mass(&base, &q);
        assert!((&dm - jp.transpose() * &jp * m).amax() < 1e-12);
        let zero = vec![0.0; base.nv];
        let dg: Vec<f64> = nle(&with, &q, &zero).iter().zip(nle(&base, &q, &zero)).map(|(a, b)| a - b).collect();
        let expect = jp.transpose() * (-base.gravity * m);
        for k in 0..base.nv {
            assert!((dg[k] - expect[k]).abs() < 1e-12);
        }
    }
    assert!((with.moving_mass() - base.moving_mass() - m).abs() < 1e-12);
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let d = dynamics(MIXED);
    let mut ws = d.workspace();
    let mut out = vec![0.0; d.nv];
    let q = vec![0.0, 1.0, 0.0, 0.0];
    assert_eq!(d.nq, 4);
    let e = d.nonlinear_effects(&q[..3], &[0.0; 3], &mut ws, &mut out).unwrap_err();
    assert!(matches!(e, Error::Shape { expected: 4, got: 3, .. }), "{e}");
    let e = d.nonlinear_effects(&q, &[0.0, f64::NAN, 0.0], &mut ws, &mut out).unwrap_err();
    assert!(e.to_string().contains("velocity v") && e.to_string().contains("NaN"), "{e}");
    let e = d.rnea(&q, &[0.0; 3], &[0.0; 3], &mut ws, &mut out[..2]).unwrap_err();
    assert!(matches!(e, Error::Shape { .. }), "{e}");
    let f = d.frame("arm", &Isometry3::identity()).unwrap();
    let mut d2 = d.clone();
    assert!(d2.add_inertia(&f, -1.0, Vector3::zeros(), Matrix3::zeros()).is_err());
    let asym = Matrix3::new(1.0, 0.5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
    assert!(d2.add_inertia(&f, 1.0, Vector3::zeros(), asym).is_err());
    assert!(d.frame("nope", &Isometry3::identity()).unwrap_err().to_string().contains("unknown link 'nope'"));
    // a floating base is refused
    let opts = ModelOptions { floating_base: true, ..Default::default() };
    let e = Dynamics::from_urdf(&Urdf::parse(MIXED).unwrap(), &opts).unwrap_err();
    assert!(e.to_string().contains("floating-base"), "{e}");
    // a moving body without inertia: forward dynamics reports it
    let massless = MIXED.replace("<mass value=\"0.9\"/>", "<mass value=\"0\"/>").replace(
        "ixx=\"0.004\" ixy=\"0\" ixz=\"0\" iyy=\"0.02\" iyz=\"0\" izz=\"0.021\"",
        "ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"",
    );
    let d3 = dynamics(&massless);
    let mut ws3 = d3.workspace();
    let e = d3.forward_dynamics(&q, &[0.0; 3], &[0.0; 3], &mut ws3, &mut out).unwrap_err();
    assert!(e.to_string().contains("not positive definite") && e.to_string().contains("elbow"), "{e}");
}

fn presets() -> Vec<(&'static str, Dynamics, &'static str)> {
    vec![
        ("ur5", Dynamics::from_description(&preset("ur5").unwrap()).unwrap(), "tool0"),
        ("panda", Dynamics::from_description(&preset("panda").unwrap()).unwrap(), "panda_hand"),
    ]
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn presets_are_consistent() {
    for (name, d, tool) in presets() {
        assert_eq!(d.nq, if name == "ur5" { 6 } else { 7 });
        let mut rng = StdRng::seed_from_u64(9);
        for _ in 0..20 {
            let (q, v) = random_state(&d, &mut rng);
            let m = mass(&d, &q);
            assert!((&m - m.transpose()).amax() < 1e-14 * m.norm(), "{name}");
            let eig = m.clone().symmetric_eigen().eigenvalues;
            assert!(eig.min() > 0.0, "{name}: M not positive definite {eig}");
            let zero = vec![0.0; d.nv];
            let g = nle(&d, &q, &zero);
            let cv: Vec<f64> = nle(&d, &q, &v).iter().zip(&g).map(|(a, b)| a - b).collect();
            let vv = nalgebra::DVector::from_column_slice(&v);
            let lhs = vv.dot(&(mdot(&d, &q, &v) * &vv));
            let rhs = 2.0 * cv.iter().zip(&v).map(|(a, b)| a * b).sum::<f64>();
            assert!((lhs - rhs).abs() < 1e-6 * (1.0 + lhs.abs()), "{name}: {lhs} vs {rhs}");
        }
        let frame = d.frame(tool, &Isometry3::translation(0.0, 0.0, 0.1)).unwrap();
        check_jacobians_by_finite_differences(&d, &frame, 10, 10);
    }
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn ur5_masses_and_locked_panda_fingers() {
    let root = find_robots_dir().unwrap();
    let ur5 = Dynamics::from_description(&preset("ur5").unwrap()).unwrap();
    // shoulder 3.7 + upper arm 8.393 + forearm 2.275 + wrists 3 x (1.219, 1.219, 0.1879); the
    // base (4 kg) is fixed to the world
    assert!((ur5.moving_mass() - (3.7 + 8.393 + 2.275 + 1.219 + 1.219 + 0.1879)).abs() < 1e-12);
    let panda = Dynamics::from_description(&preset("panda").unwrap()).unwrap();
    assert_eq!(panda.nv, 7);
    // locked fingers are lumped into the hand body
    let urdf = Urdf::from_file(root.join("panda_description/urdf/panda.urdf")).unwrap();
    let total: f64 = urdf
        .links
        .iter()
        .filter(|l| l.name != "panda_link0" && l.name != "world")
        .filter_map(|l| l.inertial.map(|i| i.mass))
        .sum();
    assert!((panda.moving_mass() - total).abs() < 1e-12, "{} vs {total}", panda.moving_mass());
}
