"""``genplan execute`` (genplan.cli.execute): a trajectory file run on the simulated robot, the log
and the plot written, the exit code saying whether the run is executable, usage errors as one
line before anything runs."""

from __future__ import annotations

import json

import numpy as np
import pytest

from genplan.cli import main
from tests.test_control import MOTION


@pytest.fixture(scope="module")
def trajectory_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("traj") / "motion.npz"
    MOTION.save(path)
    return path


def test_execute_writes_the_log_and_the_plot(trajectory_file, tmp_path, capsys):
    out, png = tmp_path / "log.npz", tmp_path / "log.png"
    assert main(["execute", "--robot", "panda", "--trajectory", str(trajectory_file), "--task-frame", "hand",
                 "--unknown-payload-mass", "0.6", "--out", str(out), "--plot", str(png)]) == 0
    text = capsys.readouterr().out
    assert "panda: 1501 ticks at 1 ms (task space on panda_hand)" in text and "x real time" in text
    with np.load(out) as z:
        meta = json.loads(str(z["meta"]))
        assert z["tau"].shape == (1501, 7) and z["error_joint"].shape == (1501, 7)
    assert meta["disturbances"]["payload"]["mass"] == 0.6 and meta["controller"]["frame"] == "panda_hand"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plain_arrays_joint_space_a_scene_and_a_run_over_the_limits(tmp_path, capsys):
    raw = tmp_path / "raw.npz"
    np.savez(raw, t=MOTION.t[::10], q=MOTION.q[::10])  # 100 Hz, no velocities: resampled to 1 kHz
    out = tmp_path / "log.npz"
    assert main(["execute", "--robot", "panda", "--trajectory", str(raw), "--joint-space", "--settle", "0",
                 "--scene", "panda_shelf", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "(joint space on panda_hand_tcp)" in text and "collision: none" in text
    # the motion turns the hand: off the Panda task's manifold (hand level), not executable for it
    assert main(["execute", "--robot", "panda", "--trajectory", str(raw), "--task", "panda_projection",
                 "--out", str(out)]) == 1
    assert "task: largest residual ratio" in capsys.readouterr().out
    # 40 kg the controller does not know: torques clipped at the limits; not executable, exit code 1
    assert main(["execute", "--robot", "panda", "--trajectory", str(raw), "--unknown-payload-mass", "40",
                 "--out", str(out)]) == 1
    assert "warning: the run exceeded the joint limits" in capsys.readouterr().out
    with np.load(out) as z:
        assert json.loads(str(z["meta"]))["summary"]["saturated_ticks"] > 0


@pytest.mark.parametrize("args, message", [
    (["--trajectory", "missing.npz"], "argument --trajectory: missing.npz: no such file"),
    (["--payload-mass", "-1"], "argument --payload-mass: expected a finite number >= 0"),
    (["--out", "log.json"], "--out log.json: the log is written as .npz"),
    (["--html", "view.png"], "--html view.png: the view is written as .html"),
    (["--task-frame", "flange"], "controller.frame: robot 'panda' has no frame 'flange'"),
    (["--robot", "ur5"], "trajectory: made for the joints ['panda_joint1'"),
])
def test_usage_errors_are_one_line(trajectory_file, tmp_path, capsys, args, message):
    base = {"--robot": "panda", "--trajectory": str(trajectory_file), "--out": str(tmp_path / "log.npz")}
    for k, v in zip(args[::2], args[1::2]):
        base[k] = v if k not in ("--out", "--html") else str(tmp_path / v)
    argv = ["execute"] + [x for kv in base.items() for x in kv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    for name in ("log.json", "view.png"):
        message = message.replace(f"{name}:", f"{tmp_path / name}:")
    assert err.startswith("genplan: error: ") and message in err, err
    assert not (tmp_path / "log.npz").exists()


def test_execute_writes_the_view_of_the_run_beside_the_plan(trajectory_file, tmp_path, capsys):
    """``--html``: one offline HTML file, the executed motion a translucent robot with its own
    trail beside the planned one, the scene's obstacles drawn."""
    pytest.importorskip("viser")
    from tests.test_viewer import decode_scene

    out, view = tmp_path / "log.npz", tmp_path / "views" / "run.html"
    assert main(["execute", "--robot", "panda", "--trajectory", str(trajectory_file), "--task-frame", "hand",
                 "--settle", "0.1", "--scene", "panda_shelf", "--out", str(out), "--html", str(view)]) == 0
    assert f"wrote {view}" in capsys.readouterr().out
    page = view.read_text(encoding="utf-8")
    names = {m.get("name") for _, m in decode_scene(page)["messages"]}
    assert {"/trail/path", "/executed_trail/path", "/environment/shelf_board_0"} <= names
    assert any(str(n).startswith("/executed/") for n in names) and "largest error" in page


def _corrupt_files(folder, source):
    """A file of junk bytes and a copy of ``source`` with one bit flipped in its arrays' data (the
    zip member then fails its CRC on reading)."""
    junk = folder / "junk.npz"
    junk.write_bytes(b"\x00genplan: not a zip file\xff" * 40)
    flipped = folder / "flipped.npz"
    raw = bytearray(source.read_bytes())
    raw[raw.find(MOTION.q[len(MOTION.q) // 2].tobytes()) + 3] ^= 0x10  # in q's data
    flipped.write_bytes(bytes(raw))
    return junk, flipped


def test_integrity_rerun_a_corrupt_trajectory_is_one_line_naming_it(trajectory_file, tmp_path, capsys):
    """Junk bytes, or one flipped bit failing the zip's CRC, given as --trajectory ended in a
    zipfile.BadZipFile traceback; now a one-line error naming the file, exit 2, and no output
    (its folder, created for it, removed again)."""
    for bad in _corrupt_files(tmp_path, trajectory_file):
        out = tmp_path / "new" / "log.npz"
        assert main(["execute", "--robot", "panda", "--trajectory", str(bad), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"genplan: error: --trajectory {bad}: not a readable .npz file (") and err.count("\n") == 1
        assert bad.name == "junk.npz" or "Bad CRC-32 for file 'q.npy'" in err, err
        assert not (tmp_path / "new").exists()


_LONG_RUN_SCRIPT = """
import resource, sys
import numpy as np
import genplan
from genplan.cli import main

q0 = genplan.load("panda").q_default
np.savez(sys.argv[1], t=np.array([0.0, 9000.0]), q=np.array([q0, q0]))
limit = int(2.5e9)
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
sys.exit(main(["execute", "--robot", "panda", "--trajectory", sys.argv[1], "--out", sys.argv[2]]))
"""


def test_integrity_rerun_a_run_too_long_to_log_is_refused_before_allocating(tmp_path):
    """A 9000 s trajectory under a 2.5 GB address-space limit aborted the interpreter (a failed
    native allocation of its log, SIGABRT; without a limit it took 10 GB): now its log's size is
    computed before the run and refused, one line naming the duration and the bound."""
    import subprocess
    import sys

    files = [str(tmp_path / "long.npz"), str(tmp_path / "log.npz")]
    run = subprocess.run([sys.executable, "-c", _LONG_RUN_SCRIPT, *files], capture_output=True, text=True, timeout=300)
    assert run.returncode == 2, (run.returncode, run.stderr[-2000:])
    assert run.stderr.startswith("genplan: error: trajectory: 9000 s at dt = 0.001 s") and run.stderr.count("\n") == 1
    assert "more than the 1.00 GiB a run may take" in run.stderr, run.stderr
    assert not (tmp_path / "log.npz").exists()
