"""Planning queries: a start and goal configurations, on a task's manifold and collision-free.

* :func:`make_query`: the query of one problem, for any robot, task and scene: a start
  configuration projected onto the task's manifold, and goals given as configurations or reached
  by IK for a target of the task's condition, or for a pose of any frame (what
  :func:`genplan.planning.plan` plans). In free space (a free task, ``Task.free``) nothing is
  projected: the start and goals must be within the joint limits as they are.
* :func:`make_queries`: seeded queries of a planning environment (the GAN paper's Table II):
  targets drawn as the environment says (:class:`QuerySource`, e.g.
  :class:`genplan.planning.environments.Environment`), reached by IK from uniform guesses.

Both project their configurations as tightly as the planner projects its states (the task's
tolerances times :data:`TOLERANCE_FACTOR`) and keep only collision-free ones; IK solutions come
from :func:`genplan.ik.valid_solutions`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from genplan import projection as P
from genplan.collision import CollisionWorld
from genplan.errors import GenplanError, InvalidGoalError, InvalidStartError, SettingsError
from genplan.ik import _targets, frame_task, solve_ik, valid_solutions
from genplan.robots import Robot

__all__ = ["TOLERANCE_FACTOR", "Query", "QuerySource", "make_queries", "make_query", "query_manifold"]

#: the planner projects ten times tighter than the constraint's tolerances (see Planner)
TOLERANCE_FACTOR = 0.1


@dataclass(frozen=True)
class Query:
    """One planning problem: a start and K goal configurations (rows), with the task-space
    targets they were solved for."""

    start: NDArray[np.float64]
    goals: NDArray[np.float64]
    start_target: NDArray[np.float64]
    goal_target: NDArray[np.float64]


class QuerySource(Protocol):
    """What :func:`make_queries` reads of an environment: the robot it is for, its collision
    world, the IK task and the targets it draws (:class:`genplan.planning.environments.Environment`
    holds them as data)."""

    name: str
    robot: str
    #: the IK task (a shipped task's name or a task file), None: the robot's ``<robot>_ik``
    task: str | None
    #: the term of that task whose target rotation is a yaw about the vertical, or None
    yaw_term: str | None
    start_yaw: float
    goal_yaw: float
    #: discrete target positions, one drawn per query; or (when empty) a box ``[[low], [high]]``
    start_targets: Sequence[tuple[float, float, float]]
    goal_targets: Sequence[tuple[float, float, float]]
    start_box: Any
    goal_box: Any

    def world(self, robot: Robot) -> Any:
        """The robot's collision world with the environment's obstacles."""


def _ik_task(robot: Robot, env: QuerySource, yaw: float) -> P.Task:
    """The environment's query IK task (its ``task``, default the robot's ``<robot>_ik``), its
    ``yaw_term`` aimed at a rotation by ``yaw`` about the vertical."""
    task = P.load_task(env.task if env.task is not None else P.default_task_name(robot), robot)
    if env.yaw_term is not None:
        task = task.with_targets(**{env.yaw_term: pin.utils.rotate("z", yaw)})
    return task


def _target_term(task: P.Task) -> str:
    if task.condition is None:
        raise GenplanError(f"query IK task '{task.name}' has no [condition]: which term the targets aim is unknown")
    return task.condition.term


def make_queries(env: QuerySource, robot: Robot, n: int, seed: int = 0, k: int = 10, progress: bool = False,
                 max_tries: int = 200) -> list[Query]:
    """``n`` seeded queries of the environment ``env`` for ``robot``: for each, a target drawn
    for the start and one for the goals (:class:`QuerySource`), and IK solutions for them
    (:func:`genplan.ik.valid_solutions`: from uniform guesses, projected as tightly as the planner
    projects its states, collision-free in the environment); a query whose start or ``k`` goals
    are not found in ``max_tries`` guesses is drawn again. The same seed gives the same queries."""
    if robot.name != env.robot:
        raise GenplanError(f"environment '{env.name}' is for {env.robot}, not {robot.name}")
    if n < 1 or k < 1:
        raise SettingsError(f"n and k must be >= 1, got n={n}, k={k}")
    rng = np.random.default_rng(seed)
    world = env.world(robot)
    # starts and goals are projected as tightly as the planner projects its states
    ik_start = P.GaussNewtonProjector(robot, _ik_task(robot, env, env.start_yaw))
    ik_goal = P.GaussNewtonProjector(robot, _ik_task(robot, env, env.goal_yaw))
    # the manifold the planner plans on: the IK task's (for the paper's tasks, the projection task)
    proj = P.GaussNewtonProjector(robot, P.manifold_task(ik_start.task, robot).with_tolerances_scaled(TOLERANCE_FACTOR))

    def draw(discrete: tuple[tuple[float, float, float], ...], box) -> NDArray[np.float64]:  # type: ignore[no-untyped-def]
        if discrete:
            return np.array(discrete[rng.integers(len(discrete))], dtype=np.float64)
        lo, hi = np.asarray(box, dtype=np.float64)
        return rng.uniform(lo, hi)

    out: list[Query] = []
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n, desc=f"queries {env.name}", unit="query", leave=False)
    attempts = 0
    while len(out) < n:
        attempts += 1
        if attempts > 20 * n + 20:
            raise RuntimeError(f"{env.name}: could not build {n} queries (IK keeps failing or colliding)")
        start_target = draw(env.start_targets, env.start_box)
        start = valid_solutions(robot, ik_start, _target_term(ik_start.task), proj, world, start_target, rng, 1, max_tries)
        if len(start) == 0:
            continue
        goal_target = draw(env.goal_targets, env.goal_box)
        goals = valid_solutions(robot, ik_goal, _target_term(ik_goal.task), proj, world, goal_target, rng, k, max_tries)
        if len(goals) < k:
            continue
        out.append(Query(start=start[0], goals=goals, start_target=start_target, goal_target=goal_target))
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    return out


def _condition_frame(task: P.Task) -> str:
    """The frame the task's condition term aims (its targets are positions of it)."""
    return P.condition_term(task).frame


def _project_free(robot: Robot, proj: P.GaussNewtonProjector | None, world: CollisionWorld, q: ArrayLike, what: str,
                  error: type[GenplanError]) -> NDArray[np.float64]:
    """``q`` projected with ``proj`` (posture around itself; None: free space, ``q`` as it is,
    within the joint limits) and checked collision-free in ``world``, else ``error`` naming
    ``what``, why (the joint outside its limits, the pairs in contact)."""
    q0 = robot.check_configuration(q, what)
    if q0.ndim != 1:
        raise error(f"{what}: expected one configuration of shape ({robot.nq},), got {q0.shape}")
    if proj is None:
        out = q0
        outside = np.nonzero((out < robot.lower) | (out > robot.upper))[0]
        if len(outside):
            j = int(outside[0])
            raise error(f"{what}: coordinate {j} (of joint {_joint_of(robot, j)}) at {out[j]:.6g} is outside its "
                        f"limits [{robot.lower[j]:.6g}, {robot.upper[j]:.6g}]")
    else:
        res = proj.solve_batch(q0[None], q0[None], parallel=False)
        if not bool(res.success[0]):
            raise error(f"{what}: cannot be projected onto the manifold of task '{proj.task.name}' from there "
                        f"(largest residual per term: {({k: round(float(v[0]), 6) for k, v in res.residuals.items()})})")
        out = res.q[0]
    if bool(np.asarray(world.in_collision(out))):
        pairs = sorted((d, a, b) for a, b, d in world.native.close_pairs(list(map(float, out)), 0.0) if d <= 0)
        names = ", ".join(f"{a} and {b}" for _, a, b in pairs[:3])
        raise error(f"{what}: in collision on the manifold{f' ({names})' if names else ''}")
    return out


def _joint_of(robot: Robot, iq: int) -> str:
    """The name of the joint whose configuration holds coordinate ``iq``."""
    for jid in range(1, robot.model.njoints):
        j = robot.model.joints[jid]
        if j.idx_q <= iq < j.idx_q + j.nq:
            return str(robot.model.names[jid])
    return "?"


def query_manifold(task: P.Task, robot: Robot) -> P.Task:
    """The manifold a query of ``task`` is planned on: the task itself when it has no
    [condition] (e.g. ``free``), else :func:`genplan.projection.manifold_task`."""
    return task if task.condition is None else P.manifold_task(task, robot)


def _pose_goals(robot: Robot, manifold: P.Task, proj: P.GaussNewtonProjector | None, world: CollisionWorld,
                frame: str, target: NDArray[np.float64], k: int, seed: int, max_tries: int) -> NDArray[np.float64]:
    """Up to ``k`` goals whose ``frame`` reaches ``target`` (a position (3,) or a pose (4, 4)):
    :func:`genplan.solve_ik` of :func:`genplan.ik.frame_task` (the manifold's terms held too)
    from batches of uniform warm starts, each solution projected onto the manifold as tightly as
    the planner projects (free space: within the joint limits as it is) and kept when
    collision-free; at most ``max_tries`` warm starts (rounded up to whole batches)."""
    ik_task = frame_task(robot, frame, None if manifold.free else manifold)
    batch = 32
    found: list[NDArray[np.float64]] = []
    tries = 0
    while len(found) < k and tries < max_tries:
        res = solve_ik(robot, ik_task, np.repeat(target[None], batch, 0), init="uniform", restarts=0,
                       seed=seed + tries, parallel=True)
        tries += batch
        q = res.q[res.success]
        if len(q) and proj is not None:
            pr = proj.solve_batch(q, q, parallel=True)
            q = pr.q[pr.success]
        if len(q):
            q = q[np.all((q >= robot.lower) & (q <= robot.upper), axis=1)]
        if len(q):
            q = q[~np.asarray(world.in_collision(q), dtype=bool)]
        found.extend(q)
    return np.array(found[:k]).reshape(-1, robot.nq)


def make_query(robot: Robot, task: P.Task, world: CollisionWorld, start: ArrayLike | str = "default",
               goal: ArrayLike | None = None, target: ArrayLike | None = None, *, frame: str | None = None,
               k: int = 10, seed: int = 0, max_tries: int = 2000, start_target: ArrayLike | None = None) -> Query:
    """A start (``"default"``: the robot's default configuration, or a configuration) projected
    onto the manifold of ``task`` (:func:`query_manifold`) and checked free, and goals: ``goal``
    (a configuration, or several as rows) projected and checked likewise, or ``k`` IK solutions
    for ``target``, from up to ``max_tries`` uniform guesses, collision-free. In free space (a
    free manifold, ``Task.free``) nothing is projected: a start or goal outside the joint limits
    is refused as it is. ``start_target`` (instead of ``start``): the start is the first such IK
    solution for that target (as ``target``, with a generator of its own), for a robot whose
    default configuration is off the manifold's free part.

    ``target``: the condition term's target (3 numbers) for a task with a [condition]; or a
    pose of ``frame`` (a 4x4 homogeneous matrix, or 7 numbers: a position and a unit
    quaternion ``x y z qx qy qz qw``; or a position alone), solved by
    :func:`genplan.solve_ik` with the manifold's terms held (``frame`` defaults to the
    condition term's frame; a task without a [condition] needs it).

    Errors name the argument: InvalidStartError / InvalidGoalError (off the manifold and not
    projectable, outside the joint limits in free space, in collision, no IK solution found, a
    bad target),
    SettingsError (neither or both of goal and target, both start and start_target, no ``frame``
    for a target of a task without a [condition]), UnknownNameError (an unknown frame). A target
    of another shape, not finite or not a pose is an InvalidGoalError (InvalidStartError for
    ``start_target``) saying so."""
    if (goal is None) == (target is None):
        raise SettingsError("give a goal configuration or a target (of the task's condition, or a pose of a frame), "
                            "not both or neither")
    if start_target is not None and not (isinstance(start, str) and start == "default"):
        raise SettingsError("give a start configuration or a start_target (a start by IK), not both")
    if isinstance(k, bool) or not isinstance(k, int) or k < 1:
        raise SettingsError(f"k must be a positive integer, got {k!r}")
    manifold = query_manifold(task, robot)
    proj = None if manifold.free else P.GaussNewtonProjector(robot, manifold.with_tolerances_scaled(TOLERANCE_FACTOR))
    q_start = robot.q_default if isinstance(start, str) and start == "default" else start
    if isinstance(q_start, str):
        raise InvalidStartError(f"start: expected 'default' or a configuration, got {start!r}")
    if frame is None and task.condition is not None:
        frame = _condition_frame(task)
    if frame is not None:
        robot.frame_id(frame)  # an unknown frame: UnknownNameError naming it
    if start_target is not None:
        starts, start_at = _target_solutions(robot, task, manifold, proj, world, frame, start_target, 1, seed, 1,
                                             max_tries, "start_target", InvalidStartError)
        s = starts[0]
    else:
        try:
            s = _project_free(robot, proj, world, q_start, "start", InvalidStartError)
        except InvalidStartError as e:
            raise InvalidStartError(f"{e}; give another start, or a start by IK for a target (start_target=, "
                                    "genplan plan --start-target X Y Z)") from None
        start_at = np.zeros(0) if frame is None else robot.frame_positions(s, frame)
    if goal is not None:
        g = robot.check_configuration(goal, "goal")
        rows = g.reshape(-1, robot.nq)
        goals = np.array([_project_free(robot, proj, world, row, f"goal[{i}]" if len(rows) > 1 else "goal",
                                        InvalidGoalError) for i, row in enumerate(rows)])
        goal_target = np.zeros(0) if frame is None else robot.frame_positions(goals[0], frame)
        return Query(start=s, goals=goals, start_target=start_at, goal_target=goal_target)
    assert target is not None  # neither or both of goal and target are refused above
    goals, goal_at = _target_solutions(robot, task, manifold, proj, world, frame, target, k, seed, 0, max_tries, "target",
                                       InvalidGoalError)
    return Query(start=s, goals=goals, start_target=start_at, goal_target=goal_at)


def _target_solutions(robot: Robot, task: P.Task, manifold: P.Task, proj: P.GaussNewtonProjector | None,
                      world: CollisionWorld, frame: str | None, target: ArrayLike, k: int, seed: int, stream: int,
                      max_tries: int, what: str, error: type[GenplanError]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Up to ``k`` collision-free IK solutions for ``target`` (the argument ``what``; see
    :func:`make_query`), at least one, else ``error``; and the target's position. ``seed`` and
    ``stream`` (0: the goals', 1: the start's) seed the guesses."""
    rng = np.random.default_rng(seed if stream == 0 else [seed, stream])
    try:
        rows_t = _targets(target, what)
    except GenplanError as e:  # the argument's shape, values or pose
        raise error(str(e)) from None
    if len(rows_t) != 1:
        raise error(f"{what}: expected one target, got shape {np.shape(target)}")
    t = rows_t[0]
    if frame is None:
        raise SettingsError(f"frame: task '{task.name}' has no [condition]: a target is a pose of a frame; give the "
                            f"frame (one of the robot's: e.g. {', '.join(list(robot.frames)[:3]) or 'its end link'})")
    if task.condition is None or t.ndim == 2:
        found = _pose_goals(robot, manifold, proj, world, frame, t, k, seed if stream == 0 else int(rng.integers(2**31)),
                            max_tries)
        if len(found) == 0:
            raise error(f"{what}: no collision-free IK solution of frame '{frame}' reaching {t.tolist()} "
                        f"in {max_tries} tries (out of reach, or blocked by the scene)")
        return found, t[:3, 3] if t.ndim == 2 else t
    ik = P.GaussNewtonProjector(robot, task)
    found = valid_solutions(robot, ik, P.condition_term(task).name, proj, world, t, rng, k, max_tries)
    if len(found) == 0:
        raise error(f"{what} {t.tolist()}: no collision-free IK solution of task '{task.name}' in "
                    f"{max_tries} tries (out of reach, or blocked by the scene)")
    return found, t
