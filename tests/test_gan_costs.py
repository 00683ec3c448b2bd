"""genplan.samplers.costs: a GAN's costs for any robot and task, from the native residuals; and the
GAN trained, saved and refused for another robot or task through them (xArm7, not a preset)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import torch

import genplan
from genplan import projection as P
from genplan.errors import GenplanError, ModelFileError, SettingsError, UnknownNameError
from genplan.samplers.costs import NativeCost, condition_term, constraint_terms, manifold_task, sampling_box, tangent_map
from genplan.samplers.gan import default_config, load_model, train

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "xarm7"


@pytest.fixture(scope="module")
def xarm7() -> genplan.Robot:
    return genplan.load(EXAMPLES / "xarm7.toml")


@pytest.fixture(scope="module")
def cup(xarm7: genplan.Robot) -> P.Task:
    return P.load_task(EXAMPLES / "upright_cup.toml", xarm7)


@pytest.mark.parametrize("name", ["panda", "talos", "kinova"])
def test_tangent_map_maps_a_configuration_change_to_its_velocity(name: str) -> None:
    """q2 = integrate(q, v) for a small v: T(q) (q2 - q) = v to first order (free flyer,
    continuous joints and revolute joints alike)."""
    robot = genplan.load(name)
    rng = np.random.default_rng(3)
    q = robot.random_configurations(4, rng)
    v = rng.normal(size=(4, robot.nv)) * 1e-6
    q2 = np.array([pin.integrate(robot.model, q[i], v[i]) for i in range(4)])
    mapped = np.einsum("bvq,bq->bv", tangent_map(robot, q), q2 - q)
    assert np.allclose(mapped, v, atol=1e-10, rtol=1e-4)


@pytest.mark.parametrize("name", ["xarm7", "talos"])
def test_native_cost_gradient_matches_finite_differences(name: str, xarm7: genplan.Robot, cup: P.Task) -> None:
    robot = xarm7 if name == "xarm7" else genplan.load("talos")
    task = cup if name == "xarm7" else P.load_task("talos_ik", robot)
    cost = NativeCost(robot, constraint_terms(task, robot))
    rng = np.random.default_rng(0)
    q = robot.random_configurations(5, rng)
    qt = torch.tensor(q, requires_grad=True)
    c_t = (cost(qt) ** 2).sum()
    c_t.backward()
    c = c_t.item()
    assert qt.grad is not None
    grad = qt.grad.numpy()
    for i in range(5):
        v = rng.normal(size=robot.nv) * 1e-6
        q2 = q.copy()
        q2[i] = pin.integrate(robot.model, q[i], v)
        c2 = float((cost(torch.tensor(q2)) ** 2).sum())
        assert c2 - c == pytest.approx(float(grad[i] @ (q2[i] - q[i])), rel=1e-3, abs=1e-12)


def test_native_cost_is_the_solvers_residual(xarm7: genplan.Robot, cup: P.Task) -> None:
    """The residual the GAN is trained on is zero exactly where the projector's solutions are."""
    cost = NativeCost(xarm7, tuple(dataclasses.replace(t, weight=1.0) for t in constraint_terms(cup, xarm7)))
    res = P.GaussNewtonProjector(xarm7, manifold_task(cup, xarm7)).solve_batch(
        xarm7.random_configurations(50, np.random.default_rng(1)))
    on = res.q[res.success]
    assert len(on) > 40
    assert np.abs(cost(torch.tensor(on)).numpy()).max() < 1e-3  # the terms' tolerance
    off = xarm7.random_configurations(50, np.random.default_rng(2))
    assert np.abs(cost(torch.tensor(off)).numpy()).max() > 0.1


def test_manifold_and_condition_of_a_task(xarm7: genplan.Robot, cup: P.Task) -> None:
    assert [t.name for t in manifold_task(cup, xarm7).primary] == ["cup_upright", "joint_limits"]
    assert [t.name for t in constraint_terms(cup, xarm7)] == ["cup_upright"]
    assert condition_term(cup).name == "tool_position"
    assert sampling_box(cup).tolist() == [[0.25, -0.45, 0.15], [0.6, 0.45, 0.55]]
    # the paper's tasks name their manifold: the projection task (other weights and tolerances)
    panda = genplan.load("panda")
    ik = P.load_task("panda_ik", panda)
    assert manifold_task(ik, panda).to_dict() == P.paper_task(panda, "projection").to_dict()
    assert sampling_box(ik).tolist() == [[-0.6, -0.6, -0.1], [0.6, 0.6, 1.0]]


def test_tasks_a_sampler_cannot_be_conditioned_on(xarm7: genplan.Robot, cup: P.Task) -> None:
    with pytest.raises(GenplanError, match="task 'upright_cup' has no \\[condition\\]"):
        condition_term(dataclasses.replace(cup, condition=None))
    on_orientation = dataclasses.replace(cup, condition=P.Condition("cup_upright", (0, 0, 0), (1, 1, 1)))
    with pytest.raises(GenplanError, match="condition term 'cup_upright' is a FrameOrientation"):
        condition_term(on_orientation)
    with pytest.raises(UnknownNameError, match="condition term 'nope' is not one of its primary terms"):
        condition_term(dataclasses.replace(cup, condition=P.Condition("nope", (0, 0, 0), (1, 1, 1))))
    with pytest.raises(SettingsError, match="robot 'xarm7' has no shipped task"):
        default_config(xarm7)


def test_default_sizes_follow_the_dimensions(xarm7: genplan.Robot, cup: P.Task) -> None:
    arm = default_config(xarm7, cup)
    assert (arm.robot, arm.task, arm.target_frame) == ("xarm7", "upright_cup", "tool")
    assert (arm.noise_dim, arm.n_net, arm.disc_hidden, arm.w_target) == (10, 10, (20, 20), 20.0)
    assert arm.target_box == ((0.25, -0.45, 0.15), (0.6, 0.45, 0.55))
    humanoid = default_config("talos")
    assert (humanoid.noise_dim, humanoid.n_net, humanoid.disc_hidden, humanoid.w_target) == (30, 5, (40, 40), 1000.0)
    # the shipped models' configurations are what the rule gives (their cards predate tasks)
    for name in ("panda", "talos"):
        shipped = load_model(name).config
        assert dataclasses.replace(default_config(name), task="") == shipped


def test_a_gan_for_a_robot_and_task_of_ones_own(xarm7: genplan.Robot, cup: P.Task, tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path / "cache"))
    cfg = default_config(xarm7, cup, iterations=30, data_size=400, n_net=2)
    model = train(cfg, robot=xarm7, task=cup, progress=False)
    # denormal floats are flushed only while training (python/genplan/samplers/gan.py)
    assert torch.tensor([1e-40], dtype=torch.float32).item() != 0.0
    assert model.card["task"]["name"] == "upright_cup"
    assert model.card["command"].startswith(f"genplan train gan --robot {EXAMPLES / 'xarm7.toml'} --task upright_cup")
    weights, _ = model.save(tmp_path / "cup.safetensors")
    again = load_model(xarm7, weights, task=cup)
    q = again.sample(np.array([[0.4, 0.0, 0.3]]), 0)
    assert q.shape == (1, 7) and np.all(np.isfinite(q))
    with pytest.raises(ModelFileError, match="is a GAN for robot 'xarm7', not 'panda'"):
        load_model("panda", weights)
    with pytest.raises(ModelFileError, match="is a GAN for task 'upright_cup', not 'panda_ik'"):
        load_model(xarm7, weights, task=dataclasses.replace(cup, name="panda_ik"))
    other_terms = dataclasses.replace(cup, primary=tuple(
        dataclasses.replace(t, tolerance=0.01) if t.name == "cup_upright" else t for t in cup.primary))
    with pytest.raises(ModelFileError, match="same name, other terms"):
        load_model(xarm7, weights, task=other_terms)
    with pytest.raises(SettingsError, match="GanConfig.task is 'upright_cup', the task given 'panda_ik'"):
        train(cfg, robot=xarm7, task=dataclasses.replace(cup, name="panda_ik"), progress=False)
