"""Conditional ensemble GAN of valid robot configurations (the GAN paper, Section III-A).

* :mod:`genplan.gan.data` -- valid configurations: uniform samples projected onto the manifold.
* :mod:`genplan.gan.model` -- ensemble generator, discriminator, training, safetensors I/O.
* :mod:`genplan.gan.sampler` -- :class:`GanSampler`, a planner Sampler (uniform and hybrid sampling:
  :func:`genplan.planning.make_sampler`).
* :mod:`genplan.gan.flow` -- beyond the paper: a conditional flow-matching sampler behind the same
  interface (``genplan train flow``); :mod:`genplan.gan.loading` loads a GAN or a flow file.

Imported lazily, so that ``import genplan`` does not import torch.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "GanConfig": "genplan.gan.model",
    "GanModel": "genplan.gan.model",
    "default_config": "genplan.gan.model",
    "load_model": "genplan.gan.model",
    "train": "genplan.gan.model",
    "GanSampler": "genplan.gan.sampler",
    "FlowConfig": "genplan.gan.flow",
    "FlowModel": "genplan.gan.flow",
    "load_sampler_model": "genplan.gan.loading",
}

#: Names removed after 0.1.0 and what replaces them (the Python twins of the native samplers).
_REMOVED = {
    "UniformSampler": 'genplan.planning.make_sampler(robot, "uniform", seed=...)',
    "HybridSampler": 'genplan.planning.make_sampler(robot, "hybrid", hybrid_p=..., seed=...)',
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    if name in _REMOVED:
        raise AttributeError(f"genplan.gan.{name} was removed after 0.1.0 (a Python twin of a native sampler): use {_REMOVED[name]}")
    raise AttributeError(f"module 'genplan.gan' has no attribute '{name}'")
