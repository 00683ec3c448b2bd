"""Planning queries: a start and goal configurations, on a task's manifold and collision-free.

* :func:`make_query`: the query of one problem, for any robot, task and scene: a start
  configuration projected onto the task's manifold, and goals given as configurations or reached
  by IK for a target of the task's condition (what :func:`genplan.planning.plan` plans).
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
from genplan.ik import valid_solutions
from genplan.robots import Robot

__all__ = ["TOLERANCE_FACTOR", "Query", "QuerySource", "make_queries", "make_query"]

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


def _project_free(robot: Robot, proj: P.GaussNewtonProjector, world: CollisionWorld, q: ArrayLike, what: str,
                  error: type[GenplanError]) -> NDArray[np.float64]:
    """``q`` projected with ``proj`` (posture around itself) and checked collision-free in
    ``world``, else ``error`` naming ``what``, why, and the pairs in contact."""
    q0 = robot.check_configuration(q, what)
    if q0.ndim != 1:
        raise error(f"{what}: expected one configuration of shape ({robot.nq},), got {q0.shape}")
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


def make_query(robot: Robot, task: P.Task, world: CollisionWorld, start: ArrayLike | str = "default",
               goal: ArrayLike | None = None, target: ArrayLike | None = None, *, k: int = 10, seed: int = 0,
               max_tries: int = 2000) -> Query:
    """A start (``"default"``: the robot's default configuration, or a configuration) projected
    onto the manifold of ``task`` and checked free, and goals: ``goal`` (a configuration, or
    several as rows) projected and checked likewise, or ``k`` IK solutions for ``target`` (the
    condition term's target), from up to ``max_tries`` uniform guesses, collision-free.

    Errors name the argument: InvalidStartError / InvalidGoalError (off the manifold and not
    projectable, in collision, no IK solution found), SettingsError (neither or both of goal
    and target)."""
    if (goal is None) == (target is None):
        raise SettingsError("give a goal configuration or a target of the task's condition, not both or neither")
    if isinstance(k, bool) or not isinstance(k, int) or k < 1:
        raise SettingsError(f"k must be a positive integer, got {k!r}")
    manifold = P.manifold_task(task, robot)
    proj = P.GaussNewtonProjector(robot, manifold.with_tolerances_scaled(TOLERANCE_FACTOR))
    q_start = robot.q_default if isinstance(start, str) and start == "default" else start
    if isinstance(q_start, str):
        raise InvalidStartError(f"start: expected 'default' or a configuration, got {start!r}")
    s = _project_free(robot, proj, world, q_start, "start", InvalidStartError)
    frame = _condition_frame(task)
    if goal is not None:
        g = robot.check_configuration(goal, "goal")
        rows = g.reshape(-1, robot.nq)
        goals = np.array([_project_free(robot, proj, world, row, f"goal[{i}]" if len(rows) > 1 else "goal",
                                        InvalidGoalError) for i, row in enumerate(rows)])
        goal_target = robot.frame_positions(goals[0], frame)
    else:
        t = np.asarray(target, dtype=np.float64).reshape(-1)
        if t.shape != (3,) or not np.all(np.isfinite(t)):
            raise InvalidGoalError(f"target: expected 3 finite numbers (x, y, z), got {np.asarray(target).tolist()}")
        ik = P.GaussNewtonProjector(robot, task)
        goals = valid_solutions(robot, ik, P.condition_term(task).name, proj, world, t, np.random.default_rng(seed), k,
                                max_tries)
        if len(goals) == 0:
            raise InvalidGoalError(f"target {t.tolist()}: no collision-free IK solution of task '{task.name}' in "
                                   f"{max_tries} tries (out of reach, or blocked by the scene)")
        goal_target = t
    return Query(start=s, goals=goals, start_target=robot.frame_positions(s, frame), goal_target=goal_target)
