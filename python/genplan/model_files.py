"""Shipped models: safetensors weights plus a JSON card beside them (never pickles).

Shared by the GAN (:mod:`genplan.gan.model`) and the seq2seq model (:mod:`genplan.pancake.model`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path
from typing import Any, Callable, TypeVar

import numpy as np

from genplan.errors import ModelFileError

__all__ = ["write_model", "read_model", "read_config", "json_default"]

T = TypeVar("T")


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


def read_model(path: Path, fmt: str, kind: str, retrain: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """Read and check a model written by :func:`write_model`: ``(card, tensors)``.

    ``kind`` names the model in messages ("GAN", "seq2seq"); ``retrain`` is the command a missing
    file's error names. Missing files raise FileNotFoundError; a card that does not parse, has
    another format or another weights sha256, and weights that do not load raise
    :class:`~genplan.errors.ModelFileError`.
    """
    from safetensors import SafetensorError
    from safetensors.torch import load_file

    card_path = path.with_suffix(".json")
    for p in (path, card_path):
        if not p.is_file():
            raise FileNotFoundError(f"{kind} model file {p} does not exist; train it with `{retrain}`")
    try:
        card = json.loads(card_path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ModelFileError(f"{kind} model card {card_path} is corrupt: {exc}") from None
    if not isinstance(card, dict) or card.get("format") != fmt:
        got = card.get("format") if isinstance(card, dict) else type(card).__name__
        raise ModelFileError(f"{card_path}: unknown format {got!r} (expected {fmt})")
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    if card.get("weights_sha256") not in (None, digest):
        raise ModelFileError(f"{path} does not match its card (sha256 {digest[:12]}..., card says "
                             f"{str(card.get('weights_sha256'))[:12]}...): the file is corrupt or was replaced")
    try:
        tensors = load_file(str(path))
    except (SafetensorError, OSError, ValueError) as exc:
        raise ModelFileError(f"{kind} model file {path} is corrupt: {exc}") from None
    return card, tensors


def read_config(card: dict[str, Any], path: Path, kind: str, make: Callable[[dict[str, Any]], T]) -> T:
    """``make(config)`` of a copy of the card's ``config``; a card without one, or whose config
    ``make`` rejects (a missing or unknown field: KeyError, TypeError), raises ModelFileError."""
    try:
        return make(dict(card["config"]))
    except (KeyError, TypeError) as exc:
        raise ModelFileError(f"{kind} model card {path.with_suffix('.json')} has a bad config: {exc}") from None
