"""``genplan bench ik`` prints its tables and writes JSON (tiny sizes; the real run is documented)."""

import json

from genplan.cli import main
from genplan.experiments.benchmarks.ik import IK_ROWS


def test_bench_ik_json(tmp_path, capsys) -> None:
    out = tmp_path / "ik.json"
    assert main(["bench", "ik", "--robots", "panda", "--targets", "12", "--plans", "1", "--seed", "1",
                 "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    panda = data["ik"]["panda"]
    assert panda["targets"] == 12 and panda["target_seed"] == 2001 and panda["task"] == "panda_ik"
    for row in IK_ROWS:
        r = panda[row]
        assert 0.0 <= r["success_within_budget"] <= r["success_rate"] <= 100.0 and r["t_mean_ms"] > 0
    for one in (r for r in IK_ROWS if "one_attempt" in r):
        assert panda[one]["attempts_max"] == 1
    assert panda["solve_ik"]["success_rate"] >= panda["gan_one_attempt"]["success_rate"]
    assert panda["solve_ik_uniform"]["success_rate"] >= panda["uniform_one_attempt"]["success_rate"]
    traj = data["trajectory"]
    if traj["planned"]:
        s = traj["summary"]
        assert s["max_velocity_ratio"]["max"] <= 1.0 and s["max_residual_ratio"]["max"] <= 1.0
        assert s["parameterisation_ms"]["median"] > 0
    assert "solve_ik" in capsys.readouterr().out


def test_bench_ik_without_trajectories(tmp_path) -> None:
    out = tmp_path / "ik.json"
    assert main(["bench", "ik", "--robots", "talos", "--targets", "5", "--plans", "0", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["trajectory"] is None and data["ik"]["talos"]["solve_ik"]["success_rate"] >= 0.0
