"""The pancake task's objectives (the seq2seq paper's J1, eq. 17, and J2, eq. 24) as objectives of
the generic method (:mod:`genplan.seq2seq.objectives`), and the spatula plant's own terms:

* ``friction_cone``: f_dyn (eq. 18), ``sum_k max(|phi[k]| - arctan(mu_max) + margin, 0)``;
* ``normal_floor``: ``sum_k max(floor - N[k], 0)`` (m/s^2), ``N`` the spatula-normal acceleration
  the spatula gives the pancake (:func:`normal_acceleration`; ``N <= 0``: it lifts off).

Both are kinds objective files can name. :class:`J1`, :class:`J2` and :class:`J2Executable` keep
the paper's parameters and names; each is an :class:`~genplan.seq2seq.objectives.Objective` of
those terms and the generic ones (``end_state``, ``end_ball``, ``end_band``, ``velocity_limits``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from numpy.typing import ArrayLike
from torch import Tensor

from genplan._arrays import as_float_array, as_real
from genplan.errors import NonFiniteError, SettingsError, ShapeError
from genplan.pancake import physics as ph
from genplan.pancake.config import D_SCALE
from genplan.seq2seq.model import check_magnitude
from genplan.seq2seq.objectives import (Context, EndBall, EndBand, EndState, Objective, Term, VelocityLimits,
                                        register)
from genplan.seq2seq.plants import Rollout

__all__ = ["FrictionCone", "NormalFloor", "J1", "J2", "J2Executable", "normal_acceleration", "AXES"]

#: the spatula's axes (the pancake model's space)
AXES = ("y", "z", "theta")


def _spatula(term: Term, r: Rollout) -> Tensor:
    phi = getattr(r, "phi", None)
    if phi is None:
        raise SettingsError(f"objective term {term.name!r} ({term.kind}) needs the spatula plant's phi: it applies to "
                            "models whose plant is 'spatula'")
    return phi


@register
class FrictionCone(Term):
    """f_dyn (eq. 18): ``sum_k max(|phi[k]| - arctan(mu_max) + margin, 0)`` (radians)."""

    kind = "friction_cone"

    def __init__(self, weight: float = 1.0, name: str | None = None, *, mu_max: float = ph.MU_MAX,
                 margin: float = 0.0) -> None:
        super().__init__(weight, name)
        self.mu_max = as_real(mu_max, f"{self.name}.mu_max", error=SettingsError)
        self.margin = as_real(margin, f"{self.name}.margin", error=SettingsError)

    def __call__(self, r: Rollout) -> Tensor:
        return ph.f_dyn(_spatula(self, r), self.mu_max, self.margin)

    def params(self) -> dict[str, Any]:
        return {"mu_max": self.mu_max, "margin": self.margin}


def normal_acceleration(r: Rollout, g: float = ph.G) -> Tensor:
    """``N = -a_y sin(theta) + (g + a_z) cos(theta)`` (B, K): the spatula-normal component of
    the acceleration the spatula must give the pancake (m/s^2); ``N <= 0``: it lifts off."""
    theta = r.p[..., 2]
    return -r.u[..., 0] * torch.sin(theta) + (g + r.u[..., 1]) * torch.cos(theta)


@register
class NormalFloor(Term):
    """``sum_k max(floor - N[k], 0)`` (m/s^2): the pancake pressed onto the spatula."""

    kind = "normal_floor"

    def __init__(self, weight: float = 1.0, name: str | None = None, *, floor: float = 3.0) -> None:
        super().__init__(weight, name)
        self.floor = as_real(floor, f"{self.name}.floor", error=SettingsError)

    def __call__(self, r: Rollout) -> Tensor:
        _spatula(self, r)
        return torch.relu(self.floor - normal_acceleration(r)).sum(-1)

    def params(self) -> dict[str, Any]:
        return {"floor": self.floor}


class _PancakeObjective(Objective):
    """An objective on the spatula's ``[y, z, theta]``, bound on first use when called on a rollout
    directly (outside :func:`genplan.seq2seq.adjust`)."""

    def __init__(self, terms: Sequence[Term], name: str) -> None:
        super().__init__(terms, name)
        self._bound_batch: int | None = None

    def bind(self, ctx: Context | int) -> None:
        """Bind to ``ctx`` (or, as the first pancake objectives took, a batch size)."""
        if isinstance(ctx, int):
            ctx = Context(axes=AXES, batch=ctx, x_in=torch.zeros(ctx, 1, len(AXES)))
        super().bind(ctx)
        self._bound_batch = ctx.batch

    def terms_of(self, r: Rollout) -> dict[str, Tensor]:
        if self._bound_batch != r.batch:
            self.bind(Context(axes=AXES, batch=r.batch, x_in=r.p.detach()))
        return super().values(r)

    def values(self, r: Rollout) -> dict[str, Tensor]:
        return self.terms_of(r)

    def terms(self, r: Rollout) -> dict[str, Tensor]:  # type: ignore[override]
        """The objective's terms, unweighted, one value per problem."""
        return self.terms_of(r)


def _vector(v: Any, n: int, what: str) -> tuple[float, ...]:
    """``v`` as ``n`` real numbers, else ShapeError naming ``what``."""
    a = as_float_array(v, what)
    if a.shape != (n,):
        raise ShapeError(f"{what} must have {n} values, got shape {a.shape}")
    return tuple(float(x) for x in a)


class J1(_PancakeObjective):
    """eq. 17: ``||D (p[K-1] - p_end)||^2 + alpha f_dyn``, one value per problem.

    ``p_end``: (3,) or (B, 3) end poses (the target of the term ``p_end``). ``margin`` (radians,
    default 0 = the paper) tightens the cone inside f_dyn only.
    """

    def __init__(self, p_end: ArrayLike, alpha: float = 1.0, mu_max: float = ph.MU_MAX,
                 d: Sequence[float] = D_SCALE, margin: float = 0.0) -> None:
        p_end_raw = as_float_array(p_end, "p_end")
        if np.all(np.isfinite(p_end_raw)):
            check_magnitude(p_end_raw, "p_end")
        else:
            raise NonFiniteError("p_end contains NaN or inf")
        self.p_end_raw = p_end_raw
        self.alpha, self.mu_max = as_real(alpha, "alpha"), as_real(mu_max, "mu_max")
        self.margin = as_real(margin, "margin")
        self.d = torch.tensor(_vector(d, 3, "d"), dtype=torch.float32)
        super().__init__([EndState(1.0, "p_end", p_end_raw, scale=self.d.numpy()),
                          FrictionCone(self.alpha, "cone", mu_max=self.mu_max, margin=self.margin)], "j1")


class J2(_PancakeObjective):
    """eq. 24: end inside a ball and an attitude band, friction cone, velocity limits.

    ``max(sqrt(y^2 + z^2) - p_lim, 0) + 0.1 max(|theta - theta_end| - theta_lim, 0)
    + alpha f_dyn + beta / K sum_k ||max(0, D (|p_dot[k]| - v_lim))||^2`` at the last sample;
    the distance is measured from ``center`` (the paper: the origin, where its moves start).
    Defaults are the paper's Section 5.2 values. :class:`J2Executable` adds execution margins.
    Terms: ``position``, ``attitude``, ``cone``, ``velocity``.
    """

    def __init__(self, theta_end: float = -0.75 * math.pi, p_lim: float = 0.2, theta_lim: float = 0.5,
                 alpha: float = 1.0, beta: float = 0.01, v_lim: Sequence[float] = (1.5, 1.5, 4.5),
                 mu_max: float = ph.MU_MAX, d: Sequence[float] = D_SCALE,
                 center: Sequence[float] = (0.0, 0.0), *, name: str = "j2", extra: Sequence[Term] = ()) -> None:
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
        terms: list[Term] = [
            EndBall(1.0, "position", radius=self.p_lim, center=center, axes=(0, 1)),
            EndBand(0.1, "attitude", axis=2, target=self.theta_end, half_width=self.theta_lim),
            FrictionCone(self.alpha, "cone", mu_max=self.mu_max),
            VelocityLimits(self.beta, "velocity", limit=v_lim, scale=d),
            *extra,
        ]
        super().__init__(terms, name)


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
    inside J2's ranges. Terms: J2's and ``cone_margin``, ``normal``, ``attitude_inset``.
    """

    def __init__(self, *args: Any, margin: float = math.radians(10.0), normal_floor: float = 3.0,
                 normal_weight: float = 0.1, attitude_weight: float = 3.0, attitude_inset: float = 0.02,
                 velocity_weight: float = 10.0, **kwargs: Any) -> None:
        names = ["margin", "normal_floor", "normal_weight", "attitude_weight", "attitude_inset", "velocity_weight"]
        extra = [as_real(v, f"J2Executable {k}", error=SettingsError) for k, v in zip(names, [
            margin, normal_floor, normal_weight, attitude_weight, attitude_inset, velocity_weight])]
        margin, normal_floor, normal_weight, attitude_weight, attitude_inset, velocity_weight = extra
        if not all(math.isfinite(v) and v >= 0 for v in extra):
            raise SettingsError(f"J2Executable: margins and weights must be finite and >= 0, got {extra}")
        probe = J2(*args, **kwargs)  # J2's own checks, and the values the checks below need
        if margin >= math.atan(probe.mu_max) or attitude_inset >= probe.theta_lim:
            raise SettingsError("J2Executable: margin must be below the cone's half-angle and attitude_inset below "
                                "theta_lim")
        self.margin, self.normal_floor, self.normal_weight = float(margin), float(normal_floor), float(normal_weight)
        self.attitude_weight, self.attitude_inset = float(attitude_weight), float(attitude_inset)
        self.velocity_weight = float(velocity_weight)
        more = [FrictionCone(1.0, "cone_margin", mu_max=probe.mu_max, margin=self.margin),
                NormalFloor(self.normal_weight / ph.G, "normal", floor=self.normal_floor),
                EndBand(self.attitude_weight, "attitude_inset", axis=2, target=probe.theta_end,
                        half_width=probe.theta_lim - self.attitude_inset)]
        super().__init__(*args, name="j2-exec", extra=more, **kwargs)

    def combine(self, values: Any) -> Tensor:
        """J2's terms and the margins' (in that order), plus ``velocity_weight`` times J2's velocity term."""
        return super().combine(values) + self.velocity_weight * values["velocity"]
