"""The genplan command line: every user error is one line on stderr and exit code 2, found before
the command starts work; a bug keeps its traceback (exit code 1)."""

import importlib
import subprocess
import sys
import time
from pathlib import Path

import pytest

from genplan import cli
from genplan.cli import main
from genplan.errors import GenplanError


def test_help_lists_commands(capsys) -> None:
    assert main([]) == 2
    assert "info" in capsys.readouterr().out


def test_info_prints_versions_and_robots() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "genplan", "info"], capture_output=True, text=True, check=True
    ).stdout
    assert "parry3d-f64 0.25" in out and "pin " in out
    for line in ("panda  nq=7", "talos  nq=35", "ur5    nq=6"):
        assert line in out, out


@pytest.fixture
def no_work(monkeypatch):
    """Every command's ``main`` fails the test if called: what is checked is checked before."""
    for _, name, module, _ in cli.COMMANDS:
        def started(args, name=name):
            pytest.fail(f"`{name}` started work")
        monkeypatch.setattr(importlib.import_module(module), "main", started)


def one_error_line(capsys) -> str:
    """The single stderr line of a user error, without the ``genplan: error: `` prefix."""
    cap = capsys.readouterr()
    assert cap.err.startswith("genplan: error: ") and cap.err.count("\n") == 1, cap.err
    assert "Traceback" not in cap.err
    return cap.err[len("genplan: error: "):-1]


@pytest.mark.parametrize("argv, message", [
    # the examples
    ("train gan --robot panda --iterations -1", "train gan: argument --iterations: expected a positive integer, got '-1'"),
    ("train gan --robot panda --seed -1", "train gan: argument --seed: expected a seed in 0..4294967295, got '-1'"),
    ("train gan --robot panda --n-net 0", "train gan: argument --n-net: expected a positive integer, got '0'"),
    ("bench coverage --threads 0", "bench coverage: argument --threads: expected a positive integer, got '0'"),
    # the same kinds in every command
    ("train gan --robot panda --threads 0", "argument --threads: expected a positive integer"),
    ("train gan --robot panda --data-size 0", "argument --data-size: expected a positive integer"),
    ("train gan --robot panda --seed 4294967296", "argument --seed: expected a seed"),
    ("train seq2seq --threads 0", "argument --threads: expected a positive integer"),
    ("train seq2seq --epochs 0", "argument --epochs: expected a positive integer"),
    ("train seq2seq --data-seed -3", "argument --data-seed: expected a seed"),
    ("train seq2seq --lr inf", "argument --lr: expected a finite number > 0, got 'inf'"),
    ("train seq2seq --alpha -1", "argument --alpha: expected a finite number >= 0"),
    ("bench projection --robot panda --tasks 0", "argument --tasks: expected a positive integer"),
    ("bench projection --robot panda --seed x", "argument --seed: expected a seed in 0..4294967295, got 'x'"),
    ("bench projection --robot panda --init gan --model no/such.safetensors",
     "argument --model: no/such.safetensors: no such file"),
    ("bench plan --queries 0", "bench plan: argument --queries: expected a positive integer"),
    ("bench plan --ompl-time-limit nan", "argument --ompl-time-limit: expected a finite number > 0, got 'nan'"),
    ("bench plan --edge-resolution -0.1", "argument --edge-resolution: expected a finite number >= 0"),
    ("bench coverage --seed -1", "bench coverage: argument --seed: expected a seed"),
    ("bench coverage --variants default,bogus", "argument --variants: expected comma-separated variants among"),
    ("train gan --robot panda --w-diversity -1", "argument --w-diversity: expected a finite number >= 0"),
    ("bench adjust --threads 0", "bench adjust: argument --threads: expected a positive integer"),
    ("bench adjust --problems 0", "argument --problems: expected a positive integer"),
    ("bench adjust --model no/such.safetensors", "argument --model: no/such.safetensors: no such file"),
    ("bench control --repeats 0", "bench control: argument --repeats: expected a positive integer"),
    ("bench control --settle -1", "argument --settle: expected a finite number >= 0"),
    ("bench control --updates -1", "argument --updates: expected an integer >= 0"),
    ("report no/such/folder", "report: argument folder: no/such/folder: no such folder"),
    ("bench plan --env kitchen", "bench plan: argument --env: invalid choice: 'kitchen'"),
    ("bench plan --algorithm rrt", "bench plan: argument --algorithm: invalid choice: 'rrt'"),
    ("plan --robot panda --task panda_ik --target 0.5 0 0.5 --out x.json --algorithm prm",
     "plan: argument --algorithm: invalid choice: 'prm'"),
    ("bench", "bench: the following arguments are required: BENCHMARK"),
    ("train gan", "train gan: the following arguments are required: --robot"),
    ("nope", "argument COMMAND: invalid choice: 'nope'"),
])
def test_bad_arguments_are_one_line_and_exit_2(argv, message, capsys, no_work) -> None:
    assert main(argv.split()) == 2
    line = one_error_line(capsys)
    assert message in line, line
    assert line.endswith("--help`)")  # where to read more


def _unwritable(tmp_path: Path, kind: str) -> list[Path]:
    """Output places that cannot be used: below a regular file (missing and impossible), and in
    /proc (read-only even for root)."""
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    name = "out.json" if kind == "file" else "figures"
    return [blocker / name, Path("/proc/genplan-test") / name]


#: (command, its other arguments, the output option, file or folder) of every output argument
OUTPUTS = [
    ("bench projection", "--robot panda", "--out", "file"),
    ("bench plan", "", "--out", "file"),
    ("bench coverage", "", "--out", "file"),
    ("bench coverage", "", "--figures", "folder"),
    ("bench adjust", "--method latent", "--out", "file"),
    ("bench adjust", "", "--out-dir", "folder"),
    ("bench adjust", "", "--figures", "folder"),
    ("bench robots", "--robots panda --samples 10", "--out", "file"),
    ("bench control", "", "--out", "file"),
    ("bench control", "", "--png", "file"),
    ("bench scaling", "", "--out", "file"),
    ("bench peers", "", "--out", "file"),
    ("bench peers", "", "--markdown", "file"),
    ("data", "--robot panda --data-size 10", "--out", "folder"),
    ("train gan", "--robot panda", "--out", "file"),
    ("train flow", "--robot panda", "--out", "file"),
    ("train seq2seq", "", "--out", "file"),
    ("report", "{tmp}", "--out", "file"),
    ("plan", "--robot panda --task panda_ik --target 0.5 0 0.5", "--out", "file"),
    ("plan", "--robot panda --task panda_ik --target 0.5 0 0.5 --out {tmp}/p.json", "--html", "file"),
    ("plan", "--robot panda --task panda_ik --target 0.5 0 0.5 --out {tmp}/p.json", "--trajectory", "file"),
    ("bench ik", "", "--out", "file"),
    ("reproduce", "--quick", "--out", "folder"),
]


def test_every_output_argument_is_listed() -> None:
    """OUTPUTS holds every output argument of every command (a new one must be added there)."""
    import argparse

    from genplan._cli_args import output_actions

    found = set()
    for group, name, module, _ in cli.COMMANDS:
        parser = argparse.ArgumentParser()
        importlib.import_module(module).add_arguments(parser)
        found |= {(f"{group} {name}".strip(), option, out.kind) for _, option, out in output_actions(parser)}
    assert found == {(command, option, kind) for command, _, option, kind in OUTPUTS}


@pytest.mark.parametrize("command, other, option, kind", OUTPUTS, ids=[f"{c} {o}" for c, _, o, _ in OUTPUTS])
def test_an_unwritable_output_fails_at_once_before_any_work(command, other, option, kind, tmp_path, capsys,
                                                            no_work) -> None:
    for bad in _unwritable(tmp_path, kind):
        t0 = time.perf_counter()
        assert main([*command.split(), *other.format(tmp=tmp_path).split(), option, str(bad)]) == 2
        assert time.perf_counter() - t0 < 1.0
        line = one_error_line(capsys)
        assert line.startswith(f"{option} {bad}: ") and ("cannot" in line or "is a file" in line), line


def test_an_output_that_is_a_folder_or_a_file_in_the_way(tmp_path, capsys, no_work) -> None:
    assert main(["bench", "plan", "--out", str(tmp_path)]) == 2
    assert one_error_line(capsys) == f"--out {tmp_path}: is a folder, not a file"
    (tmp_path / "figs").write_text("")
    assert main(["bench", "coverage", "--figures", str(tmp_path / "figs")]) == 2
    assert one_error_line(capsys) == f"--figures {tmp_path / 'figs'}: the folder is a file"


def test_missing_output_folders_are_created(tmp_path, no_work) -> None:
    """The documented behaviour: an output's folders are created (before the work, as a check)."""
    out = tmp_path / "new" / "deeper" / "plan.json"
    with pytest.raises(pytest.fail.Exception, match="started work"):
        main(["bench", "plan", "--out", str(out)])
    assert out.parent.is_dir() and list(out.parent.iterdir()) == []  # the probe file is gone


def test_computed_default_outputs_are_checked_before_training(tmp_path, monkeypatch, capsys) -> None:
    import genplan.gan.model as gan_model
    import genplan.pancake.model as seq_model

    blocker = tmp_path / "a_file"
    blocker.write_text("")

    def no_training(*args, **kwargs):
        pytest.fail("training started")

    monkeypatch.setattr(gan_model, "models_dir", lambda: blocker / "models")
    monkeypatch.setattr(gan_model, "train", no_training)
    assert main(["train", "gan", "--robot", "panda"]) == 2
    assert one_error_line(capsys).startswith(f"--out {blocker / 'models' / 'panda_gan.safetensors'}: ")
    monkeypatch.setattr(seq_model, "default_path", lambda: blocker / "models" / "pancake_seq2seq.safetensors")
    monkeypatch.setattr(seq_model, "train", no_training)
    assert main(["train", "seq2seq"]) == 2
    assert one_error_line(capsys).startswith(f"--out {blocker / 'models' / 'pancake_seq2seq.safetensors'}: ")
    # bench adjust --method all writes to benches/results (relative) unless --out-dir says otherwise
    monkeypatch.chdir(tmp_path)
    (tmp_path / "benches").write_text("")
    monkeypatch.setattr(seq_model, "load_model", no_training)
    assert main(["bench", "adjust", "--method", "all"]) == 2
    assert one_error_line(capsys).startswith("--out-dir benches/results: cannot create the folder")
    # genplan report FOLDER writes FOLDER/report.md
    monkeypatch.setattr(importlib.import_module("genplan.experiments.report"), "collect", no_training)
    assert main(["report", "/proc/self"]) == 2
    assert one_error_line(capsys).startswith("FOLDER /proc/self/report.md: cannot write in the folder /proc/self")


@pytest.mark.parametrize("error, line", [
    (GenplanError("a bad setting\n  on two lines"), "a bad setting on two lines"),
    (FileNotFoundError(2, "No such file or directory", "models/x.safetensors"), "models/x.safetensors: No such file or directory"),
    (FileNotFoundError("GAN model file m.safetensors does not exist; train it with `genplan train gan`"),
     "GAN model file m.safetensors does not exist; train it with `genplan train gan`"),
    (PermissionError(13, "Permission denied", "/root/x"), "/root/x: Permission denied"),
])
def test_user_errors_raised_inside_a_command_are_one_line(error, line, monkeypatch, capsys) -> None:
    def command(args):
        raise error

    monkeypatch.setattr(importlib.import_module("genplan.experiments.benchmarks.plan"), "main", command)
    assert main(["bench", "plan"]) == 2
    assert one_error_line(capsys) == line


def test_a_bug_keeps_its_traceback_and_exit_code_1(monkeypatch, tmp_path) -> None:
    def command(args):
        raise KeyError("a bug")

    monkeypatch.setattr(importlib.import_module("genplan.experiments.benchmarks.plan"), "main", command)
    with pytest.raises(KeyError, match="a bug"):
        main(["bench", "plan"])
    # as a program: the traceback and exit code 1
    code = ("import sys, genplan.experiments.report as r; r.write_report = None; "
            f"from genplan.cli import main; sys.exit(main(['report', {str(tmp_path)!r}]))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1 and "Traceback" in proc.stderr and "TypeError" in proc.stderr


def test_the_program_prints_one_line_and_exits_2(tmp_path) -> None:
    """The issue's cases through the real entry point (``python -m genplan``)."""
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    for argv, message in [
        (["train", "gan", "--robot", "panda", "--iterations", "-1"], "argument --iterations"),
        (["bench", "plan", "--out", str(blocker / "x.json")], f"--out {blocker / 'x.json'}: the folder {blocker} is a file"),
        (["bench", "coverage", "--threads", "0"], "argument --threads"),
    ]:
        proc = subprocess.run([sys.executable, "-m", "genplan", *argv], capture_output=True, text=True, timeout=60)
        assert proc.returncode == 2 and proc.stdout == "", proc
        assert proc.stderr.startswith("genplan: error: ") and proc.stderr.count("\n") == 1, proc.stderr
        assert message in proc.stderr


def test_help_still_exits_0(capsys) -> None:
    with pytest.raises(SystemExit) as info:
        main(["train", "gan", "--help"])
    assert info.value.code == 0 and "--iterations" in capsys.readouterr().out
