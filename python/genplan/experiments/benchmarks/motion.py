"""Free-space motion planning on MotionBenchMaker-style Panda problems, VAMP side by side.

    genplan bench motion --problems 20 --seed 0 --out benches/results/motion.json
    genplan bench motion --robot ur5 --problems 20 --seed 0 --out benches/results/motion_ur5.json

``--robot`` (:data:`ROBOTS`) puts the same families in front of another robot: the UR5 and
Baxter, which VAMP ships too, and the Kinova Jaco2, which it does not (genplan alone, its spheres
generated from its meshes); the scenes are the Panda's, scaled and shifted to the robot's reach
(:func:`placed`), handed to VAMP in its own world frame where its model stands elsewhere.

Problem families (generated here, seeded; MotionBenchMaker's names): ``bookshelf_tall``,
``bookshelf_small``, ``bookshelf_thin`` (a bookshelf in front of the robot, its boards, walls and,
for the thin one, upright objects standing on thin boards; the goal a horizontal grasp into a
slot), ``cage`` (a cage open at the front, two bars narrowing the opening; the goal a horizontal
grasp inside), ``box`` (an open box on a table; the goal a top grasp inside), ``table_pick``
(objects standing on a table; the goal a top grasp between them) and ``table_under_pick`` (the
goal a horizontal grasp under a table). Every obstacle is a box or an upright capsule (the
objects and bars), placed and turned about the vertical with seeded jitter, so that VAMP's
environment holds the same shapes (its cuboids, and its cylinders, which are capsules). The start
is the Panda's ready posture with seeded jitter; the goal is the first collision-free IK solution
(``solve_ik`` on the ``tcp`` frame's whole pose, uniform warm starts) of a seeded grasp pose. A problem is kept only when its start and goal are valid for
every planner compared (the exact geometry, genplan's spheres, VAMP's spheres in genplan and, when
installed, VAMP itself), so all of them get the same problems.

The robot is genplan's Panda with the fingers open 0.04 m (``locked_joints``), as VAMP's Panda
has them. The arms, one thread each, one call per problem from Python, in an order that
alternates problem by problem:

* ``vamp`` (when ``import vamp`` works; the ``vamp_planner`` wheel, never a dependency of
  genplan): ``vamp.panda.rrtc`` with its default settings for the Panda (range 1.0, Halton
  sampling) and its spheres, then ``vamp.panda.simplify`` (its defaults: shortcut and B-spline
  smoothing, up to 5 rounds), each call timed from Python;
* ``genplan_spheres``: ``Planner(robot, world, task="free", checker="spheres")``, RRT-Connect with
  simplification, genplan's own covering spheres (a guaranteed cover of the meshes);
* ``genplan_hybrid``: the same planner with ``checker="hybrid"``: the same spheres first, each
  collision they find checked again by the exact geometry, whose answer stands (the spheres as
  the fast path, the exact geometry as the final word: no state the spheres refuse for their
  cover's excess alone is lost);
* ``genplan_vamp_spheres``: the same planner on VAMP's 59 spheres of the Panda
  (``sphere_checker(robot, world, spheres=...)``: VAMP's spheres found in genplan's link frames
  from VAMP's forward kinematics), so both check the same robot geometry;
* ``genplan_exact``: the same planner on the exact geometry (parry's convex hulls);
* ``roboplan`` and ``ompl`` (each when installed: the ``peers`` and ``bench`` extras): roboplan's
  RRT-Connect and path shortcutter on the robot's own URDF and SRDF (Pinocchio + coal), and OMPL's
  RRTConnect and ``simplifySolution`` with genplan's exact collision world as its validity checker
  from Python (python/genplan/experiments/benchmarks/motion_peers.py).

genplan's arms are one ``Planner.plan`` call each (simplification included); the planning time is
the call's wall time less the simplification (``stats.simplify_s``). Path length: the joint-space
L2 length of the simplified path (the sum of the distances between consecutive states); genplan's
records also hold the plan's validity checks (``checks``, planning and simplification: a cost the
machine's load does not change). Per family
and arm: success %, median ms planning, median ms simplifying, median length; and per genplan arm
the median over problems of its length over VAMP's, and the ratio of its median planning time to
VAMP's.
"""

from __future__ import annotations

import os

os.environ.setdefault("RAYON_NUM_THREADS", "1")

import argparse  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

import genplan  # noqa: E402
from genplan.cli import args as A  # noqa: E402
from genplan.errors import MissingExtraError, SettingsError  # noqa: E402
from genplan.experiments.benchmarks.motion_peers import OmplArm, RoboplanArm  # noqa: E402
from genplan.experiments.common import geometric_mean, machine, table, write_json  # noqa: E402
from genplan.ik import frame_task, solve_ik  # noqa: E402
from genplan.planning import FREE_SPACE_SETTINGS, Planner, PlannerSettings, sphere_checker  # noqa: E402
from genplan.scene import Box, Capsule, Pose, Scene  # noqa: E402
from genplan.spheres import RobotSpheres, robot_spheres  # noqa: E402

#: the Panda's fingers as VAMP's Panda has them: open, 0.04 m each
FINGERS = {"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04}
#: the Panda's ready posture, the start of every problem (with jitter)
READY = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
#: the arms, in the table's order
ARMS = ("vamp", "genplan_spheres", "genplan_hybrid", "genplan_vamp_spheres", "genplan_exact", "roboplan", "ompl")
#: the tool frame the goal poses place
TOOL = "tcp"


def load_panda() -> genplan.Robot:
    """genplan's Panda with the fingers open as VAMP's are."""
    return genplan.load("panda", locked_joints=FINGERS)


def _load_baxter() -> genplan.Robot:
    """Baxter as examples/baxter/baxter.toml describes it (both arms active)."""
    from pathlib import Path

    return genplan.load(Path(genplan.__file__).resolve().parents[2] / "examples" / "baxter" / "baxter.toml")


@dataclass(frozen=True)
class RobotSetup:
    """How a robot meets the problem families: how to load it, the posture every start jitters
    (``jitter`` rad), the frame the grasps place, VAMP's model of it (its name in ``vamp``, or
    None: genplan only), and where the Panda-sized scenes go: scaled by ``scale`` about the
    robot's base and shifted by ``offset`` (m; the scenes are built for a Panda on the floor,
    its reach 0.85 m). ``vamp_base``: VAMP's world frame in genplan's (4 x 4), when VAMP's model
    stands elsewhere (the obstacles are handed to VAMP in its frame). ``tool_back``: how far
    behind a grasp point (along the tool's z) the ``tool`` frame goes, for a tool frame at the
    flange of an arm without a gripper (m). ``tool_axes``: the rotation from a grasp's frame to the
    ``tool`` frame (3 x 3, row by row: its columns are the tool's axes in the grasp's frame), when the tool does not approach along its z with its
    fingers closing along its y as the grasps are written (None: it does)."""

    load: Callable[[], genplan.Robot]
    ready: tuple[float, ...]
    tool: str
    vamp: str | None
    scale: float = 1.0
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    jitter: float = 0.15
    vamp_base: tuple[tuple[float, ...], ...] | None = None
    tool_back: float = 0.0
    tool_axes: tuple[tuple[float, float, float], ...] | None = None


#: the robots ``--robot`` takes: the Panda (VAMP's and genplan's), the UR5 (VAMP ships its UR5
#: with a Robotiq gripper on a stand: its base turned 90 degrees about z and raised 0.915 m, the
#: mean over 200 configurations of its end effector's pose against genplan's tool0; its link
#: lengths differ from example-robot-data's by centimetres; genplan's UR5 has no gripper: its
#: flange stops 0.15 m short of the grasps, as long as VAMP's gripper), Baxter (the same kinematics in both;
#: the scenes in front of its left arm, lowered to its shoulders' height) and the Kinova Jaco2,
#: which VAMP does not ship (genplan only, its spheres generated from its meshes; its end
#: effector frame approaches along its x, the fingers closing along its y)
ROBOTS: dict[str, RobotSetup] = {
    "panda": RobotSetup(load=load_panda, ready=tuple(READY), tool=TOOL, vamp="panda"),
    "ur5": RobotSetup(load=lambda: genplan.load("ur5"), ready=(0.0, -2.2, 1.6, -1.0, -1.57, 0.0), tool="tool0",
                      tool_back=0.15,
                      vamp="ur5", vamp_base=((0.0, 1.0, 0.0, 0.0), (-1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 1.0, -0.915),
                                             (0.0, 0.0, 0.0, 1.0))),
    "baxter": RobotSetup(load=_load_baxter, ready=(0.0, -0.55, 0.0, 0.75, 0.0, 1.26, 0.0) * 2, tool="left_gripper",
                         vamp="baxter", scale=1.15, offset=(0.1, 0.3, -0.55)),
    "kinova": RobotSetup(load=lambda: genplan.load("kinova"), ready=(0.0, 3.4, 1.2, 0.0, 2.0, 0.0), tool="ee",
                         vamp=None, scale=0.9, tool_axes=((0.0, 0.0, -1.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0))),
}


# --- problem families ---------------------------------------------------------------------------

Obstacles = list[Any]


def _rot_z(yaw: float) -> NDArray[np.float64]:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class _Frame:
    """A placement in the plane (x, y, yaw): local boxes and capsules to world obstacles."""

    def __init__(self, x: float, y: float, yaw: float) -> None:
        self.x, self.y, self.yaw = x, y, yaw
        self.r = _rot_z(yaw)
        self.out: Obstacles = []

    def point(self, p: Any) -> NDArray[np.float64]:
        return np.array([self.x, self.y, 0.0]) + self.r @ np.asarray(p, dtype=np.float64)

    def box(self, center: Any, half: Any) -> None:
        self.out.append(Box(name=f"box{len(self.out)}", half_extents=tuple(half),
                            pose=Pose(position=tuple(self.point(center)), rpy=(0.0, 0.0, self.yaw))))

    def capsule(self, center: Any, radius: float, height: float) -> None:
        """An upright capsule ``height`` tall overall (its segment ``height - 2 radius``)."""
        self.out.append(Capsule(name=f"capsule{len(self.out)}", radius=radius, length=height - 2 * radius,
                                pose=Pose(position=tuple(self.point(center)))))

    def grasp(self, p: Any, top: bool) -> NDArray[np.float64]:
        """The tool's pose at local point ``p``: pointing down (``top``) or horizontally along the
        local +x axis, the fingers closing across it."""
        t = np.eye(4)
        if top:  # tool z down, x along local x
            local = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
        else:  # tool z along local x, y along local y, x down
            local = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
        t[:3, :3] = self.r @ local
        t[:3, 3] = self.point(p)
        return t


def _shelf(rng: np.random.Generator, height: float, boards: int, width: float, depth: float, board: float,
           books: int) -> tuple[Obstacles, list[NDArray[np.float64]]]:
    """A bookshelf facing the robot: side walls, back, ``boards`` boards from the bottom up to
    ``height``, ``books`` upright capsules per slot; the goals: horizontal grasps into a slot."""
    f = _Frame(0.75 + rng.uniform(-0.05, 0.1), rng.uniform(-0.15, 0.15), rng.uniform(-0.25, 0.25))
    half_w, half_d = width / 2, depth / 2
    f.box((0.0, -half_w - 0.01, height / 2), (half_d, 0.01, height / 2))
    f.box((0.0, half_w + 0.01, height / 2), (half_d, 0.01, height / 2))
    f.box((half_d + 0.01, 0.0, height / 2), (0.01, half_w + 0.02, height / 2))
    zs = np.linspace(height / boards, height, boards) if boards > 1 else np.array([height])
    zs = np.concatenate([[0.0], zs])
    for z in zs[1:]:
        f.box((0.0, 0.0, z - board / 2), (half_d, half_w, board / 2))
    slots = [(lo, hi) for lo, hi in zip(zs[:-1], zs[1:]) if 0.2 <= lo <= 1.2]
    goals = []
    for lo, hi in slots:
        for _ in range(books):
            y = rng.uniform(-half_w + 0.05, half_w - 0.05)
            f.capsule((rng.uniform(0.0, half_d - 0.05), y, lo + 0.08), 0.025, 0.16)
        for _ in range(3):
            goals.append(f.grasp((rng.uniform(-half_d + 0.05, 0.0), rng.uniform(-half_w + 0.12, half_w - 0.12),
                                  lo + min(0.12, (hi - lo) / 2)), top=False))
    return f.out, goals


def bookshelf_tall(rng: np.random.Generator) -> tuple[Obstacles, list[NDArray[np.float64]]]:
    return _shelf(rng, height=1.6 + rng.uniform(-0.05, 0.05), boards=5, width=0.8, depth=0.35, board=0.03, books=0)


def bookshelf_small(rng: np.random.Generator) -> tuple[Obstacles, list[NDArray[np.float64]]]:
    return _shelf(rng, height=0.9 + rng.uniform(-0.05, 0.05), boards=3, width=0.7, depth=0.3, board=0.03, books=0)


def bookshelf_thin(rng: np.random.Generator) -> tuple[Obstacles, list[NDArray[np.float64]]]:
    return _shelf(rng, height=1.3 + rng.uniform(-0.05, 0.05), boards=4, width=0.6, depth=0.25, board=0.01, books=2)


def cage(rng: np.random.Generator) -> tuple[Obstacles, list[NDArray[np.float64]]]:
    """A cage on a pedestal, open at the front, two bars at the opening's sides."""
    f = _Frame(0.6 + rng.uniform(-0.05, 0.1), rng.uniform(-0.15, 0.15), rng.uniform(-0.3, 0.3))
    z0, h, hw, hd = 0.25 + rng.uniform(0.0, 0.1), 0.4, 0.25, 0.2
    f.box((0.0, 0.0, z0 / 2), (hd, hw, z0 / 2))  # pedestal (the cage's floor)
    f.box((0.0, 0.0, z0 + h + 0.01), (hd, hw, 0.01))  # roof
    f.box((hd + 0.01, 0.0, z0 + h / 2), (0.01, hw, h / 2))  # back
    f.box((0.0, -hw - 0.01, z0 + h / 2), (hd, 0.01, h / 2))
    f.box((0.0, hw + 0.01, z0 + h / 2), (hd, 0.01, h / 2))
    for side in (-1, 1):
        f.capsule((-hd, side * (hw - 0.04), z0 + h / 2), 0.015, h)
    goals = [f.grasp((rng.uniform(-0.1, 0.05), rng.uniform(-0.08, 0.08), z0 + rng.uniform(0.12, 0.2)), top=False)
             for _ in range(6)]
    return f.out, goals


def _table(f: _Frame, z: float, hd: float, hw: float) -> None:
    """A table top at height ``z`` on four legs."""
    f.box((0.0, 0.0, z - 0.02), (hd, hw, 0.02))
    for sx in (-1, 1):
        for sy in (-1, 1):
            f.box((sx * (hd - 0.03), sy * (hw - 0.03), (z - 0.04) / 2), (0.025, 0.025, (z - 0.04) / 2))


def box(rng: np.random.Generator) -> tuple[Obstacles, list[NDArray[np.float64]]]:
    """An open box on a table; goals: top grasps inside it."""
    f = _Frame(0.55 + rng.uniform(-0.05, 0.1), rng.uniform(-0.2, 0.2), rng.uniform(-0.4, 0.4))
    z = 0.3 + rng.uniform(0.0, 0.1)
    _table(f, z, 0.3, 0.4)
    bh, bw, bd = 0.2, 0.18, 0.15
    f.box((bd + 0.01, 0.0, z + bh / 2), (0.01, bw + 0.02, bh / 2))
    f.box((-bd - 0.01, 0.0, z + bh / 2), (0.01, bw + 0.02, bh / 2))
    f.box((0.0, bw + 0.01, z + bh / 2), (bd, 0.01, bh / 2))
    f.box((0.0, -bw - 0.01, z + bh / 2), (bd, 0.01, bh / 2))
    goals = [f.grasp((rng.uniform(-0.05, 0.05), rng.uniform(-0.08, 0.08), z + rng.uniform(0.06, 0.1)), top=True)
             for _ in range(6)]
    return f.out, goals


def table_pick(rng: np.random.Generator) -> tuple[Obstacles, list[NDArray[np.float64]]]:
    """Objects (capsules) standing on a table; goals: top grasps just above the table between them."""
    f = _Frame(0.55 + rng.uniform(-0.05, 0.1), rng.uniform(-0.2, 0.2), rng.uniform(-0.4, 0.4))
    z = 0.35 + rng.uniform(0.0, 0.1)
    _table(f, z, 0.3, 0.5)
    placed: list[tuple[float, float]] = []
    while len(placed) < 5:
        p = (rng.uniform(-0.25, 0.25), rng.uniform(-0.45, 0.45))
        if all(math.dist(p, q) > 0.15 for q in placed):
            placed.append(p)
            f.capsule((p[0], p[1], z + 0.1), 0.03, 0.2)
    goals = []
    while len(goals) < 6:
        p = (rng.uniform(-0.2, 0.2), rng.uniform(-0.35, 0.35))
        if all(math.dist(p, q) > 0.14 for q in placed):
            goals.append(f.grasp((p[0], p[1], z + 0.1), top=True))
    return f.out, goals


def table_under_pick(rng: np.random.Generator) -> tuple[Obstacles, list[NDArray[np.float64]]]:
    """A table; goals: horizontal grasps under its top."""
    f = _Frame(0.6 + rng.uniform(-0.05, 0.1), rng.uniform(-0.2, 0.2), rng.uniform(-0.3, 0.3))
    z = 0.55 + rng.uniform(0.0, 0.1)
    _table(f, z, 0.3, 0.5)
    goals = [f.grasp((rng.uniform(-0.15, 0.0), rng.uniform(-0.2, 0.2), rng.uniform(0.2, 0.3)), top=False)
             for _ in range(6)]
    return f.out, goals


#: family name -> its generator: (obstacles, candidate grasp poses of the tool) from a generator
FAMILIES: dict[str, Callable[[np.random.Generator], tuple[Obstacles, list[NDArray[np.float64]]]]] = {
    "bookshelf_tall": bookshelf_tall,
    "bookshelf_small": bookshelf_small,
    "bookshelf_thin": bookshelf_thin,
    "cage": cage,
    "box": box,
    "table_pick": table_pick,
    "table_under_pick": table_under_pick,
}


def placed(setup: RobotSetup, obstacles: Obstacles,
           grasps: list[NDArray[np.float64]]) -> tuple[Obstacles, list[NDArray[np.float64]]]:
    """A family's scene and grasps for ``setup``'s robot: positions and sizes scaled by
    ``setup.scale`` about the origin, then shifted by ``setup.offset``, the grasps' tool frame
    ``setup.tool_back`` behind them and turned to ``setup.tool_axes`` (the Panda's unchanged)."""
    if setup.scale == 1.0 and not any(setup.offset) and setup.tool_back == 0.0 and setup.tool_axes is None:
        return obstacles, grasps
    k, off = setup.scale, np.asarray(setup.offset)

    def at(o: Any) -> Pose:
        return Pose(position=tuple(k * np.asarray(o.pose.position) + off), rpy=o.pose.rpy)

    out: Obstacles = [Box(name=o.name, half_extents=tuple(k * np.asarray(o.half_extents)), pose=at(o))
                      if isinstance(o, Box) else
                      Capsule(name=o.name, radius=k * o.radius, length=k * o.length, pose=at(o)) for o in obstacles]
    moved = []
    for g in grasps:
        g = g.copy()
        g[:3, 3] = k * g[:3, 3] + off - setup.tool_back * g[:3, 2]
        if setup.tool_axes is not None:
            g[:3, :3] = g[:3, :3] @ np.asarray(setup.tool_axes)
        moved.append(g)
    return out, moved


# --- VAMP ---------------------------------------------------------------------------------------

def vamp_module() -> Any:
    """``vamp`` when installed, else None."""
    try:
        import vamp
    except ImportError:
        return None
    return vamp


def vamp_environment(vamp: Any, obstacles: Obstacles, base: Any = None) -> Any:
    """The obstacles as a VAMP environment: boxes turned about z as cuboids, upright capsules as
    VAMP's capsules (``vamp.Cylinder`` added with ``add_capsule``: a segment of ``length`` along z
    with round ends, as genplan's :class:`~genplan.scene.Capsule`); with ``base`` (VAMP's world
    frame in genplan's, a turn about z and a shift: :class:`RobotSetup`) in VAMP's frame."""
    env = vamp.Environment()
    inv = None if base is None else np.linalg.inv(np.asarray(base, dtype=np.float64))
    turn = 0.0 if inv is None else math.atan2(inv[1, 0], inv[0, 0])
    for o in obstacles:
        p = list(map(float, o.pose.position))
        yaw = (float(o.pose.rpy[2]) if o.pose.rpy is not None else 0.0) + turn
        if inv is not None:
            p = list(map(float, inv[:3, :3] @ np.asarray(p) + inv[:3, 3]))
        if isinstance(o, Box):
            env.add_cuboid(vamp.Cuboid(p, [0.0, 0.0, yaw], list(map(float, o.half_extents))))
        else:
            env.add_capsule(vamp.Cylinder(p, [0.0, 0.0, 0.0], float(o.radius), float(o.length)))
    return env


def vamp_spheres(vamp: Any, robot: genplan.Robot, configs: int = 8, seed: int = 0) -> RobotSpheres:
    """VAMP's spheres of the Panda in genplan's link frames: each sphere's world centre from VAMP's
    forward kinematics at ``configs`` random configurations, expressed in every link's frame; a
    link in whose frame it stays put (within 1e-4 m) is its link, and of several such links (the
    hand and the fingers, locked, move as one) the one whose own geometry (genplan's spheres of
    it) is nearest, so that the self-collision pairs are the link's. ValueError when a sphere
    stays put in no link's frame."""
    rng = np.random.default_rng(seed)
    qs = robot.random_configurations(configs, rng)
    links = list(robot.kinematics.link_names)
    poses = np.asarray(robot.kinematics.forward_kinematics(qs, links))  # (c, L, 4, 4)
    world = np.array([[[s.x, s.y, s.z] for s in vamp.panda.fk(q.astype(np.float32))] for q in qs])  # (c, S, 3)
    radii = np.array([s.r for s in vamp.panda.fk(qs[0].astype(np.float32))])
    rot, pos = poses[:, :, :3, :3], poses[:, :, :3, 3]
    local = np.einsum("clji,cslj->csli", rot, world[:, :, None, :] - pos[:, None, :, :])  # (c, S, L, 3)
    spread = np.linalg.norm(local - local.mean(axis=0), axis=-1).max(axis=0)  # (S, L)
    fixed = spread <= 1e-4  # (S, L)
    if not fixed.any(axis=1).all():
        raise ValueError("VAMP's spheres: a sphere moves in every link's frame (another Panda model?)")
    own = robot_spheres(robot)
    own_world = own.world_centers(robot, qs[0])  # (S', 3)
    own_links = np.array(own.links)
    gap = np.full(fixed.shape, np.inf)
    for li, name in enumerate(links):
        mine = own_world[own_links == name]
        if len(mine):
            gap[:, li] = np.linalg.norm(world[0][:, None, :] - mine[None, :, :], axis=-1).min(axis=1)
    gap[~fixed] = np.inf
    # links without geometry of their own only when no candidate has any
    best = np.where(np.isfinite(gap).any(axis=1), gap.argmin(axis=1), np.where(fixed, spread, np.inf).argmin(axis=1))
    centers = local.mean(axis=0)[np.arange(len(best)), best]
    return RobotSpheres(robot="vamp_panda", links=tuple(links[i] for i in best), centers=centers, radii=radii,
                        excess=np.zeros(len(best)), max_error=math.nan, resolution=math.nan, padding=0.0,
                        geometry_hash="vamp")


# --- problems -----------------------------------------------------------------------------------

@dataclass
class Problem:
    """One planning problem: its family, obstacles, start and goal configurations."""

    family: str
    index: int
    obstacles: Obstacles
    start: NDArray[np.float64]
    goal: NDArray[np.float64]


class _Checkers:
    """Every validity check a problem's start and goal must pass (one per planner compared)."""

    def __init__(self, robot: genplan.Robot, obstacles: Obstacles, vamp: Any, vsph: RobotSpheres | None,
                 setup: RobotSetup, world: genplan.CollisionWorld | None = None) -> None:
        """``world``: the robot's world to reuse (its obstacles replaced by the problem's), or
        None: a new one."""
        if world is None:
            world = robot.collision_world()
        else:
            world.clear_obstacles()
        self.world = world
        self.world.add_scene(Scene(name="problem", obstacles=tuple(obstacles)))
        self.checks: list[Callable[[NDArray[np.float64]], NDArray[np.bool_]]] = [
            lambda q: ~np.asarray(self.world.in_collision(q), dtype=bool)]
        s = sphere_checker(robot, self.world)
        self.checks.append(lambda q: ~np.asarray(s.in_collision(q), dtype=bool))
        if vsph is not None:
            v = sphere_checker(robot, self.world, spheres=vsph)
            self.checks.append(lambda q: ~np.asarray(v.in_collision(q), dtype=bool))
        if vamp is not None and setup.vamp is not None:
            model = getattr(vamp, setup.vamp)
            env = vamp_environment(vamp, obstacles, setup.vamp_base)
            self.checks.append(lambda q: np.array([model.validate(r.astype(np.float32), env) for r in q]))

    def valid(self, q: NDArray[np.float64]) -> NDArray[np.bool_]:
        ok = np.ones(len(q), dtype=bool)
        for c in self.checks:
            ok &= c(q)
        return ok


def make_problems(robot: genplan.Robot, family: str, n: int, seed: int, vamp: Any = None,
                  vsph: RobotSpheres | None = None, max_scenes: int | None = None,
                  setup: RobotSetup | None = None) -> list[Problem]:
    """``n`` problems of ``family`` (seeded by ``seed`` and the family's name) for ``setup``'s
    robot (default the Panda): a scene, a start (the ready posture with jitter) and a goal (IK to
    the scene's grasp poses), both valid for every checker and within VAMP's joint bounds when
    VAMP plans too; scenes where either cannot be found are skipped (at most ``max_scenes``,
    default 20 n, are drawn; fewer problems are returned when they run out)."""
    setup = setup or ROBOTS["panda"]
    rng = np.random.default_rng([seed, sum(map(ord, family))])
    task = frame_task(robot, setup.tool)
    lower, upper = robot.lower, robot.upper
    model = getattr(vamp, setup.vamp) if vamp is not None and setup.vamp is not None else None
    if model is not None:  # the joint ranges both planners sample
        lower = np.maximum(lower, np.asarray(model.lower_bounds(), dtype=np.float64))
        upper = np.minimum(upper, np.asarray(model.upper_bounds(), dtype=np.float64))
    ready = np.asarray(setup.ready, dtype=np.float64)
    # one world for every scene drawn (building a mesh robot's takes longer than checking a
    # scene), unless the robot carries objects, which a cleared world would lose
    world = None if robot.attached else robot.collision_world()
    out: list[Problem] = []
    for _ in range(max_scenes or 20 * n):
        if len(out) == n:
            break
        obstacles, grasps = placed(setup, *FAMILIES[family](rng))
        checkers = _Checkers(robot, obstacles, vamp, vsph, setup, world)
        values = ready + rng.uniform(-setup.jitter, setup.jitter, (16, len(ready)))
        starts = robot.from_joint_values(values) if robot.continuous else np.clip(values, lower, upper)
        ok = checkers.valid(starts)
        if not ok.any():
            continue
        start = starts[int(np.argmax(ok))]
        goal = None
        for g in grasps:
            ik = solve_ik(robot, task, np.repeat(g[None], 8, axis=0), init="uniform", restarts=4,
                          seed=int(rng.integers(2**31)), parallel=False)
            cand = ik.q[ik.success]
            cand = cand[((cand >= lower) & (cand <= upper)).all(axis=1)]
            if len(cand):
                ok = checkers.valid(cand) & (np.linalg.norm(cand - start, axis=1) > 0.5)
                if ok.any():
                    goal = cand[int(np.argmax(ok))]
                    break
        if goal is not None:
            out.append(Problem(family, len(out), obstacles, start, goal))
    return out


# --- the arms -----------------------------------------------------------------------------------

def path_length(path: Any) -> float:
    """The joint-space L2 length of a path (rows of configurations)."""
    p = np.asarray(path, dtype=np.float64)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) if len(p) > 1 else 0.0


def settings() -> PlannerSettings:
    """genplan's free-space settings here: what a free-space plan gets by default
    (:data:`genplan.planning.FREE_SPACE_SETTINGS`: RRT-Connect, simplification on, a search budget
    of VAMP's order, its 100,000 iterations, so that a failure is the planner's, not a budget's)."""
    return FREE_SPACE_SETTINGS


def _genplan_arm(robot: genplan.Robot, problem: Problem, checker: Any, seed: int,
                 plan_settings: PlannerSettings | None = None) -> dict[str, Any]:
    """One genplan plan of ``problem`` with ``checker`` and ``plan_settings`` (default
    :func:`settings`), timed as the module text says."""
    world = robot.collision_world()
    world.add_scene(Scene(name="problem", obstacles=tuple(problem.obstacles)))
    if isinstance(checker, RobotSpheres):
        checker = sphere_checker(robot, world, spheres=checker)
    planner = Planner(robot, world, task="free", checker=checker, settings=plan_settings or settings(), seed=seed)
    t0 = time.perf_counter()
    r = planner.plan(problem.start, problem.goal)
    wall = time.perf_counter() - t0
    simplify = float(r.stats.simplify_s)
    return {"success": bool(r.success), "plan_ms": (wall - simplify) * 1e3, "simplify_ms": simplify * 1e3,
            "length": path_length(r.path) if r.success else math.nan, "checks": int(r.stats.validity_checks),
            "shortcuts": int(r.stats.shortcuts)}


def _vamp_arm(vamp: Any, problem: Problem, seed: int, setup: RobotSetup) -> dict[str, Any]:
    assert setup.vamp is not None
    model = getattr(vamp, setup.vamp)
    env = vamp_environment(vamp, problem.obstacles, setup.vamp_base)
    plan_settings = vamp.RRTCSettings()
    plan_settings.range = vamp.ROBOT_RRT_RANGES[setup.vamp]
    simplify_settings = vamp.SimplifySettings()
    rng = model.halton()
    rng.skip(seed % 1009)  # a different stretch of the sequence per problem
    start, goal = problem.start.astype(np.float32), problem.goal.astype(np.float32)
    t0 = time.perf_counter()
    r = model.rrtc(start, goal, env, plan_settings, rng)
    t1 = time.perf_counter()
    if not r.solved:
        return {"success": False, "plan_ms": (t1 - t0) * 1e3, "simplify_ms": math.nan, "length": math.nan}
    s = model.simplify(r.path, env, simplify_settings, rng)
    t2 = time.perf_counter()
    return {"success": bool(s.solved), "plan_ms": (t1 - t0) * 1e3, "simplify_ms": (t2 - t1) * 1e3,
            "length": path_length(s.path.numpy()) if s.solved else math.nan}


def run(families: list[str], n: int, seed: int, arms: list[str] | None = None, robot_name: str = "panda") -> dict[str, Any]:
    """Every problem of every family through every arm (VAMP's only when installed and shipping
    the robot; VAMP's spheres in genplan on the Panda only) for the robot ``robot_name`` (a key of
    :data:`ROBOTS`); the results per problem and the per-family summary."""
    setup = ROBOTS[robot_name]
    installed = vamp_module()
    vamp = installed if setup.vamp is not None else None
    robot = setup.load()
    vsph = vamp_spheres(vamp, robot) if vamp is not None and robot_name == "panda" else None
    arms = [a for a in (arms or ARMS) if a != "vamp" or vamp is not None]
    skipped = {} if vamp is not None else {
        "vamp": "not installed (pip install the vamp_planner wheel)" if installed is None else
        f"VAMP does not ship a {robot_name} model"}
    checker_of = {"genplan_spheres": "spheres", "genplan_hybrid": "hybrid", "genplan_vamp_spheres": vsph,
                  "genplan_exact": "exact"}
    if vsph is None and "genplan_vamp_spheres" in arms:
        arms.remove("genplan_vamp_spheres")
        skipped["genplan_vamp_spheres"] = ("needs VAMP's spheres: vamp not installed" if robot_name == "panda" else
                                           "VAMP's spheres are mapped onto the Panda only")
    peers: dict[str, Any] = {}
    for arm, make in (("roboplan", RoboplanArm), ("ompl", OmplArm)):
        if arm in arms:
            try:
                peers[arm] = make(robot, seed=seed)
            except (MissingExtraError, SettingsError) as exc:  # not installed; a robot it cannot plan
                arms.remove(arm)
                skipped[arm] = str(exc)
    load0 = os.getloadavg()
    t_start = time.time()
    records: list[dict[str, Any]] = []
    counts: dict[str, int] = {}
    for family in families:
        problems = make_problems(robot, family, n, seed, vamp, vsph, setup=setup)
        counts[family] = len(problems)
        for p in problems:
            order = arms if p.index % 2 == 0 else arms[::-1]  # alternate who runs first
            pseed = seed * 100_003 + p.index
            for arm in order:
                if arm in peers:
                    rec = peers[arm].plan(p.start, p.goal, p.obstacles, pseed)
                    rec.pop("path")
                else:
                    rec = (_vamp_arm(vamp, p, pseed, setup) if arm == "vamp" else
                           _genplan_arm(robot, p, checker_of[arm], pseed))
                records.append({"family": family, "problem": p.index, "arm": arm, **rec})
    rows = summarize(records, families, arms)
    robot_label = "panda (fingers open 0.04 m)" if robot_name == "panda" else robot_name
    return {"benchmark": "motion", "robot": robot_label, "problems_per_family": n, "seed": seed,
            "problems": counts, "arms": arms, "skipped": skipped, "settings": settings().to_dict(),
            "rows": rows, "records": records, "wall_s": time.time() - t_start, "load_1min_start": load0[0],
            "load_1min_end": os.getloadavg()[0], "machine": machine()}


def summarize(records: list[dict[str, Any]], families: list[str], arms: list[str]) -> list[dict[str, Any]]:
    """Per family and arm: success %, median plan / simplify ms, median length; every other arm
    against VAMP's (when it ran): the median per-problem length ratio and the plan-time ratio."""
    rows = []
    for family in families:
        by_arm = {a: [r for r in records if r["family"] == family and r["arm"] == a] for a in arms}
        vamp_len = {r["problem"]: r["length"] for r in by_arm.get("vamp", []) if r["success"]}
        vamp_ms = float(np.median([r["plan_ms"] for r in by_arm["vamp"]])) if by_arm.get("vamp") else math.nan
        for arm in arms:
            rs = by_arm[arm]
            ok = [r for r in rs if r["success"]]
            ratios = [r["length"] / vamp_len[r["problem"]] for r in ok if r["problem"] in vamp_len and vamp_len[r["problem"]] > 0]
            plan_ms = float(np.median([r["plan_ms"] for r in rs])) if rs else math.nan
            rows.append({
                "family": family, "arm": arm, "problems": len(rs),
                "success_pct": 100.0 * len(ok) / len(rs) if rs else math.nan,
                "plan_ms_median": plan_ms,
                "simplify_ms_median": float(np.median([r["simplify_ms"] for r in ok])) if ok else math.nan,
                "length_median": float(np.median([r["length"] for r in ok])) if ok else math.nan,
                "length_over_vamp_median": float(np.median(ratios)) if ratios else math.nan,
                "plan_ms_over_vamp": plan_ms / vamp_ms if vamp_ms > 0 else math.nan,
            })
    return rows


def print_table(payload: dict[str, Any]) -> None:
    print(table(
        ["family", "arm", "n", "success", "plan ms", "simplify ms", "length", "length / VAMP", "plan / VAMP"],
        [[r["family"], r["arm"], r["problems"], f"{r['success_pct']:.1f} %", r["plan_ms_median"],
          r["simplify_ms_median"], r["length_median"], r["length_over_vamp_median"], r["plan_ms_over_vamp"]]
         for r in payload["rows"]],
    ))
    for arm in payload["arms"]:
        if arm == "vamp":
            continue
        ratios = [r["plan_ms_over_vamp"] for r in payload["rows"] if r["arm"] == arm and r["plan_ms_over_vamp"] > 0]
        if ratios:
            print(f"{arm}: plan time / VAMP's, geometric mean over families: {geometric_mean(ratios):.2f}")
    for arm, why in payload["skipped"].items():
        print(f"{arm}: skipped: {why}")
    print(f"load average (1 min): {payload['load_1min_start']:.2f} at the start, {payload['load_1min_end']:.2f} at the end")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--families", nargs="+", choices=list(FAMILIES), default=list(FAMILIES), metavar="FAMILY",
                   help=f"problem families (default: all: {', '.join(FAMILIES)})")
    p.add_argument("--problems", type=A.positive_int, default=20, help="problems per family")
    p.add_argument("--arms", nargs="+", choices=list(ARMS), default=list(ARMS), metavar="ARM",
                   help=f"planners compared (default: all: {', '.join(ARMS)}; vamp only when installed)")
    p.add_argument("--robot", choices=list(ROBOTS), default="panda",
                   help="the robot (default panda; VAMP plans the panda, ur5 and baxter, genplan alone the kinova)")
    p.add_argument("--seed", type=A.seed, default=0)
    p.add_argument("--out", type=A.output_file, default=None, help="write the results as JSON (folders are created)")


def main(args: argparse.Namespace) -> int:
    payload = run(args.families, args.problems, args.seed, args.arms, args.robot)
    print_table(payload)
    write_json(args.out, payload)
    return 0
