"""genplan.projection's multi-frame terms (RelativePose, RelativePosition in relative.py; PointAt,
Plane in frame.py): their Pinocchio Jacobians against finite differences, the native residuals and
Jacobians against Pinocchio's, the native solver against the Pinocchio one, task files, bad input."""

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan import projection as P
from genplan.errors import SettingsError, TaskFileError, UnknownNameError
from tests.conftest import random_configurations
from tests.test_projection import _fd_jacobian

# per robot: two frames on different branches (both move with q), and on one chain
FRAMES = {"panda": (("hand", "panda_link3"), ("panda_link7", "panda_link2")),
          "talos": (("right_hand", "left_hand"), ("left_sole", "right_hand"))}


def _relative_terms(robot):
    """The four kinds with non-trivial targets, masks, axes and normals."""
    (a, b), (c, d) = FRAMES[robot.name]
    rng = np.random.default_rng(3)
    target = pin.SE3(pin.utils.rpyToMatrix(*rng.normal(size=3)), rng.normal(size=3) * 0.3)
    axis = np.array([0.3, -0.2, 0.9]) / np.linalg.norm([0.3, -0.2, 0.9])
    return [
        P.RelativePose(name="pose", frame=a, relative_to=b, target=target, components=(1, 0.5, 2, 1, 0, 3)),
        P.RelativePose(name="chain_pose", frame=c, relative_to=d, target=target),
        P.RelativePosition(name="position", frame=a, relative_to=b, target=(0.1, -0.2, 0.3), axes=(1, 2, 0.5)),
        P.RelativePosition(name="chain_position", frame=d, relative_to=c, target=(0.0, 0.0, 0.0)),
        P.PointAt(name="point_at", frame=a, axis=axis, point=(0.4, -0.3, 0.6)),
        P.Plane(name="plane", frame=c, normal=(0.0, 0.6, -0.8), offset=0.1),
    ]


@pytest.mark.parametrize("name", ["panda", "talos"])
def test_pinocchio_jacobians_match_finite_differences(name: str) -> None:
    robot = genplan.load(name)
    for q in random_configurations(robot, 4, seed=11):
        for term in _relative_terms(robot):
            bound = term.bind(robot)
            analytic = bound.jacobian(P._State(robot, q, True))
            np.testing.assert_allclose(analytic, _fd_jacobian(robot, bound, q), rtol=1e-4, atol=2e-6, err_msg=term.name)


@pytest.mark.parametrize("name", ["panda", "talos"])
def test_native_residuals_and_jacobians_match_pinocchio(name: str) -> None:
    """The Rust terms (rust/core/src/projection/terms.rs) against their Pinocchio twins, at 1e-9, on a
    fixed base (Panda) and a free-flyer (Talos)."""
    robot = genplan.load(name)
    qs = random_configurations(robot, 6, seed=12)
    for term in _relative_terms(robot):
        native = genplan._core.Projector(robot.kinematics, [term.to_native(robot)])
        r, j = native.primary_residuals(qs, jacobian=True)
        bound = term.bind(robot)
        for i, q in enumerate(qs):
            s = P._State(robot, q, True)
            np.testing.assert_allclose(r[i], bound.residual(s), atol=1e-9, err_msg=term.name)
            np.testing.assert_allclose(j[i], bound.jacobian(s), atol=1e-9, err_msg=term.name)


def _two_hands_task(robot, q_ref):
    """Talos holding an object in both hands: the right hand's pose in the left's fixed (as at
    ``q_ref``), the left hand's position given, the feet where they are at the default."""
    right_in_left = robot.frame_placement(q_ref, "left_hand").actInv(robot.frame_placement(q_ref, "right_hand"))
    feet = [P.FramePose(name=f, frame=f, target=robot.frame_placement(robot.q_default, f), weight=10)
            for f in ("left_sole", "right_sole")]
    return P.Task(name="two_hands", primary=[
        P.RelativePose(name="grip", frame="right_hand", relative_to="left_hand", target=right_in_left, weight=10,
                       tolerance=1e-4),
        P.FramePosition(name="left", frame="left_hand", target=robot.frame_placement(q_ref, "left_hand").translation,
                        weight=10, tolerance=1e-4),
        *feet, P.JointLimits(weight=10)], secondary=[P.Posture()])


def test_native_solver_follows_the_pinocchio_solver_on_a_two_hand_task(talos: genplan.Robot) -> None:
    q_ref = talos.q_default.copy()
    task = _two_hands_task(talos, q_ref)
    rng = np.random.default_rng(4)
    q0 = np.repeat(talos.q_default[None], 12, axis=0)
    q0[:, 7:] += rng.normal(scale=0.1, size=(12, talos.nq - 7))
    q0[:, 7:] = np.clip(q0[:, 7:], talos.lower[7:], talos.upper[7:])
    a = P.GaussNewtonProjector(talos, task, backend="native").solve_batch(q0)
    b = P.GaussNewtonProjector(talos, task, backend="pinocchio").solve_batch(q0)
    np.testing.assert_array_equal(a.success, b.success)
    assert a.success.mean() >= 0.9, a.residuals
    same = a.iterations == b.iterations
    assert same.mean() >= 0.9
    assert np.abs(a.q[same] - b.q[same]).max() < 1e-6
    for q in a.q[a.success]:  # the grip is what the task says
        rel = talos.frame_placement(q, "left_hand").actInv(talos.frame_placement(q, "right_hand"))
        assert np.abs(pin.log6(task.primary[0].target.actInv(rel)).vector).max() < 1e-4


def test_a_relative_target_per_row(panda: genplan.Robot) -> None:
    """solve_batch(targets=...) aims a RelativePose at one pose per row, as a FramePose."""
    rng = np.random.default_rng(8)
    goals = panda.random_configurations(10, rng)
    rows = np.array([panda.frame_placement(q, "panda_link3").actInv(panda.frame_placement(q, "hand")).homogeneous
                     for q in goals])
    task = P.Task(primary=[P.RelativePose(name="rel", frame="hand", relative_to="panda_link3", target=rows[0],
                                          tolerance=1e-6), P.JointLimits()])
    # the hand has 4 joints below panda_link3 for 6 numbers: start near each row's goal
    q0 = np.clip(goals + rng.normal(scale=0.2, size=goals.shape), panda.lower, panda.upper)
    out = P.GaussNewtonProjector(panda, task).solve_batch(q0, targets={"rel": rows})
    assert out.success.mean() >= 0.8, out.residuals
    for q, m in zip(out.q[out.success], rows[out.success]):
        rel = panda.frame_placement(q, "panda_link3").actInv(panda.frame_placement(q, "hand"))
        np.testing.assert_allclose(rel.homogeneous, m, atol=1e-5)
    with pytest.raises(genplan.errors.ShapeError, match=r"targets\['rel'\]: expected shape \(10, 4, 4\)"):
        P.GaussNewtonProjector(panda, task).solve_batch(goals, targets={"rel": rows[:, :3]})


def test_task_files_round_trip_and_resolve_default_relative_targets(tmp_path, panda: genplan.Robot) -> None:
    task = P.Task(name="multi", primary=_relative_terms(panda), secondary=[P.Posture()])
    again = P.Task.from_file(task.to_file(tmp_path / "t.toml"), panda)
    assert again.to_dict() == task.to_dict()
    q0 = panda.random_configurations(3, 1)
    np.testing.assert_array_equal(P.GaussNewtonProjector(panda, task).solve_batch(q0).q,
                                  P.GaussNewtonProjector(panda, again).solve_batch(q0).q)
    # "default": the frame's placement in relative_to's at the robot's default configuration
    (tmp_path / "d.toml").write_text(
        '[[primary]]\nkind = "RelativePose"\nframe = "hand"\nrelative_to = "panda_link3"\ntarget = "default"\n\n'
        '[[primary]]\nkind = "RelativePosition"\nframe = "hand"\nrelative_to = "panda_link3"\ntarget = "default"\n\n'
        '[[primary]]\nkind = "PointAt"\nframe = "hand"\naxis = [0, 0, 1]\npoint = [0.5, 0, 0]\n\n'
        '[[primary]]\nkind = "Plane"\nframe = "hand"\nnormal = [0, 0, 1]\noffset = 0.5\n')
    t = P.Task.from_file(tmp_path / "d.toml", panda)
    rel = panda.frame_placement(panda.q_default, "panda_link3").actInv(panda.frame_placement(panda.q_default, "hand"))
    np.testing.assert_allclose(t.primary[0].target.homogeneous, rel.homogeneous, atol=1e-12)
    np.testing.assert_allclose(t.primary[1].target, rel.translation, atol=1e-12)
    native = genplan._core.Projector(panda.kinematics, [term.to_native(panda) for term in t.primary[:2]])
    r, _ = native.primary_residuals(panda.q_default[None], jacobian=False)
    assert np.abs(r).max() < 1e-12


def test_bad_multi_frame_terms_are_refused_before_any_work(tmp_path, panda: genplan.Robot) -> None:
    cases = [
        (P.RelativePose(frame="hand", relative_to="hand", target=np.eye(4)), SettingsError, r"relative_to 'hand' is the frame itself"),
        (P.RelativePose(frame="hand", target=np.eye(4)), SettingsError, r"RelativePose\(hand\).relative_to: not set"),
        (P.RelativePosition(frame="hand", relative_to="elbow", target=(0, 0, 0)), UnknownNameError, r"no frame 'elbow'"),
        (P.RelativePosition(frame="hand", relative_to="panda_link2"), SettingsError, r"RelativePosition\(hand\).target: not set"),
        (P.PointAt(frame="hand", axis=(0, 0, 2), point=(0, 0, 0)), SettingsError, r"PointAt\(hand\).axis: expected a unit vector"),
        (P.PointAt(frame="hand"), SettingsError, r"PointAt\(hand\).point: not set"),
        (P.Plane(frame="hand", normal=(0, np.nan, 1)), genplan.errors.NonFiniteError, r"Plane\(hand\).normal"),
    ]
    for term, error, message in cases:
        for backend in ("native", "pinocchio"):
            with pytest.raises(error, match=message):
                P.GaussNewtonProjector(panda, P.Task(primary=[term]), backend=backend)
    # the core refuses what the Python layer would have (a dict written by hand)
    with pytest.raises(ValueError, match=r"term 'x': axis must be a unit vector"):
        genplan._core.Projector(panda.kinematics, [{"type": "point_at", "name": "x", "link": "panda_hand",
                                                     "axis": [0.0, 0.0, 3.0], "point": [0.0, 0.0, 0.0]}])
    with pytest.raises(ValueError, match=r"term 'x': relative_to is the link itself"):
        genplan._core.Projector(panda.kinematics, [{"type": "relative_position", "name": "x", "link": "panda_hand",
                                                     "relative_to": "panda_hand", "target": [0.0, 0.0, 0.0]}])
    (tmp_path / "bad.toml").write_text('[[primary]]\nkind = "RelativePose"\nframe = "hand"\nrelative_to = "panda_link3"\n')
    with pytest.raises(TaskFileError, match=r"bad.toml: \[\[primary\]\] 1 \('RelativePose'\): RelativePose needs a target"):
        P.Task.from_file(tmp_path / "bad.toml", panda)
    (tmp_path / "bad2.toml").write_text('[[primary]]\nkind = "Plane"\nframe = "hand"\nheight = 0.3\n')
    with pytest.raises(TaskFileError, match=r"Plane has no field 'height' \(fields: weight, tolerance, name, frame, normal, offset\)"):
        P.Task.from_file(tmp_path / "bad2.toml", panda)


def test_the_baxter_tray_example_holds_the_grip_wherever_ik_puts_the_tray() -> None:
    """examples/baxter: a robot file and a task file alone give a two-arm task whose IK holds the
    grippers' relative pose (0.4 m apart, pointing down) at targets across its condition box."""
    root = Path(__file__).resolve().parent.parent / "examples" / "baxter"
    baxter = genplan.load(root / "baxter.toml")
    task = P.load_task(root / "tray.toml", baxter)
    P.check_task_use(task, baxter)  # a learned sampler's training and card can use it (raises if not)
    targets = np.random.default_rng(5).uniform(task.condition.low, task.condition.high, size=(8, 3))
    res = genplan.solve_ik(baxter, task, targets, init="uniform", restarts=100, seed=0)
    assert np.all(res.success)
    for q, p in zip(res.q, targets):
        left, right = baxter.frame_placement(q, "left_gripper"), baxter.frame_placement(q, "right_gripper")
        np.testing.assert_allclose(left.translation, p, atol=1e-3)
        # 0.4 m apart along the left gripper's y, level (the heading about the vertical is free)
        np.testing.assert_allclose(right.translation - left.translation, left.rotation @ (0.0, 0.4, 0.0), atol=2e-3)
        assert abs(right.translation[2] - left.translation[2]) < 2e-3
        np.testing.assert_allclose(left.rotation[:, 2], (0.0, 0.0, -1.0), atol=2e-3)
        np.testing.assert_allclose(right.rotation, left.rotation, atol=2e-3)


def test_current_targets_are_resolved_at_a_configuration(tmp_path, panda: genplan.Robot) -> None:
    """``target = "current"``: the placement the frame has at a configuration named later
    (``Task.at_configuration``), e.g. a grip held as it is at a plan's start; until then the
    solvers refuse the term, and the file round-trips with it."""
    (tmp_path / "c.toml").write_text(
        '[[primary]]\nkind = "RelativePose"\nname = "grip"\nframe = "hand"\nrelative_to = "panda_link3"\ntarget = "current"\n\n'
        '[[primary]]\nkind = "FrameOrientation"\nname = "level"\nframe = "hand"\ntarget = "current"\naxes = [1, 1, 0]\n')
    task = P.Task.from_file(tmp_path / "c.toml")  # no robot needed until it is resolved
    assert P.Task.from_file(task.to_file(tmp_path / "again.toml")).to_dict() == task.to_dict()
    for backend in ("native", "pinocchio"):
        with pytest.raises(SettingsError, match=r"RelativePose\(hand\).target: \"current\" is resolved at a configuration first"):
            P.GaussNewtonProjector(panda, task, backend=backend)
    q = panda.random_configurations(1, 3)[0]
    at_q = task.at_configuration(panda, q)
    rel = panda.frame_placement(q, "panda_link3").actInv(panda.frame_placement(q, "hand"))
    np.testing.assert_allclose(at_q.primary[0].target.homogeneous, rel.homogeneous, atol=1e-12)
    np.testing.assert_allclose(at_q.primary[1].target, panda.frame_placement(q, "hand").rotation, atol=1e-12)
    native = genplan._core.Projector(panda.kinematics, [t.to_native(panda) for t in at_q.primary])
    assert np.abs(native.primary_residuals(q[None], jacobian=False)[0]).max() < 1e-9
    # from elsewhere, the solve comes back to the grip and the hand's tilt it had at q
    out = P.GaussNewtonProjector(panda, P.Task(primary=[*at_q.primary, P.JointLimits()])).solve(
        np.clip(q + 0.1, panda.lower, panda.upper))
    assert out.success
