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


def test_hard_queries_lists_the_failures_and_retries_each(tmp_path, monkeypatch, capsys) -> None:
    out = tmp_path / "hard.json"
    # one extension per attempt: the queries fail, and each is retried with the larger budget
    _run("hard_queries.py", ["--env", "panda_shelf", "--queries", "2", "--max-extensions", "1", "--budget", "300",
                             "--out", str(out)], monkeypatch)
    data = json.loads(out.read_text())
    from genplan.planning import ALGORITHMS

    assert set(data["failed"]) == {f"{a}/{s}" for a in ALGORITHMS for s in ("uniform", "gan", "hybrid")}
    hard = sorted({i for bad in data["failed"].values() for i in bad})
    assert hard and all(0 <= i < 2 for i in hard)
    assert [(r["query"], r["algorithm"]) for r in data["retried"]] == [(i, a) for i in hard for a in ALGORITHMS]
    assert any(r["success"] for r in data["retried"]) and data["table_settings"]["max_extensions"] == 1
    assert "max_extensions 300" in capsys.readouterr().out
