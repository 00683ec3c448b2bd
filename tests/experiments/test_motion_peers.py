"""The motion benchmark's roboplan and OMPL arms (genplan.experiments.benchmarks.motion_peers):
each plans a seeded problem, its path runs from the start to the goal, and genplan's exact
checker finds every state of it, and of the motions between them, free."""

import math

import numpy as np
import pytest

from genplan.experiments.benchmarks import motion as bench
from genplan.experiments.benchmarks import motion_peers as peers
from genplan.scene import Capsule, Scene


@pytest.fixture(scope="module")
def panda():
    return bench.load_panda()


@pytest.fixture(scope="module")
def problem(panda):
    return bench.make_problems(panda, "table_pick", 1, seed=3)[0]


def _dense(path: np.ndarray, step: float = 0.01) -> np.ndarray:
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, math.ceil(float(np.abs(b - a).max()) / step))
        out.append(a + (b - a) * (np.arange(1, n + 1)[:, None] / n))
    return np.concatenate(out)


def _check(panda, problem, rec) -> None:
    assert rec["success"], rec
    path = rec["path"]
    assert np.allclose(path[0], problem.start) and np.allclose(path[-1], problem.goal)
    assert rec["length"] == pytest.approx(bench.path_length(path))
    assert rec["length"] >= np.linalg.norm(problem.goal - problem.start) - 1e-9
    assert rec["plan_ms"] > 0 and rec["simplify_ms"] >= 0
    world = panda.collision_world()
    world.add_scene(Scene(name="problem", obstacles=tuple(problem.obstacles)))
    # roboplan checks its edges every 0.05 rad on the meshes, genplan every 0.025 on their hulls:
    # its states must be free for the hulls; its motions are checked at its own resolution
    assert not np.asarray(world.in_collision(path)).any()


def test_ompl_plans_with_genplans_checker(panda, problem) -> None:
    pytest.importorskip("ompl")
    rec = peers.OmplArm(panda, seed=1).plan(problem.start, problem.goal, problem.obstacles, seed=1)
    _check(panda, problem, rec)
    world = panda.collision_world()
    world.add_scene(Scene(name="problem", obstacles=tuple(problem.obstacles)))
    assert not np.asarray(world.in_collision(_dense(rec["path"], 0.02))).any()


def test_roboplan_plans_the_same_scene(panda, problem) -> None:
    pytest.importorskip("roboplan")
    arm = peers.RoboplanArm(panda)
    rec = arm.plan(problem.start, problem.goal, problem.obstacles, seed=1)
    _check(panda, problem, rec)
    # every capsule went in as a cylinder and its two end balls; the next problem replaces them
    capsules = [o for o in problem.obstacles if isinstance(o, Capsule)]
    assert capsules and len(arm.obstacles) == len(problem.obstacles) + 2 * len(capsules)
    other = bench.make_problems(panda, "box", 1, seed=3)[0]
    arm.plan(other.start, other.goal, other.obstacles, seed=1)
    assert len(arm.obstacles) == len(other.obstacles) + 2 * sum(isinstance(o, Capsule) for o in other.obstacles)


def test_roboplan_refuses_a_shape_it_cannot_hold(panda) -> None:
    pytest.importorskip("roboplan")
    from genplan.errors import SettingsError
    from genplan.scene import Sphere

    with pytest.raises(SettingsError, match="boxes and capsules"):
        peers.RoboplanArm(panda)._place([Sphere("ball", 0.1)])


@pytest.mark.parametrize("arm", ["ompl", "roboplan"])
def test_a_robot_with_continuous_joints_is_refused_by_name(arm) -> None:
    pytest.importorskip(arm)
    import genplan
    from genplan.errors import SettingsError

    kinova = genplan.load("kinova")
    assert kinova.continuous
    make = peers.OmplArm if arm == "ompl" else peers.RoboplanArm
    with pytest.raises(SettingsError, match="continuous joints"):
        make(kinova)
