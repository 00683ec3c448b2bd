"""The ``genplan`` command line.

Every user error (a bad argument, an output location that cannot be written, a missing or unusable
input file, any :class:`genplan.errors.GenplanError`) is one line on stderr,
``genplan: error: ...``, and exit code 2, before the command starts when the arguments alone
show it. Arguments are checked by the argparse types of :mod:`genplan._cli_args`; outputs are
checked by :func:`main` once all arguments parsed. A write that fails (disk full, quota, file
size limit, permission, read-only file system) is such an error too, naming the file: every file
is written under a temporary name and renamed when whole (:mod:`genplan._files`), so nothing is
left half-written. Ctrl-C prints ``genplan: interrupted`` and exits with code 130. A command that
fails or is interrupted removes the output folders it created, when it left them empty. Anything
else is a bug and keeps its traceback (exit code 1).
"""

from __future__ import annotations

import argparse
import errno
import importlib
import importlib.metadata
import platform
import signal
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import NoReturn

from genplan._cli_args import UsageError, check_outputs, output_actions
from genplan._files import remove_empty_folders
from genplan.errors import GenplanError

#: errors of the user's making: one line and exit code 2 (OSErrors: on a path the user gave)
USER_ERRORS = (GenplanError, FileNotFoundError, PermissionError, IsADirectoryError, NotADirectoryError)
#: errnos of an OSError that is the machine's or the user's doing, not a bug: one line and exit
#: code 2 like USER_ERRORS (a write that fails: disk full, quota, file size limit, read-only)
USER_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EACCES, errno.EPERM, errno.EROFS,
                         errno.ENOENT, errno.ENOTDIR, errno.EISDIR, errno.EEXIST, errno.ENAMETOOLONG, errno.EIO})
#: the exit code of an interrupted command (128 + SIGINT, as a shell reports it)
INTERRUPTED = 130


def _version(dist: str) -> str:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


def cmd_info(args: argparse.Namespace) -> int:
    """Print versions and the robots genplan can load."""
    import genplan
    from genplan import robots

    print(f"genplan {genplan.__version__}  (python {platform.python_version()}, {platform.machine()})")
    crates = ", ".join(f"{k} {v}" for k, v in sorted(genplan.CRATE_VERSIONS.items()))
    print(f"  rust core: {crates}")
    for dist in ("numpy", "pin", "coal", "example-robot-data", "torch", "safetensors", "ompl", "casadi", "viser"):
        print(f"  {dist:<19}{_version(dist)}")
    try:
        root = robots.robots_dir()
    except FileNotFoundError as exc:
        print(f"robots: {exc}")
        return 1
    print(f"robots ({root}):")
    status = 0
    for name in robots.ROBOT_NAMES:
        t0 = time.perf_counter()
        try:
            robot = robots.load(name)
            world = robot.collision_world()
        except Exception as exc:  # report every robot, then fail
            print(f"  {name:<6} FAILED: {exc}")
            status = 1
            continue
        ms = (time.perf_counter() - t0) * 1e3
        frames = ", ".join(f"{k}={v}" for k, v in robot.frames.items())
        print(
            f"  {name:<6} nq={robot.nq:<3} nv={robot.nv:<3} joints={len(robot.joint_names):<3}"
            f" collision geometries={len(world.geometry_names):<3} self pairs={len(world.self_pairs):<4}"
            f" loaded in {ms:.0f} ms  frames: {frames}"
        )
    return status


#: (group, name, module, help) of every command but ``info``. Each module keeps its top-level
#: imports light (no torch) and defines ``add_arguments(parser)`` and ``main(args) -> int``.
COMMANDS: list[tuple[str, str, str, str]] = [
    ("", "report", "genplan.experiments.report", "report.md from a folder of benchmark JSON (e.g. benches/results)"),
    ("", "plan", "genplan.planning.plan_cli", "one constrained plan for any robot, task and scene (JSON, HTML view)"),
    ("", "data", "genplan.gan.data_cli", "a GAN's training set as shards + manifest, on the local cores or Ray (resumable)"),
    ("", "reproduce", "genplan.experiments.reproduce", "the main job: rerun both papers' experiments with the shipped models, write a report"),
    ("bench", "robots", "genplan.experiments.benchmarks.robots", "any robot through one path: FK vs Pinocchio, collision vs coal, load time"),
    ("bench", "projection", "genplan.experiments.benchmarks.projection", "Table I: projection and IK (Gauss-Newton or scipy)"),
    ("bench", "coverage", "genplan.experiments.benchmarks.coverage", "GAN coverage: planar arm (N_net 1 vs 5), Panda/Talos ablations"),
    ("bench", "ik", "genplan.experiments.benchmarks.ik", "solve_ik on 1,000 reachable targets (5 ms budget) and 1 kHz trajectories of Panda shelf plans"),
    ("bench", "plan", "genplan.experiments.benchmarks.plan", "Table II: constrained RRT (uniform / GAN / hybrid) and OMPL"),
    ("bench", "control", "genplan.experiments.benchmarks.control", "Fig. 12: the 1 kHz spatula controller (P-D + DOB) on the simulated UR5, pancake slip"),
    ("bench", "scaling", "genplan.experiments.benchmarks.scaling", "data generation on 1 vs 2 local workers and Ray: speed-up, samples/s per core, sha256"),
    ("bench", "peers", "genplan.experiments.benchmarks.peers", "genplan beside Pinocchio + coal, pink, placo, ikpy, pytorch-kinematics: FK, collision, IK, plan time vs obstacles"),
    ("bench", "adjust", "genplan.experiments.benchmarks.adjust", "seq2seq paper Figs. 5-9, 11: latent trajectory adjustment (J1, J2) vs direct U and CasADi + IPOPT"),
    ("train", "gan", "genplan.gan.train_cli", "the conditional ensemble GAN of valid configurations"),
    ("train", "flow", "genplan.gan.flow_cli", "a conditional flow-matching sampler of valid configurations (beyond the paper)"),
    ("train", "seq2seq", "genplan.pancake.train_cli", "the pancake seq2seq trajectory deformation model"),
]


class _Parser(argparse.ArgumentParser):
    """An argparse parser whose errors are :class:`UsageError` (one line, from :func:`main`)."""

    def error(self, message: str) -> NoReturn:
        command = self.prog.removeprefix("genplan").strip()
        raise UsageError(f"{command + ': ' if command else ''}{message} (see `{self.prog} --help`)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="genplan",
        description="Learned, constraint-aware robot motion generation (GAN samplers, constrained "
        "IK and planning, latent trajectory adjustment) with a Rust core.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    p = sub.add_parser("info", help="print versions and the robots found")
    p.set_defaults(func=cmd_info)

    bench = sub.add_parser("bench", help="run a benchmark: print its table, write JSON")
    bench_sub = bench.add_subparsers(dest="benchmark", metavar="BENCHMARK", required=True)
    train = sub.add_parser("train", help="train a model (written to models/ with a JSON card)")
    train_sub = train.add_subparsers(dest="model", metavar="MODEL", required=True)
    groups = {"bench": bench_sub, "train": train_sub, "": sub}
    for group, name, module, help_text in COMMANDS:
        mod = importlib.import_module(module)
        p = groups[group].add_parser(name, help=help_text, description=mod.__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
        mod.add_arguments(p)
        p.set_defaults(func=mod.main, outputs_=output_actions(p))
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``genplan ARGV``; returns the exit code (2 and one line on stderr for a user error,
    130 and ``genplan: interrupted`` for Ctrl-C)."""
    if hasattr(signal, "SIGXFSZ") and threading.current_thread() is threading.main_thread():
        # past a file size limit (ulimit -f) a write fails with EFBIG, reported as an error, instead
        # of the signal's default action killing the process
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    created: list[Path] = []
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        if not hasattr(args, "func"):
            parser.print_help()
            return 2
        created = check_outputs(args, getattr(args, "outputs_", []))
        return int(args.func(args))
    except KeyboardInterrupt:
        remove_empty_folders(created)
        print("genplan: interrupted", file=sys.stderr)
        return INTERRUPTED
    except OSError as exc:
        if not isinstance(exc, USER_ERRORS) and exc.errno not in USER_ERRNOS:
            raise
        remove_empty_folders(created)
        print(f"genplan: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except USER_ERRORS as exc:
        remove_empty_folders(created)
        print(f"genplan: error: {_one_line(exc)}", file=sys.stderr)
        return 2


def _one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line (an OSError with its path)."""
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}"
    else:
        text = str(exc) or type(exc).__name__
    return " ".join(text.split())


if __name__ == "__main__":
    sys.exit(main())
