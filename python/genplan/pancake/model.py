"""The pancake's seq2seq model (the paper's Sections 2.2 and 4.2): one configuration of the generic
method (:mod:`genplan.seq2seq.model`), with the pancake's data, training recipe and evaluation.

The configuration (:func:`genplan.pancake.config.pancake_config`, written to the model card):

* **space**: the spatula's poses ``[y, z, theta]``, K = 500 samples at 1 ms; the encoder reads
  ``[(y - y0) / 0.1, (z - z0) / 0.1, theta / pi]`` (positions relative to the start: the physics
  is invariant to translations in y and z, so the model is too; the attitude absolute: gravity
  makes it matter) at every 5th sample (and the last; 1 is the paper's);
* **latent vector** ``z`` (128 = 64 x 2 dims, as in the paper): the final hidden states of the two
  encoder layers;
* **decoder**: LSTM, 2 layers x 64 units, emitting 5 consecutive 1 ms samples of accelerations
  ``u[k]`` per step (100 LSTM steps; 1 is the paper's) and their log-variances;
* **plant**: the spatula (:class:`genplan.pancake.physics.SpatulaPlant`): ``u`` rolled out from the
  input's start pose at rest, with the friction-cone angle phi;
* **mirror symmetry**: ``(y, theta) -> (-y, -theta)`` maps the physics onto itself (phi changes
  sign), so inputs whose net rotation is negative are mirrored before the encoder and the
  decoder's accelerations mirrored back. The network only learns one sense of rotation, and every
  flip in the data teaches both.

Loss (eq. 4, 5, 18), per trajectory and divided by K:
``-sum_k log N(D p_in[k] | D p_out[k], D S[k] D^T) + alpha * f_dyn``, ``D = diag(1, 1, 0.1)``,
``S[k] = var_p[k] + var_floor``. What this budget (about 11 minutes on one CPU core, 50,000
trajectories instead of the paper's 1.6M) needed on top, all in the config and the card:

* beta-NLL weighting ``(S_D / 1e-4) ** beta`` of the NLL terms, beta going 1 -> 0.5 over the
  first 60 % of the steps: with the plain NLL the mean learns slowly under a large variance and
  the model settles on not moving, or on not rotating (a large variance is cheaper than a flip);
* alpha rising geometrically 1 -> 300 over the first 60 % of the steps, and f_dyn evaluated with
  a 0.02 rad margin: first follow the inputs, flips included, then keep the pancake on;
* ``var_floor`` = 1e-8: keeps the NLL finite at k = 0, where the rollout's variance is zero.

Files: ``pancake_seq2seq.safetensors`` (weights) + ``.json`` (card: config, data, seed, training
time, loss curve, evaluation, weights sha256), in the generic format; a card of the first
pancake-only format (``genplan-pancake-seq2seq-v1``) loads through :func:`load_legacy`.
"""

from __future__ import annotations

import math
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray
from torch import Tensor

from genplan._threads import uses_torch
from genplan.model_files import inside_package, models_dir, out_option
from genplan.pancake import physics as ph
from genplan.pancake.config import pancake_config
from genplan.seq2seq.config import Seq2SeqConfig
from genplan.seq2seq.model import Seq2SeqModel, nll

__all__ = ["DEFAULT_NAME", "DEVIATIONS", "LEGACY_FORMAT", "default_config", "default_path", "evaluate",
           "load_legacy", "load_model", "models_dir", "retrain_command", "start_state", "train"]

DEFAULT_NAME = "pancake_seq2seq"
#: the card format of the first, pancake-only model (still read)
LEGACY_FORMAT = "genplan-pancake-seq2seq-v1"
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


def start_state(p_in: Tensor) -> Tensor:
    """The spatula's initial state: the input's first pose, at rest. (B, K, 3) -> (B, 6)."""
    return torch.cat([p_in[:, 0, :], torch.zeros_like(p_in[:, 0, :])], -1)


def default_path() -> Path:
    return models_dir() / f"{DEFAULT_NAME}.safetensors"


def retrain_command(cfg: Seq2SeqConfig | None = None, out: str | Path | None = None, *,
                    data_seed: bool = False) -> str:
    """The command that trains the model of ``cfg`` (default: the shipped recipe's seed 0),
    writing ``out``. It always names ``--out`` (training never writes into the installed package:
    :func:`genplan.cli.args.model_output`): without ``out``, or with one inside the package,
    ``pancake_seq2seq.safetensors`` in the current folder. ``data_seed``: name the config's data
    seed too (when it differs from its seed)."""
    if out is None or inside_package(out):
        out = f"{DEFAULT_NAME}.safetensors"
    if cfg is None:
        return f"genplan train seq2seq --seed 0{out_option(Path(out))}"
    return (f"genplan train seq2seq --seed {cfg.seed} --trajectories {cfg.trajectories} --epochs {cfg.epochs}"
            + (f" --data-seed {cfg.data_seed}" if data_seed else "") + out_option(Path(out)))


def load_model(path: str | Path | None = None) -> Seq2SeqModel:
    """Load a pancake seq2seq model (default: the shipped ``models/pancake_seq2seq.safetensors``):
    a :class:`genplan.seq2seq.model.Seq2SeqModel` whose plant is the spatula.

    A missing file raises FileNotFoundError naming the command that trains it; a file that cannot
    be vouched for (see :mod:`genplan.model_files`) raises :class:`~genplan.errors.ModelFileError`
    naming the file and the problem; a model of another plant is refused the same way.
    """
    from genplan.errors import ModelFileError
    from genplan.seq2seq.model import load_model as load_generic

    path = default_path() if path is None else Path(path)
    model = load_generic(path, retrain=retrain_command(out=path))
    if model.config.plant != "spatula":
        raise ModelFileError(f"{path} is a seq2seq model of a {model.config.plant!r} plant, not the pancake's spatula")
    return model


def load_legacy(path: str | Path) -> Seq2SeqModel:
    """A model file of the first pancake-only card format (:data:`LEGACY_FORMAT`: the config in
    that format's names, :class:`genplan.pancake.config.Seq2SeqConfig`), as the generic model of
    the pancake's configuration (the weights are the same tensors)."""
    from genplan.model_files import read_config, read_model
    from genplan.pancake.config import Seq2SeqConfig as LegacyConfig
    from genplan.seq2seq.model import from_tensors

    path = Path(path)
    keys = frozenset({"description", "deviations_from_paper", "retrain", "data", "training", "evaluation", "notes"})
    card, tensors = read_model(path, LEGACY_FORMAT, "seq2seq", retrain_command(out=path), keys)
    legacy = read_config(card, path, "seq2seq", LegacyConfig)
    cfg = pancake_config(**{f: getattr(legacy, f) for f in legacy.__dataclass_fields__})
    return from_tensors(cfg, tensors, card, path)


def default_config(**overrides: Any) -> Seq2SeqConfig:
    """The shipped recipe (:func:`genplan.pancake.config.pancake_config`) with ``overrides``."""
    return pancake_config(**overrides)


@uses_torch("small")
@torch.no_grad()
def evaluate(model: Seq2SeqModel, p_in: NDArray[np.float32], batch: int = 512) -> dict[str, float]:
    """Deformation quality on inputs: NLL, reproduction RMSE, f_dyn, share inside the cone."""
    tot = {"nll": 0.0, "f_dyn": 0.0, "sq_pos": 0.0, "sq_ang": 0.0, "end_pos": 0.0, "end_ang": 0.0,
           "inside": 0.0}
    n = len(p_in)
    lim = ph.cone_limit()
    d = torch.tensor(model.config.nll_scale, dtype=torch.float32)
    for i in range(0, n, batch):
        x = torch.as_tensor(p_in[i:i + batch])
        _, out = model.forward(x)
        tot["nll"] += float(nll(x, out, model.config.var_floor, d).sum()) / x.shape[1]
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


def _describe(ev: dict[str, float]) -> str:
    return (f"val nll/step {ev['nll_per_step']:.3f}, rmse {ev['rmse_pos_mm']:.2f} mm {ev['rmse_ang_deg']:.2f} deg, "
            f"f_dyn {ev['f_dyn_mean']:.4f}, inside cone {ev['inside_cone_percent']:.1f} %")


def train(cfg: Any, data: NDArray[np.float32] | None = None, progress: bool = True,
          log_every: int = 50) -> Seq2SeqModel:
    """Train a pancake model of ``cfg`` (:func:`default_config`; a
    :class:`genplan.pancake.config.Seq2SeqConfig` of the first pancake model is read as that) on ``data`` (default: the
    seeded inputs of :mod:`genplan.pancake.data`, ``cfg.trajectories`` of them), validating on
    ``cfg.validation`` fresh ones after every epoch (:func:`genplan.seq2seq.train.fit`); returns
    it with a card holding the loss curve and training time.

    torch runs on ``cfg.threads`` threads (None: genplan's choice for training, see
    genplan._threads); the card records the count used."""
    from genplan.pancake.config import Seq2SeqConfig as LegacyConfig
    from genplan.pancake.data import cache_path, generate_chunk, input_trajectories
    from genplan.seq2seq.train import fit

    if isinstance(cfg, LegacyConfig):  # the first pancake config's vocabulary
        cfg = pancake_config(**{f: getattr(cfg, f) for f in cfg.__dataclass_fields__})
    cfg.validate()
    t_data = time.perf_counter()
    source = "given"
    if data is None:
        source = "cache" if cache_path(cfg.trajectories, cfg.data_seed, cfg.K).is_file() else "generated"
        data = input_trajectories(cfg.trajectories, cfg.data_seed, cfg.K, progress=progress)
    t_data = time.perf_counter() - t_data
    val = generate_chunk(cfg.validation, np.random.default_rng([cfg.data_seed, 1]), cfg.K)
    model = fit(cfg, data, val, penalty=ph.SpatulaPlant.penalty, evaluation=lambda m, v: evaluate(m, v),
                progress=progress, log_every=log_every, describe=_describe)
    training = model.card["training"]
    n = len(data)
    model.card = {
        "description": "seq2seq trajectory deformation for the pancake task (Kutsuzawa et al. 2019)",
        "deviations_from_paper": [
            f"training data: {n:,} generated inputs (the paper: 1,638,400), {cfg.epochs} epochs, "
            f"{training['seconds'] / 60:.0f} min on {training['threads']} CPU thread(s)", *DEVIATIONS],
        "retrain": retrain_command(cfg),
        "data": {"trajectories": n, "source": source, "data_seed": cfg.data_seed, "seconds": t_data,
                 "paper_trajectories": 1_638_400},
        "space": {"kind": "task", "axes": list(cfg.axes), "units": ["m", "m", "rad"]},
        "training": training,
    }
    return model


#: names this module had when it held the method, and where they live now
_MOVED = {"Seq2SeqModel": "genplan.seq2seq.model", "Seq2SeqNet": "genplan.seq2seq.model",
          "nll": "genplan.seq2seq.model", "first_nonfinite": "genplan.seq2seq.model",
          "check_magnitude": "genplan.seq2seq.model", "MAX_ABS": "genplan.seq2seq.model",
          "CARD_KEYS": "genplan.seq2seq.model", "FORMAT": "genplan.seq2seq.model"}


def __getattr__(name: str) -> Any:
    if name in _MOVED:
        import importlib

        warnings.warn(f"genplan.pancake.model.{name} moved to {_MOVED[name]} (the seq2seq method is generic now); "
                      "the old name goes in the next release", DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(_MOVED[name]), name)
    raise AttributeError(f"module 'genplan.pancake.model' has no attribute {name!r}")
