"""Execute a plan on any fixed-base robot at 1 kHz: the seq2seq paper's P-D + disturbance-observer
loop (Kutsuzawa et al. 2019, Section 5, Fig. 10), simulated in Rust.

    log = genplan.execute(robot, trajectory)          # a Trajectory (PlanResult.trajectory()) or (t, q)

Every tick (``dt``, 1 ms by default) the controller measures the simulated robot, computes
``tau = M_n(q) qdd_ref + h_n(q, v) + tau_dis_hat`` on its nominal model (the robot's URDF and the
payload it is told about) and the plant (the same robot with what the model lacks: joint
friction, torque offsets, an unknown payload: :class:`Disturbances`) runs one period under it
(RK4). The whole run is native: no Python per tick, Ctrl-C answered within a fraction of a
second.

* the controller (:class:`ControllerSettings`): task space on any frame (default: the robot's
  tool frame; ``axes`` leaves task axes free, as the task terms do; a redundant arm follows its
  reference's joint motion in the null space) or joint space (``space="joint"``), P-D gains per
  axis, the observer and its cut-off;
* what the robot holds (``payload=``, a :class:`Payload`: mass, centre of mass, inertia on a
  link; the controller knows it) and what it does not know (``Disturbances(payload=...)``);
* the joint limits (:class:`JointLimits`, default the URDF's): every tick's torque and speed
  are checked; ``policy`` "saturate" (default: the torque is clipped, as a drive does, and the
  ticks are logged), "log" or "stop"; before the run, the reference's positions and speeds
  (errors) and its inverse-dynamics torques (a :class:`LimitWarning`, or with ``strict=True`` a
  :class:`~genplan.errors.LimitExceededError`).

The log (:class:`ExecutionLog`) has, per tick, the joint and tool-frame tracking errors,
torques, the observer's estimate, limit ratios and the compute time; its maxima; the executed
motion checked against a collision world and a task's constraints when given; ``log.save`` writes
it (``.npz``, atomically). The command line: ``genplan execute`` (:mod:`genplan.cli.execute`).
The pancake experiment is one configuration of the same loop: :mod:`genplan.pancake.control`.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan import _core
from genplan._arrays import as_configurations, as_float_array, as_real
from genplan._execution import (ARRAYS, MAX_RUN_BYTES, MAX_SETTLE_S, MAX_TICKS, CollisionWarning, ExecutionLog,
                                LimitWarning, check_run_size, seconds, ticks)
from genplan.errors import GenplanError, LimitExceededError, NonFiniteError, SettingsError, ShapeError, UnknownNameError

ControllerSettings = _core.ControllerSettings
Disturbances = _core.Disturbances
Payload = _core.Payload
JointLimits = _core.JointLimits
RunSummary = _core.RunSummary

__all__ = [
    "ARRAYS", "ControllerSettings", "Disturbances", "Payload", "JointLimits", "RunSummary", "ExecutionLog", "LimitWarning",
    "CollisionWarning", "execute", "joint_reference", "joint_values", "from_joint_values", "tool_frame", "frame_link",
    "MAX_TICKS", "MAX_RUN_BYTES", "MAX_SETTLE_S", "SETTLE_S",
]

Array = NDArray[np.float64]

#: the roles tried, in order, for a robot's tool frame
TOOL_ROLES = ("tool", "tcp", "ee", "hand")


def _typed(value: Any, cls: type, what: str) -> Any:
    if not isinstance(value, cls):
        raise SettingsError(f"{what}: expected a {cls.__name__}, got {type(value).__name__} {value!r}")
    return value


def tool_frame(robot: Any) -> str:
    """The link of a robot's tool frame: its first role of :data:`TOOL_ROLES` ("tool", "tcp",
    "ee", "hand"), else its last link."""
    for role in TOOL_ROLES:
        if role in robot.frames:
            return str(robot.frames[role])
    return str(robot.kinematics.link_names[-1])


def frame_link(robot: Any, frame: str | None, what: str = "controller.frame") -> str:
    """The link of ``frame`` (a role such as "hand", a link name, or None: :func:`tool_frame`);
    UnknownNameError naming ``what`` for another name."""
    if frame is None:
        return tool_frame(robot)
    name = robot.frames.get(frame, frame)
    if name not in robot.kinematics.link_names:
        raise UnknownNameError(f"{what}: robot '{robot.name}' has no frame '{frame}' (roles: "
                               f"{', '.join(robot.frames) or 'none'}; or any link name)")
    return str(name)


# ---------------------------------------------------------------------------------------------
# the reference: a Trajectory, or q(t), at the control period
# ---------------------------------------------------------------------------------------------

def joint_values(robot: Any, q: Array) -> Array:
    """Configurations (n, nq) as joint values (n, nv): :meth:`genplan.robots.Robot.joint_values`."""
    return robot.joint_values(q)  # type: ignore[no-any-return]


def from_joint_values(robot: Any, x: Array) -> Array:
    """The inverse of :func:`joint_values`: :meth:`genplan.robots.Robot.from_joint_values`."""
    return robot.from_joint_values(x)  # type: ignore[no-any-return]


def _times(t: Any, n: int) -> Array:
    times = as_float_array(t, "trajectory.t")
    if times.shape != (n,):
        raise ShapeError(f"trajectory.t: expected {n} times (one per row of trajectory.q), got shape {times.shape}")
    if not np.all(np.isfinite(times)):
        raise NonFiniteError(f"trajectory.t: element {int(np.argmax(~np.isfinite(times)))} is not finite")
    if n > 1 and not np.all(np.diff(times) > 0):
        i = int(np.argmax(np.diff(times) <= 0)) + 1
        raise ShapeError(f"trajectory.t: times must increase, but t[{i}] = {times[i]} <= t[{i - 1}] = {times[i - 1]}")
    return times


def joint_reference(robot: Any, trajectory: Any, dt: float, *,
                    settle_ticks: int = 0) -> tuple[Array, Array, Array, Array]:
    """The reference ``(t, q, qd, qdd)`` every ``dt`` of ``trajectory``: a
    :class:`genplan.trajectory.Trajectory` (its joints must be the robot's), a mapping with
    ``t`` and ``q`` (optionally ``qd``, ``qdd``), or a tuple ``(t, q)`` / ``(t, q, qd)``.

    Samples already every ``dt`` with their velocities and accelerations are used as they are;
    otherwise a cubic spline through the samples (Hermite through their velocities when given;
    else clamped: at rest at both ends) is sampled every ``dt`` from the first time to the last,
    continuous joints on their circle. Errors name the field (ShapeError: another robot's joint
    count or times that do not increase; NonFiniteError); a run of the reference's ticks and
    ``settle_ticks`` longer than :data:`MAX_TICKS`, or whose log and reference would take more
    than :data:`MAX_RUN_BYTES`, is a SettingsError naming the trajectory's duration and the bound,
    before the reference is allocated."""
    from genplan.trajectory import Trajectory

    qd_in: Any = None
    qdd_in: Any = None
    if isinstance(trajectory, Trajectory):
        names = tuple(robot.joint_names)
        if trajectory.joint_names and tuple(trajectory.joint_names) != names:
            raise ShapeError(f"trajectory: made for the joints {list(trajectory.joint_names)}, not robot "
                             f"'{robot.name}' ({list(names)})")
        t, q_in, qd_in, qdd_in = trajectory.t, trajectory.q, trajectory.qd, trajectory.qdd
    elif isinstance(trajectory, Mapping):
        if "t" not in trajectory or "q" not in trajectory:
            raise ShapeError(f"trajectory: a mapping needs 't' and 'q', got keys {sorted(trajectory)}")
        t, q_in, qd_in, qdd_in = trajectory["t"], trajectory["q"], trajectory.get("qd"), trajectory.get("qdd")
    elif isinstance(trajectory, (tuple, list)) and len(trajectory) in (2, 3):
        t, q_in = trajectory[0], trajectory[1]
        qd_in = trajectory[2] if len(trajectory) == 3 else None
    else:
        raise ShapeError(f"trajectory: expected a Trajectory, (t, q) arrays or a mapping with 't' and 'q', got "
                         f"{type(trajectory).__name__}")
    q = as_configurations(q_in, robot.nq, "trajectory.q")
    if q.ndim != 2:
        raise ShapeError(f"trajectory.q: expected shape (n, {robot.nq}), got {q.shape}")
    q = robot.normalize(q) if robot.nq != robot.nv else q
    times = _times(t, len(q))
    qd = None if qd_in is None else as_configurations(qd_in, robot.nv, "trajectory.qd")
    qdd = None if qdd_in is None else as_configurations(qdd_in, robot.nv, "trajectory.qdd")
    for what, a in (("trajectory.qd", qd), ("trajectory.qdd", qdd)):
        if a is not None and a.shape != (len(q), robot.nv):
            raise ShapeError(f"{what}: expected shape ({len(q)}, {robot.nv}), got {a.shape}")
    steps = np.diff(times)
    on_grid = len(times) == 1 or bool(np.all(np.abs(steps - dt) <= 1e-9 * max(1.0, dt)))
    span = float(times[-1] - times[0])
    n = float(len(times)) if on_grid else span / dt + 1e-9 + 1.0  # a float: inf for a tiny dt
    what = f"trajectory: {span:.6g} s at dt = {dt:g} s"
    if settle_ticks:
        what += f" and a settle phase of {settle_ticks} ticks"
    if not n + settle_ticks <= MAX_TICKS:
        raise SettingsError(f"{what} is {n + settle_ticks:.6g} ticks; a run is limited to {MAX_TICKS}")
    count = len(times) if on_grid else int(math.floor(span / dt + 1e-9)) + 1
    check_run_size(count + settle_ticks, robot.nq, robot.nv, dt, what)
    if on_grid and qd is not None and qdd is not None:
        return times - times[0], q, qd, qdd
    if len(times) == 1:
        zero = np.zeros((1, robot.nv))
        return np.zeros(1), q, zero if qd is None else qd, zero.copy()
    from scipy.interpolate import CubicHermiteSpline, CubicSpline

    x = joint_values(robot, q)
    spline = (CubicHermiteSpline(times, x, qd) if qd is not None
              else CubicSpline(times, x, bc_type="clamped"))
    grid = times[0] + dt * np.arange(count)
    xs = spline(grid)
    return grid - times[0], np.ascontiguousarray(from_joint_values(robot, xs)), spline(grid, 1), spline(grid, 2)


# ---------------------------------------------------------------------------------------------
# execute
# ---------------------------------------------------------------------------------------------

def _payloads(payload: Any) -> list[Any]:
    if payload is None:
        return []
    items = [payload] if isinstance(payload, Payload) else list(payload) if isinstance(payload, Sequence) else [payload]
    return [_typed(p, Payload, "payload") for p in items]


def _on_link(robot: Any, payload: Any) -> Any:
    """``payload`` with its link's role ("hand") resolved to the link's name."""
    if payload.link is None:
        return payload
    return payload.replace(link=frame_link(robot, payload.link, "payload.link"))


def _residuals(robot: Any, task: Any, q: Array) -> tuple[dict[str, float], dict[str, float]]:
    """The largest residual of each primary term of ``task`` over the configurations ``q``."""
    from genplan.projection import GaussNewtonProjector, SolverSettings, load_task

    t = load_task(task, robot)
    evaluator = GaussNewtonProjector(robot, t, SolverSettings(max_iterations=0, clip_to_limits=False))
    res = evaluator.solve_batch(q, parallel=True).residuals
    tolerances = {term.label(): float(term.tolerance) for term in t.primary}
    return {k: float(np.max(v)) for k, v in res.items()}, tolerances


#: the settle phase of :func:`execute` (s)
SETTLE_S = 0.5


def execute(robot: Any, trajectory: Any = None, *, controller: Any = None, disturbances: Any = None,
            payload: Any = None, limits: Any = None, dt: float | None = None, settle: float | None = None,
            substeps: int = 1, strict: bool = False, paced: bool = False, world: Any = None, task: Any = None,
            _stacklevel: int = 2, **spatula: Any) -> ExecutionLog:
    """Execute ``trajectory`` on the simulated ``robot`` at 1 kHz (see the module's text).

    Args:
        robot: a :class:`genplan.Robot` or what :func:`genplan.load` takes (fixed base).
        trajectory: a :class:`genplan.trajectory.Trajectory` (``PlanResult.trajectory()``, an
            adjusted one), or ``(t, q)`` arrays (optionally ``qd``; a mapping with ``t``, ``q``,
            ``qd``, ``qdd``): resampled to ``dt`` when it is not at that rate
            (:func:`joint_reference`).
        controller: :class:`ControllerSettings` (default: task space on the tool frame with the
            paper's gains and 2 Hz observer); its ``frame`` may be a role ("hand") or a link.
        disturbances: what the plant has that the controller's model lacks
            (:class:`Disturbances`: friction, offsets, an unknown payload).
        payload: what the robot holds, known to the controller (:class:`Payload`, or several);
            ``link`` None puts it on the controller's frame.
        limits: :class:`JointLimits` (default: the URDF's, policy "saturate").
        dt: the control period (s; default ``controller.dt``, 1 ms).
        settle: seconds holding the first sample before the motion (the observer converges, as
            a robot holds its start pose before it moves; default :data:`SETTLE_S`); at most
            :data:`MAX_SETTLE_S`.
        substeps: RK4 steps of the plant per period.
        strict: refuse a reference whose inverse-dynamics torques exceed the torque limits, and
            stop at the first tick over a limit (:class:`~genplan.errors.LimitExceededError`).
        paced: tick on the wall clock (the log's ``jitter``).
        world: a :class:`~genplan.collision.CollisionWorld` (or a checker with ``is_valid``) the
            executed motion is checked against (``log.in_collision``; a :class:`CollisionWarning`).
        task: a task (Task, shipped name or file) whose primary terms are evaluated along the
            executed motion (``log.residuals``).

    Bad input raises before the run: ShapeError (another robot's joint count), NonFiniteError,
    UnknownNameError (a frame the robot does not have), SettingsError (a setting, naming it; a run
    longer than :data:`MAX_TICKS` or whose log would take more than :data:`MAX_RUN_BYTES`, naming
    the trajectory's duration and the bound, before anything of the run is allocated),
    :class:`~genplan.errors.InvalidTrajectoryError` (a sample outside the joint range, over the
    velocity limits, or a jump one tick at the velocity limit cannot follow). A run over the
    limits warns (:class:`LimitWarning`) unless ``strict``.

    Deprecated (one release): ``execute(trajectory (K, 3), ...)``, the spatula run of the
    seq2seq experiment, is :func:`genplan.pancake.control.execute`.
    """
    from genplan.robots import Robot, load

    if not isinstance(robot, (Robot, str, os.PathLike)):
        import genplan.pancake.control as pc

        warnings.warn("genplan.control.execute(trajectory, ...) for the spatula is deprecated: use "
                      "genplan.pancake.control.execute", DeprecationWarning, stacklevel=2)
        legacy: dict[str, Any] = {k: v for k, v in (("controller", controller), ("disturbances", disturbances),
                                                    ("limits", limits), ("settle", settle)) if v is not None}
        return pc.execute(robot, paced=paced, substeps=substeps, strict=strict, _stacklevel=3, **legacy, **spatula)
    if spatula:
        raise TypeError(f"execute() got unexpected keyword arguments {sorted(spatula)}")
    if trajectory is None:
        raise TypeError("execute() missing the trajectory")
    rob = robot if isinstance(robot, Robot) else load(robot)
    if rob.floating_base:
        raise GenplanError(f"execute: robot '{rob.name}' has a floating base; the loop simulates fixed-base robots")
    ctrl = _typed(controller if controller is not None else ControllerSettings(), ControllerSettings, "controller")
    dist = _typed(disturbances if disturbances is not None else Disturbances(), Disturbances, "disturbances")
    lim = _typed(limits if limits is not None else JointLimits(), JointLimits, "limits")
    if dt is not None:
        ctrl = ctrl.replace(dt=as_real(dt, "dt", error=SettingsError))
    ctrl = ctrl.replace(frame=frame_link(rob, ctrl.frame))
    payloads = [_on_link(rob, p) for p in _payloads(payload)]
    if dist.payload is not None:
        dist = dist.replace(payload=_on_link(rob, dist.payload))
    settle_s = seconds(SETTLE_S if settle is None else settle, "settle", MAX_SETTLE_S)
    settle_ticks = ticks(settle_s, ctrl.dt, "settle")
    t, q, qd, qdd = joint_reference(rob, trajectory, ctrl.dt, settle_ticks=settle_ticks)  # its size bounded first
    sim = _core.Simulation(rob.description, ctrl, dist, payloads, lim, int(substeps))
    out = sim.run(np.ascontiguousarray(q), np.ascontiguousarray(qd), np.ascontiguousarray(qdd), settle=settle_ticks,
                  paced=bool(paced), strict=bool(strict))
    q_ref = np.vstack([np.repeat(q[:1], settle_ticks, axis=0), q])[: len(out["t"])]
    meta = {"robot": rob.name, "frame": ctrl.frame, "space": ctrl.space, "dt": ctrl.dt, "joint_names": list(rob.joint_names),
            "settle_s": settle_s, "torque_limits": sim.limits["torque"], "velocity_limits": sim.limits["velocity"],
            "controller": ctrl.to_dict(), "disturbances": _plain(dist.to_dict()),
            "payloads": [_plain(p.to_dict()) for p in payloads], "limits": lim.to_dict()}
    log = ExecutionLog._from_native(out, q_ref=q_ref, reference_torque_ratio=float(out["reference_torque_ratio"]),
                                    reference_over=out["reference_over"], meta=meta)
    if log.reference_over is not None:
        warnings.warn(f"the trajectory's inverse-dynamics torques exceed the torque limits "
                      f"(largest ratio {log.reference_torque_ratio:.2f}), first: {log.reference_over['message']} "
                      "(strict=True refuses it)", LimitWarning, stacklevel=_stacklevel)
    v = log.limit_violation
    if v is not None:
        if strict:
            raise LimitExceededError(f"run stopped (strict=True): {v['message']}")
        warnings.warn(f"the run exceeded the joint limits in {log.summary['limit_ticks']} ticks "
                      f"({lim.policy}), first: {v['message']} (see log.limit_violation; strict=True stops there)",
                      LimitWarning, stacklevel=_stacklevel)
    if world is not None:
        from genplan.trajectory import _invalid_samples

        log.in_collision = _invalid_samples(world, log.q)
        if log.in_collision.any():
            k = int(np.argmax(log.in_collision))
            warnings.warn(f"the executed motion collides at t = {log.t[k]:.3f} s ({int(log.in_collision.sum())} ticks; "
                          "see log.in_collision)", CollisionWarning, stacklevel=_stacklevel)
    if task is not None:
        log.residuals, log.tolerances = _residuals(rob, task, log.q)
    return log


def _plain(d: dict[str, Any]) -> dict[str, Any]:
    """A settings dict with nested settings objects as dicts (for JSON)."""
    return {k: (_plain(v.to_dict()) if hasattr(v, "to_dict") else v) for k, v in d.items()}


# ---------------------------------------------------------------------------------------------
# deprecated: the spatula loop moved to genplan.pancake.control
# ---------------------------------------------------------------------------------------------

#: old name -> its place now (one release)
_MOVED = {"SpatulaArm": "SpatulaArm", "SpatulaSetup": "SpatulaSetup", "PancakeConfig": "PancakeSettings",
          "deceleration_tail": "deceleration_tail", "as_trajectory": "as_trajectory", "DT": "DT",
          "MAX_TAIL_S": "MAX_TAIL_S"}


class _Gains:
    """The old task-space gains (the paper's Kpp, Kpr, Kvp, Kvr): ``ControllerSettings.kp`` /
    ``kv`` per axis now."""

    def __init__(self, kpp: float = 450.0, kpr: float = 700.0, kvp: float = 60.0, kvr: float = 90.0) -> None:
        self.kpp, self.kpr, self.kvp, self.kvr = kpp, kpr, kvp, kvr


def _controller_config(gains: _Gains | None = None, torque_limit: Any = None, **changes: Any) -> Any:
    """The old ControllerConfig: :class:`ControllerSettings` of the paper's loop with ``changes``."""
    if torque_limit is not None:
        raise SettingsError("ControllerConfig.torque_limit is gone: clip the torque with "
                            "JointLimits(torque=..., policy='saturate')")
    g = gains or _Gains()
    return ControllerSettings.paper().replace(kp=[g.kpp] * 3 + [g.kpr] * 3, kv=[g.kvp] * 3 + [g.kvr] * 3, **changes)


def __getattr__(name: str) -> Any:
    if name in _MOVED:
        import genplan.pancake.control as pc

        warnings.warn(f"genplan.control.{name} is deprecated: use genplan.pancake.control.{_MOVED[name]}",
                      DeprecationWarning, stacklevel=2)
        return getattr(pc, _MOVED[name])
    if name in ("Gains", "ControllerConfig"):
        warnings.warn(f"genplan.control.{name} is deprecated: use genplan.control.ControllerSettings (per-axis kp, kv; "
                      "the paper's loop: genplan.pancake.control.PAPER_CONTROLLER)", DeprecationWarning, stacklevel=2)
        return _Gains if name == "Gains" else _controller_config
    raise AttributeError(f"module 'genplan.control' has no attribute {name!r}")
