"""``genplan reproduce``: rerun both papers' experiments with the shipped models, write a report.

    genplan reproduce --quick --out out/quick      # about 4 minutes on a quiet 2-core machine
    genplan reproduce --out out/full               # the papers' N (about an hour or more)

Steps (each is a ``genplan bench ...`` command, run in-process through the benchmark module's own
parser and ``main``, writing JSON and PNGs into the output folder; the report is assembled from
those files):

1. Table I (GAN paper): projection and IK, uniform vs GAN initialisation, Panda and Talos, plus the
   scipy ``least_squares`` baseline on the same tasks;
2. Table II: constrained RRT with uniform / GAN / hybrid sampling, and OMPL's
   ProjectedStateSpace + RRTConnect, on the four environments;
3. coverage of the GAN distributions (Fig. 3 and 4 made measurable); the quick run measures the
   paper's ablations shipped in the package's models folder (``<robot>_coverage_<variant>``,
   trained as ``genplan bench coverage --quick`` trains them: the command is in each card) instead
   of training them, the full run trains them with the paper's iterations;
4. seq2seq paper: J1 adjustment (Fig. 5, 9: latent / random latent / direct U, and CasADi + IPOPT)
   and J2 (Fig. 11);
5. the 1 kHz controller executing the J2 trajectory (Fig. 12), with and without the DOB;
6. 3D views (self-contained HTML) of one Panda and one Talos plan.

DIR gets ``report.md`` (every table beside the papers' numbers, the machine, seeds, the command),
the PNG figures, the HTML views and ``results.json`` (everything).
"""

from __future__ import annotations

import argparse
import importlib
import json
import shlex
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from genplan.cli import args as A
from genplan.experiments.common import machine, write_text

SEED = 0


@dataclass(frozen=True)
class Sizes:
    """How big each experiment is (quick or full)."""

    table1_tasks: int
    table1_scipy_tasks: int
    plan_queries: int
    ompl_queries: int
    ompl_time_limit: float
    coverage_quick: bool
    #: measure the shipped ablation GANs (``bench coverage --models``) instead of training them
    coverage_shipped_models: bool
    adjust_j1_updates: int
    adjust_problems: int | None


#: ``--quick`` plans one OMPL query per environment: OMPL times out on every Talos query at 10 s, so
#: each query it plans costs about 30 s of the quick run
QUICK = Sizes(table1_tasks=100, table1_scipy_tasks=50, plan_queries=10, ompl_queries=1, ompl_time_limit=10.0,
              coverage_quick=True, coverage_shipped_models=True, adjust_j1_updates=30, adjust_problems=None)
FULL = Sizes(table1_tasks=500, table1_scipy_tasks=500, plan_queries=100, ompl_queries=20, ompl_time_limit=30.0,
             coverage_quick=False, coverage_shipped_models=False, adjust_j1_updates=100, adjust_problems=None)


def _steps(out: Path, sizes: Sizes) -> list[tuple[str, list[str]]]:
    """(title, genplan command line) of every step."""
    from genplan.samplers.base import models_dir

    fig = out / "figures"
    steps: list[tuple[str, list[str]]] = []
    for robot in ("panda", "talos"):
        for init in ("uniform", "gan"):
            steps.append((f"Table I {robot} {init}", ["bench", "projection", "--robot", robot, "--init", init, "--tasks",
                                                      str(sizes.table1_tasks), "--seed", str(SEED),
                                                      "--out", str(out / f"table1_{robot}_{init}.json")]))
        steps.append((f"Table I {robot} scipy baseline", ["bench", "projection", "--robot", robot, "--init", "uniform",
                                                           "--solver", "scipy", "--tasks", str(sizes.table1_scipy_tasks),
                                                           "--seed", str(SEED), "--out", str(out / f"table1_{robot}_scipy.json")]))
    steps.append(("Table II genplan", ["bench", "plan", "--env", "all", "--sampler", "all", "--planner", "genplan",
                                       "--queries", str(sizes.plan_queries), "--seed", str(SEED),
                                       "--out", str(out / "table2_genplan.json")]))
    steps.append(("Table II OMPL peer", ["bench", "plan", "--env", "all", "--planner", "ompl",
                                         "--queries", str(sizes.ompl_queries), "--seed", str(SEED),
                                         "--ompl-time-limit", str(sizes.ompl_time_limit),
                                         "--out", str(out / "table2_ompl.json")]))
    steps.append(("GAN coverage", ["bench", "coverage", *(["--quick"] if sizes.coverage_quick else []), "--seed", str(SEED),
                                   *(["--models", str(models_dir())] if sizes.coverage_shipped_models else []),
                                   "--figures", str(fig), "--out", str(out / "coverage.json")]))
    steps.append(("seq2seq J1", ["bench", "adjust", "--method", "all", "--objective", "j1", "--updates",
                                 str(sizes.adjust_j1_updates), "--out-dir", str(out / "adjust"), "--figures", str(fig)]))
    steps.append(("seq2seq J2", ["bench", "adjust", "--method", "all", "--objective", "j2",
                                 "--out-dir", str(out / "adjust"), "--figures", str(fig)]))
    steps.append(("controller", ["bench", "control", "--out", str(out / "control.json"),
                                 "--png", str(fig / "control_fig12.png")]))
    return steps


def _bench(argv: list[str]) -> int:
    """Run ``["bench", NAME, *args]`` as ``genplan bench NAME args`` does: NAME's module in
    :mod:`genplan.experiments.benchmarks` parses ``args`` with its ``add_arguments``, then ``main``."""
    _, name, *args = argv
    module = importlib.import_module(f"genplan.experiments.benchmarks.{name}")
    parser = argparse.ArgumentParser(prog=f"genplan bench {name}")
    module.add_arguments(parser)
    return int(module.main(parser.parse_args(args)))


def _views(out: Path) -> dict[str, str]:
    from genplan.viewer import export_plan_html

    views = {}
    for env in ("panda_shelf", "talos_task1"):
        path = export_plan_html(env, out / "views" / f"{env}.html", sampler="hybrid", seed=SEED)
        views[env] = str(path.relative_to(out))
    return views


def run(out: Path, quick: bool, only: list[str] | None = None) -> dict[str, Any]:
    from tqdm import tqdm

    from genplan.experiments.report import collect, write_report

    sizes = QUICK if quick else FULL
    steps = _steps(out, sizes) + [("3D views", [])]
    if only:
        steps = [s for s in steps if any(o.lower() in s[0].lower() for o in only)]
        if not steps:
            raise A.UsageError(f"--only {' '.join(only)}: no step matches; steps: "
                               + ", ".join(t for t, _ in _steps(out, sizes)) + ", 3D views")
    A.check_output_folder(out / "figures", "--out", of=out)
    log: list[dict[str, Any]] = []
    views: dict[str, str] = {}
    t_all = time.perf_counter()
    bar = tqdm(steps, desc="reproduce", unit="step")
    for title, argv in bar:
        bar.set_postfix_str(title)
        t0 = time.perf_counter()
        status = "ok"
        try:
            if argv:
                rc = _bench(argv)
                status = "ok" if rc == 0 else f"exit {rc}"
            else:
                views = _views(out)
        except Exception as exc:  # a failing step is reported, the others still run
            status = f"failed: {type(exc).__name__}: {exc}"
            tqdm.write(f"reproduce: step '{title}' {status}", file=sys.stderr)
        log.append({"step": title, "command": "genplan " + " ".join(shlex.quote(a) for a in argv) if argv else
                    "genplan.viewer.export_plan_html", "status": status, "seconds": time.perf_counter() - t0})
    results: dict[str, Any] = {
        "command": "genplan reproduce " + ("--quick " if quick else "") + f"--out {out}",
        "quick": quick,
        "sizes": sizes.__dict__,
        "seed": SEED,
        "machine": machine(),
        "total_s": time.perf_counter() - t_all,
        "steps": log,
        "views": views,
        "results": collect(out),
    }
    write_text(out / "results.json", json.dumps(results, indent=2) + "\n")

    write_report(out, results)
    return results


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quick", action="store_true",
                   help="smaller N and the shipped ablation GANs: about 4 minutes on 2 quiet cores")
    p.add_argument("--out", type=A.output_folder, default="out/reproduce",
                   help="output folder (report.md, results.json, figures; created if missing)")
    p.add_argument("--only", nargs="*", default=None, help="run only the steps whose title contains one of these words")


def main(args: argparse.Namespace) -> int:
    results = run(args.out, args.quick, args.only)
    failed = [s for s in results["steps"] if s["status"] != "ok"]
    print(f"wrote {args.out / 'report.md'} and {args.out / 'results.json'} in {results['total_s'] / 60:.1f} min"
          + (f"; {len(failed)} step(s) failed: {', '.join(s['step'] for s in failed)}" if failed else ""))
    return 1 if failed else 0
