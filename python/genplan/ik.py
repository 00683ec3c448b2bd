"""Inverse kinematics: :func:`solve_ik`, one call for users that keeps trying until every target
is reached, and :func:`valid_solutions`, the collision-free solutions of one target that
planning queries start and end at (:mod:`genplan.planning.queries`).

    res = genplan.solve_ik(panda, "panda_ik", targets, restarts=10, time_budget_s=0.005)
    res.q, res.success, res.time_s, res.attempts

The task's [condition] term (e.g. ``hand_position``, a FramePosition) is aimed at each target
(:func:`genplan.projection.condition_term`); the task's other terms (orientation, joint limits,
...) hold as in any projection. A target is a position of the condition term's frame, or a whole
pose of it (6-D IK: a 4x4 homogeneous matrix, or a position and a unit quaternion ``x y z qx qy
qz qw``): the condition term is then a :class:`~genplan.projection.FramePose` of that frame, with
its weight and tolerance (a log6 error, metres and radians). :func:`frame_task` is the IK task of
any frame of any robot (its pose within the joint limits):

    res = genplan.solve_ik(panda, frame_task(panda, "hand"), pose_4x4, init="uniform") Each round of :func:`solve_ik` solves every target still failing
in one native batch (``GaussNewtonProjector.solve_batch``: Rust, GIL released, rows on all cores),
each from a new warm start (:data:`INITS`): for the first half of the attempts, the task's learned
sampler (``init="gan"``, its shipped model by default: conditioned on the target, a new noise draw
and ensemble member every round) or, with no model at all, the rows of the task's data set whose
condition frame is nearest the target, nearest first (``init="data"``:
:class:`genplan.samplers.data.TaskData`, the data a learned sampler is trained on); then uniform
random configurations (another basin of attraction when the first kind keeps proposing the same
one). ``genplan bench ik`` compares the warm starts. A target stops being retried when it succeeds
or after ``restarts`` retries; no round starts once the call has run for ``time_budget_s`` of
wall-clock time (its setup included), so the call returns within the budget plus one round (every
target gets its first attempt). ``time_s`` is each target's real elapsed time, from the call's
start until it was settled; ``solve_s`` its own share of the work (its solves plus its share of
the warm starts' sampling), the per-target cost to compare solvers with.

The solver is the projector's damped Gauss-Newton with two changes for IK (beyond the paper;
``settings=SolverSettings(), nominal="start"`` gives the paper's solver back):

* :data:`IK_SETTINGS`: every step is taken whole (``max_backtracks=1``: no line search, as
  differential-IK solvers such as pink take their steps), with damping ``mu`` 1e-3. The paper's
  Armijo line search only ever goes downhill, so from a far start it settles in the nearest local
  minimum, most often with a joint stuck at a limit; whole steps jump past such minima.
* ``nominal="mid"``: the task's posture (its Posture terms without a ``q_nom`` of their own: the
  null-space posture of the paper's tasks) pulls towards the middle of each bounded joint's range
  instead of towards the warm start, which keeps joints off their limits.

Each change, and both together more, raises the share of targets one attempt solves, from uniform
and from learned warm starts, on the Panda and on Talos (tuning targets, not the tables' seeds:
``python benches/ik_settings.py``, benches/results/ik_settings.json).
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from genplan._arrays import as_float_array
from genplan._core import SolverSettings
from genplan.errors import GenplanError, NonFiniteError, SettingsError, ShapeError, UnknownNameError
from genplan.robots import Robot
from genplan.samplers import WARM_STARTS

__all__ = ["ATTEMPT_ITERATIONS", "IK_SETTINGS", "INITS", "NOMINALS", "IKResult", "frame_task", "solve_ik",
           "valid_solutions"]

#: Warm starts :func:`solve_ik` accepts by name (or an (n, nq) array of configurations): the
#: samplers that are warm starts (:data:`genplan.samplers.WARM_STARTS`).
INITS = WARM_STARTS
#: Nominal postures :func:`solve_ik` accepts by name (or an (nq,) / (n, nq) array): "mid", the
#: middle of each bounded joint's range (unbounded joints and a free-flyer base: the warm
#: start's); "start", the warm start (the paper's).
NOMINALS = ("mid", "start")
#: :func:`solve_ik`'s default solver settings: whole Gauss-Newton steps (``max_backtracks=1``),
#: ``mu`` 1e-3, the rest the paper's defaults (see the module text).
IK_SETTINGS = SolverSettings(mu=1e-3, max_backtracks=1)
#: Gauss-Newton iterations per attempt. Nearly every attempt that converges with
#: :data:`IK_SETTINGS` does so within 20 iterations (benches/results/ik_settings.json), so an
#: attempt that has not is abandoned for a new warm start: more, cheaper attempts fit a time budget.
ATTEMPT_ITERATIONS = 20


@dataclass
class IKResult:
    """Per target: ``q`` (n, nq; the solution, or the best attempt's configuration when it
    failed: the smallest residual / tolerance), ``success`` (n,), ``time_s`` (n,: the wall-clock
    time from the call's start until the target was settled, by success or by its last attempt),
    ``solve_s`` (n,: its own solves plus its share of the warm starts' sampling: its cost,
    whatever else the batch held), ``attempts`` (n,), ``residuals`` (term -> (n,) at ``q``);
    ``wall_s``: the whole call; ``rounds``: the batches solved."""

    q: NDArray[np.float64]
    success: NDArray[np.bool_]
    time_s: NDArray[np.float64]
    attempts: NDArray[np.int64]
    residuals: dict[str, NDArray[np.float64]]
    wall_s: float
    rounds: int
    solve_s: NDArray[np.float64]

    def __len__(self) -> int:
        return len(self.success)

    @property
    def success_rate(self) -> float:
        """The fraction of targets reached."""
        return float(self.success.mean()) if len(self) else math.nan

    def __repr__(self) -> str:
        return (f"IKResult({len(self)} targets, success {100 * self.success_rate:.1f} %, mean solve {1e3 * float(self.solve_s.mean()):.3f} ms, "
                f"attempts <= {int(self.attempts.max()) if len(self) else 0}, wall {1e3 * self.wall_s:.1f} ms)")


#: What :func:`solve_ik` takes as targets, for its shape errors.
_TARGET_SHAPES = ("positions (n, 3), poses as 4x4 homogeneous matrices (n, 4, 4) or as a position and a unit "
                  "quaternion x y z qx qy qz qw (n, 7); one target without the leading n")


def _targets(targets: ArrayLike, what: str = "targets") -> NDArray[np.float64]:
    """The targets as positions (n, 3) or poses (n, 4, 4): a position + quaternion (x y z qx qy
    qz qw) becomes its 4x4 matrix. ShapeError for another shape, NonFiniteError for NaN or
    inf, GenplanError for a pose that is not one (a rotation that is not, a last row that is not
    0 0 0 1, a quaternion whose norm is not 1 within 1e-3)."""
    t = as_float_array(targets, what)
    if t.ndim == 1 or (t.ndim == 2 and t.shape == (4, 4)):
        t = t[None]
    if not ((t.ndim == 2 and t.shape[1] in (3, 7)) or (t.ndim == 3 and t.shape[1:] == (4, 4))):
        raise ShapeError(f"{what}: expected {_TARGET_SHAPES}; got shape {np.shape(targets)}")
    if not np.all(np.isfinite(t)):
        rows = np.nonzero(~np.isfinite(t.reshape(len(t), -1)).all(axis=1))[0]
        raise NonFiniteError(f"{what}: rows {rows[:5].tolist()} are not finite")
    if t.ndim == 2 and t.shape[1] == 7:
        norm = np.linalg.norm(t[:, 3:], axis=1)
        bad = np.nonzero(np.abs(norm - 1.0) > 1e-3)[0]
        if len(bad):
            raise GenplanError(f"{what}[{bad[0]}]: the quaternion (qx qy qz qw) has norm {norm[bad[0]]:.6g}, not 1")
        poses = np.tile(np.eye(4), (len(t), 1, 1))
        for i, row in enumerate(t):
            x, y, z, w = row[3:] / norm[i]
            poses[i, :3, :3] = pin.Quaternion(w, x, y, z).toRotationMatrix()
            poses[i, :3, 3] = row[:3]
        t = poses
    elif t.ndim == 3:
        rot = t[:, :3, :3]
        off = np.abs(np.einsum("nji,njk->nik", rot, rot) - np.eye(3)).max(axis=(1, 2))
        det = np.linalg.det(rot)
        bad = np.nonzero((off > 1e-6) | (det < 0) | np.any(np.abs(t[:, 3] - [0.0, 0.0, 0.0, 1.0]) > 1e-9, axis=1))[0]
        if len(bad):
            raise GenplanError(f"{what}[{bad[0]}]: not a pose: expected a 4x4 homogeneous matrix (a rotation, a "
                               "translation, last row 0 0 0 1)")
    return np.ascontiguousarray(t)


def frame_task(robot: Robot, frame: str, task: Any = None) -> Any:
    """The IK task of ``frame`` (a frame of ``robot``): its position as the [condition] term
    ``frame_target`` (:func:`solve_ik` aims it at a position, or at a whole pose), with the
    primary and secondary terms of ``task`` (a Task or what :func:`genplan.projection.load_task`
    takes; default: the joint limits, with the posture in their null space). UnknownNameError
    names a frame the robot lacks."""
    from genplan import projection as P

    robot.frame_id(frame)  # an unknown frame: UnknownNameError naming it
    base = P.Task(primary=(P.JointLimits(),), secondary=(P.Posture(),)) if task is None else P.load_task(task, robot)
    term = P.FramePosition(frame=frame, name="frame_target", tolerance=1e-4)
    box = (-1e3, -1e3, -1e3), (1e3, 1e3, 1e3)  # no sampler draws from it: any position is a target
    return P.Task(primary=(term, *base.primary), secondary=tuple(base.secondary), name=f"{base.name}_{frame}_ik",
                  condition=P.Condition(term.name, *box))


def _nominal_rows(robot: Robot, nominal: str | ArrayLike, n: int) -> str | NDArray[np.float64]:
    """``nominal`` checked: a name of :data:`NOMINALS`, or the (n, nq) nominal configurations."""
    if isinstance(nominal, str):
        if nominal not in NOMINALS:
            raise UnknownNameError(f"nominal: unknown nominal posture '{nominal}' (known: {', '.join(NOMINALS)}, "
                                   "or an (nq,) or (n, nq) array)")
        return nominal
    rows = robot.check_configuration(nominal, "nominal")
    if rows.ndim == 1:
        rows = np.tile(rows, (n, 1))
    if rows.shape != (n, robot.nq):
        raise ShapeError(f"nominal: expected ({robot.nq},) or ({n}, {robot.nq}) configurations, got {np.shape(nominal)}")
    return rows


def _nominals(robot: Robot, nominal: str | NDArray[np.float64], q0: NDArray[np.float64],
              rows: NDArray[np.intp]) -> NDArray[np.float64] | None:
    """The nominal postures of a round's warm starts ``q0`` (the targets ``rows``); None: the
    warm starts themselves."""
    if isinstance(nominal, str):
        if nominal == "start":
            return None
        lo, hi = robot.lower, robot.upper
        bounded = np.isfinite(lo) & np.isfinite(hi)
        out = q0.copy()
        out[:, bounded] = 0.5 * (lo[bounded] + hi[bounded])
        return out
    return nominal[rows]


def _model(robot: Robot, task: Any, model: Any) -> Any:
    from genplan.samplers.base import SamplerModel, check_model_robot
    from genplan.samplers.loading import load_sampler_model

    if isinstance(model, SamplerModel):
        check_model_robot(model, robot)  # by kinematics, not by name
        return model
    return load_sampler_model(robot, model, task=task)


def solve_ik(robot: Robot, task: Any, targets: ArrayLike, init: str | ArrayLike = "gan", restarts: int = 20,
             time_budget_s: float | None = None, model: str | os.PathLike[str] | Any = None, seed: int = 0,
             iterations: int = ATTEMPT_ITERATIONS, parallel: bool = True,
             settings: SolverSettings | None = None, nominal: str | ArrayLike = "mid") -> IKResult:
    """Solve the IK of ``task`` (a :class:`~genplan.projection.Task`, a shipped task's name or a
    task file, with a [condition]; :func:`frame_task` makes one for any frame) for each row of
    ``targets``: (n, 3) positions of the condition term's frame, or whole poses of it, (n, 4, 4)
    homogeneous matrices or (n, 7) positions and unit quaternions ``x y z qx qy qz qw`` (one
    target without the leading n is a batch of one), retrying the failures; see the module text.

    Args:
        robot: the robot (:func:`genplan.load`).
        init: one of :data:`INITS`: "gan" (the task's learned sampler, then uniform), "data"
            (the rows of the task's data set whose condition frame is nearest the target, the
            next nearest at each retry, then uniform: no model needed), "uniform"; or (n, nq)
            first warm starts (retries are uniform).
        restarts: retries per target after the first attempt (>= 0).
        time_budget_s: wall-clock seconds for the whole call, its setup included: no round
            starts once it is spent (the first, every target's first attempt, always runs); the
            call returns within it plus one round (None: no budget).
        model: the GAN for ``init="gan"``: a file, a loaded ``GanModel``, or None (the shipped
            one of the robot; a GAN for another robot or task is refused).
        seed: seeds the warm starts.
        iterations: Gauss-Newton iterations per attempt (default :data:`ATTEMPT_ITERATIONS`):
            an attempt that has not converged by then is abandoned for a new warm start.
        parallel: solve a round's rows on all cores (each row's time is its own solve).
        settings: the solver's :class:`~genplan.projection.SolverSettings` (default
            :data:`IK_SETTINGS`; ``SolverSettings()``: the paper's); ``iterations`` replaces its
            ``max_iterations``.
        nominal: the posture the task's Posture terms without a ``q_nom`` of their own pull
            towards: "mid" (default: the middle of each bounded joint's range, the warm start's
            value elsewhere), "start" (the warm start: the paper's), or an (nq,) or (n, nq) array
            of configurations.

    Raises:
        ShapeError / NonFiniteError (``targets``, ``init``), GenplanError (a target pose that is
        not one: see the shapes above), UnknownNameError (``init``),
        SettingsError (``restarts``, ``time_budget_s``, ``iterations``, ``settings``), UnknownNameError /
        ShapeError / NonFiniteError (``nominal``), GenplanError (a task without [condition]).
    """
    from genplan.projection import FramePose, GaussNewtonProjector, condition_term, load_task

    wall0 = time.perf_counter()
    if isinstance(restarts, bool) or not isinstance(restarts, (int, np.integer)) or restarts < 0:
        raise SettingsError(f"restarts must be an integer >= 0, got {restarts!r}")
    if time_budget_s is not None:
        try:
            budget_ok = math.isfinite(float(time_budget_s)) and float(time_budget_s) > 0
        except (TypeError, ValueError):
            budget_ok = False
        if not budget_ok:
            raise SettingsError(f"time_budget_s must be a positive number of seconds or None, got {time_budget_s!r}")
    budget = math.inf if time_budget_s is None else float(time_budget_s)
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 1:
        raise SettingsError(f"iterations must be an integer >= 1, got {iterations!r}")
    if settings is None:
        settings = IK_SETTINGS
    elif not isinstance(settings, SolverSettings):
        raise SettingsError(f"settings must be a SolverSettings or None, got {type(settings).__name__}")
    t = _targets(targets)
    n = len(t)
    first: NDArray[np.float64] | None = None
    if isinstance(init, str):
        if init not in INITS:
            raise UnknownNameError(f"init: unknown warm start '{init}' (known: {', '.join(INITS)}, or an (n, nq) array)")
    else:
        first = robot.check_configuration(init, "init")
        if first.shape != (n, robot.nq):
            raise ShapeError(f"init: expected ({n}, {robot.nq}) configurations (one per target), got {first.shape}")
    nominal_rows = _nominal_rows(robot, nominal, n)
    task_of_model = load_task(task, robot)  # the task a learned sampler or data set is made for
    cond = condition_term(task_of_model)
    term = cond.name
    ik_task = task_of_model
    # the warm starts are drawn for the targets' positions
    positions = t if t.ndim == 2 else np.ascontiguousarray(t[:, :3, 3])
    if t.ndim == 3:  # whole poses: the condition term aims the frame's pose
        # each row's pose is given per row; the term's own target only lets the solver be built
        pose = FramePose(frame=cond.frame, name=term, weight=cond.weight, tolerance=cond.tolerance, target=t[0])
        ik_task = dataclasses.replace(ik_task, primary=tuple(pose if tm.name == term else tm for tm in ik_task.primary))
    solver = GaussNewtonProjector(robot, ik_task, settings.replace(max_iterations=int(iterations)))
    labels = [tm.label() for tm in ik_task.primary]
    tols = np.array([float(tm.tolerance) for tm in ik_task.primary])
    gan = _model(robot, task_of_model, model) if isinstance(init, str) and init == "gan" else None
    gan_attempts = (restarts + 2) // 2  # attempts 1 .. this: GAN (or data); later ones uniform
    rng = np.random.default_rng(seed)
    nearest = None
    if isinstance(init, str) and init == "data":
        from genplan.samplers.data import TaskData

        nearest = TaskData(robot, task_of_model).nearest(positions, gan_attempts)
    if gan is not None:
        # the generator run natively (one row costs microseconds; torch's call alone ~0.7 ms),
        # on targets clipped into the box its output is vouched for (GanModel.native_sampler)
        native_gan = gan.native_sampler(seed=seed)
        box = np.asarray(gan.config.target_box, dtype=np.float64)

        def gan_starts(rows: NDArray[np.intp]) -> NDArray[np.float64]:
            return gan.draw_native(native_gan, np.clip(positions[rows], box[0], box[1]), rng)

    q = np.tile(robot.q_default, (n, 1)) if first is None else first.copy()
    success = np.zeros(n, dtype=bool)
    time_s = np.zeros(n)
    solve_s = np.zeros(n)
    attempts = np.zeros(n, dtype=np.int64)
    score = np.full(n, np.inf)
    residuals = {lab: np.full(n, np.inf) for lab in labels}
    rounds = 0
    while True:
        rows = np.nonzero(~success & (attempts <= restarts))[0]
        if len(rows) == 0 or (rounds > 0 and time.perf_counter() - wall0 >= budget):
            break
        # every row of a round is at attempt `rounds` + 1: a row leaves for good once done
        if rounds == 0 and first is not None:
            q0 = first[rows]
        elif gan is not None and rounds < gan_attempts:
            t0 = time.perf_counter()
            q0 = gan_starts(rows)
            solve_s[rows] += (time.perf_counter() - t0) / len(rows)
        elif nearest is not None and rounds < gan_attempts:
            starts, lookup_s = nearest
            q0 = starts[rows, rounds]
            if rounds == 0:
                solve_s[rows] += lookup_s  # each target's share of the nearest-neighbour queries
        else:
            q0 = robot.random_configurations(len(rows), rng)
        res = solver.solve_batch(q0, _nominals(robot, nominal_rows, q0, rows), targets={term: t[rows]},
                                 parallel=parallel)
        rounds += 1
        attempts[rows] += 1
        solve_s[rows] += res.time_s
        ratio = np.max(np.stack([res.residuals[lab] for lab in labels], axis=1) / tols, axis=1)
        better = res.success | (ratio < score[rows])
        keep = rows[better]
        q[keep] = res.q[better]
        score[keep] = ratio[better]
        for lab in labels:
            residuals[lab][keep] = res.residuals[lab][better]
        success[rows] |= res.success
        time_s[rows] = time.perf_counter() - wall0  # settled by this round, or until a later one
    return IKResult(q=q, success=success, time_s=time_s, attempts=attempts, residuals=residuals,
                    wall_s=time.perf_counter() - wall0, rounds=rounds, solve_s=solve_s)


#: initial guesses tried per batch of :func:`valid_solutions`
_BATCH = 32


def valid_solutions(robot: Robot, ik: Any, term: str, proj: Any, world: Any, target: NDArray[np.float64],
                    rng: np.random.Generator, want: int, max_tries: int) -> NDArray[np.float64]:
    """Up to ``want`` valid configurations reaching ``target``, (m, nq) with m <= ``want``: IK
    (``ik``, a :class:`~genplan.projection.GaussNewtonProjector` whose primary term ``term`` is
    aimed at ``target``) from batches of uniform guesses drawn from ``rng``, each solution then
    projected around itself with ``proj`` (the manifold the planner plans on, at its tighter
    tolerances) and kept when collision-free (``world.in_collision``); at most ``max_tries``
    guesses (rounded up to whole batches). What planning queries start and end at."""
    found: list[NDArray[np.float64]] = []
    tries = 0
    while len(found) < want and tries < max_tries:
        q0 = robot.random_configurations(_BATCH, rng)
        tries += _BATCH
        res = ik.solve_batch(q0, targets={term: np.repeat(target[None], _BATCH, 0)}, parallel=True)
        q = res.q[res.success]
        if len(q) == 0:
            continue
        pr = proj.solve_batch(q, q, parallel=True)
        q = pr.q[pr.success]
        if len(q) == 0:
            continue
        q = q[~np.asarray(world.in_collision(q), dtype=bool)]
        found.extend(q)
    return np.array(found[:want]).reshape(-1, robot.nq)
