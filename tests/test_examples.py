"""The numbered scripts in examples/ run (each is what a new user copies first)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run(script: str, *args: str) -> str:
    proc = subprocess.run([sys.executable, str(EXAMPLES / script), *args], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_every_example_is_tested() -> None:
    tested = {"01_plan_with_gan_sampler.py", "02_ik_with_a_custom_task.py", "03_adjust_a_trajectory.py",
              "04_execute_with_the_controller.py", "05_your_own_robot.py", "06_adapt_a_learned_motion.py", "07_execute_any_robot.py",
              "08_plan_through_a_point_cloud.py"}
    assert {p.name for p in EXAMPLES.glob("*.py")} == tested


def test_01_plan_with_gan_sampler(tmp_path) -> None:
    pytest.importorskip("viser")
    out = run("01_plan_with_gan_sampler.py", "--out", str(tmp_path / "plan.html"))
    assert "success True" in out
    assert (tmp_path / "plan.html").stat().st_size > 100_000


def test_02_ik_with_a_custom_task() -> None:
    out = run("02_ik_with_a_custom_task.py")
    assert out.count("success True") == 3


def test_03_adjust_a_trajectory() -> None:
    out = run("03_adjust_a_trajectory.py")
    assert "inside the friction cone: True" in out


def test_04_execute_with_the_controller() -> None:
    out = run("04_execute_with_the_controller.py")
    lines = out.splitlines()
    assert all("stayed" in line for line in lines if line.startswith("gentle"))
    assert all("slipped" in line for line in lines if line.startswith("hasty"))
    turn = {line.split("  ")[0]: line for line in lines if line.startswith("turn-over")}
    assert "slipped" in turn["turn-over, unadjusted"] and "slipped" in turn["turn-over, J2"]
    assert "stayed" in turn["turn-over, J2Executable"]


def test_06_adapt_a_learned_motion(tmp_path) -> None:
    """The Panda shelf family: planned, a small model trained, adjusted to new goals and around a
    ball on a path (small sizes: the defaults take minutes); every success is a finished, checked
    trajectory, and the counts printed are the finish's own."""
    import re

    out = run("06_adapt_a_learned_motion.py", "--count", "24", "--epochs", "5", "--problems", "3",
              "--out-dir", str(tmp_path))
    family = re.search(r"family: (\d+) planned motions of 32 samples", out)
    assert family and int(family.group(1)) == 24
    assert (tmp_path / "family.safetensors").is_file() and (tmp_path / "family.json").is_file()
    goals = re.search(r"new goals: (\d+) of 3 finished", out)
    assert goals, out
    assert "obstacle: the original motion" in out
    assert ("adjusted: finished, clear of it" in out) or ("adjusted: failed: " in out)


def test_05_your_own_robot(tmp_path) -> None:
    """xArm7 (not a preset), the upright-cup task: a small sampler trained, evaluated against
    uniform starts, a plan around the box, the HTML view (small sizes: the defaults take minutes)."""
    out = run("05_your_own_robot.py", "--iterations", "100", "--data-size", "1000", "--eval-targets", "100",
              "--out-dir", str(tmp_path))
    assert "xarm7: 7 joints" in out
    trained = next(line for line in out.splitlines() if line.startswith("trained in"))
    # projection from GAN samples needs fewer steps than from uniform ones, even after 100 iterations
    gan, uniform = (float(x.split(" in ")[1].split(" steps")[0]) for x in trained.split("projection: ")[1].split(";")[0].split(", "))
    assert gan < uniform
    assert "plan: success True" in out
    assert (tmp_path / "cup.safetensors").is_file() and (tmp_path / "plan.json").is_file()
    if importlib.util.find_spec("viser") is not None:
        assert (tmp_path / "plan.html").stat().st_size > 100_000


def test_07_execute_any_robot(tmp_path) -> None:
    """A Panda shelf plan executed with a 20 % payload error, friction and offsets (one query)."""
    out = run("07_execute_any_robot.py", "--queries", "1", "--out-dir", str(tmp_path))
    lines = out.splitlines()
    on = next(line for line in lines if "DOB on" in line)
    off = next(line for line in lines if "DOB off" in line)
    assert "collision no" in on and "collision no" in off
    ratio = float(next(line for line in lines if "the observer cuts" in line).split("error ")[1].rstrip("x"))
    assert ratio > 3.0
    assert (tmp_path / "execute_panda.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "execute_panda_dob.npz").is_file() and (tmp_path / "execute_panda_no_dob.npz").is_file()


def test_08_plan_through_a_point_cloud(tmp_path) -> None:
    """The Panda shelf scene from three simulated depth cameras (small images), planned through as
    a cloud (two ball radii) and with the shelf as one mesh: no plan state, nor any state along
    its motions, touches the true scene; the thin cloud and the mesh plan what the boxes plan; the
    conservative cloud (balls of the voxel's edge) refuses the starts 5 mm above the table."""
    out = run("08_plan_through_a_point_cloud.py", "--queries", "2", "--width", "120", "--height", "90",
              "--out-dir", str(tmp_path))
    rows = {}
    for line in out.splitlines():
        cells = line.split()
        if " of " in line and cells[0] in ("primitives", "cloud,", "shelf"):
            at = cells.index("of")
            rows[line[:24].strip()] = [int(cells[at - 1]), int(cells[at + 1])] + [int(c) for c in cells[at + 2:at + 7]]
    assert set(rows) == {"primitives (the truth)", "cloud, r 4.5 mm", "cloud, r 10 mm", "shelf as one mesh"}, out
    for planned, queries, refused, states, touching, samples, touching_samples in rows.values():
        assert queries == 2 and touching == 0 and touching_samples == 0
        assert states == 0 or samples > states
    assert rows["primitives (the truth)"][0] == 2
    assert rows["cloud, r 4.5 mm"][0] == rows["shelf as one mesh"][0] == 2
    assert rows["cloud, r 10 mm"][2] == 2
    import numpy as np

    assert np.load(tmp_path / "cloud.npz")["points"].shape[1] == 3
    if importlib.util.find_spec("viser") is not None:
        assert (tmp_path / "cloud_plan.html").stat().st_size > 100_000
