"""Inverse kinematics for users: one call that keeps trying until every target is reached.

    res = genplan.solve_ik(panda, "panda_ik", targets, restarts=10, time_budget_s=0.005)
    res.q, res.success, res.time_s, res.attempts

The task's [condition] term (e.g. ``hand_position``, a FramePosition) is aimed at each target
(:func:`genplan.projection.condition_term`); the task's other terms (orientation, joint limits,
...) hold as in any projection. Each round solves every target still failing in one native batch
(``GaussNewtonProjector.solve_batch``: Rust, GIL released, rows on all cores), each from a new warm
start: the task's GAN (``init="gan"``, its shipped model by default: conditioned on the target,
a new noise draw and ensemble member every round) for the first half of the attempts, then
uniform random configurations (another basin of attraction when the GAN keeps proposing the same
one); or, with no model at all, ``init="data"``: the rows of the task's data set (the data a GAN
is trained on) whose condition frame is nearest the target, nearest first (better warm starts than
the shipped GANs', at about half their time: ``genplan bench ik``, README "IK for users"). A target stops being retried when it succeeds or after ``restarts``
retries; no round starts once the call has run for ``time_budget_s`` of wall-clock time (its setup
included), so the call returns within the budget plus one round (every target gets its first
attempt). ``time_s`` is each target's real elapsed time, from the call's start until it was
settled; ``solve_s`` its own share of the work (its solves plus its share of the GAN's sampling),
the per-target cost to compare solvers with.

The solver is the projector's damped Gauss-Newton with two changes for IK (beyond the paper;
``settings=SolverSettings(), nominal="start"`` gives the paper's solver back):

* :data:`IK_SETTINGS`: every step is taken whole (``max_backtracks=1``: no line search, as
  differential-IK solvers such as pink take their steps), with damping ``mu`` 1e-3. The paper's
  Armijo line search only ever goes downhill, so from a far start it settles in the nearest local
  minimum, most often with a joint stuck at a limit; whole steps jump past such minima.
* ``nominal="mid"``: the task's posture (its Posture terms without a ``q_nom`` of their own: the
  null-space posture of the paper's tasks) pulls towards the middle of each bounded joint's range
  instead of towards the warm start, which keeps joints off their limits.

Measured on tuning targets (seeds 1 / 2; the tables report seed 0), one attempt of 100
iterations from uniform random starts: Panda 70.2 / 72.6 % with the paper's solver, 94.8 / 96.0 %
with both changes (79.0 / 81.0 % with the posture change alone, 85.8 / 89.4 % with whole steps
alone at the same ``mu``); Talos 94.0 / 94.8 % -> 99.8 / 99.6 %; from GAN starts, Panda 92.8 / 94.6 % -> 97.8 / 98.4 %,
Talos 99.8 / 100 % -> 100 / 100 %, with fewer iterations (``python benches/ik_settings.py --seeds 1
2 --out benches/results/ik_settings.json``).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan._arrays import as_float_array
from genplan.errors import NonFiniteError, SettingsError, ShapeError, UnknownNameError
from genplan.robots import Robot

from genplan._core import SolverSettings

__all__ = ["ATTEMPT_ITERATIONS", "IK_SETTINGS", "INITS", "NOMINALS", "IKResult", "solve_ik"]

#: Warm starts :func:`solve_ik` accepts by name (or an (n, nq) array of configurations).
INITS = ("gan", "data", "uniform")
#: Nominal postures :func:`solve_ik` accepts by name (or an (nq,) / (n, nq) array): "mid", the
#: middle of each bounded joint's range (unbounded joints and a free-flyer base: the warm
#: start's); "start", the warm start (the paper's).
NOMINALS = ("mid", "start")
#: :func:`solve_ik`'s default solver settings: whole Gauss-Newton steps (``max_backtracks=1``),
#: ``mu`` 1e-3, the rest the paper's defaults (see the module text).
IK_SETTINGS = SolverSettings(mu=1e-3, max_backtracks=1)
#: Gauss-Newton iterations per attempt. Of the Panda IK targets a GAN attempt solves, nearly all
#: converge within 20 iterations (95.2 / 97.4 % of 500 targets within 20, 97.8 / 98.4 % within 100,
#: :data:`IK_SETTINGS`, tuning seeds 1 / 2: benches/results/ik_settings.json), while a failing
#: attempt then costs 20 iterations instead of 100: more, cheaper attempts fit a time budget.
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


def _targets(targets: ArrayLike) -> NDArray[np.float64]:
    t = as_float_array(targets, "targets")
    if t.ndim == 1:
        t = t[None, :]
    if t.ndim != 2 or t.shape[1] != 3:
        raise ShapeError(f"targets: expected positions of shape (n, 3) (or one (3,)), got {np.shape(targets)}")
    if not np.all(np.isfinite(t)):
        rows = np.nonzero(~np.isfinite(t).all(axis=1))[0]
        raise NonFiniteError(f"targets: rows {rows[:5].tolist()} are not finite")
    return np.ascontiguousarray(t)


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
    from genplan.gan.loading import load_sampler_model
    from genplan.gan.model import SamplerModel, check_model_robot

    if isinstance(model, SamplerModel):
        check_model_robot(model, robot)  # by kinematics, not by name
        return model
    return load_sampler_model(robot, model, task=task)


def _nearest_rows(robot: Robot, task: Any, targets: NDArray[np.float64],
                  k: int) -> tuple[NDArray[np.float64], float]:
    """Warm starts from the task's data set (:func:`genplan.gan.data.valid_configurations`: the
    data a learned sampler of the task is trained on, made once and cached): for each target, the
    ``k`` rows whose condition frame is nearest it, nearest first, (n, k, nq); and the queries'
    seconds per target (the k-d tree's construction, like a model's loading, is not counted)."""
    from scipy.spatial import cKDTree

    from genplan.gan.data import valid_configurations
    from genplan.projection import condition_term

    data = valid_configurations(robot, 25_000, 0, progress=False, task=task)
    tree = cKDTree(robot.frame_positions(data, condition_term(task).frame))
    k = min(k, len(data))
    t0 = time.perf_counter()
    _, idx = tree.query(targets, k=k)
    lookup_s = (time.perf_counter() - t0) / len(targets)
    return data[np.asarray(idx).reshape(len(targets), k)], lookup_s


def solve_ik(robot: Robot, task: Any, targets: ArrayLike, init: str | ArrayLike = "gan", restarts: int = 20,
             time_budget_s: float | None = None, model: str | os.PathLike[str] | Any = None, seed: int = 0,
             iterations: int = ATTEMPT_ITERATIONS, parallel: bool = True,
             settings: SolverSettings | None = None, nominal: str | ArrayLike = "mid") -> IKResult:
    """Solve the IK of ``task`` (a :class:`~genplan.projection.Task`, a shipped task's name or a
    task file, with a [condition]) for each row of ``targets`` ((n, 3) positions of the condition
    term's frame; one (3,) target is a batch of one), retrying the failures; see the module text.

    Args:
        robot: the robot (:func:`genplan.load`).
        init: "gan" (the task's GAN, then uniform), "data" (the rows of the task's data set
            whose condition frame is nearest the target, the next nearest at each retry, then
            uniform: no model needed), "uniform", or (n, nq) first warm starts (retries are
            uniform).
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
        ShapeError / NonFiniteError (``targets``, ``init``), UnknownNameError (``init``),
        SettingsError (``restarts``, ``time_budget_s``, ``iterations``, ``settings``), UnknownNameError /
        ShapeError / NonFiniteError (``nominal``), GenplanError (a task without [condition]).
    """
    from genplan.projection import GaussNewtonProjector, condition_term, load_task

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
    ik_task = load_task(task, robot)
    term = condition_term(ik_task).name
    solver = GaussNewtonProjector(robot, ik_task, settings.replace(max_iterations=int(iterations)))
    labels = [tm.label() for tm in ik_task.primary]
    tols = np.array([float(tm.tolerance) for tm in ik_task.primary])
    gan = _model(robot, ik_task, model) if isinstance(init, str) and init == "gan" else None
    gan_attempts = (restarts + 2) // 2  # attempts 1 .. this: GAN (or data); later ones uniform
    rng = np.random.default_rng(seed)
    nearest = _nearest_rows(robot, ik_task, t, gan_attempts) if isinstance(init, str) and init == "data" else None
    if gan is not None:
        # the generator run natively (one row costs microseconds; torch's call alone ~0.7 ms),
        # on targets clipped into the box its output is vouched for (GanModel.native_sampler)
        native_gan = gan.native_sampler(seed=seed)
        box = np.asarray(gan.config.target_box, dtype=np.float64)

        def gan_starts(rows: NDArray[np.intp]) -> NDArray[np.float64]:
            return gan.draw_native(native_gan, np.clip(t[rows], box[0], box[1]), rng)

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
