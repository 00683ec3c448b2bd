"""genplan.robots: loading, limits, frames, configurations, errors."""

import re
import warnings

import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan import robots
from genplan.errors import RobotFileError, RobotWarning, ShapeError, UnknownNameError


def test_unknown_robot_lists_the_known_ones() -> None:
    with pytest.raises(UnknownNameError, match=r"unknown robot 'atlas' \(known: kinova, panda, talos, ur10, ur3, ur5; or a robot file"):
        robots.load("atlas")


def test_load_is_cached() -> None:
    assert robots.load("panda") is robots.load("panda")


def test_panda(panda: genplan.Robot) -> None:
    assert (panda.nq, panda.nv) == (7, 7)
    assert panda.joint_names == [f"panda_joint{i}" for i in range(1, 8)]
    assert set(panda.locked_joints) == {"panda_finger_joint1", "panda_finger_joint2"}
    np.testing.assert_allclose(panda.lower[:2], [-2.8973, -1.7628])
    np.testing.assert_allclose(panda.q_default, [0, -0.785398, 0, -2.35619, 0, 1.5707, 0.785398])
    assert panda.frames["hand"] == "panda_hand"


def test_talos_has_the_28_joints_of_the_paper(talos: genplan.Robot) -> None:
    assert talos.floating_base
    assert (talos.nq, talos.nv) == (35, 34)
    assert len(talos.joint_names) == 28
    groups = {g: sum(n.startswith(g) for n in talos.joint_names) for g in ("torso", "arm_left", "arm_right", "leg_left", "leg_right")}
    assert groups == {"torso": 2, "arm_left": 7, "arm_right": 7, "leg_left": 6, "leg_right": 6}
    assert not any(n.startswith(("head", "gripper")) for n in talos.joint_names)
    # half-sitting: base at 1.01927 m, knees bent
    assert talos.q_default[2] == pytest.approx(1.01927)
    knee = 7 + talos.joint_names.index("leg_left_4_joint")
    assert talos.q_default[knee] == pytest.approx(0.859395)
    assert list(talos.frames) == ["left_sole", "right_sole", "right_hand", "left_hand"]  # the file's order
    for role in ("left_sole", "right_sole", "right_hand"):
        talos.frame_id(role)
    # feet on the ground at half-sitting
    for sole in ("left_sole", "right_sole"):
        assert abs(talos.frame_placement(talos.q_default, sole).translation[2]) < 1e-3


def test_ur5(ur5: genplan.Robot) -> None:
    assert (ur5.nq, ur5.nv) == (6, 6)
    ur5.frame_id("tool")


def test_random_configurations_are_within_limits(panda: genplan.Robot, talos: genplan.Robot) -> None:
    q = panda.random_configurations(500, 3)
    assert q.shape == (500, 7)
    assert np.all(q >= panda.lower) and np.all(q <= panda.upper)
    np.testing.assert_array_equal(q, panda.random_configurations(500, 3))  # seeded
    qt = talos.random_configurations(100, 0)
    np.testing.assert_array_equal(qt[:, :7], np.repeat(talos.q_default[None, :7], 100, axis=0))
    assert np.all(qt[:, 7:] >= talos.lower[7:]) and np.all(qt[:, 7:] <= talos.upper[7:])


def test_frame_errors(panda: genplan.Robot) -> None:
    with pytest.raises(UnknownNameError, match="no frame 'foot'.*roles: hand, tcp"):
        panda.frame_id("foot")
    assert panda.frame_id("panda_link3") == panda.model.getFrameId("panda_link3")
    with pytest.raises(ShapeError, match="one configuration"):
        panda.frame_placement(np.zeros((2, 7)), "hand")


def test_frame_positions_by_role_or_link_name(panda: genplan.Robot) -> None:
    """frame_positions: one configuration gives (3,), a batch (n, 3); a role and its link agree,
    and with Pinocchio's placement."""
    q = panda.random_configurations(5, 0)
    by_role = panda.frame_positions(q, "hand")
    assert by_role.shape == (5, 3) and panda.frame_positions(q[0], "hand").shape == (3,)
    np.testing.assert_array_equal(by_role, panda.frame_positions(q, panda.frames["hand"]))
    np.testing.assert_allclose(by_role[2], panda.frame_placement(q[2], "hand").translation, atol=1e-9)
    with pytest.raises(UnknownNameError, match="foot"):
        panda.frame_positions(q, "foot")


def test_robots_dir_override(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("GENPLAN_ROBOTS_DIR", str(tmp_path / "missing"))
    with pytest.raises(FileNotFoundError, match="GENPLAN_ROBOTS_DIR"):
        robots.robots_dir()
    monkeypatch.setenv("GENPLAN_ROBOTS_DIR", str(tmp_path / "a" / "b"))
    (tmp_path / "a" / "b").mkdir(parents=True)
    with pytest.raises(RobotFileError, match=r"panda.toml.*'urdf': 'package://example-robot-data/robots/panda_description/urdf/panda.urdf' is not under any package folder"):
        robots.load("panda")


def test_pinocchio_model_is_the_reduced_one(panda: genplan.Robot) -> None:
    assert [panda.model.names[i] for i in range(1, panda.model.njoints)] == panda.joint_names
    pin.framesForwardKinematics(panda.model, panda.data, panda.q_default)


# --- robots as data: robot files, URDF keywords, continuous joints, no SRDF --------------------

TWO = """<robot name="two">
  <link name="base"><collision><geometry><box size="2 2 0.1"/></geometry></collision></link>
  <link name="l1"><collision><origin xyz="0 0 0.15"/><geometry><cylinder radius="0.04" length="0.3"/></geometry></collision></link>
  <link name="l2"><collision><origin xyz="0 0 0.4"/><geometry><box size="0.05 0.05 0.8"/></geometry></collision></link>
  <link name="tip"/>
  <joint name="j1" type="continuous"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.05"/><axis xyz="0 0 1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.25"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j3" type="prismatic"><parent link="l2"/><child link="tip"/><origin xyz="0 0 0.8"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="0.1" effort="1" velocity="1"/></joint>
</robot>"""


@pytest.fixture()
def two_dir(tmp_path):
    (tmp_path / "urdf").mkdir()
    (tmp_path / "urdf" / "two.urdf").write_text(TWO)
    return tmp_path


def test_a_robot_file_a_urdf_path_and_keywords_load_the_same_robot(two_dir, monkeypatch) -> None:
    f = two_dir / "two_arm.toml"
    f.write_text('urdf = "urdf/two.urdf"\nlocked_joints = { j3 = 0.05 }\n[frames]\ntool = "tip"\n')
    from_file = robots.load(f)
    assert from_file.name == "two_arm" and from_file.source == f
    assert from_file.nq == 3 and from_file.locked_joints == {"j3": 0.05}  # j1: cos, sin; j2
    assert from_file.frames == {"tool": "tip"} and from_file.srdf_path is None
    assert robots.load(f) is from_file  # cached
    monkeypatch.chdir(two_dir)
    kw = robots.load(urdf="urdf/two.urdf", locked_joints={"j3": 0.05}, frames={"tool": "tip"})
    assert kw.name == "two" and kw.nq == 3
    np.testing.assert_allclose(kw.frame_placement(kw.q_default, "tool").homogeneous,
                               from_file.frame_placement(from_file.q_default, "tool").homogeneous)
    bare = robots.load("urdf/two.urdf")
    assert bare.nq == 4 and bare.name == "two"


def test_keywords_set_to_false_or_empty_replace_the_robot_files_values(two_dir) -> None:
    f = two_dir / "floating_locked.toml"
    f.write_text('urdf = "urdf/two.urdf"\nfloating_base = true\nlocked_joints = { j3 = 0.05 }\n')
    from_file = robots.load(f)
    assert from_file.nq == 3 + 7 and from_file.locked_joints == {"j3": 0.05}
    fixed = robots.load(f, floating_base=False)
    assert fixed.nq == 3 and fixed.locked_joints == {"j3": 0.05}
    free = robots.load(f, locked_joints=[])
    assert free.nq == 4 + 7 and free.locked_joints == {}
    assert robots.load(f, locked_joints={}).nq == 4 + 7
    assert robots.load(f, floating_base=None, locked_joints=None) is from_file  # None: the file's value


def test_robot_input_errors_name_the_file_and_the_key(two_dir, monkeypatch) -> None:
    monkeypatch.chdir(two_dir)
    bad = two_dir / "bad.toml"
    for text, error, message in [
        ('urdf = "urdf/two.urdf"\nfloating = true\n', RobotFileError, r"bad.toml.*unknown key 'floating' \(known: name, urdf"),
        ('urdf = "urdf/nope.urdf"\n', RobotFileError, r"bad.toml.*'urdf':.*nope.urdf does not exist"),
        ('urdf = "urdf/two.urdf"\n[frames]\ntool = "hand"\n', UnknownNameError,
         r"unknown link 'hand' \(frame 'tool' of robot file .*bad.toml\) in URDF .*two.urdf \(known: base, l1, l2, tip\)"),
        ('urdf = "urdf/two.urdf"\nlocked_joints = ["j9"]\n', UnknownNameError,
         r"unknown joint 'j9' \(locked_joints of robot file .*bad.toml\) in URDF .*two.urdf \(known: j1, j2, j3\)"),
    ]:
        bad.write_text(text)
        with pytest.raises(error, match=message):
            robots.load(bad)
    with pytest.raises(FileNotFoundError, match="missing.toml does not exist"):
        robots.load(two_dir / "missing.toml")
    with pytest.raises(RobotFileError, match=r"'urdf':.*x.urdf does not exist"):
        robots.load(urdf="x.urdf")
    (two_dir / "broken.urdf").write_text("<robot name='b'><link name='a'>")
    with pytest.raises(RobotFileError, match="broken.urdf"):
        robots.load("broken.urdf")
    with pytest.raises(TypeError, match="'panda' names its URDF; give urdf= without a preset"):
        robots.load("panda", urdf=two_dir / "urdf" / "two.urdf")
    with pytest.raises(TypeError, match="give a preset name, a robot file, or urdf=PATH"):
        robots.load()


def test_continuous_joints_are_unit_complex_numbers_and_fk_agrees(two_dir) -> None:
    robot = robots.load(two_dir / "urdf" / "two.urdf")
    assert robot.continuous == [0]
    q = robot.random_configurations(200, 1)
    np.testing.assert_allclose(np.hypot(q[:, 0], q[:, 1]), 1.0)
    assert np.unique(np.round(np.arctan2(q[:, 1], q[:, 0]), 1)).size > 40  # the whole circle
    poses = robot.link_poses(q, ["tip"])[:, 0]
    for qi, pose in zip(q[:20], poses[:20]):
        pin.framesForwardKinematics(robot.model, robot.data, qi)
        np.testing.assert_allclose(pose, robot.data.oMf[robot.model.getFrameId("tip")].homogeneous, atol=1e-12)
    off = q[:3].copy()
    off[:, :2] *= 2.0
    np.testing.assert_allclose(robot.normalize(off), q[:3])
    with pytest.raises(ShapeError, match="count >= 0"):
        robot.random_configurations(-1)


def test_without_an_srdf_the_pairs_to_skip_are_computed_reported_and_written(two_dir, tmp_path, monkeypatch) -> None:
    from genplan.robots import compute_disabled_pairs

    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path / "cache"))
    robot = robots.load(two_dir / "urdf" / "two.urdf")
    found = compute_disabled_pairs(robot, samples=2000)
    reasons = {frozenset((a, b)): r for a, b, r in found.entries}
    assert reasons[frozenset(("base", "l1"))] == "Adjacent" and reasons[frozenset(("l1", "l2"))] == "Adjacent"
    # base and l2 meet when j2 folds the arm down (|j2| > 1.85 rad, ~7 % of samples): not skipped
    assert frozenset(("base", "l2")) not in reasons
    assert "link pairs skipped" in found.report()
    assert list((tmp_path / "cache" / "self_collision").glob("two_*.json"))  # cached
    assert compute_disabled_pairs(robot, samples=2000) == found
    world = robot.collision_world()
    links = dict(zip(world.geometry_names, world.native.geometry_links))
    checked = {frozenset((links[a], links[b])) for a, b in world.self_pairs}
    assert checked == {frozenset(("base", "l2"))}
    srdf = robot.write_srdf(tmp_path / "two.srdf")
    again = robots.load(urdf=two_dir / "urdf" / "two.urdf", srdf=srdf)
    assert sorted(again.collision_world().self_pairs) == sorted(world.self_pairs)
    assert 'reason="Adjacent"' in srdf.read_text()


# --- robots are loaded as their files say, or refused (integrity, finding 5) -----------------

#: j2 follows j1 (q_j2 = -2 q_j1 + 0.1); j3 moves on its own.
MIMIC = """<robot name="mimic">
  <link name="base"><collision><geometry><box size="0.4 0.4 0.1"/></geometry></collision></link>
  <link name="l1"><collision><origin xyz="0.15 0 0"/><geometry><box size="0.3 0.05 0.05"/></geometry></collision></link>
  <link name="l2"><collision><origin xyz="0.15 0 0"/><geometry><box size="0.3 0.05 0.05"/></geometry></collision></link>
  <link name="l3"><collision><geometry><sphere radius="0.03"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.3"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/><mimic joint="j1" multiplier="-2" offset="0.1"/></joint>
  <joint name="j3" type="prismatic"><parent link="l2"/><child link="l3"/><origin xyz="0.3 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.2" effort="1" velocity="1"/></joint>
</robot>"""


def _rot(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return {"y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]), "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]


def test_integrity_5_mimic_joints_follow_their_master(tmp_path) -> None:
    """A <mimic> joint is no coordinate of its own: q holds its master, and the mimic's value is
    multiplier * master + offset, in the Rust kinematics and in the Pinocchio model alike."""
    path = tmp_path / "mimic.urdf"
    path.write_text(MIMIC)
    robot = robots.load(path)
    assert robot.nq == 2 and robot.joint_names == ["j1", "j3"]
    assert robot.kinematics.active_joints == ["j1", "j3"]
    q = robot.random_configurations(50, 0)
    poses = robot.link_poses(q, ["l2", "l3"])
    for qi, (l2, l3) in zip(q, poses):
        r2 = _rot("z", qi[0]) @ _rot("y", -2 * qi[0] + 0.1)  # the mimic's rotation, by hand
        np.testing.assert_allclose(l2[:3, :3], r2, atol=1e-12)
        np.testing.assert_allclose(l3[:3, 3], l2[:3, 3] + r2 @ [0.3 + qi[1], 0, 0], atol=1e-12)
        pin.framesForwardKinematics(robot.model, robot.data, qi)
        np.testing.assert_allclose(l3, robot.data.oMf[robot.model.getFrameId("l3")].homogeneous, atol=1e-12)


def test_kinematic_hash_holds_a_mimics_multiplier_and_offset(tmp_path) -> None:
    """Two robots whose mimic joint differs only in its multiplier or only in its offset move
    their links differently, so a model learned on one must not load for the other; the same
    file written twice hashes the same."""
    def hashed(name: str, mimic: str) -> str:
        path = tmp_path / f"{name}.urdf"
        path.write_text(MIMIC.replace('multiplier="-2" offset="0.1"', mimic))
        return robots.load(path).kinematic_hash

    base = hashed("base", 'multiplier="-2" offset="0.1"')
    assert hashed("again", 'multiplier="-2" offset="0.1"') == base
    assert hashed("multiplier", 'multiplier="-2.5" offset="0.1"') != base
    assert hashed("offset", 'multiplier="-2" offset="0.2"') != base


def test_integrity_5_the_pandas_fingers_move_together(tmp_path) -> None:
    """example-robot-data's Panda: panda_finger_joint2 mimics panda_finger_joint1. Unlocked, the
    fingers are one coordinate; locking the master locks its mimic at the value it follows;
    locking the mimic alone is refused by name."""
    d = robots.robots_dir() / "panda_description"
    free = robots.load(urdf=d / "urdf/panda.urdf", srdf=d / "srdf/panda.srdf", reference_state="default")
    assert free.nq == 8 and free.joint_names[-1] == "panda_finger_joint1"
    q = free.random_configurations(20, 1)
    left, right = free.link_poses(q, ["panda_leftfinger", "panda_rightfinger"]).transpose(1, 0, 2, 3)
    hand = free.link_poses(q, ["panda_hand"])[:, 0]
    for k in range(20):  # each finger at q_finger from the hand's y axis, on opposite sides
        y = hand[k, :3, 1]
        assert (left[k, :3, 3] - hand[k, :3, 3]) @ y == pytest.approx(q[k, 7], abs=1e-12)
        assert (right[k, :3, 3] - hand[k, :3, 3]) @ y == pytest.approx(-q[k, 7], abs=1e-12)
    master = robots.load(urdf=d / "urdf/panda.urdf", locked_joints={"panda_finger_joint1": 0.03})
    assert master.nq == 7 and master.locked_joints == {"panda_finger_joint1": 0.03, "panda_finger_joint2": 0.03}
    assert genplan.load("panda").locked_joints == {"panda_finger_joint1": 0.001, "panda_finger_joint2": 0.001}
    with pytest.raises(RobotFileError, match=r"'panda_finger_joint2' mimics 'panda_finger_joint1', which is not locked.*lock 'panda_finger_joint1'"):
        robots.load(urdf=d / "urdf/panda.urdf", locked_joints=["panda_finger_joint2"])
    with pytest.raises(RobotFileError, match=r"locked joint 'panda_finger_joint2' at 0.01, but it follows 'panda_finger_joint1' \(0.03 \* 1 \+ 0 = 0.03\)"):
        robots.load(urdf=d / "urdf/panda.urdf", locked_joints={"panda_finger_joint1": 0.03, "panda_finger_joint2": 0.01})


@pytest.mark.parametrize("mimic, problem", [
    ('<mimic joint="j3"/>', r"joint 'j2' mimics 'j3', which comes after it in the tree"),
    ('<mimic joint="nope"/>', r"joint 'j2' mimics 'nope', which is not a joint of the URDF"),
    ('<mimic joint="j2"/>', r"joint 'j2' mimics itself"),
    ('<mimic joint="j1" multiplier="nan"/>', r"joint 'j2': <mimic multiplier>: expected 1 finite numbers"),
])
def test_integrity_5_mimic_joints_genplan_cannot_follow_are_refused_by_name(tmp_path, mimic: str, problem: str) -> None:
    path = tmp_path / "bad_mimic.urdf"
    path.write_text(MIMIC.replace('<mimic joint="j1" multiplier="-2" offset="0.1"/>', mimic))
    with pytest.raises(RobotFileError, match=problem):
        robots.load(path)


#: j3 follows j2 (q_j3 = 2 q_j2 + OFFSET), all three limited to [-1, 1].
MIMIC_RANGE = """<robot name="doubled">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="LOWER" upper="UPPER" effort="1" velocity="1"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/><mimic joint="j2" multiplier="2" offset="OFFSET"/></joint>
</robot>"""


def test_integrity_rerun_a_mimic_joint_that_leaves_its_limits_is_refused(tmp_path) -> None:
    """Before: j3 = 2 j2 with both limited to [-1, 1] loaded, and half of the random
    configurations put j3 outside its limits; a mimic of a locked master (j2 at 0.5, j3 at 1.1)
    loaded too. A mimic joint is no coordinate: nothing but its master's limits keeps it inside
    its own, so both are refused at load naming the joints, the ranges and the remedy."""
    urdf = tmp_path / "doubled.urdf"

    def write(offset: str, lower: str = "-1", upper: str = "1") -> None:
        urdf.write_text(MIMIC_RANGE.replace("OFFSET", offset).replace("LOWER", lower).replace("UPPER", upper))
        robots.clear_cache()

    write("0")
    with pytest.raises(RobotFileError, match=re.escape(
            "mimic joint 'j3' follows 'j2' (2 * j2 + 0): over the limits of 'j2', [-1, 1], it ranges over [-2, 2], "
            f"beyond its own limits [-1, 1] ({urdf}); narrow the limits of 'j2' to [-0.5, 0.5] in the URDF")):
        robots.load(urdf)
    write("0.1")
    with pytest.raises(RobotFileError, match=re.escape("it ranges over [-1.9, 2.1], beyond its own limits [-1, 1] "
                                                       f"({urdf}); narrow the limits of 'j2' to [-0.55, 0.45]")):
        robots.load(urdf)
    robot_file = tmp_path / "doubled.toml"
    robot_file.write_text('urdf = "doubled.urdf"\nlocked_joints = { j2 = 0.5 }\n')
    with pytest.raises(RobotFileError, match=re.escape(
            f"robot file {robot_file}: locked joint 'j3' at 1.1 (it mimics 'j2', locked at 0.5: 2 * 0.5 + 0.1) is "
            f"outside its limits [-1, 1] ({urdf}); lock 'j2' within [-0.55, 0.45]")):
        robots.load(robot_file)
    # a constant mimic outside its limits: no value of the master helps
    urdf.write_text(MIMIC_RANGE.replace('multiplier="2" offset="OFFSET"', 'multiplier="0" offset="1.5"')
                    .replace("LOWER", "-1").replace("UPPER", "1"))
    robots.clear_cache()
    with pytest.raises(RobotFileError, match="no value of 'j2' within its limits puts 'j3' inside them"):
        robots.load(urdf)
    # the remedy applied: j3 stays inside its limits over j2's, at them included, and follows j2
    write("0.1", "-0.55", "0.45")
    robot = robots.load(urdf)
    assert robot.joint_names == ["j1", "j2"] and robot.kinematics.mimic_joints == [("j3", "j2", 2.0, 0.1)]
    q = robot.random_configurations(200, 0)
    assert np.all(np.abs(2 * q[:, 1] + 0.1) <= 1 + 1e-12)
    robot_file.write_text('urdf = "doubled.urdf"\nlocked_joints = { j2 = 0.45 }\n')
    assert robots.load(robot_file).locked_joints == {"j2": 0.45, "j3": pytest.approx(1.0)}
    # the Panda's fingers (finger 2 mimics finger 1, the same limits) load moving and locked
    d = robots.robots_dir() / "panda_description"
    free = robots.load(urdf=d / "urdf/panda.urdf")
    assert free.joint_names[-1] == "panda_finger_joint1" and free.kinematics.mimic_joints == [
        ("panda_finger_joint2", "panda_finger_joint1", 1.0, 0.0)]
    assert robots.load(urdf=d / "urdf/panda.urdf", locked_joints={"panda_finger_joint1": 0.04}).locked_joints == {
        "panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04}


def test_integrity_5_a_locked_joint_outside_its_limits_is_refused(two_dir) -> None:
    bad = two_dir / "bad.toml"
    bad.write_text('urdf = "urdf/two.urdf"\nlocked_joints = { j2 = 100.0 }\n')
    with pytest.raises(RobotFileError, match=r"bad.toml: locked joint 'j2' at 100 is outside its limits \[-2, 2\]"):
        robots.load(bad)
    # a value from the reference state, and a reference state outside the limits of an active joint
    (two_dir / "two.srdf").write_text(
        '<robot name="two"><group_state name="up" group="all"><joint name="j2" value="2.5"/></group_state></robot>')
    bad.write_text('urdf = "urdf/two.urdf"\nsrdf = "two.srdf"\nreference_state = "up"\nlocked_joints = ["j2"]\n')
    with pytest.raises(RobotFileError, match=r"bad.toml: locked joint 'j2' at 2.5 \(group_state 'up' of .*two.srdf\) is outside its limits \[-2, 2\]"):
        robots.load(bad)
    bad.write_text('urdf = "urdf/two.urdf"\nsrdf = "two.srdf"\nreference_state = "up"\n')
    with pytest.raises(RobotFileError, match=r"bad.toml: group_state 'up' of .*two.srdf puts joint 'j2' at 2.5, outside its limits \[-2, 2\]"):
        robots.load(bad)
    # at its limit: accepted
    bad.write_text('urdf = "urdf/two.urdf"\nlocked_joints = { j2 = -2.0 }\n')
    assert robots.load(bad).locked_joints == {"j2": -2.0}


def test_integrity_5_srdf_names_unknown_to_the_urdf(two_dir) -> None:
    """Names genplan uses (disabled pairs, the reference state) are errors; a state it does not
    use that names unknown joints gives a RobotWarning naming them."""
    srdf = two_dir / "two.srdf"
    bad = two_dir / "bad.toml"
    bad.write_text('urdf = "urdf/two.urdf"\nsrdf = "two.srdf"\nreference_state = "home"\n')
    srdf.write_text('<robot name="two"><group_state name="home"><joint name="j2" value="0.5"/></group_state>'
                    '<disable_collisions link1="base" link2="l9" reason="Never"/></robot>')
    with pytest.raises(UnknownNameError, match=r"unknown link 'l9' in <disable_collisions> of SRDF .*two.srdf: not a link of URDF .*two.urdf \(known: base, l1, l2, tip\)"):
        robots.load(bad)
    srdf.write_text('<robot name="two"><group_state name="home"><joint name="j7" value="0.5"/></group_state></robot>')
    with pytest.raises(UnknownNameError, match=r"unknown joint 'j7' in group_state 'home' of SRDF .*two.srdf: not a joint of URDF .*two.urdf \(known: j1, j2, j3\)"):
        robots.load(bad)
    srdf.write_text('<robot name="two"><group_state name="home"><joint name="j2" value="0.5"/></group_state>'
                    '<group_state name="other"><joint name="j7" value="1"/><joint name="j8" value="1"/></group_state>'
                    '<disable_collisions link1="base" link2="l1"/><disable_collisions link1="l1" link2="l2"/></robot>')
    with pytest.warns(RobotWarning, match=r"two.srdf: group_state 'other' names joints unknown to .*two.urdf: j7, j8 \(not used: the reference state is 'home'\)"):
        robot = robots.load(bad)
    assert robot.q_default[2] == 0.5


def test_integrity_5_baxters_unused_states_naming_unknown_joints_are_a_warning() -> None:
    d = robots.robots_dir() / "baxter_description"
    with pytest.warns(RobotWarning, match=r"baxter_manipulation.srdf: group_state 'neutral' names joints unknown to .*baxter.urdf: baxter/head_pan, "):
        robots.load(urdf=d / "urdf/baxter.urdf", srdf=d / "srdf/baxter_manipulation.srdf")


def test_integrity_5_a_missing_reference_state_is_a_typed_error(two_dir) -> None:
    (two_dir / "two.srdf").write_text('<robot name="two"><group_state name="home"><joint name="j2" value="0.5"/></group_state>'
                                      '<group_state name="away"/></robot>')
    bad = two_dir / "bad.toml"
    for locked in ('', 'locked_joints = ["j3"]\n', 'locked_joints = { j3 = 0.05 }\n'):
        bad.write_text(f'urdf = "urdf/two.urdf"\nsrdf = "two.srdf"\nreference_state = "nope"\n{locked}')
        with pytest.raises(UnknownNameError, match=r"unknown group_state 'nope' \(reference_state of robot file .*bad.toml\) in SRDF .*two.srdf \(known: away, home\)"):
            robots.load(bad)


@pytest.mark.parametrize("text, reason", [
    ("<robot name='b'><link name='a'>", r"broken.urdf: the root node was opened but never closed"),
    ("<robot name='b'><link name='a'/><joint name='j' type='revolute'><parent link='a'/></joint></robot>",
     r"broken.urdf: joint 'j' lacks <child link=...>"),
    ("<robot name='b'><link name='a'/><link name='c'/><joint name='j' type='fixed'><parent link='a'/><child link='x'/></joint></robot>",
     r"broken.urdf: unknown child link 'x' \(known: a, c\)"),
    ("<robot name='b'><link name='a'/><link name='c'/><joint name='j' type='hinge'><parent link='a'/><child link='c'/></joint></robot>",
     r"broken.urdf: joint 'j' has unknown type Some\(\"hinge\"\)"),
    # read by the core, refused by urdfdom (which Pinocchio uses): urdfdom's reason, not its stderr
    ("<robot name='b'><link name='a'/><link name='c'/><joint name='j' type='revolute'><parent link='a'/><child link='c'/>"
     "<axis xyz='0 0 1'/></joint></robot>", r"broken.urdf.*urdfdom: Error:\s+Joint \[j\] is of type REVOLUTE but it does not specify limits"),
])
def test_integrity_5_urdf_parse_errors_carry_the_reason(two_dir, capfd, text: str, reason: str) -> None:
    (two_dir / "broken.urdf").write_text(text)
    capfd.readouterr()
    with pytest.raises(RobotFileError, match=reason):
        robots.load(two_dir / "broken.urdf")
    assert capfd.readouterr().err == ""  # the reason is in the error, not on urdfdom's stderr


def test_integrity_5_a_robot_in_self_collision_is_reported_with_the_remedy(tmp_path, monkeypatch) -> None:
    """example-robot-data's Unitree Z1 with its SRDF (which disables no pair): its gripper's
    stator and mover are in contact in every configuration. The load says so, naming the pairs
    and the remedy; the remedy (the computed pairs merged with the SRDF's) makes it usable."""
    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path / "cache"))
    d = robots.robots_dir() / "z1_description"
    with pytest.warns(RobotWarning, match=r"self-collision at the default configuration: gripperMover-gripperStator "
                                          r"\(in contact in 100 % of 1000 random configurations\).*z1.srdf does not disable "
                                          r"these pairs.*merge_computed_pairs=True"):
        robot = robots.load(urdf=d / "urdf/z1.urdf", srdf=d / "srdf/z1.srdf")
    assert ("gripperMover", "gripperStator", 1.0) in robot.default_contacts
    assert robot.collision_world().in_collision(robot.q_default)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RobotWarning)
        fixed = robots.load(urdf=d / "urdf/z1.urdf", srdf=d / "srdf/z1.srdf", merge_computed_pairs=True)
        assert fixed.default_contacts == ()
        world = fixed.collision_world()
        assert not world.in_collision(fixed.q_default)
        assert world.in_collision(fixed.random_configurations(400, 0)).mean() < 0.2
        assert {("gripperMover", "gripperStator")} <= {tuple(sorted(p)) for p in fixed.disabled_pairs}
        f = tmp_path / "z1.toml"
        f.write_text(f'urdf = "{d / "urdf/z1.urdf"}"\nsrdf = "{d / "srdf/z1.srdf"}"\nmerge_computed_pairs = true\n')
        from_file = robots.load(f)
        assert from_file.description["merge_computed_pairs"] is True and from_file.default_contacts == ()
    # cached: a second process reads the verdict instead of sampling again
    assert list((tmp_path / "cache" / "self_collision").glob("z1_*contacts*.json"))


def test_integrity_5_frame_roles_name_links(two_dir) -> None:
    bad = two_dir / "bad.toml"
    for frames, error, message in [
        ('tool = "j2"', UnknownNameError, r"unknown link 'j2' \(frame 'tool' of robot file .*bad.toml\) in URDF .*two.urdf \(known: base, l1, l2, tip\)"),
        ('l1 = "tip"', RobotFileError, r"bad.toml: frame role 'l1' is the name of another link"),
        ('"" = "tip"', RobotFileError, r"bad.toml: frame role '' is empty"),
    ]:
        bad.write_text(f'urdf = "urdf/two.urdf"\n[frames]\n{frames}\n')
        with pytest.raises(error, match=message):
            robots.load(bad)
    bad.write_text('urdf = "urdf/two.urdf"\n[frames]\ntip = "tip"\n')  # a role that is its own link: fine
    assert robots.load(bad).frames == {"tip": "tip"}


def test_integrity_5_other_robot_file_nonsense_is_refused(two_dir) -> None:
    bad = two_dir / "bad.toml"
    moved = two_dir / "urdf" / "moved.urdf"
    moved.write_text(TWO.replace('<origin xyz="0 0 0.25"/>', '<origin xyz="0 0 0.35"/>'))
    for text, message in [
        ('urdf = "urdf/two.urdf"\ncollision_urdf = "urdf/moved.urdf"\n',
         r"bad.toml: 'collision_urdf' .*moved.urdf is not the tree of 'urdf' .*two.urdf: joint 'j2' has another <origin>"),
        ('urdf = "urdf/two.urdf"\nname = "../up"\n', r"bad.toml: 'name' '../up' cannot name a file"),
        ('urdf = "urdf/two.urdf"\nlocked_joints = ["j1", "j1"]\n', r"bad.toml: 'locked_joints' names 'j1' twice"),
        ('urdf = "urdf/two.urdf"\nsrdf = "urdf/two.urdf"\n', r"cannot parse SRDF .*two.urdf: <robot> has a <link> element: this is a URDF, not an SRDF"),
    ]:
        bad.write_text(text)
        with pytest.raises(RobotFileError, match=message):
            robots.load(bad)
    # a continuous joint locked by value (its angle; refused before): Rust and Pinocchio agree
    bad.write_text('urdf = "urdf/two.urdf"\nlocked_joints = { j1 = 0.7 }\n')
    robot = robots.load(bad)
    assert robot.nq == 2 and robot.locked_joints == {"j1": 0.7}
    for q in robot.random_configurations(5, 0):
        pin.framesForwardKinematics(robot.model, robot.data, q)
        np.testing.assert_allclose(robot.link_poses(q, ["tip"])[0], robot.data.oMf[robot.model.getFrameId("tip")].homogeneous,
                                   atol=1e-12)


def test_integrity_rerun_self_collision_cache_is_checked_on_read(two_dir, tmp_path, monkeypatch) -> None:
    # A cached pair list is read back only when its bytes match the sha256 beside it and every
    # pair names links of the robot and a known reason; anything else is recomputed (a warning
    # naming the file when the bytes changed), never used to skip another pair.
    import json

    from genplan.cache import hash_path, save_text
    from genplan.robots import compute_disabled_pairs

    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path / "cache"))
    robot = robots.load(two_dir / "urdf" / "two.urdf")
    found = compute_disabled_pairs(robot, samples=2000)
    (path,) = (tmp_path / "cache" / "self_collision").glob("two_*.json")
    assert hash_path(path).is_file()
    data = json.loads(path.read_text())
    assert ["base", "l1", "Adjacent"] in data["pairs"]

    def rewritten(pairs):
        return json.dumps({**data, "pairs": pairs}, indent=1)

    # the file edited behind the cache's back: base-l2 (which does collide) would be skipped
    flipped = [["base", "l2", r] if (a, b) == ("base", "l1") else [a, b, r] for a, b, r in data["pairs"]]
    path.write_text(rewritten(flipped))
    with pytest.warns(RuntimeWarning, match=re.escape(str(path))):
        again = compute_disabled_pairs(robot, samples=2000)
    assert again == found and ("base", "l2") not in again.pairs
    assert json.loads(path.read_text()) == data  # rewritten with its hash
    # consistent hash, but a link the robot lacks or an unknown reason: recomputed
    for bad in ([["base", "hand", "Adjacent"]], [["base", "l1", "Sometimes"]], [["base", "l1"]], [[1, 2, "Never"]]):
        save_text(path, rewritten(bad))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert compute_disabled_pairs(robot, samples=2000) == found
        assert json.loads(path.read_text()) == data
    # written before the hash existed (no sidecar): recomputed, then kept with its hash
    hash_path(path).unlink()
    path.write_text(rewritten(flipped))
    assert compute_disabled_pairs(robot, samples=2000) == found and hash_path(path).is_file()


def test_a_preset_takes_the_keywords_of_a_urdf() -> None:
    """The Panda with its fingers open for a grasp: a preset's keys replaced by keywords, another
    robot (cached apart from the preset, the same one for the same keywords), checked as a robot
    file is (a joint it lacks, a value outside the limits: errors naming the key)."""
    import pinocchio as pin

    closed = robots.load("panda")
    assert robots.load("panda") is closed
    fingers = {"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04}
    open_ = robots.load("panda", locked_joints=fingers)
    assert open_ is robots.load("panda", locked_joints=dict(fingers))
    assert open_ is not closed and robots.load("panda") is closed
    assert open_.name == "panda" and open_.nq == closed.nq == 7
    assert open_.description["locked_joints"] == fingers
    # the fingers stand 4 cm from the hand's middle plane each; the preset's at its SRDF's
    # "default" state, 1 mm
    def width(robot: genplan.Robot) -> float:
        data = robot.model.createData()
        pin.framesForwardKinematics(robot.model, data, closed.q_default)
        left, right = (data.oMf[robot.model.getFrameId(f)].translation for f in ("panda_leftfinger", "panda_rightfinger"))
        return float(np.linalg.norm(left - right))

    assert abs(width(open_) - 0.08) < 1e-9 and abs(width(closed) - 0.002) < 1e-9
    assert robots.load("panda", locked_joints=fingers, name="panda_open").name == "panda_open"
    with pytest.raises(UnknownNameError, match=r"unknown joint 'nope' \(locked_joints of robot 'panda'"):
        robots.load("panda", locked_joints={"nope": 0.0})
    with pytest.raises(RobotFileError, match="locked joint 'panda_finger_joint1' at 0.5 is outside its limits"):
        robots.load("panda", locked_joints={"panda_finger_joint1": 0.5})
