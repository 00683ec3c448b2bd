"""Shipped models: safetensors weights plus a JSON card beside them (never pickles).

Shared by the learned samplers (:mod:`genplan.samplers`) and the seq2seq models
(:mod:`genplan.seq2seq.model`). The shipped models live in the installed package
(:func:`models_dir`), which no training command ever writes (:func:`inside_package`).
A loader refuses, with :class:`~genplan.errors.ModelFileError` naming the file and the problem and
before building anything, what it cannot vouch for:

* the card: not JSON, not an object, another format, a key the format does not know, no
  ``config`` or no ``weights_sha256``;
* the weights: a sha256 other than the card's, not a safetensors file, metadata that contradicts
  the card, a tensor that is not floating point or holds NaN or inf, a tensor missing, extra or of
  another shape than the card's config implies (:func:`check_tensors`);
* the config: a missing or unknown field, a value of the wrong type or not finite, or one the
  config's ``validate()`` refuses (:func:`read_config`).

:func:`write_model` refuses to write what :func:`read_model` would refuse, so a model that saves
loads.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import re
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from genplan.errors import GenplanError, ModelFileError

__all__ = ["REQUIRED_CARD_KEYS", "ModelCardWarning", "write_model", "read_model", "read_config", "check_tensors",
           "json_default", "peek_card", "check_sha256", "warn_once", "package_dir", "inside_package", "models_dir",
           "out_option"]

T = TypeVar("T")

#: keys every card has (the rest are descriptive, listed per format by the loaders)
REQUIRED_CARD_KEYS = frozenset({"format", "config", "weights_sha256"})
_SHA256 = re.compile(r"[0-9a-f]{64}")
#: the (card, weights sha256) pairs already warned about by :func:`warn_once`
_WARNED: set[tuple[str, str]] = set()


def package_dir() -> Path:
    """The installed genplan package's folder (its shipped models, presets and code)."""
    return Path(__file__).resolve().parent


def models_dir() -> Path:
    """The shipped models: ``genplan/models`` inside the installed package."""
    return package_dir() / "models"


def inside_package(path: str | os.PathLike[str]) -> bool:
    """True when ``path``, symbolic links followed (a repository checkout's ``models`` links to
    the package's models), lies inside the installed genplan package."""
    return Path(path).resolve().is_relative_to(package_dir())


def out_option(out: Path) -> str:
    """The ``--out`` of a model's retraining command (its card's ``command``): `` --out PATH``,
    the path as given, so the command rewrites that same file and no other (never the shipped
    place: :func:`genplan.cli.args.model_output`)."""
    return f" --out {out}"


class ModelCardWarning(UserWarning):
    """A model genplan loads although its card lacks something it now records (e.g. a card
    written before the robot's kinematic hash was): the message says what and how to fix it.
    Emitted once per file and process."""


def warn_once(card_path: Path, card: Mapping[str, Any], message: str) -> None:
    """A :class:`ModelCardWarning` with ``message``, unless this card (path and weights sha256)
    was already warned about in this process."""
    import warnings

    key = (str(Path(card_path).resolve()), str(card.get("weights_sha256")))
    if key not in _WARNED:
        _WARNED.add(key)
        warnings.warn(message, ModelCardWarning, stacklevel=4)


def check_sha256(value: Any, where: str) -> str:
    """``value`` if it is a sha256 in hex (64 lowercase hex digits), else ModelFileError naming
    ``where`` (the card and its key)."""
    if not isinstance(value, str) or not _SHA256.fullmatch(value):
        raise ModelFileError(f"{where} must be 64 lowercase hex digits, got {str(value)[:80]!r}")
    return value


def json_default(o: Any) -> Any:
    """JSON for the numpy scalars, arrays and tuples that cards hold."""
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, (np.ndarray, tuple)):
        return o.tolist() if isinstance(o, np.ndarray) else list(o)
    raise TypeError(f"not JSON serialisable: {type(o)}")


def _unknown_keys(card: Mapping[str, Any], card_keys: frozenset[str]) -> list[str]:
    return sorted(set(card) - card_keys - REQUIRED_CARD_KEYS)


def _bad_tensor(name: str, t: Any) -> str | None:
    """Why tensor ``t`` cannot be vouched for, or None."""
    import torch

    if not t.is_floating_point():
        return f"tensor {name} has dtype {t.dtype}, not floating point"
    if not bool(torch.isfinite(t).all()):
        return f"tensor {name} holds NaN or inf"
    return None


def _header(raw: bytes) -> tuple[int, Any]:
    """A safetensors file's header: its length and its JSON (the file opens with the length as
    8 little-endian bytes, then the JSON)."""
    n = int.from_bytes(raw[:8], "little")
    return n, json.loads(raw[8:8 + n])


def _canonical_header(raw: bytes) -> bytes:
    """``raw`` (a safetensors file) with its header's metadata in sorted key order. safetensors
    writes the metadata map in an arbitrary order that changes from run to run, so the same
    weights would get another sha256 each time they are written (a retrained model could never be
    told equal to its card's); sorted, the bytes depend on the tensors and metadata only. The
    header keeps its length (the data offsets are relative to its end)."""
    n, header = _header(raw)
    meta = header.pop("__metadata__", None)
    if meta is None:
        return raw
    text = json.dumps({"__metadata__": dict(sorted(meta.items())), **header}, separators=(",", ":")).encode()
    if len(text) > n:  # cannot happen for the same keys and values; keep the file as written
        return raw
    return raw[:8] + text + b" " * (n - len(text)) + raw[8 + n:]


def write_model(path: str | Path, tensors: dict[str, Any], metadata: dict[str, str], card: dict[str, Any],
                config: Any, card_keys: frozenset[str], kind: str) -> tuple[Path, Path]:
    """Write ``path`` (.safetensors, torch tensors) and its card (.json beside it).

    The card gets ``metadata["format"]``, the config (a dataclass) and the weights' sha256, which
    the loaders check. A card key outside ``card_keys``, a card that is not JSON or a non-finite
    tensor raises :class:`~genplan.errors.ModelFileError` before anything is written (it could
    not be loaded).

    An existing model at ``path`` stays whole until the new one is complete: both files are
    written under temporary names first, then renamed, the weights first (a write that fails,
    disk full or Ctrl-C, leaves the old pair; only a stop between the two renames leaves new
    weights beside the old card, a pair the loaders refuse as not matching, never half a file).
    Errors name ``path`` and its card, not the temporary files. The files are readable by all as
    the umask allows.
    """
    from safetensors.torch import save

    path = Path(path).with_suffix(".safetensors")
    card_path = path.with_suffix(".json")
    unknown = _unknown_keys(card, card_keys)
    if unknown:
        raise ModelFileError(f"cannot write {kind} model {path}: card keys {unknown} are not part of a {kind} card "
                             f"(known: {sorted(card_keys | REQUIRED_CARD_KEYS)})")
    for name, t in tensors.items():
        why = _bad_tensor(name, t)
        if why:
            raise ModelFileError(f"cannot write {kind} model {path}: {why}")
    from genplan._files import atomic_path

    raw = _canonical_header(save({k: v.detach().contiguous() for k, v in tensors.items()}, metadata=metadata))
    card = dict(card)
    card.update({"format": metadata["format"], "config": dataclasses.asdict(config),
                 "weights_sha256": hashlib.sha256(raw).hexdigest()})
    try:
        text = json.dumps(card, indent=2, default=json_default) + "\n"
    except (TypeError, ValueError) as exc:
        raise ModelFileError(f"cannot write {kind} model {path}: its card is not JSON ({exc})") from None
    with atomic_path(card_path) as card_tmp:  # new files: readable by all as the umask allows
        card_tmp.write_text(text, encoding="utf-8")
        with atomic_path(path) as weights_tmp:  # renamed when its block ends: before the card
            weights_tmp.write_bytes(raw)
    return path, card_path


def peek_card(path: str | Path) -> dict[str, Any] | None:
    """The card beside model file ``path`` as JSON, or None when it is missing, unreadable or not
    an object (a quick look, checking nothing: :func:`read_model` names the problem)."""
    try:
        card = json.loads(Path(path).with_suffix(".json").read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    return card if isinstance(card, dict) else None


def _safetensors_metadata(data: bytes) -> dict[str, str]:
    """The ``__metadata__`` of a safetensors file's header (8-byte length, then JSON)."""
    _, header = _header(data)
    meta = header.get("__metadata__", {}) if isinstance(header, dict) else None
    if not isinstance(meta, dict):
        raise ValueError("the header's __metadata__ is not an object")
    return meta


def read_model(path: Path, fmt: str, kind: str, retrain: str,
               card_keys: frozenset[str]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Read and check a model written by :func:`write_model`: ``(card, tensors)``.

    ``kind`` names the model in messages ("GAN", "seq2seq"); ``retrain`` is the command a missing
    file's error names; ``card_keys`` are the descriptive card keys the format allows besides
    :data:`REQUIRED_CARD_KEYS`. Missing files raise FileNotFoundError; everything else the module
    docstring lists (but the config and the tensor names and shapes, which need the config:
    :func:`read_config`, :func:`check_tensors`) raises :class:`~genplan.errors.ModelFileError`.
    The weights are read once: the bytes hashed are the bytes loaded.
    """
    from safetensors import SafetensorError
    from safetensors.torch import load as load_bytes

    card_path = path.with_suffix(".json")
    if path.suffix == ".json":
        raise ModelFileError(f"{path} is a model card; give the .safetensors file beside it "
                             f"({path.with_suffix('.safetensors')})")
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
    unknown = _unknown_keys(card, card_keys)
    if unknown:
        raise ModelFileError(f"{kind} model card {card_path} has unknown key(s) {unknown} "
                             f"(a {kind} card holds {sorted(card_keys | REQUIRED_CARD_KEYS)})")
    missing = sorted(REQUIRED_CARD_KEYS - set(card))
    if missing:
        raise ModelFileError(f"{kind} model card {card_path} lacks {missing}: the weights cannot be vouched for "
                             f"without them (re-save the model with genplan, or retrain it: `{retrain}`)")
    expected = check_sha256(card["weights_sha256"], f"{kind} model card {card_path}: weights_sha256")
    data = path.read_bytes()
    digest = hashlib.sha256(data).hexdigest()
    if digest != expected:
        raise ModelFileError(f"{path} does not match its card (sha256 {digest[:12]}..., card says "
                             f"{expected[:12]}...): the file is corrupt or was replaced")
    try:
        tensors = load_bytes(data)
        metadata = _safetensors_metadata(data)
    except (SafetensorError, OSError, ValueError, UnicodeDecodeError) as exc:
        raise ModelFileError(f"{kind} model file {path} is corrupt: {exc}") from None
    for key, value in metadata.items():
        want = fmt if key == "format" else card.get(key, value)
        if value != want:
            raise ModelFileError(f"{kind} model file {path}: its metadata says {key} {value!r}, its card {want!r}")
    for name, t in tensors.items():
        why = _bad_tensor(name, t)
        if why:
            raise ModelFileError(f"{kind} model file {path} is corrupt: {why}")
    return card, tensors


def check_tensors(tensors: Mapping[str, Any], shapes: Mapping[str, tuple[int, ...]], path: Path, kind: str) -> None:
    """The tensors are exactly ``shapes`` (name -> shape, as the card's config implies), else
    ModelFileError naming the missing, extra and misshapen ones."""
    missing = sorted(set(shapes) - set(tensors))
    extra = sorted(set(tensors) - set(shapes))
    wrong = [f"{k} {tuple(tensors[k].shape)} (expected {tuple(s)})" for k, s in shapes.items()
             if k in tensors and tuple(tensors[k].shape) != tuple(s)]
    problems = ([f"missing tensor(s) {missing}"] if missing else []) + ([f"extra tensor(s) {extra}"] if extra else []) \
        + ([f"misshapen tensor(s) {wrong}"] if wrong else [])
    if problems:
        raise ModelFileError(f"{kind} model file {path} does not fit its card: {'; '.join(problems)}")


def _as_type(value: Any, hint: Any, where: str) -> Any:
    """``value`` (read from JSON) as the type ``hint`` (bool, int, float, str, tuples of them, or
    one of them or None); tuples come back as tuples. Raises TypeError naming ``where``."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if type(None) in args:  # Optional[X] (X | None): None or an X
        (inner,) = [a for a in args if a is not type(None)]
        return None if value is None else _as_type(value, inner, where)
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise TypeError(f"{where} must be a list, got {value!r}")
        items = [args[0]] * len(value) if len(args) == 2 and args[1] is Ellipsis else list(args)
        if len(items) != len(value):
            raise TypeError(f"{where} must have {len(items)} values, got {len(value)}")
        return tuple(_as_type(v, h, f"{where}[{i}]") for i, (v, h) in enumerate(zip(value, items)))
    ok = {bool: lambda v: isinstance(v, bool),
          int: lambda v: isinstance(v, int) and not isinstance(v, bool),
          float: lambda v: isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v),
          str: lambda v: isinstance(v, str)}
    if hint not in ok:
        raise TypeError(f"{where}: no reader for the type {hint}")
    if not ok[hint](value):
        raise TypeError(f"{where} must be {'a finite float' if hint is float else hint.__name__}, got {value!r}")
    return float(value) if hint is float else value


def read_config(card: dict[str, Any], path: Path, kind: str, cls: type[T]) -> T:
    """The card's ``config`` as the dataclass ``cls``: exactly its fields (none missing, none
    unknown), each of its type and finite, and accepted by ``cls.validate()`` if it has one;
    anything else raises ModelFileError naming the card and the field. Fields named in the
    class's ``ADDED_FIELDS`` (added after cards were shipped) may be missing: their default."""
    card_path = path.with_suffix(".json")
    config = card.get("config")
    bad = f"{kind} model card {card_path} has a bad config"
    if not isinstance(config, dict):
        raise ModelFileError(f"{bad}: expected an object of {cls.__name__} fields, got {type(config).__name__}")
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
    added = getattr(cls, "ADDED_FIELDS", frozenset())
    unknown, missing = sorted(set(config) - set(names)), [n for n in names if n not in config and n not in added]
    if unknown or missing:
        parts = ([f"unknown key(s) {unknown}"] if unknown else []) + ([f"missing key(s) {missing}"] if missing else [])
        raise ModelFileError(f"{bad}: {'; '.join(parts)}")
    try:
        cfg = cls(**{n: _as_type(config[n], hints[n], n) for n in names if n in config})  # validates (__post_init__)
    except (TypeError, GenplanError) as exc:
        raise ModelFileError(f"{bad}: {exc}") from None
    return cfg
