"""PlanResult.trajectory / genplan.trajectory: time-optimal (TOPP-RA) trajectories of plans, within
the limits and on the manifold at every 1 kHz sample; files; the HTML view; `genplan plan --trajectory`."""

import importlib.util
import json

import numpy as np
import pytest

import genplan
from genplan import _core
from genplan.errors import GenplanError, SettingsError, ShapeError, UnknownNameError
from genplan.planning import Planner, PlannerSettings, PlanResult, environment
from genplan.projection import GaussNewtonProjector, SolverSettings
from genplan.trajectory import DEFAULT_ACCELERATION_FACTOR, Trajectory, parameterize


@pytest.fixture(scope="module")
def panda():
    return genplan.load("panda")


@pytest.fixture(scope="module")
def planner(panda):
    env = environment("panda_shelf")
    return Planner(panda, world=env.world(panda), sampler="gan", settings=PlannerSettings(simplify=True))


@pytest.fixture(scope="module")
def result(panda, planner):
    query = environment("panda_shelf").queries(panda, n=1, seed=0)[0]
    res = planner.plan(query.start, query.goals)
    assert res.success
    return res


@pytest.fixture(scope="module")
def traj(result):
    return result.trajectory()


def test_plan_result_wraps_the_native_one(result, planner) -> None:
    assert isinstance(result, PlanResult) and isinstance(result.native, _core.PlanResult)
    assert result.path is not None and result.path.shape == result.native.path.shape
    assert result.stats.nodes == result.native.stats.nodes and result.time_s == result.native.time_s
    assert result.goal_index == result.native.goal_index and len(result.waypoints) >= 2
    assert repr(result) == repr(result.native) and result.task is planner.task


def test_samples_at_the_rate_from_start_to_goal_at_rest(result, traj) -> None:
    assert traj.rate_hz == 1000.0 and traj.t[0] == 0.0
    assert np.allclose(np.diff(traj.t)[:-1], 1e-3) and 0 < traj.t[-1] - traj.t[-2] <= 1e-3 + 1e-12
    assert traj.q.shape == traj.qd.shape == traj.qdd.shape == (len(traj.t), 7)
    np.testing.assert_array_equal(traj.q[0], result.path[0])
    np.testing.assert_array_equal(traj.q[-1], result.path[-1])
    assert not traj.qd[0].any() and not traj.qd[-1].any()


def test_velocities_and_accelerations_within_the_limits(panda, traj) -> None:
    vlim = np.asarray(panda.model.velocityLimit)
    np.testing.assert_allclose(traj.velocity_limits, vlim)
    np.testing.assert_allclose(traj.acceleration_limits, DEFAULT_ACCELERATION_FACTOR * vlim)
    assert np.abs(traj.qd).max(axis=0) @ np.ones(7) > 0
    assert (np.abs(traj.qd) <= vlim).all() and traj.max_velocity_ratio <= 1.0
    assert (np.abs(traj.qdd) <= traj.acceleration_limits).all()
    assert traj.max_velocity_ratio > 0.7  # time-optimal: some joint near its limit


def test_derivatives_are_consistent(traj) -> None:
    """qd and qdd are the derivatives of q: central differences agree."""
    h = 1e-3
    fd_v = (traj.q[2:-1] - traj.q[:-3]) / (2 * h)
    assert np.abs(fd_v - traj.qd[1:-2]).max() < 0.02 * np.abs(traj.qd).max()
    fd_a = (traj.qd[2:-1] - traj.qd[:-3]) / (2 * h)
    assert np.median(np.abs(fd_a - traj.qdd[1:-2])) < 0.01 * np.abs(traj.qdd).max()


def test_every_sample_satisfies_the_constraint(panda, planner, traj) -> None:
    assert set(traj.residuals) == {t.label() for t in planner.task.primary}
    assert traj.within_tolerance and traj.max_residual_ratio <= 1.0
    # an independent reading: the Pinocchio backend, no solver step, on every 7th sample
    check = GaussNewtonProjector(panda, planner.task, SolverSettings(max_iterations=0, clip_to_limits=False),
                                 backend="pinocchio")
    res = check.solve_batch(traj.q[::7], parallel=False)
    for term in planner.task.primary:
        assert res.residuals[term.label()].max() <= term.tolerance
        assert res.residuals[term.label()].max() <= traj.residuals[term.label()] + 1e-12


def test_scales_and_acceleration_limits(result, traj, panda) -> None:
    slow = result.trajectory(velocity_scale=0.5, acceleration_scale=0.5, rate_hz=250)
    vlim = np.asarray(panda.model.velocityLimit)
    assert (np.abs(slow.qd) <= 0.5 * vlim).all() and slow.duration > 1.5 * traj.duration
    assert np.allclose(np.diff(slow.t)[:-1], 1 / 250)
    brisk = result.trajectory(acceleration_limits=10.0)
    assert (np.abs(brisk.qdd) <= 10.0).all() and brisk.duration < traj.duration


@pytest.mark.parametrize("kwargs, error, words", [
    ({"rate_hz": 0}, SettingsError, "rate_hz"),
    ({"velocity_scale": -1}, SettingsError, "velocity_scale"),
    ({"acceleration_scale": float("nan")}, SettingsError, "acceleration_scale"),
    ({"acceleration_limits": [1.0, 2.0]}, ShapeError, "acceleration_limits"),
    ({"acceleration_limits": -3.0}, SettingsError, "acceleration_limits"),
])
def test_bad_arguments(result, kwargs, error, words) -> None:
    with pytest.raises(error, match=words):
        result.trajectory(**kwargs)


def test_a_failed_plan_has_no_trajectory(panda, result) -> None:
    failed = PlanResult(result.native, panda, result.task, result.world)
    object.__setattr__(failed, "native", type("Failed", (), {"success": False, "path": np.zeros((0, 7))})())
    with pytest.raises(GenplanError, match="no path"):
        failed.trajectory()


def test_a_still_path_is_one_sample(panda) -> None:
    still = parameterize(panda, np.tile(panda.q_default, (3, 1)))
    assert len(still) == 1 and still.duration == 0.0 and not still.qd.any()


@pytest.mark.parametrize("suffix", [".npz", ".json", ".csv"])
def test_save_load_round_trip(traj, tmp_path, suffix) -> None:
    path = traj.save(tmp_path / f"sub/traj{suffix}")
    assert path.exists() and [p.name for p in path.parent.iterdir()] == [path.name]  # atomic: no temporary left
    back = Trajectory.load(path)
    for k in ("t", "q", "qd", "qdd"):
        np.testing.assert_array_equal(getattr(back, k), getattr(traj, k))
    assert back.joint_names == traj.joint_names and back.rate_hz == traj.rate_hz
    if suffix != ".csv":
        assert back.residuals == traj.residuals and back.tolerances == traj.tolerances
        np.testing.assert_array_equal(back.velocity_limits, traj.velocity_limits)
        assert back.stats == json.loads(json.dumps(traj.stats)) and back.robot == "panda"


def test_unknown_format_is_refused(traj, tmp_path) -> None:
    with pytest.raises(UnknownNameError, match=r"\.npz, \.json, \.csv"):
        traj.save(tmp_path / "traj.txt")
    assert not list(tmp_path.iterdir())


@pytest.mark.skipif(importlib.util.find_spec("viser") is None, reason="viewer extra not installed")
def test_the_html_view_plays_the_trajectory(panda, traj, tmp_path) -> None:
    from genplan.viewer import export_html

    out = export_html(panda, traj, tmp_path / "t.html", fps=10, max_frames=500)
    page = out.read_text()
    assert f"a {traj.duration:.2f} s trajectory" in page


def test_plan_cli_writes_the_trajectory(panda, tmp_path, capsys) -> None:
    from genplan.cli import main

    start = environment("panda_shelf").queries(panda, n=1, seed=0)[0].start  # the default collides on the manifold
    argv = ["plan", "--robot", "panda", "--task", "panda_ik", "--scene", "panda_shelf", "--start",
            " ".join(map(repr, map(float, start))), "--target", "0.5", "-0.25", "0.3", "--goals", "3", "--seed", "2",
            "--out", str(tmp_path / "p.json"), "--trajectory"]
    out = tmp_path / "traj.csv"
    assert main([*argv, str(out)]) == 0, capsys.readouterr()
    back = Trajectory.load(out)
    assert len(back) > 10 and "trajectory:" in capsys.readouterr().out
    assert np.abs(back.qd).max() > 0
    assert main([*argv, str(tmp_path / "t.txt")]) == 2
    assert "expected a .npz, .json or .csv file" in capsys.readouterr().err


def _path_parameters(states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The states without consecutive duplicates and their cumulative joint-space distance, as
    parameterize takes them."""
    steps = np.linalg.norm(np.diff(states, axis=0), axis=1)
    states = states[np.concatenate([[True], steps > 1e-12])]
    return states, np.concatenate([[0.0], np.cumsum(steps[steps > 1e-12])])


def _timed(states: np.ndarray, ss: np.ndarray, vlim: np.ndarray, alim: np.ndarray) -> "_core.TimedPath":
    from genplan import trajectory as T

    return _core.TimedPath(ss.tolist(), np.ascontiguousarray(states), vlim.tolist(), alim.tolist(), T.GRID_BASE,
                           T.GRID_CRITICAL)


def _grid_oracle(spline, ss: np.ndarray, vlim: np.ndarray, alim: np.ndarray) -> np.ndarray:
    """The grid rule of genplan.trajectory (GRID_BASE, GRID_CRITICAL) read with numpy on a scipy
    spline: an independent reading of rust/core/src/timing.rs's gridpoints."""
    from genplan.trajectory import GRID_BASE, GRID_CRITICAL

    d1, d2 = np.abs(spline(ss, 1)), np.abs(spline(ss, 2))
    s_max2 = np.min(vlim / np.maximum(d1, 1e-12), axis=1) ** 2
    need = np.max(d2 * s_max2[:, None] / alim, axis=1)
    base = np.linspace(0, len(ss) - 1, min(GRID_BASE, len(ss))).round().astype(int)
    idx = np.union1d(base, np.nonzero(need > GRID_CRITICAL)[0])
    hot = np.nonzero(np.maximum(need[:-1], need[1:]) > 4.0 * GRID_CRITICAL)[0]
    extra = (ss[hot, None] + (ss[hot + 1] - ss[hot])[:, None] * np.array([0.25, 0.5, 0.75])[None, :]).ravel()
    even = np.linspace(0.0, ss[-1], GRID_BASE) if len(ss) < GRID_BASE else ss[:0]
    return np.unique(np.concatenate([ss[idx], extra, even]))


@pytest.mark.parametrize("states", [2, 3, 5, 41, 300])
def test_the_native_spline_and_grid_are_scipys(panda, states) -> None:
    """_core.TimedPath's not-a-knot spline against scipy's CubicSpline (the samples at rest at
    its grid points: q = p(s)) and its grid against the numpy reading of the rule, on random
    paths of 2 to 300 states (uneven steps): the same grid, the same positions to round-off."""
    from scipy.interpolate import CubicSpline

    from genplan.trajectory import joint_limits

    rng = np.random.default_rng(states)
    steps = rng.uniform(0.002, 0.05, (states - 1, 7)) * rng.choice([-1.0, 1.0], (states - 1, 7))
    raw = panda.q_default + np.concatenate([np.zeros((1, 7)), np.cumsum(steps, axis=0)])
    path, ss = _path_parameters(raw)
    vlim, alim = joint_limits(panda)
    timed = _timed(path, ss, vlim, alim)
    spline = CubicSpline(ss, path)
    np.testing.assert_array_equal(timed.grid, _grid_oracle(spline, ss, vlim, alim))
    t, q, qd, _ = timed.sample(1000.0, 1.0)
    assert t[-1] == pytest.approx(timed.duration) and not qd[0].any()
    # every 50th sample on scipy's spline: its s found by Newton's method from the nearest state
    for k in range(0, len(t), max(1, len(t) // 50)):
        s = ss[np.argmin(np.linalg.norm(path - q[k], axis=1))]
        for _ in range(20):
            d = spline(s, 1)
            s = float(np.clip(s - (spline(s) - q[k]) @ d / (d @ d), 0.0, ss[-1]))
        assert np.abs(spline(s) - q[k]).max() < 1e-12, (k, np.abs(spline(s) - q[k]).max())


def test_the_native_topp_ra_matches_toppra(panda, result) -> None:
    """rust/core/src/timing.rs against the ``toppra`` package on the same path, grid and limits
    (TOPPRA, joint velocity and acceleration constraints, interpolation discretisation, its
    SplineInterpolator: scipy's not-a-knot spline): the same speed profile within toppra's
    solver tolerance, hence the same duration."""
    import toppra  # the test extra's
    import toppra.algorithm as algo
    import toppra.constraint as constraint
    from genplan import trajectory as T

    states, ss = _path_parameters(result.path)
    vlim, alim = T.joint_limits(panda)
    spline = toppra.SplineInterpolator(ss, states)
    timed = _timed(states, ss, vlim, alim)
    grid = timed.grid
    instance = algo.TOPPRA(
        [constraint.JointVelocityConstraint(np.stack([-vlim, vlim], axis=1)),
         constraint.JointAccelerationConstraint(np.stack([-alim, alim], axis=1),
                                                discretization_scheme=constraint.DiscretizationType.Interpolation)],
        spline, gridpoints=grid, solver_wrapper="seidel")
    _, sd, _, _ = instance.compute_parameterization(0.0, 0.0, return_data=True)
    theirs = np.maximum(np.asarray(sd), 0.0)
    mine = timed.sdot
    assert len(grid) > 50 and mine.max() > 0.1
    assert np.max(np.abs(mine - theirs)) <= 1e-3 * theirs.max(), np.max(np.abs(mine - theirs))
    # the native profile on the spline's derivatives through the bare function: the same
    bare = np.sqrt(np.maximum(_core.time_optimal(grid.tolist(), np.ascontiguousarray(spline(grid, 1)),
                                                 np.ascontiguousarray(spline(grid, 2)), vlim.tolist(), alim.tolist()), 0))
    assert np.max(np.abs(mine - bare)) <= 1e-6 * theirs.max()

    def duration(sdot: np.ndarray) -> float:
        return float(np.sum(2.0 * np.diff(grid) / (sdot[:-1] + sdot[1:])))

    assert abs(duration(mine) - duration(theirs)) <= 1e-3 * duration(theirs)
    assert timed.duration == pytest.approx(duration(mine), rel=1e-12)


def test_the_native_topp_ra_refuses_bad_input() -> None:
    grid = [0.0, 0.5, 1.0]
    d = np.ones((3, 2))
    with pytest.raises(ValueError, match="one limit per joint"):
        _core.time_optimal(grid, d, d, [1.0, 1.0], [1.0])
    with pytest.raises(ValueError, match="must increase"):
        _core.time_optimal([0.0, 0.5, 0.5], d, d, [1.0, 1.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="d1 and d2"):
        _core.time_optimal(grid, d[:2], d, [1.0, 1.0], [1.0, 1.0])
    with pytest.raises(ShapeError, match=r"states: expected shape \(3, 2\)"):
        _core.TimedPath(grid, d[:2], [1.0, 1.0], [1.0, 1.0], 40, 1.0)
    with pytest.raises(ValueError, match="x: must increase"):
        _core.TimedPath([0.0, 0.5, 0.5], d, [1.0, 1.0], [1.0, 1.0], 40, 1.0)
    with pytest.raises(ValueError, match="one limit per joint"):
        _core.TimedPath(grid, d, [1.0, 1.0], [1.0], 40, 1.0)


# -- a trajectory is a success only when every sample passes its checks ------------------------


def _sweep(panda, joint: int = 0, length: float = 1.0, states: int = 41) -> np.ndarray:
    """A dense straight path from the default configuration, ``joint`` moved by ``length``."""
    path = np.tile(panda.q_default, (states, 1))
    path[:, joint] += np.linspace(0.0, length, states)
    return path


def test_integrity_3_a_plan_keeps_its_world_and_its_trajectory_is_checked_against_it(panda) -> None:
    """A nodes-only plan (edge_resolution 0; seed 0, the first shelf query of seed 1): the chords
    between its states leave the manifold and pass through the shelf, and 51 of its trajectory's
    samples were in contact (the first, 8019). The trajectory is refused, naming the first bad
    sample; checked against the world alone, the first sample in contact and the pair."""
    from genplan.errors import InvalidTrajectoryError
    from genplan.trajectory import parameterize

    env = environment("panda_shelf")
    world = env.world(panda)
    q = env.queries(panda, n=1, seed=1)[0]
    res = Planner(panda, world=world, sampler="uniform", seed=0,
                  settings=PlannerSettings(edge_resolution=0.0)).plan(q.start, q.goals)
    assert res.success and res.world is world
    with pytest.raises(InvalidTrajectoryError, match=r"trajectory: sample \d+ \(t = \d+\.\d+ s\) is "):
        res.trajectory()
    timed = parameterize(panda, res.path)
    first = int(np.argmax(np.asarray(world.in_collision(timed.q), dtype=bool)))
    assert first > 0
    with pytest.raises(InvalidTrajectoryError, match=rf"sample {first} \(t = {timed.t[first]:.3f} s\) is in collision: "
                                                     r"panda_\w+ and \w+"):
        parameterize(panda, res.path, world=world)


def test_integrity_3_samples_in_collision_are_an_error_naming_the_first(panda) -> None:
    from genplan.errors import InvalidTrajectoryError

    path = _sweep(panda)
    world = panda.collision_world()
    world.add_sphere("ball", 0.02, panda.frame_positions(path[20], "tcp"))  # states 14-26 in contact
    free = panda.collision_world()
    traj = parameterize(panda, path, world=free)
    first = int(np.argmax(np.asarray(world.in_collision(traj.q), dtype=bool)))
    assert 0 < first < len(traj)
    with pytest.raises(InvalidTrajectoryError, match=rf"sample {first} \(t = {traj.t[first]:.3f} s\) is in collision: "
                                                     r"panda_\w+ and ball"):
        parameterize(panda, path, world=world)
    with pytest.raises(InvalidTrajectoryError, match=rf"sample {first} .* and ball"):  # the native world alike
        parameterize(panda, path, world=world.native)


def test_integrity_3_a_python_checker_checks_the_samples(panda) -> None:
    """A plan checked by a Python checker: its trajectory's samples go through the same checker."""
    from genplan.errors import InvalidTrajectoryError

    class Calls:
        def __init__(self, limit: float) -> None:
            self.limit, self.rows = limit, 0

        def is_valid(self, qs: np.ndarray) -> np.ndarray:
            self.rows += len(qs)
            return qs[:, 0] < self.limit

    path = _sweep(panda)
    ok = Calls(2.0)
    traj = parameterize(panda, path, world=ok)
    assert ok.rows == len(traj)
    with pytest.raises(InvalidTrajectoryError, match=r"sample \d+ \(t = \d+\.\d+ s\) is not valid \(the checker Calls\)"):
        parameterize(panda, path, world=Calls(0.5))


@pytest.mark.parametrize("values", [(-0.3, -0.05, 0.0, -0.2, -0.25), (-0.2, -0.02, 0.0, 0.0, -0.1)])
def test_integrity_3_samples_stay_within_the_joint_limits_with_no_tolerance(panda, values) -> None:
    """A path with a state at a joint's upper limit: the not-a-knot spline through it overshot the
    limit by 2-4 mrad; now every sample is within the limits, exactly, the joint at rest on its
    limit where the spline would have left it."""
    j = 3
    path = np.tile(panda.q_default, (5, 1))
    path[:, j] = panda.upper[j] + np.asarray(values)
    path[:, 0] = np.linspace(0.0, 0.5, 5)
    traj = parameterize(panda, path)
    assert (traj.q >= panda.lower).all() and (traj.q <= panda.upper).all()
    on = traj.q[:, j] == panda.upper[j]
    assert on.sum() > 10 and 0 < traj.stats["samples_into_limits"] <= on.sum()
    assert not traj.qd[on, j].any() and not traj.qdd[on, j].any()
    # elsewhere qd is still the derivative of q
    fd = (traj.q[2:, j] - traj.q[:-2, j]) / (traj.t[2:] - traj.t[:-2])
    away = ~(on[2:] | on[1:-1] | on[:-2])
    assert np.abs(fd - traj.qd[1:-1, j])[away].max() < 0.02 * np.abs(traj.qd[:, j]).max()
    assert (np.abs(traj.qd) <= traj.velocity_limits).all() and (np.abs(traj.qdd) <= traj.acceleration_limits).all()


def test_integrity_3_parameterize_refuses_states_outside_the_limits(panda) -> None:
    from genplan.errors import InvalidTrajectoryError

    path = _sweep(panda, states=5)
    path[3, 2] = panda.upper[2] + 5.0
    with pytest.raises(InvalidTrajectoryError, match=r"path\[3\]: joint 2 \(panda_joint3\) at 7\.\d+ is outside its "
                                                     r"limits \[-2\.\d+, 2\.\d+\]"):
        parameterize(panda, path)
    path[3, 2] = panda.lower[2] - 1e-12  # no tolerance
    with pytest.raises(InvalidTrajectoryError, match=r"path\[3\]: joint 2"):
        parameterize(panda, path)


@pytest.mark.parametrize("repeat", [1, 3])
def test_integrity_3_two_distinct_states_are_timed(panda, repeat) -> None:
    """Any path of two or more distinct states is timed (duplicates dropped first): from rest to
    rest along the straight line, within every limit."""
    a = panda.q_default
    b = a + np.linspace(0.1, 0.4, 7)
    traj = parameterize(panda, np.array([a] * repeat + [b] * repeat))
    assert traj.duration > 0 and len(traj) > 10 and traj.stats["path_states"] == 2
    np.testing.assert_array_equal(traj.q[0], a)
    np.testing.assert_array_equal(traj.q[-1], b)
    # on the segment: every sample a convex combination of a and b
    s = (traj.q - a) @ (b - a) / ((b - a) @ (b - a))
    np.testing.assert_allclose(traj.q, a + s[:, None] * (b - a), atol=1e-12)
    assert (np.abs(traj.qd) <= traj.velocity_limits).all() and (np.abs(traj.qdd) <= traj.acceleration_limits).all()
    assert traj.max_velocity_ratio > 0.5 or traj.max_acceleration_ratio > 0.9


def test_integrity_3_a_trajectory_off_the_manifold_is_an_error(panda) -> None:
    """Samples that leave the task's tolerance are an error naming the term and the first sample,
    not a warning."""
    from genplan.errors import InvalidTrajectoryError
    from genplan.projection import paper_task

    task = paper_task(panda, "projection")
    path = _sweep(panda, joint=5, length=0.6, states=3)  # the wrist tilts the gripper
    with pytest.raises(InvalidTrajectoryError, match=r"sample \d+ \(t = \d+\.\d+ s\) is off the task's manifold: "
                                                     r"term '\w+' residual .* > tolerance"):
        parameterize(panda, path, task)


_ALLOCATION_SCRIPT = """
import resource, sys
import numpy as np
import genplan
from genplan.errors import GenplanError
from genplan.trajectory import parameterize

panda = genplan.load("panda")
path = np.tile(panda.q_default, (41, 1))
path[:, 0] += np.linspace(0.0, 1.0, 41)
duration = parameterize(panda, path).duration
want, limit = float(sys.argv[1]) * 2**30, int(float(sys.argv[2]) * 2**30)
rate = want / (duration * (1 + 3 * 7) * 8)  # samples of t, q, qd, qdd: 8 bytes each
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
try:
    parameterize(panda, path, rate_hz=rate)
    print("no error")
except GenplanError as e:
    print(type(e).__name__, e)
"""


@pytest.mark.parametrize("gib, limit_gib, words", [
    (2.8, 2.5, r"SettingsError rate_hz: .* 2\.8\d GiB, more than the 1\.00 GiB"),   # over the bound: refused before allocating
    (0.9, 1.0, r"SettingsError rate_hz: .* could not be allocated"),                 # under it, but out of memory
])
def test_integrity_6_a_trajectory_too_large_to_allocate_is_a_typed_error(gib, limit_gib, words) -> None:
    """A sample count that needs more memory than there is aborted the interpreter (a Rust
    allocation failure, SIGABRT); now the count is bounded from the duration and the rate before
    anything is allocated, and the allocation itself is fallible: a typed error naming rate_hz
    and the size."""
    import re
    import subprocess
    import sys

    run = subprocess.run([sys.executable, "-c", _ALLOCATION_SCRIPT, str(gib), str(limit_gib)], capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, (run.returncode, run.stderr[-2000:])
    assert re.search(words, run.stdout), run.stdout


def test_integrity_3_genplan_plan_to_its_start_stays(panda, tmp_path, capsys) -> None:
    """`genplan plan` with the goal at the start: one state (it was a 237-state detour swinging
    1.8 rad), and a trajectory that stands still."""
    from genplan.cli import main

    start = " ".join(map(repr, map(float, environment("panda_shelf").queries(panda, n=1, seed=0)[0].start)))
    argv = ["plan", "--robot", "panda", "--task", "panda_ik", "--scene", "panda_shelf", "--start", start, "--goal", start,
            "--out", str(tmp_path / "p.json"), "--trajectory", str(tmp_path / "t.npz")]
    assert main(argv) == 0
    assert "found: 1 states" in capsys.readouterr().out
    assert len(json.loads((tmp_path / "p.json").read_text())["path"]) == 1
    back = Trajectory.load(tmp_path / "t.npz")
    assert len(back) == 1 and back.duration == 0.0


def test_integrity_rerun_low_rate_checks_between_samples(panda) -> None:
    """At rate_hz=10 only the output samples were checked: 2 of 20 Panda shelf plans were
    accepted although the spline between two samples collides. Now the samples are checked at
    CHECK_RATE_HZ at least and the trajectory is every k-th of them: a ball the 5 Hz samples miss
    but the motion between two of them passes through is refused, and a free trajectory at 5 Hz
    is the 1 kHz one's every 200th sample (and its end)."""
    from genplan.errors import InvalidTrajectoryError
    from genplan.trajectory import CHECK_RATE_HZ

    assert CHECK_RATE_HZ >= 1000.0
    path = _sweep(panda, length=2.5)
    free = panda.collision_world()
    slow, fast = parameterize(panda, path, rate_hz=5, world=free), parameterize(panda, path, rate_hz=1000, world=free)
    assert slow.rate_hz == 5 and fast.stats["check_rate_hz"] == slow.stats["check_rate_hz"] == 1000
    keep = np.arange(0, len(fast), 200)
    if keep[-1] != len(fast) - 1:
        keep = np.append(keep, len(fast) - 1)
    assert np.array_equal(slow.q, fast.q[keep]) and np.array_equal(slow.t, fast.t[keep])
    assert np.allclose(np.diff(slow.t[:-1]), 0.2) and slow.t[-1] == fast.t[-1]
    # a ball at the tool between two 5 Hz samples, away from both
    k = len(slow) // 2
    middle = int(np.argmin(np.abs(fast.t - 0.5 * (slow.t[k] + slow.t[k + 1]))))
    world = panda.collision_world()
    world.add_sphere("ball", 0.01, panda.frame_positions(fast.q[middle], "tcp"))
    assert not np.asarray(world.in_collision(slow.q), dtype=bool).any()  # the output samples alone miss it
    assert np.asarray(world.in_collision(fast.q), dtype=bool).any()
    with pytest.raises(InvalidTrajectoryError, match=r"of the samples checked at 1000 Hz is in collision: .*ball"):
        parameterize(panda, path, rate_hz=5, world=world)
    odd = parameterize(panda, path, rate_hz=300, world=free)  # not a divisor of 1000: checked at 1200 Hz
    assert odd.stats["check_rate_hz"] == 1200 and odd.rate_hz == 300 and np.allclose(np.diff(odd.t[:-1]), 1 / 300)


def test_integrity_rerun_a_corrupt_npz_is_a_data_file_error_naming_it(traj, tmp_path) -> None:
    """Trajectory.load of junk bytes or of a file with one bit flipped (its zip member failing
    the CRC) raised zipfile.BadZipFile; now DataFileError (a GenplanError) naming the file."""
    from genplan.errors import DataFileError

    good = traj.save(tmp_path / "good.npz")
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"\x00not a zip file\xff" * 50)
    flipped = tmp_path / "flipped.npz"
    raw = bytearray(good.read_bytes())
    raw[raw.find(traj.q[len(traj) // 2].tobytes()) + 3] ^= 0x01  # in q's data
    flipped.write_bytes(bytes(raw))
    npy = tmp_path / "one.npz"
    with open(npy, "wb") as fh:
        np.save(fh, np.zeros(3))
    for bad, why in ((junk, "ValueError"), (flipped, "BadZipFile: Bad CRC-32 for file 'q.npy'"),
                     (npy, "ValueError: a single .npy array")):
        with pytest.raises(DataFileError, match=rf"^trajectory file {bad}: not a readable \.npz file \({why}"):
            Trajectory.load(bad)
    np.savez(tmp_path / "plain.npz", t=np.zeros(2))
    with pytest.raises(DataFileError, match=r"plain\.npz: not a trajectory written by Trajectory\.save \(KeyError"):
        Trajectory.load(tmp_path / "plain.npz")
    assert np.array_equal(Trajectory.load(good).q, traj.q)


def test_continuous_joints_are_timed_as_angles_and_a_free_flyer_is_refused() -> None:
    """Kinova's continuous joints: a plan on the committed upright-tool task is time-parameterised
    (q keeps Pinocchio's unit [cos, sin] pairs, qd/qdd one per joint, every sample on the
    manifold); a move across the +-pi seam of a continuous joint takes the short way round;
    Talos (a free-flying base) is refused by name."""
    from pathlib import Path

    from genplan import projection as P
    from genplan.planning import plan

    kinova = genplan.load("kinova")
    task = P.load_task(str(Path(__file__).parents[1] / "examples" / "kinova" / "upright_tool.toml"), kinova)
    outcome = plan(kinova, task, None, start="default", target=[0.45, 0.2, 0.3], seed=0)
    assert outcome.result.success
    traj = outcome.result.trajectory()
    assert traj.q.shape[1] == kinova.nq and traj.qd.shape[1] == traj.qdd.shape[1] == kinova.nv
    assert traj.within_tolerance and traj.max_residual_ratio <= 1.0
    for i in kinova.continuous:
        np.testing.assert_allclose(np.linalg.norm(traj.q[:, i:i + 2], axis=1), 1.0, atol=1e-12)
    x = kinova.joint_values(traj.q)
    assert np.abs(np.diff(x, axis=0)).max() <= np.max(traj.velocity_limits) * 1e-3 + 1e-12  # no 2 pi jump
    np.testing.assert_allclose(kinova.from_joint_values(x), traj.q, atol=1e-12)
    # across the seam: -3.0 rad is 2 pi - 3.0 = 3.28 rad, 0.28 rad from 3.0 the short way
    a = kinova.from_joint_values(np.array([[3.0, 3.5, 2.0, 0.0, 3.0, 0.0]]))[0]
    b = kinova.from_joint_values(np.array([[-3.0, 3.5, 2.0, 0.5, 3.0, 0.5]]))[0]
    seam = kinova.joint_values(parameterize(kinova, np.array([a, b])).q)
    assert seam[0, 0] == pytest.approx(3.0) and seam[-1, 0] == pytest.approx(2 * np.pi - 3.0)
    assert np.all(np.diff(seam[:, 0]) >= -1e-12)
    talos = genplan.load("talos")
    with pytest.raises(GenplanError, match="free-flying base"):
        parameterize(talos, np.array([talos.q_default, talos.q_default]))
