"""Constrained motion planning: the GAN paper's constrained RRT (Algorithm 1) in the Rust core.

>>> import genplan
>>> from genplan.planning import Planner, environment
>>> env = environment("panda_shelf")
>>> robot = genplan.load("panda")
>>> planner = Planner(robot, world=env.world(robot), sampler="gan")
>>> query = env.queries(robot, n=1, seed=0)[0]          # start + K goal configurations (IK)
>>> result = planner.plan(query.start, query.goals)
>>> result.success, result.path.shape, result.time_s

The tree, nearest-neighbour search, extension logic and (by default) the projector and collision
checker are native; the GIL is released while the planner works. Each part can be replaced by a
Python object, called back in batches:

* ``sampler``: ``"uniform"``, ``"gan"`` (the shipped GAN's generator, run natively),
  ``"hybrid"`` (GAN with probability ``hybrid_p``, default 0.8, else uniform), or any object with
  ``sample(n) -> (n, nq)`` (e.g. :class:`genplan.gan.GanSampler`, which runs torch);
* ``projector``: a :class:`~genplan.projection.GaussNewtonProjector` (its native solver is used) or
  any object with ``project(qs, q_noms) -> (q, success[, iterations])``;
* ``checker``: a :class:`~genplan.collision.CollisionWorld` (native) or any object with
  ``is_valid(qs) -> (n,) bool``.

An exception raised inside a Python part ends the plan and reaches the caller unchanged; Ctrl-C
interrupts a long plan (KeyboardInterrupt).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan import _core
from genplan.collision import CollisionWorld
from genplan.planning.environments import ENVIRONMENT_NAMES, Environment, Query, environment
from genplan.planning.queries import TOLERANCE_FACTOR
from genplan.projection import ComBox, GaussNewtonProjector, Task, paper_task
from genplan.robots import Robot

__all__ = [
    "ENVIRONMENT_NAMES",
    "Environment",
    "PlanResult",
    "Planner",
    "PlannerSettings",
    "Query",
    "SAMPLERS",
    "environment",
    "make_sampler",
    "uniform_base_box",
]

#: Sampler names accepted by :class:`Planner`.
SAMPLERS = ("uniform", "gan", "hybrid")


@dataclass(frozen=True)
class PlannerSettings:
    """Settings of the constrained RRT (defaults: the GAN paper's public code, see DESIGN.md)."""

    #: length of one extension step (tangent norm, rad)
    step: float = 0.3
    #: extension steps per ConstrainedExtend
    max_increments: int = 10
    #: an extension stops when a projected state lands more than max_jump * step away
    max_jump: float = 3.0
    #: a goal is reached within this distance
    goal_tolerance: float = 1e-3
    #: iterations (sample, extend, extend to the nearest goal) per attempt
    max_extensions: int = 500
    #: attempts after a failed one, each from a fresh tree
    retries: int = 2
    #: project each sample onto the manifold before extending towards it (the authors' code)
    project_samples: bool = True
    #: samples requested per sampler call
    sample_batch: int = 16
    #: spacing of the projected, checked states along each edge (0: check tree nodes only)
    edge_resolution: float = 0.025
    #: validate edges lazily, only on a path that reaches a goal (a failing edge prunes its subtree)
    lazy_edges: bool = True
    #: shortcut the solution (each shortcut a projected, validated straight edge); off by default:
    #: the paper's timings have none
    simplify: bool = False
    #: nearest-neighbour index: "auto" (kd-forest up to 16 dimensions, brute force above: measured
    #: faster on each side), "linear" (brute force) or "kdtree"
    neighbors: str = "auto"
    #: give up after this many sample batches in a row without one projectable sample
    max_empty_batches: int = 100


@dataclass
class PlanResult:
    """A plan's outcome. ``path`` is dense: every state is on the manifold and valid, consecutive
    states at most ~``edge_resolution`` apart; ``waypoints`` are the tree nodes along it."""

    success: bool
    path: NDArray[np.float64]
    waypoints: NDArray[np.float64]
    goal_index: int | None
    time_s: float
    #: optimisation steps of the projections of samples and extension steps (Table II's "Opt. Steps")
    projections: int
    #: iterations of the planner (Table II's "E")
    extensions: int
    retries: int
    stats: dict[str, Any] = field(default_factory=dict)


def uniform_base_box(robot: Robot, task: Task) -> NDArray[np.float64] | None:
    """Where the uniform sampler draws a free-flyer base's position: the box of the task's
    centre-of-mass term (the authors' Talos sampler), None without a free flyer or such a term."""
    if not robot.floating_base:
        return None
    box = next((t for t in task.primary if isinstance(t, ComBox)), None)
    return None if box is None else np.array([box.lower, box.upper], dtype=np.float64)


def make_sampler(robot: Robot, kind: str | Any = "uniform", *, seed: int = 0, gan_model: Any = None,
                 hybrid_p: float = 0.8, gan_box: ArrayLike | None = None,
                 base_box: ArrayLike | None = None) -> Any:
    """A sampler the planner understands: "uniform" (native), "gan", "hybrid", or an object with
    ``sample(n)`` (returned as is). The GAN conditions on end-effector targets drawn uniformly in
    ``gan_box`` ([[x, y, z] min, max]; default: the model's task-space region of interest). Uniform
    samples hold a free-flyer base at the robot's default placement, its position drawn uniformly
    in ``base_box`` ([[x, y, z] min, max]) when given (the :class:`Planner` passes
    :func:`uniform_base_box` of its task)."""
    if not isinstance(kind, str):
        if not hasattr(kind, "sample"):
            raise TypeError(f"sampler: expected one of {SAMPLERS} or an object with sample(n), got {type(kind).__name__}")
        return kind
    if kind not in SAMPLERS:
        raise ValueError(f"unknown sampler '{kind}' (known: {', '.join(SAMPLERS)})")
    base = list(map(float, robot.q_default[:7])) if robot.floating_base else None
    box = None
    if base_box is not None:
        b = np.asarray(base_box, dtype=np.float64)
        if b.shape != (2, 3):
            raise ValueError(f"base_box: expected [[xmin, ymin, zmin], [xmax, ymax, zmax]], got shape {b.shape}")
        box = b.tolist()
    uniform = _core.UniformSampler(robot.kinematics, base, seed, box)
    if kind == "uniform":
        return uniform
    from genplan.gan.sampler import GanSampler

    gan = GanSampler(robot, gan_model, box=gan_box, seed=seed).native(seed)
    if kind == "gan":
        return gan
    return _core.MixtureSampler(gan, uniform, hybrid_p, seed)


class Planner:
    """The constrained RRT for one robot, constraint and world.

    ``task`` (default: the paper's projection task for the robot) defines the manifold; the
    native Gauss-Newton projector solves it unless ``projector`` is given, with every tolerance
    multiplied by ``tolerance_factor`` (default 0.1): states are projected ten times tighter than
    the constraint requires, so that the straight chord between two consecutive states of the
    returned path (at most ``edge_resolution`` apart) satisfies the constraint too. ``world`` (default:
    the robot's collision world, self-collision included) checks validity unless ``checker`` is
    given. ``parallel=True`` lets native projections and collision checks of one batch use all
    cores (off by default: the benchmarks compare one core against one core).
    """

    def __init__(self, robot: Robot, world: CollisionWorld | None = None, task: Task | None = None, *,
                 sampler: str | Any = "uniform", projector: Any = None, checker: Any = None,
                 settings: PlannerSettings | None = None, parallel: bool = False, seed: int = 0,
                 gan_model: Any = None, hybrid_p: float = 0.8, tolerance_factor: float = TOLERANCE_FACTOR) -> None:
        self.robot = robot
        self.settings = settings or PlannerSettings()
        self.task = task if task is not None else paper_task(robot, "projection")
        self.world = world if world is not None else robot.collision_world()
        self.parallel = bool(parallel)
        self.base_box = uniform_base_box(robot, self.task)
        self.sampler = make_sampler(robot, sampler, seed=seed, gan_model=gan_model, hybrid_p=hybrid_p,
                                    base_box=self.base_box)
        if projector is None:
            projector = GaussNewtonProjector(robot, self.task.with_tolerances_scaled(tolerance_factor))
        self.projector = projector
        self._projector_arg = projector.native if isinstance(projector, GaussNewtonProjector) and projector.native is not None else projector
        if checker is None:
            checker = self.world
        self.checker = checker
        self._checker_arg = checker.native if isinstance(checker, CollisionWorld) else checker
        self._native = _core.Planner(robot.kinematics, dataclasses.asdict(self.settings))

    def plan(self, start: ArrayLike, goals: ArrayLike, sampler: str | Any | None = None) -> PlanResult:
        """Plan from ``start`` (nq,) to any of ``goals`` ((k, nq), on the manifold: e.g. IK
        solutions from :meth:`Environment.queries`). Failing to find a path within the settings'
        budget is ``success=False``, not an exception; bad input raises ValueError. ``sampler``
        replaces the planner's sampler for this plan (e.g. a GAN conditioned on this query's
        region: ``make_sampler(robot, "gan", gan_box=...)``)."""
        q0 = self.robot.check_configuration(start, "start")
        if q0.ndim != 1:
            raise ValueError(f"start: expected shape ({self.robot.nq},), got {q0.shape}")
        g = self.robot.check_configuration(goals, "goals")
        g = np.ascontiguousarray(g.reshape(-1, self.robot.nq))
        smp = self.sampler if sampler is None else make_sampler(self.robot, sampler, base_box=self.base_box)
        out = self._native.plan(list(map(float, q0)), g, smp, self._projector_arg, self._checker_arg, self.parallel)
        stats = {k: v for k, v in out.items() if k not in ("path", "waypoints")}
        return PlanResult(success=bool(out["success"]), path=out["path"], waypoints=out["waypoints"],
                          goal_index=out["goal_index"], time_s=float(out["time_s"]), projections=int(out["projections"]),
                          extensions=int(out["extensions"]), retries=int(out["retries"]), stats=stats)
