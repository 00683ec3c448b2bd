"""Hyperparameters of the seq2seq model (torch-free, so the CLI can show the defaults)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from genplan._config import check_fields, integer, number, optional
from genplan.errors import SettingsError
from genplan.pancake.trajectories import DT, K

if TYPE_CHECKING:
    from genplan.seq2seq.config import Seq2SeqConfig as GenericConfig

#: eq. 17's scaling between metres and radians (also the reconstruction loss's D, eq. 5)
D_SCALE = (1.0, 1.0, 0.1)

__all__ = ["Seq2SeqConfig", "pancake_config", "D_SCALE"]


@dataclass
class Seq2SeqConfig:
    """Architecture and training hyperparameters (all in the model card)."""

    hidden: int = 64
    layers: int = 2
    K: int = K
    dt: float = DT
    #: accelerations = head output * u_scale (m/s^2, m/s^2, rad/s^2)
    u_scale: tuple[float, float, float] = (10.0, 10.0, 40.0)
    #: encoder input scaling of [y - y0, z - z0, theta]
    in_scale: tuple[float, float, float] = (10.0, 10.0, 1.0 / math.pi)
    #: soft bounds of the per-step acceleration log-variance (in units of u_scale^2)
    logvar_min: float = -14.0
    logvar_max: float = 4.0
    #: added to the output position variance (m^2 / rad^2): keeps the NLL finite at k = 0 (where
    #: the rollout's variance is exactly zero); small, because a larger floor lets the model
    #: explain deviations by variance instead of keeping its outputs inside the friction cone
    var_floor: float = 1e-8
    #: the encoder reads every ``encoder_stride``-th input pose (always including the first and
    #: the last); 1 = every pose, as in the paper
    encoder_stride: int = 5
    #: accelerations emitted per decoder LSTM step (the head emits that many samples at 1 ms
    #: each, so U_out keeps its K samples); 1 = one LSTM step per sample, as in the paper
    decoder_stride: int = 5
    #: exploit the task's mirror symmetry ((y, theta) -> (-y, -theta) maps trajectories that
    #: keep the pancake to trajectories that keep it): inputs whose net rotation is negative are
    #: mirrored before the encoder and the decoder's accelerations mirrored back, so the network
    #: only has to learn rotations of one sense (and every flip in the data teaches both)
    mirror_canonical: bool = True
    #: weight of f_dyn in the training loss (eq. 4) at the end of training; it rises
    #: geometrically from ``alpha_start`` over the first ``alpha_ramp_fraction`` of the steps, so
    #: that the model first learns to follow the inputs (flips included) and then to keep the
    #: pancake on the spatula while doing so
    alpha: float = 300.0
    alpha_start: float = 1.0
    alpha_ramp_fraction: float = 0.6
    #: the cone is tightened by this margin (rad) inside the training penalty only, so that the
    #: outputs keep some slack (eq. 15 is strict)
    train_margin: float = 0.02
    #: beta-NLL warm-up (Seitzer et al., ICLR 2022): each term of the NLL is weighted by
    #: ``(var / nll_var_ref) ** beta`` (no gradient through the weight), beta falling linearly
    #: from ``nll_beta`` to ``nll_beta_final`` over the first ``nll_beta_fraction`` of the steps;
    #: with ``nll_beta_final = 0`` the loss ends as the paper's plain NLL. The default keeps
    #: 0.5: with the plain NLL the model can give up on following large rotations (a large
    #: variance is cheaper than a flip), and flips are what the evaluation asks for; without the
    #: weighting the mean learns slowly under a large variance and training settles on "do not
    #: move" (the cone is then trivially kept).
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
        self.validate()

    @property
    def latent_dim(self) -> int:
        return self.hidden * self.layers

    def validate(self) -> None:
        """SettingsError naming the first field with a value the model or its training cannot use."""
        check_fields(self, {
            "hidden": integer(1), "layers": integer(1), "K": integer(2), "encoder_stride": integer(1),
            "decoder_stride": integer(1), "seed": integer(0), "data_seed": integer(0), "trajectories": integer(1),
            "validation": integer(1), "epochs": integer(1), "batch_size": integer(1)})
        if self.K % self.decoder_stride:
            raise SettingsError(f"bad seq2seq config: K {self.K} must be at least 2 and divisible by "
                                f"decoder_stride {self.decoder_stride}; strides must be positive")
        check_fields(self, {"threads": optional(integer(1))})
        for name in ("u_scale", "in_scale"):
            if not isinstance(getattr(self, name), (tuple, list)) or len(getattr(self, name)) != 3:
                raise SettingsError(f"Seq2SeqConfig.{name} must be 3 finite numbers > 0, got {getattr(self, name)!r}")
        positive, non_negative = number(above=0), number(at_least=0)
        check_fields(self, {
            "dt": positive, "u_scale": number(above=0, each=True),
            "in_scale": number(above=0, each=True), "var_floor": non_negative, "alpha": non_negative,
            "alpha_start": positive, "train_margin": non_negative, "nll_beta": non_negative,
            "nll_beta_final": non_negative, "nll_var_ref": positive, "lr": positive, "lr_final": non_negative,
            "grad_clip": positive, "logvar_min": number(), "logvar_max": number(above=self.logvar_min),
            "alpha_ramp_fraction": number(at_least=0, at_most=1), "nll_beta_fraction": number(at_least=0, at_most=1)})

    def encoder_indices(self) -> list[int]:
        """The input samples the encoder reads: every encoder_stride-th, plus the last."""
        idx = list(range(0, self.K, self.encoder_stride))
        if idx[-1] != self.K - 1:
            idx.append(self.K - 1)
        return idx


#: the pancake recipe's fields in the vocabulary of genplan.pancake's first config
#: (:class:`Seq2SeqConfig` above) and their names in the generic one
_RENAMED = {"u_scale": "out_scale", "train_margin": "penalty_margin"}


def pancake_config(**overrides: Any) -> "GenericConfig":
    """The shipped pancake model's configuration of the generic seq2seq model
    (:class:`genplan.seq2seq.config.Seq2SeqConfig`): the spatula's ``[y, z, theta]`` (positions
    relative to the start, the attitude absolute), accelerations through the spatula plant, the
    mirror symmetry ``(y, theta) -> (-y, -theta)``, the friction cone as the training penalty and
    the recipe of :class:`Seq2SeqConfig`. ``overrides`` take the generic names or this module's
    (``u_scale``, ``train_margin``, ``mirror_canonical``)."""
    from genplan.seq2seq.config import Seq2SeqConfig as GenericConfig

    legacy = {f.name: getattr(Seq2SeqConfig(), f.name) for f in dataclasses.fields(Seq2SeqConfig)}
    values: dict[str, Any] = {}
    for name, value in {**legacy, **overrides}.items():
        if name == "mirror_canonical":
            values["mirror"] = (-1.0, 1.0, -1.0) if value else None
        else:
            values[_RENAMED.get(name, name)] = value
    values.update(dim=3, axes=("y", "z", "theta"), relative=(True, True, False), condition_on_start=False,
                  plant="spatula", nll_scale=D_SCALE, penalty="plant", mirror_axis=2, in_offset=(0.0, 0.0, 0.0))
    if "nll_scale" in overrides:
        values["nll_scale"] = overrides["nll_scale"]
    return GenericConfig(**values)
