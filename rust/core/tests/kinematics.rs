//! Forward kinematics on small hand-written URDFs, against closed forms.

use std::collections::HashMap;

use genplan_core::kinematics::{KinematicModel, ModelOptions};
use genplan_core::urdf::Urdf;
use genplan_core::Error;
use nalgebra::{Isometry3, Vector3};

/// Planar 2R arm in the x-y plane (axes z), link lengths 1.0 and 0.5, plus a fixed tool.
const PLANAR: &str = r#"<robot name="planar">
  <link name="base"/>
  <link name="l1"/>
  <link name="l2"/>
  <link name="tool"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/>
  </joint>
  <joint name="j2" type="revolute">
    <parent link="l1"/><child link="l2"/>
    <origin xyz="1 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/>
  </joint>
  <joint name="tool_joint" type="fixed">
    <parent link="l2"/><child link="tool"/>
    <origin xyz="0.5 0 0" rpy="0 0 0"/>
  </joint>
</robot>"#;

fn model(options: &ModelOptions) -> KinematicModel {
    KinematicModel::from_urdf(&Urdf::parse(PLANAR).unwrap(), options).unwrap()
}

fn pose(m: &KinematicModel, q: &[f64], link: &str) -> Isometry3<f64> {
    let mut out = Vec::new();
    m.forward_kinematics(q, &mut out).unwrap();
    out[m.link_index(link).unwrap()]
}

#[test]
fn planar_arm_matches_closed_form() {
    let m = model(&ModelOptions::default());
    assert_eq!(m.nq, 2);
    assert_eq!(m.active_joints, vec!["j1", "j2"]);
    assert_eq!(m.lower, vec![-3.0, -2.0]);
    for &(a, b) in &[(0.0, 0.0), (0.3, -1.2), (-2.5, 1.9), (1.0, 1.0)] {
        let p = pose(&m, &[a, b], "tool");
        let expected = Vector3::new(a.cos() + 0.5 * (a + b).cos(), a.sin() + 0.5 * (a + b).sin(), 0.0);
        assert!((p.translation.vector - expected).norm() < 1e-14, "{a} {b}");
        assert!((p.rotation.angle() - (a + b).abs().min(2.0 * std::f64::consts::PI - (a + b).abs())).abs() < 1e-12);
    }
}

#[test]
fn fixed_links_share_their_body() {
    let m = model(&ModelOptions::default());
    let (l2, tool) = (m.link_index("l2").unwrap(), m.link_index("tool").unwrap());
    assert_eq!(m.body_of_link[tool], m.body_of_link[l2]);
    assert_ne!(m.body_of_link[l2], m.body_of_link[m.link_index("l1").unwrap()]);
}

#[test]
fn locked_joint_is_folded_in() {
    let locked = HashMap::from([("j2".to_string(), 0.7)]);
    let m = model(&ModelOptions { locked_joints: locked, ..Default::default() });
    assert_eq!(m.nq, 1);
    let full = model(&ModelOptions::default());
    let a = pose(&m, &[0.4], "tool");
    let b = pose(&full, &[0.4, 0.7], "tool");
    assert!((a.translation.vector - b.translation.vector).norm() < 1e-14);
    // l2 is now rigidly attached to l1
    assert_eq!(m.body_of_link[m.link_index("l2").unwrap()], m.body_of_link[m.link_index("l1").unwrap()]);
}

#[test]
fn floating_base_moves_everything() {
    let m = model(&ModelOptions { floating_base: true, ..Default::default() });
    assert_eq!((m.nq, m.nv), (9, 8));
    // base at (1, 2, 3), rotated 90 degrees about z: quaternion (0, 0, sin 45, cos 45)
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let p = pose(&m, &[1.0, 2.0, 3.0, 0.0, 0.0, s, s, 0.0, 0.0], "tool");
    assert!((p.translation.vector - Vector3::new(1.0, 3.5, 3.0)).norm() < 1e-14);
}

#[test]
fn joint_order_is_respected_and_validated() {
    let m = model(&ModelOptions { joint_order: Some(vec!["j2".into(), "j1".into()]), ..Default::default() });
    let p = pose(&m, &[0.0, 1.0], "tool"); // j2 = 0, j1 = 1
    assert!((p.translation.vector - Vector3::new(1.5 * 1f64.cos(), 1.5 * 1f64.sin(), 0.0)).norm() < 1e-14);
    let err = KinematicModel::from_urdf(
        &Urdf::parse(PLANAR).unwrap(),
        &ModelOptions { joint_order: Some(vec!["j1".into()]), ..Default::default() },
    )
    .unwrap_err();
    assert!(err.to_string().contains("each active joint once"), "{err}");
}

#[test]
fn bad_configurations_are_rejected_with_names() {
    let m = model(&ModelOptions::default());
    let mut out = Vec::new();
    let e = m.forward_kinematics(&[0.0], &mut out).unwrap_err();
    assert!(matches!(e, Error::Shape { expected: 2, got: 1, .. }), "{e}");
    let e = m.forward_kinematics(&[0.0, f64::NAN], &mut out).unwrap_err();
    assert!(matches!(e, Error::NonFinite { index: 1, .. }), "{e}");
    let fb = model(&ModelOptions { floating_base: true, ..Default::default() });
    let e = fb.forward_kinematics(&[0.0; 9], &mut out).unwrap_err();
    assert!(e.to_string().contains("quaternion"), "{e}");
    let e = m.link_index("nope").unwrap_err();
    assert!(e.to_string().contains("known: base"), "{e}");
}

#[test]
fn malformed_urdfs_get_clear_errors() {
    let e = Urdf::parse("<robot><link name='a'>").unwrap_err();
    assert!(e.to_string().starts_with("cannot parse URDF"), "{e}");
    let e = Urdf::parse("<model/>").unwrap_err();
    assert!(e.to_string().contains("not <robot>"), "{e}");
    let e = Urdf::parse(r#"<robot><link name="a"/><link name="b"/>
        <joint name="j" type="revolute"><parent link="a"/><child link="b"/>
        <origin xyz="1 2"/></joint></robot>"#)
        .unwrap_err();
    assert!(e.to_string().contains("expected 3 finite numbers"), "{e}");
    let two_roots = Urdf::parse(r#"<robot><link name="a"/><link name="b"/></robot>"#).unwrap();
    let e = KinematicModel::from_urdf(&two_roots, &ModelOptions::default()).unwrap_err();
    assert!(e.to_string().contains("one root link"), "{e}");
    let dangling = Urdf::parse(r#"<robot><link name="a"/>
        <joint name="j" type="fixed"><parent link="a"/><child link="zz"/></joint></robot>"#)
        .unwrap();
    let e = KinematicModel::from_urdf(&dangling, &ModelOptions::default()).unwrap_err();
    assert!(e.to_string().contains("unknown child link 'zz'"), "{e}");
    let e = Urdf::from_file("/nonexistent/robot.urdf").unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
    let locked = HashMap::from([("nope".to_string(), 0.0)]);
    let e = KinematicModel::from_urdf(&Urdf::parse(PLANAR).unwrap(), &ModelOptions { locked_joints: locked, ..Default::default() })
        .unwrap_err();
    assert!(e.to_string().contains("unknown locked joint 'nope'"), "{e}");
}

#[test]
fn rpy_follows_the_urdf_convention() {
    // R = Rz(yaw) Ry(pitch) Rx(roll)
    let (r, p, y) = (0.3, -0.7, 1.1);
    let q = genplan_core::urdf::rpy_to_rotation(r, p, y);
    let expected = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), y)
        * nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), p)
        * nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), r);
    assert!((q.to_rotation_matrix().matrix() - expected.matrix()).amax() < 1e-15);
}

#[test]
fn a_prefix_of_the_joints_places_the_links_asked_for() {
    for floating_base in [false, true] {
        let m = model(&ModelOptions { floating_base, ..Default::default() });
        let q: Vec<f64> = if floating_base { vec![0.1, -0.2, 0.3, 0.1, 0.2, 0.3, 0.9, 0.4, -0.7] } else { vec![0.4, -0.7] };
        let mut all = Vec::new();
        m.forward_kinematics(&q, &mut all).unwrap();
        let (base, l1, l2, tool) = ["base", "l1", "l2", "tool"].map(|n| m.link_index(n).unwrap()).into();
        assert_eq!(m.joints_placing(&[]), 0);
        assert_eq!(m.joints_placing(&[base]), 0);
        assert_eq!(m.joints_placing(&[tool]), m.joints.len());
        for links in [vec![base], vec![l1], vec![l2], vec![l1, tool], vec![tool, base]] {
            let k = m.joints_placing(&links);
            let mut some = Vec::new();
            m.forward_kinematics_prefix(&q, &mut some, k);
            assert_eq!(some.len(), all.len());
            for &l in &links {
                assert_eq!(some[l], all[l], "link {l} with {k} joints");
            }
        }
    }
}

/// j2 follows j1 (q_j2 = -2 q_j1 + 0.1); j3 moves on its own; j4 (prismatic) follows j3.
const MIMIC: &str = r#"<robot name="mimic">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/>
  <link name="l4"><inertial><origin xyz="0.1 0.02 0"/><mass value="2"/><inertia ixx="0.1" iyy="0.1" izz="0.1"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.3"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3"/><mimic joint="j1" multiplier="-2" offset="0.1"/></joint>
  <joint name="j3" type="prismatic"><parent link="l2"/><child link="l3"/><origin xyz="0.3 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.2"/></joint>
  <joint name="j4" type="prismatic"><parent link="l3"/><child link="l4"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="0.5"/><mimic joint="j3" multiplier="3"/></joint>
</robot>"#;

fn mimic_model(locked: &[(&str, f64)]) -> genplan_core::Result<KinematicModel> {
    let locked = locked.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    KinematicModel::from_urdf(&Urdf::parse(MIMIC).unwrap(), &ModelOptions { locked_joints: locked, ..Default::default() })
}

/// URDF `<mimic>`: the joint is no coordinate of its own and follows its master, in the poses,
/// the Jacobians (against finite differences) and the centre of mass; integrate and difference
/// move the masters only; locking a master locks its mimics; what cannot be followed is refused.
#[test]
fn integrity_5_mimic_joints_follow_their_master() {
    let m = mimic_model(&[]).unwrap();
    assert_eq!((m.nq, m.nv), (2, 2));
    assert_eq!(m.active_joints, vec!["j1", "j3"]);
    for &(a, d) in &[(0.0, 0.0), (0.7, 0.1), (-1.0, 0.2)] {
        let l2 = pose(&m, &[a, d], "l2");
        let r = nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), a)
            * nalgebra::UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -2.0 * a + 0.1);
        assert!(l2.rotation.angle_to(&r) < 1e-14, "{a}");
        let l4 = pose(&m, &[a, d], "l4");
        let expected = l2.translation.vector + r * Vector3::new(0.3 + d, 0.0, 3.0 * d);
        assert!((l4.translation.vector - expected).norm() < 1e-14, "{a} {d}");
    }
    // Jacobians: finite differences of the poses along each coordinate
    let q = [0.4, 0.05];
    let mut poses = Vec::new();
    m.forward_kinematics(&q, &mut poses).unwrap();
    let l4 = m.link_index("l4").unwrap();
    let mut jac = nalgebra::DMatrix::zeros(6, 2);
    m.frame_jacobian_local(&poses, l4, &mut jac);
    let mut jcom = nalgebra::DMatrix::zeros(3, 2);
    let com = m.center_of_mass(&poses, Some(&mut jcom));
    let h = 1e-7;
    for k in 0..2 {
        let mut dq = [0.0; 2];
        dq[k] = h;
        let mut qh = [0.0; 2];
        m.integrate(&q, &dq, &mut qh);
        let mut ph = Vec::new();
        m.forward_kinematics(&qh, &mut ph).unwrap();
        let lin = poses[l4].rotation.inverse() * (ph[l4].translation.vector - poses[l4].translation.vector) / h;
        let ang = (poses[l4].rotation.inverse() * ph[l4].rotation).scaled_axis() / h;
        for i in 0..3 {
            assert!((jac[(i, k)] - lin[i]).abs() < 1e-6, "linear {i} {k}: {} vs {}", jac[(i, k)], lin[i]);
            assert!((jac[(i + 3, k)] - ang[i]).abs() < 1e-6, "angular {i} {k}");
        }
        let dcom = (m.center_of_mass(&ph, None) - com) / h;
        for i in 0..3 {
            assert!((jcom[(i, k)] - dcom[i]).abs() < 1e-6, "com {i} {k}");
        }
    }
    let (mut back, mut v) = ([0.0; 2], [0.0; 2]);
    m.difference(&q, &[0.5, 0.1], &mut v);
    m.integrate(&q, &v, &mut back);
    assert!((back[0] - 0.5).abs() < 1e-15 && (back[1] - 0.1).abs() < 1e-15, "{back:?}");

    // a locked master locks its mimics at the values they follow
    let locked = mimic_model(&[("j1", 0.5)]).unwrap();
    assert_eq!(locked.active_joints, vec!["j3"]);
    assert_eq!(locked.locked, vec![("j1".to_string(), 0.5), ("j2".to_string(), -0.9)]);
    let a = pose(&locked, &[0.1], "l4");
    let b = pose(&m, &[0.5, 0.1], "l4");
    assert!((a.translation.vector - b.translation.vector).norm() < 1e-14);
    assert!(mimic_model(&[("j1", 0.5), ("j2", -0.9)]).is_ok());
    for (lock, problem) in [
        (vec![("j2", 0.3)], "locked joint 'j2' mimics 'j1', which is not locked: lock 'j1'"),
        (vec![("j1", 0.5), ("j2", 0.3)], "locked joint 'j2' at 0.3, but it follows 'j1' (0.5 * -2 + 0.1 = -0.9)"),
        (vec![("j1", 1.5)], "locked joint 'j1' at 1.5 is outside its limits [-1, 1]"),
    ] {
        let e = mimic_model(&lock).unwrap_err().to_string();
        assert!(e.contains(problem), "{lock:?}: {e}");
    }
    // mimics genplan (and Pinocchio) cannot follow
    for (mimic, problem) in [
        (r#"<mimic joint="j3"/>"#, "joint 'j2' mimics 'j3', which comes after it in the tree"),
        (r#"<mimic joint="j2"/>"#, "joint 'j2' mimics itself"),
        (r#"<mimic joint="zz"/>"#, "joint 'j2' mimics 'zz', which is not a joint of the URDF (known: j1, j2, j3, j4)"),
    ] {
        let text = MIMIC.replace(r#"<mimic joint="j1" multiplier="-2" offset="0.1"/>"#, mimic);
        let e = KinematicModel::from_urdf(&Urdf::parse(&text).unwrap(), &ModelOptions::default()).unwrap_err().to_string();
        assert!(e.contains(problem), "{mimic}: {e}");
    }
    // locked, a mimic genplan cannot follow is held like any locked joint, within its limits
    let unknown = Urdf::parse(&MIMIC.replace(r#"<mimic joint="j1" multiplier="-2" offset="0.1"/>"#, r#"<mimic joint="zz"/>"#)).unwrap();
    let hold = |v: f64| ModelOptions { locked_joints: HashMap::from([("j2".to_string(), v)]), ..Default::default() };
    let held = KinematicModel::from_urdf(&unknown, &hold(0.3)).unwrap();
    assert_eq!((held.active_joints.clone(), held.locked.clone()), (vec!["j1".to_string(), "j3".to_string()], vec![("j2".to_string(), 0.3)]));
    let e = KinematicModel::from_urdf(&unknown, &hold(5.0)).unwrap_err().to_string();
    assert_eq!(e, "locked joint 'j2' at 5 is outside its limits [-3, 3]");
    let chain = MIMIC.replace(r#"<mimic joint="j3" multiplier="3"/>"#, r#"<mimic joint="j2"/>"#);
    let e = KinematicModel::from_urdf(&Urdf::parse(&chain).unwrap(), &ModelOptions::default()).unwrap_err().to_string();
    assert!(e.contains("joint 'j4' mimics 'j2', which mimics 'j1' in turn"), "{e}");
    let continuous = MIMIC.replace(r#"<joint name="j2" type="revolute">"#, r#"<joint name="j2" type="continuous">"#);
    let e = KinematicModel::from_urdf(&Urdf::parse(&continuous).unwrap(), &ModelOptions::default()).unwrap_err().to_string();
    assert!(e.contains("joint 'j2' mimics 'j1' but is continuous"), "{e}");
    let e = Urdf::parse(&MIMIC.replace(r#"multiplier="-2""#, r#"multiplier="1e7""#)).unwrap_err().to_string();
    assert!(e.contains("joint 'j2': <mimic multiplier>: 1e7 is too large"), "{e}");
    // a fixed joint's <mimic> (Talos' grippers) means nothing
    let fixed = MIMIC.replace(r#"<joint name="j2" type="revolute">"#, r#"<joint name="j2" type="fixed">"#);
    assert_eq!(KinematicModel::from_urdf(&Urdf::parse(&fixed).unwrap(), &ModelOptions::default()).unwrap().nq, 2);
}

/// A locked joint outside its limits was accepted (a joint at 100 rad with limits +-2); now
/// refused, naming the joint, the value and the limits. At a limit it is accepted.
#[test]
fn integrity_5_a_locked_joint_outside_its_limits_is_refused() {
    let urdf = Urdf::parse(PLANAR).unwrap();
    let lock = |j: &str, v: f64| ModelOptions { locked_joints: HashMap::from([(j.to_string(), v)]), ..Default::default() };
    let e = KinematicModel::from_urdf(&urdf, &lock("j2", 100.0)).unwrap_err().to_string();
    assert_eq!(e, "locked joint 'j2' at 100 is outside its limits [-2, 2]");
    assert!(KinematicModel::from_urdf(&urdf, &lock("j2", -2.0)).is_ok());
    let e = KinematicModel::from_urdf(&urdf, &lock("tool_joint", 0.0)).unwrap_err().to_string();
    assert_eq!(e, "locked joint 'tool_joint' is a fixed joint: it does not move");
}

/// `KinematicModel::euclidean`: q is a vector space coordinate by coordinate for the planar arm
/// (its fixed tool no coordinate), the mimic arm (its mimics none) and a model with a locked
/// joint; not with a free-flyer or a continuous joint. Where it is, integrate and difference are
/// q + v and q1 - q0 bit for bit, and the planner's distance, interpolation and chart
/// (`planning/space.rs`, on whole slices there) are R^n's (`EuclideanSpace`, the trait's own
/// formulas) bit for bit; where it is not, the distance is still the norm of the difference.
#[test]
fn a_vector_space_of_coordinates_is_integrated_and_differenced_on_whole_slices() {
    use genplan_core::planning::{EuclideanSpace, Space};
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    let locked = model(&ModelOptions { locked_joints: HashMap::from([("j1".to_string(), 0.2)]), ..Default::default() });
    let continuous = PLANAR.replace(r#"<joint name="j2" type="revolute">"#, r#"<joint name="j2" type="continuous">"#);
    let continuous = KinematicModel::from_urdf(&Urdf::parse(&continuous).unwrap(), &ModelOptions::default()).unwrap();
    let flyer = model(&ModelOptions { floating_base: true, ..Default::default() });
    let mut rng = StdRng::seed_from_u64(3);
    let plain = model(&ModelOptions::default());
    let mimic = mimic_model(&[]).unwrap();
    let models = [(plain, true), (mimic, true), (locked, true), (continuous, false), (flyer, false)];
    for (m, euclidean) in models {
        assert_eq!(m.euclidean(), euclidean, "{:?}", m.active_joints);
        let mut draw = |n: usize| -> Vec<f64> { (0..n).map(|_| rng.random_range(-2.0..2.0)).collect() };
        for _ in 0..50 {
            let (mut q0, mut q1, v, t) = (draw(m.nq), draw(m.nq), draw(m.nv), draw(1)[0]);
            // valid configurations: a unit (cos, sin) pair, a unit base quaternion
            let fix = |q: &mut Vec<f64>| {
                let mut n = vec![0.0; m.nq];
                m.integrate(&q.clone(), &vec![0.0; m.nv], &mut n);
                *q = n;
            };
            if !euclidean {
                for q in [&mut q0, &mut q1] {
                    if m.floating_base {
                        let s = q[3..7].iter().map(|x| x * x).sum::<f64>().sqrt();
                        q[3..7].iter_mut().for_each(|x| *x /= s);
                    } else {
                        let a = q[1];
                        (q[1], q[2]) = (a.cos(), a.sin());
                    }
                    fix(q);
                }
            }
            let (mut d, mut out) = (vec![0.0; m.nv], vec![0.0; m.nq]);
            m.difference(&q0, &q1, &mut d);
            let norm = d.iter().map(|x| x * x).sum::<f64>().sqrt();
            assert_eq!(Space::distance(&m, &q0, &q1).to_bits(), norm.to_bits());
            if !euclidean {
                continue;
            }
            let r = EuclideanSpace(m.nq);
            let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&d), bits(&q0.iter().zip(&q1).map(|(a, b)| b - a).collect::<Vec<_>>()));
            m.integrate(&q0, &v, &mut out);
            assert_eq!(bits(&out), bits(&q0.iter().zip(&v).map(|(a, b)| a + b).collect::<Vec<_>>()));
            assert_eq!(Space::distance(&m, &q0, &q1).to_bits(), r.distance(&q0, &q1).to_bits());
            let mut expected = vec![0.0; m.nq];
            Space::interpolate(&m, &q0, &q1, t, &mut out);
            r.interpolate(&q0, &q1, t, &mut expected);
            assert_eq!(bits(&out), bits(&expected));
            Space::coordinates(&m, &q0, &mut out);
            assert_eq!(bits(&out), bits(&q0));
        }
    }
}
