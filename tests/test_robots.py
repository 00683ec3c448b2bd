"""genplan.robots: loading, limits, frames, configurations, errors."""

import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan import robots
from genplan.errors import ShapeError, UnknownNameError


def test_unknown_robot_lists_the_known_ones() -> None:
    with pytest.raises(UnknownNameError, match=r"unknown robot 'atlas' \(known: panda, talos, ur5\)"):
        robots.load("atlas")
    with pytest.raises(UnknownNameError, match="unknown robot 'atlas'.*panda, talos, ur5"):
        robots.Robot("atlas")


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


def test_robots_dir_override(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("GENPLAN_ROBOTS_DIR", str(tmp_path / "missing"))
    with pytest.raises(FileNotFoundError, match="GENPLAN_ROBOTS_DIR"):
        robots.robots_dir()
    monkeypatch.setenv("GENPLAN_ROBOTS_DIR", str(tmp_path))
    with pytest.raises(FileNotFoundError, match="panda.urdf does not exist"):
        robots.Robot("panda")


def test_pinocchio_model_is_the_reduced_one(panda: genplan.Robot) -> None:
    assert [panda.model.names[i] for i in range(1, panda.model.njoints)] == panda.joint_names
    pin.framesForwardKinematics(panda.model, panda.data, panda.q_default)
