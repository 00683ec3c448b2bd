"""Conditional ensemble GAN of valid robot configurations (the GAN paper, Section III-A).

* :mod:`genplan.gan.data` -- valid configurations: uniform samples projected onto the manifold.
* :mod:`genplan.gan.model` -- ensemble generator, discriminator, training, safetensors I/O.
* :mod:`genplan.gan.sampler` -- :class:`GanSampler` (and uniform, hybrid), the planner's Samplers.

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
    "UniformSampler": "genplan.gan.sampler",
    "HybridSampler": "genplan.gan.sampler",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'genplan.gan' has no attribute '{name}'")
