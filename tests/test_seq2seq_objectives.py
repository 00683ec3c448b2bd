"""genplan.seq2seq.objectives: each term against its formula (numpy or Pinocchio), objective files
(round trip, refusals naming the term and key), targets (shapes, unknown names), and the robot
terms' checks (unknown frame, no task, no scene)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

import genplan
from genplan.errors import ObjectiveFileError, SettingsError, ShapeError, UnknownNameError
from genplan.seq2seq import objectives as O
from genplan.seq2seq.plants import PositionPlant, Rollout


def _rollout(p: np.ndarray, dt: float = 0.1) -> Rollout:
    t = torch.tensor(p, dtype=torch.float32)
    return PositionPlant(dt).rollout(t - t[:, :1], None, t[:, 0])


def _ctx(b: int, axes=("a", "b", "c"), **kw) -> O.Context:
    return O.Context(axes=tuple(axes), batch=b, x_in=torch.zeros(b, 5, len(axes)), **kw)


@pytest.fixture(scope="module")
def panda():
    return genplan.load("panda")


def test_axis_terms_match_their_formulas() -> None:
    rng = np.random.default_rng(0)
    p = rng.normal(size=(4, 9, 3))
    r = _rollout(p)
    target = rng.normal(size=(4, 3))
    ctx = _ctx(4, targets={"end_state": target, "via_point": target[:, :2]})
    end = O.EndState(scale=[1.0, 2.0, 0.5])
    via = O.ViaPoint(time=0.5, axes=["a", "b"])
    ball = O.EndBall(radius=0.3, center=[0.1, -0.1], axes=[0, 1])
    band = O.EndBand(axis="c", target=0.2, half_width=0.1)
    smooth = O.Smoothness()
    vel = O.VelocityLimits(limit=[1.0, 2.0, 3.0])
    for t in (end, via, ball, band, smooth, vel):
        t.bind(ctx)
    np.testing.assert_allclose(end(r).numpy(), (((p[:, -1] - target) * [1, 2, 0.5]) ** 2).sum(-1), rtol=1e-5)
    mid = 0.5 * (p[:, 4] + p[:, 4])  # time 0.5 of 9 samples is sample 4
    np.testing.assert_allclose(via(r).numpy(), ((mid[:, :2] - target[:, :2]) ** 2).sum(-1), rtol=1e-5)
    dist = np.linalg.norm(p[:, -1, :2] - [0.1, -0.1], axis=1)
    np.testing.assert_allclose(ball(r).numpy(), np.maximum(dist - 0.3, 0), atol=1e-5)
    np.testing.assert_allclose(band(r).numpy(), np.maximum(np.abs(p[:, -1, 2] - 0.2) - 0.1, 0), atol=1e-6)
    dd = p[:, 2:] - 2 * p[:, 1:-1] + p[:, :-2]
    np.testing.assert_allclose(smooth(r).numpy(), (dd ** 2).sum(-1).mean(-1), rtol=1e-4)
    v = np.diff(p, axis=1) / 0.1
    v = np.concatenate([v, v[:, -1:]], 1)
    np.testing.assert_allclose(vel(r).numpy(), (np.maximum(np.abs(v) - [1, 2, 3], 0) ** 2).sum(-1).mean(-1), rtol=1e-4)


def test_objective_is_the_weighted_sum_in_order_and_refuses_repeated_names() -> None:
    p = np.random.default_rng(1).normal(size=(2, 5, 3))
    r = _rollout(p)
    obj = O.Objective([O.EndState(2.0, target=[0.0, 0.0, 0.0]), O.Smoothness(0.5)])
    obj.bind(_ctx(2))
    v = obj.values(r)
    np.testing.assert_allclose(obj(r).numpy(), (2.0 * v["end_state"] + 0.5 * v["smoothness"]).numpy(), rtol=1e-6)
    with pytest.raises(SettingsError, match="repeated"):
        O.Objective([O.Smoothness(), O.Smoothness()])
    with pytest.raises(SettingsError, match="no term"):
        O.Objective([])


def test_targets_are_checked_before_any_work() -> None:
    obj = O.Objective([O.EndState()])
    with pytest.raises(SettingsError, match="needs a target"):
        obj.bind(_ctx(2))
    with pytest.raises(ShapeError, match=r"targets\['end_state'\] must have shape"):
        obj.bind(_ctx(2, targets={"end_state": np.zeros((3, 3))}))
    with pytest.raises(UnknownNameError, match="name no term"):
        obj.bind(_ctx(2, targets={"end_state": np.zeros(3), "nope": np.zeros(3)}))
    with pytest.raises(UnknownNameError, match="unknown axis 'q'"):
        O.Objective([O.EndState(axes=["q"], target=[0.0])]).bind(_ctx(1))


def test_robot_terms_match_pinocchio(panda) -> None:
    from genplan.projection import load_task

    rng = np.random.default_rng(2)
    q = panda.random_configurations(6, rng=rng).reshape(2, 3, panda.nq)
    r = _rollout(q)
    target = rng.normal(size=(2, 3))
    task = load_task("panda_projection", panda)
    ctx = _ctx(2, axes=panda.joint_names, targets={"end_position": target}, robot=panda, task=task)
    end = O.EndPosition(frame="hand")
    con = O.Constraint()
    lim = O.JointLimits(margin=0.1)
    for t in (end, con, lim):
        t.bind(ctx)
    hand = panda.frame_positions(q[:, -1], "hand")
    np.testing.assert_allclose(end(r).numpy(), ((hand - target) ** 2).sum(-1), rtol=1e-4)
    from genplan.projection import _State

    terms = O.constraint_terms(task, panda)
    assert len(terms) == 1  # the orientation term (joint limits are a term of their own)
    bound = terms[0].bind(panda)
    sq = [float(np.sum((terms[0].weight * bound.residual(_State(panda, row, False))) ** 2))
          for row in q.reshape(-1, panda.nq)]
    np.testing.assert_allclose(con(r).numpy(), np.reshape(sq, (2, 3)).mean(-1), rtol=1e-4)
    lo, hi = np.asarray(panda.lower) + 0.1, np.asarray(panda.upper) - 0.1
    over = (np.maximum(q - hi, 0) ** 2 + np.maximum(lo - q, 0) ** 2).sum(-1).mean(-1)
    np.testing.assert_allclose(lim(r).numpy(), over, rtol=1e-4, atol=1e-7)


def test_robot_terms_refuse_what_they_cannot_use(panda) -> None:
    ctx = _ctx(1, axes=panda.joint_names, robot=panda, targets={"end_position": np.zeros(3)})
    with pytest.raises(UnknownNameError, match="unknown frame 'no_such_frame'"):
        O.EndPosition(frame="no_such_frame").bind(ctx)
    with pytest.raises(SettingsError, match="needs the task"):
        O.Constraint().bind(ctx)
    with pytest.raises(SettingsError, match="needs a scene"):
        O.Clearance().bind(ctx)
    with pytest.raises(SettingsError, match="needs the robot"):
        O.EndPosition(frame="hand").bind(_ctx(1, targets={"end_position": np.zeros(3)}))


def test_files_round_trip_and_refuse_with_the_term_and_key(tmp_path) -> None:
    obj = O.Objective([O.EndPosition(1e4, frame="hand"), O.Constraint(100.0), O.Clearance(1e3, margin=0.03),
                       O.ViaPoint(2.0, "mid", target=[0.1, 0.2], time=0.5, axes=[0, 1])], name="reach")
    path = obj.to_file(tmp_path / "reach.toml")
    back = O.load_objective(path)
    assert back.to_dict() == obj.to_dict()
    bad = tmp_path / "bad.toml"
    bad.write_text('[[term]]\nkind = "end_position"\nframe = "hand"\nwieght = 2.0\n')
    with pytest.raises(ObjectiveFileError, match=r"bad.toml: term 1 \(end_position\): unknown key\(s\) \['wieght'\]"):
        O.load_objective(bad)
    bad.write_text('[[term]]\nkind = "teleport"\n')
    with pytest.raises(ObjectiveFileError, match="unknown kind 'teleport'; known: .*end_position"):
        O.load_objective(bad)
    bad.write_text('[[term]]\nkind = "python"\nentry = "math:sqrt"\n')
    with pytest.raises(ObjectiveFileError, match="allow_python=True"):
        O.load_objective(bad)
    bad.write_text("not = [toml")
    with pytest.raises(ObjectiveFileError, match="not a TOML file"):
        O.load_objective(bad)
    with pytest.raises(FileNotFoundError):
        O.load_objective(tmp_path / "missing.toml")


def test_a_python_term_from_a_file_runs_only_with_the_opt_in(tmp_path) -> None:
    f = tmp_path / "obj.toml"
    f.write_text('[[term]]\nkind = "python"\nentry = "tests.test_seq2seq_objectives:last_sum"\nweight = 3.0\n')
    obj = O.load_objective(f, allow_python=True)
    obj.bind(_ctx(2))
    p = np.ones((2, 4, 3))
    np.testing.assert_allclose(obj(_rollout(p)).numpy(), [9.0, 9.0])
    assert O.load_objective(obj.to_file(tmp_path / "again.toml"), allow_python=True).to_dict() == obj.to_dict()


def last_sum(r: Rollout) -> torch.Tensor:
    """A custom term for the file test: the sum of the last sample's values."""
    return r.p[:, -1].sum(-1)


def test_pancake_kinds_are_known_to_files(tmp_path) -> None:
    f = tmp_path / "j.toml"
    f.write_text('[[term]]\nkind = "friction_cone"\nmargin = 0.1\n[[term]]\nkind = "normal_floor"\nfloor = 2.0\n')
    obj = O.load_objective(f)
    assert [t.kind for t in obj.terms] == ["friction_cone", "normal_floor"]
    obj.bind(_ctx(1, axes=("y", "z", "theta")))
    with pytest.raises(SettingsError, match="spatula plant's phi"):
        obj(_rollout(np.zeros((1, 4, 3))))
    assert math.isfinite(O.KINDS["friction_cone"]().weight)


def _clearance_np(term: O.Clearance, q: np.ndarray, world) -> np.ndarray:
    """The clearance term written out in numpy (float64): every sphere, no screening."""
    c = term.centers_np(q)
    d, _ = world.point_distances(c, 10.0)
    return (np.maximum(term.margin - (d - term._radii_np), 0.0) ** 2).sum(-1)


def _self_clearance_np(term: O.SelfClearance, q: np.ndarray) -> np.ndarray:
    c = term.centers_np(q)
    gap = np.linalg.norm(c[:, term._s_np] - c[:, term._t_np], axis=-1) - term._radii_np[term._s_np] - term._radii_np[term._t_np]
    return (np.maximum(term.margin - gap, 0.0) ** 2).sum(-1)


def _value_and_grad(term: O.Term, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The term on rollouts of one sample each (B = len(q), K = 1) and its gradient in q."""
    qt = torch.tensor(q[:, None, :], dtype=torch.float32, requires_grad=True)
    r = Rollout(p=qt, v=torch.zeros_like(qt), u=torch.zeros_like(qt))
    v = term(r)
    if not v.requires_grad:  # nothing near: a constant zero
        return v.double().numpy(), np.zeros(q.shape)
    (g,) = torch.autograd.grad(v.sum(), qt)
    return v.detach().double().numpy(), g[:, 0].double().numpy()


def _fd(f, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    out = np.zeros_like(q)
    for j in range(q.shape[1]):
        e = np.zeros(q.shape[1])
        e[j] = h
        out[:, j] = (f(q + e) - f(q - e)) / (2 * h)
    return out


def test_clearance_terms_match_their_formulas_and_gradients(panda) -> None:
    """clearance (the scene, natively screened) and self_clearance (the arm's own link pairs)
    against numpy over every sphere in float64, values and gradients (central differences)."""
    from genplan.scene import load_scene

    scene = load_scene("panda_shelf")
    rng = np.random.default_rng(4)
    q = panda.random_configurations(400, rng=rng)
    ctx = _ctx(len(q), axes=panda.joint_names, robot=panda, scene=scene)
    clear, self_clear = O.Clearance(margin=0.03), O.SelfClearance(margin=0.01)
    clear.bind(ctx)
    self_clear.bind(ctx)
    world = panda.collision_world()
    world.add_scene(scene)
    # the scene: configurations near or in the shelf
    ref = _clearance_np(clear, q, world)
    hit = ref > 1e-5
    assert hit.sum() >= 20
    value, grad = _value_and_grad(clear, q[hit][:20])
    np.testing.assert_allclose(value, ref[hit][:20], rtol=2e-3, atol=1e-7)
    fd = _fd(lambda x: _clearance_np(clear, x, world), q[hit][:20])
    np.testing.assert_allclose(grad, fd, rtol=0.02, atol=2e-3 * np.abs(fd).max())
    np.testing.assert_array_equal(_value_and_grad(clear, q[~hit][:20])[0], 0.0)
    # the arm itself: zero at the default configuration (pairs whose padding overlaps there are left
    # out, and counted), positive wherever the robot's own collision check finds a contact
    assert self_clear.dropped >= 0 and len(self_clear._s_np) > 100
    assert _value_and_grad(self_clear, np.asarray(panda.q_default)[None])[0][0] == 0.0
    alone = panda.collision_world()
    folded = q[np.asarray(alone.in_collision(q))]
    assert len(folded) >= 10
    v_folded, g_folded = _value_and_grad(self_clear, folded[:20])
    assert np.all(v_folded > 0)
    np.testing.assert_allclose(v_folded, _self_clearance_np(self_clear, folded[:20]), rtol=2e-3, atol=1e-7)
    fd = _fd(lambda x: _self_clearance_np(self_clear, x), folded[:20])
    np.testing.assert_allclose(g_folded, fd, rtol=0.02, atol=2e-3 * np.abs(fd).max())


def test_clearance_terms_of_one_objective_share_the_spheres(panda) -> None:
    """clearance, avoid_spheres and self_clearance in one objective: the same values and gradients
    as each term alone, the differentiable kinematics run once per configuration that any of them
    needs (not once per term), and nothing shared outside the evaluation."""
    from genplan.scene import load_scene

    scene = load_scene("panda_shelf")
    rng = np.random.default_rng(5)
    q = panda.random_configurations(300, rng=rng)
    b = len(q)
    obstacles = np.concatenate([panda.frame_positions(q, "hand"), np.full((b, 1), 0.05)], 1)[:, None, :]
    ctx = _ctx(b, axes=panda.joint_names, robot=panda, scene=scene, targets={"avoid_spheres": obstacles})
    terms = [O.Clearance(margin=0.03), O.AvoidSpheres(margin=0.04), O.SelfClearance(margin=0.01)]
    obj = O.Objective(terms)
    obj.bind(ctx)
    qt = torch.tensor(q[:, None, :], dtype=torch.float32, requires_grad=True)
    r = Rollout(p=qt, v=torch.zeros_like(qt), u=torch.zeros_like(qt))
    rows: list[int] = []
    original = O.Clearance.sphere_centers

    def counting(self, x):
        rows.append(len(x))
        return original(self, x)

    O.Clearance.sphere_centers = counting  # type: ignore[method-assign]
    try:
        values = obj.values(r)
        shared_rows = sum(rows)
        rows.clear()
        alone = {t.name: t(r) for t in terms}
        alone_rows = sum(rows)
    finally:
        O.Clearance.sphere_centers = original  # type: ignore[method-assign]
    assert ctx._scope is None
    for t in terms:
        assert float(alone[t.name].detach().sum()) > 0, t.name
        np.testing.assert_allclose(values[t.name].detach().numpy(), alone[t.name].detach().numpy(), rtol=1e-6)
        (g1,) = torch.autograd.grad(values[t.name].sum(), qt, retain_graph=True)
        (g2,) = torch.autograd.grad(alone[t.name].sum(), qt, retain_graph=True)
        np.testing.assert_allclose(g1.numpy(), g2.numpy(), rtol=1e-5, atol=1e-6)
    assert 0 < shared_rows <= b and shared_rows < alone_rows
