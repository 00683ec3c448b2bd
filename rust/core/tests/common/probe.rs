//! A test robot whose collision geometry is one sphere moved by three prismatic joints, shared by
//! the collision tests (`tests/collision_shapes.rs`, `tests/spheres.rs`), each including it as
//! `mod probe` with a `#[path]`.

/// Three prismatic joints (x, y, z) carrying a sphere of radius 0.1: q is the sphere's centre.
pub const XYZ: &str = r#"<robot name="xyz">
  <link name="base"/>
  <link name="lx"/>
  <link name="ly"/>
  <link name="probe"><collision><geometry><sphere radius="0.1"/></geometry></collision></link>
  <joint name="x" type="prismatic"><parent link="base"/><child link="lx"/><axis xyz="1 0 0"/>
    <limit lower="-5" upper="5" effort="1" velocity="1"/></joint>
  <joint name="y" type="prismatic"><parent link="lx"/><child link="ly"/><axis xyz="0 1 0"/>
    <limit lower="-5" upper="5" effort="1" velocity="1"/></joint>
  <joint name="z" type="prismatic"><parent link="ly"/><child link="probe"/><axis xyz="0 0 1"/>
    <limit lower="-5" upper="5" effort="1" velocity="1"/></joint>
</robot>"#;

/// A collision world of the probe robot, no obstacles (its one collision link has no self pair).
pub fn world() -> genplan_core::collision::CollisionWorld {
    let urdf = genplan_core::urdf::Urdf::parse(XYZ).unwrap();
    let options = genplan_core::kinematics::ModelOptions::default();
    let model = std::sync::Arc::new(genplan_core::kinematics::KinematicModel::from_urdf(&urdf, &options).unwrap());
    genplan_core::collision::CollisionWorld::from_urdf(model, &urdf, &[], None).unwrap()
}
