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
        assert!(msg.contains(&format!("r{i}.toml")), "{text:?}: {msg}");
        // a name the URDF lacks is an unknown name; anything else an error of the file
        if needle.starts_with("j9") || needle.starts_with("frame") {
            assert!(matches!(e, Error::UnknownName { .. }), "{text:?}: {e:?}");
        } else {
            assert!(matches!(e, Error::Parse { .. }), "{text:?}: {e:?}");
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

/// A robot file `text` in a fresh folder holding `URDF` as two.urdf and `srdf` (if any) as
/// two.srdf, read and checked: the error's message.
fn read_error(tag: &str, text: &str, srdf: Option<&str>) -> (Error, String) {
    let d = temp_dir(tag);
    write(&d, "two.urdf", URDF);
    if let Some(s) = srdf {
        write(&d, "two.srdf", s);
    }
    let f = write(&d, "r.toml", text);
    let e = RobotDescription::from_file(&f, &[]).and_then(|r| r.read().map(|_| ())).expect_err(text);
    let msg = e.to_string();
    (e, msg)
}

/// Locked and reference values outside the joints' limits were accepted; now refused, naming
/// the robot file, the joint, the value, where it came from and the limits.
#[test]
fn integrity_5_locked_and_reference_values_outside_the_limits_are_refused() {
    let (e, msg) = read_error("lim1", "urdf = \"two.urdf\"\nlocked_joints = { j2 = 100.0 }\n", None);
    assert!(matches!(e, Error::Parse { .. }) && msg.contains("r.toml: locked joint 'j2' at 100 is outside its limits [-2, 2]"), "{msg}");
    let state = r#"<robot name="two"><group_state name="up"><joint name="j2" value="2.5"/><joint name="j1" value="0.5"/></group_state></robot>"#;
    let (_, msg) = read_error("lim2", "urdf = \"two.urdf\"\nsrdf = \"two.srdf\"\nreference_state = \"up\"\nlocked_joints = [\"j2\"]\n", Some(state));
    assert!(msg.contains("locked joint 'j2' at 2.5 (group_state 'up' of SRDF ") && msg.contains("two.srdf) is outside its limits [-2, 2]"), "{msg}");
    let (_, msg) = read_error("lim3", "urdf = \"two.urdf\"\nsrdf = \"two.srdf\"\nreference_state = \"up\"\n", Some(state));
    assert!(msg.contains("group_state 'up' of SRDF ") && msg.contains("puts joint 'j2' at 2.5, outside its limits [-2, 2]"), "{msg}");
    // j1 locked without a reference state: at 0, within [-1, 1]
    let d = temp_dir("lim5");
    write(&d, "two.urdf", URDF);
    let f = write(&d, "r.toml", "urdf = \"two.urdf\"\nlocked_joints = [\"j1\"]\n");
    let files = RobotDescription::from_file(&f, &[]).unwrap().read().unwrap();
    assert_eq!(files.model.locked, vec![("j1".to_string(), 0.0)]);
    assert_eq!(files.q_default, vec![0.0]);
}

/// SRDF names the URDF lacks were accepted silently; now a name genplan uses (a disabled pair's
/// link, a joint of the reference state) is an unknown name naming both files, and another
/// state's unknown joints are a warning naming them.
#[test]
fn integrity_5_srdf_names_unknown_to_the_urdf() {
    let toml = "urdf = \"two.urdf\"\nsrdf = \"two.srdf\"\nreference_state = \"home\"\n";
    let pair = r#"<robot><group_state name="home"/><disable_collisions link1="base" link2="l9"/></robot>"#;
    let (e, msg) = read_error("srdf1", toml, Some(pair));
    assert!(matches!(e, Error::UnknownName { .. }), "{e:?}");
    assert!(msg.starts_with("unknown link 'l9' in <disable_collisions> of SRDF ") && msg.contains("two.srdf: not a link of URDF ")
        && msg.ends_with("two.urdf (known: base, l1, l2)"), "{msg}");
    let state = r#"<robot><group_state name="home"><joint name="j7" value="1"/></group_state></robot>"#;
    let (e, msg) = read_error("srdf2", toml, Some(state));
    assert!(matches!(e, Error::UnknownName { .. }) && msg.starts_with("unknown joint 'j7' in group_state 'home' of SRDF "), "{msg}");
    assert!(msg.ends_with("(known: j1, j2)"), "{msg}");
    // a state not used: a warning; root_joint (the free-flyer's name) is known
    let d = temp_dir("srdf3");
    write(&d, "two.urdf", URDF);
    write(&d, "two.srdf", r#"<robot><group_state name="home"><joint name="j1" value="0.5"/><joint name="root_joint" value="0 0 0 0 0 0 1"/></group_state>
        <group_state name="other"><joint name="zz" value="1"/><joint name="j1" value="9"/></group_state></robot>"#);
    let f = write(&d, "r.toml", toml);
    let files = RobotDescription::from_file(&f, &[]).unwrap().read().unwrap();
    assert_eq!(files.q_default, vec![0.5, 0.0]);
    assert_eq!(files.warnings.len(), 2, "{:?}", files.warnings);
    assert!(files.warnings[0].contains("group_state 'other' names joints unknown to URDF ") && files.warnings[0].ends_with(": zz (not used: the reference state is 'home')"), "{:?}", files.warnings);
    assert!(files.warnings[1].contains("places 'root_joint', the free-flyer base, but the robot has none: ignored"), "{:?}", files.warnings);
}

/// A reference state the SRDF lacks ended in a Python AttributeError; now an unknown name
/// naming the robot file and the SRDF, with the states it has, whatever the locked joints.
#[test]
fn integrity_5_a_missing_reference_state_is_an_unknown_name() {
    let srdf = r#"<robot><group_state name="home"/><group_state name="away"/></robot>"#;
    for locked in ["", "locked_joints = [\"j1\"]\n", "locked_joints = { j1 = 0.5 }\n"] {
        let text = format!("urdf = \"two.urdf\"\nsrdf = \"two.srdf\"\nreference_state = \"nope\"\n{locked}");
        let (e, msg) = read_error("ref", &text, Some(srdf));
        assert!(matches!(e, Error::UnknownName { .. }), "{e:?}");
        assert!(msg.starts_with("unknown group_state 'nope' (reference_state of robot file ") && msg.contains("r.toml) in SRDF ")
            && msg.ends_with("two.srdf (known: away, home)"), "{msg}");
    }
}

/// Malformed URDFs: the reader's reason is in the error, with the file.
#[test]
fn integrity_5_urdf_errors_carry_the_reason() {
    let d = temp_dir("parse");
    for (text, reason) in [
        ("<robot name='b'><link name='a'>", "the root node was opened but never closed"),
        ("<robot name='b'><link name='a'/><joint name='j' type='revolute'><parent link='a'/></joint></robot>", "joint 'j' lacks <child link=...>"),
        ("<robot name='b'><link name='a'/><link name='c'/><joint name='j' type='fixed'><parent link='a'/><child link='x'/></joint></robot>",
         "unknown child link 'x' (known: a, c)"),
    ] {
        write(&d, "broken.urdf", text);
        let f = write(&d, "r.toml", "urdf = \"broken.urdf\"\n");
        let e = RobotDescription::from_file(&f, &[]).unwrap().read().map(|_| ()).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, Error::Parse { .. }), "{e:?}");
        assert!(msg.starts_with("cannot parse URDF ") && msg.contains("broken.urdf: ") && msg.ends_with(reason), "{msg}");
    }
}

/// Other robot-file nonsense that was accepted: a frame naming a joint or a role named like
/// another link, a collision URDF of another tree, a name that cannot name a cache file, a
/// locked joint listed twice, a locked fixed joint.
#[test]
fn integrity_5_other_robot_file_nonsense_is_refused() {
    let d = temp_dir("nonsense");
    write(&d, "two.urdf", URDF);
    write(&d, "moved.urdf", &URDF.replace(r#"<origin xyz="0 0 0.5"/>"#, r#"<origin xyz="0 0 0.6"/>"#));
    write(&d, "renamed.urdf", &URDF.replace(r#"<link name="l2"/>"#, r#"<link name="l2"/><link name="l3"/>"#)
        .replace("</robot>", r#"<joint name="j3" type="fixed"><parent link="l2"/><child link="l3"/></joint></robot>"#));
    for (text, problem) in [
        ("urdf = \"two.urdf\"\n[frames]\ntool = \"j2\"\n", "unknown link 'j2' (frame 'tool' of robot file "),
        ("urdf = \"two.urdf\"\n[frames]\nl1 = \"l2\"\n", "frame role 'l1' is the name of another link (it names 'l2')"),
        ("urdf = \"two.urdf\"\n[frames]\n\"\" = \"l2\"\n", "frame role '' is empty"),
        ("urdf = \"two.urdf\"\ncollision_urdf = \"moved.urdf\"\n", "moved.urdf is not the tree of 'urdf' "),
        ("urdf = \"two.urdf\"\ncollision_urdf = \"renamed.urdf\"\n", "link 'l3' is in one and not the other"),
        ("urdf = \"two.urdf\"\nname = \"a/b\"\n", "'name' 'a/b' cannot name a file"),
        ("urdf = \"two.urdf\"\nname = \"..\"\n", "'name' '..' cannot name a file"),
        ("urdf = \"two.urdf\"\nlocked_joints = [\"j1\", \"j1\"]\n", "'locked_joints' names 'j1' twice"),
        ("urdf = \"two.urdf\"\nmerge_computed_pairs = 1\n", "'merge_computed_pairs' must be true or false"),
        ("urdf = \"two.urdf\"\nsrdf = \"two.urdf\"\n", "two.urdf: <robot> has a <link> element: this is a URDF, not an SRDF"),
    ] {
        let f = write(&d, "r.toml", text);
        let msg = RobotDescription::from_file(&f, &[]).and_then(|r| r.read().map(|_| ())).expect_err(text).to_string();
        assert!(msg.contains(problem), "{text:?}: {msg}");
    }
    let f = write(&d, "r.toml", "urdf = \"two.urdf\"\ncollision_urdf = \"moved.urdf\"\n");
    let msg = RobotDescription::from_file(&f, &[]).unwrap().read().map(|_| ()).unwrap_err().to_string();
    assert!(msg.ends_with("joint 'j2' has another <origin>"), "{msg}");
}

/// example-robot-data's Unitree Z1 with its own SRDF (which disables no pair) is in collision
/// in every configuration (its gripper's stator against its mover): `default_contacts` names
/// the pair, in contact in all samples; with `merge_computed_pairs` the world built by `load`
/// is free at the default configuration.
#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn integrity_5_a_robot_in_self_collision_at_its_default_configuration_is_found() {
    use genplan_core::collision::allowed::default_contacts;
    use genplan_core::robot::find_robots_dir;
    let z1 = find_robots_dir().unwrap().join("z1_description");
    let d = temp_dir("z1");
    let text = format!("urdf = \"{}\"\nsrdf = \"{}\"\n", z1.join("urdf/z1.urdf").display(), z1.join("srdf/z1.srdf").display());
    let f = write(&d, "z1.toml", &text);
    let r = RobotDescription::from_file(&f, &genplan_core::robot::default_package_dirs().unwrap()).unwrap();
    let files = r.read().unwrap();
    let (_, world) = r.load().unwrap();
    let found = default_contacts(&world, &files.q_default, 500, 0).unwrap();
    let stator = found.iter().find(|c| (c.a.as_str(), c.b.as_str()) == ("gripperMover", "gripperStator")).expect("the gripper pair");
    assert_eq!(stator.hits, 500, "{found:?}");
    assert!(world.in_collision(&files.q_default).unwrap());
}

/// The remedy: with `merge_computed_pairs`, `load` skips the computed pairs too (here the
/// overlapping adjacent links the SRDF forgot), and the default configuration is free.
#[test]
fn integrity_5_merge_computed_pairs_skips_the_computed_pairs_too() {
    use genplan_core::collision::allowed::default_contacts;
    let d = temp_dir("merge");
    let boxes = URDF
        .replace(r#"<link name="l1"/>"#, r#"<link name="l1"><collision><geometry><box size="0.2 0.2 1.2"/></geometry></collision></link>"#)
        .replace(r#"<link name="l2"/>"#, r#"<link name="l2"><collision><geometry><box size="0.2 0.2 0.4"/></geometry></collision></link>"#);
    write(&d, "two.urdf", &boxes);
    write(&d, "two.srdf", "<robot/>");
    let f = write(&d, "r.toml", "urdf = \"two.urdf\"\nsrdf = \"two.srdf\"\n");
    let r = RobotDescription::from_file(&f, &[]).unwrap();
    let q = r.read().unwrap().q_default;
    let (_, world) = r.load().unwrap();
    let found = default_contacts(&world, &q, 100, 0).unwrap();
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!((found[0].a.as_str(), found[0].b.as_str(), found[0].hits), ("l1", "l2", 100));
    let (_, merged) = RobotDescription { merge_computed_pairs: true, ..r }.load().unwrap();
    assert!(default_contacts(&merged, &q, 100, 0).unwrap().is_empty());
    assert!(!merged.in_collision(&q).unwrap());
}
