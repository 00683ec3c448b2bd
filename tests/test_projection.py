"""genplan.projection: Jacobians, the native solver against the Pinocchio one, the paper's tasks,
bad input."""

import dataclasses
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan import projection as P
from genplan.errors import GenplanError, NonFiniteError, ShapeError, TaskFileError, UnknownNameError
from tests.conftest import random_configurations
from tests.interrupt import MAX_LATENCY_S, ctrl_c_latency


def _fd_jacobian(robot, bound, q, eps=1e-7):
    """Central finite differences of a bound term's residual in the tangent space."""
    def res(x):
        return bound.residual(P._State(robot, pin.integrate(robot.model, q, x), False))

    cols = []
    for k in range(robot.nv):
        e = np.zeros(robot.nv)
        e[k] = eps
        cols.append((res(e) - res(-e)) / (2 * eps))
    return np.array(cols).T


def _terms(robot):
    q_ref = robot.random_configurations(1, 99)[0]
    hand = "hand" if robot.name == "panda" else "right_hand"
    target = robot.frame_placement(q_ref, hand)
    return [
        P.FramePose(frame=hand, target=target),
        P.FramePosition(frame=hand, target=target.translation + 0.1),
        P.FrameOrientation(frame=hand, target=pin.utils.rpyToMatrix(0.3, -0.2, 0.5), axes=(1, 1, 0), offset=P.PANDA_HAND_OFFSET),
        P.Posture(q_nom=q_ref, joint_weights=np.linspace(0.5, 2.0, robot.nv)),
        P.JointLimits(margin=10.0),  # wide margin: every row active, so every column is checked
        P.ComBox(lower=(-0.01, -0.01, 0.3), upper=(0.01, 0.01, 0.4), margin=0.0),
        P.PointAt(frame=hand, axis=np.array([0.3, -0.2, 0.9]) / np.linalg.norm([0.3, -0.2, 0.9]), point=(0.5, 0.3, 0.4)),
        P.Plane(frame=hand, normal=(0.6, 0.0, 0.8), offset=0.4),
    ]


@pytest.mark.parametrize("name", ["panda", "talos"])
def test_pinocchio_jacobians_match_finite_differences(name: str) -> None:
    robot = genplan.load(name)
    for q in random_configurations(robot, 5, seed=1):
        for term in _terms(robot):
            bound = term.bind(robot)
            s = P._State(robot, q, True)
            analytic = bound.jacobian(s)
            numeric = _fd_jacobian(robot, bound, q)
            if isinstance(term, P.JointLimits):  # piecewise linear: compare where outside the limits
                rows = np.abs(bound.residual(s)) > 1e-6
                analytic, numeric = analytic[rows], numeric[rows]
            if isinstance(term, P.ComBox):
                rows = np.abs(bound.residual(s)) > 1e-6
                analytic, numeric = analytic[rows], numeric[rows]
            np.testing.assert_allclose(analytic, numeric, rtol=1e-4, atol=2e-6, err_msg=f"{name} {type(term).__name__}")


@pytest.mark.parametrize("name", ["panda", "talos", "ur5"])
def test_native_frame_jacobian_and_com_match_pinocchio(name: str) -> None:
    robot = genplan.load(name)
    native = genplan._core.Projector(robot.kinematics, [{"type": "joint_limits"}])
    links = robot.kinematics.link_names
    for q in random_configurations(robot, 20, seed=2):
        pin.computeJointJacobians(robot.model, robot.data, q)
        pin.updateFramePlacements(robot.model, robot.data)
        for link in links[:: max(1, len(links) // 8)]:
            fid = robot.model.getFrameId(link, pin.BODY)
            ref = pin.getFrameJacobian(robot.model, robot.data, fid, pin.LOCAL)
            np.testing.assert_allclose(native.frame_jacobian_local(list(q), link), ref, atol=1e-9, err_msg=link)
        jcom = pin.jacobianCenterOfMass(robot.model, robot.data, q, False)
        com, jac = native.center_of_mass(list(q))
        np.testing.assert_allclose(com, robot.data.com[0], atol=1e-9)
        np.testing.assert_allclose(jac, jcom, atol=1e-9)


@pytest.mark.parametrize("name", ["panda", "talos"])
@pytest.mark.parametrize("kind", ["projection", "ik"])
@pytest.mark.parametrize("active_set", [False, True])
def test_native_solver_follows_the_pinocchio_solver(name: str, kind: str, active_set: bool) -> None:
    """Same algorithm in Rust and in Python/Pinocchio, with the paper's clipped step and with
    the joint limits as an active set: same iteration counts, same answers."""
    settings = P.SolverSettings(active_set=active_set)
    robot = genplan.load(name)
    task = P.paper_task(robot, kind)
    rng = np.random.default_rng(5)
    q0 = robot.random_configurations(25, rng)
    targets = None
    if kind == "ik":
        box = P.PANDA_IK_BOX if name == "panda" else P.TALOS_IK_BOX
        targets = {task.primary[0].name: rng.uniform(box[0], box[1], size=(25, 3))}
    a = P.GaussNewtonProjector(robot, task, settings, backend="native").solve_batch(q0, targets=targets)
    b = P.GaussNewtonProjector(robot, task, settings, backend="pinocchio").solve_batch(q0, targets=targets)
    np.testing.assert_array_equal(a.success, b.success)
    assert (a.iterations == b.iterations).mean() >= 0.95
    # rounding can flip one line-search decision on a long solve: nearly all answers are the same
    same = a.success & (a.iterations == b.iterations)
    agree = np.abs(a.q[same] - b.q[same]).max(axis=1) < 1e-6
    assert agree.mean() >= 0.9, agree
    assert a.success.mean() > 0.6


def test_the_active_set_holds_joints_at_their_limits_instead_of_losing_the_step() -> None:
    """``active_set=True``: a joint at a limit whose step points out is held and the others take
    the step, instead of the clipping throwing that part of the step away. Without the task's
    joint-limit residual (only the clipping keeps q in range) it solves clearly more Panda IK
    targets from uniform starts (here 74.0 % vs 66.5 %); the answers stay in range."""
    panda = genplan.load("panda")
    task = P.paper_task(panda, "ik")
    task = dataclasses.replace(task, primary=[t for t in task.primary if t.name != "joint_limits"])
    rng = np.random.default_rng(7)
    q0 = panda.random_configurations(200, rng)
    targets = {task.primary[0].name: rng.uniform(P.PANDA_IK_BOX[0], P.PANDA_IK_BOX[1], size=(200, 3))}
    clipped = P.GaussNewtonProjector(panda, task).solve_batch(q0, targets=targets)
    held = P.GaussNewtonProjector(panda, task, P.SolverSettings(active_set=True)).solve_batch(q0, targets=targets)
    assert held.success.mean() >= clipped.success.mean() + 0.05, (held.success.mean(), clipped.success.mean())
    assert np.all(held.q >= panda.lower) and np.all(held.q <= panda.upper)


def test_panda_projection_keeps_the_gripper_horizontal(panda: genplan.Robot) -> None:
    res = P.GaussNewtonProjector(panda, P.panda_task("projection")).solve_batch(panda.random_configurations(200, 0))
    assert res.success.mean() >= 0.98
    for q in res.q[res.success]:
        rot = panda.frame_placement(q, "hand").rotation @ P.PANDA_HAND_OFFSET
        # a pure rotation about the world z axis: its z column is the world z axis
        assert np.abs(rot[:, 2] - [0, 0, 1]).max() < 3e-4
        assert np.all(q >= panda.lower - 1e-3) and np.all(q <= panda.upper + 1e-3)
        assert res.residuals["hand_orientation"].max() < 1e-4


def test_talos_projection_fixes_the_feet_and_keeps_static_balance(talos: genplan.Robot) -> None:
    task = P.talos_task(talos, "projection")
    res = P.GaussNewtonProjector(talos, task).solve_batch(talos.random_configurations(100, 0))
    assert res.success.mean() >= 0.85
    left0 = talos.frame_placement(talos.q_default, "left_sole")
    for q in res.q[res.success]:
        left = talos.frame_placement(q, "left_sole")
        assert np.abs(pin.log6(left0.actInv(left)).vector).max() < 1e-4
        com = pin.centerOfMass(talos.model, talos.data, q)
        assert np.all(com >= P.TALOS_COM_BOX[0] - 1e-3) and np.all(com <= P.TALOS_COM_BOX[1] + 1e-3)
        # the posture task holds the left arm at its default
        left_arm = [7 + talos.joint_names.index(j) for j in talos.joint_names if j.startswith("arm_left")]
        np.testing.assert_allclose(q[left_arm], talos.q_default[left_arm], atol=1e-3)


def test_ik_reaches_targets_given_per_row(panda: genplan.Robot) -> None:
    task = P.panda_task("ik")
    rng = np.random.default_rng(1)
    targets = rng.uniform(P.PANDA_IK_BOX[0], P.PANDA_IK_BOX[1], size=(40, 3))
    res = P.GaussNewtonProjector(panda, task).solve_batch(panda.random_configurations(40, rng), targets={"hand_position": targets})
    assert res.success.mean() > 0.6
    for q, t in zip(res.q[res.success], targets[res.success]):
        assert np.abs(panda.frame_placement(q, "hand").translation - t).max() < 1e-3


def test_large_batches_solve_each_row_with_its_own_target(panda: genplan.Robot) -> None:
    """Batches run in chunks (Ctrl-C is checked between them): each row keeps its own start and
    target, whatever chunk it falls in."""
    task = P.panda_task("ik")
    rng = np.random.default_rng(2)
    q0 = panda.random_configurations(600, rng)
    targets = rng.uniform(P.PANDA_IK_BOX[0], P.PANDA_IK_BOX[1], size=(600, 3))
    res = P.GaussNewtonProjector(panda, task).solve_batch(q0, targets={"hand_position": targets})
    for i in range(0, 600, 37):
        one = P.GaussNewtonProjector(panda, task.with_targets(hand_position=targets[i])).solve(q0[i])
        np.testing.assert_array_equal(one.q, res.q[i])
        assert one.iterations == res.iterations[i]


@pytest.mark.parametrize("targets", [False, True])
def test_ctrl_c_interrupts_a_long_solve_batch(panda: genplan.Robot, targets: bool) -> None:
    """Within 0.5 s of the signal. Every row aims at a hand target 3 m away and runs all its
    iterations: uninterrupted, the batch would take about 6 s on an idle 2-core machine."""
    task = P.panda_task("ik", target=[3.0, 0.0, 0.5])
    n = 15_000
    q0 = random_configurations(panda, n, seed=3)
    given = {"hand_position": np.tile([3.0, 0.0, 0.5], (n, 1))} if targets else None
    proj = P.GaussNewtonProjector(panda, task)
    assert ctrl_c_latency(lambda: proj.solve_batch(q0, targets=given)) < MAX_LATENCY_S


@pytest.mark.parametrize("backend", P.BACKENDS)
def test_unreachable_target_fails_softly_with_the_best_q(panda: genplan.Robot, backend: str) -> None:
    task = P.panda_task("ik", target=[3.0, 0.0, 0.5])
    res = P.GaussNewtonProjector(panda, task, backend=backend).solve(panda.q_default)
    assert not res.success
    assert res.iterations == 50
    assert res.residuals["hand_position"] > 1.0
    assert np.all(np.isfinite(res.q))
    # the best q points the hand at the target: the hand is at the edge of the workspace
    reach = np.linalg.norm(panda.frame_placement(res.q, "hand").translation[:2])
    assert reach > 0.7


def test_user_defined_task_and_python_term(panda: genplan.Robot) -> None:
    @dataclass(frozen=True)
    class HandHeight(P.Term):
        """r = z_hand - height (a user term with its own Jacobian)."""

        height: float = 0.5

        def bind(self, robot):
            fid = robot.frame_id("hand")
            term = self

            class Bound(P._BoundTerm):
                def __init__(self):
                    self.term = term

                def residual(self, s):
                    return np.array([s.placement(fid).translation[2] - term.height])

                def jacobian(self, s):
                    return (s.placement(fid).rotation @ s.frame_jacobian_local(fid)[:3])[2:3]

            return Bound()

    task = P.Task(primary=[HandHeight(name="height", height=0.4, weight=10, tolerance=1e-4), P.JointLimits()],
                  secondary=[P.Posture()], name="height")
    with pytest.raises(NotImplementedError, match="no native form; use backend='pinocchio'"):
        P.GaussNewtonProjector(panda, task)
    res = P.GaussNewtonProjector(panda, task, backend="pinocchio").solve(panda.q_default)
    assert res.success
    assert panda.frame_placement(res.q, "hand").translation[2] == pytest.approx(0.4, abs=1e-4)


def test_bad_input(panda: genplan.Robot) -> None:
    solver = P.GaussNewtonProjector(panda, P.panda_task("projection"))
    with pytest.raises(ShapeError, match=r"expected shape \(7,\)"):
        solver.solve(np.zeros(6))
    with pytest.raises(NonFiniteError, match="not finite"):
        solver.solve(np.full(7, np.nan))
    with pytest.raises(ShapeError, match="use solve_batch"):
        solver.solve(np.zeros((2, 7)))
    with pytest.raises(ShapeError, match=r"q0s: expected shape \(n, 7\)"):
        solver.solve_batch(np.zeros(7))
    with pytest.raises(UnknownNameError, match="no frame 'elbow'"):
        P.GaussNewtonProjector(panda, P.Task(primary=[P.FramePosition(frame="elbow", target=[0, 0, 0])]))
    with pytest.raises(UnknownNameError, match="unknown backend 'gpu'"):
        P.GaussNewtonProjector(panda, P.panda_task(), backend="gpu")
    with pytest.raises(UnknownNameError, match="unknown task kind 'walk'"):
        P.panda_task("walk")
    with pytest.raises(UnknownNameError, match="has no term named"):
        P.panda_task("ik").with_targets(foot=[0, 0, 0])
    with pytest.raises(ShapeError, match="expected 3 numbers"):
        P.GaussNewtonProjector(panda, P.panda_task("ik", target=[1.0, 2.0]))
    ik = P.GaussNewtonProjector(panda, P.panda_task("ik"))
    with pytest.raises(ShapeError, match="expected 2 finite rows"):
        ik.solve_batch(np.zeros((2, 7)), targets={"hand_position": np.zeros((3, 3))})
    with pytest.raises(UnknownNameError, match="unknown target term 'foot'"):
        ik.solve_batch(np.zeros((2, 7)), targets={"foot": np.zeros((2, 3))})
    with pytest.raises(GenplanError, match=r"weight must be in \(0, 1e6\]"):
        P.GaussNewtonProjector(panda, P.Task(primary=[P.JointLimits(weight=-1.0)]))
    with pytest.raises(GenplanError, match="at least one primary term"):
        P.GaussNewtonProjector(panda, P.Task(primary=[]))


@pytest.mark.parametrize("backend", P.BACKENDS)
def test_targets_that_are_not_real_numbers_name_themselves(panda: genplan.Robot, backend: str) -> None:
    """Findings PY-2 / PY-4 of tests/test_fuzz_inputs.py: a string leaked numpy's ValueError, a
    complex array lost its imaginary part."""
    ik = P.GaussNewtonProjector(panda, P.panda_task("ik"), backend=backend)
    with pytest.raises(ShapeError, match=r"^targets\['hand_position'\]: cannot be read"):
        ik.solve_batch(np.zeros((2, 7)), targets={"hand_position": "ab"})
    with pytest.raises(ShapeError, match=r"^targets\['hand_position'\]: complex numbers"):
        ik.solve_batch(np.zeros((2, 7)), targets={"hand_position": np.zeros((2, 3)) + 1j})
    with pytest.raises(ShapeError, match=r"^q0s: complex numbers"):
        ik.solve_batch(np.zeros((2, 7)) + 0j)
    with pytest.raises(ShapeError, match=r"^FramePosition\(hand\).target: cannot be read"):
        P.GaussNewtonProjector(panda, P.panda_task("ik", target="abc"), backend=backend)


def test_settings_and_result(panda: genplan.Robot) -> None:
    q0 = panda.random_configurations(1, 3)[0]
    res = P.GaussNewtonProjector(panda, P.panda_task(), P.SolverSettings(max_iterations=0)).solve(q0)
    assert res.iterations == 0 and res.time_s >= 0.0
    assert set(res.residuals) == {"hand_orientation", "joint_limits"}
    solver = P.GaussNewtonProjector(panda, P.panda_task())
    qs, ok = solver.project(panda.random_configurations(8, 4), panda.random_configurations(8, 5))
    assert qs.shape == (8, 7) and ok.shape == (8,) and ok.dtype == bool


# --- tasks as data: task files ---------------------------------------------------------------


def test_every_shipped_task_round_trips_through_a_file(tmp_path, panda: genplan.Robot, talos: genplan.Robot) -> None:
    assert set(P.task_names()) >= {"panda_projection", "panda_ik", "talos_projection", "talos_ik"}
    for name in P.task_names():
        robot = talos if name.startswith("talos") else panda
        task = P.load_task(name, robot)
        again = P.Task.from_file(task.to_file(tmp_path / f"{name}.toml"), robot)
        assert again.to_dict() == task.to_dict()
    ik = P.paper_task(panda, "ik")
    assert ik.condition == P.Condition("hand_position", tuple(P.PANDA_IK_BOX[0]), tuple(P.PANDA_IK_BOX[1]),
                                       (-0.6, -0.6, -0.1), (0.6, 0.6, 1.0), "panda_projection")
    # "default" values resolve on the robot: the soles where they are at the default configuration
    sole = next(t for t in P.paper_task(talos).primary if t.name == "left_sole")
    np.testing.assert_allclose(sole.target.homogeneous, talos.frame_placement(talos.q_default, "left_sole").homogeneous)
    arm = next(t for t in P.paper_task(talos).primary if t.name == "left_arm")
    assert int(arm.joint_weights.sum()) == 7  # joint_weights = { "arm_left_*" = 1.0 }


def test_every_built_in_term_round_trips(tmp_path, panda: genplan.Robot) -> None:
    rng = np.random.default_rng(0)
    target = pin.SE3(pin.utils.rpyToMatrix(*rng.normal(size=3)), rng.normal(size=3))
    task = P.Task(
        name="all_terms",
        primary=[
            P.FramePose(name="pose", frame="hand", target=target, components=(1, 1, 1, 0, 0, 1), weight=3.0),
            P.FramePosition(name="pos", frame="panda_link5", target=[0.1, 0.2, 0.3], axes=(1, 0, 1), tolerance=1e-4),
            P.FrameOrientation(name="ori", frame="hand", target=pin.utils.rotate("x", 0.3), offset=P.PANDA_HAND_OFFSET),
            P.JointLimits(margin=0.01),
            P.ComBox(lower=(-1, -1, 0), upper=(1, 1, 1)),
            P.Posture(name="p", q_nom=panda.q_default, joint_weights=np.arange(7.0), overrides={"panda_joint1": 0.5}),
        ],
        secondary=[P.Posture(name="posture")],
        condition=P.Condition("pos", (0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (0.1, 0.1, 0.1), (0.9, 0.9, 0.9), "panda_projection"),
    )
    again = P.Task.from_file(task.to_file(tmp_path / "t.toml"), panda)
    assert again.to_dict() == task.to_dict()
    q0 = panda.random_configurations(3, 1)
    a = P.GaussNewtonProjector(panda, task).solve_batch(q0)
    b = P.GaussNewtonProjector(panda, again).solve_batch(q0)
    np.testing.assert_array_equal(a.q, b.q)


def test_task_file_errors_name_the_file_the_table_and_the_key(tmp_path, panda: genplan.Robot) -> None:
    f = tmp_path / "bad.toml"
    cases = [
        ('[[primary]]\nkind = "Elbow"\n', TaskFileError, r"bad.toml: \[\[primary\]\] 1: unknown term kind 'Elbow' \(known: FramePose"),
        ('[[primary]]\nkind = "JointLimits"\nmargn = 1\n', TaskFileError, r"\[\[primary\]\] 1: JointLimits has no field 'margn'"),
        ('name = "x"\n', TaskFileError, r"needs at least one \[\[primary\]\] term"),
        ('colour = 1\n[[primary]]\nkind = "JointLimits"\n', TaskFileError, r"unknown key 'colour'"),
        ('[[primary]]\nkind = "JointLimits"\n[condition]\nterm = "hand"\nlow = [0]\nhigh = [1]\n', UnknownNameError,
         r"\[condition\] term 'hand' is not a primary term"),
        ('[[primary]]\nkind = "FramePose"\nframe = "hand"\ntarget = "default"\n', TaskFileError, r"'default' needs the robot"),
        ('[[primary\n', TaskFileError, r"bad.toml: "),
    ]
    for text, error, message in cases:
        f.write_text(text)
        with pytest.raises(error, match=message):
            P.Task.from_file(f)
    with pytest.raises(FileNotFoundError, match="nope.toml does not exist"):
        P.Task.from_file(tmp_path / "nope.toml")
    with pytest.raises(UnknownNameError, match=r"unknown task 'kitchen' \(shipped: free, panda_ik, panda_projection"):
        P.load_task("kitchen")
    with pytest.raises(UnknownNameError, match="no shipped task 'ur5_projection'"):
        P.paper_task(genplan.load("ur5"))


def _no_target_task(tmp_path, name: str = "no_target"):
    """panda_ik with its condition term's target left out (each query sets it)."""
    text = (P.TASKS_DIR / "panda_ik.toml").read_text()
    assert "target = [0.55, 0.0, 0.65]\n" in text
    f = tmp_path / f"{name}.toml"
    f.write_text(text.replace("target = [0.55, 0.0, 0.65]\n", "").replace('name = "panda_ik"', f'name = "{name}"'))
    return f


@pytest.mark.parametrize("backend", ["native", "pinocchio"])
def test_integrity_7_the_condition_term_may_leave_its_target_out(tmp_path, panda: genplan.Robot, backend) -> None:
    from genplan.errors import SettingsError

    f = _no_target_task(tmp_path)
    task = P.Task.from_file(f, panda)
    assert P.condition_term(task).target is None
    d = task.to_dict()
    assert "target" not in next(t for t in d["primary"] if t["name"] == "hand_position")
    again = P.Task.from_file(task.to_file(tmp_path / "again.toml"), panda)
    assert again.to_dict() == d
    # solved with per-row targets: the same answers as the task whose target is set
    targets = np.array([[0.5, 0.1, 0.6], [0.45, -0.2, 0.7]])
    q0 = panda.random_configurations(2, 0)
    a = P.GaussNewtonProjector(panda, task, backend=backend).solve_batch(q0, targets={"hand_position": targets})
    b = P.GaussNewtonProjector(panda, P.panda_task("ik"), backend=backend).solve_batch(
        q0, targets={"hand_position": targets})
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.success, b.success)
    # without a target there is nothing to aim at: refused, naming the term
    proj = P.GaussNewtonProjector(panda, task, backend=backend)
    for attempt in (lambda: proj.solve(q0[0]), lambda: proj.solve_batch(q0), lambda: proj.project(q0, q0)):
        with pytest.raises(SettingsError, match="condition term 'hand_position' has no target"):
            attempt()
    if backend == "native":
        with pytest.raises(SettingsError, match="condition term 'hand_position' has no target"):
            proj.native  # noqa: B018 -- what a planner would run
    # the manifold (the task without its condition term) needs none
    assert P.GaussNewtonProjector(panda, P.manifold_task(task, panda), backend=backend).solve_batch(q0).q.shape == (2, 7)
    # set, it solves
    assert P.GaussNewtonProjector(panda, task.with_targets(hand_position=targets[0]), backend=backend).solve(q0[0]).success


def test_integrity_7_only_the_condition_term_may_leave_its_target_out(tmp_path, panda: genplan.Robot) -> None:
    text = _no_target_task(tmp_path).read_text() + (
        '\n[[primary]]\nkind = "FramePosition"\nname = "elbow"\nframe = "panda_link4"\n')
    f = tmp_path / "elbow.toml"
    f.write_text(text)
    with pytest.raises(TaskFileError, match=r"elbow.toml: \[\[primary\]\] 4 \('elbow'\): FramePosition needs a target "
                                            r"\(only the \[condition\] term 'hand_position' may leave it out"):
        P.Task.from_file(f, panda)
    # a task built in Python: refused when it is solved, naming the term
    from genplan.errors import SettingsError

    task = P.Task(primary=[P.FramePosition(name="elbow", frame="panda_link4")], name="t")
    with pytest.raises(SettingsError, match=r"FramePosition\(panda_link4\).target: not set"):
        P.GaussNewtonProjector(panda, task)


def test_the_paper_constants_are_read_when_first_used() -> None:
    """genplan.projection reads no task file at import: the paper's constants (PANDA_IK_BOX, ...)
    are read from the shipped task files when first used, once."""
    import subprocess
    import sys

    code = ("import genplan.projection as P, genplan.projection.paper as paper\n"
            "assert 'PANDA_IK_BOX' not in vars(paper)\n"
            "box = P.PANDA_IK_BOX\n"
            "assert vars(paper)['PANDA_IK_BOX'] is box and P.PANDA_IK_BOX is box\n"
            "print(box.tolist(), P.TALOS_COM_BOX.shape, P.PANDA_HAND_OFFSET.shape)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().endswith("(2, 3) (3, 3)"), out
    assert P.PANDA_IK_BOX.tolist() == [list(P.load_task("panda_ik").condition.low),
                                       list(P.load_task("panda_ik").condition.high)]


@pytest.mark.parametrize("backend", ["native", "pinocchio"])
def test_residual_sizes_are_the_unstepped_solves_residuals(panda: genplan.Robot, backend: str) -> None:
    """``residual_sizes``: per primary term, the residual size ``solve_batch`` reports, without a
    step (the check of a trajectory's samples); rows beyond the joint limits are not clipped."""
    task = P.load_task("panda_projection", panda)
    q = random_configurations(panda, 40, seed=5)
    q[3, 1] = panda.upper[1] + 0.2  # beyond a limit: the limits term sees it
    sizes = P.GaussNewtonProjector(panda, task, backend=backend).residual_sizes(q)
    unstepped = P.GaussNewtonProjector(panda, task, P.SolverSettings(max_iterations=0, clip_to_limits=False),
                                       backend=backend).solve_batch(q).residuals
    assert list(sizes) == [t.label() for t in task.primary]
    for name, expected in unstepped.items():
        assert sizes[name].shape == (40,)
        np.testing.assert_allclose(sizes[name], expected, rtol=1e-12, atol=1e-15)
    assert sizes["joint_limits"][3] == pytest.approx(0.2) and sizes["hand_orientation"].max() > 1e-2
    solver = P.GaussNewtonProjector(panda, task, backend=backend)
    with pytest.raises(ShapeError, match=r"q: expected shape \(n, 7\)"):
        solver.residual_sizes(q[0])
    bad = q.copy()
    bad[7, 2] = np.nan
    with pytest.raises(NonFiniteError, match="q"):
        solver.residual_sizes(bad)
