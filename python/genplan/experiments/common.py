"""Shared pieces of the benchmarks: machine description, output files (written whole or not at
all), table printing."""

from __future__ import annotations

import json
import os
import platform
import subprocess
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from genplan._files import atomic_path, write_text
from genplan.errors import GenplanError


def machine() -> dict[str, Any]:
    """What ran the benchmark (so numbers can be compared honestly)."""
    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "git": _git_rev(),
    }


def _git_rev() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                              cwd=Path(__file__).parent, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def save_figure(fig: Any, path: Path, **savefig: Any) -> Path:
    """``fig.savefig(path, **savefig)`` atomically (:func:`atomic_path`; the format is the suffix's)."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, **savefig)
    return Path(path)


def write_json(path: Path | None, payload: dict[str, Any]) -> None:
    if path is None:
        return
    write_text(path, json.dumps(payload, indent=2) + "\n")
    print(f"wrote {path}")


def geometric_mean(values: Any) -> float:
    """The geometric mean of positive ``values`` (how the benchmarks average speed-up ratios)."""
    v = np.asarray(list(values), dtype=np.float64)
    return float(np.exp(np.mean(np.log(v))))


def table(headers: list[str], rows: list[list[Any]]) -> str:
    """A plain-text table (markdown-compatible)."""
    cells = [[str(c) for c in headers]] + [[_fmt(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    lines = ["| " + " | ".join(c.ljust(w) for c, w in zip(r, widths)) + " |" for r in cells]
    lines.insert(1, "|" + "|".join("-" * (w + 2) for w in widths) + "|")
    return "\n".join(lines)


def _fmt(c: Any) -> str:
    if isinstance(c, float):
        return f"{c:.3g}" if abs(c) < 100 else f"{c:.1f}"
    return str(c)


class _Fields(dict[str, Any]):
    """A JSON object of a benchmark file: a missing field raises GenplanError naming the file and
    the field (not a bare KeyError)."""

    def __init__(self, data: dict[str, Any], where: str) -> None:
        super().__init__({k: _fields(v, f"{where}.{k}") for k, v in data.items()})
        self.where = where

    def __getitem__(self, key: str) -> Any:
        try:
            return super().__getitem__(key)
        except KeyError:
            raise GenplanError(f"{self.where}: no field {key!r} (not what a genplan benchmark writes, or from "
                               "another version)") from None


def _fields(value: Any, where: str) -> Any:
    if isinstance(value, dict):
        return _Fields(value, where)
    if isinstance(value, list):
        return [_fields(v, f"{where}[{i}]") for i, v in enumerate(value)]
    return value


def read_json(path: Path) -> Any:
    """A benchmark's JSON file: a file that is not a JSON object raises GenplanError naming it,
    and so does a missing field when it is read (FileNotFoundError for a missing file)."""
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise GenplanError(f"{path}: not a valid JSON file ({exc})") from None
    if not isinstance(data, dict):
        raise GenplanError(f"{path}: expected a JSON object (a benchmark's results), got {type(data).__name__}")
    return _Fields(data, str(path))
