import numpy as np
import pytest

import genplan


@pytest.fixture(scope="session")
def panda() -> genplan.Robot:
    return genplan.load("panda")


@pytest.fixture(scope="session")
def talos() -> genplan.Robot:
    return genplan.load("talos")


@pytest.fixture(scope="session")
def ur5() -> genplan.Robot:
    return genplan.load("ur5")


def random_configurations(robot: genplan.Robot, n: int, seed: int) -> np.ndarray:
    """Joints uniform in their limits; a free-flyer base anywhere in a 2 m cube with a uniformly
    random orientation (so FK is checked away from the default base placement too)."""
    rng = np.random.default_rng(seed)
    q = robot.random_configurations(n, rng)
    if robot.floating_base:
        q[:, :3] = rng.uniform(-1.0, 1.0, size=(n, 3))
        quat = rng.normal(size=(n, 4))
        q[:, 3:7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    return q
