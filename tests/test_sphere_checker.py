"""The sphere checker (``genplan._core.SphereChecker``, ``genplan.planning.sphere_checker``,
``Planner(..., checker="spheres")``): conservative against the exact world on the shelf scene,
one configuration and a batch alike, motions checked state by state, plans whose paths are valid
by the exact geometry, a link fixed to the world inside an obstacle (every configuration in
collision, the start refused), and the refusals (unknown checker, the certified edge check, bad
spheres)."""

from __future__ import annotations

import numpy as np
import pytest

import genplan
from genplan import _core
from genplan.errors import GenplanError, InvalidStartError, ShapeError, SettingsError, UnknownNameError
from genplan.planning import CHECKERS, Planner, PlannerSettings, environment, plan, sphere_checker
from genplan.spheres import robot_spheres


@pytest.fixture(scope="module")
def shelf(panda: genplan.Robot):
    world = environment("panda_shelf").world(panda)
    return world, sphere_checker(panda, world)


def test_free_by_spheres_is_free_by_the_exact_world(panda: genplan.Robot, shelf) -> None:
    world, sc = shelf
    q = panda.random_configurations(4000, np.random.default_rng(0))
    exact = np.asarray(world.in_collision(q), dtype=bool)
    spheres = np.asarray(sc.in_collision(q), dtype=bool)
    assert spheres.shape == (len(q),) and spheres.dtype == bool
    assert not np.any(exact & ~spheres), "a configuration in collision by the exact geometry is free by the spheres"
    assert 0.1 < exact.mean() < 0.9
    # false positives: near contact only, a small share of the free configurations
    assert (spheres & ~exact).sum() < 0.2 * (~exact).sum()
    # one configuration at a time answers as the batch does
    for i in range(0, 400, 7):
        assert sc.in_collision(q[i]) is bool(spheres[i])
    assert sc.n_spheres == len(robot_spheres(panda))
    assert len(sc.self_pairs) > 0


def test_a_motion_is_free_when_its_states_are(panda: genplan.Robot, shelf) -> None:
    _, sc = shelf
    rng = np.random.default_rng(1)
    seen = set()
    for _ in range(60):
        a, b = panda.random_configurations(2, rng)
        b = a + 0.3 * (b - a)
        steps = max(1, int(np.ceil(np.abs(b - a).max() / 0.05)))
        states = a + np.linspace(0, 1, steps + 1)[:, None] * (b - a)
        want = not np.asarray(sc.in_collision(states)).any()
        assert sc.motion_free(a.tolist(), b.tolist(), 0.05) is want
        seen.add(want)
    assert seen == {True, False}
    with pytest.raises(GenplanError, match="resolution"):
        sc.motion_free(a.tolist(), b.tolist(), 0.0)
    with pytest.raises(ShapeError):
        sc.motion_free(a[:3].tolist(), b.tolist(), 0.05)


def test_planner_with_spheres_plans_paths_valid_by_the_exact_geometry(panda: genplan.Robot, shelf) -> None:
    world, sc = shelf
    assert CHECKERS == ("exact", "spheres", "hybrid")
    rng = np.random.default_rng(2)
    q = panda.random_configurations(200, rng)
    q = q[~np.asarray(sc.in_collision(q), dtype=bool)]
    planner = Planner(panda, world=world, task="free", checker="spheres", algorithm="rrt_connect")
    assert isinstance(planner.checker, _core.SphereChecker)
    solved = 0
    for start, goal in zip(q[0:8:2], q[1:8:2]):
        res = planner.plan(start, goal)
        if res.success:
            solved += 1
            assert not np.asarray(world.in_collision(res.path)).any()
            assert not np.asarray(sc.in_collision(res.path)).any()
            assert res.world is world  # the trajectory is checked against the exact geometry
    assert solved >= 3


def test_plan_takes_the_checker_by_name(panda: genplan.Robot, shelf) -> None:
    world, sc = shelf
    q = panda.random_configurations(100, np.random.default_rng(3))
    q = q[~np.asarray(sc.in_collision(q), dtype=bool)]
    out = plan(panda, scene="panda_shelf", start=q[0], goal=q[1], checker="spheres", algorithm="rrt_connect", parallel=False)
    assert out.result.success
    assert not np.asarray(world.in_collision(out.result.path)).any()
    assert not np.asarray(sc.in_collision(out.result.path)).any()
    with pytest.raises(UnknownNameError, match="checker"):
        plan(panda, checker="voxels")
    with pytest.raises(UnknownNameError, match="spheres"):
        Planner(panda, task="free", checker="boxes")


def test_the_hybrid_checker_answers_as_the_exact_geometry(panda: genplan.Robot, shelf) -> None:
    """checker="hybrid": the spheres, each collision they find confirmed by the exact geometry.
    A start 2-6 mm from an obstacle, which the spheres (reaching up to 1 cm beyond the links)
    refuse, is planned from, and every state of the path is free by the exact geometry."""
    world, sc = shelf
    q = panda.random_configurations(4000, np.random.default_rng(8))
    d = np.asarray(world.min_distance(q)).reshape(-1)
    close = q[(d > 0.002) & (d < 0.006) & ~np.asarray(world.in_collision(q), dtype=bool)]
    close = close[np.asarray(sc.in_collision(close), dtype=bool)]  # the spheres' false positives
    free = q[~np.asarray(sc.in_collision(q), dtype=bool)]
    assert len(close) >= 2 and len(free) >= 2
    hybrid = Planner(panda, world=world, task="free", checker="hybrid", algorithm="rrt_connect", seed=1)
    assert isinstance(hybrid.checker, _core.SphereChecker) and hybrid.checker.confirm
    assert not sphere_checker(panda, world).confirm
    with pytest.raises(InvalidStartError):
        Planner(panda, world=world, task="free", checker="spheres", algorithm="rrt_connect").plan(close[0], free[0])
    solved = 0
    for start, goal in zip(close[:3], free[:3]):
        res = hybrid.plan(start, goal)
        if res.success:
            solved += 1
            assert not np.asarray(world.in_collision(res.path)).any()
    assert solved >= 1
    with pytest.raises(SettingsError, match="hybrid.*certified"):
        Planner(panda, task="free", checker="hybrid", settings=PlannerSettings(edge_check="certified"))
    with pytest.raises(SettingsError, match="confirm"):
        sphere_checker(panda, world, confirm=1)


def test_a_fixed_link_inside_an_obstacle_collides_in_every_configuration(panda: genplan.Robot, shelf) -> None:
    _, free = shelf
    world = panda.collision_world()
    world.add_sphere("ball", 0.03, [0.0, 0.0, 0.05])  # inside the base, which no joint moves
    sc = sphere_checker(panda, world)
    q = panda.random_configurations(50, np.random.default_rng(4))
    assert np.asarray(sc.in_collision(q), dtype=bool).all()
    assert np.asarray(world.in_collision(q), dtype=bool).all()
    assert sc.motion_free(q[0].tolist(), q[1].tolist(), 0.05) is False
    # the moving links are checked as before: the shelf alone leaves some of them free
    assert not np.asarray(free.in_collision(q), dtype=bool).all()
    planner = Planner(panda, world=world, task="free", checker="spheres", algorithm="rrt_connect")
    with pytest.raises(InvalidStartError):
        planner.plan(q[0], q[1])


def test_certified_edges_need_the_exact_checker(panda: genplan.Robot) -> None:
    with pytest.raises(SettingsError, match="certified"):
        Planner(panda, task="free", checker="spheres", settings=PlannerSettings(edge_check="certified"))


def test_bad_spheres_are_refused_naming_the_argument(panda: genplan.Robot) -> None:
    w = panda.collision_world().native
    with pytest.raises(ShapeError, match="centers"):
        _core.SphereChecker(w, ["panda_link1", "panda_link2"], [[0.0, 0.0, 0.0]], [0.1, 0.1])
    with pytest.raises(UnknownNameError, match="nowhere"):
        _core.SphereChecker(w, ["nowhere"], [[0.0, 0.0, 0.0]], [0.1])
    with pytest.raises(GenplanError, match="radii"):
        _core.SphereChecker(w, ["panda_link1"], [[0.0, 0.0, 0.0]], [-0.1])


def test_an_attached_object_is_covered_by_spheres_of_its_own(panda: genplan.Robot) -> None:
    """A block held 10 cm below the hand: the sphere checker covers it (conservative against the
    exact world, which checks it as one more robot geometry), finds the configurations where
    only the block collides (with the wall or a link), checks it against the links of its self pairs (not its
    touch links), and refuses a world holding an object the robot does not."""
    from genplan.scene import Box, Pose

    held = panda.with_attached("block", Box("block", (0.03, 0.03, 0.08)), link="panda_hand",
                               pose=Pose(position=(0.0, 0.0, 0.18)))
    world = held.collision_world()
    world.add_box("wall", (0.1, 0.3, 0.3), (0.7, 0.0, 0.5))
    bare = panda.collision_world()
    bare.add_box("wall", (0.1, 0.3, 0.3), (0.7, 0.0, 0.5))
    sc = sphere_checker(held, world)
    assert sc.n_spheres > len(robot_spheres(panda))
    names = {n for pair in sc.self_pairs for n in pair}
    touch = dict((name, t) for name, _link, t in world.attached)["block"]
    assert "block" in names and not any("block" in p and set(p) & set(touch) for p in sc.self_pairs)
    q = panda.random_configurations(3000, np.random.default_rng(4))
    exact = np.asarray(world.in_collision(q), dtype=bool)
    spheres = np.asarray(sc.in_collision(q), dtype=bool)
    assert not np.any(exact & ~spheres), "the held block collides by the exact world, not by the spheres"
    only_block = exact & ~np.asarray(bare.in_collision(q), dtype=bool)
    assert only_block.sum() >= 50 and spheres[only_block].all()
    assert (spheres & ~exact).sum() < 0.2 * (~exact).sum()
    # the spheres without the block's are refused; a world holding an object the robot does not
    with pytest.raises(GenplanError, match="attached object 'block' needs its spheres"):
        _core.SphereChecker(world.native, list(robot_spheres(panda).links), robot_spheres(panda).centers.tolist(),
                            robot_spheres(panda).radii.tolist())
    with pytest.raises(SettingsError, match="attached object 'block' on link 'panda_hand'.*holds: none"):
        sphere_checker(panda, world)
    s = robot_spheres(panda)
    with pytest.raises(UnknownNameError, match="ghost.*block"):
        _core.SphereChecker(world.native, list(s.links), s.centers.tolist(), s.radii.tolist(),
                            [("block", [[0.0, 0.0, 0.1]], [0.05]), ("ghost", [[0.0, 0.0, 0.0]], [0.1])])
    with pytest.raises(GenplanError, match="block.*radii"):
        _core.SphereChecker(world.native, list(s.links), s.centers.tolist(), s.radii.tolist(),
                            [("block", [[0.0, 0.0, 0.1]], [-0.05])])
