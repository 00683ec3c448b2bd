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
