"""The pancake task of the seq2seq paper (Kutsuzawa et al. 2019): spatula physics, a seq2seq
trajectory deformation model, and latent-space trajectory adjustment.

* :mod:`genplan.pancake.trajectories` -- S-curve and constant-velocity reference moves and the
  friction-cone angle phi (numpy only).
* :mod:`genplan.pancake.physics` -- eqs. 8-18 in torch (batched, differentiable) with a numpy twin.
* :mod:`genplan.pancake.data` -- seeded, cached training inputs.
* :mod:`genplan.pancake.model` -- the seq2seq model (encoder LSTM -> z -> decoder LSTM ->
  accelerations -> physics), training, safetensors + JSON card files.
* :mod:`genplan.pancake.adjustment` -- :func:`adjust`: gradient descent on the latent vector
  ("latent", "random-latent") or on the accelerations ("direct-u"), objectives J1, J2 (J2Executable: with
  execution margins) or yours.

Imported lazily, so that ``import genplan.pancake`` does not import torch.
"""

from __future__ import annotations

import importlib
from typing import Any

from genplan.pancake.trajectories import DT, G, K, MU_MAX, linear, phi, s_curve, wrap_angle

_EXPORTS: dict[str, str] = {
    "Rollout": "genplan.pancake.physics",
    "Seq2SeqModel": "genplan.pancake.model",
    "load_model": "genplan.pancake.model",
    "train": "genplan.pancake.model",
    "Seq2SeqConfig": "genplan.pancake.config",
    "adjust": "genplan.pancake.adjustment",
    "AdjustResult": "genplan.pancake.adjustment",
    "J1": "genplan.pancake.adjustment",
    "J2": "genplan.pancake.adjustment",
    "J2Executable": "genplan.pancake.adjustment",
}

__all__ = sorted(["DT", "G", "K", "MU_MAX", "linear", "phi", "s_curve", "wrap_angle", *_EXPORTS])


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'genplan.pancake' has no attribute '{name}'")
