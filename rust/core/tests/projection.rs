//! Frame and centre-of-mass Jacobians against finite differences (fixed and free-flyer base),
//! and the Gauss-Newton projector on a small arm.

use genplan_core::kinematics::KinematicModel;
use genplan_core::projection::{Projector, Settings, Term, TermKind};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

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

/// Central finite differences of f(q (+) e) (`rows` values) along each tangent direction.
fn fd_rows(m: &KinematicModel, q: &[f64], rows: usize, f: impl Fn(&[f64]) -> DVector<f64>) -> DMatrix<f64> {
    let h = 1e-6;
    let mut out = DMatrix::zeros(rows, m.nv);
    let (mut qp, mut qm) = (vec![0.0; m.nq], vec![0.0; m.nq]);
    for k in 0..m.nv {
        let mut e = vec![0.0; m.nv];
        e[k] = h;
        m.integrate(q, &e, &mut qp);
        e[k] = -h;
        m.integrate(q, &e, &mut qm);
        out.column_mut(k).copy_from(&((f(&qp) - f(&qm)) / (2.0 * h)));
    }
    out
}

/// Finite-difference derivative of f(q (+) e) along each tangent direction.
fn fd<const N: usize>(m: &KinematicModel, q: &[f64], f: impl Fn(&[f64]) -> [f64; N]) -> DMatrix<f64> {
    fd_rows(m, q, N, |q| DVector::from_row_slice(&f(q)))
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

/// Central finite differences of the projector's (single, weight 1) term's residual along each
/// tangent direction.
fn fd_residual(p: &Projector, q: &[f64]) -> DMatrix<f64> {
    fd_rows(&p.model, q, p.primary_dim(), |q| p.primary_residuals(q, false).unwrap().0)
}

/// The relative, point-at and plane terms with non-trivial targets, masks, axes and normals.
fn multi_frame_terms(m: &KinematicModel) -> Vec<Term> {
    let [l1, l2, l3, tool] = ["l1", "l2", "l3", "tool"].map(|n| m.link_index(n).unwrap());
    let target = nalgebra::Isometry3::new(Vector3::new(0.1, -0.3, 0.2), Vector3::new(0.4, -0.2, 0.9));
    let term = |name: &str, kind| Term { name: name.into(), kind, weight: 1.0, tolerance: 1e-6 };
    vec![
        term("pose", TermKind::RelativePose { link: tool, relative_to: l2, target, mask: [1.0, 0.5, 2.0, 1.0, 0.0, 3.0] }),
        term("pose_in_base_link", TermKind::RelativePose { link: l3, relative_to: l1, target, mask: [1.0; 6] }),
        term("position", TermKind::RelativePosition { link: tool, relative_to: l1, target: Vector3::new(0.2, 0.1, -0.1), mask: [1.0, 2.0, 0.5] }),
        // the second link further down the chain than the first
        term("position_inverse", TermKind::RelativePosition { link: l1, relative_to: tool, target: Vector3::zeros(), mask: [1.0; 3] }),
        term("point_at", TermKind::PointAt { link: tool, axis: Vector3::new(0.3, -0.2, 0.9).normalize(), point: Vector3::new(0.5, 0.4, 0.3) }),
        term("point_at_x", TermKind::PointAt { link: l3, axis: Vector3::x(), point: Vector3::new(-0.2, 0.1, 0.8) }),
        term("plane", TermKind::Plane { link: tool, normal: Vector3::new(0.2, 0.5, -0.8).normalize(), offset: 0.3 }),
    ]
}

#[test]
fn relative_point_at_and_plane_jacobians_match_finite_differences() {
    for floating in [false, true] {
        let m = model(floating);
        for q in configurations(&m) {
            for t in multi_frame_terms(&m) {
                let name = t.name.clone();
                let p = Projector::new(m.clone(), vec![t], vec![], Settings::default()).unwrap();
                let (_, j) = p.primary_residuals(&q, true).unwrap();
                let j = j.unwrap();
                let numeric = fd_residual(&p, &q);
                let err = (&j - &numeric).amax();
                assert!(err < 1e-6, "{name} floating={floating} q={q:?}: {err}\n{j}\n{numeric}");
            }
        }
    }
}

/// The residuals are what they measure: a RelativePose's target is `T_B^-1 T_A` at the
/// configuration it was taken from, a RelativePosition's `R_B^T (p_A - p_B)`; a PointAt is zero
/// when the point is on the axis, its norm the distance from the axis's line; a Plane the signed
/// distance.
#[test]
fn relative_point_at_and_plane_residuals_measure_their_geometry() {
    let m = model(true);
    let [l1, tool] = ["l1", "tool"].map(|n| m.link_index(n).unwrap());
    let q = &configurations(&m)[0];
    let mut poses = Vec::new();
    m.forward_kinematics(q, &mut poses).unwrap();
    let rel = poses[l1].inverse() * poses[tool];
    let axis = Vector3::new(0.0, 0.6, 0.8);
    let on_axis = poses[tool] * nalgebra::Point3::from(axis * 0.7);
    let off = poses[tool].rotation * Vector3::new(0.0, 0.8, -0.6) * 0.05; // orthogonal to the axis
    let normal = Vector3::new(0.0, 0.0, 1.0);
    let term = |kind| Term { name: "t".into(), kind, weight: 1.0, tolerance: 1e-6 };
    let res = |kind| Projector::new(m.clone(), vec![term(kind)], vec![], Settings::default()).unwrap().primary_residuals(q, false).unwrap().0;
    assert!(res(TermKind::RelativePose { link: tool, relative_to: l1, target: rel, mask: [1.0; 6] }).amax() < 1e-12);
    let p_rel = rel.translation.vector;
    assert!(res(TermKind::RelativePosition { link: tool, relative_to: l1, target: p_rel, mask: [1.0; 3] }).amax() < 1e-12);
    assert!(res(TermKind::PointAt { link: tool, axis, point: on_axis.coords }).amax() < 1e-12);
    assert!((res(TermKind::PointAt { link: tool, axis, point: on_axis.coords + off }).norm() - 0.05).abs() < 1e-12);
    let z = poses[tool].translation.vector.z;
    assert!((res(TermKind::Plane { link: tool, normal, offset: 0.25 })[0] - (z - 0.25)).abs() < 1e-12);
}

#[test]
fn relative_pose_point_at_and_plane_are_solved() {
    let m = model(false);
    let [l1, l2, tool] = ["l1", "l2", "tool"].map(|n| m.link_index(n).unwrap());
    let mut poses = Vec::new();
    m.forward_kinematics(&[0.8, -0.5, 0.7, 0.05], &mut poses).unwrap();
    let goal = poses[l1].inverse() * poses[tool];
    let pose = Term {
        name: "rel".into(),
        kind: TermKind::RelativePose { link: tool, relative_to: l1, target: goal, mask: [1.0; 6] },
        weight: 1.0,
        tolerance: 1e-8,
    };
    let p = Projector::new(m.clone(), vec![pose], vec![], Settings::default()).unwrap();
    // j1 moves both frames alike: the relative pose does not see it, so it stays where it starts
    let out = p.solve(&[-1.0, 0.1, 0.0, 0.0], None).unwrap();
    assert!(out.success, "{out:?}");
    m.forward_kinematics(&out.q, &mut poses).unwrap();
    let got = poses[l1].inverse() * poses[tool];
    assert!((got.to_homogeneous() - goal.to_homogeneous()).amax() < 1e-7);
    assert!((out.q[0] + 1.0).abs() < 1e-9, "{out:?}");

    // retargeted with a pose (16 numbers) like a FramePose; 3 numbers are refused
    let moved = nalgebra::Translation3::new(0.01, 0.0, -0.02) * goal;
    let flat: Vec<f64> = (0..4).flat_map(|i| (0..4).map(move |j| moved.to_homogeneous()[(i, j)])).collect();
    assert!(p.retargeted(0, &flat).is_ok());
    assert!(p.retargeted(0, &[1.0, 2.0, 3.0]).is_err());
    let position = Term {
        name: "relpos".into(),
        kind: TermKind::RelativePosition { link: tool, relative_to: l2, target: Vector3::zeros(), mask: [1.0; 3] },
        weight: 1.0,
        tolerance: 1e-8,
    };
    let p = Projector::new(m.clone(), vec![position], vec![], Settings::default()).unwrap();
    m.forward_kinematics(&[0.0, 0.0, 0.4, 0.03], &mut poses).unwrap();
    let t = poses[l2].inverse() * poses[tool];
    let p = p.retargeted(0, t.translation.vector.as_slice()).unwrap();
    let out = p.solve(&[0.3, 0.2, -0.5, 0.08], None).unwrap();
    assert!(out.success && out.residuals[0] < 1e-8, "{out:?}");

    // the tool's z axis through a point, its origin on a plane, together (both met at a known q)
    m.forward_kinematics(&[0.5, 0.6, -0.9, 0.02], &mut poses).unwrap();
    let point = poses[tool] * nalgebra::Point3::new(0.0, 0.0, 0.5);
    let (point, height) = (point.coords, poses[tool].translation.vector.z);
    let terms = vec![
        Term { name: "look".into(), kind: TermKind::PointAt { link: tool, axis: Vector3::z(), point }, weight: 1.0, tolerance: 1e-8 },
        Term { name: "plane".into(), kind: TermKind::Plane { link: tool, normal: Vector3::z(), offset: height }, weight: 1.0, tolerance: 1e-8 },
    ];
    let p = Projector::new(m.clone(), terms, vec![], Settings::default()).unwrap();
    let out = p.solve(&[0.3, 0.4, -0.5, 0.05], None).unwrap();
    assert!(out.success, "{out:?}");
    m.forward_kinematics(&out.q, &mut poses).unwrap();
    let (origin, z) = (poses[tool].translation.vector, poses[tool].rotation * Vector3::z());
    assert!((origin.z - height).abs() < 1e-8);
    assert!((point - origin).cross(&z).norm() < 1e-7);
}

#[test]
fn bad_relative_point_at_and_plane_terms_name_the_term_and_field() {
    let m = model(false);
    let [l1, tool] = ["l1", "tool"].map(|n| m.link_index(n).unwrap());
    let term = |kind| Term { name: "bad".into(), kind, weight: 1.0, tolerance: 1e-6 };
    let err = |kind| Projector::new(m.clone(), vec![term(kind)], vec![], Settings::default()).unwrap_err().to_string();
    let id = nalgebra::Isometry3::identity();
    let e = err(TermKind::RelativePose { link: tool, relative_to: tool, target: id, mask: [1.0; 6] });
    assert!(e.contains("term 'bad'") && e.contains("relative_to is the link itself"), "{e}");
    let e = err(TermKind::RelativePosition { link: tool, relative_to: 99, target: Vector3::zeros(), mask: [1.0; 3] });
    assert!(e.contains("link index 99 out of range"), "{e}");
    let e = err(TermKind::RelativePosition { link: tool, relative_to: l1, target: Vector3::new(f64::NAN, 0.0, 0.0), mask: [1.0; 3] });
    assert!(e.contains("term 'bad' target"), "{e}");
    let e = err(TermKind::PointAt { link: tool, axis: Vector3::new(0.0, 0.0, 2.0), point: Vector3::zeros() });
    assert!(e.contains("axis must be a unit vector, got norm 2.0"), "{e}");
    let e = err(TermKind::Plane { link: tool, normal: Vector3::z(), offset: 1e9 });
    assert!(e.contains("offset element 0 is 1000000000.0"), "{e}");
    let e = err(TermKind::Plane { link: 42, normal: Vector3::z(), offset: 0.0 });
    assert!(e.contains("link index 42 out of range"), "{e}");
}

#[test]
fn residual_sizes_are_the_unstepped_solves_residuals() {
    let m = model(false);
    let tool = m.link_index("tool").unwrap();
    let terms = vec![
        Term { name: "tool".into(), kind: TermKind::FramePosition { link: tool, target: Vector3::new(0.3, 0.1, 0.4), mask: [1.0; 3] }, weight: 10.0, tolerance: 1e-6 },
        Term { name: "limits".into(), kind: TermKind::JointLimits { margin: 1e-3 }, weight: 10.0, tolerance: 1e-6 },
        Term { name: "posture".into(), kind: TermKind::Posture { q_nom: Some(vec![0.1; m.nq]), weights: vec![1.0; m.nv], overrides: vec![] }, weight: 1.0, tolerance: 1.0 },
    ];
    let unstepped = Settings { max_iterations: 0, clip_to_limits: false, ..Settings::default() };
    let p = Projector::new(m.clone(), terms, vec![], unstepped).unwrap();
    // a row beyond a joint limit too, so that the limits term is not zero everywhere
    let mut rows = configurations(&m);
    rows.push(vec![0.2, 9.0, -0.3, 0.02]);
    let flat: Vec<f64> = rows.concat();
    for parallel in [false, true] {
        let sizes = p.try_residual_sizes(&flat, parallel).unwrap();
        assert_eq!(sizes.len(), rows.len() * 3);
        for (q, row) in rows.iter().zip(sizes.chunks(3)) {
            let out = p.solve(q, None).unwrap();
            assert_eq!(out.iterations, 0);
            assert_eq!(row, out.residuals.as_slice(), "q {q:?}");
        }
        assert!(sizes.iter().any(|&x| x > 0.0) && sizes[3 * 3 + 1] > 1.0, "{sizes:?}");
    }
    assert!(p.try_residual_sizes(&[], true).unwrap().is_empty());
    // rows are checked before any work: a NaN, a partial row
    assert!(p.try_residual_sizes(&[0.0, f64::NAN, 0.0, 0.0], false).is_err());
    assert!(p.try_residual_sizes(&[0.0; 6], true).is_err());
}

/// The residual-only check evaluates only the joints its terms read, into buffers kept across
/// rows: its sizes are those of an unstepped solve bit for bit, for every built-in term kind
/// (alone, so that a task reading only the first links computes only their joints, and all
/// together), on a fixed and a free-flyer base, a posture with overrides and one with a nominal
/// of its own, in parallel or not.
#[test]
fn residual_sizes_of_every_term_kind_are_the_solves_bit_for_bit() {
    for floating in [false, true] {
        let m = model(floating);
        let [base, l1, l2, tool] = ["base", "l1", "l2", "tool"].map(|n| m.link_index(n).unwrap());
        let term = |name: &str, kind| Term { name: name.into(), kind, weight: 2.0, tolerance: 1e-6 };
        let target = nalgebra::Isometry3::new(Vector3::new(0.1, -0.3, 0.2), Vector3::new(0.4, -0.2, 0.9));
        let rot = *target.rotation.to_rotation_matrix().matrix();
        let offset = *nalgebra::Rotation3::from_euler_angles(0.1, 0.2, -0.3).matrix();
        let (nq, nv) = (m.nq, m.nv);
        let mut kinds = vec![
            term("pose_l1", TermKind::FramePose { link: l1, target, mask: [1.0, 0.5, 2.0, 1.0, 0.0, 3.0] }),
            term("position_l2", TermKind::FramePosition { link: l2, target: target.translation.vector, mask: [1.0, 2.0, 0.5] }),
            term("orientation_base", TermKind::FrameOrientation { link: base, target: rot, offset, mask: [1.0; 3] }),
            term("orientation_tool", TermKind::FrameOrientation { link: tool, target: rot, offset, mask: [0.0, 1.0, 1.0] }),
            term("limits", TermKind::JointLimits { margin: 1e-3 }),
            term("com", TermKind::ComBox { lower: Vector3::new(-0.1, -0.1, 0.0), upper: Vector3::new(0.1, 0.05, 0.3), margin: 0.01 }),
            term("posture_overrides", TermKind::Posture { q_nom: None, weights: (0..nv).map(|i| 0.5 + i as f64).collect(), overrides: vec![(nq - 2, 0.7)] }),
            term("posture_own", TermKind::Posture { q_nom: Some(configurations(&m)[1].clone()), weights: vec![1.5; nv], overrides: vec![] }),
        ];
        kinds.extend(multi_frame_terms(&m));
        let mut rows = configurations(&m);
        // beyond the limits of the second and last joints
        let mut beyond = rows[0].clone();
        beyond[nq - 3] = 2.6;
        beyond[nq - 1] = -0.3;
        rows.push(beyond);
        let flat: Vec<f64> = rows.concat();
        let unstepped = Settings { max_iterations: 0, clip_to_limits: false, ..Settings::default() };
        let tasks = kinds.iter().map(|t| vec![t.clone()]).chain([kinds.clone()]);
        for terms in tasks {
            let n = terms.len();
            let names: Vec<String> = terms.iter().map(|t| t.name.clone()).collect();
            let p = Projector::new(m.clone(), terms, vec![], unstepped.clone()).unwrap();
            for parallel in [false, true] {
                let sizes = p.try_residual_sizes(&flat, parallel).unwrap();
                assert_eq!(sizes.len(), rows.len() * n);
                for (q, row) in rows.iter().zip(sizes.chunks(n)) {
                    let want = p.solve(q, None).unwrap().residuals;
                    let (got, want): (Vec<u64>, Vec<u64>) = (row.iter().map(|x| x.to_bits()).collect(), want.iter().map(|x| x.to_bits()).collect());
                    assert_eq!(got, want, "floating {floating}, terms {names:?}, q {q:?}");
                }
            }
            // every term measures something at some row (no size is trivially zero everywhere)
            let sizes = p.try_residual_sizes(&flat, false).unwrap();
            for (i, name) in names.iter().enumerate() {
                assert!(sizes.iter().skip(i).step_by(n).any(|&x| x > 0.0), "{name}: {sizes:?}");
            }
        }
    }
}
