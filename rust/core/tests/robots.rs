//! Robot descriptions: the shipped presets (robot files under python/genplan/presets/robots)
//! load from example-robot-data (found through GENPLAN_ROBOTS_DIR or the project's .venv;
//! ignored by a bare `cargo test`, `scripts/test` runs them), and robot files are read strictly.

use std::path::PathBuf;

use genplan_core::robot::{preset, preset_names, resolve_path, RobotDescription, LockedJoints};
use genplan_core::Error;

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn presets_load_and_default_postures_are_collision_free() {
    let names = preset_names();
    for must in ["panda", "talos", "ur5", "ur10", "kinova"] {
        assert!(names.iter().any(|n| n == must), "{must} not in {names:?}");
    }
    for name in &names {
        let d = preset(name).unwrap();
        assert_eq!(&d.name, name);
        let (model, world) = d.load().unwrap();
        let expected = match name.as_str() {
            "panda" => Some((7, 7)),
            "talos" => Some((35, 34)),
            "kinova" => Some((9, 6)),
            n if n.starts_with("ur") => Some((6, 6)),
            _ => None,
        };
        if let Some(e) = expected {
            assert_eq!((model.nq, model.nv), e, "{name}");
        }
        assert!(!world.geometries().is_empty() && !world.self_pairs().is_empty(), "{name}");
        for (_, link) in &d.frames {
            model.link_index(link).unwrap();
        }
        // limits midpoint (base at 1 m) is a configuration; FK must run on it
        let mut q: Vec<f64> =
            model.lower.iter().zip(&model.upper).map(|(l, u)| if l.is_finite() { 0.5 * (l + u) } else { 0.0 }).collect();
        if model.floating_base {
            q[2] = 1.0;
            q[6] = 1.0;
        }
        world.min_distance(&q).unwrap();
    }
}

#[test]
fn unknown_preset_lists_known_ones() {
    let e = preset("atlas").unwrap_err().to_string();
    assert!(e.contains("unknown robot 'atlas'") && e.contains("panda") && e.contains("talos"), "{e}");
}

fn temp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("genplan-robots-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

const URDF: &str = r#"<robot name="two">
  <link name="base"/><link name="l1"/><link name="l2"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.5"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
</robot>"#;

fn write(dir: &std::path::Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_robot_file_resolves_paths_relative_to_itself_and_loads() {
    let d = temp_dir("ok");
    std::fs::create_dir_all(d.join("urdf")).unwrap();
    write(&d.join("urdf"), "two.urdf", URDF);
    let f = write(&d, "mine.toml", "urdf = \"urdf/two.urdf\"\nlocked_joints = { j2 = 0.25 }\n[frames]\ntip = \"l2\"\n");
    let r = RobotDescription::from_file(&f, &[]).unwrap();
    assert_eq!(r.name, "mine");
    assert!(r.urdf.ends_with("urdf/two.urdf") && r.urdf.is_absolute(), "{:?}", r.urdf);
    assert_eq!(r.collision_urdf, r.urdf);
    assert_eq!(r.srdf, None);
    assert_eq!(r.locked_joints, LockedJoints::Values(vec![("j2".into(), 0.25)]));
    assert_eq!(r.frames, vec![("tip".to_string(), "l2".to_string())]);
    let (model, _) = r.load().unwrap();
    assert_eq!(model.nq, 1);
}

#[test]
fn package_uris_resolve_against_the_package_folders_in_order() {
    let d = temp_dir("pkg");
    std::fs::create_dir_all(d.join("a/pkg")).unwrap();
    std::fs::create_dir_all(d.join("b/pkg")).unwrap();
    write(&d.join("b/pkg"), "x.urdf", URDF);
    let p = resolve_path("package://pkg/x.urdf", None, &[d.join("a"), d.join("b")]).unwrap();
    assert_eq!(p, d.join("b/pkg/x.urdf"));
    let e = resolve_path("package://pkg/y.urdf", None, &[d.join("a")]).unwrap_err().to_string();
    assert!(e.contains("package://pkg/y.urdf") && e.contains("searched"), "{e}");
}

#[test]
fn bad_robot_files_name_the_file_and_the_key() {
    let d = temp_dir("bad");
    write(&d, "two.urdf", URDF);
    let cases: &[(&str, &str)] = &[
        ("urdf = \"two.urdf\"\nfloating = true\n", "unknown key 'floating'"),
        ("srdf = \"x.srdf\"\n", "'urdf' is missing"),
        ("urdf = \"nope.urdf\"\n", "'urdf':"),
        ("urdf = 3\n", "'urdf' must be a string"),
        ("urdf = \"two.urdf\"\nfloating_base = \"yes\"\n", "'floating_base' must be true or false"),
        ("urdf = \"two.urdf\"\nlocked_joints = 3\n", "'locked_joints' must be"),
        ("urdf = \"two.urdf\"\nlocked_joints = { j2 = \"a\" }\n", "'locked_joints.j2' must be a number"),
        ("urdf = \"two.urdf\"\nreference_state = \"home\"\n", "no 'srdf'"),
        ("urdf = \"two.urdf\"\nframes = [\"l2\"]\n", "'frames' must be a table"),
        ("urdf = \"two.urdf\"\n[frames]\ntip = \"nowhere\"\n", "frame 'tip'"),
        ("urdf = \"two.urdf\"\nlocked_joints = [\"j9\"]\n", "j9"),
        ("urdf = [\n", "TOML"),
    ];
    for (i, (text, needle)) in cases.iter().enumerate() {
        let f = write(&d, &format!("r{i}.toml"), text);
        let e = RobotDescription::from_file(&f, &[]).and_then(|r| r.load().map(|_| ()));
        let e = e.expect_err(text);
        let msg = e.to_string();
        assert!(msg.contains(needle), "{text:?}: {msg}");
        if !needle.starts_with("j9") {
            assert!(matches!(e, Error::Parse { .. }), "{text:?}: {e:?}");
            assert!(msg.contains(&format!("r{i}.toml")), "{text:?}: {msg}");
        }
    }
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn bounding_volume_filters_never_change_a_collision_verdict() {
    use nalgebra::Isometry3;
    use rand::{Rng, SeedableRng};

    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    for name in ["panda", "talos", "ur5"] {
        let (model, mut world) = preset(name).unwrap().load().unwrap();
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

/// One `Scratch` reused across queries keeps, per pair of hulls, the axes that last separated
/// them (src/collision/world.rs, `self_pair_intersects`), and the order of the link pairs, the
/// last in contact first (`collides_with_itself`): the verdicts stay the exhaustive ones,
/// along 40 straight motions per robot (where the kept axes are nearly right), through contacts.
#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn kept_separating_axes_never_change_a_collision_verdict() {
    use genplan_core::Scratch;
    use rand::{Rng, SeedableRng};

    let mut rng = rand::rngs::StdRng::seed_from_u64(4);
    for name in ["talos", "ur5", "panda"] {
        let (model, world) = preset(name).unwrap().load().unwrap();
        let draw = |rng: &mut rand::rngs::StdRng| -> Vec<f64> {
            let mut q: Vec<f64> =
                model.lower.iter().zip(&model.upper).map(|(l, u)| if l.is_finite() { rng.random_range(*l..=*u) } else { 0.0 }).collect();
            if model.floating_base {
                q[2] = 1.0;
                q[6] = 1.0;
            }
            q
        };
        let mut s = Scratch::default();
        let (mut hits, mut n, mut changes) = (0, 0, 0);
        for _ in 0..40 {
            let (a, b) = (draw(&mut rng), draw(&mut rng));
            let mut last = None;
            for k in 0..=20 {
                let t = k as f64 / 20.0;
                let q: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + t * (y - x)).collect();
                let hit = world.in_collision_unchecked(&q, &mut s);
                assert_eq!(hit, world.in_collision_exhaustive(&q).unwrap(), "{name} {q:?}");
                changes += (last.is_some_and(|l| l != hit)) as usize;
                last = Some(hit);
                hits += hit as usize;
                n += 1;
            }
        }
        assert!(hits > 0 && hits < n && changes > 0, "{name}: {hits} of {n} in collision, {changes} changes along motions");
    }
}
