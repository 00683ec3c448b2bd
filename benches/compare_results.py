"""Compare a fresh benchmark JSON with a committed one: are the results the same?

    python benches/compare_results.py benches/results/table2_genplan_nodes_only.json out/table2.json
    python benches/compare_results.py benches/results/table1_panda_gan.json out/table1_panda_gan.json

Seeded runs of genplan's planner and solver are deterministic, so a refactoring that keeps
behaviour must reproduce every count exactly (success, projection steps, extensions, nodes,
retries; Table I: success and steps*); times are printed beside each other as a ratio, since
they depend on the machine's load. Prints one line per row and exits 1 if any count differs.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

#: fields compared exactly (the rest are times)
TABLE2_COUNTS = ("success_rate", "projections", "extensions", "nodes", "retries")
TABLE1_COUNTS = ("success_rate", "steps_star")


def _rows(d: dict[str, Any]) -> dict[tuple[str, ...], tuple[dict[str, Any], tuple[str, ...], str]]:
    """(row key) -> (row, count fields, time field) for Table II (rows) or Table I (projection/ik)."""
    if "rows" in d:
        return {(r["env"], r["planner"], r["sampler"]): (r, TABLE2_COUNTS, "t_ave_s") for r in d["rows"]}
    return {(d["robot"], d["init"], part): (d[part], TABLE1_COUNTS, "t_ave_ms") for part in ("projection", "ik") if part in d}


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    ref, new = (_rows(json.loads(Path(p).read_text())) for p in argv)
    status = 0
    for key in sorted(ref.keys() & new.keys()):
        (a, fields, t), (b, _, _) = ref[key], new[key]
        diffs = [f"{f} {a[f]} -> {b[f]}" for f in fields if a.get(f) != b.get(f)]
        ratio = b[t] / a[t] if a.get(t) else float("nan")
        print(f"{' / '.join(key):<32} {'identical counts' if not diffs else 'DIFFERENT: ' + '; '.join(diffs)}"
              f"   {t} {a[t]:.4g} -> {b[t]:.4g} ({ratio:.2f}x)")
        status |= bool(diffs)
    for key in sorted(ref.keys() ^ new.keys()):
        print(f"{' / '.join(key):<32} only in {'the reference' if key in ref else 'the new run'}")
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
