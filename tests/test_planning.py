"""The constrained planners (the paper's cRRT, RRT-Connect) from Python: environments and
queries, valid paths (dense check of every edge: constraint within tolerance, no collision,
self-collision included), Python components called back from Rust, exceptions and Ctrl-C, bad
input."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan import _core
from genplan import projection as P
from genplan.errors import (CallbackError, GenplanError, InvalidGoalError, InvalidStartError, NonFiniteError, SettingsError,
                            ShapeError, UnknownNameError)
from genplan.planning import (ALGORITHMS, EDGE_CHECKS, ENVIRONMENT_NAMES, Planner, PlannerSettings, data_sampler, environment,
                              make_sampler, uniform_base_box)
from tests.interrupt import MAX_LATENCY_S, ctrl_c_latency


@pytest.fixture(scope="module")
def shelf(panda):
    env = environment("panda_shelf")
    return env, env.world(panda), env.queries(panda, n=2, seed=1)


@pytest.fixture(scope="module")
def task1(talos):
    env = environment("talos_task1")
    return env, env.world(talos), env.queries(talos, n=1, seed=1)


def assert_path_valid(robot: genplan.Robot, world, result, query, sub: int = 8) -> None:
    """Every state and `sub` points on every chord between consecutive states: each primary term
    of the paper's projection task within its tolerance, not in collision."""
    assert result.success
    path = result.path
    assert np.allclose(path[0], query.start)
    assert np.allclose(path[-1], query.goals[result.goal_index])
    task = P.paper_task(robot, "projection")
    terms = [t.bind(robot) for t in task.primary]
    points = [path[0]]
    for a, b in zip(path[:-1], path[1:]):
        points.extend(pin.interpolate(robot.model, a, b, s) for s in np.linspace(0, 1, sub + 1)[1:])
    points = np.array(points)
    for x in points:
        st = P._State(robot, x, False)
        for t, bt in zip(task.primary, terms):
            r = np.abs(bt.residual(st))
            assert r.size == 0 or r.max() < t.tolerance, f"{t.label()} violated by {r.max():.2e} (tolerance {t.tolerance})"
    assert not np.any(world.in_collision(points)), "a state or chord point collides"
    assert world.check_self
    steps = [np.linalg.norm(pin.difference(robot.model, a, b)) for a, b in zip(path[:-1], path[1:])]
    assert max(steps) <= 1.25 * PlannerSettings().edge_resolution + 1e-9


def test_environments_are_data(panda, talos) -> None:
    assert ENVIRONMENT_NAMES == ("panda_shelf", "talos_task1", "talos_task2", "talos_task3")
    with pytest.raises(UnknownNameError, match="known: panda_shelf"):
        environment("kitchen")
    env = environment("talos_task3")
    assert len(env.boxes) == 8 and env.robot == "talos"
    with pytest.raises(GenplanError, match="is for talos"):
        env.world(panda)
    w = env.world(talos)
    assert set(w.obstacle_names) == {b.name for b in env.boxes}


def test_queries_are_seeded_valid_and_on_the_manifold(panda, shelf) -> None:
    env, world, queries = shelf
    again = env.queries(panda, n=2, seed=1)
    for a, b in zip(queries, again):
        assert np.array_equal(a.start, b.start) and np.array_equal(a.goals, b.goals)
    proj = P.GaussNewtonProjector(panda, P.paper_task(panda, "projection"))
    for q in queries:
        assert q.goals.shape == (10, 7)
        rows = np.vstack([q.start, q.goals])
        assert not np.any(world.in_collision(rows))
        res = proj.solve_batch(rows, rows, parallel=False)
        assert res.success.all() and (res.iterations == 0).all()
        hands = panda.link_poses(rows, ["panda_hand"])[:, 0, :3, 3]
        assert np.linalg.norm(hands[0] - q.start_target) < 2e-3
        assert np.all(np.linalg.norm(hands[1:] - q.goal_target, axis=1) < 2e-3)


@pytest.mark.parametrize("sampler", ["uniform", "gan", "hybrid", "adaptive"])
def test_panda_paths_are_valid(panda, shelf, sampler) -> None:
    env, world, queries = shelf
    planner = Planner(panda, world=world, sampler=sampler, seed=2)
    for q in queries:
        res = planner.plan(q.start, q.goals)
        assert_path_valid(panda, world, res, q)
        assert res.projections > 0 and res.extensions > 0 and res.time_s > 0
        assert len(res.waypoints) >= 2 and res.stats.nodes >= len(res.waypoints)


@pytest.mark.parametrize("sampler", ["uniform", "gan"])
def test_rrt_connect_paths_are_valid(panda, shelf, sampler) -> None:
    """RRT-Connect: the same dense re-check as the cRRT's; the goal reached is one of the goals."""
    env, world, queries = shelf
    planner = Planner(panda, world=world, sampler=sampler, seed=2, algorithm="rrt_connect")
    assert planner.settings.algorithm == "rrt_connect"
    for q in queries:
        res = planner.plan(q.start, q.goals)
        assert_path_valid(panda, world, res, q)
        assert res.projections > 0 and res.extensions > 0 and res.time_s > 0
        assert len(res.waypoints) >= 2 and res.stats.nodes >= len(res.waypoints)
        # the waypoints lie on the dense path, in order
        k = 0
        for w in res.waypoints:
            k += int(np.flatnonzero((res.path[k:] == w).all(axis=1))[0])


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_talos_path_is_valid(talos, task1, algorithm) -> None:
    env, world, queries = task1
    planner = Planner(talos, world=world, sampler="hybrid", seed=0, algorithm=algorithm)
    res = planner.plan(queries[0].start, queries[0].goals)
    assert_path_valid(talos, world, res, queries[0], sub=4)


def test_the_algorithm_is_a_known_name(panda, shelf) -> None:
    assert ALGORITHMS == ("crrt", "rrt_connect") and PlannerSettings().algorithm == "crrt"
    with pytest.raises(UnknownNameError, match="unknown algorithm 'rrt' \\(known: crrt, rrt_connect\\)"):
        Planner(panda, world=shelf[1], algorithm="rrt")
    with pytest.raises(SettingsError, match="PlannerSettings.algorithm: unknown algorithm 'rrt' \\(known: 'crrt', 'rrt_connect'\\)"):
        PlannerSettings(algorithm="rrt")
    with pytest.raises(SettingsError, match="PlannerSettings.algorithm"):
        PlannerSettings(algorithm=1)
    # the keyword overrides the settings' algorithm and keeps the rest
    p = Planner(panda, world=shelf[1], settings=PlannerSettings(step=0.2, algorithm="rrt_connect"), algorithm="crrt")
    assert (p.settings.algorithm, p.settings.step) == ("crrt", 0.2)


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_certified_edges_are_dense_rechecked(panda, talos, shelf, task1, algorithm) -> None:
    """edge_check="certified": every motion between consecutive states certified collision-free
    (conservative advancement); the returned paths pass the dense re-check at twice the
    sub-points, and cost certificates; the spacing bound still holds (states are only added)."""
    settings = PlannerSettings(edge_check="certified", algorithm=algorithm)
    for robot, (env, world, queries), sub in [(panda, shelf, 16), (talos, task1, 4)]:
        planner = Planner(robot, world=world, sampler="gan", seed=2, settings=settings)
        res = planner.plan(queries[0].start, queries[0].goals)
        assert_path_valid(robot, world, res, queries[0], sub=sub)
        assert res.stats.motion_certificates > 0
        assert planner.settings.edge_check == "certified"


def test_certified_edges_need_a_certifying_checker(panda, shelf) -> None:
    env, world, queries = shelf
    assert PlannerSettings().edge_check == "sampled" and EDGE_CHECKS == ("sampled", "certified")
    with pytest.raises(SettingsError, match="unknown edge check 'exact' \\(known: 'sampled', 'certified'\\)"):
        PlannerSettings(edge_check="exact")
    with pytest.raises(SettingsError, match="edge_check 'certified' needs edge_resolution > 0"):
        PlannerSettings(edge_check="certified", edge_resolution=0.0)
    planner = Planner(panda, world=world, checker=PythonChecker(world), settings=PlannerSettings(edge_check="certified"))
    with pytest.raises(SettingsError, match="needs a checker that certifies motions"):
        planner.plan(queries[0].start, queries[0].goals)
    # sampled stats count no certificate
    res = Planner(panda, world=world, seed=2).plan(queries[0].start, queries[0].goals)
    assert res.stats.motion_certificates == 0


class CountingSampler:
    def __init__(self, robot: genplan.Robot) -> None:
        self.robot, self.calls, self.rng = robot, 0, np.random.default_rng(0)

    def sample(self, n: int) -> np.ndarray:
        self.calls += 1
        return self.robot.random_configurations(n, self.rng)


class PythonProjector:
    """The planner's projector as a plain Python object (forces the callback path)."""

    def __init__(self, robot: genplan.Robot) -> None:
        self.inner = P.GaussNewtonProjector(robot, P.paper_task(robot, "projection").with_tolerances_scaled(0.1))
        self.calls = 0

    def project(self, qs: np.ndarray, q_noms: np.ndarray):
        self.calls += 1
        r = self.inner.solve_batch(qs, q_noms, parallel=False)
        return r.q, r.success, r.iterations


class PythonChecker:
    def __init__(self, world) -> None:
        self.world, self.calls = world, 0

    def is_valid(self, qs: np.ndarray) -> np.ndarray:
        self.calls += 1
        return ~np.asarray(self.world.in_collision(qs), dtype=bool)


def test_python_components_are_called_back_in_batches(panda, shelf) -> None:
    env, world, queries = shelf
    sampler, projector, checker = CountingSampler(panda), PythonProjector(panda), PythonChecker(world)
    planner = Planner(panda, world=world, sampler=sampler, projector=projector, checker=checker,
                      settings=PlannerSettings(sample_batch=8))
    res = planner.plan(queries[0].start, queries[0].goals)
    assert_path_valid(panda, world, res, queries[0])
    assert sampler.calls >= 1 and projector.calls >= 1 and checker.calls >= 1
    # batched: several samples per sampler call
    assert res.stats.samples == 8 * sampler.calls
    # the same plan with native parts gives the same answer (same samples, same projector): the
    # same tree; the edge states within micro-radians (the native projector drops the posture
    # step on them, the Python one cannot: rust/core/src/planning/projector.rs)
    native = Planner(panda, world=world, sampler=CountingSampler(panda), settings=PlannerSettings(sample_batch=8))
    again = native.plan(queries[0].start, queries[0].goals)
    assert again.extensions == res.extensions and np.array_equal(again.waypoints, res.waypoints)
    assert again.path.shape == res.path.shape and np.abs(again.path - res.path).max() < 1e-4


class Boom(Exception):
    pass


def test_an_exception_in_a_callback_reaches_the_caller_unchanged(panda, shelf) -> None:
    env, world, queries = shelf

    class Failing:
        def sample(self, n: int) -> np.ndarray:
            raise Boom("sampler failed")

    with pytest.raises(Boom, match="sampler failed"):
        Planner(panda, world=world, sampler=Failing()).plan(queries[0].start, queries[0].goals)

    class BadShape:
        def sample(self, n: int) -> np.ndarray:
            return np.zeros((n, 3))

    with pytest.raises(CallbackError, match=r"sampler.sample\(n\): expected shape \(16, 7\)"):
        Planner(panda, world=world, sampler=BadShape()).plan(queries[0].start, queries[0].goals)

    class NaNSampler:
        def sample(self, n: int) -> np.ndarray:
            return np.full((n, 7), np.nan)

    with pytest.raises(CallbackError, match="sampler returned a bad configuration"):
        Planner(panda, world=world, sampler=NaNSampler()).plan(queries[0].start, queries[0].goals)

    class FailingChecker:
        def is_valid(self, qs):
            raise Boom("checker failed")

    with pytest.raises(Boom, match="checker failed"):
        Planner(panda, world=world, checker=FailingChecker()).plan(queries[0].start, queries[0].goals)

    class BadProjector:
        def project(self, qs, q_noms):
            return qs

    with pytest.raises(CallbackError, match=r"projector.project\(qs, q_noms\) must return \(q, success\) or "
                                            r"\(q, success, iterations\), got ndarray"):
        Planner(panda, world=world, projector=BadProjector()).plan(queries[0].start, queries[0].goals)


def test_ctrl_c_interrupts_a_long_native_plan(panda, shelf) -> None:
    env, world, queries = shelf
    # every extension stops at once (any step is a "jump"): the planner would keep sampling for
    # 10^9 iterations
    planner = Planner(panda, world=world, settings=PlannerSettings(max_jump=1e-9, max_extensions=10**9))
    assert ctrl_c_latency(lambda: planner.plan(queries[0].start, queries[0].goals), after=0.5) < MAX_LATENCY_S


@pytest.mark.parametrize("kind", ["uniform", "gan"])
def test_native_samplers_draw_the_same_stream_in_any_batch_size(panda, kind) -> None:
    """Large draws run in chunks (Ctrl-C is checked between them) without changing the stream."""
    once = make_sampler(panda, kind, seed=5).sample(2000)
    sampler = make_sampler(panda, kind, seed=5)
    pieces = np.vstack([sampler.sample(n) for n in (1, 0, 999, 1000)])
    np.testing.assert_array_equal(once, pieces)


def test_the_data_sampler_draws_rows_of_its_data_in_its_box(panda, talos, shelf) -> None:
    """data_sampler: rows of the data given (or of the learned sampler's training data), only those
    whose target frame is in the box, every one reachable; the planner plans with it natively."""
    from genplan.samplers.data import valid_configurations
    from genplan.samplers.gan import default_config

    data = valid_configurations(panda, 25_000, 0, progress=False)
    cfg = default_config(panda)
    hand = lambda q: panda.link_poses(q, [panda.frames[cfg.target_frame]])[:, 0, :3, 3]  # noqa: E731
    lo, hi = np.asarray(cfg.target_box)
    inside = np.all((hand(data) >= lo) & (hand(data) <= hi), axis=1)
    assert 0 < inside.sum() < len(data)  # the box keeps some rows, not all
    default = data_sampler(panda, seed=2)
    assert len(default) == inside.sum() and len(data_sampler(panda, in_box=False)) == len(data)
    drawn = default.sample(3000)
    rows = {tuple(r) for r in data[inside]}
    assert all(tuple(r) in rows for r in drawn)
    np.testing.assert_array_equal(drawn, data_sampler(panda, seed=2).sample(3000))  # seeded
    # a box of one's own, over data of one's own
    few = data[:40]
    box = np.array([hand(few).min(0), hand(few).mean(0)])
    mine = data_sampler(panda, few, box=box)
    kept = np.all((hand(few) >= box[0]) & (hand(few) <= box[1]), axis=1)
    assert len(mine) == kept.sum() and {tuple(r) for r in mine.sample(400)} == {tuple(r) for r in few[kept]}
    # bad input: named, before any work
    with pytest.raises(ShapeError, match="data"):
        data_sampler(panda, few[:, :6])
    with pytest.raises(NonFiniteError, match="data"):
        data_sampler(panda, np.where(np.arange(7) == 3, np.nan, few))
    with pytest.raises(SettingsError, match="box"):
        data_sampler(panda, few, box=[[5, 5, 5], [6, 6, 6]])
    with pytest.raises(ShapeError, match="box"):
        data_sampler(panda, few, box=[0, 0, 0])
    # the planner draws from it natively; a sampler of another robot's rows is refused
    env, world, queries = shelf
    res = Planner(panda, world=world, sampler=default, seed=1).plan(queries[0].start, queries[0].goals)
    assert res.success and res.stats.sampler_s > 0
    by_name = Planner(panda, world=world, sampler="data", seed=1).plan(queries[0].start, queries[0].goals)
    by_object = Planner(panda, world=world, sampler=data_sampler(panda, seed=1), seed=1).plan(queries[0].start,
                                                                                              queries[0].goals)
    assert by_name.success and by_name.extensions == by_object.extensions  # the same rows, the same seed
    other = _core.DataSampler(np.zeros((3, talos.nq)))
    with pytest.raises(ShapeError, match="data rows of length"):
        Planner(panda, world=world, sampler=other).plan(queries[0].start, queries[0].goals)


def test_ctrl_c_interrupts_a_long_native_sampling(panda) -> None:
    """Within 0.5 s of the signal (uninterrupted: about 5 s on an idle 2-core machine)."""
    gan = make_sampler(panda, "gan", seed=0)
    assert ctrl_c_latency(lambda: gan.sample(300_000)) < MAX_LATENCY_S


def test_bad_input_is_a_clear_error(panda, shelf) -> None:
    env, world, queries = shelf
    planner = Planner(panda, world=world)
    q, goals = queries[0].start, queries[0].goals
    with pytest.raises(ShapeError, match="start"):
        planner.plan(q[:6], goals)
    with pytest.raises(NonFiniteError, match="start"):
        planner.plan(np.where(np.arange(7) == 2, np.nan, q), goals)
    with pytest.raises(ShapeError, match="goals"):
        planner.plan(q, goals[:, :5])
    colliding = q.copy()
    colliding[1], colliding[3] = 1.7, -0.1  # the arm folded into the table
    colliding = planner.projector.solve(colliding).q  # on the manifold
    assert world.in_collision(colliding)
    with pytest.raises(InvalidStartError, match="start: the configuration is not valid"):
        planner.plan(colliding, goals)
    with pytest.raises(InvalidGoalError, match="none of the goal"):
        planner.plan(q, colliding[None])
    with pytest.raises(UnknownNameError, match="unknown sampler 'sobol'"):
        Planner(panda, world=world, sampler="sobol")
    with pytest.raises(SettingsError, match="step must be positive"):
        PlannerSettings(step=0.0)
    with pytest.raises(SettingsError, match="PlannerSettings.neighbors: expected 'auto', 'linear' or 'kdtree', got 'octree'"):
        PlannerSettings(neighbors="octree")
    with pytest.raises(SettingsError, match="PlannerSettings.retries: expected a whole number >= 0, got -1"):
        PlannerSettings(retries=-1)
    with pytest.raises(SettingsError, match="unknown setting 'stepp'"):
        PlannerSettings(stepp=0.2)
    with pytest.raises(SettingsError, match=r"p must be in \[0, 1\]"):
        _core.MixtureSampler(make_sampler(panda), make_sampler(panda), 1.5)


def _violation(robot: genplan.Robot, q: np.ndarray) -> float:
    """The largest primary residual of the paper's projection task at q, over its tolerance."""
    task = P.paper_task(robot, "projection")
    st = P._State(robot, q, False)
    return max(float(np.abs(r).max()) / t.tolerance
               for t in task.primary if (r := t.bind(robot).residual(st)).size)


def test_start_and_goals_off_the_manifold_are_refused(panda, shelf) -> None:
    """Issue 15, kind 1: goals collision-free but off the manifold (joint 6 shifted by 0.3) gave
    success=True with a last state 211x over the orientation tolerance; a start off it failed
    silently after the whole budget. Each is refused before the search, naming which and why."""
    env, world, queries = shelf
    q = queries[0]
    planner = Planner(panda, world=world, sampler="gan", seed=0)
    one_off = q.goals.copy()
    one_off[3, 5] -= 0.3
    assert not world.in_collision(one_off[3]) and _violation(panda, one_off[3]) > 100
    # refused even though the other goals are fine: such a goal was not made for this constraint
    with pytest.raises(InvalidGoalError, match=r"^goals\[3\]: not on the constraint manifold: the projector moved it by "
                                               r"0\.[0-9]+ \(goal_tolerance 0\.001\)$"):
        planner.plan(q.start, one_off)
    all_off = q.goals.copy()
    all_off[:, 5] -= 0.3
    with pytest.raises(InvalidGoalError, match=r"^goals\[0\]: .*; also off it: goals\[1\], goals\[2\], .*, goals\[9\]$"):
        planner.plan(q.start, all_off)
    start = q.start.copy()
    start[5] -= 0.3
    with pytest.raises(InvalidStartError, match=r"^start: not on the constraint manifold: the projector moved it by"):
        planner.plan(start, q.goals)
    # a projector that cannot move anything (no iterations): an input off the manifold cannot
    # be projected at all
    stiff = P.GaussNewtonProjector(panda, P.paper_task(panda, "projection").with_tolerances_scaled(0.1),
                                   P.SolverSettings(max_iterations=0))
    with pytest.raises(InvalidGoalError, match=r"^goals\[3\]: not on the constraint manifold: the projector could not project it$"):
        Planner(panda, world=world, projector=stiff).plan(q.start, one_off)
    # a start and goals on the manifold are used exactly as given
    res = planner.plan(q.start, q.goals)
    assert res.success
    np.testing.assert_array_equal(res.path[0], q.start)
    np.testing.assert_array_equal(res.path[-1], q.goals[res.goal_index])


def test_start_and_goals_within_goal_tolerance_of_the_manifold_are_projected(panda, shelf) -> None:
    """Off the manifold by less than goal_tolerance: planned from and to their projections, so
    that every state of the path, its ends included, satisfies the constraint."""
    env, world, queries = shelf
    q = queries[1]
    start, goals = q.start.copy(), q.goals.copy()
    start[5] += 6e-4
    goals[:, 5] -= 6e-4
    assert _violation(panda, start) > 1 and min(_violation(panda, g) for g in goals) > 1
    res = Planner(panda, world=world, sampler="gan", seed=0).plan(start, goals)
    assert res.success
    for end, given in ((res.path[0], start), (res.path[-1], goals[res.goal_index])):
        assert 0 < np.linalg.norm(pin.difference(panda.model, given, end)) <= PlannerSettings().goal_tolerance
    assert max(_violation(panda, x) for x in res.path) < 1
    assert not np.any(world.in_collision(res.path))


class _Answers:
    """A validity checker that answers every configuration with the same value."""

    def __init__(self, value, dtype=None) -> None:
        self.value, self.dtype = value, dtype

    def is_valid(self, qs: np.ndarray):
        return np.full(len(qs), self.value, dtype=self.dtype)


@pytest.mark.parametrize("value, shown", [(np.nan, "returned NaN at index 0"), (0.5, "returned 0.5 at index 0"),
                                          (2.0, "returned 2 at index 0"), (-1, "returned -1 at index 0"),
                                          ("yes", "returned an array of dtype <U3"), (None, "returned an array of dtype object")])
def test_a_checker_must_answer_with_booleans(panda, shelf, value, shown) -> None:
    """Issue 15, kind 1: a checker returning NaN, 0.5 or 2.0 was read as "valid"."""
    env, world, queries = shelf
    planner = Planner(panda, world=world, checker=_Answers(value))
    with pytest.raises(CallbackError, match=rf"^checker\.is_valid\(qs\): {shown}; expected booleans \(or 0 / 1\)$"):
        planner.plan(queries[0].start, queries[0].goals)


@pytest.mark.parametrize("value, dtype", [(True, bool), (1, np.int64), (1.0, np.float64), (1, np.uint8)])
def test_a_checker_may_answer_with_zeros_and_ones(panda, shelf, value, dtype) -> None:
    env, world, queries = shelf
    res = Planner(panda, world=world, checker=_Answers(value, dtype), seed=1).plan(queries[0].start, queries[0].goals)
    assert res.success


def test_a_projector_must_report_success_with_booleans(panda, shelf) -> None:
    env, world, queries = shelf
    inner = PythonProjector(panda)

    class Unsure:
        def project(self, qs, q_noms):
            q, ok, _ = inner.project(qs, q_noms)
            return q, np.where(ok, 0.5, 0.0)

    with pytest.raises(CallbackError, match=r"^projector\.project: success: returned 0\.5 at index 0; expected booleans"):
        Planner(panda, world=world, projector=Unsure()).plan(queries[0].start, queries[0].goals)


def test_native_samplers(panda, talos) -> None:
    u = make_sampler(talos, "uniform", seed=3)
    q = u.sample(50)
    assert q.shape == (50, talos.nq)
    assert np.allclose(q[:, :7], talos.q_default[:7])  # the base held at its default placement
    inside = (q[:, 7:] >= talos.lower[7:]) & (q[:, 7:] <= talos.upper[7:])
    assert inside.all()
    h = make_sampler(panda, "hybrid", seed=3, hybrid_p=0.5)
    assert h.p == 0.5
    assert make_sampler(panda, "gan", seed=3).sample(5).shape == (5, 7)


def test_uniform_sampling_of_a_free_flyer_base(panda, talos) -> None:
    """The authors' Talos sampler: the base position uniform in the centre-of-mass box, its
    orientation the default's; the planner takes the box from its task."""
    box = uniform_base_box(talos, P.paper_task(talos, "projection"))
    np.testing.assert_array_equal(box, P.TALOS_COM_BOX)
    assert uniform_base_box(panda, P.paper_task(panda, "projection")) is None
    assert Planner(talos).base_box is not None and Planner(panda).base_box is None
    q = make_sampler(talos, "uniform", seed=3, base_box=box).sample(300)
    assert ((q[:, :3] >= box[0]) & (q[:, :3] <= box[1])).all()
    assert np.ptp(q[:, :3], axis=0).min() > 0.9 * np.diff(box, axis=0).min()  # spread over the box
    np.testing.assert_array_equal(q[:, 3:7], np.tile(talos.q_default[3:7], (300, 1)))
    with pytest.raises(GenplanError, match="bad base box"):
        make_sampler(talos, "uniform", base_box=box[::-1])
    with pytest.raises(ShapeError, match="base_box: expected"):
        make_sampler(talos, "uniform", base_box=[0.0, 1.0])
    with pytest.raises(GenplanError, match="free-flyer"):
        make_sampler(panda, "uniform", base_box=box)


def test_simplified_paths_are_valid_and_no_longer(panda, shelf) -> None:
    env, world, queries = shelf

    def length(path: np.ndarray) -> float:
        return float(sum(np.linalg.norm(pin.difference(panda.model, a, b)) for a, b in zip(path[:-1], path[1:])))

    for q in queries:
        plain = Planner(panda, world=world, sampler="uniform", seed=4).plan(q.start, q.goals)
        short = Planner(panda, world=world, sampler="uniform", seed=4,
                        settings=PlannerSettings(simplify=True)).plan(q.start, q.goals)
        assert_path_valid(panda, world, short, q)
        assert length(short.path) <= length(plain.path) + 1e-9
        assert short.stats.shortcuts >= 1 and len(short.waypoints) <= len(plain.waypoints)


def test_settings_are_typed_records() -> None:
    s = PlannerSettings(step=0.2, neighbors="linear")
    assert s.step == 0.2 and s.neighbors == "linear" and s.max_extensions == 500
    assert s.replace(step=0.1).step == 0.1 and s.step == 0.2            # immutable: replace copies
    assert s == PlannerSettings(**s.to_dict()) and s != PlannerSettings()
    assert list(s.to_dict()) == PlannerSettings.fields
    assert "step=0.2" in repr(s)
    import pickle
    assert pickle.loads(pickle.dumps(s)) == s
    with pytest.raises(AttributeError):
        s.step = 0.5  # type: ignore[misc]
    assert P.SolverSettings(max_iterations=0).max_iterations == 0
    with pytest.raises(SettingsError, match=r"backtrack must be in \(0, 1\), got 1.5"):
        P.SolverSettings(backtrack=1.5)
    with pytest.raises(SettingsError, match="SolverSettings.clip_to_limits: expected True or False"):
        P.SolverSettings(clip_to_limits=1)


def test_the_adaptive_sampler_starts_as_the_gan_and_ends_uniform(panda) -> None:
    """p = 1 at first, halving every half_life samples of a plan (rust/core/tests/planning.rs
    checks the shares drawn); a bad half-life is refused naming it."""
    from genplan.planning import ADAPTIVE_HALF_LIFE

    adaptive = make_sampler(panda, "adaptive", seed=3)
    assert (adaptive.p, adaptive.half_life) == (1.0, ADAPTIVE_HALF_LIFE)
    assert make_sampler(panda, "adaptive", seed=3, half_life=10.0).half_life == 10.0
    with pytest.raises(SettingsError, match="half_life must be a finite number > 0"):
        make_sampler(panda, "adaptive", half_life=0.0)
    with pytest.raises(SettingsError, match="half_life must be a finite number > 0"):
        make_sampler(panda, "adaptive", half_life=float("nan"))


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_integrity_3_a_start_at_the_goal_is_a_one_state_path(panda, shelf, algorithm) -> None:
    """A start already at a goal (or within goal_tolerance of one) is reached: a path of one state,
    no search, no detour; the goal reached is that goal, even after others."""
    env, world, queries = shelf
    q = queries[0]
    planner = Planner(panda, world=world, seed=0, algorithm=algorithm)
    res = planner.plan(q.start, q.start[None])
    assert res.success and res.goal_index == 0
    np.testing.assert_array_equal(res.path, q.start[None])
    np.testing.assert_array_equal(res.waypoints, q.start[None])
    assert res.extensions == 0 and res.stats.nodes == 1
    # 5e-4 rad of the base joint away (on the manifold: the gripper stays horizontal), after two far goals
    near = q.start.copy()
    near[0] += 5e-4
    res = planner.plan(q.start, np.vstack([q.goals[:2], near]))
    assert res.success and res.goal_index == 2 and res.path.shape == (1, 7)
    np.testing.assert_array_equal(res.path[0], q.start)
    # its trajectory stands still
    traj = res.trajectory()
    assert len(traj) == 1 and traj.duration == 0.0


def test_integrity_3_plan_to_the_start_stays(panda, shelf) -> None:
    """The front end (`genplan plan --goal` the start): one state, not a detour."""
    from genplan.planning import plan

    start = shelf[2][0].start
    outcome = plan(panda, "panda_ik", "panda_shelf", start=start, goal=start)
    r = outcome.result
    assert r.success and r.path.shape == (1, 7)
    np.testing.assert_array_equal(r.path[0], outcome.query.start)


def _chord_ratio(robot: genplan.Robot, task: P.Task, a: np.ndarray, b: np.ndarray) -> float:
    """The largest primary residual / tolerance of ``task`` at the midpoint of the chord a-b."""
    return _task_violation(robot, task, pin.interpolate(robot.model, a, b, 0.5))


def _task_violation(robot: genplan.Robot, task: P.Task, x: np.ndarray) -> float:
    s = P._State(robot, x, False)
    return max((float(np.abs(r).max()) / t.tolerance for t in task.primary if (r := t.bind(robot).residual(s)).size),
               default=0.0)


def test_integrity_3_shortcut_chords_keep_the_constraint(panda, shelf) -> None:
    """A seeded shortcut plan (uniform sampler, seed 3, the second query of seed 0) whose chords
    once left the tolerance (1.05x): every chord's midpoint is on the manifold within the task's
    tolerance, every step at most 1.25 x edge_resolution."""
    env, world, _ = shelf
    q = env.queries(panda, n=2, seed=0)[1]
    planner = Planner(panda, world=world, sampler="uniform", seed=3, settings=PlannerSettings(simplify=True))
    res = planner.plan(q.start, q.goals)
    assert res.success and res.stats.shortcuts > 0
    path = res.path
    worst = max(_chord_ratio(panda, planner.task, a, b) for a, b in zip(path[:-1], path[1:]))
    assert worst < 1.0, f"a chord's midpoint leaves the tolerance: {worst:.3f}x"
    steps = np.linalg.norm([pin.difference(panda.model, a, b) for a, b in zip(path[:-1], path[1:])], axis=1)
    assert steps.max() <= 1.25 * PlannerSettings().edge_resolution + 1e-12
    assert res.stats.chord_checks > 0
