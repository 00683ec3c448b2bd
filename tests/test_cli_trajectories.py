"""The trajectory family from the shell (genplan.cli.data_trajectories, genplan.cli.train_seq2seq
--data, genplan.cli.adjust) at tiny sizes: ``genplan data trajectories`` writes shards + manifest
(sha256 per shard checked on read, resumed after an interrupted run with the same sha256, another
data set refused, the lock), the old ``genplan data`` form still runs ``data configurations``,
``genplan train seq2seq --data`` trains and writes a model with its card, ``genplan adjust``
adjusts, finishes and writes every result, and bad input is a one-line error naming the file and
the field before any work."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

import genplan
from genplan._shards import LOCK
from genplan.cli import main
from genplan.cli.args import FAILED
from genplan.seq2seq import data as S

BOXES = ["--start-box", "0.45", "-0.3", "0.15", "0.75", "0.3", "0.3",
         "--goal-box", "0.45", "-0.3", "0.35", "0.75", "0.3", "0.45"]


def argv(out: Path, *extra: str, count: int = 6, seed: int = 0) -> list[str]:
    return ["data", "trajectories", "--robot", "panda", "--task", "panda_projection", "--scene", "panda_shelf",
            "--count", str(count), "--steps", "8", "--shard-size", "2", "--seed", str(seed), "--spread", "0.3",
            "--frame", "hand", "--workers", "1", "--no-progress", *BOXES, "--out", str(out), *extra]


@pytest.fixture(autouse=True)
def one_torch_thread(monkeypatch):
    monkeypatch.setenv("GENPLAN_TORCH_THREADS", "1")


@pytest.fixture(scope="module")
def family(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("family") / "d"
    assert main(argv(out)) == 0
    return out


@pytest.fixture(scope="module")
def model(family, tmp_path_factory) -> Path:
    os.environ.setdefault("GENPLAN_TORCH_THREADS", "1")
    out = tmp_path_factory.mktemp("model") / "m.safetensors"
    assert main(["train", "seq2seq", "--data", str(family), "--out", str(out), "--epochs", "2", "--held-out", "0.34",
                 "--threads", "1", "--no-progress"]) == 0
    return out


def _error(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("genplan: error: "), err
    return err


def test_data_trajectories_writes_a_checked_data_set_equal_to_the_planner_in_memory(family) -> None:
    m = json.loads((family / "manifest.json").read_text())
    assert m["format"] == S.FORMAT and m["complete"] and m["count"] == 6 and m["K"] == 8
    assert [s["file"] for s in m["shards"]] == ["shard_00000.npz", "shard_00001.npz", "shard_00002.npz"]
    assert m["failures"].keys() == {"endpoints", "plan", "timing"} and m["attempts"] >= 6
    assert not (family / LOCK).exists() and not list(family.glob(".*"))
    data = S.read_trajectories(family, genplan.load("panda"))
    assert data.positions.shape == (6, 8, 7) and data.sha256 == m["sha256"] and data.scene["name"] == "panda_shelf"
    assert data.source["seed"] == 0 and data.source["failures"] == m["failures"]
    memory = S.plan_trajectories("panda", "panda_projection", "panda_shelf", count=6, steps=8, seed=0, shard_size=2,
                                 spread=0.3, frame="hand", start_box=[[0.45, -0.3, 0.15], [0.75, 0.3, 0.3]],
                                 goal_box=[[0.45, -0.3, 0.35], [0.75, 0.3, 0.45]], progress=False)
    np.testing.assert_array_equal(memory.positions, data.positions)


def test_a_changed_shard_is_refused_on_read_and_recomputed_on_resume(family, tmp_path, capsys) -> None:
    import shutil

    out = tmp_path / "d"
    shutil.copytree(family, out)
    first = json.loads((out / "manifest.json").read_text())
    with np.load(out / "shard_00001.npz") as z:
        pos, dur = z["positions"].copy(), z["durations"]
    pos[0, 3, 2] += 1e-3
    np.savez(out / "shard_00001.npz", positions=pos, durations=dur)
    with pytest.raises(genplan.errors.GenplanError, match="shard_00001.npz: its arrays do not match the manifest's sha256"):
        S.read_trajectories(out)
    (out / "shard_00002.npz").unlink()  # an interrupted run's missing shard
    capsys.readouterr()
    assert main(argv(out)) == 0
    log = capsys.readouterr().out
    assert "resuming" in log and "1 of 3 shards finished and verified, 2 listed but missing" in log, log
    again = json.loads((out / "manifest.json").read_text())
    assert again["sha256"] == first["sha256"] and again["last_run"]["shards_computed"] == 2
    assert [s["sha256"] for s in again["shards"]] == [s["sha256"] for s in first["shards"]]


def test_another_data_set_is_refused_then_overwritten_and_a_lock_refuses_a_second_run(family, tmp_path,
                                                                                      capsys) -> None:
    import shutil

    out = tmp_path / "d"
    shutil.copytree(family, out)
    assert main(argv(out, count=4, seed=1)) == 2
    err = _error(capsys)
    assert f"{out} holds another data set (count 6 there, 4 here; seed 0 there, 1 here" in err, err
    assert "--overwrite" in err
    # a configuration data set's folder is another data set too
    conf = tmp_path / "conf"
    assert main(["data", "--robot", "panda", "--data-size", "20", "--shard-size", "10", "--workers", "1",
                 "--out", str(conf)]) == 0  # the old form of `genplan data configurations`
    assert json.loads((conf / "manifest.json").read_text())["format"] == "genplan-dataset/1"
    assert main(argv(conf, count=2)) == 2
    assert "holds another data set" in _error(capsys)
    assert main(argv(conf, "--overwrite", count=2)) == 0
    assert sorted(p.name for p in conf.iterdir()) == ["manifest.json", "shard_00000.npz"]
    with pytest.raises(genplan.errors.GenplanError, match="format 'genplan-trajectories/1', expected 'genplan-dataset/1'"):
        from genplan.samplers.data import read_dataset

        read_dataset(conf)
    # a folder another live run holds (this process) is refused, naming it
    (out / LOCK).write_text(json.dumps({"run": "0123456789abcdef", "host": __import__("socket").gethostname(),
                                        "pid": os.getpid(), "pid_start": None, "started": "2024-01-01T00:00:00Z",
                                        "command": "genplan data trajectories"}))
    assert main(argv(out)) == 2
    assert f"{out} is being written by another run" in _error(capsys)


def test_data_configurations_keeps_its_old_form(tmp_path, capsys) -> None:
    new, old = tmp_path / "new", tmp_path / "old"
    common = ["--robot", "panda", "--data-size", "20", "--shard-size", "10", "--workers", "1"]
    assert main(["data", "configurations", *common, "--out", str(new)]) == 0
    assert main(["data", *common, "--out", str(old)]) == 0
    sha = [json.loads((d / "manifest.json").read_text())["sha256"] for d in (new, old)]
    assert sha[0] == sha[1]
    assert main(["data", "--robot", "panda", "--data-size", "0", "--out", str(tmp_path / "x")]) == 2
    assert "data configurations: argument --data-size: expected a positive integer" in _error(capsys)
    assert main(["data", "trajectories", "--robot", "panda", "--task", "panda_projection", "--count", "2",
                 "--start-box", "1", "0", "0", "0", "0", "0", "--out", str(tmp_path / "y")]) == 2
    assert "--start-box: expected X0 Y0 Z0 X1 Y1 Z1, finite, low corner <= high corner" in _error(capsys)
    assert not (tmp_path / "y").exists()


def test_train_seq2seq_from_a_data_set_writes_the_model_and_its_card(model, family) -> None:
    from genplan.seq2seq.model import load_model

    m = load_model(model)
    card = json.loads(model.with_suffix(".json").read_text())
    manifest = json.loads((family / "manifest.json").read_text())
    assert card["data"]["sha256"] == manifest["sha256"] and card["data"]["held_out"] == 2
    assert card["evaluation"]["rmse"] > 0 and card["evaluation"]["max_residual_ratio"] >= 0
    assert card["training"]["total_seconds"] > 0
    assert card["retrain"].startswith(f"genplan train seq2seq --data {family} --out {model} --seed 0 --held-out 0.34")
    assert m.config.K == 8 and m.config.axes == tuple(genplan.load("panda").joint_names)


def test_train_seq2seq_data_refuses_the_pancakes_options(family, tmp_path, capsys) -> None:
    assert main(["train", "seq2seq", "--data", str(family), "--trajectories", "10",
                 "--out", str(tmp_path / "m.safetensors")]) == 2
    assert "--trajectories: an option of the pancake's model" in _error(capsys)
    assert main(["train", "seq2seq", "--data", str(family)]) == 2
    assert "--out: give the model's path" in _error(capsys)
    assert not list(tmp_path.iterdir())


def _reach_objective(tmp_path: Path) -> Path:
    path = tmp_path / "reach.toml"
    path.write_text('name = "reach"\n\n[[term]]\nkind = "end_position"\nframe = "hand"\nweight = 1e4\n\n'
                    '[[term]]\nkind = "joint_limits"\nweight = 100.0\nmargin = 0.01\n\n'
                    '[[term]]\nkind = "stay_near"\nweight = 0.1\n')
    return path


def test_adjust_end_to_end(model, family, tmp_path, capsys) -> None:
    panda = genplan.load("panda")
    data = S.read_trajectories(family)
    x = data.positions[:3]
    goals = panda.frame_positions(data.positions[3:6, -1], "hand")  # other trajectories' ends: reachable, free
    np.savez(tmp_path / "in.npz", q=x, joint_names=np.array(panda.joint_names))
    np.savez(tmp_path / "targets.npz", end_position=goals)
    out = tmp_path / "out"
    code = main(["adjust", "--model", str(model), "--input", str(tmp_path / "in.npz"), "--objective",
                 str(_reach_objective(tmp_path)), "--targets", str(tmp_path / "targets.npz"), "--out", str(out),
                 "--updates", "10", "--scene", "panda_shelf", "--threads", "1", "--no-progress"])
    summary = json.loads((out / "summary.json").read_text())
    assert code == (0 if summary["failed"] == 0 else 1)
    assert summary["problems"] == 3 and summary["succeeded"] + summary["failed"] == 3
    # an objective without a clearance term runs one start per problem by default
    assert summary["starts"] == 1 and summary["restarted"] == 0
    assert all(r["starts_run"] == 1 and r["start"] == 0 for r in summary["results"])
    printed = capsys.readouterr().out
    assert f"{summary['succeeded']} of 3 problems adjusted" in printed
    if summary["failed"]:
        assert f"{summary['failed']} of 3 problems failed: " in printed
    with np.load(out / "adjusted.npz") as z:
        assert z["p"].shape == (3, 8, 7) and z["objective_history"].shape == (11, 3)
        np.testing.assert_array_equal(z["success"], [r["success"] for r in summary["results"]])
        assert np.all(np.diff(z["objective_history"], axis=0) <= 1e-6)  # the adaptive rule never rises
    hist = json.loads((out / "objective.json").read_text())
    assert len(hist["per_problem"]) == 11 and len(hist["mean"]) == 11
    world = panda.collision_world()
    world.add_scene("panda_shelf")
    for r in summary["results"]:
        if r["success"]:  # every success is a trajectory that passes its checks
            traj = genplan.trajectory.Trajectory.load(out / r["trajectory"])
            assert traj.within_tolerance and not np.any(world.in_collision(traj.q[::20]))
            assert r["end_error_m"] < 1e-3
            end = panda.frame_positions(traj.q[-1:], "hand")[0]
            assert np.linalg.norm(end - goals[r["problem"]]) < 1e-3
        else:
            assert r["trajectory"] is None and r["reason"]
            assert not (out / f"trajectory_{r['problem']:05d}.npz").exists()
    # the data set's folder as the input, its scene the default
    out2 = tmp_path / "out2"
    np.savez(tmp_path / "t6.npz", end_position=panda.frame_positions(data.positions[::-1, -1], "hand"))
    code = main(["adjust", "--model", str(model), "--input", str(family), "--objective",
                 str(_reach_objective(tmp_path)), "--targets", str(tmp_path / "t6.npz"), "--out", str(out2),
                 "--updates", "0", "--no-progress"])
    summary = json.loads((out2 / "summary.json").read_text())
    assert summary["problems"] == 6 and summary["scene"] == "panda_shelf"
    assert code == (0 if summary["failed"] == 0 else FAILED)
    # a target out of reach: that problem fails, is reported with its reason, and the exit code is 3
    capsys.readouterr()
    np.savez(tmp_path / "far.npz", end_position=np.array([goals[0], [3.0, 3.0, 3.0]]))
    np.savez(tmp_path / "in2.npz", q=x[:2])
    assert main(["adjust", "--model", str(model), "--input", str(tmp_path / "in2.npz"), "--objective",
                 str(_reach_objective(tmp_path)), "--targets", str(tmp_path / "far.npz"), "--out", str(out),
                 "--updates", "2", "--scene", "panda_shelf", "--no-progress"]) == FAILED == 3
    summary = json.loads((out / "summary.json").read_text())
    assert [r["success"] for r in summary["results"]][1] is False and summary["failed"] >= 1
    assert f"{summary['failed']} of 2 problems failed: " in capsys.readouterr().out
    assert not (out / "trajectory_00001.npz").exists() and not (out / "trajectory_00002.npz").exists()
    # restarts from the data set as the pool: without a clearance term every problem runs them
    out3 = tmp_path / "out3"
    code = main(["adjust", "--model", str(model), "--input", str(tmp_path / "in.npz"), "--objective",
                 str(_reach_objective(tmp_path)), "--targets", str(tmp_path / "targets.npz"), "--out", str(out3),
                 "--updates", "2", "--scene", "panda_shelf", "--starts", "3", "--pool", str(family), "--no-progress"])
    summary = json.loads((out3 / "summary.json").read_text())
    assert summary["starts"] == 3 and summary["restarted"] == 3
    assert all(r["starts_run"] == 3 and r["start"] in (0, 1, 2) for r in summary["results"])
    assert code == (0 if summary["failed"] == 0 else FAILED)


def test_adjust_refuses_bad_input_naming_the_file_and_the_field(model, tmp_path, capsys, monkeypatch) -> None:
    import genplan.seq2seq.adjust as adjust_module

    def started(*args, **kwargs):
        pytest.fail("adjustment started")

    panda = genplan.load("panda")
    objective = _reach_objective(tmp_path)
    good = np.tile(panda.q_default, (2, 8, 1))
    np.savez(tmp_path / "in.npz", q=good)
    np.savez(tmp_path / "t.npz", end_position=np.full((2, 3), 0.5))
    out = tmp_path / "out"
    base = ["adjust", "--model", str(model), "--objective", str(objective), "--out", str(out), "--no-progress"]
    cases = []
    np.savez(tmp_path / "unknown.npz", end_position=np.full((2, 3), 0.5), via=np.zeros((2, 3)))
    cases.append((["--input", str(tmp_path / "in.npz"), "--targets", str(tmp_path / "unknown.npz")],
                  f"--targets {tmp_path / 'unknown.npz'}: ['via'] name no term of the objective 'reach'"))
    np.savez(tmp_path / "nan.npz", end_position=np.array([[0.5, np.nan, 0.5], [0.5, 0.5, 0.5]]))
    cases.append((["--input", str(tmp_path / "in.npz"), "--targets", str(tmp_path / "nan.npz")],
                  f"--targets {tmp_path / 'nan.npz'}: end_position contains NaN or inf (first at index (0, 1))"))
    np.savez(tmp_path / "short.npz", end_position=np.full((3, 3), 0.5))
    cases.append((["--input", str(tmp_path / "in.npz"), "--targets", str(tmp_path / "short.npz")],
                  "end_position has shape (3, 3), expected one target per problem (2, ...)"))
    np.savez(tmp_path / "wide.npz", end_position=np.full((2, 4), 0.5))
    cases.append((["--input", str(tmp_path / "in.npz"), "--targets", str(tmp_path / "wide.npz")],
                  f"--objective {objective} with --targets {tmp_path / 'wide.npz'}: targets['end_position'] must have "
                  "shape (3,)"))
    np.savez(tmp_path / "k.npz", q=np.tile(panda.q_default, (2, 5, 1)))
    cases.append((["--input", str(tmp_path / "k.npz"), "--targets", str(tmp_path / "t.npz")],
                  f"--input {tmp_path / 'k.npz'}: q must be trajectories of shape (8, 7)"))
    bad = good.copy()
    bad[1, 4, 2] = np.nan
    np.savez(tmp_path / "qnan.npz", q=bad)
    cases.append((["--input", str(tmp_path / "qnan.npz"), "--targets", str(tmp_path / "t.npz")],
                  f"--input {tmp_path / 'qnan.npz'}: q contains NaN or inf (first at index (1, 4, 2))"))
    np.savez(tmp_path / "ur5.npz", q=np.zeros((2, 8, 7)), joint_names=np.array([f"j{i}" for i in range(7)]))
    cases.append((["--input", str(tmp_path / "ur5.npz"), "--targets", str(tmp_path / "t.npz")],
                  f"--input {tmp_path / 'ur5.npz'}: joint_names ['j0'"))
    np.savez(tmp_path / "noq.npz", x=good)
    cases.append((["--input", str(tmp_path / "noq.npz")], f"--input {tmp_path / 'noq.npz'}: no array 'q'"))
    (tmp_path / "broken.toml").write_text('[[term]]\nkind = "end_positon"\n')
    cases.append((["--input", str(tmp_path / "in.npz"), "--objective", str(tmp_path / "broken.toml")],
                  f"{tmp_path / 'broken.toml'}: term 1 (end_positon): unknown kind 'end_positon'"))
    (tmp_path / "frame.toml").write_text('[[term]]\nkind = "end_position"\nframe = "nope"\n')
    cases.append((["--input", str(tmp_path / "in.npz"), "--objective", str(tmp_path / "frame.toml"),
                   "--targets", str(tmp_path / "t.npz")], "unknown frame 'nope'"))
    cases.append((["--input", str(tmp_path / "in.npz"), "--method", "newton"],
                  "argument --method: invalid choice: 'newton' (choose from latent, random-latent, direct)"))
    cases.append((["--input", str(tmp_path / "in.npz"), "--targets", str(tmp_path / "t.npz"), "--starts", "0"],
                  "argument --starts"))
    cases.append((["--input", str(tmp_path / "in.npz"), "--targets", str(tmp_path / "t.npz"), "--starts", "3",
                   "--pool", str(tmp_path / "k.npz")], f"--pool {tmp_path / 'k.npz'}: q must be trajectories of shape (8, 7)"))
    cases.append((["--input", str(tmp_path / "in.npz"), "--targets", str(tmp_path / "t.npz"), "--pool",
                   str(tmp_path / "in.npz")], "pool gives restarts their latent starts: it needs starts > 1"))
    monkeypatch.setattr(adjust_module, "_run", started)
    for extra, message in cases:
        assert main([*base, *extra]) == 2, message
        err = _error(capsys)
        assert message in err, (message, err)
    # another robot's data set as the input
    ur5 = tmp_path / "ur5set"
    S.write_trajectories(ur5, S.TrajectorySet(np.zeros((2, 8, 6)), np.ones(2), genplan.load("ur5").joint_names))
    assert main([*base, "--input", str(ur5)]) == 2
    assert f"--input {ur5}: a data set of the axes" in _error(capsys)
    assert not list(out.glob("*.npz")) and not (out / "summary.json").exists()


def test_integrity_rerun_a_task_frame_the_robot_lacks_is_refused_before_the_old_set_is_touched(family, tmp_path,
                                                                                              capsys) -> None:
    import hashlib
    import shutil

    out = tmp_path / "d"
    shutil.copytree(family, out)
    before = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in out.iterdir()}
    bad = ["data", "trajectories", "--robot", "ur5", "--task", "panda_projection", "--count", "6", "--steps", "8",
           "--shard-size", "3", "--workers", "1", "--no-progress", "--out", str(out), "--overwrite"]
    assert main(bad) == 2
    err = _error(capsys)
    assert "task 'panda_projection': robot 'ur5' has no frame 'hand'" in err, err
    assert {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in out.iterdir()} == before


def test_integrity_rerun_a_corrupt_npz_input_is_one_line_naming_it(model, tmp_path, capsys) -> None:
    """A corrupt --input or --targets (junk bytes, or one bit flipped: the zip's CRC fails) ended
    in a zipfile.BadZipFile traceback and left an empty --out folder; now a one-line error naming
    the file, exit 2, and no --out folder."""
    panda = genplan.load("panda")
    good = tmp_path / "in.npz"
    np.savez(good, q=np.tile(panda.q_default, (2, 8, 1)))
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"\x00not a zip file\xff" * 50)
    flipped = tmp_path / "flipped.npz"
    raw = bytearray(good.read_bytes())
    raw[raw.find(np.asarray(panda.q_default, dtype=np.float64).tobytes()) + 3] ^= 0x01  # in q's data
    flipped.write_bytes(bytes(raw))
    out = tmp_path / "out"
    base = ["adjust", "--model", str(model), "--objective", str(_reach_objective(tmp_path)), "--out", str(out),
            "--no-progress"]
    for option, extra in (("--input", []), ("--targets", ["--input", str(good)])):
        for bad in (junk, flipped):
            assert main([*base, *extra, option, str(bad)]) == 2
            err = capsys.readouterr().err
            assert err.startswith(f"genplan: error: {option} {bad}: not a readable .npz file (")
            assert err.count("\n") == 1
            assert bad == junk or "Bad CRC-32 for file 'q.npy'" in err, err
            assert not out.exists()
