"""genplan.executor: seeded shards on local threads, local processes and an in-process Ray with 2
CPUs give the same results bit for bit; a shard that raises or whose worker dies is retried (a
bounded number of times), and a run that cannot finish names its failed shards; --ray without
Ray says how to install it."""

from __future__ import annotations

import builtins
import hashlib
import json
import os
import time
from pathlib import Path

import numpy as np
import pytest

import genplan
from genplan.cli import main
from genplan.errors import GenplanError
from genplan.executor import (RETRIES, LocalExecutor, MissingExtraError, RayExecutor, ShardsFailedError, chunks,
                              executor, shard_rng, shard_seed)
from genplan.samplers import data as D

import ray  # noqa: E402 -- the ray extra: scripts/setup installs it, so these tests never skip silently


@pytest.fixture(scope="module")
def local_ray():
    """A Ray of 2 CPUs started in this process (RayExecutor("auto") joins it)."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


# -- shard functions (module-level: pickled by reference to processes and Ray workers)


def square_after(item: tuple[int, float]) -> int:
    i, delay = item
    time.sleep(delay)
    return i * i


def fail_once(item: tuple[int, str, str]) -> int:
    """Shard ``i`` fails on its first attempt (a marker file records it): raises, or kills its
    worker process with ``how == "die"``."""
    i, marker, how = item
    m = Path(marker)
    if i == 1 and not m.exists():
        m.write_text("failed once")
        if how == "die":
            os._exit(3)
        raise RuntimeError("injected failure")
    return 10 * i


def always_fails(i: int) -> int:
    if i == 2:
        raise RuntimeError(f"shard {i} is broken")
    return i


def input_error(i: int) -> int:
    raise GenplanError("the manifold is out of reach")


def draw(i: int) -> float:
    return float(shard_rng(7, i).standard_normal())


# -- the layer


def test_shard_seeds_depend_on_the_run_seed_and_the_index_only() -> None:
    children = np.random.SeedSequence(5).spawn(4)
    for i, child in enumerate(children):
        assert shard_seed(5, i).generate_state(4).tolist() == child.generate_state(4).tolist()
    assert shard_rng(5, 2).random() == np.random.default_rng(children[2]).random()
    assert shard_rng(5, 2).random() != shard_rng(6, 2).random() != shard_rng(5, 3).random()
    assert chunks(12, 5) == [5, 5, 2] and chunks(5, 5) == [5]
    with pytest.raises(GenplanError):
        chunks(0, 5)


def test_results_come_in_the_order_of_the_items_on_every_executor(local_ray) -> None:
    items = [(i, 0.05 * (3 - i)) for i in range(4)]  # the last finishes first
    seen: list[int] = []
    for ex in (LocalExecutor(1), LocalExecutor(2), LocalExecutor(2, "process"), RayExecutor("auto")):
        with ex:
            assert ex.map(square_after, items, progress=False) == [0, 1, 4, 9], ex.name
            seen.clear()
            kept = ex.map(square_after, items, progress=False, on_result=lambda i, r: seen.append(i) or -r)
            assert kept == [0, -1, -4, -9] and sorted(seen) == [0, 1, 2, 3]
        assert ex.map(draw, range(3), progress=False) == [draw(0), draw(1), draw(2)]
    assert RayExecutor("auto").workers == 2  # the in-process Ray's CPUs


@pytest.mark.parametrize("kind, how", [("thread", "raise"), ("process", "raise"), ("process", "die"),
                                       ("ray", "raise"), ("ray", "die")])
def test_a_failed_shard_is_retried(kind, how, tmp_path, local_ray) -> None:
    marker = tmp_path / "marker"
    ex = RayExecutor("auto") if kind == "ray" else LocalExecutor(2, kind)
    with ex:
        out = ex.map(fail_once, [(i, str(marker), how) for i in range(4)], progress=False)
    assert out == [0, 10, 20, 30]
    assert marker.read_text() == "failed once"  # the failure happened, then the retry succeeded


def test_a_shard_that_keeps_failing_is_named_and_the_others_finish() -> None:
    done: list[int] = []
    with LocalExecutor(2) as ex, pytest.raises(ShardsFailedError) as err:
        ex.map(always_fails, list(range(5)), desc="demo", progress=False, on_result=lambda i, r: done.append(i))
    assert sorted(done) == [0, 1, 3, 4]
    assert err.value.failures == {2: f"RuntimeError: shard 2 is broken (after {1 + RETRIES} attempts)"}
    assert str(err.value) == f"demo: 1 of 5 shards failed: shard 2: RuntimeError: shard 2 is broken (after 3 attempts)"


def test_an_input_error_is_not_retried_and_stops_the_run() -> None:
    with LocalExecutor(1) as ex, pytest.raises(ShardsFailedError, match="stopped at an input error") as err:
        ex.map(input_error, list(range(6)), progress=False)
    assert err.value.failures == {0: "GenplanError: the manifold is out of reach"}  # the others never started


def test_ray_missing_says_how_to_install_it(monkeypatch, capsys, tmp_path) -> None:
    real_import = builtins.__import__

    def no_ray(name, *args, **kwargs):
        if name == "ray" or name.startswith("ray."):
            raise ImportError("No module named 'ray'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_ray)
    with pytest.raises(MissingExtraError, match=r"pip install 'genplan\[ray\]'"):
        executor(2, ray="auto")
    assert isinstance(MissingExtraError("x"), GenplanError)
    assert main(["data", "--robot", "panda", "--data-size", "10", "--out", str(tmp_path / "d"), "--ray", "auto"]) == 2
    assert capsys.readouterr().err == ("genplan: error: --ray: Ray is not installed (pip install 'genplan[ray]')\n")
    assert not (tmp_path / "d" / "manifest.json").exists()


# -- the data set on every executor


def test_the_data_set_is_identical_on_1_and_2_workers_processes_and_ray(panda: genplan.Robot, local_ray,
                                                                        tmp_path) -> None:
    n, size = 700, 200  # 4 shards, the last of 100
    ref = D.valid_configurations(panda, n, seed=3, use_cache=False, progress=False, shard_size=size)
    digest = hashlib.sha256(ref.tobytes()).hexdigest()
    for ex in (LocalExecutor(1), LocalExecutor(2), LocalExecutor(2, "process"), RayExecutor("auto")):
        with ex:
            data = D.generate(panda, n, 3, shard_size=size, executor=ex, progress=False)
        assert hashlib.sha256(data.tobytes()).hexdigest() == digest, ex.name
    # the command line: 1 worker, 2 workers, --ray auto (joins the in-process Ray)
    for flags in (["--workers", "1"], ["--workers", "2"], ["--ray", "auto"]):
        out = tmp_path / "_".join(flags)
        assert main(["data", "--robot", "panda", "--data-size", str(n), "--seed", "3", "--shard-size", str(size),
                     "--out", str(out), *flags]) == 0
        manifest = json.loads((out / "manifest.json").read_text())
        assert manifest["sha256"] == digest and manifest["complete"], flags
        assert manifest["last_run"]["executor"] == ("ray" if "--ray" in flags else "local-threads")
    # a different seed is a different data set
    assert D.dataset_sha256([D.generate(panda, n, 4, shard_size=size, progress=False)]) != digest


# -- Ctrl-C


def wait_for_stop(seconds: float) -> str:
    """A shard that runs ``seconds`` unless its run is interrupted (it polls stopping())."""
    from genplan.executor import stopping

    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        if stopping():
            raise KeyboardInterrupt("stopped")
        time.sleep(0.01)
    return "finished"


def test_integrity_6_ctrl_c_stops_worker_threads_that_poll_stopping() -> None:
    from genplan.executor import stopping
    from tests.interrupt import MAX_LATENCY_S, ctrl_c_latency

    t0 = time.perf_counter()
    with LocalExecutor(2) as ex:
        latency = ctrl_c_latency(lambda: ex.map(wait_for_stop, [30.0] * 4, progress=False), after=0.3)
    assert latency < MAX_LATENCY_S and not stopping()
    assert time.perf_counter() - t0 < 0.3 + 2 * MAX_LATENCY_S  # the threads ended too, not after 30 s
    # a data shard stops between pieces of its projections
    panda = genplan.load("panda")
    shard = D.shards(panda, 2000, shard_size=2000)[0]
    import genplan.executor as E

    E._STOP.set()
    try:
        with pytest.raises(KeyboardInterrupt, match="shard 0: the run was interrupted"):
            D.project_shard(shard)
    finally:
        E._STOP.clear()


def _group_ends(pgid: int, seconds: float) -> bool:
    """Whether every process of the group ``pgid`` has ended within ``seconds``."""
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


@pytest.mark.parametrize("after", [0.05, 0.3, 2.0])
def test_integrity_6_ctrl_c_ends_worker_processes_without_a_traceback(after: float) -> None:
    import signal
    import subprocess
    import sys

    code = ("import signal, sys, time\n"
            "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
            "from genplan.executor import LocalExecutor\n"
            "print('start', flush=True)\n"
            "try:\n"
            "    with LocalExecutor(2, 'process') as ex:\n"
            "        ex.map(time.sleep, [30, 30, 30], progress=False)\n"
            "except KeyboardInterrupt:\n"
            "    sys.exit(130)\n")
    # a session of its own: the Ctrl-C goes to the whole process group, as a terminal sends it
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    assert proc.stdout.readline().strip() == "start"
    time.sleep(after)
    t0 = time.perf_counter()
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and time.perf_counter() - t0 < 10
    assert err == "", err  # no worker printed a traceback
    if not _group_ends(proc.pid, 5.0):  # and none is left running
        pytest.fail("worker processes outlived the interrupted run")


@pytest.mark.parametrize("how", ["SIGTERM", "SIGKILL"])
def test_worker_processes_exit_when_their_parent_is_ended_without_ending_them(how: str) -> None:
    import signal
    import subprocess
    import sys

    code = ("import time\n"
            "from genplan.executor import LocalExecutor\n"
            "with LocalExecutor(2, 'process') as ex:\n"
            "    ex.map(time.sleep, [0.0, 0.0], progress=False)\n"  # both workers started and idle
            "    print('start', flush=True)\n"
            "    ex.map(time.sleep, [30, 30, 30], progress=False)\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    assert proc.stdout.readline().strip() == "start"
    time.sleep(0.3)
    os.kill(proc.pid, getattr(signal, how))  # the parent only: its pool gets no chance to end the workers
    proc.communicate(timeout=60)
    if not _group_ends(proc.pid, 5.0):  # the workers: the rest of the process group
        os.killpg(proc.pid, signal.SIGKILL)
        pytest.fail(f"worker processes outlived their parent's {how} by 5 s")
