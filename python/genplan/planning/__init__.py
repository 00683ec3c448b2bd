"""Constrained motion planning: the GAN paper's constrained RRT (Algorithm 1) and a
bidirectional constrained RRT-Connect (``algorithm="rrt_connect"``), in the Rust core; and
free-space planning (``task="free"``: no constraint but the joint limits, nothing projected).

>>> import genplan
>>> from genplan.planning import Planner, environment
>>> env = environment("panda_shelf")
>>> robot = genplan.load("panda")
>>> planner = Planner(robot, world=env.world(robot), sampler="gan")
>>> query = env.queries(robot, n=1, seed=0)[0]          # start + K goal configurations (IK)
>>> result = planner.plan(query.start, query.goals)
>>> result.success, result.path.shape, result.time_s

The tree, nearest-neighbour search, extension logic and (by default) the projector and collision
checker are native; the GIL is released while the planner works. Both algorithms (:data:`ALGORITHMS`)
run on the same constrained space (steps and edges projected and checked alike) and components:
``"crrt"`` (default; the paper's, grown from the start towards samples, then greedily towards the
nearest goal) and ``"rrt_connect"`` (a tree from the start and one rooted at every goal, each
extended towards samples in turn while the other connects to it). Each part can be replaced by a
Python object, called back in batches:

* ``sampler``: ``"uniform"``, ``"gan"`` (the shipped GAN's generator, run natively),
  ``"hybrid"`` (GAN with probability ``hybrid_p``, default 0.8, else uniform), ``"adaptive"``
  (GAN at first, its share halving every ``half_life`` samples of a plan: complete, and as fast
  as the GAN where it covers the query), ``"data"`` (:func:`data_sampler`: rows of the data set a
  learned sampler is trained on, native, no training), or any object with ``sample(n) -> (n, nq)``
  (e.g. :class:`genplan.samplers.GanSampler`, which runs torch); :data:`SAMPLERS` lists the names;
* ``projector``: a :class:`~genplan.projection.GaussNewtonProjector` (its native solver is used) or
  any object with ``project(qs, q_noms) -> (q, success[, iterations])``;
* ``checker``: ``"exact"`` (the world's exact geometry, the default), ``"spheres"`` (the robot's
  covering spheres, :func:`genplan.spheres.robot_spheres`, against the world's obstacles: faster
  and conservative, see :data:`CHECKERS`), a :class:`~genplan.collision.CollisionWorld` (native),
  a ``genplan._core.SphereChecker``, or any object with
  ``is_valid(qs) -> (n,) bool`` (booleans or exactly 0 / 1; anything else is a
  :class:`~genplan.errors.CallbackError`).

An exception raised inside a Python part ends the plan and reaches the caller unchanged; Ctrl-C
interrupts a long plan (KeyboardInterrupt). A start or goal off the constraint manifold is refused
before the search (see :meth:`Planner.plan`).

Free space: ``Planner(robot, world, task="free")`` (the shipped task of the joint limits alone; any
task whose primary terms are all :class:`~genplan.projection.JointLimits` is free,
:attr:`Task.free <genplan.projection.Task.free>`) plans with no projector in the loop: samples,
steps and edge states are taken as they are, and the checker holds the joint limits and the
collisions of every state (``stats.projections == 0``, ``stats.projector_s == 0``). Without
``settings`` a free plan takes :data:`FREE_SPACE_SETTINGS` (RRT-Connect, extensions of at most
0.9 rad, the path simplified), a constrained one the paper's ``PlannerSettings()``.

>>> planner = Planner(robot, world=env.world(robot), task="free")   # FREE_SPACE_SETTINGS
>>> result = planner.plan(start, goal)                   # configurations, (nq,) and (k, nq)
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan import _core
from genplan import projection as P
from genplan.collision import CollisionWorld
from genplan.errors import SettingsError, ShapeError, UnknownNameError
from genplan.planning.environments import ENVIRONMENT_NAMES, Environment, environment
from genplan.planning.queries import TOLERANCE_FACTOR, Query, make_query, query_manifold
from genplan.projection import ComBox, GaussNewtonProjector, Task, paper_task
from genplan.robots import Robot
from genplan.samplers import SAMPLERS

__all__ = [
    "ALGORITHMS",
    "CHECKERS",
    "EDGE_CHECKS",
    "FREE_SPACE_SETTINGS",
    "SAMPLINGS",
    "ENVIRONMENT_NAMES",
    "Environment",
    "Outcome",
    "PlanResult",
    "PlanStats",
    "Planner",
    "PlannerSettings",
    "Query",
    "SAMPLERS",
    "environment",
    "data_sampler",
    "default_settings",
    "make_query",
    "make_sampler",
    "sphere_checker",
    "plan",
    "uniform_base_box",
]

#: Search algorithms (``PlannerSettings.algorithm``, ``Planner(..., algorithm=)``): the paper's
#: constrained RRT (default) and the bidirectional constrained RRT-Connect. The core's table.
ALGORITHMS: tuple[str, ...] = _core.ALGORITHMS
#: Edge checks (``PlannerSettings.edge_check``): states checked at ``edge_resolution`` (default),
#: or every motion between them certified collision-free as well. The core's table.
EDGE_CHECKS: tuple[str, ...] = _core.EDGE_CHECKS
#: How uniform samples are drawn (``PlannerSettings.sampling``): ``"random"`` (default) or
#: ``"halton"``, a Halton sequence shifted by the planner's seed (low discrepancy: the box is
#: covered evenly from the first samples on; different seeds, different points). It applies to
#: the uniform sampler the :class:`Planner` makes (``sampler="uniform"``, and the uniform part of
#: ``"hybrid"`` and ``"adaptive"``). The core's table.
SAMPLINGS: tuple[str, ...] = _core.SAMPLINGS
#: Validity checkers by name (``Planner(..., checker=)``, :func:`plan`): ``"exact"``, the
#: world's exact geometry (parry); ``"spheres"``, the robot's covering spheres
#: (:func:`genplan.spheres.robot_spheres`) against the world's obstacles in closed form, several
#: states at once (rust/core/src/collision/spheres.rs). The spheres cover the links, so a state
#: valid by them is valid by the exact geometry (the converse fails near contact: a path may be
#: missed, never one in collision returned); a point cloud is met through its grid of balls.
#: ``"hybrid"``: the spheres first, each collision they find checked again by the exact geometry,
#: whose answer stands (the exact checker's answers; the spheres' cost where the robot is free,
#: both where the spheres touch: their false positives near contact and between the covers of
#: close links refuse nothing).
CHECKERS: tuple[str, ...] = ("exact", "spheres", "hybrid")
#: The adaptive sampler's half-life: the rows drawn within a plan after which the learned
#: sampler's share has halved (about 100 extensions of 16 samples; ``half_life=`` overrides it,
#: see :func:`make_sampler`). Long enough for the queries the learned sampler covers to be solved
#: at its speed, short enough for the others to get uniform samples soon: of the half-lives
#: benches/adaptive_half_life.py compares on tuning queries (seed 1, not the tables' seed 0), the
#: one that planned fastest over the four environments (benches/results/adaptive_half_life.json).
ADAPTIVE_HALF_LIFE = 1600.0


#: Settings of the constrained RRT, defined once in the Rust core (``planning::Settings``):
#: keyword-only, immutable (``settings.replace(step=0.2)`` makes a changed copy), validated
#: (:class:`~genplan.errors.SettingsError` names the field). Defaults: the GAN paper's public code.
PlannerSettings = _core.PlannerSettings
#: The settings of a free-space plan when none are given (:class:`Planner` with a free task,
#: :func:`plan`, ``genplan plan`` without ``--task``): RRT-Connect growing the smaller tree
#: (``balance``), the path simplified, extensions of at most 3 steps of 0.3 rad (0.9 rad, the
#: order of VAMP's RRT-Connect range; the paper's 10 steps, 3 rad, suit its constrained RRT), and a
#: search budget of 20,000 iterations per attempt, 5 attempts (VAMP's order: a failure is the
#: planner's, not a budget's; ``time_limit`` bounds it in seconds). Chosen on the motion bench's
#: tuning problems (seed 1; the tables report seed 0) of the Panda, the UR5 and Baxter against
#: VAMP (benches/free_space_settings.py, its figures in benches/results/free_space_settings.json):
#: of 2, 3, 5 and 10 steps, each with and without ``balance``, 3 and 2 steps balanced planned
#: fastest (a tie within that run's noise), the paper's 10 steps alternating markedly slower.
FREE_SPACE_SETTINGS = PlannerSettings(algorithm="rrt_connect", simplify=True, max_increments=3, balance=True,
                                      max_extensions=20_000, retries=4)


def default_settings(free: bool) -> PlannerSettings:
    """The settings a plan takes when none are given: :data:`FREE_SPACE_SETTINGS` in free space
    (``free``: nothing projected), the paper's ``PlannerSettings()`` on a constraint manifold."""
    return FREE_SPACE_SETTINGS if free else PlannerSettings()


class PlanResult:
    """A plan's outcome: the native result (``_core.PlanResult``: ``success``, dense ``path``,
    ``waypoints``, ``goal_index``, ``time_s``, ``projections``, ``extensions``, ``retries`` and its
    :class:`PlanStats`), whose attributes it delegates, with the robot, the manifold's task and
    the world it was planned in (``world``: the collision world, or the checker, that said which
    states are valid), so that it can be turned into a trajectory checked the same way
    (:meth:`trajectory`)."""

    __slots__ = ("native", "robot", "task", "world")

    def __init__(self, native: _core.PlanResult, robot: Robot, task: Task, world: Any) -> None:
        self.native = native
        self.robot = robot
        self.task = task
        self.world = world

    success = property(lambda self: self.native.success, doc="a path was found")
    path = property(lambda self: self.native.path, doc="(m, nq) dense path: every state on the manifold and valid")
    waypoints = property(lambda self: self.native.waypoints, doc="the tree nodes along the path (after shortcuts)")
    goal_index = property(lambda self: self.native.goal_index, doc="the goal reached (None without a path)")
    stats = property(lambda self: self.native.stats, doc="what the plan cost (:class:`PlanStats`)")
    time_s = property(lambda self: self.native.time_s, doc="wall-clock time of the plan (s)")
    projections = property(lambda self: self.native.projections, doc="optimisation steps of the projections")
    extensions = property(lambda self: self.native.extensions, doc="iterations of the planner")
    retries = property(lambda self: self.native.retries, doc="attempts made after the first")

    def __getattr__(self, name: str) -> Any:  # anything else the native result has
        return getattr(object.__getattribute__(self, "native"), name)

    def __repr__(self) -> str:
        return repr(self.native)

    def trajectory(self, rate_hz: float = 1000.0, velocity_scale: float = 1.0, acceleration_scale: float = 1.0,
                   acceleration_limits: ArrayLike | None = None) -> Any:
        """The path as a time-optimal trajectory (:class:`genplan.trajectory.Trajectory`: ``t``,
        ``q``, ``qd``, ``qdd`` sampled at ``rate_hz``, at rest at both ends) within the URDF's
        velocity limits times ``velocity_scale`` and ``acceleration_limits`` (rad/s^2, one number
        or one per joint; default 2 x the velocity limits, see
        :data:`genplan.trajectory.DEFAULT_ACCELERATION_FACTOR`) times ``acceleration_scale``,
        by TOPP-RA (native, rust/core/src/timing.rs) along a spline through every state of the dense
        path. The dense path, not the waypoints, is the geometric path: a spline through the
        waypoints alone would leave the manifold; plan with ``PlannerSettings(simplify=True)``
        for the shortcut path (fewer corners, a shorter trajectory). Every sample is checked as
        the path's states were: within the joint limits (no tolerance), on the task's manifold
        (``traj.residuals``), and valid in the plan's ``world`` (not in collision, or the plan's
        checker's ``is_valid``); also within the velocity and acceleration limits. See
        :func:`genplan.trajectory.parameterize`.

        Raises GenplanError when there is no path (``success`` is False);
        :class:`~genplan.errors.InvalidTrajectoryError` naming the first sample that fails a
        check (its index, time, and the joint limit, term or pair in contact)."""
        from genplan.errors import GenplanError
        from genplan.trajectory import parameterize

        if not self.native.success:
            raise GenplanError("trajectory: the plan found no path (success is False)")
        return parameterize(self.robot, self.native.path, self.task, rate_hz=rate_hz, velocity_scale=velocity_scale,
                            acceleration_scale=acceleration_scale, acceleration_limits=acceleration_limits,
                            world=self.world)


#: What a plan cost (counts and times), read-only; ``to_dict()`` for JSON.
PlanStats = _core.PlanStats


def uniform_base_box(robot: Robot, task: Task) -> NDArray[np.float64] | None:
    """Where the uniform sampler draws a free-flyer base's position: the box of the task's
    centre-of-mass term (the authors' Talos sampler), None without a free flyer or such a term."""
    if not robot.floating_base:
        return None
    box = next((t for t in task.primary if isinstance(t, ComBox)), None)
    return None if box is None else np.array([box.lower, box.upper], dtype=np.float64)


def make_sampler(robot: Robot, kind: str | Any = "uniform", *, seed: int = 0, gan_model: Any = None,
                 hybrid_p: float = 0.8, half_life: float = ADAPTIVE_HALF_LIFE, gan_box: ArrayLike | None = None,
                 base_box: ArrayLike | None = None, sampling: str = "random") -> Any:
    """A sampler the planner understands: "uniform" (native), "gan", "hybrid" (the GAN with
    probability ``hybrid_p``, else uniform), "adaptive" (the GAN with probability 0.5^(k /
    ``half_life``) for the k-th sample of a plan, else uniform), "data" (:func:`data_sampler` of the
    robot's shipped task, its box ``gan_box``), or an object with ``sample(n)``
    (returned as is). The GAN conditions on end-effector targets drawn uniformly in
    ``gan_box`` ([[x, y, z] min, max]; default: the model's task-space region of interest). Uniform
    samples hold a free-flyer base at the robot's default placement, its position drawn uniformly
    in ``base_box`` ([[x, y, z] min, max]) when given (the :class:`Planner` passes
    :func:`uniform_base_box` of its task); ``sampling`` (:data:`SAMPLINGS`) is how they are drawn:
    random, or a Halton sequence shifted by ``seed``."""
    if not isinstance(kind, str):
        if not hasattr(kind, "sample") and not isinstance(kind, _core.MixtureSampler):  # native: no Python sample
            raise TypeError(f"sampler: expected one of {SAMPLERS} or an object with sample(n), got {type(kind).__name__}")
        return kind
    if kind not in SAMPLERS:
        raise UnknownNameError(f"unknown sampler '{kind}' (known: {', '.join(SAMPLERS)})")
    base = list(map(float, robot.q_default[:7])) if robot.floating_base else None
    box = None
    if base_box is not None:
        b = np.asarray(base_box, dtype=np.float64)
        if b.shape != (2, 3):
            raise ShapeError(f"base_box: expected [[xmin, ymin, zmin], [xmax, ymax, zmax]], got shape {b.shape}")
        box = b.tolist()
    uniform = _core.UniformSampler(robot.kinematics, base, seed, box, sampling)
    if kind == "uniform":
        return uniform
    if kind == "data":
        return data_sampler(robot, box=gan_box, seed=seed)
    from genplan.samplers.sampler import GanSampler

    gan = GanSampler(robot, gan_model, box=gan_box, seed=seed).native(seed)
    if kind == "gan":
        return gan
    if kind == "adaptive":  # the GAN paper's future work: p = 1 at first, decaying towards uniform
        return _core.MixtureSampler(gan, uniform, 1.0, seed, half_life)
    return _core.MixtureSampler(gan, uniform, hybrid_p, seed)


def data_sampler(robot: Robot, data: ArrayLike | None = None, *, task: "str | os.PathLike[str] | Task | None" = None,
                 box: ArrayLike | None = None, in_box: bool = True, size: int = 25_000, data_seed: int = 0,
                 seed: int = 0, progress: bool = False) -> _core.DataSampler:
    """A sampler that needs no training: rows of a data set of valid configurations, each drawn
    uniformly at random, natively (pass it as a :class:`Planner`'s ``sampler``).

    ``data`` (n, nq): the configurations; default: the data set a learned sampler of ``robot`` and
    ``task`` (default: the robot's shipped ``<robot>_ik``) is trained on
    (:func:`genplan.samplers.data.valid_configurations`, ``size`` rows of seed ``data_seed``, made
    once and cached), i.e. uniform configurations projected onto the task's manifold. With
    ``in_box`` (default) only the rows whose condition frame (the one a learned sampler is
    conditioned on) lies in ``box`` are kept; default box: the one the learned sampler draws its
    targets from when planning. The rows are :class:`genplan.samplers.data.TaskData`'s, which
    :func:`genplan.solve_ik`'s ``init="data"`` draws from too. benches/data_sampler_plan.py
    compares it with the learned samplers. Raises ShapeError or NonFiniteError for bad ``data``,
    SettingsError when the box keeps no row.
    """
    from genplan.samplers.data import TaskData

    rows = TaskData(robot, task, data, size=size, seed=data_seed, progress=progress)
    return _core.DataSampler(np.ascontiguousarray(rows.in_box(box) if in_box else rows.rows), seed)


def sphere_checker(robot: Robot, world: CollisionWorld, spheres: Any = None, confirm: bool = False) -> Any:
    """The native sphere checker of ``robot`` (its :func:`~genplan.spheres.robot_spheres`, cached
    on disk, or ``spheres``: a :class:`~genplan.spheres.RobotSpheres` of the caller's, e.g. another
    planner's spheres to compare on the same geometry) against ``world``'s obstacles and self pairs
    as they are now: ``in_collision(q)`` ((nq,) -> bool, (n, nq) -> (n,) bool),
    ``motion_free(a, b, resolution)``, and a checker the planner takes. A point cloud in ``world``
    is tested as its balls (each sphere against the balls in the grid cells around it); each
    obstacle's padding grows the spheres tested against it. The objects ``robot`` holds
    (:meth:`~genplan.robots.Robot.with_attached`) that ``world`` has are covered by spheres of
    their own (:func:`~genplan.spheres.attached_spheres`, the same generator and guarantee),
    checked against the obstacles and the links of their self pairs; an object attached in
    ``world`` that ``robot`` does not hold is refused (a SettingsError naming it). ``confirm``:
    a planner given this checker checks each collision the spheres find again by ``world``'s
    exact geometry, whose answer stands (the ``"hybrid"`` of :data:`CHECKERS`)."""
    from genplan.spheres import attached_spheres, robot_spheres

    if not isinstance(confirm, bool):
        raise SettingsError(f"confirm: expected True or False, got {confirm!r}")

    s = robot_spheres(robot) if spheres is None else spheres
    objects = []
    for name, link, _touch in world.attached:
        held = robot.attached.get(name)
        if held is None or held.link != link:
            raise SettingsError(
                f"checker 'spheres': attached object '{name}' on link '{link}' is not one robot '{robot.name}' holds "
                f"(it holds: {', '.join(sorted(robot.attached)) or 'none'}): build the world with robot.collision_world()")
        centers, radii = attached_spheres(held)
        objects.append((name, centers.tolist(), radii.tolist()))
    return _core.SphereChecker(world.native, list(s.links), np.ascontiguousarray(s.centers).tolist(),
                               np.ascontiguousarray(s.radii).tolist(), objects, confirm)


def _check_algorithm(algorithm: str) -> str:
    """``algorithm`` if it is one of :data:`ALGORITHMS`, else UnknownNameError listing them."""
    if algorithm not in ALGORITHMS:
        raise UnknownNameError(f"unknown algorithm {algorithm!r} (known: {', '.join(ALGORITHMS)})")
    return algorithm


class _WithinLimits:
    """A Python checker in free space, where no projector keeps the states within the joint
    limits: a row outside the robot's limits (the native checker's slack, 1e-9) is invalid
    whatever ``checker`` says. Its flags are returned as it gave them (the planner checks them),
    with the rows outside the limits set to False."""

    def __init__(self, robot: Robot, checker: Any) -> None:
        self.checker = checker
        self.lower = robot.lower - 1e-9
        self.upper = robot.upper + 1e-9

    def is_valid(self, qs: NDArray[np.float64]) -> Any:
        flags = self.checker.is_valid(qs)
        q = np.asarray(qs)
        within = np.all((q >= self.lower) & (q <= self.upper), axis=1)
        if within.all():
            return flags
        a = np.asarray(flags)
        if a.shape != within.shape or a.dtype.kind not in "biuf":
            return flags  # malformed: the planner names what is wrong with it
        a = a.copy()
        a[~within] = 0
        return a


class Planner:
    """The constrained planner for one robot, constraint and world: the paper's constrained RRT,
    or RRT-Connect with ``algorithm="rrt_connect"`` (which overrides ``settings.algorithm``).

    ``task`` (a Task, a shipped task's name or a task file; default: the paper's projection task
    for the robot) defines the manifold. A free task (``"free"``: the joint limits alone,
    :attr:`Task.free <genplan.projection.Task.free>`) plans in free space with no projector at
    all (unless ``projector`` is given): the checker holds the limits (the native one checks
    them; a row outside them is invalid whatever a Python ``checker`` answers for it),
    ``stats.projections`` and ``stats.projector_s`` stay 0, the path is straight segments at
    ``edge_resolution``, :attr:`free` is True, and without ``settings`` the plan takes
    :data:`FREE_SPACE_SETTINGS` (RRT-Connect, simplified; the paper's ``PlannerSettings()``
    otherwise). Otherwise the
    native Gauss-Newton projector solves it unless ``projector`` is given, with every tolerance
    multiplied by ``tolerance_factor`` (default 0.1): states are projected ten times tighter than
    the constraint requires, and the midpoint of every straight chord between two consecutive
    states of an edge (at most 1.25 x ``edge_resolution`` apart) is checked against the task's own
    tolerances (1 / ``tolerance_factor`` times the projector's), a chord that strays being split at
    its projected midpoint (rust/core/src/planning/constrained.rs, ``hold_chords``): so the chords
    of the returned path satisfy the constraint too (``stats.chord_checks`` counts the midpoints;
    a ``projector`` given by the caller has no such check). ``world`` (default:
    the robot's collision world, self-collision included) checks validity unless ``checker`` is
    given. ``parallel=True`` lets native projections and collision checks of one batch use all
    cores (off by default: the benchmarks compare one core against one core).

    ``checker="spheres"`` checks the robot's covering spheres instead of its exact geometry
    (:data:`CHECKERS`, :func:`sphere_checker`); the result's trajectory is still checked against
    the exact ``world``.

    ``PlannerSettings(edge_check="certified")`` also certifies every motion between consecutive
    states collision-free, not only the states (conservative advancement with swept-motion bounds
    of the robot's geometry, rust/core/src/collision/motion.rs; states are added where a chord
    cannot be certified, and an edge is refused when a chord 8x finer than ``edge_resolution``
    still cannot). It needs the native checker (a CollisionWorld) and costs several times the
    plan time of the default ``"sampled"`` check (``python benches/certified_edges.py``,
    benches/results/certified_edges.json).
    """

    def __init__(self, robot: Robot, world: CollisionWorld | None = None,
                 task: Task | str | os.PathLike[str] | None = None, *,
                 sampler: str | Any = "uniform", projector: Any = None, checker: Any = None,
                 settings: PlannerSettings | None = None, parallel: bool = False, seed: int = 0,
                 gan_model: Any = None, hybrid_p: float = 0.8, half_life: float = ADAPTIVE_HALF_LIFE,
                 tolerance_factor: float = TOLERANCE_FACTOR, algorithm: str | None = None) -> None:
        self.robot = robot
        self.task = P.load_task(task, robot) if task is not None else paper_task(robot, "projection")
        #: free space: no projector in the loop (the task's only constraint is the joint limits)
        self.free = projector is None and self.task.free
        self.settings = settings or default_settings(self.free)
        if algorithm is not None:
            self.settings = self.settings.replace(algorithm=_check_algorithm(algorithm))
        self.world = world if world is not None else robot.collision_world()
        self.parallel = bool(parallel)
        self.base_box = uniform_base_box(robot, self.task)
        self.sampler = make_sampler(robot, sampler, seed=seed, gan_model=gan_model, hybrid_p=hybrid_p, half_life=half_life,
                                    base_box=self.base_box, sampling=self.settings.sampling)
        # the chords between the states are held to the task's own tolerances: 1 / tolerance_factor
        # times the projector's (unknown for a projector given by the caller: no chord check)
        self._chord_tolerance: float | None = None
        if self.free:
            self._projector_arg: Any = None
        elif projector is None:
            projector = GaussNewtonProjector(robot, self.task.with_tolerances_scaled(tolerance_factor))
            self._chord_tolerance = 1.0 / float(tolerance_factor)
        self.projector = projector
        if not self.free:
            self._projector_arg = projector.native if isinstance(projector, GaussNewtonProjector) and projector.native is not None else projector
        if checker is None:
            checker = "exact"
        if isinstance(checker, str):
            if checker not in CHECKERS:
                raise UnknownNameError(f"checker: unknown checker {checker!r} (known: {', '.join(CHECKERS)})")
            if checker != "exact" and self.settings.edge_check == "certified":
                raise SettingsError(f"checker '{checker}': edge_check 'certified' needs the exact checker "
                                    "(the spheres certify no motion); use edge_check 'sampled'")
            checker = self.world if checker == "exact" else sphere_checker(robot, self.world, confirm=checker == "hybrid")
        self.checker = checker
        self._checker_arg = checker.native if isinstance(checker, CollisionWorld) else checker
        if self.free and not isinstance(checker, (CollisionWorld, _core.SphereChecker)):
            self._checker_arg = _WithinLimits(robot, checker)
        # what a result's trajectory is checked in: a sphere checker's path against the exact
        # geometry (which it implies), any other checker's against itself
        self._result_world = self.world if isinstance(checker, _core.SphereChecker) else checker
        self._native = _core.Planner(robot.kinematics, self.settings)

    def plan(self, start: ArrayLike, goals: ArrayLike, sampler: str | Any | None = None) -> PlanResult:
        """Plan from ``start`` (nq,) to any of ``goals`` ((k, nq), on the manifold: e.g. IK
        solutions from :meth:`Environment.queries`). Failing to find a path within the settings'
        budget is ``success=False``, not an exception; bad input raises a :mod:`genplan.errors` class. ``sampler``
        replaces the planner's sampler for this plan (e.g. a GAN conditioned on this query's
        region: ``make_sampler(robot, "gan", gan_box=...)``).

        Before the search, every input the result's guarantee rests on is checked:

        * on the manifold: the start and each goal are projected with the planner's projector
          (posture around themselves). One it cannot project, or moves by more than
          ``settings.goal_tolerance``, is refused: :class:`~genplan.errors.InvalidStartError`, or
          :class:`~genplan.errors.InvalidGoalError` naming every such goal and the distance, e.g.
          ``goals[3]: not on the constraint manifold: the projector moved it by 0.312
          (goal_tolerance 0.001)``. A goal off the manifold is refused even when other goals are
          fine (as OMPL refuses a constrained problem whose goal does not satisfy the
          constraint): it was not made for this task, and planning to the others would hide
          that. One it moves by less is replaced by its projection, so that the path's first and
          last states satisfy the constraint too (a configuration already on the manifold, such
          as the queries', is used exactly as given);
        * in free space (:attr:`free`) nothing is projected: the start and goals are used as
          given, and the straight edge from the start to the nearest valid goal is tried before
          any search (its states checked at ``edge_resolution``; a clear one is the path);
        * valid (the checker): a start in collision or outside the joint limits is refused; goals
          that are not valid are dropped (IK solutions often collide), and refused only when
          none is left. ``result.goal_index`` says which goal was reached.

        A Python checker's or projector's flags must be booleans (or exactly 0 / 1): anything
        else is a :class:`~genplan.errors.CallbackError` naming the callback and the value.

        On success, ``result.path`` runs from the start to ``goals[result.goal_index]`` (each as
        projected above), every state of it on the manifold and valid, consecutive states at most
        ``1.25 * edge_resolution`` apart, the midpoint of the chord between them on the manifold
        within the task's tolerances (with the planner's own projector). A start within
        ``settings.goal_tolerance`` of a valid goal has reached it: ``result.path`` is the start
        alone (one state; its trajectory stands still)."""
        smp = (self.sampler if sampler is None else
               make_sampler(self.robot, sampler, base_box=self.base_box, sampling=self.settings.sampling))
        # the native planner reads and checks start (nq,) and goals (nq,) or (k, nq) itself, with
        # genplan._arrays.as_configurations' errors (ShapeError, NonFiniteError, naming them)
        native = self._native.plan(start, goals, smp, self._projector_arg, self._checker_arg, self.parallel,
                                   self._chord_tolerance)
        return PlanResult(native, self.robot, self.task, self._result_world)


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
    #: the frame whose pose a target gave (None: the task's condition frame, if any)
    frame: str | None = None

    @property
    def trail_frame(self) -> str | None:
        """The frame whose trail a viewer draws: the target's frame, else the frame the task
        conditions on; None when there is neither (the viewer's default, the hand)."""
        if self.frame is not None:
            return self.frame
        return P.condition_term(self.task).frame if self.task.condition is not None else None

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


def plan(robot: Robot | str | os.PathLike[str], task: P.Task | str | os.PathLike[str] = "free", scene: Any = None,
         *, start: ArrayLike | str = "default", goal: ArrayLike | None = None, target: ArrayLike | None = None,
         frame: str | None = None, sampler: str = "uniform", model: str | os.PathLike[str] | None = None, k: int = 10,
         seed: int = 0, settings: PlannerSettings | None = None, parallel: bool = True,
         algorithm: str | None = None, checker: str = "exact", start_target: ArrayLike | None = None) -> Outcome:
    """Plan for ``robot`` (a Robot or what :func:`genplan.load` takes) on the manifold of ``task``
    (a Task, shipped name or task file; default ``"free"``: free space, the joint limits alone,
    nothing projected) among ``scene`` (a Scene, a shipped scene's name or a scene file; None: no
    obstacles, self-collision only), from ``start`` to ``goal`` (configurations) or to IK goals for
    ``target`` (:func:`make_query`: a target of the task's [condition], or a pose of ``frame``, a
    4x4 matrix or ``x y z qx qy qz qw``); ``start_target`` instead of ``start``: a start by IK for
    that target, likewise. A task with a [condition] plans on its manifold
    (:func:`genplan.projection.manifold_task`), one without on its own terms.
    ``sampler``: "uniform", "gan", "hybrid" or "adaptive" (the learned sampler of ``model``, which
    must be trained for this robot and task), or "data" (:func:`data_sampler` of this task: no
    model, no training), the last four for a task with a [condition] only; ``algorithm``: one of
    :data:`ALGORITHMS` (default: ``settings.algorithm``; without ``settings``, "rrt_connect" of
    :data:`FREE_SPACE_SETTINGS` when the manifold is free, else "crrt"); ``checker``: one of
    :data:`CHECKERS` ("exact"; "spheres": the robot's covering spheres; "hybrid": the spheres,
    their collisions confirmed by the exact geometry).

    Not finding a path within the settings' budget is ``outcome.result.success == False``."""
    from genplan.robots import load

    if algorithm is not None:
        _check_algorithm(algorithm)
    if checker not in CHECKERS:
        raise UnknownNameError(f"checker: unknown checker {checker!r} (known: {', '.join(CHECKERS)})")
    rob = robot if isinstance(robot, Robot) else load(robot)
    t = P.load_task(task, rob)
    if sampler not in SAMPLERS:
        raise UnknownNameError(f"unknown sampler '{sampler}' (known: {', '.join(SAMPLERS)})")
    if sampler != "uniform" and t.condition is None:
        raise SettingsError(f"sampler '{sampler}': task '{t.name}' has no [condition], which the learned samplers and "
                            "the data sampler draw for; plan with sampler 'uniform'")
    gan_model = None
    chosen: str | Any = sampler
    if sampler == "data":
        if model is not None:
            raise SettingsError("model: sampler 'data' draws rows of the task's data set and takes no model "
                                "(give sampler 'gan', 'hybrid' or 'adaptive' to plan with it)")
    elif sampler != "uniform":
        if model is None:
            raise SettingsError(f"sampler '{sampler}' needs a model: a GAN trained for robot '{rob.name}' and task "
                                f"'{t.name}' (genplan train gan --robot ... --task ...)")
        from genplan.samplers.loading import load_sampler_model

        gan_model = load_sampler_model(rob, Path(model), task=t)  # another robot's or task's GAN: refused, both named
    world = rob.collision_world()
    scene_obj = None
    if scene is not None:
        from genplan.scene import load_scene

        scene_obj = load_scene(scene)
        world.add_scene(scene_obj)
    manifold = query_manifold(t, rob)
    query = make_query(rob, t, world, start, goal, target, frame=frame, k=k, seed=seed, start_target=start_target)
    if sampler == "data":  # this task's data, not the robot's shipped task's
        chosen = data_sampler(rob, task=t, seed=seed, progress=True)
    planner = Planner(rob, world=world, task=manifold, sampler=chosen, gan_model=gan_model, seed=seed,
                      settings=settings, parallel=parallel, algorithm=algorithm, checker=checker)
    result = planner.plan(query.start, query.goals)
    return Outcome(rob, t, manifold, world, query, result, sampler, scene_obj, planner.settings.algorithm, frame)
