"""Writing shipped models: safetensors weights plus a JSON card beside them (never pickles).

Shared by the GAN (:mod:`genplan.gan.model`) and the seq2seq model (:mod:`genplan.pancake.model`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["write_model", "json_default"]


def json_default(o: Any) -> Any:
    """JSON for the numpy scalars, arrays and tuples that cards hold."""
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, (np.ndarray, tuple)):
        return o.tolist() if isinstance(o, np.ndarray) else list(o)
    raise TypeError(f"not JSON serialisable: {type(o)}")


def write_model(path: str | Path, tensors: dict[str, Any], metadata: dict[str, str], card: dict[str, Any],
                config: Any) -> tuple[Path, Path]:
    """Write ``path`` (.safetensors, torch tensors) and its card (.json beside it).

    The card gets ``metadata["format"]``, the config (a dataclass) and the weights' sha256, which
    the loaders check.
    """
    from safetensors.torch import save_file

    path = Path(path).with_suffix(".safetensors")
    path.parent.mkdir(parents=True, exist_ok=True)
    save_file({k: v.detach().contiguous() for k, v in tensors.items()}, str(path), metadata=metadata)
    card = dict(card)
    card.update({"format": metadata["format"], "config": dataclasses.asdict(config),
                 "weights_sha256": hashlib.sha256(path.read_bytes()).hexdigest()})
    card_path = path.with_suffix(".json")
    card_path.write_text(json.dumps(card, indent=2, default=json_default) + "\n")
    return path, card_path
