"""Deprecated: what this module held lives in :mod:`genplan.samplers.gan` (the GAN),
:mod:`genplan.samplers.base` (what the GAN and the flow share) and :mod:`genplan.samplers.costs`
(:class:`Constraints`); config checks are :func:`genplan._config.check_fields`. Each name
forwards for one release, with a DeprecationWarning naming its new place.
"""

from __future__ import annotations

import importlib
from typing import Any

from genplan.gan import _deprecated

#: the names of genplan.gan.model and the modules that define them now
_MOVED = {
    "Codec": "genplan.samplers.base",
    "NATIVE_NOISE_MAX": "genplan.samplers.base",
    "ROBOT_HASH_KEY": "genplan.samplers.base",
    "STD_FLOOR": "genplan.samplers.base",
    "SamplerModel": "genplan.samplers.base",
    "TARGET_MARGIN": "genplan.samplers.base",
    "TrainingData": "genplan.samplers.base",
    "check_model_fits": "genplan.samplers.base",
    "check_model_robot": "genplan.samplers.base",
    "feature_dim": "genplan.samplers.base",
    "models_dir": "genplan.samplers.base",
    "prepare_training": "genplan.samplers.base",
    "retrain_hint": "genplan.samplers.base",
    "robot_origin": "genplan.samplers.base",
    "train_command": "genplan.samplers.base",
    "CARD_KEYS": "genplan.samplers.gan",
    "DISC_MIN_STD": "genplan.samplers.gan",
    "EnsembleGenerator": "genplan.samplers.gan",
    "FORMAT": "genplan.samplers.gan",
    "GanConfig": "genplan.samplers.gan",
    "GanModel": "genplan.samplers.gan",
    "SMALL_DIM": "genplan.samplers.gan",
    "default_config": "genplan.samplers.gan",
    "gradient_penalty": "genplan.samplers.gan",
    "load_model": "genplan.samplers.gan",
    "mode_seeking_loss": "genplan.samplers.gan",
    "spread_members": "genplan.samplers.gan",
    "tensor_shapes": "genplan.samplers.gan",
    "train": "genplan.samplers.gan",
    "Constraints": "genplan.samplers.costs",
}


def check_fields(cfg: Any, *, positive: tuple[str, ...] = (), non_negative: tuple[str, ...] = (),
                 widths: tuple[str, ...] = (), rates: tuple[str, ...] = (), weights: tuple[str, ...] = ()) -> None:
    """Deprecated: :func:`genplan._config.check_fields` with a rule per field."""
    from genplan._config import check_fields as check, integer, number

    _deprecated("genplan.gan.model.check_fields", "genplan._config.check_fields")
    check(cfg, {**dict.fromkeys(positive, integer(1)), **dict.fromkeys(non_negative, integer(0)),
                **dict.fromkeys(widths, integer(1, each=True)), **dict.fromkeys(rates, number(above=0)),
                **dict.fromkeys(weights, number(at_least=0))})


def __getattr__(name: str) -> Any:
    if name in _MOVED:
        _deprecated(f"genplan.gan.model.{name}", f"{_MOVED[name]}.{name}")
        return getattr(importlib.import_module(_MOVED[name]), name)
    raise AttributeError(f"module 'genplan.gan.model' has no attribute '{name}'")
