"""Jerk-limited timing (genplan.trajectory.parameterize_jerk, genplan_core::jerk): every sample
within the joint, velocity, acceleration and jerk limits with no tolerance, the states reached
exactly and at rest, every sample on its segment's straight line, the durations ruckig's
phase-synchronised ones (when ruckig is installed: the ``bench`` extra), the checks of a
world, bad input refused with typed errors naming the argument."""

from __future__ import annotations

import numpy as np
import pytest

import genplan
from genplan import _core
from genplan.errors import (GenplanError, InvalidTrajectoryError, LimitExceededError, NonFiniteError, SettingsError,
                            ShapeError)
from genplan.trajectory import DEFAULT_JERK_FACTOR, Trajectory, joint_limits, parameterize_jerk


@pytest.fixture(scope="module")
def panda():
    return genplan.load("panda")


def _moves(panda, n: int, seed: int, states: int = 2) -> np.ndarray:
    return np.random.default_rng(seed).uniform(panda.lower, panda.upper, size=(n, states, panda.nq))


def _on_segments(traj: Trajectory, states: np.ndarray) -> None:
    """Every sample on the straight line of the segment its time falls in, between its ends."""
    times = np.asarray(traj.stats["waypoint_times"])
    seg = np.clip(np.searchsorted(times, traj.t, side="right") - 1, 0, len(states) - 2)
    q0, d = states[seg], states[seg + 1] - states[seg]
    frac = np.einsum("ij,ij->i", traj.q - q0, d) / np.einsum("ij,ij->i", d, d)
    assert frac.min() >= -1e-12 and frac.max() <= 1 + 1e-12
    assert np.abs(traj.q - (q0 + frac[:, None] * d)).max() <= 1e-12


def test_random_moves_stay_within_every_limit_on_the_line_ending_exactly_at_rest(panda) -> None:
    vlim, alim = joint_limits(panda)
    for i, path in enumerate(_moves(panda, 30, seed=3)):
        jerks = np.random.default_rng(i).uniform(5.0, 5000.0, panda.nv)
        traj = parameterize_jerk(panda, path, jerk_limits=jerks, velocity_scale=0.3 + 0.02 * i)
        assert np.array_equal(traj.q[0], path[0]) and np.array_equal(traj.q[-1], path[-1])
        assert not traj.qd[[0, -1]].any() and not traj.qdd[[0, -1]].any()
        assert (np.abs(traj.qd) <= traj.velocity_limits).all() and (np.abs(traj.qdd) <= alim).all()
        assert (np.abs(traj.qddd) <= jerks).all() and (traj.q >= panda.lower).all() and (traj.q <= panda.upper).all()
        assert np.allclose(traj.velocity_limits, vlim * (0.3 + 0.02 * i))
        # at least one joint at its jerk limit (an S-curve's jerk phases are at the bound)
        assert np.isclose(np.max(np.abs(traj.qddd) / jerks), 1.0, rtol=1e-8)
        _on_segments(traj, path)
        # the samples are the profile's: the positions integrate the velocities
        assert np.allclose(np.diff(traj.q, axis=0), 0.5 * (traj.qd[1:] + traj.qd[:-1]) * np.diff(traj.t)[:, None],
                           atol=1e-5)


def test_a_path_of_several_states_stops_at_each(panda) -> None:
    path = _moves(panda, 1, seed=5, states=4)[0]
    traj = parameterize_jerk(panda, path)
    times = np.asarray(traj.stats["waypoint_times"])
    assert len(times) == 4 and times[0] == 0.0 and times[-1] == traj.duration
    native = _core.JerkPath(path, *(x.tolist() for x in (traj.velocity_limits, traj.acceleration_limits,
                                                         traj.jerk_limits)))
    assert np.array_equal(native.times, times)
    _on_segments(traj, path)
    # each state passed at rest: the samples nearest its time are nearly still, the state itself
    for k, tk in enumerate(times):
        i = int(np.argmin(np.abs(traj.t - tk)))
        assert np.abs(traj.qd[i]).max() < 1e-2 and np.abs(traj.q[i] - path[k]).max() < 1e-5
    # the same segments timed one by one add up to the path
    singles = [parameterize_jerk(panda, path[k:k + 2]).duration for k in range(3)]
    assert np.isclose(sum(singles), traj.duration, rtol=1e-12)


def test_a_lower_rate_keeps_every_kth_checked_sample(panda) -> None:
    path = _moves(panda, 1, seed=6)[0]
    fine, coarse = parameterize_jerk(panda, path), parameterize_jerk(panda, path, rate_hz=100.0)
    assert coarse.rate_hz == 100.0 and np.array_equal(coarse.q[-1], path[-1])
    assert np.array_equal(coarse.qddd[:-1], fine.qddd[::10][:len(coarse) - 1])


def test_durations_are_ruckigs_phase_synchronised_ones(panda) -> None:
    ruckig = pytest.importorskip("ruckig")
    vlim, alim = joint_limits(panda)
    jlim = DEFAULT_JERK_FACTOR * alim
    n = panda.nv
    for q0, q1 in _moves(panda, 50, seed=8):
        otg, inp, out = ruckig.Ruckig(n), ruckig.InputParameter(n), ruckig.Trajectory(n)
        inp.current_position, inp.target_position = q0.tolist(), q1.tolist()
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = vlim.tolist(), alim.tolist(), jlim.tolist()
        inp.synchronization = ruckig.Synchronization.Phase
        assert otg.calculate(inp, out) == ruckig.Result.Working
        ours = _core.JerkPath(np.stack([q0, q1]), vlim.tolist(), alim.tolist(), jlim.tolist()).duration
        # ours is built for the limits times 1 - 1e-9 (rounding margin): longer by about that
        assert 0.0 <= ours / out.duration - 1.0 < 1e-8


def test_a_still_path_is_one_sample(panda) -> None:
    still = parameterize_jerk(panda, np.tile(panda.q_default, (3, 1)))
    assert len(still) == 1 and still.duration == 0.0 and not still.qddd.any()


def test_world_checks_and_time_limit(panda) -> None:
    path = _moves(panda, 1, seed=9)[0]

    class HalfBlocked:  # a checker refusing the second half of the motion
        def is_valid(self, qs):
            return np.linalg.norm(qs - path[0], axis=1) < 0.5 * np.linalg.norm(path[1] - path[0])

    with pytest.raises(InvalidTrajectoryError, match="sample .* is not valid"):
        parameterize_jerk(panda, path, world=HalfBlocked())
    duration = parameterize_jerk(panda, path).duration
    assert parameterize_jerk(panda, path, time_limit=duration * 1.01).duration == duration
    with pytest.raises(LimitExceededError, match="time_limit"):
        parameterize_jerk(panda, path, time_limit=duration * 0.99)


@pytest.mark.parametrize("kwargs, error, words", [
    ({"jerk_limits": 0.0}, SettingsError, "jerk_limits"),
    ({"jerk_limits": -5.0}, SettingsError, "jerk_limits"),
    ({"jerk_limits": [1.0, 2.0]}, ShapeError, "jerk_limits"),
    ({"jerk_limits": float("nan")}, NonFiniteError, "jerk_limits"),
    ({"jerk_scale": 0}, SettingsError, "jerk_scale"),
    ({"velocity_scale": -1}, SettingsError, "velocity_scale"),
    ({"acceleration_limits": 0.0}, SettingsError, "acceleration_limits"),
    ({"rate_hz": float("nan")}, SettingsError, "rate_hz"),
    ({"time_limit": -1.0}, SettingsError, "time_limit"),
    ({"rate_hz": 1e12}, SettingsError, "rate_hz"),
])
def test_bad_arguments(panda, kwargs, error, words) -> None:
    with pytest.raises(error, match=words):
        parameterize_jerk(panda, _moves(panda, 1, seed=1)[0], **kwargs)


def test_bad_paths(panda) -> None:
    path = _moves(panda, 1, seed=2)[0]
    with pytest.raises(NonFiniteError, match="path"):
        parameterize_jerk(panda, np.where(np.arange(panda.nq) == 3, np.nan, path))
    with pytest.raises(ShapeError, match="path"):
        parameterize_jerk(panda, path[:, :5])
    beyond = path.copy()
    beyond[1, 0] = panda.upper[0] + 0.1
    with pytest.raises(InvalidTrajectoryError, match=r"path\[1\]: joint 0"):
        parameterize_jerk(panda, beyond)
    with pytest.raises(GenplanError, match="states"):
        _core.JerkPath(np.zeros((2, 3)), [1.0] * 3, [1.0] * 3, [1.0] * 3)


def test_a_sample_beyond_the_jerk_limit_is_refused(panda) -> None:
    from genplan.trajectory import _checked

    traj = parameterize_jerk(panda, _moves(panda, 1, seed=4)[0])
    qddd = traj.qddd.copy()
    qddd[7, 2] = traj.jerk_limits[2] * (1 + 1e-15) + 1e-12
    with pytest.raises(InvalidTrajectoryError, match="sample 7 .* jerk limit of joint 2"):
        _checked(traj.replace(qddd=qddd), panda, None, None)
