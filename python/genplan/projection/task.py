"""Tasks as data: a :class:`Task` is a primary list of terms (all must hold) and a secondary
list solved in the primary's null space, with an optional :class:`Condition` (the term a learned
sampler is conditioned on and the box its targets are drawn from). A task reads from and writes
to its plain form and a task file (TOML, docs/TASKS.md) of built-in terms (:data:`TERM_KINDS`)
and Python terms (``kind = "python"``: a :class:`CustomTerm` subclass by its importable name and
parameters, imported only with ``allow_python=True``); shipped task files are in
``genplan/presets/tasks`` (:func:`task_names`, :func:`load_task`).
What a learned sampler does with a task: :func:`condition_term`, :func:`manifold_task`."""

from __future__ import annotations

import dataclasses
import fnmatch
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from genplan._arrays import as_float_array
from genplan.errors import GenplanError, SettingsError, TaskFileError, UnknownNameError
from genplan.projection.base import CURRENT, Term, _is_current
from genplan.projection.com import ComBox
from genplan.projection.custom import CustomTerm
from genplan.projection.frame import FrameOrientation, FramePose, FramePosition, Plane, PointAt
from genplan.projection.joints import JointLimits, Posture
from genplan.projection.relative import RelativePose, RelativePosition
from genplan.robots import Robot


@dataclass(frozen=True)
class Task:
    """A primary list of terms (all must be satisfied) and an optional secondary list solved in
    the primary's null space (typically a :class:`Posture`)."""

    primary: Sequence[Term]
    secondary: Sequence[Term] = ()
    name: str = "task"
    #: The term whose target a sampler is conditioned on, and the box its targets are drawn from
    #: (training data is projected without that term; IK sets its target per query).
    condition: "Condition | None" = None

    @property
    def python_terms(self) -> tuple[CustomTerm, ...]:
        """Its terms written in Python (:class:`CustomTerm`, primary and secondary): they hold the
        GIL while they run, so data generation runs them in processes, each importing them by
        their entry (see :func:`python_term_entry`)."""
        return tuple(t for t in [*self.primary, *self.secondary] if isinstance(t, CustomTerm))

    @property
    def free(self) -> bool:
        """Its only constraint is the joint limits (every primary term a :class:`JointLimits`):
        free space, which needs no projection (the shipped ``free`` task is one). A planner
        projects nothing for it; its checker holds the limits."""
        return all(isinstance(t, JointLimits) for t in self.primary)

    def to_dict(self) -> dict[str, Any]:
        """The task as plain data (the task file's tables; see docs/TASKS.md)."""
        out: dict[str, Any] = {"name": self.name}
        out["primary"] = [_term_to_dict(t) for t in self.primary]
        if self.secondary:
            out["secondary"] = [_term_to_dict(t) for t in self.secondary]
        if self.condition is not None:
            c = self.condition
            out["condition"] = {"term": c.term, "low": [float(x) for x in c.low], "high": [float(x) for x in c.high]}
            if c.sample_low is not None and c.sample_high is not None:
                out["condition"]["sample_low"] = [float(x) for x in c.sample_low]
                out["condition"]["sample_high"] = [float(x) for x in c.sample_high]
            if c.manifold is not None:
                out["condition"]["manifold"] = c.manifold
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], robot: Robot | None = None, origin: str = "task", *,
                  allow_python: bool = False) -> "Task":
        """A task from plain data (:meth:`to_dict`'s form); ``robot`` resolves values given as
        ``"default"`` (a frame's placement or the posture at the robot's default configuration)
        and joint-name patterns (``joint_weights = {"arm_left_*" = 1.0}``), and is a python term's
        ``robot`` field. A python term (``kind = "python"``) is imported only with
        ``allow_python=True``; without it, TaskFileError naming the table and the entry."""
        return _task_from_dict(data, robot, origin, allow_python)

    def to_file(self, path: str | os.PathLike[str]) -> Path:
        """Write the task as a task file (TOML), atomically; :meth:`from_file` reads it back."""
        from genplan._files import write_text

        return write_text(path, _toml(self.to_dict()))

    @classmethod
    def from_file(cls, path: str | os.PathLike[str], robot: Robot | None = None, *,
                  allow_python: bool = False) -> "Task":
        """Read a task file (TOML); errors name the file, the table and the key. A file's python
        term (``kind = "python"``, ``entry = "module:Class"``) imports and runs that module's code:
        it is read only with ``allow_python=True`` (the commands' ``--allow-python``), else
        TaskFileError naming the file, the table and the entry."""
        from genplan._files import read_toml

        path = Path(path)
        data = read_toml(path, "task", TaskFileError)
        task = _task_from_dict(data, robot, f"task file {path}", allow_python)
        c = task.condition
        if c is not None and c.manifold is not None and c.manifold not in task_names() and not Path(c.manifold).is_absolute():
            # a manifold task given as a file: relative to this task file
            task = dataclasses.replace(task, condition=dataclasses.replace(c, manifold=str(path.parent / c.manifold)))
        return task

    def with_targets(self, **targets: Any) -> "Task":
        """A copy whose terms named in ``targets`` get that ``target`` (e.g. ``hand_position=p``)."""
        names = {t.name for t in [*self.primary, *self.secondary]}
        unknown = set(targets) - names
        if unknown:
            raise UnknownNameError(f"task '{self.name}' has no term named {sorted(unknown)} (terms: {sorted(n for n in names if n)})")

        def swap(terms: Sequence[Term]) -> tuple[Term, ...]:
            return tuple(dataclasses.replace(t, target=targets[t.name]) if t.name in targets else t for t in terms)

        return dataclasses.replace(self, primary=swap(self.primary), secondary=swap(self.secondary))

    def at_configuration(self, robot: Robot, q: Any) -> "Task":
        """A copy whose terms with ``target = "current"`` (FramePose, FramePosition,
        FrameOrientation, RelativePose, RelativePosition) get the target their frame meets at
        ``q``: e.g. a two-arm grip held as it is at the start of a plan. Such a term is refused by
        the solvers until then (SettingsError)."""
        q = robot.check_configuration(q, "q")

        def resolve(terms: Sequence[Term]) -> tuple[Term, ...]:
            return tuple(dataclasses.replace(t, target=_placement_target(type(t), robot, q, t.frame, getattr(t, "relative_to", "")))
                         if isinstance(t, _PLACED) and _is_current(t.target) else t for t in terms)

        return dataclasses.replace(self, primary=resolve(self.primary), secondary=resolve(self.secondary))

    def with_tolerances_scaled(self, factor: float) -> "Task":
        """A copy whose primary terms' tolerances are multiplied by ``factor`` (e.g. 0.1: project
        ten times tighter than the constraint, so the straight chord between two nearby projected
        states still satisfies it)."""
        if not (np.isfinite(factor) and factor > 0):
            raise SettingsError(f"factor must be positive, got {factor}")
        return dataclasses.replace(
            self, primary=tuple(dataclasses.replace(t, tolerance=t.tolerance * factor) for t in self.primary))


@dataclass(frozen=True)
class Condition:
    """The term a sampler is conditioned on (its ``target`` varies per query, so the term may
    leave it out: see :class:`GaussNewtonProjector`) and the box its targets are drawn from
    (``low``, ``high``: as many numbers as the target)."""

    term: str
    low: tuple[float, ...]
    high: tuple[float, ...]
    #: where a sampler draws targets when a planner asks for configurations without one (default:
    #: ``low`` / ``high``)
    sample_low: tuple[float, ...] | None = None
    sample_high: tuple[float, ...] | None = None
    #: the task (shipped name or file, relative to this task file) whose manifold a sampler's
    #: training data covers; default: this task without the condition term
    manifold: str | None = None

    def middle(self) -> tuple[float, ...]:
        """The middle of the box, ``(low + high) / 2``."""
        return tuple(0.5 * (lo + hi) for lo, hi in zip(self.low, self.high))


#: The built-in term kinds, by the name a task file's ``kind`` gives.
TERM_KINDS: dict[str, type[Term]] = {c.__name__: c for c in (FramePose, FramePosition, FrameOrientation, RelativePose,
                                                            RelativePosition, PointAt, Plane, Posture, JointLimits,
                                                            ComBox)}
#: Presets: the task files shipped with genplan (their stem is the name).
TASKS_DIR = Path(__file__).parent.parent / "presets" / "tasks"


def task_names() -> tuple[str, ...]:
    """The shipped task files' names (``panda_projection``, ``talos_ik``, ...)."""
    return tuple(sorted(p.stem for p in TASKS_DIR.glob("*.toml")))


def load_task(task: "str | os.PathLike[str] | Task", robot: Robot | None = None, *, allow_python: bool = False) -> Task:
    """A task: a :class:`Task` as is, a shipped task's name (:func:`task_names`) or a task file
    (its python terms read only with ``allow_python=True``: :meth:`Task.from_file`)."""
    if isinstance(task, Task):
        return task
    if isinstance(task, str) and task in task_names():
        return Task.from_file(TASKS_DIR / f"{task}.toml", robot)
    path = Path(task)
    if path.suffix != ".toml" and not path.exists():
        raise UnknownNameError(f"unknown task '{task}' (shipped: {', '.join(task_names())}; or a task file .toml)")
    return Task.from_file(path, robot, allow_python=allow_python)


def default_task_name(robot: Robot) -> str:
    """The task of ``robot`` when none is named (a GAN's, a scene's queries'): the shipped
    ``<robot>_ik``, else a SettingsError asking for one."""
    name = f"{robot.name}_ik"
    if name not in task_names():
        raise SettingsError(f"robot '{robot.name}' has no shipped task: give one (a task file with a [condition], "
                            f"see docs/TASKS.md; shipped tasks: {', '.join(task_names())})")
    return name


def condition_term(task: Task) -> FramePosition:
    """The task's condition term, which a sampler is conditioned on: a FramePosition (3 target
    numbers, the sampler's input), else GenplanError naming the task and the term."""
    if task.condition is None:
        raise GenplanError(f"task '{task.name}' has no [condition]: a learned sampler is conditioned on a "
                           "term's target (e.g. [condition] term = \"hand_position\" with low/high boxes); see "
                           "docs/TASKS.md")
    for t in task.primary:
        if t.name == task.condition.term:
            if not isinstance(t, FramePosition):
                raise GenplanError(f"task '{task.name}': its condition term '{t.name}' is a {type(t).__name__}; a "
                                   "learned sampler is conditioned on a FramePosition (a 3-D target)")
            if len(task.condition.low) != 3:
                raise GenplanError(f"task '{task.name}': its condition box needs 3 numbers per corner, got "
                                   f"{len(task.condition.low)}")
            return t
    names = [t.name for t in task.primary]
    raise UnknownNameError(f"task '{task.name}': condition term '{task.condition.term}' is not one of its primary "
                           f"terms (known: {names})")


def unset_condition_term(task: Task) -> str | None:
    """The name of ``task``'s condition term when it leaves its target out (each query sets it),
    else None."""
    c = task.condition
    term = None if c is None else next((t for t in task.primary if t.name == c.term), None)
    return term.name if term is not None and getattr(term, "target", 0) is None else None


def manifold_task(task: Task, robot: Robot | None = None) -> Task:
    """The manifold a learned sampler covers (its training data is projected onto it): the task
    named by the condition's ``manifold`` when given (the paper's projection task, whose weights
    and tolerances differ from its IK task's), else the task without its condition term."""
    cond = condition_term(task)
    assert task.condition is not None
    if task.condition.manifold is not None:
        return load_task(task.condition.manifold, robot)
    primary = tuple(t for t in task.primary if t.name != cond.name)
    if not primary:
        raise GenplanError(f"task '{task.name}': without its condition term '{cond.name}' no primary term is left")
    return dataclasses.replace(task, primary=primary, condition=None)


def _plain(v: Any) -> Any:
    """A term field as TOML-able data (None stays None: the field is left out)."""
    if isinstance(v, pin.SE3):
        return v.homogeneous.tolist()
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (tuple, list)):
        return [_plain(x) for x in v]
    if isinstance(v, Mapping):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    return v


def _term_to_dict(t: Term) -> dict[str, Any]:
    kind = type(t).__name__
    if isinstance(t, CustomTerm):
        return _python_term_to_dict(t)
    if TERM_KINDS.get(kind) is not type(t):
        raise TaskFileError(f"term '{t.label()}': {kind} is not a built-in term kind (known: {', '.join(TERM_KINDS)})")
    out: dict[str, Any] = {"kind": kind}
    for f in dataclasses.fields(t):
        v = _plain(getattr(t, f.name))
        if v is None or v == {} or (f.name == "name" and v == ""):
            continue
        out[f.name] = v
    return out


#: The terms whose target is a frame's placement (in the world, or in another frame's).
_PLACED = (FramePose, FramePosition, FrameOrientation, RelativePose, RelativePosition)


def _placement_target(cls: type[Term], robot: Robot, q: Any, frame: str, relative_to: str) -> Any:
    """The target of a ``cls`` term that its frame meets at ``q``: the frame's placement (an SE3,
    its position or its rotation), in ``relative_to``'s frame for a relative term."""
    m = robot.frame_placement(q, frame)
    if cls in (RelativePose, RelativePosition):
        m = robot.frame_placement(q, relative_to).actInv(m)
    return m.translation.copy() if cls in (FramePosition, RelativePosition) else m.rotation.copy() if cls is FrameOrientation else m


def _need_robot(robot: Robot | None, where: str, what: str) -> Robot:
    """``robot``, or TaskFileError: ``what`` (a robot-relative value) cannot be read without it."""
    if robot is None:
        raise TaskFileError(f"{where}: {what} needs the robot (pass robot= when reading the task)")
    return robot


def _term_from_dict(d: Mapping[str, Any], robot: Robot | None, where: str, allow_python: bool = False) -> Term:
    if not isinstance(d, Mapping):
        raise TaskFileError(f"{where}: expected a table, got {type(d).__name__}")
    kind = d.get("kind")
    if kind == PYTHON_KIND:
        return _python_term_from_dict(d, robot, where, allow_python)
    cls = TERM_KINDS.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise TaskFileError(f"{where}: unknown term kind {kind!r} (known: {', '.join(TERM_KINDS)}, or "
                            f"{PYTHON_KIND!r}: a CustomTerm by its entry)")
    names = [f.name for f in dataclasses.fields(cls)]
    fields: dict[str, Any] = {}
    for key, v in d.items():
        if key == "kind":
            continue
        if key not in names:
            raise TaskFileError(f"{where}: {kind} has no field '{key}' (fields: {', '.join(names)})")
        if v == "default" and key in ("target", "q_nom"):
            r = _need_robot(robot, where if key == "q_nom" else f"{where} target", "'default'")
            if key == "q_nom":
                v = r.q_default.copy()
            else:
                v = _placement_target(cls, r, r.q_default, str(d.get("frame", "")), str(d.get("relative_to", "")))
        elif v == CURRENT and key == "target" and cls in _PLACED:
            pass  # resolved by Task.at_configuration
        elif key == "joint_weights" and isinstance(v, Mapping):  # joint-name patterns -> nv weights
            robot = _need_robot(robot, where, "joint_weights by joint name")
            w = np.zeros(robot.nv)
            for pattern, weight in v.items():
                hit = [j for j in robot.joint_names if fnmatch.fnmatchcase(j, pattern)]
                if not hit:
                    raise UnknownNameError(f"{where}: joint_weights pattern '{pattern}' matches no joint of robot '{robot.name}'")
                for j in hit:
                    w[robot.model.joints[robot.model.getJointId(j)].idx_v] = float(weight)
            v = w
        elif key in ("axes", "components", "axis", "normal") and isinstance(v, list):
            v = tuple(float(x) for x in v)
        elif isinstance(v, list):
            v = as_float_array(v, f"{where} {key}")
        fields[key] = v
    try:
        return cls(**fields)
    except TypeError as exc:
        raise TaskFileError(f"{where}: {exc}") from None


def _task_from_dict(data: Mapping[str, Any], robot: Robot | None, origin: str, allow_python: bool = False) -> Task:
    known = ("name", "primary", "secondary", "condition")
    for key in data:
        if key not in known:
            raise TaskFileError(f"{origin}: unknown key '{key}' (known: {', '.join(known)})")
    primary = data.get("primary")
    if not isinstance(primary, list) or not primary:
        raise TaskFileError(f"{origin}: needs at least one [[primary]] term")
    secondary = data.get("secondary", [])
    if not isinstance(secondary, list):
        raise TaskFileError(f"{origin}: 'secondary' must be a list of [[secondary]] tables")
    terms = [tuple(_term_from_dict(t, robot, f"{origin}: [[{group}]] {i + 1}", allow_python) for i, t in enumerate(items))
             for group, items in (("primary", primary), ("secondary", secondary))]
    condition = None
    if "condition" in data:
        c = data["condition"]
        optional = {"sample_low", "sample_high", "manifold"}
        if not isinstance(c, Mapping) or not {"term", "low", "high"} <= set(c) <= {"term", "low", "high"} | optional:
            raise TaskFileError(f"{origin}: [condition] needs the keys term, low, high (optional: "
                                f"{', '.join(sorted(optional))}), got {sorted(c) if isinstance(c, Mapping) else c!r}")
        names = [t.name for t in terms[0]]
        if c["term"] not in names:
            raise UnknownNameError(f"{origin}: [condition] term '{c['term']}' is not a primary term (terms: {', '.join(names)})")

        def box(lo_key: str, hi_key: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
            low = as_float_array(c[lo_key], f"{origin}: [condition] {lo_key}").ravel()
            high = as_float_array(c[hi_key], f"{origin}: [condition] {hi_key}").ravel()
            if low.shape != high.shape or np.any(low > high) or not np.all(np.isfinite(low) & np.isfinite(high)):
                raise TaskFileError(f"{origin}: [condition] {lo_key} and {hi_key} must be finite, of one length, "
                                    f"{lo_key} <= {hi_key}")
            return tuple(map(float, low)), tuple(map(float, high))

        low, high = box("low", "high")
        sample_low = sample_high = None
        if ("sample_low" in c) != ("sample_high" in c):
            raise TaskFileError(f"{origin}: [condition] give both sample_low and sample_high, or neither")
        if "sample_low" in c:
            sample_low, sample_high = box("sample_low", "sample_high")
            if len(sample_low) != len(low):
                raise TaskFileError(f"{origin}: [condition] sample_low has {len(sample_low)} numbers, low {len(low)}")
        manifold = c.get("manifold")
        if manifold is not None and not isinstance(manifold, str):
            raise TaskFileError(f"{origin}: [condition] manifold must be a task name or file, got {manifold!r}")
        condition = Condition(str(c["term"]), low, high, sample_low, sample_high, manifold)
    for group, items in (("primary", terms[0]), ("secondary", terms[1])):
        for i, t in enumerate(items):
            if (isinstance(t, (FramePosition, FramePose, RelativePosition, RelativePose)) and t.target is None
                    and not (group == "primary" and condition is not None and t.name == condition.term)):
                which = f"the [condition] term '{condition.term}'" if condition is not None else "a [condition] term"
                raise TaskFileError(f"{origin}: [[{group}]] {i + 1} ('{t.label()}'): {type(t).__name__} needs a target "
                                    f"(only {which} may leave it out: each query sets it)")
    return Task(primary=terms[0], secondary=terms[1], name=str(data.get("name", "task")), condition=condition)


#: The ``kind`` of a task file's python term: a :class:`CustomTerm` subclass by its ``entry``.
PYTHON_KIND = "python"
#: A python term's field that is the task's robot: left out of its ``params``, given the robot the
#: task is read with.
ROBOT_FIELD = "robot"
#: The fields every term has, written beside ``entry`` rather than in ``params``.
_TERM_FIELDS = tuple(f.name for f in dataclasses.fields(Term))


def python_term_entry(term: CustomTerm) -> str:
    """The importable name (``"module:Class"``) a task file, a model card and a data worker give
    ``term``'s class; TaskFileError saying why when it has none (a class defined in ``__main__``
    or inside a function can be used in this process, not rebuilt in another)."""
    from genplan._entries import entry_of

    entry, why = entry_of(type(term))
    if entry is None:
        raise TaskFileError(f"term '{term.label()}': {why}; a task file, a model card and a data-generation worker "
                            f"rebuild a python term by importing its class: define {type(term).__name__} in an "
                            "importable module (a .py file on the Python path)")
    return entry


def _python_term_to_dict(t: CustomTerm) -> dict[str, Any]:
    """A python term's plain form: ``kind = "python"``, its ``entry``, the subclass's own fields
    as ``params`` (plain data; a None field left out, its default applies), and ``weight``,
    ``tolerance``, ``name`` as every term has them. Its ``robot`` field is not written: the
    task's robot fills it when the task is read."""
    entry = python_term_entry(t)
    out: dict[str, Any] = {"kind": PYTHON_KIND, "entry": entry}
    params: dict[str, Any] = {}
    fields = dataclasses.fields(t) if dataclasses.is_dataclass(t) else ()
    for f in fields:
        if f.name in _TERM_FIELDS or f.name == ROBOT_FIELD:
            continue
        v = _plain(getattr(t, f.name))
        if v is None:
            continue
        if not _is_plain(v):
            raise TaskFileError(f"term '{t.label()}' ({entry}): field '{f.name}' holds a {type(getattr(t, f.name)).__name__}, "
                                "which a task file cannot hold (numbers, strings, booleans, lists and tables of them): a "
                                "python term is rebuilt from its entry and params")
        params[f.name] = v
    out["params"] = params
    for name in _TERM_FIELDS:
        v = _plain(getattr(t, name))
        if not (name == "name" and v == ""):
            out[name] = v
    return out


def _is_plain(v: Any) -> bool:
    if isinstance(v, (bool, int, float, str)):
        return True
    if isinstance(v, list):
        return all(_is_plain(x) for x in v)
    if isinstance(v, Mapping):
        return all(isinstance(k, str) and _is_plain(x) for k, x in v.items())
    return False


def _frozen(v: Any) -> Any:
    """A param as the term's field gets it: lists as tuples (a frozen dataclass stays hashable)."""
    if isinstance(v, list):
        return tuple(_frozen(x) for x in v)
    if isinstance(v, Mapping):
        return {k: _frozen(x) for k, x in v.items()}
    return v


def _python_term_from_dict(d: Mapping[str, Any], robot: Robot | None, where: str, allow_python: bool) -> CustomTerm:
    """A python term read back: its entry imported (only with ``allow_python``), checked to be
    a CustomTerm subclass, made with its params (and the task's robot for its ``robot`` field)."""
    entry = d.get("entry")
    if not allow_python:
        raise TaskFileError(f"{where}: a python term (entry {entry!r}) imports and runs that module's code; read the "
                            "task with allow_python=True (on the command line: --allow-python) to use it")
    extra = sorted(set(d) - {"kind", "entry", "params", *_TERM_FIELDS})
    if extra:
        raise TaskFileError(f"{where}: unknown key(s) {extra} (a python term holds entry, params, "
                            f"{', '.join(_TERM_FIELDS)})")
    from genplan._entries import import_entry

    cls = import_entry(entry, f"{where} entry", TaskFileError, "module:Class")
    if not (isinstance(cls, type) and issubclass(cls, CustomTerm)):
        raise TaskFileError(f"{where}: entry {entry!r} is {cls!r}, not a genplan.projection.CustomTerm subclass")
    params = d.get("params", {})
    if not isinstance(params, Mapping):
        raise TaskFileError(f"{where}: params must be a table, got {type(params).__name__}")
    kwargs: dict[str, Any] = {k: _frozen(v) for k, v in params.items()}
    if any(k in _TERM_FIELDS or k == ROBOT_FIELD for k in kwargs):
        raise TaskFileError(f"{where}: params may not hold {', '.join(_TERM_FIELDS)} (keys of the term's table) nor "
                            f"'{ROBOT_FIELD}' (the task's robot)")
    names = {f.name for f in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) else set()
    if ROBOT_FIELD in names:
        kwargs[ROBOT_FIELD] = _need_robot(robot, where, f"{entry}'s '{ROBOT_FIELD}' field")
    kwargs.update({k: d[k] for k in _TERM_FIELDS if k in d})
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as exc:
        raise TaskFileError(f"{where}: {entry}({', '.join(sorted(kwargs))}): {exc}") from None


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if np.isfinite(v) else ("nan" if np.isnan(v) else ("inf" if v > 0 else "-inf"))
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a TOML basic string
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{json.dumps(str(k))} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TaskFileError(f"cannot write {type(v).__name__} to a task file")


def _toml(data: Mapping[str, Any]) -> str:
    """The TOML text of a task's plain data (:meth:`Task.to_dict`)."""
    lines = [f"name = {_toml_value(data['name'])}"]
    if "condition" in data:
        lines += ["", "[condition]"] + [f"{k} = {_toml_value(v)}" for k, v in data["condition"].items()]
    for group in ("primary", "secondary"):
        for t in data.get(group, []):
            lines += ["", f"[[{group}]]"] + [f"{k} = {_toml_value(v)}" for k, v in t.items()]
    return "\n".join(lines) + "\n"
