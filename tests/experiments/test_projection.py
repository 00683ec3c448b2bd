"""``genplan bench projection`` (Table I) prints its table and writes JSON (tiny N; the real runs are
documented)."""

import json

from genplan.cli import main


def test_bench_projection_json(tmp_path, capsys) -> None:
    for solver in ("gauss-newton", "scipy"):
        out = tmp_path / f"{solver}.json"
        assert main(["bench", "projection", "--robot", "panda", "--tasks", "4", "--seed", "1", "--solver", solver, "--out", str(out)]) == 0
        data = json.loads(out.read_text())
        for kind in ("projection", "ik"):
            for key in ("success_rate", "t_ave_ms", "t_star_ave_ms", "steps_star"):
                assert key in data[kind]
            assert 0.0 <= data[kind]["success_rate"] <= 100.0
            assert data[kind]["tasks"] == 4
        assert data["paper"]["ik"]["success_rate"] == 76.4
    table = capsys.readouterr().out
    assert "uniform (gauss-newton)" in table and "uniform (scipy)" in table


def test_bench_projection_gan_init(tmp_path) -> None:
    out = tmp_path / "gan.json"
    assert main(["bench", "projection", "--robot", "panda", "--init", "gan", "--tasks", "6", "--seed", "2", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["init"] == "gan" and data["gan_sample_ms_per_task"] > 0
    assert data["paper"]["projection"]["steps_star"] == 1.9
    assert data["projection"]["success_rate"] == 100.0


def test_bench_projection_seed_sweep(tmp_path, capsys) -> None:
    """--seeds A..B: one row per seed, the same numbers as single-seed runs, and their median."""
    out = tmp_path / "sweep.json"
    assert main(["bench", "projection", "--robot", "panda", "--tasks", "5", "--seeds", "1..3", "--workers", "2",
                 "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["seeds"] == [1, 2, 3] and [r["seed"] for r in data["per_seed"]] == [1, 2, 3]
    assert data["executor"] == {"executor": "local-threads", "workers": 2}
    single = tmp_path / "single.json"
    assert main(["bench", "projection", "--robot", "panda", "--tasks", "5", "--seed", "2", "--out", str(single)]) == 0
    one = json.loads(single.read_text())
    for kind in ("projection", "ik"):
        assert data["per_seed"][1][kind]["success_rate"] == one[kind]["success_rate"]
        assert data["per_seed"][1][kind]["steps_star"] == one[kind]["steps_star"]
        rates = sorted(r[kind]["success_rate"] for r in data["per_seed"])
        assert data["aggregate"][kind]["success_rate"] == rates[1]  # the median of three
        assert data["aggregate"][kind]["tasks"] == 5
    assert data["aggregate_rule"] == "median across seeds" and data["paper"]["ik"]["success_rate"] == 76.4
    assert "| median " in capsys.readouterr().out


def test_bench_projection_workers_need_seeds(capsys) -> None:
    assert main(["bench", "projection", "--robot", "panda", "--workers", "2"]) == 2
    assert "--workers/--ray: they run the seeds of --seeds A..B; give --seeds" in capsys.readouterr().err
