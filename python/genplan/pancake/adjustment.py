"""Latent-space trajectory adjustment (the paper's Section 3) and its two comparisons.

:func:`adjust` minimises an objective ``J(X_out, U_out)`` of the model's output by gradient
descent on

* ``"latent"`` -- the latent vector z, starting from the encoder's z of the input (case 1, the
  paper's method);
* ``"random-latent"`` -- z, starting from ``z ~ N(0, I)`` (case 2; the mirror sign of a
  mirror-canonical model still comes from the input's sense of rotation);
* ``"direct-u"`` -- the accelerations U_out themselves, starting from the decoder's output for
  the input (case 3).

Many problems run in one call (a batch): each problem has its own objective value and its own
variables; the summed objective's gradient is the per-problem gradient.

Step rules:

* ``"gd"`` is eq. 7, ``v <- v - eta dJ/dv``, with the paper's learning rates as defaults
  (eta = 200, 200, 1000 for J1 in cases 1-3; 100 for J2);
* ``"adaptive"`` is eq. 7 inside a trust radius per problem: the step ``eta dJ/dv`` is
  shortened to at most ``radius`` (root mean square over the variable's elements; starts at
  ``max_step``, default :data:`ADAPTIVE_RADIUS`); a step that raises that problem's J is undone
  and retried with half its length, after a step that lowers J the radius grows by half. Still
  one forward and one backward pass per update, the objective never rises, and eta matters much
  less (the paper's eta is tied to its model's latent scale; on genplan's model eq. 7 with it
  diverges -- see the benchmark JSON for both rules);
* ``"adam"`` (elementwise Adam, so per problem).

Objectives: :class:`J1` (eq. 17), :class:`J2` (eq. 24), or any callable taking a
:class:`~genplan.pancake.physics.Rollout` (batched torch tensors) and returning one
differentiable value per problem, shape (B,) (a 0-d tensor is accepted when B = 1).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, Union

import numpy as np
import torch
from numpy.typing import ArrayLike, NDArray
from torch import Tensor

from genplan._arrays import as_count, as_float_array, as_real
from genplan._threads import uses_torch
from genplan.errors import CallbackError, NonFiniteError, SettingsError, ShapeError, UnknownNameError
from genplan.pancake import physics as ph
from genplan.pancake.model import (
    Seq2SeqModel, check_magnitude, check_trajectories, first_nonfinite, load_model, mirror, start_state,
)

Method = Literal["latent", "random-latent", "direct-u"]
METHODS: tuple[str, ...] = ("latent", "random-latent", "direct-u")
STEPS: tuple[str, ...] = ("gd", "adaptive", "adam")
Objective = Union[str, Callable[[ph.Rollout], Tensor]]

#: the paper's learning rates (eta of eq. 7): J1 cases 1-3 (Section 4.3.3) and J2 (Section 5.2)
PAPER_LR = {("j1", "latent"): 200.0, ("j1", "random-latent"): 200.0, ("j1", "direct-u"): 1000.0,
            ("j2", "latent"): 100.0, ("j2", "random-latent"): 100.0, ("j2", "direct-u"): 100.0}
#: the adaptive rule's initial trust radius (RMS of a step): latent units, m/s^2 for direct-u.
#: Measured on the 27 J1 problems with the shipped model (mean J1 after 5 / 100 updates, end
#: RMSE): 0.003 -> 1.9e-4 / 9.4e-7, 0.63 mm; 0.01 -> 2.5e-4 / 1.3e-6, 0.97 mm; 0.02 -> 2.8e-4 /
#: 2.4e-7, 0.21 mm; 0.05 -> 3.7e-4 / 1.4e-5, 2.8 mm (larger first steps cross into the cone more
#: often and each crossing halves the radius)
ADAPTIVE_RADIUS = {"latent": 0.02, "random-latent": 0.02, "direct-u": 0.5}
#: most updates per call (the history keeps one objective per problem and update)
MAX_UPDATES = 1_000_000
#: defaults for the Adam step rule (chosen by the measurements in benches/results/adjust_*adam*.json)
ADAM_LR = {"latent": 0.02, "random-latent": 0.02, "direct-u": 2.0}

__all__ = ["adjust", "AdjustResult", "J1", "J2", "J2Executable", "normal_acceleration", "METHODS", "STEPS", "PAPER_LR", "ADAM_LR", "ADAPTIVE_RADIUS",
           "MAX_UPDATES", "default_lr"]


def _as_tensor(a: ArrayLike, b: int, name: str, dim: int = 3) -> Tensor:
    arr = as_float_array(a, name)
    if arr.shape == (dim,):
        arr = np.broadcast_to(arr, (b, dim))
    if arr.shape != (b, dim):
        raise ShapeError(f"{name} must have shape ({dim},) or ({b}, {dim}) for {b} problem(s), got {np.shape(a)}")
    if not np.all(np.isfinite(arr)):
        raise NonFiniteError(f"{name} contains NaN or inf")
    check_magnitude(arr, name)
    return torch.tensor(arr, dtype=torch.float32)


class J1:
    """eq. 17: ``||D (p[K-1] - p_end)||^2 + alpha f_dyn``, one value per problem.

    ``p_end``: (3,) or (B, 3) end poses. ``margin`` (radians, default 0 = the paper) tightens
    the cone inside f_dyn only.
    """

    name = "j1"

    def __init__(self, p_end: ArrayLike, alpha: float = 1.0, mu_max: float = ph.MU_MAX,
                 d: Sequence[float] = ph.D_SCALE, margin: float = 0.0) -> None:
        self.p_end_raw = as_float_array(p_end, "p_end")
        self.alpha, self.mu_max = as_real(alpha, "alpha"), as_real(mu_max, "mu_max")
        self.margin = as_real(margin, "margin")
        self.d = torch.tensor(_vector(d, 3, "d"), dtype=torch.float32)
        self._p_end: Tensor | None = None

    def bind(self, batch: int) -> None:
        self._p_end = _as_tensor(self.p_end_raw, batch, "p_end")

    def __call__(self, r: ph.Rollout) -> Tensor:
        if self._p_end is None or self._p_end.shape[0] != r.batch:
            self.bind(r.batch)
        assert self._p_end is not None
        err = (r.p[:, -1, :] - self._p_end) * self.d
        return (err ** 2).sum(-1) + self.alpha * ph.f_dyn(r.phi, self.mu_max, self.margin)


class J2:
    """eq. 24: end inside a ball and an attitude band, friction cone, velocity limits.

    ``max(sqrt(y^2 + z^2) - p_lim, 0) + 0.1 max(|theta - theta_end| - theta_lim, 0)
    + alpha f_dyn + beta / K sum_k ||max(0, D (|p_dot[k]| - v_lim))||^2`` at the last sample;
    the distance is measured from ``center`` (the paper: the origin, where its moves start).
    Defaults are the paper's Section 5.2 values. :class:`J2Executable` adds execution margins.
    """

    name = "j2"

    def __init__(self, theta_end: float = -0.75 * math.pi, p_lim: float = 0.2, theta_lim: float = 0.5,
                 alpha: float = 1.0, beta: float = 0.01, v_lim: Sequence[float] = (1.5, 1.5, 4.5),
                 mu_max: float = ph.MU_MAX, d: Sequence[float] = ph.D_SCALE,
                 center: Sequence[float] = (0.0, 0.0)) -> None:
        scalars = dict(theta_end=theta_end, p_lim=p_lim, theta_lim=theta_lim, alpha=alpha, beta=beta, mu_max=mu_max)
        theta_end, p_lim, theta_lim, alpha, beta, mu_max = (as_real(v, f"J2 {k}") for k, v in scalars.items())
        vectors = [as_float_array(v, f"J2 {k}") for k, v in (("v_lim", v_lim), ("d", d), ("center", center))]
        if [v.shape for v in vectors] != [(3,), (3,), (2,)]:
            raise ShapeError("J2: v_lim and d need 3 values, center 2")
        v_lim, d, center = (tuple(float(x) for x in v) for v in vectors)
        vals = [theta_end, p_lim, theta_lim, alpha, beta, mu_max, *v_lim, *d, *center]
        if not all(math.isfinite(v) for v in vals):
            raise NonFiniteError("J2 parameters must be finite")
        # poses, limits and centre in m or rad (the weights may be large; an infinite objective is an error)
        check_magnitude(np.array([theta_end, p_lim, theta_lim, *v_lim, *center], dtype=np.float64), "J2 parameters")
        self.theta_end, self.p_lim, self.theta_lim = float(theta_end), float(p_lim), float(theta_lim)
        self.alpha, self.beta, self.mu_max = float(alpha), float(beta), float(mu_max)
        self.v_lim = torch.tensor(tuple(v_lim), dtype=torch.float32)
        self.d = torch.tensor(tuple(d), dtype=torch.float32)
        self.center = torch.tensor(tuple(center), dtype=torch.float32)

    def bind(self, batch: int) -> None:
        pass

    def terms(self, r: ph.Rollout) -> dict[str, Tensor]:
        """eq. 24's terms, unweighted, one value per problem: ``position`` (m beyond p_lim),
        ``attitude`` (rad beyond theta_lim), ``cone`` (f_dyn), ``velocity`` (mean squared
        excess over v_lim, scaled by D)."""
        end = r.p[:, -1, :]
        dist = torch.sqrt(((end[:, :2] - self.center) ** 2).sum(-1) + 1e-12)
        return {
            "position": torch.relu(dist - self.p_lim),
            "attitude": torch.relu((end[:, 2] - self.theta_end).abs() - self.theta_lim),
            "cone": ph.f_dyn(r.phi, self.mu_max),
            "velocity": (torch.relu(self.d * (r.v.abs() - self.v_lim)) ** 2).sum(-1).mean(-1),
        }

    def combine(self, t: dict[str, Tensor]) -> Tensor:
        """The objective from :meth:`terms`."""
        return t["position"] + 0.1 * t["attitude"] + self.alpha * t["cone"] + self.beta * t["velocity"]

    def __call__(self, r: ph.Rollout) -> Tensor:
        return self.combine(self.terms(r))


def normal_acceleration(r: ph.Rollout, g: float = ph.G) -> Tensor:
    """``N = -a_y sin(theta) + (g + a_z) cos(theta)`` (B, K): the spatula-normal component of
    the acceleration the spatula must give the pancake (m/s^2); ``N <= 0``: it lifts off."""
    theta = r.p[..., 2]
    return -r.u[..., 0] * torch.sin(theta) + (g + r.u[..., 1]) * torch.cos(theta)


class J2Executable(J2):
    """eq. 24 plus execution margins: plans the 1 kHz P-D + DOB can execute without losing
    the pancake.

    The paper's J2 optimum rides the cone's edge (|phi| = 45 deg) and ends in near free fall
    (N ~ 0.1 m/s^2), so the controller's tracking lag tips the pancake off
    (``genplan bench control``). Added to eq. 24 (defaults in brackets):

    ``+ f_dyn(phi, margin)`` (10 deg: |phi| <= 35 deg)
    ``+ normal_weight / g * sum_k max(normal_floor - N[k], 0)`` (0.1; 3 m/s^2; N:
    :func:`normal_acceleration`)
    ``+ attitude_weight * max(|theta - theta_end| - (theta_lim - attitude_inset), 0)`` (3;
    0.02 rad: at J2's own weight 0.1 the floor pulls the end attitude out of the band)
    ``+ velocity_weight * velocity term`` (10: at J2's beta 0.01 a 2x overshoot of the attitude
    rate costs as much as 0.3 mm of end position).

    Reach it with Adam (500 updates in ``genplan bench control``). The weights come from an
    exploratory sweep (floor 2-3 m/s^2, attitude weight 1-10, velocity weight 1-30, margin 8-10
    deg): most settings kept the pancake; these also keep the velocity excess small and the end
    inside J2's ranges.
    """

    name = "j2-exec"

    def __init__(self, *args: Any, margin: float = math.radians(10.0), normal_floor: float = 3.0,
                 normal_weight: float = 0.1, attitude_weight: float = 3.0, attitude_inset: float = 0.02,
                 velocity_weight: float = 10.0, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        names = ["margin", "normal_floor", "normal_weight", "attitude_weight", "attitude_inset", "velocity_weight"]
        extra = [as_real(v, f"J2Executable {k}", error=SettingsError) for k, v in zip(names, [
            margin, normal_floor, normal_weight, attitude_weight, attitude_inset, velocity_weight])]
        margin, normal_floor, normal_weight, attitude_weight, attitude_inset, velocity_weight = extra
        if not all(math.isfinite(v) and v >= 0 for v in extra):
            raise SettingsError(f"J2Executable: margins and weights must be finite and >= 0, got {extra}")
        if margin >= math.atan(self.mu_max) or attitude_inset >= self.theta_lim:
            raise SettingsError("J2Executable: margin must be below the cone's half-angle and attitude_inset below "
                                "theta_lim")
        self.margin, self.normal_floor, self.normal_weight = float(margin), float(normal_floor), float(normal_weight)
        self.attitude_weight, self.attitude_inset = float(attitude_weight), float(attitude_inset)
        self.velocity_weight = float(velocity_weight)

    def terms(self, r: ph.Rollout) -> dict[str, Tensor]:
        """eq. 24's terms plus ``cone_margin``, ``normal`` (sum of m/s^2 below the floor) and
        ``attitude_inset`` (rad beyond the inset band)."""
        t = super().terms(r)
        end_theta = r.p[:, -1, 2]
        t["cone_margin"] = ph.f_dyn(r.phi, self.mu_max, self.margin)
        t["normal"] = torch.relu(self.normal_floor - normal_acceleration(r)).sum(-1)
        t["attitude_inset"] = torch.relu((end_theta - self.theta_end).abs() - (self.theta_lim - self.attitude_inset))
        return t

    def combine(self, t: dict[str, Tensor]) -> Tensor:
        """eq. 24 (:meth:`J2.combine`) plus the margins' terms."""
        return (super().combine(t) + t["cone_margin"] + self.normal_weight / ph.G * t["normal"]
                + self.attitude_weight * t["attitude_inset"] + self.velocity_weight * t["velocity"])


@dataclass
class AdjustResult:
    """What :func:`adjust` returns (numpy, float64; B problems, K samples).

    ``objective_history[i]`` holds the objective of every problem after ``i`` updates (row 0:
    before any update), shape (updates + 1, B). ``snapshots`` maps an update index to the
    trajectory (``p``, ``v``, ``u``, ``phi``) at that point. Timing: ``update_times_s`` holds the
    wall time of each update of the whole batch (forward, backward, step), ``time_updates_s``
    their sum, ``ms_per_update`` their median over B; ``time_init_s`` is the encoder (or
    decoder) pass that gives the start point.
    """

    p: NDArray[np.float64]
    v: NDArray[np.float64]
    u: NDArray[np.float64]
    phi: NDArray[np.float64]
    objective_history: NDArray[np.float64]
    z: NDArray[np.float64] | None
    method: str
    step: str
    lr: float
    updates: int
    time_init_s: float
    time_updates_s: float
    time_total_s: float
    update_times_s: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    snapshots: dict[int, dict[str, NDArray[np.float64]]] = field(default_factory=dict)

    @property
    def batch(self) -> int:
        return int(self.p.shape[0])

    @property
    def ms_per_update(self) -> float:
        """Median wall time of one update (forward, backward, step) of the batch, over B (ms);
        NaN without updates or problems."""
        if len(self.update_times_s) == 0 or self.batch == 0:
            return float("nan")
        return 1e3 * float(np.median(self.update_times_s)) / self.batch

    @property
    def max_abs_phi(self) -> NDArray[np.float64]:
        """Per problem, the largest |phi| over the trajectory (radians)."""
        return np.abs(self.phi).max(-1)

    def inside_cone(self, mu_max: float = ph.MU_MAX) -> NDArray[np.bool_]:
        """Per problem: is every step strictly inside the friction cone (eq. 15)?"""
        return self.max_abs_phi < math.atan(mu_max)

    def first_update_below(self, level: float) -> NDArray[np.int64]:
        """Per problem, the first update index whose objective is below ``level`` (-1: never)."""
        below = self.objective_history < level
        return np.where(below.any(0), below.argmax(0), -1)


def default_lr(objective: str, method: str, step: str = "gd") -> float:
    """The paper's eta for ``gd`` (J1 / J2 and the case); :data:`ADAM_LR` for ``adam``."""
    if step == "adam":
        return ADAM_LR[method]
    return PAPER_LR.get((objective, method), PAPER_LR[("j1", method)])


def _vector(v: Any, n: int, what: str) -> tuple[float, ...]:
    """``v`` as ``n`` real numbers, else ShapeError naming ``what``."""
    a = as_float_array(v, what)
    if a.shape != (n,):
        raise ShapeError(f"{what} must have {n} values, got shape {a.shape}")
    return tuple(float(x) for x in a)


def _check_value(j: Any, b: int) -> Tensor:
    if not isinstance(j, Tensor):
        raise TypeError(f"the objective must return a torch.Tensor, got {type(j).__name__}")
    if j.ndim == 0 and b == 1:
        j = j.reshape(1)
    if j.shape != (b,):
        raise CallbackError(f"the objective must return one value per problem, shape ({b},), got shape "
                            f"{tuple(j.shape)}" + (" (a scalar: for a batch return the per-problem values, "
                                                   "not their sum)" if j.ndim == 0 else ""))
    if not j.requires_grad:
        raise CallbackError("the objective does not depend on the trajectory (its value has no gradient); "
                            "build it from the Rollout's tensors with torch operations")
    return j


def _empty_result(model: Seq2SeqModel, method: str, step: str, lr: float, updates: int, keep: set[int]) -> AdjustResult:
    """What :func:`adjust` returns for an empty batch (torch's LSTMs do not take one)."""
    k = model.config.K
    arrays = {"p": np.zeros((0, k, 3)), "v": np.zeros((0, k, 3)), "u": np.zeros((0, k, 3)), "phi": np.zeros((0, k))}
    return AdjustResult(**arrays, objective_history=np.zeros((updates + 1, 0)),
                        z=None if method == "direct-u" else np.zeros((0, model.config.latent_dim)), method=method,
                        step=step, lr=lr, updates=updates, time_init_s=0.0, time_updates_s=0.0, time_total_s=0.0,
                        update_times_s=np.zeros(updates),
                        snapshots={i: {key: a.copy() for key, a in arrays.items()} for i in sorted(keep)})


@uses_torch("small")
def adjust(x_in: ArrayLike, objective: Objective = "j1", method: Method = "latent", updates: int = 100,
           lr: float | None = None, *, model: Seq2SeqModel | None = None, p_end: ArrayLike | None = None,
           step: str = "adaptive", seed: int = 0, snapshots: Sequence[int] = (), progress: bool = False,
           objective_kwargs: dict[str, Any] | None = None, max_step: float | None = None,
           threads: int | None = None) -> AdjustResult:
    """Adjust the model's deformation of ``x_in`` to minimise ``objective``.

    ``x_in``: input poses (K, 3) or (B, K, 3); the output starts at ``x_in[:, 0]`` at rest.
    ``objective``: ``"j1"`` (end pose ``p_end``, default the input's last pose), ``"j2"``
    (keywords in ``objective_kwargs``), a :class:`J1` / :class:`J2`, or a callable.
    ``method``: ``"latent"``, ``"random-latent"`` or ``"direct-u"``. ``lr``: default
    :func:`default_lr`. ``step``: ``"adaptive"`` (default: eq. 7 inside a per-problem trust
    radius), ``"gd"`` (eq. 7 as written) or ``"adam"``. ``seed``: z ~ N(0, I) of
    ``"random-latent"``. ``max_step``: the adaptive rule's initial trust radius.
    ``snapshots``: update indices whose trajectories to keep. With
    ``"adaptive"`` the history, the snapshots and the result are those of the kept (best) iterate.
    ``updates``: at most :data:`MAX_UPDATES`. ``model``: default the shipped model.
    ``threads``: torch threads for the call (default: genplan's choice, one; see genplan._threads).

    Every decoded trajectory is finite, or FloatingPointError names the problem and the update
    (as for an objective that becomes NaN or inf). An empty batch (0, K, 3) gives an empty result
    (B = 0) once the arguments are checked.
    """
    if method not in METHODS:
        raise UnknownNameError(f"method must be one of {METHODS}, got {method!r}")
    if step not in STEPS:
        raise UnknownNameError(f"step must be one of {STEPS}, got {step!r}")
    if isinstance(updates, bool) or not isinstance(updates, (int, np.integer)) or updates < 0:
        raise SettingsError(f"updates must be a non-negative integer, got {updates!r}")
    updates = as_count(updates, "updates", maximum=MAX_UPDATES)
    model = load_model() if model is None else model
    x = check_trajectories(x_in, model.config.K)
    b = x.shape[0]
    kw = dict(objective_kwargs or {})
    if isinstance(objective, str):
        name = objective.lower()
        if name == "j1":
            obj: Callable[[ph.Rollout], Tensor] = J1(x[:, -1, :] if p_end is None else p_end, **kw)
        elif name == "j2":
            obj = J2(**kw)
        else:
            raise UnknownNameError(f"objective must be 'j1', 'j2' or a callable, got {objective!r}")
    elif callable(objective):
        if kw:
            raise SettingsError("objective_kwargs only apply to the built-in objectives 'j1' and 'j2'")
        name = getattr(objective, "name", "custom")
        obj = objective
    else:
        raise TypeError(f"objective must be 'j1', 'j2' or a callable, got {type(objective).__name__}")
    if hasattr(obj, "bind"):
        obj.bind(b)  # validates p_end's shape before any work
    if lr is None:
        lr = default_lr(name if name in ("j1", "j2") else "j1", method, step)
    if not (isinstance(lr, (int, float)) and math.isfinite(lr) and lr > 0):
        raise SettingsError(f"lr must be a positive finite number, got {lr!r}")
    if max_step is not None:
        max_step = as_real(max_step, "max_step", error=SettingsError)
        if not (math.isfinite(max_step) and max_step > 0):
            raise SettingsError(f"max_step must be a positive finite number, got {max_step!r}")
    seed = as_count(seed, "seed", maximum=2**64 - 1)
    keep = {as_count(s, "snapshots") for s in snapshots}
    if any(s > updates for s in keep):  # as_count refused negatives
        raise SettingsError(f"snapshots must lie in [0, {updates}], got {sorted(keep)}")
    if b == 0:
        return _empty_result(model, method, step, float(lr), updates, keep)

    t_start = time.perf_counter()
    xt = torch.as_tensor(x, dtype=torch.float32)
    x0 = start_state(xt)
    sign = model.chirality(xt)  # the mirror sign of each problem (fixed while adjusting)
    with torch.no_grad():
        if method == "random-latent":
            gen = torch.Generator().manual_seed(int(seed))
            var = torch.randn(b, model.config.latent_dim, generator=gen)
        else:
            var = model.encode(xt, sign)
            if method == "direct-u":
                var = mirror(model.net.decode(var)[0], sign)
    var = var.clone().requires_grad_(True)
    t_init = time.perf_counter() - t_start

    def forward(v: Tensor) -> ph.Rollout:
        if method == "direct-u":
            return ph.simulate(v, x0, dt=model.config.dt)
        return model.decode(v, x0, sign)

    opt = torch.optim.Adam([var], lr=float(lr)) if step == "adam" else None
    adaptive = step == "adaptive"
    shape1 = (b,) + (1,) * (var.ndim - 1)
    n_el = var[0].numel()
    radius = torch.full(shape1, float(ADAPTIVE_RADIUS[method] if max_step is None else max_step), dtype=var.dtype)
    used = torch.zeros(shape1, dtype=var.dtype)
    acc_var = var.detach().clone()
    acc_j = torch.full((b,), math.inf, dtype=var.dtype)
    acc_grad = torch.zeros_like(acc_var)
    keys = ("p", "v", "u", "phi")
    acc_r: dict[str, Tensor] = {}
    hist = np.empty((updates + 1, b))
    snaps: dict[int, dict[str, NDArray[np.float64]]] = {}
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=updates, desc=f"adjust ({method}, {name})", unit="update")
    times = np.zeros(updates)
    for i in range(updates + 1):
        t0 = time.perf_counter()
        with torch.enable_grad():
            r = forward(var)
            j = _check_value(obj(r), b)
        jd = j.detach()
        bad_r = first_nonfinite(r)
        bad_j = None if bool(torch.isfinite(jd).all()) else int((~torch.isfinite(jd)).nonzero()[0, 0])
        if bad_r is not None or bad_j is not None:
            what = (f"the decoded trajectory of problem {bad_r}" if bad_r is not None
                    else f"the objective of problem {bad_j}")
            hint = (f"method {method}, step {step}, lr {lr}; lower lr" if i > 0
                    else "the model cannot decode this input" if bad_r is not None
                    else "check the objective and its parameters")
            raise FloatingPointError(f"{what} became NaN or inf after {i} update(s) ({hint})")
        need_grad = i < updates
        if need_grad:
            (grad,) = torch.autograd.grad(j.sum(), var, allow_unused=True)
            if grad is None:
                raise CallbackError("the objective has no gradient with respect to the trajectory")
        if adaptive:
            # eq. 7 inside a trust radius per problem: a step that raises J is undone and retried
            # with half its length; after a step that lowers J the radius grows by half
            ok = jd <= acc_j
            okx = ok.reshape(shape1)
            with torch.no_grad():
                acc_var = torch.where(okx, var.detach(), acc_var)
                acc_j = torch.where(ok, jd, acc_j)
                if need_grad:
                    acc_grad = torch.where(okx, grad, acc_grad)
                if i > 0:
                    radius = torch.where(okx, radius * 1.5, 0.5 * torch.minimum(radius, used))
                for k in keys:
                    new = getattr(r, k).detach()
                    acc_r[k] = new if i == 0 else torch.where(ok.reshape((b,) + (1,) * (new.ndim - 1)), new, acc_r[k])
            hist[i] = acc_j.double().numpy()
            if i in keep:
                snaps[i] = {k: acc_r[k].double().numpy() for k in keys}
        else:
            hist[i] = jd.double().numpy()
            if i in keep:
                snaps[i] = {k: getattr(r, k).detach().double().numpy() for k in keys}
        if not need_grad:
            break
        with torch.no_grad():
            if adaptive:
                d = float(lr) * acc_grad
                rms = d.reshape(b, -1).norm(dim=1).reshape(shape1) / math.sqrt(n_el)
                scale = torch.clamp(radius / torch.clamp(rms, min=1e-30), max=1.0)
                used = rms * scale
                var = (acc_var - scale * d).requires_grad_(True)
            elif opt is None:
                var -= float(lr) * grad
            else:
                var.grad = grad
                opt.step()
        times[i] = time.perf_counter() - t0
        if bar is not None:
            bar.update(1)
            bar.set_postfix(J=f"{float(hist[i].mean()):.3g}")
    if bar is not None:
        bar.close()
    if adaptive:
        final = acc_r
        var_out = acc_var
    else:
        final = {k: getattr(r, k).detach() for k in keys}
        var_out = var.detach()
    t_total = time.perf_counter() - t_start
    return AdjustResult(
        p=final["p"].double().numpy(), v=final["v"].double().numpy(), u=final["u"].double().numpy(),
        phi=final["phi"].double().numpy(), objective_history=hist,
        z=None if method == "direct-u" else var_out.double().numpy(), method=method, step=step,
        lr=float(lr), updates=updates, time_init_s=t_init, time_updates_s=float(times.sum()),
        time_total_s=t_total, update_times_s=times, snapshots=snaps,
    )
