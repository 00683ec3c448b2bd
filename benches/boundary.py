"""The cost of crossing from Python into the native core (issue 18, items 1-2): single calls and
batched outputs through genplan's public API, interleaved with Pinocchio doing the same work.

    python benches/boundary.py [--label after] [--repeats 7] [--out benches/results/boundary.json]

* ``panda_hand_fk_single``: one Panda hand pose per call, ``robot.link_poses(q, ["panda_hand"])``
  vs ``pin.forwardKinematics`` + ``pin.updateFramePlacement`` (q a float64 array; us per call);
* ``talos_all_links_batched``: every Talos link pose for 10k configurations,
  ``robot.link_poses(qs)`` vs a Pinocchio loop of ``forwardKinematics`` + ``updateFramePlacements``
  (us per configuration); also into a reused array (``out=``) and as float32 (``dtype=``);
* ``panda_collision_single``: one ``world.in_collision(q)`` / ``world.min_distance(q)`` call on
  the Panda with a table (self + obstacle), beside the per-row time of the same check batched
  (10k rows, on all of rayon's threads), and one ``in_collision(q)`` on a world with nothing to
  check (no obstacle, self-collision off): the fixed cost of a call plus the robot's FK.

Each figure is the median of ``--repeats`` runs, genplan and Pinocchio alternating inside each
repeat; the load average is recorded before and after. Results are stored under ``--label`` in
the JSON (other labels already in the file are kept), so a before/after pair sits in one file.

``--before-site DIR`` alternates two builds: each round runs once in a fresh process with the
genplan installed in DIR (``pip install --no-deps --target DIR`` of an older wheel, put first on
PYTHONPATH) and once with this tree's, their order alternating; stored as LABEL_before and
LABEL_after.
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

import genplan

ROOT = Path(__file__).resolve().parents[1]


def per_call(f: Callable[[Any], Any], args: list[Any], calls: int) -> float:
    """Seconds per call of ``f(a)`` over ``calls`` calls cycling through ``args``."""
    k = len(args)
    t0 = time.perf_counter()
    for i in range(calls):
        f(args[i % k])
    return (time.perf_counter() - t0) / calls


def interleaved(sides: dict[str, Callable[[], float]], repeats: int) -> dict[str, float]:
    """Median (in us) of each side's figure over ``repeats`` rounds, the sides alternating, after
    one untimed round."""
    runs: dict[str, list[float]] = {k: [] for k in sides}
    for f in sides.values():  # warm-up (first calls: imports, thread pools, caches), not counted
        f()
    for _ in range(repeats):
        for k, f in sides.items():
            runs[k].append(f() * 1e6)
    return {k: statistics.median(v) for k, v in runs.items()}


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """Every figure of this build (the genplan that imports), medians of ``args.repeats``."""
    results: dict[str, Any] = {}

    # --- Panda hand FK, one call ------------------------------------------------------------
    panda = genplan.load("panda")
    qs = [np.ascontiguousarray(q) for q in panda.random_configurations(64, 0)]
    fid = panda.model.getFrameId("panda_hand")
    model, data = panda.model, panda.data
    hand = ["panda_hand"]

    def pin_hand(q: Any) -> Any:
        pin.forwardKinematics(model, data, q)
        return pin.updateFramePlacement(model, data, fid)

    assert np.allclose(panda.link_poses(qs[3], hand)[0], pin_hand(qs[3]).homogeneous, atol=1e-9)
    results["panda_hand_fk_single"] = interleaved({
        "genplan_us": lambda: per_call(lambda q: panda.link_poses(q, hand), qs, args.calls),
        "genplan_native_us": lambda: per_call(lambda q: panda.kinematics.forward_kinematics(q, hand), qs, args.calls),
        "pinocchio_us": lambda: per_call(pin_hand, qs, args.calls),
    }, args.repeats)

    # --- Talos, every link, batch of n ---------------------------------------------------------
    talos = genplan.load("talos")
    tq = talos.random_configurations(args.n, 0)
    tmodel, tdata = talos.model, talos.data
    m = min(args.n, 5000)

    def talos_ours() -> float:
        t0 = time.perf_counter()
        talos.link_poses(tq)
        return (time.perf_counter() - t0) / args.n

    def talos_pin() -> float:
        t0 = time.perf_counter()
        for q in tq[:m]:
            pin.forwardKinematics(tmodel, tdata, q)
            pin.updateFramePlacements(tmodel, tdata)
        return (time.perf_counter() - t0) / m

    sides = {"genplan_us_per_config": talos_ours, "pinocchio_loop_us_per_config": talos_pin}
    if "out" in inspect.signature(talos.link_poses).parameters:  # issue 18's outputs (not in the "before" build)
        out = np.empty((args.n, len(talos.kinematics.link_names), 4, 4))

        def talos_out() -> float:
            t0 = time.perf_counter()
            talos.link_poses(tq, out=out)
            return (time.perf_counter() - t0) / args.n

        def talos_f32() -> float:
            t0 = time.perf_counter()
            talos.link_poses(tq, dtype=np.float32)
            return (time.perf_counter() - t0) / args.n

        sides |= {"genplan_out_us_per_config": talos_out, "genplan_float32_us_per_config": talos_f32}
    results["talos_all_links_batched"] = interleaved(sides, args.repeats)
    results["talos_all_links_batched"]["links"] = len(talos.kinematics.link_names)
    results["talos_all_links_batched"]["n"] = args.n

    # --- Panda collision, one call vs batched ---------------------------------------------------
    world = panda.collision_world()
    world.add_box("table", [0.5, 0.5, 0.02], [0.5, 0.0, -0.03])
    pq = panda.random_configurations(args.n, 1)
    rows = [np.ascontiguousarray(q) for q in pq[:64]]

    def batch(f: Callable[[Any], Any]) -> Callable[[], float]:
        def run() -> float:
            t0 = time.perf_counter()
            f(pq)
            return (time.perf_counter() - t0) / args.n
        return run

    empty = panda.collision_world(self_collision=False)  # nothing to check: the call's fixed cost + FK

    results["panda_collision_single"] = interleaved({
        "in_collision_single_empty_world_us": lambda: per_call(empty.in_collision, rows, args.calls // 4),
        "in_collision_single_us": lambda: per_call(world.in_collision, rows, args.calls // 4),
        "in_collision_batched_us_per_row": batch(world.in_collision),
        "min_distance_single_us": lambda: per_call(world.min_distance, rows, args.calls // 4),
        "min_distance_batched_us_per_row": batch(world.min_distance),
    }, args.repeats)

    return results


def ratios(results: dict[str, Any]) -> None:
    r = results["panda_hand_fk_single"]
    r["ratio_pinocchio_over_genplan"] = r["pinocchio_us"] / r["genplan_us"]
    r = results["talos_all_links_batched"]
    r["ratio_pinocchio_over_genplan"] = r["pinocchio_loop_us_per_config"] / r["genplan_us_per_config"]


def alternate(args: argparse.Namespace) -> dict[str, dict[str, Any]]:
    """Rounds of one repeat each in fresh processes, the build installed in ``--before-site``
    (PYTHONPATH: a ``pip install --target`` of an older wheel) and this tree's alternating;
    medians over rounds per side."""
    rounds: dict[str, list[dict[str, Any]]] = {"before": [], "after": []}
    base = [sys.executable, __file__, "--child", "--repeats", "1", "--calls", str(args.calls), "--n", str(args.n)]
    for r in range(args.repeats):
        for side in (("before", "after") if r % 2 == 0 else ("after", "before")):
            env = dict(os.environ)
            if side == "before":
                env["PYTHONPATH"] = str(args.before_site)
            out = subprocess.run(base, env=env, capture_output=True, text=True, check=True).stdout
            rounds[side].append(json.loads(out.strip().splitlines()[-1]))
    merged: dict[str, dict[str, Any]] = {}
    for side, runs in rounds.items():
        merged[side] = {name: {k: statistics.median(run[name][k] for run in runs) for k in runs[0][name]}
                        for name in runs[0]}
        merged[side]["build"] = runs[0]["build"]
    return merged


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--label", default="current")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--calls", type=int, default=20_000, help="single calls per repeat")
    parser.add_argument("--n", type=int, default=10_000, help="rows of a batch")
    parser.add_argument("--out", type=Path, default=ROOT / "benches" / "results" / "boundary.json")
    parser.add_argument("--before-site", type=Path, help="alternate with the genplan installed there (see alternate)")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:  # one round for alternate(): JSON on the last line
        res = measure(args)
        res["build"] = {"genplan": str(Path(genplan.__file__).parent)}
        print(json.dumps(res))
        return
    load_before = os.getloadavg()
    if args.before_site:
        sides = alternate(args)
        stored_as = {f"{args.label}_before": sides["before"], f"{args.label}_after": sides["after"]}
    else:
        stored_as = {args.label: measure(args)}
    for label, results in stored_as.items():
        ratios(results)
        print(label)
        for name, entry in results.items():
            print(" ", name, {k: round(v, 3) if isinstance(v, float) else v for k, v in entry.items()})
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    dirty = bool(subprocess.run(["git", "status", "--porcelain"], cwd=ROOT, capture_output=True, text=True).stdout.strip())
    command = f"python benches/boundary.py --label {args.label} --repeats {args.repeats}"
    if args.before_site:
        command += f" --before-site {args.before_site}"
    meta = {"commit": commit, "dirty_tree": dirty, "repeats": args.repeats, "calls": args.calls,
            "load_before": load_before, "load_after": os.getloadavg(), "command": command}
    print("load", meta["load_before"], "->", meta["load_after"])
    stored = json.loads(args.out.read_text()) if args.out.is_file() else {}
    for label, results in stored_as.items():
        results["meta"] = meta
        stored[label] = results
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(stored, indent=2) + "\n")
    print(f"wrote {args.out} ({', '.join(stored_as)})")


if __name__ == "__main__":
    main()
