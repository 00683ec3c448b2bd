"""The pancake task of the seq2seq paper (Kutsuzawa et al. 2019): the spatula's plant, its data,
its objectives and the shipped model's configuration. The method itself (the model, training,
latent adjustment) is generic: :mod:`genplan.seq2seq`.

* :mod:`genplan.pancake.trajectories` -- S-curve and constant-velocity reference moves and the
  friction-cone angle phi (numpy only).
* :mod:`genplan.pancake.physics` -- eqs. 8-18 in torch (batched, differentiable) with a numpy twin;
  the spatula plant.
* :mod:`genplan.pancake.data` -- seeded, cached training inputs.
* :mod:`genplan.pancake.config` -- the shipped model's configuration of the generic model.
* :mod:`genplan.pancake.model` -- the shipped model (load, train, evaluate).
* :mod:`genplan.pancake.objectives` -- J1, J2 (J2Executable: with execution margins) and the
  spatula's terms (friction cone, normal force).
* :mod:`genplan.pancake.adjustment` -- :func:`adjust`: the generic adjustment with the pancake's
  model, objectives and the paper's settings ("latent", "random-latent", "direct-u").

Imported lazily, so that ``import genplan.pancake`` does not import torch.
"""

from __future__ import annotations

import importlib
from typing import Any

from genplan.pancake.trajectories import DT, G, K, MU_MAX, linear, phi, s_curve, wrap_angle

_EXPORTS: dict[str, str] = {
    "Rollout": "genplan.pancake.physics",
    "Seq2SeqModel": "genplan.seq2seq.model",
    "load_model": "genplan.pancake.model",
    "train": "genplan.pancake.model",
    "Seq2SeqConfig": "genplan.pancake.config",
    "adjust": "genplan.pancake.adjustment",
    "AdjustResult": "genplan.pancake.adjustment",
    "J1": "genplan.pancake.objectives",
    "J2": "genplan.pancake.objectives",
    "J2Executable": "genplan.pancake.objectives",
}

__all__ = sorted(["DT", "G", "K", "MU_MAX", "linear", "phi", "s_curve", "wrap_angle", *_EXPORTS])


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'genplan.pancake' has no attribute '{name}'")
