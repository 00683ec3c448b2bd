"""Jerk-limited rest-to-rest timing against ruckig: random Panda moves (start and goal uniform
within the joint limits), each timed by genplan's phase-synchronised S-curve
(genplan_core::jerk, ``genplan.trajectory.parameterize_jerk``) and by ruckig (offline
``Ruckig.calculate``) with phase synchronisation (the straight line in joint space, as genplan's)
and with ruckig's default time synchronisation (each joint its own profile, ending together:
not a straight line, so it may be shorter).

    python benches/jerk_timing.py --moves 1000 --seed 0 --out benches/results/jerk_timing.json

Limits: the Panda URDF's velocity limits, genplan's default acceleration (2 x velocity per
second) and jerk (10 x acceleration per second) limits, the same for both. Per move: the
durations, their ratios, ruckig's deviation from the straight line (largest distance of its
positions from the segment, 200 samples), and the compute time of each, in alternating order
(which goes first flips each move), each the fastest of ``--repeats`` calls: genplan's profile
alone (``_core.JerkPath``: the durations), ruckig's ``calculate``, and genplan's whole
``parameterize_jerk`` at 1 kHz (profile, samples, limit checks). Needs ``pip install ruckig``
(the ``bench`` extra).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

import genplan
from genplan import _core
from genplan.experiments.common import machine, write_json
from genplan.trajectory import DEFAULT_JERK_FACTOR, joint_limits, parameterize_jerk


def fastest(f: Any, repeats: int) -> tuple[float, Any]:
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--moves", type=int, default=1000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args()
    import ruckig

    panda = genplan.load("panda")
    n = panda.nv
    vlim, alim = joint_limits(panda)
    jlim = DEFAULT_JERK_FACTOR * alim
    rng = np.random.default_rng(args.seed)
    lower, upper = panda.lower, panda.upper
    moves = rng.uniform(lower, upper, size=(args.moves, 2, n))

    def ruckig_time(q0: np.ndarray, q1: np.ndarray, sync: Any) -> tuple[float, Any]:
        otg = ruckig.Ruckig(n)
        inp = ruckig.InputParameter(n)
        inp.current_position, inp.target_position = q0.tolist(), q1.tolist()
        inp.current_velocity = inp.current_acceleration = [0.0] * n
        inp.target_velocity = inp.target_acceleration = [0.0] * n
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = vlim.tolist(), alim.tolist(), jlim.tolist()
        inp.synchronization = sync
        traj = ruckig.Trajectory(n)

        def calc() -> Any:
            return otg.calculate(inp, traj)

        s, result = fastest(calc, args.repeats)
        if result != ruckig.Result.Working:
            raise RuntimeError(f"ruckig: {result}")
        return s, traj

    def off_line(traj: Any, q0: np.ndarray, q1: np.ndarray) -> float:
        d = q1 - q0
        worst = 0.0
        for t in np.linspace(0.0, traj.duration, 200):
            q = np.asarray(traj.at_time(t)[0])
            s = float(np.clip(np.dot(q - q0, d) / np.dot(d, d), 0.0, 1.0))
            worst = max(worst, float(np.linalg.norm(q - (q0 + s * d))))
        return worst

    rows: list[dict[str, Any]] = []
    t_start = time.time()
    parameterize_jerk(panda, moves[0])  # warm-up
    for i, (q0, q1) in enumerate(moves):
        states = np.ascontiguousarray(moves[i])
        # alternating order: genplan first on even moves, ruckig first on odd ones
        order = ("genplan", "ruckig") if i % 2 == 0 else ("ruckig", "genplan")
        row: dict[str, Any] = {"move": i}
        for who in order:
            if who == "genplan":
                s, path = fastest(lambda: _core.JerkPath(states, vlim.tolist(), alim.tolist(), jlim.tolist()),
                                  args.repeats)
                row["genplan_profile_us"] = 1e6 * s
                row["genplan_s"] = path.duration
                s, traj = fastest(lambda: parameterize_jerk(panda, states), args.repeats)
                row["genplan_parameterize_jerk_ms"] = 1e3 * s
                row["genplan_samples"] = len(traj)
            else:
                s, phase = ruckig_time(q0, q1, ruckig.Synchronization.Phase)
                row["ruckig_phase_us"] = 1e6 * s
                row["ruckig_phase_s"] = phase.duration
                row["ruckig_phase_off_line"] = off_line(phase, q0, q1)
                s, timed = ruckig_time(q0, q1, ruckig.Synchronization.Time)
                row["ruckig_time_us"] = 1e6 * s
                row["ruckig_time_s"] = timed.duration
                row["ruckig_time_off_line"] = off_line(timed, q0, q1)
        row["ratio_phase"] = row["genplan_s"] / row["ruckig_phase_s"]
        row["ratio_time"] = row["genplan_s"] / row["ruckig_time_s"]
        rows.append(row)

    def col(k: str) -> np.ndarray:
        return np.asarray([r[k] for r in rows])

    straight = col("ruckig_phase_off_line") <= 1e-6
    summary = {
        "moves": len(rows),
        "ratio_phase_median": float(np.median(col("ratio_phase"))),
        "ratio_phase_min": float(col("ratio_phase").min()),
        "ratio_phase_max": float(col("ratio_phase").max()),
        "ruckig_phase_straight": int(straight.sum()),
        "ratio_phase_straight_max_abs_error": float(np.max(np.abs(col("ratio_phase")[straight] - 1.0)))
        if straight.any() else None,
        "ratio_time_median": float(np.median(col("ratio_time"))),
        "ratio_time_max": float(col("ratio_time").max()),
        "ruckig_time_off_line_median": float(np.median(col("ruckig_time_off_line"))),
        "genplan_profile_us_median": float(np.median(col("genplan_profile_us"))),
        "ruckig_phase_us_median": float(np.median(col("ruckig_phase_us"))),
        "ruckig_time_us_median": float(np.median(col("ruckig_time_us"))),
        "profile_time_ratio_vs_ruckig_phase": float(np.median(col("genplan_profile_us") / col("ruckig_phase_us"))),
        "genplan_parameterize_jerk_ms_median": float(np.median(col("genplan_parameterize_jerk_ms"))),
        "genplan_samples_median": float(np.median(col("genplan_samples"))),
    }
    for k, v in summary.items():
        print(f"{k}: {v:.6g}" if isinstance(v, float) else f"{k}: {v}")
    write_json(args.out, {"command": f"python benches/jerk_timing.py --moves {args.moves} --seed {args.seed} "
                                     f"--repeats {args.repeats}",
                          "machine": machine(), "load_average": os.getloadavg(), "seconds": time.time() - t_start,
                          "limits": {"velocity": vlim.tolist(), "acceleration": alim.tolist(), "jerk": jlim.tolist()},
                          "ruckig": getattr(ruckig, "__version__", "?"), "summary": summary, "rows": rows})


if __name__ == "__main__":
    main()
