"""Writing genplan's TOML files (tasks, scenes, objectives): one writer for the plain data their
``to_dict()`` gives. Reading is the standard library's ``tomllib``.

Top-level scalars and lists of scalars come first, then tables (``[name]``), then arrays of
tables (``[[name]]``, e.g. a task's ``[[primary]]`` terms, a scene's ``[[box]]`` obstacles), each
in the order of the data, so that ``tomllib.loads(dumps(d)) == d`` for such data.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

from genplan.errors import GenplanError

__all__ = ["dumps", "value"]


def value(v: Any, error: type[GenplanError] = GenplanError) -> str:
    """One TOML value: a bool, an int, a float (finite, or ``nan``/``inf``), a string, a list of
    values, or an inline table; anything else raises ``error``."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a TOML basic string
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(value(x, error) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{json.dumps(str(k))} = {value(x, error)}" for k, x in v.items()) + " }"
    raise error(f"cannot write {type(v).__name__} to a TOML file")


def _is_tables(v: Any) -> bool:
    return isinstance(v, list) and len(v) > 0 and all(isinstance(x, Mapping) for x in v)


def dumps(data: Mapping[str, Any], error: type[GenplanError] = GenplanError) -> str:
    """The TOML text of ``data`` (see the module's text)."""
    lines = [f"{k} = {value(v, error)}" for k, v in data.items() if not isinstance(v, Mapping) and not _is_tables(v)]
    for k, v in data.items():
        if isinstance(v, Mapping):
            lines += ["", f"[{k}]"] + [f"{kk} = {value(vv, error)}" for kk, vv in v.items()]
    for k, v in data.items():
        if _is_tables(v):
            for row in v:
                lines += ["", f"[[{k}]]"] + [f"{kk} = {value(vv, error)}" for kk, vv in row.items()]
    return "\n".join(lines).lstrip("\n") + "\n"
