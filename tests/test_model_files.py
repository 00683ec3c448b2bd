"""genplan.model_files: a model's bytes depend on its tensors and metadata only (the same weights
written twice have one sha256, whatever order safetensors wrote the metadata in)."""

from __future__ import annotations

import json

import numpy as np
import torch
from safetensors import safe_open
from safetensors.torch import save_file

from genplan.model_files import _canonical_header


def _header(raw: bytes) -> bytes:
    return raw[8:8 + int.from_bytes(raw[:8], "little")]


def test_the_header_metadata_is_written_in_sorted_order(tmp_path) -> None:
    tensors = {"w": torch.arange(6, dtype=torch.float32).reshape(2, 3), "b": torch.ones(3)}
    raws = []
    for i, meta in enumerate(({"robot": "panda", "format": "genplan-flow/1"},
                              {"format": "genplan-flow/1", "robot": "panda"})):
        path = tmp_path / f"m{i}.safetensors"
        save_file(tensors, str(path), metadata=meta)
        raw = _canonical_header(path.read_bytes())
        assert len(raw) == path.stat().st_size  # the header keeps its length
        path.write_bytes(raw)
        raws.append(raw)
        with safe_open(str(path), "pt") as f:  # still a safetensors file with the same content
            assert f.metadata() == meta
            for k, t in tensors.items():
                assert torch.equal(f.get_tensor(k), t)
    assert raws[0] == raws[1]
    meta = json.loads(_header(raws[0]))["__metadata__"]
    assert list(meta) == ["format", "robot"]


def test_a_file_without_metadata_is_left_as_it_is(tmp_path) -> None:
    path = tmp_path / "plain.safetensors"
    save_file({"x": torch.from_numpy(np.zeros(4, dtype=np.float32))}, str(path))
    raw = path.read_bytes()
    assert _canonical_header(raw) == raw
