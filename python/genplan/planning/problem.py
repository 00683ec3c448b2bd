"""A planning problem for any robot, task and scene: a start on the task's manifold, goals given
as configurations or reached by IK for a target of the task's condition, a plan between them.

>>> import genplan
>>> from genplan.planning import plan   # uses make_query
>>> robot = genplan.load("examples/xarm7/xarm7.toml")
>>> outcome = plan(robot, "examples/xarm7/upright_cup.toml", scene="my_scene.toml",
...                start="default", target=(0.4, -0.3, 0.3), sampler="gan", model="cup.safetensors")
>>> outcome.result.success, outcome.result.path.shape

The manifold is the task's (:func:`genplan.gan.costs.manifold_task`: the task without its
condition term); the start is projected onto it (tightly, as the planner projects its states) and
must be collision-free; each goal likewise; a ``target`` gives ``k`` goals, solved by IK of the
whole task with its condition term aimed at the target from uniform initial guesses, projected,
and kept only when collision-free (as the paper's queries, :mod:`genplan.planning.queries`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan import projection as P
from genplan.collision import CollisionWorld
from genplan.errors import GenplanError, InvalidGoalError, InvalidStartError, SettingsError
from genplan.planning.environments import Query
from genplan.planning.queries import TOLERANCE_FACTOR, solve_ik
from genplan.robots import Robot

__all__ = ["Outcome", "make_query"]


@dataclass(frozen=True)
class Outcome:
    """What :func:`plan` did: the query it built, the planner's result, and what they were for."""

    robot: Robot
    task: P.Task
    manifold: P.Task
    world: CollisionWorld
    query: Query
    result: Any  # genplan.planning.PlanResult
    sampler: str
    #: the obstacles (a genplan.scene.Scene) or None
    scene: Any = None
    #: the search algorithm (genplan.planning.ALGORITHMS)
    algorithm: str = "crrt"

    @property
    def trail_frame(self) -> str:
        """The frame the task conditions on (its trail is what a viewer draws)."""
        return _condition_frame(self.robot, self.task)

    def to_dict(self) -> dict[str, Any]:
        """The outcome as JSON-able data (what ``genplan plan --out`` writes)."""
        r = self.result
        return {
            "robot": self.robot.name,
            "task": self.task.name,
            "manifold": self.manifold.name,
            "sampler": self.sampler,
            "algorithm": self.algorithm,
            "obstacles": list(self.world.obstacle_names),
            "start": self.query.start.tolist(),
            "goals": self.query.goals.tolist(),
            "start_target": self.query.start_target.tolist(),
            "goal_target": self.query.goal_target.tolist(),
            "success": bool(r.success),
            "goal_index": r.goal_index,
            "path": r.path.tolist(),
            "waypoints": r.waypoints.tolist(),
            "stats": r.stats.to_dict(),
        }


def _condition_frame(robot: Robot, task: P.Task) -> str:
    from genplan.projection import condition_term

    return condition_term(task).frame


def _project_free(robot: Robot, proj: P.GaussNewtonProjector, world: CollisionWorld, q: ArrayLike, what: str,
                  error: type[GenplanError]) -> NDArray[np.float64]:
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
    from genplan.projection import condition_term, manifold_task

    if (goal is None) == (target is None):
        raise SettingsError("give a goal configuration or a target of the task's condition, not both or neither")
    if isinstance(k, bool) or not isinstance(k, int) or k < 1:
        raise SettingsError(f"k must be a positive integer, got {k!r}")
    manifold = manifold_task(task, robot)
    proj = P.GaussNewtonProjector(robot, manifold.with_tolerances_scaled(TOLERANCE_FACTOR))
    q_start = robot.q_default if isinstance(start, str) and start == "default" else start
    if isinstance(q_start, str):
        raise InvalidStartError(f"start: expected 'default' or a configuration, got {start!r}")
    s = _project_free(robot, proj, world, q_start, "start", InvalidStartError)
    frame = _condition_frame(robot, task)
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
        goals = solve_ik(robot, ik, condition_term(task).name, proj, world, t, np.random.default_rng(seed), k, max_tries)
        if len(goals) == 0:
            raise InvalidGoalError(f"target {t.tolist()}: no collision-free IK solution of task '{task.name}' in "
                                   f"{max_tries} tries (out of reach, or blocked by the scene)")
        goal_target = t
    return Query(start=s, goals=goals, start_target=robot.frame_positions(s, frame), goal_target=goal_target)
