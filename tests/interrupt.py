"""Ctrl-C in a long native call: send SIGINT to this process while the call runs and measure how
long the KeyboardInterrupt takes to arrive (the target: 0.5 s in every batched call)."""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable
from typing import Any

#: Ctrl-C must be answered within this many seconds of the signal.
MAX_LATENCY_S = 0.5


def ctrl_c_latency(call: Callable[[], Any], after: float = 0.2) -> float:
    """Run ``call`` with Python's own SIGINT handler installed, send SIGINT ``after`` seconds in,
    and return the seconds from the signal to the KeyboardInterrupt (printed too). Fails if the
    call ends without one (then its input is too small to still be running at the signal)."""
    # Python's own Ctrl-C handler, whatever the runner inherited (a shell without job control
    # starts background jobs with SIGINT ignored, and then the signal would never arrive)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    sent: list[float] = []

    def send() -> None:
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)

    timer = threading.Timer(after, send)
    t0 = time.perf_counter()
    timer.start()
    try:
        try:
            call()
        except KeyboardInterrupt:
            got = time.perf_counter()
        else:
            raise AssertionError(f"the call ended after {time.perf_counter() - t0:.2f} s without a KeyboardInterrupt "
                                 f"(signal sent: {bool(sent)}); give it a larger input")
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, previous)
    latency = got - sent[0]
    print(f"Ctrl-C answered {latency * 1e3:.0f} ms after the signal")
    return latency
