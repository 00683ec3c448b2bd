"""The GAN paper's tasks: the shipped task files ``panda_projection``, ``panda_ik``,
``talos_projection`` and ``talos_ik`` (:func:`paper_task`, :func:`panda_task`, :func:`talos_task`),
and the paper's constants read from them (their one definition), when first used:

* ``PANDA_HAND_OFFSET``: the rotation of the Panda's hand frame (-pi/2 about y) whose result must
  be a pure rotation about the world z axis (the gripper horizontal, yaw free);
* ``PANDA_IK_BOX``: the Panda's IK targets, a box of hand positions (m), [[low], [high]];
* ``TALOS_IK_BOX``: Talos' IK targets, a box of right-hand positions (m) in front of and to the
  right of the robot, most of it reachable with the feet fixed;
* ``TALOS_COM_BOX``: the box Talos' centre of mass stays in (static stability, m).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import tomllib
from numpy.typing import ArrayLike

from genplan.errors import GenplanError, UnknownNameError
from genplan.projection.task import TASKS_DIR, Task, load_task, task_names
from genplan.robots import Robot

__all__ = ["PANDA_HAND_OFFSET", "PANDA_IK_BOX", "TALOS_COM_BOX", "TALOS_IK_BOX", "TASK_KINDS", "paper_task",
           "panda_task", "talos_task"]

TASK_KINDS = ("projection", "ik")


def _preset_table(task: str, term: str) -> dict[str, Any]:
    data = tomllib.loads((TASKS_DIR / f"{task}.toml").read_text())
    return data["condition"] if term == "[condition]" else next(t for t in data["primary"] if t["name"] == term)


def _box(task: str, term: str, low: str, high: str) -> Callable[[], np.ndarray]:
    return lambda: np.array([_preset_table(task, term)[k] for k in (low, high)])


#: the paper's constants (see the module's text) and how each is read from its task file
_CONSTANTS: dict[str, Callable[[], np.ndarray]] = {
    "PANDA_HAND_OFFSET": lambda: np.array(_preset_table("panda_projection", "hand_orientation")["offset"]),
    "PANDA_IK_BOX": _box("panda_ik", "[condition]", "low", "high"),
    "TALOS_IK_BOX": _box("talos_ik", "[condition]", "low", "high"),
    "TALOS_COM_BOX": _box("talos_projection", "com", "lower", "upper"),
}


def __getattr__(name: str) -> Any:
    if name in _CONSTANTS:
        value = _CONSTANTS[name]()
        globals()[name] = value  # read once
        return value
    raise AttributeError(f"module 'genplan.projection.paper' has no attribute '{name}'")


def paper_task(robot: Robot, kind: str = "projection", target: ArrayLike | None = None) -> Task:
    """The paper's task for ``robot``: the shipped task file ``<robot>_<kind>`` (``panda_ik``,
    ``talos_projection``, ...; see :func:`task_names`); ``target`` sets the IK task's condition
    term (the hand position)."""
    _check_kind(kind)
    name, shipped = f"{robot.name}_{kind}", task_names()
    if name not in shipped:
        raise UnknownNameError(f"no shipped task '{name}' (shipped: {', '.join(shipped)}); "
                               "give a task of your own (a Task, or a task file: Task.from_file)")
    task = load_task(name, robot)
    if target is None:
        return task
    if task.condition is None:
        raise GenplanError(f"task '{name}' has no condition term to set a target on")
    return task.with_targets(**{task.condition.term: target})


def panda_task(kind: str = "projection", target: ArrayLike | None = None) -> Task:
    """Panda with the gripper horizontal (yaw free) and within its limits; ``ik`` adds the hand
    position (weights and tolerances of the paper's public code): the shipped task files
    ``panda_projection`` / ``panda_ik``."""
    _check_kind(kind)
    task = load_task(f"panda_{kind}")
    return task if target is None else task.with_targets(hand_position=target)


def talos_task(robot: Robot, kind: str = "projection", target: ArrayLike | None = None) -> Task:
    """Talos with both soles fixed at their half-sitting placement (full SE(3)), the centre of
    mass in :data:`TALOS_COM_BOX`, within joint limits and the left arm held at its default
    posture; ``ik`` adds the right-hand position. The secondary task keeps the rest of the
    posture near the initial guess. The shipped task files ``talos_projection`` / ``talos_ik``."""
    _check_kind(kind)
    task = load_task(f"talos_{kind}", robot)
    return task if target is None else task.with_targets(right_hand_position=target)


def _check_kind(kind: str) -> None:
    if kind not in TASK_KINDS:
        raise UnknownNameError(f"unknown task kind '{kind}' (known: {', '.join(TASK_KINDS)})")
