"""Data sets on disk: a folder of shards and a ``manifest.json``, written by one run at a time,
resumed from the shards a run finished (the one definition for every kind of data set: the
configurations of :mod:`genplan.samplers.data` and the trajectories of :mod:`genplan.seq2seq.data`).

A kind of data set gives :func:`write_shards` its header (what makes two runs the same data set),
its shards (each with an ``index`` and a ``count``), the function that computes one (run on an
executor, :mod:`genplan.executor`), and how a shard is stored, verified and hashed. The writer:

* takes the folder's lock (:class:`FolderLock`, the file :data:`LOCK`): a second run into the
  same folder is refused naming the first; a lock whose process is gone (this host) is taken
  over, ``force`` takes any;
* refuses a folder holding another data set (another header: :func:`differences` names what
  differs) unless ``overwrite``, which replaces that data set's files (:data:`OWN_FILES`: the
  manifest and the shards genplan wrote, of any kind) and nothing else: they are moved aside
  (into the hidden folder :data:`REPLACED` inside ``out``: renames on one file system) and
  removed once the new run's first shard and manifest are written; a run that ends before that
  (an error, Ctrl-C) puts them back unchanged and says so, and the next run into the folder does
  the same for a run that was killed;
* keeps the shards the folder's manifest lists and that still verify (their sha256), computes the
  rest, writes each shard atomically (:mod:`genplan._files`) and rewrites the manifest as shards
  finish (at most once a second) and when the run ends, failed or not; a run that fails before
  its first shard leaves no manifest, and removes the folders it created.

:func:`load_manifest` is the reading side's shared part: the manifest of a finished data set of
one format, its shard records checked and in order.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import socket
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Protocol

from genplan._files import missing_folders, remove_empty_folders, write_text
from genplan.errors import GenplanError

__all__ = ["LOCK", "MANIFEST", "OWN_FILES", "REPLACED", "FolderLock", "write_shards", "load_manifest", "read_manifest",
           "differences", "record", "same", "shard_file"]

MANIFEST = "manifest.json"
#: the lock file of a data set folder while a run writes it: JSON ``{"run", "host", "pid",
#: "pid_start", "started", "command"}`` (see :class:`FolderLock`)
LOCK = "genplan.lock"
#: the formats of the manifests genplan writes start with one of these (a manifest of another
#: format is not genplan's, and ``overwrite`` never removes it)
FORMAT_PREFIXES = ("genplan-dataset/", "genplan-trajectories/")
#: the files of a data set folder that genplan writes (what ``overwrite`` removes): the manifest,
#: the shards (configurations: .npy; trajectories: .npz), and the temporary files of either left
#: by a killed run
OWN_FILES = re.compile(r"manifest\.json|shard_\d{5,}\.np[yz]|\.(manifest|shard_\d{5,})\..*\.tmp\.(json|np[yz])")
#: the hidden folder inside a data set folder holding the data set an ``overwrite`` run replaces,
#: until that run's first shard is written
REPLACED = ".genplan-replaced"


def shard_file(index: int, suffix: str) -> str:
    """The file name of shard ``index`` (``shard_00000.npy``, ...)."""
    return f"shard_{index:05d}{suffix}"


def same(a: Any, b: Any) -> bool:
    """Whether two JSON values are equal (key order aside)."""
    return json.dumps(a, sort_keys=True, default=str) == json.dumps(b, sort_keys=True, default=str)


# -- the folder's lock


def _process_start(pid: int) -> str | None:
    """When process ``pid`` started (Linux: /proc/PID/stat, in clock ticks since boot), or None
    where that cannot be read: told apart from a later process given the same pid."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        return stat.rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError, ValueError):
        return None


def _alive(pid: int) -> bool:
    """Whether process ``pid`` (>= 1) of this host runs."""
    try:
        os.kill(pid, 0)
    except (ProcessLookupError, OverflowError):  # OverflowError: no process has such a pid
        return False
    except PermissionError:
        return True  # another user's process
    except OSError:
        return True  # cannot tell: assume it runs
    return True


class FolderLock:
    """A data set folder's lock (:data:`LOCK`), held by one run while it writes there.

    The lock file is created whole or not at all (written under a temporary name, then hard-linked
    to :data:`LOCK`, which fails when one exists: also on NFS) and holds the run's id, host, pid,
    the pid's start time, when it started and its command. A second run is refused with a
    GenplanError naming the first (host, pid, start). A lock of this host whose process is gone
    (its pid not running, or running a process started later) is taken over with a message;
    ``force`` takes any lock (a run on another host cannot be checked from here: Ray nodes,
    shared file systems). :meth:`release` removes the lock only while it is still this run's."""

    def __init__(self, folder: Path, *, force: bool = False, log: Callable[[str], Any] = print) -> None:
        self.folder = Path(folder)
        self.path = self.folder / LOCK
        self.force = force
        self.log = log
        pid = os.getpid()
        self.record = {"run": secrets.token_hex(8), "host": socket.gethostname(), "pid": pid,
                       "pid_start": _process_start(pid),
                       "started": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
                       "command": " ".join(sys.argv)[:500]}
        self.held = False

    def __enter__(self) -> "FolderLock":
        self.acquire()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.release()

    def _create(self) -> bool:
        """Create the lock file holding this run's record; False when one exists."""
        tmp = self.folder / f".{LOCK}.{self.record['run']}.tmp"
        try:
            tmp.write_text(json.dumps(self.record, indent=1) + "\n")
            try:
                os.link(tmp, self.path)
            except FileExistsError:
                return False
            except OSError:  # a file system without hard links: an exclusive create
                try:
                    fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
                except FileExistsError:
                    return False
                with os.fdopen(fd, "w") as f:
                    f.write(tmp.read_text())
            return True
        finally:
            tmp.unlink(missing_ok=True)

    def _read(self) -> tuple[dict[str, Any] | None, bytes | None, str]:
        """(the lock's record, its bytes, why it is not a lock genplan wrote ("" when it is));
        (None, None, "") when it vanished."""
        try:
            raw = self.path.read_bytes()
        except FileNotFoundError:
            return None, None, ""
        except OSError as exc:
            return None, b"", str(exc.strerror or exc)
        try:
            rec = json.loads(raw)
        except (ValueError, UnicodeDecodeError) as exc:
            return None, raw, f"not JSON: {exc}"
        fields = {"run": str, "host": str, "started": str, "pid": int}
        if (not isinstance(rec, dict) or any(not isinstance(rec.get(k), t) or isinstance(rec.get(k), bool)
                                             for k, t in fields.items())
                or rec["pid"] < 1 or not isinstance(rec.get("pid_start"), (str, type(None)))):
            return None, raw, f"expected the fields {', '.join(fields)} (pid >= 1)"
        return rec, raw, ""

    def _gone(self, rec: dict[str, Any]) -> str:
        """Why the lock's run is known to be gone ("" when it may still run)."""
        if rec["host"] != self.record["host"]:
            return ""
        pid = rec["pid"]
        if not _alive(pid):
            return f"its process {pid} is gone"
        start = rec.get("pid_start")
        if start is not None and _process_start(pid) not in (None, start):
            return f"its process {pid} is gone (the pid now runs another process)"
        return ""

    def _take_over(self, raw: bytes) -> None:
        """Remove the lock file if it still holds ``raw``: renamed away first (only one run wins
        a rename), and put back if it was another run's newer lock."""
        grabbed = self.folder / f".{LOCK}.{self.record['run']}.old"
        try:
            os.rename(self.path, grabbed)
        except FileNotFoundError:
            return
        try:
            if grabbed.read_bytes() != raw:
                try:
                    os.link(grabbed, self.path)
                except OSError:
                    pass
        finally:
            grabbed.unlink(missing_ok=True)

    def acquire(self) -> None:
        for _ in range(5):
            if self._create():
                self.held = True
                return
            rec, raw, problem = self._read()
            if raw is None:
                continue  # released meanwhile: try again
            if problem:
                if not self.force:
                    raise GenplanError(f"{self.path}: not a genplan lock file ({problem}): if no run is writing "
                                       f"{self.folder}, remove it or rerun with --force (force=True)")
                self.log(f"taking over the unreadable lock file {self.path} (--force)")
                self._take_over(raw)
                continue
            assert rec is not None
            who = f"host {rec['host']}, pid {rec['pid']}, started {rec['started']}"
            gone = self._gone(rec)
            if not gone and not self.force:
                here = rec["host"] == self.record["host"]
                raise GenplanError(f"{self.folder} is being written by another run ({who}): "
                                   + ("wait for it to finish or give another folder (--force takes the folder "
                                      "even so)" if here else "if that run is gone, rerun with --force (force=True)"))
            self.log(f"taking over the lock of run {rec['run']} ({who}): {gone or 'forced'}")
            self._take_over(raw)
        raise GenplanError(f"{self.path}: other runs keep taking the lock; give another folder")

    def release(self) -> None:
        if not self.held:
            return
        self.held = False
        rec, _, _ = self._read()
        if rec is not None and rec.get("run") == self.record["run"]:
            self.path.unlink(missing_ok=True)



# -- manifests


def read_manifest(path: Path) -> dict[str, Any]:
    """A data set's manifest as JSON data, or GenplanError naming ``path`` when it is not one
    genplan wrote (unreadable, not JSON, no format of :data:`FORMAT_PREFIXES`)."""
    try:
        m = json.loads(Path(path).read_text())
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise GenplanError(f"{path}: not a readable data set manifest ({exc}); remove it or give another "
                           "folder") from None
    if not isinstance(m, dict) or not str(m.get("format", "")).startswith(FORMAT_PREFIXES):
        raise GenplanError(f"{path}: not a genplan data set manifest (no format "
                           f"{' or '.join(repr(p + '...') for p in FORMAT_PREFIXES)}); remove it or give another folder")
    return m


def record(m: Mapping[str, Any], key: str) -> dict[str, Any]:
    """``m[key]`` when it is a dict, else an empty one (a manifest's field read defensively)."""
    value = m.get(key)
    return value if isinstance(value, dict) else {}


def differences(old: Mapping[str, Any], header: Mapping[str, Any], keys: Sequence[str]) -> list[str]:
    """What makes the data set of manifest ``old`` another than the one of ``header``: each of
    ``keys`` whose values differ, and the robot (its record's sha256, when either has one)."""
    diffs = [f"{k} {json.dumps(old.get(k), default=str)[:80]} there, {json.dumps(header.get(k), default=str)[:80]} here"
             for k in keys if not same(old.get(k), header.get(k))]
    theirs, mine = record(old, "robot"), record(header, "robot")
    if theirs.get("sha256") != mine.get("sha256"):
        diffs.insert(0, f"robot '{theirs.get('name')}' (sha256 {str(theirs.get('sha256'))[:12]}) there, "
                        f"'{mine.get('name')}' (sha256 {str(mine.get('sha256'))[:12]}) here")
    return diffs


def _own_files(out: Path) -> list[Path]:
    """The files genplan wrote in ``out`` (:data:`OWN_FILES`), in name order."""
    return sorted(f for f in out.iterdir() if f.is_file() and OWN_FILES.fullmatch(f.name))


def _set_aside(out: Path, log: Callable[[str], Any]) -> Path:
    """Move the files genplan wrote in ``out`` (manifest, shards, their temporary files) into
    ``out / REPLACED``, and nothing else; all of them or (an error) none."""
    aside = out / REPLACED
    aside.mkdir()
    files = sorted(_own_files(out), key=lambda f: f.name != MANIFEST)  # the manifest first
    try:
        for f in files:
            os.rename(f, aside / f.name)
    except BaseException:
        _put_back(out, aside, clear=False)
        raise
    log(f"overwriting {out}: its manifest and {sum(f.name.startswith('shard_') for f in files)} shard files are "
        f"moved aside to {aside} and removed once this run's first shard is written")
    return aside


def _put_back(out: Path, aside: Path, clear: bool = True) -> int:
    """Put the data set set aside in ``aside`` back into ``out``, its manifest last
    (:func:`_set_aside` moves it first: while ``aside`` exists, a manifest in ``out`` is the
    replacing run's); with ``clear``, the files the replacing run wrote in ``out`` are removed
    first (only when all of the old set is known to be in ``aside``). Returns the count of its
    shard files."""
    if clear:
        for f in _own_files(out):
            f.unlink(missing_ok=True)
    files = sorted(aside.iterdir(), key=lambda f: f.name == MANIFEST)
    for f in files:
        os.rename(f, out / f.name)
    aside.rmdir()
    return sum(f.name.startswith("shard_") for f in files)


def _drop(aside: Path) -> None:
    """Remove the replaced data set set aside in ``aside``."""
    for f in aside.iterdir():
        f.unlink(missing_ok=True)
    aside.rmdir()


def _recover(out: Path, log: Callable[[str], Any]) -> None:
    """Finish what a killed ``overwrite`` run left in ``out``: the data set it set aside is put
    back when the run wrote no manifest (it ended before its first shard, maybe while moving the
    set aside: what it wrote is left, overwritten by the set's files of the same name), else
    removed."""
    aside = out / REPLACED
    if not aside.is_dir():
        return
    if (out / MANIFEST).is_file():
        _drop(aside)
    else:
        n = _put_back(out, aside, clear=False)
        log(f"{out}: put back the data set ({n} shard files) that an interrupted --overwrite run had moved aside to "
            f"{aside}")


def _say_put_back(exc: BaseException, text: str, log: Callable[[str], Any]) -> None:
    """Add ``text`` to the error ``exc`` that ends a run: to its message when that is its one
    string argument (as a GenplanError's), else printed with ``log``; a note either way."""
    if (isinstance(exc, Exception) and type(exc).__str__ is BaseException.__str__ and len(exc.args) == 1
            and isinstance(exc.args[0], str)):
        exc.args = (f"{exc.args[0]} ({text})",)
    else:
        log(text)
    exc.add_note(text)


class ShardSpec(Protocol):
    """What :func:`write_shards` needs of a shard: its index and size."""

    @property
    def index(self) -> int: ...

    @property
    def count(self) -> int: ...


def write_shards(out: Path, header: dict[str, Any], parts: Sequence[ShardSpec], compute: Callable[[Any], Any], *,
                 store: Callable[[Path, int, Any], dict[str, Any]],
                 verify: Callable[[Path, dict[str, Any], Any], bool],
                 digest: Callable[[Path, list[dict[str, Any]]], str],
                 keys: Sequence[str], suffix: str, desc: str, unit: str = "shard", executor: Any = None,
                 progress: bool = True, log: Callable[[str], Any] = print, overwrite: bool = False,
                 force: bool = False, finish: Callable[[dict[str, Any]], dict[str, Any]] | None = None) -> dict[str, Any]:
    """Write the data set of ``header`` and shards ``parts`` to the folder ``out`` (created if
    missing) and return its manifest (see the module's text).

    ``parts``: the shards (anything with an ``index``, its position, and a ``count``);
    ``compute(part)``: a shard's data, run on ``executor`` (default: local threads, one per
    core); ``store(out, index, data)``: writes it (atomically) and returns its manifest record
    (``index``, ``file``, ``count``, ``sha256`` and what the kind adds); ``verify(file, record,
    part)``: whether a listed shard file still holds that shard; ``digest(out, records)``: the
    whole set's sha256 from its shards in order; ``keys``: the header's fields that tell two data
    sets apart (with the robot's record); ``suffix``: the shards' file suffix; ``finish``: what
    the finished manifest adds (from the manifest). Every check of the arguments is the caller's,
    before this is called."""
    from genplan.executor import LocalExecutor
    from genplan.model_files import json_default

    header = json.loads(json.dumps(header, default=json_default))  # plain JSON, as a manifest reads back
    out = Path(out)
    created = missing_folders(out)
    out.mkdir(parents=True, exist_ok=True)
    lock = FolderLock(out, force=force, log=log)
    try:
        lock.acquire()
    except BaseException:
        remove_empty_folders(created)
        raise
    aside: Path | None = None  # where the data set this run replaces waits until its first shard
    try:
        _recover(out, log)
        path = out / MANIFEST
        done: dict[int, dict[str, Any]] = {}
        listed = False  # whether the folder holds a manifest of this data set
        if path.exists():
            old = read_manifest(path)
            diffs = differences(old, header, keys)
            if diffs and not overwrite:
                raise GenplanError(f"{out} holds another data set ({'; '.join(diffs)}): give another folder, or "
                                   "--overwrite to replace it (overwrite=True)")
            if diffs:
                aside = _set_aside(out, log)
            else:
                listed = True
                bad = 0
                records = old.get("shards")
                for rec in records if isinstance(records, list) else []:
                    rec = rec if isinstance(rec, dict) else {}
                    i, f = rec.get("index"), out / str(rec.get("file"))
                    if (type(i) is int and 0 <= i < len(parts) and f.name == shard_file(i, suffix) and f.is_file()
                            and verify(f, rec, parts[i])):
                        done[i] = rec
                    else:
                        bad += 1
                log(f"resuming {out}: {len(done)} of {len(parts)} shards finished and verified"
                    + (f", {bad} listed but missing or not matching their sha256 (recomputed)" if bad else ""))
        elif overwrite and _own_files(out):
            aside = _set_aside(out, log)
        todo = [s for s in parts if s.index not in done]
        last = [0.0]

        def manifest(complete: bool, sha: str | None = None) -> dict[str, Any]:
            return {**header, "complete": complete, "shards_done": len(done), "shards_total": len(parts),
                    "sha256": sha, "shards": [done[i] for i in sorted(done)]}

        def finished(k: int, data: Any) -> None:
            i = todo[k].index  # k: the position in todo
            nonlocal aside
            done[i] = store(out, i, data)
            if time.monotonic() - last[0] > 1.0 or aside is not None:
                write_text(path, json.dumps(manifest(False), indent=1))
                last[0] = time.monotonic()
            if aside is not None:  # this run's first shard and manifest are written: the old set goes
                _drop(aside)
                aside = None

        ex = executor or LocalExecutor()
        t0 = time.perf_counter()
        try:
            if todo:
                ex.map(compute, todo, desc=desc, progress=progress, on_result=finished,
                       weights=[s.count for s in todo], unit=unit)
        finally:
            if executor is None:
                ex.close()
            if len(done) < len(parts) and (done or listed):
                try:  # what finished, for a rerun; the run's own error is the one raised
                    write_text(path, json.dumps(manifest(False), indent=1))
                except OSError:
                    pass
        seconds = time.perf_counter() - t0
        records = [done[i] for i in sorted(done)]
        result = manifest(True, digest(out, records))
        if finish is not None:
            result.update(finish(result))
        result["last_run"] = {**ex.describe(), "shards_computed": len(todo), "seconds": seconds}
        write_text(path, json.dumps(result, indent=1, default=json_default))
        if aside is not None:  # no shard to compute: the new manifest is the first thing written
            _drop(aside)
            aside = None
        return result
    except BaseException as exc:
        if aside is not None:
            try:
                n = _put_back(out, aside)
            except OSError as put:
                _say_put_back(exc, f"the data set it was to replace could not be put back ({put}): its files are in "
                                   f"{aside}; the next run into {out} puts them back", log)
            else:
                _say_put_back(exc, f"the data set it was to replace is put back in {out} unchanged: its manifest and "
                                   f"{n} shard files", log)
        raise
    finally:
        lock.release()
        remove_empty_folders(created)  # the folders this run made, when it wrote nothing there


def load_manifest(folder: Path, fmt: str, suffix: str, command: str) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The manifest of the finished data set of format ``fmt`` in ``folder`` and its shard
    records in order (each with an int ``index``, a str ``sha256`` and the ``file``
    ``shard_file(index, suffix)``); FileNotFoundError without a manifest, GenplanError naming the
    file for anything else (``command``: what writes such a data set, for the messages)."""
    folder = Path(folder)
    path = folder / MANIFEST
    if not path.is_file():
        raise FileNotFoundError(f"{folder}: no {MANIFEST} (a data set is written by `{command}`)")
    m = read_manifest(path)
    if m.get("format") != fmt:
        raise GenplanError(f"{path}: format {m.get('format')!r}, expected {fmt!r} (a data set of `{command}`)")
    if not m.get("complete"):
        raise GenplanError(f"{folder}: an unfinished data set ({m.get('shards_done')} of {m.get('shards_total')} "
                           f"shards): rerun the `{command}` command to finish it")
    records = m.get("shards")
    if not isinstance(records, list) or not all(isinstance(r, dict) and type(r.get("index")) is int
                                                and isinstance(r.get("sha256"), str) for r in records):
        raise GenplanError(f"{path}: not a data set manifest (its shards are malformed)")
    records = sorted(records, key=lambda r: r["index"])
    if [r["index"] for r in records] != list(range(len(records))) or any(r.get("file") != shard_file(r["index"], suffix)
                                                                         for r in records):
        raise GenplanError(f"{path}: its shards are not {shard_file(0, suffix)}, {shard_file(1, suffix)}, ... in order")
    return m, records
