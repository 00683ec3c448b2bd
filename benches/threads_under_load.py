"""torch threads under load: genplan's workloads with torch's default thread count against
genplan's choice (genplan._threads.POLICY), on an idle machine and with a second process busy.

    .venv/bin/python benches/threads_under_load.py [--repeats 5] [--out benches/results/threads_under_load.json]

Workloads (each timed ``--repeats`` times after a warm-up; the median is reported):

* ``latent update``: one update of :func:`genplan.pancake.adjust` on the seq2seq paper's 27 J1
  problems, batched (shipped model, latent, adaptive step); a repeat is the median update of a
  ``--updates``-update call.
* ``gan sampling``: one ``GanSampler.sample_for`` call of 100 targets (shipped Panda GAN).
* ``gan training``: one iteration of :func:`genplan.samplers.train` (the paper's Panda configuration:
  10 members x batch 100, 5 discriminator steps); a repeat is a ``--train-iterations`` run.
* ``seq2seq training``: one optimiser step of the seq2seq model's training loop (batch 128,
  forward, backward, Adam); a repeat is the median of ``--train-iterations`` steps.

Modes: ``torch default`` (torch's own thread count, one per core) and ``genplan`` (no keyword:
genplan's policy). ``busy``: a second Python process spins on single-threaded numpy matrix
products (one core's worth of work); it is started once, paused (SIGSTOP) for the ``idle``
measurements and stopped at the end. The repeats are interleaved (each round times every
workload, load and mode once), so load from other processes on a shared machine falls on every
cell alike; the JSON records the 1-minute load average at each measurement. Prints a table and
writes the JSON (command, machine, date, every repeat).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import signal
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any
from contextlib import contextmanager
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
SPIN = """
import numpy as np
a = np.random.default_rng(0).standard_normal((200, 200))
while True:
    a = np.tanh(a @ a)
"""
#: one core's worth of work: a single-threaded BLAS in the busy process
SINGLE_THREAD_ENV = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}


@contextmanager
def busy_process() -> Iterator[Callable[[bool], None]]:
    """A second process spinning on one core for the duration (started here, stopped on exit);
    yields ``busy(on)``, which resumes (SIGCONT) or pauses (SIGSTOP) it."""
    proc = subprocess.Popen([sys.executable, "-c", SPIN], env={**os.environ, **SINGLE_THREAD_ENV})

    def busy(on: bool) -> None:
        if proc.poll() is not None:
            raise RuntimeError(f"the busy process exited with {proc.returncode}")
        proc.send_signal(signal.SIGCONT if on else signal.SIGSTOP)
        time.sleep(0.2)  # let the scheduler see the change

    try:
        time.sleep(1.0)  # let it reach its loop
        yield busy
    finally:
        proc.send_signal(signal.SIGCONT)
        proc.terminate()
        proc.wait(timeout=10)


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def workloads(args: argparse.Namespace) -> dict[str, Callable[[int | None], float]]:
    """name -> run(threads) returning the time of one unit of work (ms); threads None: genplan's
    choice."""
    import genplan
    from genplan._threads import torch_threads
    from genplan.pancake import adjust
    from genplan.pancake.data import generate_chunk
    from genplan.pancake.model import default_config as seq_config
    from genplan.pancake.model import load_model as load_seq2seq
    from genplan.pancake.trajectories import j1_problems
    from genplan.samplers.gan import default_config, load_model, train
    from genplan.samplers.sampler import GanSampler
    from genplan.seq2seq.model import Seq2SeqModel, Seq2SeqNet

    x_in, p_end = j1_problems()
    seq2seq = load_seq2seq()
    panda = genplan.load("panda")
    gan = load_model(panda)
    rng = np.random.default_rng(0)
    box = np.asarray(gan.config.target_box)
    targets = rng.uniform(box[0], box[1], size=(100, 3))
    gan_cfg = default_config("panda", iterations=args.train_iterations)
    gan_data = gan.sample(rng.uniform(box[0], box[1], size=(2000, 3)), rng)  # stands in for the projected data
    seq_cfg = seq_config()
    seq_batch = torch.as_tensor(generate_chunk(seq_cfg.batch_size, np.random.default_rng(0)))

    def latent(threads: int | None) -> float:
        res = adjust(x_in, "j1", "latent", args.updates, model=seq2seq, p_end=p_end, threads=threads)
        return 1e3 * float(np.median(res.update_times_s))

    def sampling(threads: int | None) -> float:
        sampler = GanSampler(panda, gan, seed=0, threads=threads)
        t0 = time.perf_counter()
        sampler.sample_for(targets)
        return 1e3 * (time.perf_counter() - t0)

    def gan_training(threads: int | None) -> float:
        model = train(gan_cfg, data=gan_data, progress=False, threads=threads)
        return 1e3 * model.card["training"]["seconds"] / gan_cfg.iterations

    def seq_training(threads: int | None) -> float:
        torch.manual_seed(0)
        model = Seq2SeqModel(seq_cfg, Seq2SeqNet(seq_cfg))
        opt = torch.optim.Adam(model.net.parameters(), lr=seq_cfg.lr)
        times = []
        with torch_threads("training", threads):
            for _ in range(args.train_iterations):
                t0 = time.perf_counter()
                loss, _ = model.loss(seq_batch, 0.5, seq_cfg.alpha)
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                times.append(time.perf_counter() - t0)
        return 1e3 * float(np.median(times))

    return {"latent update (27 problems)": latent, "gan sampling (100 targets)": sampling,
            "gan training (1 iteration)": gan_training, "seq2seq training (1 step, batch 128)": seq_training}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--repeats", type=int, default=5, help="timed repeats per cell (default 5)")
    p.add_argument("--updates", type=int, default=5, help="latent updates per adjust call (default 5)")
    p.add_argument("--train-iterations", type=int, default=1, help="training iterations per repeat (default 1)")
    p.add_argument("--out", type=Path, default=ROOT / "benches" / "results" / "threads_under_load.json")
    args = p.parse_args()
    if args.repeats < 5 or args.updates < 1 or args.train_iterations < 1:
        p.error("--repeats must be >= 5, --updates and --train-iterations >= 1")
    args.out.parent.mkdir(parents=True, exist_ok=True)

    from genplan._threads import ENV, POLICY

    if os.environ.get(ENV):
        p.error(f"unset {ENV}: it would override genplan's choice being measured")
    default_threads = torch.get_num_threads()
    modes = {f"torch default ({default_threads} threads)": default_threads, "genplan": None}
    work = workloads(args)
    results: list[dict[str, Any]] = [{"workload": name, "load": load, "mode": mode, "repeats_ms": [],
                                      "load_average_1min": []}
                                     for name in work for load in ("idle", "busy") for mode in modes]
    t_start = time.perf_counter()
    # Repeats are interleaved (every workload, mode and load once per round, round 0 a warm-up),
    # so that the load other processes put on the machine falls on every cell alike; "idle" has
    # the busy process paused, "busy" has it running.
    with busy_process() as busy:
        for round_ in range(args.repeats + 1):
            for name, run in work.items():
                for load in ("idle", "busy"):
                    busy(load == "busy")
                    for mode, threads in modes.items():
                        ms = run(threads)
                        if round_ == 0:
                            continue
                        row = next(r for r in results if (r["workload"], r["load"], r["mode"]) == (name, load, mode))
                        row["repeats_ms"].append(ms)
                        row["load_average_1min"].append(os.getloadavg()[0])
            print(f"  round {round_}/{args.repeats} done ({time.perf_counter() - t_start:.0f} s, 1-min load average "
                  f"{os.getloadavg()[0]:.2f})", flush=True)
    for row in results:
        row["median_ms"] = statistics.median(row["repeats_ms"])
        row["threads"] = modes[row["mode"]] or POLICY["training" if "training" in row["workload"] else "small"]

    def cell(name: str, load: str, mode: str) -> float:
        return next(float(r["median_ms"]) for r in results
                    if r["workload"] == name and r["load"] == load and r["mode"] == mode)

    default_mode, ours = list(modes)
    print()
    header = f"{'workload':38s} | {'idle, default':>13s} | {'idle, genplan':>13s} | {'busy, default':>13s} | " \
             f"{'busy, genplan':>13s} | busy/idle genplan"
    print(header)
    print("-" * len(header))
    table: list[dict[str, Any]] = []
    for name in work:
        c = {(load, mode): cell(name, load, mode) for load in ("idle", "busy") for mode in (default_mode, ours)}
        ratio = c[("busy", ours)] / c[("idle", ours)]
        table.append({"workload": name, "idle_default_ms": c[("idle", default_mode)], "idle_genplan_ms": c[("idle", ours)],
                      "busy_default_ms": c[("busy", default_mode)], "busy_genplan_ms": c[("busy", ours)],
                      "busy_over_idle_genplan": ratio})
        print(f"{name:38s} | {c[('idle', default_mode)]:10.2f} ms | {c[('idle', ours)]:10.2f} ms | "
              f"{c[('busy', default_mode)]:10.2f} ms | {c[('busy', ours)]:10.2f} ms | {ratio:5.2f}x")
    latent = table[0]
    target_met = latent["busy_over_idle_genplan"] <= 2.0
    print(f"\ntarget (latent update, busy second core, within 2x of idle): "
          f"{latent['busy_over_idle_genplan']:.2f}x -> {'met' if target_met else 'NOT met'}")
    out = {
        "command": " ".join([Path(sys.executable).name, *sys.argv]),
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": {"cpu": cpu_model(), "cores": os.cpu_count(), "platform": platform.platform(),
                    "python": platform.python_version(), "torch": torch.__version__,
                    "torch_default_threads": default_threads, "torch_parallel_backend":
                    torch.__config__.parallel_info().splitlines()[-1].strip()},
        "busy_process": "one Python process spinning on single-threaded numpy 200x200 matrix products, "
                        "paused (SIGSTOP) for the idle measurements; repeats interleaved across cells",
        "policy": dict(POLICY), "repeats": args.repeats, "updates_per_adjust": args.updates,
        "train_iterations_per_repeat": args.train_iterations, "seconds": time.perf_counter() - t_start,
        "table": table, "target_latent_busy_within_2x_of_idle": target_met, "results": results,
    }
    args.out.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
