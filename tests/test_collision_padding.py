"""Clearance margins (CollisionWorld.padding, an obstacle's own padding, a scene file's
``padding`` key): a state closer than the margin is a collision for in_collision, plans (sampled
and certified edges) and trajectories; distances stay geometric; bad margins are typed errors."""

import numpy as np
import pytest

import genplan
from genplan.errors import GenplanError, SceneFileError
from genplan.planning import Planner, PlannerSettings
from genplan.scene import Box, Pose, Scene, Sphere
from tests.conftest import random_configurations


def _box_at_distance(robot: genplan.Robot, q, distance: float) -> genplan.CollisionWorld:
    """A world (no self-collision) with one box beside the arm at ``q``, moved along y until its
    distance to the robot is ``distance`` (bisection on min_distance, to 1e-7 m)."""
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        w = robot.collision_world(self_collision=False)
        w.add_box("box", (0.05, 0.05, 0.3), (0.3, 0.2 + mid, 0.4))
        if w.min_distance(q) < distance:
            lo = mid
        else:
            hi = mid
    w = robot.collision_world(self_collision=False)
    w.add_box("box", (0.05, 0.05, 0.3), (0.3, 0.2 + hi, 0.4))
    assert w.min_distance(q) == pytest.approx(distance, abs=1e-6)
    return w


def test_two_centimetres_refuse_a_state_one_centimetre_away_and_accept_one_at_three(panda: genplan.Robot) -> None:
    q = panda.q_default
    near, far = _box_at_distance(panda, q, 0.01), _box_at_distance(panda, q, 0.03)
    assert not near.in_collision(q) and not far.in_collision(q)
    for w in (near, far):
        w.padding = 0.02
    assert near.in_collision(q) and not far.in_collision(q)
    assert near.min_distance(q) == pytest.approx(0.01, abs=1e-6)  # distances stay geometric
    # an obstacle's own padding replaces the world's, either way
    near.set_obstacle_padding("box", 0.0)
    assert not near.in_collision(q)
    near.padding = 0.0
    near.set_obstacle_padding("box", 0.02)
    assert near.in_collision(q) and near.obstacle_paddings == {"box": 0.02}
    near.set_obstacle_padding("box", None)
    assert not near.in_collision(q)


def test_padded_checks_are_distances_below_the_margin(panda: genplan.Robot) -> None:
    """On random configurations, with spheres and boxes and a floor: in collision exactly when the
    obstacle distance is at most the obstacle's padding (to 1e-6 m)."""
    world = panda.collision_world(self_collision=False)
    world.add_box("box", (0.1, 0.1, 0.1), (0.5, 0.0, 0.3))
    world.add_sphere("ball", 0.08, (0.0, 0.5, 0.5))
    world.add_halfspace("floor", (0, 0, 1), -0.3)
    world.padding = 0.05
    world.set_obstacle_padding("ball", 0.1)
    qs = random_configurations(panda, 2000, seed=8)
    hit = world.in_collision(qs)
    d = {}
    for name in ("box", "ball", "floor"):
        single = panda.collision_world(self_collision=False)
        if name == "box":
            single.add_box("box", (0.1, 0.1, 0.1), (0.5, 0.0, 0.3))
        elif name == "ball":
            single.add_sphere("ball", 0.08, (0.0, 0.5, 0.5))
        else:
            single.add_halfspace("floor", (0, 0, 1), -0.3)
        d[name] = single.min_distance(qs)
    slack = np.minimum.reduce([d["box"] - 0.05, d["ball"] - 0.1, d["floor"] - 0.05])
    decided = np.abs(slack) > 1e-6
    assert 0.1 < hit.mean() < 0.9
    np.testing.assert_array_equal(hit[decided], slack[decided] <= 0)
    # one check or a batch: the same answers
    assert [world.in_collision(q) for q in qs[:50]] == hit[:50].tolist()


def test_an_attached_object_keeps_the_padding(panda: genplan.Robot) -> None:
    held = panda.with_attached("rod", Box("rod", (0.015, 0.015, 0.1)), "panda_hand", Pose(position=(0, 0, 0.25)))
    q = panda.q_default
    hand = held.link_poses(q, ["panda_hand"])[0]
    tip = hand[:3, :3] @ np.array([0.0, 0.0, 0.35]) + hand[:3, 3]
    world = held.collision_world(self_collision=False)
    world.add_sphere("ball", 0.05, tip + hand[:3, 2] * 0.065)  # 1.5 cm beyond the rod's end
    assert world.close_pairs(q, 0.02)[0][:2] == ("rod", "ball")
    assert not world.in_collision(q)
    world.padding = 0.02
    assert world.in_collision(q)
    # the robot without the rod is clear of the ball by far more
    bare = panda.collision_world(self_collision=False)
    bare.add_sphere("ball", 0.05, tip + hand[:3, 2] * 0.065)
    bare.padding = 0.02
    assert not bare.in_collision(q)


@pytest.mark.parametrize("edge_check", ["sampled", "certified"])
def test_a_padded_plan_keeps_every_trajectory_sample_two_centimetres_away(panda: genplan.Robot, edge_check: str) -> None:
    scene = Scene("wall", obstacles=(Box("wall", (0.05, 0.3, 0.25), Pose(position=(0.45, 0.0, 0.3)), padding=0.02),))
    world = panda.collision_world()
    world.add_scene(scene)
    start = np.array([-1.2, 0.3, 0.0, -1.8, 0.0, 2.0, 0.8])
    goal = np.array([1.2, 0.3, 0.0, -1.8, 0.0, 2.0, 0.8])
    planner = Planner(panda, world=world, task="free", seed=1, settings=PlannerSettings(edge_check=edge_check))
    line = start + np.linspace(0, 1, 200)[:, None] * (goal - start)
    geometric = panda.collision_world(self_collision=False)
    geometric.add_scene(Scene("wall", obstacles=(Box("wall", (0.05, 0.3, 0.25), Pose(position=(0.45, 0.0, 0.3))),)))
    assert geometric.min_distance(line).min() < 0  # the straight motion goes through the wall
    result = planner.plan(start, goal)
    assert result.success
    traj = result.trajectory()
    d = geometric.min_distance(traj.q)
    assert d.min() >= 0.02 - 1e-9, d.min()


def test_a_scene_files_padding_reaches_the_world(tmp_path) -> None:
    path = tmp_path / "s.toml"
    Scene("s", obstacles=(Sphere("ball", 0.1, Pose(position=(1, 0, 0)), padding=0.03),
                          Box("box", (0.1, 0.1, 0.1), Pose(position=(0, 1, 0))))).to_file(path)
    assert "padding = 0.03" in path.read_text()
    scene = Scene.from_file(path)
    assert scene.obstacles[0].padding == 0.03 or scene.obstacles[1].padding == 0.03
    world = genplan.load("panda").collision_world()
    world.add_scene(scene)
    assert world.obstacle_paddings == {"ball": 0.03, "box": None}


def test_bad_margins_are_typed_errors_naming_the_field(panda: genplan.Robot, tmp_path) -> None:
    world = panda.collision_world()
    world.add_box("box", (0.1, 0.1, 0.1), (1, 0, 0))
    for bad in (-0.01, float("nan"), float("inf"), 11.0):
        with pytest.raises(GenplanError, match="padding"):
            world.padding = bad
        with pytest.raises(GenplanError, match="obstacle 'box' padding"):
            world.set_obstacle_padding("box", bad)
    assert world.padding == 0.0 and world.obstacle_paddings == {"box": None}
    with pytest.raises(genplan.errors.UnknownNameError, match="crate.*known: box"):
        world.set_obstacle_padding("crate", 0.01)
    with pytest.raises(SceneFileError, match="box 'b'.*padding"):
        Box("b", (0.1, 0.1, 0.1), padding=-0.02)
    path = tmp_path / "bad.toml"
    path.write_text('name = "bad"\n[[box]]\nname = "b"\nsize = [0.1, 0.1, 0.1]\nposition = [1, 0, 0]\npadding = -1\n')
    with pytest.raises(SceneFileError, match=r"bad.toml.*\[\[box\]\] 1.*padding"):
        Scene.from_file(path)


def test_the_sphere_checker_keeps_the_paddings(panda: genplan.Robot) -> None:
    """The sphere checker grows its spheres by each obstacle's padding (its own, else the
    world's), as the exact check counts a pair closer than the padding: it stays conservative
    (every configuration the exact padded check finds colliding is colliding by the spheres), and
    a configuration whose robot passes 1-2 cm from the box is free without padding and colliding
    with a 3 cm one, by both checkers."""
    world = panda.collision_world()
    world.add_box("box", (0.1, 0.1, 0.1), (0.45, 0.0, 0.45))
    world.add_sphere("ball", 0.05, (0.0, 0.5, 0.5))
    q = panda.random_configurations(3000, 7)
    # configurations 1-2 cm from the box, 5 cm from the ball and free of self-collision
    only_box = panda.collision_world(self_collision=False)
    only_box.add_box("box", (0.1, 0.1, 0.1), (0.45, 0.0, 0.45))
    only_ball = panda.collision_world(self_collision=False)
    only_ball.add_sphere("ball", 0.05, (0.0, 0.5, 0.5))
    d_box = np.asarray(only_box.min_distance(q)).reshape(-1)
    d_ball = np.asarray(only_ball.min_distance(q)).reshape(-1)
    plain = genplan.planning.sphere_checker(panda, world)
    near = q[(d_box > 0.01) & (d_box < 0.02) & (d_ball > 0.05) & ~np.asarray(plain.in_collision(q))]
    assert len(near) >= 5
    world.set_obstacle_padding("box", 0.03)
    world.padding = 0.005
    padded = genplan.planning.sphere_checker(panda, world)
    exact = np.asarray(world.in_collision(q))
    spheres = np.asarray(padded.in_collision(q))
    assert exact.any() and not (exact & ~spheres).any()
    assert np.asarray(world.in_collision(near)).all() and np.asarray(padded.in_collision(near)).all()
    # the world's padding alone (the box's own set to 0): conservative still, and the ball's
    # near misses (0-5 mm) collide by both
    world.set_obstacle_padding("box", 0.0)
    checker = genplan.planning.sphere_checker(panda, world)
    exact = np.asarray(world.in_collision(q))
    assert not (exact & ~np.asarray(checker.in_collision(q))).any()
    grazing = q[(d_ball > 0.0) & (d_ball < 0.005)]
    assert len(grazing) and np.asarray(world.in_collision(grazing)).all() and np.asarray(checker.in_collision(grazing)).all()


def test_a_clouds_own_padding_survives_a_new_frame(panda: genplan.Robot) -> None:
    """replace_points keeps the cloud's padding (as its radius and voxel): after a new frame, a
    state 0.5-1.5 cm from the cloud is a collision with the cloud's 2 cm padding, and free without it."""
    w = panda.collision_world(self_collision=False)
    w.add_points("cloud", np.array([[2.0, 0.0, 0.4], [2.0, 0.1, 0.4]]), radius=0.005)
    w.set_obstacle_padding("cloud", 0.02)
    q = panda.q_default
    hand = panda.frame_positions(q[None], "hand")[0]
    for dz in np.linspace(0.0, 0.3, 601):  # a point above the hand, raised until it is 0.5-1.5 cm away
        w.replace_points("cloud", (hand + [0.0, 0.0, dz])[None])
        d = float(np.asarray(w.min_distance(q)).reshape(-1)[0])
        if 0.005 < d < 0.015:
            break
    else:
        pytest.fail("no point above the hand 0.5-1.5 cm from the robot")
    assert w.obstacle_paddings["cloud"] == 0.02
    assert bool(np.asarray(w.in_collision(q)).reshape(-1)[0])
    w.set_obstacle_padding("cloud", 0.0)
    assert not bool(np.asarray(w.in_collision(q)).reshape(-1)[0])
