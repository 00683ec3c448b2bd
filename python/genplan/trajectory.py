"""Time-parameterised trajectories of planned paths: ``result.trajectory()`` (genplan.planning).

A plan's dense path (every state projected onto the task's manifold and checked) is the geometric
path: a cubic spline through all its states, parameterised by joint-space arc length ``s``. Its
timing ``s(t)`` is the time-optimal one under the joint velocity and acceleration limits, computed
by TOPP-RA (native: rust/core/src/timing.rs, the model of the ``toppra`` package's TOPPRA with
joint velocity and acceleration constraints, interpolation discretisation: constant ``s''``
between grid points; cross-checked against ``toppra`` in tests/test_trajectory.py), then sampled
at ``rate_hz``:

    q = p(s),  qd = p'(s) s',  qdd = p'(s) s'' + p''(s) s'^2.

Every sample is checked, not only the grid points, at :data:`CHECK_RATE_HZ` at least (a lower
``rate_hz`` is sampled at the smallest multiple of it that high, checked, and every k-th sample
kept: what lies between the kept samples is checked too); a trajectory that fails a check is an
:class:`~genplan.errors.InvalidTrajectoryError` naming the first bad sample (its index, time, and
the joint, term or pair), never a trajectory:

* **joint limits**, with no tolerance: the path's states must be within them (a state outside is
  refused before any work, naming it and its joint); the not-a-knot spline through a state at a
  limit overshoots it between the states (the planner's states at a limit are clipped there, the
  spline smooths the corner: 0.74 mrad on one of the 20 default Panda shelf plans), so a joint
  beyond a limit is put on it, at rest, and with a task the sample is projected back onto the
  manifold (``stats["samples_into_limits"]``);
* **velocity and acceleration limits**: TOPP-RA enforces them at its grid points; between them
  (and within its numerical tolerance) a sample may exceed them slightly, and then the whole
  timing is stretched uniformly (``t -> k t``: velocities / k, accelerations / k^2) until none
  does; ``stats["time_scaling"]`` is that factor (1.0: none);
* **constraint**: a spline between two projected states leaves the manifold a little (the planner
  projects ten times tighter than the tolerance, and holds the chords between its states to the
  tolerance, for that reason: genplan.planning.Planner). Every sample's residual is evaluated per
  primary term of the task (native, no solver step, no clipping) and recorded (``residuals``);
* **world**: with a collision world (a plan's, ``PlanResult.world``) no sample may be in
  collision; with a checker, every sample must be ``is_valid`` (the check the path's states had).

Grid points: every ``GRID_BASE``-th part of the path's states, plus every state where the
spline's curvature could call for more than ``GRID_CRITICAL`` of an acceleration limit at the
largest speed the velocity limits allow there (the path's corners, at its waypoints), those
corners' intervals subdivided (the grid ``toppra``'s Python loop needed to stay fast).

The spline, the grid, TOPP-RA, the stretch and the samples are one native object
(``_core.TimedPath``, rust/core/src/timing.rs): the stretch evaluates the samples without storing
them and only the final ones are allocated; what remains in Python is the checks' bookkeeping and
the residual check (``_core.residual_sizes``, the most of the time on a task's path).

Files: :meth:`Trajectory.save` writes ``.npz``, ``.json`` or ``.csv`` (by suffix, atomically);
:meth:`Trajectory.load` reads them back (a CSV holds the arrays and joint names only).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan import _core
from genplan.errors import (DataFileError, GenplanError, InvalidTrajectoryError, NonFiniteError, SettingsError,
                            ShapeError, UnknownNameError)
from genplan.robots import Robot

__all__ = ["DEFAULT_ACCELERATION_FACTOR", "DEFAULT_JERK_FACTOR", "FORMATS", "Trajectory", "parameterize",
           "parameterize_jerk"]

Array = NDArray[np.float64]

#: Without ``acceleration_limits`` (URDFs carry none), each joint's acceleration limit is this
#: factor times its URDF velocity limit (per second): full speed is reached in 0.5 s.
DEFAULT_ACCELERATION_FACTOR = 2.0
#: Without ``jerk_limits`` (URDFs carry none), each joint's jerk limit in
#: :func:`parameterize_jerk` is this factor times its acceleration limit (per second): full
#: acceleration is reached in 0.1 s.
DEFAULT_JERK_FACTOR = 10.0
#: The file formats :meth:`Trajectory.save` writes, by suffix.
FORMATS = (".npz", ".json", ".csv")
#: Base grid: at most this many grid points spread evenly over the path's states.
GRID_BASE = 40
#: A state whose curvature could demand this fraction of an acceleration limit is a grid point;
#: four times as much and its intervals are split in four.
GRID_CRITICAL = 1.0
#: The least rate (Hz) the samples are checked at, whatever ``rate_hz`` the trajectory is asked
#: at: a lower rate is sampled at the smallest multiple of it at least this high, checked there,
#: and every k-th of those samples (and the end) is the trajectory. At 1 kHz consecutive samples
#: of a plan's trajectory lie an order of magnitude closer than the path's states
#: (``edge_resolution`` apart); 10 Hz samples, a few centimetres of motion apart, would let the
#: spline between them pass through an obstacle unchecked.
CHECK_RATE_HZ = 1000.0


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A time-parameterised trajectory sampled at ``rate_hz``: times ``t`` (m,), positions ``q``,
    velocities ``qd`` and accelerations ``qdd`` (m, nq), the first and last at rest.

    ``velocity_limits`` / ``acceleration_limits`` are the limits it was made for (scales applied);
    ``residuals`` the largest residual of each primary term of the task over the samples,
    ``tolerances`` the terms' tolerances; ``stats`` what it took (``parameterisation_s``: TOPP-RA
    and sampling; ``check_s``: the residual check; ``gridpoints``; ``time_scaling``)."""

    t: Array
    q: Array
    qd: Array
    qdd: Array
    joint_names: tuple[str, ...]
    rate_hz: float
    velocity_limits: Array | None = None
    acceleration_limits: Array | None = None
    residuals: dict[str, float] = field(default_factory=dict)
    tolerances: dict[str, float] = field(default_factory=dict)
    robot: str = ""
    task: str = ""
    stats: dict[str, Any] = field(default_factory=dict)
    #: The jerks (m, nq) of a jerk-limited trajectory (:func:`parameterize_jerk`; not written
    #: to files), and the jerk limits it was made for.
    qddd: Array | None = None
    jerk_limits: Array | None = None

    @property
    def duration(self) -> float:
        """Its length in seconds."""
        return float(self.t[-1])

    def __len__(self) -> int:
        return len(self.t)

    @property
    def max_velocity_ratio(self) -> float:
        """max |qd| / velocity limit over the samples and joints (<= 1)."""
        return _ratio(self.qd, self.velocity_limits)

    @property
    def max_acceleration_ratio(self) -> float:
        """max |qdd| / acceleration limit over the samples and joints (<= 1)."""
        return _ratio(self.qdd, self.acceleration_limits)

    @property
    def max_residual_ratio(self) -> float:
        """The largest residual / tolerance over the task's primary terms (<= 1: on the manifold)."""
        return max((self.residuals[k] / self.tolerances[k] for k in self.residuals if self.tolerances.get(k)),
                   default=0.0)

    @property
    def within_tolerance(self) -> bool:
        """Every sample satisfies every primary term of the task within its tolerance."""
        return all(self.residuals[k] <= self.tolerances[k] for k in self.residuals)

    def __repr__(self) -> str:
        return (f"Trajectory({len(self)} samples at {self.rate_hz:g} Hz, {self.duration:.3f} s, robot '{self.robot}', "
                f"max velocity ratio {self.max_velocity_ratio:.3f}, max residual ratio {self.max_residual_ratio:.3f})")

    # -- files -------------------------------------------------------------------------------

    def _meta(self) -> dict[str, Any]:
        return {"format": "genplan.trajectory/1", "joint_names": list(self.joint_names), "rate_hz": self.rate_hz,
                "robot": self.robot, "task": self.task, "residuals": self.residuals, "tolerances": self.tolerances,
                "stats": self.stats,
                "velocity_limits": None if self.velocity_limits is None else self.velocity_limits.tolist(),
                "acceleration_limits": None if self.acceleration_limits is None else self.acceleration_limits.tolist(),
                "jerk_limits": None if self.jerk_limits is None else self.jerk_limits.tolist()}

    def to_dict(self) -> dict[str, Any]:
        """The trajectory as plain data (the JSON file's content)."""
        return {**self._meta(), "t": self.t.tolist(), "q": self.q.tolist(), "qd": self.qd.tolist(),
                "qdd": self.qdd.tolist()}

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the trajectory to ``path``: ``.npz`` (arrays + metadata), ``.json`` (the same as
        text) or ``.csv`` (a header ``t,q_<joint>...,qd_<joint>...,qdd_<joint>...`` and one row
        per sample), by suffix; atomically (genplan._files.atomic_path). Returns ``path``."""
        from genplan._files import atomic_path, write_text

        path = Path(path)
        suffix = _suffix(path)
        if suffix == ".json":
            return write_text(path, json.dumps(self.to_dict()) + "\n")
        with atomic_path(path) as tmp:
            if suffix == ".npz":
                with open(tmp, "wb") as fh:
                    np.savez(fh, t=self.t, q=self.q, qd=self.qd, qdd=self.qdd, meta=np.array(json.dumps(self._meta())))
            else:
                header = ",".join(["t", *(f"{k}_{j}" for k in ("q", "qd", "qdd") for j in self.joint_names)])
                np.savetxt(tmp, np.column_stack([self.t, self.q, self.qd, self.qdd]), delimiter=",", header=header,
                           comments="", fmt="%.17g")
        return path

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> "Trajectory":
        """Read a file written by :meth:`save` (a CSV gives the arrays and joint names only)."""
        path = Path(path)
        suffix = _suffix(path)
        if not path.exists():
            raise FileNotFoundError(f"trajectory file {path} does not exist")
        if suffix == ".npz":
            from genplan._files import read_npz

            return cls._from_npz(read_npz(path, "trajectory file"), path)
        try:
            if suffix == ".json":
                data = json.loads(path.read_text())
                return cls._from({k: np.asarray(data[k], dtype=np.float64) for k in ("t", "q", "qd", "qdd")}, data)
            with open(path) as fh:
                header = fh.readline().strip().split(",")
            values = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
            n = (len(header) - 1) // 3
            names = [h[2:] for h in header[1:1 + n]]
            t = values[:, 0]
            rate = 1.0 / float(t[1] - t[0]) if len(t) > 1 and t[1] > t[0] else 0.0
            return cls(t=t, q=values[:, 1:1 + n], qd=values[:, 1 + n:1 + 2 * n], qdd=values[:, 1 + 2 * n:1 + 3 * n],
                       joint_names=tuple(names), rate_hz=round(rate, 6))
        except (KeyError, ValueError, IndexError) as exc:
            raise DataFileError(f"trajectory file {path}: not a trajectory written by Trajectory.save "
                                f"({exc})") from None

    @classmethod
    def _from_npz(cls, arrays: dict[str, Any], path: Path) -> "Trajectory":
        """The trajectory of the arrays of an ``.npz`` file of :meth:`save` (genplan._files.read_npz)."""
        try:
            meta = json.loads(str(arrays["meta"]))
            return cls._from({k: np.asarray(arrays[k], dtype=np.float64) for k in ("t", "q", "qd", "qdd")}, meta)
        except (KeyError, ValueError, TypeError, IndexError) as exc:
            raise DataFileError(f"trajectory file {path}: not a trajectory written by Trajectory.save "
                                f"({type(exc).__name__}: {exc})") from None

    @classmethod
    def _from(cls, arrays: dict[str, Array], meta: dict[str, Any]) -> "Trajectory":
        def limits(key: str) -> Array | None:
            return None if meta.get(key) is None else np.asarray(meta[key], dtype=np.float64)

        return cls(**arrays, joint_names=tuple(meta["joint_names"]), rate_hz=float(meta["rate_hz"]),
                   velocity_limits=limits("velocity_limits"), acceleration_limits=limits("acceleration_limits"),
                   jerk_limits=limits("jerk_limits"),
                   residuals=dict(meta.get("residuals", {})), tolerances=dict(meta.get("tolerances", {})),
                   robot=meta.get("robot", ""), task=meta.get("task", ""), stats=dict(meta.get("stats", {})))

    def replace(self, **changes: Any) -> "Trajectory":
        return dataclasses.replace(self, **changes)


def _ratio(values: Array, limits: Array | None) -> float:
    if limits is None or values.size == 0:
        return math.nan
    return float(np.max(np.abs(values) / limits))


def _suffix(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise UnknownNameError(f"path: unknown trajectory format '{path.suffix or path.name}' of {path} "
                               f"(known: {', '.join(FORMATS)})")
    return suffix


def _positive(value: float, what: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SettingsError(f"{what} must be a positive number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise SettingsError(f"{what} must be a positive number, got {value!r}")
    return v


def _limits(value: ArrayLike, n: int, what: str) -> Array:
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,):
        raise ShapeError(f"{what}: expected one number or {n} (one per joint), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise NonFiniteError(f"{what}: expected finite numbers, got {a.tolist()}")
    if not np.all(a > 0):
        raise SettingsError(f"{what}: expected positive numbers, got {a.tolist()}")
    return a


def joint_limits(robot: Robot, velocity_scale: float = 1.0, acceleration_scale: float = 1.0,
                 acceleration_limits: ArrayLike | None = None) -> tuple[Array, Array]:
    """The (velocity, acceleration) limits per joint: the URDF's velocity limits times
    ``velocity_scale``; ``acceleration_limits`` (one number or one per joint; default
    :data:`DEFAULT_ACCELERATION_FACTOR` x the URDF velocity limits) times ``acceleration_scale``."""
    vs = _positive(velocity_scale, "velocity_scale")
    acs = _positive(acceleration_scale, "acceleration_scale")
    urdf = np.asarray(robot.model.velocityLimit, dtype=np.float64)
    if not (np.all(np.isfinite(urdf)) and np.all(urdf > 0)):
        raise SettingsError(f"robot '{robot.name}': its URDF's velocity limits are not all positive and finite "
                            f"({urdf.tolist()}): a trajectory needs them")
    acc = DEFAULT_ACCELERATION_FACTOR * urdf if acceleration_limits is None else _limits(
        acceleration_limits, robot.nv, "acceleration_limits")
    return urdf * vs, acc * acs


def parameterize(robot: Robot, path: ArrayLike, task: Any = None, *, rate_hz: float = 1000.0,
                 velocity_scale: float = 1.0, acceleration_scale: float = 1.0,
                 acceleration_limits: ArrayLike | None = None, world: Any = None) -> Trajectory:
    """The time-optimal trajectory along ``path`` ((m, nq) states, dense: e.g. a plan's
    ``result.path``), at rest at both ends, sampled at ``rate_hz``; see the module's text.

    Args:
        robot: the robot (its URDF's velocity limits are used). A continuous joint is timed as
            its angle (q's [cos, sin] unwrapped along the path); a free-flying base is not
            supported yet.
        path: the states, finite, within the joint limits; consecutive duplicates are dropped.
            Any path of two or more distinct states is timed; one distinct state is a trajectory
            of one sample at rest.
        task: a :class:`~genplan.projection.Task` whose primary terms every sample must satisfy
            within their tolerances (a plan's manifold), or None (no such check).
        rate_hz: sampling rate (Hz).
        velocity_scale: multiplies the URDF velocity limits (e.g. 0.5).
        acceleration_scale: multiplies the acceleration limits.
        acceleration_limits: rad/s^2, one number or one per joint; default
            :data:`DEFAULT_ACCELERATION_FACTOR` (2.0) x the URDF velocity limits per second.
        world: what every sample must be valid in: a :class:`~genplan.collision.CollisionWorld`
            (no sample in collision) or a checker with ``is_valid(qs) -> (n,) bool`` (a plan's
            checker), or None (no such check).

    Every sample is within the joint limits, exactly (where the spline through the states would
    overshoot a limit, the joint is put on it, at rest, and with ``task`` the sample projected
    back onto the manifold: ``stats["samples_into_limits"]`` counts them), and within the
    velocity and acceleration limits; with ``task`` and ``world``, on the manifold and valid.

    Raises:
        GenplanError: a bad argument (ShapeError, NonFiniteError, SettingsError naming it; a
            ``rate_hz`` whose samples would take more than ``_core.MAX_TRAJECTORY_BYTES``), an
            unsupported robot; InvalidTrajectoryError: a state outside the joint limits, no
            parameterisation within the limits, or a sample that fails a check (naming the first
            bad state or sample).
    """
    if robot.floating_base:
        raise GenplanError(f"robot '{robot.name}': trajectories of a free-flying base (nq {robot.nq} != nv {robot.nv}) "
                           "are not supported yet")
    rate = _positive(rate_hz, "rate_hz")
    vlim, alim = joint_limits(robot, velocity_scale, acceleration_scale, acceleration_limits)
    configurations = robot.check_configuration(path, "path")
    if configurations.ndim != 2 or len(configurations) == 0:
        raise ShapeError(f"path: expected shape (m, {robot.nq}) with m >= 1, got {configurations.shape}")
    names = tuple(robot.joint_names)  # one per joint value (nv)
    # the path is timed in joint values: a continuous joint's [cos, sin] as its angle, unwrapped
    # along the path (Robot.joint_values); the samples' q are configurations again
    states = robot.joint_values(robot.normalize(configurations) if robot.continuous else configurations)
    lower, upper = _value_limits(robot)
    _check_states(states, names, lower, upper)
    t0 = time.perf_counter()
    steps = np.linalg.norm(np.diff(states, axis=0), axis=1)
    keep = np.concatenate([[True], steps > 1e-12])
    states, steps = states[keep], steps[keep[1:]]
    if len(states) == 1:  # nothing to move: one sample at rest
        zero = np.zeros((1, robot.nv))
        traj = Trajectory(t=np.zeros(1), q=robot.from_joint_values(states), qd=zero, qdd=zero.copy(), joint_names=names,
                          rate_hz=rate,
                          velocity_limits=vlim, acceleration_limits=alim, robot=robot.name,
                          stats={"parameterisation_s": time.perf_counter() - t0, "gridpoints": 1, "time_scaling": 1.0,
                                 "path_states": 1})
        return _checked(traj, robot, task, world)

    ss = np.concatenate([[0.0], np.cumsum(steps)])
    try:  # native: the not-a-knot spline through the states, the grid, TOPP-RA's speed profile
        timed = _core.TimedPath(ss.tolist(), np.ascontiguousarray(states), vlim.tolist(), alim.tolist(), GRID_BASE,
                                GRID_CRITICAL)
    except ValueError as e:
        raise InvalidTrajectoryError(f"trajectory: TOPP-RA found no parameterisation of the path ({len(states)} states) "
                                     f"within the limits ({e})") from e

    # the samples are checked at check_rate (every = 1: the asked rate itself), the trajectory is
    # every `every`-th of them and the end
    every = max(1, math.ceil(CHECK_RATE_HZ / rate - 1e-9))
    check_rate = rate * every

    def bounded(scale: float) -> str:
        # the memory the samples take at this stretch, bounded before anything is allocated
        duration = timed.duration * scale
        size = _core.sample_bytes(duration, check_rate, robot.nq)
        at = f"{rate:g} Hz" if every == 1 else f"{rate:g} Hz (checked at {check_rate:g} Hz)"
        what = f"rate_hz: a {duration:.4g} s trajectory of {robot.nq} joints at {at} needs {size / 2**30:.2f} GiB"
        if not size <= _core.MAX_TRAJECTORY_BYTES:
            raise SettingsError(f"{what}, more than the {_core.MAX_TRAJECTORY_BYTES / 2**30:.2f} GiB a trajectory may take "
                                "(lower rate_hz, or raise velocity_scale / acceleration_scale)")
        return what

    bounded(1.0)
    # the limits certified on the samples themselves, with no tolerance: the least uniform
    # stretch t -> k t that keeps every sample within them (native, samples evaluated but not
    # stored), then the samples at it: q = p(s(t)), qd = p'(s) s', qdd = p'(s) s'' + p''(s) s'^2
    scale = timed.stretch(check_rate)
    what = bounded(scale)
    try:
        t, q, qd, qdd = timed.sample(check_rate, scale)
    except SettingsError as e:  # the allocation failed (the core's own bound is the one above)
        raise SettingsError(f"{what}, which could not be allocated ({e})") from None
    q[0], q[-1] = states[0], states[-1]
    qd[0] = qd[-1] = 0.0
    q, qd, qdd, moved = _into_limits(robot, task, q, qd, qdd, lower, upper)
    q = robot.from_joint_values(q)
    stats = {"parameterisation_s": time.perf_counter() - t0, "gridpoints": int(len(timed.grid)), "time_scaling": scale,
             "optimal_duration_s": float(timed.duration), "path_states": int(len(states)), "samples_into_limits": moved,
             "check_rate_hz": check_rate}
    checked = _checked(Trajectory(t=t, q=q, qd=qd, qdd=qdd, joint_names=names, rate_hz=check_rate,
                                  velocity_limits=vlim, acceleration_limits=alim, robot=robot.name, stats=stats),
                       robot, task, world, "" if every == 1 else f" of the samples checked at {check_rate:g} Hz")
    return _every(checked, every, rate)


def _every(checked: Trajectory, every: int, rate: float) -> Trajectory:
    """The samples of ``checked`` at ``rate`` Hz, every ``every``-th of them (sampled and checked
    ``every`` times faster) and the end: a subset of checked samples."""
    if every == 1:
        return checked
    t = checked.t
    keep = np.arange(0, len(t), every)
    if t[-1] - t[keep[-1]] > 1e-9:
        keep = np.append(keep, len(t) - 1)
    return checked.replace(t=t[keep], q=checked.q[keep], qd=checked.qd[keep], qdd=checked.qdd[keep],
                           qddd=None if checked.qddd is None else checked.qddd[keep], rate_hz=rate)


def parameterize_jerk(robot: Robot, path: ArrayLike, task: Any = None, *, rate_hz: float = 1000.0,
                      velocity_scale: float = 1.0, acceleration_scale: float = 1.0, jerk_scale: float = 1.0,
                      acceleration_limits: ArrayLike | None = None, jerk_limits: ArrayLike | None = None,
                      world: Any = None, time_limit: float | None = None) -> Trajectory:
    """The jerk-limited trajectory through the states of ``path`` ((m, nq): a plan's waypoints,
    or two states for a point-to-point move) **stopping at each state**, sampled at ``rate_hz``.

    Each segment between two consecutive states is a rest-to-rest motion along the straight
    line in joint space between them (the motion the planner checked), timed by a 7-segment
    S-curve under the velocity, acceleration and jerk limits, phase-synchronised: every joint
    follows one normalised profile, the least duration any straight-line motion takes under the
    limits (native: rust/core/src/jerk.rs; within 1e-9 of ruckig's phase-synchronised duration,
    ``python benches/jerk_timing.py``). Stopping at every state is the simple, honest timing of
    a plan's waypoints: it cuts no corner the planner did not check, but a path of many states
    (a dense path) takes long; :func:`parameterize` (TOPP-RA, no jerk limit) does not stop.

    Args:
        robot, path, task, rate_hz, velocity_scale, acceleration_scale, acceleration_limits,
            world: as :func:`parameterize` (the states within the joint limits, consecutive
            duplicates dropped; every sample checked at :data:`CHECK_RATE_HZ` at least).
        jerk_limits: rad/s^3, one number or one per joint; default :data:`DEFAULT_JERK_FACTOR`
            (10.0) x the acceleration limits per second.
        jerk_scale: multiplies the jerk limits.
        time_limit: the longest the trajectory may last (seconds), or None: a longer one is a
            LimitExceededError naming it, before any sample is taken.

    Every sample is within the joint limits, the velocity, acceleration and jerk limits
    (``Trajectory.qddd``, ``jerk_limits``), with no tolerance (the profiles are built for the
    limits times 1 - 1e-9, against rounding), each state reached exactly, at rest; with ``task``
    and ``world``, on the manifold and valid. ``stats["waypoint_times"]`` holds when each state
    is reached.

    Raises:
        GenplanError: a bad argument (ShapeError, NonFiniteError, SettingsError naming it), an
            unsupported robot; LimitExceededError: longer than ``time_limit``;
            InvalidTrajectoryError: a state outside the joint limits or a sample that fails a
            check (naming the first bad state or sample).
    """
    if robot.floating_base:
        raise GenplanError(f"robot '{robot.name}': trajectories of a free-flying base (nq {robot.nq} != nv {robot.nv}) "
                           "are not supported yet")
    rate = _positive(rate_hz, "rate_hz")
    vlim, alim = joint_limits(robot, velocity_scale, acceleration_scale, acceleration_limits)
    jscale = _positive(jerk_scale, "jerk_scale")
    jlim = (DEFAULT_JERK_FACTOR * alim if jerk_limits is None else _limits(jerk_limits, robot.nv, "jerk_limits")) * jscale
    limit = None if time_limit is None else _positive(time_limit, "time_limit")
    configurations = robot.check_configuration(path, "path")
    if configurations.ndim != 2 or len(configurations) == 0:
        raise ShapeError(f"path: expected shape (m, {robot.nq}) with m >= 1, got {configurations.shape}")
    names = tuple(robot.joint_names)
    states = robot.joint_values(robot.normalize(configurations) if robot.continuous else configurations)
    lower, upper = _value_limits(robot)
    _check_states(states, names, lower, upper)
    t0 = time.perf_counter()
    keep = np.concatenate([[True], np.any(np.diff(states, axis=0) != 0.0, axis=1)])
    states = np.ascontiguousarray(states[keep])
    base: dict[str, Any] = dict(velocity_limits=vlim, acceleration_limits=alim, jerk_limits=jlim, robot=robot.name)
    if len(states) == 1:  # nothing to move: one sample at rest
        zero = np.zeros((1, robot.nv))
        traj = Trajectory(t=np.zeros(1), q=robot.from_joint_values(states), qd=zero, qdd=zero.copy(), qddd=zero.copy(),
                          joint_names=names, rate_hz=rate, **base,
                          stats={"parameterisation_s": time.perf_counter() - t0, "path_states": 1,
                                 "waypoint_times": [0.0]})
        return _checked(traj, robot, task, world)
    timed = _core.JerkPath(states, vlim.tolist(), alim.tolist(), jlim.tolist())
    if limit is not None and timed.duration > limit:
        from genplan.errors import LimitExceededError

        raise LimitExceededError(f"time_limit: the jerk-limited trajectory through the path's {len(states)} states "
                                 f"lasts {timed.duration:.4g} s, more than the {limit:g} s allowed (it stops at each "
                                 "state: fewer states, or higher limits)")
    every = max(1, math.ceil(CHECK_RATE_HZ / rate - 1e-9))
    check_rate = rate * every
    try:
        t, q, qd, qdd, qddd = timed.sample(check_rate)
    except SettingsError as e:
        raise SettingsError(f"rate_hz: a {timed.duration:.4g} s trajectory of {robot.nq} joints at {rate:g} Hz "
                            f"(checked at {check_rate:g} Hz): {e}") from None
    stats = {"parameterisation_s": time.perf_counter() - t0, "path_states": int(len(states)),
             "waypoint_times": timed.times.tolist(), "check_rate_hz": check_rate}
    checked = _checked(Trajectory(t=t, q=robot.from_joint_values(q), qd=qd, qdd=qdd, qddd=qddd, joint_names=names,
                                  rate_hz=check_rate, **base, stats=stats),
                       robot, task, world, "" if every == 1 else f" of the samples checked at {check_rate:g} Hz")
    return _every(checked, every, rate)


def _value_limits(robot: Robot) -> tuple[Array, Array]:
    """The joint limits per joint value (nv): a continuous joint has none."""
    if robot.nq == robot.nv:
        return robot.lower, robot.upper
    keep = [i for i in range(robot.nq) if i - 1 not in robot.continuous]  # a continuous joint's cos column
    return robot.lower[keep], robot.upper[keep]


def _check_states(states: Array, names: tuple[str, ...], lower: Array, upper: Array) -> None:
    """InvalidTrajectoryError naming the first state of ``states`` (joint values) outside the
    joint limits ``lower``, ``upper`` and its joint (no tolerance)."""
    out = (states < lower) | (states > upper)
    if out.any():
        i, j = (int(k) for k in np.argwhere(out)[0])
        raise InvalidTrajectoryError(f"path[{i}]: joint {j} ({names[j]}) at {states[i, j]:.6g} is outside its limits "
                                     f"[{lower[j]:.6g}, {upper[j]:.6g}]")


def _into_limits(robot: Robot, task: Any, q: Array, qd: Array, qdd: Array, lower: Array,
                 upper: Array) -> tuple[Array, Array, Array, int]:
    """The samples put within the joint limits, exactly: a joint beyond a limit is put on it, at
    rest there (its ``qd`` and ``qdd`` 0 at that sample), and with a ``task`` the sample is
    projected back onto the task's manifold within the limits (its other joints move to keep the
    constraint). Returns q, qd, qdd and how many samples were moved.

    A spline through states at a limit overshoots it between them (the states on the manifold
    clipped to the limits, the spline smooths the corner), by a fraction of a milliradian on dense
    paths and more on sparse ones. Clamping that joint alone would leave the manifold, well
    beyond the task's tolerances: the other joints compensate for it along the spline, hence the
    projection, which moves them by as little."""
    out = (q < lower) | (q > upper)
    rows = np.nonzero(out.any(axis=1))[0]
    if len(rows) == 0:
        return q, qd, qdd, 0
    q, qd, qdd = q.copy(), qd.copy(), qdd.copy()
    q[rows] = np.clip(q[rows], lower, upper)
    qd[out] = 0.0
    qdd[out] = 0.0
    if task is not None:
        # as tight as the planner projects its states; clip_to_limits (the solver's default)
        # keeps every joint within its limits
        start = robot.from_joint_values(q[rows])
        res = _evaluator(robot, task, tight=True).solve_batch(start, start, parallel=True)
        moved = robot.joint_values(res.q)
        # a continuous joint's angle back on the branch of the sample it was projected from
        moved = q[rows] + np.remainder(moved - q[rows] + np.pi, 2 * np.pi) - np.pi if robot.continuous else moved
        q[rows] = np.where(res.success[:, None], moved, q[rows])
    return q, qd, qdd, int(len(rows))


def _checked(traj: Trajectory, robot: Robot, task: Any, world: Any, where: str = "") -> Trajectory:
    """``traj`` if every sample is within the joint, velocity and acceleration limits (no
    tolerance), on the manifold of ``task`` (each primary term within its tolerance; the
    residuals are recorded) and valid in ``world``; else InvalidTrajectoryError naming the
    earliest sample that fails a check (``where`` follows its index and time), and why. The
    times taken are in ``stats["check_s"]`` (all checks) and ``stats["collision_check_s"]``."""
    t0 = time.perf_counter()
    failures: list[tuple[int, str]] = []  # per check that fails: its first sample, and why

    values = robot.joint_values(traj.q)
    lower, upper = _value_limits(robot)
    out = (values < lower) | (values > upper)
    if out.any():
        i, j = (int(k) for k in np.argwhere(out)[0])
        failures.append((i, f"is outside the limits of joint {j} ({traj.joint_names[j]}): {float(values[i, j])!r} not "
                            f"in [{float(lower[j])!r}, {float(upper[j])!r}]"))
    for what, derivative, limits in (("velocity", traj.qd, traj.velocity_limits),
                                     ("acceleration", traj.qdd, traj.acceleration_limits),
                                     ("jerk", traj.qddd, traj.jerk_limits)):
        if limits is None or derivative is None:
            continue
        over = np.abs(derivative) > limits
        if over.any():
            i, j = (int(k) for k in np.argwhere(over)[0])
            failures.append((i, f"exceeds the {what} limit of joint {j} ({traj.joint_names[j]}): |{derivative[i, j]:.6g}| > "
                                f"{limits[j]:.6g}"))
    stats = dict(traj.stats)
    if task is not None:
        res = _evaluator(robot, task).residual_sizes(traj.q)  # no step: the residuals at the samples
        tolerances = {t.label(): float(t.tolerance) for t in task.primary}
        traj = traj.replace(residuals={k: float(np.max(v)) for k, v in res.items()}, tolerances=tolerances,
                            task=getattr(task, "name", ""))
        beyond = [(int(b[0]), k) for k, v in res.items() if len(b := np.nonzero(np.asarray(v) > tolerances[k])[0])]
        if beyond:
            i, k = min(beyond)
            failures.append((i, f"is off the task's manifold: term '{k}' residual {float(res[k][i]):.3g} > tolerance "
                                f"{tolerances[k]:.3g} (plan with a denser path, PlannerSettings(edge_resolution=...), "
                                "or a tighter projection)"))
    if world is not None:
        t1 = time.perf_counter()
        invalid = _invalid_samples(world, traj.q)
        stats["collision_check_s"] = time.perf_counter() - t1
        if invalid.any():
            i = int(np.argmax(invalid))
            failures.append((i, _why_invalid(world, traj.q[i])))
    if failures:
        i, why = min(failures, key=lambda f: f[0])
        raise InvalidTrajectoryError(f"trajectory: sample {i} (t = {traj.t[i]:.3f} s){where} {why}")
    stats["check_s"] = time.perf_counter() - t0
    return traj.replace(stats=stats)


#: The projectors of the last (robot, task, tight) triples used, each with weak references to its
#: robot and task (an entry serves only while both are the objects it was built for).
_EVALUATORS: dict[tuple[int, int, bool], tuple[Any, Any, Any]] = {}
_EVALUATORS_KEPT = 8


def _evaluator(robot: Robot, task: Any, tight: bool = False) -> Any:
    """The native projector of ``task`` on ``robot`` that evaluates the samples' residuals
    (:meth:`~genplan.projection.GaussNewtonProjector.residual_sizes`), or with ``tight`` the one
    that projects samples back onto the manifold (the task's tolerances scaled by the planner's
    ``TOLERANCE_FACTOR``, as tight as it projects its states), kept for the next trajectory of
    the same task: building one binds every term (about 2 ms, as much as checking a few thousand
    samples), and a batch of trajectories shares one task."""
    import weakref

    from genplan.projection import GaussNewtonProjector

    key = (id(robot), id(task), tight)
    kept = _EVALUATORS.get(key)
    if kept is not None and kept[0]() is robot and kept[1]() is task:
        return kept[2]
    if tight:
        from genplan.planning.queries import TOLERANCE_FACTOR

        evaluator = GaussNewtonProjector(robot, task.with_tolerances_scaled(TOLERANCE_FACTOR))
    else:
        evaluator = GaussNewtonProjector(robot, task)
    if len(_EVALUATORS) >= _EVALUATORS_KEPT:
        _EVALUATORS.pop(next(iter(_EVALUATORS)), None)
    _EVALUATORS[key] = (weakref.ref(robot), weakref.ref(task), evaluator)
    return evaluator


def _invalid_samples(world: Any, q: Array) -> NDArray[np.bool_]:
    """Per sample: not valid in ``world`` (a collision world, genplan's or the native one: in
    collision; a checker: not ``is_valid``, booleans or exactly 0 / 1 as the planner reads them).

    A collision world checks every sample (``in_collision``, the check the planner's path states
    had), not certified motions between samples: checking the samples costs about as much as the
    parameterisation itself, certifying the motions between them (conservative advancement)
    several times more (``python benches/trajectory_check.py``), and at 1 kHz consecutive samples
    lie an order of magnitude closer than the path's states (checked ``edge_resolution`` apart)."""
    if hasattr(world, "in_collision"):
        return np.asarray(world.in_collision(q), dtype=bool)
    flags = np.asarray(world.is_valid(q))
    if flags.shape != (len(q),) or not (flags.dtype == bool or np.isin(flags, (0, 1)).all()):
        from genplan.errors import CallbackError

        raise CallbackError(f"{type(world).__name__}.is_valid: expected {len(q)} booleans for the trajectory's samples, "
                            f"got {flags.dtype} of shape {flags.shape}")
    return ~flags.astype(bool)


def _why_invalid(world: Any, q: Array) -> str:
    """Why the sample ``q`` is not valid in ``world``: the pairs in contact, closest first."""
    if not hasattr(world, "close_pairs"):
        return f"is not valid (the checker {type(world).__name__})"
    pairs = sorted((d, a, b) for a, b, d in world.close_pairs(list(map(float, q)), 0.0) if d <= 0)
    return ("is in collision: " + (", ".join(f"{a} and {b}" for _, a, b in pairs[:3]) or "(no pair named)")
            + " (a plan's states are checked, the motion between them only with "
              "PlannerSettings(edge_check='certified'): plan with it, or a finer edge_resolution)")
