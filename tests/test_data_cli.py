"""``genplan data`` (genplan.gan.data_cli, genplan.gan.data.write_dataset / read_dataset): a data
set as shards + manifest, resumed after an interrupted or failed run from its verified shards,
refused when the folder holds another run; ``genplan train gan --data`` trains from it and
refuses another robot's or task's data."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

import genplan
from genplan.cli import main
from genplan.gan import data as D

N, SIZE = 500, 150  # 4 shards, the last of 50


def make(out, *extra: str, n: int = N, robot: str = "panda") -> dict:
    assert main(["data", "--robot", robot, "--data-size", str(n), "--shard-size", str(SIZE), "--seed", "2",
                 "--workers", "2", "--out", str(out), *extra]) == 0
    return json.loads((out / "manifest.json").read_text())


def test_data_writes_shards_and_a_manifest_equal_to_valid_configurations(panda: genplan.Robot, tmp_path,
                                                                        capsys) -> None:
    m = make(tmp_path / "d")
    ref = D.valid_configurations(panda, N, seed=2, use_cache=False, progress=False, shard_size=SIZE)
    assert m["sha256"] == hashlib.sha256(ref.tobytes()).hexdigest()
    assert f"sha256 {m['sha256']}" in capsys.readouterr().out
    assert m["complete"] and m["data_size"] == N and m["seed"] == 2 and m["shard_size"] == SIZE
    assert [(s["index"], s["count"], s["seed"]) for s in m["shards"]] == [(0, 150, [2, 0]), (1, 150, [2, 1]),
                                                                        (2, 150, [2, 2]), (3, 50, [2, 3])]
    for s in m["shards"]:
        f = tmp_path / "d" / s["file"]
        assert hashlib.sha256(f.read_bytes()).hexdigest() == s["sha256"]
    assert m["task"]["name"] == "panda_ik" and m["manifold"]["name"] == "panda_projection"
    assert m["robot"]["name"] == "panda" and set(m["robot"]["files"]) >= {"urdf", "source"}
    assert m["genplan_version"] == genplan.__version__
    assert not list((tmp_path / "d").glob(".*"))  # no temporary file left
    data, manifest = D.read_dataset(tmp_path / "d", panda)
    np.testing.assert_array_equal(data, ref)


def test_a_resumed_run_keeps_the_verified_shards_and_recomputes_the_rest(tmp_path, monkeypatch, capsys) -> None:
    out = tmp_path / "d"
    first = make(out)
    capsys.readouterr()
    # an interrupted run: one shard lost, one corrupt (a killed write never leaves one: atomic_path)
    (out / "shard_00001.npy").unlink()
    (out / "shard_00003.npy").write_bytes(b"not a shard")
    computed: list[int] = []
    real = D.project_shard

    def counting(shard):
        computed.append(shard.index)
        return real(shard)

    monkeypatch.setattr(D, "project_shard", counting)
    again = make(out)
    assert sorted(computed) == [1, 3]
    log = capsys.readouterr().out
    assert "resuming" in log and "2 of 4 shards finished and verified, 2 listed but missing or not matching" in log
    assert again["sha256"] == first["sha256"] and again["last_run"]["shards_computed"] == 2
    computed.clear()
    assert make(out)["sha256"] == first["sha256"] and computed == []  # a finished run: nothing to do


def test_a_failing_shard_is_retried_then_named_and_the_run_resumes(tmp_path, monkeypatch, capsys) -> None:
    out = tmp_path / "d"
    real = D.project_shard
    attempts: list[int] = []

    def broken(shard):
        if shard.index == 2:
            attempts.append(2)
            raise RuntimeError("disk on fire")
        return real(shard)

    monkeypatch.setattr(D, "project_shard", broken)
    argv = ["data", "--robot", "panda", "--data-size", str(N), "--shard-size", str(SIZE), "--seed", "2",
            "--workers", "2", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.splitlines()[-1]  # after the progress bar
    assert err.startswith("genplan: error: panda data: 1 of 4 shards failed: shard 2: RuntimeError: disk on fire "
                          "(after 3 attempts)"), err
    assert attempts == [2, 2, 2]
    m = json.loads((out / "manifest.json").read_text())
    assert not m["complete"] and [s["index"] for s in m["shards"]] == [0, 1, 3]
    with pytest.raises(genplan.errors.GenplanError, match="unfinished data set .3 of 4 shards"):
        D.read_dataset(out)
    # a shard that fails once is retried within the run
    flaky = iter([True])

    def once(shard):
        if next(flaky, False):
            raise RuntimeError("transient")
        return real(shard)

    monkeypatch.setattr(D, "project_shard", once)
    assert main(argv) == 0
    m = json.loads((out / "manifest.json").read_text())
    assert m["complete"] and m["last_run"]["shards_computed"] == 1
    monkeypatch.setattr(D, "project_shard", real)
    assert m["sha256"] == make(tmp_path / "fresh")["sha256"]


def test_a_folder_of_another_run_is_refused(tmp_path, capsys) -> None:
    make(tmp_path / "d")
    assert main(["data", "--robot", "panda", "--data-size", "600", "--shard-size", str(SIZE), "--seed", "2",
                 "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert "holds another data set (data_size 500 there, 600 here)" in err, err
    assert main(["data", "--robot", "panda", "--data-size", "10", "--out", str(tmp_path / "e"), "--ray", "a b"]) == 2
    assert "argument --ray: expected 'auto' or a Ray address" in capsys.readouterr().err


def test_train_gan_from_a_data_set_checks_robot_and_task(tmp_path, capsys, monkeypatch) -> None:
    monkeypatch.setenv("GENPLAN_CACHE", str(tmp_path / "cache"))
    d = tmp_path / "d"
    m = make(d)
    model = tmp_path / "m.safetensors"
    assert main(["train", "gan", "--robot", "panda", "--data", str(d), "--iterations", "5", "--n-net", "2",
                 "--eval-targets", "5", "--out", str(model)]) == 0
    card = json.loads(model.with_suffix(".json").read_text())
    assert card["training"]["data_set"]["sha256"] == m["sha256"] and card["config"]["data_size"] == N
    assert card["command"].endswith(f"--data {d} --out {model}")
    capsys.readouterr()
    # another robot's data set
    talos = tmp_path / "talos"
    assert main(["data", "--robot", "talos", "--data-size", "20", "--shard-size", "20", "--out", str(talos)]) == 0
    capsys.readouterr()
    assert main(["train", "gan", "--robot", "panda", "--data", str(talos), "--out", str(model)]) == 2
    err = capsys.readouterr().err
    assert f"{talos} was made for robot 'talos'" in err and "this run's robot is 'panda'" in err, err
    # another task's manifold (the same robot)
    manifest = json.loads((d / "manifest.json").read_text())
    manifest["manifold"]["name"] = "elsewhere"
    (d / "manifest.json").write_text(json.dumps(manifest))
    assert main(["train", "gan", "--robot", "panda", "--data", str(d), "--out", str(model)]) == 2
    err = capsys.readouterr().err
    assert "was made for task 'panda_ik' (manifold 'elsewhere'), this run's task is 'panda_ik' (manifold " \
           "'panda_projection')" in err, err
    assert main(["train", "gan", "--robot", "panda", "--data", str(d), "--data-size", "10", "--out", str(model)]) == 2
    assert "--data-size: the data set given by --data fixes the size" in capsys.readouterr().err


@pytest.mark.parametrize("text, ok", [("0..3", range(0, 4)), ("5", range(5, 6)), ("2..2", range(2, 3)),
                                      ("3..1", None), ("a..b", None), ("-1..2", None), ("0..4294967296", None)])
def test_seed_ranges(text, ok) -> None:
    import argparse

    from genplan._cli_args import seed_range

    if ok is None:
        with pytest.raises(argparse.ArgumentTypeError, match="expected seeds A..B"):
            seed_range(text)
    else:
        assert seed_range(text) == ok
