"""genplan.seq2seq.finish: the clearance repair of finished paths (push_clear), and the
trajectory check it feeds (every repaired state still checked against the world and the task)."""

import numpy as np
import pytest

import genplan
from genplan.projection import GaussNewtonProjector, load_task
from genplan.seq2seq.finish import CLEAR_MARGIN, push_clear
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
