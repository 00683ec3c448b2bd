"""The seq2seq paper's method for any robot and any motion (Kutsuzawa et al. 2019): learn a
family of trajectories with a sequence-to-sequence model, then meet new objectives by gradient
descent on its latent vector.

* :mod:`genplan.seq2seq.config` -- :class:`Seq2SeqConfig`: the space, the network, the plant and
  the training recipe (torch-free).
* :mod:`genplan.seq2seq.plants` -- how the decoder's output becomes a trajectory.
* :mod:`genplan.seq2seq.model` -- :class:`Seq2SeqModel`: encode, decode, deform, loss, files.

Imported lazily, so that ``import genplan.seq2seq`` does not import torch.
"""

from __future__ import annotations

import importlib
from typing import Any

from genplan.seq2seq.config import Seq2SeqConfig

_EXPORTS: dict[str, str] = {
    "Rollout": "genplan.seq2seq.plants",
    "Seq2SeqModel": "genplan.seq2seq.model",
    "load_model": "genplan.seq2seq.model",
}

__all__ = sorted(["Seq2SeqConfig", *_EXPORTS])


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'genplan.seq2seq' has no attribute '{name}'")
