"""The CPU time of `genplan train gan` with the defaults, per part: a shortened training run and the
data generation, for a robot and task (default: Baxter carrying the tray, examples/baxter).

    python benches/gan_training.py [--robot examples/baxter/baxter_tray.toml] [--task examples/baxter/tray.toml]
                                   [--iterations 300] [--data-rows 2000] [--data-size N] [--rounds 3]
                                   [--baseline DIR]
                                   [--out benches/results/gan_training_baxter_tray.json]

Each measurement runs in a fresh worker process (this script with ``--worker``): ``train`` runs
:func:`genplan.samplers.gan.train` on :func:`~genplan.samplers.gan.default_config` with
``--iterations`` (its data from the data cache, generated once beforehand; one torch thread,
genplan's training choice); ``data`` runs :func:`genplan.samplers.data.generate` for
``--data-rows`` rows (the default share in the condition box, every core). Both record the
process's CPU seconds (``time.process_time``: all its threads) and wall seconds; the training's
CPU per iteration (the run's less a one-iteration run's, which holds the setup) times the default
iteration count, plus the setup, estimates the full run's training.

``--baseline DIR``: DIR holds another build of the ``genplan`` package (a copy of
``python/genplan`` with its ``_core`` module); each round runs both builds, alternating which goes
first, and the JSON holds both builds' medians and the ratio this build / baseline. The 1-minute
load average before and after is recorded: on a shared machine the wall times follow the load,
the CPU times much less.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "baxter"


def worker(args: argparse.Namespace) -> dict[str, Any]:
    """One measurement in this process: ``args.part`` is "train" or "data"."""
    import warnings

    import torch

    import genplan
    from genplan import projection as P
    from genplan.samplers import gan

    warnings.simplefilter("ignore")  # the robot file's SRDF warnings, once per process
    torch.set_num_threads(1)
    robot = genplan.load(str(args.robot))
    task = P.load_task(str(args.task), robot)
    cfg = gan.default_config(robot, task, iterations=args.iterations, seed=0,
                             **({"data_size": args.data_size} if args.data_size else {}))
    out: dict[str, Any] = {"default_iterations": gan.GanConfig.iterations, "data_size": cfg.data_size,
                           "genplan": gan.__file__}
    if args.part == "train":
        # a one-iteration run to warm the process (imports, the data cache, torch's first calls),
        # another for the setup (the data's kinematics, the networks), then the run
        gan.train(dataclasses.replace(cfg, iterations=1), progress=False, robot=robot, task=task, threads=1)
        for key, its in (("setup", 1), ("", args.iterations)):
            c0, w0 = time.process_time(), time.perf_counter()
            gan.train(dataclasses.replace(cfg, iterations=its), progress=False, robot=robot, task=task, threads=1)
            out[key + "cpu_s" if not key else f"{key}_cpu_s"] = time.process_time() - c0
            out["wall_s" if not key else f"{key}_wall_s"] = time.perf_counter() - w0
        return out
    from genplan.samplers.data import generate

    c0, w0 = time.process_time(), time.perf_counter()
    generate(robot, args.data_rows, 1, task, progress=False, in_box=cfg.data_in_box)
    return {**out, "cpu_s": time.process_time() - c0, "wall_s": time.perf_counter() - w0}


def run(build: Path | None, part: str, args: argparse.Namespace) -> dict[str, Any]:
    """A worker process of ``build`` (None: this checkout's) measuring ``part``."""
    env = dict(os.environ, GENPLAN_TORCH_THREADS="1")
    if build is not None:
        env["PYTHONPATH"] = str(build)
    cmd = [sys.executable, __file__, "--worker", "--part", part, "--robot", str(args.robot), "--task", str(args.task),
           "--iterations", str(args.iterations), "--data-rows", str(args.data_rows), "--data-size", str(args.data_size)]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        name = "this build" if build is None else f"the baseline build ({build})"
        raise SystemExit(f"gan_training: {name} failed measuring {part}:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", type=Path, default=EXAMPLES / "baxter_tray.toml")
    ap.add_argument("--task", type=Path, default=EXAMPLES / "tray.toml")
    ap.add_argument("--iterations", type=int, default=300, help="training iterations a measurement runs (>= 2)")
    ap.add_argument("--data-rows", type=int, default=2000, help="rows a data measurement generates (0: none)")
    ap.add_argument("--data-size", type=int, default=0,
                    help="rows of the training's data set (default 0: the config's, 25,000)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--baseline", type=Path, default=None, help="a directory holding another build's genplan package")
    ap.add_argument("--out", type=Path, default=ROOT / "benches" / "results" / "gan_training_baxter_tray.json")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--part", choices=("train", "data"), default="train", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(worker(args)))
        return
    from genplan._files import write_text

    builds: dict[str, Path | None] = {"this": None}
    if args.baseline is not None:
        if not (args.baseline / "genplan" / "__init__.py").is_file():
            ap.error(f"--baseline: expected a folder holding a genplan package, got {args.baseline}")
        builds["baseline"] = args.baseline.resolve()
    if args.iterations < 2:
        ap.error(f"--iterations: at least 2 (one is the setup's run), got {args.iterations}")
    parts = ["train"] + (["data"] if args.data_rows > 0 else [])
    load_start = os.getloadavg()[0]
    rows: dict[str, dict[str, list[dict[str, Any]]]] = {b: {p: [] for p in parts} for b in builds}
    for r in range(args.rounds):
        order = list(builds) if r % 2 == 0 else list(reversed(builds))
        for part in parts:
            for b in order:
                m = run(builds[b], part, args)
                rows[b][part].append(m)
                if len(builds) == 2 and len(rows["baseline"][part]) == len(rows["this"][part]) == 1 \
                        and rows["baseline"][part][0]["genplan"] == rows["this"][part][0]["genplan"]:
                    raise SystemExit(f"--baseline: both builds imported genplan from {m['genplan']}")
                print(f"round {r} {part} {b}: cpu {m['cpu_s']:.2f} s, wall {m['wall_s']:.2f} s, "
                      f"load {os.getloadavg()[0]:.1f}", flush=True)
    summary: dict[str, Any] = {}
    for b in builds:
        s: dict[str, Any] = {}
        train = rows[b]["train"]
        cpu = statistics.median(m["cpu_s"] for m in train)
        setup = statistics.median(m["setup_cpu_s"] for m in train)  # one iteration and the setup
        per_it = statistics.median((m["cpu_s"] - m["setup_cpu_s"]) / (args.iterations - 1) for m in train)
        s["train"] = {"iterations": args.iterations, "median_cpu_s": cpu,
                      "median_wall_s": statistics.median(m["wall_s"] for m in train),
                      "median_setup_cpu_s": setup, "cpu_ms_per_iteration": 1e3 * per_it,
                      "full_run_cpu_s_estimate": setup + per_it * (train[0]["default_iterations"] - 1)}
        if "data" in parts:
            data = rows[b]["data"]
            dcpu = statistics.median(m["cpu_s"] for m in data)
            s["data"] = {"rows": args.data_rows, "median_cpu_s": dcpu,
                         "median_wall_s": statistics.median(m["wall_s"] for m in data),
                         "full_data_cpu_s_estimate": dcpu / args.data_rows * data[0]["data_size"]}
        summary[b] = s
    result: dict[str, Any] = {
        "robot": str(args.robot.resolve().relative_to(ROOT)) if args.robot.resolve().is_relative_to(ROOT) else str(args.robot),
        "task": str(args.task.resolve().relative_to(ROOT)) if args.task.resolve().is_relative_to(ROOT) else str(args.task),
        "command": " ".join(["python", "benches/gan_training.py", *sys.argv[1:]]),
        "rounds": args.rounds, "cores": os.cpu_count(), "torch_threads": 1,
        "load_average_1min_start_end": [load_start, os.getloadavg()[0]],
        "summary": summary, "measurements": rows,
    }
    if args.baseline is not None:
        result["ratio_this_over_baseline"] = {
            p: summary["this"][p]["median_cpu_s"] / summary["baseline"][p]["median_cpu_s"] for p in parts}
    write_text(args.out, json.dumps(result, indent=1) + "\n")
    print(json.dumps({"summary": summary, "ratio_this_over_baseline": result.get("ratio_this_over_baseline"),
                      "load_average_1min_start_end": result["load_average_1min_start_end"]}, indent=1))


if __name__ == "__main__":
    main()
