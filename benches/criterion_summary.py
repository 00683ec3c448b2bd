"""Run the Rust core's criterion benches and summarise their medians.

    python benches/criterion_summary.py [--out benches/results/criterion.json] [--skip-run]

Prints one line per bench (median and 95 % interval of the median, from criterion's own
estimates) and writes them as JSON with the machine's description.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "benches" / "results" / "criterion.json")
    parser.add_argument("--skip-run", action="store_true", help="only summarise the last run")
    parser.add_argument("--filter", default="", help="criterion filter (bench name substring)")
    args = parser.parse_args()
    if not args.skip_run:
        cmd = ["cargo", "bench", "--package", "genplan-core", "--", *([args.filter] if args.filter else [])]
        print("+", " ".join(cmd), flush=True)
        subprocess.run(cmd, cwd=ROOT, check=True)
    results = {}
    for est in sorted((ROOT / "target" / "criterion").glob("**/new/estimates.json")):
        bench = est.parent.parent.relative_to(ROOT / "target" / "criterion").as_posix()
        if args.filter and args.filter not in bench:
            continue
        median = json.loads(est.read_text())["median"]
        ci = median["confidence_interval"]
        results[bench] = {
            "median_ns": median["point_estimate"],
            "ci95_ns": [ci["lower_bound"], ci["upper_bound"]],
        }
    if not results:
        print("no criterion results found under target/criterion", file=sys.stderr)
        return 1
    width = max(len(b) for b in results)
    for bench, r in results.items():
        print(f"{bench:<{width}}  median {r['median_ns'] / 1e3:9.3f} us   "
              f"[{r['ci95_ns'][0] / 1e3:.3f}, {r['ci95_ns'][1] / 1e3:.3f}]")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "processor": platform.processor()},
        "benches": results,
    }
    args.out.write_text(json.dumps(payload, indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
