"""Hyperparameters of a seq2seq trajectory model (torch-free, so the CLI can show the defaults).

One :class:`Seq2SeqConfig` describes any family: the space the trajectories live in (its
dimension, its axes, how inputs are scaled for the encoder), the network, the plant that turns
the decoder's output into a trajectory, and the training recipe. The pancake model of the
seq2seq paper is one configuration of it (:func:`genplan.pancake.model.pancake_config`); a robot's
joint-space family is another (:func:`joint_space_config`, sized from the data).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from genplan._config import check_fields, integer, number, one_of, optional
from genplan.errors import SettingsError

__all__ = ["Seq2SeqConfig", "PLANT_NAMES", "PENALTIES", "NETWORKS", "LOSSES", "joint_space_config"]

#: how the decoder's output becomes a trajectory: the generic plants (genplan.seq2seq.plants) and
#: the pancake's, which genplan.pancake declares (genplan.seq2seq.plugins)
PLANT_NAMES = ("position", "integrator", "spatula")
#: the training penalty added to the reconstruction loss (eq. 4's L2): the plant's own constraint
#: (the spatula's friction cone), the data set's task residuals along the decoded trajectory, or none
PENALTIES = ("plant", "task", "none")
#: the encoder and decoder: LSTMs (the paper's) or multilayer perceptrons over the whole sequence
NETWORKS = ("lstm", "mlp")
#: the reconstruction loss: the paper's Gaussian NLL with learned variances (eq. 5), or the mean
#: squared error in units of out_scale (no variances)
LOSSES = ("nll", "mse")


def _floats(value: Any) -> tuple[float, ...]:
    return tuple(float(v) for v in value)


@dataclass
class Seq2SeqConfig:
    """Architecture and training hyperparameters of a seq2seq model (all in its card).

    Space: trajectories are ``K`` samples of ``dim`` values (axes ``axes``, joint names or plant
    axes such as the spatula's ``y, z, theta``). The encoder reads
    ``(x - relative * x[0] - in_offset) * in_scale`` at every ``encoder_stride``-th sample (and
    the last): ``relative`` marks the axes the family is invariant to translating (measured from
    the start), the others are absolute.

    Network (``network``): ``"lstm"``, the paper's: encoder LSTM (``layers`` x ``hidden``) -> z
    (the final hidden states of its layers, ``hidden * layers`` values) -> decoder LSTM whose
    initial hidden state is z and initial cell state a learned linear function of z; its input is
    a clock from 0 to 1 (and the start's encoder features with ``condition_on_start``); a linear
    head emits ``decoder_stride`` samples per LSTM step. ``"mlp"``: the encoder reads the whole
    sequence of features (``layers`` hidden layers of ``hidden`` GELU units) into z (``latent``
    values), the decoder maps z (and the start's features) through the same shape of layers to all
    K samples at once. Outputs are scaled by ``out_scale``; with the ``"nll"`` loss each has a
    log-variance (softly bounded by ``logvar_min``/``logvar_max``, in units of ``out_scale``^2).

    Plant (:mod:`genplan.seq2seq.plants`): ``"position"`` (the output is the trajectory's
    displacement from its start), ``"integrator"`` (the output is accelerations, rolled out
    exactly from the start at rest every ``dt`` s) or ``"spatula"`` (the integrator plus the
    pancake's friction-cone angle phi).

    Symmetry: with ``mirror`` (one sign per axis), inputs whose net change along
    ``mirror_axis`` is negative are mirrored (each axis times its sign) before the encoder and
    the output mirrored back, so the network learns one sense of the motion only.

    Loss (eq. 4): the reconstruction loss (``loss``: the NLL of eq. 5, each axis scaled by
    ``nll_scale``, with beta-NLL weighting ``nll_beta`` -> ``nll_beta_final`` over the first
    ``nll_beta_fraction`` of the steps; or ``"mse"``, the squared error in units of ``out_scale``
    times ``nll_scale``) plus ``alpha`` times the penalty (``penalty``: ``"plant"``, ``"task"`` or ``"none"``;
    ``alpha`` rises geometrically from ``alpha_start`` over the first ``alpha_ramp_fraction``;
    ``penalty_margin`` tightens the plant's constraint inside the penalty).
    """

    dim: int = 7
    axes: tuple[str, ...] = ()
    K: int = 64
    dt: float = 1e-3
    network: str = "lstm"
    hidden: int = 128
    layers: int = 2
    #: latent values of the "mlp" network (the "lstm" one has hidden * layers); None: 64
    latent: int | None = None
    encoder_stride: int = 1
    decoder_stride: int = 1
    in_scale: tuple[float, ...] = ()
    in_offset: tuple[float, ...] = ()
    relative: tuple[bool, ...] = ()
    condition_on_start: bool = True
    plant: str = "position"
    loss: str = "nll"
    out_scale: tuple[float, ...] = ()
    logvar_min: float = -14.0
    logvar_max: float = 4.0
    var_floor: float = 1e-8
    mirror: tuple[float, ...] | None = None
    mirror_axis: int = 0
    nll_scale: tuple[float, ...] = ()
    penalty: str = "none"
    penalty_margin: float = 0.0
    alpha: float = 1.0
    alpha_start: float = 1.0
    alpha_ramp_fraction: float = 0.6
    nll_beta: float = 1.0
    nll_beta_final: float = 0.5
    nll_beta_fraction: float = 0.6
    nll_var_ref: float = 1e-4
    # training
    seed: int = 0
    data_seed: int = 0
    trajectories: int = 50_000
    validation: int = 2048
    epochs: int = 7
    batch_size: int = 128
    lr: float = 3e-3
    lr_final: float = 1e-4
    grad_clip: float = 1.0
    #: torch threads for training; None: genplan's choice for training (genplan._threads: one,
    #: or $GENPLAN_TORCH_THREADS). The card's training record holds the count used.
    threads: int | None = None

    def __post_init__(self) -> None:
        d = self.dim
        if isinstance(d, bool) or not isinstance(d, int) or d < 1:
            raise SettingsError(f"Seq2SeqConfig.dim must be an integer >= 1, got {d!r}")
        # per-axis fields left empty take their neutral value (one per axis)
        for name, neutral in (("in_scale", 1.0), ("in_offset", 0.0), ("out_scale", 1.0), ("nll_scale", 1.0)):
            value = getattr(self, name)
            setattr(self, name, (neutral,) * d if len(value) == 0 else _floats(value))
        self.relative = (False,) * d if len(self.relative) == 0 else tuple(bool(v) for v in self.relative)
        self.axes = tuple(f"x{i}" for i in range(d)) if len(self.axes) == 0 else tuple(str(a) for a in self.axes)
        if self.mirror is not None:
            self.mirror = _floats(self.mirror)
        self.validate()

    @property
    def latent_dim(self) -> int:
        if self.network == "mlp":
            return 64 if self.latent is None else self.latent
        return self.hidden * self.layers

    @property
    def decoder_inputs(self) -> int:
        """The decoder LSTM's input size: the clock, and the start's features when conditioned."""
        return 1 + (self.dim if self.condition_on_start else 0)

    def validate(self) -> None:
        """SettingsError naming the first field with a value the model or its training cannot use."""
        check_fields(self, {
            "dim": integer(1), "hidden": integer(1), "layers": integer(1), "K": integer(2), "encoder_stride": integer(1),
            "decoder_stride": integer(1), "seed": integer(0), "data_seed": integer(0), "trajectories": integer(1),
            "validation": integer(1), "epochs": integer(1), "batch_size": integer(1), "mirror_axis": integer(0)})
        if self.K % self.decoder_stride:
            raise SettingsError(f"Seq2SeqConfig.K ({self.K}) must be divisible by decoder_stride "
                                f"({self.decoder_stride})")
        check_fields(self, {"threads": optional(integer(1)), "network": one_of(NETWORKS), "loss": one_of(LOSSES)})
        if self.latent is not None and (isinstance(self.latent, bool) or not isinstance(self.latent, int)
                                        or self.latent < 1 or self.network != "mlp"):
            raise SettingsError(f"Seq2SeqConfig.latent must be None or a positive integer, and only for the 'mlp' "
                                f"network (an LSTM's latent is hidden * layers), got {self.latent!r}")
        check_fields(self, {"plant": one_of(PLANT_NAMES), "penalty": one_of(PENALTIES)})
        if self.plant == "spatula" and self.dim != 3:
            raise SettingsError(f"Seq2SeqConfig.plant 'spatula' moves [y, z, theta]: dim must be 3, got {self.dim}")
        if self.penalty == "plant" and self.plant != "spatula":
            raise SettingsError(f"Seq2SeqConfig.penalty 'plant': the plant {self.plant!r} has no constraint of its "
                                "own (only 'spatula' has: the friction cone)")
        if len(self.axes) != self.dim or len(set(self.axes)) != self.dim:
            raise SettingsError(f"Seq2SeqConfig.axes must name {self.dim} distinct axes, got {list(self.axes)}")
        for name in ("in_scale", "in_offset", "out_scale", "nll_scale", "relative"):
            if len(getattr(self, name)) != self.dim:
                raise SettingsError(f"Seq2SeqConfig.{name} needs one value per axis ({self.dim}), "
                                    f"got {len(getattr(self, name))}")
        if self.mirror is not None:
            if len(self.mirror) != self.dim or not all(v in (-1.0, 1.0) for v in self.mirror):
                raise SettingsError(f"Seq2SeqConfig.mirror must be None or {self.dim} signs (+1 or -1), "
                                    f"got {self.mirror!r}")
            if self.mirror_axis >= self.dim:
                raise SettingsError(f"Seq2SeqConfig.mirror_axis must be below dim ({self.dim}), got {self.mirror_axis}")
        positive, non_negative = number(above=0), number(at_least=0)
        check_fields(self, {
            "dt": positive, "in_scale": number(above=0, each=True), "in_offset": number(each=True),
            "out_scale": number(above=0, each=True), "nll_scale": number(above=0, each=True), "var_floor": non_negative,
            "alpha": non_negative, "alpha_start": positive, "penalty_margin": non_negative, "nll_beta": non_negative,
            "nll_beta_final": non_negative, "nll_var_ref": positive, "lr": positive, "lr_final": non_negative,
            "grad_clip": positive, "logvar_min": number(), "logvar_max": number(above=self.logvar_min),
            "alpha_ramp_fraction": number(at_least=0, at_most=1), "nll_beta_fraction": number(at_least=0, at_most=1)})

    def encoder_indices(self) -> list[int]:
        """The input samples the encoder reads: every encoder_stride-th, plus the last."""
        idx = list(range(0, self.K, self.encoder_stride))
        if idx[-1] != self.K - 1:
            idx.append(self.K - 1)
        return idx

    def replace(self, **changes: Any) -> "Seq2SeqConfig":
        """A copy with ``changes`` (checked)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """The config as JSON data (the card's ``config``)."""
        out = dataclasses.asdict(self)
        for k, v in out.items():
            if isinstance(v, tuple):
                out[k] = list(v)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], where: str = "config") -> "Seq2SeqConfig":
        """The config of a card (SettingsError naming ``where`` and the field for an unknown key)."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise SettingsError(f"{where}: unknown seq2seq config field(s) {unknown}; known: {sorted(names)}")
        values = {k: (tuple(v) if isinstance(v, list) else v) for k, v in data.items()}
        return cls(**values)


def joint_space_config(axes: Sequence[str], k: int, lower: Sequence[float], upper: Sequence[float],
                       **overrides: Any) -> Seq2SeqConfig:
    """The defaults for a robot's joint-space family of ``K`` samples: positions scaled by their
    joint ranges for the encoder (``in_offset`` the range's middle, ``in_scale`` 2 / range),
    the decoder emitting displacements from the start in units of a tenth of the range,
    conditioned on the start; the "mlp" network and the squared error (measured against the
    paper's LSTM and NLL on a Panda family: benches/seq2seq_architectures.py), and the data set's
    task residuals as the penalty when it has a task."""
    lo, hi = _floats(lower), _floats(upper)
    if len(lo) != len(axes) or len(hi) != len(axes):
        raise SettingsError(f"joint_space_config: {len(axes)} axes but {len(lo)} lower and {len(hi)} upper limits")
    span = tuple(max(h - low, 1e-3) if math.isfinite(h - low) else 2.0 * math.pi for low, h in zip(lo, hi))
    mid = tuple(0.5 * (h + low) if math.isfinite(h + low) else 0.0 for low, h in zip(lo, hi))
    base: dict[str, Any] = dict(
        dim=len(axes), axes=tuple(axes), K=k, in_scale=tuple(2.0 / s for s in span), in_offset=mid,
        out_scale=tuple(0.1 * s for s in span), nll_scale=(1.0,) * len(axes), plant="position",
        condition_on_start=True, network="mlp", loss="mse", hidden=512, layers=2, latent=64, encoder_stride=1,
        decoder_stride=1, trajectories=1, validation=1, epochs=200, batch_size=64, lr=1e-3, lr_final=1e-5,
        alpha=0.05, alpha_start=1e-3)
    base.update(overrides)
    return Seq2SeqConfig(**base)
