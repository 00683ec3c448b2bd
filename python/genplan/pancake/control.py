"""The seq2seq paper's experiment (Kutsuzawa et al. 2019, Section 5, Fig. 10): spatula
trajectories executed at 1 kHz on the simulated UR5, with the pancake on the blade.

It is one configuration of genplan's 1 kHz loop (:mod:`genplan.control`): the task-space P-D +
disturbance-observer controller on the spatula frame (the UR5's ``tool0`` moved 0.1 m along its
z axis), commanded by eq. 23 from the paper's poses; the spatula a payload the controller
knows; the pancake a payload with its own dynamics (Coulomb stick/slip on the blade); the
paper's loop feeds no acceleration forward (:data:`PAPER_CONTROLLER`).

>>> from genplan.pancake import s_curve
>>> from genplan.pancake.control import execute
>>> log = execute(s_curve([0, 0, 0], [0.05, 0.02, -0.4]), settle=0.2)
>>> log.slipped, round(log.max_tracking_error_mm, 1) < 10
(False, True)

Conventions (see ``rust/core/src/control/spatula.rs`` for the full statement):

* a trajectory is ``(K, 3)`` poses ``[y, z, theta]`` every ``dt`` (1 ms): the paper's spatula
  pose in the vertical y-z plane, ``theta`` counter-clockwise from +y (as
  :mod:`genplan.pancake.trajectories`);
* the command is eq. 23, ``q_cmd = [0.5, y, z + 0.35, theta, pi/2, 0]``; the attitude ``[a, b, c]``
  is intrinsic X-Y'-Z'', ``R = Rx(a) Ry(b) Rz(c)``, so ``R_cmd = Rx(theta) Ry(pi/2)``: the spatula
  frame's z axis (the handle, along the UR5 flange axis) points along world +x, the blade normal
  is ``[0, -sin theta, cos theta]`` and ``theta`` tilts the blade about world x.

Safety: every tick's torque and joint speed are checked against the arm's rated limits (the
URDF's, or :class:`JointLimits`; recorded, not enforced: policy "log"). A run over them warns
(:class:`~genplan.control.LimitWarning`) and says so in its log (``log.exceeded_limits``,
``log.limit_violation``); ``strict=True`` refuses it with
:class:`genplan.errors.LimitExceededError`. Bad settings raise
:class:`genplan.errors.SettingsError` naming the field when they are made.

Bounds: ``settle`` is at most :data:`MAX_SETTLE_S` seconds and ``tail`` at most
:data:`MAX_TAIL_S`; a whole run (settle, trajectory and tail) is at most :data:`MAX_TICKS`
ticks; beyond them a :class:`~genplan.errors.SettingsError` names the argument before anything
is allocated.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan import _core
from genplan._arrays import as_configurations, as_float_array, as_real, error_class
from genplan._execution import MAX_SETTLE_S, MAX_TICKS, ExecutionLog, LimitWarning, seconds, ticks
from genplan.errors import LimitExceededError, NonFiniteError, SettingsError, ShapeError

ControllerSettings = _core.ControllerSettings
Disturbances = _core.Disturbances
Payload = _core.Payload
JointLimits = _core.JointLimits
SpatulaSetup = _core.SpatulaSetup
PancakeSettings = _core.PancakeSettings
PancakeSummary = _core.PancakeSummary

__all__ = [
    "SpatulaArm", "SpatulaLog", "SpatulaSetup", "PancakeSettings", "PancakeSummary", "ControllerSettings",
    "Disturbances", "Payload", "JointLimits", "PAPER_CONTROLLER", "reference_disturbances", "execute",
    "deceleration_tail", "as_trajectory", "DT", "MAX_TICKS", "MAX_SETTLE_S", "MAX_TAIL_S",
]

#: the paper's control period (s)
DT = 1e-3
#: the longest deceleration tail (s): 100 times the paper's 0.1 s
MAX_TAIL_S = 10.0
#: the paper's loop (Section 5.1): its gains, the 2 Hz observer, no acceleration feed-forward
PAPER_CONTROLLER = ControllerSettings.paper()


def reference_disturbances() -> Any:
    """The plant deviations of genplan's reproduction of the experiment (defined in the Rust
    core, ``control::spatula::reference_disturbances``): a 0.3 kg payload error at the spatula
    point, Coulomb and viscous friction and a torque offset on each of the UR5's six joints."""
    return _core.spatula_reference_disturbances()


@dataclass
class SpatulaLog(ExecutionLog):
    """A spatula run (an :class:`~genplan.control.ExecutionLog`) with the paper's view of it:
    ``p_cmd`` / ``p`` (N, 3) commanded / achieved ``[y, z, theta]`` (achieved ``theta``: the
    blade's in-plane tilt, unwrapped); the pancake: ``phi`` (rad, eq. 16 on the achieved motion),
    ``slide`` (m along the blade), ``normal`` (normal force per unit mass), ``pancake_mode`` (0
    stuck, 1 sliding, 2 left the spatula). ``summary`` holds the pancake's verdicts too
    (``slipped``, ``first_slip_time``, ``left_time``, ``max_abs_phi``, ``max_abs_slide``)."""

    p_cmd: NDArray[np.float64] | None = None
    p: NDArray[np.float64] | None = None
    phi: NDArray[np.float64] | None = None
    slide: NDArray[np.float64] | None = None
    normal: NDArray[np.float64] | None = None
    pancake_mode: NDArray[np.uint8] | None = None

    @property
    def slip(self) -> NDArray[np.bool_]:
        assert self.pancake_mode is not None
        return self.pancake_mode != 0

    @property
    def slipped(self) -> bool:
        """Did the pancake slide or leave the spatula during the motion (not the tail)?"""
        return bool(self.summary["slipped"])

    @property
    def max_abs_phi_deg(self) -> float:
        """Largest |phi| of the achieved motion during the motion window (degrees)."""
        return math.degrees(float(self.summary["max_abs_phi"]))


def as_trajectory(trajectory: ArrayLike, what: str = "trajectory") -> NDArray[np.float64]:
    """``trajectory`` as a C-contiguous float64 (K, 3) array, K >= 2, finite (else ShapeError or
    NonFiniteError naming ``what``)."""
    arr = np.ascontiguousarray(as_float_array(trajectory, what))
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] < 2:
        raise ShapeError(f"{what}: expected shape (K, 3) with K >= 2 rows [y, z, theta], got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        row, col = (int(i) for i in np.argwhere(~np.isfinite(arr))[0])
        raise NonFiniteError(f"{what}: row {row} ({['y', 'z', 'theta'][col]}) is not finite ({arr[row, col]})")
    return arr


def deceleration_tail(trajectory: ArrayLike, duration: float = 0.1, dt: float = DT) -> NDArray[np.float64]:
    """``trajectory`` followed by the paper's constant-deceleration tail: from the last sample's
    velocity (backward difference) down to rest in ``duration`` seconds (Section 5.3: 0.1 s).

    Returns (K + n, 3) with ``n = round(duration / dt)``; the tail travels ``v duration / 2``.
    ``duration`` is at most :data:`MAX_TAIL_S` and ``K + n`` at most :data:`MAX_TICKS`, else a
    SettingsError naming it.
    """
    x = as_trajectory(trajectory)
    duration = seconds(duration, "duration", MAX_TAIL_S)
    dt = as_real(dt, "dt", error=SettingsError)
    if not (math.isfinite(dt) and dt > 0):
        raise SettingsError(f"dt must be > 0, got {dt}")
    n = ticks(duration, dt, "duration", MAX_TICKS - x.shape[0])
    if n == 0:
        return x.copy()
    v = (x[-1] - x[-2]) / dt
    t = dt * np.arange(1, n + 1)
    tail_t = np.minimum(t, duration)
    tail = x[-1] + v[None, :] * (tail_t - tail_t ** 2 / (2.0 * duration))[:, None]
    return np.vstack([x, tail])


class SpatulaArm:
    """A simulated arm with the spatula, its controller and the pancake (reusable for many
    runs). ``robot``: a fixed-base 6-joint preset of :mod:`genplan.robots` ("ur5").
    ``controller``: gains, observer and period (default :data:`PAPER_CONTROLLER`; the frame and
    axes are the spatula's). ``disturbances``: what the plant has that the controller's model
    lacks (a payload: at the spatula point; :func:`reference_disturbances` is the benchmark's
    set). ``settle``: seconds holding the first pose before the motion (the observer converges;
    the paper's robot waited 25 s; at most :data:`MAX_SETTLE_S`). ``limits``: the joint limits
    runs are checked against (default: the robot model's, recorded). Every setting is checked
    here (a SettingsError names the field)."""

    def __init__(self, *, robot: Any = "ur5", controller: Any = None, disturbances: Any = None, setup: Any = None,
                 pancake: Any = None, substeps: int = 1, settle: float = 1.0, limits: Any = None) -> None:
        from genplan.robots import load

        controller = PAPER_CONTROLLER if controller is None else controller
        for value, cls, what in ((controller, ControllerSettings, "controller"), (disturbances, Disturbances, "disturbances"),
                                 (setup, SpatulaSetup, "setup"), (pancake, PancakeSettings, "pancake"),
                                 (limits, JointLimits, "limits")):
            if value is not None and not isinstance(value, cls):
                raise SettingsError(f"{what}: expected a {cls.__name__}, got {type(value).__name__} {value!r}")
        settle = seconds(settle, "settle", MAX_SETTLE_S)
        if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)):
            raise SettingsError(f"substeps must be an integer, got {substeps!r}")
        self.dt = float(controller.dt)
        self.settle_ticks = ticks(settle, self.dt, "settle")
        if limits is None:
            limits = JointLimits(policy="log")
        arm = robot if hasattr(robot, "description") else load(robot)
        self._sim = _core.SpatulaSimulation(arm.description, controller, disturbances, setup, pancake, limits,
                                            int(substeps), self.settle_ticks)
        self.setup = setup if setup is not None else SpatulaSetup()
        self.robot = robot
        self.robot_name = str(arm.name)

    @property
    def joint_names(self) -> list[str]:
        return self._sim.joint_names

    @property
    def controller(self) -> Any:
        """The controller's settings (the spatula's frame and axes)."""
        return self._sim.controller

    @property
    def limits(self) -> dict[str, NDArray[np.float64]]:
        """The joint limits in force: ``{"torque": (6,), "velocity": (6,)}`` (N m, rad/s)."""
        return {k: np.asarray(v, dtype=np.float64) for k, v in self._sim.limits.items()}

    def command_pose(self, p: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """eq. 23: world position (3,) and rotation (3, 3) commanded for a pose [y, z, theta]."""
        a = as_float_array(p, "p")
        if a.shape != (3,) or not np.all(np.isfinite(a)):
            raise error_class(a, a.shape == (3,))(f"p must be a finite pose [y, z, theta], got {a.tolist()}")
        return self._sim.command_pose([float(x) for x in a])

    def spatula_pose(self, q: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World position and rotation of the spatula frame at joint configuration q."""
        return self._sim.spatula_pose(as_configurations(q, len(self.joint_names), "q"))

    def check(self, trajectory: ArrayLike) -> NDArray[np.float64]:
        """Validate a trajectory as :meth:`execute` does (shape, NaN, reachability of every
        pose by IK within the joint limits); return the initial joint configuration."""
        return self._sim.check_trajectory(as_trajectory(trajectory))

    def execute(self, trajectory: ArrayLike, *, tail: float = 0.0, paced: bool = False,
                strict: bool = False, _stacklevel: int = 2) -> SpatulaLog:
        """Run ``trajectory`` (K, 3); ``tail`` > 0 appends :func:`deceleration_tail` of that many
        seconds (outside the motion window). ``paced``: tick on the wall clock every dt and
        report the jitter. Bad input raises ValueError before the loop starts; ``tail`` is at most
        :data:`MAX_TAIL_S` seconds and the run (settle, trajectory, tail) at most :data:`MAX_TICKS`
        ticks, else a SettingsError naming ``tail``.

        A run over the joint limits (:attr:`limits`) warns with
        :class:`~genplan.control.LimitWarning` and is flagged in the log; with ``strict=True``
        the run stops at the first tick over a limit and
        :class:`~genplan.errors.LimitExceededError` names the joint, the time and the limit."""
        x = as_trajectory(trajectory)
        k = x.shape[0]
        tail = seconds(tail, "tail", MAX_TAIL_S)
        if tail:
            ticks(tail, self.dt, "tail", MAX_TICKS - self.settle_ticks - k)  # before the tail is allocated
            x = deceleration_tail(x, tail, self.dt)
        out = self._sim.run(x, motion_len=k, paced=bool(paced), stop_at_limit=bool(strict))
        log = self._log(out, x)
        violation = log.limit_violation
        if violation is not None:
            if strict:
                raise LimitExceededError(f"trajectory refused (strict=True): {violation['message']}")
            warnings.warn(f"the run exceeded the arm's joint limits in {log.summary['limit_ticks']} ticks, first: "
                          f"{violation['message']} (see log.limit_violation; strict=True refuses it)",
                          LimitWarning, stacklevel=_stacklevel)
        return log

    def _log(self, out: dict[str, Any], x: NDArray[np.float64]) -> SpatulaLog:
        n = len(out["t"])
        channels = list(out["payload_channels"])
        payload = out["payload"]
        column = {name: payload[:, i] for i, name in enumerate(channels)}
        origin = self.setup.origin
        position = out["position"]
        p = np.column_stack([position[:, 1] - origin[1], position[:, 2] - origin[2], column["tilt"]])
        p_cmd = np.vstack([np.repeat(x[:1], self.settle_ticks, axis=0), x])[:n]
        log = SpatulaLog._from_native(out, p_cmd=p_cmd, p=p, phi=column["phi"], slide=column["slide"],
                                      normal=column["normal"], pancake_mode=column["mode"].astype(np.uint8),
                                      meta={"robot": self.robot_name, "dt": self.dt})
        log.summary.update(out["pancake"].to_dict())
        return log


def execute(trajectory: ArrayLike, *, dob: bool = True, disturbances: Any = None, controller: Any = None,
            setup: Any = None, pancake: Any = None, tail: float = 0.0, settle: float = 1.0, paced: bool = False,
            substeps: int = 1, robot: Any = "ur5", limits: Any = None, strict: bool = False,
            _stacklevel: int = 2) -> SpatulaLog:
    """Execute a spatula trajectory (K, 3) of ``[y, z, theta]`` at 1 kHz on the simulated arm.

    ``dob``: feed the disturbance observer back (overrides ``controller.dob``).
    ``disturbances``: unmodelled plant effects (default none; :func:`reference_disturbances` is
    the benchmark's set). ``settle``: seconds holding the first pose before the motion (at most
    :data:`MAX_SETTLE_S`). ``tail``: seconds of constant deceleration after the motion (the
    paper: 0.1; at most :data:`MAX_TAIL_S`). A run (settle, trajectory, tail) is at most
    :data:`MAX_TICKS` ticks. ``paced``: tick on the wall clock and report jitter. ``substeps``:
    RK4 steps of the plant per tick. ``limits``: the joint limits every tick is checked against
    (default: the robot model's, from its URDF).

    Returns a :class:`SpatulaLog`. A trajectory with the wrong shape, a NaN, or a pose the arm
    cannot reach raises ValueError naming the row before the loop starts; a bad setting raises
    SettingsError naming the field. A run over the joint limits warns
    (:class:`~genplan.control.LimitWarning`; ``log.limit_violation`` has the first tick) or, with
    ``strict=True``, raises :class:`~genplan.errors.LimitExceededError`.
    """
    controller = PAPER_CONTROLLER if controller is None else controller
    if not isinstance(controller, ControllerSettings):
        raise SettingsError(f"controller: expected a ControllerSettings, got {type(controller).__name__} {controller!r}")
    arm = SpatulaArm(robot=robot, controller=controller.replace(dob=bool(dob)), disturbances=disturbances, setup=setup,
                     pancake=pancake, substeps=substeps, settle=settle, limits=limits)
    return arm.execute(trajectory, tail=tail, paced=paced, strict=strict, _stacklevel=_stacklevel + 1)
