"""Seeded start/goal queries for the planning environments (IK from uniform initial guesses)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from genplan import projection as P
from genplan.errors import GenplanError, SettingsError
from genplan.robots import Robot

if TYPE_CHECKING:
    from genplan.planning.environments import Environment, Query

#: initial guesses tried per IK batch
_BATCH = 32
#: the planner projects ten times tighter than the constraint's tolerances (see Planner)
TOLERANCE_FACTOR = 0.1


def _ik_task(robot: Robot, env: Environment, yaw: float) -> P.Task:
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


def solve_ik(robot: Robot, ik: P.GaussNewtonProjector, term: str, proj: P.GaussNewtonProjector, world: Any,
             target: NDArray[np.float64], rng: np.random.Generator, want: int, max_tries: int) -> NDArray[np.float64]:
    """Up to ``want`` valid configurations reaching ``target`` (the target of ``ik``'s primary term
    ``term``): IK from uniform guesses, then the planning projection ``proj`` (tighter tolerances)
    around the IK solution; collision-free ones (``world.in_collision``) kept."""
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


def make_queries(env: Environment, robot: Robot, n: int, seed: int = 0, k: int = 10, progress: bool = False,
                 max_tries: int = 200) -> list[Query]:
    from genplan.planning.environments import Query

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
        start = solve_ik(robot, ik_start, _target_term(ik_start.task), proj, world, start_target, rng, 1, max_tries)
        if len(start) == 0:
            continue
        goal_target = draw(env.goal_targets, env.goal_box)
        goals = solve_ik(robot, ik_goal, _target_term(ik_goal.task), proj, world, goal_target, rng, k, max_tries)
        if len(goals) < k:
            continue
        out.append(Query(start=start[0], goals=goals, start_target=start_target, goal_target=goal_target))
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    return out
