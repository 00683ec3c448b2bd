"""genplan.model_files: a model's bytes depend on its tensors and metadata only (the same weights
written twice have one sha256, whatever order safetensors wrote the metadata in); a model replaced
stays whole until the new one is complete; errors name the user's path; the shipped cards'
retraining commands write outside the installed package."""

from __future__ import annotations

import errno
import json
from pathlib import Path

import numpy as np
import pytest
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


# --------------------------------------------------------------------------------------------
# Replacing a model, messages that name the user's path, shipped cards' retraining commands
# --------------------------------------------------------------------------------------------

REPO = Path(__file__).resolve().parents[1]


def _tiny_gan(robot, seed: int = 0):
    """An untrained small GAN for ``robot`` (nothing here needs it trained)."""
    from genplan.samplers.base import Codec
    from genplan.samplers.gan import EnsembleGenerator, GanModel, default_config

    torch.manual_seed(seed)
    cfg = default_config(robot, n_net=2, gen_hidden=(8,), noise_dim=4)
    gen = EnsembleGenerator(cfg.n_net, cfg.noise_dim + 3, cfg.gen_hidden, robot.nq)
    return GanModel(cfg, robot, gen, Codec(robot, np.zeros(robot.nq), np.ones(robot.nq)))


def test_integrity_1_a_failed_replacement_keeps_the_old_model_whole(panda, tmp_path, monkeypatch) -> None:
    """Before: the new weights were renamed over the old ones before the card was written, so a
    failure writing the card (disk full) left the old card beside new weights: the old model was
    lost. Now both files are written under temporary names before either is renamed."""
    from genplan.samplers.gan import load_model

    path = tmp_path / "m.safetensors"
    _tiny_gan(panda, 0).save(path)
    before = (path.read_bytes(), path.with_suffix(".json").read_bytes())
    real = Path.write_text

    def full_disk(self, *args, **kwargs):
        if self.suffix == ".json":
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Path, "write_text", full_disk)
    with pytest.raises(OSError) as info:
        _tiny_gan(panda, 1).save(path)
    monkeypatch.undo()
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(path.with_suffix(".json"))
    assert (path.read_bytes(), path.with_suffix(".json").read_bytes()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.json", "m.safetensors"]  # no temporaries left
    load_model(panda, path)


def test_integrity_1_a_card_that_cannot_be_written_is_refused_before_anything_is(panda, tmp_path) -> None:
    from genplan.errors import ModelFileError

    path = tmp_path / "m.safetensors"
    model = _tiny_gan(panda)
    model.card["notes"] = {"a set": {1, 2}}
    with pytest.raises(ModelFileError, match=r"cannot write GAN model .*m.safetensors: its card is not JSON"):
        model.save(path)
    assert not list(tmp_path.iterdir())


def test_integrity_8_saving_over_a_folder_names_the_path_given(panda, tmp_path) -> None:
    folder = tmp_path / "m.safetensors"
    folder.mkdir()
    with pytest.raises(IsADirectoryError) as info:
        _tiny_gan(panda).save(folder)
    assert info.value.filename == str(folder) and ".tmp" not in str(info.value)
    assert [p.name for p in tmp_path.iterdir()] == ["m.safetensors"]


def test_integrity_8_a_card_given_as_the_model_says_give_the_weights(panda, tmp_path) -> None:
    """Before: ``--model m.json`` read the card as the weights: "corrupt or replaced"."""
    from genplan.errors import ModelFileError
    from genplan.pancake.model import load_model as load_seq2seq
    from genplan.samplers.loading import load_sampler_model

    weights, card = _tiny_gan(panda).save(tmp_path / "m.safetensors")
    for load in (lambda: load_sampler_model(panda, card), lambda: load_seq2seq(card)):
        with pytest.raises(ModelFileError) as info:
            load()
        assert str(info.value) == (f"{card} is a model card; give the .safetensors file beside it ({weights})")


def _cards() -> list[Path]:
    from genplan.samplers.base import models_dir

    return sorted(models_dir().glob("*.json")) + sorted((REPO / "examples" / "xarm7").glob("*_gan.json"))


@pytest.mark.parametrize("card", _cards(), ids=lambda p: p.name)
def test_integrity_1_shipped_cards_retrain_outside_the_package(card: Path) -> None:
    """Each shipped card's retraining command names --out, the same file name as the card's
    weights, and a place outside the installed package, from the repository's root (where
    ``models`` links to the package's models) as from anywhere else."""
    from genplan.model_files import inside_package

    data = json.loads(card.read_text())
    command = data.get("command", data.get("retrain"))
    words = command.split()
    assert "--out" in words, command
    out = Path(words[words.index("--out") + 1])
    assert out.name == card.with_suffix(".safetensors").name, command
    assert not inside_package(REPO / out) and not inside_package(out), command
