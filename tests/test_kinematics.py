"""Rust forward kinematics (genplan._core.KinematicModel) against Pinocchio."""

import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan import _core
from genplan._arrays import as_configurations
from genplan.errors import GenplanError, NonFiniteError, RobotFileError, SettingsError, ShapeError, UnknownNameError
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
    # the native module checks (with the messages of genplan._arrays.as_configurations: the
    # element of a batch is (row, column))
    qs = np.zeros((3, 7))
    qs[2, 4] = np.inf
    with pytest.raises(NonFiniteError, match=r"^q: element \(2, 4\) is not finite \(inf\)$"):
        panda.kinematics.forward_kinematics(qs)
    with pytest.raises(ShapeError, match=r"^q: expected shape \(7,\) or \(n, 7\), got \(2, 3, 7\)$"):
        panda.kinematics.forward_kinematics(np.zeros((2, 3, 7)))
    # a row the core refuses is named in a batch
    qt = np.repeat(talos.q_default[None], 3, axis=0)
    qt[1, 3:7] = 0.0
    with pytest.raises(GenplanError, match=r"^q\[1\]: configuration q: the base quaternion"):
        talos.link_poses(qt)


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


# --- the boundary: configurations read in Rust, outputs written in place (issue 18) -----------

#: Inputs that are not a C-contiguous float64 array, each read as as_configurations reads it.
READABLE = {
    "list": lambda q: list(q),
    "tuple": lambda q: tuple(q),
    "list of ints": lambda q: [int(round(x)) for x in q],
    "float32": lambda q: q.astype(np.float32),
    "int64": lambda q: np.round(q).astype(np.int64),
    "strided": lambda q: np.repeat(q, 2)[::2],
    "reversed": lambda q: q[::-1].copy()[::-1],
    "numeric strings": lambda q: [str(x) for x in q],
    "numpy scalars": lambda q: [np.float32(x) for x in q],
}


@pytest.mark.parametrize("kind", list(READABLE))
def test_one_configuration_of_any_readable_form_gives_the_poses_of_its_float64_values(panda: genplan.Robot, kind: str) -> None:
    q = random_configurations(panda, 1, seed=3)[0]
    given = READABLE[kind](q)
    expected = panda.link_poses(as_configurations(given, panda.nq))
    np.testing.assert_array_equal(panda.link_poses(given), expected)
    np.testing.assert_array_equal(panda.link_poses(given, ["panda_hand"]), expected[[panda.kinematics.link_index("panda_hand")]])


@pytest.mark.parametrize("layout", ["C", "F", "rows strided", "float32", "list of lists"])
def test_a_batch_of_any_layout_gives_the_rows_poses(panda: genplan.Robot, layout: str) -> None:
    qs = random_configurations(panda, 40, seed=4)
    given = {
        "C": qs,
        "F": np.asfortranarray(qs),
        "rows strided": np.repeat(qs, 2, axis=0)[::2],
        "float32": qs.astype(np.float32),
        "list of lists": qs.tolist(),
    }[layout]
    ref = qs.astype(np.float32).astype(np.float64) if layout == "float32" else qs
    poses = panda.link_poses(given)
    assert poses.shape == (40, len(panda.kinematics.link_names), 4, 4) and poses.dtype == np.float64
    for i in (0, 17, 39):  # a batch row is the single call's answer, bit for bit
        np.testing.assert_array_equal(poses[i], panda.link_poses(ref[i]))


@pytest.mark.parametrize("bad, error, match", [
    (np.zeros(6), ShapeError, r"^q: expected shape \(7,\) or \(n, 7\), got \(6,\)$"),
    ([0.0] * 8, ShapeError, r"^q: expected shape \(7,\) or \(n, 7\), got \(8,\)$"),
    (np.zeros((2, 6), dtype=np.float32), ShapeError, r"^q: expected shape \(7,\) or \(n, 7\), got \(2, 6\)$"),
    (np.zeros(()), ShapeError, r"^q: expected shape \(7,\) or \(n, 7\), got \(\)$"),
    ([0, 0, np.nan, 0, 0, 0, 0], NonFiniteError, r"^q: element \(2,\) is not finite \(nan\)$"),
    (np.array([0, 0, 0, 0, 0, -np.inf, 0], dtype=np.float32), NonFiniteError, r"^q: element \(5,\) is not finite \(-inf\)$"),
    (np.full((2, 7), np.inf)[:, ::1], NonFiniteError, r"^q: element \(0, 0\) is not finite \(inf\)$"),
    (np.zeros(7) + 1j, ShapeError, r"^q: complex numbers"),
    ([None] * 7, ShapeError, r"^q: cannot be read"),
    (["a"] * 7, ShapeError, r"^q: cannot be read"),
    ([0.0] * 6 + [1e17], GenplanError, r"^q: configuration q: joint 'panda_joint7' \(q\[6\]\) is at"),
])
def test_bad_configurations_give_the_python_layers_errors(panda: genplan.Robot, bad, error, match) -> None:
    """The checks moved into Rust answer with the classes and messages of as_configurations."""
    with pytest.raises(error, match=match):
        panda.link_poses(bad)
    with pytest.raises(error, match=match):
        panda.link_poses(bad, ["panda_hand"])
    with pytest.raises(error, match=match):
        panda.collision_world().in_collision(bad)


def test_poses_as_float32_and_into_a_given_array(panda: genplan.Robot) -> None:
    qs = random_configurations(panda, 30, seed=8)
    ref = panda.link_poses(qs, ["panda_hand", "panda_link3"])
    f32 = panda.link_poses(qs, ["panda_hand", "panda_link3"], dtype=np.float32)
    assert f32.dtype == np.float32 and f32.shape == ref.shape
    np.testing.assert_array_equal(f32, ref.astype(np.float32))
    assert panda.link_poses(qs[0], dtype="float32").dtype == np.float32
    assert panda.link_poses(qs[0], dtype=np.float64).dtype == np.float64
    for dtype in (np.float64, np.float32):
        out = np.full((30, 2, 4, 4), np.nan, dtype=dtype)
        got = panda.link_poses(qs, ["panda_hand", "panda_link3"], out=out)
        assert got is out
        np.testing.assert_array_equal(out, ref.astype(dtype))
    one = np.empty((1, 4, 4))
    assert panda.link_poses(qs[3], ["panda_hand"], out=one) is one
    np.testing.assert_array_equal(one, ref[3, :1])


@pytest.mark.parametrize("kwargs, error, match", [
    ({"dtype": np.int32}, SettingsError, r"^dtype: expected float64 or float32, got "),
    ({"dtype": "nonsense"}, SettingsError, r"^dtype: expected float64 or float32"),
    ({"out": np.empty((5, 1, 4, 4))}, ShapeError, r"^out: expected shape \(4, 1, 4, 4\), got \(5, 1, 4, 4\)$"),
    ({"out": np.empty((4, 1, 4, 4), dtype=np.int64)}, ShapeError, r"^out: expected dtype float64 or float32, got int64$"),
    ({"out": np.empty((4, 1, 4, 4)), "dtype": np.float32}, ShapeError, r"^out: its dtype is float64, but dtype=float32"),
    ({"out": np.empty((4, 1, 4, 8))[..., ::2]}, ShapeError, r"^out: the array must be C-contiguous$"),
    ({"out": [[0.0]]}, ShapeError, r"^out: expected a numpy array, got list$"),
])
def test_bad_outputs_are_refused_before_any_work(panda: genplan.Robot, kwargs, error, match) -> None:
    qs = random_configurations(panda, 4, seed=9)
    with pytest.raises(error, match=match):
        panda.link_poses(qs, ["panda_hand"], **kwargs)


def test_a_read_only_or_aliased_output_is_refused(panda: genplan.Robot) -> None:
    qs = random_configurations(panda, 4, seed=9)
    out = np.zeros((4, 1, 4, 4))
    out.flags.writeable = False
    with pytest.raises(ShapeError, match="^out: the array cannot be written"):
        panda.link_poses(qs, ["panda_hand"], out=out)
    assert not out.any()
    # a batch q that is a view of out's memory: refused (it would be overwritten while read)
    buf = np.zeros((4, 1, 4, 4))
    buf.reshape(-1)[:28] = qs.reshape(-1)
    with pytest.raises(ShapeError, match="^out: the array cannot be written"):
        panda.link_poses(buf.reshape(-1)[:28].reshape(4, 7), ["panda_hand"], out=buf)
    # one row sharing out's memory is read before out is written
    one = np.zeros((1, 4, 4))
    one.reshape(-1)[:7] = qs[0]
    panda.link_poses(one.reshape(-1)[:7], ["panda_hand"], out=one)
    np.testing.assert_array_equal(one, panda.link_poses(qs[0], ["panda_hand"]))


def test_frames_subset_and_unknown_names(panda: genplan.Robot) -> None:
    names = panda.kinematics.link_names
    q = panda.q_default
    allp = panda.link_poses(q)
    sub = panda.link_poses(q, ("panda_link5", "panda_hand", "panda_link5"))
    np.testing.assert_array_equal(sub, allp[[names.index("panda_link5"), names.index("panda_hand"), names.index("panda_link5")]])
    assert panda.link_poses(q, []).shape == (0, 4, 4)
    with pytest.raises(UnknownNameError, match=r"^unknown link 'hand' \(known: .*panda_hand"):
        panda.link_poses(q, ["hand"])
    with pytest.raises(TypeError, match="^links: expected a list of link names, got a str"):
        panda.link_poses(q, "panda_hand")  # type: ignore[arg-type]


def test_talos_batch_in_place_matches_pinocchio(talos: genplan.Robot) -> None:
    qs = random_configurations(talos, 200, seed=11)
    links = talos.kinematics.link_names
    out = np.empty((200, len(links), 4, 4))
    talos.link_poses(qs, out=out)
    for k in (0, 99, 199):
        pin.framesForwardKinematics(talos.model, talos.data, qs[k])
        for i, link in enumerate(links):
            ref = talos.data.oMf[talos.model.getFrameId(link, pin.BODY)]
            np.testing.assert_allclose(out[k, i], ref.homogeneous, atol=1e-9)


@pytest.mark.parametrize("urdf", ["panda_description/urdf/panda.urdf", "mimic"])
def test_integrity_5_mimic_joints_fk_jacobians_and_com_match_pinocchio(urdf: str, tmp_path) -> None:
    """Mimic joints follow their master in the Rust kinematics as in Pinocchio's model
    (``buildModelFromUrdf(..., mimic=True)``): link poses, LOCAL frame Jacobians (the mimic's
    motion in its master's column) and the centre of mass with its Jacobian. The Panda with its
    fingers free (panda_finger_joint2 mimics panda_finger_joint1), and a mimic with a
    multiplier and an offset on a revolute joint (tests/test_robots.py MIMIC)."""
    if urdf == "mimic":
        from tests.test_robots import MIMIC

        path = tmp_path / "mimic.urdf"
        path.write_text(MIMIC.replace("<link name=\"l2\">", "<link name=\"l2\"><inertial><mass value=\"2\"/>"
                                      "<origin xyz=\"0.1 0.02 0\"/><inertia ixx=\"0.1\" iyy=\"0.1\" izz=\"0.1\"/></inertial>"))
    else:
        path = genplan.robots.robots_dir() / urdf
    robot = genplan.load(path)
    assert robot.kinematics.mimic_joints and robot.nq == robot.kinematics.nq == robot.model.nq
    native = _core.Projector(robot.kinematics, [{"type": "joint_limits"}])
    links = robot.kinematics.link_names
    qs = robot.random_configurations(30, 5)
    poses = robot.link_poses(qs)
    for q, pose in zip(qs, poses):
        pin.computeJointJacobians(robot.model, robot.data, q)
        pin.updateFramePlacements(robot.model, robot.data)
        for i, link in enumerate(links):
            fid = robot.model.getFrameId(link, pin.BODY)
            np.testing.assert_allclose(pose[i], robot.data.oMf[fid].homogeneous, atol=1e-12, err_msg=link)
            ref = pin.getFrameJacobian(robot.model, robot.data, fid, pin.LOCAL)
            np.testing.assert_allclose(native.frame_jacobian_local(list(q), link), ref, atol=1e-12, err_msg=link)
        jcom = pin.jacobianCenterOfMass(robot.model, robot.data, q, False)
        com, jac = native.center_of_mass(list(q))
        np.testing.assert_allclose(com, robot.data.com[0], atol=1e-12)
        np.testing.assert_allclose(jac, jcom, atol=1e-12)
