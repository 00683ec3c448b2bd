"""Python terms first-class (genplan.projection.task's ``kind = "python"``, genplan._entries): a
task holding a CustomTerm importable by its entry is written to a task file and a model card as
``entry = "module:Class"`` + params, read back only with ``allow_python=True`` (the commands'
``--allow-python``), generates its data in worker processes that import the term, trains a GAN
whose card loads again; a term that cannot be rebuilt elsewhere is refused with the reason."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import numpy as np
import pytest

import genplan
from genplan import projection as P
from genplan.cli import main
from genplan.errors import TaskFileError
from genplan.executor import LocalExecutor
from tests.custom_terms_example import OnCircle

ENTRY = "tests.custom_terms_example:OnCircle"


def _task(robot: genplan.Robot, term: P.Term | None = None) -> P.Task:
    """The Panda's hand position as the condition, the wrist on a circle (a python term)."""
    term = OnCircle(robot=robot, weight=30, tolerance=1e-3, name="wrist") if term is None else term
    return P.Task(primary=[P.FramePosition(frame="hand", target=None, weight=50, name="hand_position"), term,
                           P.JointLimits(weight=30, name="joint_limits")],
                  secondary=[P.Posture(name="posture")], name="panda_wrist_on_circle",
                  condition=P.Condition("hand_position", (0.3, -0.4, 0.3), (0.6, 0.4, 0.7)))


def test_a_python_term_is_written_by_its_entry_and_read_back_with_the_opt_in(tmp_path, panda: genplan.Robot) -> None:
    task = _task(panda, OnCircle(robot=panda, center=(0.0, 0.0, 0.55), radius=0.35, weight=30, tolerance=1e-3,
                                 name="wrist"))
    entry = task.to_dict()["primary"][1]
    assert entry == {"kind": "python", "entry": ENTRY, "params": {"frame": "panda_link6", "center": [0.0, 0.0, 0.55],
                                                                   "radius": 0.35},
                     "weight": 30, "tolerance": 1e-3, "name": "wrist"}
    path = task.to_file(tmp_path / "task.toml")
    again = P.Task.from_file(path, panda, allow_python=True)
    assert again.primary[1] == task.primary[1] and again.primary[1].robot is panda
    assert again.to_dict() == task.to_dict() and again.python_terms == (again.primary[1],)
    assert P.load_task(str(path), panda, allow_python=True).to_dict() == task.to_dict()
    # the term solves as the one it was written from
    q0 = panda.random_configurations(3, rng=1)
    a = P.GaussNewtonProjector(panda, P.manifold_task(task, panda)).solve_batch(q0, parallel=False)
    b = P.GaussNewtonProjector(panda, P.manifold_task(again, panda)).solve_batch(q0, parallel=False)
    assert a.success.any() and np.array_equal(a.q, b.q) and np.array_equal(a.success, b.success)


def test_a_task_file_with_a_python_term_is_refused_without_the_opt_in_before_any_import(tmp_path,
                                                                                        panda: genplan.Robot) -> None:
    path = tmp_path / "trap.toml"
    # the module does not exist: an import attempt would say "cannot import"; the refusal comes first
    path.write_text('name = "t"\n[[primary]]\nkind = "JointLimits"\n\n[[primary]]\nkind = "python"\n'
                    'entry = "no_such_module_anywhere:Term"\n')
    for read in (lambda: P.Task.from_file(path, panda), lambda: P.load_task(str(path), panda)):
        with pytest.raises(TaskFileError) as info:
            read()
        text = str(info.value)
        assert f"task file {path}: [[primary]] 2" in text and "'no_such_module_anywhere:Term'" in text
        assert "allow_python=True" in text and "--allow-python" in text
    with pytest.raises(TaskFileError, match="cannot import 'no_such_module_anywhere:Term'"):
        P.Task.from_file(path, panda, allow_python=True)


@pytest.mark.parametrize("row, message", [
    ({"entry": "genplan.projection:FramePose"}, r"is <class .*FramePose'>, not a genplan.projection.CustomTerm subclass"),
    ({"entry": "OnCircle"}, r"entry must be 'module:Class', got 'OnCircle'"),
    ({"entry": ENTRY, "params": {"radius": 0.2, "spokes": 3}}, r"unexpected keyword argument 'spokes'"),
    ({"entry": ENTRY, "params": {"weight": 2.0}}, r"params may not hold weight"),
    ({"entry": ENTRY, "params": [1, 2]}, r"params must be a table, got list"),
    ({"entry": ENTRY, "colour": "red"}, r"unknown key\(s\) \['colour'\]"),
])
def test_bad_python_terms_name_the_table(panda: genplan.Robot, row: dict[str, Any], message: str) -> None:
    data = {"name": "t", "primary": [{"kind": "JointLimits"}, {"kind": "python", **row}]}
    with pytest.raises(TaskFileError, match=r"^t: \[\[primary\]\] 2.*" + message):
        P.Task.from_dict(data, panda, origin="t", allow_python=True)


def test_a_python_term_needs_the_robot_it_is_read_with(panda: genplan.Robot) -> None:
    data = _task(panda).to_dict()
    with pytest.raises(TaskFileError, match=r"\[\[primary\]\] 2: .*'robot' field needs the robot"):
        P.Task.from_dict(data, None, allow_python=True)


def test_a_term_that_cannot_be_rebuilt_elsewhere_runs_here_and_is_refused_with_the_reason(
        tmp_path, panda: genplan.Robot) -> None:
    @dataclasses.dataclass(frozen=True)
    class LocalCircle(OnCircle):
        pass

    from genplan.samplers.data import generate

    task = _task(panda, LocalCircle(robot=panda, weight=30, tolerance=1e-3, name="wrist"))
    res = P.GaussNewtonProjector(panda, P.manifold_task(task, panda)).solve(panda.q_default)  # in-process: works
    assert res.iterations >= 1
    reason = r"term 'wrist': .*LocalCircle is defined inside a function.*define LocalCircle in an importable module"
    for use in (lambda: task.to_file(tmp_path / "t.toml"), lambda: P.check_task_use(task, panda),
                lambda: generate(panda, 10, 0, task, progress=False)):
        with pytest.raises(TaskFileError, match=reason):
            use()
    assert not (tmp_path / "t.toml").exists()
    from genplan.samplers.gan import default_config, train

    with pytest.raises(TaskFileError, match=reason):  # before any data or training
        train(default_config(panda, task, iterations=1, data_size=10), robot=panda, task=task, progress=False)


def test_a_python_term_with_a_field_a_file_cannot_hold_is_refused(panda: genplan.Robot) -> None:
    task = _task(panda, OnCircle(robot=panda, frame=object(), name="wrist"))  # type: ignore[arg-type]
    with pytest.raises(TaskFileError, match=r"term 'wrist' \(tests.custom_terms_example:OnCircle\): field 'frame' "
                                            r"holds a object"):
        task.to_dict()


def test_a_python_term_holding_another_robot_is_refused(panda: genplan.Robot, ur5: genplan.Robot) -> None:
    with pytest.raises(TaskFileError, match="python term 'wrist' holds robot 'ur5', not the robot 'panda'"):
        P.check_task_use(_task(panda, OnCircle(robot=ur5, name="wrist")), panda)


def test_data_with_a_python_term_runs_in_processes_with_the_same_rows_as_in_threads(panda: genplan.Robot) -> None:
    from genplan.samplers.data import executor_kind, generate

    task = _task(panda)
    assert executor_kind(task) == "process" and executor_kind(P.load_task("panda_ik", panda)) == "thread"
    with LocalExecutor(2, "process") as ex:
        in_processes = generate(panda, 40, 3, task, shard_size=10, executor=ex, progress=False)
    with LocalExecutor(1, "thread") as ex:
        in_threads = generate(panda, 40, 3, task, shard_size=10, executor=ex, progress=False)
    assert in_processes.shape == (40, panda.nq) and np.array_equal(in_processes, in_threads)
    term = task.primary[1]
    assert np.abs(term.residual(in_processes)).max() < 1e-3  # every row on the circle


def test_a_gan_trains_on_a_python_term_and_its_card_loads_again(tmp_path, panda: genplan.Robot) -> None:
    from genplan.samplers.gan import default_config, load_model, train

    task = _task(panda)
    cfg = default_config(panda, task, iterations=3, data_size=60, n_net=2)
    model = train(cfg, robot=panda, task=task, progress=False)
    assert model.card["data"]["from"] in ("generated", "cache")
    weights, card_path = model.save(tmp_path / "wrist_gan.safetensors")
    card = json.loads(card_path.read_text())
    assert card["task"] == task.to_dict()
    assert card["task"]["primary"][1]["entry"] == ENTRY and card["task"]["primary"][1]["params"]["radius"] == 0.3
    loaded = load_model(panda, weights, task=task)
    assert loaded.sample(np.array([[0.45, 0.0, 0.5]]), 0).shape == (1, panda.nq)
    # the task the card records is the task again, read with the opt-in
    assert P.Task.from_dict(card["task"], panda, allow_python=True).to_dict() == task.to_dict()
    with pytest.raises(TaskFileError, match="allow_python=True"):
        P.Task.from_dict(card["task"], panda)
    # and a file of that task gives the same model match
    path = task.to_file(tmp_path / "wrist.toml")
    assert load_model(panda, weights, task=P.load_task(str(path), panda, allow_python=True)).card["task"] == card["task"]


def test_train_gan_and_data_take_a_python_task_file_only_with_allow_python(tmp_path, panda: genplan.Robot,
                                                                           capsys) -> None:
    path = _task(panda).to_file(tmp_path / "wrist.toml")
    out = tmp_path / "m.safetensors"
    train = ["train", "gan", "--robot", "panda", "--task", str(path), "--iterations", "2", "--data-size", "40",
             "--n-net", "2", "--eval-targets", "2", "--out", str(out)]
    data = ["data", "--robot", "panda", "--task", str(path), "--data-size", "20", "--shard-size", "10",
            "--workers", "2", "--out", str(tmp_path / "d")]
    for argv in (train, data):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert f"task file {path}: [[primary]] 2" in err and "--allow-python" in err and ENTRY in err
    assert not out.exists() and not (tmp_path / "d").exists()
    assert main([*data, "--allow-python"]) == 0
    manifest = json.loads((tmp_path / "d" / "manifest.json").read_text())
    assert manifest["last_run"]["executor"] == "local-processes"
    assert manifest["manifold"]["primary"][0]["entry"] == ENTRY  # the manifold: without the condition term
    assert main([*train, "--allow-python"]) == 0
    card = json.loads(out.with_suffix(".json").read_text())
    assert card["task"]["primary"][1]["entry"] == ENTRY
    assert card["command"].startswith(f"genplan train gan --robot panda --task {path} --seed 0")
    assert "--allow-python" in card["command"]


def test_plan_and_train_flow_take_a_python_task_file_only_with_allow_python(tmp_path, capsys) -> None:
    panda = genplan.load("panda")
    path = _task(panda).to_file(tmp_path / "wrist.toml")
    flow = tmp_path / "f.safetensors"
    train = ["train", "flow", "--robot", "panda", "--task", str(path), "--iterations", "2", "--data-size", "40",
             "--eval-targets", "2", "--out", str(flow)]
    out = tmp_path / "plan.json"
    plan = ["plan", "--robot", "panda", "--task", str(path), "--start", "default", "--target", "0.45", "0.1", "0.5",
            "--seed", "0", "--out", str(out)]
    for argv in (train, plan):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "--allow-python" in err and ENTRY in err
    assert not flow.exists() and not out.exists()
    assert main([*train, "--allow-python"]) == 0
    assert json.loads(flow.with_suffix(".json").read_text())["task"]["primary"][1]["entry"] == ENTRY
    # with the opt-in the plan is made on the python term's manifold (start and goal projected)
    assert main(["plan", "--robot", "panda", "--task", str(path), "--start", "default", "--goal", "0.3 -0.3 0 -2.2 0 2 0.8",
                 "--seed", "0", "--out", str(out), "--allow-python"]) == 0
    report = json.loads(out.read_text())
    assert report["success"] and report["task"] == "panda_wrist_on_circle"
    wrist = P.GaussNewtonProjector(panda, P.manifold_task(P.load_task(str(path), panda, allow_python=True), panda))
    sizes = wrist.residual_sizes(np.array(report["path"]))
    assert np.all(sizes["wrist"] <= 1e-3)  # every state of the path on the python term's circle
