"""genplan.seq2seq.adjust: the step rules' arithmetic; blocked ends moved to a clear branch
(clear_ends) and inputs bent to a new end (aim_inputs)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from genplan.errors import SettingsError, ShapeError
from genplan.seq2seq.adjust import _Adam, aim_inputs, clear_ends


def test_adam_is_torch_adam_step_for_step() -> None:
    """The written-out Adam (torch.optim imports torch's compiler, seconds) gives torch.optim.Adam's
    iterates exactly, on a non-convex function over 200 steps."""
    torch.manual_seed(0)
    x0 = torch.randn(5, 8)
    a = x0.clone().requires_grad_(True)
    b = x0.clone().requires_grad_(True)
    ref, mine = torch.optim.Adam([a], lr=0.02), _Adam(b, 0.02)
    for _ in range(200):
        (a.grad,) = torch.autograd.grad((a ** 3).sin().sum(), a)
        ref.step()
        (g,) = torch.autograd.grad((b ** 3).sin().sum(), b)
        with torch.no_grad():
            mine.step(b, g)
    assert torch.equal(a, b)
    assert not torch.equal(a, x0)


def _on_manifold(panda, n: int, seed: int):
    """``n`` states on panda_projection's manifold (its projector at the finish's tolerances)."""
    from genplan.projection import GaussNewtonProjector, load_task
    from tests.conftest import random_configurations

    task = load_task("panda_projection", panda)
    res = GaussNewtonProjector(panda, task.with_tolerances_scaled(0.1)).solve_batch(random_configurations(panda, n, seed=seed))
    return task, res.q[res.success]


def test_aim_inputs_keeps_each_start_and_ends_at_the_new_end() -> None:
    rng = np.random.default_rng(0)
    x = rng.standard_normal((3, 16, 7))
    ends = x[:, -1].copy()
    ends[1] += 0.5
    out = aim_inputs(x, ends)
    assert out.shape == x.shape
    np.testing.assert_allclose(out[:, 0], x[:, 0], atol=1e-12)
    np.testing.assert_allclose(out[:, -1], ends, atol=1e-12)
    np.testing.assert_array_equal(out[[0, 2]], x[[0, 2]])  # an unchanged end leaves its input as it was
    # the bend is monotone in time and adds no slope at either end
    bend = out[1, :, 0] - x[1, :, 0]
    assert np.all(np.diff(bend) >= 0)
    assert bend[1] < 0.01 and 0.5 - bend[-2] < 0.01


def test_aim_inputs_refuses_ends_of_the_wrong_shape() -> None:
    with pytest.raises(ShapeError, match="ends"):
        aim_inputs(np.zeros((2, 8, 7)), np.zeros((3, 7)))
    with pytest.raises(ShapeError, match="ends"):
        aim_inputs(np.zeros((2, 8, 7)), np.zeros((2, 6)))


def test_clear_ends_moves_a_blocked_end_to_a_clear_branch_at_the_same_hand_position(panda) -> None:
    """A ball on the elbow of one end: another configuration with the hand where it was, on the
    task's manifold and clear of the ball; the other end (clear) is returned unchanged."""
    task, q = _on_manifold(panda, 40, 5)
    clear = np.asarray(panda.collision_world().min_distance(q)) > 0.05
    ends = q[clear][:2]
    blocked_world = panda.collision_world()
    blocked_world.add_sphere("ball", 0.06, panda.frame_positions(ends[:1], "panda_link4")[0])
    free_world = panda.collision_world()
    assert blocked_world.in_collision(ends[0]) and not free_world.in_collision(ends[1])
    out = clear_ends(panda, ends, [blocked_world, free_world], "hand", task=task, seed=1)
    assert out.blocked.tolist() == [True, False] and out.found.tolist() == [True, False]
    assert not blocked_world.in_collision(out.q[0])
    np.testing.assert_array_equal(out.q[1], ends[1])
    assert out.moved[0] == pytest.approx(float(np.linalg.norm(out.q[0] - ends[0]))) and out.moved[1] == 0.0
    hand = panda.frame_positions(out.q, "hand")
    np.testing.assert_allclose(hand, panda.frame_positions(ends, "hand"), atol=1e-3)
    from genplan.projection import GaussNewtonProjector

    sizes = GaussNewtonProjector(panda, task).residual_sizes(out.q[:1])
    assert all(sizes[t.label()][0] <= t.tolerance for t in task.primary)


def test_clear_ends_refuses_bad_arguments_before_any_work(panda) -> None:
    world = panda.collision_world()
    with pytest.raises(ShapeError):
        clear_ends(panda, np.zeros((2, 6)), world, "hand")
    with pytest.raises(SettingsError, match="world"):
        clear_ends(panda, np.zeros((2, panda.nq)), [world], "hand")
    with pytest.raises(SettingsError, match="margin"):
        clear_ends(panda, np.zeros((1, panda.nq)), world, "hand", margin=-1.0)
