"""``report.md`` of ``genplan reproduce``: every table beside the papers' numbers, from the JSON the
benchmarks wrote (nothing here measures anything).

    genplan report benches/results      # the committed benchmark JSON -> benches/results/report.md
    genplan report benches/results --benchmarks docs/BENCHMARKS.md     # the benchmarks page

reads a folder laid out like ``genplan reproduce``'s output (``table1_*.json``,
``table2_*.json``, ``coverage.json``, ``adjust/adjust_*.json``, ``control.json``, ``figures/``).
With ``--benchmarks PAGE`` it writes the benchmarks page instead
(:mod:`genplan.experiments.benchmarks_md`).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from genplan.cli import args as A
from genplan.errors import GenplanError
from genplan.experiments.common import geometric_mean, read_json, table, write_text


def _f(x: Any, digits: int = 3) -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, (int, float)):
        return f"{x:.{digits}g}" if abs(x) < 1000 else f"{x:.0f}"
    return str(x)


def _table1(res: dict[str, Any]) -> str:
    rows = []
    for robot in ("panda", "talos"):
        for kind in ("projection", "ik"):
            for init in ("uniform", "gan"):
                r = res.get(f"table1_{robot}_{init}.json")
                if r is None:
                    continue
                m, p = r[kind], r["paper"][kind]
                rows.append([robot, kind, init, f"{m['success_rate']:.1f}", f"{m['t_ave_ms']:.3f}", _f(m["t_star_ave_ms"]),
                             _f(m["steps_star"], 2), f"{p['success_rate']}", f"{p['t_ave_ms']}", f"{p['steps_star']}"])
            s = res.get(f"table1_{robot}_scipy.json")
            g = res.get(f"table1_{robot}_uniform.json")
            if s is not None:
                m = s[kind]
                ratio = f" ({m['t_ave_ms'] / g[kind]['t_ave_ms']:.0f}x genplan's T_ave)" if g else ""
                rows.append([robot, kind, "uniform, scipy least_squares", f"{m['success_rate']:.1f}",
                             f"{m['t_ave_ms']:.3f}{ratio}", _f(m["t_star_ave_ms"]), _f(m["steps_star"], 2), "", "", ""])
    if not rows:
        return "_not run_\n"
    tasks = next((res[k]["tasks"] for k in res if k.startswith("table1_")), "?")
    return (f"{tasks} tasks per row (scipy: see its JSON), one after the other on one core; T in ms.\n\n"
            + table(["robot", "task", "init", "success %", "T_ave", "T*_ave", "steps*", "paper success %", "paper T_ave",
                     "paper steps*"], rows) + "\n")


def _sampler_ratios(by: dict[str, dict[str, Any]]) -> list[str]:
    """Mean-time ratios of one environment's genplan rows (keyed by sampler): uniform over GAN
    and over hybrid, where both rows exist."""
    return [f"uniform / {label} {by['uniform']['t_ave_s'] / by[s]['t_ave_s']:.2f}x"
            for s, label in (("gan", "GAN"), ("hybrid", "hybrid")) if "uniform" in by and s in by]


def _table2(res: dict[str, Any]) -> str:
    rows = []
    lines = []
    for name in ("table2_genplan.json", "table2_ompl.json"):
        r = res.get(name)
        if r is None:
            continue
        for row in r["rows"]:
            p = row.get("paper") or {}
            who = row["sampler"] if row["planner"] == "genplan" else "OMPL ProjectedStateSpace + RRTConnect"
            extra = ""
            if row["planner"] == "ompl":
                extra = f" (without Python callbacks {row['t_ave_without_callbacks_s']:.3f})"
            rows.append([row["env"], who, row["queries"], f"{row['success_rate']:.1f}", f"{row['t_ave_s']:.3f}{extra}",
                         f"{row['t_median_s']:.3f}", f"{row['projections']:.0f}", _f(row.get("extensions"), 3),
                         _f(p.get("success_rate")), _f(p.get("t_ave_s")), _f(p.get("projections")), _f(p.get("extensions"))])
    if not rows:
        return "_not run_\n"
    g = res.get("table2_genplan.json", {}).get("rows", [])
    o = res.get("table2_ompl.json", {}).get("rows", [])
    for env in dict.fromkeys(r["env"] for r in g):
        by = {r["sampler"]: r for r in g if r["env"] == env}
        om = next((r for r in o if r["env"] == env), None)
        parts = _sampler_ratios(by)
        if om is not None:
            for s in ("uniform", "gan", "hybrid"):
                if s in by:
                    parts.append(f"OMPL / {s} {om['t_ave_s'] / by[s]['t_ave_s']:.0f}x")
        lines.append(f"- {env}: " + ", ".join(parts))
    return ("T in s per query (all queries, retries included), Opt. steps = projection iterations (OMPL: "
            "projection calls), E = extension steps. OMPL rows plan fewer queries (the first ones of the "
            "same seeded set) with a time limit.\n\n"
            + table(["env", "sampler / planner", "queries", "success %", "T_ave", "T_median", "Opt. steps", "E",
                     "paper success %", "paper T_ave", "paper steps", "paper E"], rows)
            + "\n\nRatios of mean times, same queries:\n\n" + "\n".join(lines) + "\n")


def _table2_nodes_only(res: dict[str, Any]) -> str:
    """Table II under the paper's protocol: tree nodes checked, edges not validated."""
    r = res.get("table2_genplan_nodes_only.json")
    if r is None:
        return ""
    g = r["rows"]
    full = {(x["env"], x["sampler"]): x for x in res.get("table2_genplan.json", {}).get("rows", [])}
    rows = []
    for row in g:
        f = full.get((row["env"], row["sampler"]))
        rows.append([row["env"], row["sampler"], row["queries"], f"{row['success_rate']:.1f}", f"{row['t_ave_s']:.3f}",
                     f"{row['t_median_s']:.3f}", f"{row['projections']:.0f}", _f(row.get("extensions"), 3),
                     "-" if f is None else f"{f['t_ave_s'] - row['t_ave_s']:+.3f}"])
    lines = []
    for env in dict.fromkeys(x["env"] for x in g):
        by = {x["sampler"]: x for x in g if x["env"] == env}
        if "uniform" in by and "gan" in by:
            lines.append(f"- {env}: " + ", ".join(_sampler_ratios(by)))
    return ("\n### The same queries under the paper's protocol (tree nodes checked, edges not validated)\n\n"
            "`--edge-resolution 0`: what the paper timed (Algorithm 1; its collision check saw the nodes only). The "
            "last column is the default run's time minus this one: mostly validating the returned path's edges "
            "(projected, checked states 0.025 rad apart), but the searches differ too (a failed edge prunes its "
            "subtree and the search goes on) and machine noise is included. Where it is about the same for every "
            "sampler (Talos tasks 1-2) it dilutes the sampler's ratio.\n\n"
            + table(["env", "sampler", "queries", "success %", "T_ave", "T_median", "Opt. steps", "E",
                     "default run T_ave - this"], rows)
            + "\n\nRatios of mean times, same queries:\n\n" + "\n".join(lines) + "\n")


def _coverage(res: dict[str, Any]) -> str:
    c = res.get("coverage.json")
    if c is None:
        return "_not run_\n"
    rows = []
    for k in ("n_net_1", "n_net_5"):
        r = c["planar"].get(k)
        if r:
            rows.append(["planar 2-link", k, _f(r["cluster_coverage"]), _f(r["mmd"]), f"valid {r['valid_rate']:.3f}"])
    for robot in ("panda", "talos"):
        for label in ("default", "no_discriminator", "n_net_1"):
            r = c.get(robot, {}).get(label)
            if r:
                rows.append([robot, label, _f(r["cluster_coverage"]), _f(r["mmd"]), f"projects {r['projection_success']:.3f}"])
    source = (f" The GANs were read from `{c['models']}` (each file's card names the command that trained it), "
              "not trained here." if c.get("models") else "")
    return (f"Share of k-means clusters (k = {c.get('k_clusters')}) of held-out valid data that samples reach, and "
            f"MMD between samples and data (lower is closer); quick runs train fewer iterations.{source}\n\n"
            + table(["setup", "variant", "cluster coverage", "MMD", "quality"], rows) + "\n")


def _table2_algorithms(res: dict[str, Any]) -> str:
    """Table II with both search algorithms ([planner]), edges checked and nodes only."""
    parts = []
    for name, protocol in (("table2_genplan_algorithms.json", "edges checked"),
                           ("table2_genplan_algorithms_nodes_only.json", "nodes only (`--edge-resolution 0`)")):
        r = res.get(name)
        if r is None:
            continue
        rows = [[x["env"], x["algorithm"], x["sampler"], x["queries"], f"{x['success_rate']:.1f}", f"{x['t_ave_s']:.3f}",
                 _f(x.get("extensions"), 3), f"{x['projections']:.0f}"] for x in r["rows"]]
        ratios = []
        for algorithm, by_env in r["ratios_by_algorithm"].items():
            values = [v["uniform_over_gan"] for v in by_env.values() if v.get("uniform_over_gan")]
            if values:
                ratios.append(f"- {algorithm}: uniform / GAN " + ", ".join(f"{v:.2f}x" for v in values)
                              + f" (geometric mean {geometric_mean(values):.2f}x)")
        parts.append(f"\n### Both algorithms, {protocol} (`{name}`)\n\n"
                     + table(["env", "algorithm", "sampler", "queries", "success %", "T_ave", "E", "Opt. steps"], rows)
                     + "\n\n" + "\n".join(ratios) + "\n")
    return "".join(parts)


def _coverage_variants(res: dict[str, Any]) -> str:
    """The coverage variants ([sampler]): `genplan bench coverage --variants`."""
    c = res.get("coverage_variants.json")
    if c is None:
        return ""
    rows = []
    for robot in ("panda", "talos"):
        r = c.get(robot)
        if not r:
            continue
        for label, v in r.items():
            if isinstance(v, dict) and "cluster_coverage" in v:
                rows.append([robot, label, r["iterations"], r["seed"], _f(v["cluster_coverage"]), _f(v["mmd"]),
                             f"{v['projection_success']:.3f}", _f(v["projection_steps_mean"]), f"{v['train_s']:.0f}"])
    return ("\n### Coverage variants (`coverage_variants.json`)\n\n"
            + table(["robot", "variant", "iterations", "seed", "cluster coverage", "MMD", "projects", "steps*",
                     "train s"], rows) + "\n")


def _ik(res: dict[str, Any]) -> str:
    """IK for users ([planner] item 5, [core-speed] item 4): `genplan bench ik`."""
    r = res.get("ik.json")
    if r is None:
        return ""
    rows = []
    for robot, by in r["ik"].items():
        for kind, v in by.items():
            if isinstance(v, dict) and "success_rate" in v:
                rows.append([robot, kind, f"{v['success_rate']:.1f}", f"{v['success_within_budget']:.1f}",
                             f"{v['t_mean_ms']:.3f}", f"{v['t_p99_ms']:.3f}", v["attempts_max"]])
    text = ("## IK for users\n\n`ik.json`: reachable targets, one target after the other on one core; a row's "
            "budget is 5 ms per target unless its JSON says otherwise.\n\n"
            + table(["robot", "IK", "success %", "within budget %", "mean ms", "p99 ms", "attempts max"], rows) + "\n")
    traj = r.get("trajectory")
    if traj and traj["summary"]:
        text += "\nTrajectories (Panda shelf, 1 kHz):\n\n" + table(
            ["", "median", "max"], [[k, _f(v["median"], 4), _f(v["max"], 4)] for k, v in traj["summary"].items()]) + "\n"
    return text


def _certified_edges(res: dict[str, Any]) -> str:
    """Certified edges ([planner] item 3): `python benches/certified_edges.py`."""
    r = res.get("certified_edges.json")
    if r is None:
        return ""
    rows = [[x["env"], x["edge_check"], x["queries"], f"{x['success_rate']:.1f}", f"{x['t_median_s']:.4f}",
             f"{x['checker_median_s']:.4f}", f"{x['projector_median_s']:.4f}", _f(x.get("path_states_median"), 4),
             f"{x['motion_certificates_median']:.0f}"] for x in r["rows"]]
    ratios = ", ".join(f"{env} {v:.2f}x" for env, v in r["certified_over_sampled_median_time"].items())
    return (f"\n### Certified edges (`certified_edges.json`: {r['algorithm']}, {r['sampler']} sampler)\n\n"
            + table(["env", "edge check", "queries", "success %", "T median s", "checker s", "projector s",
                     "path states", "certificates"], rows)
            + f"\n\nCertified / sampled median plan time: {ratios}.\n")


#: the markdown tables `genplan bench peers` writes beside its JSON (a run of some sections only
#: writes its own pair of files)
PEERS_FILES = (("peers", "all sections"), ("peers_ik", "IK, with solve_ik's retries"),
               ("peers_collision", "collision"))


def _peers(res: dict[str, Any]) -> str:
    """`genplan bench peers` writes its own markdown table beside its JSON."""
    links = [f"- [{stem}.md]({stem}.md) ({what}; `genplan bench peers`)" for stem, what in PEERS_FILES
             if f"{stem}.json" in res]
    return "## Beside the peers\n\n" + "\n".join(links) + "\n" if links else ""


def _figures(out: Path) -> str:
    figs = sorted(out.glob("**/*.png"))
    if not figs:
        return "_no figures_\n"
    return "\n".join(f"![{p.stem}]({p.relative_to(out).as_posix()})" for p in figs) + "\n"


def write_report(out: Path, results: dict[str, Any], extra_sections: dict[str, str] | None = None,
                 path: Path | None = None) -> Path:
    """Write the report of ``results`` (figures: those below ``out``) to ``path`` (default
    ``out/report.md``), atomically."""
    res = results["results"]
    m = results["machine"]
    from genplan.experiments.report_seq2seq import adjust_section, control_section

    steps = results.get("steps") or []
    lines = [
        "# genplan reproduce" if steps else "# genplan benchmarks",
        "",
        f"Command: `{results['command']}` (seed {results['seed']}), {m['date']}, git {m['git']}.",
        f"Machine: {m['cpu']}, {m['cores']} cores, {m['platform']}, Python {m['python']}."
        + (f" Total {results['total_s'] / 60:.1f} min." if results.get("total_s") else ""),
        "",
    ]
    if steps:
        lines += ["Steps:", "",
                  table(["step", "status", "seconds", "command"],
                        [[s["step"], s["status"], f"{s['seconds']:.0f}", f"`{s['command']}`"] for s in steps]), ""]
    else:
        lines += ["Each JSON file records the command, machine and date of its own run.", ""]
    lines += [
        "## GAN paper, Table I: projection and IK",
        "",
        _table1(res),
        "## GAN paper, Table II: constrained RRT",
        "",
        _table2(res),
        _table2_nodes_only(res),
        _table2_algorithms(res),
        _certified_edges(res),
        "## GAN coverage (Fig. 3 and 4 as numbers)",
        "",
        _coverage(res),
        _coverage_variants(res),
        _ik(res),
        _peers(res),
        "## seq2seq paper: latent trajectory adjustment",
        "",
        adjust_section(res),
        "## seq2seq paper: the 1 kHz controller (Fig. 12)",
        "",
        control_section(res),
        "## 3D views",
        "",
        "\n".join(f"- [{env}]({path}) (self-contained HTML: orbit, play, scrub)" for env, path in results.get("views", {}).items())
        or "_not made here (genplan reproduce makes them)_",
        "",
        "## Figures",
        "",
        _figures(out),
    ]
    for title, body in (extra_sections or {}).items():
        lines += [f"## {title}", "", body]
    path = out / "report.md" if path is None else path
    return write_text(path, "\n".join(lines) + "\n")


def collect(folder: Path) -> dict[str, Any]:
    """Every benchmark JSON below ``folder`` (:func:`read_json`), keyed by its relative path."""
    return {p.relative_to(folder).as_posix(): read_json(p) for p in sorted(folder.glob("**/*.json"))
            if p.name not in ("results.json", "criterion.json")}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("folder", type=A.existing_folder, help="folder of benchmark JSON (e.g. benches/results)")
    p.add_argument("--out", type=A.output_file, default=None,
                   help="report file (default FOLDER/report.md; folders are created)")
    p.add_argument("--benchmarks", type=A.output_file, default=None, metavar="PAGE",
                   help="write the benchmarks page (docs/BENCHMARKS.md: the measured tables, each with the command "
                        "that wrote its JSON, and their notes) to PAGE instead of the report")


def main(args: argparse.Namespace) -> int:
    from genplan.experiments.common import machine

    if args.benchmarks is not None:
        if args.out is not None:
            raise A.UsageError("--out: the report's file; --benchmarks writes the benchmarks page instead (give one)")
        from genplan.experiments.benchmarks_md import write

        print(f"wrote {write(args.folder, args.benchmarks)}")
        return 0
    out = args.out or A.check_output_file(args.folder / "report.md", "FOLDER")
    results = {"command": f"genplan report {args.folder}", "seed": 0, "machine": machine(),
               "results": collect(args.folder)}
    path = write_report(args.folder, results, path=out)
    print(f"wrote {path}")
    return 0
