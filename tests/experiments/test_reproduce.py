"""genplan reproduce: the orchestration (a subset of its steps), results.json and report.md."""

from __future__ import annotations

import json

import pytest

from genplan.cli import main


def test_reproduce_a_subset_writes_results_and_report(tmp_path) -> None:
    out = tmp_path / "rep"
    assert main(["reproduce", "--quick", "--out", str(out), "--only", "Table I panda uniform"]) == 0
    res = json.loads((out / "results.json").read_text())
    assert res["quick"] is True and res["seed"] == 0 and res["machine"]["cores"] >= 1
    assert [s["step"] for s in res["steps"]] == ["Table I panda uniform"]
    assert res["steps"][0]["status"] == "ok" and res["steps"][0]["command"].startswith("genplan bench projection")
    row = res["results"]["table1_panda_uniform.json"]
    assert row["tasks"] == 100 and 0 < row["projection"]["success_rate"] <= 100
    report = (out / "report.md").read_text()
    assert "Table I" in report and "genplan reproduce --quick" in report
    assert "98.6" in report  # the paper's number stands beside ours


def test_reproduce_rejects_an_unknown_step(tmp_path) -> None:
    with pytest.raises(SystemExit, match="no step matches"):
        main(["reproduce", "--quick", "--out", str(tmp_path), "--only", "no-such-step"])


def test_report_rebuilds_from_a_folder_of_json(tmp_path) -> None:
    out = tmp_path / "rep"
    assert main(["reproduce", "--quick", "--out", str(out), "--only", "Table I talos uniform"]) == 0
    (out / "report.md").unlink()
    (out / "results.json").unlink()
    assert main(["report", str(out)]) == 0
    report = (out / "report.md").read_text()
    assert report.startswith("# genplan benchmarks") and "| talos | projection | uniform" in report
    assert "84.4" in report  # the paper's Talos success rate beside ours
    with pytest.raises(SystemExit, match="is not a folder"):
        main(["report", str(tmp_path / "missing")])
