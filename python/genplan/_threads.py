"""torch's thread count, chosen per workload for the duration of a genplan call.

torch's default (one thread per core) is slow for genplan's small batches, and on a shared machine
it is far slower: its threads wait for cores another process keeps busy, many times longer than
one thread takes for the whole batch. genplan therefore sets torch's thread count at its entry
points, for the duration of the call, and restores the caller's afterwards. The choice per
workload (:data:`POLICY`) is measured by ``benches/threads_under_load.py``
(``benches/results/threads_under_load.json``):

* ``"small"`` -- latent updates (:func:`genplan.pancake.adjust`), the seq2seq deformation and
  evaluation, GAN sampling for a query (:class:`genplan.samplers.GanSampler`): one thread.
* ``"training"`` -- training the GAN or the seq2seq model: one thread as well (a batch of 100-128
  gains little from a second thread when idle and loses much when the other core is busy).

Generating training data does not run torch (the GAN's data is projected by the native core on
all cores; the pancake inputs are numpy).

Overrides, strongest first: the ``threads=`` keyword of an entry point (``adjust(...,
threads=2)``, ``GanSampler(..., threads=2)``, ``gan.train(cfg, threads=2)``, the seq2seq config's
``threads``); the environment variable ``GENPLAN_TORCH_THREADS`` (a positive integer, for every
workload); else :data:`POLICY`.

torch's setting is process-wide. Nested calls restore the enclosing call's value; when calls
from several Python threads overlap, the last one to finish restores the value from before the
first.
"""

from __future__ import annotations

import functools
import os
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, Literal, TypeVar

from genplan.errors import SettingsError, UnknownNameError

__all__ = ["ENV", "POLICY", "Workload", "resolve", "torch_threads", "uses_torch"]

ENV = "GENPLAN_TORCH_THREADS"
Workload = Literal["small", "training"]
#: torch threads per workload (measured: benches/results/threads_under_load.json)
POLICY: dict[str, int] = {"small": 1, "training": 1}

F = TypeVar("F", bound=Callable[..., Any])

_lock = threading.Lock()
_active = 0  # calls inside torch_threads, over all Python threads
_before = 0  # torch's setting before the first of them
_local = threading.local()  # per Python thread: the values of its enclosing calls


def _positive(value: Any, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise SettingsError(f"{what} must be a positive integer, got {value!r}")
    return value


def resolve(workload: str, threads: int | None = None) -> int:
    """The torch thread count for ``workload``: ``threads`` if given, else ``$GENPLAN_TORCH_THREADS``
    if set, else :data:`POLICY`."""
    if workload not in POLICY:
        raise UnknownNameError(f"unknown torch workload {workload!r} (known: {sorted(POLICY)})")
    if threads is not None:
        return _positive(threads, "threads")
    raw = os.environ.get(ENV, "").strip()
    if raw:
        if not raw.isdigit() or int(raw) < 1:
            raise SettingsError(f"{ENV} must be a positive integer, got {raw!r}")
        return int(raw)
    return POLICY[workload]


@contextmanager
def torch_threads(workload: str, threads: int | None = None) -> Iterator[int]:
    """Run the body with :func:`resolve`'s thread count; yields it. Restores torch's setting."""
    global _active, _before
    import torch

    n = resolve(workload, threads)
    stack: list[int] = _local.__dict__.setdefault("stack", [])
    with _lock:
        current = torch.get_num_threads()
        if _active == 0:
            _before = current
        _active += 1
        stack.append(current)
        if current != n:
            torch.set_num_threads(n)
    try:
        yield n
    finally:
        with _lock:
            _active -= 1
            enclosing = stack.pop()
            restore = _before if _active == 0 else enclosing if stack else None
            if restore is not None and torch.get_num_threads() != restore:
                torch.set_num_threads(restore)


def uses_torch(workload: Workload) -> Callable[[F], F]:
    """Decorator: run the function inside :func:`torch_threads` for ``workload``, with the
    function's own ``threads`` keyword (if the caller passes one) as the override."""

    def decorate(f: F) -> F:
        @functools.wraps(f)
        def run(*args: Any, **kwargs: Any) -> Any:
            with torch_threads(workload, kwargs.get("threads")):
                return f(*args, **kwargs)

        return run  # type: ignore[return-value]

    return decorate
