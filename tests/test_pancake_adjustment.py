"""genplan.pancake.adjustment: the three methods, the objectives (built in and custom), batching,
timing, and bad input. Uses the shipped model and a few updates."""

import math

import numpy as np
import pytest
import torch

from genplan.errors import CallbackError, GenplanError, NonFiniteError, SettingsError, ShapeError, UnknownNameError
from genplan.pancake import physics as ph
from genplan.pancake.adjustment import J1, J2, PAPER_LR, J2Executable, adjust, default_lr, normal_acceleration
from genplan.pancake.model import load_model
from genplan.seq2seq.model import Seq2SeqModel
from genplan.pancake.trajectories import linear, s_curve

P_END = np.array([[0.1, -0.1, math.pi], [0.0, 0.1, 0.0], [-0.1, 0.0, -math.pi]])


@pytest.fixture(scope="module")
def model() -> Seq2SeqModel:
    return load_model()


@pytest.fixture(scope="module")
def x_in() -> np.ndarray:
    return np.stack([s_curve(np.zeros(3), p) for p in P_END])


def _j1_np(p: np.ndarray, phi: np.ndarray, p_end: np.ndarray) -> np.ndarray:
    return (((p[:, -1] - p_end) * np.array(ph.D_SCALE)) ** 2).sum(-1) + ph.f_dyn_np(phi)


def test_gd_step_is_eq_7(model, x_in) -> None:
    from genplan.pancake.model import start_state

    res = adjust(x_in, "j1", "latent", 1, lr=0.5, model=model, step="gd")
    assert res.lr == 0.5 and res.step == "gd"
    xt = torch.tensor(x_in, dtype=torch.float32)
    z0 = model.encode(xt).detach().requires_grad_(True)
    j = J1(P_END)(model.decode(z0, start_state(xt), model.chirality(xt)))
    (g,) = torch.autograd.grad(j.sum(), z0)
    step = res.z - z0.detach().numpy()
    expected = -0.5 * g.numpy()
    assert np.abs(step - expected).max() < 1e-3 * np.abs(expected).max() + 1e-5
    np.testing.assert_allclose(res.objective_history[0], j.detach().numpy(), rtol=1e-4, atol=1e-9)
    assert adjust(x_in, "j1", "latent", 0, model=model).lr == PAPER_LR[("j1", "latent")]


def test_latent_method_reduces_j1_and_reports_everything(model, x_in) -> None:
    res = adjust(x_in, "j1", "latent", 5, model=model, snapshots=(0, 5), step="adaptive")
    h = res.objective_history
    assert h.shape == (6, 3) and res.batch == 3 and res.lr == PAPER_LR[("j1", "latent")]
    assert h[-1].mean() < h[0].mean()
    assert res.p.shape == (3, 500, 3) and res.u.shape == (3, 500, 3) and res.phi.shape == (3, 500)
    assert res.z is not None and res.z.shape == (3, 128)
    assert len(res.update_times_s) == 5 and res.ms_per_update > 0 and res.time_init_s > 0
    assert set(res.snapshots) == {0, 5}
    # the history's last row is J1 of the returned trajectory, recomputed with the numpy twin
    np.testing.assert_allclose(h[-1], _j1_np(res.p, res.phi, P_END), rtol=1e-4, atol=1e-7)
    np.testing.assert_allclose(res.snapshots[5]["p"], res.p)
    # and the returned trajectory is the physics' response to the returned accelerations
    x = np.stack([ph.rollout_np(res.u[i]) for i in range(3)])
    np.testing.assert_allclose(res.p, x[..., :3], atol=2e-5)
    np.testing.assert_allclose(res.phi, ph.phi_np(x[..., 2], res.u), atol=1e-4)


def test_latent_adjustment_reaches_level_end_poses_exactly(model) -> None:
    # the paper's 9 end poses with theta_end = 0: the pancake never has to leave the cone's core
    from genplan.pancake.trajectories import j1_problems

    x, p_end = j1_problems()
    sel = np.isclose(p_end[:, 2], 0.0)
    res = adjust(x[sel], "j1", "latent", 30, model=model, p_end=p_end[sel], step="adaptive")
    assert np.all(res.objective_history[-1] < 1e-8)
    np.testing.assert_allclose(res.p[:, -1], p_end[sel], atol=2e-4)
    assert res.inside_cone().all()


def test_batched_equals_one_by_one(model, x_in) -> None:
    both = adjust(x_in[:2], "j1", "latent", 3, model=model, step="adaptive")
    one = adjust(x_in[1], "j1", "latent", 3, model=model, step="adaptive")
    np.testing.assert_allclose(both.objective_history[:, 1], one.objective_history[:, 0], rtol=1e-4, atol=1e-8)
    np.testing.assert_allclose(both.p[1], one.p[0], atol=1e-5)


def test_random_latent_is_seeded_and_direct_u_optimises_u(model, x_in) -> None:
    a = adjust(x_in, "j1", "random-latent", 2, model=model, seed=7)
    b = adjust(x_in, "j1", "random-latent", 2, model=model, seed=7)
    c = adjust(x_in, "j1", "random-latent", 2, model=model, seed=8)
    np.testing.assert_array_equal(a.objective_history, b.objective_history)
    assert not np.allclose(a.z, c.z)
    d = adjust(x_in, "j1", "direct-u", 2, model=model)
    assert d.z is None and d.lr == 1000.0
    # direct-u starts where the latent method starts: the decoder's output for the input
    lat = adjust(x_in, "j1", "latent", 0, model=model)
    np.testing.assert_allclose(d.objective_history[0], lat.objective_history[0], rtol=1e-5)


def test_adaptive_step_never_raises_the_objective(model, x_in) -> None:
    # a step size far too large for plain gradient descent: the adaptive rule backs off
    res = adjust(x_in, "j1", "latent", 12, lr=1e5, model=model, step="adaptive", snapshots=(12,))
    h = res.objective_history
    assert np.all(np.diff(h, axis=0) <= 0)
    assert np.all(h[-1] < h[0])
    # the result is the kept iterate: its J1 is the last history row
    np.testing.assert_allclose(h[-1], _j1_np(res.p, res.phi, P_END), rtol=1e-4, atol=1e-7)
    np.testing.assert_allclose(res.snapshots[12]["p"], res.p)
    assert len(res.update_times_s) == 12


def test_adam_step_rule(model, x_in) -> None:
    res = adjust(x_in, "j1", "latent", 5, model=model, step="adam")
    assert res.step == "adam" and res.lr == default_lr("j1", "latent", "adam")
    assert res.objective_history[-1].mean() < res.objective_history[0].mean()


def test_j2_matches_its_definition(model) -> None:
    x = linear(np.zeros(3), [0.0, 0.0, -0.75 * math.pi])
    res = adjust(x, "j2", "latent", 2, model=model)
    assert res.lr == PAPER_LR[("j2", "latent")]
    p, v, phi = res.p[0], res.v[0], res.phi[0]
    pos = max(math.hypot(p[-1, 0], p[-1, 1]) - 0.2, 0) + 0.1 * max(abs(p[-1, 2] + 0.75 * math.pi) - 0.5, 0)
    vel = (np.maximum(np.array(ph.D_SCALE) * (np.abs(v) - [1.5, 1.5, 4.5]), 0) ** 2).sum(-1).mean()
    ref = pos + ph.f_dyn_np(phi) + 0.01 * vel
    np.testing.assert_allclose(res.objective_history[-1, 0], ref, rtol=1e-4, atol=1e-7)
    # J2's keywords are passed through
    res2 = adjust(x, "j2", "latent", 0, model=model, objective_kwargs={"p_lim": 0.0, "beta": 0.0})
    assert res2.objective_history[0, 0] != res.objective_history[0, 0]


def test_j2_executable_is_j2_plus_its_margins(model) -> None:
    x = linear(np.zeros(3), [0.0, 0.0, -0.75 * math.pi])
    res = adjust(x, J2Executable(), "latent", 2, model=model, step="adam")
    p, v, u, phi = res.p[0], res.v[0], res.u[0], res.phi[0]
    # N by hand: the blade normal (-sin, cos) dotted with the acceleration the blade gives, a - g
    n_hand = np.array([[-math.sin(t), math.cos(t)] for t in p[:, 2]])
    normal = (n_hand * (u[:, :2] + [0.0, ph.G])).sum(-1)
    t = lambda a: torch.as_tensor(a[None], dtype=torch.float32)
    r = ph.Rollout(t(p), t(v), t(u), t(phi))
    np.testing.assert_allclose(normal_acceleration(r)[0].numpy(), normal, rtol=1e-5, atol=1e-4)
    vel = (np.maximum(np.array(ph.D_SCALE) * (np.abs(v) - [1.5, 1.5, 4.5]), 0) ** 2).sum(-1).mean()
    d_theta = abs(p[-1, 2] + 0.75 * math.pi)
    j2 = (max(math.hypot(p[-1, 0], p[-1, 1]) - 0.2, 0) + 0.1 * max(d_theta - 0.5, 0) + ph.f_dyn_np(phi)
          + 0.01 * vel)
    extra = (ph.f_dyn_np(phi, margin=math.radians(10)) + 0.1 / ph.G * np.maximum(3.0 - normal, 0).sum()
             + 3.0 * max(d_theta - 0.48, 0) + 10.0 * vel)
    np.testing.assert_allclose(res.objective_history[-1, 0], j2 + extra, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(float(J2()(r)[0]), j2, rtol=1e-4, atol=1e-7)
    with pytest.raises(SettingsError, match="margin must be below"):
        J2Executable(margin=math.radians(50))
    with pytest.raises(SettingsError, match="finite and >= 0"):
        J2Executable(normal_floor=-1.0)


def test_custom_objective(model, x_in) -> None:
    def end_height(r: ph.Rollout) -> torch.Tensor:  # end 5 cm up, anything else free
        return (r.p[:, -1, 1] - 0.05) ** 2 + ph.f_dyn(r.phi)

    res = adjust(x_in, end_height, "latent", 5, model=model, step="adaptive")
    assert res.objective_history[-1].mean() < res.objective_history[0].mean()
    obj = J1(P_END, alpha=2.0, margin=0.05)
    assert adjust(x_in, obj, "latent", 1, model=model).objective_history.shape == (2, 3)


def test_bad_objectives_get_clear_errors(model, x_in) -> None:
    with pytest.raises(CallbackError, match=r"one value per problem, shape \(3,\), got shape \(3, 3\)"):
        adjust(x_in, lambda r: r.p[:, -1], "latent", 1, model=model)
    with pytest.raises(CallbackError, match="a scalar: for a batch return the per-problem values"):
        adjust(x_in, lambda r: r.p.sum(), "latent", 1, model=model)
    with pytest.raises(CallbackError, match="no gradient"):
        adjust(x_in, lambda r: torch.zeros(3), "latent", 1, model=model)
    with pytest.raises(TypeError, match="must return a torch.Tensor"):
        adjust(x_in, lambda r: 1.0, "latent", 1, model=model)
    with pytest.raises(FloatingPointError, match="NaN or inf after 0 update"):
        adjust(x_in, lambda r: r.p[:, -1, 0] * float("nan"), "latent", 1, model=model)
    # a scalar is fine for a single problem
    res = adjust(x_in[0], lambda r: r.p[0, -1, 1] ** 2, "latent", 1, model=model, lr=1.0)
    assert res.objective_history.shape == (2, 1)


def test_bad_inputs_get_clear_errors(model, x_in) -> None:
    with pytest.raises(ShapeError, match=r"x_in must be trajectories of shape .* got shape \(500, 2\)"):
        adjust(np.zeros((500, 2)), model=model)
    bad = x_in.copy()
    bad[0, 3, 1] = np.nan
    with pytest.raises(NonFiniteError, match="NaN or inf"):
        adjust(bad, model=model)
    with pytest.raises(UnknownNameError, match="method must be one of"):
        adjust(x_in, method="latnet", model=model)  # type: ignore[arg-type]
    with pytest.raises(UnknownNameError, match="step must be one of"):
        adjust(x_in, step="lbfgs", model=model)
    with pytest.raises(SettingsError, match="lr must be a positive finite number"):
        adjust(x_in, lr=-1.0, model=model)
    with pytest.raises(SettingsError, match="updates must be a non-negative integer"):
        adjust(x_in, updates=-2, model=model)
    with pytest.raises(ShapeError, match=r"targets\['p_end'\] must have shape \(3,\) or \(3, 3\)"):
        adjust(x_in, "j1", p_end=np.zeros((2, 3)), model=model)
    with pytest.raises(NonFiniteError, match="p_end contains NaN"):
        adjust(x_in, "j1", p_end=[0.0, np.nan, 0.0], model=model)
    with pytest.raises(UnknownNameError, match="objective must be 'j1', 'j2' or a callable"):
        adjust(x_in, "j3", model=model)
    with pytest.raises(SettingsError, match="snapshots must lie in"):
        adjust(x_in, updates=2, snapshots=(5,), model=model)
    with pytest.raises(NonFiniteError, match="J2 parameters must be finite"):
        J2(p_lim=float("nan"))


def test_inputs_beyond_float32_are_refused_up_front(model, x_in) -> None:
    """Before: x_in or p_end of 1e200 (finite in float64, inf in float32) failed with "the
    objective became NaN ... lower lr". Now: refused before any work, naming the element."""
    with pytest.raises(GenplanError, match=r"x_in: element \(0, 0, 0\) is 1e\+200, beyond 10000"):
        adjust(x_in + [1e200, 0.0, 0.0], model=model)
    with pytest.raises(GenplanError, match=r"p_end: element \(1, 2\) is 1e\+39, beyond 10000"):
        adjust(x_in, "j1", p_end=[[0, 0, 0], [0, 0, 1e39], [0, 0, 0]], model=model)
    with pytest.raises(GenplanError, match="J2 parameters: element .* beyond 10000"):
        J2(theta_end=1e200)


def test_every_decoded_trajectory_is_finite_or_an_error(model, x_in) -> None:
    """An objective that hides a non-finite trajectory (nan_to_num) no longer returns NaN
    trajectories: the rollout itself is checked at every update, naming the problem."""

    def blind(r):
        return torch.nan_to_num(r.p[:, -1, 0], nan=0.0, posinf=0.0, neginf=0.0) ** 2 + 1.0

    with pytest.raises(FloatingPointError, match=r"decoded trajectory of problem 0 became NaN or inf after 1 "
                                                 r"update\(s\) \(method direct, step gd, .*lower lr"):
        adjust(x_in, blind, "direct-u", 3, lr=1e45, step="gd", model=model)
    from genplan.seq2seq.model import Seq2SeqNet

    net = Seq2SeqNet(model.config)
    net.load_state_dict(model.net.state_dict())
    with torch.no_grad():
        net.head.bias[1] = float("nan")
    with pytest.raises(FloatingPointError, match=r"problem 0 became NaN or inf after 0 update\(s\) \(the model cannot"):
        adjust(x_in, "j1", "latent", 2, model=Seq2SeqModel(model.config, net))


@pytest.mark.parametrize("method", ["latent", "random-latent", "direct-u"])
def test_an_empty_batch_gives_an_empty_result(model, method) -> None:
    """Finding PY-8 of tests/test_fuzz_inputs.py: (0, K, 3) was refused with a ShapeError."""
    res = adjust(np.zeros((0, 500, 3)), "j1", method, 3, model=model, snapshots=(0, 3), p_end=[0.1, 0.0, 0.0])
    assert res.p.shape == res.v.shape == res.u.shape == (0, 500, 3) and res.phi.shape == (0, 500)
    assert res.objective_history.shape == (4, 0) and res.batch == 0 and res.updates == 3
    assert res.z is None if method == "direct-u" else res.z.shape == (0, model.config.latent_dim)
    assert set(res.snapshots) == {0, 3} and res.snapshots[3]["phi"].shape == (0, 500)
    assert res.max_abs_phi.shape == (0,) and res.inside_cone().shape == (0,) and res.first_update_below(1.0).shape == (0,)
    assert math.isnan(res.ms_per_update)
    assert adjust(np.zeros((0, 500, 3)), "j2", model=model, updates=0).objective_history.shape == (1, 0)
    # the arguments are still checked
    with pytest.raises(ShapeError, match="p_end"):
        adjust(np.zeros((0, 500, 3)), "j1", p_end=np.zeros((2, 3)), model=model)
    with pytest.raises(SettingsError, match="lr"):
        adjust(np.zeros((0, 500, 3)), lr=-1.0, model=model)
    deformed = model.deform(np.zeros((0, 500, 3)))
    assert deformed["p"].shape == (0, 500, 3) and deformed["z"].shape == (0, model.config.latent_dim)


@pytest.mark.parametrize("call, error, match", [
    (lambda x, m: adjust("abc", model=m), ShapeError, "^x_in: cannot be read"),
    (lambda x, m: adjust(x + 1j, model=m), ShapeError, "^x_in: complex numbers"),
    (lambda x, m: adjust(x, p_end="abc", model=m), ShapeError, "^p_end: cannot be read"),
    (lambda x, m: adjust(x, seed="abc", model=m), SettingsError, "^seed must be an integer"),
    (lambda x, m: adjust(x, seed=1.5, model=m), SettingsError, "^seed must be an integer"),
    (lambda x, m: adjust(x, max_step="big", model=m), SettingsError, "^max_step: cannot be read"),
    (lambda x, m: adjust(x, updates=2, snapshots=("1",), model=m), SettingsError, "^snapshots must be an integer"),
    (lambda x, m: adjust(x, updates=10**9, model=m), SettingsError, "^updates must be at most 1000000"),
    (lambda x, m: J1([0, 0, 0], alpha="x"), ShapeError, "^alpha: cannot be read"),
    (lambda x, m: J1([0, 0, 0], d=[1, 1]), ShapeError, "^d must have 3 values"),
    (lambda x, m: J2(p_lim="x"), ShapeError, "^J2 p_lim: cannot be read"),
    (lambda x, m: J2(v_lim=(1.0, 1.0)), ShapeError, "^J2: v_lim and d need 3 values"),
    (lambda x, m: J2(center="ab"), ShapeError, "^J2 center: cannot be read"),
    (lambda x, m: J2Executable(margin="x"), SettingsError, "^J2Executable margin: cannot be read"),
])
def test_arguments_that_are_not_numbers_name_themselves(model, x_in, call, error, match) -> None:
    """Finding PY-2 of tests/test_fuzz_inputs.py: strings leaked numpy's or float()'s ValueError."""
    with pytest.raises(error, match=match):
        call(x_in, model)
