"""The GAN sampler: configurations from a trained GAN, conditioned on end-effector targets.

It has ``sample(n) -> (n, nq)`` (a :class:`genplan.protocols.Sampler`) and runs torch; its
:meth:`GanSampler.native` twin runs the same generator in Rust, which is what the planner uses.
Uniform and hybrid sampling are native only: :func:`genplan.planning.make_sampler`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from genplan._arrays import as_box
from genplan._threads import resolve
from genplan.errors import ModelFileError, SettingsError
from genplan.gan.model import GanModel, load_model
from genplan.robots import Robot


class GanSampler:
    """Configurations from a trained GAN, conditioned on end-effector targets.

    ``sample(n)`` draws targets uniformly in ``box`` (default: the model's target box);
    ``sample_for(targets)`` conditions on given targets. Targets (and ``box``) must be finite and
    lie inside the model's :meth:`~genplan.gan.GanModel.target_limits` (its target box widened
    by 1 m): farther ones are refused with an error naming the first bad row, not clipped (clip
    them yourself to sample anyway). Every sample is finite, or NonFiniteError names its target
    row. ``threads``: torch threads while sampling (default: genplan's choice, one; see
    genplan._threads).
    """

    def __init__(self, robot: Robot, model: GanModel | str | Path | None = None,
                 box: ArrayLike | None = None, seed: int | None = None, *, threads: int | None = None) -> None:
        self.robot = robot
        self.model = model if isinstance(model, GanModel) else load_model(robot, model)
        if self.model.config.robot != robot.name:
            raise ModelFileError(f"the GAN is for '{self.model.config.robot}', not '{robot.name}'")
        self.box = as_box(self.model.config.target_box if box is None else box)
        self.model.check_targets(self.box, "box")
        self.threads = None if threads is None else resolve("small", threads)
        self.rng = np.random.default_rng(seed)

    def native(self, seed: int | None = None) -> Any:
        """The same sampler run natively (Rust): what the planner uses for ``sampler="gan"``."""
        return self.model.native_sampler(self.box, int(self.rng.integers(2**63)) if seed is None else seed)

    def sample_for(self, targets: ArrayLike) -> NDArray[np.float64]:
        """One configuration per target position (n, 3) -> (n, nq)."""
        return self.model.sample(targets, self.rng, threads=self.threads)

    def sample(self, n: int) -> NDArray[np.float64]:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
            raise SettingsError(f"n must be a non-negative integer, got {n!r}")
        targets = self.rng.uniform(self.box[0], self.box[1], size=(int(n), 3))
        return self.sample_for(targets)
