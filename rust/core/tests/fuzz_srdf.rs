//! Property tests of the SRDF reader and of what genplan builds from what it accepts: any text,
//! bytes or mutation of a valid SRDF is read as `Ok` or `Err`, never a panic; an `Ok` SRDF's
//! numbers are finite; its disabled pairs are exactly the self-collision pairs the collision
//! world leaves out; and a robot whose locked joints take their values from its group state is
//! usable ([`fuzz::check_robot`]).

#[path = "common/fuzz.rs"]
mod fuzz;

use std::collections::HashSet;
use std::sync::Arc;

use fuzz::{check_robot, config, El, Gaps};
use genplan_core::collision::CollisionWorld;
use genplan_core::kinematics::{KinematicModel, ModelOptions};
use genplan_core::robot::RobotSpec;
use genplan_core::srdf::Srdf;
use genplan_core::urdf::Urdf;
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

/// Its SRDF: a group state (the reference of the locked joint j2) and disabled pairs.
const SEED: &str = r#"<robot name="shapes">
  <group name="arm"><joint name="j1"/><joint name="j2"/></group>
  <group_state name="default" group="arm"><joint name="j1" value="0.1"/><joint name="j2" value="0.2"/>
    <joint name="j3" value="0"/></group_state>
  <disable_collisions link1="base" link2="l1" reason="Adjacent"/>
  <disable_collisions link1="l2" link2="tool" reason="Adjacent"/>
  <disable_collisions link1="tool" link2="not_a_link" reason="Never"/>
</robot>"#;

/// The robot of `SHAPES` with j2 locked at the SRDF's reference value (as a preset does).
const SPEC: RobotSpec = RobotSpec {
    name: "shapes",
    urdf: "",
    collision_urdf: "",
    srdf: "",
    floating_base: false,
    locked_joints: &["j2"],
    reference_state: "default",
    frames: &[],
};

/// What must hold of any text (see the module doc); `strict`: known gaps are not exempted.
fn check_text(text: &str, strict: bool) -> Result<(), TestCaseError> {
    let Ok(srdf) = Srdf::parse(text) else { return Ok(()) };
    let non_finite = srdf.group_states.values().flat_map(|s| s.values()).flatten().any(|x| !x.is_finite());
    if strict || !non_finite {
        prop_assert!(!non_finite, "an SRDF with a non-finite group_state value was accepted: {:?}", srdf.group_states);
    }
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
    let kept: HashSet<(usize, usize)> = world.self_pairs.iter().copied().collect();
    for &(i, j) in &all.self_pairs {
        let links = (all.geometries[i].link, all.geometries[j].link);
        prop_assert_eq!(kept.contains(&(i, j)), !disabled.contains(&links), "pair {:?}", world.self_pair_names());
    }
    // the locked joint takes its reference value
    let locked = SPEC.locked_values(&srdf);
    let options = ModelOptions { locked_joints: locked.clone(), ..Default::default() };
    if let Ok(model) = KinematicModel::from_urdf(&urdf, &options) {
        let values: Vec<f64> = locked.values().copied().collect();
        let gaps = if strict { Gaps::default() } else { Gaps::of_urdf(&urdf).of_model(&model, &values) };
        check_robot(&urdf, model, &[0.3, 1.0, 0.0], gaps)?;
    }
    Ok(())
}

proptest! {
    #![proptest_config(config(256))]

    /// Any bytes (read as UTF-8, invalid sequences replaced).
    #[test]
    fn arbitrary_bytes_are_read_or_refused(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
        check_text(&String::from_utf8_lossy(&bytes), false)?;
    }

    /// Any UTF-8 text.
    #[test]
    fn arbitrary_text_is_read_or_refused(text in any::<String>()) {
        check_text(&text, false)?;
    }

    /// Text shaped like an SRDF: disabled pairs of known, unknown and missing links; group
    /// states with any values.
    #[test]
    fn srdf_shaped_text_is_read_or_refused(text in concat!(
        "<robot( name=\"[a-z]{0,3}\")?>(",
        "<disable_collisions( link1=\"(base|l1|l2|tool|x|)\")?( link2=\"(base|l1|l2|tool|x|)\")?/>",
        "|<group_state( name=\"(default|other|)\")?>(<joint( name=\"j[1-4]\")?( value=\"(0|1\\.5|-2|1e308|1e999|NaN|nan|inf|-inf|infinity|1 2|1e-400|abc| |)\")?/>){0,4}</group_state>",
        "|<group_state/>|<bogus/>){0,6}</robot>")) {
        check_text(&text, false)?;
    }

    /// Structured mutations of a valid SRDF.
    #[test]
    fn mutated_srdfs_are_read_or_refused(mutations in proptest::collection::vec(fuzz::mutation(), 1..6)) {
        let mut el = El::parse(SEED);
        for m in &mutations {
            el.apply(m);
        }
        check_text(&el.write(), false)?;
    }
}

#[test]
fn the_seed_srdf_is_usable() {
    check_text(SEED, true).unwrap();
    let srdf = Srdf::parse(SEED).unwrap();
    assert_eq!(srdf.disabled_pairs.len(), 3);
    assert_eq!(SPEC.locked_values(&srdf)["j2"], 0.2);
}

/// SRDF-1: a group state value that is not finite (`NaN`, `inf`, or `1e999`, which overflows)
/// is accepted; a preset locks its joints at these values, and forward kinematics then answers
/// Ok with NaN poses (neither the SRDF reader nor `KinematicModel::from_urdf` checks them).
#[test]
#[should_panic(expected = "an SRDF with a non-finite group_state value was accepted")]
fn finding_srdf_1_non_finite_group_state_values_are_accepted() {
    check_text(r#"<robot name="shapes"><group_state name="default"><joint name="j2" value="NaN"/></group_state></robot>"#, true)
        .unwrap();
}

/// SRDF-1, downstream: the locked joint at NaN gives NaN poses with no error.
#[test]
#[should_panic(expected = "FK at the default configuration: pose 2 is not finite")]
fn finding_srdf_1_a_joint_locked_at_nan_gives_nan_poses() {
    let urdf = Urdf::parse(SHAPES).unwrap();
    let srdf = Srdf::parse(r#"<robot><group_state name="default"><joint name="j2" value="1e999"/></group_state></robot>"#).unwrap();
    let options = ModelOptions { locked_joints: SPEC.locked_values(&srdf), ..Default::default() };
    let model = KinematicModel::from_urdf(&urdf, &options).expect("accepted");
    check_robot(&urdf, model, &[0.0], Gaps::default()).unwrap();
}
