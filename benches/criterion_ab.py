"""Two builds of a criterion bench run alternately, for a before/after of a kernel on a busy
machine (one criterion run after the other drifts with the load by more than most changes).

    python benches/criterion_ab.py BEFORE_BIN AFTER_BIN FILTER [--rounds 5] [--time 2] [--out FILE]

BEFORE_BIN / AFTER_BIN: the bench executables (``cargo bench --bench kinematics --no-run``
prints the path; build "before" from ``git archive <rev>`` in another folder with its own
CARGO_TARGET_DIR). Each round runs both with ``--bench FILTER --measurement-time T``
(their order alternating); prints and returns the median over rounds of each bench's criterion
median, with the load average before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess

LINE = re.compile(r"^(\S+)\s+time:\s+\[\S+ \S+ (\S+) (\S+) \S+ \S+\]", re.M)
UNIT = {"ps": 1e-3, "ns": 1.0, "µs": 1e3, "us": 1e3, "ms": 1e6, "s": 1e9}


def run(binary: str, flt: str, seconds: float) -> dict[str, float]:
    out = subprocess.run([binary, "--bench", flt, "--measurement-time", str(seconds), "--noplot"],
                         capture_output=True, text=True, check=True).stdout
    # criterion prints "name  time:   [lo unit med unit hi unit]" (the name on its own line if long)
    flat = re.sub(r"\n\s+time:", " time:", out)
    return {name: float(med) * UNIT[unit] for name, med, unit in LINE.findall(flat)}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("before")
    parser.add_argument("after")
    parser.add_argument("filter")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--time", type=float, default=2.0)
    parser.add_argument("--out", help="also write the JSON here")
    args = parser.parse_args()
    load_before = os.getloadavg()
    runs: dict[str, dict[str, list[float]]] = {"before": {}, "after": {}}
    for r in range(args.rounds):
        order = ["before", "after"] if r % 2 == 0 else ["after", "before"]
        for side in order:
            for name, ns in run(getattr(args, side), args.filter, args.time).items():
                runs[side].setdefault(name, []).append(ns)
    result = {side: {name: statistics.median(v) for name, v in benches.items()} for side, benches in runs.items()}
    result["load"] = {"before": load_before, "after": os.getloadavg()}
    result["command"] = f"python benches/criterion_ab.py BEFORE AFTER {args.filter} --rounds {args.rounds} --time {args.time}"
    print(json.dumps(result, indent=2))
    if args.out:
        with open(args.out, "w") as f:
            f.write(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
