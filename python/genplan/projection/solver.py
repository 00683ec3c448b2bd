"""The projector: damped Gauss-Newton with a task hierarchy (the GAN paper's Section III-B), the
planner's Projector and the IK solver. :class:`GaussNewtonProjector` runs the native solver
(rust/core/src/projection/) or, with ``backend="pinocchio"``, the same algorithm here in Python
on Pinocchio's analytic derivatives (the test oracle of the native one, and the solver of terms
that only define ``bind()``). :func:`check_task_use` tries, before any training, every use a
learned sampler makes of a task."""

from __future__ import annotations

import json
import time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from genplan import _core
from genplan._arrays import as_float_array, error_class
from genplan.errors import GenplanError, SettingsError, ShapeError, TaskFileError, UnknownNameError
from genplan.projection.base import Array, _State
from genplan.projection.frame import FrameOrientation, FramePose, FramePosition
from genplan.projection.joints import _PostureBound
from genplan.projection.relative import RelativePose, RelativePosition
from genplan.projection.task import ROBOT_FIELD, Task, condition_term, manifold_task, unset_condition_term
from genplan.robots import Robot


#: Damped Gauss-Newton settings, defined once in the Rust core (``projection::Settings``):
#: keyword-only, immutable (``replace(**changes)``), validated (:class:`~genplan.errors.SettingsError`).
#: Defaults: the GAN paper and its public code (``mu``: damping lambda = mu r^T r + mu_bar).
SolverSettings = _core.SolverSettings
#: ``SolverSettings.active_set``: a bounded joint within this of a limit is at it (as
#: rust/core/src/projection/solver.rs ``AT_LIMIT``; the clipping puts it exactly there).
AT_LIMIT = 1e-9


@dataclass
class ProjectionResult:
    """Outcome of one solve."""

    q: Array
    success: bool
    iterations: int
    #: per primary term: largest absolute component of its unweighted residual at ``q``
    residuals: dict[str, float]
    time_s: float


@dataclass
class BatchResult:
    """Outcome of many solves, as arrays."""

    q: Array  # (n, nq)
    success: NDArray[np.bool_]
    iterations: NDArray[np.int64]
    residuals: dict[str, Array]
    time_s: Array

    def __len__(self) -> int:
        return len(self.success)


def _damped_pinv(jac: Array, lam: float) -> Array:
    m, n = jac.shape
    if m <= n:
        return jac.T @ np.linalg.solve(jac @ jac.T + lam * np.eye(m), np.eye(m))
    return np.linalg.solve(jac.T @ jac + lam * np.eye(n), jac.T)


BACKENDS = ("native", "pinocchio")


class GaussNewtonProjector:
    """Damped Gauss-Newton with a null-space posture task (the Projector the planner calls).

    ``solve(q0)`` projects one configuration; ``solve_batch(q0s)`` many; ``project(qs, q_noms)``
    is the planner's batched entry point (posture around ``q_noms``).

    ``backend="native"`` (default) runs the Rust solver (built-in terms and :class:`CustomTerm`
    subclasses, GIL released but for a custom term's calls, batches in parallel);
    ``backend="pinocchio"`` runs the same algorithm in Python on Pinocchio's analytic derivatives
    (the test oracle of the native one), and also accepts :class:`Term` subclasses that only
    define ``bind()``.

    A task whose condition term leaves its target out (each query sets it, docs/TASKS.md) is
    solved only with per-row targets for that term (``solve_batch(q0s, targets={term: rows})``);
    ``solve``, ``solve_batch`` without them, ``project`` and :attr:`native` (what a planner runs)
    raise SettingsError naming the term.
    """

    def __init__(self, robot: Robot, task: Task, settings: SolverSettings | None = None, backend: str = "native") -> None:
        if backend not in BACKENDS:
            raise UnknownNameError(f"unknown backend '{backend}' (known: {', '.join(BACKENDS)})")
        if not task.primary:
            raise GenplanError("a task needs at least one primary term")
        self.robot = robot
        self.task = task
        self.backend = backend
        self.settings = settings or SolverSettings()
        # A condition term without its target (each query sets it): solved only with per-row
        # targets for it (solve_batch(targets=...)); the solver is built with a stand-in target, the
        # middle of the condition's box, which every such solve replaces.
        self._unset = unset_condition_term(task)
        c = task.condition
        if self._unset is not None and c is not None and len(c.low) == 3:
            task = task.with_targets(**{self._unset: np.array(c.middle())})
        self._primary = [t.bind(robot) for t in task.primary]
        self._secondary = [t.bind(robot) for t in task.secondary]
        labels = [t.label() for t in task.primary]
        if len(set(labels)) != len(labels):
            raise GenplanError(f"primary term names must be unique, got {labels}")
        self._labels = labels
        self._weights = [float(t.weight) for t in task.primary]
        self._tols = [float(t.tolerance) for t in task.primary]
        self._bounded = np.isfinite(robot.lower) & np.isfinite(robot.upper)
        # (q index, v index) of each bounded 1-dof joint, in the model's order (the active set's)
        self._bounded_qv = [(j.idx_q, j.idx_v) for j in robot.model.joints[1:]
                            if j.nq == 1 and j.nv == 1 and self._bounded[j.idx_q]]
        self._eye_nv = np.eye(robot.nv)
        self._native: _core.Projector | None = None
        if backend == "native":
            self._native = _core.Projector(
                robot.kinematics,
                [t.to_native(robot) for t in task.primary],
                [t.to_native(robot) for t in task.secondary],
                self.settings,
            )

    @property
    def native(self) -> _core.Projector | None:
        """The native solver (``backend="native"``), which the planner calls without Python.
        SettingsError for a task whose condition term has no target (nothing to aim at)."""
        self._need_target(None)
        return self._native

    def _need_target(self, term_name: str | None) -> None:
        """SettingsError unless the condition term without a target gets one per row
        (``term_name``: the term given per-row targets)."""
        if self._unset is not None and term_name != self._unset:
            raise SettingsError(f"task '{self.task.name}': its condition term '{self._unset}' has no target (each "
                                f"query sets it): give one per row, solve_batch(..., targets={{'{self._unset}': "
                                f"rows}}), or set it, task.with_targets({self._unset}=...)")

    # -- evaluation --------------------------------------------------------------------------

    def _primary_residuals(self, q: Array, with_jacobians: bool) -> tuple[_State, list[Array]]:
        s = _State(self.robot, q, with_jacobians)
        return s, [b.residual(s) for b in self._primary]

    def _cost(self, raws: list[Array]) -> float:
        return float(sum(w * w * float(r @ r) for w, r in zip(self._weights, raws)))

    def _satisfied(self, raws: list[Array]) -> bool:
        return all(r.size == 0 or float(np.abs(r).max()) < tol for r, tol in zip(raws, self._tols))

    def _clip(self, q: Array) -> Array:
        if self.settings.clip_to_limits:
            b = self._bounded
            q[b] = np.clip(q[b], self.robot.lower[b], self.robot.upper[b])
        return q

    def _hold_at_limits(self, q: Array, lam: float, r1: Array, j1: Array, j1_pinv: Array,
                        dq1: Array) -> tuple[list[int], Array, Array, Array]:
        """``SolverSettings.active_set``: while the step ``-dq1`` moves a bounded joint that sits
        at a limit out of its range, hold it (zero its Jacobian column) and solve the step again;
        as rust/core/src/projection/solver.rs ``Projector::hold_at_limits``."""
        held: list[int] = []
        lower, upper = self.robot.lower, self.robot.upper
        while True:
            before = len(held)
            for iq, iv in self._bounded_qv:
                v = -dq1[iv]
                out = (q[iq] <= lower[iq] + AT_LIMIT and v < 0.0) or (q[iq] >= upper[iq] - AT_LIMIT and v > 0.0)
                if out and iv not in held:
                    held.append(iv)
                    j1[:, iv] = 0.0
            if len(held) == before:
                return held, j1, j1_pinv, dq1
            j1_pinv = _damped_pinv(j1, lam)
            dq1 = j1_pinv @ r1

    def _step(self, q: Array, dq: Array, alpha: float) -> Array:
        return self._clip(pin.integrate(self.robot.model, q, -alpha * dq))

    def residual_sizes(self, q: ArrayLike) -> dict[str, Array]:
        """Per primary term (by label), its residual size at each row of ``q`` ((n, nq)): the
        largest absolute component of its unweighted residual (+inf for a NaN), what
        :meth:`solve_batch` reports as ``residuals`` and the terms' tolerances bound, here with no
        solver step, no clipping and no Jacobian: the check of many configurations (a timed
        trajectory's samples) against the task. Native: one forward kinematics a row, the rows in
        parallel with the GIL released (``_core.residual_sizes``)."""
        self._need_target(None)
        qs = self.robot.check_configuration(q, "q")
        if qs.ndim != 2:
            raise ShapeError(f"q: expected shape (n, {self.robot.nq}), got {qs.shape}")
        if self._native is not None:
            sizes = _core.residual_sizes(self._native, np.ascontiguousarray(qs, dtype=np.float64))
            return {lab: sizes[:, i] for i, lab in enumerate(self._labels)}

        def size(r: Array) -> float:
            return 0.0 if r.size == 0 else float("inf") if np.isnan(r).any() else float(np.abs(r).max())

        rows = [[size(r) for r in self._primary_residuals(row, False)[1]] for row in qs]
        table = np.array(rows, dtype=np.float64).reshape(len(qs), len(self._labels))
        return {lab: table[:, i] for i, lab in enumerate(self._labels)}

    # -- solving -----------------------------------------------------------------------------

    def solve(self, q0: ArrayLike, q_nom: ArrayLike | None = None) -> ProjectionResult:
        """Project ``q0`` (shape (nq,)); the posture task regularises around ``q_nom``
        (default ``q0``). A target out of reach ends with ``success=False`` and the best q."""
        t0 = time.perf_counter()
        self._need_target(None)
        q = self.robot.check_configuration(q0, "q0")
        if q.ndim != 1:
            raise ShapeError(f"q0: solve takes one configuration of shape ({self.robot.nq},); use solve_batch")
        if self._native is not None:
            nom = None if q_nom is None else self.robot.check_configuration(q_nom, "q_nom").reshape(1, -1)
            qs, ok, it, res, ts = self._native.solve_batch(q.reshape(1, -1), nom, False)
            return ProjectionResult(q=qs[0], success=bool(ok[0]), iterations=int(it[0]),
                                    residuals=dict(zip(self._labels, map(float, res[0]))), time_s=float(ts[0]))
        q = self._clip(q.copy())
        nominal = q.copy() if q_nom is None else self.robot.check_configuration(q_nom, "q_nom")
        for b in (*self._primary, *self._secondary):
            if isinstance(b, _PostureBound):
                b.set_nominal(nominal)
        st = self.settings
        model = self.robot.model
        iterations = 0
        s, raws = self._primary_residuals(q, True)
        while not self._satisfied(raws) and iterations < st.max_iterations:
            r1 = np.concatenate([w * r for w, r in zip(self._weights, raws)])
            j1 = np.vstack([w * b.jacobian(s) for w, b in zip(self._weights, self._primary)])
            c0 = float(r1 @ r1)
            lam = st.mu * c0 + st.mu_bar
            j1_pinv = _damped_pinv(j1, lam)
            dq1 = j1_pinv @ r1
            held: list[int] = []
            if st.active_set:
                held, j1, j1_pinv, dq1 = self._hold_at_limits(q, lam, r1, j1.copy(), j1_pinv, dq1)
            slope = 2.0 * float(r1 @ (j1 @ dq1))  # -d cost / d alpha at alpha = 0
            alpha = 1.0
            for _ in range(st.max_backtracks):
                q_new = self._step(q, dq1, alpha)
                _, raws_new = self._primary_residuals(q_new, False)
                c = self._cost(raws_new)
                if c <= c0 - st.armijo_c1 * alpha * slope:
                    break
                alpha *= st.backtrack
            if self._secondary:
                # eq. (3): the posture step in the primary's null space, kept only while it does
                # not make the primary cost worse (beyond a slack).
                r2 = np.concatenate([b.term.weight * b.residual(s) for b in self._secondary])
                j2 = np.vstack([b.term.weight * b.jacobian(s) for b in self._secondary])
                j2[:, held] = 0.0
                n1 = self._eye_nv - j1_pinv @ j1
                dq2 = n1 @ (_damped_pinv(j2 @ n1, st.mu_bar) @ (r2 - alpha * (j2 @ dq1)))
                alpha2 = 1.0
                for _ in range(st.secondary_backtracks):
                    q_try = self._step(q_new, dq2, alpha2)
                    _, raws_try = self._primary_residuals(q_try, False)
                    if self._cost(raws_try) <= c + st.secondary_slack:
                        q_new = q_try
                        break
                    alpha2 *= st.backtrack
            q = q_new
            iterations += 1
            s, raws = self._primary_residuals(q, True)
        residuals = {lab: (float(np.abs(r).max()) if r.size else 0.0) for lab, r in zip(self._labels, raws)}
        return ProjectionResult(
            q=q,
            success=self._satisfied(raws),
            iterations=iterations,
            residuals=residuals,
            time_s=time.perf_counter() - t0,
        )

    def solve_batch(self, q0s: ArrayLike, q_noms: ArrayLike | None = None, *, targets: Mapping[str, ArrayLike] | None = None,
                    progress: bool = False, parallel: bool = True) -> BatchResult:
        """Solve from each row of ``q0s`` (shape (n, nq)); ``q_noms`` likewise or None.

        ``targets`` gives one primary term per-row targets, e.g. ``{"hand_position": P}`` with P of
        shape (n, 3) (a FramePose term takes (n, 4, 4)). The native backend runs the rows on all
        cores when ``parallel`` (each row's ``time_s`` is its own solve time); ``parallel=False``
        runs them one after the other, as it always does for a task with a :class:`CustomTerm`
        (its calls hold the GIL: threads contending for it were slower, see
        rust/python/src/lib.rs, ``PyProjector::solve_batch``)."""
        qs = self.robot.check_configuration(q0s, "q0s")
        if qs.ndim != 2:
            raise ShapeError(f"q0s: expected shape (n, {self.robot.nq}), got {qs.shape}")
        noms = None if q_noms is None else self.robot.check_configuration(q_noms, "q_noms")
        if noms is not None and noms.shape != qs.shape:
            raise ShapeError(f"q_noms: expected shape {qs.shape}, got {noms.shape}")
        term_name, target_rows = None, None
        if targets:
            if len(targets) != 1:
                raise GenplanError(f"targets: give per-row targets for one term, got {sorted(targets)}")
            term_name, raw = next(iter(targets.items()))
            target_rows = np.ascontiguousarray(as_float_array(raw, f"targets['{term_name}']"))
            if target_rows.shape[0] != len(qs) or not np.all(np.isfinite(target_rows)):
                raise error_class(target_rows, target_rows.shape[0] == len(qs))(
                    f"targets['{term_name}']: expected {len(qs)} finite rows, got shape {target_rows.shape}")
            term = next((t for t in self.task.primary if t.name == term_name), None)
            row_shape = {FramePosition: (3,), FrameOrientation: (3, 3), FramePose: (4, 4), RelativePosition: (3,),
                         RelativePose: (4, 4)}.get(type(term))
            if row_shape is not None and target_rows.shape[1:] != row_shape:
                raise ShapeError(f"targets['{term_name}']: expected shape ({len(qs)}, "
                                 f"{', '.join(map(str, row_shape))}), got {target_rows.shape}")
        self._need_target(term_name)
        if self._native is not None:
            if target_rows is not None:
                # one row of numbers per configuration (a FramePose's (4, 4) flattened); zero rows too
                target_rows = target_rows.reshape(len(qs), int(np.prod(target_rows.shape[1:])))
            q, ok, it, res, ts = self._native.solve_batch(qs, noms, parallel, term_name, target_rows)
            return BatchResult(q=q, success=ok, iterations=it,
                               residuals={lab: res[:, i] for i, lab in enumerate(self._labels)}, time_s=ts)
        rows = range(len(qs))
        if progress:
            from tqdm import tqdm

            rows = tqdm(rows, desc=f"{self.task.name}", unit="task", leave=False)
        results = []
        for i in rows:
            solver = self
            if term_name is not None:
                assert target_rows is not None
                solver = GaussNewtonProjector(self.robot, self.task.with_targets(**{term_name: target_rows[i]}),
                                              self.settings, backend=self.backend)
            results.append(solver.solve(qs[i], None if noms is None else noms[i]))
        return _stack(results, self._labels, self.robot.nq)

    def project(self, qs: ArrayLike, q_noms: ArrayLike | None = None) -> tuple[Array, NDArray[np.bool_]]:
        """The planner's Projector call: project each row, posture around ``q_noms``.
        Returns (projected configurations (n, nq), success mask (n,))."""
        res = self.solve_batch(qs, q_noms)
        return res.q, res.success


def _stack(results: list[ProjectionResult], labels: list[str], nq: int) -> BatchResult:
    return BatchResult(
        q=np.array([r.q for r in results]).reshape(len(results), nq),
        success=np.array([r.success for r in results], dtype=bool),
        iterations=np.array([r.iterations for r in results], dtype=np.int64),
        residuals={lab: np.array([r.residuals[lab] for r in results]) for lab in labels},
        time_s=np.array([r.time_s for r in results]),
    )


def check_task_use(task: Task, robot: Robot) -> None:
    """Try, on ``robot``'s default configuration, every use a learned sampler's training, its
    card and its evaluation make of ``task``, so that a task they cannot use fails before the
    work, with the error the late use would raise: its plain form (the card's ``task``: JSON,
    read back equal), its condition term and box (:func:`condition_term`), the projector of its
    manifold (the training data, :func:`manifold_task`), and the projector of the whole task
    with the condition's target given per row (the card's IK evaluation). A python term
    (:class:`CustomTerm`) must be importable by its entry (:func:`python_term_entry`) with plain
    parameters, and its ``robot`` field, when it has one, must be ``robot``: a card and a
    data-generation worker rebuild it from that."""
    data = task.to_dict()
    try:
        text = json.dumps(data, sort_keys=True)
    except (TypeError, ValueError) as exc:
        raise TaskFileError(f"task '{task.name}': its plain form is not JSON ({exc})") from None
    for t in task.python_terms:
        held = getattr(t, ROBOT_FIELD, None)
        if isinstance(held, Robot) and held is not robot and held.kinematic_hash != robot.kinematic_hash:
            raise TaskFileError(f"task '{task.name}': python term '{t.label()}' holds robot '{held.name}', not the "
                                f"robot '{robot.name}' it is used with (a card records the task without its robot, "
                                "and reading it back gives the term this one)")
    # allow_python: the entries read back are those of the terms this process already holds
    again = Task.from_dict(json.loads(text), robot, origin=f"task '{task.name}' (read back)", allow_python=True)
    if json.dumps(again.to_dict(), sort_keys=True) != text:
        raise TaskFileError(f"task '{task.name}': its plain form does not read back the same (a term whose fields a "
                            "task file cannot hold)")
    cond = condition_term(task)
    assert task.condition is not None
    q = robot.q_default[None]
    GaussNewtonProjector(robot, manifold_task(task, robot)).solve_batch(q, parallel=False)
    middle = np.array([task.condition.middle()])
    GaussNewtonProjector(robot, task).solve_batch(q, targets={cond.name: middle}, parallel=False)
