"""docs/BENCHMARKS.md: every measured table of genplan, made from the committed benchmark JSON.

    genplan report benches/results --benchmarks docs/BENCHMARKS.md

The page is the notes of :data:`TEMPLATE` (Markdown: what was measured, why, and what it
showed) with each ``{{name}}`` line replaced by the table :data:`TABLES` makes from the JSON files
below the results folder, followed by the command that wrote them (the JSON's own ``command``
where it records one), their date and machine. Nothing here measures anything: rerun a
benchmark, then this command; tests/experiments/test_benchmarks_md.py fails while the committed
page differs from what it writes.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from genplan.errors import GenplanError
from genplan.experiments.common import geometric_mean, read_json

#: the notes of the page, with a ``{{name}}`` line where each table of :data:`TABLES` goes
TEMPLATE = Path(__file__).with_name("benchmarks_md.template.md")
#: a table's place in the template: a line ``{{name}}``
MARKER = re.compile(r"^\{\{(?P<name>[a-z0-9_]+)\}\}$", re.M)

Results = dict[str, Any]


@dataclass(frozen=True)
class Table:
    """A table of the page: the JSON files it reads (below the results folder), the command that
    wrote them when the files do not record it, and the function that makes its Markdown."""

    files: tuple[str, ...]
    command: str
    make: Callable[[Results], str]


# ---------------------------------------------------------------------------------------------
# formatting
# ---------------------------------------------------------------------------------------------


def _md(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A Markdown table (cells as given: every number is formatted by its table)."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _mmd(x: float) -> str:
    """An MMD as the tables print it: four decimals below 0.1, three significant digits above."""
    return f"{x:.4f}" if x < 0.1 else f"{x:.3g}"


def _sci(x: float) -> str:
    """Three significant digits; below 0.01 as ``2.76e-4``."""
    if abs(x) >= 0.01:
        return f"{x:.3g}"
    mantissa, exponent = f"{x:.2e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:.1f} ms"


def _x(ratio: float) -> str:
    return f"{ratio:.2f}x"


def _rows(res: Results, name: str, **match: Any) -> list[Any]:
    """The rows of ``name`` whose fields equal ``match``."""
    return [r for r in res[name]["rows"] if all(r.get(k) == v for k, v in match.items())]


def _row(res: Results, name: str, **match: Any) -> Any:
    rows = _rows(res, name, **match)
    if len(rows) != 1:
        raise GenplanError(f"{name}: expected one row with {match}, found {len(rows)}")
    return rows[0]


ENVS = ("panda_shelf", "talos_task1", "talos_task2", "talos_task3")
ENV_NAMES = {"panda_shelf": "Panda, shelf", "talos_task1": "Talos, task 1", "talos_task2": "Talos, task 2",
             "talos_task3": "Talos, task 3"}


# ---------------------------------------------------------------------------------------------
# the tables
# ---------------------------------------------------------------------------------------------


def table1(res: Results) -> str:
    """Table I of the GAN paper: projection and IK, uniform and GAN starts, scipy beside."""
    rows = []
    for robot in ("panda", "talos"):
        for kind, kind_name in (("projection", "projection"), ("ik", "IK")):
            for init, init_name in (("uniform", "uniform"), ("gan", "GAN")):
                m = res[f"table1_{robot}_{init}.json"]
                r, p = m[kind], m["paper"][kind]
                scipy = ""
                if init == "uniform":
                    s = res[f"table1_{robot}_scipy.json"][kind]["t_ave_ms"]
                    first = robot == "panda" and kind == "projection"
                    scipy = f"{s:.3g} ({s / r['t_ave_ms']:.0f}x{' slower' if first else ''})"
                rows.append([robot, kind_name, init_name, f"{r['success_rate']:.1f}", f"{r['t_ave_ms']:.3f}",
                             f"{r['steps_star']:.1f}", p["success_rate"], p["t_ave_ms"], scipy])
    return _md(["robot", "task", "init", "success %", "T_ave ms", "steps*", "paper success %", "paper T_ave ms",
                "scipy least_squares T_ave ms"], rows)


def table2(res: Results) -> str:
    """Table II of the GAN paper: the cRRT with each sampler, OMPL beside."""
    rows = []
    for env in ENVS:
        by = {s: _row(res, "table2_genplan.json", env=env, sampler=s) for s in ("uniform", "gan", "hybrid")}
        ompl = _row(res, "table2_ompl.json", env=env)
        paper = by["uniform"]["paper"], by["gan"]["paper"]
        rows.append([ENV_NAMES[env], *(f"{by[s]['t_ave_s']:.3f}" for s in by),
                     _x(by["uniform"]["t_ave_s"] / by["gan"]["t_ave_s"]),
                     f"{paper[0]['t_ave_s']:g} / {paper[1]['t_ave_s']:g}",
                     f"{ompl['t_ave_s']:.3g} ({ompl['success_rate']:.0f} %)"])
    return _md(["environment", "uniform s", "GAN s", "hybrid s", "uniform / GAN", "paper uniform / GAN s",
                "OMPL s (success)"], rows)


def _algorithms(res: Results, edges: str, nodes: str, learned: dict[str, str] | None = None) -> str:
    """Mean plan times of both algorithms (uniform / learned / hybrid), edges checked, with the
    uniform / learned ratios, and those of the nodes-only run."""
    rows = []
    for env in ENVS:
        cells = [ENV_NAMES[env] + (f" ({learned[env]})" if learned else "")]
        times, ratios = [], []
        for algorithm in ("crrt", "rrt_connect"):
            by = {s: _row(res, edges, env=env, sampler=s, algorithm=algorithm) for s in ("uniform", "gan", "hybrid")}
            times.append(" / ".join(f"{by[s]['t_ave_s']:.3f}" for s in by))
            ratios.append(_x(by["uniform"]["t_ave_s"] / by["gan"]["t_ave_s"]))
        node_ratios = []
        for algorithm in ("crrt", "rrt_connect"):
            u, g = (_row(res, nodes, env=env, sampler=s, algorithm=algorithm) for s in ("uniform", "gan"))
            node_ratios.append(_x(u["t_ave_s"] / g["t_ave_s"]))
        rows.append([*cells, *times, *ratios, ", ".join(node_ratios)])
    what = "learned" if learned else "GAN"
    return _md(["environment", "cRRT s", "RRT-Connect s", f"cRRT uniform / {what}", f"RRT-Connect uniform / {what}",
                "nodes only: cRRT, RRT-Connect"], rows)


def table2_algorithms(res: Results) -> str:
    """Table II with both algorithms, edges checked and nodes only."""
    return _algorithms(res, "table2_genplan_algorithms.json", "table2_genplan_algorithms_nodes_only.json")


def table2_talos_flow(res: Results) -> str:
    """Both algorithms with the Talos flow as the learned sampler (the Panda keeps its GAN)."""
    learned = {"panda_shelf": "GAN", "talos_task1": "flow", "talos_task2": "flow", "talos_task3": "flow"}
    return _algorithms(res, "table2_talos_flow.json", "table2_talos_flow_nodes_only.json", learned)


def _failed(rows: Sequence[Any]) -> str:
    """The success and failed queries of the rows below 100 %, as ``99 %, 38`` (one row) or
    ``98 %, 18 and 38``; "" when every row succeeded."""
    bad = [r for r in rows if r["success_rate"] < 100]
    if not bad:
        return ""
    parts = []
    for r in bad:
        queries = [str(q) for q in r["failed_queries"]]
        parts.append(f"{r['success_rate']:.0f} %, " + (" and ".join(queries) if len(queries) <= 2 else ", ".join(queries)))
    return "; ".join(parts)


def table2_all_samplers(res: Results) -> str:
    """Every sampler, both algorithms, both protocols: uniform / sampler per environment and
    their geometric mean, with the failed queries."""
    rows = []
    for algorithm, algorithm_name in (("crrt", "cRRT"), ("rrt_connect", "RRT-Connect")):
        for name, protocol in (("table2_all_samplers_nodes_only.json", "nodes only"),
                               ("table2_all_samplers.json", "edges checked")):
            uniform = {env: _row(res, name, env=env, sampler="uniform", algorithm=algorithm) for env in ENVS}
            cells = [f"{algorithm_name}, {protocol}"]
            for sampler in ("gan", "hybrid", "adaptive", "data"):
                by = [_row(res, name, env=env, sampler=sampler, algorithm=algorithm) for env in ENVS]
                ratios = [uniform[env]["t_ave_s"] / r["t_ave_s"] for env, r in zip(ENVS, by)]
                mean = geometric_mean(ratios)
                failed = _failed(by)
                if sampler in ("gan", "data"):
                    text = ", ".join(f"{v:.2f}" for v in ratios) + f"x; **{mean:.2f}x**"
                    if sampler == "gan":
                        text += f" (task 3: {failed})" if failed and algorithm_name == "cRRT" and protocol == "nodes only" \
                            else (f" ({failed})" if failed else "")
                    else:
                        text += f" ({failed})" if failed else ", all 100 %"
                else:
                    text = f"{mean:.2f}x" + (f" ({failed})" if failed else "")
                cells.append(text)
            rows.append(cells)
    order = [0, 2, 1, 3]  # cRRT and RRT-Connect nodes only, then both edges checked
    return _md(["algorithm, protocol", "GAN", "hybrid", "adaptive", "data (no training)"], [rows[i] for i in order])


def _coverage_cells(r: Any, steps_with_success: bool) -> list[str]:
    steps = f"{r['projection_steps_mean']:.2f}"
    return [f"{r['cluster_coverage']:.2f}", _mmd(r["mmd"]),
            f"{r['projection_success'] * 100:.0f} %, {steps}" if steps_with_success else steps,
            f"{r['native_sample_us']:.1f}"]


def flow_coverage(res: Results) -> str:
    """The pure flow-matching flows, large and small: coverage against held-out data."""
    c = res["coverage_flow.json"]
    rows = []
    for robot in ("panda", "talos"):
        for label in ("flow_pure", "flow_pure_small"):
            r = c[robot][label]
            cfg = r["config"]
            rows.append([robot.capitalize(), f"flow, {len(cfg['hidden'])} x {cfg['hidden'][0]}, {cfg['steps']} steps",
                         *_coverage_cells(r, False), f"{r['train_s']:.0f}"])
    return _md(["robot", "variant", "cluster coverage", "MMD", "projection steps", "native us/sample", "train s"], rows)


def distilled_coverage(res: Results) -> str:
    """The shipped GAN, the flow teacher and its one-step student, measured in one run."""
    c = res["coverage_distilled.json"]
    names = {"shipped_gan": "shipped GAN", "flow_pure": "flow, 8 steps (teacher)", "flow_distilled": "flow, distilled to 1 step"}
    rows = []
    for robot in ("panda", "talos"):
        for label, name in names.items():
            r = c[robot][label]
            train = f"{r['train_s']:.0f}" + (" (card)" if label == "shipped_gan" else "")
            rows.append([robot.capitalize(), name, *_coverage_cells(r, True), train])
    return _md(["robot", "sampler", "cluster coverage", "MMD", "projection: success, steps", "native us/sample",
                "train s"], rows)


def talos_flow_plan(res: Results) -> str:
    """The Talos flow against the shipped GAN on the Table II queries (cRRT), both protocols."""
    rows = []
    for task in (1, 2, 3):
        name = f"sampler_variant_plan_talos_flow_task{task}.json"
        cells = [f"task {task}"]
        for protocol in ("nodes", "edges"):
            u = _row(res, name, protocol=protocol, sampler="uniform")
            cells.append(_ms(u["t_ave_s"]))
            for sampler in ("gan", "gan_variant"):
                r = _row(res, name, protocol=protocol, sampler=sampler)
                cells.append(f"{_ms(r['t_ave_s'])}, {r['extensions']:.0f} ext, {_x(u['t_ave_s'] / r['t_ave_s'])}")
        rows.append(cells)
    return _md(["Talos", "nodes only: uniform", "GAN", "flow", "edges checked: uniform", "GAN", "flow"], rows)


def data_sampler_plan(res: Results) -> str:
    """Uniform / sampler on the Table II queries for the shipped GAN, the Talos flow, the data set
    and the data set in the GAN's box."""
    summary = res["data_sampler_plan.json"]["summary"]
    model = next(k for k in summary if k.startswith("nodes/model"))
    rows = []
    for key, name in (("gan", "shipped GAN"), ("model", "Talos flow (Talos rows)"), ("data", "the data set"),
                      ("data_box", "the data set in the GAN's box")):
        if key == "model":
            n, e = summary[model], summary[model.replace("nodes/", "edges/")]
            rows.append([name, "", *(_x(v) for v in n["per_env"]), f"({_x(n['geometric_mean'])} over the three)",
                         ", ".join(_x(v) for v in e["per_env"]), f"({_x(e['geometric_mean'])})"])
            continue
        n, e = summary[f"nodes/{key}"], summary[f"edges/{key}"]
        bold = "**" if key == "data_box" else ""
        rows.append([name, *(_x(v) for v in n["per_env"]), f"{bold}{_x(n['geometric_mean'])}{bold}",
                     ", ".join(_x(v) for v in e["per_env"]), f"{bold}{_x(e['geometric_mean'])}{bold}"])
    return _md(["sampler", "Panda", "Talos 1", "Talos 2", "Talos 3", "geometric mean", "edges checked: per environment",
                "geometric mean"], rows)


def distill_cost_sweep(res: Results) -> str:
    """One-step students distilled with the constraint and joint-limit costs of each weight."""
    rows = [[f"{r['w_cost']:g}", f"{r['cluster_coverage']:.2f}", _mmd(r["mmd"]), f"{r['projection_steps_mean']:.2f}",
             f"{r['train_s']:.0f}"]
            for r in res["coverage_tuning/distill_constraint_panda_seed1.json"]["rows"] if r["model"] == "student"]
    return _md(["cost weight", "cluster coverage", "MMD", "projection steps", "train s"], rows)


def j1(res: Results) -> str:
    """The seq2seq paper's J1: latent, random latent and direct-U adjustment, CasADi beside."""
    rows = []
    for method, name in (("latent", "latent (the paper's case 1)"), ("random-latent", "random latent (case 2)"),
                         ("direct-u", "direct U (case 3)")):
        r = res[f"adjust/adjust_j1_{method}.json"]
        curve = r["objective_curve"]
        # the time to J1 < 1e-3 of a method that brings every problem there (median per problem)
        reached = r["problems_below_1e-3"] == len(r["per_problem"])
        rows.append([name, f"{curve[0]:.3g}", _sci(curve[5]), _sci(curve[-1]),
                     f"{r['rmse_pos_mm']:.3g} mm / {r['rmse_ang_deg']:.3g} deg",
                     f"{r['inside_cone']} / {len(r['per_problem'])}", f"{r['ms_per_update']:.2f} ms",
                     f"{r['ms_to_j1_below_1e-3']['median']:.1f} ms" if reached else "-"])
    c = res["adjust/adjust_j1_casadi.json"]
    rows.append(["CasADi + IPOPT, hard cone", "", "", "exact", f"{c['rmse_pos_mm']:.0e} mm",
                 f"{c['inside_cone']} / {len(c['per_problem'])}", "", f"{c['ms_per_problem']:.0f} ms per solve"])
    return _md(["method", "J1 before", "after 5 updates", "after 100", "end RMSE", "in the cone", "per update",
                "to J1 < 1e-3"], rows)


def control(res: Results) -> str:
    """The turn-over executed at 1 kHz under the reference deviations: each trajectory's tracking
    error, friction-cone angle and the pancake's fate."""
    c = res["control.json"]

    def fate(r: Any) -> str:
        if not r["slipped"]:
            return "stays"
        return f"slides off at {r['first_slip_time_s']:.2f} s"

    runs = [("latent-adjusted for J2 + execution margins (`J2Executable`, 500 Adam updates, 4.1 s), P-D + DOB", c,
             "stays (leaves in the tail: the flip)"),
            ("same, without the DOB", c["without_dob"], None),
            ("latent-adjusted for the paper's J2 (20 updates), P-D + DOB", c["paper_j2"], None),
            ("CasADi + IPOPT J2 optimum (hard cone), P-D + DOB", c["casadi_j2"], None),
            ("unadjusted input (constant velocity, 0.5 s), P-D + DOB", c["unadjusted"], None)]
    def mm(x: float) -> str:
        return f"{x:.2f}" if x < 1 else f"{x:#.3g}"

    rows = [[name, f"{mm(r['max_tracking_error_mm'])} / {r['max_tracking_error_deg']:#.3g}",
             f"{r['max_abs_phi_deg']:.1f}", text or fate(r)] for name, r, text in runs]
    return _md(["trajectory", "max error mm / deg", "max abs(phi) deg", "pancake"], rows)


def robots(res: Results) -> str:
    """Every robot through one loading path: FK against Pinocchio, collision against coal."""
    rows = []
    for r in res["robots.json"]["rows"]:
        rows.append([r["robot"], r["nq"], "yes" if r["srdf"] else "computed",
                     r["self_pairs"], f"{r['fk_max_error']:.1e}", f"{r['agreement_hulls'] * 100:.2f} %",
                     f"{r['agreement_meshes'] * 100:.2f} %, {r['disagree_max_distance_meshes'] * 1e3:.1f} mm",
                     f"{r['load_ms']:.0f}"])
    return _md(["robot", "nq", "SRDF", "self pairs", "FK error vs Pinocchio", "agreement with coal, same hulls",
                "coal on raw meshes: agreement, largest disagreement distance", "load ms"], rows)


def _card_evaluation(card: Any, label: str) -> str:
    """A GAN card's evaluation: projection and IK from GAN against uniform starts."""
    e = card["evaluation"]
    rows = []
    for kind, name in (("projection", "projection onto the manifold: success, steps*"),
                       ("ik", "IK to the target: success, steps*")):
        g, u = e["gan"][kind], e["uniform"][kind]
        rows.append([name, f"{g['success_rate']:.1f} %, {g['steps_star']:.2f}",
                     f"{u['success_rate']:.1f} %, {u['steps_star']:.2f}", f"{g['steps_star'] / u['steps_star']:.2f}"])
    return _md([label, "GAN starts", "uniform starts", "GAN / uniform steps*"], rows)


def xarm_cup(res: Results) -> str:
    """The xArm7 cup GAN's card evaluation: GAN against uniform starts."""
    return _card_evaluation(res["../../examples/xarm7/upright_cup_gan.json"], "xArm7, cup upright")


def baxter_tray_card(res: Results) -> str:
    """The Baxter tray GAN's card evaluation: GAN against uniform starts."""
    return _card_evaluation(res["../../examples/baxter/tray_gan.json"], "Baxter, tray in both hands")


def baxter_tray_quiet_training(res: Results) -> str:
    """The Baxter tray GAN trained with the defaults on a quiet machine from an empty cache: the
    data's, the training's and the whole run's seconds (its card), and the evaluation."""
    c = res["baxter_tray_train_quiet.json"]
    t, e = c["training"], c["evaluation"]
    load = t["load_average_1min_start_end"]
    row = [f"{c['data']['seconds']:.0f}", f"{t['seconds']:.0f}", f"**{t['total_seconds_including_data'] / 60:.1f} min**",
           f"{load[0]:.1f} -> {load[1]:.1f}",
           f"{e['gan']['projection']['success_rate']:.1f} %, {e['gan']['projection']['steps_star']:.2f}",
           f"{e['uniform']['projection']['success_rate']:.1f} %, {e['uniform']['projection']['steps_star']:.2f}"]
    return _md(["data s", "training s", "data + training + evaluation", "load (1 min) start -> end",
                "GAN projection: success, steps*", "uniform: success, steps*"], [row])


def scaling(res: Results) -> str:
    """Data generation on 1 and 2 local workers and Ray: wall time, throughput, speed-up."""
    s = res["scaling.json"]
    rows = []
    for robot in ("panda", "talos"):
        for key, r in s[robot].items():
            local = r["executor"].startswith("local")
            name = (f"local, {r['workers']} worker{'s' if r['workers'] > 1 else ''}" if local
                    else f"Ray, {r['workers']} CPUs")
            speed = s[robot]["local-1"]["wall_median_s"] / r["wall_median_s"]
            local_same = s[robot].get(f"local-{r['workers']}")
            extra = (f" ({r['wall_median_s'] / local_same['wall_median_s']:.2f}x local {r['workers']}'s time)"
                     if not local and local_same is not None else "")
            rows.append([robot.capitalize(), name, f"{r['samples']:,}",
                         f"{r['wall_median_s']:.2f} ({r['wall_min_s']:.2f})", f"{r['samples_per_s']:,.0f}",
                         f"{r['samples_per_s_per_core']:,.0f}", f"{speed:.2f}x{extra}"])
    return _md(["robot", "executor", "samples", "wall s", "samples/s", "per core", "speed-up"], rows)


#: every table of the page, by its name in the template
def adapt(res: Results) -> str:
    """A learned Panda family adapted to held-out goals (latent adjustment + finish) against direct
    optimisation, replanning and ProMP, and around a ball on each path."""
    a = res["adapt_panda.json"]
    r = a["rows"]

    def cells(name: str, label: str, updates: str) -> list[str]:
        x = r[name]
        return [label, updates, f"{x['success_percent']:.1f} %", f"{x['max_end_error_mm']:.3f}",
                f"{x['max_residual_ratio']:.3g}", f"{x['ms_per_problem']:.1f}"]

    rows = [cells("latent", "latent adjustment + finish (genplan)", str(r["latent"]["updates"]))]
    d = r["direct"]
    ratio = d["update_ratio_to_latent"]
    rows.append(["direct optimisation, same objective and starts", str(d["updates"]),
                 f"{d['reached_latent_level_percent']:.0f} % reach the latent's objective",
                 "", "", f"{d['ms_per_update_per_problem']:.3f} per update (latent "
                 f"{d['latent_ms_per_update_per_problem']:.3f}); updates to the latent's level: "
                 + (f"{ratio:.2f}x" if ratio is not None else "never")])
    rows.append(["replanning (RRT-Connect + TOPP-RA) to the reached goal", "", f"{r['replanning']['success_percent']:.1f} %",
                 "", "", f"{r['replanning']['ms_per_problem']:.1f} (median {r['replanning']['median_ms']:.1f})"])
    if "success_percent" in r.get("promp", {}):
        pr = r["promp"]
        rows.append(["ProMP conditioned on the same start and goal", "", f"{pr['success_percent']:.1f} %",
                     f"{pr['max_end_error_mm']:.3f}", f"{pr['max_residual_ratio']:.3g} (median "
                     f"{pr['median_residual_ratio']:.3g}; genplan's {pr['genplan_median_residual_ratio']:.3g})",
                     f"{pr['ms_per_problem']:.1f}"])
    o = r["obstacle"]
    rows.append(cells("obstacle", f"a {100 * o['radius_m']:.0f} cm ball on each path at mid-time"
                      + (f", up to {o['starts']} starts" if o.get("starts", 1) > 1 else ""), str(o["updates"])))
    table = _md(["row", "updates", "success", "end error mm (max)", "residual / tolerance (max)", "ms per problem"], rows)
    if "free_problems" not in o:
        return table
    parts = [f"of the {o['free_problems']} problems whose input starts and ends clear of the ball "
             f"{o['free_success_percent']:.1f} % succeed; of the {o['ends_reaimed']} whose end was moved to a clear "
             f"configuration first {o['reaimed_success_percent']:.1f} %; {o['starts_in_collision_percent']:.1f} % of the "
             f"inputs start inside the ball"]
    if "restarted_problems" in o:
        parts.append(f"{o['restarted_problems']} problems ran the other starts ({o['success_from_restart']} succeed "
                     f"from one), {o['starts_run_mean']:.2f} starts per problem on average")
    reasons = ", ".join(f"{k.strip()}: {v}" for k, v in sorted(o.get("failure_reasons", {}).items(), key=lambda kv: -kv[1]))
    if reasons:
        parts.append(f"failures by reason: {reasons}")
    return table + "\n\nThe ball: " + "; ".join(parts) + "."


#: the motion bench's results, one a robot
MOTION_FILES = ("motion.json", "motion_ur5.json", "motion_baxter.json", "motion_kinova.json")


#: the motion bench's arms besides VAMP's in the table, in its columns' order, with their headers (an arm
#: is a column when a robot's results hold it; a robot without it shows a dash there)
MOTION_ARMS = {
    "genplan_spheres": "genplan spheres: success, ms plan + simplify (plan / VAMP); length / VAMP",
    "genplan_hybrid": "genplan hybrid (spheres, contacts confirmed exactly): the same",
    "genplan_exact": "genplan exact: the same",
    "roboplan": "roboplan (Pinocchio + coal): the same",
    "ompl": "OMPL RRTConnect (genplan's exact checker from Python): the same",
}


def motion(res: Results) -> str:
    """Free-space planning against VAMP on MotionBenchMaker-style families, per robot: success,
    median planning and simplification time, path length against VAMP's; the geometric mean of
    the families' planning-time ratios. A robot VAMP does not ship (the Kinova) has genplan's arms
    only: their lengths in rad, no ratios. The columns are the arms of :data:`MOTION_ARMS` any
    robot's results hold (the hybrid checker was added to the bench after some robots' runs)."""
    rows = []
    present = {r["arm"] for name in MOTION_FILES for r in res[name]["rows"]}
    columns = [a for a in MOTION_ARMS if a in present]
    for name in MOTION_FILES:
        m = res[name]
        by = {(r["family"], r["arm"]): r for r in m["rows"]}
        families = list(dict.fromkeys(r["family"] for r in m["rows"]))
        arms = [a for a in columns if any(k[1] == a for k in by)]
        vamp = any(k[1] == "vamp" for k in by)
        for fam in families:
            if vamp:
                v = by[(fam, "vamp")]
                cells = [m["robot"], fam, f"{v['success_pct']:.0f} %, {v['plan_ms_median']:.2f} + {v['simplify_ms_median']:.2f}"]
            else:
                cells = [m["robot"], fam, "(not shipped)"]
            for arm in columns:
                if arm not in arms:
                    cells.append("-")
                    continue
                g = by[(fam, arm)]
                timing = f"{g['success_pct']:.0f} %, {g['plan_ms_median']:.2f} + {g['simplify_ms_median']:.2f}"
                cells.append(f"{timing} ({_x(g['plan_ms_over_vamp'])}); length {g['length_over_vamp_median']:.2f}x"
                             if vamp else f"{timing}; length {g['length_median']:.2f} rad")
            rows.append(cells)
        if vamp:
            means = {arm: geometric_mean([by[(f, arm)]["plan_ms_over_vamp"] for f in families]) for arm in arms}
            rows.append([m["robot"], "**geometric mean of the planning-time ratios**", "1x",
                         *[f"**{_x(means[arm])}**" if arm in means else "-" for arm in columns]])
    table = _md(["robot", "family", "VAMP: success, ms plan + simplify", *[MOTION_ARMS[a] for a in columns]], rows)
    # genplan's planner on VAMP's own spheres (hand-made, not a guaranteed cover), where run
    notes = []
    for name in MOTION_FILES:
        m = res[name]
        own = {r["family"]: r for r in m["rows"] if r["arm"] == "genplan_vamp_spheres"}
        if own:
            listed = ", ".join(f"{f} {_x(r['plan_ms_over_vamp'])}" for f, r in own.items())
            notes.append(f"genplan's planner on VAMP's own spheres of the {m['robot']} (`genplan_vamp_spheres` in "
                         f"{name}; hand-made, not a guaranteed cover): plan time over VAMP's {listed}; geometric mean "
                         f"**{_x(geometric_mean([r['plan_ms_over_vamp'] for r in own.values()]))}**.")
    return table + "".join("\n\n" + n for n in notes)


#: Table II's queries with each checker: the sphere cover at 5 mm, and the hybrid at the default
TABLE2_CHECKER_FILES = ("table2_checkers.json", "table2_hybrid_panda_shelf.json", "table2_hybrid_talos_task1.json",
                        "table2_hybrid_talos_task2.json", "table2_hybrid_talos_task3.json",
                        "table2_spheres_panda_shelf.json")


def table2_checkers(res: Results) -> str:
    """Table II's constrained plans (GAN sampler) with the exact checker against the spheres
    (a 5 mm cover) and the hybrid (the default 1 cm cover, its collisions confirmed by the exact
    geometry), each pair on the same queries, taking turns."""
    rows = []
    for name in TABLE2_CHECKER_FILES:
        for r in res[name]["rows"]:
            v = r.get("vs_exact")
            if v is None:
                continue
            cover = f" ({r['sphere_max_error_m'] * 1000:g} mm cover)" if r.get("sphere_max_error_m") else " (1 cm cover)"
            rows.append([r["env"], r["checker"] + cover, f"{v['exact_success_rate']:.0f} % / {v['success_rate']:.0f} %",
                         str(len(r.get("refused_queries") or [])),
                         f"{v['exact_t_ave_s'] * 1e3:.1f} / {v['t_ave_s'] * 1e3:.1f}",
                         f"{v['exact_t_median_s'] * 1e3:.1f} / {v['t_median_s'] * 1e3:.1f}",
                         f"**{_x(v['exact_over_checker_t_ave'])}**", _x(v["exact_over_checker_t_median"])])
    return _md(["environment", "checker", "success: exact / checker", "queries refused", "mean ms: exact / checker",
                "median ms: exact / checker", "speed-up (exact's mean over the checker's)", "on the medians"], rows)


def roboplan_box(res: Results) -> str:
    """roboplan's own UR5 example scene: its RRT-Connect + shortcutting against genplan's
    RRT-Connect + simplification on the same queries."""
    r = res["roboplan_box.json"]
    s = r["summary"]
    rows = [[name, f"{s[name]['success_pct']:.0f} %", f"{s[name]['plan_ms_median']:.2f} + {s[name]['shortcut_ms_median']:.2f}",
             f"{s[name]['length_median']:.3f}", f"{s[name]['paths_free_for_itself']} / {s[name]['paths_free_for_the_other']}"]
            for name in ("roboplan", "genplan")]
    return (_md(["planner", "success", "median ms: plan + shortcut", "median path length (rad)",
                 "paths free every 0.01 rad: by its own checker / the other's"], rows)
            + f"\n\nOver the {s['both_solved']} queries both solved: genplan's length over roboplan's, median "
            f"**{s['length_genplan_over_roboplan_median']:.3f}** (mean {s['length_genplan_over_roboplan_mean']:.3f}; "
            f"longer on {s['queries_genplan_longer']}); over the {s['both_free_for_both']} whose two paths pass every "
            f"check: median **{s['length_genplan_over_roboplan_median_both_free']:.3f}** (longer on "
            f"{s['queries_genplan_longer_both_free']}); roboplan's time over genplan's, median "
            f"{_x(s['time_roboplan_over_genplan_median'])}; roboplan {r['roboplan']['version']}; load average {_load(r)}.")


def gan_training(res: Results) -> str:
    """The CPU a default GAN training costs, this build against a baseline build, interleaved."""
    r = res["gan_training_baxter_tray.json"]
    s = r["summary"]
    rows = []
    for side in ("baseline", "this"):
        if side in s:
            t, d = s[side]["train"], s[side]["data"]
            rows.append([side, f"{t['cpu_ms_per_iteration']:.1f}", f"{t['full_run_cpu_s_estimate'] / 60:.1f}",
                         f"{d['full_data_cpu_s_estimate'] / 60:.1f}",
                         f"{(t['full_run_cpu_s_estimate'] + d['full_data_cpu_s_estimate']) / 60:.1f}"])
    load = _load(r)
    load = f"; load average {load}" if load != "-" else ""
    return (_md(["build", "training CPU ms / iteration", "training CPU min (10,000 iterations, estimated)",
                 "data CPU min (25,000 rows, estimated)", "total CPU min"], rows)
            + f"\n\n{r['rounds']} interleaved rounds of {s['this']['train']['iterations']} iterations and "
            f"{s['this']['data']['rows']:,} rows, {r['torch_threads']} torch thread{load}.")

def jerk_timing(res: Results) -> str:
    """Jerk-limited rest-to-rest moves: genplan's phase-synchronised S-curve against ruckig."""
    s = res["jerk_timing.json"]["summary"]
    return _md(["moves", "duration / ruckig's (phase sync.)", "ruckig's phase-sync. paths straight",
                "profile us: genplan / ruckig", "parameterize_jerk at 1 kHz with its checks (ms)"],
               [[str(s["moves"]), f"{s['ratio_phase_median']:.9f} (max {s['ratio_phase_max']:.9f})",
                 f"{s['ruckig_phase_straight']} of {s['moves']}",
                 f"{s['genplan_profile_us_median']:.2f} / {s['ruckig_phase_us_median']:.2f} "
                 f"({_x(s['profile_time_ratio_vs_ruckig_phase'])})", f"{s['genplan_parameterize_jerk_ms_median']:.2f}"]])


def free_space_settings(res: Results) -> str:
    """The free-space defaults' tuning run: per arm (max_increments, alternating or balanced
    trees), the planning time over VAMP's, geometric mean over the families, per robot and over
    the robots; the default's row in bold."""
    r = res["free_space_settings.json"]
    robots = list(dict.fromkeys(row["robot"] for row in r["rows"]))
    default = f"{r['default_max_increments']}+balance" if r["default_balance"] else str(r["default_max_increments"])
    rows = []
    for arm, overall in r["over_robots"].items():
        label = f"{arm.replace('+balance', ' steps, balanced')}" if "+" in arm else f"{arm} steps, alternating"
        cells = [label, *(_x(r["summary"][f"{robot}/{arm}"]) for robot in robots), _x(overall)]
        rows.append([f"**{c}**" for c in cells] if arm == default else cells)
    return _md(["extensions of at most (0.3 rad steps), trees", *robots, "over the robots"], rows)


def baxter_tray(res: Results) -> str:
    """Baxter carrying a tray in both hands through a padded two-box scene, every 1 kHz sample
    checked again with Pinocchio + coal."""
    rows = []
    for name in ("baxter_tray.json", "baxter_tray_hybrid.json"):
        b = res[name]
        s = b["summary"]
        rows.append([b["sampler"], f"{s['succeeded']} of {s['queries']}",
                     f"{s['all_samples_pass_independent_check']} ({s['samples_checked']:,} samples)",
                     f"{100 * s['min_clearance_m']:.2f} (padding {100 * s['padding_m']:.0f})",
                     f"{s['max_velocity_ratio_urdf']:.3f}", f"{1e3 * s['max_grip_position_error_m']:.2f}",
                     f"{1e3 * s['max_tray_tilt_rad']:.2f}", f"{s['median_plan_ms']:.0f}"])
    return _md(["sampler", "planned", "plans passing the independent check", "min clearance cm",
                "max velocity / limit", "grip error mm (max)", "tray tilt mrad (max)", "median plan ms"], rows)



def _load(r: Any) -> str:
    """A results file's load average (first and last reading), as the text of a cell."""
    la = r.get("load_average") or r.get("load_average_before_after") or r.get("load_average_1min_start_end") or []
    flat = [float(x) for part in la for x in (part if isinstance(part, list) else [part])]
    return f"{min(flat):.1f}-{max(flat):.1f}" if flat else "-"


def execute_ticks(res: Results) -> str:
    """The 1 kHz loop per robot: the wall time of a tick (controller, plant, observer, log), the
    median and the best of the runs, and how much faster than real time the loop runs."""
    r = res["execute_ticks.json"]
    def compute(t: Any) -> str:  # recorded since the rows take turns
        return f"{t['compute_us_median']:.2f}" if "compute_us_median" in t else "-"

    rows = [[t["robot"], t["configuration"], str(t["joints"]), compute(t), f"{t['us_per_tick']:.1f}",
             f"{t['us_per_tick_min']:.1f}", f"{t['realtime_factor']:.0f}x"] for t in r["ticks"]]
    return _md(["robot", "controller", "joints", "tick compute us (median)", "loop us / tick with the log (median)",
                "best run", "real time / wall time (median)"], rows) + f"\n\nLoad average during the run: {_load(r)}."


def execute_instructions(res: Results) -> str:
    """Instructions per 1 kHz tick (callgrind, ``Simulation::tick`` alone): a count the machine's
    load does not move."""
    r = res["execute_instructions.json"]
    rows = [[t["robot"], t["configuration"], str(t["joints"]), f"{t['instructions_per_tick'] / 1e3:.1f}k"]
            for t in r["rows"]]
    return _md(["robot", "controller", "joints", "instructions per tick"], rows)


def execute_tracking(res: Results) -> str:
    """The Panda shelf plans executed with an unknown payload, friction and offsets in the plant:
    tracking error with and without the disturbance observer, torques, limits, collisions."""
    r = res["execute.json"]["plans"]
    d = r["deviations"]
    rows = []
    for space, s in r["summary"].items():
        rows.append([space, str(s["planned"]), f"{s['max_error_mm_dob']:.2f} / {s['max_error_mm_no_dob']:.2f}",
                     f"{s['error_ratio_min']:.2f} (median {s['error_ratio_median']:.2f})",
                     f"{s['plans_at_least_3x']} of {s['planned']}",
                     f"{s['max_torque_ratio_dob']:.2f} / {s['max_torque_ratio_no_dob']:.2f}",
                     f"{s['plans_colliding_dob']} / {s['plans_colliding_no_dob']}",
                     f"{s['max_plan_residual_ratio']:.2f} / {s['max_residual_ratio_dob']:.0f}"])
    table = _md(["controller", "plans", "max tool error mm: DOB / none", "error without / with DOB: min",
                 "plans with a ratio >= 3", "max torque / limit: DOB / none", "plans touching: DOB / none",
                 "task residual / tolerance: plan / executed (max)"], rows)
    return (f"{table}\n\nIn the plant: {d['payload']['mass']} kg at `{d['payload']['link']}` (com "
            f"{d['payload']['com']}), Coulomb friction {d['coulomb']} N m, viscous {d['viscous']} N m s, "
            f"offsets {d['offset']} N m, per joint.")


def compiled_robot(res: Results) -> str:
    """genplan's data-driven sphere checker against the same Panda compiled in (VAMP's way), on the
    same states of one motion-bench scene: instructions per state (callgrind), VAMP's per edge
    state, and what the faster checker would make of genplan's planning time (Amdahl)."""
    r = res["compiled_robot.json"]
    ips = r["instructions_per_state"]
    labels = {"cover": "genplan's cover", "vamp": "VAMP's 59 spheres"}
    modes = (("single_random", "one state"), ("batch8", "8 states at once"), ("edge", "an edge's states (motion_free)"))
    rows = []
    for spheres, label in labels.items():
        i = ips[spheres]
        for mode, what in modes:
            g, c = i[f"{mode}_genplan"], i[f"{mode}_compiled"]
            rows.append([label, what, f"{g:,.0f}", f"{c:,.0f}", f"**{_x(g / c)}**"])
    a = r["summary"]["cover"]["amdahl"]
    b = a["by_instructions"]
    return (_md(["spheres", "check", "genplan instructions / state", "compiled", "genplan / compiled"], rows)
            + f"\n\nVAMP: {r['vamp']['instructions_per_edge_state']:,.0f} instructions per edge state on the same scene. "
            f"genplan's tests against obstacles and self pairs are {100 * ips['cover']['genplan_tests_share']:.0f} % of "
            f"its instructions, the compiled kinematics and placement {100 * ips['cover']['compiled_batch8_placement_share']:.0f} % "
            f"of the compiled check. The checker's share of genplan's planning time on the motion problems "
            f"({r['plans']['problems_per_family']} a family) is {a['checker_share']:.2f}: a checker "
            f"{b['checker_speedup']:.2f}x cheaper would make planning {b['plan_time_factor']:.2f}x as long. "
            f"Load average {min(r['load_1min_start'], r['load_1min_end']):.1f}-{max(r['load_1min_start'], r['load_1min_end']):.1f}.")


def point_clouds(res: Results) -> str:
    """The Panda shelf scene as a point cloud against its primitives: check cost, agreement with
    coal, the cost of a new frame, plans."""
    r = res["point_clouds.json"]
    c, sp, rp, co = r["check_us"], r["spheres_us"], r["replace_ms"], r["coal"]
    rows = [["`in_collision` per configuration (median of the rounds)", f"{c['primitives']:.1f} us",
             f"{c['cloud']:.1f} us ({_x(c['ratio'])})"],
            ["the sphere checker per configuration", f"{sp['primitives']:.1f} us", f"{sp['cloud']:.1f} us ({_x(sp['ratio'])})"],
            ["agreement with coal (each ball a coal sphere)", "-",
             f"{100 * co['agreement']:.2f} % ({co['missed']} missed, {co['extra']} extra)"],
            [f"replacing the cloud ({r['points']:,} points): with the {100 * r['voxel']:g} cm voxel / without", "-",
             f"{rp['voxel']:.1f} ms / {rp['no_voxel']:.1f} ms"]]
    plans = {name: f"{p['planned']} of {p['queries']} ({p['refused']} starts or goals refused); touching the "
             f"primitives: {p['states_touching']} of {p['states']:,} states, {p['motion_samples_touching']} of "
             f"{p['motion_samples']:,} motion samples" for name, p in r["plans"].items()}
    for name, text in plans.items():
        if name != "primitives":
            rows.append([f"Table II shelf queries planned, {name.replace('cloud ', 'balls of ')} m",
                         plans.get("primitives", "-"), text])
    return (_md(["measure", "primitives", f"cloud ({r['balls']:,} balls of {100 * r['radius']:g} cm)"], rows)
            + f"\n\n{r['configurations']:,} random configurations; load average {_load(r)}.")


def custom_term_data(res: Results) -> str:
    """Training data for a task with a Python term on 1 and 2 worker processes (and 2 threads),
    with the control that measures what the machine gave."""
    r = res["custom_term_data.json"]
    m, cpu = r["median_seconds"], r["median_cpu_seconds"]
    rows = [[side.replace("_", " x"), f"{m[side]:.1f}", f"{cpu[side]:.1f}", f"{r['configurations_per_second'][side]:.1f}"]
            for side in ("process_1", "process_2", "thread_2")]
    return (_md(["workers", "median s", "median CPU s", "configurations / s"], rows)
            + f"\n\n{r['n']:,} configurations in shards of {r['shard_size']}, {r['rounds']} rounds; 2 processes over 1: "
            f"**{r['speedup_2_processes_over_1']:.2f}x** (median of the rounds' ratios "
            f"{r['speedup_median_of_round_ratios']:.2f}x); the control (pure Python on 1 or 2 processes): "
            f"{r['control_speedup']:.2f}x; load average {_load(r)}.")


TABLES: dict[str, Table] = {
    "table1": Table(("table1_panda_uniform.json", "table1_panda_gan.json", "table1_panda_scipy.json",
                     "table1_talos_uniform.json", "table1_talos_gan.json", "table1_talos_scipy.json"),
                    "genplan bench projection --robot R --init {uniform,gan} --tasks 500 --seed 0 [--solver scipy] "
                    "--out benches/results/table1_R_{uniform,gan,scipy}.json", table1),
    "table2": Table(("table2_genplan.json", "table2_ompl.json"),
                    "genplan bench plan --env all --sampler all --queries 100 --seed 0 --out "
                    "benches/results/table2_genplan.json; OMPL: genplan bench plan --env all --planner ompl --queries 10 "
                    "--seed 0 --ompl-time-limit 20 --out benches/results/table2_ompl.json", table2),
    "table2_algorithms": Table(("table2_genplan_algorithms.json", "table2_genplan_algorithms_nodes_only.json"),
                               "genplan bench plan --env all --sampler all --algorithm all --queries 100 --seed 0 "
                               "[--edge-resolution 0] --out benches/results/table2_genplan_algorithms[_nodes_only].json",
                               table2_algorithms),
    "table2_talos_flow": Table(("table2_talos_flow.json", "table2_talos_flow_nodes_only.json"),
                               "genplan bench plan --env all --sampler all --algorithm all --queries 100 --seed 0 "
                               "--model talos=models/talos_flow.safetensors [--edge-resolution 0] --out "
                               "benches/results/table2_talos_flow[_nodes_only].json", table2_talos_flow),
    "table2_all_samplers": Table(("table2_all_samplers.json", "table2_all_samplers_nodes_only.json"),
                                 "genplan bench plan --env all --sampler all+ --algorithm all --queries 100 --seed 0 "
                                 "[--edge-resolution 0] --out benches/results/table2_all_samplers[_nodes_only].json",
                                 table2_all_samplers),
    "flow_coverage": Table(("coverage_flow.json",),
                           "genplan bench coverage --no-planar --variants flow_pure,flow_pure_small --seed 0 --figures "
                           "benches/results/coverage_flow --out benches/results/coverage_flow.json", flow_coverage),
    "distilled_coverage": Table(("coverage_distilled.json",),
                                "genplan bench coverage --no-planar --robots panda talos --variants "
                                "shipped_gan,flow_pure,flow_distilled --seed 0 --threads 1 --figures "
                                "benches/results/coverage_distilled --out benches/results/coverage_distilled.json",
                                distilled_coverage),
    "talos_flow_plan": Table(tuple(f"sampler_variant_plan_talos_flow_task{t}.json" for t in (1, 2, 3)),
                             "python benches/sampler_variant_plan.py --env talos_taskN --model "
                             "models/talos_flow.safetensors --queries 100 --seed 0 --out "
                             "benches/results/sampler_variant_plan_talos_flow_taskN.json", talos_flow_plan),
    "data_sampler_plan": Table(("data_sampler_plan.json",),
                               "python benches/data_sampler_plan.py --queries 100 --seed 0 --model "
                               "talos=models/talos_flow.safetensors --out benches/results/data_sampler_plan.json",
                               data_sampler_plan),
    "distill_cost_sweep": Table(("coverage_tuning/distill_constraint_panda_seed1.json",),
                                "python benches/distill_constraint_sweep.py --robot panda --seed 1 --w-cost 0,0.01,0.1,1 "
                                "--iterations 10000 --out benches/results/coverage_tuning/distill_constraint_panda_seed1.json",
                                distill_cost_sweep),
    "j1": Table(("adjust/adjust_j1_latent.json", "adjust/adjust_j1_random-latent.json", "adjust/adjust_j1_direct-u.json",
                 "adjust/adjust_j1_casadi.json"),
                "genplan bench adjust --method all --objective j1 --updates 100 --out-dir benches/results/adjust", j1),
    "control": Table(("control.json",), "genplan bench control --out benches/results/control.json", control),
    "adapt": Table(("adapt_panda.json",), "genplan bench adapt --model models/panda_shelf_seq2seq.safetensors --data "
                   "DATA --held-out HELD_OUT --problems 200 --out benches/results/adapt_panda.json", adapt),
    "motion": Table(MOTION_FILES,
                    "genplan bench motion --robot {panda,ur5,baxter,kinova} --problems 20 --seed 0 --out "
                    "benches/results/motion[_ROBOT].json", motion),
    "roboplan_box": Table(("roboplan_box.json",), "python benches/roboplan_box.py --queries 50 --seed 0", roboplan_box),
    "table2_checkers": Table(TABLE2_CHECKER_FILES,
                             "genplan bench plan --env panda_shelf --sampler gan --queries 100 --seed 0 --checker all "
                             "--sphere-max-error 0.005 --out benches/results/table2_checkers.json (exact and spheres; "
                             "hybrid not yet a checker then); genplan bench plan --env ENV --sampler gan --queries 100 "
                             "--seed 0 --checker exact,hybrid --out benches/results/table2_hybrid_ENV.json; the default "
                             "cover with the wrist at 5 mm: genplan bench plan --env panda_shelf --sampler gan --queries 100 "
                             "--seed 0 --checker exact,spheres --out benches/results/table2_spheres_panda_shelf.json",
                             table2_checkers),
    "gan_training": Table(("gan_training_baxter_tray.json",), "python benches/gan_training.py --iterations 300 "
                          "--data-rows 2000 --rounds 3 --baseline DIR", gan_training),
    "jerk_timing": Table(("jerk_timing.json",), "python benches/jerk_timing.py --moves 1000 --seed 0 --out "
                         "benches/results/jerk_timing.json", jerk_timing),
    "baxter_tray": Table(("baxter_tray.json", "baxter_tray_hybrid.json"),
                         "python benches/baxter_tray.py [--sampler hybrid --model examples/baxter/tray_gan.safetensors "
                         "--out benches/results/baxter_tray_hybrid.json]", baxter_tray),
    "baxter_tray_card": Table(("../../examples/baxter/tray_gan.json",),
                              "genplan train gan --robot examples/baxter/baxter_tray.toml --task examples/baxter/tray.toml "
                              "--seed 0 --out examples/baxter/tray_gan.safetensors", baxter_tray_card),
    "baxter_tray_quiet_training": Table(("baxter_tray_train_quiet.json",),
                                        "GENPLAN_CACHE=EMPTY genplan train gan --robot examples/baxter/baxter_tray.toml "
                                        "--task examples/baxter/tray.toml --seed 0 --out OUT (its card)",
                                        baxter_tray_quiet_training),
    "execute_ticks": Table(("execute_ticks.json",), "python benches/execute.py --plans 0 --repeats 5 --out "
                           "benches/results/execute_ticks.json", execute_ticks),
    "execute_instructions": Table(("execute_instructions.json",), "python benches/execute_instructions.py --out "
                                  "benches/results/execute_instructions.json", execute_instructions),
    "compiled_robot": Table(("compiled_robot.json",), "python benches/compiled_robot.py --problems 3 --out "
                            "benches/results/compiled_robot.json", compiled_robot),
    "free_space_settings": Table(("free_space_settings.json",), "python benches/free_space_settings.py --robots panda ur5 "
                                 "baxter --problems 10 --rounds 2 --increments 2 3 5 10 --balance 0 1 --seed 1 --out "
                                 "benches/results/free_space_settings.json", free_space_settings),
    "execute_tracking": Table(("execute.json",), "python benches/execute.py --plans 20 --out benches/results/execute.json",
                              execute_tracking),
    "point_clouds": Table(("point_clouds.json",), "python benches/point_clouds.py --rounds 5", point_clouds),
    "custom_term_data": Table(("custom_term_data.json",), "python benches/custom_term_data.py", custom_term_data),
    "robots": Table(("robots.json",), "genplan bench robots --samples 10000 --seed 0 --out benches/results/robots.json",
                    robots),
    "xarm_cup": Table(("../../examples/xarm7/upright_cup_gan.json",),
                      "genplan train gan --robot examples/xarm7/xarm7.toml --task examples/xarm7/upright_cup.toml --out "
                      "examples/xarm7/upright_cup_gan.safetensors --seed 0", xarm_cup),
    "scaling": Table(("scaling.json",), "genplan bench scaling --repeats 5 --out benches/results/scaling.json", scaling),
}


# ---------------------------------------------------------------------------------------------
# the page
# ---------------------------------------------------------------------------------------------


def _read(folder: Path, files: Sequence[str]) -> Results:
    """The JSON ``files`` below ``folder``; a missing or broken file or a missing field is a
    GenplanError naming it (:func:`genplan.experiments.common.read_json`)."""

    return {name: read_json(folder / name) for name in files}


def _source(table: Table, res: Results, folder: Path, page: Path) -> str:
    """The line under a table: its JSON files (linked from the page), the command that wrote
    them and when, on what."""
    links = ", ".join(f"[`{Path(name).name}`]({Path(os.path.relpath(folder / name, page.parent)).as_posix()})"
                      for name in table.files)
    commands = list(dict.fromkeys(res[name].get("command") for name in table.files if res[name].get("command")))
    command = "; ".join(commands) if len(commands) == 1 and len(table.files) == 1 else table.command
    machines = [res[name].get("machine") for name in table.files]
    dates = sorted({m["date"][:10] for m in machines if isinstance(m, dict) and m.get("date")})
    cpus = sorted({f"{m['cpu']}, {m['cores']} cores" for m in machines if isinstance(m, dict) and m.get("cpu")})
    when = ", ".join(part for part in (" to ".join(dict.fromkeys([dates[0], dates[-1]])) if dates else "",
                                       "; ".join(cpus)) if part)
    return f"JSON: {links}; written by `{command}`" + (f" ({when})" if when else "") + "."


def render(folder: Path, page: Path, template: str | None = None) -> str:
    """The page for the results in ``folder``, as it would be written to ``page`` (its links are
    relative to the page's folder)."""
    text = TEMPLATE.read_text() if template is None else template
    names = [m.group("name") for m in MARKER.finditer(text)]
    unknown = [n for n in names if n not in TABLES]
    if unknown:
        raise GenplanError(f"{TEMPLATE}: no table named {', '.join(unknown)} (tables: {', '.join(TABLES)})")
    missing = [n for n in TABLES if n not in names]
    if missing:
        raise GenplanError(f"{TEMPLATE}: the tables {', '.join(missing)} have no {{{{name}}}} line")

    def table(m: re.Match[str]) -> str:
        t = TABLES[m.group("name")]
        res = _read(folder, t.files)
        return t.make(res) + "\n\n" + _source(t, res, folder, page)

    header = ("<!-- Generated by `genplan report benches/results --benchmarks docs/BENCHMARKS.md` from the JSON in "
              "benches/results and the notes in python/genplan/experiments/benchmarks_md.template.md: edit those, "
              "then run the command; not this file. -->\n")
    return header + MARKER.sub(table, text)


def write(folder: Path, page: Path) -> Path:
    """Write the page for ``folder`` to ``page`` (whole or not at all)."""
    from genplan.experiments.common import write_text

    return write_text(page, render(folder, page))
