//! The shipped presets load from example-robot-data (found through GENPLAN_ROBOTS_DIR or the
//! project's .venv). Ignored by a bare `cargo test`; `scripts/test` runs them.

use genplan_core::robot::{find_robots_dir, RobotSpec, ROBOT_NAMES};

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn presets_load_and_default_postures_are_collision_free() {
    let root = find_robots_dir().unwrap();
    for name in ROBOT_NAMES {
        let spec = RobotSpec::by_name(name).unwrap();
        let (model, world) = spec.load(&root).unwrap();
        let expected = match name {
            "panda" => (7, 7),
            "talos" => (35, 34),
            _ => (6, 6),
        };
        assert_eq!((model.nq, model.nv), expected, "{name}");
        assert!(!world.geometries.is_empty() && !world.self_pairs.is_empty(), "{name}");
        for (_, link) in spec.frames {
            model.link_index(link).unwrap();
        }
        // limits midpoint (base at 1 m) is a configuration; FK must run on it
        let mut q: Vec<f64> = model.lower.iter().zip(&model.upper).map(|(l, u)| if l.is_finite() { 0.5 * (l + u) } else { 0.0 }).collect();
        if model.floating_base {
            q[2] = 1.0;
            q[6] = 1.0;
        }
        world.min_distance(&q).unwrap();
    }
}

#[test]
fn unknown_robot_lists_known_ones() {
    let e = RobotSpec::by_name("atlas").unwrap_err().to_string();
    assert!(e.contains("unknown robot 'atlas'") && e.contains("panda, talos, ur5"), "{e}");
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn bounding_volume_filters_never_change_a_collision_verdict() {
    use nalgebra::Isometry3;
    use rand::{Rng, SeedableRng};

    let root = find_robots_dir().unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    for name in ROBOT_NAMES {
        let (model, mut world) = RobotSpec::by_name(name).unwrap().load(&root).unwrap();
        world.add_box("table", [0.25, 0.4, 0.03], Isometry3::translation(0.5, 0.0, 0.6)).unwrap();
        world.add_sphere("ball", 0.1, [0.3, -0.3, 1.0]).unwrap();
        let (mut hits, n) = (0, 1000);
        for _ in 0..n {
            let mut q: Vec<f64> =
                model.lower.iter().zip(&model.upper).map(|(l, u)| if l.is_finite() { rng.random_range(*l..=*u) } else { 0.0 }).collect();
            if model.floating_base {
                q[2] = 1.0;
                q[6] = 1.0;
            }
            let fast = world.in_collision(&q).unwrap();
            assert_eq!(fast, world.in_collision_exhaustive(&q).unwrap(), "{name} {q:?}");
            hits += fast as usize;
        }
        assert!(hits > 0 && hits < n, "{name}: {hits} of {n} in collision");
    }
}
