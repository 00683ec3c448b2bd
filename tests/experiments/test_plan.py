"""``genplan bench plan`` (Table II) prints its table and writes JSON (tiny N; the real runs are
documented)."""

import json

import pytest

from genplan.cli import main


def test_bench_plan_json_genplan_and_ompl(tmp_path, capsys) -> None:
    out = tmp_path / "plan.json"
    assert main(["bench", "plan", "--env", "panda_shelf", "--sampler", "all", "--planner", "all", "--queries", "2",
                 "--seed", "3", "--ompl-time-limit", "5", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    rows = {(r["planner"], r["sampler"]): r for r in data["rows"]}
    assert set(rows) == {("genplan", "uniform"), ("genplan", "gan"), ("genplan", "hybrid"),
                         ("ompl", "ProjectedStateSpace+RRTConnect")}
    for r in rows.values():
        for key in ("success_rate", "t_ave_s", "projections", "extensions"):
            assert key in r
        assert r["queries"] == 2 and 0.0 <= r["success_rate"] <= 100.0
    assert rows[("genplan", "uniform")]["paper"]["t_ave_s"] == 1.44
    assert rows[("genplan", "hybrid")]["success_rate"] == 100.0
    assert data["ratios"]["panda_shelf"]["ompl_over_uniform"] > 0
    assert "uniform_over_gan" in capsys.readouterr().out


def test_bench_plan_seed_sweep(tmp_path) -> None:
    """--seeds A..B: per-seed rows (the same as single-seed runs but for the times) and the median
    per (env, planner, sampler)."""
    out = tmp_path / "sweep.json"
    assert main(["bench", "plan", "--env", "panda_shelf", "--sampler", "uniform", "--queries", "2", "--seeds", "3..4",
                 "--workers", "2", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert [r["seed"] for r in data["per_seed"]] == [3, 4] and data["executor"]["workers"] == 2
    single = tmp_path / "single.json"
    assert main(["bench", "plan", "--env", "panda_shelf", "--sampler", "uniform", "--queries", "2", "--seed", "4",
                 "--out", str(single)]) == 0
    one = json.loads(single.read_text())["rows"][0]
    row = data["per_seed"][1]["rows"][0]
    for key in ("success_rate", "projections", "extensions", "nodes"):
        assert row[key] == one[key], key
    (agg,) = data["aggregate"]
    assert (agg["env"], agg["planner"], agg["sampler"]) == ("panda_shelf", "genplan", "uniform")
    values = [r["rows"][0]["projections"] for r in data["per_seed"]]
    assert agg["projections"] == sum(values) / 2  # the median of two
    assert agg["paper"]["t_ave_s"] == 1.44


def test_bench_plan_both_algorithms(tmp_path, capsys) -> None:
    """--algorithm all: every sampler's row for each algorithm, on the same queries; the ratios of
    each algorithm, the first's as ``ratios``."""
    out = tmp_path / "plan.json"
    assert main(["bench", "plan", "--env", "panda_shelf", "--sampler", "all", "--algorithm", "all", "--queries", "2",
                 "--seed", "3", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["algorithms"] == ["crrt", "rrt_connect"]
    rows = {(r["algorithm"], r["sampler"]): r for r in data["rows"]}
    assert set(rows) == {(a, s) for a in ("crrt", "rrt_connect") for s in ("uniform", "gan", "hybrid")}
    assert all(r["queries"] == 2 and r["success_rate"] == 100.0 for r in rows.values())
    by = data["ratios_by_algorithm"]
    assert data["ratios"] == by["crrt"]
    for alg in ("crrt", "rrt_connect"):
        u, g = rows[(alg, "uniform")], rows[(alg, "gan")]
        assert by[alg]["panda_shelf"]["uniform_over_gan"] == u["t_ave_s"] / g["t_ave_s"]
    text = capsys.readouterr().out
    assert "rrt_connect panda_shelf: uniform_over_gan" in text
    # a cRRT-only run plans the same queries to the same counts
    single = tmp_path / "crrt.json"
    assert main(["bench", "plan", "--env", "panda_shelf", "--sampler", "uniform", "--queries", "2", "--seed", "3",
                 "--out", str(single)]) == 0
    one = json.loads(single.read_text())["rows"][0]
    assert one["algorithm"] == "crrt"
    for key in ("success_rate", "projections", "extensions", "nodes"):
        assert one[key] == rows[("crrt", "uniform")][key], key


def test_bench_plan_certified_edges(tmp_path) -> None:
    """--edge-check certified: the settings in the JSON say so, the plans succeed and pay for
    motion certificates (mean per query)."""
    out = tmp_path / "certified.json"
    assert main(["bench", "plan", "--env", "panda_shelf", "--sampler", "gan", "--queries", "2", "--seed", "3",
                 "--edge-check", "certified", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["settings"]["edge_check"] == "certified"
    (row,) = data["rows"]
    assert row["success_rate"] == 100.0
    assert row["motion_certificates"] > 0


def test_bench_plan_with_another_learned_sampler_file(tmp_path, monkeypatch) -> None:
    """--model ROBOT=FILE: the gan rows of that robot's environments use the file (here a tiny flow,
    which plans otherwise than the shipped GAN), and the JSON names it with its hash; the uniform
    rows are untouched."""
    from genplan.samplers.flow import default_config, train

    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path / "cache"))
    model = train(default_config("panda", iterations=20, data_size=300, hidden=(16,), steps=2, w_cost=0.0, seed=1),
                  progress=False)
    weights, card = model.save(tmp_path / "tiny_flow.safetensors")
    rows = {}
    for name, extra in (("shipped", []), ("flow", ["--model", f"panda={weights}"])):
        out = tmp_path / f"{name}.json"
        assert main(["bench", "plan", "--env", "panda_shelf", "--sampler", "all", "--queries", "2", "--seed", "3",
                     *extra, "--out", str(out)]) == 0
        data = json.loads(out.read_text())
        rows[name] = {r["sampler"]: r for r in data["rows"]}
        if name == "flow":
            assert data["models"] == {"panda": {"file": str(weights), "format": "genplan-flow/1",
                                                "weights_sha256": json.loads(card.read_text())["weights_sha256"]}}
        else:
            assert data["models"] == {}
    assert rows["flow"]["uniform"]["projections"] == rows["shipped"]["uniform"]["projections"]
    assert rows["flow"]["gan"]["projections"] != rows["shipped"]["gan"]["projections"]


def test_bench_plan_rows_name_their_failed_queries() -> None:
    """Each row lists the indices of the queries that failed, in the environment's query order, so
    that a failure can be replayed: with a budget too small for some queries, the listed ones are
    exactly those a fresh planner with the same seed fails again."""
    import genplan
    from genplan.experiments.benchmarks.plan import run_genplan
    from genplan.planning import Planner, PlannerSettings, environment

    env = environment("panda_shelf")
    robot = genplan.load(env.robot)
    queries = env.queries(robot, n=6, seed=3)
    tight = PlannerSettings(max_extensions=20, retries=0)
    row = run_genplan("panda_shelf", "uniform", queries, 3, tight, progress=False)
    planner = Planner(robot, world=env.world(robot), sampler="uniform", settings=tight, seed=3)
    replay = [i for i, q in enumerate(queries) if not planner.plan(q.start, q.goals).success]
    assert row["failed_queries"] == replay
    assert 0 < len(replay) < len(queries), replay  # the budget fails some queries, not all
    assert row["success_rate"] == pytest.approx(100.0 * (len(queries) - len(replay)) / len(queries))


def test_bench_plan_data_sampler_rows(tmp_path) -> None:
    """--sampler all+: the paper's samplers, adaptive and data (rows of the data set in the learned
    sampler's box, no model), each with its ratio to uniform."""
    out = tmp_path / "data.json"
    assert main(["bench", "plan", "--env", "panda_shelf", "--sampler", "all+", "--queries", "2", "--seed", "3",
                 "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    rows = {r["sampler"]: r for r in data["rows"]}
    assert set(rows) == {"uniform", "gan", "hybrid", "adaptive", "data"}
    row = rows["data"]
    assert row["success_rate"] == 100.0 and row["sampler_s"] > 0
    ratios = data["ratios"]["panda_shelf"]
    assert ratios["uniform_over_data"] == rows["uniform"]["t_ave_s"] / row["t_ave_s"]
    assert ratios["uniform_over_adaptive"] == rows["uniform"]["t_ave_s"] / rows["adaptive"]["t_ave_s"]


def test_bench_plan_checkers_alternate_and_list_the_queries_a_checker_refuses(monkeypatch) -> None:
    """run_checkers: one row per checker on the same queries; a query whose start the second
    checker refuses is listed in its row's refused_queries and counted as failed, its times are
    over the queries it planned, and vs_exact compares both on the queries both planned."""
    import numpy as np

    import genplan
    from genplan.experiments.benchmarks import plan as bench
    from genplan.planning import PlannerSettings, environment

    env = environment("panda_shelf")
    robot = genplan.load(env.robot)
    queries = env.queries(robot, n=3, seed=3)
    refused_start = np.asarray(queries[1].start)

    class RefusesOneStart:
        """The world's own answer, but the second query's start invalid."""

        def __init__(self, world) -> None:
            self.world = world

        def is_valid(self, qs):
            qs = np.asarray(qs)
            return ~np.asarray(self.world.in_collision(qs)) & ~np.all(np.abs(qs - refused_start) < 1e-12, axis=1)

    monkeypatch.setattr(bench, "_checker", lambda robot, world, c, m: c if c == "exact" else RefusesOneStart(world))
    exact, other = bench.run_checkers("panda_shelf", "gan", queries, 3, PlannerSettings(), False,
                                      checkers=["exact", "spheres"])
    assert (exact["checker"], other["checker"]) == ("exact", "spheres")
    assert exact["queries"] == 3 and exact["success_rate"] == 100.0 and "refused_queries" not in exact
    assert other["refused_queries"] == [1] and other["planned"] == 2 and other["queries"] == 3
    assert other["failed_queries"] == [1] and other["success_rate"] == pytest.approx(200.0 / 3)
    v = other["vs_exact"]
    assert v["queries"] == 2 and v["exact_success_rate"] == v["success_rate"] == 100.0
    assert v["exact_over_checker_t_ave"] == pytest.approx(v["exact_t_ave_s"] / v["t_ave_s"])
    assert other["t_ave_s"] == pytest.approx(v["t_ave_s"])  # the planned queries are the common ones


def test_bench_plan_sphere_checker_refusing_every_start_is_an_error(capsys, monkeypatch) -> None:
    """--checker spheres on the Panda shelf with a cover of 1 cm on every link (the default's
    wrist at 5 mm turned off: with it these starts are accepted): every start lies within a few
    millimetres of the table, inside the cover's reach, so each is refused, and the bench
    says so (exit 2) instead of writing rows of nothing; --sphere-max-error without the sphere
    checker, and certified edges with it, are usage errors before any query is made."""
    from genplan import spheres as sph

    monkeypatch.setitem(sph.DEFAULT_LINK_MAX_ERROR, "panda", {})
    assert main(["bench", "plan", "--env", "panda_shelf", "--sampler", "gan", "--queries", "2", "--seed", "3",
                 "--checker", "spheres"]) == 2
    assert "checker 'spheres': every query of panda_shelf refused (2)" in capsys.readouterr().err
    assert main(["bench", "plan", "--env", "panda_shelf", "--queries", "2", "--sphere-max-error", "0.005"]) == 2
    assert "--sphere-max-error" in capsys.readouterr().err
    assert main(["bench", "plan", "--env", "panda_shelf", "--queries", "2", "--checker", "all",
                 "--edge-check", "certified"]) == 2
    assert "--edge-check certified: it needs the exact checker" in capsys.readouterr().err


def test_bench_plan_checker_takes_one_several_or_all() -> None:
    """--checker: one name, several joined by commas (each once), or all; anything else is
    argparse's error naming the known checkers."""
    import argparse

    from genplan.experiments.benchmarks import plan as bench
    from genplan.planning import CHECKERS

    assert bench.checker_list("hybrid") == ["hybrid"]
    assert bench.checker_list("exact,hybrid") == ["exact", "hybrid"]
    assert bench.checker_list("all") == list(CHECKERS)
    for bad in ("voxels", "exact,exact", "exact,", ""):
        with pytest.raises(argparse.ArgumentTypeError, match="exact, spheres, hybrid"):
            bench.checker_list(bad)
