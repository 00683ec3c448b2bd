"""Argument types and output checks of the ``genplan`` commands (one definition for all of them,
the library's commands in :mod:`genplan.cli` and the benchmarks' in :mod:`genplan.experiments`).

Each command's ``add_arguments(parser)`` uses these as argparse ``type=``: a bad value is an
argparse error naming the option before anything runs. Output locations (:data:`output_file`,
:data:`output_folder`) are checked by ``genplan.cli.main`` after every argument parsed and before
the command starts (:func:`check_outputs`): the folder is created if missing (the commands' writers
do the same) and a temporary file is created and removed in it, so a read-only or impossible place
fails in a fraction of a second instead of after the work. A command whose output has a computed
default checks it itself, first, with :func:`check_output_file` / :func:`check_output_folder`;
a training command's model file goes through :func:`model_output`, which refuses any place inside
the installed package (its shipped models are never written by a command).
User errors found inside a command raise :class:`UsageError`; ``genplan.cli.main`` prints any
:class:`~genplan.errors.GenplanError` as one line and exits with code 2.
"""

from __future__ import annotations

import argparse
import math
import os
import secrets
import sys
from pathlib import Path
from typing import Any

from genplan._files import missing_folders, remove_empty_folders
from genplan.errors import GenplanError
from genplan.model_files import inside_package, package_dir

#: the exit code of a command that ran but whose result fails its own check (no path, a
#: trajectory over a limit, a problem not adjusted): not 1, which a bug's traceback exits with
FAILED = 3

#: largest seed the commands accept (numpy, torch and the Rust samplers all take it)
MAX_SEED = 2**32 - 1


class UsageError(GenplanError):
    """A command line genplan cannot run: a bad argument or combination of arguments, or an
    output location that cannot be written; the message names the option."""


def _int(text: str, what: str, lo: int, hi: int | None = None) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
    if value < lo or (hi is not None and value > hi):
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """An integer >= 1."""
    return _int(text, "a positive integer", 1)


#: the most held-out targets a card's evaluation takes (``--eval-targets``): its arrays grow with
#: the count (targets, samples and the solver's results per start), and the rates it reports
#: are settled long before (the default is 500)
MAX_EVAL_TARGETS = 100_000


def eval_targets(text: str) -> int:
    """The held-out targets of a card's evaluation: an integer in 1..:data:`MAX_EVAL_TARGETS`
    (checked while the arguments are read, before any training)."""
    return _int(text, f"an integer in 1..{MAX_EVAL_TARGETS:,}", 1, MAX_EVAL_TARGETS)


def non_negative_int(text: str) -> int:
    """An integer >= 0."""
    return _int(text, "an integer >= 0", 0)


def seed(text: str) -> int:
    """A seed: an integer in 0..2^32 - 1."""
    return _int(text, f"a seed in 0..{MAX_SEED}", 0, MAX_SEED)


def seed_range(text: str) -> range:
    """Seeds ``A..B`` (both included, A <= B) or one seed ``A``: a range of seeds."""
    first, sep, last = text.partition("..")
    what = f"seeds A..B (A <= B, each in 0..{MAX_SEED})"
    try:
        lo = _int(first.strip(), what, 0, MAX_SEED)
        hi = _int(last.strip(), what, 0, MAX_SEED) if sep else lo
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
    if hi < lo:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return range(lo, hi + 1)


def ray_address(text: str) -> str:
    """``auto`` (the Ray this process joined, else a local one) or a Ray cluster's address
    (``host:port`` or ``ray://host:port``)."""
    text = text.strip()
    if text != "auto" and (not text or any(c.isspace() for c in text) or ":" not in text):
        raise argparse.ArgumentTypeError(f"expected 'auto' or a Ray address (host:port, ray://host:port), got {text!r}")
    return text


def add_executor_arguments(p: argparse.ArgumentParser, workers_help: str) -> None:
    """``--workers K`` and ``--ray auto|ADDRESS``: where a command's shards run
    (:func:`genplan.executor.executor`)."""
    p.add_argument("--workers", type=positive_int, default=None, help=workers_help)
    p.add_argument("--ray", type=ray_address, default=None, metavar="auto|ADDRESS",
                   help="run the shards on Ray: 'auto' (a local Ray with --workers CPUs, or the one already "
                        "running) or a cluster's address; needs pip install 'genplan[ray]'")


def _float(text: str, what: str, ok: Any) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
    if not (math.isfinite(value) and ok(value)):
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    return _float(text, "a finite number > 0", lambda x: x > 0)


def non_negative_float(text: str) -> float:
    """A finite number >= 0."""
    return _float(text, "a finite number >= 0", lambda x: x >= 0)


def share(text: str) -> float:
    """A number in [0, 1] (a share of something)."""
    return _float(text, "a share in [0, 1]", lambda x: 0 <= x <= 1)


def existing_file(text: str) -> Path:
    """An input file that exists."""
    path = Path(text)
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text}: {'is a folder, not a file' if path.is_dir() else 'no such file'}")
    return path


def existing_folder(text: str) -> Path:
    """An input folder that exists."""
    path = Path(text)
    if not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: {'is a file, not a folder' if path.exists() else 'no such folder'}")
    return path


class Output:
    """The argparse type of an output location (``kind``: "file" or "folder"): a Path, checked
    by :func:`check_outputs` once every argument parsed."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self.__name__ = f"output {kind}"  # argparse names the type in some messages

    def __call__(self, text: str) -> Path:
        if not text:
            raise argparse.ArgumentTypeError(f"expected an output {self.kind}, got ''")
        return Path(text)

    def check(self, path: Path, what: str) -> Path:
        return check_output_file(path, what) if self.kind == "file" else check_output_folder(path, what)


output_file = Output("file")
output_folder = Output("folder")


def check_output_folder(path: Path, what: str, *, of: Path | None = None) -> Path:
    """Create ``path`` if missing and make sure a file can be written in it, else raise
    :class:`UsageError` naming ``what`` (the option) and why. ``of``: the file it is the folder
    of, for the message."""
    path = Path(path)
    where = f"{what} {of if of is not None else path}: "
    folder = f"the folder {path}" if of is not None else "the folder"
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise UsageError(f"{where}{folder} is a file") from None
    except OSError as exc:
        raise UsageError(f"{where}cannot create {folder} ({exc.strerror or exc})") from None
    probe = path / f".genplan-write-test-{os.getpid()}-{secrets.token_hex(4)}"
    try:
        probe.touch(exist_ok=False)
        probe.unlink()
    except OSError as exc:
        raise UsageError(f"{where}cannot write in {folder} ({exc.strerror or exc})") from None
    return path


def check_output_file(path: Path, what: str) -> Path:
    """An output file's location: not a folder, and its folder writable (created if missing)."""
    path = Path(path)
    if path.is_dir():
        raise UsageError(f"{what} {path}: is a folder, not a file")
    check_output_folder(path.parent, what, of=path)
    return path


def _elsewhere(name: str) -> str:
    """``name`` in the current folder, or in the home folder when the current one lies inside
    the package: a place to suggest for a model file."""
    return name if not inside_package(name) else str(Path.home() / name)


def model_output(out: Path | None, default: Path) -> Path:
    """The model file a training command writes: ``--out`` as given, or ``default`` when it is
    None and ``default`` lies outside the installed package; checked as :func:`check_output_file`
    does. The package's files (the shipped models, which every default use loads) are never
    written by a command: without ``--out`` when the default lies inside it, or with an ``--out``
    inside it, :class:`UsageError` naming ``--out`` and suggesting a path elsewhere."""
    if out is None:
        if not inside_package(default):
            return check_output_file(default, "--out")
        raise UsageError(f"--out: give the model's path, e.g. --out {_elsewhere(default.name)} (the default, "
                         f"{default}, is a model shipped inside the installed genplan package, which training "
                         "never overwrites)")
    if inside_package(out):
        raise UsageError(f"--out {out}: inside the installed genplan package ({package_dir()}), whose shipped "
                         f"models training never overwrites; write elsewhere, e.g. --out {_elsewhere(Path(out).name)}")
    return Path(out)


def announce_replacement(paths: list[Path]) -> None:
    """One line on stderr when any of the model files ``paths`` (written as .safetensors plus a
    .json card) exists: it is replaced once its new model is complete, and kept until then."""
    found = [p for p in (Path(p).with_suffix(".safetensors") for p in paths)
             if p.exists() or p.with_suffix(".json").exists()]
    if found:
        what = f"{found[0]} exists" if len(found) == 1 else f"{len(found)} models exist ({found[0]}, ...)"
        print(f"genplan: {what}: replaced once the new model is complete (kept until then)", file=sys.stderr)


def output_actions(parser: argparse.ArgumentParser) -> list[tuple[str, str, Output]]:
    """(dest, option, type) of every output argument of ``parser``."""
    return [(a.dest, a.option_strings[0] if a.option_strings else a.dest, a.type)
            for a in parser._actions if isinstance(a.type, Output)]


def check_outputs(args: argparse.Namespace, actions: list[tuple[str, str, Output]]) -> list[Path]:
    """Check every output location given in ``args`` (see :func:`output_actions`); returns the
    folders the checks created, deepest first (a command that fails removes those left empty)."""
    created: list[Path] = []
    for dest, option, out in actions:
        value = getattr(args, dest, None)
        for path in value if isinstance(value, list) else [value]:
            if path is not None:
                created += missing_folders(path if out.kind == "folder" else Path(path).parent)
                try:
                    out.check(Path(path), option)
                except BaseException:
                    remove_empty_folders(sorted(created, key=lambda p: len(p.parts), reverse=True))
                    raise
    return sorted(created, key=lambda p: len(p.parts), reverse=True)


def add_model_out(p: argparse.ArgumentParser) -> None:
    """``--out``: the model file a training command writes (checked by :func:`model_output`)."""
    p.add_argument("--out", type=output_file, default=None,
                   help="model path (required: the shipped models in the installed package are never overwritten; "
                        "folders are created; an existing model is replaced once the new one is complete)")


def add_robot_and_task(p: argparse.ArgumentParser, task_default: str | None, *, task_required: bool = False) -> None:
    """``--robot`` and ``--task``, one definition for every command that takes them;
    ``task_default``: what a missing ``--task`` means (for the help), None when it is required."""
    p.add_argument("--robot", required=True,
                   help="a preset name (genplan info lists them), a robot file (.toml) or a URDF")
    p.add_argument("--task", required=task_required, default=None,
                   help="a task with a [condition]: a shipped task's name or a task file (.toml)"
                        + ("" if task_default is None else f"; default: {task_default}"))


def add_allow_python(p: argparse.ArgumentParser, option: str = "--task") -> None:
    """``--allow-python``: the ``option`` file's python terms (``kind = "python"``, ``entry =
    "module:Class"``: a task's, :meth:`genplan.projection.Task.from_file`, or an objective's,
    :func:`genplan.seq2seq.load_objective`) are imported only with it, since importing runs that
    module's code (their ``allow_python``)."""
    p.add_argument("--allow-python", action="store_true",
                   help=f"read the {option} file's python terms (kind = \"python\", entry = \"module:Class\"): this "
                        "imports and runs that module's code (without it, such a file is refused)")
