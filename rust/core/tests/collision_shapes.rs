//! Cylinder, capsule and mesh obstacles (`CollisionWorld::add_cylinder`, `add_capsule`,
//! `add_mesh` in src/collision/world.rs): where they collide, their signed distances against
//! closed forms, the axis convention (local z, as in URDF), convex hulls of mesh files, and the
//! input checks.

use std::path::Path;

use genplan_core::collision::{CollisionWorld, MAX_OBSTACLE_EXTENT};
use genplan_core::error::Error;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};

/// Radius of the probe sphere the test robot carries.
const PROBE: f64 = 0.1;

#[path = "common/probe.rs"]
mod probe;
#[path = "common/temp_dir.rs"]
mod temp_dir;
use temp_dir::TempDir;

fn world() -> CollisionWorld {
    let mut w = probe::world();
    w.check_self = false;
    w
}

/// A pose from a translation and roll-pitch-yaw (URDF's convention).
fn pose(t: [f64; 3], rpy: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::new(t[0], t[1], t[2]), UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]))
}

/// Signed distance from a point to a solid cylinder along z (radius r, half height h), in its frame.
fn cylinder_sd(p: Vector3<f64>, r: f64, h: f64) -> f64 {
    let radial = (p.x * p.x + p.y * p.y).sqrt() - r;
    let axial = p.z.abs() - h;
    if radial <= 0.0 && axial <= 0.0 {
        radial.max(axial)
    } else {
        (radial.max(0.0).powi(2) + axial.max(0.0).powi(2)).sqrt()
    }
}

/// Signed distance from a point to a capsule along z (radius r, segment z in [-h, h]), in its frame.
fn capsule_sd(p: Vector3<f64>, r: f64, h: f64) -> f64 {
    let z = p.z.clamp(-h, h);
    (p - Vector3::new(0.0, 0.0, z)).norm() - r
}

/// Signed distance from a point to a box of half extents `e` centred at the origin, in its frame.
fn box_sd(p: Vector3<f64>, e: Vector3<f64>) -> f64 {
    let q = p.abs() - e;
    let outside = q.map(|v| v.max(0.0)).norm();
    outside + q.max().min(0.0)
}

/// Every probe position of a grid around `center`, with step `step` over +-`span`.
fn grid(center: [f64; 3], span: f64, step: f64) -> Vec<[f64; 3]> {
    let n = (span / step).round() as i32;
    let mut out = Vec::new();
    for i in -n..=n {
        for j in -n..=n {
            for k in -n..=n {
                out.push([
                    center[0] + i as f64 * step,
                    center[1] + j as f64 * step,
                    center[2] + k as f64 * step,
                ]);
            }
        }
    }
    out
}

/// On a grid of probe positions: in_collision agrees with the closed form (away from the
/// surface), with the exhaustive check everywhere, and the distance of separated probes matches
/// the closed form to `tol`.
fn check_against(w: &CollisionWorld, at: &Isometry3<f64>, center: [f64; 3], span: f64, sd: &dyn Fn(Vector3<f64>) -> f64, tol: f64) {
    let (mut hits, mut misses) = (0, 0);
    for q in grid(center, span, 0.07) {
        let local = at.inverse_transform_point(&q.into()).coords;
        let expected = sd(local) - PROBE;
        let hit = w.in_collision(&q).unwrap();
        // touching probes (distance 0 up to rounding) may go either way
        if expected.abs() > 1e-6 {
            assert_eq!(hit, w.in_collision_exhaustive(&q).unwrap(), "filtered and exhaustive disagree at {q:?}");
            assert_eq!(hit, expected < 0.0, "at {q:?}: signed distance {expected}");
        }
        if expected < 0.0 {
            hits += 1;
        } else {
            misses += 1;
            let d = w.min_distance(&q).unwrap();
            assert!((d - expected).abs() < tol, "at {q:?}: distance {d}, expected {expected}");
        }
    }
    assert!(hits > 20 && misses > 20, "the grid must straddle the obstacle ({hits} hits, {misses} misses)");
}

#[test]
fn cylinder_axis_is_local_z_and_distances_match_the_closed_form() {
    let (r, h) = (0.2, 0.6);
    let mut w = world();
    w.add_cylinder("post", r, h, Isometry3::translation(1.0, 0.0, 0.0)).unwrap();
    // along the axis (z) the cylinder reaches 0.6, sideways (x, y) only 0.2: parry's own axis (y)
    // would put the probe at y = 0.5 inside it
    assert!(w.in_collision(&[1.0, 0.0, 0.65]).unwrap());
    assert!(!w.in_collision(&[1.0, 0.5, 0.0]).unwrap());
    assert!((w.min_distance(&[1.0, 0.5, 0.0]).unwrap() - 0.2).abs() < 1e-9);
    assert!((w.min_distance(&[1.0, 0.0, 0.75]).unwrap() - 0.05).abs() < 1e-9);
    let at = Isometry3::translation(1.0, 0.0, 0.0);
    check_against(&w, &at, [1.0, 0.0, 0.0], 0.9, &|p| cylinder_sd(p, r, h), 1e-6);

    // tilted: pitch 90 deg turns the local z axis to world x
    let mut w = world();
    let at = pose([0.5, -0.3, 0.2], [0.0, std::f64::consts::FRAC_PI_2, 0.0]);
    w.add_cylinder("beam", r, h, at).unwrap();
    assert!(w.in_collision(&[0.5 + 0.65, -0.3, 0.2]).unwrap());
    assert!(!w.in_collision(&[0.5, -0.3, 0.2 + 0.35]).unwrap());
    check_against(&w, &at, [0.5, -0.3, 0.2], 0.9, &|p| cylinder_sd(p, r, h), 1e-6);

    // any orientation
    let mut w = world();
    let at = pose([0.1, 0.2, -0.1], [0.3, -0.7, 1.1]);
    w.add_cylinder("tilted", 0.3, 0.25, at).unwrap();
    check_against(&w, &at, [0.1, 0.2, -0.1], 0.7, &|p| cylinder_sd(p, 0.3, 0.25), 1e-6);
}

#[test]
fn capsule_axis_is_local_z_and_distances_match_the_closed_form() {
    let (r, h) = (0.15, 0.4);
    let mut w = world();
    w.add_capsule("rail", r, h, Isometry3::translation(0.0, 1.0, 0.0)).unwrap();
    // the end cap reaches z = 0.55; the probe touches it below z = 0.65
    assert!(w.in_collision(&[0.0, 1.0, 0.6]).unwrap());
    assert!(!w.in_collision(&[0.0, 1.0 + 0.3, 0.0]).unwrap());
    assert!((w.min_distance(&[0.0, 1.0, 0.7]).unwrap() - 0.05).abs() < 1e-9);
    // off the end cap, diagonally: |(0.2, 0.2)| - r - probe
    let d = w.min_distance(&[0.2, 1.0, 0.6]).unwrap();
    assert!((d - (0.08f64.sqrt() - r - PROBE)).abs() < 1e-9, "{d}");
    check_against(&w, &Isometry3::translation(0.0, 1.0, 0.0), [0.0, 1.0, 0.0], 0.8, &|p| capsule_sd(p, r, h), 1e-6);

    let mut w = world();
    let at = pose([-0.4, 0.3, 0.5], [1.2, 0.4, -0.9]);
    w.add_capsule("tilted", r, h, at).unwrap();
    check_against(&w, &at, [-0.4, 0.3, 0.5], 0.8, &|p| capsule_sd(p, r, h), 1e-6);
}


/// An OBJ cube of side 1 centred at the origin.
const CUBE_OBJ: &str = "v -0.5 -0.5 -0.5\nv 0.5 -0.5 -0.5\nv 0.5 0.5 -0.5\nv -0.5 0.5 -0.5\n\
v -0.5 -0.5 0.5\nv 0.5 -0.5 0.5\nv 0.5 0.5 0.5\nv -0.5 0.5 0.5\n\
f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n";

fn ascii_stl(tris: &[[[f64; 3]; 3]]) -> String {
    let mut s = String::from("solid t\n");
    for t in tris {
        s += "facet normal 0 0 0\nouter loop\n";
        for v in t {
            s += &format!("vertex {} {} {}\n", v[0], v[1], v[2]);
        }
        s += "endloop\nendfacet\n";
    }
    s + "endsolid t\n"
}

#[test]
fn mesh_obstacles_are_scaled_posed_convex_hulls() {
    let dir = TempDir::new("mesh-obstacle");
    let cube = dir.write("cube.obj", CUBE_OBJ);
    let mut w = world();
    // scaled to half extents (1, 0.5, 0.25), turned 90 deg about z: the long side along world y
    let at = pose([0.0, 0.0, 1.0], [0.0, 0.0, std::f64::consts::FRAC_PI_2]);
    w.add_mesh("crate", &cube, [2.0, 1.0, 0.5], at).unwrap();
    assert!(w.in_collision(&[0.0, 1.05, 1.0]).unwrap());
    assert!(!w.in_collision(&[1.05, 0.0, 1.0]).unwrap());
    assert!((w.min_distance(&[0.0, 0.0, 1.4]).unwrap() - 0.05).abs() < 1e-9);
    let e = Vector3::new(1.0, 0.5, 0.25);
    check_against(&w, &at, [0.0, 0.0, 1.0], 1.3, &|p| box_sd(p, e), 1e-6);

    // a concave mesh (two separate tetrahedra far apart) is filled in: the gap between them collides
    let tet = |x: f64| [[x, 0.0, 0.0], [x + 0.2, 0.0, 0.0], [x, 0.2, 0.0], [x, 0.0, 0.2]];
    let faces = |v: [[f64; 3]; 4]| [[v[0], v[2], v[1]], [v[0], v[1], v[3]], [v[0], v[3], v[2]], [v[1], v[2], v[3]]];
    let mut tris = faces(tet(-1.0)).to_vec();
    tris.extend(faces(tet(1.0)));
    let pair = dir.write("pair.stl", &ascii_stl(&tris));
    let mut w = world();
    w.add_mesh("pair", &pair, [1.0; 3], Isometry3::identity()).unwrap();
    assert!(w.in_collision(&[0.0, 0.05, 0.05]).unwrap(), "the hull spans the gap between the pieces");
    assert!(!w.in_collision(&[0.0, 0.5, 0.5]).unwrap());
}

#[test]
fn mesh_errors_name_the_file() {
    let dir = TempDir::new("mesh-errors");
    let mut w = world();
    let missing = dir.0.join("missing.stl");
    let e = w.add_mesh("m", &missing, [1.0; 3], Isometry3::identity()).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e}");
    assert!(e.to_string().contains("missing.stl"), "{e}");

    let broken = dir.write("broken.obj", "v 0 0 0\nf 1 2 3\n");
    let e = w.add_mesh("m", &broken, [1.0; 3], Isometry3::identity()).unwrap_err();
    assert!(matches!(e, Error::Mesh { .. }), "{e}");
    assert!(e.to_string().contains("broken.obj"), "{e}");

    let flat = dir.write("flat.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n");
    // a flat mesh is a plate of zero thickness: accepted, and a probe through it collides
    w.add_mesh("flat", &flat, [1.0; 3], Isometry3::identity()).unwrap();
    assert!(w.in_collision(&[0.5, 0.5, 0.05]).unwrap());
    assert!((w.min_distance(&[0.5, 0.5, 0.05]).unwrap() + 0.05).abs() < 1e-9);
    assert!((w.min_distance(&[0.5, 0.5, 0.15]).unwrap() - 0.05).abs() < 1e-9);
    w.remove_obstacle("flat").unwrap();

    let unknown = dir.write("cube.ply", "ply\n");
    let e = w.add_mesh("m", &unknown, [1.0; 3], Isometry3::identity()).unwrap_err();
    assert!(e.to_string().contains("cube.ply"), "{e}");

    let cube = dir.write("cube.obj", CUBE_OBJ);
    let e = w.add_mesh("m", &cube, [2e6, 1.0, 1.0], Isometry3::identity()).unwrap_err();
    assert!(e.to_string().contains("scale"), "{e}");
    let e = w.add_mesh("m", &cube, [0.0, 1.0, 1.0], Isometry3::identity()).unwrap_err();
    assert!(e.to_string().contains("scale"), "{e}");
    // scale within bounds, but the scaled vertices beyond them
    let big = dir.write("big.obj", &CUBE_OBJ.replace("0.5", "2"));
    let e = w.add_mesh("m", &big, [MAX_OBSTACLE_EXTENT, 1.0, 1.0], Isometry3::identity()).unwrap_err();
    assert!(e.to_string().contains("beyond"), "{e}");
    assert!(w.obstacles.is_empty(), "no failed call added anything");
}

#[test]
fn bad_sizes_poses_and_duplicate_names_are_refused() {
    let dir = TempDir::new("shape-checks");
    let cube = dir.write("cube.obj", CUBE_OBJ);
    let mut w = world();
    let id = Isometry3::identity();
    assert!(matches!(w.add_cylinder("c", f64::NAN, 0.1, id).unwrap_err(), Error::NonFinite { .. }));
    assert!(matches!(w.add_capsule("c", 0.1, f64::INFINITY, id).unwrap_err(), Error::NonFinite { .. }));
    for (r, h) in [(0.0, 0.1), (0.1, -0.1), (2e6, 0.1), (0.1, 2e6)] {
        let e = w.add_cylinder("c", r, h, id).unwrap_err();
        assert!(e.to_string().contains("must be positive and at most"), "{e}");
        let e = w.add_capsule("c", r, h, id).unwrap_err();
        assert!(e.to_string().contains("must be positive and at most"), "{e}");
    }
    let far = Isometry3::translation(2e6, 0.0, 0.0);
    assert!(w.add_cylinder("c", 0.1, 0.1, far).unwrap_err().to_string().contains("within"));
    assert!(w.add_capsule("c", 0.1, 0.1, far).unwrap_err().to_string().contains("within"));
    assert!(w.add_mesh("c", &cube, [1.0; 3], far).unwrap_err().to_string().contains("within"));
    let skewed = Isometry3::from_parts(Translation3::identity(), UnitQuaternion::new_unchecked(Quaternion::new(2.0, 0.0, 0.0, 0.0)));
    for e in [
        w.add_cylinder("c", 0.1, 0.1, skewed).unwrap_err(),
        w.add_capsule("c", 0.1, 0.1, skewed).unwrap_err(),
        w.add_mesh("c", &cube, [1.0; 3], skewed).unwrap_err(),
    ] {
        assert!(e.to_string().contains("not a unit quaternion"), "{e}");
    }
    assert!(w.obstacles.is_empty());

    w.add_cylinder("a", 0.1, 0.1, id).unwrap();
    w.add_capsule("b", 0.1, 0.1, id).unwrap();
    w.add_mesh("m", Path::new(&cube), [1.0; 3], id).unwrap();
    for e in [
        w.add_cylinder("b", 0.1, 0.1, id).unwrap_err(),
        w.add_capsule("m", 0.1, 0.1, id).unwrap_err(),
        w.add_mesh("a", &cube, [1.0; 3], id).unwrap_err(),
        w.add_box("m", [0.1; 3], id).unwrap_err(),
    ] {
        assert!(e.to_string().contains("already exists"), "{e}");
    }
    assert_eq!(w.obstacles.iter().map(|o| o.name.as_str()).collect::<Vec<_>>(), ["a", "b", "m"]);
    w.remove_obstacle("a").unwrap();
    assert_eq!(w.obstacles.iter().map(|o| o.name.as_str()).collect::<Vec<_>>(), ["b", "m"]);
}
