"""Execute spatula trajectories with the seq2seq paper's 1 kHz controller on a simulated arm.

The paper (Kutsuzawa et al. 2019, Section 5, Fig. 10) drives the spatula of a 6-joint arm with a
task-space P-D controller and a disturbance observer (DOB) at 1 kHz. genplan runs that loop in
Rust (:class:`genplan._core.SpatulaSimulation`): controller, true plant (RK4 on the arm's rigid-body
dynamics with friction, an unknown payload and a torque offset) and the pancake's Coulomb
stick/slip, with no Python call per tick.

>>> import numpy as np
>>> from genplan import control
>>> from genplan.pancake import s_curve
>>> log = control.execute(s_curve([0, 0, 0], [0.05, 0.02, -0.4]), settle=0.2)
>>> log.slipped, round(log.max_tracking_error_mm, 1) < 10
(False, True)

Conventions (see ``rust/core/src/control.rs`` for the full statement):

* a trajectory is ``(K, 3)`` poses ``[y, z, theta]`` every ``dt`` (1 ms): the paper's spatula
  pose in the vertical y-z plane, ``theta`` counter-clockwise from +y (as
  :mod:`genplan.pancake.trajectories`);
* the command is eq. 23, ``q_cmd = [0.5, y, z + 0.35, theta, pi/2, 0]``; the attitude ``[a, b, c]``
  is intrinsic X-Y'-Z'', ``R = Rx(a) Ry(b) Rz(c)``, so ``R_cmd = Rx(theta) Ry(pi/2)``: the spatula
  frame's z axis (the handle, along the UR5 flange axis) points along world +x, the blade normal
  is ``[0, -sin theta, cos theta]`` and ``theta`` tilts the blade about world x;
* the spatula point is the UR5's ``tool0`` frame moved 0.1 m along its z axis.

Safety: every tick's torque and joint speed are checked against the arm's rated limits (the
URDF's ``<limit effort velocity>``, or :class:`JointLimits`). A run over them warns
(:class:`LimitWarning`) and says so in its log (``log.exceeded_limits``,
``log.limit_violation``: the first tick's time, joint, value and limit); ``strict=True`` refuses
it with :class:`genplan.errors.LimitExceededError`. Bad configuration values (``dt <= 0``, a
negative gain, a payload outside [0, 100] kg, ...) raise :class:`genplan.errors.SettingsError`
naming the field before anything runs.

Bounds: ``settle`` is at most :data:`MAX_SETTLE_S` seconds and ``tail`` at most
:data:`MAX_TAIL_S`; a whole run (settle, trajectory and tail) is at most :data:`MAX_TICKS` ticks
(the native core's limit; its log takes ~600 bytes a tick). Beyond them a
:class:`~genplan.errors.SettingsError` names the argument before anything is allocated.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan import _core
from genplan._arrays import as_configurations, as_float_array, as_real, error_class
from genplan.errors import LimitExceededError, NonFiniteError, SettingsError, ShapeError

__all__ = [
    "Gains", "ControllerConfig", "Disturbances", "SpatulaSetup", "PancakeConfig", "JointLimits", "ExecutionLog",
    "LimitWarning", "SpatulaArm", "execute", "deceleration_tail", "as_trajectory", "DT", "MAX_TICKS",
    "MAX_SETTLE_S", "MAX_TAIL_S",
]

#: the paper's control period (s)
DT = 1e-3
#: the longest run in ticks (settle + trajectory + tail): the native core's ``MAX_TICKS``
#: (rust/core/src/control.rs; 2.8 hours at 1 kHz, the log takes ~600 bytes a tick)
MAX_TICKS = 10_000_000
#: the longest settle phase (s); the paper's robot waited 25 s
MAX_SETTLE_S = 60.0
#: the longest deceleration tail (s): 100 times the paper's 0.1 s
MAX_TAIL_S = 10.0


def _seconds(value: Any, what: str, maximum: float) -> float:
    """``value`` as a duration in [0, maximum] seconds, else SettingsError naming ``what``."""
    t = as_real(value, what, error=SettingsError)
    if not (math.isfinite(t) and 0.0 <= t <= maximum):
        raise SettingsError(f"{what} must be in [0, {maximum:g}] seconds, got {t}")
    return t


def _ticks(seconds: float, dt: float, what: str, budget: int = MAX_TICKS) -> int:
    """``round(seconds / dt)``, at most ``budget`` ticks, else SettingsError naming ``what``."""
    n = seconds / dt  # Python floats: inf on overflow
    if not (math.isfinite(n) and round(n) <= budget):
        raise SettingsError(f"{what}: {seconds} s at dt = {dt} s is {n:.3g} ticks; a run is limited to "
                            f"{MAX_TICKS} ticks ({max(budget, 0)} left for it)")
    return int(round(n))


@dataclass
class Gains:
    """Task-space P-D gains (the paper's Section 5.1)."""

    kpp: float = 450.0
    kpr: float = 700.0
    kvp: float = 60.0
    kvr: float = 90.0


@dataclass
class ControllerConfig:
    """The controller of Fig. 10. ``model_compensation`` adds the nominal Coriolis and gravity
    torque ``h_n(q, v)``; ``velocity_feedforward`` puts the D term on ``v_cmd - v`` (else
    ``-v``); ``acceleration_feedforward`` adds the command's acceleration (the paper does not);
    ``singular_det``: ``|det J|`` (m^3) below which the Jacobian inverse is damped (damping up to
    ``max_damping``); ``torque_limit``: symmetric limits per joint (N m) at which the controller
    clips its torque, or None (the arm's rated limits are checked apart: :class:`JointLimits`)."""

    gains: Gains = field(default_factory=Gains)
    dt: float = DT
    dob: bool = True
    dob_cutoff_hz: float = 2.0
    model_compensation: bool = True
    velocity_feedforward: bool = True
    acceleration_feedforward: bool = False
    singular_det: float = 1e-3
    max_damping: float = 0.05
    torque_limit: list[float] | None = None

    def to_dict(self) -> dict[str, Any]:
        d = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "gains"}
        d.update(asdict(self.gains))
        if d["torque_limit"] is not None:
            d["torque_limit"] = [float(x) for x in d["torque_limit"]]
        return d


@dataclass
class Disturbances:
    """What the true plant has and the controller's model lacks (per joint, N m; zero by
    default): Coulomb friction ``coulomb * tanh(v / friction_velocity)``, viscous friction, a
    constant torque offset, and a payload (kg) at the spatula point (+ ``payload_com`` in the
    spatula frame)."""

    coulomb: list[float] = field(default_factory=lambda: [0.0] * 6)
    viscous: list[float] = field(default_factory=lambda: [0.0] * 6)
    friction_velocity: float = 0.05
    offset: list[float] = field(default_factory=lambda: [0.0] * 6)
    payload_mass: float = 0.0
    payload_com: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])

    @classmethod
    def reference(cls) -> Disturbances:
        """The deviations of ``genplan bench control`` (defined once, in the Rust core)."""
        _, ref = _core.spatula_defaults()
        return cls(**ref)

    def to_dict(self) -> dict[str, Any]:
        return {k: (list(map(float, v)) if isinstance(v, (list, tuple, np.ndarray)) else float(v))
                for k, v in asdict(self).items()}


@dataclass
class SpatulaSetup:
    """Where the task sits on the arm: eq. 23's ``origin`` ([0.5, 0, 0.35]) and attitude
    (``q_cmd[4:6]`` = [pi/2, 0]); the spatula point ``spatula_length`` along the flange's z axis;
    the nominal spatula (mass, centre of mass along the handle), known to the controller."""

    tool_link: str = "tool0"
    spatula_length: float = 0.1
    spatula_mass: float = 0.2
    spatula_com: float = 0.05
    origin: list[float] = field(default_factory=lambda: [0.5, 0.0, 0.35])
    attitude: list[float] = field(default_factory=lambda: [math.pi / 2, 0.0])
    q_seed: list[float] | None = None

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["origin"] = [float(x) for x in self.origin]
        d["attitude"] = [float(x) for x in self.attitude]
        d["q_seed"] = None if self.q_seed is None else [float(x) for x in self.q_seed]
        return d


@dataclass
class PancakeConfig:
    """Coulomb friction of the pancake on the blade (the paper: mu = 1) and the blade's half
    length (m) past which it falls off."""

    mu_static: float = 1.0
    mu_kinetic: float = 1.0
    blade_half_length: float = 0.06


@dataclass
class JointLimits:
    """The rated limits every tick of a run is checked against, per joint: ``torque`` (N m)
    and ``velocity`` (rad/s); None takes the robot model's (the URDF's ``<limit effort>`` and
    ``<limit velocity>``: 150/150/150/28/28/28 N m and 3.15/3.15/3.15/3.2/3.2/3.2 rad/s on the
    UR5); ``math.inf`` leaves a joint unchecked."""

    torque: list[float] | None = None
    velocity: list[float] | None = None

    def to_dict(self) -> dict[str, Any]:
        return {k: None if v is None else [float(x) for x in v] for k, v in asdict(self).items()}


class LimitWarning(RuntimeWarning):
    """A run went over the arm's joint limits (see :attr:`ExecutionLog.limit_violation`)."""


@dataclass
class ExecutionLog:
    """One run, one row per 1 ms tick (the state at the tick's start, the torque it applied).

    Poses: ``p_cmd`` / ``p`` (N, 3) commanded / achieved ``[y, z, theta]`` (achieved ``theta`` is
    the blade's in-plane tilt, unwrapped); ``position_cmd`` / ``position`` (N, 3) world (m),
    ``rotation`` (N, 3, 3); tracking errors ``error_position`` (m, norm) and ``error_rotation``
    (rad, angle of ``R_cmd R^T``). Arm: ``q``, ``v``, ``tau`` (N, 6); ``tau_dis_hat`` the DOB's
    estimate and ``tau_dis`` the torque the nominal model does not explain (what the DOB
    estimates, unfiltered). Spatula: ``acceleration`` (N, 6) achieved [linear; angular], world.
    Pancake: ``phi`` (rad, eq. 16 on the achieved motion), ``slide`` (m along the blade),
    ``normal`` (normal force per unit mass), ``pancake_mode`` (0 stuck, 1 sliding, 2 left the
    spatula), ``slip`` (mode != 0). ``damped``: ticks where the Jacobian was near-singular.
    Ticks ``[motion_start, motion_end)`` are the motion proper (before: settle, after: tail).
    ``summary``: the Rust summary (errors, slip, timing, ``max_abs_tau``, ``max_abs_v``, the
    joint limits' ``limit_violation`` and ``limit_ticks``); ``jitter``: paced runs only (us).
    """

    t: NDArray[np.float64]
    p_cmd: NDArray[np.float64]
    p: NDArray[np.float64]
    position_cmd: NDArray[np.float64]
    position: NDArray[np.float64]
    rotation: NDArray[np.float64]
    error_position: NDArray[np.float64]
    error_rotation: NDArray[np.float64]
    q: NDArray[np.float64]
    v: NDArray[np.float64]
    tau: NDArray[np.float64]
    tau_dis_hat: NDArray[np.float64]
    tau_dis: NDArray[np.float64]
    acceleration: NDArray[np.float64]
    phi: NDArray[np.float64]
    slide: NDArray[np.float64]
    normal: NDArray[np.float64]
    pancake_mode: NDArray[np.uint8]
    damped: NDArray[np.bool_]
    det_j: NDArray[np.float64]
    motion_start: int
    motion_end: int
    summary: dict[str, Any]
    jitter: dict[str, float] | None = None
    lateness: NDArray[np.float64] | None = None
    compute: NDArray[np.float64] | None = None

    @property
    def slip(self) -> NDArray[np.bool_]:
        return self.pancake_mode != 0

    @property
    def slipped(self) -> bool:
        """Did the pancake slide or leave the spatula during the motion (not the tail)?"""
        return bool(self.summary["slipped"])

    @property
    def max_tracking_error_mm(self) -> float:
        """Largest position error after the settle phase (mm)."""
        return 1e3 * float(self.summary["max_error_position"])

    @property
    def max_tracking_error_deg(self) -> float:
        """Largest attitude error after the settle phase (degrees)."""
        return math.degrees(float(self.summary["max_error_rotation"]))

    @property
    def max_abs_phi_deg(self) -> float:
        """Largest |phi| of the achieved motion during the motion window (degrees)."""
        return math.degrees(float(self.summary["max_abs_phi"]))

    @property
    def us_per_tick(self) -> float:
        """Wall time of the loop per tick (us); for a paced run, the period."""
        return float(self.summary["us_per_tick"])

    @property
    def exceeded_limits(self) -> bool:
        """Did any tick go over the arm's torque or speed limits (settle and tail included)?"""
        return self.summary["limit_violation"] is not None

    @property
    def limit_violation(self) -> dict[str, Any] | None:
        """The first tick over a joint limit: ``time`` (s from the start of the run), ``tick``,
        ``joint`` (name), ``quantity`` ("torque" or "velocity"), ``value``, ``limit``, ``unit``
        and ``message``; None if the run stayed within the limits."""
        v = self.summary["limit_violation"]
        return None if v is None else dict(v)


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
    duration = _seconds(duration, "duration", MAX_TAIL_S)
    dt = as_real(dt, "dt", error=SettingsError)
    if not (math.isfinite(dt) and dt > 0):
        raise SettingsError(f"dt must be > 0, got {dt}")
    n = _ticks(duration, dt, "duration", MAX_TICKS - x.shape[0])
    if n == 0:
        return x.copy()
    v = (x[-1] - x[-2]) / dt
    t = dt * np.arange(1, n + 1)
    tail_t = np.minimum(t, duration)
    tail = x[-1] + v[None, :] * (tail_t - tail_t ** 2 / (2.0 * duration))[:, None]
    return np.vstack([x, tail])


def _config(controller: ControllerConfig | None, disturbances: Disturbances | None, setup: SpatulaSetup | None,
            pancake: PancakeConfig | None, substeps: int, settle_ticks: int,
            limits: JointLimits | None = None) -> dict[str, Any]:
    return {
        "controller": (controller or ControllerConfig()).to_dict(),
        "disturbances": (disturbances or Disturbances()).to_dict(),
        "setup": (setup or SpatulaSetup()).to_dict(),
        "pancake": asdict(pancake or PancakeConfig()),
        "substeps": int(substeps),
        "settle_ticks": int(settle_ticks),
        "limits": (limits or JointLimits()).to_dict(),
    }


class SpatulaArm:
    """A simulated arm with the spatula, its controller and the pancake (reusable for many
    runs). ``robot``: a fixed-base 6-joint preset of :mod:`genplan.robots` ("ur5"). ``limits``:
    the joint limits runs are checked against (default: the robot model's). The configuration
    is checked here (the native core names the bad field in a SettingsError)."""

    def __init__(self, *, robot: str = "ur5", controller: ControllerConfig | None = None,
                 disturbances: Disturbances | None = None, setup: SpatulaSetup | None = None,
                 pancake: PancakeConfig | None = None, substeps: int = 1, settle: float = 1.0,
                 limits: JointLimits | None = None) -> None:
        from genplan.robots import load

        controller = controller or ControllerConfig()
        settle = _seconds(settle, "settle", MAX_SETTLE_S)
        if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)):
            raise SettingsError(f"substeps must be an integer, got {substeps!r}")
        # a bad dt is the core's to refuse (SettingsError naming controller.dt); no ticks then
        try:
            dt = as_real(controller.dt, "controller.dt", error=SettingsError)
        except SettingsError:
            dt = math.nan
        dt_ok = not isinstance(controller.dt, bool) and math.isfinite(dt) and dt > 0
        settle_ticks = _ticks(settle, dt, "settle") if dt_ok else 0
        self.config: dict[str, Any] = _config(controller, disturbances, setup, pancake, substeps, settle_ticks, limits)
        arm = robot if hasattr(robot, "description") else load(robot)
        self._sim = _core.SpatulaSimulation(arm.description, self.config)
        self.robot = robot
        self.dt = float(controller.dt)

    @property
    def joint_names(self) -> list[str]:
        return self._sim.joint_names

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
                strict: bool = False, _stacklevel: int = 2) -> ExecutionLog:
        """Run ``trajectory`` (K, 3); ``tail`` > 0 appends :func:`deceleration_tail` of that many
        seconds (outside the motion window). ``paced``: tick on the wall clock every dt and
        report the jitter. Bad input raises ValueError before the loop starts; ``tail`` is at most
        :data:`MAX_TAIL_S` seconds and the run (settle, trajectory, tail) at most :data:`MAX_TICKS`
        ticks, else a SettingsError naming ``tail``.

        A run over the joint limits (:attr:`limits`) warns with :class:`LimitWarning` and is
        flagged in the log; with ``strict=True`` the run stops at the first tick over a limit
        and :class:`~genplan.errors.LimitExceededError` names the joint, the time and the limit."""
        x = as_trajectory(trajectory)
        k = x.shape[0]
        tail = _seconds(tail, "tail", MAX_TAIL_S)
        if tail:
            budget = MAX_TICKS - int(self.config["settle_ticks"]) - k
            _ticks(tail, self.dt, "tail", budget)  # before the tail is allocated
            x = deceleration_tail(x, tail, self.dt)
        out = self._sim.run(x, motion_len=k, paced=bool(paced), stop_at_limit=bool(strict))
        summary = out.pop("summary")
        violation = summary["limit_violation"]
        if violation is not None:
            if strict:
                raise LimitExceededError(f"trajectory refused (strict=True): {violation['message']}")
            warnings.warn(f"the run exceeded the arm's joint limits in {summary['limit_ticks']} ticks, first: "
                          f"{violation['message']} (see log.limit_violation; strict=True refuses it)",
                          LimitWarning, stacklevel=_stacklevel)
        jitter = summary.pop("jitter", None)
        return ExecutionLog(summary=summary, jitter=jitter, lateness=out.pop("lateness", None),
                            compute=out.pop("compute", None), **out)


def execute(trajectory: ArrayLike, *, dob: bool = True, disturbances: Disturbances | None = None,
            controller: ControllerConfig | None = None, setup: SpatulaSetup | None = None,
            pancake: PancakeConfig | None = None, tail: float = 0.0, settle: float = 1.0,
            paced: bool = False, substeps: int = 1, robot: str = "ur5", limits: JointLimits | None = None,
            strict: bool = False) -> ExecutionLog:
    """Execute a spatula trajectory (K, 3) of ``[y, z, theta]`` at 1 kHz on the simulated arm.

    ``dob``: feed the disturbance observer back (overrides ``controller.dob``).
    ``disturbances``: unmodelled plant effects (default none; :meth:`Disturbances.reference` is
    the benchmark's set). ``settle``: seconds holding the first pose before the motion (the DOB
    converges; the paper's robot waited 25 s; at most :data:`MAX_SETTLE_S`). ``tail``: seconds of
    constant deceleration after the motion (the paper: 0.1; at most :data:`MAX_TAIL_S`). A run
    (settle, trajectory, tail) is at most :data:`MAX_TICKS` ticks. ``paced``: tick on the wall
    clock and report jitter.
    ``substeps``: RK4 steps of the plant per tick. ``limits``: the joint limits every tick is
    checked against (default: the robot model's, from its URDF).

    Returns an :class:`ExecutionLog`. A trajectory with the wrong shape, a NaN, or a pose the arm
    cannot reach raises ValueError naming the row before the loop starts; a bad configuration
    value raises SettingsError naming the field. A run over the joint limits warns
    (:class:`LimitWarning`; ``log.limit_violation`` has the first tick) or, with ``strict=True``,
    raises :class:`~genplan.errors.LimitExceededError` naming the joint, the time and the limit.
    """
    controller = controller or ControllerConfig()
    controller = ControllerConfig(**{**{f.name: getattr(controller, f.name) for f in fields(controller)}, "dob": bool(dob)})
    arm = SpatulaArm(robot=robot, controller=controller, disturbances=disturbances, setup=setup,
                     pancake=pancake, substeps=substeps, settle=settle, limits=limits)
    return arm.execute(trajectory, tail=tail, paced=paced, strict=strict, _stacklevel=3)
