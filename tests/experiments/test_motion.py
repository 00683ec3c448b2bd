"""genplan bench motion: MotionBenchMaker-style Panda problems (seeded, valid for every planner
compared), VAMP's environment and spheres built from the same shapes, and a small run of the
command (VAMP's arm only when it is installed)."""

import json

import numpy as np
import pytest

from genplan.cli import main
from genplan.experiments.benchmarks import motion as bench
from genplan.planning import sphere_checker
from genplan.scene import Scene


@pytest.fixture(scope="module")
def panda():
    return bench.load_panda()


def _world(robot, obstacles):
    world = robot.collision_world()
    world.add_scene(Scene(name="problem", obstacles=tuple(obstacles)))
    return world


@pytest.mark.parametrize("family", list(bench.FAMILIES))
def test_problems_are_seeded_and_valid(panda, family: str) -> None:
    problems = bench.make_problems(panda, family, 2, seed=3)
    assert len(problems) == 2
    again = bench.make_problems(panda, family, 2, seed=3)
    for p, q in zip(problems, again):
        assert np.array_equal(p.start, q.start) and np.array_equal(p.goal, q.goal)
        assert p.obstacles == q.obstacles
    for p in problems:
        world = _world(panda, p.obstacles)
        both = np.stack([p.start, p.goal])
        assert not np.asarray(world.in_collision(both)).any()
        assert not np.asarray(sphere_checker(panda, world).in_collision(both)).any()
        assert np.all((both >= panda.lower) & (both <= panda.upper))
        assert np.linalg.norm(p.goal - p.start) > 0.5
    other = bench.make_problems(panda, family, 1, seed=4)[0]
    assert not np.array_equal(other.goal, problems[0].goal)


def test_path_length_is_the_joint_space_l2_sum() -> None:
    assert bench.path_length([[0.0, 0.0], [3.0, 4.0], [3.0, 5.0]]) == pytest.approx(6.0)
    assert bench.path_length([[1.0, 2.0]]) == 0.0


def test_vamp_sees_the_same_obstacles_and_spheres(panda) -> None:
    vamp = pytest.importorskip("vamp")
    spheres = bench.vamp_spheres(vamp, panda)
    assert len(spheres) == vamp.panda.n_spheres()
    # VAMP's spheres through genplan's kinematics land where VAMP's own kinematics puts them
    q = panda.random_configurations(4, np.random.default_rng(1))
    ours = spheres.world_centers(panda, q)
    theirs = np.array([[[s.x, s.y, s.z] for s in vamp.panda.fk(r.astype(np.float32))] for r in q])
    assert np.abs(ours - theirs).max() < 1e-4
    # the same obstacles: VAMP's environment and the genplan world on VAMP's spheres agree
    p = bench.make_problems(panda, "table_pick", 1, seed=0)[0]
    env = bench.vamp_environment(vamp, p.obstacles)
    checker = sphere_checker(panda, _world(panda, p.obstacles), spheres=spheres)
    qs = np.clip(bench.READY + np.random.default_rng(2).uniform(-1.0, 1.0, (300, 7)), panda.lower, panda.upper)
    ours = ~np.asarray(checker.in_collision(qs), dtype=bool)
    theirs = np.array([vamp.panda.validate(r.astype(np.float32), env) for r in qs])
    assert ours.any() and (~ours).any()
    assert np.mean(ours == theirs) >= 0.97


def test_a_small_run_writes_the_table_and_json(tmp_path, capsys) -> None:
    out = tmp_path / "motion.json"
    code = main(["bench", "motion", "--families", "box", "table_pick", "--problems", "2", "--out", str(out)])
    assert code == 0
    payload = json.loads(out.read_text())
    arms = payload["arms"]
    assert {"genplan_spheres", "genplan_exact"} <= set(arms)
    assert len(payload["records"]) == 2 * 2 * len(arms)
    for r in payload["rows"]:
        assert r["problems"] == 2 and r["success_pct"] == 100.0, r
        assert r["plan_ms_median"] > 0 and r["length_median"] > 0
    for r in payload["records"]:
        assert r["success"] and r["simplify_ms"] >= 0.0 and r["length"] > 0
    printed = capsys.readouterr().out
    assert "table_pick" in printed and "genplan_exact" in printed
    if "vamp" not in arms:
        assert "vamp" in payload["skipped"]


def test_other_robots_get_the_scenes_placed_for_them() -> None:
    obstacles, grasps = bench.FAMILIES["box"](np.random.default_rng(0))
    # the Panda's scenes are the families' own
    same = bench.placed(bench.ROBOTS["panda"], obstacles, grasps)
    assert same[0] is obstacles and same[1] is grasps
    setup = bench.ROBOTS["baxter"]
    moved, goals = bench.placed(setup, obstacles, grasps)
    k, off = setup.scale, np.asarray(setup.offset)
    for a, b in zip(obstacles, moved):
        assert np.allclose(b.pose.position, k * np.asarray(a.pose.position) + off)
    assert np.allclose(goals[0][:3, 3], k * grasps[0][:3, 3] + off) and np.allclose(goals[0][:3, :3], grasps[0][:3, :3])
    # the UR5's tool frame (its flange) stops tool_back short of the grasp, along the tool's z
    ur5 = bench.ROBOTS["ur5"]
    _, back = bench.placed(ur5, obstacles, grasps)
    assert np.allclose(grasps[0][:3, 3] - back[0][:3, 3], ur5.tool_back * grasps[0][:3, 2])
    # the Kinova's end effector approaches along its x, its fingers closing along its y
    kinova = bench.ROBOTS["kinova"]
    _, turned = bench.placed(kinova, obstacles, grasps)
    assert np.allclose(turned[0][:3, 0], grasps[0][:3, 2]) and np.allclose(turned[0][:3, 1], grasps[0][:3, 1])
    assert np.allclose(np.linalg.det(turned[0][:3, :3]), 1.0)


def test_ur5_problems_are_valid_for_vamp_in_its_own_frame() -> None:
    vamp = pytest.importorskip("vamp")
    setup = bench.ROBOTS["ur5"]
    ur5 = setup.load()
    p = bench.make_problems(ur5, "table_pick", 1, seed=0, vamp=vamp, setup=setup)[0]
    env = bench.vamp_environment(vamp, p.obstacles, setup.vamp_base)
    assert all(vamp.ur5.validate(q.astype(np.float32), env) for q in (p.start, p.goal))
    # the same obstacles in genplan's frame (no base given) collide with VAMP's UR5 somewhere else:
    # a table top at VAMP's origin level in front of the arm's base
    lifted = bench.vamp_environment(vamp, p.obstacles)
    qs = np.random.default_rng(0).uniform(-3.0, 3.0, (200, 6)).astype(np.float32)
    assert [vamp.ur5.validate(q, env) for q in qs] != [vamp.ur5.validate(q, lifted) for q in qs]
    assert np.all((p.start >= np.asarray(vamp.ur5.lower_bounds())) & (p.goal <= np.asarray(vamp.ur5.upper_bounds())))
