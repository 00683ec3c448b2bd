"""Where configurations come from: the samplers' names, and the learned samplers.

:data:`SAMPLERS` names every sampler a planner takes (``Planner(sampler=...)``,
:func:`genplan.planning.plan`, ``genplan plan --sampler``); :data:`WARM_STARTS`, the ones that
start :func:`genplan.solve_ik`'s attempts (``init=``). The learned samplers, a conditional
ensemble GAN (the GAN paper, Section III-A) and a conditional flow-matching sampler behind the
same interface, are modules of this package:

* :mod:`genplan.samplers.base` -- what both share: the configuration features (:class:`Codec`),
  the model interface (:class:`SamplerModel`), matching a model file to a robot and a task,
  the checked inputs of a training run.
* :mod:`genplan.samplers.gan` -- the GAN: ensemble generator, discriminator, training, files.
* :mod:`genplan.samplers.flow` -- the flow (``genplan train flow``), and its one-step students.
* :mod:`genplan.samplers.loading` -- one loader for either family's files.
* :mod:`genplan.samplers.sampler` -- :class:`GanSampler`, a planner Sampler from either model
  (run natively by the planner: :func:`genplan.planning.make_sampler`).
* :mod:`genplan.samplers.data` -- the data they are trained on: configurations projected onto a
  task's manifold, in memory or as shards on disk (``genplan data``); :class:`TaskData`, the rows
  the ``"data"`` sampler draws.
* :mod:`genplan.samplers.costs` -- the task's costs as differentiable torch functions.
* :mod:`genplan.samplers.evaluate` -- a model card's held-out evaluation.

The classes and functions are imported on first use, so that ``import genplan.samplers`` does
not import torch.
"""

from __future__ import annotations

import importlib
from typing import Any

#: Samplers that mix two others within a plan: "hybrid" (the learned sampler with probability
#: ``hybrid_p``, else uniform) and "adaptive" (the learned sampler, its share halving every
#: ``half_life`` samples of a plan).
MIXTURES = ("hybrid", "adaptive")
#: Every sampler, by the name a planner takes: "uniform" (uniform in the joint limits), "gan"
#: (the learned sampler: a GAN or a flow, conditioned on targets), the :data:`MIXTURES`, and
#: "data" (rows of the data set a learned sampler is trained on: no training).
SAMPLERS = ("uniform", "gan", *MIXTURES, "data")
#: The samplers that start :func:`genplan.solve_ik`'s attempts (``init=``): all but the mixtures,
#: which ``solve_ik``'s rounds already are (the learned sampler's attempts, then uniform ones).
WARM_STARTS = tuple(name for name in SAMPLERS if name not in MIXTURES)

_EXPORTS = {
    "Codec": "genplan.samplers.base",
    "SamplerModel": "genplan.samplers.base",
    "GanConfig": "genplan.samplers.gan",
    "GanModel": "genplan.samplers.gan",
    "default_config": "genplan.samplers.gan",
    "load_model": "genplan.samplers.gan",
    "train": "genplan.samplers.gan",
    "FlowConfig": "genplan.samplers.flow",
    "FlowModel": "genplan.samplers.flow",
    "load_sampler_model": "genplan.samplers.loading",
    "GanSampler": "genplan.samplers.sampler",
    "TaskData": "genplan.samplers.data",
}

__all__ = ["MIXTURES", "SAMPLERS", "WARM_STARTS", *sorted(_EXPORTS)]


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'genplan.samplers' has no attribute '{name}'")
