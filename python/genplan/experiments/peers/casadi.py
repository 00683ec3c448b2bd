"""The peer: the pancake reaching problem solved directly by CasADi + IPOPT.

Direct transcription of the same problem the latent method solves with J1 (eq. 17), with the
constraints made hard instead of penalised:

* variables: accelerations ``u[0..K-1]`` and states ``x[1..K-1]`` (``x[0]`` fixed: start pose at
  rest), ``K = 500``, ``dt = 1 ms``;
* dynamics: ``x[k+1] = A x[k] + B u[k]`` (eq. 8) as equality constraints;
* end pose: ``p[K-1] = p_end`` (equality);
* friction cone at every sample (eq. 15): with ``f = g - u[k]``, normal force
  ``N = f . [sin theta, -cos theta]`` and tangential force ``T = f . [cos theta, sin theta]``,
  ``|T| <= tan(arctan(mu_max) - margin) N`` -- smooth, and equivalent to
  ``|phi| <= arctan(mu_max) - margin`` (``margin`` = 1e-3 rad by default keeps the solution
  strictly inside the cone, as eq. 15 asks); and ``N >= n_min`` (0.1 m/s^2 by default): without
  it IPOPT ends the flips in free fall (``u = g``, a zero resultant, where phi is undefined and
  the slightest error drops the pancake);
* cost: ``dt sum_k ||D u[k]||^2`` (acceleration effort, D = diag(1, 1, 0.1)) so the problem has
  a unique, smooth solution.

``objective="j2"`` solves the paper's Section 5.2 problem (eq. 24) instead: the end inside the
ball ``y^2 + z^2 <= p_lim^2`` and the band ``|theta - theta_end| <= theta_lim`` (hard), the cone
(hard), and the cost ``beta / K sum_k ||max(0, D(|p_dot[k]| - v_lim))||^2`` (smooth: each side
of the absolute value is its own squared hinge) plus ``1e-8 x`` the effort as a regulariser.

The NLP is built once (start and end poses are parameters) and solved per problem, warm-started
from the S-curve's accelerations (the same input the seq2seq model gets).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan.pancake.trajectories import DT, G, K, MU_MAX, phi, s_curve_profile

__all__ = ["PancakeNLP", "CasadiResult", "solve_batch", "s_curve_accelerations"]


def s_curve_accelerations(p_start: ArrayLike, p_end: ArrayLike, k: int = K, dt: float = DT) -> NDArray[np.float64]:
    """The S-curve's accelerations (k, 3) (its analytic second derivative in time)."""
    _, _, d2s = s_curve_profile(k)
    T = (k - 1) * dt
    delta = np.asarray(p_end, dtype=np.float64) - np.asarray(p_start, dtype=np.float64)
    return d2s[:, None] * delta[None, :] / T**2


@dataclass
class CasadiResult:
    """Per problem (B of them): trajectories, phi, IPOPT status and wall time of each solve."""

    p: NDArray[np.float64]
    v: NDArray[np.float64]
    u: NDArray[np.float64]
    phi: NDArray[np.float64]
    success: NDArray[np.bool_]
    status: list[str]
    iterations: NDArray[np.int64]
    solve_time_s: NDArray[np.float64]
    build_time_s: float


class PancakeNLP:
    """The transcribed NLP, built once; :meth:`solve` runs IPOPT for one start/end pair."""

    def __init__(self, k: int = K, dt: float = DT, mu_max: float = MU_MAX, margin: float = 1e-3,
                 tol: float = 1e-8, max_iter: int = 1000, d: tuple[float, float, float] = (1.0, 1.0, 0.1),
                 objective: str = "reach", beta: float = 0.01, n_min: float = 0.1,
                 v_lim: tuple[float, float, float] = (1.5, 1.5, 4.5)) -> None:
        import casadi as ca

        if objective not in ("reach", "j2"):
            raise ValueError(f"objective must be 'reach' or 'j2', got {objective!r}")
        t0 = time.perf_counter()
        self.k, self.dt, self.objective = k, dt, objective
        mu = math.tan(math.atan(mu_max) - margin)
        U = ca.SX.sym("u", 3, k)
        X = ca.SX.sym("x", 6, k - 1)  # x[1..k-1]
        P = ca.SX.sym("par", 9)  # x0 (6) and p_end (3); for j2: x0, theta_end, p_lim, theta_lim
        A = np.block([[np.eye(3), dt * np.eye(3)], [np.zeros((3, 3)), np.eye(3)]])
        B = np.vstack([0.5 * dt * dt * np.eye(3), dt * np.eye(3)])
        xs = ca.horzcat(P[:6], X)  # (6, k)
        dyn = ca.vec(X - (ca.mtimes(A, xs[:, :-1]) + ca.mtimes(B, U[:, :-1])))
        th = xs[2, :]
        fy = -U[0, :]
        fz = -G - U[1, :]
        n_force = fy * ca.sin(th) - fz * ca.cos(th)
        t_force = fy * ca.cos(th) + fz * ca.sin(th)
        cone = ca.vertcat(ca.vec(t_force - mu * n_force), ca.vec(-t_force - mu * n_force), ca.vec(n_min - n_force))
        w = ca.DM(np.asarray(d) ** 2)
        effort = dt * ca.sum2(ca.mtimes(w.T, U * U))
        self.n_dyn, self.n_cone = dyn.shape[0], cone.shape[0]
        if objective == "reach":
            end = xs[:3, -1] - P[6:]
            cost = effort
            lb_end, ub_end = np.zeros(3), np.zeros(3)
        else:
            dm = ca.DM(np.asarray(d))
            vl = ca.DM(np.asarray(v_lim))
            V = xs[3:, :]
            over = ca.fmax(0, dm * (V - vl)) ** 2 + ca.fmax(0, dm * (-V - vl)) ** 2
            cost = beta / k * ca.sum1(ca.sum2(over)) + 1e-8 * effort
            # y^2 + z^2 - p_lim^2 <= 0 and theta - theta_end in [-theta_lim, theta_lim] (set per solve)
            end = ca.vertcat(xs[0, -1] ** 2 + xs[1, -1] ** 2 - P[7] ** 2, xs[2, -1] - P[6])
            lb_end = np.array([-np.inf, -np.inf])
            ub_end = np.array([0.0, np.inf])
        g = ca.vertcat(dyn, end, cone)
        self.n_end = end.shape[0]
        self.lbg = np.concatenate([np.zeros(self.n_dyn), lb_end, -np.inf * np.ones(self.n_cone)])
        self.ubg = np.concatenate([np.zeros(self.n_dyn), ub_end, np.zeros(self.n_cone)])
        nlp = {"x": ca.vertcat(ca.vec(U), ca.vec(X)), "p": P, "f": cost, "g": g}
        opts: dict[str, Any] = {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes",
                                "ipopt.tol": tol, "ipopt.max_iter": max_iter}
        self.solver = ca.nlpsol("pancake", "ipopt", nlp, opts)
        self.A, self.B = A, B
        self.build_time_s = time.perf_counter() - t0

    def _states(self, x0: NDArray[np.float64], u: NDArray[np.float64]) -> NDArray[np.float64]:
        x = np.zeros((self.k, 6))
        x[0] = x0
        for i in range(self.k - 1):
            x[i + 1] = self.A @ x[i] + self.B @ u[i]
        return x

    def solve(self, p_start: ArrayLike, p_end: ArrayLike, u_init: ArrayLike | None = None,
              j2_limits: tuple[float, float] = (0.2, 0.5)) -> dict[str, Any]:
        """Solve one problem; returns p, v, u (k, 3), success, status, iterations, time_s.

        ``p_end``: the end pose (reach), or for j2 the pose whose attitude is ``theta_end``;
        ``j2_limits``: ``(p_lim, theta_lim)`` of J2. ``u_init``: default the S-curve's
        accelerations from ``p_start`` to ``p_end``.
        """
        ps = np.asarray(p_start, dtype=np.float64)
        pe = np.asarray(p_end, dtype=np.float64)
        for name, a in (("p_start", ps), ("p_end", pe)):
            if a.shape != (3,) or not np.all(np.isfinite(a)):
                raise ValueError(f"{name} must be a finite pose of shape (3,), got {a.tolist()}")
        x0 = np.concatenate([ps, np.zeros(3)])
        par = np.concatenate([x0, pe]) if self.objective == "reach" else \
            np.concatenate([x0, [pe[2], j2_limits[0], j2_limits[1]]])
        if self.objective == "j2":
            self.lbg[self.n_dyn + 1] = -j2_limits[1]
            self.ubg[self.n_dyn + 1] = j2_limits[1]
        u0 = s_curve_accelerations(ps, pe, self.k, self.dt) if u_init is None else np.asarray(u_init, float)
        if u0.shape != (self.k, 3):
            raise ValueError(f"u_init must have shape ({self.k}, 3), got {u0.shape}")
        xg = self._states(x0, u0)
        w0 = np.concatenate([u0.reshape(-1), xg[1:].reshape(-1)])  # column-major vec of (3,k) = row-major (k,3)
        t0 = time.perf_counter()
        sol = self.solver(x0=w0, p=par, lbg=self.lbg, ubg=self.ubg)
        dt_s = time.perf_counter() - t0
        st = self.solver.stats()
        w = np.asarray(sol["x"]).ravel()
        u = w[: 3 * self.k].reshape(self.k, 3)
        x = self._states(x0, u)  # states re-simulated from u (the reported trajectory is exact)
        return {"p": x[:, :3], "v": x[:, 3:], "u": u, "success": bool(st["success"]),
                "status": str(st["return_status"]), "iterations": int(st["iter_count"]), "time_s": dt_s}


def solve_batch(p_start: ArrayLike, p_end: ArrayLike, progress: bool = False,
                u_init: ArrayLike | None = None, **nlp_kwargs: Any) -> CasadiResult:
    """Solve B problems one after the other: ``p_start``, ``p_end`` of shape (3,) or (B, 3).

    ``u_init``: (B, K, 3) initial accelerations (default: each problem's S-curve). Keywords go
    to :class:`PancakeNLP` (e.g. ``objective="j2"``).
    """
    pe = np.atleast_2d(np.asarray(p_end, dtype=np.float64))
    ps = np.broadcast_to(np.asarray(p_start, dtype=np.float64), pe.shape)
    if pe.ndim != 2 or pe.shape[1] != 3:
        raise ValueError(f"p_end must have shape (3,) or (B, 3), got {np.shape(p_end)}")
    nlp = PancakeNLP(**nlp_kwargs)
    out: list[dict[str, Any]] = []
    it = range(len(pe))
    if progress:
        from tqdm import tqdm

        it = tqdm(it, desc="casadi + ipopt", unit="problem")
    ui = None if u_init is None else np.asarray(u_init, dtype=np.float64)
    for i in it:
        out.append(nlp.solve(ps[i], pe[i], None if ui is None else ui[i]))
    p = np.stack([o["p"] for o in out])
    u = np.stack([o["u"] for o in out])
    return CasadiResult(
        p=p, v=np.stack([o["v"] for o in out]), u=u, phi=phi(p[..., 2], u),
        success=np.array([o["success"] for o in out]), status=[o["status"] for o in out],
        iterations=np.array([o["iterations"] for o in out]), solve_time_s=np.array([o["time_s"] for o in out]),
        build_time_s=nlp.build_time_s,
    )
