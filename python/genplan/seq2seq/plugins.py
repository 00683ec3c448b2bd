"""What other packages add to the generic method, found by name: plants, objective term kinds and
model card formats, declared as entry points of the group ``genplan.seq2seq`` (named
``<kind>.<name>``, e.g. ``plant.spatula = "genplan.pancake.physics:SpatulaPlant"``). genplan's own
pancake task is declared so in pyproject.toml; another package declares its own the same way.
The generic package never imports the packages that extend it: they are loaded when a file or a
card names what they provide.
"""

from __future__ import annotations

import functools
from importlib.metadata import entry_points
from typing import Any

__all__ = ["GROUP", "find", "names"]

GROUP = "genplan.seq2seq"


@functools.lru_cache(maxsize=1)
def _table() -> dict[str, Any]:
    return {ep.name: ep for ep in entry_points(group=GROUP)}


def find(kind: str, name: str) -> Any | None:
    """The object an installed package declares as ``<kind>.<name>`` (loaded now), or None."""
    ep = _table().get(f"{kind}.{name}")
    return None if ep is None else ep.load()


def names(kind: str) -> list[str]:
    """The names declared for ``kind``."""
    prefix = f"{kind}."
    return sorted(k[len(prefix):] for k in _table() if k.startswith(prefix))
