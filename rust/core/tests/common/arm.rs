//! The test arm shared by `tests/projection.rs` and `tests/projection_custom.rs` (included as
//! `mod arm` with a `#[path]`): a spatial 3R arm with masses, plus a prismatic joint.

use std::sync::Arc;

use genplan_core::kinematics::{KinematicModel, ModelOptions};
use genplan_core::urdf::Urdf;

/// Its URDF.
pub const ARM: &str = r#"<robot name="arm">
  <link name="base"><inertial><mass value="2"/><origin xyz="0 0 0.05"/></inertial></link>
  <link name="l1"><inertial><mass value="1"/><origin xyz="0 0 0.2"/></inertial></link>
  <link name="l2"><inertial><mass value="0.8"/><origin xyz="0.2 0 0"/></inertial></link>
  <link name="l3"><inertial><mass value="0.5"/><origin xyz="0.1 0.02 0"/></inertial></link>
  <link name="tool"><inertial><mass value="0.2"/><origin xyz="0 0 0.03"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.4" rpy="1.5707963 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0.4 0 0"/>
    <axis xyz="0.3 0.4 0.866"/><limit lower="-2.5" upper="2.5" effort="1" velocity="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="l3"/><child link="tool"/><origin xyz="0.2 0 0" rpy="0 1.5707963 0"/>
    <axis xyz="0 0 1"/><limit lower="0" upper="0.1" effort="1" velocity="1"/></joint>
</robot>"#;

/// Its kinematic model, on a free-flyer base when `floating`.
pub fn model(floating: bool) -> Arc<KinematicModel> {
    let urdf = Urdf::parse(ARM).unwrap();
    Arc::new(KinematicModel::from_urdf(&urdf, &ModelOptions { floating_base: floating, ..Default::default() }).unwrap())
}

