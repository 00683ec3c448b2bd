"""The cost of a projection iteration with the native RelativePose term against a built-in
absolute FramePose term of the same size (6 rows), on Baxter holding a tray in both hands
(examples/baxter): the right gripper's pose in the left's, or in the world.

    python benches/relative_terms.py [--n 200] [--iterations 5] [--rounds 9] [--no-python]
                                     [--out benches/results/relative_terms.json]

Each side solves the same ``--n`` uniform random starts towards the same poses (taken at other
random configurations) with the task ``[pose term, JointLimits]`` + ``[Posture]``, on one thread
(``parallel=False``), ``max_iterations = --iterations``, whole steps (``max_backtracks = 1``,
``secondary_backtracks = 1``: each iteration evaluates the same things on every side, whatever
the line search would have done on each problem); a projection iteration costs the sum of the
solves' own times (the native ``time_s``) over the sum of their iterations. The sides alternate
within each of ``--rounds`` rounds (after one untimed round); the figures are the medians over the
rounds, and the ratio is ``relative_pose / frame_pose`` (of the medians; also the median of the
rounds' own ratios, steadier when the machine's load changes between rounds). The ``python_custom`` side, unless
``--no-python``, is the same relative pose as a Python ``CustomTerm`` (Pinocchio per call: what
a user had to write without the native term). The load average is recorded before and after.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import os
import statistics
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

import genplan
from genplan import projection as P
from genplan._files import write_text

ROOT = Path(__file__).resolve().parents[1]
LEFT, RIGHT = "left_gripper", "right_gripper"


@dataclasses.dataclass(frozen=True)
class PythonRelativePose(P.CustomTerm):
    """The RelativePose residual and Jacobian in Python, through its Pinocchio twin."""

    robot: Any = None
    target: Any = None

    @property
    def dim(self) -> int:
        return 6

    @functools.cached_property
    def _bound(self) -> Any:  # bound once (frame ids, the target's inverse)
        return P.RelativePose(frame=RIGHT, relative_to=LEFT, target=self.target).bind(self.robot)

    def residual(self, q: np.ndarray) -> np.ndarray:
        b = self._bound
        return np.array([b.residual(P._State(self.robot, x, False)) for x in q])

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        b = self._bound
        return np.array([b.jacobian(P._State(self.robot, x, True)) for x in q])

    def residual_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        b = self._bound
        states = [P._State(self.robot, x, True) for x in q]
        return np.array([b.residual(s) for s in states]), np.array([b.jacobian(s) for s in states])


def task(term: P.Term) -> P.Task:
    return P.Task(name=type(term).__name__, primary=[term, P.JointLimits(weight=10.0)], secondary=[P.Posture()])


def per_iteration(solver: P.GaussNewtonProjector, q0: np.ndarray) -> tuple[float, float]:
    """(us per iteration, share of the solves that ran every iteration) of one batch."""
    out = solver.solve_batch(q0, parallel=False)
    return float(out.time_s.sum() / max(1, out.iterations.sum()) * 1e6), float((out.iterations == solver.settings.max_iterations).mean())


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=200, help="starts per side and round")
    ap.add_argument("--iterations", type=int, default=5, help="max_iterations of every solve")
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--no-python", action="store_true", help="skip the Python CustomTerm side")
    ap.add_argument("--out", type=Path, default=ROOT / "benches" / "results" / "relative_terms.json")
    args = ap.parse_args(argv)
    load_before = os.getloadavg()

    baxter = genplan.load(ROOT / "examples" / "baxter" / "baxter.toml")
    rng = np.random.default_rng(0)
    goal = baxter.random_configurations(1, rng)[0]
    q0 = baxter.random_configurations(args.n, rng)
    world = baxter.frame_placement(goal, RIGHT)
    rel = baxter.frame_placement(goal, LEFT).actInv(world)
    # whole steps, one posture try: every iteration of every side does the same evaluations (one
    # Jacobian, the step's residuals, one posture step's), so the ratio measures the terms, not
    # how many backtracks each problem happens to take
    settings = P.SolverSettings(max_iterations=args.iterations, max_backtracks=1, secondary_backtracks=1)
    terms: dict[str, P.Term] = {
        "frame_pose": P.FramePose(name="pose", frame=RIGHT, target=world, weight=10.0, tolerance=1e-9),
        "relative_pose": P.RelativePose(name="pose", frame=RIGHT, relative_to=LEFT, target=rel, weight=10.0, tolerance=1e-9),
    }
    if not args.no_python:
        terms["python_custom"] = PythonRelativePose(name="pose", robot=baxter, target=rel, weight=10.0, tolerance=1e-9)
    solvers = {k: P.GaussNewtonProjector(baxter, task(t), settings) for k, t in terms.items()}
    # the native and Python relative terms are one residual: the same first iterate
    if "python_custom" in solvers:
        a = solvers["relative_pose"].solve_batch(q0[:3], parallel=False)
        b = solvers["python_custom"].solve_batch(q0[:3], parallel=False)
        assert np.abs(a.q - b.q).max() < 1e-6, np.abs(a.q - b.q).max()

    sides: dict[str, Callable[[], tuple[float, float]]] = {k: functools.partial(per_iteration, s, q0) for k, s in solvers.items()}
    for f in sides.values():  # warm-up, not counted
        f()
    runs: dict[str, list[float]] = {k: [] for k in sides}
    full: dict[str, list[float]] = {k: [] for k in sides}
    for r in range(args.rounds):
        order = list(sides) if r % 2 == 0 else list(reversed(sides))  # alternate who goes first
        for k in order:
            us, share = sides[k]()
            runs[k].append(us)
            full[k].append(share)
    medians = {k: statistics.median(v) for k, v in runs.items()}
    result: dict[str, Any] = {
        "robot": "baxter (examples/baxter/baxter.toml, 14 joints)",
        "task": "[pose term (6 rows), JointLimits] + [Posture]; pose term: right_gripper in the world (frame_pose) "
                "or in left_gripper's frame (relative_pose, python_custom); whole steps (max_backtracks=1, "
                "secondary_backtracks=1)",
        "n": args.n, "max_iterations": args.iterations, "rounds": args.rounds,
        "us_per_iteration_median": medians,
        "us_per_iteration_rounds": runs,
        "share_of_solves_at_max_iterations": {k: statistics.median(v) for k, v in full.items()},
        "ratio_relative_over_frame_pose": medians["relative_pose"] / medians["frame_pose"],
        # the two sides of one round ran back to back, under the same load
        "ratio_per_round_median": statistics.median(a / b for a, b in zip(runs["relative_pose"], runs["frame_pose"])),
        "target_ratio": 1.5,
        "load_before": load_before, "load_after": os.getloadavg(),
        "command": " ".join(["python benches/relative_terms.py", *(sys.argv[1:] if argv is None else argv)]),
    }
    if "python_custom" in medians:
        result["ratio_python_custom_over_relative_pose"] = medians["python_custom"] / medians["relative_pose"]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_text(args.out, json.dumps(result, indent=2) + "\n")
    for k, v in medians.items():
        print(f"{k:>15}: {v:8.2f} us per iteration")
    print(f"relative_pose / frame_pose = {result['ratio_relative_over_frame_pose']:.3f} (target <= 1.5); "
          f"load {load_before[0]:.2f} -> {result['load_after'][0]:.2f}; written to {args.out}")


if __name__ == "__main__":
    main()
