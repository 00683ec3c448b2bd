"""Latent trajectory adjustment: the seq2seq paper's Section 4.3 (J1) and 5.2 (J2), and a
CasADi + IPOPT peer on the same problems.

    genplan bench adjust --method latent --objective j1 --updates 100 --out benches/results/adjust_j1_latent.json
    genplan bench adjust --method all --objective j1 --updates 100 --out-dir benches/results \\
        --figures benches/results/pancake
    genplan bench adjust --method casadi --objective j1 --out benches/results/adjust_j1_casadi.json

J1 problems: the paper's 27 end poses (y, z in {-0.1, 0, 0.1} m, theta in {-pi, 0, pi}); each
input is the S-curve from the origin pose at rest to the end pose. All problems of a method run
as one batch. J2 problem: the paper's Section 5.2 (input: constant velocity from the origin to
[0, 0, -3 pi / 4]; theta_end = -3 pi / 4, p_lim 0.2, theta_lim 0.5, alpha 1, beta 0.01,
v_lim [1.5, 1.5, 4.5]).

Methods: ``latent`` (case 1), ``random-latent`` (case 2, z ~ N(0, I) with ``--seed``),
``direct-u`` (case 3), ``casadi`` (direct transcription solved by IPOPT, friction cone hard; see
:mod:`genplan.experiments.peers.casadi`), ``all`` (the four in one run, one JSON per method in
``--out-dir``, and the figures). Step rule ``--step adaptive`` (default: eq. 7 with the paper's
learning rates inside a per-problem step size that halves when J rises and grows when it falls),
``--step gd`` (eq. 7 as written) or ``--step adam``; several can be given, each is measured;
JSON files of the non-default rules get a suffix.

JSON keys: ``objective_curve`` (mean objective per update, index 0 = before any update; for
casadi: [initial guess, solution]), ``rmse_pos_mm`` / ``rmse_ang_deg`` (J1: RMS over problems of
the end-position distance in the y-z plane and of the end-attitude error; J2: of how far the end
lies outside the allowed ball / band), ``ms_per_update`` (median wall time of one update of the
batch, divided by the batch size), ``ms_per_problem`` (casadi: median wall time of one solve),
``max_abs_phi_deg``, ``constraint_ok`` (every step of every trajectory strictly inside the
cone), ``ms_to_j1_below_1e-3`` (per problem: encoder pass plus updates until J1 < 1e-3, each at
``ms_per_update``), and per-problem details. Torch runs with ``--threads`` threads (default 1;
IPOPT is single-threaded too).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan.cli import args as A
from genplan.experiments.common import machine, table, write_json
from genplan.pancake.trajectories import j1_problems

GD_METHODS = ("latent", "random-latent", "direct-u")
ALL_METHODS = (*GD_METHODS, "casadi")
LEVEL = 1e-3
#: the step rule whose JSON and figures carry no suffix
DEFAULT_STEP = "adaptive"
PAPER = {
    "j1_mean_below_1e-3_after_updates": 5,
    "rmse_pos_mm_case1": 0.27,
    "rmse_ang_deg_case1": 0.30,
    "s_per_update_case1_2": 1.21,
    "s_per_update_case3": 1.05,
    "hardware": "Intel Core i7-8700",
}
J2_SETUP = {"theta_end": -0.75 * math.pi, "p_lim": 0.2, "theta_lim": 0.5, "alpha": 1.0, "beta": 0.01,
            "v_lim": (1.5, 1.5, 4.5)}


def j2_problem() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The Section 5.2 input (1, K, 3) and its end pose (1, 3)."""
    from genplan.pancake.trajectories import linear

    p_end = np.array([[0.0, 0.0, J2_SETUP["theta_end"]]])
    return linear(np.zeros(3), p_end[0])[None], p_end


def _ci95(h: NDArray[np.float64]) -> NDArray[np.float64]:
    n = h.shape[1]
    return 1.96 * h.std(1, ddof=1) / math.sqrt(n) if n > 1 else np.zeros(h.shape[0])


def _j1_np(p: NDArray[np.float64], phi: NDArray[np.float64], p_end: NDArray[np.float64]) -> NDArray[np.float64]:
    from genplan.pancake.physics import D_SCALE, f_dyn_np

    d = np.asarray(D_SCALE)
    return (((p[:, -1] - p_end) * d) ** 2).sum(-1) + f_dyn_np(phi)


def _j2_errors(p: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    dist = np.hypot(p[:, -1, 0], p[:, -1, 1])
    pos = np.maximum(dist - J2_SETUP["p_lim"], 0.0)
    ang = np.maximum(np.abs(p[:, -1, 2] - J2_SETUP["theta_end"]) - J2_SETUP["theta_lim"], 0.0)
    return pos, ang


def _common(objective: str, p: NDArray[np.float64], v: NDArray[np.float64], phi: NDArray[np.float64],
            p_end: NDArray[np.float64]) -> dict[str, Any]:
    from genplan.pancake.physics import cone_limit

    if objective == "j1":
        pos = np.hypot(*(p[:, -1, :2] - p_end[:, :2]).T)
        ang = np.abs(p[:, -1, 2] - p_end[:, 2])
        definition = "end error: distance in the y-z plane to p_end, |theta - theta_end|"
    else:
        pos, ang = _j2_errors(p)
        definition = "end error beyond J2's ranges: max(|(y, z)| - p_lim, 0), max(|theta - theta_end| - theta_lim, 0)"
    max_phi = np.abs(phi).max(-1)
    out: dict[str, Any] = {
        "rmse_pos_mm": 1e3 * float(np.sqrt(np.mean(pos**2))),
        "rmse_ang_deg": math.degrees(float(np.sqrt(np.mean(ang**2)))),
        "error_definition": definition,
        "max_abs_phi_deg": math.degrees(float(max_phi.max())),
        "constraint_ok": bool(np.all(max_phi < cone_limit())),
        "inside_cone": int(np.sum(max_phi < cone_limit())),
        "max_abs_velocity": np.abs(v).max((0, 1)).tolist(),
    }
    out["per_problem"] = [
        {"p_end": p_end[i].tolist(), "end": p[i, -1].tolist(), "err_pos_mm": 1e3 * float(pos[i]),
         "err_ang_deg": math.degrees(float(ang[i])), "max_abs_phi_deg": math.degrees(float(max_phi[i])),
         "max_abs_velocity": np.abs(v[i]).max(0).tolist()}
        for i in range(len(p))
    ]
    return out


def run_gd(method: str, objective: str, updates: int, lr: float | None, step: str, seed: int,
           model: Any, problems: int | None = None, snapshots: tuple[int, ...] = (),
           threads: int | None = None) -> tuple[dict[str, Any], Any]:
    """One gradient method on the J1 (27) or J2 (1) problems, as one batch."""
    from genplan.pancake.adjustment import adjust

    x_in, p_end = j1_problems() if objective == "j1" else j2_problem()
    if problems is not None:
        x_in, p_end = x_in[:problems], p_end[:problems]
    kw = {"p_end": p_end} if objective == "j1" else {"objective_kwargs": dict(J2_SETUP)}
    res = adjust(x_in, objective, method, updates, lr, model=model, step=step, seed=seed,
                 snapshots=snapshots, progress=True, threads=threads, **kw)
    h = res.objective_history
    mean = h.mean(1)
    first = res.first_update_below(LEVEL)
    ms_init = 1e3 * res.time_init_s / res.batch
    reached = first >= 0
    ms_to = ms_init + first * res.ms_per_update
    below = np.nonzero(mean < LEVEL)[0]
    out: dict[str, Any] = {
        "objective_curve": mean.tolist(),
        "objective_curve_ci95": _ci95(h).tolist(),
        "objective_curve_median": np.median(h, 1).tolist(),
        "objective_final_max": float(h[-1].max()),
        "lr": res.lr,
        "ms_per_update": res.ms_per_update,
        "ms_per_update_mean": 1e3 * res.time_updates_s / max(1, updates) / res.batch,
        "ms_init_per_problem": ms_init,
        "updates_to_mean_below_1e-3": int(below[0]) if len(below) else None,
        "problems_below_1e-3": int(reached.sum()),
        "ms_to_j1_below_1e-3": {
            "median": float(np.median(ms_to[reached])) if reached.any() else None,
            "max": float(ms_to[reached].max()) if reached.any() else None,
            "problems_reached": int(reached.sum()),
            "definition": "per problem: encoder pass + (first update with J < 1e-3) x ms_per_update",
        },
    }
    out.update(_common(objective, res.p, res.v, res.phi, p_end))
    for i, row in enumerate(out["per_problem"]):
        row["objective_initial"] = float(h[0, i])
        row["objective_final"] = float(h[-1, i])
        row["first_update_below_1e-3"] = int(first[i])
    return out, res


def run_casadi(objective: str, problems: int | None = None) -> tuple[dict[str, Any], Any]:
    """CasADi + IPOPT, one solve per problem, warm-started from the S-curve to the end pose."""
    from genplan.experiments.peers.casadi import s_curve_accelerations, solve_batch
    from genplan.pancake.physics import phi_np, rollout_np

    x_in, p_end = j1_problems() if objective == "j1" else j2_problem()
    if problems is not None:
        x_in, p_end = x_in[:problems], p_end[:problems]
    u0 = np.stack([s_curve_accelerations(np.zeros(3), pe) for pe in p_end])
    x0 = np.stack([rollout_np(u) for u in u0])
    init = SimpleNamespace(p=x0[..., :3], v=x0[..., 3:], phi=phi_np(x0[..., 2], u0))
    if objective == "j1":
        res = solve_batch(np.zeros(3), p_end, progress=True)
        j_init = _j1_np(init.p, init.phi, p_end)
        j_final = _j1_np(res.p, res.phi, p_end)
    else:
        res = solve_batch(np.zeros(3), p_end, progress=True, objective="j2", beta=J2_SETUP["beta"],
                          v_lim=J2_SETUP["v_lim"])
        j_init, j_final = _j2_np(init), _j2_np(res)
    out: dict[str, Any] = {
        "objective_curve": [float(np.mean(j_init)), float(np.mean(j_final))],
        "objective_curve_note": "[initial guess (the S-curve's accelerations), IPOPT's solution]",
        "ms_to_j1_below_1e-3": {
            "median": 1e3 * float(np.median(res.solve_time_s)),
            "definition": "one IPOPT solve (its solution meets the end pose exactly, inside the cone)",
        } if objective == "j1" else None,
        "ms_per_problem": 1e3 * float(np.median(res.solve_time_s)),
        "ms_per_problem_mean": 1e3 * float(np.mean(res.solve_time_s)),
        "ms_per_problem_max": 1e3 * float(np.max(res.solve_time_s)),
        "build_ms": 1e3 * res.build_time_s,
        "solved": int(res.success.sum()),
        "status": sorted(set(res.status)),
        "iterations_median": float(np.median(res.iterations)),
        "formulation": ("direct transcription, K = 500, u and x as variables, dynamics and the end "
                        "pose as equalities, friction cone |phi| <= atan(mu) - 1e-3 rad as a hard "
                        "smooth constraint, cost dt sum ||D u||^2" if objective == "j1" else
                        "J2 ranges and the friction cone as hard constraints, velocity penalty of eq. 24 as cost"),
    }
    out.update(_common(objective, res.p, res.v, res.phi, p_end))
    for i, row in enumerate(out["per_problem"]):
        row["ms"] = 1e3 * float(res.solve_time_s[i])
        row["status"] = res.status[i]
        row["iterations"] = int(res.iterations[i])
        row["objective_final"] = float(np.atleast_1d(j_final)[i])
    return out, res


def _j2_np(res: Any) -> NDArray[np.float64]:
    """J2 (eq. 24) of numpy trajectories."""
    from genplan.pancake.physics import D_SCALE, f_dyn_np

    pos, ang = _j2_errors(res.p)
    d = np.asarray(D_SCALE)
    vel = (np.maximum(d * (np.abs(res.v) - np.asarray(J2_SETUP["v_lim"])), 0.0) ** 2).sum(-1).mean(-1)
    return pos + 0.1 * ang + J2_SETUP["alpha"] * f_dyn_np(res.phi) + J2_SETUP["beta"] * vel


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--method", choices=[*ALL_METHODS, "all"], default="all")
    p.add_argument("--objective", choices=["j1", "j2"], default="j1")
    p.add_argument("--updates", type=A.non_negative_int, default=None, help="gradient updates (default 100 for j1, 20 for j2)")
    p.add_argument("--lr", type=A.positive_float, default=None, help="learning rate (default: the paper's eta per case)")
    p.add_argument("--step", choices=["gd", "adaptive", "adam"], nargs="+", default=["adaptive"],
                   help="step rule(s), each measured in this run: adaptive = eq. 7 inside a per-problem "
                        "trust radius (a step that raises J is undone and retried at half length; default); "
                        "gd = eq. 7 with a fixed eta (the paper's); adam")
    p.add_argument("--seed", type=A.seed, default=0, help="seed of z ~ N(0, I) for random-latent")
    p.add_argument("--threads", type=A.positive_int, default=1, help="torch threads (default 1)")
    p.add_argument("--model", type=A.existing_file, default=None, help="model file (default: the shipped one)")
    p.add_argument("--problems", type=A.positive_int, default=None, help="only the first N problems (smoke tests)")
    p.add_argument("--out", type=A.output_file, default=None, help="JSON file (one method; folders are created)")
    p.add_argument("--out-dir", type=A.output_folder, default=None,
                   help="with --method all: write adjust_<objective>_<method>[_<step>].json here "
                        "(default benches/results; created if missing)")
    p.add_argument("--figures", type=A.output_folder, default=None,
                   help="write PNG figures to this folder (created if missing)")
    p.add_argument("--skip-casadi", action="store_true", help="with --method all: leave out the CasADi peer")


def _model_info(model: Any, path: Path | None) -> dict[str, Any]:
    from genplan.pancake.model import default_path

    return {"path": str(path or default_path()), "sha256": model.card.get("weights_sha256"),
            "encoder_stride": model.config.encoder_stride, "decoder_stride": model.config.decoder_stride,
            "trajectories": model.card.get("data", {}).get("trajectories")}


def main(args: argparse.Namespace) -> int:
    import torch

    from genplan.pancake.model import load_model

    if args.method == "all" and args.out is not None:
        raise A.UsageError("--method all writes one JSON per method: use --out-dir, not --out")
    if args.out is not None and len(args.step) > 1:
        raise A.UsageError("several --step rules write one JSON each: use --method all and --out-dir")
    out_dir = None
    if args.method == "all":
        out_dir = args.out_dir or A.check_output_folder(Path("benches/results"), "--out-dir")
    torch.set_num_threads(args.threads)
    updates = args.updates if args.updates is not None else (100 if args.objective == "j1" else 20)
    methods: tuple[str, ...] = ALL_METHODS if args.method == "all" else (args.method,)
    if args.method == "all" and args.skip_casadi:
        methods = GD_METHODS
    steps = list(dict.fromkeys(args.step))
    need_model = any(m != "casadi" for m in methods)
    model = load_model(args.model) if need_model else None
    base = {"benchmark": "adjust", "objective": args.objective, "threads": args.threads, "machine": machine(),
            "torch": torch.__version__, "paper": PAPER}
    if args.objective == "j2":
        base["j2_setup"] = {k: list(v) if isinstance(v, tuple) else v for k, v in J2_SETUP.items()}
    results: dict[tuple[str, str], dict[str, Any]] = {}
    raw: dict[tuple[str, str], Any] = {}
    snaps = tuple(s for s in (0, 10, 20) if s <= updates) if args.objective == "j2" else ()
    for m in methods:
        for st in (["-"] if m == "casadi" else steps):
            t0 = time.perf_counter()
            if m == "casadi":
                out, res = run_casadi(args.objective, args.problems)
                out.update({"method": m})
            else:
                try:
                    out, res = run_gd(m, args.objective, updates, args.lr, st, args.seed, model, args.problems,
                                      snapshots=snaps, threads=args.threads)
                except FloatingPointError as exc:  # eq. 7 with too large an eta: report it
                    print(f"{m} ({st}): diverged: {exc}")
                    out, res = {"diverged": True, "error": str(exc), "per_problem": [],
                                "lr": args.lr if args.lr is not None else _default_lr(args.objective, m, st)}, None
                out.update({"method": m, "step": st, "updates": updates, "seed": args.seed,
                            "model": _model_info(model, args.model)})
            out["wall_s"] = time.perf_counter() - t0
            out["problems"] = len(out["per_problem"])
            results[(m, st)] = {**base, **out}
            raw[(m, st)] = res
    _print(args.objective, results)
    if out_dir is not None:
        for (m, st), r in results.items():
            suffix = f"_{st}" if st not in (DEFAULT_STEP, "-") else ""
            write_json(out_dir / f"adjust_{args.objective}_{m}{suffix}.json", r)
    elif args.out is not None:
        write_json(args.out, next(iter(results.values())))
    if args.figures is not None:
        _figures(args.figures, args.objective, results, raw, steps)
    return 0


def _default_lr(objective: str, method: str, step: str) -> float:
    from genplan.pancake.adjustment import default_lr

    return default_lr(objective, method, step)


def _print(objective: str, results: dict[tuple[str, str], dict[str, Any]]) -> None:
    rows = []
    for (m, st), r in results.items():
        if r.get("diverged"):
            rows.append([m, st, r["lr"], "diverged"] + ["-"] * 10)
            continue
        curve = r["objective_curve"]
        rows.append([m, st, r.get("lr", "-"), curve[0], curve[min(5, len(curve) - 1)] if m != "casadi" else "-",
                     curve[-1], r["rmse_pos_mm"], r["rmse_ang_deg"], r["max_abs_phi_deg"], r["constraint_ok"],
                     r.get("ms_per_update", "-"), r.get("ms_per_problem", "-"),
                     (r.get("ms_to_j1_below_1e-3") or {}).get("median", "-") if objective == "j1" else "-",
                     r.get("problems_below_1e-3", r.get("solved", "-"))])
    print(table(["method", "step", "eta", "J[0]", "J[5]", "J[end]", "RMSE pos mm", "RMSE ang deg", "max|phi| deg",
                 "cone ok", "ms/update", "ms/problem", "ms to J<1e-3", "reached"], rows))


def _figures(fig_dir: Path, objective: str, results: dict[tuple[str, str], dict[str, Any]],
             raw: dict[tuple[str, str], Any], steps: list[str]) -> None:
    from genplan.experiments import figures_seq2seq as F

    fig_dir.mkdir(parents=True, exist_ok=True)
    ok = {k: r for k, r in results.items() if not r.get("diverged")}
    written = []
    for st in steps:
        tag = "" if st == DEFAULT_STEP else f"_{st}"
        curves = {m: (np.asarray(r["objective_curve"]), np.asarray(r["objective_curve_ci95"]))
                  for (m, s_), r in ok.items() if s_ == st}
        if curves:
            written.append(F.objective_curves(curves, fig_dir / f"fig5_objective_{objective}{tag}.png",
                                              f"{objective.upper()}: objective vs update (step rule {st})",
                                              LEVEL if objective == "j1" else None))
    if objective == "j1":
        _, p_end = j1_problems()
        for (m, st), res in raw.items():
            if res is None or m not in ("latent", "casadi"):
                continue
            tag = "" if st in (DEFAULT_STEP, "-") else f"_{st}"
            n = len(res.p)
            for fig_no, th, name in ((6, -math.pi, "-pi"), (7, 0.0, "0"), (8, math.pi, "pi")):
                sel = np.nonzero(np.isclose(p_end[:n, 2], th))[0]
                if len(sel) == 0:
                    continue
                label = (f"{m} ({st}) after {results[(m, st)]['updates']} updates" if m != "casadi"
                         else "CasADi + IPOPT")
                written.append(F.trajectories(res.p[sel], res.phi[sel], p_end[sel],
                                              fig_dir / f"fig{fig_no}_theta_{name}_{m}{tag}.png",
                                              f"{label}: final attitude {name}"))
        rows = [(m if st in (DEFAULT_STEP, "-") else f"{m} {st}", r["rmse_pos_mm"], r["rmse_ang_deg"])
                for (m, st), r in ok.items()]
        written.append(F.rmse_bars(rows, fig_dir / "fig9_rmse.png", "end-pose RMSE over the 27 problems"))
        trows = []
        for (m, st), r in ok.items():
            if m == "casadi":
                trows.append(("casadi solve", r["ms_per_problem"]))
            elif r["ms_to_j1_below_1e-3"]["median"] is not None:
                trows.append((f"{m} {st} to J1<1e-3", r["ms_to_j1_below_1e-3"]["median"]))
        if trows:
            written.append(F.time_bars(trows, fig_dir / "time_to_solution_j1.png", "time per problem (median)"))
    else:
        for (m, st), res in raw.items():
            if res is None:
                continue
            tag = "" if st in (DEFAULT_STEP, "-") else f"_{st}"
            if m == "casadi":
                written.append(F.j2_snapshots({0: {"p": res.p, "v": res.v, "phi": res.phi}},
                                              fig_dir / "fig11_j2_casadi.png", "J2, CasADi + IPOPT solution",
                                              labels={0: "IPOPT"}))
            elif res.snapshots:
                written.append(F.j2_snapshots(res.snapshots, fig_dir / f"fig11_j2_{m}{tag}.png",
                                              f"J2, {m} ({st}): trajectories at updates {sorted(res.snapshots)}"))
    for w in written:
        print(f"wrote {w}")
