"""``genplan bench plan`` (Table II) prints its table and writes JSON (tiny N; the real runs are
documented)."""

import json

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
