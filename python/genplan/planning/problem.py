"""Deprecated: :class:`Outcome` lives in :mod:`genplan.planning` (beside :func:`~genplan.planning.plan`,
which returns it) and :func:`make_query` in :mod:`genplan.planning.queries` (beside
``make_queries``); both are exported by :mod:`genplan.planning`. Each name forwards for one
release, with a DeprecationWarning naming its new place.
"""

from __future__ import annotations

import importlib
import warnings
from typing import Any

_MOVED = {"Outcome": "genplan.planning", "make_query": "genplan.planning.queries"}


def __getattr__(name: str) -> Any:
    if name in _MOVED:
        warnings.warn(f"genplan.planning.problem.{name} is deprecated (removed in the next release): use "
                      f"genplan.planning.{name}", DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(_MOVED[name]), name)
    raise AttributeError(f"module 'genplan.planning.problem' has no attribute '{name}'")
