"""genplan.robots: loading, limits, frames, configurations, errors."""

import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan import robots
from genplan.errors import RobotFileError, ShapeError, UnknownNameError


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


def test_robot_input_errors_name_the_file_and_the_key(two_dir, monkeypatch) -> None:
    monkeypatch.chdir(two_dir)
    bad = two_dir / "bad.toml"
    for text, error, message in [
        ('urdf = "urdf/two.urdf"\nfloating = true\n', RobotFileError, r"bad.toml.*unknown key 'floating' \(known: name, urdf"),
        ('urdf = "urdf/nope.urdf"\n', RobotFileError, r"bad.toml.*'urdf':.*nope.urdf does not exist"),
        ('urdf = "urdf/two.urdf"\n[frames]\ntool = "hand"\n', UnknownNameError, r"bad.toml: frame 'tool' = 'hand' is not a link"),
        ('urdf = "urdf/two.urdf"\nlocked_joints = ["j9"]\n', UnknownNameError, r"locked joint 'j9' is not a joint.*known: j1, j2, j3"),
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
    with pytest.raises(TypeError, match="takes no keywords"):
        robots.load("panda", frames={"a": "b"})
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
