"""genplan.planning.queries.make_query and genplan.planning.plan: queries and plans for any robot, task and
scene (the xArm7 of examples/xarm7, not a preset), and ``genplan plan`` (genplan/cli/plan.py)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

import genplan
from genplan import projection as P
from genplan.cli import main
from genplan.errors import InvalidGoalError, InvalidStartError, ModelFileError, SettingsError, UnknownNameError
from genplan.samplers.costs import manifold_task
from genplan.planning import make_query, plan

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "xarm7"
ROBOT, TASK, SCENE = EXAMPLES / "xarm7.toml", EXAMPLES / "upright_cup.toml", EXAMPLES / "table_box.toml"
MODEL = EXAMPLES / "upright_cup_gan.safetensors"


@pytest.fixture(scope="module")
def arm() -> genplan.Robot:
    return genplan.load(ROBOT)


@pytest.fixture(scope="module")
def cup(arm: genplan.Robot) -> P.Task:
    return P.load_task(TASK, arm)


def _upright(arm: genplan.Robot, q: np.ndarray) -> np.ndarray:
    """The tool's z axis in the world, per row (the task wants it straight down)."""
    return arm.link_poses(q.reshape(-1, arm.nq), ["link_eef"])[:, 0, :3, 2]


@pytest.mark.parametrize("sampler,algorithm", [("uniform", "crrt"), ("gan", "crrt"), ("hybrid", "crrt"),
                                               ("gan", "rrt_connect")])
def test_plan_keeps_the_cup_upright_around_the_box(sampler: str, algorithm: str, arm: genplan.Robot, cup: P.Task) -> None:
    out = plan(arm, cup, scene=SCENE, start="default", target=(0.45, -0.3, 0.25), sampler=sampler, model=MODEL, seed=0,
               algorithm=algorithm)
    r = out.result
    assert r.success
    # every state: the constraint (tool z down within the planner's tolerance), collision-free
    z = _upright(arm, r.path)
    assert np.abs(z - [0, 0, -1]).max() < 2e-3
    assert not np.asarray(out.world.in_collision(r.path)).any()
    assert set(out.world.obstacle_names) >= {"table", "box"}
    # it ends at an IK goal for the target
    tool = arm.link_poses(r.path[-1:], ["link_eef"])[0, 0, :3, 3]
    assert np.linalg.norm(tool - [0.45, -0.3, 0.25]) < 2e-3
    assert np.allclose(r.path[-1], out.query.goals[r.goal_index])
    data = out.to_dict()
    assert data["task"] == "upright_cup" and data["manifold"] == "upright_cup" and data["success"]
    assert data["algorithm"] == algorithm
    json.dumps(data)  # JSON-able


def test_plan_with_the_tasks_data_needs_no_model(arm: genplan.Robot, cup: P.Task, tmp_path, capsys) -> None:
    """sampler="data": rows of this task's data set (not the robot's shipped task's: the xArm7 has
    none), no model; a model given with it is refused."""
    out = plan(arm, cup, scene=SCENE, start="default", target=(0.45, -0.3, 0.25), sampler="data", seed=0)
    assert out.result.success and out.to_dict()["sampler"] == "data"
    assert np.abs(_upright(arm, out.result.path) - [0, 0, -1]).max() < 2e-3
    assert not np.asarray(out.world.in_collision(out.result.path)).any()
    from genplan.planning import data_sampler

    drawn = data_sampler(arm, task=cup, seed=1).sample(200)  # the rows are on the cup task's manifold
    assert np.abs(_upright(arm, drawn) - [0, 0, -1]).max() < 1e-2
    with pytest.raises(SettingsError, match="sampler 'data' .* takes no model"):
        plan(arm, cup, target=(0.45, -0.3, 0.25), sampler="data", model=MODEL)
    js = tmp_path / "plan.json"
    assert main(["plan", "--robot", str(ROBOT), "--task", str(TASK), "--scene", str(SCENE), "--target", "0.45", "-0.3",
                 "0.25", "--sampler", "data", "--out", str(js)]) == 0
    d = json.loads(js.read_text())
    assert d["success"] and "data sampler" in capsys.readouterr().out
    # a task's manifold keeps the constrained planner's defaults (FREE_SPACE_SETTINGS are free space's)
    assert d["algorithm"] == "crrt" and d["stats"]["simplify_s"] == 0.0


def test_queries_start_on_the_manifold_and_goals_by_ik(arm: genplan.Robot, cup: P.Task) -> None:
    world = arm.collision_world()
    world.add_scene(SCENE)
    q = make_query(arm, cup, world, "default", target=(0.4, 0.2, 0.3), k=4, seed=1)
    assert q.goals.shape == (4, 7)
    assert np.abs(_upright(arm, np.vstack([q.start, q.goals])) - [0, 0, -1]).max() < 2e-3
    assert not np.asarray(world.in_collision(np.vstack([q.start, q.goals]))).any()
    again = make_query(arm, cup, world, q.start, goal=q.goals[0])  # configurations on the manifold: kept
    assert np.allclose(again.start, q.start, atol=1e-9) and np.allclose(again.goals[0], q.goals[0], atol=1e-9)


def test_a_start_by_ik_for_a_target(arm: genplan.Robot, cup: P.Task, tmp_path, capsys) -> None:
    """start_target (genplan plan --start-target): the start is a collision-free IK solution on the
    manifold reaching that target, as the goals are for target; refused with a start, or when none
    is found, naming start_target; a colliding start's error says how to give one."""
    world = arm.collision_world()
    world.add_scene(SCENE)
    q = make_query(arm, cup, world, start_target=(0.3, -0.2, 0.3), target=(0.4, 0.2, 0.3), k=2, seed=3)
    reached = arm.frame_positions(q.start, "link_eef")
    assert np.abs(reached - [0.3, -0.2, 0.3]).max() < 1e-3 and np.allclose(q.start_target, [0.3, -0.2, 0.3])
    assert np.abs(_upright(arm, q.start) - [0, 0, -1]).max() < 2e-3 and not bool(world.in_collision(q.start))
    again = make_query(arm, cup, world, start_target=(0.3, -0.2, 0.3), target=(0.4, 0.2, 0.3), k=2, seed=3)
    np.testing.assert_array_equal(again.start, q.start)
    with pytest.raises(SettingsError, match="start_target"):
        make_query(arm, cup, world, q.start, start_target=(0.3, -0.2, 0.3), target=(0.4, 0.2, 0.3))
    with pytest.raises(InvalidStartError, match="start_target .*no collision-free IK solution"):
        make_query(arm, cup, world, start_target=(3.0, 0.0, 0.3), target=(0.4, 0.2, 0.3), max_tries=64)
    in_box = make_query(arm, cup, arm.collision_world(), "default", target=(0.38, -0.12, 0.2), k=1).goals[0]
    with pytest.raises(InvalidStartError, match="start: in collision.*start_target="):
        make_query(arm, cup, world, in_box, target=(0.4, 0.2, 0.3))
    out, traj = tmp_path / "plan.json", tmp_path / "plan.npz"
    assert main(["plan", "--robot", str(ROBOT), "--task", str(TASK), "--scene", str(SCENE), "--start-target", "0.3", "-0.2",
                 "0.3", "--target", "0.4", "0.2", "0.3", "--seed", "3", "--out", str(out), "--trajectory", str(traj)]) == 0
    data = json.loads(out.read_text())
    assert data["success"] and np.allclose(data["start"], q.start) and traj.is_file()
    assert main(["plan", "--robot", str(ROBOT), "--start", "0 0 0 0 0 0 0", "--start-target", "0.3", "0", "0.3", "--target", "0.4",
                 "0", "0.3", "--out", str(out)]) == 2
    assert "not allowed with argument --start" in capsys.readouterr().err
    assert main(["plan", "--robot", str(ROBOT), "--start-target", "0.3", "0", "--target", "0.4", "0", "0.3",
                 "--out", str(out)]) == 2
    assert "argument --start-target: expected 3 numbers" in capsys.readouterr().err


def test_bad_queries_are_refused_naming_the_argument(arm: genplan.Robot, cup: P.Task) -> None:
    world = arm.collision_world()
    world.add_scene(SCENE)
    with pytest.raises(SettingsError, match="not both or neither"):
        make_query(arm, cup, world, "default")
    with pytest.raises(InvalidStartError, match="start: expected 'default' or a configuration"):
        make_query(arm, cup, world, "home", target=(0.4, 0, 0.3))
    with pytest.raises(InvalidGoalError, match=r"target: rows \[0\] are not finite"):
        make_query(arm, cup, world, "default", target=(0.4, np.nan, 0.3))
    with pytest.raises(InvalidGoalError, match="no collision-free IK solution"):
        make_query(arm, cup, world, "default", target=(3.0, 0.0, 0.3), max_tries=64)
    in_box = make_query(arm, cup, arm.collision_world(), "default", target=(0.38, -0.12, 0.2), k=1).goals[0]
    with pytest.raises(InvalidGoalError, match="goal: in collision"):
        make_query(arm, cup, world, "default", goal=in_box)


def test_a_model_for_another_robot_or_task_is_refused(arm: genplan.Robot, cup: P.Task) -> None:
    with pytest.raises(SettingsError, match="sampler 'gan' needs a model"):
        plan(arm, cup, target=(0.4, 0, 0.3), sampler="gan")
    with pytest.raises(ModelFileError, match="GAN for robot 'panda', not 'xarm7'"):
        plan(arm, cup, target=(0.4, 0, 0.3), sampler="gan", model=genplan.samplers.base.models_dir() / "panda_gan.safetensors")
    with pytest.raises(ModelFileError, match="GAN for robot 'xarm7', not 'panda'"):
        plan("panda", "panda_ik", target=(0.5, 0, 0.5), sampler="hybrid", model=MODEL)


def test_plan_on_a_shipped_robot_and_task() -> None:
    from genplan.planning import environment

    panda = genplan.load("panda")
    start = environment("panda_shelf").queries(panda, n=1, seed=0)[0].start  # the default collides on the manifold
    out = plan(panda, "panda_ik", scene="panda_shelf", start=start, target=(0.5, -0.25, 0.3), k=3, seed=2)
    assert out.result.success
    assert out.manifold.to_dict() == P.paper_task(out.robot, "projection").to_dict()
    assert out.trail_frame == "hand"


def test_plan_command_writes_json_and_html(tmp_path, capsys) -> None:
    js, page = tmp_path / "plan.json", tmp_path / "plan.html"
    argv = ["plan", "--robot", str(ROBOT), "--task", str(TASK), "--scene", str(SCENE), "--start", "default",
            "--target", "0.45", "-0.3", "0.25", "--sampler", "hybrid", "--model", str(MODEL), "--out", str(js),
            "--algorithm", "rrt_connect"]
    viewer = importlib.util.find_spec("viser") is not None  # the HTML view is an extra
    if viewer:
        argv += ["--html", str(page)]
    assert main(argv) == 0
    data = json.loads(js.read_text())
    assert data["success"] and data["sampler"] == "hybrid" and data["algorithm"] == "rrt_connect" and len(data["path"]) > 2
    assert not viewer or page.stat().st_size > 100_000
    assert "found:" in (text := capsys.readouterr().out) and "(rrt_connect, hybrid sampler, sampled edges)" in text
    # certified edges: the same query, every motion between the path's states certified
    assert main(argv[:-2] + ["--edge-check", "certified"] if viewer else argv + ["--edge-check", "certified"]) == 0
    data = json.loads(js.read_text())
    assert data["success"] and data["stats"]["motion_certificates"] > 0
    assert "sampler, certified edges)" in capsys.readouterr().out


def test_plan_command_errors_are_one_line(tmp_path, capsys) -> None:
    out = tmp_path / "p.json"
    assert main(["plan", "--robot", str(ROBOT), "--task", str(TASK), "--out", str(out)]) == 2  # no goal
    assert "one of the arguments --goal --target is required" in capsys.readouterr().err
    assert main(["plan", "--robot", str(ROBOT), "--task", "nope", "--target", "0.4", "0", "0.3", "--out", str(out)]) == 2
    assert "unknown task 'nope'" in capsys.readouterr().err
    assert main(["plan", "--robot", str(ROBOT), "--task", str(TASK), "--start", "1 2", "--target", "0.4", "0", "0.3",
                 "--out", str(out)]) == 2
    assert "start" in capsys.readouterr().err
    with pytest.raises(UnknownNameError, match="unknown algorithm 'prm' \\(known: crrt, rrt_connect\\)"):
        plan(ROBOT, TASK, target=(0.4, 0, 0.3), algorithm="prm")
    assert not out.exists()


def test_manifold_task_of_the_example(arm: genplan.Robot, cup: P.Task) -> None:
    assert [t.name for t in manifold_task(cup, arm).primary] == ["cup_upright", "joint_limits"]


def test_genplan_planning_problem_is_a_deprecated_alias() -> None:
    """make_query lives in genplan.planning.queries, Outcome in genplan.planning (both exported by
    genplan.planning); the old module forwards them for one release, with a DeprecationWarning."""
    import genplan.planning as planning
    import genplan.planning.problem as problem

    with pytest.warns(DeprecationWarning, match="genplan.planning.problem.make_query is deprecated"):
        assert problem.make_query is planning.make_query is planning.queries.make_query
    with pytest.warns(DeprecationWarning, match="genplan.planning.problem.Outcome is deprecated"):
        assert problem.Outcome is planning.Outcome
