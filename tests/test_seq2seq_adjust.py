"""genplan.seq2seq.adjust: the step rules' arithmetic; several starts per problem (the restarts of
problems left in an obstacle, the finish falling back on another start); blocked ends moved to a
clear branch (clear_ends) and inputs bent to a new end (aim_inputs)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from genplan.errors import SettingsError, ShapeError
from genplan.seq2seq.adjust import MAX_STARTS, _Adam, adjust, aim_inputs, clear_ends


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


@pytest.fixture(scope="module")
def tiny_panda_model(panda):
    """An untrained small joint-space model of the Panda (8 samples): with the input anchor the
    adjustment starts from the input itself, whatever the weights."""
    from genplan.seq2seq.config import joint_space_config
    from genplan.seq2seq.model import Seq2SeqModel, Seq2SeqNet

    torch.manual_seed(0)
    cfg = joint_space_config(panda.joint_names, 8, panda.lower, panda.upper, hidden=16, latent=4)
    return Seq2SeqModel(cfg, Seq2SeqNet(cfg), {"description": "tiny test model"})


def _ball_problems(panda):
    """Two copies of a straight joint-space move (8 samples, the base joint turning 1.6 rad): the
    first with a ball far from it, the second with a ball of 8 cm on its hand's mid-time
    position; their avoid_spheres targets."""
    q0 = np.asarray(panda.q_default, dtype=np.float64)
    turn = np.zeros(panda.nq)
    turn[0] = 0.8
    x = np.linspace(q0 - turn, q0 + turn, 8)[None].repeat(2, 0)
    mid = panda.frame_positions(x[1, 4:5], "hand")[0]
    balls = np.array([[[5.0, 5.0, 5.0, 0.08]], [[*mid, 0.08]]])
    return x, balls


def _ball_objective():
    from genplan.seq2seq.objectives import AvoidSpheres, Objective, StayNear

    return Objective([AvoidSpheres(1e4, margin=0.04), StayNear(1.0)], name="avoid")


def test_starts_rerun_only_problems_left_in_an_obstacle_and_keep_the_lowest_objective(panda, tiny_panda_model) -> None:
    """starts=3: the problem whose path still runs through the ball after its first start runs
    two more, seeded; the problem clear of its ball runs one start and is the single start's
    result exactly."""
    import genplan.seq2seq.adjust as adj

    x, balls = _ball_problems(panda)
    kw = dict(targets={"avoid_spheres": balls}, updates=3, step="adam", lr=0.02, robot=panda)
    one = adjust(tiny_panda_model, x, _ball_objective(), starts=1, **kw)
    three = adjust(tiny_panda_model, x, _ball_objective(), starts=3, **kw)
    assert one.starts == 1 and one.starts_run.tolist() == [1, 1] and one.start_index.tolist() == [0, 0]
    assert three.starts == 3 and three.starts_run.tolist() == [1, 3]
    np.testing.assert_array_equal(three.p[0], one.p[0])
    np.testing.assert_array_equal(three.objective_history[:, 0], one.objective_history[:, 0])
    # the kept start is one left clear of the ball when there is one, else the lowest objective
    obj = _ball_objective()
    three = adjust(tiny_panda_model, x, obj, starts=3, **kw)
    if adj._blocked(obj, three.p)[1]:
        assert three.objective_history[-1, 1] <= one.objective_history[-1, 1]
    assert three.alternatives[0] == []
    assert {s for s, _ in three.alternatives[1]} <= {0, 1, 2} - {int(three.start_index[1])}
    assert all(not np.allclose(p, three.p[1]) for _, p in three.alternatives[1])
    again = adjust(tiny_panda_model, x, _ball_objective(), starts=3, **kw)
    np.testing.assert_array_equal(again.p, three.p)  # seeded
    # the default: several starts for an objective with a clearance term, one without
    from genplan.seq2seq.adjust import DEFAULT_STARTS
    from genplan.seq2seq.objectives import Objective, StayNear

    assert adjust(tiny_panda_model, x, _ball_objective(), **kw).starts == DEFAULT_STARTS
    assert adjust(tiny_panda_model, x, Objective([StayNear(1.0)]), updates=1, robot=panda).starts == 1


def test_finish_falls_back_on_another_start_when_the_kept_one_collides(panda, tiny_panda_model) -> None:
    """A problem whose kept trajectory runs through its ball and whose other start goes around it
    is finished from that start (start_index says which, starts_finished how many were tried);
    when every start collides the problem fails with the kept start's reason."""
    x, balls = _ball_problems(panda)
    res = adjust(tiny_panda_model, x, _ball_objective(), targets={"avoid_spheres": balls}, updates=0, robot=panda,
                 starts=1)
    worlds = []
    for ball in balls[:, 0]:
        w = panda.collision_world()
        w.add_sphere("ball", float(ball[3]), ball[:3])
        worlds.append(w)
    assert np.asarray(worlds[1].in_collision(res.p[1])).any()
    # another start of problem 1: the same move with the elbow bent, the hand clear of the ball
    around = x[1].copy()
    around[1:-1, 3] += 0.9
    assert not np.asarray(worlds[1].in_collision(around)).any()
    res.alternatives = [[], [(2, x[1].copy()), (1, around)]]
    fin = res.finish(world=worlds, time_parameterize=False)
    assert fin.success.tolist() == [True, True]
    assert fin.start_index.tolist() == [0, 1] and fin.starts_finished.tolist() == [1, 3]
    assert not np.asarray(worlds[1].in_collision(fin.paths[1])).any()
    res.alternatives = [[], [(1, x[1].copy())]]
    fin = res.finish(world=worlds, time_parameterize=False)
    assert fin.success.tolist() == [True, False] and "collision" in fin.reasons[1]
    assert fin.start_index.tolist() == [0, 0] and fin.starts_finished.tolist() == [1, 2]


@pytest.fixture
def no_updates(monkeypatch) -> None:
    """Any update loop (genplan.seq2seq.adjust._run) fails the test: the arguments must be
    refused before one starts."""
    import genplan.seq2seq.adjust as adj

    def started(*args, **kwargs):
        raise AssertionError("an update ran before the arguments were checked")

    monkeypatch.setattr(adj, "_run", started)


def test_starts_refuses_bad_values_before_any_work(panda, tiny_panda_model, no_updates) -> None:
    x, balls = _ball_problems(panda)
    kw = dict(targets={"avoid_spheres": balls}, robot=panda)
    for bad in (0, -1, 2.0, True, "2", MAX_STARTS + 1):
        with pytest.raises(SettingsError, match="starts"):
            adjust(tiny_panda_model, x, _ball_objective(), starts=bad, **kw)
    for bad in (0.0, -0.5, float("nan"), float("inf"), "a"):
        with pytest.raises(SettingsError, match="start_spread"):
            adjust(tiny_panda_model, x, _ball_objective(), start_spread=bad, **kw)
    with pytest.raises(SettingsError, match="starts > 1 needs an Objective"):
        adjust(tiny_panda_model, x, lambda r: r.p.square().mean((1, 2)), starts=2, robot=panda)


def test_pool_restarts_start_from_the_best_scored_of_the_nearest_pool_trajectories(panda, tiny_panda_model,
                                                                                  monkeypatch) -> None:
    """With a pool, a restarted problem's restarts start from the encodings of the pool's
    trajectories nearest its input (start and end samples), lowest objective first when decoded
    from its start; a pool member far from the input is not scored; restarts beyond the members
    found keep the random spread; seeded."""
    import genplan.seq2seq.adjust as adj

    x, balls = _ball_problems(panda)
    near_a, near_b = x[1].copy(), x[1].copy()
    near_a[1:-1, 3] += 0.9  # the elbow bent
    near_b[1:-1, 1] -= 0.5  # the shoulder lifted
    far = x[1] + 1.0  # start and end a radian away in every joint
    pool = np.stack([far, near_a, x[1], near_b])  # the input itself is not a restart
    monkeypatch.setattr(adj, "POOL_NEAREST", 2)
    calls: list[tuple[int, torch.Tensor | None, adj.AdjustResult]] = []
    run = adj._run

    def spy(*args, **kwargs):
        out = run(*args, **kwargs)
        calls.append((args[4], kwargs.get("perturb"), out))  # (updates, perturb, result)
        return out

    monkeypatch.setattr(adj, "_run", spy)
    kw = dict(targets={"avoid_spheres": balls}, updates=2, step="adam", lr=0.02, robot=panda)
    res = adjust(tiny_panda_model, x, _ball_objective(), starts=4, pool=pool, **kw)
    assert res.starts_run.tolist() == [1, 4]
    (_, first, _), (scored_updates, scored, scores), (_, restarts, _) = calls
    assert first is None and scored_updates == 0 and scored is not None and restarts is not None
    with torch.no_grad():
        z = tiny_panda_model.encode(torch.as_tensor(np.concatenate([x[1:], pool[[0, 1, 3]]]), dtype=torch.float32))
    # the two near members scored (their offsets from the problem's own encoding), the far one not
    torch.testing.assert_close(scored, z[[2, 3]] - z[0], rtol=0, atol=1e-6)
    assert scores.batch == 2 and scores.objective_history.shape == (1, 2)
    assert scores.objective_history[0, 0] != scores.objective_history[0, 1]
    best, other = 2 + np.argsort(scores.objective_history[0])
    torch.testing.assert_close(restarts[:2], z[[best, other]] - z[0], rtol=0, atol=1e-6)
    # the third restart: two members near, so the random spread
    assert not any(torch.allclose(restarts[2], z[k] - z[0], atol=1e-3) for k in (1, 2, 3))
    calls.clear()
    again = adjust(tiny_panda_model, x, _ball_objective(), starts=4, pool=pool, **kw)
    np.testing.assert_array_equal(again.p, res.p)


def test_pool_refuses_bad_values_before_any_work(panda, tiny_panda_model, no_updates) -> None:
    from genplan.errors import NonFiniteError

    x, balls = _ball_problems(panda)
    kw = dict(targets={"avoid_spheres": balls}, robot=panda)
    with pytest.raises(ShapeError, match="pool"):
        adjust(tiny_panda_model, x, _ball_objective(), starts=3, pool=x[:, :5], **kw)
    with pytest.raises(ShapeError, match="pool"):
        adjust(tiny_panda_model, x, _ball_objective(), starts=3, pool=x[:0], **kw)
    bad = x.copy()
    bad[1, 3, 2] = np.nan
    with pytest.raises(NonFiniteError, match="pool"):
        adjust(tiny_panda_model, x, _ball_objective(), starts=3, pool=bad, **kw)
    for wrong in (dict(starts=1), dict(starts=3, method="random-latent")):
        with pytest.raises(SettingsError, match="pool"):
            adjust(tiny_panda_model, x, _ball_objective(), pool=x, **{**kw, **wrong})
