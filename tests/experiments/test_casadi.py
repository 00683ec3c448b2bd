"""genplan.experiments.peers.casadi: the CasADi + IPOPT peer solves the same problem correctly."""

import math

import numpy as np
import pytest

pytest.importorskip("casadi")

from genplan.experiments.peers.casadi import PancakeNLP, s_curve_accelerations, solve_batch  # noqa: E402
from genplan.pancake.physics import rollout_np  # noqa: E402
from genplan.pancake.trajectories import phi, s_curve  # noqa: E402


def test_reaches_the_end_pose_inside_the_cone() -> None:
    p_end = np.array([[0.1, -0.1, math.pi], [0.0, 0.1, 0.0]])
    res = solve_batch(np.zeros(3), p_end)
    assert res.success.all(), res.status
    np.testing.assert_allclose(res.p[:, -1], p_end, atol=1e-6)
    assert np.abs(res.phi).max() < math.atan(1.0)
    # the reported trajectory is the dynamics' response to the reported accelerations
    for i in range(2):
        x = rollout_np(res.u[i])
        np.testing.assert_allclose(res.p[i], x[:, :3], atol=1e-12)
        np.testing.assert_allclose(res.phi[i], phi(x[:, 2], res.u[i]), atol=1e-12)
    assert np.all(res.solve_time_s > 0) and res.build_time_s > 0


def test_initial_guess_is_the_s_curve() -> None:
    u = s_curve_accelerations(np.zeros(3), [0.1, 0.0, math.pi])
    x = rollout_np(u)
    # the analytic acceleration sampled at 1 ms reproduces the S-curve to 0.3 % of the move
    np.testing.assert_allclose(x[:, :3], s_curve(np.zeros(3), [0.1, 0.0, math.pi]), atol=3e-3 * math.pi)


def test_bad_poses_are_rejected() -> None:
    nlp = PancakeNLP()
    with pytest.raises(ValueError, match="p_end must be a finite pose"):
        nlp.solve(np.zeros(3), [0.0, np.nan, 0.0])
    with pytest.raises(ValueError, match="u_init must have shape"):
        nlp.solve(np.zeros(3), np.zeros(3), u_init=np.zeros((10, 3)))
    with pytest.raises(ValueError, match="objective must be"):
        PancakeNLP(objective="j3")
