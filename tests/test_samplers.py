"""genplan.samplers: the samplers' names (one registry, what the planner, the CLI and solve_ik
accept), the one source of the "data" sampler's rows (TaskData), and genplan.gan, the deprecated
alias of the package."""

import argparse

import numpy as np
import pytest

import genplan
import genplan.ik
import genplan.planning
from genplan.errors import SettingsError
from genplan.samplers import MIXTURES, SAMPLERS, WARM_STARTS
from genplan.samplers.data import TaskData


def test_the_sampler_names_are_one_registry() -> None:
    assert genplan.planning.SAMPLERS is SAMPLERS
    assert genplan.ik.INITS == WARM_STARTS == tuple(s for s in SAMPLERS if s not in MIXTURES)
    assert set(MIXTURES) < set(SAMPLERS) and {"uniform", "gan", "data"} == set(WARM_STARTS)
    from genplan.cli import plan

    p = argparse.ArgumentParser()
    plan.add_arguments(p)
    assert next(a for a in p._actions if a.dest == "sampler").choices == SAMPLERS


def test_task_data_is_where_the_data_sampler_and_the_ik_warm_starts_draw(panda) -> None:
    rows = panda.random_configurations(400, 3)
    data = TaskData(panda, "panda_ik", rows)
    assert data.frame == genplan.projection.condition_term(data.task).frame
    np.testing.assert_array_equal(data.positions, panda.frame_positions(rows, data.frame))
    box = np.array([[0.2, -0.4, 0.2], [0.7, 0.4, 0.8]])
    inside = np.all((data.positions >= box[0]) & (data.positions <= box[1]), axis=1)
    np.testing.assert_array_equal(data.in_box(box), rows[inside])
    drawn = genplan.planning.data_sampler(panda, rows, task="panda_ik", box=box, seed=1).sample(200)
    assert all(np.any(np.all(rows[inside] == q, axis=1)) for q in drawn)
    with pytest.raises(SettingsError, match="none of the 400 configurations"):
        data.in_box([[5, 5, 5], [6, 6, 6]])
    targets = np.array([[0.4, 0.0, 0.5], [0.5, 0.2, 0.3]])
    near, seconds = data.nearest(targets, 5)
    assert near.shape == (2, 5, 7) and seconds >= 0
    for t, qs in zip(targets, near):
        d = np.linalg.norm(panda.frame_positions(qs, data.frame) - t, axis=1)
        assert np.all(np.diff(d) >= 0) and d[0] == np.min(np.linalg.norm(data.positions - t, axis=1))


def test_rows_given_need_no_task_until_one_is_asked_for(ur5) -> None:
    """data_sampler(robot, data, in_box=False) draws rows of any robot, with a shipped task or not."""
    rows = ur5.random_configurations(10, 0)
    assert len(genplan.planning.data_sampler(ur5, rows, in_box=False)) == 10


def test_genplan_gan_is_a_deprecated_alias_of_genplan_samplers() -> None:
    """genplan.gan's names and modules moved to genplan.samplers; for one release they forward,
    each with a DeprecationWarning naming the new place."""
    import importlib
    import sys

    import genplan.gan
    import genplan.samplers
    import genplan.samplers.base
    import genplan.samplers.flow
    import genplan.samplers.gan

    with pytest.warns(DeprecationWarning, match=r"genplan.gan.GanSampler is deprecated.*genplan.samplers.sampler"):
        assert genplan.gan.GanSampler is genplan.samplers.GanSampler
    with pytest.warns(DeprecationWarning, match=r"genplan.gan.model.Codec .*genplan.samplers.base.Codec"):
        assert importlib.import_module("genplan.gan.model").Codec is genplan.samplers.base.Codec
    with pytest.warns(DeprecationWarning, match=r"genplan.gan.model.GanConfig .*genplan.samplers.gan.GanConfig"):
        assert importlib.import_module("genplan.gan.model").GanConfig is genplan.samplers.gan.GanConfig
    sys.modules.pop("genplan.gan.flow", None)
    with pytest.warns(DeprecationWarning, match=r"genplan.gan.flow is deprecated.*genplan.samplers.flow"):
        assert importlib.import_module("genplan.gan.flow") is genplan.samplers.flow
    with pytest.raises(AttributeError, match="no attribute 'UniformSampler'"):
        genplan.gan.UniformSampler  # noqa: B018


def test_a_missing_gan_names_a_training_command_that_works(tmp_path, monkeypatch, capsys) -> None:
    """A robot genplan ships no GAN for, asked for its GAN without --model: the error names no path
    inside the package, and its command (with the --task given) trains one as typed."""
    import re
    import shlex
    from pathlib import Path

    from genplan.cli import main
    from genplan.samplers.base import task_option
    from genplan.samplers.gan import load_model

    examples = Path(__file__).resolve().parents[1] / "examples" / "baxter"
    robot, task = examples / "baxter.toml", examples / "tray.toml"
    monkeypatch.chdir(tmp_path)
    assert main(["bench", "projection", "--robot", str(robot), "--task", str(task), "--init", "gan", "--tasks", "2"]) == 2
    err = capsys.readouterr().err
    assert "robot 'baxter' has no shipped GAN" in err and "genplan/models" not in err and "site-packages" not in err
    command = re.search(r"`(genplan train gan [^`]*)`", err)
    assert command is not None and f"--task {task}" in command.group(1)
    argv = shlex.split(command.group(1))[1:] + ["--iterations", "2", "--data-size", "40", "--n-net", "2",
                                                "--eval-targets", "2"]
    assert main(argv) == 0  # the hint's command, shrunk: it trains and writes the model it names
    assert (tmp_path / "baxter_gan.safetensors").is_file()
    # without a task to name, the command says which file to write instead of failing for want of one
    baxter = genplan.load(str(robot))
    with pytest.raises(FileNotFoundError, match=r"--task TASK.toml .*\(TASK.toml: a task file with a \[condition\]"):
        load_model(baxter)
    assert task_option(genplan.load("panda"), None) is None and task_option(genplan.load("panda"), "panda_ik") is None
    assert task_option(genplan.load("panda"), "talos_ik") == "talos_ik"
