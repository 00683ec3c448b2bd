"""The OMPL peer: ProjectedStateSpace + RRTConnect on genplan's own constraint and collision model.

genplan's constrained RRT is benchmarked against OMPL's projection-based constrained planning
(Kingston et al.), run in the same process on the same queries, the same :class:`Task` and the same
:class:`~genplan.collision.CollisionWorld`. Nothing here re-implements kinematics: residuals and
Jacobians come from :mod:`genplan.projection`'s bound terms (Pinocchio), collisions from parry.

How a genplan :class:`~genplan.projection.Task` becomes an OMPL problem (``task.primary`` only;
the secondary posture task has no OMPL counterpart and is ignored):

* **Equalities** -> one ``ob.Constraint`` F(x) = 0, the unweighted residual rows stacked:
  :class:`FramePose` (rows whose ``components`` are non-zero), :class:`FramePosition` and
  :class:`FrameOrientation` (rows whose ``axes`` are non-zero), :class:`Posture` (the joints whose
  ``joint_weights`` are non-zero; it needs an explicit ``q_nom``). Jacobians are analytic. OMPL
  satisfies ``||F(x)||_2 <= tolerance``; the default tolerance is the smallest ``tolerance`` of the
  equality terms (1e-4 for both paper tasks: Panda hand orientation, Talos soles), which implies
  genplan's per-component test ``max |r_i| < tol_i`` for every term.
* :class:`JointLimits` -> the bounds of the ambient ``RealVectorStateSpace`` (always the robot's
  limits) and, because projection can leave them, a bounds test in the validity checker with the
  term's tolerance as slack (genplan counts a configuration within ``tolerance`` of a limit as
  satisfied).
* :class:`ComBox` (an inequality) -> the validity checker: the centre of mass must lie in the box
  grown by the term's tolerance.
* Collisions -> the validity checker: ``world.in_collision`` (self-collision included if the
  world checks it).

Free-flyer robots (Talos) need a Euclidean ambient space, so OMPL plans in a chart
``x = [base position (3), base rotation vector log3(R) (3), joints]`` (``nv`` numbers); see
:class:`ManifoldChart`. The base is boxed to +-0.5 m and +-1 rad (per rotation-vector component)
around the robot's default base pose; the soles constraint keeps it near there anyway.

Goals: all K goal configurations go into one ``ob.GoalStates``; RRTConnect roots its goal tree at
them as it samples the goal (the reached one is reported as ``goal_index``).

Starts and goals are re-projected once with OMPL's own Newton projection (genplan's
``max |r_i| < 1e-4`` is not OMPL's ``||F||_2 <= 1e-4``, and OMPL refuses to traverse from a state
that fails its test); this moves them by ~1e-4 at most. A start that is then invalid (collision,
CoM, limits) ends with ``success=False, status="INVALID_START"``; invalid goals are dropped
(``goals_used``), none left gives ``status="INVALID_GOAL"``.

Resolution: OMPL's ``ConstrainedStateSpace::setDelta`` ties the validity-checking resolution to
``delta`` (the step of the discrete geodesic: every delta-step is projected and checked, OMPL
default 0.05 in the ambient Euclidean metric, i.e. radians for joints); it overrides any
``setStateValidityCheckingResolution`` made before. So ``delta`` is the one resolution knob.

Bindings (ompl 2.0.x, nanobind) -- the calls that work::

    class C(ob.Constraint):                      # trampoline: override function / jacobian
        def __init__(self): super().__init__(n, m, tol)
        def function(self, x, out): out[:] = ...     # x: read-only view, out: write in place
        def jacobian(self, x, out): out[:, :] = ...
    css = ob.ProjectedStateSpace(rvss, C()); csi = ob.ConstrainedSpaceInformation(css)
    css.setup(); css.setDelta(d)
    s = css.allocState(); s.copy(list_of_floats); s[i]   # no ob.State(space) constructor
    ss = og.SimpleSetup(csi); ss.setStateValidityChecker(python_callable_taking_state)
    g = ob.GoalStates(csi); g.addState(s); ss.setGoal(g); ss.setStartState(s0)
    ss.solve(ob.PlannerTerminationCondition(python_callable))
    ss.getSolutionPath().interpolate(); path.getStates()

nanobind reports "leaked instance" at interpreter exit only for OMPL objects still alive then
(module-level globals, or reference cycles through C++ holders); :func:`plan_ompl` keeps every
OMPL object local and its callbacks hold no OMPL object, so nothing is left at exit.
"""

from __future__ import annotations

import functools
import math
import time
import traceback
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from genplan._arrays import as_configurations
from genplan.collision import CollisionWorld
from genplan.projection import (
    ComBox,
    FrameOrientation,
    FramePose,
    FramePosition,
    JointLimits,
    Posture,
    Task,
    _BoundTerm,
    _State,
)
from genplan.robots import Robot

Array = NDArray[np.float64]

#: OMPL's defaults (ompl::magic), repeated so the module imports without ompl.
OMPL_DEFAULT_DELTA = 0.05
#: Free-flyer chart box around the default base pose: +- metres, +- radians per rotation-vector axis.
BASE_POSITION_BOX = 0.5
BASE_ROTATION_BOX = 1.0


def _ompl() -> tuple[Any, Any, Any]:
    try:
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("the OMPL peer needs the `ompl` package: pip install 'genplan[bench]' (or ompl>=2.0)") from exc
    return ob, og, ou


# --------------------------------------------------------------------------------------------
# Chart: q (Pinocchio, nq) <-> x (Euclidean, nv)
# --------------------------------------------------------------------------------------------


class ManifoldChart:
    """Euclidean coordinates x for OMPL's ambient space.

    Fixed base: x = q. Free-flyer (q = [p, qx, qy, qz, qw, joints]): x = [p, log3(R), joints], so
    ``dim = nv``. :meth:`dv_dx` maps a change of x to Pinocchio's tangent vector v (local base
    twist): v_lin = R^T dp, v_ang = Jexp3(r) dr, joints unchanged; Jacobians w.r.t. x are then
    ``J_v @ dv_dx``.
    """

    def __init__(self, robot: Robot) -> None:
        self.nq = robot.nq
        self.nv = robot.nv
        self.dim = robot.nv
        self.floating = bool(robot.floating_base)
        if self.floating:
            j = robot.model.joints[1]
            if j.shortname() != "JointModelFreeFlyer" or j.idx_q != 0 or j.idx_v != 0:
                raise ValueError(f"robot '{robot.name}': expected the free-flyer as the first joint, got {j.shortname()}")

    def to_x(self, q: Array) -> Array:
        q = np.asarray(q, dtype=np.float64)
        if not self.floating:
            return q.copy()
        quat = pin.Quaternion(q[6], q[3], q[4], q[5])  # (w, x, y, z)
        quat.normalize()
        return np.concatenate([q[:3], pin.log3(quat.toRotationMatrix()), q[7:]])

    def to_q(self, x: Array) -> Array:
        if not self.floating:
            return np.array(x, dtype=np.float64)
        q = np.empty(self.nq)
        q[:3] = x[:3]
        # unit quaternion (x, y, z, w) of the rotation vector r: (sin(|r|/2) r/|r|, cos(|r|/2));
        # plain floats: this runs in every OMPL callback
        rx, ry, rz = float(x[3]), float(x[4]), float(x[5])
        th = math.sqrt(rx * rx + ry * ry + rz * rz)
        s = 0.5 - th * th / 48.0 if th < 1e-6 else math.sin(0.5 * th) / th
        q[3], q[4], q[5], q[6] = s * rx, s * ry, s * rz, math.cos(0.5 * th)
        q[7:] = x[6:]
        return q

    def dv_dx(self, x: Array) -> Array | None:
        """d v / d x (nv, nv); None for a fixed base (identity)."""
        if not self.floating:
            return None
        r = np.asarray(x[3:6], dtype=np.float64)
        m = np.eye(self.nv)
        m[:3, :3] = pin.exp3(r).T
        m[3:6, 3:6] = pin.Jexp3(r)
        return m

    def jacobian_x(self, jv: Array, x: Array) -> Array:
        """A Jacobian w.r.t. v turned into one w.r.t. x: ``jv @ dv_dx(x)`` (only the base
        columns change)."""
        if not self.floating:
            return jv
        r = np.asarray(x[3:6], dtype=np.float64)
        jx = jv.copy()
        jx[:, :3] = jv[:, :3] @ pin.exp3(r).T
        jx[:, 3:6] = jv[:, 3:6] @ pin.Jexp3(r)
        return jx

    def bounds(self, robot: Robot) -> tuple[Array, Array]:
        """Ambient bounds: the joint limits; a free-flyer base boxed around its default pose."""
        lo = np.empty(self.dim)
        hi = np.empty(self.dim)
        off = 6 if self.floating else 0
        jlo, jhi = (robot.lower[7:], robot.upper[7:]) if self.floating else (robot.lower, robot.upper)
        if not (np.all(np.isfinite(jlo)) and np.all(np.isfinite(jhi))):
            raise ValueError(f"robot '{robot.name}': OMPL needs finite joint limits")
        lo[off:], hi[off:] = jlo, jhi
        if self.floating:
            x0 = self.to_x(robot.q_default)
            lo[:3], hi[:3] = x0[:3] - BASE_POSITION_BOX, x0[:3] + BASE_POSITION_BOX
            lo[3:6], hi[3:6] = x0[3:6] - BASE_ROTATION_BOX, x0[3:6] + BASE_ROTATION_BOX
        return lo, hi


# --------------------------------------------------------------------------------------------
# The task as equalities F(x) = 0 plus validity conditions
# --------------------------------------------------------------------------------------------


class _PinView:
    """What :class:`_State` needs from a robot (model + data), with a private ``pin.Data`` so
    the peer never shares Pinocchio scratch memory with other users of the Robot."""

    __slots__ = ("model", "data")

    def __init__(self, model: pin.Model) -> None:
        self.model = model
        self.data = model.createData()


class TaskEquality:
    """A genplan :class:`Task`'s primary equality terms as F(x) = 0 in chart coordinates, plus its
    inequality parts (joint limits, CoM boxes) for the validity checker.

    ``function(x)`` -> (codim,), ``jacobian(x)`` -> (codim, dim). Pure numpy/Pinocchio: usable and
    testable without OMPL.
    """

    def __init__(self, robot: Robot, task: Task) -> None:
        if not isinstance(task, Task):
            raise ValueError(f"task: expected a genplan.projection.Task, got {type(task).__name__}")
        self.robot = robot
        self.chart = ManifoldChart(robot)
        self._view = _PinView(robot.model)
        self.terms: list[tuple[_BoundTerm, NDArray[np.intp]]] = []
        self.labels: list[str] = []
        self.tolerances: list[float] = []
        self.com_boxes: list[tuple[Array, Array]] = []  # (lower - tol, upper + tol)
        self.limit_slack = 0.0
        self.has_joint_limits = False
        for term in task.primary:
            if isinstance(term, (FramePose, FramePosition, FrameOrientation)):
                bound = term.bind(robot)
                rows = np.flatnonzero(bound.mask)  # type: ignore[attr-defined]
            elif isinstance(term, Posture):
                if term.q_nom is None:
                    raise ValueError(f"Posture term '{term.label()}' in the primary task needs an explicit q_nom "
                                     "to be an equality constraint")
                bound = term.bind(robot)
                rows = np.flatnonzero(bound.w)  # type: ignore[attr-defined]
            elif isinstance(term, JointLimits):
                self.has_joint_limits = True
                self.limit_slack = max(self.limit_slack, float(term.tolerance))
                continue
            elif isinstance(term, ComBox):
                b = term.bind(robot)
                tol = float(term.tolerance)
                self.com_boxes.append((b.lo - tol, b.hi + tol))  # type: ignore[attr-defined]
                continue
            else:
                raise ValueError(f"term '{term.label()}' ({type(term).__name__}) has no OMPL form "
                                 "(supported: FramePose, FramePosition, FrameOrientation, Posture, JointLimits, ComBox)")
            if rows.size:
                self.terms.append((bound, rows))
                self.labels.append(term.label())
                self.tolerances.append(float(term.tolerance))
        self.codim = int(sum(rows.size for _, rows in self.terms))
        self.dim = self.chart.dim
        if self.codim == 0:
            raise ValueError(f"task '{task.name}' has no equality rows: nothing for a constrained planner to do")
        if self.codim >= self.dim:
            raise ValueError(f"task '{task.name}': {self.codim} equality rows leave no manifold in {self.dim} dimensions")

    @property
    def manifold_dim(self) -> int:
        return self.dim - self.codim

    @property
    def default_tolerance(self) -> float:
        return min(self.tolerances)

    def function_q(self, q: Array) -> Array:
        s = _State(self._view, q, False)  # type: ignore[arg-type]
        if len(self.terms) == 1:
            b, rows = self.terms[0]
            return b.residual(s)[rows]
        return np.concatenate([b.residual(s)[rows] for b, rows in self.terms])

    def function(self, x: Array) -> Array:
        return self.function_q(self.chart.to_q(x))

    def jacobian(self, x: Array) -> Array:
        q = self.chart.to_q(x)
        s = _State(self._view, q, True)  # type: ignore[arg-type]
        if len(self.terms) == 1:
            b, rows = self.terms[0]
            jv = b.jacobian(s)[rows]
        else:
            jv = np.vstack([b.jacobian(s)[rows] for b, rows in self.terms])
        return self.chart.jacobian_x(jv, x)

    def residuals_by_term(self, q: ArrayLike) -> dict[str, float]:
        """Largest absolute component per equality term (genplan's satisfaction measure)."""
        qa = as_configurations(q, self.robot.nq, "q")
        s = _State(self._view, qa, False)  # type: ignore[arg-type]
        return {lab: float(np.abs(b.residual(s)[rows]).max()) for lab, (b, rows) in zip(self.labels, self.terms)}

    def com_ok(self, q: Array) -> bool:
        if not self.com_boxes:
            return True
        pin.centerOfMass(self._view.model, self._view.data, q, False)
        c = self._view.data.com[0]
        return all(bool(np.all(c >= lo) and np.all(c <= hi)) for lo, hi in self.com_boxes)


# --------------------------------------------------------------------------------------------
# OMPL glue
# --------------------------------------------------------------------------------------------


class _Aborted(Exception):
    """A callback failed; its exception is in the guard."""


class _Guard:
    """First exception raised inside an OMPL callback (re-raised after the solve; KeyboardInterrupt
    included) -- OMPL's C++ frames are never unwound by a Python exception."""

    __slots__ = ("error",)

    def __init__(self) -> None:
        self.error: BaseException | None = None


@dataclass
class _Counters:
    function: int = 0
    jacobian: int = 0
    satisfied: int = 0
    validity: int = 0
    #: wall time spent inside the Python callbacks (constraint and validity), s
    callback_s: float = 0.0


@functools.lru_cache(maxsize=1)
def _constraint_class() -> type:
    ob, _, _ = _ompl()

    class TaskConstraint(ob.Constraint):  # type: ignore[misc, name-defined]
        """ob.Constraint over a :class:`TaskEquality`. Holds no OMPL object (no C++ <-> Python
        reference cycle). ``project`` stays OMPL's Newton method (C++); ``isSatisfied`` and
        ``distance`` are overridden (same semantics) only so that every ``function`` call is
        part of a projection: projections = function calls - jacobian calls."""

        def __init__(self, eq: TaskEquality, tolerance: float, guard: _Guard, counters: _Counters) -> None:
            super().__init__(eq.dim, eq.codim, tolerance)
            self.eq = eq
            self.tol = float(tolerance)
            self.guard = guard
            self.counters = counters

        def _f(self, x: Any) -> Array | None:
            if self.guard.error is not None:
                return None
            try:
                return self.eq.function(x)  # x: OMPL's buffer, read during this call only
            except BaseException as exc:  # noqa: BLE001 - re-raised by plan_ompl
                self.guard.error = exc
                return None

        def function(self, x: Any, out: Any) -> None:
            t = time.perf_counter()
            self.counters.function += 1
            f = self._f(x)
            out[:] = np.nan if f is None else f
            self.counters.callback_s += time.perf_counter() - t

        def jacobian(self, x: Any, out: Any) -> None:
            t = time.perf_counter()
            self.counters.jacobian += 1
            try:
                if self.guard.error is not None:
                    out[:, :] = np.nan
                else:
                    out[:, :] = self.eq.jacobian(x)
            except BaseException as exc:  # noqa: BLE001
                self.guard.error = exc
                out[:, :] = np.nan
            self.counters.callback_s += time.perf_counter() - t

        def isSatisfied(self, x: Any) -> bool:  # noqa: N802 - OMPL's name
            # must return a Python bool: a numpy.bool_ makes the trampoline throw std::bad_cast
            t = time.perf_counter()
            self.counters.satisfied += 1
            f = self._f(x)
            ok = f is not None and bool(np.all(np.isfinite(f))) and float(f @ f) <= self.tol * self.tol
            self.counters.callback_s += time.perf_counter() - t
            return ok

        def distance(self, x: Any) -> float:
            t = time.perf_counter()
            self.counters.satisfied += 1
            f = self._f(x)
            d = math.inf if f is None else float(np.linalg.norm(f))
            self.counters.callback_s += time.perf_counter() - t
            return d

    return TaskConstraint


class _Validity:
    """State validity: chart bounds (+ joint-limit slack), CoM boxes, collisions. Holds no OMPL
    object; ``check_x`` is the same test on a chart vector."""

    def __init__(self, eq: TaskEquality, world: CollisionWorld, lo: Array, hi: Array,
                 guard: _Guard, counters: _Counters) -> None:
        self.eq = eq
        self.chart = eq.chart
        self.world = world
        self.lo = lo - eq.limit_slack
        self.hi = hi + eq.limit_slack
        self.n = eq.dim
        self.guard = guard
        self.counters = counters

    def check_x(self, x: Array) -> bool:
        if not (np.all(x >= self.lo) and np.all(x <= self.hi)):
            return False
        q = self.chart.to_q(x)
        if not self.eq.com_ok(q):
            return False
        return not bool(self.world.in_collision(q))

    def __call__(self, state: Any) -> bool:
        t = time.perf_counter()
        self.counters.validity += 1
        ok = False
        if self.guard.error is None:
            try:
                x = np.fromiter((state[i] for i in range(self.n)), dtype=np.float64, count=self.n)
                ok = self.check_x(x)
            except BaseException as exc:  # noqa: BLE001
                self.guard.error = exc
        self.counters.callback_s += time.perf_counter() - t
        return ok


# --------------------------------------------------------------------------------------------
# Public entry point
# --------------------------------------------------------------------------------------------


@dataclass
class OmplResult:
    """Outcome of one OMPL query."""

    success: bool
    #: (n, nq) float64 in genplan's q convention, from the (re-projected, see the module
    #: docstring) start to the goal ``goal_index``: the interpolated path (every state projected
    #: by OMPL, consecutive states at most ~delta apart in x) or, with ``interpolate=False``, the
    #: planner's raw vertices; empty (0, nq) on failure.
    path: Array
    #: wall time of ``SimpleSetup.solve`` (s)
    time_s: float
    #: wall time of everything before it: building the spaces, re-projecting start and goals,
    #: ``SimpleSetup.setup`` (s)
    setup_s: float
    #: OMPL PlannerStatus name (EXACT_SOLUTION, TIMEOUT, APPROXIMATE_SOLUTION, ...) or
    #: INVALID_START / INVALID_GOAL (detected here, before planning)
    status: str
    #: index into ``q_goals`` of the goal the path ends at (-1 on failure)
    goal_index: int = -1
    #: calls to OMPL's Newton projection (Constraint::project): function calls - jacobian calls
    projections: int = 0
    #: Newton iterations (= Jacobian evaluations) over all projections
    projection_iterations: int = 0
    #: calls of Constraint.function / isSatisfied+distance / the state validity checker
    function_calls: int = 0
    satisfied_checks: int = 0
    validity_checks: int = 0
    #: part of ``time_s`` spent in genplan's Python callbacks (constraint function/Jacobian via
    #: Pinocchio, validity via parry); the rest is OMPL's C++ (Newton steps' SVDs, trees, NN)
    callback_s: float = 0.0
    #: states of the planner's path before interpolation
    raw_states: int = 0
    #: indices into ``q_goals`` handed to OMPL (valid after re-projection)
    goals_used: list[int] = field(default_factory=list)
    delta: float = OMPL_DEFAULT_DELTA
    tolerance: float = 0.0
    planner: str = "RRTConnect"


def _status_name(status: Any) -> str:
    st = status.getStatus() if hasattr(status, "getStatus") else status
    return getattr(st, "name", str(st))


def plan_ompl(
    robot: Robot,
    world: CollisionWorld,
    task: Task,
    q_start: ArrayLike,
    q_goals: ArrayLike,
    *,
    time_limit: float = 10.0,
    seed: int = 0,
    planner: str = "RRTConnect",
    delta: float | None = None,
    tolerance: float | None = None,
    planner_range: float | None = None,
    interpolate: bool = True,
    verbose: bool = False,
) -> OmplResult:
    """Plan from ``q_start`` (nq,) to any of ``q_goals`` ((K, nq) or (nq,)) with OMPL's
    ProjectedStateSpace and ``planner`` (default RRTConnect; any ``ompl.geometric`` planner name).

    ``delta``: geodesic step = validity-checking resolution (default OMPL's 0.05);
    ``tolerance``: ``||F||_2`` bound (default the smallest equality-term tolerance of ``task``);
    ``planner_range``: the planner's range (default OMPL's: 0.2 x the ambient space's extent);
    ``seed``: OMPL's global seed is reset (to ``seed % (2**31 - 1) + 1``: OMPL rejects 0) before
    anything is allocated, so a query is reproducible (up to the time limit). The projection's
    Newton iterations stay at OMPL's default 50 (genplan's projector: 50 too). Never raises on planning
    failure (``success=False``); ValueError on bad input (shapes, NaN, non-positive parameters,
    starts/goals far from the manifold, a rank-deficient constraint). Exceptions from genplan
    callbacks (and Ctrl-C) stop the solve and are re-raised.
    """
    ob, og, ou = _ompl()
    t0 = time.perf_counter()
    if not isinstance(robot, Robot):
        raise ValueError(f"robot: expected a genplan.Robot, got {type(robot).__name__}")
    if not isinstance(world, CollisionWorld):
        raise ValueError(f"world: expected a genplan.CollisionWorld, got {type(world).__name__}")
    start = as_configurations(q_start, robot.nq, "q_start")
    if start.ndim != 1:
        raise ValueError(f"q_start: expected one configuration of shape ({robot.nq},), got {start.shape}")
    goals = as_configurations(q_goals, robot.nq, "q_goals").reshape(-1, robot.nq)
    if len(goals) == 0:
        raise ValueError("q_goals: need at least one goal configuration")
    if not (isinstance(time_limit, (int, float)) and math.isfinite(time_limit) and time_limit > 0):
        raise ValueError(f"time_limit: expected a positive number of seconds, got {time_limit!r}")
    delta = OMPL_DEFAULT_DELTA if delta is None else float(delta)
    if not (math.isfinite(delta) and delta > 0):
        raise ValueError(f"delta: expected a positive step, got {delta}")
    if planner_range is not None and not (math.isfinite(planner_range) and planner_range > 0):
        raise ValueError(f"planner_range: expected a positive distance, got {planner_range}")
    planner_cls = getattr(og, planner, None)
    if not (isinstance(planner_cls, type) and issubclass(planner_cls, ob.Planner)):
        raise ValueError(f"planner: '{planner}' is not an ompl.geometric planner")

    eq = TaskEquality(robot, task)
    tol = eq.default_tolerance if tolerance is None else float(tolerance)
    if not (math.isfinite(tol) and tol > 0):
        raise ValueError(f"tolerance: expected a positive number, got {tol}")
    lo, hi = eq.chart.bounds(robot)

    guard = _Guard()
    old_level = ou.getLogLevel()
    ou.setLogLevel(ou.LogLevel.LOG_INFO if verbose else ou.LogLevel.LOG_NONE)
    try:
        ou.RNG.setSeed(int(seed) % (2**31 - 1) + 1)  # complains (muted) but reseeds when RNGs exist
        if not verbose:
            ou.setLogLevel(ou.LogLevel.LOG_WARN)
        out = _plan(ob, og, robot, world, eq, start, goals, lo, hi, tol, delta, float(time_limit),
                    planner, planner_cls, planner_range, interpolate, t0, guard)
    except BaseException as exc:
        # the traceback must not keep _plan's OMPL objects alive (nanobind would report them as
        # leaked at exit); file/line information is kept
        traceback.clear_frames(exc.__traceback__)
        raise
    finally:
        ou.setLogLevel(old_level)
    if guard.error is not None or out is None:
        err = guard.error or RuntimeError("OMPL solve aborted")
        guard.error = None
        # the callback frames hold OMPL states whose memory is gone now: drop their locals
        traceback.clear_frames(err.__traceback__)
        raise err
    return out


def _plan(ob: Any, og: Any, robot: Robot, world: CollisionWorld, eq: TaskEquality, start: Array, goals: Array,
          lo: Array, hi: Array, tol: float, delta: float, time_limit: float, planner: str, planner_cls: type,
          planner_range: float | None, interpolate: bool, t0: float, guard: _Guard) -> OmplResult | None:
    """Everything that touches OMPL objects; returns None when a callback failed (guard.error)."""
    counters = _Counters()
    constraint = _constraint_class()(eq, tol, guard, counters)
    validity = _Validity(eq, world, lo, hi, guard, counters)
    chart = eq.chart
    nq = robot.nq

    def result(success: bool, status: str, **kw: Any) -> OmplResult:
        return OmplResult(success=success, status=status, setup_s=kw.pop("setup_s", time.perf_counter() - t0),
                          time_s=kw.pop("time_s", 0.0), path=kw.pop("path", np.zeros((0, nq))),
                          projections=counters.function - counters.jacobian, projection_iterations=counters.jacobian,
                          function_calls=counters.function, satisfied_checks=counters.satisfied,
                          validity_checks=counters.validity, callback_s=counters.callback_s, delta=delta,
                          tolerance=tol, planner=planner, **kw)

    def reproject(q: Array, what: str) -> Array:
        x = chart.to_x(q)
        x0 = x.copy()
        ok = constraint.project(x)  # OMPL's Newton projection, in place
        if guard.error is not None:
            raise _Aborted
        if not ok or not np.all(np.isfinite(x)) or np.abs(x - x0).max() > 1e-2:
            res = eq.residuals_by_term(q)
            raise ValueError(f"{what} is not on the constraint manifold (residuals {res}); "
                             "project it first (GaussNewtonProjector)")
        return x

    try:
        x_start = reproject(start, "q_start")
        x_goals = [reproject(g, f"q_goals[{i}]") for i, g in enumerate(goals)]
    except _Aborted:
        return None
    # rank of the constraint at the start (OMPL needs the co-dimension exactly)
    sv = np.linalg.svd(eq.jacobian(x_start), compute_uv=False)
    if sv.size < eq.codim or sv[-1] < 1e-9 * max(1.0, sv[0]):
        raise ValueError(f"the task's {eq.codim} equality rows have rank < {eq.codim} at q_start "
                         f"(smallest singular value {sv[-1] if sv.size else 0:.2e}): remove redundant rows")
    if not validity.check_x(x_start):
        return result(False, "INVALID_START")
    goals_used = [i for i, xg in enumerate(x_goals) if validity.check_x(xg)]
    if not goals_used:
        return result(False, "INVALID_GOAL")

    rvss = ob.RealVectorStateSpace(eq.dim)
    bounds = ob.RealVectorBounds(eq.dim)
    for i in range(eq.dim):
        bounds.setLow(i, float(lo[i]))
        bounds.setHigh(i, float(hi[i]))
    rvss.setBounds(bounds)
    css = ob.ProjectedStateSpace(rvss, constraint)
    csi = ob.ConstrainedSpaceInformation(css)
    css.setup()
    css.setDelta(delta)  # also sets the validity-checking resolution (see the module docstring)
    ss = og.SimpleSetup(csi)
    ss.setStateValidityChecker(validity)
    s_start = css.allocState()
    s_start.copy(x_start.tolist())
    ss.setStartState(s_start)
    goal = ob.GoalStates(csi)
    for i in goals_used:
        s = css.allocState()
        s.copy(x_goals[i].tolist())
        goal.addState(s)
    ss.setGoal(goal)
    pl = planner_cls(csi)
    if planner_range is not None:
        pl.setRange(float(planner_range))
    ss.setPlanner(pl)
    ss.setup()
    setup_s = time.perf_counter() - t0

    deadline = time.perf_counter() + time_limit

    def stop() -> bool:  # called by the planner every iteration
        try:
            return guard.error is not None or time.perf_counter() >= deadline
        except BaseException as exc:  # noqa: BLE001 - e.g. Ctrl-C landing here
            guard.error = exc
            return True

    ptc = ob.PlannerTerminationCondition(stop)
    # the statistics describe the solve only (not the start/goal re-projection above)
    counters.function = counters.jacobian = counters.satisfied = counters.validity = 0
    counters.callback_s = 0.0
    t1 = time.perf_counter()
    status = ss.solve(ptc)
    time_s = time.perf_counter() - t1
    if guard.error is not None:
        return None
    name = _status_name(status)
    if name != "EXACT_SOLUTION" or not ss.haveExactSolutionPath():
        return result(False, name, setup_s=setup_s, time_s=time_s, goals_used=goals_used)

    path = ss.getSolutionPath()
    raw = path.getStateCount()
    if interpolate:
        path.interpolate()
    n = eq.dim
    xs = np.array([[st[i] for i in range(n)] for st in path.getStates()], dtype=np.float64)
    qs = np.array([chart.to_q(x) for x in xs]).reshape(-1, nq)
    d_goal = [float(np.linalg.norm(xs[-1] - x_goals[i])) for i in goals_used]
    goal_index = goals_used[int(np.argmin(d_goal))]
    if guard.error is not None:
        return None
    return result(True, name, setup_s=setup_s, time_s=time_s, path=qs, goal_index=goal_index,
                  raw_states=raw, goals_used=goals_used)


__all__ = ["BASE_POSITION_BOX", "BASE_ROTATION_BOX", "OMPL_DEFAULT_DELTA", "ManifoldChart", "OmplResult", "TaskEquality",
           "plan_ompl"]
