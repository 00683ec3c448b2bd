//! Collision world on small hand-written robots: self-collision filtering, obstacles,
//! signed distances against closed forms, STL convex hulls.

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;

use genplan_core::collision::CollisionWorld;
use genplan_core::kinematics::{KinematicModel, ModelOptions};
use genplan_core::srdf::Srdf;
use genplan_core::urdf::Urdf;
use nalgebra::Isometry3;

/// A prismatic slider along x carrying a sphere (r = 0.1), and a fixed sphere (r = 0.1) at the
/// base's origin; a second revolute link far away with a box.
const SLIDER: &str = r#"<robot name="slider">
  <link name="base"><collision><geometry><sphere radius="0.1"/></geometry></collision></link>
  <link name="cart"><collision><origin xyz="0 0 0"/><geometry><sphere radius="0.1"/></geometry></collision></link>
  <link name="arm"><collision><origin xyz="0 0 5"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
  <joint name="slide" type="prismatic">
    <parent link="base"/><child link="cart"/><axis xyz="1 0 0"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/>
  </joint>
  <joint name="turn" type="revolute">
    <parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/>
  </joint>
</robot>"#;

fn world(srdf: Option<&str>) -> CollisionWorld {
    let urdf = Urdf::parse(SLIDER).unwrap();
    let model = Arc::new(KinematicModel::from_urdf(&urdf, &ModelOptions::default()).unwrap());
    let srdf = srdf.map(|s| Srdf::parse(s).unwrap());
    CollisionWorld::from_urdf(model, &urdf, &[], srdf.as_ref()).unwrap()
}

#[test]
fn self_collision_and_signed_distance_of_two_spheres() {
    let w = world(None);
    assert_eq!(w.geometries().len(), 3);
    assert_eq!(w.self_pairs().len(), 3);
    // cart at x: distance between sphere centres is |x|, so signed distance |x| - 0.2
    for &x in &[0.05, 0.15, 0.19, 0.21, 0.5, 1.5] {
        let q = [x, 0.0];
        assert_eq!(w.in_collision(&q).unwrap(), x < 0.2, "x = {x}");
        let d = w.min_distance(&q).unwrap();
        assert!((d - (x - 0.2)).abs() < 1e-9, "x = {x}: {d}");
    }
    let pairs = w.close_pairs(&[0.1, 0.0], 0.0).unwrap();
    assert_eq!(pairs.len(), 1);
    assert_eq!((pairs[0].a.as_str(), pairs[0].b.as_str()), ("base_0", "cart_0"));
    assert!((pairs[0].distance + 0.1).abs() < 1e-9);
}

#[test]
fn srdf_disabled_pairs_are_not_checked() {
    let w = world(Some(
        r#"<robot name="slider"><disable_collisions link1="cart" link2="base" reason="Adjacent"/>
           <disable_collisions link1="cart" link2="not_a_link" reason="Never"/></robot>"#,
    ));
    assert_eq!(w.self_pairs().len(), 2);
    assert!(!w.in_collision(&[0.0, 0.0]).unwrap());
}

#[test]
fn obstacles_box_sphere_halfspace() {
    let mut w = world(None);
    w.check_self = false;
    // box of half extents 0.1 centred at (1, 0, 0): cart sphere touches when x >= 0.8
    w.add_box("crate", [0.1, 0.1, 0.1], Isometry3::translation(1.0, 0.0, 0.0)).unwrap();
    assert!(!w.in_collision(&[0.7, 0.0]).unwrap());
    assert!((w.min_distance(&[0.7, 0.0]).unwrap() - 0.1).abs() < 1e-9);
    assert!(w.in_collision(&[0.85, 0.0]).unwrap());
    assert!((w.min_distance(&[0.85, 0.0]).unwrap() + 0.05).abs() < 1e-9);
    assert!(w.add_box("crate", [0.1, 0.1, 0.1], Isometry3::identity()).is_err());
    assert!(w.add_box("flat", [0.0, 0.1, 0.1], Isometry3::identity()).is_err());
    w.remove_obstacle("crate").unwrap();
    assert!(w.remove_obstacle("crate").unwrap_err().to_string().contains("unknown obstacle"));
    // floor: everything below z = -0.05 -> the base spheres (radius 0.1 at z = 0) dip into it
    w.add_halfspace("floor", [0.0, 0.0, 1.0], -0.05).unwrap();
    assert!(w.in_collision(&[0.0, 0.0]).unwrap());
    let d = w.min_distance(&[1.0, 0.0]).unwrap();
    assert!((d + 0.05).abs() < 1e-9, "{d}");
    w.remove_obstacle("floor").unwrap();
    // the arm's box sits at z = 5 on a radius 0 circle: a sphere there collides at any angle
    w.add_sphere("ball", 0.2, [0.0, 0.0, 5.0]).unwrap();
    assert!(w.in_collision(&[1.5, 1.3]).unwrap());
    assert!(w.add_sphere("bad", f64::NAN, [0.0; 3]).is_err());
}

fn cube_stl(path: &PathBuf, half: f32) {
    let v = |x: f32, y: f32, z: f32| stl_io::Vector::new([x * half, y * half, z * half]);
    let corners = [
        v(-1., -1., -1.), v(1., -1., -1.), v(1., 1., -1.), v(-1., 1., -1.),
        v(-1., -1., 1.), v(1., -1., 1.), v(1., 1., 1.), v(-1., 1., 1.),
    ];
    let faces = [
        [0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
        [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7],
    ];
    let tris: Vec<stl_io::Triangle> = faces
        .iter()
        .map(|f| stl_io::Triangle {
            normal: stl_io::Vector::new([0.0, 0.0, 0.0]),
            vertices: [corners[f[0]], corners[f[1]], corners[f[2]]],
        })
        .collect();
    let mut file = std::fs::File::create(path).unwrap();
    stl_io::write_stl(&mut file, tris.iter()).unwrap();
    file.flush().unwrap();
}

#[test]
fn stl_meshes_become_convex_hulls_and_bad_meshes_are_reported() {
    let dir = std::env::temp_dir().join(format!("genplan-stl-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("pkg/meshes")).unwrap();
    cube_stl(&dir.join("pkg/meshes/cube.stl"), 0.5);
    std::fs::write(dir.join("pkg/meshes/broken.stl"), b"solid nothing here").unwrap();
    let text = |mesh: &str| {
        format!(
            r#"<robot name="m"><link name="a"><collision><geometry>
               <mesh filename="package://pkg/meshes/{mesh}" scale="2 1 1"/></geometry></collision></link></robot>"#
        )
    };
    let urdf = Urdf::parse(&text("cube.stl")).unwrap();
    let model = Arc::new(KinematicModel::from_urdf(&urdf, &ModelOptions::default()).unwrap());
    let mut w = CollisionWorld::from_urdf(model.clone(), &urdf, &[dir.clone()], None).unwrap();
    // the hull spans x in [-1, 1] (scaled by 2), y and z in [-0.5, 0.5]
    w.add_sphere("probe", 0.1, [1.05, 0.0, 0.0]).unwrap();
    assert!(w.in_collision(&[]).unwrap());
    assert!((w.min_distance(&[]).unwrap() + 0.05).abs() < 1e-9);
    w.remove_obstacle("probe").unwrap();
    w.add_sphere("probe", 0.1, [0.0, 0.7, 0.0]).unwrap();
    assert!((w.min_distance(&[]).unwrap() - 0.1).abs() < 1e-9);

    let missing = CollisionWorld::from_urdf(model.clone(), &Urdf::parse(&text("none.stl")).unwrap(), &[dir.clone()], None);
    assert!(missing.err().unwrap().to_string().contains("not found in package dirs"));
    let broken = CollisionWorld::from_urdf(model, &Urdf::parse(&text("broken.stl")).unwrap(), &[dir.clone()], None);
    assert!(broken.err().unwrap().to_string().contains("bad mesh"));
    std::fs::remove_dir_all(dir).ok();
}
