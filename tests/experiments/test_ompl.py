"""The OMPL peer (ProjectedStateSpace + RRTConnect on genplan's constraint and collision model)."""

import numpy as np
import pinocchio as pin
import pytest

pytest.importorskip("ompl")

import genplan  # noqa: E402
from genplan.errors import NonFiniteError, ShapeError  # noqa: E402
from genplan.experiments.peers.ompl import ManifoldChart, TaskEquality, _constraint_class, _Counters, _Guard, plan_ompl  # noqa: E402
from genplan.projection import GaussNewtonProjector, paper_task  # noqa: E402


def on_manifold(robot: genplan.Robot, world: genplan.CollisionWorld, n: int, seed: int, shrink: float = 1.0) -> np.ndarray:
    """n collision-free configurations projected onto the paper's projection task."""
    q0 = robot.random_configurations(8 * n, seed)
    q0 = robot.q_default + shrink * (q0 - robot.q_default)
    res = GaussNewtonProjector(robot, paper_task(robot, "projection")).solve_batch(q0)
    q = res.q[res.success]
    q = q[~world.in_collision(q)]
    assert len(q) >= n
    return q[:n]


def fd_jacobian(f, x: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    cols = []
    for i in range(len(x)):
        e = np.zeros_like(x)
        e[i] = eps
        cols.append((f(x + e) - f(x - e)) / (2 * eps))
    return np.stack(cols, axis=1)


@pytest.mark.parametrize("name, codim", [("panda", 2), ("talos", 19)])
def test_constraint_jacobian_matches_finite_differences(name: str, codim: int) -> None:
    robot = genplan.load(name)
    eq = TaskEquality(robot, paper_task(robot, "projection"))
    assert eq.codim == codim and eq.dim == robot.nv and eq.manifold_dim == robot.nv - codim
    assert eq.default_tolerance == 1e-4
    for q in on_manifold(robot, robot.collision_world(), 3, seed=1, shrink=0.3 if robot.floating_base else 1.0):
        x = eq.chart.to_x(q)
        assert np.abs(eq.function(x)).max() < 1e-4
        jac = eq.jacobian(x)
        assert jac.shape == (codim, robot.nv)
        np.testing.assert_allclose(jac, fd_jacobian(eq.function, x), atol=1e-6)
        assert np.linalg.matrix_rank(jac) == codim


@pytest.mark.parametrize("name", ["panda", "talos"])
def test_ompl_projection_uses_the_analytic_jacobian(name: str) -> None:
    """OMPL's own Newton projection (C++) through the Python constraint lands on the manifold."""
    robot = genplan.load(name)
    eq = TaskEquality(robot, paper_task(robot, "projection"))
    counters = _Counters()
    constraint = _constraint_class()(eq, 1e-4, _Guard(), counters)
    q = on_manifold(robot, robot.collision_world(), 1, seed=2, shrink=0.3 if robot.floating_base else 1.0)[0]
    x = eq.chart.to_x(q) + np.random.default_rng(0).normal(scale=0.02, size=eq.dim)
    assert np.linalg.norm(eq.function(x)) > 1e-3
    assert constraint.project(x)  # in place
    assert np.linalg.norm(eq.function(x)) <= 1e-4
    assert counters.jacobian >= 1 and counters.function == counters.jacobian + 1  # one projection


def test_talos_chart_round_trip_and_tangent_map() -> None:
    robot = genplan.load("talos")
    chart = ManifoldChart(robot)
    assert chart.dim == 34 and chart.floating
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = robot.random_configurations(1, rng)[0]
        q[:3] = rng.uniform(-1, 1, 3)
        r = rng.normal(size=3)
        r *= rng.uniform(0, 3.0) / np.linalg.norm(r)  # rotation angle below pi
        q[3:7] = pin.Quaternion(pin.exp3(r)).coeffs()
        x = chart.to_x(q)
        assert x.shape == (34,)
        np.testing.assert_allclose(x[3:6], r, atol=1e-12)
        q2 = chart.to_q(x)
        sign = np.sign(q2[3:7] @ q[3:7])  # q and -q are the same rotation
        np.testing.assert_allclose(q2[3:7] * sign, q[3:7], atol=1e-12)
        np.testing.assert_allclose(q2[[0, 1, 2, *range(7, 35)]], q[[0, 1, 2, *range(7, 35)]], atol=1e-15)
        np.testing.assert_allclose(chart.to_x(q2), x, atol=1e-12)
        # d v / d x against finite differences of pinocchio.difference
        fd = fd_jacobian(lambda xx: pin.difference(robot.model, q2, chart.to_q(xx)), x)
        np.testing.assert_allclose(chart.dv_dx(x), fd, atol=1e-6)
    lo, hi = chart.bounds(robot)
    x0 = chart.to_x(robot.q_default)
    np.testing.assert_allclose(hi[:6] - x0[:6], [0.5, 0.5, 0.5, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(lo[6:], robot.lower[7:])


@pytest.fixture(scope="module")
def panda_table():
    robot = genplan.load("panda")
    world = robot.collision_world()
    world.add_box("table", [0.3, 0.5, 0.02], [0.6, 0.0, 0.2])
    task = paper_task(robot, "projection")
    return robot, world, task, on_manifold(robot, world, 6, seed=3)


def test_panda_query_is_solved_with_a_valid_path(panda_table) -> None:
    robot, world, task, qs = panda_table
    out = plan_ompl(robot, world, task, qs[0], qs[1:4], time_limit=10.0, seed=0)
    assert out.success, out.status
    assert out.status == "EXACT_SOLUTION"
    assert out.time_s < 5.0 and out.setup_s < 1.0
    assert out.goal_index in (0, 1, 2) and out.goals_used == [0, 1, 2]
    assert out.projections > 0 and out.projection_iterations > 0 and out.validity_checks > 0
    path = out.path
    assert path.ndim == 2 and path.shape[1] == robot.nq and len(path) >= out.raw_states >= 2
    np.testing.assert_allclose(path[0], qs[0], atol=1e-3)
    np.testing.assert_allclose(path[-1], qs[1 + out.goal_index], atol=1e-3)
    eq = TaskEquality(robot, task)
    # every state of the interpolated path was projected by OMPL: within its tolerance
    assert max(np.linalg.norm(eq.function_q(q)) for q in path) <= out.tolerance * (1 + 1e-9)
    # consecutive states are about delta apart; straight-line midpoints stay within 10x tolerance
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    assert steps.max() <= 2 * out.delta
    mid = 0.5 * (path[1:] + path[:-1])
    assert max(np.linalg.norm(eq.function_q(q)) for q in mid) <= 10 * out.tolerance
    # collision-free (self and table), states and midpoints; within the joint limits (+ tolerance)
    assert not world.in_collision(path).any()
    assert not world.in_collision(mid).any()
    assert np.all(path >= robot.lower - 1e-3) and np.all(path <= robot.upper + 1e-3)
    # reproducible for a seed
    again = plan_ompl(robot, world, task, qs[0], qs[1:4], time_limit=10.0, seed=0)
    np.testing.assert_array_equal(again.path, out.path)


def test_failures_and_bad_input(panda_table) -> None:
    robot, world, task, qs = panda_table
    out = plan_ompl(robot, world, task, qs[0], qs[1], time_limit=1e-6)
    assert not out.success and out.status == "TIMEOUT" and out.path.shape == (0, robot.nq) and out.goal_index == -1
    with pytest.raises(ShapeError, match="q_start"):
        plan_ompl(robot, world, task, qs[0][:6], qs[1])
    with pytest.raises(NonFiniteError, match="not finite"):
        plan_ompl(robot, world, task, qs[0], np.full(robot.nq, np.nan))
    with pytest.raises(ValueError, match="not on the constraint manifold"):
        plan_ompl(robot, world, task, robot.q_default + 0.5, qs[1])
    with pytest.raises(ValueError, match="planner"):
        plan_ompl(robot, world, task, qs[0], qs[1], planner="NoSuchPlanner")
    with pytest.raises(ValueError, match="time_limit"):
        plan_ompl(robot, world, task, qs[0], qs[1], time_limit=0)
    blocked = robot.collision_world()
    hand = robot.frame_placement(qs[0], "hand").translation
    blocked.add_sphere("ball", 0.05, hand)
    assert plan_ompl(robot, blocked, task, qs[0], qs[1]).status == "INVALID_START"
    hand_goal = robot.frame_placement(qs[1], "hand").translation
    blocked = robot.collision_world()
    blocked.add_sphere("ball", 0.05, hand_goal)
    if not blocked.in_collision(qs[0]):
        assert plan_ompl(robot, blocked, task, qs[0], qs[1]).status == "INVALID_GOAL"
