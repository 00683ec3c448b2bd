"""Empty batches work everywhere (issue 15, kind 8): zero configurations, targets or samples in,
empty arrays of the right shape and type out, never an error. One test per entry point."""

from __future__ import annotations

import numpy as np
import pytest

import genplan
from genplan import projection as P
from genplan.samplers.sampler import GanSampler
from genplan.planning import make_sampler


@pytest.fixture(scope="module")
def none(panda: genplan.Robot) -> np.ndarray:
    return np.zeros((0, panda.nq))


def test_forward_kinematics(panda: genplan.Robot, none: np.ndarray) -> None:
    n_links = len(panda.kinematics.link_names)
    assert panda.link_poses(none).shape == (0, n_links, 4, 4)
    assert panda.link_poses(none, ["panda_hand", "panda_link3"]).shape == (0, 2, 4, 4)
    assert panda.kinematics.forward_kinematics(none).shape == (0, n_links, 4, 4)


def test_collision_and_distance(panda: genplan.Robot, none: np.ndarray) -> None:
    world = panda.collision_world()
    for answer, dtype in ((world.in_collision(none), bool), (world.min_distance(none), np.float64)):
        assert isinstance(answer, np.ndarray) and answer.shape == (0,) and answer.dtype == dtype


@pytest.mark.parametrize("backend", P.BACKENDS)
def test_solve_batch(panda: genplan.Robot, none: np.ndarray, backend: str) -> None:
    task = P.paper_task(panda, "ik")
    proj = P.GaussNewtonProjector(panda, task, backend=backend)
    for res in (proj.solve_batch(none), proj.solve_batch(none, none),
                proj.solve_batch(none, targets={"hand_position": np.zeros((0, 3))})):
        assert res.q.shape == (0, panda.nq) and len(res) == 0
        assert res.success.shape == res.iterations.shape == res.time_s.shape == (0,)
        assert res.success.dtype == bool and res.iterations.dtype == np.int64
        assert set(res.residuals) == {t.name for t in task.primary}
        assert all(r.shape == (0,) for r in res.residuals.values())
    q, ok = proj.project(none, none)
    assert q.shape == (0, panda.nq) and ok.shape == (0,)


def test_solve_batch_with_pose_targets(panda: genplan.Robot, none: np.ndarray) -> None:
    task = P.Task(primary=[P.FramePose(name="hand_pose", frame="hand", target=np.eye(4))])
    res = P.GaussNewtonProjector(panda, task).solve_batch(none, targets={"hand_pose": np.zeros((0, 4, 4))})
    assert res.q.shape == (0, panda.nq) and res.residuals["hand_pose"].shape == (0,)


@pytest.mark.parametrize("kind", ["uniform", "gan"])
def test_native_samplers(panda: genplan.Robot, kind: str) -> None:
    q = make_sampler(panda, kind, seed=0).sample(0)
    assert q.shape == (0, panda.nq) and q.dtype == np.float64


def test_native_gan_generate(panda: genplan.Robot) -> None:
    gan = make_sampler(panda, "gan", seed=0)
    noise_dim = GanSampler(panda).model.config.noise_dim
    assert gan.generate([], np.zeros((0, noise_dim)), np.zeros((0, 3))).shape == (0, panda.nq)


def test_gan_sampler(panda: genplan.Robot) -> None:
    sampler = GanSampler(panda, seed=0)
    assert sampler.sample(0).shape == (0, panda.nq)
    assert sampler.sample_for(np.zeros((0, 3))).shape == (0, panda.nq)


def test_random_configurations(panda: genplan.Robot) -> None:
    assert panda.random_configurations(0, 0).shape == (0, panda.nq)
