"""The planning environments of the GAN paper (Fig. 5, Table II) as data, and their queries.

Each environment is a scene file in ``genplan/presets/scenes/`` (docs/SCENES.md: the obstacles)
whose ``[queries]`` table says how start and goal targets are drawn:

* ``robot``: the robot it is for (``"panda"``, ``"talos"``);
* ``start_targets`` / ``goal_targets``: lists of hand positions, one drawn uniformly per query
  (the Panda), or ``start_box`` / ``goal_box``: ``[[low], [high]]``, a position drawn uniformly
  inside (Talos's right hand); exactly one of the two forms for the start and for the goal;
* ``start_yaw`` / ``goal_yaw`` (rad, default 0): the yaw of the Panda's horizontal gripper.

Geometry and queries follow the authors' public code (the notes are in the files):
``panda_shelf`` (the Panda, a table in front and a bookshelf to its left, the floor) and
``talos_task1..3`` (Talos with both feet fixed, static stability; boxes as tables, a wall, a bar
on posts). Any scene file with a ``[queries]`` table is an environment too
(:func:`environment` takes a path).

A query is a start configuration and K goal configurations (default 10), solved by IK from
uniform initial guesses with the paper's IK tasks and kept only when collision-free; the same
seed gives the same queries, whatever sampler is planned with.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomllib

from genplan import scene as S
from genplan.collision import CollisionWorld
from genplan.errors import GenplanError, SceneFileError, UnknownNameError
from genplan.planning.queries import Query, make_queries
from genplan.robots import Robot

__all__ = ["ENVIRONMENT_NAMES", "Box", "Environment", "Query", "environment"]


@dataclass(frozen=True)
class Box:
    """An axis-aligned box obstacle: half extents and centre (m, world frame)."""

    name: str
    half_extents: tuple[float, float, float]
    center: tuple[float, float, float]


@dataclass(frozen=True)
class Environment:
    """A scene (the obstacles) plus how start and goal targets are drawn for one robot."""

    name: str
    robot: str
    scene: S.Scene
    #: Panda: the discrete start / goal hand positions; Talos: boxes [[lo], [hi]] for the right hand
    start_targets: tuple[tuple[float, float, float], ...] = ()
    goal_targets: tuple[tuple[float, float, float], ...] = ()
    start_box: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    goal_box: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    description: str = ""
    #: the IK task of the queries (a shipped task's name or a task file; its [condition] term is
    #: aimed at the start / goal targets); None: the robot's shipped ``<robot>_ik``
    task: str | None = None
    #: a term of that task (FrameOrientation or FramePose) whose target rotation is a yaw about the
    #: vertical, ``start_yaw`` at the start and ``goal_yaw`` at the goals (rad); None: no yaw
    yaw_term: str | None = None
    start_yaw: float = 0.0
    goal_yaw: float = 0.0
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def boxes(self) -> tuple[Box, ...]:
        """The scene's boxes as (name, half extents, centre); a box's rotation, if any, is not
        carried (the paper's are axis-aligned)."""
        return tuple(Box(o.name, o.half_extents, o.pose.position) for o in self.scene.obstacles
                     if isinstance(o, S.Box))

    @property
    def halfspaces(self) -> tuple[tuple[str, tuple[float, float, float], float], ...]:
        """The scene's half-spaces (name, outward normal, offset): x with normal . x <= offset inside."""
        return tuple((o.name, o.normal, o.offset) for o in self.scene.obstacles if isinstance(o, S.HalfSpace))

    @classmethod
    def from_file(cls, path: str | os.PathLike[str]) -> Environment:
        """An environment from a scene file with a ``[queries]`` table (see the module's notes)."""
        from genplan._files import read_toml

        path = Path(path)
        origin = f"scene file {path}"
        data = read_toml(path, "scene", SceneFileError)
        scene = S.Scene.from_dict(data, base_dir=Path(os.path.abspath(path)).parent, origin=origin, source=path)
        if "queries" not in data:
            raise SceneFileError(f"{origin}: missing table [queries] (an environment says how its queries are drawn)")
        fields = _queries(data["queries"], f"{origin}: [queries]")
        task = fields.get("task")
        if task is not None and task.endswith(".toml") and not Path(task).is_absolute():
            fields["task"] = str(Path(os.path.abspath(path)).parent / task)  # a task file: relative to the scene file
        return cls(name=scene.name, scene=scene, description=scene.description, **fields)

    def world(self, robot: Robot, self_collision: bool = True) -> CollisionWorld:
        """The robot's collision world with this environment's obstacles."""
        if robot.name != self.robot:
            raise GenplanError(f"environment '{self.name}' is for {self.robot}, not {robot.name}")
        w = robot.collision_world(self_collision=self_collision)
        w.add_scene(self.scene)
        return w

    def queries(self, robot: Robot, n: int, seed: int = 0, k: int = 10, progress: bool = False,
                max_tries: int = 200) -> list[Query]:
        """n seeded queries: a valid start and k valid goal configurations each
        (:func:`genplan.planning.queries.make_queries`)."""
        return make_queries(self, robot, n, seed=seed, k=k, progress=progress, max_tries=max_tries)


_QUERY_KEYS = ("robot", "task", "yaw_term", "start_targets", "goal_targets", "start_box", "goal_box", "start_yaw",
               "goal_yaw")


def _queries(q: Any, where: str) -> dict[str, Any]:
    """The Environment fields a ``[queries]`` table gives, checked (SceneFileError naming the key)."""
    if not isinstance(q, Mapping):
        raise SceneFileError(f"{where}: expected a table, got {type(q).__name__}")
    for key in q:
        if key not in _QUERY_KEYS:
            raise SceneFileError(f"{where}: unknown key '{key}' (known: {', '.join(_QUERY_KEYS)})")
    if not isinstance(q.get("robot"), str) or not q["robot"]:
        raise SceneFileError(f"{where}: robot: expected the robot's name, got {q.get('robot')!r}")
    out: dict[str, Any] = {"robot": q["robot"]}
    for key in ("task", "yaw_term"):
        if key in q:
            if not isinstance(q[key], str) or not q[key]:
                raise SceneFileError(f"{where}: {key}: expected a name, got {q[key]!r}")
            out[key] = q[key]
    if ("start_yaw" in q or "goal_yaw" in q) and "yaw_term" not in q:
        raise SceneFileError(f"{where}: start_yaw / goal_yaw need yaw_term (the task's orientation term they set)")
    for end in ("start", "goal"):
        targets, box = f"{end}_targets", f"{end}_box"
        if (targets in q) == (box in q):
            raise SceneFileError(f"{where}: give exactly one of {targets} and {box}")
        try:
            if targets in q:
                rows = q[targets]
                if not isinstance(rows, list) or not rows:
                    raise SceneFileError(f"{targets}: expected a non-empty list of positions")
                out[targets] = tuple(S._vector(r, 3, f"{targets}[{i}]") for i, r in enumerate(rows))
            else:
                b = q[box]
                if not isinstance(b, list) or len(b) != 2:
                    raise SceneFileError(f"{box}: expected [[low], [high]]")
                lo, hi = S._vector(b[0], 3, f"{box} low"), S._vector(b[1], 3, f"{box} high")
                if any(a > c for a, c in zip(lo, hi)):
                    raise SceneFileError(f"{box}: low must not exceed high, got {list(lo)} and {list(hi)}")
                out[box] = (lo, hi)
            yaw = f"{end}_yaw"
            out[yaw] = S._real(q.get(yaw, 0.0), yaw)
        except SceneFileError as exc:
            raise SceneFileError(f"{where}: {exc}") from None
    return out


def _shipped() -> tuple[str, ...]:
    """The shipped scenes that are environments (have a [queries] table)."""
    return tuple(n for n in S.scene_names() if "queries" in tomllib.loads((S.SCENES_DIR / f"{n}.toml").read_text()))


#: Names accepted by :func:`environment`: the shipped scenes with a ``[queries]`` table.
ENVIRONMENT_NAMES: tuple[str, ...] = _shipped()
_CACHE: dict[str, Environment] = {}


def environment(name: str | os.PathLike[str]) -> Environment:
    """One of the paper's environments ("panda_shelf", "talos_task1", "talos_task2",
    "talos_task3": :data:`ENVIRONMENT_NAMES`), or a scene file with a ``[queries]`` table."""
    if isinstance(name, str) and name in ENVIRONMENT_NAMES:
        if name not in _CACHE:
            _CACHE[name] = Environment.from_file(S.SCENES_DIR / f"{name}.toml")
        return _CACHE[name]
    if isinstance(name, (str, os.PathLike)) and Path(name).suffix == ".toml":
        return Environment.from_file(name)
    raise UnknownNameError(f"unknown environment '{name}' (known: {', '.join(ENVIRONMENT_NAMES)}; or a scene file .toml)")
