"""genplan reproduce: the orchestration (a subset of its steps), results.json and report.md."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

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


def test_reproduce_rejects_an_unknown_step(tmp_path, capsys) -> None:
    assert main(["reproduce", "--quick", "--out", str(tmp_path), "--only", "no-such-step"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("genplan: error: --only no-such-step: no step matches") and err.count("\n") == 1


def test_report_rebuilds_from_a_folder_of_json(tmp_path) -> None:
    out = tmp_path / "rep"
    assert main(["reproduce", "--quick", "--out", str(out), "--only", "Table I talos uniform"]) == 0
    (out / "report.md").unlink()
    (out / "results.json").unlink()
    assert main(["report", str(out)]) == 0
    report = (out / "report.md").read_text()
    assert report.startswith("# genplan benchmarks") and "| talos | projection | uniform" in report
    assert "84.4" in report  # the paper's Talos success rate beside ours



def test_report_has_the_algorithms_coverage_variants_ik_and_peers(tmp_path) -> None:
    """The committed JSON of `bench plan --algorithm all`, `bench coverage --variants`, `bench ik`
    and `bench peers` each get their section (and a folder without them none)."""
    results = Path(__file__).parents[2] / "benches" / "results"
    names = ["table2_genplan_algorithms.json", "table2_genplan_algorithms_nodes_only.json",
             "coverage_variants.json", "ik.json", "peers.json"]
    for name in names:
        shutil.copy(results / name, tmp_path / name)
    assert main(["report", str(tmp_path)]) == 0
    report = (tmp_path / "report.md").read_text()
    for words in ("### Both algorithms, edges checked", "### Both algorithms, nodes only", "rrt_connect",
                  "geometric mean", "### Coverage variants", "diversity_data_init", "## IK for users",
                  "solve_ik_uniform", "max_velocity_ratio", "[peers.md](peers.md)"):
        assert words in report, words
    for name in names:
        (tmp_path / name).unlink()
    assert main(["report", str(tmp_path)]) == 0
    report = (tmp_path / "report.md").read_text()
    assert "Both algorithms" not in report and "IK for users" not in report and "peers.md" not in report


def test_report_names_a_broken_json_file(tmp_path, capsys) -> None:
    assert main(["report", str(tmp_path / "missing")]) == 2
    assert "report: argument folder: " in capsys.readouterr().err
    (tmp_path / "table1_panda_uniform.json").write_text('{"tasks": 100,')
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"genplan: error: {tmp_path / 'table1_panda_uniform.json'}: not a valid JSON file")
    assert err.count("\n") == 1 and not (tmp_path / "report.md").exists()
    # valid JSON that lacks what the report reads: the file and the field
    (tmp_path / "table1_panda_uniform.json").write_text('{"tasks": 100, "projection": {}, "paper": {"projection": {}}}')
    assert main(["report", str(tmp_path)]) == 2
    assert capsys.readouterr().err == (f"genplan: error: {tmp_path / 'table1_panda_uniform.json'}.projection: no field "
                                       "'success_rate' (not what a genplan benchmark writes, or from another version)\n")


def test_the_quick_run_measures_the_shipped_ablations_and_the_full_run_trains_them(tmp_path) -> None:
    """--quick's coverage step reads the paper's ablation GANs from the package's models folder
    (no training: the bulk of the quick run's time before); the full run trains them."""
    from genplan.experiments.reproduce import FULL, QUICK, _steps
    from genplan.model_files import models_dir

    def coverage(sizes):  # type: ignore[no-untyped-def]
        return next(argv for title, argv in _steps(tmp_path, sizes) if title == "GAN coverage")

    quick, full = coverage(QUICK), coverage(FULL)
    assert quick[quick.index("--models") + 1] == str(models_dir()) and "--quick" in quick
    assert "--models" not in full and "--quick" not in full
