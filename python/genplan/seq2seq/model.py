"""The seq2seq trajectory model (the seq2seq paper's Sections 2.2 and 4.2), for any family.

* **encoder**: LSTM (``layers`` x ``hidden``) over the input's features
  ``(x - relative * x[0] - in_offset) * in_scale`` at every ``encoder_stride``-th sample (and the
  last).
* **latent vector** ``z`` (``hidden * layers`` values, 128 in the paper): the final hidden states
  of the encoder's layers, concatenated. The encoder's cell states are not part of z, so
  everything the decoder does is a function of z (and the start), which latent adjustment needs.
* **decoder**: LSTM whose initial hidden state is z (layer by layer) and initial cell state a
  learned linear function of z; its input at each step is a clock from 0 to 1 (and, with
  ``condition_on_start``, the start's features); no autoregressive feedback, so the whole
  sequence runs in one fused LSTM call. A linear head emits ``decoder_stride`` samples per
  LSTM step of the output (scaled by ``out_scale``) and their log-variances (softly bounded).
* **plant** (:mod:`genplan.seq2seq.plants`): the output to the trajectory, from the input's
  start.
* **mirror symmetry** (optional): inputs whose net change along ``mirror_axis`` is negative
  are mirrored before the encoder and the decoder's output mirrored back; a problem's mirror
  sign comes from its input and stays fixed while its z is adjusted.

Loss (eq. 4, 5), per trajectory and divided by K: ``-sum_k log N(D x_in[k] | D x_out[k], D S[k]
D^T) + alpha * penalty``, ``D = diag(nll_scale)``, ``S[k] = var_p[k] + var_floor``, with the
beta-NLL weighting and the alpha ramp of :class:`~genplan.seq2seq.config.Seq2SeqConfig`.

Files: ``<name>.safetensors`` (weights) + ``<name>.json`` (card: config, data, seed, training
time, loss curve, evaluation, weights sha256). Never pickles.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import ArrayLike, NDArray
from torch import Tensor, nn

from genplan._arrays import as_float_array
from genplan._threads import uses_torch
from genplan.errors import GenplanError, NonFiniteError, ShapeError
from genplan.seq2seq.config import Seq2SeqConfig
from genplan.seq2seq.plants import Plant, Rollout, plant

__all__ = ["FORMAT", "CARD_KEYS", "MAX_ABS", "Seq2SeqNet", "Seq2SeqModel", "nll", "squared_error", "load_model",
           "check_trajectories", "first_nonfinite", "Penalty"]

FORMAT = "genplan-seq2seq-v1"
#: the descriptive keys a seq2seq card may hold (besides format, config and weights_sha256)
CARD_KEYS = frozenset({"description", "deviations_from_paper", "retrain", "command", "data", "training",
                       "evaluation", "notes", "robot", "task", "scene", "space"})
#: largest |value| accepted in a trajectory (m, rad): the model computes in float32, which beyond
#: 1e4 no longer resolves a millimetre (and overflows to inf beyond 3.4e38)
MAX_ABS = 1e4

#: a training penalty: (rollout, margin) -> one value per trajectory (B,)
Penalty = Callable[[Rollout, float], Tensor]


class Seq2SeqNet(nn.Module):
    """Encoder -> z -> decoder -> outputs (and log-variances with the NLL loss): LSTMs (the
    paper's) or multilayer perceptrons (:class:`~genplan.seq2seq.config.Seq2SeqConfig`)."""

    def __init__(self, cfg: Seq2SeqConfig) -> None:
        super().__init__()
        cfg.validate()
        self.cfg = cfg
        d = cfg.dim
        self.outputs = 2 * d if cfg.loss == "nll" else d
        if cfg.network == "lstm":
            self.encoder = nn.LSTM(d, cfg.hidden, cfg.layers, batch_first=True)
            self.bridge = nn.Linear(cfg.latent_dim, cfg.latent_dim)
            self.decoder = nn.LSTM(cfg.decoder_inputs, cfg.hidden, cfg.layers, batch_first=True)
            self.head = nn.Linear(cfg.hidden, self.outputs * cfg.decoder_stride)
        else:
            n_in = len(cfg.encoder_indices()) * d
            self.encoder = _mlp(n_in, cfg.hidden, cfg.layers, cfg.latent_dim)
            self.decoder = _mlp(cfg.latent_dim + (d if cfg.condition_on_start else 0), cfg.hidden, cfg.layers - 1,
                                cfg.hidden)
            self.head = nn.Linear(cfg.hidden, self.outputs * cfg.K)
        with torch.no_grad():
            self.head.weight.mul_(0.1)
            self.head.bias.zero_()
        f32 = torch.float32
        self.register_buffer("in_scale", torch.tensor(cfg.in_scale, dtype=f32), persistent=False)
        self.register_buffer("in_offset", torch.tensor(cfg.in_offset, dtype=f32), persistent=False)
        self.register_buffer("relative", torch.tensor([float(r) for r in cfg.relative], dtype=f32), persistent=False)
        self.register_buffer("out_scale", torch.tensor(cfg.out_scale, dtype=f32), persistent=False)
        self.register_buffer("enc_idx", torch.tensor(cfg.encoder_indices()), persistent=False)
        n_dec = cfg.K // cfg.decoder_stride
        clock = torch.arange(n_dec, dtype=f32) / max(1, n_dec - 1)
        self.register_buffer("clock", clock[None, :, None], persistent=False)

    def features(self, x: Tensor) -> Tensor:
        """Encoder inputs at the read samples: ``(x - relative * x[0] - in_offset) * in_scale``."""
        rel = x - x[:, :1] * self.relative
        if bool(self.in_offset.any()):
            rel = rel - self.in_offset
        return rel[:, self.enc_idx] * self.in_scale

    def start_features(self, x0: Tensor) -> Tensor:
        """The decoder's conditioning on the start positions (B, d): their absolute features."""
        return (x0 - self.in_offset) * self.in_scale

    def encode(self, x: Tensor) -> Tensor:
        """(B, K, d) trajectories -> (B, latent_dim) latent vectors."""
        f = self.features(x)
        if self.cfg.network == "mlp":
            out: Tensor = self.encoder(f.reshape(x.shape[0], -1))
            return out
        _, (h, _) = self.encoder(f)
        return h.transpose(0, 1).reshape(x.shape[0], -1)

    def decode(self, z: Tensor, x0: Tensor | None = None) -> tuple[Tensor, Tensor | None]:
        """(B, latent_dim) latent vectors (and (B, d) start positions when the decoder is
        conditioned on them) -> outputs (B, K, d) and their variances (B, K, d), None with the
        squared-error loss."""
        cfg = self.cfg
        if z.ndim != 2 or z.shape[1] != cfg.latent_dim:
            raise ShapeError(f"z must have shape (batch, {cfg.latent_dim}), got {tuple(z.shape)}")
        b = z.shape[0]
        if cfg.condition_on_start and (x0 is None or x0.shape != (b, cfg.dim)):
            raise ShapeError(f"the decoder is conditioned on the start: x0 must have shape ({b}, {cfg.dim})")
        if cfg.network == "mlp":
            inputs = torch.cat([z, self.start_features(x0)], -1) if cfg.condition_on_start else z
            y = self.head(self.decoder(inputs)).reshape(b, cfg.K, self.outputs)
        else:
            h0 = z.reshape(b, cfg.layers, cfg.hidden).transpose(0, 1).contiguous()
            c0 = self.bridge(z).reshape(b, cfg.layers, cfg.hidden).transpose(0, 1).contiguous()
            inputs = self.clock.expand(b, -1, 1)
            if cfg.condition_on_start:
                start = self.start_features(x0)[:, None, :].expand(b, inputs.shape[1], cfg.dim)
                inputs = torch.cat([inputs, start], -1)
            out, _ = self.decoder(inputs, (h0, c0))
            y = self.head(out).reshape(b, cfg.K, self.outputs)
        u = y[..., :cfg.dim] * self.out_scale
        if cfg.loss != "nll":
            return u, None
        lo, hi = cfg.logvar_min, cfg.logvar_max
        # a zero head output gives log-variance 0, i.e. a standard deviation of one out_scale
        frac = -lo / (hi - lo)
        logvar = lo + (hi - lo) * torch.sigmoid(y[..., cfg.dim:] + math.log(frac / (1.0 - frac)))
        var_u = torch.exp(logvar) * self.out_scale ** 2
        return u, var_u


def _mlp(n_in: int, hidden: int, layers: int, n_out: int) -> nn.Sequential:
    """``layers`` hidden layers of ``hidden`` GELU units, then a linear map to ``n_out``."""
    mods: list[nn.Module] = []
    width = n_in
    for _ in range(max(layers, 0)):
        mods += [nn.Linear(width, hidden), nn.GELU()]
        width = hidden
    mods.append(nn.Linear(width, n_out))
    return nn.Sequential(*mods)


def mirror(a: Tensor, s: Tensor, signs: Tensor) -> Tensor:
    """Each batch element's last axis times ``signs`` where its sign ``s`` is -1 (unchanged where
    +1): ``(y, z, theta) -> (s y, z, s theta)`` for the spatula's signs (-1, 1, -1)."""
    m = torch.where(signs < 0, s[:, None], torch.ones_like(s)[:, None])
    return a * m.reshape((a.shape[0],) + (1,) * (a.ndim - 2) + (a.shape[-1],))


def nll(x_in: Tensor, out: Rollout, var_floor: float, d: Tensor, beta: float = 0.0, var_ref: float = 1.0) -> Tensor:
    """eq. 5 per trajectory (B,): -sum_k log N(D x_in | D x_out, D S D^T).

    ``beta`` > 0 weights each term by ``(S_D / var_ref) ** beta`` without gradient through the
    weight (beta-NLL; beta = 0 is the plain NLL).
    """
    assert out.var_p is not None
    var = (out.var_p + var_floor) * d ** 2
    err = (x_in - out.p) * d
    per = 0.5 * (torch.log(2.0 * math.pi * var) + err ** 2 / var)
    if beta > 0.0:
        per = per * (var.detach() / var_ref) ** beta
    return per.sum((-1, -2))


def squared_error(x_in: Tensor, out: Rollout, scale: Tensor) -> Tensor:
    """The reconstruction's squared error per trajectory (B,): ``sum_k ||scale (x_in - x_out)||^2``."""
    return (((x_in - out.p) * scale) ** 2).sum((-1, -2))


@dataclass
class Seq2SeqModel:
    """A seq2seq model with its card: encode, decode, deform, the training loss, save."""

    config: Seq2SeqConfig
    net: Seq2SeqNet
    card: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.plant: Plant = plant(self.config.plant, self.config.dt)
        signs = self.config.mirror
        self._signs = None if signs is None else torch.tensor(signs, dtype=torch.float32)

    # ----------------------------------------------------------------- torch API
    def chirality(self, x: Tensor) -> Tensor:
        """The mirror sign of each input: -1 where its net change along ``mirror_axis`` is
        negative (all +1 without a mirror symmetry)."""
        if self._signs is None:
            return torch.ones(x.shape[0], dtype=x.dtype)
        a = self.config.mirror_axis
        return torch.where(x[:, -1, a] >= x[:, 0, a], 1.0, -1.0).to(x.dtype)

    def mirror(self, a: Tensor, s: Tensor) -> Tensor:
        """``a`` (B, ..., d) mirrored where ``s`` is -1 (unchanged without a symmetry)."""
        return a if self._signs is None else mirror(a, s, self._signs)

    def start(self, x: Tensor) -> Tensor:
        """The start positions (B, d) of trajectories (B, K, d): where their decodings start."""
        return x[:, 0, :]

    def encode(self, x: Tensor, s: Tensor | None = None) -> Tensor:
        """(B, K, d) input trajectories -> (B, latent_dim) latent vectors (of the mirrored input
        where s = -1)."""
        s = self.chirality(x) if s is None else s
        return self.net.encode(self.mirror(x, s))

    def decode(self, z: Tensor, x0: Tensor, s: Tensor | None = None) -> Rollout:
        """Decoder and plant: latent vectors, start positions (B, d) (or, for the integrator
        plants, start states (B, 2d): positions and velocities) and mirror signs to trajectories."""
        d = self.config.dim
        pos = x0[:, :d]
        if s is None:
            s = torch.ones(z.shape[0], dtype=z.dtype)
        u, var_u = self.net.decode(z, self.mirror(pos, s) if self.config.condition_on_start else None)
        u = self.mirror(u, s)
        return self.plant.rollout(u, var_u, x0)

    def forward(self, x: Tensor) -> tuple[Tensor, Rollout]:
        """The deformation: (B, K, d) inputs to (z, output rollout)."""
        s = self.chirality(x)
        z = self.encode(x, s)
        return z, self.decode(z, self.start(x), s)

    def loss(self, x: Tensor, penalty: Penalty | None, beta: float = 0.0,
             alpha: float | None = None) -> tuple[Tensor, dict[str, float]]:
        """Training loss (eq. 4) averaged over the batch and divided by K, and its parts.

        ``penalty(rollout, margin)``: the constraint penalty per trajectory (None: none);
        ``beta`` > 0: the beta-NLL weighting; ``alpha``: default the config's final value. The
        penalty is evaluated with the config's ``penalty_margin``; the reported ``penalty`` is
        without the margin; the reconstruction part is reported under the loss's name (``nll`` or
        ``mse``, per sample).
        """
        _, out = self.forward(x)
        cfg = self.config
        a = cfg.alpha if alpha is None else alpha
        d = torch.tensor(cfg.nll_scale, dtype=x.dtype)
        if cfg.loss == "nll":
            l1 = nll(x, out, cfg.var_floor, d, beta=beta, var_ref=cfg.nll_var_ref)
        else:
            l1 = squared_error(x, out, d / self.net.out_scale)
        k = x.shape[1]
        if penalty is None:
            total = l1.mean() / k
            reported = 0.0
        else:
            l2m = penalty(out, cfg.penalty_margin)
            with torch.no_grad():
                reported = float(penalty(_detached(out), 0.0).mean())
            total = (l1 + a * l2m).mean() / k
        with torch.no_grad():
            plain = l1.detach() if (beta == 0.0 or cfg.loss != "nll") else nll(x, out, cfg.var_floor, d)
        return total, {cfg.loss: float(plain.mean()) / k, "penalty": reported}

    # ----------------------------------------------------------------- numpy API
    @uses_torch("small")
    @torch.no_grad()
    def deform(self, x_in: ArrayLike, *, threads: int | None = None) -> dict[str, NDArray[np.float64]]:
        """Deform input trajectories (K, d) or (B, K, d): returns p, v, u, var_p, z (and phi for
        the spatula plant).

        The inputs are checked (:func:`check_trajectories`); an output that is not finite raises
        FloatingPointError naming the problem. ``threads``: torch threads for the call (default:
        genplan's choice, see genplan._threads)."""
        cfg = self.config
        x = check_trajectories(x_in, cfg.K, cfg.dim)
        names = ("p", "v", "u", "var_p") + (("phi",) if cfg.plant == "spatula" else ())
        if len(x) == 0:  # an empty batch: torch's LSTMs do not take one
            empty = {k: np.zeros((0, cfg.K) + (() if k == "phi" else (cfg.dim,))) for k in names}
            return {**empty, "z": np.zeros((0, cfg.latent_dim))}
        z, out = self.forward(torch.as_tensor(x, dtype=torch.float32))
        bad = first_nonfinite(out)
        if bad is not None:
            raise FloatingPointError(f"the deformation of x_in[{bad}] is not finite (the model overflows there)")
        res = {k: getattr(out, k) for k in names}
        res["z"] = z
        return {k: v.double().numpy() for k, v in res.items() if v is not None}

    # ----------------------------------------------------------------- files
    def save(self, path: str | Path) -> tuple[Path, Path]:
        """Write ``path`` (.safetensors) and its card (.json beside it)."""
        from genplan.model_files import write_model

        return write_model(path, dict(self.net.state_dict()), {"format": FORMAT}, self.card, self.config,
                           CARD_KEYS, "seq2seq")


def _detached(r: Rollout) -> Rollout:
    """``r`` with every tensor detached (the same type: a plant's rollout may carry more)."""
    import copy

    out = copy.copy(r)
    for k, v in vars(r).items():
        if isinstance(v, Tensor):
            setattr(out, k, v.detach())
    return out


def first_nonfinite(r: Rollout) -> int | None:
    """The first problem (batch row) whose trajectory (p, v, u) holds NaN or inf, or None."""
    bad = torch.zeros(r.batch, dtype=torch.bool)
    for t in (r.p, r.v, r.u):
        bad |= ~torch.isfinite(t.detach().reshape(r.batch, -1)).all(1)
    return int(bad.nonzero()[0, 0]) if bool(bad.any()) else None


def check_trajectories(x_in: ArrayLike, k: int, dim: int, name: str = "x_in") -> NDArray[np.float64]:
    """Validate input trajectories: (K, d) or (B, K, d), finite, within :data:`MAX_ABS`. Returns
    (B, K, d) float64; B may be 0 (an empty batch)."""
    if isinstance(x_in, Tensor):
        x_in = x_in.detach().cpu().numpy()
    x = as_float_array(x_in, name)
    if x.ndim == 2:
        x = x[None]
    if x.ndim != 3 or x.shape[1:] != (k, dim):
        raise ShapeError(f"{name} must be trajectories of shape ({k}, {dim}) or (batch, {k}, {dim}), "
                         f"got shape {np.shape(x_in)}")
    if not np.all(np.isfinite(x)):
        bad = np.argwhere(~np.isfinite(x))[0]
        raise NonFiniteError(f"{name} contains NaN or inf (first at index {tuple(int(i) for i in bad)})")
    check_magnitude(x, name)
    return x


def check_magnitude(x: NDArray[np.float64], name: str) -> None:
    """A GenplanError naming the first element of ``x`` beyond :data:`MAX_ABS`."""
    big = np.abs(x) > MAX_ABS
    if big.any():
        idx = tuple(int(i) for i in np.argwhere(big)[0])
        raise GenplanError(f"{name}: element {idx} is {x[idx]:.6g}, beyond {MAX_ABS:g} (m or rad): the model "
                           "computes in float32 and cannot vouch for values that large")


def load_model(path: str | Path, *, retrain: str | None = None) -> Seq2SeqModel:
    """Load a seq2seq model file (safetensors + its JSON card), or a shipped model by its name
    (``"panda_shelf_seq2seq"``: ``models/panda_shelf_seq2seq.safetensors``).

    A missing file raises FileNotFoundError naming the command that trains it (``retrain``, else
    the card's); a file that cannot be vouched for (see :mod:`genplan.model_files`) raises
    :class:`~genplan.errors.ModelFileError` naming the file and the problem. A card of a format an
    installed package declares a reader for (:mod:`genplan.seq2seq.plugins`; the first pancake
    cards, ``genplan-pancake-seq2seq-v1``) loads through that reader.
    """
    from genplan.model_files import models_dir, peek_card, read_config, read_model

    from genplan.seq2seq import plugins

    path = Path(path)
    if not path.suffix and len(path.parts) == 1 and not path.exists() and (models_dir() / f"{path}.safetensors").is_file():
        path = models_dir() / f"{path}.safetensors"  # a shipped model by its name
    card0 = peek_card(path) or {}
    fmt = card0.get("format")
    if isinstance(fmt, str) and fmt != FORMAT:
        loader = plugins.find("format", fmt)
        if loader is not None:  # a format another package reads (the first pancake cards)
            model: Seq2SeqModel = loader(path)
            return model
    retrain = retrain or str(card0.get("retrain") or card0.get("command") or "genplan train seq2seq --data DIR --out M")
    card, tensors = read_model(path, FORMAT, "seq2seq", retrain, CARD_KEYS)
    cfg = read_config(card, path, "seq2seq", Seq2SeqConfig)
    return from_tensors(cfg, tensors, card, path)


def from_tensors(cfg: Seq2SeqConfig, tensors: dict[str, Any], card: dict[str, Any], path: Path) -> Seq2SeqModel:
    """The model of ``cfg`` with the weights ``tensors`` (checked: names and shapes), in eval mode."""
    from genplan.model_files import check_tensors

    net = Seq2SeqNet(cfg)
    check_tensors(tensors, {k: tuple(v.shape) for k, v in net.state_dict().items()}, path, "seq2seq")
    net.load_state_dict(tensors, strict=True)
    net.eval()
    return Seq2SeqModel(cfg, net, card)
