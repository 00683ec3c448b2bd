"""The genplan command line: every user error is one line on stderr and exit code 2, found before
the command starts work; a bug keeps its traceback (exit code 1)."""

import importlib
import os
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
    ("plan --robot panda --target 0.5 0 0.5 1 --frame hand --out x.json",
     "--target: expected 3 numbers (X Y Z) or 7 (X Y Z QX QY QZ QW), got 4"),
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
    ("bench motion", "", "--out", "file"),
    ("data configurations", "--robot panda --data-size 10", "--out", "folder"),
    ("data trajectories", "--robot panda --task panda_projection --count 2", "--out", "folder"),
    ("adjust", f"--model {Path(__file__).resolve()} --input x.npz --objective {Path(__file__).resolve()}", "--out",
     "folder"),
    ("bench adapt", f"--model {Path(__file__).resolve()} --data {Path(__file__).parent} --held-out "
                    f"{Path(__file__).parent}", "--out", "file"),
    ("train gan", "--robot panda", "--out", "file"),
    ("train flow", "--robot panda", "--out", "file"),
    ("train seq2seq", "", "--out", "file"),
    ("report", "{tmp}", "--out", "file"),
    ("report", "{tmp}", "--benchmarks", "file"),
    ("plan", "--robot panda --task panda_ik --target 0.5 0 0.5", "--out", "file"),
    ("view", "panda_shelf", "--out", "file"),
    ("plan", "--robot panda --task panda_ik --target 0.5 0 0.5 --out {tmp}/p.json", "--html", "file"),
    ("plan", "--robot panda --task panda_ik --target 0.5 0 0.5 --out {tmp}/p.json", "--trajectory", "file"),
    ("bench ik", "", "--out", "file"),
    ("reproduce", "--quick", "--out", "folder"),
    ("execute", f"--robot panda --trajectory {Path(__file__).resolve()}", "--out", "file"),
    ("execute", f"--robot panda --trajectory {Path(__file__).resolve()} --out {{tmp}}/log.npz", "--plot", "file"),
    ("execute", f"--robot panda --trajectory {Path(__file__).resolve()} --out {{tmp}}/log.npz", "--html", "file"),
]


def test_every_output_argument_is_listed() -> None:
    """OUTPUTS holds every output argument of every command (a new one must be added there)."""
    import argparse

    from genplan.cli.args import output_actions

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
    import genplan.pancake.model as seq_model
    import genplan.samplers.base as sampler_base
    import genplan.samplers.gan as gan_model

    blocker = tmp_path / "a_file"
    blocker.write_text("")

    def no_training(*args, **kwargs):
        pytest.fail("training started")

    monkeypatch.setattr(sampler_base, "models_dir", lambda: blocker / "models")
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


EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "xarm7"


def _run_cli(argv: list[str], cwd: Path, **kwargs) -> subprocess.CompletedProcess:
    """``genplan ARGV`` in a fresh interpreter; its stderr's last line says whether torch was imported."""
    code = ("import sys; from genplan.cli import main\n"
            "try:\n    rc = main(sys.argv[1:])\n"
            "finally:\n    print('torch imported:', 'torch' in sys.modules, file=sys.stderr)\n"
            "sys.exit(rc)")
    return subprocess.run([sys.executable, "-c", code, *argv], cwd=cwd, capture_output=True, text=True, timeout=120,
                          **kwargs)


@pytest.mark.parametrize("argv", [
    ["data", "--robot", "panda", "--data-size", "20", "--shard-size", "10", "--workers", "1", "--out", "d"],
    ["plan", "--robot", str(EXAMPLES / "xarm7.toml"), "--task", str(EXAMPLES / "upright_cup.toml"), "--scene",
     str(EXAMPLES / "table_box.toml"), "--target", "0.45", "-0.3", "0.25", "--sampler", "uniform", "--out", "plan.json"],
], ids=["data", "plan-uniform"])
def test_integrity_6_commands_that_need_no_model_import_no_torch(argv, tmp_path) -> None:
    proc = _run_cli(argv, tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines()[-1] == "torch imported: False", proc.stderr[-2000:]


def _package_files() -> dict[str, bytes]:
    """Every file of the installed package's shipped models, by name."""
    from genplan.samplers.base import models_dir

    return {p.name: p.read_bytes() for p in sorted(models_dir().iterdir())}


@pytest.fixture
def no_training(monkeypatch):
    """Training fails the test if it starts (and so cannot write anything)."""
    import genplan.pancake.model as seq_model
    import genplan.samplers.flow as flow
    import genplan.samplers.gan as gan_model

    def started(*args, **kwargs):
        pytest.fail("training started")

    for module in (gan_model, flow, seq_model):
        monkeypatch.setattr(module, "train", started)


@pytest.mark.parametrize("argv, name", [
    (["train", "gan", "--robot", "panda"], "panda_gan.safetensors"),
    (["train", "flow", "--robot", "talos"], "talos_flow.safetensors"),
    (["train", "seq2seq"], "pancake_seq2seq.safetensors"),
], ids=["gan", "flow", "seq2seq"])
def test_integrity_1_training_without_out_never_writes_into_the_package(argv, name, capsys, no_training) -> None:
    """Before: `genplan train gan --robot panda` trained and wrote over the installed package's
    models/panda_gan.*, which every default use of the Panda GAN loads. Now --out is needed
    (a one-line error naming it and suggesting a path), before any work."""
    before = _package_files()
    assert main(argv) == 2
    line = one_error_line(capsys)
    assert line.startswith("--out: ") and f"--out {name}" in line and "installed genplan package" in line, line
    assert _package_files() == before


@pytest.mark.parametrize("command", ["gan", "flow", "seq2seq"])
def test_integrity_1_an_out_inside_the_package_is_refused(command, monkeypatch, capsys, no_training) -> None:
    """The repository's `models` links to the package's models: `--out models/x.safetensors` from
    the repository's root would write into the package; refused like the default."""
    from genplan.samplers.base import models_dir

    monkeypatch.chdir(Path(__file__).resolve().parents[1])
    robot = [] if command == "seq2seq" else ["--robot", "panda"]
    for out in ("models/panda_gan.safetensors", str(models_dir() / "new.safetensors")):
        before = _package_files()
        assert main(["train", command, *robot, "--out", out]) == 2
        line = one_error_line(capsys)
        assert line.startswith(f"--out {out}: ") and "inside the installed genplan package" in line, line
        assert _package_files() == before


@pytest.mark.parametrize("command", ["gan", "flow", "seq2seq"])
def test_integrity_1_replacing_a_model_says_so_and_keeps_it_until_the_new_one_is_complete(command, tmp_path,
                                                                                          monkeypatch, capsys) -> None:
    import genplan.pancake.model as seq_model
    import genplan.samplers.flow as flow
    import genplan.samplers.gan as gan_model

    class Interrupted(Exception):
        pass

    def cut_short(*args, **kwargs):
        raise Interrupted

    for module in (gan_model, flow, seq_model):
        monkeypatch.setattr(module, "train", cut_short)
    out = tmp_path / "m.safetensors"
    out.write_bytes(b"old weights")
    out.with_suffix(".json").write_text("old card")
    robot = [] if command == "seq2seq" else ["--robot", "panda"]
    with pytest.raises(Interrupted):
        main(["train", command, *robot, "--out", str(out)])
    assert f"genplan: {out} exists: replaced once the new model is complete (kept until then)\n" in capsys.readouterr().err
    assert out.read_bytes() == b"old weights" and out.with_suffix(".json").read_text() == "old card"
    fresh = tmp_path / "new.safetensors"
    with pytest.raises(Interrupted):
        main(["train", command, *robot, "--out", str(fresh)])
    assert "exists" not in capsys.readouterr().err


def _fsize_limit(limit: int):
    """A preexec_fn: a file size limit of ``limit`` bytes (``ulimit -f``) in the child."""
    def set_limit() -> None:
        import resource

        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return set_limit


def _temporary_files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob(".*") if ".tmp" in p.name)


def test_integrity_6_a_write_that_fails_is_one_line_naming_the_file(tmp_path) -> None:
    # a data shard past the file size limit (ulimit -f): EFBIG, not SIGXFSZ killing the process
    proc = _run_cli(["data", "--robot", "panda", "--data-size", "300", "--shard-size", "150", "--workers", "1",
                     "--out", "d"], tmp_path, preexec_fn=_fsize_limit(4096))
    lines = proc.stderr.splitlines()
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    assert lines[-2].endswith(f"genplan: error: {Path('d') / 'shard_00000.npy'}: File too large"), lines[-2]
    assert not (tmp_path / "d").exists()  # nothing half-written, no folder left behind
    # a --trajectory file: the plan's JSON (90 kB) is written, the trajectory (~1 MB) is not
    argv = ["plan", "--robot", str(EXAMPLES / "xarm7.toml"), "--task", str(EXAMPLES / "upright_cup.toml"), "--scene",
            str(EXAMPLES / "table_box.toml"), "--target", "0.45", "-0.3", "0.25", "--out", "plan.json",
            "--trajectory", "plan.npz"]
    proc = _run_cli(argv, tmp_path, preexec_fn=_fsize_limit(300_000))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    assert proc.stderr.splitlines()[-2] == "genplan: error: plan.npz: File too large", proc.stderr[-3000:]
    assert (tmp_path / "plan.json").is_file() and not (tmp_path / "plan.npz").exists()
    assert _temporary_files(tmp_path) == []


def test_integrity_6_a_training_output_that_cannot_be_written_is_one_line(tmp_path) -> None:
    env = {**os.environ, "GENPLAN_CACHE": str(tmp_path / "cache"), "GENPLAN_TORCH_THREADS": "1"}
    proc = _run_cli(["train", "gan", "--robot", "panda", "--iterations", "2", "--n-net", "2", "--data-size", "200",
                     "--eval-targets", "5", "--out", "m.safetensors"], tmp_path, preexec_fn=_fsize_limit(60_000),
                    env=env)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    assert proc.stderr.splitlines()[-2] == "genplan: error: m.safetensors: File too large", proc.stderr[-3000:]
    assert not (tmp_path / "m.safetensors").exists() and not (tmp_path / "m.json").exists()
    assert _temporary_files(tmp_path) == []


def test_integrity_6_ctrl_c_is_one_line_exit_130_and_the_data_set_resumes(tmp_path) -> None:
    import json
    import signal

    code = ("import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler)\n"
            "from genplan.cli import main; sys.exit(main(sys.argv[1:]))")
    argv = ["data", "--robot", "panda", "--data-size", "60000", "--shard-size", "500", "--workers", "1", "--out", "d"]
    proc = subprocess.Popen([sys.executable, "-c", code, *argv], cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    t0 = time.perf_counter()
    while not (tmp_path / "d" / "manifest.json").exists() and proc.poll() is None and time.perf_counter() - t0 < 60:
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err[-3000:]
    assert err.splitlines()[-1].endswith("genplan: interrupted") and "Traceback" not in err, err[-3000:]
    m = json.loads((tmp_path / "d" / "manifest.json").read_text())
    assert not m["complete"] and 1 <= m["shards_done"] < m["shards_total"]
    assert _temporary_files(tmp_path) == [] and not (tmp_path / "d" / "genplan.lock").exists()
    proc = _run_cli(argv, tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert f"resuming d: {m['shards_done']} of 120 shards finished and verified" in proc.stdout


def test_integrity_rerun_eval_targets_bounded_before_training(tmp_path, capsys, monkeypatch) -> None:
    # --eval-targets sizes the card's evaluation arrays: a count beyond the bound is refused while
    # the arguments are read, naming the option, before the robot is loaded or anything trains.
    import genplan.samplers.gan as gan

    def no_training(*a, **k):
        raise AssertionError("trained before --eval-targets was checked")

    monkeypatch.setattr(gan, "train", no_training)
    for command in ("gan", "flow"):
        out = tmp_path / command / "m.safetensors"
        assert main(["train", command, "--robot", "panda", "--eval-targets", "1000000000000", "--iterations", "1",
                     "--data-size", "100", "--out", str(out)]) == 2
        line = one_error_line(capsys)
        assert "--eval-targets" in line and "100,000" in line and "1000000000000" in line, line
        assert not out.parent.exists()


def test_plan_without_a_task_plans_in_free_space(tmp_path, capsys) -> None:
    """``genplan plan --robot R --scene S --start Q --goal Q``: the shipped free task, nothing
    projected, a valid path from the start to the goal; a pose of --frame as the goal too."""
    import json

    import numpy as np

    import genplan

    panda = genplan.load("panda")
    start, goal = "0 -0.5 0 -2.4 0 1.9 0.8", "0.5 -0.3 0.2 -2.2 0 2.0 0.8"
    out = tmp_path / "plan.json"
    argv = ["plan", "--robot", "panda", "--scene", "panda_shelf", "--start", start, "--goal", goal, "--out", str(out)]
    assert main([*argv, "--no-simplify"]) == 0, capsys.readouterr()
    d = json.loads(out.read_text())
    assert d["task"] == "free" and d["manifold"] == "free" and d["success"]
    assert d["algorithm"] == "rrt_connect"  # the free-space default (FREE_SPACE_SETTINGS)
    assert d["stats"]["projections"] == 0 and d["stats"]["projector_s"] == 0
    path = np.array(d["path"])
    assert np.allclose(path[0], [float(x) for x in start.split()]) and np.allclose(path[-1], [float(x) for x in goal.split()])
    assert np.all(path >= panda.lower) and np.all(path <= panda.upper)
    world = genplan.planning.environment("panda_shelf").world(panda)
    assert not np.any(world.in_collision(path))
    # simplified by default in free space: shortcuts and smoothing, the same ends, a path no longer
    # than the one planned with --no-simplify, still valid
    assert main(argv) == 0, capsys.readouterr()
    short = np.array(json.loads(out.read_text())["path"])
    assert np.allclose(short[[0, -1]], path[[0, -1]]) and not np.any(world.in_collision(short))
    length = lambda p: float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())  # noqa: E731
    assert length(short) <= length(path) + 1e-9
    pose = panda.frame_placement(np.array([float(x) for x in goal.split()]), "hand")
    import pinocchio as pin

    quat = pin.Quaternion(pose.rotation).coeffs()
    argv = ["plan", "--robot", "panda", "--scene", "panda_shelf", "--start", start, "--target",
            *map(str, [*pose.translation, *quat]), "--frame", "hand", "--goals", "2", "--out", str(out)]
    assert main(argv) == 0, capsys.readouterr()
    d = json.loads(out.read_text())
    end = panda.frame_placement(np.array(d["path"][-1]), "hand")
    assert d["success"] and np.abs(pin.log6(pose.inverse() * end).vector).max() < 1e-3


def test_a_plan_that_fails_exits_3_not_1_and_writes_no_trajectory(tmp_path, capsys, monkeypatch) -> None:
    """A command whose result fails (here: no path within one extension) says so and exits with
    FAILED (3), which a bug's traceback (1) and a user error (2) do not share."""
    import json

    import genplan.planning
    from genplan.cli.args import FAILED

    # the free-space defaults the command plans with, cut to one extension and no retry
    monkeypatch.setattr(genplan.planning, "FREE_SPACE_SETTINGS",
                        genplan.planning.FREE_SPACE_SETTINGS.replace(max_extensions=1, retries=0))
    # the straight line between them crosses the shelf: no path within one extension
    start, goal = "0 -0.5 0 -2.4 0 1.9 0.8", "1.77 1.09 0.09 -2.21 -2.58 1.43 -0.53"
    out, traj = tmp_path / "plan.json", tmp_path / "plan.npz"
    argv = ["plan", "--robot", "panda", "--scene", "panda_shelf", "--start", start, "--goal", goal, "--out", str(out),
            "--trajectory", str(traj)]
    assert main(argv) == FAILED == 3
    assert "no path: no trajectory written" in capsys.readouterr().out
    assert not traj.exists() and json.loads(out.read_text())["success"] is False
    # without --trajectory, the same failure exits FAILED too
    assert main(argv[:-2]) == FAILED


def test_plan_time_limit_stops_the_search(tmp_path, capsys) -> None:
    """``genplan plan --time-limit S``: a search still running after S seconds ends unsuccessful,
    says so, exits FAILED (3) and records ``timed_out`` in the plan's JSON; a bad value is refused."""
    import json

    from genplan.cli.args import FAILED

    start, goal = "0 -0.5 0 -2.4 0 1.9 0.8", "1.77 1.09 0.09 -2.21 -2.58 1.43 -0.53"
    out = tmp_path / "plan.json"
    argv = ["plan", "--robot", "panda", "--scene", "panda_shelf", "--start", start, "--goal", goal, "--out", str(out),
            "--algorithm", "rrt_connect"]
    assert main([*argv, "--time-limit", "1e-6"]) == FAILED
    assert "no path found within --time-limit" in capsys.readouterr().out
    d = json.loads(out.read_text())
    assert d["success"] is False and d["stats"]["timed_out"] is True
    assert main([*argv, "--time-limit", "600"]) == 0
    assert json.loads(out.read_text())["stats"]["timed_out"] is False
    assert main([*argv, "--time-limit", "-1"]) == 2
    assert "--time-limit" in capsys.readouterr().err
