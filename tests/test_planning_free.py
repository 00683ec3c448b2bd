"""Free-space planning (genplan.planning with the shipped ``free`` task, or any task of joint
limits alone): no projector in the loop, every state within the joint limits and collision-free,
the same paths as the projector that has nothing to do; ``genplan.planning.plan`` and queries
without a task, goals as configurations or as poses of a frame."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan import _core
from genplan import projection as P
from genplan.errors import InvalidGoalError, InvalidStartError, SettingsError, UnknownNameError
from genplan.planning import (FREE_SPACE_SETTINGS, Planner, PlannerSettings, default_settings, environment,
                              make_query, plan)


@pytest.fixture(scope="module")
def shelf(panda):
    """The shelf's world and valid configurations of it (seed 3): starts and goals."""
    world = environment("panda_shelf").world(panda)
    qs = panda.random_configurations(600, np.random.default_rng(3))
    return world, qs[~np.asarray(world.in_collision(qs), dtype=bool)]


def assert_free_path(robot: genplan.Robot, world, result, start, goal) -> None:
    """Every state within the joint limits (no tolerance) and collision-free, ``sub`` points on
    every chord too; consecutive states at most 1.25 edge resolutions apart; from start to goal."""
    assert result.success
    path = result.path
    np.testing.assert_array_equal(path[0], start)
    np.testing.assert_array_equal(path[-1], goal)
    assert np.all(path >= robot.lower) and np.all(path <= robot.upper)
    chords = np.concatenate([a + np.linspace(0, 1, 5)[:, None] * (b - a) for a, b in zip(path[:-1], path[1:])])
    assert not np.any(world.in_collision(chords))
    assert np.linalg.norm(np.diff(path, axis=0), axis=1).max() <= 1.25 * PlannerSettings().edge_resolution + 1e-9


def test_the_free_task_is_shipped_for_any_robot(panda, talos) -> None:
    for robot in (panda, talos):
        task = P.load_task("free", robot)
        assert task.free and task.condition is None
        assert [type(t) for t in task.primary] == [P.JointLimits]
    assert not P.load_task("panda_projection", panda).free


@pytest.mark.parametrize("algorithm", ["crrt", "rrt_connect"])
def test_free_plans_project_nothing_and_are_valid(panda, shelf, algorithm) -> None:
    world, qs = shelf
    planner = Planner(panda, world, task="free", algorithm=algorithm, settings=PlannerSettings(simplify=True))
    assert planner.free and planner._projector_arg is None
    for i in range(3):
        res = planner.plan(qs[2 * i], qs[2 * i + 1])
        assert_free_path(panda, world, res, qs[2 * i], qs[2 * i + 1])
        s = res.stats
        assert (s.projections, s.projection_calls, s.edge_projections, s.chord_checks) == (0, 0, 0, 0)
        assert s.projector_s == 0.0
        # a trajectory of it passes every check (limits, the task's residuals, the world)
        if i == 0:
            traj = res.trajectory()
            assert traj.q.shape[1] == panda.nq


def test_a_free_task_plans_with_the_free_space_defaults(panda, shelf) -> None:
    """Without settings a free plan gets FREE_SPACE_SETTINGS (RRT-Connect, simplified, extensions
    of at most 3 steps), a constrained one the paper's PlannerSettings(); settings given are used
    as they are, ``algorithm=`` replacing theirs; plan() and the result follow the same rule."""
    world, qs = shelf
    assert FREE_SPACE_SETTINGS.algorithm == "rrt_connect" and FREE_SPACE_SETTINGS.simplify
    assert FREE_SPACE_SETTINGS.max_increments == 3 and FREE_SPACE_SETTINGS.max_increments < PlannerSettings().max_increments
    assert FREE_SPACE_SETTINGS.balance and not PlannerSettings().balance  # the smaller tree grows
    assert default_settings(True) == FREE_SPACE_SETTINGS and default_settings(False) == PlannerSettings()
    assert Planner(panda, world, task="free").settings == FREE_SPACE_SETTINGS
    assert Planner(panda, world, task="panda_projection").settings == PlannerSettings()
    given = PlannerSettings(step=0.2)
    assert Planner(panda, world, task="free", settings=given).settings == given
    assert Planner(panda, world, task="free", algorithm="crrt").settings == FREE_SPACE_SETTINGS.replace(algorithm="crrt")
    # a task of joint limits alone given as a Task is free too; a projector given makes it constrained
    free = P.load_task("free", panda)
    assert Planner(panda, world, task=free).settings == FREE_SPACE_SETTINGS
    projector = P.GaussNewtonProjector(panda, free)
    assert Planner(panda, world, task=free, projector=projector).settings == PlannerSettings()
    out = plan(panda, "free", "panda_shelf", start=qs[0], goal=qs[1])
    assert out.algorithm == "rrt_connect" and out.result.success
    assert_free_path(panda, world, out.result, qs[0], qs[1])


def straight_edge(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The states of the straight edge from a to b at the default edge resolution, as the
    planner spaces them (ends included)."""
    n = int(np.ceil(np.linalg.norm(b - a) / PlannerSettings().edge_resolution))
    return a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a)


def test_free_plans_match_the_projector_that_has_nothing_to_do(panda, shelf) -> None:
    """The same samples, the same trees: the free plan's path is the one planned with the free
    task's projector in the loop (which leaves every state within the limits where it is), at a
    cost the free plan does not pay. (A goal whose straight edge is clear is joined by it in free
    space, without a tree: test_a_goal_in_plain_view_is_joined_by_the_straight_edge; here the
    edge is blocked.)"""
    world, qs = shelf
    goal = next(q for q in qs[1:] if np.any(world.in_collision(straight_edge(qs[0], q))))
    free = P.load_task("free", panda)
    settings = PlannerSettings()  # the same for both (a free task's defaults are FREE_SPACE_SETTINGS)
    for algorithm in ("crrt", "rrt_connect"):
        a = Planner(panda, world, task="free", algorithm=algorithm, settings=settings, seed=5).plan(qs[0], goal)
        projector = P.GaussNewtonProjector(panda, free.with_tolerances_scaled(0.1))
        through = Planner(panda, world, task=free, projector=projector, algorithm=algorithm, settings=settings, seed=5)
        assert not through.free
        b = through.plan(qs[0], goal)
        assert a.success and b.success
        np.testing.assert_array_equal(a.path, b.path)
        assert b.stats.projection_calls > 0 and b.stats.projector_s > 0
        assert a.stats.projector_s == 0


@pytest.mark.parametrize("checker", ["exact", "spheres"])
def test_a_goal_in_plain_view_is_joined_by_the_straight_edge(panda, shelf, checker) -> None:
    """In free space the straight edge from the start to a goal is tried first, whatever its
    length: when it is clear the path is that edge (two waypoints, its states at the edge
    resolution, no sample drawn); when it is blocked the search runs."""
    world, qs = shelf
    planner = Planner(panda, world, task="free", algorithm="rrt_connect", checker=checker)
    clear = next(q for q in qs[1:] if np.linalg.norm(q - qs[0]) > 1.0 and not np.any(world.in_collision(straight_edge(qs[0], q))))
    r = planner.plan(qs[0], clear)
    assert_free_path(panda, world, r, qs[0], clear)
    np.testing.assert_array_equal(r.waypoints, np.stack([qs[0], clear]))
    np.testing.assert_allclose(r.path, straight_edge(qs[0], clear), atol=1e-12)
    assert (r.stats.samples, r.stats.extensions, r.stats.nodes) == (0, 1, 2)
    blocked = next(q for q in qs[1:] if np.any(world.in_collision(straight_edge(qs[0], q))))
    r = planner.plan(qs[0], blocked)
    assert_free_path(panda, world, r, qs[0], blocked)
    assert r.stats.samples > 0 and len(r.waypoints) > 2


@pytest.mark.parametrize("sampling", ["random", "halton"])
def test_halton_sampling_is_seeded(panda, shelf, sampling) -> None:
    """``PlannerSettings(sampling=...)``: the same seed plans the same path, another seed draws
    other samples; the uniform sampler the planner makes draws within the joint limits."""
    world, qs = shelf
    goal = next(q for q in qs[1:] if np.any(world.in_collision(straight_edge(qs[0], q))))
    settings = PlannerSettings(algorithm="rrt_connect", sampling=sampling)
    plans = [Planner(panda, world, task="free", settings=settings, seed=s).plan(qs[0], goal) for s in (1, 1, 2)]
    assert all(p.success for p in plans)
    np.testing.assert_array_equal(plans[0].path, plans[1].path)
    assert plans[0].path.shape != plans[2].path.shape or not np.array_equal(plans[0].path, plans[2].path)
    for p in plans:  # every state (the default edge check samples states, not the chords between them)
        np.testing.assert_array_equal(p.path[[0, -1]], np.stack([qs[0], goal]))
        assert np.all(p.path >= panda.lower) and np.all(p.path <= panda.upper)
        assert not np.any(world.in_collision(p.path))
    samples = _core.UniformSampler(panda.kinematics, None, 3, None, sampling).sample(256)
    assert np.all(samples >= panda.lower) and np.all(samples <= panda.upper)
    np.testing.assert_array_equal(samples, _core.UniformSampler(panda.kinematics, None, 3, None, sampling).sample(256))
    assert not np.array_equal(samples, _core.UniformSampler(panda.kinematics, None, 4, None, sampling).sample(256))


def test_an_unknown_sampling_is_refused() -> None:
    with pytest.raises(SettingsError, match="sampling: unknown sampling 'sobol' .*'random', 'halton'"):
        PlannerSettings(sampling="sobol")


@pytest.mark.parametrize("algorithm", ["rrt_connect", "crrt"])
def test_a_search_out_of_its_time_limit_is_an_unsuccessful_plan(panda, shelf, algorithm) -> None:
    """``PlannerSettings(time_limit=...)``: a search still running when the limit passes stops,
    unsuccessful, with ``stats.timed_out``; a generous limit changes nothing (the same path)."""
    world, qs = shelf
    goal = next(q for q in qs[1:] if np.any(world.in_collision(straight_edge(qs[0], q))))
    settings = PlannerSettings(algorithm=algorithm, max_extensions=10**9, time_limit=1e-6)
    r = Planner(panda, world, task="free", settings=settings, seed=1).plan(qs[0], goal)
    assert not r.success and r.stats.timed_out and len(r.path) == 0
    assert r.stats.time_s >= 1e-6 and r.stats.extensions < 10**9
    plain = Planner(panda, world, task="free", settings=settings.replace(time_limit=0.0), seed=1).plan(qs[0], goal)
    timed = Planner(panda, world, task="free", settings=settings.replace(time_limit=600.0), seed=1).plan(qs[0], goal)
    assert plain.success and timed.success and not plain.stats.timed_out and not timed.stats.timed_out
    np.testing.assert_array_equal(plain.path, timed.path)


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf"), 2e6])
def test_a_bad_time_limit_is_refused_naming_it(bad) -> None:
    with pytest.raises(SettingsError, match=r"time_limit must be 0 \(no limit\) or in \(0, 1e6\] seconds"):
        PlannerSettings(time_limit=bad)


def test_a_start_or_goal_the_model_refuses_is_an_invalid_start_or_goal(panda, shelf) -> None:
    """Read by the native planner before any work: a joint beyond the model's range of numbers
    is the plan's InvalidStartError / InvalidGoalError, naming it."""
    world, qs = shelf
    planner = Planner(panda, world, task="free")
    far = qs[0].copy()
    far[2] = 1e17
    with pytest.raises(InvalidStartError, match=r"^start: configuration q: joint 'panda_joint3' \(q\[2\]\) is at 1e\+?17"):
        planner.plan(far, qs[1])
    with pytest.raises(InvalidGoalError, match=r"^goals: configuration q: joint 'panda_joint3'"):
        planner.plan(qs[0], far)
    with pytest.raises(InvalidGoalError, match=r"^goals\[1\]: configuration q: joint 'panda_joint3'"):
        planner.plan(qs[0], np.stack([qs[1], far]))


class OutOfLimits:
    """Samples half of them beyond the upper joint limits."""

    def __init__(self, robot: genplan.Robot) -> None:
        self.robot, self.rng = robot, np.random.default_rng(0)

    def sample(self, n: int) -> np.ndarray:
        q = self.robot.random_configurations(n, self.rng)
        q[::2] += (self.robot.upper - self.robot.lower)
        return q


class Everything:
    """A Python checker that finds every configuration valid."""

    def __init__(self) -> None:
        self.rows = 0

    def is_valid(self, qs: np.ndarray) -> np.ndarray:
        self.rows += len(qs)
        return np.ones(len(qs), dtype=bool)


def test_a_python_checker_in_free_space_cannot_leave_the_limits(panda, shelf) -> None:
    """No projector keeps the states within the limits: the planner does, whatever a Python
    checker says (a sampler that draws beyond them leaves no state there)."""
    world, qs = shelf
    checker = Everything()
    planner = Planner(panda, world, task="free", sampler=OutOfLimits(panda), checker=checker,
                      settings=PlannerSettings(max_extensions=300))
    res = planner.plan(qs[0], qs[1])
    assert res.success and checker.rows > 0
    assert np.all(res.path >= panda.lower) and np.all(res.path <= panda.upper)
    assert res.stats.projector_s == 0
    with pytest.raises(InvalidStartError, match="outside the joint limits"):
        planner.plan(panda.upper + 0.1, qs[1])


def test_plan_without_a_task_plans_in_free_space(panda, shelf) -> None:
    world, qs = shelf
    out = plan(panda, scene="panda_shelf", start=qs[4], goal=qs[5], algorithm="rrt_connect")
    assert out.task.name == "free" and out.manifold.free and out.trail_frame is None
    assert_free_path(panda, out.world, out.result, qs[4], qs[5])
    assert out.result.stats.projector_s == 0
    d = out.to_dict()
    assert d["task"] == "free" and d["success"] and d["goal_target"] == []


@pytest.mark.parametrize("form", ["matrix", "quaternion"])
def test_a_pose_goal_is_reached_by_collision_free_ik(panda, shelf, form) -> None:
    world, qs = shelf
    goal_pose = panda.frame_placement(qs[7], "hand")
    target = goal_pose.homogeneous if form == "matrix" else np.concatenate(
        [goal_pose.translation, pin.Quaternion(goal_pose.rotation).coeffs()])  # x y z qx qy qz qw
    out = plan(panda, scene="panda_shelf", start=qs[6], target=target, frame="hand", k=3, algorithm="rrt_connect")
    assert len(out.query.goals) == 3 and out.trail_frame == "hand"
    assert not np.any(out.world.in_collision(out.query.goals))
    for g in out.query.goals:
        err = pin.log6(goal_pose.inverse() * panda.frame_placement(g, "hand")).vector
        assert np.abs(err).max() < 1e-3
        assert np.all(g >= panda.lower) and np.all(g <= panda.upper)
    assert_free_path(panda, out.world, out.result, qs[6], out.query.goals[out.result.goal_index])


def test_free_queries_refuse_bad_input_naming_it(panda, shelf) -> None:
    world, qs = shelf
    free = P.load_task("free", panda)
    outside = qs[0].copy()
    outside[3] = panda.upper[3] + 0.05
    with pytest.raises(InvalidStartError, match=r"start: coordinate 3 \(of joint panda_joint4\) at .* outside"):
        make_query(panda, free, world, outside, goal=qs[1])
    with pytest.raises(InvalidGoalError, match="goal: .*outside its limits"):
        make_query(panda, free, world, qs[0], goal=outside)
    with pytest.raises(SettingsError, match="frame: task 'free' has no \\[condition\\]"):
        make_query(panda, free, world, qs[0], target=[0.5, 0.0, 0.5])
    with pytest.raises(UnknownNameError, match="nowhere"):
        make_query(panda, free, world, qs[0], target=[0.5, 0.0, 0.5], frame="nowhere")
    with pytest.raises(InvalidGoalError, match=r"target: expected positions \(n, 3\), poses"):
        make_query(panda, free, world, qs[0], target=[0.5, 0.0, 0.5, 1.0], frame="hand")
    with pytest.raises(InvalidGoalError, match="target: no collision-free IK solution of frame 'hand'"):
        make_query(panda, free, world, qs[0], target=[3.0, 0.0, 0.5], frame="hand", max_tries=64)
    with pytest.raises(SettingsError, match="sampler 'gan': task 'free' has no \\[condition\\]"):
        plan(panda, start=qs[0], goal=qs[1], sampler="gan")


def test_the_native_planner_takes_no_projector_as_free_space(panda, shelf) -> None:
    world, qs = shelf
    native = _core.Planner(panda.kinematics, PlannerSettings())
    res = native.plan(list(qs[0]), qs[1][None], _core.UniformSampler(panda.kinematics, None, 0, None), None,
                      world.native)
    assert res.success and res.stats.projections == 0 and res.stats.projector_s == 0
