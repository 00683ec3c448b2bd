"""The standalone benchmark scripts in benches/ run on tiny sizes and write their JSON (the real
runs are documented in each script and in the README)."""

from __future__ import annotations

import json
import runpy
import sys
from pathlib import Path

import pytest

BENCHES = Path(__file__).resolve().parents[1] / "benches"


def _run(script: str, args: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "argv", [script, *args])
    runpy.run_path(str(BENCHES / script), run_name="__main__")


def test_ik_settings_writes_one_row_per_variant(tmp_path, monkeypatch, capsys) -> None:
    out = tmp_path / "ik_settings.json"
    _run("ik_settings.py", ["--robots", "panda", "--targets", "6", "--seeds", "1", "--iterations", "20",
                            "--out", str(out)], monkeypatch)
    data = json.loads(out.read_text())
    mod = runpy.run_path(str(BENCHES / "ik_settings.py"))
    assert len(data["rows"]) == 2 * len(mod["VARIANTS"])  # uniform and GAN starts
    assert {r["variant"] for r in data["rows"]} == {v[0] for v in mod["VARIANTS"]}
    assert all(0.0 <= r["success_percent"] <= 100.0 and r["t_mean_ms"] > 0 for r in data["rows"])
    assert "whole_steps_mid_posture_mu_0.001" in capsys.readouterr().out


def test_ik_settings_refuses_the_report_seed(monkeypatch, capsys) -> None:
    with pytest.raises(SystemExit):
        _run("ik_settings.py", ["--seeds", "0", "--targets", "2"], monkeypatch)
    assert "seed 0" in capsys.readouterr().err
