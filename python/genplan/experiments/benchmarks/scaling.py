"""Scaling of data generation (genplan.executor, genplan.samplers.data): one data set made on 1 and 2
local workers and on a local Ray with 2 CPUs; the speed-ups, projected samples per second per
core (Panda and Talos), and the data sets' sha256 (identical on every executor).

    genplan bench scaling --out benches/results/scaling.json
    genplan bench scaling --samples 200000 --talos-samples 20000 --repeats 3 --workers 2

The data set is the GAN's training set of the robot's shipped ``<robot>_ik`` task (its manifold:
for Panda the paper's projection task). Each configuration is timed ``--repeats`` times, the
configurations interleaved within a repeat so that they share the machine's load; the table
gives the median wall time (and the fastest). Ray's start (``ray.init``) and a warm-up run that
builds the projector in each worker are timed separately, not in the wall times. The 1-minute
load average is recorded before and after each run (on a shared machine others' work counts).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from typing import Any

from genplan.cli import args as A
from genplan.experiments.common import machine, table, write_json


def _load() -> float:
    return os.getloadavg()[0]


def timed(robot: Any, n: int, seed: int, shard_size: int, ex: Any) -> dict[str, Any]:
    """One data set of ``n`` configurations on ``ex``: wall time, rate, sha256, load before/after."""
    from genplan.samplers.data import dataset_sha256, generate

    load0 = _load()
    t0 = time.perf_counter()
    data = generate(robot, n, seed, shard_size=shard_size, executor=ex, progress=False)
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "samples_per_s": n / wall, "sha256": dataset_sha256([data]),
            "load_before": load0, "load_after": _load()}


def _summary(runs: list[dict[str, Any]], n: int, workers: int) -> dict[str, Any]:
    walls = [r["wall_s"] for r in runs]
    med = statistics.median(walls)
    return {"workers": workers, "samples": n, "wall_median_s": med, "wall_min_s": min(walls),
            "samples_per_s": n / med, "samples_per_s_per_core": n / med / workers,
            "sha256": runs[0]["sha256"], "sha256_same_every_repeat": len({r["sha256"] for r in runs}) == 1,
            "runs": runs}


def run(samples: int, talos_samples: int, repeats: int, workers: int, shard_size: int, seed: int = 0,
        use_ray: bool = True) -> dict[str, Any]:
    import genplan
    from genplan.executor import LocalExecutor, MissingExtraError, RayExecutor
    from genplan.samplers.data import CHUNK

    panda = genplan.load("panda")
    configs: dict[str, Any] = {"local-1": LocalExecutor(1), f"local-{workers}": LocalExecutor(workers)}
    ray_info: dict[str, Any] = {}
    if use_ray:
        t0 = time.perf_counter()
        try:
            configs[f"ray-{workers}"] = RayExecutor("auto", workers)
            ray_info = {"init_s": time.perf_counter() - t0, **configs[f"ray-{workers}"].describe()}
        except MissingExtraError as exc:
            ray_info = {"unavailable": str(exc)}
    try:
        warm = {}
        for name, ex in configs.items():  # builds the projector in every worker (Ray: in its processes)
            t0 = time.perf_counter()
            timed(panda, 4 * workers * CHUNK, seed + 1, CHUNK, ex)
            warm[name] = time.perf_counter() - t0
        runs: dict[str, list[dict[str, Any]]] = {name: [] for name in configs}
        for _ in range(repeats):
            for name, ex in configs.items():
                runs[name].append(timed(panda, samples, seed, shard_size, ex))
        rows = {name: {"executor": configs[name].name, **_summary(r, samples, configs[name].workers)}
                for name, r in runs.items()}
        base = rows["local-1"]["wall_median_s"]
        for r in rows.values():
            r["speedup_vs_local_1"] = base / r["wall_median_s"]
        local2 = rows[f"local-{workers}"]["wall_median_s"]
        if f"ray-{workers}" in rows:
            rows[f"ray-{workers}"]["wall_over_local"] = rows[f"ray-{workers}"]["wall_median_s"] / local2
        talos = genplan.load("talos")
        talos_rows = {}
        for name in ("local-1", f"local-{workers}"):
            ex = configs[name]
            timed(talos, workers * 200, seed + 1, 200, ex)  # warm-up: the Talos projector in each worker
            talos_rows[name] = {"executor": ex.name, **_summary(
                [timed(talos, talos_samples, seed, min(shard_size, max(1, talos_samples // (4 * workers))), ex)
                 for _ in range(repeats)], talos_samples, ex.workers)}
    finally:
        for ex in configs.values():
            ex.close()
    shas = {r["sha256"] for r in rows.values()}
    return {
        "benchmark": "scaling",
        "task": "panda_ik (its manifold: the paper's Panda projection task); talos_ik for Talos",
        "samples": samples,
        "talos_samples": talos_samples,
        "seed": seed,
        "shard_size": shard_size,
        "chunk": CHUNK,
        "repeats": repeats,
        "workers": workers,
        "units": {"samples_per_s": "projected configurations kept per second (wall time of the median repeat)",
                  "wall_*": "seconds", "load_*": "1-minute load average"},
        "warmup_s": warm,
        "ray": ray_info,
        "panda": rows,
        "talos": talos_rows,
        "sha256_identical": len(shas) == 1,
        "targets": {"local_2_over_1_speedup": {"target": ">= 1.7",
                                                "measured": rows[f"local-{workers}"]["speedup_vs_local_1"]},
                    "ray_within_15_percent_of_local": {"target": "<= 1.15",
                                                       "measured": rows.get(f"ray-{workers}", {}).get("wall_over_local")}},
        "machine": machine(),
    }


def print_table(payload: dict[str, Any]) -> None:
    rows = []
    for robot in ("panda", "talos"):
        for name, r in payload[robot].items():
            rows.append([robot, name, r["samples"], f"{r['wall_median_s']:.2f} ({r['wall_min_s']:.2f})",
                         f"{r['samples_per_s']:.0f}", f"{r['samples_per_s_per_core']:.0f}",
                         "-" if "speedup_vs_local_1" not in r else f"{r['speedup_vs_local_1']:.2f}x",
                         f"{min(x['load_before'] for x in r['runs']):.1f}-{max(x['load_after'] for x in r['runs']):.1f}",
                         r["sha256"][:16]])
    print(table(["robot", "executor", "samples", "wall s median (min)", "samples/s", "per core", "speed-up",
                 "load", "sha256"], rows))
    print(f"sha256 identical across executors: {payload['sha256_identical']}; "
          + ", ".join(f"{k}: {v['measured']:.2f} (target {v['target']})" for k, v in payload["targets"].items()
                      if v["measured"] is not None)
          + (f"; ray start {payload['ray']['init_s']:.1f} s" if "init_s" in payload["ray"] else
             f"; ray: {payload['ray'].get('unavailable', 'not run')}"))


def add_arguments(p: argparse.ArgumentParser) -> None:
    from genplan.samplers.data import SHARD_SIZE

    p.add_argument("--samples", type=A.positive_int, default=200_000, help="Panda data set size (default 200,000)")
    p.add_argument("--talos-samples", type=A.positive_int, default=20_000,
                   help="Talos data set size for its per-core rate (default 20,000)")
    p.add_argument("--repeats", type=A.positive_int, default=3, help="timed runs per executor (default 3)")
    p.add_argument("--workers", type=A.positive_int, default=2, help="workers of the parallel runs (default 2)")
    p.add_argument("--shard-size", type=A.positive_int, default=SHARD_SIZE,
                   help=f"configurations per shard (default {SHARD_SIZE})")
    p.add_argument("--seed", type=A.seed, default=0)
    p.add_argument("--no-ray", action="store_true", help="skip the Ray runs")
    p.add_argument("--out", type=A.output_file, default=None, help="write the results as JSON (folders are created)")


def main(args: argparse.Namespace) -> int:
    payload = run(args.samples, args.talos_samples, args.repeats, args.workers, args.shard_size, args.seed,
                  use_ray=not args.no_ray)
    print_table(payload)
    write_json(args.out, payload)
    return 0
