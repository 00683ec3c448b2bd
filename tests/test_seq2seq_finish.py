"""genplan.seq2seq.finish: the clearance repair of finished paths (push_clear, its step along the
manifold), and the trajectory check it feeds (every repaired state still checked against the world
and the task)."""

import numpy as np
import pytest

import genplan
from genplan.projection import GaussNewtonProjector, load_task
from genplan.seq2seq.finish import CLEAR_MARGIN, _tangent, push_clear
from tests.conftest import random_configurations


@pytest.fixture(scope="module")
def setting(panda: genplan.Robot):
    task = load_task("panda_projection", panda)
    proj = GaussNewtonProjector(panda, task.with_tolerances_scaled(0.1))
    # a state on the manifold at least 5 cm clear of the arm itself
    res = proj.solve_batch(random_configurations(panda, 50, seed=3))
    clear = res.success & (np.asarray(panda.collision_world().min_distance(res.q)) > 0.05)
    start = res.q[int(np.argmax(clear))]
    assert clear.any()
    return task, proj, start


def _world_with_ball(panda: genplan.Robot, q: np.ndarray, link: str, radius: float, above: float = 0.1):
    """The robot's world with a ball ``above`` m over ``link``'s origin at ``q`` (``q`` in it by a
    few centimetres)."""
    world = panda.collision_world()
    world.add_sphere("ball", radius, panda.frame_positions(q[None], link)[0] + [0.0, 0.0, above])
    return world


def test_push_clear_moves_a_state_out_of_a_ball_and_keeps_it_on_the_manifold(panda, setting) -> None:
    task, proj, start = setting
    world = _world_with_ball(panda, start, "panda_link4", 0.05)
    assert world.in_collision(start)
    out = push_clear(start[None], world, lambda x: proj.solve_batch(x, x), steps=30)
    assert out is not None and out.shape == (1, panda.nq)
    assert not world.in_collision(out[0])
    assert world.min_distance(out[0]) >= 0.0
    sizes = GaussNewtonProjector(panda, task).residual_sizes(out)
    assert all(sizes[t.label()][0] <= t.tolerance for t in task.primary)
    assert np.abs(out[0] - start).max() > 1e-3  # it moved


def test_push_clear_leaves_clear_states_as_they_are(panda, setting) -> None:
    _, proj, start = setting
    world = panda.collision_world()
    world.add_sphere("far", 0.05, [3.0, 3.0, 3.0])
    assert world.min_distance(start) > CLEAR_MARGIN
    out = push_clear(start[None], world, lambda x: proj.solve_batch(x, x))
    assert out is not None
    np.testing.assert_array_equal(out, start[None])


def test_push_clear_reports_a_failed_projection(panda, setting) -> None:
    _, _, start = setting
    world = _world_with_ball(panda, start, "panda_link4", 0.05)

    class Failed:
        def __init__(self, q):
            self.q, self.success = q, np.zeros(len(q), dtype=bool)

    assert push_clear(start[None], world, Failed) is None


def test_the_clearance_step_lies_in_the_tangent_space_of_the_manifold(panda, setting) -> None:
    """With constraints, the gradient loses exactly its part across the manifold: the task
    Jacobian maps the result to zero and the removed part lies in the Jacobian's row space."""
    _, proj, start = setting
    q = np.repeat(start[None], 3, 0)
    v = np.random.default_rng(0).standard_normal((3, panda.nq))
    t = _tangent(proj, q, v)
    _, jac = proj.native.primary_residuals(q, True)
    np.testing.assert_allclose(np.einsum("mij,mj->mi", jac, t), 0.0, atol=1e-9)
    removed = v - t
    rows = np.linalg.pinv(jac) @ jac  # the projector onto the row space
    np.testing.assert_allclose(np.einsum("mij,mj->mi", rows, removed), removed, atol=1e-9)
    assert np.linalg.norm(t) > 0.1 * np.linalg.norm(v)  # the manifold has free directions


def test_push_clear_along_the_manifold_clears_a_state_and_keeps_it_on_it(panda, setting) -> None:
    task, proj, start = setting
    world = _world_with_ball(panda, start, "panda_link4", 0.05)
    assert world.in_collision(start)
    out = push_clear(start[None], world, lambda x: proj.solve_batch(x, x), steps=30, constraints=proj)
    assert out is not None
    assert world.min_distance(out[0]) >= 0.0
    sizes = GaussNewtonProjector(panda, task).residual_sizes(out)
    assert all(sizes[t.label()][0] <= t.tolerance for t in task.primary)


# -- dense paths (native: genplan_core::projection::dense_path) ------------------------------


def _walk(panda: genplan.Robot, proj, start: np.ndarray, k: int, sigma: float, seed: int) -> np.ndarray:
    """``k`` states on the manifold: a random walk from ``start`` (steps of ``sigma`` rad), each
    state projected."""
    rng = np.random.default_rng(seed)
    walk = np.clip(start + np.cumsum(rng.normal(0.0, sigma, (k, panda.nq)), 0), panda.lower, panda.upper)
    res = proj.solve_batch(walk, walk)
    assert res.success.all()
    return res.q


def test_densify_keeps_the_states_in_order_steps_within_the_resolution_on_the_manifold(panda, setting) -> None:
    from genplan.seq2seq.finish import _ChordCheck, densify

    task, proj, start = setting
    q = _walk(panda, proj, start, 6, 0.08, seed=1)
    path, why = densify(q, 0.025, proj)
    assert why is None
    assert np.abs(np.diff(path, axis=0)).max() <= 0.025 * (1 + 1e-9)
    rows = [int(np.nonzero((path == s).all(axis=1))[0][0]) for s in q]  # every input state, in order
    assert rows == sorted(rows) and rows[0] == 0 and rows[-1] == len(path) - 1
    tight = GaussNewtonProjector(panda, task.with_tolerances_scaled(0.1))
    assert all(np.max(v) <= t.tolerance * 0.1 for v, t in zip(tight.residual_sizes(path).values(), task.primary))
    # the chords held: every midpoint within 3/4 of the task's tolerance, no state lost
    held, why = _ChordCheck(panda, task).hold(path, proj, 0.025)
    assert why is None and len(held) >= len(path)
    mids = 0.5 * (held[1:] + held[:-1])
    sizes = GaussNewtonProjector(panda, task).residual_sizes(mids)
    assert all(np.max(v) <= 0.75 * t.tolerance for v, t in zip(sizes.values(), task.primary))
    # without a projector: the interpolation, evenly cut
    plain, why = densify(np.array([np.zeros(panda.nq), np.full(panda.nq, 0.1)]), 0.025)
    assert why is None and len(plain) == 5
    np.testing.assert_allclose(np.diff(plain, axis=0), 0.025, atol=1e-12)


def test_densify_reports_failures_and_refuses_bad_input(panda, setting) -> None:
    from genplan.errors import NonFiniteError, SettingsError, ShapeError
    from genplan.seq2seq import finish as fin

    task, proj, start = setting
    q = _walk(panda, proj, start, 4, 0.2, seed=2)
    # a manifold out of reach (the hand 5 m up): no interpolated state projects; the input comes back
    from genplan.projection import FramePosition, Task

    far = GaussNewtonProjector(panda, Task(primary=(FramePosition(name="up", frame="hand", target=[0.0, 0.0, 5.0],
                                                                  weight=1.0, tolerance=1e-4),), name="far"))
    path, why = fin.densify(q, 0.025, far)
    assert why == "an interpolated state could not be projected onto the task's manifold"
    np.testing.assert_array_equal(path, q)
    bad = q.copy()
    bad[1, 2] = np.nan
    with pytest.raises(NonFiniteError, match=r"paths\[0\]\[1\]"):
        fin.densify(bad, 0.025, proj)
    with pytest.raises(SettingsError, match="resolution"):
        fin.densify(q, 0.0, proj)
    with pytest.raises(ShapeError, match="paths"):
        fin._dense(q[:, :3][None], 0.025, proj, None)
    with pytest.raises(SettingsError, match="native backend"):
        fin.densify(q, 0.025, GaussNewtonProjector(panda, task, backend="pinocchio"))
