//! Frame and centre-of-mass Jacobians against finite differences (fixed and free-flyer base),
//! and the Gauss-Newton projector on a small arm.

use genplan_core::kinematics::KinematicModel;
use genplan_core::projection::{Projector, Settings, Term, TermKind};
use nalgebra::{DMatrix, Matrix3, Vector3};

#[path = "common/arm.rs"]
mod arm;
use arm::model;

fn configurations(m: &KinematicModel) -> Vec<Vec<f64>> {
    let joints = [[0.3, -0.7, 1.1, 0.04], [-2.0, 1.5, -0.4, 0.09], [0.0, 0.0, 0.0, 0.0]];
    joints
        .iter()
        .map(|j| {
            let mut q = Vec::new();
            if m.floating_base {
                let rot = nalgebra::UnitQuaternion::from_euler_angles(0.4, -0.3, 1.2);
                q.extend([0.1, -0.2, 0.7, rot.i, rot.j, rot.k, rot.w]);
            }
            q.extend(j);
            q
        })
        .collect()
}

/// Finite-difference derivative of f(q (+) e) along each tangent direction.
fn fd<const N: usize>(m: &KinematicModel, q: &[f64], f: impl Fn(&[f64]) -> [f64; N]) -> DMatrix<f64> {
    let h = 1e-6;
    let mut out = DMatrix::zeros(N, m.nv);
    let mut qp = vec![0.0; m.nq];
    let mut qm = vec![0.0; m.nq];
    for k in 0..m.nv {
        let mut e = vec![0.0; m.nv];
        e[k] = h;
        m.integrate(q, &e, &mut qp);
        e[k] = -h;
        m.integrate(q, &e, &mut qm);
        let (a, b) = (f(&qp), f(&qm));
        for i in 0..N {
            out[(i, k)] = (a[i] - b[i]) / (2.0 * h);
        }
    }
    out
}

#[test]
fn frame_and_com_jacobians_match_finite_differences() {
    for floating in [false, true] {
        let m = model(floating);
        let tool = m.link_index("tool").unwrap();
        for q in configurations(&m) {
            let mut poses = Vec::new();
            m.forward_kinematics(&q, &mut poses).unwrap();
            let mut j = DMatrix::zeros(6, m.nv);
            m.frame_jacobian_local(&poses, tool, &mut j);
            let pose0 = poses[tool];
            // local-frame velocity: d/de of log6(pose0^-1 pose(q (+) e))
            let numeric = fd(&m, &q, |qq| {
                let mut p = Vec::new();
                m.forward_kinematics(qq, &mut p).unwrap();
                let d = genplan_core::lie::log6(&(pose0.inverse() * p[tool]));
                [d[0], d[1], d[2], d[3], d[4], d[5]]
            });
            assert!((&j - &numeric).amax() < 1e-6, "floating={floating}: {}", (&j - &numeric).amax());

            let mut jc = DMatrix::zeros(3, m.nv);
            m.center_of_mass(&poses, Some(&mut jc));
            let numeric = fd(&m, &q, |qq| {
                let mut p = Vec::new();
                m.forward_kinematics(qq, &mut p).unwrap();
                let c = m.center_of_mass(&p, None);
                [c.x, c.y, c.z]
            });
            assert!((&jc - &numeric).amax() < 1e-6, "com floating={floating}");
        }
    }
}

#[test]
fn center_of_mass_is_the_mass_weighted_mean() {
    let m = model(true);
    let q = &configurations(&m)[2];
    let mut poses = Vec::new();
    m.forward_kinematics(q, &mut poses).unwrap();
    let c = m.center_of_mass(&poses, None);
    let names = ["base", "l1", "l2", "l3", "tool"];
    let (mut num, mut den) = (Vector3::zeros(), 0.0);
    for n in names {
        let i = m.link_index(n).unwrap();
        num += (poses[i] * nalgebra::Point3::from(m.local_coms[i])).coords * m.masses[i];
        den += m.masses[i];
    }
    assert!((c - num / den).amax() < 1e-12);
    assert!((m.total_mass - 4.5).abs() < 1e-12);
    // on a fixed base the base link belongs to the world (Pinocchio's convention)
    assert!((model(false).total_mass - 2.5).abs() < 1e-12);
}

#[test]
fn projector_reaches_a_reachable_position_and_fails_softly_on_an_unreachable_one() {
    let m = model(false);
    let tool = m.link_index("tool").unwrap();
    // a target from FK of a known configuration is reachable
    let mut poses = Vec::new();
    m.forward_kinematics(&[0.8, -0.5, 0.7, 0.05], &mut poses).unwrap();
    let goal = poses[tool].translation.vector;
    let term = |target: Vector3<f64>| Term {
        name: "tool".into(),
        kind: TermKind::FramePosition { link: tool, target, mask: [1.0; 3] },
        weight: 10.0,
        tolerance: 1e-6,
    };
    let limits = Term { name: "limits".into(), kind: TermKind::JointLimits { margin: 1e-3 }, weight: 10.0, tolerance: 1e-6 };
    let posture = Term {
        name: "posture".into(),
        kind: TermKind::Posture { q_nom: None, weights: vec![1.0; m.nv], overrides: vec![] },
        weight: 1.0,
        tolerance: 1.0,
    };
    let p = Projector::new(m.clone(), vec![term(goal), limits.clone()], vec![posture], Settings::default()).unwrap();
    let out = p.solve(&[0.0, 0.1, 0.0, 0.0], None).unwrap();
    assert!(out.success, "{out:?}");
    m.forward_kinematics(&out.q, &mut poses).unwrap();
    assert!((poses[tool].translation.vector - goal).amax() < 1e-6);
    assert!(out.q.iter().zip(&m.lower).zip(&m.upper).all(|((q, l), u)| q >= l && q <= u));

    let far = p.retargeted(0, &[5.0, 0.0, 0.0]).unwrap();
    let out = far.solve(&[0.0, 0.1, 0.0, 0.0], None).unwrap();
    assert!(!out.success && out.iterations == 50 && out.residuals[0] > 3.0);
    assert!(out.q.iter().all(|x| x.is_finite()));

    assert!(p.retargeted(0, &[1.0, 2.0]).is_err());
    assert!(p.retargeted(7, &[1.0, 2.0, 3.0]).is_err());
    assert!(p.solve(&[0.0, f64::NAN, 0.0, 0.0], None).is_err());
    assert!(p.solve(&[0.0; 3], None).is_err());
}

#[test]
fn frame_orientation_with_a_free_axis() {
    // yaw-free orientation: any rotation about z satisfies it
    let m = model(false);
    let tool = m.link_index("tool").unwrap();
    let t = Term {
        name: "ori".into(),
        kind: TermKind::FrameOrientation { link: tool, target: Matrix3::identity(), offset: Matrix3::identity(), mask: [1.0, 1.0, 0.0] },
        weight: 1.0,
        tolerance: 1e-8,
    };
    let p = Projector::new(m.clone(), vec![t], vec![], Settings::default()).unwrap();
    let out = p.solve(&[0.3, 0.4, -0.5, 0.0], None).unwrap();
    assert!(out.success, "{out:?}");
    let mut poses = Vec::new();
    m.forward_kinematics(&out.q, &mut poses).unwrap();
    let z = poses[tool].rotation * Vector3::z();
    assert!((z - Vector3::z()).amax() < 1e-6, "{z}");
}
