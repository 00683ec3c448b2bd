"""``genplan bench adjust`` and ``genplan train seq2seq`` from the command line (small sizes)."""

import json
import math

import numpy as np
import pytest

from genplan.experiments.benchmarks.adjust import j2_problem
from genplan.cli import COMMANDS, main


def test_commands_are_registered() -> None:
    names = {(g, n): m for g, n, m, _ in COMMANDS}
    assert names[("bench", "adjust")] == "genplan.experiments.benchmarks.adjust"
    assert names[("train", "seq2seq")] == "genplan.cli.train_seq2seq"


def test_the_papers_j2_problem() -> None:
    x2, pe2 = j2_problem()
    np.testing.assert_allclose(pe2, [[0, 0, -0.75 * math.pi]])
    assert np.allclose(np.diff(x2[0, :, 2]), x2[0, 1, 2])  # constant velocity


def test_bench_latent_and_casadi_write_their_json(tmp_path, capsys) -> None:
    out = tmp_path / "lat.json"
    assert main(["bench", "adjust", "--method", "latent", "--objective", "j1", "--updates", "3",
                 "--problems", "2", "--out", str(out)]) == 0
    r = json.loads(out.read_text())
    for key in ("objective_curve", "rmse_pos_mm", "rmse_ang_deg", "ms_per_update", "max_abs_phi_deg",
                "constraint_ok", "ms_to_j1_below_1e-3", "per_problem", "machine", "model"):
        assert key in r, key
    assert len(r["objective_curve"]) == 4 and r["problems"] == 2 and r["ms_per_update"] > 0
    assert r["objective_curve"][0] == pytest.approx(np.mean([p["objective_initial"] for p in r["per_problem"]]))
    out = tmp_path / "cas.json"
    assert main(["bench", "adjust", "--method", "casadi", "--problems", "1", "--out", str(out)]) == 0
    c = json.loads(out.read_text())
    assert c["solved"] == 1 and c["ms_per_problem"] > 0 and c["constraint_ok"] is True
    assert c["rmse_pos_mm"] < 1e-3
    table = capsys.readouterr().out
    assert "ms/update" in table and "casadi" in table


def test_bench_j2_with_two_step_rules_and_figures(tmp_path) -> None:
    figs = tmp_path / "figs"
    assert main(["bench", "adjust", "--method", "all", "--objective", "j2", "--updates", "2", "--step", "gd",
                 "adaptive", "--out-dir", str(tmp_path), "--figures", str(figs), "--skip-casadi"]) == 0
    for m in ("latent", "random-latent", "direct-u"):
        for suffix, step in (("_gd", "gd"), ("", "adaptive")):
            r = json.loads((tmp_path / f"adjust_j2_{m}{suffix}.json").read_text())
            assert r["objective"] == "j2" and r["step"] == step
            assert r.get("diverged") or len(r["objective_curve"]) == 3
    assert (figs / "fig5_objective_j2.png").stat().st_size > 1000
    assert (figs / "fig5_objective_j2_gd.png").stat().st_size > 1000
    assert (figs / "fig11_j2_latent.png").stat().st_size > 1000


def test_bench_j1_figures(tmp_path) -> None:
    figs = tmp_path / "figs"
    assert main(["bench", "adjust", "--method", "all", "--objective", "j1", "--updates", "2", "--step",
                 "adaptive", "--problems", "27", "--out-dir", str(tmp_path), "--figures", str(figs),
                 "--skip-casadi"]) == 0
    for name in ("fig5_objective_j1", "fig6_theta_-pi_latent", "fig7_theta_0_latent",
                 "fig8_theta_pi_latent", "fig9_rmse"):
        assert (figs / f"{name}.png").stat().st_size > 1000, name


def test_bench_rejects_out_with_all(tmp_path, capsys) -> None:
    assert main(["bench", "adjust", "--method", "all", "--out", str(tmp_path / "x.json")]) == 2
    assert capsys.readouterr().err == ("genplan: error: --method all writes one JSON per method: use --out-dir, "
                                       "not --out\n")
    assert main(["bench", "adjust", "--method", "latent", "--step", "gd", "adam", "--out", str(tmp_path / "x.json")]) == 2
    assert "several --step rules write one JSON each" in capsys.readouterr().err
