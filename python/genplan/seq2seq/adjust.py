"""Latent-space trajectory adjustment (the seq2seq paper's Section 3) for any model, and its two
comparisons.

:func:`adjust` minimises an objective ``J`` of the model's decoded trajectories by gradient
descent on

* ``"latent"`` -- the latent vector z, starting from the encoder's z of the input trajectory
  (case 1, the paper's method);
* ``"random-latent"`` -- z, starting from ``z ~ N(0, I)`` (case 2; a mirror-symmetric model's
  mirror sign still comes from the input);
* ``"direct"`` -- the decoder's output itself (the plant's input U_out: accelerations, or the
  displacements of a position plant), starting from the decoding of the input (case 3;
  ``"direct-u"`` is the same method's first name).

Many problems run in one call (a batch): each problem has its own objective value and its own
variables; the summed objective's gradient is the per-problem gradient.

Step rules:

* ``"gd"`` is eq. 7, ``v <- v - eta dJ/dv``;
* ``"adaptive"`` is eq. 7 inside a trust radius per problem: the step ``eta dJ/dv`` is shortened
  to at most ``radius`` (root mean square over the variable's elements; starts at ``max_step``,
  default :data:`ADAPTIVE_RADIUS`); a step that raises that problem's J is undone and retried with
  half its length, after a step that lowers J the radius grows by half. Still one forward and
  one backward pass per update, the objective never rises, and eta matters much less;
* ``"adam"`` (elementwise Adam, so per problem; torch's rule and defaults, betas (0.9, 0.999),
  eps 1e-8, written out in :class:`_Adam`: ``torch.optim`` imports torch's compiler on first use,
  seconds more than a whole adjustment).

Objectives: an :class:`~genplan.seq2seq.objectives.Objective` (terms as data, or a file), or any
callable taking a :class:`~genplan.seq2seq.plants.Rollout` and returning one differentiable
value per problem, shape (B,) (a 0-d tensor is accepted when B = 1).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import torch
from numpy.typing import ArrayLike, NDArray
from torch import Tensor

from genplan._arrays import as_configurations, as_count, as_float_array, as_real
from genplan._threads import uses_torch
from genplan.errors import CallbackError, SettingsError, ShapeError, UnknownNameError
from genplan.seq2seq.model import Seq2SeqModel, check_trajectories, first_nonfinite
from genplan.seq2seq.objectives import Context, Objective, load_objective
from genplan.seq2seq.plants import Rollout

__all__ = ["adjust", "AdjustResult", "ClearEnds", "clear_ends", "aim_inputs", "METHODS", "STEPS", "ADAPTIVE_RADIUS", "ADAM_LR", "MAX_UPDATES", "MAX_STARTS", "DEFAULT_STARTS", "START_SPREAD", "method_name"]

Method = Literal["latent", "random-latent", "direct"]
METHODS: tuple[str, ...] = ("latent", "random-latent", "direct")
#: names a method had before (still accepted)
ALIASES = {"direct-u": "direct"}
STEPS: tuple[str, ...] = ("gd", "adaptive", "adam")
#: where the adjustment starts: see :func:`adjust`'s ``anchor``
ANCHORS: tuple[str, ...] = ("auto", "input", "none")
#: the adaptive rule's initial trust radius (RMS of a step): latent units; for "direct", in units
#: of the model's ``out_scale`` (its root mean square)
ADAPTIVE_RADIUS = {"latent": 0.02, "random-latent": 0.02, "direct": 0.02}
#: the adam step rule's learning rates: latent units; for "direct", in units of ``out_scale``
ADAM_LR = {"latent": 0.02, "random-latent": 0.02, "direct": 0.08}
#: most updates per call (the history keeps one objective per problem and update)
MAX_UPDATES = 1_000_000
#: most starts per problem (see :func:`adjust`'s ``starts``)
MAX_STARTS = 64
#: a problem runs the other starts when a clearance term of the objective, its margin times this,
#: is positive after the first start: a robot's sphere nearer an obstacle than that (the spheres
#: cover the links, so 0: a sample possibly in collision; on the Panda obstacle case 0 restarts
#: the fewest problems and still every one whose finished trajectory fails its checks)
RESTART_MARGIN = 0.0
#: the starts per problem by default for an objective with clearance terms (one otherwise): on
#: the Panda obstacle case (``genplan bench adapt --rows obstacle --skip 60``, tuning problems)
#: 8 starts clear more problems than 4 for under twice the time of one start, since only the
#: problems the first start leaves blocked run the others
DEFAULT_STARTS = 8
#: the spread of the restarts' latent starts around the first one (standard deviation, latent
#: units: the encoder's prior is N(0, I))
START_SPREAD = 0.5
#: with a ``pool`` (see :func:`adjust`): the pool's trajectories nearest a restarted problem's
#: input (start and end samples) whose decodings from the problem's start are scored on the
#: objective
POOL_NEAREST = 32
#: with a ``pool``: the share of a problem's restarts that start from pool trajectories (the
#: best scored), the others from the random spread around the first start; all from the pool:
#: on the Panda obstacle case's tuning problems (``genplan bench adapt --rows obstacle
#: --obstacle-pool data|none``) it clears more problems than half, and half more than none
POOL_SHARE = 1.0


def method_name(method: str) -> str:
    """The method's name (its first name accepted), else UnknownNameError listing them."""
    name = ALIASES.get(method, method)
    if name not in METHODS:
        raise UnknownNameError(f"method must be one of {METHODS}, got {method!r}")
    return name


@dataclass
class AdjustResult:
    """What :func:`adjust` returns (numpy, float64; B problems, K samples, d axes).

    ``p``, ``v``, ``u``: (B, K, d) the adjusted trajectories, their velocities and the decoder's
    output; ``extras``: what the plant adds (the spatula's ``phi``, (B, K)), also readable as
    attributes (``result.phi``). ``objective_history[i]`` holds the objective of every problem
    after ``i`` updates (row 0: before any update), shape (updates + 1, B). ``snapshots`` maps an
    update index to the trajectory (``p``, ``v``, ``u`` and the extras) at that point. Timing:
    ``update_times_s`` holds the wall time of each update of the whole batch (forward, backward,
    step), ``time_updates_s`` their sum, ``ms_per_update`` their median over B; ``time_init_s`` is
    the encoder (or decoder) pass that gives the start point. ``context``: what the objective was
    bound to (the robot, task and scene :meth:`finish` uses); ``objective``: what was minimised.

    Several starts (``adjust(..., starts=K)``): ``starts`` is K; ``starts_run[b]`` how many starts
    problem b ran (1 when its first start left no clearance term positive, else K);
    ``start_index[b]`` the start whose trajectory the result holds (0: the first, from the input's
    encoding; j >= 1: the j-th restart): of the starts that leave no clearance term positive (at
    :data:`RESTART_MARGIN` times its margin) the one of lowest objective, else the lowest of all;
    the result holds its history, ``z`` and snapshots too; ``alternatives[b]``: the other clear
    starts' trajectories as (start index, positions (K, d)), lowest objective first, which
    :meth:`finish` falls back on when the kept one fails its checks.
    """

    p: NDArray[np.float64]
    v: NDArray[np.float64]
    u: NDArray[np.float64]
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
    extras: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    starts: int = 1
    starts_run: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    start_index: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    alternatives: list[list[tuple[int, NDArray[np.float64]]]] = field(default_factory=list, repr=False)
    model: Seq2SeqModel | None = field(default=None, repr=False)
    context: Context | None = field(default=None, repr=False)
    objective: Any = field(default=None, repr=False)

    def __getattr__(self, name: str) -> Any:
        extras = self.__dict__.get("extras", {})
        if name in extras:
            return extras[name]
        raise AttributeError(f"{type(self).__name__} has no attribute {name!r}")

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

    def __post_init__(self) -> None:
        b = self.batch
        if len(self.starts_run) != b:
            self.starts_run = np.ones(b, dtype=np.int64)
        if len(self.start_index) != b:
            self.start_index = np.zeros(b, dtype=np.int64)
        if len(self.alternatives) != b:
            self.alternatives = [[] for _ in range(b)]

    def first_update_below(self, level: float) -> NDArray[np.int64]:
        """Per problem, the first update index whose objective is below ``level`` (-1: never)."""
        below = self.objective_history < level
        return np.where(below.any(0), below.argmax(0), -1)

    def finish(self, **kwargs: Any) -> Any:
        """The adjusted trajectories made executable: see :func:`genplan.seq2seq.finish.finish`."""
        from genplan.seq2seq.finish import finish

        return finish(self, **kwargs)


class _Adam:
    """Adam (Kingma and Ba) on one tensor, with torch.optim.Adam's defaults (betas (0.9, 0.999),
    eps 1e-8, no weight decay) and its arithmetic, step for step."""

    BETAS = (0.9, 0.999)
    EPS = 1e-8

    def __init__(self, var: Tensor, lr: float) -> None:
        self.lr = lr
        self.steps = 0
        self.m = torch.zeros_like(var, memory_format=torch.preserve_format)
        self.v = torch.zeros_like(var, memory_format=torch.preserve_format)

    def step(self, var: Tensor, grad: Tensor) -> None:
        """Update ``var`` in place (under no_grad) with its gradient ``grad``."""
        b1, b2 = self.BETAS
        self.steps += 1
        self.m.lerp_(grad, 1 - b1)
        self.v.mul_(b2).addcmul_(grad, grad, value=1 - b2)
        step_size = self.lr / (1 - b1 ** self.steps)
        denom = (self.v.sqrt() / math.sqrt(1 - b2 ** self.steps)).add_(self.EPS)
        var.addcdiv_(self.m, denom, value=-step_size)


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


def _rollout_keys(r: Rollout) -> tuple[str, ...]:
    """The per-problem arrays of a rollout a result keeps: p, v, u and what the plant adds."""
    extra = tuple(k for k, v in vars(r).items() if isinstance(v, Tensor) and k not in ("p", "v", "u", "var_p"))
    return ("p", "v", "u") + extra


def _empty_result(model: Seq2SeqModel, method: str, step: str, lr: float, updates: int, keep: set[int],
                  ctx: Context, obj: Any) -> AdjustResult:
    """What :func:`adjust` returns for an empty batch (torch's LSTMs do not take one)."""
    cfg = model.config
    k, d = cfg.K, cfg.dim
    arrays = {"p": np.zeros((0, k, d)), "v": np.zeros((0, k, d)), "u": np.zeros((0, k, d))}
    extras = {"phi": np.zeros((0, k))} if cfg.plant == "spatula" else {}
    return AdjustResult(p=arrays["p"], v=arrays["v"], u=arrays["u"], objective_history=np.zeros((updates + 1, 0)),
                        z=None if method == "direct" else np.zeros((0, cfg.latent_dim)), method=method,
                        step=step, lr=lr, updates=updates, time_init_s=0.0, time_updates_s=0.0, time_total_s=0.0,
                        update_times_s=np.zeros(updates), extras=extras,
                        snapshots={i: {key: a.copy() for key, a in {**arrays, **extras}.items()} for i in sorted(keep)},
                        model=model, context=ctx, objective=obj)


def _default_lr(method: str, step: str, model: Seq2SeqModel) -> float:
    if step == "adam":
        return ADAM_LR[method] * (_out_rms(model) if method == "direct" else 1.0)
    return 1.0


def _out_rms(model: Seq2SeqModel) -> float:
    s = np.asarray(model.config.out_scale, dtype=float)
    return float(np.sqrt(np.mean(s ** 2)))


@uses_torch("small")
def adjust(model: Seq2SeqModel, x_in: ArrayLike, objective: Any, *, targets: Mapping[str, ArrayLike] | None = None,
           method: str = "latent", updates: int = 100, lr: float | None = None, step: str = "adaptive",
           seed: int = 0, snapshots: Sequence[int] = (), progress: bool = False, max_step: float | None = None,
           robot: Any = None, task: Any = None, scene: Any = None, allow_python: bool = False,
           anchor: str = "auto", threads: int | None = None, device: str | torch.device = "cpu",
           starts: int | None = None, start_spread: float = START_SPREAD, pool: ArrayLike | None = None) -> AdjustResult:
    """Adjust the model's decoding of ``x_in`` to minimise ``objective``.

    ``model``: a :class:`~genplan.seq2seq.model.Seq2SeqModel` (or a model file's path).
    ``x_in``: input trajectories (K, d) or (B, K, d) in the model's space; each decoded trajectory
    starts where its input does. ``objective``: an :class:`~genplan.seq2seq.objectives.Objective`,
    an objective file (TOML) or its dict form, or a callable on a rollout returning (B,).
    ``targets``: per-problem targets keyed by term name (arrays of shape (B, ...)). ``method``:
    ``"latent"``, ``"random-latent"`` or ``"direct"``. ``step``: ``"adaptive"`` (default),
    ``"gd"`` or ``"adam"``; ``lr``: eta (default 1 for gd and adaptive, :data:`ADAM_LR` for
    adam). ``max_step``: the adaptive rule's initial trust radius (default
    :data:`ADAPTIVE_RADIUS`; for "direct" times the RMS of the model's ``out_scale``). ``seed``:
    z ~ N(0, I) of "random-latent". ``snapshots``: update indices whose trajectories to keep.
    With "adaptive" the history, the snapshots and the result are those of the kept (best)
    iterate. ``robot``, ``task``, ``scene``: what the objective's robot terms and :meth:`finish`
    need (default: the robot, task and scene the model's card names, those of its data; a scene
    is a :class:`~genplan.scene.Scene`, a shipped scene's name or a scene file). ``anchor``:
    ``"input"`` decodes the change of z from the input's own encoding and adds it to the input, so the adjustment starts from the input
    trajectory itself (a valid member of the family) rather than from its reconstruction, and a
    model's reconstruction error does not carry into the result; ``"none"`` decodes z alone (the
    paper's method, where the input is only a sketch the model deforms); ``"auto"`` (default):
    "input" for plants that can invert a trajectory (the position plant of robot families),
    "none" otherwise (the pancake's). ``threads``: torch threads (default one, see
    genplan._threads); ``device``: the torch device (CPU by default).

    ``starts``: the starts per problem (default :data:`DEFAULT_STARTS` for an objective with a
    clearance term, 1 otherwise). With K > 1, a problem whose adjusted
    trajectory still has a clearance term of the objective positive at :data:`RESTART_MARGIN`
    times the term's margin (``clearance``, ``avoid_spheres``, ``self_clearance``: a robot sphere
    of some sample that near an obstacle; without such terms, every problem; not a problem whose
    start sample itself is blocked, which no start can clear) is adjusted again
    from K - 1 other starts, all in one batch: the first start's z plus normal noise of
    ``start_spread`` latent units (seeded by ``seed``), the same updates, step and objective. A gradient method is local: the clearance's
    gradient from opposite sides of an obstacle cancels and a path that must pass it on the other
    side never gets there, which another start often does. Each problem keeps, of its starts that
    leave every clearance term zero at that margin, the one of lowest objective (of all, when
    none does); the other clear ones stay in the result (``alternatives``), which :meth:`finish`
    tries in turn when the kept trajectory fails its checks. ``starts_run`` and ``start_index``
    say what each problem used. Needs an :class:`~genplan.seq2seq.objectives.Objective` (a
    callable's per-problem values cannot be repeated for the restarts).

    ``pool``: trajectories (N, K, d) in the model's space (the family's own data, say) that the
    restarts may start from. For each restarted problem, the pool's :data:`POOL_NEAREST`
    trajectories nearest its input (distance of the start and end samples) are decoded from the
    problem's start (their encodings) and scored on the objective; its restarts (a share
    :data:`POOL_SHARE` of them, all by default) start from the encodings of the best scored, the
    rest from the random spread (also when fewer members are near). A member of the family that
    already passes an obstacle on another side is a start no local perturbation reaches.

    Every argument is checked before any update. Every decoded trajectory is finite, or
    FloatingPointError names the problem and the update (as for an objective that becomes NaN or
    inf). An empty batch gives an empty result (B = 0) once the arguments are checked.
    """
    if not isinstance(model, Seq2SeqModel):
        from genplan.seq2seq.model import load_model

        model = load_model(model)
    method = method_name(method)
    if anchor not in ANCHORS:
        raise UnknownNameError(f"anchor must be one of {ANCHORS}, got {anchor!r}")
    use_anchor = anchor == "input" or (anchor == "auto" and hasattr(model.plant, "inputs"))
    if use_anchor and not hasattr(model.plant, "inputs"):
        raise SettingsError(f"anchor 'input': the {model.config.plant!r} plant cannot tell which of its inputs gives a "
                            "trajectory (only plants with an inputs() method can: 'position')")
    if step not in STEPS:
        raise UnknownNameError(f"step must be one of {STEPS}, got {step!r}")
    if isinstance(updates, bool) or not isinstance(updates, (int, np.integer)) or updates < 0:
        raise SettingsError(f"updates must be a non-negative integer, got {updates!r}")
    updates = as_count(updates, "updates", maximum=MAX_UPDATES)
    cfg = model.config
    x = check_trajectories(x_in, cfg.K, cfg.dim)
    b = x.shape[0]
    dev = torch.device(device)
    obj: Callable[[Rollout], Tensor]
    ctx = _context(model, x, dict(targets or {}), robot, task, scene, dev)
    if callable(objective) and not isinstance(objective, Objective):
        if targets:
            raise SettingsError("targets are keyed by objective terms: give an Objective (or a file) to use them")
        obj = objective
    else:
        obj = load_objective(objective, allow_python=allow_python)
        obj.bind(ctx)  # checks targets, frames, the task and the scene before any work
    if lr is None:
        lr = _default_lr(method, step, model)
    if not (isinstance(lr, (int, float)) and not isinstance(lr, bool) and math.isfinite(lr) and lr > 0):
        raise SettingsError(f"lr must be a positive finite number, got {lr!r}")
    if max_step is not None:
        max_step = as_real(max_step, "max_step", error=SettingsError)
        if not (math.isfinite(max_step) and max_step > 0):
            raise SettingsError(f"max_step must be a positive finite number, got {max_step!r}")
    else:
        max_step = ADAPTIVE_RADIUS[method] * (_out_rms(model) if method == "direct" else 1.0)
    seed = as_count(seed, "seed", maximum=2**64 - 1)
    if starts is None:
        starts = DEFAULT_STARTS if _clearance_terms(obj) else 1
    starts = as_count(starts, "starts", minimum=1, maximum=MAX_STARTS)
    start_spread = as_real(start_spread, "start_spread", error=SettingsError)
    if not (math.isfinite(start_spread) and start_spread > 0):
        raise SettingsError(f"start_spread must be a positive finite number (latent units), got {start_spread!r}")
    if starts > 1 and not isinstance(obj, Objective):
        raise SettingsError("starts > 1 needs an Objective (terms as data, or a file): a callable's per-problem values "
                            "cannot be repeated for the restarts")
    pool_x = None if pool is None else check_trajectories(pool, cfg.K, cfg.dim, name="pool")
    if pool_x is not None and len(pool_x) == 0:
        raise ShapeError("pool must hold at least one trajectory, got an empty array")
    if pool_x is not None and (starts == 1 or method == "random-latent"):
        raise SettingsError("pool gives restarts their latent starts: it needs starts > 1 and the 'latent' or 'direct' "
                            f"method (got starts={starts}, method={method!r})")
    keep = {as_count(s, "snapshots") for s in snapshots}
    if any(s > updates for s in keep):  # as_count refused negatives
        raise SettingsError(f"snapshots must lie in [0, {updates}], got {sorted(keep)}")
    if b == 0:
        res = _empty_result(model, method, step, float(lr), updates, keep, ctx, obj)
        res.starts = starts
        return res
    if dev != torch.device("cpu"):
        model.net.to(dev)
    xt = torch.as_tensor(x, dtype=torch.float32, device=dev)
    name = getattr(obj, "name", "objective")
    first = _run(model, xt, obj, method, updates, float(lr), step, seed, keep, progress, float(max_step), ctx, name,
                 use_anchor)
    first.starts = starts
    if starts == 1:
        return first
    assert isinstance(obj, Objective)
    blocked = _blocked(obj, first.p)
    # a problem whose start itself is blocked (the decoding starts there) no start can clear
    redo = blocked & ~_blocked(obj, first.p[:, :1]) if _clearance_terms(obj) else np.ones(b, dtype=bool)
    todo = np.nonzero(redo)[0]
    if len(todo) == 0:
        return first
    # the restarts: each unresolved problem K - 1 times, the objective bound to that batch (the
    # targets as bound for the problems), then bound back to the problems for finish
    rows = np.repeat(todo, starts - 1)
    gen = torch.Generator().manual_seed(int(seed))
    noise = start_spread * torch.randn(len(rows), model.config.latent_dim, generator=gen).to(dev)
    base = {t.name: t.target for t in obj.terms if t.has_target}
    try:
        if pool_x is not None:
            from_pool = max(1, round(POOL_SHARE * (starts - 1)))
            offsets, found = _pool_offsets(model, xt, x, todo, pool_x, from_pool, obj, ctx, base, method, step,
                                           float(lr), float(max_step), name, use_anchor)
            per = noise.view(len(todo), starts - 1, -1)[:, :offsets.shape[1]]
            per[torch.as_tensor(found, device=dev)] = offsets[torch.as_tensor(found, device=dev)]
        ctx_rows = _bind_rows(obj, ctx, base, rows)
        again = _run(model, xt[torch.as_tensor(rows, device=dev)], obj, method, updates, float(lr), step,
                     (seed + 1) % 2**64, keep, progress, float(max_step), ctx_rows, name, use_anchor, perturb=noise)
        blocked_again = _blocked(obj, again.p)
    finally:
        obj.bind(ctx)
    return _merge(first, again, todo, starts, blocked, blocked_again)


def _bind_rows(obj: Objective, ctx: Context, base: Mapping[str, Tensor], rows: NDArray[np.int64]) -> Context:
    """Bind ``obj`` to the problems ``rows`` of ``ctx`` (repeats allowed): their inputs and the
    targets ``base`` as bound for all the problems. Returns that context."""
    idx = torch.as_tensor(rows, device=ctx.device)
    bound = {k: v[idx] for k, v in base.items()}
    ctx_rows = dataclasses.replace(ctx, batch=len(rows), x_in=ctx.x_in[torch.as_tensor(rows)], targets=bound, _scope=None)
    obj.bind(ctx_rows)
    return ctx_rows


def _pool_offsets(model: Seq2SeqModel, xt: Tensor, x: NDArray[np.float64], todo: NDArray[np.int64],
                  pool: NDArray[np.float64], count: int, obj: Objective, ctx: Context, base: Mapping[str, Tensor],
                  method: str, step: str, lr: float, max_step: float, name: str,
                  anchor: bool) -> tuple[Tensor, NDArray[np.bool_]]:
    """(len(todo), c, latent) latent offsets from each problem's own encoding to the encodings of
    the c <= ``count`` pool trajectories (of the :data:`POOL_NEAREST` nearest its input by start
    and end samples) whose decodings from the problem's start score lowest on ``obj``, and
    (len(todo), c) which of them are usable: pool members of the problem's own mirror sign that
    are not its input itself (which the first start already ran); the others keep the random
    spread. Leaves ``obj`` bound to a scoring batch: the caller rebinds it."""
    dev = xt.device
    pt = torch.as_tensor(pool, dtype=torch.float32, device=dev)
    with torch.no_grad():
        z_pool = model.encode(pt)
        sign_pool = model.chirality(pt).cpu().numpy()
        xs = xt[torch.as_tensor(todo, device=dev)]
        z_own = model.encode(xs)
        sign_own = model.chirality(xs).cpu().numpy()
    ends = np.concatenate([pool[:, 0], pool[:, -1]], 1)
    near = min(POOL_NEAREST, len(pool))
    cand = np.empty((len(todo), near), dtype=np.int64)
    unusable = np.zeros((len(todo), near), dtype=bool)
    for j, i in enumerate(todo):
        d = np.sum((ends - np.concatenate([x[i, 0], x[i, -1]])) ** 2, 1)
        d[sign_pool != sign_own[j]] = np.inf  # a mirrored member's latent means another motion
        d[np.all(pool == x[i], axis=(1, 2))] = np.inf  # the input itself: the first start
        cand[j] = np.argsort(d, kind="stable")[:near]
        unusable[j] = np.isinf(d[cand[j]])
    rows = np.repeat(todo, near)
    perturb = z_pool[torch.as_tensor(cand.reshape(-1), device=dev)] - z_own.repeat_interleave(near, 0)
    ctx_rows = _bind_rows(obj, ctx, base, rows)
    scored = _run(model, xt[torch.as_tensor(rows, device=dev)], obj, method, 0, lr, step, 0, set(), False, max_step,
                  ctx_rows, name, anchor, perturb=perturb)
    score = scored.objective_history[0].reshape(len(todo), near)
    score[unusable] = np.inf  # never picked while a usable member remains
    best = np.argsort(score, 1, kind="stable")[:, :count]
    found = ~np.take_along_axis(unusable, best, 1)
    chosen = perturb.reshape(len(todo), near, -1)
    offsets = torch.stack([chosen[j, torch.as_tensor(best[j], device=dev)] for j in range(len(todo))])
    return offsets, found


def _context(model: Seq2SeqModel, x: NDArray[np.float64], targets: dict[str, Any], robot: Any, task: Any,
             scene: Any, device: torch.device) -> Context:
    """The objective's context: the card's robot and task unless given; the scene loaded."""
    card = model.card
    if robot is None and isinstance(card.get("robot"), Mapping):
        from genplan.robots import load

        robot = load(card["robot"].get("source") or card["robot"].get("name"))
    elif isinstance(robot, str):
        from genplan.robots import load

        robot = load(robot)
    if task is None and robot is not None and isinstance(card.get("task"), Mapping):
        from genplan.projection import Task

        task = Task.from_dict(card["task"]["terms"], robot) if "terms" in card["task"] else None
    elif isinstance(task, str) and robot is not None:
        from genplan.projection import load_task

        task = load_task(task, robot)
    if scene is None:  # the scene the model's data was made in (or None)
        scene = card.get("scene")
    if scene is not None:
        from genplan.scene import load_scene

        scene = load_scene(scene)
    return Context(axes=model.config.axes, batch=len(x), x_in=torch.as_tensor(x, dtype=torch.float32),
                   targets=targets, robot=robot, task=task, scene=scene, device=device)


def _run(model: Seq2SeqModel, xt: Tensor, obj: Callable[[Rollout], Tensor], method: str, updates: int, lr: float,
         step: str, seed: int, keep: set[int], progress: bool, max_step: float, ctx: Context,
         name: str, anchor: bool, perturb: Tensor | None = None) -> AdjustResult:
    """The update loop of :func:`adjust` (arguments checked); ``perturb`` (B, latent) is added to
    each problem's starting z (after the anchor's offset is taken at the unperturbed z)."""
    b = xt.shape[0]
    t_start = time.perf_counter()
    x0 = model.start(xt)
    sign = model.chirality(xt)  # the mirror sign of each problem (fixed while adjusting)
    cond = model.mirror(x0, sign) if model.config.condition_on_start else None

    def outputs(z: Tensor) -> Tensor:
        """The plant's input the decoder gives for ``z`` (mirrored back)."""
        return model.mirror(model.net.decode(z, cond)[0], sign)

    offset: Tensor | None = None
    with torch.no_grad():
        if method == "random-latent":
            gen = torch.Generator().manual_seed(int(seed))
            var = torch.randn(b, model.config.latent_dim, generator=gen).to(xt.device)
        else:
            var = model.encode(xt, sign)
        if anchor:
            # the decoding's change from the input's own encoding, added to the input: the
            # adjustment starts from the input trajectory itself, not from its reconstruction
            z_in = var if method != "random-latent" else model.encode(xt, sign)
            offset = model.plant.inputs(xt, x0) - outputs(z_in)
        if perturb is not None:
            var = var + perturb
        if method == "direct":
            var = outputs(var) + (offset if offset is not None else 0.0)
    var = var.clone().requires_grad_(True)
    t_init = time.perf_counter() - t_start

    def forward(v: Tensor) -> Rollout:
        if method == "direct":
            return model.plant.rollout(v, None, x0)
        if offset is None:
            return model.decode(v, x0, sign)
        return model.plant.rollout(outputs(v) + offset, None, x0)

    opt = _Adam(var, lr) if step == "adam" else None
    adaptive = step == "adaptive"
    shape1 = (b,) + (1,) * (var.ndim - 1)
    n_el = var[0].numel()
    radius = torch.full(shape1, max_step, dtype=var.dtype, device=var.device)
    used = torch.zeros(shape1, dtype=var.dtype, device=var.device)
    acc_var = var.detach().clone()
    acc_j = torch.full((b,), math.inf, dtype=var.dtype, device=var.device)
    acc_grad = torch.zeros_like(acc_var)
    keys: tuple[str, ...] = ()
    acc_r: dict[str, Tensor] = {}
    hist = np.empty((updates + 1, b))
    snaps: dict[int, dict[str, NDArray[np.float64]]] = {}
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=updates, desc=f"adjust ({method}, {name})", unit="update")
    times = np.zeros(updates)
    r: Rollout | None = None
    for i in range(updates + 1):
        t0 = time.perf_counter()
        with torch.enable_grad():
            r = forward(var)
            j = _check_value(obj(r), b)
        keys = keys or _rollout_keys(r)
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
            hist[i] = acc_j.double().cpu().numpy()
            if i in keep:
                snaps[i] = {k: acc_r[k].double().cpu().numpy() for k in keys}
        else:
            hist[i] = jd.double().cpu().numpy()
            if i in keep:
                snaps[i] = {k: getattr(r, k).detach().double().cpu().numpy() for k in keys}
        if not need_grad:
            break
        with torch.no_grad():
            if adaptive:
                d = lr * acc_grad
                rms = d.reshape(b, -1).norm(dim=1).reshape(shape1) / math.sqrt(n_el)
                scale = torch.clamp(radius / torch.clamp(rms, min=1e-30), max=1.0)
                used = rms * scale
                var = (acc_var - scale * d).requires_grad_(True)
            elif opt is None:
                var -= lr * grad
            else:
                opt.step(var, grad)
        times[i] = time.perf_counter() - t0
        if bar is not None:
            bar.update(1)
            bar.set_postfix(J=f"{float(hist[i].mean()):.3g}")
    if bar is not None:
        bar.close()
    assert r is not None
    if adaptive:
        final = acc_r
        var_out = acc_var
    else:
        final = {k: getattr(r, k).detach() for k in keys}
        var_out = var.detach()
    t_total = time.perf_counter() - t_start
    arrays = {k: v.double().cpu().numpy() for k, v in final.items()}
    return AdjustResult(
        p=arrays.pop("p"), v=arrays.pop("v"), u=arrays.pop("u"), objective_history=hist,
        z=None if method == "direct" else var_out.double().cpu().numpy(), method=method, step=step, lr=lr,
        updates=updates, time_init_s=t_init, time_updates_s=float(times.sum()), time_total_s=t_total,
        update_times_s=times, snapshots=snaps, extras=arrays, model=model, context=ctx, objective=obj)


def _clearance_terms(obj: Any) -> list[str]:
    """The names of the clearance terms of ``obj`` (``clearance``, ``avoid_spheres``,
    ``self_clearance``; none for a callable)."""
    from genplan.seq2seq.objectives import Clearance

    return [t.name for t in obj.terms if isinstance(t, Clearance)] if isinstance(obj, Objective) else []


def _blocked(obj: Objective, p: NDArray[np.float64]) -> NDArray[np.bool_]:
    """(B,) the trajectories ``p`` (B, K, d) that leave a clearance term of ``obj`` positive at
    :data:`RESTART_MARGIN` times its margin (none when ``obj`` has no such term)."""
    from genplan.seq2seq.objectives import Clearance

    terms = [t for t in obj.terms if isinstance(t, Clearance)]
    if not terms or len(p) == 0:
        return np.zeros(len(p), dtype=bool)
    dev = obj._ctx.device if obj._ctx is not None else torch.device("cpu")
    pt = torch.as_tensor(p, dtype=torch.float32, device=dev)
    r = Rollout(p=pt, v=torch.zeros_like(pt), u=torch.zeros_like(pt))
    margins = [t.margin for t in terms]
    try:  # the terms' screening cutoffs were set at bind for their full margins: still conservative
        for t in terms:
            t.margin = RESTART_MARGIN * t.margin
        with torch.no_grad():
            values = [t(r) for t in terms]
    finally:
        for t, m in zip(terms, margins):
            t.margin = m
    return np.asarray(torch.stack(values).amax(0).cpu().numpy() > 0.0, dtype=bool)


def _merge(first: AdjustResult, again: AdjustResult, todo: NDArray[np.int64], starts: int,
           blocked: NDArray[np.bool_], blocked_again: NDArray[np.bool_]) -> AdjustResult:
    """``first`` (B problems) with the restarts ``again`` (starts - 1 rows per problem of
    ``todo``, in order): per problem the starts ranked, those left clear of the obstacles
    (``blocked``, ``blocked_again`` false: no clearance term positive, see :func:`_blocked`)
    first, then by final objective; the first kept, the other clear ones kept as alternatives in
    that order (a blocked trajectory is one the finish's dense check fails or repairs slowly)."""
    n = starts - 1
    out = dataclasses.replace(first, extras={k: a.copy() for k, a in first.extras.items()},
                              snapshots={i: {k: a.copy() for k, a in d.items()} for i, d in first.snapshots.items()})
    out.p, out.v, out.u = first.p.copy(), first.v.copy(), first.u.copy()
    out.objective_history = first.objective_history.copy()
    out.z = None if first.z is None else first.z.copy()
    out.starts_run = first.starts_run.copy()
    out.start_index = first.start_index.copy()
    out.alternatives = [list(a) for a in first.alternatives]
    for j, i in enumerate(todo):
        rows = j * n + np.arange(n)
        finals = np.concatenate([[first.objective_history[-1, i]], again.objective_history[-1, rows]])
        stuck = np.concatenate([[blocked[i]], blocked_again[rows]])
        order = np.lexsort((finals, stuck))
        source = [(first, int(i))] + [(again, int(r)) for r in rows]  # start s: (its result, its row)
        best, row = source[int(order[0])]
        out.p[i], out.v[i], out.u[i] = best.p[row], best.v[row], best.u[row]
        out.objective_history[:, i] = best.objective_history[:, row]
        if out.z is not None and best.z is not None:
            out.z[i] = best.z[row]
        for k in out.extras:
            out.extras[k][i] = best.extras[k][row]
        for u, snap in out.snapshots.items():
            for k in snap:
                snap[k][i] = best.snapshots[u][k][row]
        out.starts_run[i] = starts
        out.start_index[i] = int(order[0])
        out.alternatives[i] = [(int(s), source[s][0].p[source[s][1]].copy()) for s in order[1:] if not stuck[s]]
    out.update_times_s = first.update_times_s + again.update_times_s
    out.time_init_s = first.time_init_s + again.time_init_s
    out.time_updates_s = first.time_updates_s + again.time_updates_s
    out.time_total_s = first.time_total_s + again.time_total_s
    return out


#: :func:`clear_ends`: the IK guesses per blocked end (half drawn around the end with the spreads
#: of CLEAR_END_SPREADS rad in turn, half uniform)
CLEAR_END_GUESSES = 64
CLEAR_END_SPREADS = (0.25, 0.5, 1.0)
#: :func:`clear_ends`: the steps of the walk along the self-motion (push_clear's, each at most
#: its CLEAR_MAX_STEP rad a joint)
CLEAR_END_WALK = 30


@dataclass
class ClearEnds:
    """What :func:`clear_ends` returns, per problem (B): ``q`` (B, nq) the end configurations
    (a blocked end replaced by the clear one found, the others as given); ``blocked``: the given
    end was in collision; ``found``: a clear end was found for it (``blocked & ~found``: none
    among the guesses); ``moved``: the joint distance (rad, Euclidean) from the given end to the
    chosen one (0 where nothing changed)."""

    q: NDArray[np.float64]
    blocked: NDArray[np.bool_]
    found: NDArray[np.bool_]
    moved: NDArray[np.float64]


def clear_ends(robot: Any, ends: ArrayLike, world: Any, frame: str, *, task: Any = None, seed: int = 0,
               guesses: int = CLEAR_END_GUESSES, margin: float | None = None) -> ClearEnds:
    """For each end configuration of ``ends`` (B, nq) that is in collision in ``world`` (one
    :class:`~genplan.collision.CollisionWorld`, or one per problem), another configuration with
    ``frame`` at the same position on the task's manifold (``task``: its primary terms hold, as
    the finish projects them; None: the joint limits alone) that is collision-free: the same
    position reached elsewhere on the arm's self-motion. Candidates: the blocked end walked along
    its self-motion (:func:`genplan.seq2seq.finish.push_clear` on its own target, stepping in the
    null space of the task's and the position's Jacobian, :data:`CLEAR_END_WALK` steps), and IK
    (the task with ``frame``'s position as its condition, :func:`genplan.ik.frame_task`, solved
    with :data:`genplan.ik.IK_SETTINGS`) from ``guesses`` warm starts per blocked end, half drawn
    around it (normal spreads of :data:`CLEAR_END_SPREADS` rad) and half uniform (seeded by
    ``seed``), all blocked ends in one native batch, each solution projected onto the manifold at
    the finish's tolerances. Of the candidates clear in the problem's world, the nearest to the
    blocked end in joint space among those at least ``margin`` (m; default the finish's
    :data:`~genplan.seq2seq.finish.CLEAR_MARGIN`) from every obstacle (else the clearest) is chosen.

    A redundant arm often reaches a goal position only on another branch once an obstacle sits
    where its elbow was, and the latent adjustment, which moves an input continuously, does not
    reach a branch a radian or more away; with the chosen end as the input's new end
    (:func:`aim_inputs`) the adjustment starts from a trajectory that ends clear."""
    from genplan import projection as P
    from genplan.ik import IK_SETTINGS, frame_task
    from genplan.seq2seq.finish import CLEAR_MARGIN, push_clear

    q = np.array(as_configurations(ends, robot.nq, "ends"), dtype=np.float64, ndmin=2)
    b = len(q)
    worlds = list(world) if isinstance(world, Sequence) else [world] * b
    if len(worlds) != b:
        raise SettingsError(f"world: one collision world or one per end ({b}), got {len(worlds)}")
    guesses = as_count(guesses, "guesses", minimum=1)
    margin = CLEAR_MARGIN if margin is None else as_real(margin, "margin", error=SettingsError)
    if not (math.isfinite(margin) and margin >= 0):
        raise SettingsError(f"margin must be a non-negative number of metres, got {margin!r}")
    blocked = np.array([bool(w.in_collision(row)) for w, row in zip(worlds, q)], dtype=bool)
    found = np.zeros(b, dtype=bool)
    moved = np.zeros(b)
    out = q.copy()
    todo = np.nonzero(blocked)[0]
    if len(todo) == 0:
        return ClearEnds(q=out, blocked=blocked, found=found, moved=moved)
    ik_task = frame_task(robot, frame, task)
    ik = P.GaussNewtonProjector(robot, ik_task, IK_SETTINGS)
    proj = P.GaussNewtonProjector(robot, P.manifold_task(ik_task, robot).with_tolerances_scaled(0.1))
    rng = np.random.default_rng(as_count(seed, "seed"))
    lo, hi = np.asarray(robot.lower, dtype=np.float64), np.asarray(robot.upper, dtype=np.float64)
    near = guesses // 2
    sigma = np.asarray(CLEAR_END_SPREADS)[np.arange(near) % len(CLEAR_END_SPREADS)]
    seeds = np.concatenate([
        np.clip(q[todo][:, None, :] + sigma[None, :, None] * rng.standard_normal((len(todo), near, robot.nq)), lo, hi),
        robot.random_configurations(len(todo) * (guesses - near), rng).reshape(len(todo), guesses - near, robot.nq),
    ], 1).reshape(-1, robot.nq)
    targets = np.repeat(robot.frame_positions(q[todo], frame), guesses, 0)
    sol = ik.solve_batch(seeds, targets={"frame_target": targets})
    pr = proj.solve_batch(sol.q, sol.q)
    good = (sol.success & pr.success).reshape(len(todo), guesses)
    cand = pr.q.reshape(len(todo), guesses, robot.nq)
    for row, i in enumerate(todo):
        c = cand[row][good[row]]
        # the walk along the self-motion: the blocked end pushed clear on its own target
        on_target = P.GaussNewtonProjector(robot, ik_task.with_targets(frame_target=targets[row * guesses]).with_tolerances_scaled(0.1))
        walked = push_clear(q[i:i + 1], worlds[i], lambda x, pe=on_target: pe.solve_batch(x, x), margin=margin,
                            steps=CLEAR_END_WALK, constraints=on_target)
        if walked is not None:
            c = np.concatenate([walked, c])
        if len(c):
            c = c[~np.asarray(worlds[i].in_collision(c), dtype=bool).reshape(len(c))]
        if len(c) == 0:
            continue
        gap = np.asarray(worlds[i].min_distance(c), dtype=np.float64).reshape(len(c))
        dist = np.linalg.norm(c - q[i], axis=1)
        pick = int(np.argmin(np.where(gap >= margin, dist, np.inf))) if (gap >= margin).any() else int(np.argmax(gap))
        out[i] = c[pick]
        found[i] = True
        moved[i] = float(dist[pick])
    return ClearEnds(q=out, blocked=blocked, found=found, moved=moved)


def aim_inputs(x_in: ArrayLike, ends: ArrayLike) -> NDArray[np.float64]:
    """The input trajectories ``x_in`` (B, K, d) bent to end at ``ends`` (B, d): each sample
    moved by the change of its end times a smooth ramp of normalised time (the quintic
    ``10 s^3 - 15 s^4 + 6 s^5``, 0 at the start and 1 at the end with zero slope and curvature at
    both), so the start stays where it was and the bend adds no velocity or acceleration at the
    ends. A problem whose end does not change is returned as it was."""
    x = np.array(as_float_array(x_in, "x_in"), dtype=np.float64, ndmin=3)
    e = np.array(as_float_array(ends, "ends"), dtype=np.float64, ndmin=2)
    if x.ndim != 3 or e.shape != (x.shape[0], x.shape[2]):
        raise ShapeError(f"ends: expected shape (B, d) = {x.shape[::2]} (one end per input of x_in, shape (B, K, d)), "
                         f"got {e.shape}")
    s = np.linspace(0.0, 1.0, x.shape[1])
    ramp = s ** 3 * (10.0 - 15.0 * s + 6.0 * s ** 2)
    return x + ramp[None, :, None] * (e - x[:, -1])[:, None, :]
