"""The standalone benchmark scripts in benches/ run on tiny sizes and write their JSON (the real
runs are documented in each script and in the README)."""

from __future__ import annotations

import json
import re
import runpy
import sys
from pathlib import Path

import pytest

BENCHES = Path(__file__).resolve().parents[1] / "benches"


def _run(script: str, args: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "argv", [script, *args])
    monkeypatch.syspath_prepend(str(BENCHES))  # as `python benches/<script>.py`: its siblings import
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


def test_plan_ab_plans_the_same_queries_with_both_builds(tmp_path, monkeypatch, capsys) -> None:
    import shutil

    import genplan

    # "before" is a copy of the installed package: the same code, so the same trees
    before = tmp_path / "before"
    shutil.copytree(Path(genplan.__file__).parent, before / "genplan", ignore=shutil.ignore_patterns("__pycache__"))
    out = tmp_path / "ab.json"
    _run("plan_ab.py", ["--before", str(before), "--env", "panda_shelf", "--queries", "2", "--rounds", "2",
                        "--out", str(out)], monkeypatch)
    (row,) = json.loads(out.read_text())["rows"]
    assert (row["env"], row["sampler"], row["algorithm"]) == ("panda_shelf", "gan", "rrt_connect")
    assert row["packages"] == {"before": str(before / "genplan"), "after": str(Path(genplan.__file__).parent)}
    assert row["same_counts"] and row["extensions"]["before"] == row["extensions"]["after"] > 0
    assert row["t_ave_s"]["before"] > 0 and row["t_ave_s"]["after"] > 0
    assert "same counts: True" in capsys.readouterr().out


def test_plan_ab_refuses_a_folder_without_a_package(tmp_path, monkeypatch, capsys) -> None:
    with pytest.raises(SystemExit):
        _run("plan_ab.py", ["--before", str(tmp_path), "--queries", "1"], monkeypatch)
    assert "--before: expected a folder holding a genplan package" in capsys.readouterr().err


def test_plan_ab_says_which_build_failed(tmp_path, monkeypatch) -> None:
    # a "before" package that cannot be imported: the error names the build and carries its stderr
    (tmp_path / "genplan").mkdir()
    (tmp_path / "genplan" / "__init__.py").write_text("raise ImportError('this build is broken')\n")
    with pytest.raises(SystemExit, match="(?s)the before build failed on panda_shelf.*this build is broken"):
        _run("plan_ab.py", ["--before", str(tmp_path), "--env", "panda_shelf", "--queries", "1", "--rounds", "1"],
             monkeypatch)


def test_plan_ab_refuses_a_before_that_is_the_installed_package(monkeypatch, capsys) -> None:
    import genplan

    # the folder the installed package is imported from: both builds are one package, refused
    # after the first round rather than after all of them
    installed = Path(genplan.__file__).parent
    with pytest.raises(SystemExit, match=re.escape(f"--before: both builds imported genplan from {installed}")):
        _run("plan_ab.py", ["--before", str(installed.parent), "--env", "panda_shelf", "--queries", "1",
                            "--rounds", "3"], monkeypatch)
    assert "round 2/3" not in capsys.readouterr().err


def test_distill_constraint_sweep_measures_the_teacher_and_each_student(tmp_path, monkeypatch, capsys) -> None:
    out = tmp_path / "sweep.json"
    _run("distill_constraint_sweep.py", ["--robot", "panda", "--seed", "5", "--w-cost", "0,0.5", "--iterations", "5",
                                         "--out", str(out)], monkeypatch)
    data = json.loads(out.read_text())
    assert [(r["model"], r["steps"], r["w_cost"]) for r in data["rows"]] == [("teacher", 8, 0.0), ("student", 1, 0.0),
                                                                            ("student", 1, 0.5)]
    for r in data["rows"]:
        assert 0.0 <= r["cluster_coverage"] <= 1.0 and 0.0 <= r["projection_success"] <= 1.0
        assert r["native_sample_us"] > 0 and r["train_s"] > 0
    assert data["command"].startswith("python benches/distill_constraint_sweep.py --robot panda --seed 5 --w-cost 0.0,0.5")
    with pytest.raises(SystemExit):
        _run("distill_constraint_sweep.py", ["--w-cost", "0.1,-1"], monkeypatch)
    assert "non-negative weights" in capsys.readouterr().err


def test_data_sampler_plan_plans_with_the_data_set_beside_uniform_and_the_gan(tmp_path, monkeypatch, capsys) -> None:
    out = tmp_path / "data.json"
    _run("data_sampler_plan.py", ["--env", "panda_shelf", "--queries", "2", "--seed", "3", "--out", str(out)],
         monkeypatch)
    data = json.loads(out.read_text())
    rows = {(r["protocol"], r["sampler"]): r for r in data["rows"]}
    assert set(rows) == {(p, s) for p in ("nodes", "edges") for s in ("uniform", "gan", "data", "data_box")}
    assert all(r["success_rate"] == 100.0 and r["uniform_over_this"] > 0 for r in rows.values())
    assert rows[("nodes", "data")]["sampler_s"] > 0 and rows[("nodes", "data")]["extensions"] > 0
    assert set(data["summary"]) == {f"{p}/{s}" for p in ("nodes", "edges") for s in ("uniform", "gan", "data", "data_box")}
    assert 0 < data["data_box_rows"]["panda_shelf"] < 25_000


def test_trajectory_check_times_the_checks_or_names_the_refusal(tmp_path, monkeypatch, capsys) -> None:
    out = tmp_path / "trajectory_check.json"
    _run("trajectory_check.py", ["--plans", "1", "--seed", "1", "--repeats", "1", "--out", str(out)], monkeypatch)
    data = json.loads(out.read_text())
    assert data["command"] == "python benches/trajectory_check.py --plans 1 --seed 1 --repeats 1"
    row = data["rows"][0]
    assert "refused" in row or 0 < row["collision_check_ms"] <= row["check_ms"]
    assert data["summary"]["timed"] + data["summary"]["refused"] <= 1 and "median:" in capsys.readouterr().out


def test_execute_prints_the_tick_table_and_the_dob_table(tmp_path, monkeypatch, capsys) -> None:
    out = tmp_path / "execute.json"
    _run("execute.py", ["--plans", "1", "--repeats", "1", "--out", str(out)], monkeypatch)
    data = json.loads(out.read_text())
    robots = {(r["robot"], r["configuration"].split(" on ")[0]) for r in data["ticks"]}
    assert {("ur5", "spatula (eq. 23, pancake)"), ("panda", "task space"), ("panda", "joint space"),
            ("kinova", "task space"), ("xarm7", "task space")} <= robots
    assert all(0 < r["us_per_tick_min"] <= r["us_per_tick"] and r["realtime_factor"] > 0 for r in data["ticks"])
    assert all(len(r["compute_us_runs"]) == 1 and r["compute_us_median"] > 0 for r in data["ticks"])
    assert len(data["load_average"]) == 3
    row = data["plans"]["rows"][0]
    for space in ("task", "joint"):
        assert row["planned"] and row[space]["error_ratio"] > 1.0 and row[space]["dob"]["collision_ticks"] == 0
        assert data["plans"]["summary"][space]["planned"] == 1
    assert data["plans"]["deviations"]["payload"]["mass"] == 0.6
    assert "error ratio without / with the observer" in capsys.readouterr().out


def test_execute_tick_rows_take_turns_and_report_the_median_tick_compute() -> None:
    import numpy as np

    tick_rows = runpy.run_path(str(BENCHES / "execute.py"))["tick_rows"]
    calls: list[str] = []

    class Log:
        def __init__(self, name: str, k: int) -> None:
            self.us_per_tick = 10.0 + k
            self.compute = np.array([1e-6, 2e-6 + 1e-6 * k, 9e-6])  # a preempted tick does not move the median
            self.t = np.zeros(3)
            self.meta = {"frame": "tool"}
            self.max_tracking_error_mm = 0.5

    def configuration(name: str, row: dict) -> tuple:
        def run() -> Log:
            calls.append(name)
            return Log(name, calls.count(name) - 1)
        return row, run

    fake = [configuration("a", {"robot": "ur5", "configuration": "spatula (eq. 23, pancake)", "joints": 6}),
            configuration("b", {"robot": "panda", "space": "task", "joints": 7})]
    tick_rows.__globals__["tick_configurations"] = lambda: fake
    rows = tick_rows(3)
    assert calls == ["a", "b", "a", "b", "a", "b"]
    assert [r["configuration"] for r in rows] == ["spatula (eq. 23, pancake)", "task space on tool"]
    for r in rows:
        assert r["us_per_tick_runs"] == [10.0, 11.0, 12.0] and r["us_per_tick"] == 11.0 and r["us_per_tick_min"] == 10.0
        assert r["compute_us_runs"] == pytest.approx([2.0, 3.0, 4.0]) and r["compute_us_median"] == pytest.approx(3.0)
    assert "max_error_mm" not in rows[0] and rows[1]["max_error_mm"] == 0.5


def test_free_space_plan_compares_the_same_queries_with_and_without_the_projector(tmp_path, monkeypatch) -> None:
    out = tmp_path / "free.json"
    _run("free_space_plan.py", ["--queries", "3", "--rounds", "2", "--out", str(out)], monkeypatch)
    data = json.loads(out.read_text())
    from genplan.planning import ALGORITHMS

    assert [r["algorithm"] for r in data["rows"]] == list(ALGORITHMS)
    for r in data["rows"]:
        # the same samples, the same trees: the projector had nothing to project
        assert r["success_free"] == r["success_projected"] == r["same_path"] == 3
        assert r["free_median_ms"] > 0 and r["projected_median_ms"] > 0 and r["projector_share_median"] > 0


def test_sphere_checker_counts_the_cover_and_times_both_checkers(tmp_path, monkeypatch) -> None:
    out = tmp_path / "spheres.json"
    monkeypatch.setenv("RAYON_NUM_THREADS", "1")  # what the script sets before genplan is imported
    _run("sphere_checker.py", ["--configs", "2000", "--rounds", "2", "--single", "200", "--queries", "2",
                               "--out", str(out)], monkeypatch)
    data = json.loads(out.read_text())
    assert data["cover"]["configs"] == 2000 and data["cover"]["missed"] == 0
    assert data["cover"]["exact_in_collision"] > 0
    assert all(len(v) == 2 and min(v) > 0 for v in data["checks"]["per_second"].values())
    assert data["plans"]["success"] == {"exact": 2, "spheres": 2}
    assert data["plans"]["median_ms"]["spheres"] > 0


def test_relative_terms_times_both_pose_terms_and_writes_the_ratio(tmp_path, monkeypatch, capsys) -> None:
    out = tmp_path / "relative_terms.json"
    _run("relative_terms.py", ["--n", "4", "--iterations", "2", "--rounds", "2", "--out", str(out)], monkeypatch)
    data = json.loads(out.read_text())
    medians = data["us_per_iteration_median"]
    assert set(medians) == {"frame_pose", "relative_pose", "python_custom"} and all(v > 0 for v in medians.values())
    assert all(len(v) == 2 for v in data["us_per_iteration_rounds"].values())
    assert data["ratio_relative_over_frame_pose"] == pytest.approx(medians["relative_pose"] / medians["frame_pose"])
    assert data["command"].startswith("python benches/relative_terms.py --n 4")
    assert "relative_pose / frame_pose" in capsys.readouterr().out


def test_custom_term_data_times_1_and_2_processes_on_the_same_rows(tmp_path, monkeypatch) -> None:
    out = tmp_path / "custom_term_data.json"
    _run("custom_term_data.py", ["--n", "8", "--shard-size", "4", "--rounds", "1", "--control-seconds", "0",
                                 "--out", str(out)], monkeypatch)
    data = json.loads(out.read_text())
    assert set(data["median_seconds"]) == {"process_1", "process_2", "thread_2"}
    assert data["speedup_2_processes_over_1"] == pytest.approx(data["median_seconds"]["process_1"]
                                                               / data["median_seconds"]["process_2"])
    assert data["task"]["primary"][1]["entry"] == "tests.custom_terms_example:OnCircle"
    assert data["command"].startswith("python benches/custom_term_data.py --n 8") and data["control_speedup"] is None


def test_roboplan_box_plans_the_same_queries_with_both_planners(tmp_path, monkeypatch, capsys) -> None:
    pytest.importorskip("roboplan.rrt")
    out = tmp_path / "roboplan_box.json"
    _run("roboplan_box.py", ["--queries", "2", "--seed", "3", "--out", str(out)], monkeypatch)
    data = json.loads(out.read_text())
    assert len(data["records"]) == 2 and data["ground_drop_m"] >= 0.001
    for r in data["records"]:
        for side in ("roboplan", "genplan"):
            assert r[side]["success"] and r[side]["length"] > 0
        assert r["genplan"]["free_for_itself"]  # genplan's path, checked again every 0.01 rad
        # roboplan's own length metric is the same joint-space L2 length
        assert r["roboplan"]["length"] == pytest.approx(r["roboplan"]["length_roboplan_metric"], rel=1e-9)
    assert data["summary"]["both_solved"] == 2
    assert "genplan length / roboplan's" in capsys.readouterr().out


def test_gan_training_times_both_builds_on_a_short_run(tmp_path, monkeypatch, capsys) -> None:
    import shutil

    import genplan

    # the baseline is a copy of the installed package: the same code in another folder
    before = tmp_path / "before"
    shutil.copytree(Path(genplan.__file__).parent, before / "genplan", ignore=shutil.ignore_patterns("__pycache__"))
    out = tmp_path / "gan_training.json"
    _run("gan_training.py", ["--robot", "panda", "--task", "panda_ik", "--iterations", "3", "--data-rows", "20",
                             "--data-size", "200", "--rounds", "1", "--baseline", str(before), "--out", str(out)], monkeypatch)
    data = json.loads(out.read_text())
    for build in ("this", "baseline"):
        train, gen = data["summary"][build]["train"], data["summary"][build]["data"]
        assert train["iterations"] == 3 and train["median_cpu_s"] > 0 and train["cpu_ms_per_iteration"] > 0
        assert train["full_run_cpu_s_estimate"] > train["median_setup_cpu_s"] and gen["rows"] == 20
    assert data["measurements"]["baseline"]["train"][0]["genplan"].startswith(str(before))
    assert set(data["ratio_this_over_baseline"]) == {"train", "data"}


def test_gan_training_refuses_a_folder_without_a_package(tmp_path, monkeypatch, capsys) -> None:
    with pytest.raises(SystemExit):
        _run("gan_training.py", ["--baseline", str(tmp_path), "--rounds", "1"], monkeypatch)
    assert "--baseline: expected a folder holding a genplan package" in capsys.readouterr().err


def test_execute_motions_swing_about_a_configuration_away_from_singularities() -> None:
    """The Panda's default configuration is kept; a UR5's (stretched: its tool Jacobian singular)
    is replaced by the best-conditioned of the seeded candidates, the same each call."""
    import numpy as np
    import pinocchio as pin

    import genplan
    from genplan import control

    bench = runpy.run_path(str(BENCHES / "execute.py"))
    centre, singular = bench["centre"], bench["SINGULAR"]

    def sigma_min(robot, q) -> float:
        j = pin.computeFrameJacobian(robot.model, robot.model.createData(), q, robot.frame_id(control.tool_frame(robot)),
                                     pin.LOCAL_WORLD_ALIGNED)
        return float(np.linalg.svd(j, compute_uv=False)[-1])

    panda, ur5 = genplan.load("panda"), genplan.load("ur5")
    np.testing.assert_array_equal(centre(panda), panda.normalize(panda.q_default))
    assert sigma_min(ur5, ur5.normalize(ur5.q_default)) < singular
    q = centre(ur5)
    assert sigma_min(ur5, q) >= 2 * singular
    np.testing.assert_array_equal(centre(ur5), q)
    assert np.all((q >= ur5.lower) & (q <= ur5.upper))


def test_nonconvex_meshes_times_the_ur10_against_a_baseline_build(tmp_path, monkeypatch, capsys) -> None:
    import shutil

    import genplan

    # the baseline is a copy of the installed package: both workers answer every round
    before = tmp_path / "before"
    shutil.copytree(Path(genplan.__file__).parent, before / "genplan", ignore=shutil.ignore_patterns("__pycache__"))
    out = tmp_path / "ur10.json"
    monkeypatch.syspath_prepend(str(BENCHES))
    script = runpy.run_path(str(BENCHES / "nonconvex_meshes.py"), run_name="nonconvex_meshes")
    assert script["main"](["--parts", "ur10", "--samples", "40", "--rounds", "3", "--baseline", str(before),
                           "--out", str(out)]) == 0
    ur10 = json.loads(out.read_text())["ur10"]
    b = ur10["baseline"]
    for build in ("before", "after"):
        assert set(b[build]["check_us"]) == {"hull", "decomposed"}
        assert all(v > 0 for v in b[build]["check_us"].values())
        assert len(b[build]["rounds_us"]) == 3
        assert b[build]["ratio_to_hulls"] == b[build]["check_us"]["decomposed"] / b[build]["check_us"]["hull"]
    assert b["after_before"]["decomposed"] == b["after"]["check_us"]["decomposed"] / b["before"]["check_us"]["decomposed"]
    assert ur10["rows"]["decomposed"]["missed"] == 0
    assert "UR10 decomposed / hulls: after" in capsys.readouterr().out


def test_execute_instructions_child_runs_each_row_once_and_refuses_an_unknown_one(monkeypatch, capsys, tmp_path) -> None:
    # the process valgrind runs: one JSON line per row with its ticks (the divisor of the count)
    _run("execute_instructions.py", ["--child", "panda:joint"], monkeypatch)
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines() if x.startswith("{")]
    assert [x["key"] for x in lines] == ["panda:joint"] and lines[0]["ticks"] == 2001
    with pytest.raises(SystemExit, match="unknown row 'panda:nowhere'"):
        _run("execute_instructions.py", ["--child", "panda:nowhere"], monkeypatch)
    # a callgrind dump's count is its totals line
    dump = tmp_path / "callgrind.out.1"
    dump.write_text("version: 1\nevents: Ir\nfn=(1) f\n3 12\ntotals: 87439865\n")
    assert runpy.run_path(str(BENCHES / "execute_instructions.py"))["totals"](dump) == 87439865


def test_free_space_settings_compares_extension_lengths(tmp_path, monkeypatch, capsys) -> None:
    """benches/free_space_settings.py: one row per family and value (and VAMP's when installed),
    each plan successful, ratios to the reference; a geometric mean per robot and over robots."""
    out = tmp_path / "fss.json"
    _run("free_space_settings.py", ["--robots", "ur5", "--families", "table_pick", "--problems", "1", "--rounds", "1",
                                    "--increments", "3", "10", "--balance", "0", "1", "--out", str(out)], monkeypatch)
    data = json.loads(out.read_text())
    arms = {r["arm"] for r in data["rows"]}
    expected = {"3", "10", "3+balance", "10+balance"}
    assert expected <= arms <= expected | {"vamp"}
    assert all(r["success_pct"] == 100.0 and r["plan_ms_median"] > 0 and r["over_reference"] > 0 for r in data["rows"])
    ref = data["rows"][0]["reference"]
    assert ref in ("vamp", "10") and [r["over_reference"] for r in data["rows"] if r["arm"] == ref] == [1.0]
    assert set(data["over_robots"]) == expected and data["default_max_increments"] == 3 and data["default_balance"]
    assert "geometric mean over the robots" in capsys.readouterr().out


def test_free_space_settings_refuses_the_report_seed(monkeypatch, capsys) -> None:
    with pytest.raises(SystemExit):
        _run("free_space_settings.py", ["--seed", "0"], monkeypatch)
    assert "seed 0" in capsys.readouterr().err
