"""The log of a 1 kHz run (:class:`ExecutionLog`), its warnings and the bounds of a run: what
:mod:`genplan.control` (any robot) and :mod:`genplan.pancake.control` (the seq2seq paper's
spatula configuration) share."""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan import _core
from genplan._arrays import as_real
from genplan.errors import SettingsError, UnknownNameError

__all__ = ["ARRAYS", "CollisionWarning", "ExecutionLog", "LimitWarning", "MAX_RUN_BYTES", "MAX_SETTLE_S", "MAX_TICKS",
           "check_run_size", "log_bytes", "run_bytes", "seconds", "ticks"]

Array = NDArray[np.float64]

#: the longest run in ticks (settle and trajectory): the native core's ``MAX_TICKS``
MAX_TICKS: int = _core.MAX_TICKS
#: the longest settle phase (s); the paper's robot waited 25 s
MAX_SETTLE_S = 60.0
#: the most memory a run's log and reference may take (:func:`run_bytes`): 1 GiB, the bound of
#: a trajectory's samples (``_core.MAX_TRAJECTORY_BYTES``); about 21 minutes of a 7-joint arm at
#: 1 kHz
MAX_RUN_BYTES: int = _core.MAX_TRAJECTORY_BYTES


class LimitWarning(RuntimeWarning):
    """A run, or its reference, went over the robot's joint limits (see
    :attr:`ExecutionLog.limit_violation`)."""


class CollisionWarning(RuntimeWarning):
    """The executed motion collided (see :attr:`ExecutionLog.in_collision`)."""


def seconds(value: Any, what: str, maximum: float) -> float:
    """``value`` as a duration in [0, maximum] seconds, else SettingsError naming ``what``."""
    t = as_real(value, what, error=SettingsError)
    if not (math.isfinite(t) and 0.0 <= t <= maximum):
        raise SettingsError(f"{what} must be in [0, {maximum:g}] seconds, got {t}")
    return t


def ticks(duration: float, dt: float, what: str, budget: int = MAX_TICKS) -> int:
    """``round(duration / dt)``, at most ``budget`` ticks, else SettingsError naming ``what``."""
    n = duration / dt  # Python floats: inf on overflow
    if not (math.isfinite(n) and round(n) <= budget):
        raise SettingsError(f"{what}: {duration} s at dt = {dt} s is {n:.3g} ticks; a run is limited to "
                            f"{MAX_TICKS} ticks ({max(budget, 0)} left for it)")
    return int(round(n))


def log_bytes(ticks: int, nq: int, nv: int, channels: int = 0) -> int:
    """The bytes of the arrays of a log (:data:`ARRAYS`) of ``ticks`` ticks: per tick ``t``,
    ``q`` and ``q_ref`` (nq), ``v``, ``tau``, ``tau_dis_hat``, ``tau_dis``, ``error_joint`` (nv),
    the tool frame's ``position_cmd``, ``position`` (3), ``rotation`` (9), ``velocity``,
    ``acceleration`` (6), six scalars and ``channels`` payload channels (float64), and the flags
    ``damped``, ``saturated``, ``in_collision``."""
    return ticks * (8 * (1 + 2 * nq + 5 * nv + 33 + channels) + 3)


def run_bytes(ticks: int, nq: int, nv: int) -> int:
    """The bytes a run of ``ticks`` ticks holds at once, at least: its log (:func:`log_bytes`)
    and its reference (``t``, ``q``, ``qd``, ``qdd`` per tick)."""
    return log_bytes(ticks, nq, nv) + ticks * 8 * (1 + nq + 2 * nv)


def check_run_size(ticks: int, nq: int, nv: int, dt: float, what: str) -> None:
    """SettingsError when a run of ``ticks`` ticks of ``dt`` would hold more than
    :data:`MAX_RUN_BYTES` (:func:`run_bytes`), naming ``what`` (the run's duration, e.g.
    "trajectory: 9000 s at dt = 0.001 s"), the size and the bound; checked before anything of the
    run is allocated."""
    size = run_bytes(ticks, nq, nv)
    if size > MAX_RUN_BYTES:
        longest = MAX_RUN_BYTES // run_bytes(1, nq, nv)
        raise SettingsError(f"{what} is {ticks} ticks, whose log and reference take {size / 2**30:.2f} GiB, more than "
                            f"the {MAX_RUN_BYTES / 2**30:.2f} GiB a run may take (at most {longest} ticks, "
                            f"{longest * dt:.6g} s, for this robot): execute it in parts, or at a larger dt")


#: the arrays of a log, in its .npz file
ARRAYS = ("t", "q", "q_ref", "v", "tau", "tau_dis_hat", "tau_dis", "error_joint", "position_cmd", "position",
          "rotation", "error_position", "error_rotation", "velocity", "acceleration", "det_j", "damped", "saturated",
          "torque_ratio", "velocity_ratio", "compute", "payload", "in_collision")


@dataclass
class ExecutionLog:
    """One run, one row per tick: the state at the tick's start and what it applied.

    Joints: ``q`` (N, nq), ``q_ref`` the reference (the settle phase holds its first sample),
    ``v``, ``tau`` (applied), ``tau_dis_hat`` (the observer's estimate), ``tau_dis`` (the torque
    the nominal model does not explain: what the observer filters), ``error_joint``
    (``q_ref (-) q``, N x nv; None without a joint reference). Tool frame (the controller's):
    ``position_cmd`` / ``position`` (N, 3), ``rotation`` (N, 3, 3), ``error_position`` (m) and
    ``error_rotation`` (rad), ``velocity`` and ``acceleration`` (N, 6: linear, angular; world
    axes). ``det_j``: the task solve's singularity measure (NaN in joint space) and ``damped``;
    ``saturated``: the torque was clipped; ``torque_ratio`` / ``velocity_ratio``: the largest
    |commanded torque| / limit and |speed| / limit; ``compute``: the tick's compute time (s).
    ``payload``: a payload's own channels (``payload_channels``). Ticks ``[motion_start,
    motion_end)`` are the motion (before: the settle phase). ``summary``: the native summary
    (:class:`RunSummary` as a dict); ``limit_violation``: the first tick over a limit (or None);
    ``reference_torque_ratio`` / ``reference_over``: the reference's inverse-dynamics torques
    against the limits; ``in_collision``: per tick, with a collision world; ``residuals`` /
    ``tolerances``: the largest residual of each primary term of a task along the executed
    motion."""

    t: Array
    q: Array
    v: Array
    tau: Array
    tau_dis_hat: Array
    tau_dis: Array
    position_cmd: Array
    position: Array
    rotation: Array
    error_position: Array
    error_rotation: Array
    velocity: Array
    acceleration: Array
    det_j: Array
    damped: NDArray[np.bool_]
    saturated: NDArray[np.bool_]
    torque_ratio: Array
    velocity_ratio: Array
    compute: Array
    payload: Array
    payload_channels: tuple[str, ...]
    motion_start: int
    motion_end: int
    summary: dict[str, Any]
    limit_violation: dict[str, Any] | None = None
    q_ref: Array | None = None
    error_joint: Array | None = None
    reference_torque_ratio: float = math.nan
    reference_over: dict[str, Any] | None = None
    in_collision: NDArray[np.bool_] | None = None
    residuals: dict[str, float] = field(default_factory=dict)
    tolerances: dict[str, float] = field(default_factory=dict)
    jitter: dict[str, float] | None = None
    lateness: Array | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def _from_native(cls, out: dict[str, Any], **extra: Any) -> Any:
        out = dict(out)
        summary = out.pop("summary").to_dict()
        out.pop("reference_torque_ratio", None)
        out.pop("reference_over", None)
        names = tuple(out.pop("payload_channels"))
        summary["limit_violation"] = out.get("limit_violation")
        known = {f for f in cls.__dataclass_fields__}
        return cls(summary=summary, payload_channels=names, **{k: v for k, v in out.items() if k in known}, **extra)

    @property
    def max_tracking_error_mm(self) -> float:
        """Largest position error of the tool frame after the settle phase (mm)."""
        return 1e3 * float(self.summary["max_error_position"])

    @property
    def max_tracking_error_deg(self) -> float:
        """Largest attitude error of the tool frame after the settle phase (degrees)."""
        return math.degrees(float(self.summary["max_error_rotation"]))

    @property
    def max_joint_error(self) -> float:
        """Largest |joint error| after the settle phase (rad or m; NaN without a joint reference)."""
        return float(self.summary["max_error_joint"])

    @property
    def us_per_tick(self) -> float:
        """Wall time of the loop per tick (us); for a paced run, the period."""
        return float(self.summary["us_per_tick"])

    @property
    def realtime_factor(self) -> float:
        """How much faster than real time the loop ran (the period / the time per tick)."""
        dt = float(self.t[1] - self.t[0]) if len(self.t) > 1 else float(self.meta.get("dt", 1e-3))
        return dt * 1e6 / self.us_per_tick if self.us_per_tick > 0 else math.inf

    @property
    def exceeded_limits(self) -> bool:
        """Did any tick go over the robot's torque or speed limits (the settle phase included)?"""
        return self.limit_violation is not None

    @property
    def collided(self) -> bool:
        """Did the executed motion collide (False without a collision world)?"""
        return self.in_collision is not None and bool(self.in_collision.any())

    @property
    def within_tolerance(self) -> bool:
        """Every term of the task within its tolerance along the executed motion (True without
        a task)."""
        return all(self.residuals[k] <= self.tolerances[k] for k in self.residuals)

    @property
    def executable(self) -> bool:
        """The run went through within the joint limits, without a collision, on the task's
        manifold (the checks that were asked for), with a reference within the torque limits."""
        return (not self.exceeded_limits and not self.summary["stopped_at_limit"] and not self.collided
                and self.within_tolerance and self.reference_over is None)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the log to ``path`` (``.npz``: its arrays, and its summary and metadata as JSON
        under ``meta``), atomically (genplan._files.atomic_path). Returns ``path``."""
        from genplan._files import atomic_path

        path = Path(path)
        if path.suffix.lower() != ".npz":
            raise UnknownNameError(f"path: a log is written as .npz, got '{path.suffix or path.name}' ({path})")
        arrays = {k: getattr(self, k) for k in ARRAYS if getattr(self, k, None) is not None}
        meta = {"format": "genplan.execution_log/1", "summary": self.summary, "limit_violation": self.limit_violation,
                "payload_channels": list(self.payload_channels), "motion_start": self.motion_start,
                "motion_end": self.motion_end, "reference_torque_ratio": self.reference_torque_ratio,
                "reference_over": self.reference_over, "residuals": self.residuals, "tolerances": self.tolerances,
                "jitter": self.jitter, **self.meta}
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays, meta=np.array(json.dumps(meta, default=float)))
        return path

    def plot(self, path: str | os.PathLike[str], title: str | None = None) -> Path:
        """A PNG of the run: the tool frame's position and attitude errors, the joint errors, the
        torques relative to their limits and the observer's estimate, over time (matplotlib)."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from genplan._files import atomic_path

        t = self.t - self.t[self.motion_start]
        fig, ax = plt.subplots(4, 1, figsize=(8, 10), sharex=True)
        ax[0].plot(t, 1e3 * self.error_position, "C0-", lw=1.0, label="position [mm]")
        ax0b = ax[0].twinx()
        ax0b.plot(t, np.degrees(self.error_rotation), "C1-", lw=0.8, label="attitude [deg]")
        ax[0].set_ylabel("tool error [mm]")
        ax0b.set_ylabel("tool error [deg]")
        ax[0].legend(loc="upper left", fontsize=7)
        ax0b.legend(loc="upper right", fontsize=7)
        if self.error_joint is not None:
            ax[1].plot(t, np.degrees(self.error_joint), lw=0.8)
            ax[1].set_ylabel("joint error [deg]")
        limits = np.asarray(self.meta.get("torque_limits", np.full(self.tau.shape[1], np.nan)), dtype=np.float64)
        rel = self.tau / limits if np.all(np.isfinite(limits)) else self.tau
        ax[2].plot(t, rel, lw=0.8)
        ax[2].set_ylabel("torque / limit" if np.all(np.isfinite(limits)) else "torque [N m]")
        if np.all(np.isfinite(limits)):
            for y in (-1.0, 1.0):
                ax[2].axhline(y, color="r", lw=0.6, ls="--")
        ax[3].plot(t, self.tau_dis_hat, lw=0.8)
        ax[3].set_ylabel("DOB estimate [N m]")
        ax[-1].set_xlabel("time from motion start [s]")
        for a in ax:
            a.axvline(0.0, color="0.5", lw=0.5)
        fig.suptitle(title or f"{self.meta.get('robot', '')}: {self.max_tracking_error_mm:.2f} mm / "
                              f"{self.max_tracking_error_deg:.2f} deg max tool error", fontsize=9)
        fig.tight_layout()
        path = Path(path)
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110, format="png")
        plt.close(fig)
        return path
