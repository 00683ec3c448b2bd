"""The seq2seq trajectory deformation model (the paper's Section 2.2 and 4.2).

Architecture (written to the model card):

* **encoder**: LSTM, 2 layers x 64 units, over the input poses. Its input features are
  ``[(y - y0) / 0.1, (z - z0) / 0.1, theta / pi]``: positions relative to the start (the
  physics is invariant to translations in y and z, so the model is too), the attitude absolute
  (gravity makes it matter). With ``encoder_stride`` s it reads every s-th pose (and the last):
  the inputs are smooth, and s = 5 cuts the encoder's cost five-fold (s = 1 is the paper's).
* **latent vector** ``z`` (128 = 64 x 2 dims, as in the paper): the final hidden states ``h`` of
  the two encoder layers, concatenated. The encoder's cell states are not part of ``z``, so
  everything the decoder does is a function of ``z`` alone (which latent adjustment needs).
* **decoder**: LSTM, 2 layers x 64 units, initial hidden state ``z`` (layer by layer), initial
  cell state a learned linear function of ``z``; its input at each step is a clock running from
  0 to 1 (no autoregressive feedback, so the whole sequence runs in one fused LSTM call). A
  linear head emits, per LSTM step, ``decoder_stride`` consecutive 1 ms samples of accelerations
  ``u[k]`` (scaled by ``u_scale``) and their log-variances (softly bounded); U_out always has
  all K = 500 samples. ``decoder_stride`` = 1 is one LSTM step per sample (the paper's);
  the shipped model uses 5 (100 LSTM steps), which makes training and each adjustment update
  about 5x cheaper on a CPU.
* **physics**: :func:`genplan.pancake.physics.simulate` rolls ``u`` out from the input's start
  pose at rest to the output trajectory, its phi, and the position variance.
* **mirror symmetry** (``mirror_canonical``): ``(y, theta) -> (-y, -theta)`` maps the physics
  onto itself (phi changes sign), so inputs whose net rotation is negative are mirrored before
  the encoder and the decoder's accelerations are mirrored back. The network only learns one
  sense of rotation, and every flip in the data teaches both. A problem's mirror sign comes from
  its input and stays fixed while its z is adjusted.

Loss (eq. 4, 5, 18), per trajectory and divided by K:
``-sum_k log N(D p_in[k] | D p_out[k], D S[k] D^T) + alpha * f_dyn``, ``D = diag(1, 1, 0.1)``,
``S[k] = var_p[k] + var_floor``. (With a diagonal D the scaling cancels in the Mahalanobis term
and only adds a constant ``log|D|``; it is kept as written.) What this budget (about 11 minutes on
one CPU core, 50,000 trajectories instead of the paper's 1.6M) needed on top, all in the config and the
card:

* beta-NLL weighting ``(S_D / 1e-4) ** beta`` of the NLL terms, beta going 1 -> 0.5 over the
  first 60 % of the steps: with the plain NLL the mean learns slowly under a large variance and
  the model settles on not moving, or on not rotating (a large variance is cheaper than a flip);
* alpha rising geometrically 1 -> 300 over the first 60 % of the steps, and f_dyn evaluated with
  a 0.02 rad margin: first follow the inputs, flips included, then keep the pancake on;
* ``var_floor`` = 1e-8: keeps the NLL finite at k = 0, where the rollout's variance is zero.

Files: ``<name>.safetensors`` (weights) + ``<name>.json`` (card: config, data, seed, training
time, loss curve, evaluation, weights sha256). Never pickles.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import ArrayLike, NDArray
from torch import Tensor, nn

from genplan._arrays import as_float_array
from genplan._threads import torch_threads, uses_torch
from genplan.errors import GenplanError, NonFiniteError, ShapeError
from genplan.pancake import physics as ph
from genplan.pancake.config import Seq2SeqConfig

FORMAT = "genplan-pancake-seq2seq-v1"
DEFAULT_NAME = "pancake_seq2seq"
RETRAIN_COMMAND = "genplan train seq2seq --seed 0"
#: the descriptive keys a seq2seq card may hold (besides format, config and weights_sha256)
CARD_KEYS = frozenset({"description", "deviations_from_paper", "retrain", "data", "training", "evaluation", "notes"})
#: largest |pose value| accepted (m, rad): the model computes in float32, which beyond 1e4 no
#: longer resolves a millimetre (and overflows to inf beyond 3.4e38)
MAX_ABS = 1e4
#: how the shipped recipe differs from the paper's Section 4.2 (written to every card)
DEVIATIONS = [
    "data families: S-curves, perturbed S-curves, constant-velocity lines, and motions that keep the pancake "
    "by construction (cone-projected P-D tracking, flips included) -- see genplan.pancake.data",
    "encoder reads every 5th pose (and the last); decoder emits 5 samples of u per LSTM step "
    "(100 LSTM steps instead of 500); K = 500 samples of u and of the trajectory as in the paper",
    "z = final hidden states h of the 2 encoder layers (128); the decoder's initial cell state is a learned "
    "linear function of z",
    "mirror-canonical: inputs rotating clockwise are mirrored (y, theta -> -y, -theta) and the output mirrored back",
    "loss: beta-NLL weighting (beta 1 -> 0.5), f_dyn weight rising 1 -> 300 with a 0.02 rad margin, "
    "position variance floor 1e-8 (finite NLL at k = 0)",
]


class Seq2SeqNet(nn.Module):
    """Encoder LSTM -> z -> decoder LSTM -> accelerations and log-variances."""

    def __init__(self, cfg: Seq2SeqConfig) -> None:
        super().__init__()
        cfg.validate()
        self.cfg = cfg
        self.encoder = nn.LSTM(3, cfg.hidden, cfg.layers, batch_first=True)
        self.bridge = nn.Linear(cfg.latent_dim, cfg.latent_dim)
        self.decoder = nn.LSTM(1, cfg.hidden, cfg.layers, batch_first=True)
        self.head = nn.Linear(cfg.hidden, 6 * cfg.decoder_stride)
        with torch.no_grad():
            self.head.weight.mul_(0.1)
            self.head.bias.zero_()
        self.register_buffer("in_scale", torch.tensor(cfg.in_scale, dtype=torch.float32), persistent=False)
        self.register_buffer("u_scale", torch.tensor(cfg.u_scale, dtype=torch.float32), persistent=False)
        self.register_buffer("enc_idx", torch.tensor(cfg.encoder_indices()), persistent=False)
        n_dec = cfg.K // cfg.decoder_stride
        clock = torch.arange(n_dec, dtype=torch.float32) / max(1, n_dec - 1)
        self.register_buffer("clock", clock[None, :, None], persistent=False)

    def features(self, p_in: Tensor) -> Tensor:
        """Encoder inputs: ``[(y - y0) / 0.1, (z - z0) / 0.1, theta / pi]`` at the read samples."""
        rel = p_in - torch.cat([p_in[:, :1, :2], torch.zeros_like(p_in[:, :1, 2:])], -1)
        return rel[:, self.enc_idx] * self.in_scale

    def encode(self, p_in: Tensor) -> Tensor:
        """(B, K, 3) poses -> (B, 128) latent vectors."""
        _, (h, _) = self.encoder(self.features(p_in))
        return h.transpose(0, 1).reshape(p_in.shape[0], -1)

    def decode(self, z: Tensor) -> tuple[Tensor, Tensor]:
        """(B, 128) -> accelerations (B, K, 3) and their variances (B, K, 3)."""
        if z.ndim != 2 or z.shape[1] != self.cfg.latent_dim:
            raise ShapeError(f"z must have shape (batch, {self.cfg.latent_dim}), got {tuple(z.shape)}")
        b = z.shape[0]
        cfg = self.cfg
        h0 = z.reshape(b, cfg.layers, cfg.hidden).transpose(0, 1).contiguous()
        c0 = self.bridge(z).reshape(b, cfg.layers, cfg.hidden).transpose(0, 1).contiguous()
        out, _ = self.decoder(self.clock.expand(b, -1, 1), (h0, c0))
        y = self.head(out).reshape(b, cfg.K, 6)
        u = y[..., :3] * self.u_scale
        lo, hi = cfg.logvar_min, cfg.logvar_max
        # a zero head output gives log-variance 0, i.e. a standard deviation of one u_scale
        frac = -lo / (hi - lo)
        logvar = lo + (hi - lo) * torch.sigmoid(y[..., 3:] + math.log(frac / (1.0 - frac)))
        var_u = torch.exp(logvar) * self.u_scale ** 2
        return u, var_u


def start_state(p_in: Tensor) -> Tensor:
    """The rollout's initial state: the input's first pose, at rest. (B, K, 3) -> (B, 6)."""
    return torch.cat([p_in[:, 0, :], torch.zeros_like(p_in[:, 0, :])], -1)


def chirality(p_in: Tensor) -> Tensor:
    """+1 where the input's net rotation ``theta[K-1] - theta[0]`` is >= 0, else -1. (B,)."""
    return torch.where(p_in[:, -1, 2] >= p_in[:, 0, 2], 1.0, -1.0).to(p_in.dtype)


def mirror(a: Tensor, s: Tensor) -> Tensor:
    """``(y, z, theta) -> (s y, z, s theta)`` per batch element (last axis 3, or 6 for states)."""
    m = torch.stack([s, torch.ones_like(s), s], -1)
    if a.shape[-1] == 6:
        m = torch.cat([m, m], -1)
    return a * m.reshape((a.shape[0],) + (1,) * (a.ndim - 2) + (a.shape[-1],))


def nll(p_in: Tensor, out: ph.Rollout, var_floor: float, d: tuple[float, ...] = ph.D_SCALE,
        beta: float = 0.0, var_ref: float = 1.0) -> Tensor:
    """eq. 5 per trajectory (B,): -sum_k log N(D p_in | D p_out, D S D^T).

    ``beta`` > 0 weights each term by ``(S_D / var_ref) ** beta`` without gradient through the
    weight (beta-NLL; beta = 0 is the plain NLL).
    """
    assert out.var_p is not None
    dd = torch.tensor(d, dtype=p_in.dtype)
    var = (out.var_p + var_floor) * dd ** 2
    err = (p_in - out.p) * dd
    per = 0.5 * (torch.log(2.0 * math.pi * var) + err ** 2 / var)
    if beta > 0.0:
        per = per * (var.detach() / var_ref) ** beta
    return per.sum((-1, -2))


@dataclass
class Seq2SeqModel:
    """A trained seq2seq model with its card."""

    config: Seq2SeqConfig
    net: Seq2SeqNet
    card: dict[str, Any] = field(default_factory=dict)

    # ----------------------------------------------------------------- torch API
    def chirality(self, p_in: Tensor) -> Tensor:
        """The mirror sign of each input (all +1 when the model is not mirror-canonical)."""
        if not self.config.mirror_canonical:
            return torch.ones(p_in.shape[0], dtype=p_in.dtype)
        return chirality(p_in)

    def encode(self, p_in: Tensor, s: Tensor | None = None) -> Tensor:
        """(B, K, 3) input poses -> (B, 128) latent vectors (of the mirrored input where s = -1)."""
        s = self.chirality(p_in) if s is None else s
        return self.net.encode(mirror(p_in, s))

    def decode(self, z: Tensor, x0: Tensor, s: Tensor | None = None) -> ph.Rollout:
        """Decoder and physics: latent vectors, start states and mirror signs to trajectories."""
        u, var_u = self.net.decode(z)
        if s is not None:
            u = mirror(u, s)
        return ph.simulate(u, x0, var_u, self.config.dt)

    def forward(self, p_in: Tensor) -> tuple[Tensor, ph.Rollout]:
        """The deformation: (B, K, 3) input poses to (z, output rollout)."""
        s = self.chirality(p_in)
        z = self.encode(p_in, s)
        return z, self.decode(z, start_state(p_in), s)

    def loss(self, p_in: Tensor, beta: float = 0.0, alpha: float | None = None) -> tuple[Tensor, dict[str, float]]:
        """Training loss (eq. 4) averaged over the batch and divided by K, and its parts.

        ``beta`` > 0: the beta-NLL warm-up weighting; ``alpha``: default the config's final
        value (see :class:`Seq2SeqConfig`). The penalty uses the config's ``train_margin``; the
        reported ``f_dyn`` is the paper's (no margin).
        """
        _, out = self.forward(p_in)
        cfg = self.config
        a = cfg.alpha if alpha is None else alpha
        l1 = nll(p_in, out, cfg.var_floor, beta=beta, var_ref=cfg.nll_var_ref)
        l2m = ph.f_dyn(out.phi, margin=cfg.train_margin)
        l2 = ph.f_dyn(out.phi.detach())
        k = p_in.shape[1]
        total = (l1 + a * l2m).mean() / k
        with torch.no_grad():
            plain = l1 if beta == 0.0 else nll(p_in, out, cfg.var_floor)
        return total, {"nll": float(plain.mean()) / k, "f_dyn": float(l2.detach().mean())}

    # ----------------------------------------------------------------- numpy API
    @uses_torch("small")
    @torch.no_grad()
    def deform(self, p_in: ArrayLike, *, threads: int | None = None) -> dict[str, NDArray[np.float64]]:
        """Deform input trajectories (K, 3) or (B, K, 3): returns p, v, u, phi, var_p, z.

        The inputs are checked (:func:`check_trajectories`); an output that is not finite raises
        FloatingPointError naming the problem. ``threads``: torch threads for the call (default:
        genplan's choice, see genplan._threads)."""
        x = check_trajectories(p_in, self.config.K)
        if len(x) == 0:  # an empty batch: torch's LSTMs do not take one
            k = self.config.K
            return {"p": np.zeros((0, k, 3)), "v": np.zeros((0, k, 3)), "u": np.zeros((0, k, 3)),
                    "phi": np.zeros((0, k)), "var_p": np.zeros((0, k, 3)), "z": np.zeros((0, self.config.latent_dim))}
        z, out = self.forward(torch.as_tensor(x, dtype=torch.float32))
        bad = first_nonfinite(out)
        if bad is not None:
            raise FloatingPointError(f"the deformation of x_in[{bad}] is not finite (the model overflows there)")
        res = {"p": out.p, "v": out.v, "u": out.u, "phi": out.phi, "var_p": out.var_p, "z": z}
        return {k: v.double().numpy() for k, v in res.items() if v is not None}

    # ----------------------------------------------------------------- files
    def save(self, path: str | Path) -> tuple[Path, Path]:
        """Write ``path`` (.safetensors) and its card (.json beside it)."""
        from genplan.model_files import write_model

        return write_model(path, dict(self.net.state_dict()), {"format": FORMAT}, self.card, self.config,
                           CARD_KEYS, "seq2seq")


def first_nonfinite(r: ph.Rollout) -> int | None:
    """The first problem (batch row) whose trajectory (p, v, u, phi) holds NaN or inf, or None."""
    bad = torch.zeros(r.batch, dtype=torch.bool)
    for t in (r.p, r.v, r.u, r.phi):
        bad |= ~torch.isfinite(t.detach().reshape(r.batch, -1)).all(1)
    return int(bad.nonzero()[0, 0]) if bool(bad.any()) else None


def check_trajectories(p_in: ArrayLike, k: int = ph.K, name: str = "x_in") -> NDArray[np.float64]:
    """Validate input poses: (K, 3) or (B, K, 3), finite, within :data:`MAX_ABS`. Returns (B, K, 3)
    float64; B may be 0 (an empty batch)."""
    if isinstance(p_in, Tensor):
        p_in = p_in.detach().cpu().numpy()
    x = as_float_array(p_in, name)
    if x.ndim == 2:
        x = x[None]
    if x.ndim != 3 or x.shape[1:] != (k, 3):
        raise ShapeError(f"{name} must be poses [y, z, theta] of shape ({k}, 3) or (batch, {k}, 3), "
                         f"got shape {np.shape(p_in)}")
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
                           "computes in float32 and cannot vouch for poses that large")


def models_dir() -> Path:
    """The shipped models: ``genplan/models`` inside the installed package."""
    return Path(__file__).resolve().parent.parent / "models"


def default_path() -> Path:
    return models_dir() / f"{DEFAULT_NAME}.safetensors"


def load_model(path: str | Path | None = None) -> Seq2SeqModel:
    """Load a seq2seq model (default: the shipped ``models/pancake_seq2seq.safetensors``).

    A missing file raises FileNotFoundError naming the command that trains it; a file that cannot
    be vouched for (see :mod:`genplan.model_files`: no or another weights sha256, a bad card or
    config, NaN weights, missing, extra or misshapen tensors) raises
    :class:`~genplan.errors.ModelFileError` naming the file and the problem.
    """
    from genplan.model_files import check_tensors, read_config, read_model

    path = default_path() if path is None else Path(path)
    retrain = RETRAIN_COMMAND + ("" if path == default_path() else f" --out {path}")
    card, tensors = read_model(path, FORMAT, "seq2seq", retrain, CARD_KEYS)
    cfg = read_config(card, path, "seq2seq", Seq2SeqConfig)
    net = Seq2SeqNet(cfg)
    check_tensors(tensors, {k: tuple(v.shape) for k, v in net.state_dict().items()}, path, "seq2seq")
    net.load_state_dict(tensors, strict=True)
    net.eval()
    return Seq2SeqModel(cfg, net, card)


# --------------------------------------------------------------------------------- training


def default_config(**overrides: Any) -> Seq2SeqConfig:
    return dataclasses.replace(Seq2SeqConfig(), **overrides)


@uses_torch("small")
@torch.no_grad()
def evaluate(model: Seq2SeqModel, p_in: NDArray[np.float32], batch: int = 512) -> dict[str, float]:
    """Deformation quality on inputs: NLL, reproduction RMSE, f_dyn, share inside the cone."""
    tot = {"nll": 0.0, "f_dyn": 0.0, "sq_pos": 0.0, "sq_ang": 0.0, "end_pos": 0.0, "end_ang": 0.0,
           "inside": 0.0}
    n = len(p_in)
    lim = ph.cone_limit()
    for i in range(0, n, batch):
        x = torch.as_tensor(p_in[i:i + batch])
        _, out = model.forward(x)
        m = len(x)
        tot["nll"] += float(nll(x, out, model.config.var_floor).sum()) / x.shape[1]
        tot["f_dyn"] += float(ph.f_dyn(out.phi).sum())
        err = out.p - x
        tot["sq_pos"] += float((err[..., :2] ** 2).mean((-1, -2)).sum())
        tot["sq_ang"] += float((err[..., 2] ** 2).mean(-1).sum())
        tot["end_pos"] += float((err[:, -1, :2] ** 2).sum(-1).sum())
        tot["end_ang"] += float((err[:, -1, 2] ** 2).sum())
        tot["inside"] += float((out.phi.abs() < lim).all(-1).sum())
    return {
        "nll_per_step": tot["nll"] / n,
        "f_dyn_mean": tot["f_dyn"] / n,
        "rmse_pos_mm": 1e3 * math.sqrt(tot["sq_pos"] / n),
        "rmse_ang_deg": math.degrees(math.sqrt(tot["sq_ang"] / n)),
        "end_rmse_pos_mm": 1e3 * math.sqrt(tot["end_pos"] / n),
        "end_rmse_ang_deg": math.degrees(math.sqrt(tot["end_ang"] / n)),
        "inside_cone_percent": 100.0 * tot["inside"] / n,
    }


def train(cfg: Seq2SeqConfig, data: NDArray[np.float32] | None = None, progress: bool = True,
          log_every: int = 50) -> Seq2SeqModel:
    """Train a model; returns it with a card holding the loss curve and training time.

    torch runs on ``cfg.threads`` threads (None: genplan's choice for training, see
    genplan._threads); the card records the count used."""
    cfg.validate()
    with torch_threads("training", cfg.threads) as threads:
        return _train(cfg, data, progress, log_every, threads)


def _train(cfg: Seq2SeqConfig, data: NDArray[np.float32] | None, progress: bool, log_every: int,
           threads: int) -> Seq2SeqModel:
    from genplan.pancake.data import cache_path, generate_chunk, input_trajectories

    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    t_data = time.perf_counter()
    source = "given"
    if data is None:
        source = "cache" if cache_path(cfg.trajectories, cfg.data_seed, cfg.K).is_file() else "generated"
        data = input_trajectories(cfg.trajectories, cfg.data_seed, cfg.K, progress=progress)
    t_data = time.perf_counter() - t_data
    if data.ndim != 3 or data.shape[1:] != (cfg.K, 3):
        raise ShapeError(f"training data must have shape (n, {cfg.K}, 3), got {data.shape}")
    if not np.all(np.isfinite(data)):
        raise NonFiniteError(f"training data: element {tuple(int(i) for i in np.argwhere(~np.isfinite(data))[0])} "
                             "is NaN or inf")
    data = np.ascontiguousarray(data, dtype=np.float32)
    val = generate_chunk(cfg.validation, np.random.default_rng([cfg.data_seed, 1]), cfg.K)

    net = Seq2SeqNet(cfg)
    model = Seq2SeqModel(cfg, net)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    n = len(data)
    steps_per_epoch = max(1, n // cfg.batch_size)
    total_steps = steps_per_epoch * cfg.epochs
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, total_steps, eta_min=cfg.lr_final)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=total_steps, desc="seq2seq training", unit="batch")
    log: list[dict[str, float]] = []
    val_log: list[dict[str, float]] = []
    acc = {"loss": 0.0, "nll": 0.0, "f_dyn": 0.0, "m": 0}
    t0 = time.perf_counter()
    step = 0
    for epoch in range(cfg.epochs):
        net.train()
        perm = rng.permutation(n)
        for i in range(steps_per_epoch):
            idx = np.sort(perm[i * cfg.batch_size:(i + 1) * cfg.batch_size])
            x = torch.from_numpy(data[idx])
            frac_b = min(1.0, step / max(1.0, cfg.nll_beta_fraction * total_steps))
            beta = cfg.nll_beta + (cfg.nll_beta_final - cfg.nll_beta) * frac_b
            frac_a = min(1.0, step / max(1.0, cfg.alpha_ramp_fraction * total_steps))
            alpha = cfg.alpha_start * (cfg.alpha / cfg.alpha_start) ** frac_a
            loss, parts = model.loss(x, beta, alpha)
            if not torch.isfinite(loss):
                raise FloatingPointError(f"training diverged at step {step} (loss {float(loss)})")
            opt.zero_grad(set_to_none=True)
            loss.backward()
            nn.utils.clip_grad_norm_(net.parameters(), cfg.grad_clip)
            opt.step()
            sched.step()
            step += 1
            acc["loss"] += float(loss.detach())
            acc["nll"] += parts["nll"]
            acc["f_dyn"] += parts["f_dyn"]
            acc["m"] += 1
            if step % log_every == 0 or step == total_steps:
                m = acc.pop("m")
                entry = {"step": step, "seconds": time.perf_counter() - t0, "lr": sched.get_last_lr()[0], "beta": beta, "alpha": alpha,
                         **{k: v / m for k, v in acc.items()}}
                log.append(entry)
                acc = {"loss": 0.0, "nll": 0.0, "f_dyn": 0.0, "m": 0}
                if bar is not None:
                    bar.set_postfix(loss=f"{entry['loss']:.3f}", f_dyn=f"{entry['f_dyn']:.3f}")
            if bar is not None:
                bar.update(1)
        net.eval()
        ev = evaluate(model, val)
        ev.update({"epoch": epoch + 1, "step": step, "seconds": time.perf_counter() - t0})
        val_log.append(ev)
        if bar is not None:
            bar.write(f"epoch {epoch + 1}: val nll/step {ev['nll_per_step']:.3f}, rmse {ev['rmse_pos_mm']:.2f} mm "
                      f"{ev['rmse_ang_deg']:.2f} deg, f_dyn {ev['f_dyn_mean']:.4f}, inside cone "
                      f"{ev['inside_cone_percent']:.1f} %")
    if bar is not None:
        bar.close()
    seconds = time.perf_counter() - t0
    model.card = {
        "description": "seq2seq trajectory deformation for the pancake task (Kutsuzawa et al. 2019)",
        "deviations_from_paper": [
            f"training data: {n:,} generated inputs (the paper: 1,638,400), {cfg.epochs} epochs, "
            f"{seconds / 60:.0f} min on {threads} CPU thread(s)", *DEVIATIONS],
        "retrain": f"genplan train seq2seq --seed {cfg.seed} --trajectories {cfg.trajectories} --epochs {cfg.epochs}",
        "data": {"trajectories": n, "source": source, "data_seed": cfg.data_seed, "seconds": t_data,
                 "paper_trajectories": 1_638_400},
        "training": {"seconds": seconds, "steps": step, "threads": threads, "torch": torch.__version__,
                     "loss_log": log, "validation_log": val_log},
    }
    return model
