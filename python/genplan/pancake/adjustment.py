"""Latent-space trajectory adjustment of the pancake task: the generic method
(:func:`genplan.seq2seq.adjust`) with the pancake's model, objectives and the paper's settings.

:func:`adjust` minimises an objective ``J(X_out, U_out)`` of the shipped model's output by
gradient descent on

* ``"latent"`` -- the latent vector z, starting from the encoder's z of the input (case 1, the
  paper's method);
* ``"random-latent"`` -- z, starting from ``z ~ N(0, I)`` (case 2; the mirror sign of a
  mirror-canonical model still comes from the input's sense of rotation);
* ``"direct-u"`` -- the accelerations U_out themselves, starting from the decoder's output for
  the input (case 3).

Step rules (:mod:`genplan.seq2seq.adjust`): ``"gd"`` is eq. 7 with the paper's learning rates as
defaults (eta = 200, 200, 1000 for J1 in cases 1-3; 100 for J2); ``"adaptive"`` is eq. 7 inside
a trust radius per problem (the paper's eta is tied to its model's latent scale; on genplan's
model eq. 7 with it diverges -- see the benchmark JSON for both rules); ``"adam"``.

Objectives: :class:`J1` (eq. 17), :class:`J2` (eq. 24), :class:`J2Executable`, or any callable
taking a :class:`~genplan.pancake.physics.Rollout` (batched torch tensors) and returning one
differentiable value per problem, shape (B,) (a 0-d tensor is accepted when B = 1).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import Any, Literal, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray
from torch import Tensor

from genplan.errors import SettingsError, UnknownNameError
from genplan.pancake import physics as ph
from genplan.pancake.model import load_model
from genplan.pancake.objectives import J1, J2, J2Executable, normal_acceleration
from genplan.seq2seq import adjust as generic
from genplan.seq2seq.model import Seq2SeqModel, check_trajectories

Method = Literal["latent", "random-latent", "direct-u"]
METHODS: tuple[str, ...] = ("latent", "random-latent", "direct-u")
STEPS = generic.STEPS
Objective = Union[str, Callable[[ph.Rollout], Tensor]]

#: the paper's learning rates (eta of eq. 7): J1 cases 1-3 (Section 4.3.3) and J2 (Section 5.2)
PAPER_LR = {("j1", "latent"): 200.0, ("j1", "random-latent"): 200.0, ("j1", "direct-u"): 1000.0,
            ("j2", "latent"): 100.0, ("j2", "random-latent"): 100.0, ("j2", "direct-u"): 100.0}
#: the adaptive rule's initial trust radius (RMS of a step): latent units, m/s^2 for direct-u
#: (the best of the radii benches/results/adjust_j1.json compares on the 27 J1 problems with the
#: shipped model)
ADAPTIVE_RADIUS = {"latent": 0.02, "random-latent": 0.02, "direct-u": 0.5}
#: most updates per call (the history keeps one objective per problem and update)
MAX_UPDATES = generic.MAX_UPDATES
#: defaults for the Adam step rule (chosen by the measurements in benches/results/adjust_*adam*.json)
ADAM_LR = {"latent": 0.02, "random-latent": 0.02, "direct-u": 2.0}

__all__ = ["adjust", "AdjustResult", "J1", "J2", "J2Executable", "normal_acceleration", "METHODS", "STEPS", "PAPER_LR",
           "ADAM_LR", "ADAPTIVE_RADIUS", "MAX_UPDATES", "default_lr"]


@dataclasses.dataclass
class AdjustResult(generic.AdjustResult):
    """A pancake adjustment's result: :class:`genplan.seq2seq.adjust.AdjustResult` with the
    spatula's ``phi`` (B, K) and the friction cone's checks."""

    @property
    def phi(self) -> NDArray[np.float64]:
        return self.extras["phi"]

    @property
    def max_abs_phi(self) -> NDArray[np.float64]:
        """Per problem, the largest |phi| over the trajectory (radians)."""
        return np.abs(self.phi).max(-1)

    def inside_cone(self, mu_max: float = ph.MU_MAX) -> NDArray[np.bool_]:
        """Per problem: is every step strictly inside the friction cone (eq. 15)?"""
        return self.max_abs_phi < math.atan(mu_max)


def default_lr(objective: str, method: str, step: str = "gd") -> float:
    """The paper's eta for ``gd`` (J1 / J2 and the case); :data:`ADAM_LR` for ``adam``."""
    if step == "adam":
        return ADAM_LR[method]
    return PAPER_LR.get((objective, method), PAPER_LR[("j1", method)])


def adjust(x_in: ArrayLike, objective: Objective = "j1", method: Method = "latent", updates: int = 100,
           lr: float | None = None, *, model: Seq2SeqModel | None = None, p_end: ArrayLike | None = None,
           step: str = "adaptive", seed: int = 0, snapshots: Sequence[int] = (), progress: bool = False,
           objective_kwargs: dict[str, Any] | None = None, max_step: float | None = None,
           threads: int | None = None) -> AdjustResult:
    """Adjust the pancake model's deformation of ``x_in`` to minimise ``objective``.

    ``x_in``: input poses (K, 3) or (B, K, 3); the output starts at ``x_in[:, 0]`` at rest.
    ``objective``: ``"j1"`` (end pose ``p_end``, default the input's last pose), ``"j2"``
    (keywords in ``objective_kwargs``), a :class:`J1` / :class:`J2`, or a callable.
    ``method``: ``"latent"``, ``"random-latent"`` or ``"direct-u"``. ``lr``: default
    :func:`default_lr`. ``step``: ``"adaptive"`` (default: eq. 7 inside a per-problem trust
    radius), ``"gd"`` (eq. 7 as written) or ``"adam"``. ``seed``: z ~ N(0, I) of
    ``"random-latent"``. ``max_step``: the adaptive rule's initial trust radius (default
    :data:`ADAPTIVE_RADIUS`). ``snapshots``: update indices whose trajectories to keep. With
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
    model = load_model() if model is None else model
    kw = dict(objective_kwargs or {})
    if isinstance(objective, str):
        name = objective.lower()
        if name == "j1":
            x = check_trajectories(x_in, model.config.K, model.config.dim)
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
    if lr is None:
        lr = default_lr(name if name in ("j1", "j2") else "j1", method, step)
    if max_step is None:
        max_step = ADAPTIVE_RADIUS[method]
    res = generic.adjust(model, x_in, obj, method=method, updates=updates, lr=lr, step=step, seed=seed,
                         snapshots=snapshots, progress=progress, max_step=max_step, threads=threads)
    return AdjustResult(**{f.name: getattr(res, f.name) for f in dataclasses.fields(res)})
