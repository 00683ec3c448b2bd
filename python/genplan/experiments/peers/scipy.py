"""The scipy peer of Table I (``genplan bench projection --solver scipy``): ``least_squares`` on the
same tasks as genplan's Gauss-Newton projector."""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from scipy.optimize import least_squares

import genplan
from genplan import projection as P


def scipy_solve(robot: genplan.Robot, task: P.Task, q0: NDArray[np.float64]) -> tuple[bool, float, int]:
    """What users write today: scipy.optimize.least_squares (trust-region reflective) on the
    same weighted primary residuals and analytic Jacobians, joint limits as box bounds,
    optimising a tangent displacement x from q0 (q = q0 (+) x)."""
    t0 = time.perf_counter()
    model = robot.model
    bound = [t.bind(robot) for t in task.primary]
    weights = [float(t.weight) for t in task.primary]
    tols = [float(t.tolerance) for t in task.primary]
    q0 = np.clip(q0, robot.lower, robot.upper)
    lb = np.full(robot.nv, -np.inf)
    ub = np.full(robot.nv, np.inf)
    for jid in range(1, model.njoints):
        j = model.joints[jid]
        if j.nq == 1 and np.isfinite(robot.lower[j.idx_q]):
            lb[j.idx_v] = robot.lower[j.idx_q] - q0[j.idx_q]
            ub[j.idx_v] = robot.upper[j.idx_q] - q0[j.idx_q]

    def fun(x: NDArray[np.float64]) -> NDArray[np.float64]:
        s = P._State(robot, pin.integrate(model, q0, x), False)
        return np.concatenate([w * b.residual(s) for w, b in zip(weights, bound)])

    def jac(x: NDArray[np.float64]) -> NDArray[np.float64]:
        s = P._State(robot, pin.integrate(model, q0, x), True)
        j = np.vstack([w * b.jacobian(s) for w, b in zip(weights, bound)])
        return j @ pin.dIntegrate(model, q0, x, pin.ARG1)

    res = least_squares(fun, np.zeros(robot.nv), jac=jac, bounds=(lb, ub), method="trf",
                        xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=200)
    s = P._State(robot, pin.integrate(model, q0, res.x), False)
    ok = all(float(np.abs(b.residual(s)).max(initial=0.0)) < tol for b, tol in zip(bound, tols))
    return ok, time.perf_counter() - t0, int(res.nfev)
