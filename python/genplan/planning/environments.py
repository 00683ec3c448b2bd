"""The planning environments of the GAN paper (Fig. 5, Table II) as data, and their queries.

Geometry and queries follow the authors' public code (the notes below):

* ``panda_shelf``: the Panda on its stand, a table in front (table top x in [0.2, 1.2], y in
  [-0.75, 0.75], z in [0.075, 0.125]) and a bookshelf to its left (five 0.75 x 0.4 x 0.02 boards
  and two 0.02 x 0.4 x 1.4 side panels; x in [-0.59, 0.16], y in [0.6, 1.0]), the floor at
  z = -0.5. Starts: the hand at one of (0.5 | 0.7, -0.25 | 0.25, 0.2) pointing along +x; goals: the
  hand at one of (-0.4 | -0.02, 0.65, 0.2 | 0.54) pointing into the shelf (+y); both with the
  gripper horizontal. The authors' stand (a box under the robot's base) is left out: only the base
  link touches it, and the base never moves.
* ``talos_task1..3``: Talos with both feet fixed, static stability; boxes as tables, a bar and
  posts in front of it. Starts: the right hand in a box above the table; goals: the right hand in a
  box below it. Task 3's rear legs (x = 0.9), which the authors created but did not check, are
  included: a table has four legs.

A query is a start configuration and K goal configurations (default 10), solved by IK from
uniform initial guesses with the paper's IK tasks and kept only when collision-free; the same
seed gives the same queries, whatever sampler is planned with.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from genplan.collision import CollisionWorld
from genplan.errors import GenplanError, UnknownNameError
from genplan.robots import Robot

__all__ = ["ENVIRONMENT_NAMES", "Box", "Environment", "Query", "environment"]


@dataclass(frozen=True)
class Box:
    """An axis-aligned box obstacle: half extents and centre (m, world frame)."""

    name: str
    half_extents: tuple[float, float, float]
    center: tuple[float, float, float]


@dataclass(frozen=True)
class Query:
    """One planning problem: a start and K goal configurations (rows), with the task-space
    targets they were solved for."""

    start: NDArray[np.float64]
    goals: NDArray[np.float64]
    start_target: NDArray[np.float64]
    goal_target: NDArray[np.float64]


@dataclass(frozen=True)
class Environment:
    """Obstacles plus how start and goal targets are drawn for one robot."""

    name: str
    robot: str
    boxes: tuple[Box, ...]
    #: half-spaces (name, outward normal, offset): points x with normal . x <= offset are inside
    halfspaces: tuple[tuple[str, tuple[float, float, float], float], ...] = ()
    #: Panda: the discrete start / goal hand positions; Talos: boxes [[lo], [hi]] for the right hand
    start_targets: tuple[tuple[float, float, float], ...] = ()
    goal_targets: tuple[tuple[float, float, float], ...] = ()
    start_box: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    goal_box: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    description: str = ""
    #: yaw of the Panda's horizontal gripper at the start / goal (rad)
    start_yaw: float = 0.0
    goal_yaw: float = 0.0
    notes: tuple[str, ...] = field(default_factory=tuple)

    def world(self, robot: Robot, self_collision: bool = True) -> CollisionWorld:
        """The robot's collision world with this environment's obstacles."""
        if robot.name != self.robot:
            raise GenplanError(f"environment '{self.name}' is for {self.robot}, not {robot.name}")
        w = robot.collision_world(self_collision=self_collision)
        for b in self.boxes:
            w.add_box(b.name, half_extents=b.half_extents, center=b.center)
        for name, normal, offset in self.halfspaces:
            w.add_halfspace(name, normal, offset)
        return w

    def queries(self, robot: Robot, n: int, seed: int = 0, k: int = 10, progress: bool = False,
                max_tries: int = 200) -> list[Query]:
        """n seeded queries: a valid start and k valid goal configurations each."""
        from genplan.planning.queries import make_queries

        return make_queries(self, robot, n, seed=seed, k=k, progress=progress, max_tries=max_tries)


def _shelf() -> tuple[Box, ...]:
    boards = [Box(f"shelf_board_{i}", (0.375, 0.2, 0.01), (-0.215, 0.8, z))
              for i, z in enumerate((-0.3675, -0.0075, 0.3425, 0.6925, 1.0425))]
    panels = [Box(f"shelf_side_{i}", (0.01, 0.2, 0.7), (x, 0.8, 0.3325)) for i, x in enumerate((-0.58, 0.15))]
    return (*boards, *panels)


_ENVIRONMENTS: dict[str, Environment] = {
    "panda_shelf": Environment(
        name="panda_shelf",
        robot="panda",
        boxes=(Box("table_top", (0.5, 0.75, 0.025), (0.7, 0.0, 0.1)), *_shelf()),
        halfspaces=(("floor", (0.0, 0.0, 1.0), -0.5),),
        start_targets=tuple((x, y, 0.2) for x in (0.5, 0.7) for y in (-0.25, 0.25)),
        goal_targets=tuple((x, 0.65, z) for x in (-0.4, -0.02) for z in (0.2, 0.54)),
        start_yaw=0.0,
        goal_yaw=np.pi / 2,
        description="Panda, gripper horizontal: from above the table into the bookshelf (Table II, Fig. 5a)",
    ),
    "talos_task1": Environment(
        name="talos_task1",
        robot="talos",
        boxes=(Box("table", (0.25, 0.4, 0.03), (0.7, 0.0, 0.95)),),
        start_box=((0.55, -0.25, 1.1), (0.85, 0.25, 1.3)),
        goal_box=((0.55, -0.25, 0.4), (0.85, 0.25, 0.8)),
        description="Talos, feet fixed, static stability: the right hand from above a table to below it (Fig. 5b)",
    ),
    "talos_task2": Environment(
        name="talos_task2",
        robot="talos",
        boxes=(Box("table", (0.25, 0.4, 0.03), (0.55, 0.0, 0.8)), Box("wall", (0.03, 0.4, 0.12), (0.33, 0.0, 0.95))),
        start_box=((0.3, -0.25, 1.0), (0.7, 0.25, 1.3)),
        goal_box=((0.3, -0.25, 0.4), (0.7, 0.25, 0.8)),
        description="Talos: a lower table with a low wall at its near edge (Fig. 5c)",
    ),
    "talos_task3": Environment(
        name="talos_task3",
        robot="talos",
        boxes=(
            Box("table", (0.25, 0.4, 0.03), (0.7, 0.0, 0.75)),
            Box("bar", (0.03, 0.4, 0.03), (0.5, 0.0, 1.22)),
            Box("post_left", (0.03, 0.03, 0.25), (0.5, 0.3, 1.0)),
            Box("post_right", (0.03, 0.03, 0.25), (0.5, -0.3, 1.0)),
            Box("leg_front_left", (0.03, 0.03, 0.35), (0.5, 0.3, 0.4)),
            Box("leg_front_right", (0.03, 0.03, 0.35), (0.5, -0.3, 0.4)),
            Box("leg_rear_left", (0.03, 0.03, 0.35), (0.9, 0.3, 0.4)),
            Box("leg_rear_right", (0.03, 0.03, 0.35), (0.9, -0.3, 0.4)),
        ),
        start_box=((0.55, -0.2, 0.8), (0.7, 0.2, 1.1)),
        goal_box=((0.55, -0.2, 0.4), (0.7, 0.2, 0.6)),
        description="Talos: a table under a frame (bar on posts): reach from inside the frame to under the table (Fig. 5d)",
    ),
}

#: Names accepted by :func:`environment`.
ENVIRONMENT_NAMES: tuple[str, ...] = tuple(_ENVIRONMENTS)


def environment(name: str) -> Environment:
    """One of the paper's environments: "panda_shelf", "talos_task1", "talos_task2", "talos_task3"."""
    try:
        return _ENVIRONMENTS[name]
    except KeyError:
        raise UnknownNameError(f"unknown environment '{name}' (known: {', '.join(ENVIRONMENT_NAMES)})") from None
