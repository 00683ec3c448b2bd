import pytest

import genplan
from genplan.experiments.benchmarks.robots import configurations


@pytest.fixture(scope="session")
def panda() -> genplan.Robot:
    return genplan.load("panda")


@pytest.fixture(scope="session")
def talos() -> genplan.Robot:
    return genplan.load("talos")


@pytest.fixture(scope="session")
def ur5() -> genplan.Robot:
    return genplan.load("ur5")


# Joints uniform in their limits (continuous joints as unit complex numbers); a free-flyer base
# anywhere in a 2 m cube with a uniformly random orientation (FK checked away from the default
# base placement too): the definition `genplan bench robots` uses.
random_configurations = configurations
