"""genplan.projection.CustomTerm: a term of the user's own (numpy + Pinocchio) runs inside the native
solver (rust/python/src/lib.rs, PyCustomTerm) and gives the Pinocchio twin's answers; its
exceptions reach the caller unchanged; bad outputs raise typed errors naming the term."""

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

import genplan
from genplan import projection as P
from genplan.errors import GenplanError, NonFiniteError, ShapeError, TaskFileError
from tests.conftest import random_configurations


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _frame(robot: genplan.Robot, frame: str, q: np.ndarray) -> tuple[pin.SE3, np.ndarray]:
    """Placement and LOCAL Jacobian (6 x nv) of a frame, on a Data of its own."""
    data = robot.model.createData()
    fid = robot.frame_id(frame)
    pin.computeJointJacobians(robot.model, data, q)
    pin.updateFramePlacements(robot.model, data)
    return data.oMf[fid].copy(), pin.getFrameJacobian(robot.model, data, fid, pin.LOCAL)


@dataclass(frozen=True)
class ToolUpright(P.CustomTerm):
    """The tool's z axis vertical: r = (z_x, z_y) of the frame's z axis in the world;
    dz/dv = -[z]x R J_local[3:] (the world angular velocity crossed with z)."""

    robot: Any = None
    frame: str = "hand"
    dim = 2

    def residual(self, q: np.ndarray) -> np.ndarray:
        return np.array([_frame(self.robot, self.frame, row)[0].rotation[:2, 2] for row in q])

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        out = []
        for row in q:
            m, jl = _frame(self.robot, self.frame, row)
            z = m.rotation[:, 2]
            out.append((-_skew(z) @ m.rotation @ jl[3:])[:2])
        return np.array(out)


@dataclass(frozen=True)
class HandPosition(P.CustomTerm):
    """The built-in FramePosition written by hand: r = p(q) - target, J = R J_local[:3]; residual
    and Jacobian from one forward kinematics (``residual_and_jacobian``)."""

    robot: Any = None
    frame: str = "hand"
    target: Any = None
    dim = 3

    def residual_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        frames = [_frame(self.robot, self.frame, row) for row in q]
        r = np.array([m.translation - self.target for m, _ in frames])
        j = np.array([m.rotation @ jl[:3] for m, jl in frames])
        return r, j

    def residual(self, q: np.ndarray) -> np.ndarray:
        return self.residual_and_jacobian(q)[0]

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        return self.residual_and_jacobian(q)[1]


class Boom(RuntimeError):
    """An exception of the user's own."""


@dataclass(frozen=True)
class Faulty(ToolUpright):
    """ToolUpright that misbehaves on its ``after``-th call of ``where`` (``residual`` or
    ``jacobian``): raises ``error``, or returns ``output(value)`` instead."""

    where: str = "residual"
    after: int = 1
    error: Exception | None = None
    output: Any = None
    calls: list[int] = field(default_factory=list, compare=False, hash=False)

    def _maybe(self, method: str, value: np.ndarray) -> Any:
        if method != self.where:
            return value
        self.calls.append(1)
        if len(self.calls) < self.after:
            return value
        if self.error is not None:
            raise self.error
        return self.output(value)

    def residual(self, q: np.ndarray) -> np.ndarray:
        return self._maybe("residual", super().residual(q))

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        return self._maybe("jacobian", super().jacobian(q))


def _upright_task(robot: genplan.Robot, term: P.Term | None = None) -> P.Task:
    term = term or ToolUpright(robot=robot, name="upright", weight=10.0, tolerance=1e-6)
    return P.Task(primary=[term, P.JointLimits(weight=10.0, tolerance=1e-6)], secondary=[P.Posture()], name="upright")


def _starts(robot: genplan.Robot, n: int, seed: int) -> np.ndarray:
    return random_configurations(robot, n, seed=seed)


def test_custom_term_runs_natively_and_matches_the_pinocchio_twin(panda: genplan.Robot) -> None:
    task = _upright_task(panda)
    native = P.GaussNewtonProjector(panda, task)
    oracle = P.GaussNewtonProjector(panda, task, backend="pinocchio")
    assert native.backend == "native" and native.native is not None
    assert oracle.native is None
    solved = 0
    for q0 in _starts(panda, 6, seed=3):
        a, b = native.solve(q0), oracle.solve(q0)
        assert (a.success, a.iterations) == (b.success, b.iterations)
        np.testing.assert_allclose(a.q, b.q, atol=1e-6)
        assert a.residuals.keys() == b.residuals.keys() == {"upright", "JointLimits"}
        assert a.residuals["upright"] == pytest.approx(b.residuals["upright"], abs=1e-6)
        if a.success:
            solved += 1
            z = panda.frame_placement(a.q, "hand").rotation[:, 2]
            assert abs(z[0]) < 1e-6 and abs(z[1]) < 1e-6
    assert solved >= 5


def test_custom_jacobian_matches_finite_differences(panda: genplan.Robot) -> None:
    term = ToolUpright(robot=panda)
    for q in _starts(panda, 3, seed=5):
        jac = term.jacobian(q[None])[0]
        cols = []
        for k in range(panda.nv):
            e = np.zeros(panda.nv)
            e[k] = 1e-7
            plus = term.residual(pin.integrate(panda.model, q, e)[None])[0]
            minus = term.residual(pin.integrate(panda.model, q, -e)[None])[0]
            cols.append((plus - minus) / 2e-7)
        np.testing.assert_allclose(jac, np.array(cols).T, atol=1e-6)


def test_custom_term_equal_to_a_built_in_one_solves_like_it(panda: genplan.Robot) -> None:
    target = panda.frame_placement(_starts(panda, 1, seed=11)[0], "hand").translation
    built_in = P.Task(primary=[P.FramePosition(frame="hand", target=target, weight=50.0, tolerance=1e-5, name="hand"),
                               P.JointLimits(weight=30.0)], secondary=[P.Posture()])
    custom = P.Task(primary=[HandPosition(robot=panda, target=target, weight=50.0, tolerance=1e-5, name="hand"),
                             P.JointLimits(weight=30.0)], secondary=[P.Posture()])
    starts = _starts(panda, 8, seed=12)
    a = P.GaussNewtonProjector(panda, built_in).solve_batch(starts)
    b = P.GaussNewtonProjector(panda, custom).solve_batch(starts)
    np.testing.assert_array_equal(a.success, b.success)
    np.testing.assert_array_equal(a.iterations, b.iterations)
    np.testing.assert_allclose(a.q, b.q, atol=1e-9)
    assert a.success.sum() >= 6
    # the weighted residuals the GAN's costs use (genplan.samplers.costs) agree too
    native_a = P.GaussNewtonProjector(panda, built_in).native
    native_b = P.GaussNewtonProjector(panda, custom).native
    assert native_a is not None and native_b is not None
    ra, ja = native_a.primary_residuals(starts)
    rb, jb = native_b.primary_residuals(starts)
    np.testing.assert_allclose(ra, rb, atol=1e-9)
    np.testing.assert_allclose(ja, jb, atol=1e-9)


@pytest.mark.parametrize("parallel", [True, False])
def test_solve_batch_with_a_custom_term(panda: genplan.Robot, parallel: bool) -> None:
    task = _upright_task(panda)
    starts = _starts(panda, 12, seed=21)
    res = P.GaussNewtonProjector(panda, task).solve_batch(starts, parallel=parallel)
    oracle = P.GaussNewtonProjector(panda, task, backend="pinocchio").solve_batch(starts)
    np.testing.assert_array_equal(res.success, oracle.success)
    np.testing.assert_array_equal(res.iterations, oracle.iterations)
    np.testing.assert_allclose(res.q, oracle.q, atol=1e-6)
    np.testing.assert_allclose(res.residuals["upright"], oracle.residuals["upright"], atol=1e-6)
    assert res.success.sum() >= 8


@pytest.mark.parametrize("backend", ["native", "pinocchio"])
@pytest.mark.parametrize("where, after", [("residual", 1), ("residual", 4), ("jacobian", 2)])
def test_an_exception_in_the_term_reaches_the_caller_unchanged(panda: genplan.Robot, backend: str, where: str, after: int) -> None:
    error = Boom(f"user code failed in {where}")
    term = Faulty(robot=panda, name="upright", weight=10.0, tolerance=1e-6, where=where, after=after, error=error)
    solver = P.GaussNewtonProjector(panda, _upright_task(panda, term), backend=backend)
    q0 = _starts(panda, 1, seed=31)[0]
    with pytest.raises(Boom) as info:
        solver.solve(q0)
    assert info.value is error
    for parallel in (True, False):
        term.calls.clear()
        with pytest.raises(Boom) as info:
            solver.solve_batch(_starts(panda, 6, seed=32), parallel=parallel)
        assert info.value is error


def test_an_exception_in_the_term_reaches_the_costs_unchanged(panda: genplan.Robot) -> None:
    error = Boom("in the costs")
    term = Faulty(robot=panda, name="upright", where="jacobian", after=1, error=error)
    native = P.GaussNewtonProjector(panda, _upright_task(panda, term)).native
    assert native is not None
    r, _ = native.primary_residuals(_starts(panda, 3, seed=33), False)  # no Jacobian asked: fine
    assert r.shape == (3, 2 + 7)
    with pytest.raises(Boom) as info:
        native.primary_residuals(_starts(panda, 3, seed=33), True)
    assert info.value is error


BAD_OUTPUTS = [
    ("residual", lambda r: r[0], ShapeError, r"term 'upright': residual\(q\) must return an array of shape \(1, 2\).*got shape \(2,\)"),
    ("residual", lambda r: np.zeros((1, 3)), ShapeError, r"term 'upright': residual\(q\) .*got shape \(1, 3\)"),
    ("residual", lambda r: "not numbers", ShapeError, r"term 'upright': residual\(q\) must return an array"),
    ("jacobian", lambda j: j[:, :, :6], ShapeError, r"term 'upright': jacobian\(q\) must return an array of shape \(1, 2, 7\)"),
    ("residual", lambda r: np.full_like(r, np.nan), NonFiniteError, r"term 'upright' residual: element 0 is not finite"),
    ("jacobian", lambda j: np.where(np.arange(j.size).reshape(j.shape) == 3, np.inf, j), NonFiniteError,
     r"term 'upright' Jacobian \(row-major\): element 3 is not finite"),
]


@pytest.mark.parametrize("backend", ["native", "pinocchio"])
@pytest.mark.parametrize("where, output, error, match", BAD_OUTPUTS)
def test_bad_outputs_raise_typed_errors_naming_the_term(panda: genplan.Robot, backend: str, where: str, output: Any,
                                                        error: type[Exception], match: str) -> None:
    term = Faulty(robot=panda, name="upright", weight=10.0, tolerance=1e-6, where=where, after=1, output=output)
    solver = P.GaussNewtonProjector(panda, _upright_task(panda, term), backend=backend)
    with pytest.raises(error, match=match):
        solver.solve(_starts(panda, 1, seed=41)[0])
    term.calls.clear()
    with pytest.raises(error, match=match):
        solver.solve_batch(_starts(panda, 4, seed=42))


def test_a_term_without_a_valid_dim_is_refused(panda: genplan.Robot) -> None:
    @dataclass(frozen=True)
    class NoDim(P.CustomTerm):
        pass

    @dataclass(frozen=True)
    class ZeroDim(ToolUpright):
        dim = 0

    for cls, match in [(NoDim, "set dim"), (ZeroDim, "dim must be a positive int, got 0")]:
        for backend in ("native", "pinocchio"):
            with pytest.raises((GenplanError, NotImplementedError), match=match):
                P.GaussNewtonProjector(panda, _upright_task(panda, cls(name="upright")), backend=backend)


def test_a_plain_object_with_the_batch_methods_is_a_native_term(panda: genplan.Robot) -> None:
    """The native adapter's contract, without the base class: dim, residual(q), jacobian(q)."""
    upright = ToolUpright(robot=panda)

    class Plain:
        dim = 2

        def residual(self, q: np.ndarray) -> np.ndarray:
            return upright.residual(q)

        def jacobian(self, q: np.ndarray) -> np.ndarray:
            return upright.jacobian(q)

    terms = [{"type": "custom", "name": "plain", "weight": 10.0, "tolerance": 1e-6, "term": Plain()},
             P.JointLimits(weight=10.0, tolerance=1e-6).to_native(panda)]
    native = genplan._core.Projector(panda.kinematics, terms, [P.Posture().to_native(panda)])
    reference = P.GaussNewtonProjector(panda, _upright_task(panda)).native
    assert reference is not None
    starts = _starts(panda, 4, seed=51)
    (qa, ok_a, it_a, res_a, _), (qb, ok_b, it_b, res_b, _) = native.solve_batch(starts), reference.solve_batch(starts)
    np.testing.assert_array_equal(ok_a, ok_b)
    np.testing.assert_array_equal(it_a, it_b)
    np.testing.assert_allclose(qa, qb, atol=1e-12)
    np.testing.assert_allclose(res_a, res_b, atol=1e-12)
    assert ok_a.sum() >= 3
    with pytest.raises(GenplanError, match="custom term 'bad': needs an attribute dim"):
        genplan._core.Projector(panda.kinematics, [{"type": "custom", "name": "bad", "term": object()}])

    class NoJacobian:
        dim = 2

        def residual(self, q: np.ndarray) -> np.ndarray:
            return upright.residual(q)

    with pytest.raises(GenplanError, match=r"custom term 'bad': needs methods residual\(q\) and jacobian\(q\)"):
        genplan._core.Projector(panda.kinematics, [{"type": "custom", "name": "bad", "term": NoJacobian()}])


def test_a_task_with_a_custom_term_is_written_to_a_file_by_its_entry(tmp_path, panda: genplan.Robot) -> None:
    """ToolUpright is importable (tests.test_projection_custom:ToolUpright): a file records it as a
    python term, read back only with allow_python=True (tests/test_custom_terms.py)."""
    task = _upright_task(panda)
    path = task.to_file(tmp_path / "task.toml")
    assert 'entry = "tests.test_projection_custom:ToolUpright"' in path.read_text()
    with pytest.raises(TaskFileError, match="allow_python=True"):
        P.Task.from_file(path, panda)
    assert P.Task.from_file(path, panda, allow_python=True).primary[0] == task.primary[0]
    # copies made the way the planner makes them keep the term (a frozen dataclass)
    tighter = task.with_tolerances_scaled(0.1)
    assert isinstance(tighter.primary[0], ToolUpright) and tighter.primary[0].tolerance == pytest.approx(1e-7)
    assert P.GaussNewtonProjector(panda, tighter).native is not None


def test_the_example_of_docs_tasks_runs_natively() -> None:
    """The ```python block of docs/TASKS.md's "Terms of your own", as written."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "TASKS.md").read_text()
    section = text.split("## Terms of your own", 1)[1]
    block = re.search(r"^```python\n(.*?)^```", section, re.S | re.M)
    assert block is not None
    namespace: dict[str, Any] = {"__name__": "tasks_md"}
    exec(compile(block.group(1), "docs/TASKS.md", "exec"), namespace)
    assert namespace["solver"].native is not None
    assert namespace["res"].success and len(namespace["batch"]) == 8


def test_a_plan_on_a_custom_term_and_its_exceptions(panda: genplan.Robot) -> None:
    """The planner projects with the custom term natively (rust/core/src/planning/projector.rs):
    a plan on the upright manifold succeeds and every state holds the term; an exception the
    term raises mid-plan ends the plan and reaches the caller as itself, and a bad output as a
    typed error naming the term."""
    from genplan.planning import Planner

    # the planner holds the chords between a path's states to the task's tolerance: 1e-4 here (a
    # chord 1/8 of the edge resolution long on this manifold strays by about 1e-5, so 1e-6 cannot
    # be held and every edge would be refused)
    task = _upright_task(panda, ToolUpright(robot=panda, name="upright", weight=10.0, tolerance=1e-4))
    solver = P.GaussNewtonProjector(panda, task)
    ends = solver.solve_batch(_starts(panda, 40, seed=5))
    free = ~np.asarray(panda.collision_world().in_collision(ends.q)) & ends.success
    start, goal = ends.q[free][:2]
    result = Planner(panda, task=task, seed=0).plan(start, goal[None])
    assert result.success
    z = panda.link_poses(result.path, [panda.frames["hand"]])[:, 0, :2, 2]
    assert np.abs(z).max() < 1e-4 / 10.0  # the term's tolerance over its weight
    boom = Boom("mid-plan")
    faulty = _upright_task(panda, Faulty(robot=panda, name="upright", weight=10.0, tolerance=1e-6, after=40, error=boom))
    with pytest.raises(Boom) as info:
        Planner(panda, task=faulty, seed=0).plan(start, goal[None])
    assert info.value is boom
    nan_out = _upright_task(panda, Faulty(robot=panda, name="upright", weight=10.0, tolerance=1e-6, after=40,
                                          output=lambda v: v * np.nan))
    with pytest.raises(NonFiniteError, match="term 'upright'"):
        Planner(panda, task=nan_out, seed=0).plan(start, goal[None])


def test_an_exception_in_the_term_reaches_the_residual_check_unchanged(panda: genplan.Robot) -> None:
    error = Boom("in the residual check")
    term = Faulty(robot=panda, name="upright", where="residual", after=3, error=error)
    solver = P.GaussNewtonProjector(panda, _upright_task(panda, term))
    with pytest.raises(Boom) as info:
        solver.residual_sizes(_starts(panda, 6, seed=34))
    assert info.value is error
