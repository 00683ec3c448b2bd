"""genplan.planning.environments: the paper's four environments read from their scene files
(python/genplan/presets/scenes/*.toml) are the environments the code defined before the files
existed: the same obstacles, the same query definitions, the same collision answers."""

from __future__ import annotations

import numpy as np
import pytest

import genplan
from genplan import scene as S
from genplan.errors import SceneFileError, UnknownNameError
from genplan.planning import ENVIRONMENT_NAMES, environment
from genplan.planning.environments import Environment

# The obstacles and queries as python/genplan/planning/environments.py defined them in code
# before the scene files: (name, half extents, centre) per box, (name, normal, offset) per plane.
_BOARDS = [(f"shelf_board_{i}", (0.375, 0.2, 0.01), (-0.215, 0.8, z))
           for i, z in enumerate((-0.3675, -0.0075, 0.3425, 0.6925, 1.0425))]
_PANELS = [(f"shelf_side_{i}", (0.01, 0.2, 0.7), (x, 0.8, 0.3325)) for i, x in enumerate((-0.58, 0.15))]
BEFORE = {
    "panda_shelf": dict(
        robot="panda",
        boxes=[("table_top", (0.5, 0.75, 0.025), (0.7, 0.0, 0.1)), *_BOARDS, *_PANELS],
        halfspaces=[("floor", (0.0, 0.0, 1.0), -0.5)],
        start_targets=tuple((x, y, 0.2) for x in (0.5, 0.7) for y in (-0.25, 0.25)),
        goal_targets=tuple((x, 0.65, z) for x in (-0.4, -0.02) for z in (0.2, 0.54)),
        start_box=None, goal_box=None, start_yaw=0.0, goal_yaw=np.pi / 2,
        description="Panda, gripper horizontal: from above the table into the bookshelf (Table II, Fig. 5a)",
    ),
    "talos_task1": dict(
        robot="talos",
        boxes=[("table", (0.25, 0.4, 0.03), (0.7, 0.0, 0.95))],
        halfspaces=[],
        start_targets=(), goal_targets=(),
        start_box=((0.55, -0.25, 1.1), (0.85, 0.25, 1.3)),
        goal_box=((0.55, -0.25, 0.4), (0.85, 0.25, 0.8)),
        start_yaw=0.0, goal_yaw=0.0,
        description="Talos, feet fixed, static stability: the right hand from above a table to below it (Fig. 5b)",
    ),
    "talos_task2": dict(
        robot="talos",
        boxes=[("table", (0.25, 0.4, 0.03), (0.55, 0.0, 0.8)), ("wall", (0.03, 0.4, 0.12), (0.33, 0.0, 0.95))],
        halfspaces=[],
        start_targets=(), goal_targets=(),
        start_box=((0.3, -0.25, 1.0), (0.7, 0.25, 1.3)),
        goal_box=((0.3, -0.25, 0.4), (0.7, 0.25, 0.8)),
        start_yaw=0.0, goal_yaw=0.0,
        description="Talos: a lower table with a low wall at its near edge (Fig. 5c)",
    ),
    "talos_task3": dict(
        robot="talos",
        boxes=[
            ("table", (0.25, 0.4, 0.03), (0.7, 0.0, 0.75)),
            ("bar", (0.03, 0.4, 0.03), (0.5, 0.0, 1.22)),
            ("post_left", (0.03, 0.03, 0.25), (0.5, 0.3, 1.0)),
            ("post_right", (0.03, 0.03, 0.25), (0.5, -0.3, 1.0)),
            ("leg_front_left", (0.03, 0.03, 0.35), (0.5, 0.3, 0.4)),
            ("leg_front_right", (0.03, 0.03, 0.35), (0.5, -0.3, 0.4)),
            ("leg_rear_left", (0.03, 0.03, 0.35), (0.9, 0.3, 0.4)),
            ("leg_rear_right", (0.03, 0.03, 0.35), (0.9, -0.3, 0.4)),
        ],
        halfspaces=[],
        start_targets=(), goal_targets=(),
        start_box=((0.55, -0.2, 0.8), (0.7, 0.2, 1.1)),
        goal_box=((0.55, -0.2, 0.4), (0.7, 0.2, 0.6)),
        start_yaw=0.0, goal_yaw=0.0,
        description="Talos: a table under a frame (bar on posts): reach from inside the frame to under the table (Fig. 5d)",
    ),
}


def test_every_environment_is_a_shipped_scene_file() -> None:
    assert ENVIRONMENT_NAMES == tuple(BEFORE)
    assert set(ENVIRONMENT_NAMES) <= set(S.scene_names())
    for name in ENVIRONMENT_NAMES:
        assert (S.SCENES_DIR / f"{name}.toml").is_file()
        # the scene part of the file is an ordinary scene (its [queries] table is ignored)
        assert S.load_scene(name) == environment(name).scene


@pytest.mark.parametrize("name", list(BEFORE))
def test_obstacles_and_queries_are_the_ones_defined_before(name: str) -> None:
    before, env = BEFORE[name], environment(name)
    assert env.name == name and env.robot == before["robot"]
    assert [(b.name, b.half_extents, b.center) for b in env.boxes] == before["boxes"]
    assert list(env.halfspaces) == before["halfspaces"]
    assert all(not o.pose.rotated for o in env.scene.obstacles if isinstance(o, S.Box))
    assert len(env.scene.obstacles) == len(before["boxes"]) + len(before["halfspaces"])
    for key in ("start_targets", "goal_targets", "start_box", "goal_box", "start_yaw", "goal_yaw", "description"):
        assert getattr(env, key) == before[key], key


@pytest.mark.parametrize("name", list(BEFORE))
def test_the_file_world_answers_as_the_world_built_before(name: str, panda: genplan.Robot,
                                                         talos: genplan.Robot) -> None:
    """The world from the scene file and the world built the old way (add_box / add_halfspace from
    the literal list) give bit-identical answers on random configurations, obstacles only and
    with self-collision."""
    robot = {"panda": panda, "talos": talos}[BEFORE[name]["robot"]]
    env = environment(name)
    for self_collision in (False, True):
        new = env.world(robot, self_collision=self_collision)
        old = robot.collision_world(self_collision=self_collision)
        for n, h, c in BEFORE[name]["boxes"]:
            old.add_box(n, half_extents=h, center=c)
        for n, normal, offset in BEFORE[name]["halfspaces"]:
            old.add_halfspace(n, normal, offset)
        assert new.obstacle_names == old.obstacle_names
        qs = robot.random_configurations(400, np.random.default_rng(7))
        hits = np.asarray(new.in_collision(qs))
        assert np.array_equal(hits, old.in_collision(qs))
        assert np.array_equal(new.min_distance(qs), old.min_distance(qs))
        if not self_collision:
            # the sample reaches the obstacles and misses them: the comparison is not vacuous
            assert 0 < hits.sum() < len(hits), hits.sum()


def test_environment_files_and_their_errors(tmp_path, panda: genplan.Robot) -> None:
    # a scene file of one's own with a [queries] table is an environment
    text = (S.SCENES_DIR / "panda_shelf.toml").read_text().replace('name = "panda_shelf"', 'name = "mine"')
    (tmp_path / "mine.toml").write_text(text)
    env = environment(tmp_path / "mine.toml")
    assert isinstance(env, Environment) and env.name == "mine"
    assert env.scene.obstacles == environment("panda_shelf").scene.obstacles
    assert env.world(panda).obstacle_names == environment("panda_shelf").world(panda).obstacle_names

    with pytest.raises(UnknownNameError, match="known: panda_shelf"):
        environment("kitchen")
    (tmp_path / "plain.toml").write_text('name = "plain"\n[[sphere]]\nname = "s"\nradius = 0.1\nposition = [1, 0, 0]\n')
    with pytest.raises(SceneFileError, match=r"plain.toml: missing table \[queries\]"):
        environment(tmp_path / "plain.toml")
    cases = {
        "robot = 'panda'\nstart_targets = [[0, 0, 0]]\ngoal_box = [[0, 0, 0], [1, 1, 1]]\ncolour = 1":
            r"\[queries\]: unknown key 'colour' \(known: robot, ",
        "start_targets = [[0, 0, 0]]\ngoal_targets = [[0, 0, 0]]": r"\[queries\]: robot: expected",
        "robot = 'panda'\nstart_targets = [[0, 0, 0]]\nstart_box = [[0, 0, 0], [1, 1, 1]]\ngoal_targets = [[0, 0, 0]]":
            "exactly one of start_targets and start_box",
        "robot = 'panda'\nstart_targets = [[0, 0]]\ngoal_targets = [[0, 0, 0]]": r"start_targets\[0\]: expected 3 numbers",
        "robot = 'panda'\nstart_targets = [[0, 0, 0]]\ngoal_box = [[1, 0, 0], [0, 1, 1]]": "goal_box: low must not exceed high",
        "robot = 'panda'\nyaw_term = 'hand_orientation'\nstart_targets = [[0, 0, 0]]\ngoal_targets = [[0, 0, 0]]\ngoal_yaw = nan":
            "goal_yaw: must be finite",
        "robot = 'panda'\nstart_targets = [[0, 0, 0]]\ngoal_targets = [[0, 0, 0]]\ngoal_yaw = 1.0":
            "start_yaw / goal_yaw need yaw_term",
        "robot = 'panda'\ntask = 3\nstart_targets = [[0, 0, 0]]\ngoal_targets = [[0, 0, 0]]": "task: expected a name",
    }
    for body, match in cases.items():
        (tmp_path / "bad.toml").write_text(f'name = "bad"\n[queries]\n{body}\n')
        with pytest.raises(SceneFileError, match=match):
            environment(tmp_path / "bad.toml")


def test_query_ik_tasks_as_data_are_the_code_they_replaced() -> None:
    """The Panda shelf's query IK (hand position, full orientation at a yaw, joint limits; the
    authors' code, a Python task before presets/tasks/panda_query_ik.toml) and the manifold the
    queries are projected on: the same native terms, so the same seeded queries."""
    import pinocchio as pin

    from genplan import projection as P
    from genplan.planning.queries import _ik_task

    panda = genplan.load("panda")
    env = environment("panda_shelf")
    for yaw in (0.0, np.pi / 2):
        before = P.Task(primary=[
            P.FramePosition(name="hand_position", frame="hand", target=(0.5, 0.0, 0.5), weight=50, tolerance=1e-3),
            P.FrameOrientation(name="hand_orientation", frame="hand", axes=(1, 1, 1), offset=P.PANDA_HAND_OFFSET,
                               target=pin.utils.rotate("z", yaw), weight=30, tolerance=1e-3),
            P.JointLimits(name="joint_limits", weight=30, tolerance=1e-3)], secondary=[P.Posture(name="posture")])
        now = _ik_task(panda, env, yaw)
        assert repr([t.to_native(panda) for t in [*now.primary, *now.secondary]]) == \
            repr([t.to_native(panda) for t in [*before.primary, *before.secondary]])
    assert P.manifold_task(now, panda).to_dict() == P.paper_task(panda, "projection").to_dict()
    talos = genplan.load("talos")
    ik = _ik_task(talos, environment("talos_task2"), 0.0)
    assert ik.to_dict() == P.paper_task(talos, "ik").to_dict()
    assert P.manifold_task(ik, talos).to_dict() == P.paper_task(talos, "projection").to_dict()
