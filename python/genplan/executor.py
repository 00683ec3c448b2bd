"""One execution layer for seeded shards: independent pieces of work (a data set's shards, the
seeds of a benchmark sweep, one training per seed) run on the local cores or on Ray.

    from genplan.executor import executor, shard_rng
    with executor(workers=2) as ex:                    # local: threads (the default)
        parts = ex.map(fn, items, desc="data")         # results in the order of ``items``
    with executor(ray="auto") as ex:                   # a local Ray (or an address: a cluster)
        parts = ex.map(fn, items)

Results do not depend on the executor or the number of workers: a shard's randomness comes from
:func:`shard_rng` (the run's seed and the shard's index only), and ``map`` returns the results in
the order of the items whatever order they finished in.

* :class:`LocalExecutor` runs ``kind="thread"`` workers (for work that releases the GIL into the
  Rust core: the native projector's ``solve_batch`` does, rust/python/src/lib.rs ``for_chunks``)
  or ``kind="process"`` workers (spawned; for work that holds the GIL or runs torch).
* :class:`RayExecutor` runs each shard as a Ray task of one CPU (``pip install 'genplan[ray]'``).
  The functions and items are pickled; genplan must be installed on a cluster's nodes.

Ctrl-C (KeyboardInterrupt in ``map``): no new shard starts; worker processes are ended at once
(SIGINT is blocked while they are spawned and ignored in them, so a terminal's Ctrl-C, sent to
the whole process group, prints no traceback of theirs); worker
threads cannot be ended, so a long shard function polls :func:`stopping` between pieces of its
work and stops early; Ray tasks are cancelled. The KeyboardInterrupt then reaches the caller.
A worker process whose parent ended without ending it (SIGTERM, SIGKILL) exits within a second.

Failures: a shard that raises, or whose worker dies, is retried up to ``retries`` times; a
:class:`~genplan.errors.GenplanError` (the input's fault: the same on every attempt) is not
retried and stops the run. A run that cannot finish raises :class:`ShardsFailedError` naming
each failed shard and why, after the other shards finished (their results went to
``on_result``, so a resumable run keeps them). One tqdm bar counts the shards (or their
``weights``) on every executor.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import signal
import threading
import time
import traceback
from collections.abc import Callable, Iterable, Sequence
from typing import Any, TypeVar

import numpy as np

from genplan.errors import GenplanError, MissingExtraError, ShardsFailedError

__all__ = ["Executor", "LocalExecutor", "MissingExtraError", "RayExecutor", "RETRIES", "ShardsFailedError",
           "chunks", "executor", "shard_rng", "shard_seed", "stopping"]

T = TypeVar("T")
R = TypeVar("R")

#: attempts after the first for a shard that raises or whose worker dies
RETRIES = 2

RAY_HINT = "pip install 'genplan[ray]'"


def shard_seed(seed: int, index: int) -> np.random.SeedSequence:
    """The seed sequence of shard ``index`` of a run seeded ``seed``: the same as
    ``np.random.SeedSequence(seed).spawn(k)[index]`` for any k > index, and a function of
    (seed, index) only."""
    return np.random.SeedSequence(seed, spawn_key=(index,))


def shard_rng(seed: int, index: int) -> np.random.Generator:
    """The generator of shard ``index`` of a run seeded ``seed`` (:func:`shard_seed`)."""
    return np.random.default_rng(shard_seed(seed, index))


#: set while an interrupted run waits for its worker threads (:func:`stopping`)
_STOP = threading.Event()


def stopping() -> bool:
    """True while an interrupted run (Ctrl-C in :meth:`Executor.map`) waits for its worker
    threads: a long shard function polls it between pieces of its work and, when it is True,
    raises KeyboardInterrupt instead of finishing."""
    return _STOP.is_set()


def _init_worker(parent: int) -> None:
    """A worker process's initializer: Ctrl-C is the parent's to handle (it ends the workers),
    and a worker whose parent is gone (ended by SIGTERM or SIGKILL, with no chance to end its
    pool) exits within half a second instead of waiting for work forever: its task queue holds
    a writing end of its own, so it never sees the parent's end close."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="genplan-parent-watch", daemon=True).start()


def _describe(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return f"{type(exc).__name__}: {text}"[:500]


class Executor:
    """Runs ``fn(item)`` for every item on ``workers`` workers (see the module's docstring).
    Subclasses provide ``_start(fn, item) -> handle`` and ``_wait(handles) -> done handles``
    and ``_result(handle)`` (the value, or raises the shard's error)."""

    name = "executor"
    workers = 1

    def __enter__(self) -> "Executor":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def close(self) -> None:
        """Release the workers."""

    def describe(self) -> dict[str, Any]:
        """The executor as plain data (for a benchmark's or a manifest's record)."""
        return {"executor": self.name, "workers": self.workers}

    # -- to be provided by subclasses
    def _start(self, fn: Callable[[Any], Any], item: Any) -> Any:
        raise NotImplementedError

    def _wait(self, handles: list[Any]) -> list[Any]:
        raise NotImplementedError

    def _result(self, handle: Any) -> Any:
        raise NotImplementedError

    def _worker_died(self, exc: BaseException) -> bool:
        """Whether ``exc`` says the worker died (not the shard's own error)."""
        return False

    def _recover(self) -> None:
        """Make new workers after one died (a process pool breaks as a whole)."""

    def _in_flight(self) -> int:
        return self.workers

    def _interrupt(self, handles: list[Any]) -> None:
        """Stop the shards ``handles`` (running) and those not started, after a Ctrl-C."""

    def map(self, fn: Callable[[T], R], items: Sequence[T], *, desc: str = "shards", progress: bool = True,
            retries: int = RETRIES, on_result: Callable[[int, R], Any] | None = None,
            weights: Sequence[float] | None = None, unit: str = "shard") -> list[Any]:
        """``[fn(item) for item in items]`` on the workers, in the order of ``items``.

        ``on_result(index, result)``, when given, is called in this thread as each shard
        finishes, and the list holds what it returns instead of the results (so that a large
        run need not keep them). ``weights``: what each shard adds to the progress bar (default
        1, ``unit``). Raises :class:`ShardsFailedError` when a shard fails ``1 + retries`` times
        or raises a GenplanError."""
        _STOP.clear()  # a run starts unstopped (after an interrupted one whose wait was cut short)
        n = len(items)
        out: list[Any] = [None] * n
        attempts = [0] * n
        failures: dict[int, str] = {}
        pending = list(range(n))[::-1]  # popped from the end: shard 0 first
        running: dict[Any, int] = {}
        fatal: str | None = None
        from tqdm import tqdm

        total = sum(weights) if weights is not None else n
        bar = tqdm(total=total, desc=desc, unit=unit, disable=not progress, dynamic_ncols=True)
        retried = 0
        try:
            while pending or running:
                while pending and fatal is None and len(running) < self._in_flight():
                    i = pending.pop()
                    attempts[i] += 1
                    running[self._start(fn, items[i])] = i
                if not running:
                    break
                for handle in self._wait(list(running)):
                    i = running.pop(handle)
                    try:
                        value = self._result(handle)
                    except GenplanError as exc:  # the input's fault: the same on every attempt
                        failures[i] = _describe(exc)
                        fatal = fatal or f"shard {i}: {failures[i]}"
                        continue
                    except Exception as exc:  # noqa: BLE001 -- any error of a shard is retried, then reported
                        died = self._worker_died(exc)
                        why = ("its worker died: " if died else "") + _describe(exc)
                        if died:
                            self._recover()
                        if attempts[i] <= retries and fatal is None:
                            pending.append(i)
                            retried += 1
                            bar.set_postfix(retried=retried, refresh=False)
                        else:
                            failures[i] = f"{why} (after {attempts[i]} attempts)"
                            if os.environ.get("GENPLAN_DEBUG"):
                                traceback.print_exception(exc)
                        continue
                    out[i] = on_result(i, value) if on_result is not None else value
                    bar.update(weights[i] if weights is not None else 1)
        except KeyboardInterrupt:
            self._interrupt(list(running))
            raise
        finally:
            bar.close()
        if failures:
            if fatal is None:
                lines = "; ".join(f"shard {i}: {why}" for i, why in sorted(failures.items()))
                raise ShardsFailedError(f"{desc}: {len(failures)} of {n} shards failed: {lines}", failures)
            others = "; ".join(f"shard {i}: {why}" for i, why in sorted(failures.items())
                               if not fatal.startswith(f"shard {i}: "))
            raise ShardsFailedError(f"{desc}: stopped at an input error: {fatal}"
                                    + (f" (also failed: {others})" if others else ""), failures)
        return out


class LocalExecutor(Executor):
    """``workers`` local threads (``kind="thread"``) or spawned processes (``kind="process"``).
    Default: one worker per core (``os.cpu_count()``)."""

    def __init__(self, workers: int | None = None, kind: str = "thread") -> None:
        if kind not in ("thread", "process"):
            raise GenplanError(f"kind: expected 'thread' or 'process', got {kind!r}")
        if workers is not None and workers < 1:
            raise GenplanError(f"workers: expected a positive integer, got {workers}")
        self.workers = workers or os.cpu_count() or 1
        self.kind = kind
        self.name = {"thread": "local-threads", "process": "local-processes"}[kind]
        self._pool: cf.Executor | None = None

    def _make(self) -> cf.Executor:
        if self.kind == "thread":
            return cf.ThreadPoolExecutor(self.workers, thread_name_prefix="genplan-shard")
        # spawned, not forked: torch and Rust thread pools do not survive a fork
        return cf.ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context("spawn"),
                                      initializer=_init_worker, initargs=(os.getpid(),))

    def _start(self, fn: Callable[[Any], Any], item: Any) -> cf.Future:
        if self._pool is None:
            self._pool = self._make()
        if (self.kind == "thread" or not hasattr(signal, "pthread_sigmask")
                or threading.current_thread() is not threading.main_thread()):
            return self._pool.submit(fn, item)
        # A submit may spawn workers. They inherit SIGINT blocked (the mask of the thread that
        # forks them), so a terminal's Ctrl-C, sent to the whole process group, interrupts none of
        # them, even while they start. Here the Ctrl-C is held until the submit returned (another
        # thread may take the signal, so blocking it in this one is not enough: a handler that
        # records it), so that no worker is left half-started.
        held: list[int] = []
        handler = signal.signal(signal.SIGINT, lambda signum, frame: held.append(signum))
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            future = self._pool.submit(fn, item)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
            signal.signal(signal.SIGINT, handler)
        if held:
            raise KeyboardInterrupt
        return future

    def _wait(self, handles: list[Any]) -> list[Any]:
        done, _ = cf.wait(handles, return_when=cf.FIRST_COMPLETED)
        return list(done)

    def _result(self, handle: cf.Future) -> Any:
        return handle.result()

    def _worker_died(self, exc: BaseException) -> bool:
        from concurrent.futures.process import BrokenProcessPool

        return isinstance(exc, BrokenProcessPool)

    def _recover(self) -> None:
        # a broken pool fails every shard in it (each is retried); the next start makes a new one
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None

    def _interrupt(self, handles: list[Any]) -> None:
        pool, self._pool = self._pool, None
        if pool is None:
            return
        if self.kind == "process":
            # no public way to end a pool's busy workers before Python 3.14 (terminate_workers)
            for proc in list((getattr(pool, "_processes", None) or {}).values()):
                proc.terminate()
            pool.shutdown(wait=False, cancel_futures=True)
            return
        _STOP.set()  # the running shards stop at their next check (stopping())
        pool.shutdown(wait=True, cancel_futures=True)
        _STOP.clear()  # left set if a second Ctrl-C cut the wait short: the process is ending

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


def _import_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise MissingExtraError(f"--ray: Ray is not installed ({RAY_HINT})") from None
    return ray


def _call(fn: Callable[[Any], Any], item: Any) -> Any:
    """A Ray task's body (module-level: pickled by reference)."""
    return fn(item)


class RayExecutor(Executor):
    """Each shard a Ray task of one CPU. ``address="auto"``: the Ray this process already
    joined, else a local one (``workers`` CPUs, default all); any other address: that cluster
    (``ray.init(address=...)``, e.g. ``ray://host:10001``). A Ray this executor started is shut
    down by :meth:`close`."""

    def __init__(self, address: str = "auto", workers: int | None = None) -> None:
        ray = self._ray = _import_ray()
        self._started = False
        if not ray.is_initialized():
            kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": True}
            if address == "auto":
                kwargs["num_cpus"] = workers or os.cpu_count() or 1
            else:
                kwargs["address"] = address
            ray.init(**kwargs)
            self._started = True
        self.address = address
        self.workers = max(1, int(ray.cluster_resources().get("CPU", 1)))
        self.name = "ray"
        # max_retries=0: map retries (the same rule as the local executor's)
        self._task = ray.remote(num_cpus=1, max_retries=0)(_call)

    def _in_flight(self) -> int:
        return 2 * self.workers  # a queued task per CPU, so that none waits on the driver

    def _start(self, fn: Callable[[Any], Any], item: Any) -> Any:
        return self._task.remote(fn, item)

    def _wait(self, handles: list[Any]) -> list[Any]:
        done, _ = self._ray.wait(handles, num_returns=1)
        return list(done)

    def _result(self, handle: Any) -> Any:
        return self._ray.get(handle)

    def _worker_died(self, exc: BaseException) -> bool:
        from ray import exceptions as rex

        return isinstance(exc, (rex.WorkerCrashedError, rex.NodeDiedError, rex.LocalRayletDiedError))

    def _interrupt(self, handles: list[Any]) -> None:
        for handle in handles:
            try:
                self._ray.cancel(handle, force=True)
            except Exception:  # noqa: BLE001 -- a task that already ended cannot be cancelled
                pass

    def describe(self) -> dict[str, Any]:
        return {"executor": "ray", "workers": self.workers, "address": self.address,
                "ray_version": self._ray.__version__}

    def close(self) -> None:
        if self._started and self._ray.is_initialized():
            self._ray.shutdown()
        self._started = False


def executor(workers: int | None = None, ray: str | None = None, kind: str = "thread") -> Executor:
    """The executor of a command's ``--workers`` and ``--ray`` options: Ray when ``ray`` is given
    ("auto" or an address; MissingExtraError when Ray is not installed), else local."""
    if ray is not None:
        return RayExecutor(ray, workers)
    return LocalExecutor(workers, kind)


def chunks(n: int, size: int) -> list[int]:
    """The sizes of the shards of ``n`` items, ``size`` each but the last (the rest)."""
    if n < 1 or size < 1:
        raise GenplanError(f"expected positive sizes, got n={n}, size={size}")
    return [min(size, n - s) for s in range(0, n, size)]

