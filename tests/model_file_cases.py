"""Tampering with saved models (safetensors + JSON card), shared by the GAN and seq2seq loader tests.

Each case changes the card or the weights and, unless the case is about the hash, writes the
card's ``weights_sha256`` anew, so the loader's later checks are reached.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any, Callable

import torch
from safetensors import safe_open
from safetensors.torch import save_file

Tensors = dict[str, torch.Tensor]


def tamper(weights: Path, card: Callable[[dict[str, Any]], None] | None = None,
           tensors: Callable[[Tensors], None] | None = None, rehash: bool = True) -> None:
    """Apply ``card`` to the card (a dict) and ``tensors`` to the weights, in place."""
    card_path = weights.with_suffix(".json")
    data = json.loads(card_path.read_text())
    if tensors is not None:
        with safe_open(str(weights), "pt") as f:
            meta = f.metadata()
            ts = {k: f.get_tensor(k) for k in f.keys()}
        tensors(ts)
        save_file(ts, str(weights), metadata=meta)
    if rehash and "weights_sha256" in data:
        data["weights_sha256"] = hashlib.sha256(weights.read_bytes()).hexdigest()
    if card is not None:
        card(data)
    card_path.write_text(json.dumps(data))


def _set(t: Tensors, name: str, value: torch.Tensor) -> None:
    t[name] = value


#: (case id, card change, tensor change, rehash, message the ModelFileError must match), for a
#: model whose first tensor is ``first``. Shared by both loaders.
def common_cases(first: str) -> list[tuple[str, Any, Any, bool, str]]:
    return [
        ("no_hash", lambda c: c.pop("weights_sha256"), None, True, r"lacks \['weights_sha256'\]"),
        ("hash_not_hex", lambda c: c.update(weights_sha256="abc"), None, True, "64 lowercase hex digits"),
        ("hash_mismatch", None, lambda t: t[first].add_(1e-3), False, "does not match its card"),
        ("nan_weights", None, lambda t: t[first].view(-1).__setitem__(0, float("nan")), True,
         f"tensor {first} holds NaN or inf"),
        ("inf_weights", None, lambda t: t[first].view(-1).__setitem__(0, float("inf")), True,
         f"tensor {first} holds NaN or inf"),
        ("integer_tensor", None, lambda t: _set(t, first, t[first].to(torch.int32)), True, "not floating point"),
        ("no_config", lambda c: c.pop("config"), None, True, r"lacks \['config'\]"),
        ("config_not_object", lambda c: c.update(config=[1, 2]), None, True, "bad config: expected an object"),
        ("unknown_config_key", lambda c: c["config"].update(bogus=1), None, True, r"unknown key\(s\) \['bogus'\]"),
        ("unknown_card_key", lambda c: c.update(bogus=1), None, True, r"has unknown key\(s\) \['bogus'\]"),
        ("no_format", lambda c: c.pop("format"), None, True, "unknown format None"),
        ("missing_tensor", None, lambda t: t.pop(first), True, rf"missing tensor\(s\) \['{first}'\]"),
        ("extra_tensor", None, lambda t: _set(t, "bogus", torch.zeros(2)), True, r"extra tensor\(s\) \['bogus'\]"),
        ("misshapen_tensor", None, lambda t: _set(t, first, t[first][..., :-1].contiguous()), True,
         rf"misshapen tensor\(s\) \['{first} "),
    ]
