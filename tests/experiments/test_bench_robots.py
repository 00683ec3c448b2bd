"""genplan bench robots: every robot (presets, xArm7 from its URDF, robots without an SRDF and
with continuous joints or Collada meshes) through the one loading path, checked against
Pinocchio (FK) and coal (collision on the same convex hulls) (issue [any-robot], targets)."""

import pytest

from genplan.experiments.benchmarks import robots as bench


@pytest.mark.parametrize("name", list(bench.ROBOTS))
def test_every_robot_agrees_with_pinocchio_and_coal(name: str) -> None:
    row = bench.check_robot(name, samples=2000, seed=5, fresh=False)
    assert row["fk_max_error"] <= 1e-9, row
    assert row["agreement_hulls"] >= 0.999, row
    assert row["disagree_max_distance_hulls"] <= 1e-3, row
    assert 0.0 < row["collision_rate"] < 1.0, row  # both answers are exercised
    assert row["self_pairs"] > 0 and row["geometries"] > 0, row


def test_the_set_covers_what_the_issue_names() -> None:
    assert {"panda", "ur3", "ur5", "ur10", "xarm7", "kinova", "talos"} <= set(bench.ROBOTS)
    assert any(bench.ROBOTS[n]().srdf_path is None for n in bench.ROBOTS)  # one without an SRDF
