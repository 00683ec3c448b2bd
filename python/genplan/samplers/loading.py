"""One loader for the learned samplers' files: a GAN file (:func:`genplan.samplers.gan.load_model`)
or a flow file (:func:`genplan.samplers.flow.load_flow`), told apart by the format in the card beside
the weights; both refuse what they cannot vouch for with the same errors. What takes a model file
(``--model``, ``genplan.planning.plan``, ``solve_ik``, :class:`~genplan.samplers.GanSampler`) loads it
here."""

from __future__ import annotations

import os
from pathlib import Path

from genplan import projection as P
from genplan.robots import Robot, load
from genplan.samplers.flow import FlowModel, is_flow_file, load_flow
from genplan.samplers.gan import GanModel, load_model


def load_sampler_model(robot: str | Robot, path: str | Path | None = None,
                       task: "str | os.PathLike[str] | P.Task | None" = None) -> GanModel | FlowModel:
    """The model of ``path`` (default: the robot's shipped GAN) for ``robot`` and ``task``: a
    :class:`~genplan.samplers.flow.FlowModel` when its card's format is a flow's, else a GAN."""
    rob = robot if isinstance(robot, Robot) else load(robot)
    if path is not None and is_flow_file(Path(path)):
        return load_flow(rob, path, task)
    return load_model(rob, path, task)
