"""Importable names of Python code a file refers to (``entry = "module:attribute"``): the one
reader of such names (an objective file's ``python`` term, a task file's ``python`` term) and the
name of an object already imported (:func:`entry_of`), so that a worker process or a model card
can rebuild what a process holds by importing it again instead of pickling it.

Reading a name imports its module, which runs its code: callers import only when the user opted
in (``allow_python=True``, ``--allow-python``)."""

from __future__ import annotations

import importlib
import sys
from typing import Any


def import_entry(entry: Any, where: str, error: type[Exception], form: str = "module:attribute") -> Any:
    """The object ``entry`` (``"package.module:Name"``, ``Name`` possibly dotted: ``Outer.Inner``)
    names, imported; ``error`` (a GenplanError subclass) naming ``where`` when ``entry`` is not of
    that ``form`` or does not import."""
    module, sep, attr = str(entry).partition(":") if isinstance(entry, str) else ("", "", "")
    if not sep or not module or not attr:
        raise error(f"{where}: entry must be '{form}', got {entry!r}")
    try:
        obj: Any = importlib.import_module(module)
        for part in attr.split("."):
            obj = getattr(obj, part)
    except (ImportError, AttributeError) as exc:
        raise error(f"{where}: cannot import {entry!r} ({type(exc).__name__}: {exc})") from None
    return obj


def entry_of(obj: Any) -> tuple[str | None, str]:
    """``(entry, "")`` when ``obj`` (a class or a function) can be imported again by its name
    (``"module:QualName"``, the module already imported, the name resolving to ``obj`` itself),
    else ``(None, why not)``: defined in ``__main__`` (a script or a notebook, which another
    process does not import) or inside a function, or its module no longer holds it under that
    name."""
    module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
    if not module or not qualname:
        return None, f"{obj!r} has no module and name"
    if module == "__main__":
        return None, f"{qualname} is defined in __main__ (a script or notebook), which another process cannot import"
    if "<locals>" in qualname:
        return None, f"{qualname} is defined inside a function, where an import cannot reach it"
    found: Any = sys.modules.get(module)
    for part in qualname.split("."):
        found = getattr(found, part, None)
    if found is not obj:
        return None, f"{module}:{qualname} does not name it (its module holds another object under that name)"
    return f"{module}:{qualname}", ""
