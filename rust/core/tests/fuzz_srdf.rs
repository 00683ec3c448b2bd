//! Property tests of the SRDF reader and of what genplan builds from what it accepts: any text,
//! bytes or mutation of a valid SRDF is read as `Ok` or `Err`, never a panic; an `Ok` SRDF's
//! numbers are finite and within `urdf::MAX_JOINT_POSITION`; its disabled pairs are exactly the
//! self-collision pairs the collision world leaves out; and a robot whose locked joints take
//! their values from its group state is built and usable ([`fuzz::check_robot`]) when the
//! values lie within the joints' limits, refused otherwise. A robot
//! description read with the SRDF ([`RobotDescription::read`]) is refused with an error of the
//! files (never a panic or an I/O error), or is what its files say ([`check_description`]): its
//! disabled pairs and reference state name what the URDF has, its locked and default values lie
//! within the joints' limits.

#[path = "common/fuzz.rs"]
mod fuzz;

use std::collections::HashSet;
use std::sync::Arc;

use fuzz::{check_robot, config, El, Gaps};
use genplan_core::collision::CollisionWorld;
use genplan_core::kinematics::{KinematicModel, ModelOptions};
use genplan_core::kinematics::Motion;
use genplan_core::robot::{LockedJoints, RobotDescription, FREE_FLYER};
use genplan_core::Error;
use genplan_core::srdf::Srdf;
use genplan_core::urdf::{Urdf, MAX_JOINT_POSITION};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

/// A small arm with a collision shape on every link (as in `fuzz_urdf.rs`).
const SHAPES: &str = r#"<robot name="shapes">
  <link name="base"><collision><geometry><box size="0.4 0.4 0.1"/></geometry></collision></link>
  <link name="l1"><collision><origin xyz="0 0 0.2"/><geometry><cylinder radius="0.05" length="0.4"/></geometry></collision></link>
  <link name="l2"><collision><geometry><capsule radius="0.04" length="0.3"/></geometry></collision></link>
  <link name="tool"><collision><geometry><sphere radius="0.05"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
  <joint name="j2" type="prismatic"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.4"/>
    <axis xyz="1 0 0"/><limit lower="-0.5" upper="0.5"/></joint>
  <joint name="j3" type="continuous"><parent link="l2"/><child link="tool"/><origin xyz="0 0 0.2"/>
    <axis xyz="0 1 0"/></joint>
</robot>"#;

/// Its SRDF: a group state (the reference of the locked joint j2), another state, disabled
/// pairs.
const SEED: &str = r#"<robot name="shapes">
  <group name="arm"><joint name="j1"/><joint name="j2"/></group>
  <group_state name="default" group="arm"><joint name="j1" value="0.1"/><joint name="j2" value="0.2"/>
    <joint name="j3" value="0"/></group_state>
  <group_state name="other" group="arm"><joint name="j1" value="-0.1"/></group_state>
  <disable_collisions link1="base" link2="l1" reason="Adjacent"/>
  <disable_collisions link1="l2" link2="tool" reason="Adjacent"/>
  <disable_collisions link1="l1" link2="tool" reason="Never"/>
</robot>"#;

/// The robot of `SHAPES` with j2 locked at the SRDF's reference value (as a preset does).
fn spec() -> RobotDescription {
    RobotDescription {
        name: "shapes".into(),
        urdf: "shapes.urdf".into(),
        collision_urdf: "shapes.urdf".into(),
        srdf: Some("shapes.srdf".into()),
        package_dirs: Vec::new(),
        floating_base: false,
        locked_joints: LockedJoints::FromReference(vec!["j2".into()]),
        reference_state: Some("default".into()),
        merge_computed_pairs: false,
        mesh_shape: Default::default(),
        frames: Vec::new(),
        attached: Vec::new(),
        source: None,
    }
}

/// What must hold of any text (see the module doc). No gap is exempted (finding SRDF-1 is
/// fixed).
fn check_text(text: &str) -> Result<(), TestCaseError> {
    let Ok(srdf) = Srdf::parse(text) else { return Ok(()) };
    let non_finite = srdf.group_states.values().flat_map(|s| s.values()).flatten().any(|x| !x.is_finite());
    prop_assert!(!non_finite, "an SRDF with a non-finite group_state value was accepted: {:?}", srdf.group_states);
    let huge = srdf.group_states.values().flat_map(|s| s.values()).flatten().any(|x| x.abs() > MAX_JOINT_POSITION);
    prop_assert!(!huge, "an SRDF with a group_state value beyond the bound was accepted: {:?}", srdf.group_states);
    // the collision world drops exactly the disabled pairs of known links
    let urdf = Urdf::parse(SHAPES).unwrap();
    let model = Arc::new(KinematicModel::from_urdf(&urdf, &ModelOptions::default()).unwrap());
    let all = CollisionWorld::from_urdf(model.clone(), &urdf, &[], None).unwrap();
    let world = CollisionWorld::from_urdf(model.clone(), &urdf, &[], Some(&srdf));
    prop_assert!(world.is_ok(), "a world with an accepted SRDF was refused: {:?}", world.err());
    let world = world.unwrap();
    let disabled: HashSet<(usize, usize)> = srdf
        .disabled_pairs
        .iter()
        .filter_map(|(a, b)| Some((model.link_index(a).ok()?, model.link_index(b).ok()?)))
        .flat_map(|(a, b)| [(a, b), (b, a)])
        .collect();
    let kept: HashSet<(usize, usize)> = world.self_pairs().iter().copied().collect();
    for &(i, j) in all.self_pairs() {
        let links = (all.geometries()[i].link, all.geometries()[j].link);
        prop_assert_eq!(kept.contains(&(i, j)), !disabled.contains(&links), "pair {:?}", world.self_pair_names());
    }
    // the locked joint takes its reference value
    // (an SRDF without the "default" state is refused for a robot file naming it; here the
    // joint is then locked at 0, as a description without a reference state does)
    let locked = spec()
        .locked_values(Some(&srdf))
        .unwrap_or_else(|_| RobotDescription { reference_state: None, ..spec() }.locked_values(None).unwrap());
    let options = ModelOptions { locked_joints: locked.clone(), ..Default::default() };
    let model = KinematicModel::from_urdf(&urdf, &options);
    // j2's limits are [-0.5, 0.5]: a value outside them is refused, any other accepted
    let within = locked.values().all(|v| (-0.5..=0.5).contains(v));
    prop_assert_eq!(model.is_ok(), within, "the locked values {:?}: {:?}", locked, model.as_ref().err());
    if let Ok(model) = model {
        check_robot(&urdf, model, &[0.3, 1.0, 0.0], Gaps::default())?;
    }
    check_description(text)?;
    Ok(())
}

/// [`spec`] (j2 locked at the reference state's value) and the same without locks, with
/// `srdf_text` as its SRDF file, read and checked: an error of the files, or a robot whose
/// names and values are the files' (see the module's documentation).
fn check_description(srdf_text: &str) -> Result<(), TestCaseError> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static CASE: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!("genplan-fuzz-srdf-{}-{}", std::process::id(), CASE.fetch_add(1, Ordering::Relaxed)));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("shapes.urdf"), SHAPES).unwrap();
    std::fs::write(dir.join("shapes.srdf"), srdf_text).unwrap();
    let urdf = Urdf::parse(SHAPES).unwrap();
    let base = RobotDescription { urdf: dir.join("shapes.urdf"), collision_urdf: dir.join("shapes.urdf"), srdf: Some(dir.join("shapes.srdf")), ..spec() };
    let unlocked = RobotDescription { locked_joints: LockedJoints::FromReference(Vec::new()), ..base.clone() };
    let mut outcome = Ok(());
    for d in [base, unlocked] {
        let files = match d.read() {
            Ok(f) => f,
            Err(e @ Error::Io { .. }) => {
                outcome = Err(TestCaseError::fail(format!("an I/O error for files that exist: {e}")));
                break;
            }
            Err(_) => continue,
        };
        let srdf = files.srdf.as_ref().unwrap();
        let links: HashSet<&str> = urdf.links.iter().map(|l| l.name.as_str()).collect();
        let joints: HashSet<&str> = urdf.joints.iter().map(|j| j.name.as_str()).collect();
        for (a, b) in &srdf.disabled_pairs {
            prop_assert!(links.contains(a.as_str()) && links.contains(b.as_str()), "a disabled pair of unknown links ({}, {}) was accepted", a, b);
        }
        let state = srdf.group_states.get("default");
        prop_assert!(state.is_some(), "a reference state the SRDF lacks was accepted");
        for j in state.unwrap().keys() {
            prop_assert!(joints.contains(j.as_str()) || j == FREE_FLYER, "the reference state's unknown joint '{}' was accepted", j);
        }
        let m = &files.model;
        prop_assert_eq!(files.q_default.len(), m.nq);
        for j in m.joints.iter().filter(|j| j.q_index != usize::MAX && matches!(j.motion, Motion::Revolute { .. } | Motion::Prismatic { .. })) {
            let x = files.q_default[j.q_index];
            prop_assert!(m.lower[j.q_index] <= x && x <= m.upper[j.q_index], "joint '{}' at {} by default, outside its limits", j.name, x);
        }
        for (name, value) in &m.locked {
            let uj = urdf.joints.iter().find(|j| &j.name == name).unwrap();
            if matches!(uj.joint_type, genplan_core::urdf::JointType::Revolute | genplan_core::urdf::JointType::Prismatic) {
                prop_assert!(uj.lower <= *value && *value <= uj.upper, "joint '{}' locked at {}, outside its limits", name, value);
            }
        }
        check_robot(&urdf, (**m).clone(), &files.q_default, Gaps::default())?;
    }
    std::fs::remove_dir_all(&dir).ok();
    outcome
}

proptest! {
    #![proptest_config(config(256))]

    /// Any bytes (read as UTF-8, invalid sequences replaced).
    #[test]
    fn arbitrary_bytes_are_read_or_refused(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
        check_text(&String::from_utf8_lossy(&bytes))?;
    }

    /// Any UTF-8 text.
    #[test]
    fn arbitrary_text_is_read_or_refused(text in any::<String>()) {
        check_text(&text)?;
    }

    /// Text shaped like an SRDF: disabled pairs of known, unknown and missing links; group
    /// states with any values.
    #[test]
    fn srdf_shaped_text_is_read_or_refused(text in concat!(
        "<robot( name=\"[a-z]{0,3}\")?>(",
        "<disable_collisions( link1=\"(base|l1|l2|tool|x|)\")?( link2=\"(base|l1|l2|tool|x|)\")?/>",
        "|<group_state( name=\"(default|other|)\")?>(<joint( name=\"j[1-4]\")?( value=\"(0|1\\.5|-2|1e308|1e999|NaN|nan|inf|-inf|infinity|1 2|1e-400|abc| |)\")?/>){0,4}</group_state>",
        "|<group_state/>|<bogus/>){0,6}</robot>")) {
        check_text(&text)?;
    }

    /// Structured mutations of a valid SRDF.
    #[test]
    fn mutated_srdfs_are_read_or_refused(mutations in proptest::collection::vec(fuzz::mutation(), 1..6)) {
        let mut el = El::parse(SEED);
        for m in &mutations {
            el.apply(m);
        }
        check_text(&el.write())?;
    }
}

#[test]
fn the_seed_srdf_is_usable() {
    check_text(SEED).unwrap();
    let srdf = Srdf::parse(SEED).unwrap();
    assert_eq!(srdf.disabled_pairs.len(), 3);
    assert_eq!(spec().locked_values(Some(&srdf)).unwrap()["j2"], 0.2);
    // read with its URDF, as a robot file would be: accepted
    let dir = std::env::temp_dir().join(format!("genplan-fuzz-srdf-seed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("shapes.urdf"), SHAPES).unwrap();
    std::fs::write(dir.join("shapes.srdf"), SEED).unwrap();
    let d = RobotDescription { urdf: dir.join("shapes.urdf"), collision_urdf: dir.join("shapes.urdf"), srdf: Some(dir.join("shapes.srdf")), ..spec() };
    let files = d.read().unwrap();
    assert_eq!(files.model.locked, vec![("j2".to_string(), 0.2)]);
    assert_eq!(files.q_default, vec![0.1, 1.0, 0.0]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// SRDF-1 (fixed): a group state value that is not finite (`NaN`, `inf`, or `1e999`, which
/// overflows) was accepted; a preset locked its joints at these values, and forward kinematics
/// then answered Ok with NaN poses. The reader now refuses a value that is not finite, or beyond
/// `urdf::MAX_JOINT_POSITION` (1e16), naming the group state and the joint.
#[test]
fn srdf_1_non_finite_group_state_values_are_refused() {
    for (value, problem) in [
        ("NaN", "value NaN is not finite"),
        ("inf", "value inf is not finite"),
        ("-infinity", "value -inf is not finite"),
        ("1e999", "value inf is not finite"),
        ("1e308", "value 1e308 is too large (at most 1e16 in magnitude)"),
        ("0 0 1 0 0 0 -1e17", "value -1e17 is too large"),
    ] {
        let text = format!(r#"<robot name="shapes"><group_state name="default"><joint name="j2" value="{value}"/></group_state></robot>"#);
        let e = Srdf::parse(&text).unwrap_err().to_string();
        assert!(e.contains(&format!("group_state 'default', joint 'j2': {problem}")), "{e}");
        check_text(&text).unwrap();
    }
    // read from a file, the error names it
    let dir = std::env::temp_dir().join(format!("genplan-fuzz-srdf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("nan.srdf");
    std::fs::write(&path, r#"<robot><group_state name="s"><joint name="j" value="nan"/></group_state></robot>"#).unwrap();
    let e = Srdf::from_file(&path).unwrap_err().to_string();
    assert!(e.starts_with(&format!("cannot parse SRDF {}: group_state 's', joint 'j'", path.display())), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// SRDF-1, downstream (fixed): a joint locked at a value that is not finite gave NaN poses with
/// no error; the model now refuses a locked value that is not finite, or beyond
/// `urdf::MAX_JOINT_POSITION`, naming the joint (whichever way the value came).
#[test]
fn srdf_1_a_joint_locked_at_nan_is_refused() {
    let urdf = Urdf::parse(SHAPES).unwrap();
    for (value, problem) in [
        (f64::NAN, "locked joint 'j2' value: element 0 is not finite (NaN)"),
        (f64::INFINITY, "locked joint 'j2' value: element 0 is not finite (inf)"),
        (1e300, "locked joint 'j2': value 1e300 is too large (at most 1e16 in magnitude)"),
    ] {
        let options = ModelOptions { locked_joints: [("j2".to_string(), value)].into(), ..Default::default() };
        let e = KinematicModel::from_urdf(&urdf, &options).unwrap_err().to_string();
        assert_eq!(e, problem);
    }
    // at the bound (a continuous joint: any angle): accepted and usable
    let options = ModelOptions { locked_joints: [("j3".to_string(), -1e16)].into(), ..Default::default() };
    let model = KinematicModel::from_urdf(&urdf, &options).unwrap();
    check_robot(&urdf, model, &[0.0], Gaps::default()).unwrap();
}
