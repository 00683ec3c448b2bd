"""Adjusted trajectories made executable: projected, checked and timed, as plans are.

A decoded trajectory of a robot's joint-space family is close to the task's manifold (the model
was trained with its residuals, the objective may hold them) but not on it, and its K samples are
too sparse to check the motion between them. :func:`finish` turns each into the same
:class:`~genplan.trajectory.Trajectory` a plan gives:

1. every sample is projected onto the task's manifold with the native projector (tolerances ten
   times tighter than the task's, as the planner does, so that the chords between projected
   states stay within the tolerance), its posture pulled towards the sample; the last sample is
   projected onto the manifold *and* the objective's end target (an ``end_position`` or
   ``end_pose`` term's target for that problem), which makes the end exact; a solution in
   collision (a redundant arm reaches a target many ways) is solved again from the sample moved
   a little, its posture pulled towards the moved sample (towards the original one the solver
   returns to the solution in collision), up to ``END_RETRIES`` times;
2. the path is densified: wherever two consecutive states are more than ``resolution`` apart (max
   over the joints), states are interpolated and projected in turn, until every step is at most
   ``resolution`` (a projected state that jumps more than ``MAX_JUMP`` steps away from its
   neighbours is a failure: the path would change branch); then the chords between the states are
   held to the task's tolerance as the planner's are (a straying chord split at its projected
   midpoint); natively, one call for the batch (``genplan_core::projection::dense_path``, the
   paths on rayon's threads);
3. every dense state is checked against the joint limits (no tolerance) and the collision world
   (the robot, the scene and any per-problem obstacle); a path with a state in collision (the
   projection onto the manifold can undo part of a detour the adjustment made around an
   obstacle) is repaired first: its states near a collision are moved along the clearance's
   gradient, its part in the manifold's tangent space, and projected back onto the manifold,
   alternately (:func:`push_clear`), the path
   densified again (the end state keeps its target: it is pushed with the end projector), and
   then checked as any other;
4. the dense path is timed by TOPP-RA (:func:`genplan.trajectory.parameterize`), whose samples
   are checked again on the limits and the task's residuals (the paths on :data:`TIME_WORKERS`
   threads).

A problem that fails a step is reported as failed with the reason (the step, the sample), never
as a success.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan.errors import GenplanError, SettingsError

__all__ = ["finish", "densify", "push_clear", "FinishResult", "DEFAULT_RESOLUTION"]

#: the largest joint step (rad) between dense states: the planner's edge resolution
DEFAULT_RESOLUTION = 0.025
#: a projected interpolated state further than this many resolutions from its neighbours' chord
#: is a branch change (the planner's max_jump)
MAX_JUMP = 3.0
#: densification rounds (each at most halves the largest step; 0.4 rad -> 0.025 in four)
MAX_ROUNDS = 8
#: the end target's projection is retried this many times when its solution collides, from the
#: last sample moved by a normal step of END_SPREAD rad (doubled every three attempts)
END_RETRIES = 12
END_SPREAD = 0.05
#: a path with a dense state in collision is repaired: the states closer than CLEAR_MARGIN (m) to
#: a collision are stepped along the gradient of the robot's minimum signed distance (finite
#: differences, FD_STEP rad) to CLEAR_MARGIN, at most CLEAR_MAX_STEP rad a joint, then projected
#: back onto the manifold (posture at the stepped state), CLEAR_STEPS times; then densified and
#: checked again, CLEAR_ROUNDS times
CLEAR_MARGIN = 0.01
CLEAR_MAX_STEP = 0.05
CLEAR_STEPS = 8
CLEAR_ROUNDS = 3
FD_STEP = 1e-5
#: the paths are timed on this many threads (at most one per core; see :func:`_threads`)
TIME_WORKERS = 2


@dataclass
class FinishResult:
    """What :func:`finish` returns, per problem (B): ``success``; ``trajectories`` (a
    :class:`~genplan.trajectory.Trajectory`, or None for a failure); ``reasons`` (None, or why it
    failed); ``paths`` (the dense paths, or None); ``end_error_m`` (the distance of the end
    target's frame from its target after finishing; NaN without such a term or when the problem
    failed before); ``max_residual_ratio`` (the largest residual over its tolerance along the
    timed trajectory; NaN for a failure); ``seconds``: the time of each stage for the batch.
    After an adjustment with several starts: ``start_index`` the start whose trajectory was
    finished (see :class:`~genplan.seq2seq.adjust.AdjustResult`), ``starts_finished`` how many of
    a problem's starts were finished (more than one when the kept one failed and another start's
    trajectory was tried: the first that passes is the result)."""

    success: NDArray[np.bool_]
    trajectories: list[Any]
    reasons: list[str | None]
    paths: list[NDArray[np.float64] | None]
    end_error_m: NDArray[np.float64]
    max_residual_ratio: NDArray[np.float64]
    seconds: dict[str, float] = field(default_factory=dict)
    start_index: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    starts_finished: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def batch(self) -> int:
        return len(self.trajectories)

    @property
    def success_rate(self) -> float:
        return float(np.mean(self.success)) if self.batch else float("nan")


def _end_target(result: Any) -> tuple[Any, str, NDArray[np.float64]] | None:
    """(term, frame, targets (B, 3) or (B, 4, 4)) of the objective's end target, or None."""
    from genplan.seq2seq.objectives import EndPose, EndPosition

    obj = getattr(result, "objective", None)
    rows = getattr(result, "rows", None)  # a _Candidates' problems
    for t in getattr(obj, "terms", ()):
        if isinstance(t, (EndPosition, EndPose)) and t._target is not None:
            targets = t._target.double().cpu().numpy()
            return t, t.frame, targets if rows is None else targets[rows]
    return None


@dataclass
class _Candidates:
    """Other starts' trajectories of some problems of an adjustment, finished as it is: ``p``
    (m, K, d), ``rows`` (m,) the problems they belong to."""

    p: NDArray[np.float64]
    rows: NDArray[np.int64]
    context: Any
    objective: Any


def finish(result: Any, *, world: Any = None, robot: Any = None, task: Any = None,
           resolution: float = DEFAULT_RESOLUTION, velocity_scale: float = 1.0, acceleration_scale: float = 1.0,
           rate_hz: float = 1000.0, time_parameterize: bool = True) -> FinishResult:
    """Project, densify, check and time the adjusted trajectories of ``result`` (an
    :class:`~genplan.seq2seq.adjust.AdjustResult` of a robot's joint-space model).

    ``world``: a :class:`~genplan.collision.CollisionWorld` (or one per problem, for
    per-problem obstacles); default: the robot's world with the scene the adjustment was given.
    ``robot``, ``task``: default the adjustment's. ``resolution``: the largest joint step between
    dense states (rad). ``velocity_scale``, ``acceleration_scale``, ``rate_hz``: TOPP-RA's (see
    :func:`genplan.trajectory.parameterize`); ``time_parameterize=False`` stops after the checks
    (the trajectories are then None for every problem and ``paths`` holds the checked paths).
    """
    from genplan.projection import FramePose, FramePosition, GaussNewtonProjector, Task, manifold_task
    from genplan.trajectory import parameterize

    ctx = result.context
    robot = robot if robot is not None else getattr(ctx, "robot", None)
    task = task if task is not None else getattr(ctx, "task", None)
    if robot is None:
        raise SettingsError("finish: the adjustment has no robot (a task-space family such as the pancake's has "
                            "nothing to project); pass robot= for a joint-space model")
    p = np.asarray(result.p, dtype=np.float64)
    b, k, n = p.shape
    if n != robot.nq:
        raise SettingsError(f"finish: the trajectories have {n} axes, robot '{robot.name}' has {robot.nq} joints")
    if not (np.isfinite(resolution) and resolution > 0):
        raise SettingsError(f"finish: resolution must be a positive number of radians, got {resolution!r}")
    worlds = _worlds(world, robot, ctx, b)
    manifold = None
    if task is not None:
        manifold = manifold_task(task, robot) if task.condition is not None else task
    seconds: dict[str, float] = {}
    reasons: list[str | None] = [None] * b
    end = _end_target(result)

    # 1. project every sample; the last onto the end target as well
    t0 = time.perf_counter()
    q = p.copy()
    if manifold is not None:
        proj = GaussNewtonProjector(robot, manifold.with_tolerances_scaled(0.1))
        inner = q[:, :-1].reshape(-1, n) if end is not None else q.reshape(-1, n)
        res = proj.solve_batch(inner, inner)
        inner_q = res.q.reshape(b, -1, n)
        ok = res.success.reshape(b, -1)
        q[:, :inner_q.shape[1]] = inner_q
        for i in range(b):
            if not ok[i].all():
                reasons[i] = f"sample {int(np.argmin(ok[i]))} could not be projected onto the task's manifold"
    if end is not None:
        term, frame, targets = end
        label = "end_target"
        extra = (FramePosition(name=label, frame=frame, target=targets[0], weight=50.0, tolerance=1e-4)
                 if targets.ndim == 2 else
                 FramePose(name=label, frame=frame, target=targets[0], weight=50.0, tolerance=1e-4))
        base = manifold.primary if manifold is not None else ()
        end_task = Task(primary=(*base, extra), secondary=manifold.secondary if manifold is not None else (),
                        name="finish_end")
        proj_end = GaussNewtonProjector(robot, end_task.with_tolerances_scaled(0.1))
        last = p[:, -1]
        res = proj_end.solve_batch(last, last, targets={label: targets})
        q[:, -1] = res.q
        ok = res.success & ~_hits(worlds, res.q)
        # a solution in collision: first pushed out along the clearance's gradient (its part along the
        # manifold and the target: the self-motion), on the target
        for i in np.nonzero(res.success & ~ok)[0]:
            pushed = push_clear(res.q[i:i + 1], worlds[i],
                                lambda x, i=i: proj_end.solve_batch(x, x, targets={label: np.repeat(targets[i:i + 1], len(x), 0)}),
                                constraints=proj_end)
            if pushed is not None and not _hits([worlds[i]], pushed)[0]:
                q[i, -1] = pushed[0]
                ok[i] = True
        # a solution in collision (a redundant arm has many): again from the sample moved a little
        rng = np.random.default_rng(0)
        lo, hi = np.asarray(robot.lower, dtype=float), np.asarray(robot.upper, dtype=float)
        for attempt in range(END_RETRIES):
            todo = np.nonzero(~ok)[0]
            if len(todo) == 0:
                break
            sigma = END_SPREAD * 2 ** (attempt // 3)
            seeds = np.clip(last[todo] + sigma * rng.standard_normal((len(todo), n)), lo, hi)
            again = proj_end.solve_batch(seeds, seeds, targets={label: targets[todo]})
            good = again.success & ~_hits([worlds[i] for i in todo], again.q)
            q[todo[good], -1] = again.q[good]
            ok[todo[good]] = True
        for i in range(b):
            if reasons[i] is None and not ok[i]:
                reasons[i] = ("the last sample could not be projected onto the manifold and the end target "
                              f"without a collision ({END_RETRIES + 1} attempts)")
    seconds["project"] = time.perf_counter() - t0

    # 2. densify, holding the chords between dense states to the task's tolerance
    t0 = time.perf_counter()
    proj_dense = GaussNewtonProjector(robot, manifold.with_tolerances_scaled(0.1)) if manifold is not None else None
    chords = _ChordCheck(robot, manifold) if manifold is not None else None
    # one native call for the batch: the paths on rayon's threads
    dense = _dense(q, resolution, proj_dense, chords.check if chords is not None else None,
                   todo=[r is None for r in reasons])
    paths: list[NDArray[np.float64] | None] = [None] * b
    for i, d in enumerate(dense):
        if d is not None:
            paths[i], reasons[i] = d
    seconds["densify"] = time.perf_counter() - t0

    # 3. check limits and collisions
    t0 = time.perf_counter()
    lo, hi = np.asarray(robot.lower, dtype=float), np.asarray(robot.upper, dtype=float)
    for i in range(b):
        path = paths[i]
        if reasons[i] is not None or path is None:
            continue
        over = (path < lo) | (path > hi)
        if over.any():
            s, j = np.argwhere(over)[0]
            reasons[i] = (f"dense state {int(s)} of {len(path)}: joint {robot.joint_names[j]} at {path[s, j]:.6g} is "
                          f"outside its limits [{lo[j]:.6g}, {hi[j]:.6g}]")
            continue
        hit = np.asarray(worlds[i].in_collision(path), dtype=bool)
        if hit.any() and proj_dense is not None and chords is not None:
            path, why = _repair(path, worlds[i], proj_dense, chords, resolution)
            paths[i] = path
            if why is not None:
                reasons[i] = why
                continue
            if ((path < lo) | (path > hi)).any():
                reasons[i] = "the path repaired out of collision leaves the joint limits"
                continue
            hit = np.asarray(worlds[i].in_collision(path), dtype=bool)
        if hit.any():
            s = int(np.argmax(hit))
            reasons[i] = f"dense state {s} of {len(path)} is in collision"
    seconds["check"] = time.perf_counter() - t0

    # 4. time
    t0 = time.perf_counter()
    trajectories: list[Any] = [None] * b
    ratio = np.full(b, np.nan)
    if time_parameterize:
        to_time = [i for i in range(b) if reasons[i] is None]

        def timed(i: int) -> Any:
            try:
                return parameterize(robot, paths[i], manifold, rate_hz=rate_hz, velocity_scale=velocity_scale,
                                    acceleration_scale=acceleration_scale)
            except GenplanError as exc:
                return exc

        for i, traj in zip(to_time, _threads(timed, to_time)):
            if isinstance(traj, GenplanError):
                reasons[i] = f"timing: {traj}"
                continue
            r = traj.max_residual_ratio if manifold is not None else 0.0
            if manifold is not None and not traj.within_tolerance:
                reasons[i] = f"timing: the timed samples leave the task's tolerance ({r:.3g} x)"
                continue
            trajectories[i] = traj
            ratio[i] = r
    seconds["time"] = time.perf_counter() - t0

    end_err = np.full(b, np.nan)
    if end is not None:
        term, frame, targets = end
        for i in range(b):
            if paths[i] is not None:
                pos = robot.frame_positions(paths[i][-1:], frame)[0]
                goal = targets[i] if targets.ndim == 2 else targets[i][:3, 3]
                end_err[i] = float(np.linalg.norm(pos - goal))
    success = np.array([reasons[i] is None and (trajectories[i] is not None or not time_parameterize)
                        for i in range(b)], dtype=bool)
    out = FinishResult(success=success, trajectories=trajectories, reasons=reasons, paths=paths,
                       end_error_m=end_err, max_residual_ratio=ratio, seconds=seconds,
                       start_index=np.array(getattr(result, "start_index", np.zeros(b, dtype=np.int64)), dtype=np.int64),
                       starts_finished=np.ones(b, dtype=np.int64))
    alternatives = getattr(result, "alternatives", None)
    if alternatives:
        _fall_back(out, result, alternatives, worlds, dict(robot=robot, task=task, resolution=resolution,
                                                           velocity_scale=velocity_scale,
                                                           acceleration_scale=acceleration_scale, rate_hz=rate_hz,
                                                           time_parameterize=time_parameterize))
    return out


def _fall_back(out: FinishResult, result: Any, alternatives: list[list[tuple[int, NDArray[np.float64]]]],
               worlds: list[Any], kwargs: dict[str, Any]) -> None:
    """The failures of ``out`` finished again from their other starts' trajectories (lowest
    objective first), round by round, each round one batch; the first that passes replaces the
    failure (``out`` updated in place; the reason kept is the kept start's)."""
    t0 = time.perf_counter()
    for rnd in range(max(len(a) for a in alternatives)):
        todo = np.array([i for i in range(out.batch) if not out.success[i] and len(alternatives[i]) > rnd], dtype=np.int64)
        if len(todo) == 0:
            break
        cand = _Candidates(p=np.stack([alternatives[i][rnd][1] for i in todo]), rows=todo, context=result.context,
                           objective=result.objective)
        again = finish(cand, world=[worlds[i] for i in todo], **kwargs)
        out.starts_finished[todo] += 1
        for j, i in enumerate(todo):
            if again.success[j]:
                out.success[i] = True
                out.trajectories[i] = again.trajectories[j]
                out.reasons[i] = None
                out.paths[i] = again.paths[j]
                out.end_error_m[i] = again.end_error_m[j]
                out.max_residual_ratio[i] = again.max_residual_ratio[j]
                out.start_index[i] = alternatives[i][rnd][0]
    out.seconds["other_starts"] = time.perf_counter() - t0


def push_clear(q: NDArray[np.float64], world: Any, project: Any, margin: float = CLEAR_MARGIN,
               steps: int = CLEAR_STEPS, constraints: Any = None) -> NDArray[np.float64] | None:
    """The states ``q`` (m, nq) moved at least ``margin`` (m) away from any collision in
    ``world``, alternating a step along the gradient of the minimum signed distance
    (``world.min_distance``, by finite differences; the step that would bring it to ``margin``,
    at most :data:`CLEAR_MAX_STEP` rad a joint) with ``project(states)`` (a projector's
    ``solve_batch`` onto the task's manifold: a result with ``q`` and ``success``), up to ``steps``
    times; the states already that clear are left as they are. With ``constraints`` (a
    :class:`~genplan.projection.GaussNewtonProjector` of the same manifold) the gradient is first
    projected onto the manifold's tangent space at each state, the null space of the Jacobian of
    the projector's primary terms: a step across the manifold is what the projection takes back,
    so only the tangent part of the gradient moves a state clear, and the step is sized on it.
    Returns the states (each one projected, possibly still nearer than ``margin`` when the steps
    ran out: the caller checks them), or None when a projection failed."""
    q = np.array(q, dtype=np.float64)
    n = q.shape[1]
    eye = FD_STEP * np.eye(n)
    for _ in range(steps):
        d = np.asarray(world.min_distance(q), dtype=np.float64).reshape(len(q))
        todo = np.nonzero(d < margin)[0]
        if len(todo) == 0:
            break
        probes = (q[todo][:, None, :] + eye[None]).reshape(-1, n)
        grad = (np.asarray(world.min_distance(probes), dtype=np.float64).reshape(len(todo), n) - d[todo, None]) / FD_STEP
        if constraints is not None:
            grad = _tangent(constraints, q[todo], grad)
        norm2 = np.maximum(np.einsum("ij,ij->i", grad, grad), 1e-12)
        step = grad * ((margin - d[todo]) / norm2)[:, None]
        step *= np.minimum(1.0, CLEAR_MAX_STEP / np.maximum(np.abs(step).max(axis=1), 1e-12))[:, None]
        res = project(q[todo] + step)
        if not np.all(res.success):
            return None
        q[todo] = res.q
    return q


def _tangent(proj: Any, q: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """The vectors ``v`` (m, nq) projected onto the tangent space of ``proj``'s manifold at the
    states ``q`` (m, nq): ``v - J^+ J v`` with ``J`` the Jacobian of its primary terms' residuals
    (a term that is inactive there, such as a joint limit not reached, has zero rows). Without a
    native solver (the Pinocchio backend), or for a robot whose configuration has more
    coordinates than velocities, ``v`` is returned as it is."""
    native = proj.native
    if native is None:
        return v
    _, jac = native.primary_residuals(q, True)
    jac = np.asarray(jac, dtype=np.float64)
    if jac.shape[-1] != q.shape[1]:
        return v
    return v - np.einsum("mij,mj->mi", np.linalg.pinv(jac, rcond=1e-8), np.einsum("mij,mj->mi", jac, v))


def _repair(path: NDArray[np.float64], world: Any, proj: Any, chords: Any,
            resolution: float) -> tuple[NDArray[np.float64], str | None]:
    """``path`` (a dense path with states in collision in ``world``) with its states nearer than
    :data:`CLEAR_MARGIN` to a collision (but its ends, fixed: the start is the input's, the end
    solved on its target) pushed clear (:func:`push_clear` with ``proj``), densified and its
    chords held again, up to :data:`CLEAR_ROUNDS` times while a state collides. Returns the path
    and None, or the path so far and why it could not be repaired."""
    for _ in range(CLEAR_ROUNDS):
        hit = np.asarray(world.in_collision(path), dtype=bool)
        if not hit.any():
            return path, None
        near = np.asarray(world.min_distance(path), dtype=np.float64) < CLEAR_MARGIN
        near[0] = near[-1] = False
        rows = np.nonzero(near)[0]
        if len(rows) == 0:
            return path, None  # only an end collides: the check names it
        pushed = push_clear(path[rows], world, lambda x: proj.solve_batch(x, x), constraints=proj)
        if pushed is None:
            return path, "a state pushed out of collision could not be projected back onto the task's manifold"
        path = path.copy()
        path[rows] = pushed
        path, why = densify(path, resolution, proj)
        if why is None:
            path, why = chords.hold(path, proj, resolution)
        if why is not None:
            return path, f"the path repaired out of collision: {why}"
    return path, None


def _threads(fn: Any, items: list[int]) -> list[Any]:
    """``[fn(i) for i in items]`` on :data:`TIME_WORKERS` threads (at most one per core), in
    order: TOPP-RA, the samples and their residual check run natively without the GIL, so one
    path's native work overlaps another's Python. An exception ``fn`` raises reaches the caller
    unchanged (the items not started are cancelled)."""
    import os
    from concurrent.futures import ThreadPoolExecutor

    workers = min(TIME_WORKERS, os.cpu_count() or 1, len(items))
    if workers <= 1:
        return [fn(i) for i in items]
    pool = ThreadPoolExecutor(workers, thread_name_prefix="genplan-finish")
    try:
        return list(pool.map(fn, items))
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _hits(worlds: list[Any], q: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Per row of ``q``, whether it is in collision in its problem's world."""
    if len(q) and all(w is worlds[0] for w in worlds):
        return np.asarray(worlds[0].in_collision(q), dtype=bool)
    return np.array([bool(w.in_collision(row)) for w, row in zip(worlds, q)], dtype=bool)


def _worlds(world: Any, robot: Any, ctx: Any, b: int) -> list[Any]:
    """One collision world per problem."""
    if world is None:
        world = robot.collision_world()
        scene = getattr(ctx, "scene", None)
        if scene is not None:
            world.add_scene(scene)
    if isinstance(world, Sequence) and not isinstance(world, (str, bytes)):
        worlds = list(world)
        if len(worlds) != b:
            raise SettingsError(f"finish: world must be one collision world or one per problem ({b}), got {len(worlds)}")
        return worlds
    return [world] * b


class _ChordCheck:
    """The planner's chord rule (rust/core/src/planning/constrained.rs, ``hold_chords``) for a
    dense path: the midpoint of every chord between consecutive states is evaluated on the task's
    primary terms (no solver step) and a chord whose midpoint strays beyond :attr:`FRACTION` of
    the tolerance is split at its projected midpoint, in :attr:`ROUNDS` rounds, down to
    ``resolution / 8``; the spline TOPP-RA lays through the states then stays within the
    tolerance. Native: ``genplan_core::projection::hold_chords``."""

    ROUNDS = 3
    FRACTION = 0.75

    def __init__(self, robot: Any, task: Any) -> None:
        from genplan.projection import GaussNewtonProjector

        self.check = GaussNewtonProjector(robot, task)

    def hold(self, path: NDArray[np.float64], proj: Any, resolution: float) -> tuple[NDArray[np.float64], str | None]:
        """``path`` (a dense path) with its straying chords split at their midpoints projected
        with ``proj``; the path and None, or the path so far and why it failed."""
        out = _dense(np.asarray(path, dtype=np.float64)[None], resolution, proj, self.check, densify_first=False)[0]
        assert out is not None
        return out


#: the failures of the native dense paths (genplan_core::projection::DenseFailure), as reasons
_DENSE_FAILURES = {
    "projection": "an interpolated state could not be projected onto the task's manifold",
    "jump": "a projected interpolated state jumped {value:.3g} rad off its chord (a change of branch)",
    "steps": "the path could not be densified to {resolution} rad steps (largest {value:.3g})",
    "chord_too_short": "a chord strays off the task's manifold even at an eighth of the resolution",
    "chord_projection": "a chord's midpoint could not be projected onto the task's manifold",
}


def _native(proj: Any, what: str) -> Any:
    """The native solver of the projector ``proj`` (None for None); a SettingsError naming
    ``what`` for a projector without one (the Pinocchio backend)."""
    if proj is None:
        return None
    native = getattr(proj, "native", None)
    if native is None:
        raise SettingsError(f"{what}: dense paths need a projector with the native backend "
                            "(GaussNewtonProjector(..., backend='native'))")
    return native


def _dense(paths: NDArray[np.float64], resolution: float, proj: Any, check: Any, *, todo: Sequence[bool] | None = None,
           densify_first: bool = True) -> list[tuple[NDArray[np.float64], str | None] | None]:
    """Per path of ``paths`` (B, K, n) whose ``todo`` flag is set (all by default): the path
    made dense with ``proj`` (:func:`densify`, when ``densify_first``) and then, with ``check``
    (the task's projector at its own tolerances), its chords held (:class:`_ChordCheck`), and
    None or why it failed; None for a path not to do. One native call for the batch
    (``_core.dense_paths``: the paths on rayon's threads, every row checked first)."""
    if not (np.isfinite(resolution) and resolution > 0):
        raise SettingsError(f"resolution must be a positive number of radians, got {resolution!r}")
    from genplan import _core

    out = _core.dense_paths(np.ascontiguousarray(paths, dtype=np.float64), float(resolution), max_jump=MAX_JUMP,
                            max_rounds=MAX_ROUNDS, chord_rounds=_ChordCheck.ROUNDS, chord_fraction=_ChordCheck.FRACTION,
                            projector=_native(proj, "proj"), chords=_native(check, "chords") if proj is not None else None,
                            todo=None if todo is None else [bool(t) for t in todo], densify=densify_first)
    return [None if d is None else
            (d[0], None if d[1] is None else _DENSE_FAILURES[d[1][0]].format(value=d[1][1], resolution=resolution))
            for d in out]


def densify(q: NDArray[np.float64], resolution: float, proj: Any = None) -> tuple[NDArray[np.float64], str | None]:
    """The path through the states ``q`` (K, n) with every step at most ``resolution`` (max over
    the joints): states interpolated linearly between neighbours further apart and projected
    with ``proj`` (a :class:`~genplan.projection.GaussNewtonProjector` with the native backend,
    each around itself, or None to keep the interpolation), in rounds (at most
    :data:`MAX_ROUNDS`; steps of up to 1.5 resolutions accepted after them); a projected state
    more than :data:`MAX_JUMP` resolutions off its chord is a change of branch. Returns the path
    and None, or the path so far and why it failed. Native:
    ``genplan_core::projection::densify``."""
    q = np.asarray(q, dtype=np.float64)
    if q.ndim != 2:
        from genplan.errors import ShapeError

        raise ShapeError(f"q: expected shape (K, n), got {q.shape}")
    out = _dense(q[None], resolution, proj, None)[0]
    assert out is not None
    return out
