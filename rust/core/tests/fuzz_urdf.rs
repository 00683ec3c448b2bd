//! Property tests of the URDF reader and of what is built from what it accepts (the kinematic
//! model, the collision world): any text, bytes or mutation of a valid URDF is read as `Ok` or
//! `Err`, never a panic, and an `Ok` robot is usable: its model holds every link once, forward
//! kinematics of its default configuration gives finite rigid poses (or an `Err`), and collision
//! queries answer (or give an `Err`).

#[path = "common/fuzz.rs"]
mod fuzz;

use fuzz::{any_f64, check_robot, config, El, Gaps, ABSURD, ABSURD_TRIPLES};
use genplan_core::kinematics::{KinematicModel, ModelOptions};
use genplan_core::urdf::Urdf;
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

const MIXED: &str = include_str!("../../../tests/data/mixed.urdf");

/// A small arm with every primitive collision shape, a prismatic and a continuous joint.
const SHAPES: &str = r#"<robot name="shapes">
  <link name="base"><collision><geometry><box size="0.4 0.4 0.1"/></geometry></collision></link>
  <link name="l1"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1"/></inertial>
    <collision><origin xyz="0 0 0.2" rpy="0 0.1 0"/><geometry><cylinder radius="0.05" length="0.4"/></geometry></collision></link>
  <link name="l2"><collision><geometry><capsule radius="0.04" length="0.3"/></geometry></collision></link>
  <link name="tool"><collision><geometry><sphere radius="0.05"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
  <joint name="j2" type="prismatic"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.4"/>
    <axis xyz="1 0 0"/><limit lower="-0.5" upper="0.5" effort="10" velocity="1"/></joint>
  <joint name="j3" type="continuous"><parent link="l2"/><child link="tool"/><origin xyz="0 0 0.2" rpy="0.3 0 0"/>
    <axis xyz="0 1 0"/></joint>
</robot>"#;

/// What must hold of any text: the reader answers, and what it accepts is usable
/// ([`fuzz::check_robot`]) at the default configuration and at `q`, with or without a
/// free-flyer base. `strict`: known gaps are not exempted.
fn check_text(text: &str, q: &[f64], strict: bool) -> Result<(), TestCaseError> {
    let Ok(urdf) = Urdf::parse(text) else { return Ok(()) };
    let gaps = if strict { Gaps::default() } else { Gaps::of_urdf(&urdf) };
    for floating_base in [false, true] {
        let options = ModelOptions { floating_base, ..Default::default() };
        if let Ok(model) = KinematicModel::from_urdf(&urdf, &options) {
            let gaps = if strict { gaps } else { gaps.of_model(&model, &[]) };
            check_robot(&urdf, model, q, gaps)?;
        }
    }
    Ok(())
}

/// A joint of a generated URDF: type, parent and child (indices into the link names, past the
/// end: an unknown link), origin, axis and limits (indices into the absurd spellings).
#[derive(Debug, Clone)]
struct JointSpec {
    kind: usize,
    parent: usize,
    child: usize,
    origin: usize,
    rpy: usize,
    axis: usize,
    limits: Option<(usize, usize)>,
}

const KINDS: &[&str] = &["fixed", "revolute", "continuous", "prismatic", "floating", "planar", "hinge"];
const LINKS: &[&str] = &["a", "b", "c", "d", "e"];

/// Joint `i` of a generated robot: mostly a tree edge (child `i + 1`, parent any earlier link,
/// sane numbers), else anything (any parent, any child, unknown links, absurd numbers).
fn joint_spec(i: usize) -> impl Strategy<Value = JointSpec> {
    let sane = (
        0..4usize,
        0..=i,
        prop_oneof![Just(0usize), Just(1), Just(2), Just(3), 0..ABSURD_TRIPLES.len()],
        prop_oneof![Just(0usize), Just(3), 0..ABSURD_TRIPLES.len()],
        prop_oneof![Just(1usize), Just(2), 0..ABSURD_TRIPLES.len()],
        proptest::option::of(prop_oneof![Just((3usize, 2usize)), (0..ABSURD.len(), 0..ABSURD.len())]),
    )
        .prop_map(move |(kind, parent, origin, rpy, axis, limits)| JointSpec { kind, parent, child: i + 1, origin, rpy, axis, limits });
    let wild = (
        0..KINDS.len(),
        0..LINKS.len() + 1,
        0..LINKS.len() + 1,
        0..ABSURD_TRIPLES.len(),
        0..ABSURD_TRIPLES.len(),
        0..ABSURD_TRIPLES.len(),
        proptest::option::of((0..ABSURD.len(), 0..ABSURD.len())),
    )
        .prop_map(|(kind, parent, child, origin, rpy, axis, limits)| JointSpec { kind, parent, child, origin, rpy, axis, limits });
    prop_oneof![4 => sane, 1 => wild]
}

fn joint_specs() -> impl Strategy<Value = Vec<JointSpec>> {
    (0usize..LINKS.len()).prop_flat_map(|n| (0..n).map(joint_spec).collect::<Vec<_>>())
}

fn link_name(i: usize) -> &'static str {
    LINKS.get(i).copied().unwrap_or("unknown")
}

/// A URDF of as many links as joints + 1 (a collision sphere of radius `radius` on each) and
/// the joints.
fn small_urdf(radius: usize, mass: usize, joints: &[JointSpec]) -> String {
    let mut s = String::from("<robot name=\"gen\">");
    for l in &LINKS[..=joints.len()] {
        s += &format!(
            "<link name=\"{l}\"><inertial><mass value=\"{}\"/></inertial><collision><origin xyz=\"0.1 0 0\"/>\
             <geometry><sphere radius=\"{}\"/></geometry></collision></link>",
            ABSURD[mass], ABSURD[radius]
        );
    }
    for (i, j) in joints.iter().enumerate() {
        s += &format!(
            "<joint name=\"j{i}\" type=\"{}\"><parent link=\"{}\"/><child link=\"{}\"/>\
             <origin xyz=\"{}\" rpy=\"{}\"/><axis xyz=\"{}\"/>",
            KINDS[j.kind],
            link_name(j.parent),
            link_name(j.child),
            ABSURD_TRIPLES[j.origin],
            ABSURD_TRIPLES[j.rpy],
            ABSURD_TRIPLES[j.axis]
        );
        if let Some((lo, hi)) = j.limits {
            s += &format!("<limit lower=\"{}\" upper=\"{}\" effort=\"1\" velocity=\"1\"/>", ABSURD[lo], ABSURD[hi]);
        }
        s += "</joint>";
    }
    s + "</robot>"
}

/// A configuration to try (cycled to the model's length): any numbers, NaN and inf included.
fn configuration() -> impl Strategy<Value = Vec<f64>> {
    proptest::collection::vec(any_f64(), 1..9)
}

proptest! {
    #![proptest_config(config(256))]

    /// Any bytes (read as UTF-8, invalid sequences replaced).
    #[test]
    fn arbitrary_bytes_are_read_or_refused(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
        check_text(&String::from_utf8_lossy(&bytes), &[0.0], false)?;
    }

    /// Any UTF-8 text.
    #[test]
    fn arbitrary_text_is_read_or_refused(text in any::<String>()) {
        check_text(&text, &[0.0], false)?;
    }

    /// Text shaped like a URDF: links and joints with names from a small set, so that unknown
    /// parents, two parents, several roots and cycles come up.
    #[test]
    fn urdf_shaped_text_is_read_or_refused(text in concat!(
        "<robot( name=\"[a-z]{0,3}\")?>",
        "(<link name=\"[a-d]\"/>|<link name=\"[a-d]\"><collision><geometry><(box size=\"[-0-9. ]{0,8}\"|sphere radius=\"[-0-9.e]{0,5}\")/></geometry></collision></link>",
        "|<joint name=\"[j-l]\" type=\"(fixed|revolute|continuous|prismatic|floating)\"><parent link=\"[a-e]\"/><child link=\"[a-e]\"/>(<axis xyz=\"[-01 ]{0,7}\"/>)?(<limit lower=\"[-0-9]{0,2}\" upper=\"[-0-9]{0,2}\"/>)?</joint>",
        "|<bogus/>|<link/>|<joint/>){0,8}</robot>"), q in configuration()) {
        check_text(&text, &q, false)?;
    }

    /// Small generated robots, mostly trees, with absurd origins, axes, limits, masses and radii,
    /// and now and then any parent, any child, unknown links, cycles.
    #[test]
    fn generated_urdfs_are_read_or_refused(
        radius in prop_oneof![Just(4usize), 0..ABSURD.len()],
        mass in prop_oneof![Just(2usize), 0..ABSURD.len()],
        joints in joint_specs(),
        q in configuration(),
    ) {
        check_text(&small_urdf(radius, mass, &joints), &q, false)?;
    }

    /// Structured mutations of valid URDFs: elements and attributes dropped, duplicated, moved,
    /// renamed, set to absurd values.
    #[test]
    fn mutated_urdfs_are_read_or_refused(
        seed in prop_oneof![Just(MIXED), Just(SHAPES)],
        mutations in proptest::collection::vec(fuzz::mutation(), 1..6),
        q in configuration(),
    ) {
        let mut el = El::parse(seed);
        for m in &mutations {
            el.apply(m);
        }
        check_text(&el.write(), &q, false)?;
    }
}

#[test]
fn the_seed_urdfs_are_usable() {
    for seed in [MIXED, SHAPES] {
        assert!(Urdf::parse(&El::parse(seed).write()).is_ok());
        let urdf = Urdf::parse(seed).unwrap();
        let model = KinematicModel::from_urdf(&urdf, &ModelOptions::default()).unwrap();
        check_robot(&urdf, model, &[0.3, -0.2, 1.0], Gaps::default()).unwrap();
    }
}

#[test]
fn non_utf8_files_are_refused() {
    let dir = std::env::temp_dir().join(format!("genplan-fuzz-urdf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bad.urdf");
    std::fs::write(&path, b"<robot name=\"x\"><link name=\"\xff\xfe\"/></robot>").unwrap();
    assert!(Urdf::from_file(&path).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn deep_nesting_and_entities_are_read_or_refused() {
    let deep = format!("<robot>{}<link name=\"a\"/>{}</robot>", "<g>".repeat(20_000), "</g>".repeat(20_000));
    check_text(&deep, &[0.0], true).unwrap();
    let mut laughs = String::from("<!DOCTYPE robot [<!ENTITY l0 \"lol\">");
    for i in 1..10 {
        laughs += &format!("<!ENTITY l{i} \"{}\">", format!("&l{};", i - 1).repeat(10));
    }
    laughs += "]><robot name=\"&l9;\"><link name=\"a\"/></robot>";
    check_text(&laughs, &[0.0], true).unwrap();
}

// ---------------------------------------------------------------------------------------------
// Findings: known gaps, each the minimal input the properties above found. Each test asserts the
// property as it should hold and is expected to fail (`should_panic` naming the property) until
// the gap is closed; then it fails, and it and the gap's exemption in `common/fuzz.rs` go.
// ---------------------------------------------------------------------------------------------

/// URDF-1: a cycle in the joint graph off the root is accepted and its links (and joints) are
/// dropped from the model without a word (urdfdom refuses a graph that is not a tree).
#[test]
#[should_panic(expected = "every link of the URDF is in the model")]
fn finding_urdf_1_a_cycle_off_the_root_drops_its_links_silently() {
    strict(&three_links(&[joint("x", "fixed", "a", "b", ""), joint("y", "fixed", "b", "a", "")]), &[0.0]);
}

/// URDF-1 (self-loop): a joint whose parent is its child.
#[test]
#[should_panic(expected = "every link of the URDF is in the model")]
fn finding_urdf_1_a_self_loop_drops_its_link_silently() {
    strict(r#"<robot name="r"><link name="r"/><link name="a"/>
      <joint name="x" type="revolute"><parent link="a"/><child link="a"/></joint></robot>"#, &[0.0]);
}

/// URDF-2: two joints with the same name are accepted; the model counts both in nq but both
/// read the same q slot (nq 2, active ["x", "x"], q[0] unused).
#[test]
#[should_panic(expected = "each active joint once")]
fn finding_urdf_2_duplicate_joint_names_share_one_q_slot() {
    let z = r#"<axis xyz="0 0 1"/>"#;
    strict(&three_links(&[joint("x", "revolute", "r", "a", z), joint("x", "revolute", "a", "b", z)]), &[0.0]);
}

/// URDF-3: finite but absurd origins (1e308, twice along a chain) are accepted, and forward
/// kinematics returns Ok with an infinite translation.
#[test]
#[should_panic(expected = "FK at the default configuration: pose 2 is not finite")]
fn finding_urdf_3_huge_origins_overflow_to_infinite_poses() {
    let far = r#"<origin xyz="1e308 0 0"/>"#;
    strict(&three_links(&[joint("x", "fixed", "r", "a", far), joint("y", "fixed", "a", "b", far)]), &[0.0]);
}

/// URDF-4: an axis whose squared norm overflows (`1e200 0 0`) is normalised to the zero vector
/// (not refused like a zero axis); at any angle but 0 the child's pose is not a rigid transform.
#[test]
#[should_panic(expected = "is not rigid")]
fn finding_urdf_4_an_overflowing_axis_becomes_zero() {
    strict(r#"<robot name="r"><link name="r"/><link name="a"/>
      <joint name="x" type="revolute"><parent link="r"/><child link="a"/><axis xyz="1e200 0 0"/>
      <limit lower="-1" upper="1"/></joint></robot>"#, &[0.5]);
}

/// A robot of links r, a, b and the given joints.
fn three_links(joints: &[String]) -> String {
    format!(r#"<robot name="r"><link name="r"/><link name="a"/><link name="b"/>{}</robot>"#, joints.concat())
}

/// A joint element; `more`: its other elements.
fn joint(name: &str, kind: &str, parent: &str, child: &str, more: &str) -> String {
    format!(r#"<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>{more}</joint>"#)
}

/// [`check_text`] with no gap exempted; panics with the broken property.
fn strict(text: &str, q: &[f64]) {
    check_text(text, q, true).unwrap();
}

fn model_of(text: &str) -> std::sync::Arc<KinematicModel> {
    let urdf = Urdf::parse(text).expect("read");
    std::sync::Arc::new(KinematicModel::from_urdf(&urdf, &ModelOptions::default()).expect("accepted"))
}

/// URDF-3 (configurations): a free-flyer quaternion whose components are finite but whose norm
/// overflows (1e300) passes the configuration check (which only refuses a zero norm), and FK
/// answers with a zero rotation, not a rigid pose.
#[test]
#[should_panic(expected = "is not rigid")]
fn finding_urdf_3_a_huge_base_quaternion_passes_the_check() {
    let urdf = Urdf::parse(r#"<robot name="r"><link name="r"/></robot>"#).unwrap();
    let model = KinematicModel::from_urdf(&urdf, &ModelOptions { floating_base: true, ..Default::default() }).unwrap();
    check_robot(&urdf, model, &[0.0, 0.0, 0.0, 1e300, 1e300, 1e300, 1e300], Gaps::default()).unwrap();
}

const REVERSED: &str = r#"<robot name="r"><link name="r"/><link name="a"/>
  <joint name="x" type="revolute"><parent link="r"/><child link="a"/><axis xyz="0 0 1"/>
  <limit lower="1" upper="-1"/></joint></robot>"#;

/// URDF-5: reversed limits (lower 1 > upper -1) are accepted; the uniform sampler then panics
/// in `rand` ("cannot sample empty range").
#[test]
#[should_panic(expected = "cannot sample empty range")]
fn finding_urdf_5_reversed_limits_panic_the_uniform_sampler() {
    let _ = fuzz::use_uniform_sampler(&model_of(REVERSED));
}

/// URDF-5: ... and the native projector panics in `f64::clamp` ("min > max").
#[test]
#[should_panic(expected = "min > max")]
fn finding_urdf_5_reversed_limits_panic_the_projector() {
    let _ = fuzz::use_projector(&model_of(REVERSED), &[0.0]);
}

/// URDF-5: limits whose width overflows (-1e308 .. 1e308) are accepted as finite limits; the
/// uniform sampler then panics in `rand` (`Result::unwrap()` on `NonFinite`).
#[test]
#[should_panic(expected = "NonFinite")]
fn finding_urdf_5_limits_too_wide_to_sample_panic_the_uniform_sampler() {
    let _ = fuzz::use_uniform_sampler(&model_of(
        r#"<robot name="r"><link name="r"/><link name="a"/>
      <joint name="x" type="prismatic"><parent link="r"/><child link="a"/><axis xyz="0 0 1"/>
      <limit lower="-1e308" upper="1e308"/></joint></robot>"#,
    ));
}

/// URDF-6: a robot without an active joint (one link; nq 0) is accepted, and the uniform
/// sampler on it panics ("chunk size must be non-zero" in `chunks_mut(nq)`).
#[test]
#[should_panic(expected = "chunk size must be non-zero")]
fn finding_urdf_6_the_uniform_sampler_panics_without_joints() {
    let _ = fuzz::use_uniform_sampler(&model_of(r#"<robot name="r"><link name="a"/></robot>"#));
}
