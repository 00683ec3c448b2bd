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
from genplan.errors import ModelFileError
from genplan.gan.model import GanModel, load_model
from genplan.robots import Robot


class GanSampler:
    """Configurations from a trained GAN, conditioned on end-effector targets.

    ``sample(n)`` draws targets uniformly in ``box`` (default: the model's target box);
    ``sample_for(targets)`` conditions on given targets.
    """

    def __init__(self, robot: Robot, model: GanModel | str | Path | None = None,
                 box: ArrayLike | None = None, seed: int | None = None) -> None:
        self.robot = robot
        self.model = model if isinstance(model, GanModel) else load_model(robot, model)
        if self.model.config.robot != robot.name:
            raise ModelFileError(f"the GAN is for '{self.model.config.robot}', not '{robot.name}'")
        self.box = as_box(self.model.config.target_box if box is None else box)
        self.rng = np.random.default_rng(seed)

    def native(self, seed: int | None = None) -> Any:
        """The same sampler run natively (Rust): what the planner uses for ``sampler="gan"``."""
        return self.model.native_sampler(self.box, int(self.rng.integers(2**63)) if seed is None else seed)

    def sample_for(self, targets: ArrayLike) -> NDArray[np.float64]:
        """One configuration per target position (n, 3) -> (n, nq)."""
        return self.model.sample(np.asarray(targets, dtype=np.float64), self.rng)

    def sample(self, n: int) -> NDArray[np.float64]:
        targets = self.rng.uniform(self.box[0], self.box[1], size=(int(n), 3))
        return self.sample_for(targets)
