"""Rust forward kinematics (genplan._core.KinematicModel) against Pinocchio."""

import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan import _core
from genplan.errors import GenplanError, NonFiniteError, RobotFileError, ShapeError, UnknownNameError
from tests.conftest import random_configurations


@pytest.mark.parametrize("name", ["panda", "talos", "ur5"])
def test_rust_fk_matches_pinocchio_on_1000_configurations(name: str) -> None:
    robot = genplan.load(name)
    qs = random_configurations(robot, 1000, seed=7)
    links = robot.kinematics.link_names
    rust = robot.link_poses(qs)  # (1000, L, 4, 4)
    assert rust.shape == (1000, len(links), 4, 4)
    frame_ids = [robot.model.getFrameId(link, pin.BODY) for link in links]
    assert all(fid < robot.model.nframes for fid in frame_ids)
    max_pos = max_rot = 0.0
    for k, q in enumerate(qs):
        pin.framesForwardKinematics(robot.model, robot.data, q)
        for i, fid in enumerate(frame_ids):
            ref = robot.data.oMf[fid]
            max_pos = max(max_pos, float(np.abs(ref.translation - rust[k, i, :3, 3]).max()))
            max_rot = max(max_rot, float(np.linalg.norm(pin.log3(ref.rotation.T @ rust[k, i, :3, :3]))))
    assert max_pos <= 1e-9, max_pos
    assert max_rot <= 1e-9, max_rot


@pytest.mark.parametrize("name", ["panda", "talos", "ur5", "kinova"])
def test_rust_default_joint_order_is_pinocchios(name: str) -> None:
    """The pure-Rust loader (used by cargo benches) orders q like Pinocchio does."""
    robot = genplan.load(name)
    model, _ = _core.load_robot(robot.source, genplan.robots.default_package_dirs())
    assert model.active_joints == robot.joint_names
    assert model.nq == robot.nq and model.nv == robot.nv
    finite = np.isfinite(robot.lower)
    np.testing.assert_array_equal(model.lower[finite], robot.lower[finite])
    np.testing.assert_array_equal(model.upper[finite], robot.upper[finite])


def test_single_and_selected_links(panda: genplan.Robot) -> None:
    q = panda.q_default
    poses = panda.link_poses(q, ["panda_hand", "panda_link0"])
    assert poses.shape == (2, 4, 4)
    ref = panda.frame_placement(q, "hand")
    np.testing.assert_allclose(poses[0][:3, 3], ref.translation, atol=1e-12)
    np.testing.assert_allclose(poses[1], np.eye(4), atol=1e-15)


def test_bad_configurations_raise_clear_errors(panda: genplan.Robot, talos: genplan.Robot) -> None:
    with pytest.raises(ShapeError, match=r"expected shape \(7,\) or \(n, 7\), got \(6,\)"):
        panda.link_poses(np.zeros(6))
    with pytest.raises(NonFiniteError, match="not finite"):
        panda.link_poses([0, 0, np.nan, 0, 0, 0, 0])
    with pytest.raises(ShapeError, match="cannot be read as an array"):
        panda.link_poses(["a"] * 7)
    with pytest.raises(UnknownNameError, match="unknown link 'nope'"):
        panda.link_poses(panda.q_default, ["nope"])
    q = talos.q_default.copy()
    q[3:7] = 0.0
    with pytest.raises(GenplanError, match="quaternion"):
        talos.link_poses(q)
    # the native module checks too (and names the row of a batch)
    qs = np.zeros((3, 7))
    qs[2, 4] = np.inf
    with pytest.raises(NonFiniteError, match=r"q\[2\]: configuration q: element 4 is not finite"):
        panda.kinematics.forward_kinematics(qs)
    with pytest.raises(ShapeError, match="expected shape"):
        panda.kinematics.forward_kinematics(np.zeros((2, 3, 7)))


def test_urdf_errors(tmp_path) -> None:
    with pytest.raises(FileNotFoundError, match="does_not_exist.urdf"):
        _core.KinematicModel.from_urdf(tmp_path / "does_not_exist.urdf")
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot>")
    with pytest.raises(RobotFileError, match="cannot parse URDF .*bad.urdf"):
        _core.KinematicModel.from_urdf(bad)
    loop = tmp_path / "twice.urdf"
    loop.write_text(
        "<robot name='x'><link name='a'/><link name='b'/>"
        "<joint name='j1' type='fixed'><parent link='a'/><child link='b'/></joint>"
        "<joint name='j2' type='fixed'><parent link='a'/><child link='b'/></joint></robot>"
    )
    with pytest.raises(RobotFileError, match="two parent joints"):
        _core.KinematicModel.from_urdf(loop)
