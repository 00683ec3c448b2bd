"""How long a free-space extension should be, and which tree should grow: RRT-Connect with
extensions of at most ``max_increments`` steps of 0.3 rad, alternating trees or the smaller one
growing (``balance``), on the motion bench's problem families, VAMP side by side.

    python benches/free_space_settings.py --robots panda ur5 baxter --problems 10 --rounds 2 \\
        --increments 2 3 5 10 --balance 0 1 --seed 1 --out benches/results/free_space_settings.json

The tuning run behind ``genplan.planning.FREE_SPACE_SETTINGS`` (``max_increments``, ``balance``): seed 1, not
the tables' seed 0 (``genplan bench motion --seed 0``). The problems are the motion bench's
(python/genplan/experiments/benchmarks/motion.py: ``make_problems``, the robots of its ROBOTS);
each is planned by genplan's free-space defaults with the spheres checker, ``max_increments`` and
``balance`` replaced by each pair of the values given (an arm "3" alternates, "3+balance" balances), and by VAMP when it is installed, every round in an order that
alternates problem by problem, one call each from Python. Planning time: the call's wall time less
the simplification's. Printed and written per robot, family and value: success, the median
planning time, its ratio to VAMP's median (or to the largest value's when VAMP is missing), the
median validity checks (a cost the machine's load does not change) and the median simplified
path length; per robot and value, the geometric mean of the ratios over the families, and per
value the geometric mean of those over the robots.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from genplan.experiments.benchmarks import motion as M
from genplan.experiments.common import geometric_mean, machine, table, write_json
from genplan.planning import FREE_SPACE_SETTINGS


def arm_name(increments: int, balance: bool) -> str:
    return f"{increments}+balance" if balance else str(increments)


def plan_once(robot: Any, problem: M.Problem, increments: int, balance: bool, seed: int) -> dict[str, Any]:
    """One free-space plan of ``problem`` (the motion bench's genplan arm with the spheres) with
    the default settings but ``max_increments`` and ``balance``."""
    return M._genplan_arm(robot, problem, "spheres", seed,
                          FREE_SPACE_SETTINGS.replace(max_increments=increments, balance=balance))


def run_robot(name: str, families: list[str], n: int, rounds: int, increments: list[int], balance: list[bool],
              seed: int) -> list[dict[str, Any]]:
    setup = M.ROBOTS[name]
    robot = setup.load()
    installed = M.vamp_module()
    vamp = installed if setup.vamp is not None else None
    vsph = M.vamp_spheres(vamp, robot) if vamp is not None and name == "panda" else None
    variants = {arm_name(k, b): (k, b) for k in increments for b in balance}
    arms = list(variants) + (["vamp"] if vamp is not None else [])
    rows = []
    for family in families:
        problems = M.make_problems(robot, family, n, seed, vamp, vsph, setup=setup)
        records: dict[str, list[dict[str, Any]]] = {a: [] for a in arms}
        for k in range(rounds):
            for p in problems:
                pseed = seed * 100_003 + p.index + 7 * k
                for arm in (arms if (p.index + k) % 2 == 0 else arms[::-1]):
                    rec = (M._vamp_arm(vamp, p, pseed, setup) if arm == "vamp" else
                           plan_once(robot, p, *variants[arm], pseed))
                    records[arm].append(rec)
        ref_arm = "vamp" if vamp is not None else arm_name(max(increments), balance[0])
        ref = float(np.median([r["plan_ms"] for r in records[ref_arm]]))
        for arm in arms:
            rs = records[arm]
            ms = float(np.median([r["plan_ms"] for r in rs]))
            rows.append({"robot": name, "family": family, "arm": arm, "problems": len(problems), "plans": len(rs),
                         "success_pct": 100.0 * sum(r["success"] for r in rs) / len(rs),
                         "plan_ms_median": ms, "over_reference": ms / ref, "reference": str(ref_arm),
                         "checks_median": float(np.median([r.get("checks", math.nan) for r in rs])),
                         "length_median": float(np.nanmedian([r["length"] for r in rs]))})
        print(f"{name} {family}: " + ", ".join(f"{r['arm']} {r['plan_ms_median']:.3f} ms" for r in rows[-len(arms):]),
              flush=True)
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--robots", nargs="+", choices=list(M.ROBOTS), default=["panda", "ur5", "baxter"])
    p.add_argument("--families", nargs="+", choices=list(M.FAMILIES), default=list(M.FAMILIES))
    p.add_argument("--problems", type=int, default=10, help="problems per family")
    p.add_argument("--rounds", type=int, default=2, help="plans of each problem per value (seeds differ)")
    p.add_argument("--increments", type=int, nargs="+", default=[2, 3, 5, 10], help="max_increments values")
    p.add_argument("--balance", type=int, nargs="+", choices=[0, 1], default=[0, 1], help="balance values (0: off, 1: on)")
    p.add_argument("--seed", type=int, default=1, help="the problems' seed (1: tuning; the tables report 0)")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args()
    if args.seed == 0:
        p.error("--seed 0 is the seed the tables report (genplan bench motion --seed 0): tune on another (default 1)")
    if min(args.problems, args.rounds, *args.increments) < 1:
        p.error("--problems, --rounds and --increments must be positive")
    load0 = os.getloadavg()[0]
    rows = [r for name in args.robots
            for r in run_robot(name, args.families, args.problems, args.rounds, args.increments,
                               [bool(b) for b in args.balance], args.seed)]
    print(table(["robot", "family", "arm", "success", "plan ms", "/ reference", "checks", "length"],
                [[r["robot"], r["family"], r["arm"], f"{r['success_pct']:.0f} %", r["plan_ms_median"],
                  r["over_reference"], r["checks_median"], r["length_median"]] for r in rows]))
    summary = {}
    for name in args.robots:
        for arm in dict.fromkeys(r["arm"] for r in rows if r["robot"] == name):
            ratios = [r["over_reference"] for r in rows if r["robot"] == name and r["arm"] == arm]
            summary[f"{name}/{arm}"] = geometric_mean(ratios)
            ref = next(r["reference"] for r in rows if r["robot"] == name)
            print(f"{name}, {arm}: plan time / {ref}'s, geometric mean over families: "
                  f"{summary[f'{name}/{arm}']:.2f}")
    overall = {}
    for arm in (arm_name(k, bool(b)) for k in args.increments for b in args.balance):
        overall[arm] = geometric_mean([v for k, v in summary.items() if k.endswith(f"/{arm}")])
        print(f"{arm}: geometric mean over the robots: {overall[arm]:.2f}")
    write_json(args.out, {"benchmark": "free_space_settings", "seed": args.seed, "families": args.families,
                          "problems_per_family": args.problems,
                          "rounds": args.rounds, "increments": args.increments, "balance": args.balance,
                          "rows": rows, "summary": summary, "over_robots": overall,
                          "default_max_increments": FREE_SPACE_SETTINGS.max_increments,
                          "default_balance": FREE_SPACE_SETTINGS.balance,
                          "load_1min_start": load0, "load_1min_end": os.getloadavg()[0], "machine": machine()})


if __name__ == "__main__":
    main()
