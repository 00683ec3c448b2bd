"""Data generation with a Python constraint term on 1 and on 2 worker processes: the training data
of a Panda task whose manifold holds a Python ``CustomTerm`` (the wrist on a circle,
tests/custom_terms_example.py: a curve no built-in term expresses), each worker importing the
term by its entry.

    python benches/custom_term_data.py [--n 1200] [--shard-size 150] [--rounds 5]
                                       [--out benches/results/custom_term_data.json]

Each round times ``genplan.samplers.data.generate`` (the same ``--n`` configurations, seed 0, in
shards of ``--shard-size``) on a ``LocalExecutor`` of 1 process, of 2 processes, and of 2 threads
(the run before Python terms went to processes: the GIL lets one term call run at a time), the
sides alternating (after one untimed round of each); a time is the whole call, the workers'
start (spawn, imports, the robot and its projector) included. The figures are the medians over
the rounds; ``speedup`` is ``1 process / 2 processes`` of the medians (also the median of the
rounds' own ratios). Every side's data set is checked to be the same array (the executor never
changes a result). The load average is recorded before and after, and each side's CPU seconds
(the worker processes', or this process's for threads): on a machine whose cores other work
keeps busy, two workers get less than two cores, and the CPU seconds show whether the work itself
grew (the second worker's start) or only the wait for a core. A control measures what the
machine gives at that moment: the same ``--control-seconds`` of pure-Python CPU work split over 1
or 2 spawned processes (``control_speedup``: 2.0 on two idle cores).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # the example term's module, tests.custom_terms_example (workers inherit sys.path)
    sys.path.insert(0, str(ROOT))

SIDES = (("process", 1), ("process", 2), ("thread", 2))


def make_task(robot: Any) -> Any:
    """The Panda's hand position as the condition, the wrist on a circle (a Python term)."""
    from genplan import projection as P
    from tests.custom_terms_example import OnCircle

    return P.Task(primary=[P.FramePosition(frame="hand", target=None, weight=50, name="hand_position"),
                           OnCircle(robot=robot, weight=30, tolerance=1e-3, name="wrist"),
                           P.JointLimits(weight=30, name="joint_limits")],
                  secondary=[P.Posture(name="posture")], name="panda_wrist_on_circle",
                  condition=P.Condition("hand_position", (0.3, -0.4, 0.3), (0.6, 0.4, 0.7)))


def _spin(seconds: float) -> int:
    """``seconds`` of this process's CPU time in a Python loop (the control's work)."""
    t0, x = time.process_time(), 0
    while time.process_time() - t0 < seconds:
        x += 1
    return x


def _control(workers: int, seconds: float) -> float:
    """Wall seconds of ``seconds`` of CPU work split over ``workers`` spawned processes (started
    before the clock starts)."""
    import concurrent.futures as cf
    import multiprocessing

    with cf.ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        list(pool.map(_spin, [0.0] * workers))  # the workers start
        t0 = time.perf_counter()
        list(pool.map(_spin, [seconds / workers] * workers))
        return time.perf_counter() - t0


def _cpu_seconds() -> float:
    """User + system CPU seconds of this process and of its ended children."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def main(argv: list[str] | None = None) -> int:
    import genplan
    from genplan._files import write_text
    from genplan.executor import LocalExecutor
    from genplan.samplers.data import generate

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=1200, help="configurations per data set")
    p.add_argument("--shard-size", type=int, default=150, help="configurations per shard")
    p.add_argument("--rounds", type=int, default=5, help="timed rounds (each side once per round)")
    p.add_argument("--control-seconds", type=float, default=3.0,
                   help="CPU seconds of the control's work (0: no control; it needs this file run as a script)")
    p.add_argument("--out", type=Path, default=ROOT / "benches" / "results" / "custom_term_data.json")
    args = p.parse_args(argv)
    os.environ.setdefault("GENPLAN_TORCH_THREADS", "1")
    robot = genplan.load("panda")
    task = make_task(robot)
    load_before = os.getloadavg()
    times: dict[str, list[float]] = {f"{k}_{w}": [] for k, w in SIDES}
    cpu: dict[str, list[float]] = {f"{k}_{w}": [] for k, w in SIDES}
    control: dict[str, list[float]] = {"1": [], "2": []}
    reference: np.ndarray | None = None
    for r in range(args.rounds + 1):  # round 0: untimed
        for kind, workers in SIDES:
            c0 = _cpu_seconds()
            with LocalExecutor(workers, kind) as ex:
                t0 = time.perf_counter()
                data = generate(robot, args.n, 0, task, shard_size=args.shard_size, executor=ex, progress=False)
                dt = time.perf_counter() - t0
            used = _cpu_seconds() - c0  # after the pool's close: its workers have ended and are counted
            if reference is None:
                reference = data
            elif not np.array_equal(reference, data):
                raise AssertionError(f"{kind} x{workers}: another data set than the first side's")
            if r > 0:
                times[f"{kind}_{workers}"].append(dt)
                cpu[f"{kind}_{workers}"].append(used)
            print(f"round {r}{' (untimed)' if r == 0 else ''}: {kind} x{workers}: {dt:.2f} s ({used:.2f} CPU s)",
                  flush=True)
        if r > 0 and args.control_seconds > 0:
            for workers in (1, 2):
                control[str(workers)].append(_control(workers, args.control_seconds))
            print(f"round {r}: control {control['1'][-1]:.2f} s on 1 process, {control['2'][-1]:.2f} s on 2", flush=True)
    med = {k: statistics.median(v) for k, v in times.items()}
    ratios = [a / b for a, b in zip(times["process_1"], times["process_2"])]
    out = {
        "benchmark": "custom_term_data",
        "command": "python benches/custom_term_data.py " + " ".join(sys.argv[1:] if argv is None else argv),
        "robot": robot.name, "task": task.to_dict(), "n": args.n, "shard_size": args.shard_size,
        "rounds": args.rounds, "seconds": times, "median_seconds": med, "cpu_seconds": cpu,
        "median_cpu_seconds": {k: statistics.median(v) for k, v in cpu.items()},
        "cores_used": {k: statistics.median(c / t for c, t in zip(cpu[k], times[k])) for k in times},
        "configurations_per_second": {k: args.n / v for k, v in med.items()},
        "speedup_2_processes_over_1": med["process_1"] / med["process_2"],
        "speedup_median_of_round_ratios": statistics.median(ratios),
        "processes_2_over_threads_2": med["thread_2"] / med["process_2"],
        "control_seconds": control,
        "control_speedup": (statistics.median(control["1"]) / statistics.median(control["2"])
                            if control["1"] else None),
        "load_average_before_after": [list(load_before), list(os.getloadavg())],
        "cpu_count": os.cpu_count(),
    }
    write_text(args.out, json.dumps(out, indent=1) + "\n")
    print(f"median: 1 process {med['process_1']:.2f} s, 2 processes {med['process_2']:.2f} s "
          f"(speedup {out['speedup_2_processes_over_1']:.2f}x; median of round ratios "
          f"{out['speedup_median_of_round_ratios']:.2f}x), 2 threads {med['thread_2']:.2f} s; cores used "
          + ", ".join(f"{k} {v:.2f}" for k, v in out["cores_used"].items())
          + (f"; control speedup {out['control_speedup']:.2f}x" if control["1"] else "") + "; "
          f"load {load_before[0]:.2f} -> {os.getloadavg()[0]:.2f}; wrote {args.out}")
    return 0


if __name__ == "__main__":
    main()
