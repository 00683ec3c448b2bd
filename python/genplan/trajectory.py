"""Time-parameterised trajectories of planned paths: ``result.trajectory()`` (genplan.planning).

A plan's dense path (every state projected onto the task's manifold and checked) is the geometric
path: a cubic spline through all its states, parameterised by joint-space arc length ``s``. Its
timing ``s(t)`` is the time-optimal one under the joint velocity and acceleration limits, computed
by TOPP-RA (native: rust/core/src/timing.rs, the model of the ``toppra`` package's TOPPRA with
joint velocity and acceleration constraints, interpolation discretisation: constant ``s''``
between grid points; cross-checked against ``toppra`` in tests/test_trajectory.py), then sampled
at ``rate_hz``:

    q = p(s),  qd = p'(s) s',  qdd = p'(s) s'' + p''(s) s'^2.

Two checks make the samples, not only the grid points, trustworthy:

* **limits**: TOPP-RA enforces the limits at its grid points; between them (and within its
  numerical tolerance) a sample may exceed them slightly. The samples are checked, and when one
  exceeds a limit the whole timing is stretched uniformly (``t -> k t``: velocities / k,
  accelerations / k^2) until none does; ``stats["time_scaling"]`` is that factor (1.0: none).
* **constraint**: a spline between two projected states leaves the manifold a little (the planner
  projects ten times tighter than the tolerance for that reason: genplan.planning.Planner). Every
  sample's residual is evaluated per primary term of the task (native, no solver step, no clipping)
  and reported (``residuals``, ``within_tolerance``); a trajectory that leaves the tolerance warns.

Grid points: every ``GRID_BASE``-th part of the path's states, plus every state where the
spline's curvature could call for more than ``GRID_CRITICAL`` of an acceleration limit at the
largest speed the velocity limits allow there (the path's corners, at its waypoints), those
corners' intervals subdivided (the grid ``toppra``'s Python loop needed to stay fast; the native
pass takes well under a millisecond on it; benchmark: ``genplan bench ik``, its trajectory part).

Files: :meth:`Trajectory.save` writes ``.npz``, ``.json`` or ``.csv`` (by suffix, atomically);
:meth:`Trajectory.load` reads them back (a CSV holds the arrays and joint names only).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan import _core
from genplan.errors import GenplanError, NonFiniteError, SettingsError, ShapeError, UnknownNameError
from genplan.robots import Robot

__all__ = ["DEFAULT_ACCELERATION_FACTOR", "FORMATS", "Trajectory", "parameterize"]

Array = NDArray[np.float64]

#: Without ``acceleration_limits`` (URDFs carry none), each joint's acceleration limit is this
#: factor times its URDF velocity limit (per second): full speed is reached in 0.5 s.
DEFAULT_ACCELERATION_FACTOR = 2.0
#: The file formats :meth:`Trajectory.save` writes, by suffix.
FORMATS = (".npz", ".json", ".csv")
#: Base grid: at most this many grid points spread evenly over the path's states.
GRID_BASE = 40
#: A state whose curvature could demand this fraction of an acceleration limit is a grid point;
#: four times as much and its intervals are split in four.
GRID_CRITICAL = 1.0


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
                "acceleration_limits": None if self.acceleration_limits is None else self.acceleration_limits.tolist()}

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
        try:
            if suffix == ".npz":
                with np.load(path, allow_pickle=False) as z:
                    meta = json.loads(str(z["meta"]))
                    arrays = {k: np.asarray(z[k], dtype=np.float64) for k in ("t", "q", "qd", "qdd")}
                return cls._from(arrays, meta)
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
            raise GenplanError(f"trajectory file {path}: not a trajectory written by Trajectory.save ({exc})") from None

    @classmethod
    def _from(cls, arrays: dict[str, Array], meta: dict[str, Any]) -> "Trajectory":
        def limits(key: str) -> Array | None:
            return None if meta.get(key) is None else np.asarray(meta[key], dtype=np.float64)

        return cls(**arrays, joint_names=tuple(meta["joint_names"]), rate_hz=float(meta["rate_hz"]),
                   velocity_limits=limits("velocity_limits"), acceleration_limits=limits("acceleration_limits"),
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
                 acceleration_limits: ArrayLike | None = None) -> Trajectory:
    """The time-optimal trajectory along ``path`` ((m, nq) states, dense: e.g. a plan's
    ``result.path``), at rest at both ends, sampled at ``rate_hz``; see the module's text.

    Args:
        robot: the robot (its URDF's velocity limits are used). Robots whose configuration has
            more numbers than velocities (a free-flyer's quaternion, continuous joints) are not
            supported yet.
        path: the states, finite, within the joint limits; consecutive duplicates are dropped.
        task: a :class:`~genplan.projection.Task` whose primary terms the samples are checked on
            (a plan's manifold), or None (no check).
        rate_hz: sampling rate (Hz).
        velocity_scale: multiplies the URDF velocity limits (e.g. 0.5).
        acceleration_scale: multiplies the acceleration limits.
        acceleration_limits: rad/s^2, one number or one per joint; default
            :data:`DEFAULT_ACCELERATION_FACTOR` (2.0) x the URDF velocity limits per second.

    Raises:
        GenplanError: a bad argument (ShapeError, NonFiniteError, SettingsError naming it), an
            unsupported robot, or TOP-RA finding no parameterisation.
    """
    if robot.nq != robot.nv:
        raise GenplanError(f"robot '{robot.name}': trajectories need as many configuration numbers as velocities "
                           f"(nq {robot.nq} != nv {robot.nv}: a free flyer or continuous joints); not supported yet")
    rate = _positive(rate_hz, "rate_hz")
    vlim, alim = joint_limits(robot, velocity_scale, acceleration_scale, acceleration_limits)
    states = robot.check_configuration(path, "path")
    if states.ndim != 2 or len(states) == 0:
        raise ShapeError(f"path: expected shape (m, {robot.nq}) with m >= 1, got {states.shape}")
    names = tuple(str(n) for n in list(robot.model.names)[1:])
    t0 = time.perf_counter()
    steps = np.linalg.norm(np.diff(states, axis=0), axis=1)
    keep = np.concatenate([[True], steps > 1e-12])
    states, steps = states[keep], steps[keep[1:]]
    if len(states) == 1:  # nothing to move: one sample at rest
        zero = np.zeros((1, robot.nv))
        traj = Trajectory(t=np.zeros(1), q=states.copy(), qd=zero, qdd=zero.copy(), joint_names=names, rate_hz=rate,
                          velocity_limits=vlim, acceleration_limits=alim, robot=robot.name,
                          stats={"parameterisation_s": time.perf_counter() - t0, "gridpoints": 1, "time_scaling": 1.0,
                                 "path_states": 1})
        return _checked(traj, robot, task)

    from scipy.interpolate import CubicSpline

    ss = np.concatenate([[0.0], np.cumsum(steps)])
    spline = CubicSpline(ss, states)  # not-a-knot, as toppra's SplineInterpolator; spline(s, order)
    grid = _gridpoints(spline, ss, vlim, alim)
    try:
        x = _core.time_optimal(grid.tolist(), spline(grid, 1), spline(grid, 2), vlim.tolist(), alim.tolist())
    except ValueError as e:
        raise GenplanError(f"trajectory: TOPP-RA found no parameterisation of the path ({len(states)} states) within "
                           f"the limits ({e})") from e
    x = np.maximum(x, 0.0)
    x[0] = x[-1] = 0.0
    ds = np.diff(grid)
    sdd = (x[1:] - x[:-1]) / (2.0 * ds)  # constant s'' per interval, consistent with x = s'^2
    sdot = np.sqrt(x)
    if np.any(sdot[:-1] + sdot[1:] <= 0.0):
        raise GenplanError("trajectory: TOPP-RA's speed profile stops inside the path; no parameterisation")
    seg_t = 2.0 * ds / (sdot[:-1] + sdot[1:])
    knots_t = np.concatenate([[0.0], np.cumsum(seg_t)])

    # the spline's coefficients as (intervals, 4, nq) for the native sampler (scipy's: (4, intervals, nq))
    coefficients = np.ascontiguousarray(np.moveaxis(spline.c, 0, 1), dtype=np.float64)
    timed = (spline.x.tolist(), coefficients, grid.tolist(), knots_t.tolist(), sdot.tolist(), sdd.tolist())

    def sample(scale: float) -> tuple[Array, Array, Array, Array]:
        # native: q = p(s(t)), qd = p'(s) s', qdd = p'(s) s'' + p''(s) s'^2 at each tick
        return _core.sample_timed_spline(*timed, rate, scale)

    scale = 1.0
    t, q, qd, qdd = sample(scale)
    for _ in range(10):  # certify the limits on the samples themselves
        over = max(float(np.max(np.abs(qd) / vlim)), math.sqrt(float(np.max(np.abs(qdd) / alim))))
        if over <= 1.0:
            break
        scale *= over * (1.0 + 1e-9)
        t, q, qd, qdd = sample(scale)
    q[0], q[-1] = states[0], states[-1]
    qd[0] = qd[-1] = 0.0
    stats = {"parameterisation_s": time.perf_counter() - t0, "gridpoints": int(len(grid)), "time_scaling": scale,
             "optimal_duration_s": float(knots_t[-1]), "path_states": int(len(states))}
    traj = Trajectory(t=t, q=q, qd=qd, qdd=qdd, joint_names=names, rate_hz=rate, velocity_limits=vlim,
                      acceleration_limits=alim, robot=robot.name, stats=stats)
    return _checked(traj, robot, task)


def _gridpoints(spline: Any, ss: Array, vlim: Array, alim: Array) -> Array:
    """TOPP-RA's grid: an even base over the states plus the states (and, where it is larger still,
    a subdivision of the intervals) whose curvature could call for a sizeable part of an
    acceleration limit at the fastest speed the velocity limits allow there."""
    d1 = np.abs(spline(ss, 1))
    d2 = np.abs(spline(ss, 2))
    s_max2 = np.min(vlim / np.maximum(d1, 1e-12), axis=1) ** 2
    need = np.max(d2 * s_max2[:, None] / alim, axis=1)
    base = np.linspace(0, len(ss) - 1, min(GRID_BASE, len(ss))).round().astype(int)
    idx = np.union1d(base, np.nonzero(need > GRID_CRITICAL)[0])
    hot = np.nonzero(np.maximum(need[:-1], need[1:]) > 4.0 * GRID_CRITICAL)[0]
    extra = (ss[hot, None] + (ss[hot + 1] - ss[hot])[:, None] * np.array([0.25, 0.5, 0.75])[None, :]).ravel()
    return np.unique(np.concatenate([ss[idx], extra]))


def _checked(traj: Trajectory, robot: Robot, task: Any) -> Trajectory:
    """``traj`` with the residual of each primary term of ``task`` over its samples."""
    if task is None:
        return traj
    from genplan.projection import GaussNewtonProjector, SolverSettings

    t0 = time.perf_counter()
    evaluator = GaussNewtonProjector(robot, task, SolverSettings(max_iterations=0, clip_to_limits=False))
    res = evaluator.solve_batch(traj.q, parallel=True).residuals  # no step: the residuals at the samples
    residuals = {k: float(np.max(v)) for k, v in res.items()}
    tolerances = {t.label(): float(t.tolerance) for t in task.primary}
    out = traj.replace(residuals=residuals, tolerances=tolerances, task=getattr(task, "name", ""),
                       stats={**traj.stats, "check_s": time.perf_counter() - t0})
    if not out.within_tolerance:
        worst = max(residuals, key=lambda k: residuals[k] / tolerances[k])
        warnings.warn(f"trajectory: its samples leave the task's tolerance (term '{worst}': residual "
                      f"{residuals[worst]:.3g} > tolerance {tolerances[worst]:.3g}); plan with a denser path "
                      "(PlannerSettings(edge_resolution=...)) or a tighter projection", stacklevel=3)
    return out
