"""genplan.seq2seq.data and .recordings: trajectory data sets (checks, split, ranges, another robot
refused), resampling, the planner as a source (small), and recordings in every format (.npz, CSV,
ROS 2 bag / MCAP), with their refusals naming the file and the problem."""

from __future__ import annotations

import numpy as np
import pytest

import genplan
from genplan.errors import GenplanError, NonFiniteError, SettingsError, ShapeError, UnknownNameError
from genplan.seq2seq.data import TrajectorySet, from_recordings, plan_trajectories, resample


@pytest.fixture(scope="module")
def panda():
    return genplan.load("panda")


def _set(n: int = 4, k: int = 5, d: int = 3) -> TrajectorySet:
    rng = np.random.default_rng(0)
    return TrajectorySet(rng.normal(size=(n, k, d)), rng.random(n) + 1.0, tuple(f"j{i}" for i in range(d)))


def test_a_set_checks_its_arrays() -> None:
    s = _set()
    assert (len(s), s.K, s.dim) == (4, 5, 3) and len(s.sha256) == 64
    with pytest.raises(ShapeError, match="one column per axis"):
        TrajectorySet(np.zeros((2, 5, 4)), np.ones(2), ("a", "b", "c"))
    with pytest.raises(ShapeError, match="one value per trajectory"):
        TrajectorySet(np.zeros((2, 5, 3)), np.ones(3), ("a", "b", "c"))
    bad = np.zeros((2, 5, 3))
    bad[1, 2, 0] = np.nan
    with pytest.raises(NonFiniteError, match=r"positions holds NaN or inf \(first at index \(1, 2, 0\)\)"):
        TrajectorySet(bad, np.ones(2), ("a", "b", "c"))
    with pytest.raises(SettingsError, match="space must be one of"):
        TrajectorySet(np.zeros((2, 5, 3)), np.ones(2), ("a", "b", "c"), space="cartesian")


def test_split_ranges_and_subsets() -> None:
    s = _set(n=20)
    train, held = s.split(0.25, seed=1)
    assert (len(train), len(held)) == (15, 5)
    assert sorted(np.concatenate([train.positions[:, 0, 0], held.positions[:, 0, 0]])) == sorted(s.positions[:, 0, 0])
    r = s.ranges()
    np.testing.assert_allclose(r["end_low"], s.positions[:, -1].min(0))
    with pytest.raises(SettingsError, match="cannot be split"):
        _set(n=1).split(0.5)


def test_resample_is_linear_on_a_uniform_grid() -> None:
    t = np.array([0.0, 1.0, 3.0])
    q = np.array([[0.0, 1.0], [1.0, 1.0], [3.0, -1.0]])
    out = resample(t, q, 4)
    np.testing.assert_allclose(out[:, 0], [0.0, 1.0, 2.0, 3.0])
    np.testing.assert_allclose(out[:, 1], [1.0, 1.0, 0.0, -1.0])
    with pytest.raises(SettingsError, match="times must increase"):
        resample([0.0, 0.0, 1.0], q, 4)
    with pytest.raises(NonFiniteError):
        resample([0.0, np.nan, 1.0], q, 4)


def test_another_robots_set_is_refused(panda) -> None:
    s = TrajectorySet(np.zeros((2, 3, 6)), np.ones(2), tuple(f"j{i}" for i in range(6)))
    with pytest.raises(GenplanError, match="holds trajectories of the joints"):
        s.check_robot(panda)


def test_recordings_in_every_format(tmp_path, panda) -> None:
    names = list(panda.joint_names)
    t = np.linspace(0.0, 2.0, 21)
    q = panda.q_default + 0.1 * np.sin(t)[:, None] * np.ones(panda.nq)
    np.savez(tmp_path / "a.npz", q=q, t=t, joint_names=np.array(names))
    with open(tmp_path / "b.csv", "w") as f:
        f.write("t," + ",".join(reversed(names)) + "\n")
        for ti, row in zip(t, q):
            f.write(f"{ti}," + ",".join(str(v) for v in row[::-1]) + "\n")
    s = from_recordings([tmp_path / "a.npz", tmp_path / "b.csv"], panda, steps=11)
    assert s.positions.shape == (2, 11, panda.nq)
    np.testing.assert_allclose(s.positions[0], s.positions[1], atol=1e-12)  # the CSV's columns reordered by name
    np.testing.assert_allclose(s.durations, [2.0, 2.0])
    np.testing.assert_allclose(s.positions[0, -1], q[-1])


def test_recordings_are_refused_naming_the_file_and_the_problem(tmp_path, panda) -> None:
    names = list(panda.joint_names)
    t = np.linspace(0.0, 1.0, 5)
    q = np.tile(panda.q_default, (5, 1))
    np.savez(tmp_path / "short.npz", q=q[:, :-1], t=t, joint_names=np.array(names[:-1]))
    with pytest.raises(UnknownNameError, match=r"short.npz: no column for joint\(s\) \['panda_joint7'\]"):
        from_recordings([tmp_path / "short.npz"], panda)
    bad = q.copy()
    bad[2, 3] = np.nan
    np.savez(tmp_path / "nan.npz", q=bad, t=t, joint_names=np.array(names))
    with pytest.raises(NonFiniteError, match="nan.npz: NaN or inf in the recording"):
        from_recordings([tmp_path / "nan.npz"], panda)
    far = q.copy()
    far[1, 0] = 10.0
    np.savez(tmp_path / "far.npz", q=far, t=t, joint_names=np.array(names))
    with pytest.raises(GenplanError, match="far.npz: sample .* outside its limits"):
        from_recordings([tmp_path / "far.npz"], panda)
    (tmp_path / "x.txt").write_text("1 2 3")
    with pytest.raises(GenplanError, match="unknown recording format '.txt'"):
        from_recordings([tmp_path / "x.txt"], panda)
    np.savez(tmp_path / "nonames.npz", q=q, t=t)
    with pytest.raises(GenplanError, match="names no joints"):
        from_recordings([tmp_path / "nonames.npz"], panda)
    assert from_recordings([tmp_path / "nonames.npz"], panda, joint_names=names, steps=3).K == 3


def test_ros2_bags_and_mcap_files(tmp_path, panda) -> None:
    pytest.importorskip("rosbags")
    from pathlib import Path

    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    js = ts.types["sensor_msgs/msg/JointState"]
    header, stamp = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    names = list(panda.joint_names)
    folder = Path(tmp_path / "bag")
    with Writer(folder, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection("/joint_states", js.__msgtype__, typestore=ts)
        for i in range(6):
            msg = js(header=header(stamp=stamp(sec=i, nanosec=500_000_000), frame_id=""), name=names,
                     position=panda.q_default + 0.01 * i, velocity=np.zeros(0), effort=np.zeros(0))
            w.write(conn, i * 10**9, ts.serialize_cdr(msg, js.__msgtype__))
    from_folder = from_recordings([folder], panda, steps=6)
    from_file = from_recordings([next(folder.glob("*.mcap"))], panda, steps=6)
    np.testing.assert_allclose(from_folder.positions, from_file.positions)
    np.testing.assert_allclose(from_folder.positions[0, :, 0], panda.q_default[0] + 0.01 * np.arange(6))
    assert from_folder.durations[0] == pytest.approx(5.0)
    with pytest.raises(UnknownNameError, match="no JointState or JointTrajectory topic '/other'"):
        from_recordings([folder], panda, topic="/other")


def test_the_planner_as_a_source(panda) -> None:
    s = plan_trajectories(panda, "panda_projection", "panda_shelf", count=3, steps=8, seed=0, shard_size=2,
                          progress=False, spread=0.3, start_box=[[0.45, -0.3, 0.15], [0.75, 0.3, 0.3]],
                          goal_box=[[0.45, -0.3, 0.35], [0.75, 0.3, 0.45]], frame="hand")
    assert s.positions.shape == (3, 8, panda.nq) and np.all(s.durations > 0)
    assert s.source["kind"] == "planner" and s.task["name"] == "panda_projection"
    world = panda.collision_world()
    world.add_scene("panda_shelf")
    assert not np.any(world.in_collision(s.positions[:, [0, -1]].reshape(-1, panda.nq)))
    hands = panda.frame_positions(s.positions[:, -1], "hand")
    assert np.all((hands >= [0.45 - 1e-3, -0.3 - 1e-3, 0.35 - 1e-3]) & (hands <= [0.75 + 1e-3, 0.3 + 1e-3, 0.45 + 1e-3]))
    again = plan_trajectories(panda, "panda_projection", "panda_shelf", count=3, steps=8, seed=0, shard_size=2,
                              progress=False, spread=0.3, start_box=[[0.45, -0.3, 0.15], [0.75, 0.3, 0.3]],
                              goal_box=[[0.45, -0.3, 0.35], [0.75, 0.3, 0.45]], frame="hand")
    np.testing.assert_array_equal(s.positions, again.positions)
    with pytest.raises(SettingsError, match="goal_box must be"):
        plan_trajectories(panda, "panda_projection", count=1, goal_box=[[0, 0, 0], [-1, 0, 0]], progress=False)
    with pytest.raises(UnknownNameError, match="frame 'nope'"):
        plan_trajectories(panda, "panda_projection", count=1, frame="nope", progress=False)


def test_integrity_rerun_a_corrupt_npz_recording_is_a_data_file_error_naming_it(tmp_path, panda) -> None:
    """A recording .npz of junk bytes or with one bit flipped (its zip member failing the CRC)
    raised zipfile.BadZipFile; now DataFileError naming the file (genplan._files.read_npz)."""
    from genplan.errors import DataFileError

    t = np.linspace(0.0, 1.0, 5)
    good = tmp_path / "good.npz"
    np.savez(good, q=np.tile(panda.q_default, (5, 1)), t=t, joint_names=np.array(panda.joint_names))
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"\x00not a zip file\xff" * 50)
    flipped = tmp_path / "flipped.npz"
    raw = bytearray(good.read_bytes())
    raw[raw.find(np.asarray(panda.q_default, dtype=np.float64).tobytes()) + 3] ^= 0x01  # in q's data
    flipped.write_bytes(bytes(raw))
    for bad, why in ((junk, "ValueError"), (flipped, "BadZipFile: Bad CRC-32 for file 'q.npy'")):
        with pytest.raises(DataFileError, match=rf"^recording {bad}: not a readable \.npz file \({why}"):
            from_recordings([bad], panda, steps=5)
    assert from_recordings([good], panda, steps=5).positions.shape == (1, 5, panda.nq)
