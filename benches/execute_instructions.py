"""Instructions per 1 kHz tick under callgrind: the cost of a tick that the machine's load does
not move.

    python benches/execute_instructions.py --out benches/results/execute_instructions.json

Runs the tick configurations of ``benches/execute.py`` (the same motions, controllers and plant
deviations; by default the UR5 spatula configuration, the Panda in task and joint space and the
xArm7 in task space; ``--rows all``: every row) once each in one Python process under
``valgrind --tool=callgrind``, counting only the instructions executed inside
``Simulation::tick`` (controller, observer, plant RK4 step, payload step: ``--toggle-collect``)
and writing one callgrind dump per run (``--dump-after`` on ``Simulation::run_with``). Per row:
the instructions over the run divided by its ticks. Rounding-dependent branches (the friction's
small-speed series, a damped task solve) follow the motion, so the count is that of the whole
bench motion, not of one state. Needs valgrind (Debian's package); a run takes a minute or two,
most of it Python's start under valgrind.

``--child`` is the process valgrind runs (not for direct use).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

#: the function whose instructions are counted, and the one after which each run's count is dumped
TICK = "genplan_core::control::run::Simulation::tick"
RUN = "genplan_core::control::run::Simulation::run_with"
#: the rows of ``execute.py`` counted by default (robot, configuration prefix)
DEFAULT_ROWS = ["ur5:spatula", "panda:task", "panda:joint", "xarm7:task"]


def row_key(row: dict[str, Any]) -> str:
    """``robot:space`` of an ``execute.py`` configuration row (``ur5:spatula`` for the spatula)."""
    return f"{row['robot']}:{row.get('space', 'spatula')}"


def child(keys: list[str]) -> None:
    """Run the selected configurations one after the other; print each one's key and ticks as
    JSON lines (stdout)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import execute

    configurations = execute.tick_configurations()
    known = [row_key(row) for row, _ in configurations]
    for key in keys:
        if key not in known:
            raise SystemExit(f"unknown row {key!r}; rows: {', '.join(known)}")
    for key in keys:
        row, run = configurations[known.index(key)]
        log = run()
        print(json.dumps({"key": key, "row": row, "ticks": len(log.t)}), flush=True)


def totals(path: Path) -> int:
    """The instructions of one callgrind dump (its ``totals:`` line)."""
    for line in path.read_text().splitlines():
        if line.startswith(("totals:", "summary:")):
            return int(line.split()[1])
    raise ValueError(f"{path}: no totals line")


def count(keys: list[str], valgrind: str) -> list[dict[str, Any]]:
    """Run the child under callgrind; per key its ticks, instructions and instructions per tick."""
    with tempfile.TemporaryDirectory(prefix="genplan_callgrind_") as tmp:
        out = Path(tmp) / "callgrind.out"
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
        cmd = [valgrind, "--tool=callgrind", f"--callgrind-out-file={out}", "--collect-atstart=no",
               f"--toggle-collect={TICK}", f"--dump-after={RUN}", sys.executable, str(Path(__file__).resolve()),
               "--child", *keys]
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if proc.returncode != 0:
            raise SystemExit(f"callgrind run failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
        runs = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
        # the dumps after each run_with, in order (callgrind numbers them .1, .2, ...), then the final one
        dumps = sorted(Path(tmp).glob("callgrind.out.*"), key=lambda p: int(re.sub(r"\D", "", p.suffix) or 0))
        dumps = [d for d in dumps if d.suffix[1:].isdigit()]
        if len(dumps) < len(runs):
            raise SystemExit(f"{len(dumps)} callgrind dumps for {len(runs)} runs")
        rows = []
        for r, dump in zip(runs, dumps):
            ir = totals(dump)
            rows.append({"key": r["key"], "robot": r["row"]["robot"], "joints": r["row"]["joints"],
                         "configuration": r["row"].get("configuration") or f"{r['row']['space']} space",
                         "ticks": r["ticks"], "instructions": ir, "instructions_per_tick": ir / r["ticks"]})
        return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", nargs="+", default=DEFAULT_ROWS,
                        help="robot:space keys of execute.py's rows (ur5:spatula, panda:task, ...; 'all': every row)")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child)
        return
    from genplan.experiments.common import machine, table, write_json

    valgrind = shutil.which("valgrind")
    if valgrind is None:
        raise SystemExit("valgrind not found (apt-get install valgrind)")
    keys = args.rows
    if keys == ["all"]:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        import execute

        keys = [row_key(row) for row, _ in execute.tick_configurations()]
    t0 = time.perf_counter()
    rows = count(keys, valgrind)
    print(table(["robot", "controller", "joints", "ticks", "instructions / tick"],
                [[r["robot"], r["configuration"], r["joints"], r["ticks"], round(r["instructions_per_tick"])] for r in rows]))
    import genplan

    payload = {"benchmark": "execute_instructions", "machine": machine(), "seconds": time.perf_counter() - t0,
               "command": " ".join(["python", *sys.argv]), "counted": TICK, "module": str(Path(genplan.__file__).parent),
               "rows": rows}
    write_json(args.out, payload)


if __name__ == "__main__":
    main()
