"""The conditional ensemble GAN of the GAN paper (Section III-A), in torch.

* Generator: an ensemble of ``n_net`` MLPs (2 x 200, ReLU) mapping Gaussian noise and an
  end-effector target to a configuration; each member is a stand-alone generator.
* Discriminator: an MLP (2 x 20 for Panda, 2 x 40 for Talos) fed the configuration augmented with
  its end-effector pose (and, for Talos, its centre of mass).
* Generator loss: adversarial (BCE) + end-effector target cost + joint-limit cost + the task's
  constraint costs (Panda: gripper horizontal; Talos: soles fixed, CoM in the support box).
* Adam, batch 100, 5 discriminator steps per generator step.

Beyond the paper, as :class:`GanConfig` options (defaults: the paper's): a Wasserstein critic with
gradient penalty (``loss="wgan_gp"``), a mode-seeking diversity term (``w_diversity``) and members
initialised apart on the data (``member_init="data"``); the generator's architecture, hence the
native sampler (rust/core/src/gan.rs), is the same for all of them. Their coverage:
``genplan bench coverage --variants ...`` (genplan/experiments/benchmarks/coverage.py).

A model is saved as ``<name>.safetensors`` (weights and normalisation) plus ``<name>.json`` (the
card: hyperparameters, data, seed, training time, evaluation). Never pickles.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch
from numpy.typing import ArrayLike, NDArray

from genplan import _core
from genplan import projection as P
from genplan._arrays import as_box
from genplan._config import check_fields, integer, number, one_of
from genplan._threads import torch_threads, uses_torch
from genplan.errors import ModelFileError, NonFiniteError
from genplan.robots import Robot, load
from genplan.samplers.base import (
    NATIVE_NOISE_MAX, ROBOT_HASH_KEY, STD_FLOOR, Codec, SamplerConfig, SamplerModel, check_model_fits, feature_dim,
    missing_model, models_dir, prepare_training, retrain_hint, train_command,
)
from genplan.samplers.costs import Constraints

__all__ = ["CARD_KEYS", "DISC_MIN_STD", "FORMAT", "SMALL_DIM", "EnsembleGenerator", "GanConfig", "GanModel",
           "default_config", "gradient_penalty", "load_model", "mode_seeking_loss", "spread_members", "tensor_shapes",
           "train"]

FORMAT = "genplan-gan/1"
#: the descriptive keys a GAN card may hold (besides format, config and weights_sha256)
CARD_KEYS = frozenset({"robot", "genplan_version", "data", "training", "command", "discriminator_features",
                       "evaluation", "notes", "task", "robot_source", ROBOT_HASH_KEY})
#: features whose spread in the data is below this (rad, m, or rotation-matrix entries) are
#: pinned by the constraints and withheld from the discriminator
DISC_MIN_STD = 1e-3


@dataclass(frozen=True)
class GanConfig(SamplerConfig):
    """Hyperparameters (defaults: the authors' public code; the card records every value)."""

    robot: str
    target_frame: str
    #: box the sampler draws targets from when none are given (task-space region of interest)
    target_box: tuple[tuple[float, float, float], tuple[float, float, float]]
    noise_dim: int = 10
    n_net: int = 10
    gen_hidden: tuple[int, ...] = (200, 200)
    disc_hidden: tuple[int, ...] = (20, 20)
    lr_gen: float = 5e-4
    lr_disc: float = 1e-3
    batch: int = 100
    disc_steps: int = 5
    iterations: int = 10_000
    use_discriminator: bool = True
    w_target: float = 1000.0
    w_limits: float = 1000.0
    w_constraint: float = 1000.0
    data_size: int = 25_000
    data_seed: int = 0
    seed: int = 0
    #: the task (its name) the GAN samples for; "" in cards written before tasks were files: the
    #: robot's shipped ``<robot>_ik``
    task: str = ""
    #: adversarial loss: "bce" (the paper's: binary cross-entropy, a classifier discriminator) or
    #: "wgan_gp" (Wasserstein critic with a gradient penalty on real/fake interpolates, Gulrajani
    #: et al. 2017; the paper's future work); ``disc_steps`` is the critic's steps per generator step
    loss: str = "bce"
    #: weight of the gradient penalty (``loss="wgan_gp"`` only)
    gp_weight: float = 10.0
    #: weight of the mode-seeking term (Mao et al. 2019, :func:`mode_seeking_loss`): pairs of noise
    #: for the same target whose outputs lie close are penalised, against a generator that ignores
    #: its noise; 0: off (the paper's)
    w_diversity: float = 0.0
    #: the members' initialisation: "uniform" (the paper's: PyTorch's default for every layer) or
    #: "data" (each member's output bias starts at a different configuration of the data, spread by
    #: farthest-point selection, so the members start in different regions of the manifold)
    member_init: str = "uniform"
    #: the share of the generated training rows drawn with the condition frame in the condition's
    #: box (:mod:`genplan.samplers.data`; 0 in cards written before it existed: uniform
    #: projections alone); :func:`default_config` takes :func:`genplan.samplers.data.default_in_box`
    data_in_box: float = 0.0

    #: fields a card written before they existed may lack (model_files.read_config)
    ADDED_FIELDS: ClassVar[frozenset[str]] = frozenset({"task", "loss", "gp_weight", "w_diversity", "member_init",
                                                        "data_in_box"})
    #: the values of :attr:`loss` and :attr:`member_init`
    LOSSES: ClassVar[tuple[str, ...]] = ("bce", "wgan_gp")
    MEMBER_INITS: ClassVar[tuple[str, ...]] = ("uniform", "data")

    def validate(self) -> None:
        """SettingsError naming the first field with a value training or sampling cannot use."""
        check_fields(self, {
            **dict.fromkeys(("noise_dim", "n_net", "batch", "disc_steps", "iterations", "data_size"), integer(1)),
            **dict.fromkeys(("seed", "data_seed"), integer(0)),
            **dict.fromkeys(("gen_hidden", "disc_hidden"), integer(1, each=True)),
            **dict.fromkeys(("lr_gen", "lr_disc"), number(above=0)),
            **dict.fromkeys(("w_target", "w_limits", "w_constraint", "gp_weight", "w_diversity"), number(at_least=0)),
            "data_in_box": number(at_least=0, at_most=1),
            "loss": one_of(self.LOSSES), "member_init": one_of(self.MEMBER_INITS)})
        self.check_target_box()


def default_config(robot: "str | Robot", task: "str | os.PathLike[str] | P.Task | None" = None,
                   **overrides: Any) -> GanConfig:
    """The GAN for ``robot`` (a :class:`~genplan.robots.Robot` or what :func:`genplan.load` takes)
    and ``task`` (a task with a [condition], default the robot's shipped ``<robot>_ik``), sized
    from the dimensions, with optional overrides.

    The sizes are the paper's two (its public code): a configuration of at most
    :data:`SMALL_DIM` features (an arm: Panda's 7) gets 10 noise dimensions, 10 members, a 2 x 20
    discriminator and the Panda's loss weights; a larger one (a humanoid: Talos' 34) 30 noise
    dimensions, 5 members, a 2 x 40 discriminator, the Talos learning rates and weights. The
    targets are the condition term's frame; the sampling box is the condition's ``sample_low`` /
    ``sample_high`` (else its ``low`` / ``high``). The training data draws
    :func:`~genplan.samplers.data.default_in_box` of its rows in the condition's box.
    """
    from genplan.samplers.costs import condition_term, default_task_name, sampling_box
    from genplan.samplers.data import default_in_box

    rob = robot if isinstance(robot, Robot) else load(robot)
    t = P.load_task(default_task_name(rob) if task is None else task, rob)
    cond = condition_term(t)
    frame = next((role for role, link in rob.frames.items() if role == cond.frame or link == cond.frame), cond.frame)
    box = sampling_box(t)
    common = {"robot": rob.name, "task": t.name, "target_frame": frame, "data_in_box": default_in_box(t),
              "target_box": (tuple(map(float, box[0])), tuple(map(float, box[1])))}
    if feature_dim(rob) <= SMALL_DIM:
        # The authors' relative weight of the target term: lambda = 0.1 on a Gaussian
        # log-likelihood with a 5 cm deviation, 0.1 / (2 * 0.05^2) = 20 per m^2 against the
        # adversarial term. Weighted as heavily as the other costs, the generator ignores its
        # noise and collapses onto one configuration per target and member: the targets are met
        # closely, but the samples cover the manifold worse and the planner fails in the shelf.
        cfg = GanConfig(**common, w_target=20.0, w_limits=100.0, w_constraint=100.0)  # type: ignore[arg-type]
    else:
        cfg = GanConfig(**common, noise_dim=30, n_net=5, disc_hidden=(40, 40),  # type: ignore[arg-type]
                        lr_gen=7e-4, lr_disc=1.4e-3)
    return dataclasses.replace(cfg, **overrides)


#: configurations of at most this many features get the paper's Panda-sized GAN, larger ones its
#: Talos-sized GAN (:func:`default_config`)
SMALL_DIM = 12


class EnsembleGenerator(torch.nn.Module):
    """``n_net`` independent MLPs evaluated together with batched matrix products."""

    def __init__(self, n_net: int, in_dim: int, hidden: tuple[int, ...], out_dim: int) -> None:
        super().__init__()
        dims = [in_dim, *hidden, out_dim]
        self.weights = torch.nn.ParameterList()
        self.biases = torch.nn.ParameterList()
        for a, b in zip(dims[:-1], dims[1:]):
            bound = 1.0 / math.sqrt(a)
            self.weights.append(torch.nn.Parameter(torch.empty(n_net, a, b).uniform_(-bound, bound)))
            self.biases.append(torch.nn.Parameter(torch.empty(n_net, 1, b).uniform_(-bound, bound)))
        self.n_net = n_net

    def forward(self, inputs: torch.Tensor) -> torch.Tensor:
        """inputs (n_net, B, in_dim) -> (n_net, B, out_dim)."""
        h = inputs
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            h = torch.baddbmm(b, h, w)
            if i < len(self.weights) - 1:
                h = torch.relu(h)
        return h


def gradient_penalty(critic: torch.nn.Module, real: torch.Tensor, fake: torch.Tensor, eps: torch.Tensor) -> torch.Tensor:
    """WGAN-GP's penalty (Gulrajani et al. 2017): the mean of ``(|grad critic(x)| - 1)^2`` over the
    interpolates ``x = eps * real + (1 - eps) * fake`` (``eps``: (B, 1) in [0, 1]), differentiable
    in the critic's parameters."""
    x = (eps * real + (1.0 - eps) * fake).detach().requires_grad_(True)
    (grad,) = torch.autograd.grad(critic(x).sum(), x, create_graph=True)
    return ((grad.norm(dim=-1) - 1.0) ** 2).mean()


def mode_seeking_loss(out_a: torch.Tensor, out_b: torch.Tensor, z_a: torch.Tensor, z_b: torch.Tensor,
                      eps: float = 1e-5) -> torch.Tensor:
    """The mode-seeking regulariser (Mao et al. 2019, MSGAN) of an ensemble: per member, the ratio
    of the mean distance between outputs to that between their noises, for pairs (``*_a``,
    ``*_b``: (n_net, B, .)) made with the same target; the loss is the mean over members of
    ``1 / (ratio + eps)``, large when a member maps different noise to the same output."""
    ratio = (out_a - out_b).abs().mean((1, 2)) / (z_a - z_b).abs().mean((1, 2))
    return (1.0 / (ratio + eps)).mean()


def spread_members(feats: torch.Tensor, n_net: int, rng: np.random.Generator, pool: int = 2000) -> torch.Tensor:
    """``n_net`` rows of ``feats`` (N, d) far apart: farthest-point selection from a random row
    over a random pool of at most ``pool`` rows (``member_init="data"``)."""
    cand = feats[torch.from_numpy(rng.choice(len(feats), size=min(pool, len(feats)), replace=False))]
    picked = [int(rng.integers(len(cand)))]
    d = ((cand - cand[picked[0]]) ** 2).sum(-1)
    for _ in range(1, n_net):
        picked.append(int(torch.argmax(d)))
        d = torch.minimum(d, ((cand - cand[picked[-1]]) ** 2).sum(-1))
    return cand[picked]


def _mlp(dims: list[int]) -> torch.nn.Sequential:
    layers: list[torch.nn.Module] = []
    for i, (a, b) in enumerate(zip(dims[:-1], dims[1:])):
        layers.append(torch.nn.Linear(a, b))
        if i < len(dims) - 2:
            layers.append(torch.nn.ReLU())
    return torch.nn.Sequential(*layers)


@dataclass
class GanModel(SamplerModel):
    """A trained generator with its codec: samples configurations given targets."""

    config: GanConfig
    robot: Robot
    generator: EnsembleGenerator
    codec: Codec
    card: dict[str, Any] = field(default_factory=dict)
    KIND: ClassVar[str] = "GAN"

    @torch.no_grad()
    def generate(self, z: NDArray[np.float64], targets: NDArray[np.float64], offset: int = 0) -> NDArray[np.float64]:
        """Every member's configurations for noise ``z`` (n_net, n, noise_dim) and checked targets
        (n, 3): (n_net, n, nq), finite, else NonFiniteError naming the first target row (counted
        from ``offset``, for callers that generate in chunks)."""
        x = torch.tensor(targets, dtype=torch.float32).expand(self.config.n_net, len(targets), 3)
        q = self.codec.decode(self.generator(torch.cat([torch.tensor(z, dtype=torch.float32), x], -1))).double().numpy()
        bad = ~np.isfinite(q).all(-1)
        if bad.any():
            m, i = (int(v) for v in np.argwhere(bad)[0])
            raise NonFiniteError(f"GAN sample for target row {offset + i} {targets[i].tolist()} is not finite "
                                 f"(member {m}): the generator overflows there")
        return q

    @torch.no_grad()
    def sample_members(self, targets: ArrayLike, rng: np.random.Generator | int | None = None, *,
                       threads: int | None = None) -> NDArray[np.float64]:
        """One configuration per target from every ensemble member: (n_net, n, nq).

        ``targets``: finite positions (n, 3) inside :meth:`target_limits` (else an error naming
        the row); a sample that comes out non-finite raises NonFiniteError naming its target row.
        ``threads``: torch threads for the call (default: genplan's choice, see genplan._threads).
        """
        t = self.check_targets(targets)
        rng = np.random.default_rng(rng)
        with torch_threads("small", threads):
            return self.generate(rng.standard_normal((self.config.n_net, len(t), self.config.noise_dim)), t)

    def sample(self, targets: ArrayLike, rng: np.random.Generator | int | None = None, *,
               threads: int | None = None) -> NDArray[np.float64]:
        """One configuration per target, each from a member chosen at random: (n, nq). Targets and
        output are checked as in :meth:`sample_members`."""
        rng = np.random.default_rng(rng)
        allq = self.sample_members(targets, rng, threads=threads)
        pick = rng.integers(0, self.config.n_net, size=allq.shape[1])
        return allq[pick, np.arange(allq.shape[1])]

    def feature_bound(self, box: Any = None, noise_max: float = NATIVE_NOISE_MAX) -> float:
        """An upper bound on ``|feature|`` of any sample for targets in ``box`` (default: the
        target box) and noise in ``[-noise_max, noise_max]`` (interval arithmetic through the
        layers, float64); inf when the bound overflows."""
        b = as_box(self.config.target_box if box is None else box)
        nd = self.config.noise_dim
        lo = np.concatenate([np.full(nd, -noise_max), b[0]])[None, None, :]
        hi = np.concatenate([np.full(nd, noise_max), b[1]])[None, None, :]
        last = len(self.generator.weights) - 1
        with np.errstate(over="ignore", invalid="ignore"):
            for i, (w, bias) in enumerate(zip(self.generator.weights, self.generator.biases)):
                wd, bd = w.detach().double().numpy(), bias.detach().double().numpy()
                wp, wn = np.maximum(wd, 0.0), np.minimum(wd, 0.0)
                lo, hi = lo @ wp + hi @ wn + bd, hi @ wp + lo @ wn + bd
                if i < last:
                    lo, hi = np.maximum(lo, 0.0), np.maximum(hi, 0.0)
            mean, std = self.codec.mean.double().numpy(), self.codec.std.double().numpy()
            bound = np.maximum(np.abs(lo), np.abs(hi)) * np.abs(std) + np.abs(mean)
        return float(bound.max()) if np.all(np.isfinite(bound)) else math.inf

    def native_sampler(self, box: Any = None, seed: int = 0) -> _core.GanSampler:
        """The generator run natively (Rust, no GIL): ``sample(n)`` draws targets uniformly in
        ``box`` (default: the model's target box), a member at random and Gaussian noise, like
        :meth:`sample`. The planner uses it without calling back into Python.

        Its samples are finite: ``box`` must lie inside :meth:`target_limits`, and the weights
        must bound the output over that box (:meth:`feature_bound`), else an error before any
        sampling.
        """
        b = as_box(self.config.target_box if box is None else box)
        self.check_targets(b, "box")
        if not math.isfinite(self.feature_bound(b)):
            raise NonFiniteError(f"GAN generator: its output over the box {b.tolist()} is not bounded in float64 "
                                 "(non-finite or huge weights or codec): its samples cannot be vouched for")
        return _core.GanSampler(
            self.config.noise_dim,
            [w.detach().double().numpy() for w in self.generator.weights],
            [bias.detach().double().numpy() for bias in self.generator.biases],
            self.codec.mean.double().tolist(),
            self.codec.std.double().tolist(),
            self.robot.floating_base,
            b[0].tolist(),
            b[1].tolist(),
            int(seed),
            continuous=self.codec.continuous,
        )

    def draw_native(self, native: Any, targets: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.float64]:
        members = rng.integers(0, self.config.n_net, size=len(targets)).tolist()
        noise = np.clip(rng.standard_normal((len(targets), self.config.noise_dim)), -NATIVE_NOISE_MAX, NATIVE_NOISE_MAX)
        return native.generate(members, noise, targets)  # type: ignore[no-any-return]

    def save(self, path: str | Path) -> tuple[Path, Path]:
        """Write ``path`` (.safetensors) and its card (.json beside it)."""
        from genplan.model_files import write_model

        tensors = {f"generator.weight.{i}": w for i, w in enumerate(self.generator.weights)}
        tensors.update({f"generator.bias.{i}": b for i, b in enumerate(self.generator.biases)})
        tensors["codec.mean"] = self.codec.mean
        tensors["codec.std"] = self.codec.std
        return write_model(path, tensors, {"format": FORMAT, "robot": self.config.robot}, self.card_to_write(),
                           self.config, CARD_KEYS, "GAN")


def tensor_shapes(cfg: GanConfig, robot: Robot) -> dict[str, tuple[int, ...]]:
    """The tensors of a GAN file for ``cfg`` and ``robot``: name -> shape."""
    dim = feature_dim(robot)
    dims = [cfg.noise_dim + 3, *cfg.gen_hidden, dim]
    shapes: dict[str, tuple[int, ...]] = {}
    for i, (a, b) in enumerate(zip(dims[:-1], dims[1:])):
        shapes[f"generator.weight.{i}"] = (cfg.n_net, a, b)
        shapes[f"generator.bias.{i}"] = (cfg.n_net, 1, b)
    shapes["codec.mean"] = shapes["codec.std"] = (dim,)
    return shapes


def load_model(robot: str | Robot, path: str | Path | None = None,
               task: "str | os.PathLike[str] | P.Task | None" = None) -> GanModel:
    """Load a GAN (default: the shipped ``models/<robot>_gan.safetensors``; a GAN or a flow file:
    :func:`genplan.samplers.loading.load_sampler_model`).

    ``task`` (a :class:`~genplan.projection.Task`, a shipped task's name or a task file): the
    task the caller samples for; a GAN trained for another task is refused naming both (by name,
    and by its terms: those the card records, else the shipped task's of that name). A missing
    file raises FileNotFoundError naming the command that trains it; a file that cannot be vouched for (see
    :mod:`genplan.model_files`: no or another weights sha256, a bad card or config, NaN weights,
    missing, extra or misshapen tensors, a GAN for another robot or target frame, a non-positive
    codec scale) raises :class:`~genplan.errors.ModelFileError` naming the file and the problem,
    before any sampling.
    """
    from genplan.model_files import check_tensors, read_config, read_model

    rob = robot if isinstance(robot, Robot) else load(robot)
    if path is None:
        path = models_dir() / f"{rob.name}_gan.safetensors"
        if not path.is_file():  # no shipped GAN for this robot: say what to give, not the package's path
            shipped = tuple(sorted(p.name.removesuffix("_gan.safetensors") for p in models_dir().glob("*_gan.safetensors")))
            raise missing_model(rob, "GAN", "gan", shipped, task)
    path = Path(path)
    card, tensors = read_model(path, FORMAT, "GAN", retrain_hint(rob, path, task=task), CARD_KEYS)
    cfg = read_config(card, path, "GAN", GanConfig)
    check_model_fits(path, "GAN", cfg, card, rob, task)
    check_tensors(tensors, tensor_shapes(cfg, rob), path, "GAN")
    if not bool((tensors["codec.std"] > 0).all()):
        raise ModelFileError(f"GAN model file {path} is corrupt: tensor codec.std holds a scale <= 0")
    codec = Codec(rob, tensors["codec.mean"].double().numpy(), tensors["codec.std"].double().numpy())
    gen = EnsembleGenerator(cfg.n_net, cfg.noise_dim + 3, cfg.gen_hidden, codec.dim)
    with torch.no_grad():
        for i in range(len(gen.weights)):
            gen.weights[i].copy_(tensors[f"generator.weight.{i}"])
            gen.biases[i].copy_(tensors[f"generator.bias.{i}"])
    gen.eval()
    return GanModel(cfg, rob, gen, codec, card)


@uses_torch("training")
def train(cfg: GanConfig, data: NDArray[np.float64] | None = None, progress: bool = True,
          log_every: int = 500, *, robot: Robot | None = None, task: "P.Task | None" = None,
          threads: int | None = None) -> GanModel:
    """Train a GAN; returns the model with a card holding the loss log and training time.

    ``robot``: the robot (default: ``genplan.load(cfg.robot)``, a preset); ``task``: the task
    (default: ``cfg.task_name``, a shipped task). ``threads``: torch threads for the call
    (default: genplan's choice for training, see genplan._threads; the card records the count
    used)."""
    # a saturated discriminator drives activations into denormal floats, which are ~4x slower:
    # flushed while training, restored after (torch's default), also on an error
    torch.set_flush_denormal(True)
    try:
        return _train(cfg, data, progress, log_every, robot, task)
    finally:
        torch.set_flush_denormal(False)


def _train(cfg: GanConfig, data: NDArray[np.float64] | None, progress: bool, log_every: int,
           robot: Robot | None, task: "P.Task | None") -> GanModel:
    """:func:`train`'s work."""
    from genplan.samplers.data import box_share, data_description

    prep = prepare_training(cfg, data, progress, robot, task, "GAN")
    robot, task, data, data_source, t_data, feats, codec = (prep.robot, prep.task, prep.data, prep.data_source,
                                                            prep.data_seconds, prep.features, prep.codec)
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    cons = Constraints(robot, cfg, task)
    with torch.no_grad():
        real_all = cons.evaluate(torch.tensor(data, dtype=torch.float32), constraint=False)
        real_targets = real_all["ee_pos"].clone()
        real_aug = real_all["augment"].clone()
    real_feats = (torch.tensor(feats, dtype=torch.float32) - codec.mean) / codec.std
    aug_mean, aug_std = real_aug.mean(0), real_aug.std(0).clamp_min(STD_FLOOR)
    real_disc = torch.cat([real_feats, (real_aug - aug_mean) / aug_std], -1)
    # The discriminator sees only the features that vary in the data. A feature the constraints
    # pin (the Panda hand's vertical axis, Talos' left arm) carries no distribution information:
    # its constraint cost already drives it; fed to the discriminator, the generator's tiny
    # residual on it makes real and fake perfectly separable, and the adversarial gradient then
    # only tightens the constraint instead of spreading the samples (mode collapse).
    disc_keep = torch.cat([torch.tensor(feats.std(0) > DISC_MIN_STD), real_aug.std(0) > DISC_MIN_STD])
    real_disc = real_disc[:, disc_keep]

    gen = EnsembleGenerator(cfg.n_net, cfg.noise_dim + 3, cfg.gen_hidden, codec.dim)
    if cfg.member_init == "data":
        with torch.no_grad():
            gen.biases[-1].copy_(spread_members(real_feats, cfg.n_net, rng)[:, None, :])
    disc = _mlp([real_disc.shape[1], *cfg.disc_hidden, 1])
    wgan = cfg.loss == "wgan_gp"
    betas = (0.5, 0.9) if wgan else (0.9, 0.999)  # WGAN-GP's usual Adam momentum; else torch's default
    # fused: Adam's update of all of a network's parameters in one kernel (the same update; the
    # discriminator's six small tensors took more time in per-tensor operations than in arithmetic);
    # torch has the fused CPU kernel from 2.4 on
    fused = {"fused": True} if torch.torch_version.TorchVersion(torch.__version__) >= "2.4" else {}
    opt_g = torch.optim.Adam(gen.parameters(), lr=cfg.lr_gen, betas=betas, **fused)
    opt_d = torch.optim.Adam(disc.parameters(), lr=cfg.lr_disc, betas=betas, **fused)
    bce = torch.nn.BCEWithLogitsLoss()
    n, b, k = len(data), cfg.batch, cfg.n_net
    pairs = cfg.w_diversity > 0 and b >= 2

    def fake_batch(paired: bool = False) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(outputs, targets, noise), each (k, b, .); ``paired``: the second half of the batch
        repeats the first half's targets (with other noise), for the mode-seeking term."""
        idx = torch.from_numpy(rng.integers(0, n, size=(k, b // 2 if paired else b)))
        if paired:
            idx = torch.cat([idx, idx, idx[:, : b % 2]], 1)
        x = real_targets[idx]  # targets: end-effector positions of data samples
        z = torch.randn(k, b, cfg.noise_dim)
        return gen(torch.cat([z, x], -1)), x, z

    def disc_input(out: torch.Tensor, aug: torch.Tensor) -> torch.Tensor:
        return torch.cat([out.reshape(-1, codec.dim), (aug - aug_mean) / aug_std], -1)[:, disc_keep]

    log: list[dict[str, float]] = []
    iterator = range(cfg.iterations)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(iterator, desc=f"train gan ({cfg.robot})", unit="it")
        iterator = bar
    t0 = time.perf_counter()
    load_start = os.getloadavg()[0]  # the machine's load, so a training time can be judged
    ones_b, zeros_b = torch.ones(b, 1), torch.zeros(b, 1)
    for it in iterator:
        d_loss = torch.tensor(0.0)
        if cfg.use_discriminator:
            # the generator does not change during the discriminator steps: one forward pass
            # (and one kinematics pass) serves them all, each a batch of b of its k * b samples
            with torch.no_grad():
                out, _, _ = fake_batch()
                pick = torch.from_numpy(rng.choice(k * b, size=cfg.disc_steps * b, replace=cfg.disc_steps > k))
                out = out.reshape(k * b, -1)[pick]
                fakes = disc_input(out, cons.evaluate(codec.decode(out), constraint=False)["augment"])
            for step in range(cfg.disc_steps):
                fake_in = fakes[step * b:(step + 1) * b]
                real_in = real_disc[torch.from_numpy(rng.integers(0, n, size=b))]
                if wgan:
                    d_loss = (disc(fake_in).mean() - disc(real_in).mean()
                              + cfg.gp_weight * gradient_penalty(disc, real_in, fake_in, torch.rand(b, 1)))
                else:  # real and fake rows through the network in one pass
                    scores = disc(torch.cat([real_in, fake_in]))
                    d_loss = bce(scores[:b], ones_b) + bce(scores[b:], zeros_b)
                opt_d.zero_grad()
                d_loss.backward()
                opt_d.step()
        out, x, z = fake_batch(pairs)
        q = codec.decode(out.reshape(k * b, -1))
        ev = cons.evaluate(q)
        c_target = ((ev["ee_pos"] - x.reshape(k * b, 3)) ** 2).sum(-1).mean()
        c_limits = ev["limits"].mean()
        c_cons = ev["constraint"].mean()
        g_loss = cfg.w_target * c_target + cfg.w_limits * c_limits + cfg.w_constraint * c_cons
        adv = torch.tensor(0.0)
        if cfg.use_discriminator:
            scores = disc(disc_input(out, ev["augment"]))
            adv = -scores.mean() if wgan else bce(scores, torch.ones(k * b, 1))
            g_loss = g_loss + adv
        div = torch.tensor(0.0)
        if pairs:
            h = b // 2
            div = mode_seeking_loss(out[:, :h], out[:, h:2 * h], z[:, :h], z[:, h:2 * h])
            g_loss = g_loss + cfg.w_diversity * div
        opt_g.zero_grad()
        g_loss.backward()
        opt_g.step()
        if it % log_every == 0 or it == cfg.iterations - 1:
            entry = {"iteration": it, "d_loss": float(d_loss.detach()), "adversarial": float(adv.detach()),
                     "target_m2": float(c_target.detach()), "limits": float(c_limits.detach()), "constraint": float(c_cons.detach()),
                     "mode_seeking": float(div.detach())}
            log.append(entry)
            if bar is not None:
                bar.set_postfix(d=f"{entry['d_loss']:.3f}", tgt=f"{math.sqrt(entry['target_m2']) * 100:.1f}cm",
                                cons=f"{entry['constraint']:.1e}")
    train_s = time.perf_counter() - t0
    if not all(bool(torch.isfinite(w).all()) for w in gen.parameters()):
        raise FloatingPointError(f"GAN training diverged: the generator's weights hold NaN or inf after "
                                 f"{cfg.iterations} iterations")
    gen.eval()
    card = {
        "robot": cfg.robot,
        "genplan_version": _core.__version__,
        "data": {"size": int(len(data)), "seed": cfg.data_seed, "seconds": t_data, "from": data_source,
                 "source": data_description(cfg.data_in_box if data_source != "given" else None),
                 "in_condition_box": box_share(robot, task, data)},
        "training": {"seconds": train_s, "iterations": cfg.iterations, "seed": cfg.seed,
                     "load_average_1min_start_end": [load_start, os.getloadavg()[0]],
                     "threads": torch.get_num_threads(), "torch": torch.__version__, "loss_log": log},
        "command": train_command(robot, None if cfg.task_name == f"{robot.name}_ik" else cfg.task_name, cfg.seed),
        "task": task.to_dict(),
        "robot_source": str(robot.source) if robot.source is not None else robot.description.get("urdf"),
        "discriminator_features": {"used": int(disc_keep.sum()), "withheld_pinned": int((~disc_keep).sum())},
    }
    return GanModel(cfg, robot, gen, codec, card)


