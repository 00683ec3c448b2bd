"""The ``genplan`` command line: one module per command (``add_arguments(parser)``, ``main(args)``),
each parsing its arguments and calling the library; :data:`COMMANDS` lists them.

Every user error (a bad argument, an output location that cannot be written, a missing or unusable
input file, any :class:`genplan.errors.GenplanError`) is one line on stderr,
``genplan: error: ...``, and exit code 2, before the command starts when the arguments alone
show it. Arguments are checked by the argparse types of :mod:`genplan.cli.args`; outputs are
checked by :func:`main` once all arguments parsed. A write that fails (disk full, quota, file
size limit, permission, read-only file system) is such an error too, naming the file: every file
is written under a temporary name and renamed when whole (:mod:`genplan._files`), so nothing is
left half-written. Ctrl-C prints ``genplan: interrupted`` and exits with code 130. A command that
ran but whose result fails its own check (no path found, a trajectory over a limit, problems not
adjusted, a robot that does not load) says so on stdout and exits with code 3
(:data:`genplan.cli.args.FAILED`).
A command that fails or is interrupted removes the output folders it created, when it left them
empty. Anything else is a bug and keeps its traceback (exit code 1).

Commands are grouped (``bench``, ``train``, ``data``: ``genplan GROUP NAME ...``). A group that
was one command before keeps its old form (:data:`FORMER_COMMANDS`): ``genplan data --robot
panda ...`` is ``genplan data configurations --robot panda ...``, told apart by the word after
the group's name (an option: the old form; a subcommand's name or ``--help``: the group's).
"""

from __future__ import annotations

import argparse
import errno
import importlib
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from genplan._files import remove_empty_folders
from genplan.cli.args import UsageError, check_outputs, output_actions
from genplan.errors import GenplanError

#: errors of the user's making: one line and exit code 2 (OSErrors: on a path the user gave)
USER_ERRORS = (GenplanError, FileNotFoundError, PermissionError, IsADirectoryError, NotADirectoryError)
#: errnos of an OSError that is the machine's or the user's doing, not a bug: one line and exit
#: code 2 like USER_ERRORS (a write that fails: disk full, quota, file size limit, read-only)
USER_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EACCES, errno.EPERM, errno.EROFS,
                         errno.ENOENT, errno.ENOTDIR, errno.EISDIR, errno.EEXIST, errno.ENAMETOOLONG, errno.EIO})
#: the exit code of an interrupted command (128 + SIGINT, as a shell reports it)
INTERRUPTED = 130


#: (group, name, module, help) of every command, in the order ``genplan --help`` lists them (a
#: group where its first command stands). Each
#: module keeps its top-level imports light (no torch) and defines ``add_arguments(parser)`` and
#: ``main(args) -> int``: the library's commands are modules of this package, the benchmarks
#: modules of :mod:`genplan.experiments`.
COMMANDS: list[tuple[str, str, str, str]] = [
    ("", "info", "genplan.cli.info", "print versions and the robots found"),
    ("bench", "robots", "genplan.experiments.benchmarks.robots", "any robot through one path: FK vs Pinocchio, collision vs coal, load time"),
    ("bench", "projection", "genplan.experiments.benchmarks.projection", "Table I: projection and IK (Gauss-Newton or scipy)"),
    ("bench", "coverage", "genplan.experiments.benchmarks.coverage", "GAN coverage: planar arm (N_net 1 vs 5), Panda/Talos ablations"),
    ("bench", "ik", "genplan.experiments.benchmarks.ik", "solve_ik on 1,000 reachable targets (5 ms budget) and 1 kHz trajectories of Panda shelf plans"),
    ("bench", "plan", "genplan.experiments.benchmarks.plan", "Table II: constrained RRT (uniform / GAN / hybrid) and OMPL"),
    ("bench", "control", "genplan.experiments.benchmarks.control", "Fig. 12: the 1 kHz spatula controller (P-D + DOB) on the simulated UR5, pancake slip"),
    ("bench", "scaling", "genplan.experiments.benchmarks.scaling", "data generation on 1 vs 2 local workers and Ray: speed-up, samples/s per core, sha256"),
    ("bench", "peers", "genplan.experiments.benchmarks.peers", "genplan beside Pinocchio + coal, pink, placo, ikpy, pytorch-kinematics: FK, collision, IK, plan time vs obstacles"),
    ("bench", "adjust", "genplan.experiments.benchmarks.adjust", "seq2seq paper Figs. 5-9, 11: latent trajectory adjustment (J1, J2) vs direct U and CasADi + IPOPT"),
    ("bench", "adapt", "genplan.experiments.benchmarks.adapt", "a learned family adapted to new goals and obstacles: latent vs direct, replanning, ProMP"),
    ("bench", "motion", "genplan.experiments.benchmarks.motion", "free-space Panda plans on MotionBenchMaker-style families beside VAMP: success, plan and simplify ms, path length"),
    ("train", "gan", "genplan.cli.train_gan", "the conditional ensemble GAN of valid configurations"),
    ("train", "flow", "genplan.cli.train_flow", "a conditional flow-matching sampler of valid configurations (beyond the paper)"),
    ("train", "seq2seq", "genplan.cli.train_seq2seq", "a seq2seq model of a trajectory data set (--data), or the pancake's"),
    ("", "report", "genplan.experiments.report", "report.md, or with --benchmarks docs/BENCHMARKS.md, from a folder of benchmark JSON (benches/results)"),
    ("", "plan", "genplan.cli.plan", "one constrained plan for any robot, task and scene (JSON, HTML view)"),
    ("data", "configurations", "genplan.cli.data", "a GAN's training set as shards + manifest, on the local cores or Ray "
                                                   "(resumable; also `genplan data --robot ...`)"),
    ("data", "trajectories", "genplan.cli.data_trajectories", "a family of planned trajectories (a seq2seq model's "
                                                              "training set) as shards + manifest (resumable)"),
    ("", "reproduce", "genplan.experiments.reproduce", "the main job: rerun both papers' experiments with the shipped models, write a report"),
    ("", "view", "genplan.cli.view", "plan a query of a paper environment and write its 3D view (one HTML file, offline)"),
    ("", "adjust", "genplan.cli.adjust", "adjust trajectories to an objective in a seq2seq model's latent space, "
                                         "then project, check and time them"),
    ("", "execute", "genplan.cli.execute", "run a trajectory on the simulated robot at 1 kHz (P-D + DOB): tracking, torques, limits"),
]


#: the command groups: help, and what a group's subcommand is called
GROUPS = {"bench": ("run a benchmark: print its table, write JSON", "benchmark"),
          "train": ("train a model (written to models/ with a JSON card)", "model"),
          "data": ("write a data set as shards + manifest: configurations (a learned sampler's) or trajectories "
                   "(a seq2seq model's)", "dataset")}
#: groups that were one command before: their old form (options right after the group's name,
#: ``genplan data --robot panda ...``) runs this subcommand (``genplan data configurations ...``)
FORMER_COMMANDS = {"data": "configurations"}


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
    groups: dict[str, Any] = {"": sub}
    for group, name, module, help_text in COMMANDS:
        if group not in groups:
            what = GROUPS[group]
            groups[group] = sub.add_parser(group, help=what[0]).add_subparsers(dest=what[1], metavar=what[1].upper(),
                                                                                required=True)
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
        args = parser.parse_args(_former_form(list(sys.argv[1:] if argv is None else argv)))
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


def _former_form(argv: list[str]) -> list[str]:
    """``argv`` with a group's former single-command form (:data:`FORMER_COMMANDS`) spelled as
    its subcommand: ``data --robot panda ...`` -> ``data configurations --robot panda ...``. The
    word after the group decides: an option other than ``-h``/``--help`` is the former form; a
    subcommand's name, help or nothing is the group's."""
    if len(argv) >= 2 and argv[0] in FORMER_COMMANDS and argv[1].startswith("-") and argv[1] not in ("-h", "--help"):
        return [argv[0], FORMER_COMMANDS[argv[0]], *argv[1:]]
    return argv


def _one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line (an OSError with its path)."""
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}"
    else:
        text = str(exc) or type(exc).__name__
    return " ".join(text.split())

