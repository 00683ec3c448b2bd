"""Seed sweeps of the benchmarks (``--seeds A..B``): each seed a shard on the execution layer
(:mod:`genplan.executor`), one JSON with the per-seed results and their median across seeds.

A seed's row is the benchmark's single-seed result for that seed (the same numbers as a run with
``--seed S``, but for the times, measured while other seeds may run: ``--workers 1``, the
default, runs them one after the other so that times are not shared between seeds).
"""

from __future__ import annotations

import statistics
from collections.abc import Callable, Sequence
from typing import Any

from genplan.executor import executor


def run_seeds(fn: Callable[[Any], dict[str, Any]], jobs: Sequence[Any], *, workers: int | None, ray: str | None,
              kind: str, desc: str) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """``fn(job)`` for each job (one per seed) on the executor of ``--workers`` (default 1) and
    ``--ray``; returns the results in the order of the jobs and the executor's description."""
    with executor(workers or 1, ray, kind=kind) as ex:
        rows = ex.map(fn, list(jobs), desc=desc, unit="seed")
        return rows, ex.describe()


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def median_of(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The median across ``rows`` of every numeric field (nested dicts too); a field that is not
    a number in every row (None, text, lists) is left out, but for text equal in all rows."""
    out: dict[str, Any] = {}
    for key in rows[0]:
        values: list[Any] = [r.get(key) for r in rows]
        if all(_number(v) for v in values):
            out[key] = values[0] if len(set(values)) == 1 else float(statistics.median(values))
        elif all(isinstance(v, dict) for v in values):
            out[key] = median_of(values)
        elif all(isinstance(v, str) for v in values) and len(set(values)) == 1:
            out[key] = values[0]
    return out
