"""Deprecated: the learned samplers (the GAN, the flow and what they share) live in
:mod:`genplan.samplers`. This alias keeps ``genplan.gan.X`` and ``import genplan.gan.<module>``
working for one release, each with a DeprecationWarning naming the new place.
"""

from __future__ import annotations

import importlib
import sys
import warnings
from typing import Any

#: genplan.gan's names and the modules that define them now
_MOVED = {
    "GanConfig": "genplan.samplers.gan",
    "GanModel": "genplan.samplers.gan",
    "default_config": "genplan.samplers.gan",
    "load_model": "genplan.samplers.gan",
    "train": "genplan.samplers.gan",
    "GanSampler": "genplan.samplers.sampler",
    "FlowConfig": "genplan.samplers.flow",
    "FlowModel": "genplan.samplers.flow",
    "load_sampler_model": "genplan.samplers.loading",
}

__all__ = sorted(_MOVED)


def _deprecated(old: str, new: str, stacklevel: int = 3) -> None:
    warnings.warn(f"{old} is deprecated (removed in the next release): use {new}", DeprecationWarning,
                  stacklevel=stacklevel)


def alias_module(old: str, new: str) -> None:
    """Make the module ``old`` (running this in its body) the module ``new``, with a warning."""
    _deprecated(old, new, stacklevel=4)  # the importer's line (the import system's frames are skipped)
    sys.modules[old] = importlib.import_module(new)


def __getattr__(name: str) -> Any:
    if name in _MOVED:
        _deprecated(f"genplan.gan.{name}", f"{_MOVED[name]}.{name}")
        return getattr(importlib.import_module(_MOVED[name]), name)
    raise AttributeError(f"module 'genplan.gan' has no attribute '{name}'")
