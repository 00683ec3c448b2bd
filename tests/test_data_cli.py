"""``genplan data`` (genplan.cli.data, genplan.samplers.data.write_dataset / read_dataset): a data
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
from genplan.samplers import data as D

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

    from genplan.cli.args import seed_range

    if ok is None:
        with pytest.raises(argparse.ArgumentTypeError, match="expected seeds A..B"):
            seed_range(text)
    else:
        assert seed_range(text) == ok


# -- integrity: one run per folder, no mixed data sets, nothing left by a failed run, sizes bounded


def _lock(out, **fields) -> None:
    """A lock file as another run writes it (see genplan.samplers.data.LOCK)."""
    import socket

    record = {"run": "0123456789abcdef", "host": socket.gethostname(), "pid": 1, "started": "2024-01-01T00:00:00Z",
              "command": "genplan data ...", **fields}
    out.mkdir(parents=True, exist_ok=True)
    (out / D.LOCK).write_text(json.dumps(record))


def _dead_pid() -> int:
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_integrity_2_a_folder_is_written_by_one_run_at_a_time(tmp_path, monkeypatch, capsys) -> None:
    import threading

    out = tmp_path / "d"
    real = D.project_shard
    started, go = threading.Event(), threading.Event()

    def held(shard):
        if shard.seed == 2:  # the first run's shards wait until the second run was refused
            started.set()
            assert go.wait(60)
        return real(shard)

    monkeypatch.setattr(D, "project_shard", held)
    first: list[int] = []
    t = threading.Thread(target=lambda: first.append(main(["data", "--robot", "panda", "--data-size", str(N),
                                                            "--shard-size", str(SIZE), "--seed", "2", "--workers", "1",
                                                            "--out", str(out)])))
    t.start()
    try:
        assert started.wait(60)
        # a second run into the same folder, with another seed: refused, naming the first
        assert main(["data", "--robot", "panda", "--data-size", str(N), "--shard-size", str(SIZE), "--seed", "0",
                     "--workers", "1", "--out", str(out)]) == 2
        err = capsys.readouterr().err  # the first run's progress bar, then the error
        lock = json.loads((out / D.LOCK).read_text())
        assert (f"genplan: error: {out} is being written by another run (host {lock['host']}, pid {lock['pid']}, "
                f"started {lock['started']})") in err, err
        assert "--force" in err
    finally:
        go.set()
        t.join(120)
    assert first == [0]
    monkeypatch.setattr(D, "project_shard", real)
    m = json.loads((out / "manifest.json").read_text())
    assert m["seed"] == 2 and m["complete"] and not (out / D.LOCK).exists()
    assert m["sha256"] == make(tmp_path / "fresh")["sha256"]  # not mixed with the refused run's shards
    capsys.readouterr()

    # a lock left by a process that is gone (this host) is taken over, with a message
    _lock(tmp_path / "stale", pid=_dead_pid())
    make(tmp_path / "stale")
    assert "taking over the lock of run 0123456789abcdef" in capsys.readouterr().out
    assert not (tmp_path / "stale" / D.LOCK).exists()
    # one of another host cannot be checked: refused, then taken with --force
    _lock(tmp_path / "far", host="node-17.cluster", pid=4242)
    argv = ["data", "--robot", "panda", "--data-size", "20", "--shard-size", "10", "--out", str(tmp_path / "far")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert ("is being written by another run (host node-17.cluster, pid 4242, started 2024-01-01T00:00:00Z): "
            "if that run is gone, rerun with --force") in err, err
    assert not (tmp_path / "far" / "manifest.json").exists()
    assert main([*argv, "--force"]) == 0
    assert "taking over the lock of run 0123456789abcdef (host node-17.cluster, pid 4242" in capsys.readouterr().out
    # a lock that is not a lock genplan wrote: refused, naming the file
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / D.LOCK).write_text("{not json")
    assert main(["data", "--robot", "panda", "--data-size", "20", "--out", str(tmp_path / "junk")]) == 2
    assert f"{tmp_path / 'junk' / D.LOCK}: not a genplan lock file" in capsys.readouterr().err


def test_integrity_2_another_data_set_is_refused_and_overwrite_replaces_it(tmp_path, capsys) -> None:
    out = tmp_path / "d"
    make(out)
    (out / "notes.txt").write_text("mine")
    argv = ["data", "--robot", "panda", "--data-size", str(N), "--shard-size", str(SIZE), "--seed", "0",
            "--workers", "2", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"{out} holds another data set (seed 2 there, 0 here): give another folder, or --overwrite to " \
           "replace it" in err, err
    assert json.loads((out / "manifest.json").read_text())["seed"] == 2  # untouched
    assert main([*argv, "--overwrite"]) == 0
    m = json.loads((out / "manifest.json").read_text())
    assert m["seed"] == 0 and m["complete"] and m["last_run"]["shards_computed"] == 4
    ref = D.valid_configurations(genplan.load("panda"), N, seed=0, use_cache=False, progress=False, shard_size=SIZE)
    assert m["sha256"] == hashlib.sha256(ref.tobytes()).hexdigest()
    assert (out / "notes.txt").read_text() == "mine"  # --overwrite removes only what genplan wrote
    # a manifest.json that genplan did not write is not removed by --overwrite
    (tmp_path / "web").mkdir()
    (tmp_path / "web" / "manifest.json").write_text('{"name": "my app"}')
    assert main(["data", "--robot", "panda", "--data-size", "20", "--out", str(tmp_path / "web"), "--overwrite"]) == 2
    assert "not a genplan data set manifest" in capsys.readouterr().err
    assert (tmp_path / "web" / "manifest.json").read_text() == '{"name": "my app"}'


def test_integrity_2_a_run_that_fails_before_its_first_shard_leaves_nothing(tmp_path, monkeypatch, capsys) -> None:
    out = tmp_path / "new" / "d"
    assert main(["data", "--robot", "talos", "--task", "panda_ik", "--data-size", "100", "--out", str(out)]) == 2
    assert "no frame 'hand'" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()  # the folders the run created are gone
    existing = tmp_path / "existing"
    existing.mkdir()
    real = D.project_shard

    def broken(shard):
        raise RuntimeError("node lost")

    monkeypatch.setattr(D, "project_shard", broken)
    assert main(["data", "--robot", "panda", "--data-size", "20", "--workers", "1", "--out", str(existing)]) == 2
    assert existing.is_dir() and list(existing.iterdir()) == []  # a folder given is kept, and left empty
    monkeypatch.setattr(D, "project_shard", real)
    # the corrected run into the same place
    assert main(["data", "--robot", "talos", "--data-size", "20", "--shard-size", "10", "--out", str(out)]) == 0
    capsys.readouterr()
    # a run that failed after some shards keeps them for a rerun of itself; another data set needs --overwrite
    failing = tmp_path / "failing"

    def third_fails(shard):
        if shard.index == 2:
            raise genplan.errors.GenplanError("out of reach")
        return real(shard)

    monkeypatch.setattr(D, "project_shard", third_fails)
    assert main(["data", "--robot", "panda", "--data-size", str(N), "--shard-size", str(SIZE), "--seed", "2",
                 "--workers", "1", "--out", str(failing)]) == 2
    monkeypatch.setattr(D, "project_shard", real)
    assert not json.loads((failing / "manifest.json").read_text())["complete"]
    argv = ["data", "--robot", "panda", "--data-size", "40", "--shard-size", "20", "--out", str(failing)]
    assert main(argv) == 2
    assert "holds another data set" in capsys.readouterr().err
    assert main([*argv, "--overwrite"]) == 0
    assert sorted(p.name for p in failing.iterdir()) == ["manifest.json", "shard_00000.npy", "shard_00001.npy"]


def test_integrity_2_sizes_are_bounded_before_any_allocation(panda: genplan.Robot, tmp_path, monkeypatch,
                                                              capsys) -> None:
    import time

    t0 = time.perf_counter()
    assert main(["data", "--robot", "panda", "--data-size", "1000000000000", "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert time.perf_counter() - t0 < 5
    assert "--data-size 1000000000000: the data set needs 56.0 TB on disk (1000000000000 x 7 float64)" in err, err
    assert not (tmp_path / "d").exists()
    # a shard must fit in memory on every worker
    monkeypatch.setattr(D, "available_memory", lambda: 10_000_000)
    assert main(["data", "--robot", "panda", "--data-size", "200000", "--shard-size", "200000", "--workers", "2",
                 "--out", str(tmp_path / "e")]) == 2
    err = capsys.readouterr().err
    assert "--shard-size 200000: 2 workers hold a shard of 11.2 MB each" in err, err
    # the in-memory data set (genplan train gan --data-size, valid_configurations)
    with pytest.raises(genplan.errors.SettingsError, match=r"data size 1000000000: 1000000000 configurations of "
                                                           r"panda need 56.0 GB in memory"):
        D.valid_configurations(panda, 10**9, use_cache=False, progress=False)
    t0 = time.perf_counter()
    with pytest.raises(genplan.errors.SettingsError, match="data size"):
        D.write_dataset(tmp_path / "f", panda, 10**12, progress=False)
    assert time.perf_counter() - t0 < 5 and not (tmp_path / "f").exists()


def _digests(folder) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


def test_integrity_rerun_overwrite_keeps_the_old_set_until_the_first_shard(tmp_path, monkeypatch, capsys) -> None:
    # --overwrite moves the old data set aside and removes it only once the new run's first shard
    # is written: a run that fails before that (an input error seen only by the shards) puts it
    # back unchanged and says so; one killed before that has it put back by the next run.
    from genplan._shards import REPLACED

    out = tmp_path / "d"
    make(out)
    (out / "notes.txt").write_text("mine")
    before = _digests(out)
    real = D.project_shard

    def out_of_reach(shard):
        assert (out / REPLACED / "manifest.json").is_file() and not (out / "manifest.json").exists()
        raise genplan.errors.GenplanError("shard 0: the task's manifold is out of reach")

    argv = ["data", "--robot", "panda", "--data-size", "40", "--shard-size", "20", "--workers", "1", "--out", str(out)]
    monkeypatch.setattr(D, "project_shard", out_of_reach)
    assert main([*argv, "--overwrite"]) == 2
    err = capsys.readouterr().err
    assert "out of reach" in err and f"the data set it was to replace is put back in {out} unchanged" in err, err
    assert _digests(out) == before  # the same files, the same bytes; no folder left aside
    # a run killed before its first shard (the set still aside, nothing of its own written yet)
    (out / REPLACED).mkdir()
    for f in out.iterdir():
        if f.name.startswith(("manifest", "shard_")):
            f.rename(out / REPLACED / f.name)
    monkeypatch.setattr(D, "project_shard", real)
    assert main(["data", "--robot", "panda", "--data-size", str(N), "--shard-size", str(SIZE), "--seed", "2",
                 "--workers", "2", "--out", str(out)]) == 0
    log = capsys.readouterr().out
    assert "put back the data set (4 shard files)" in log and "4 of 4 shards finished and verified" in log, log
    after = _digests(out)  # the manifest is rewritten (its last run), the shards are the same
    assert {k: v for k, v in after.items() if k != "manifest.json"} == {k: v for k, v in before.items()
                                                                         if k != "manifest.json"}
    assert json.loads((out / "manifest.json").read_text())["last_run"]["shards_computed"] == 0
    # a run that succeeds removes the old set once its first shard is written

    def checked(shard):
        aside = (out / REPLACED).exists()
        assert aside == (shard.index == 0), shard.index  # one worker: shard 0 is computed before any is written
        return real(shard)

    monkeypatch.setattr(D, "project_shard", checked)
    assert main([*argv, "--overwrite"]) == 0
    assert sorted(_digests(out)) == ["manifest.json", "notes.txt", "shard_00000.npy", "shard_00001.npy"]
    assert json.loads((out / "manifest.json").read_text())["complete"]
