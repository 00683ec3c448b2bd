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
              "04_execute_with_the_controller.py", "05_your_own_robot.py"}
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
