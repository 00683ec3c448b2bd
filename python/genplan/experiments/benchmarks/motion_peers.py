"""The motion benchmark's other peers: roboplan and OMPL's RRTConnect, each planning the same
problems as VAMP and genplan (python/genplan/experiments/benchmarks/motion.py), one call per
problem from Python, planning and path simplification timed apart.

* ``roboplan`` (``pip install roboplan``, the ``peers`` extra; never a dependency of genplan):
  Pinocchio + coal on the robot's own URDF and SRDF (the file genplan reads: its collision meshes
  as coal meshes, its SRDF's disabled pairs), the robot's joints as one group and its locked joints
  held at their values; RRT-Connect (``roboplan.rrt.RRT`` with ``rrt_connect=True``, its default
  0.05 rad edge checks, 20,000 nodes) then its ``PathShortcutter``. Boxes go in as boxes, an
  upright capsule as a cylinder with a ball at each end (the same solid).
* ``ompl`` (the ``ompl`` wheel, the ``bench`` extra): ``og.SimpleSetup`` on a real vector space
  bounded by the robot's joint limits, RRTConnect with OMPL's default range, states and motions
  checked by genplan's exact collision world from a Python callback (each state one
  ``CollisionWorld.in_collision`` call, the motion resolution 0.025 rad of the space's extent as
  genplan's), then ``simplifySolution``. OMPL as a Python user drives it: the callback's cost is
  part of its time.

Each returns the same record as the other arms: ``success``, ``plan_ms``, ``simplify_ms``,
``length`` (joint-space L2 length of the final path), and the final ``path`` (rows of
configurations; None on failure), which the benchmark drops from its JSON.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

import genplan
from genplan.errors import MissingExtraError, SettingsError
from genplan.scene import Box, Capsule, Scene

#: genplan's edge resolution (rad), given to OMPL as the fraction of its space's extent
EDGE_RESOLUTION = 0.025
#: the search budget, as genplan's (motion.settings: 20,000 extensions)
MAX_NODES = 20_000
#: seconds OMPL and roboplan may search one problem
TIME_LIMIT = 10.0


def _length(path: NDArray[np.float64]) -> float:
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum()) if len(path) > 1 else 0.0


def _pose_matrix(pose: Any) -> NDArray[np.float64]:
    """A scene pose as a 4 x 4 in Fortran order, as roboplan takes it."""
    m = np.eye(4, order="F")
    m[:3, :3] = pose.matrix()
    m[:3, 3] = pose.position
    return m


def _no_continuous(robot: genplan.Robot, arm: str) -> None:
    """SettingsError for a robot with continuous joints (genplan's q holds each as cos, sin): these
    arms plan joint angles in a bounded real vector space."""
    if robot.continuous:
        raise SettingsError(f"{arm} arm plans bounded joint angles; robot {robot.name!r} has continuous joints "
                            f"(their configuration is cos, sin)")


class RoboplanArm:
    """roboplan on ``robot``'s URDF and SRDF; :meth:`plan` one problem at a time (its obstacles
    replace the previous problem's)."""

    def __init__(self, robot: genplan.Robot, seed: int = 0) -> None:  # seed: per plan (roboplan's RNG is the planner's)
        try:
            import roboplan.core as rc
            import roboplan.rrt as rr
        except ImportError as exc:
            raise MissingExtraError(f"roboplan is not installed ({exc}): pip install roboplan (the 'peers' extra)") from None
        _no_continuous(robot, "roboplan's")
        self.rc, self.rr = rc, rr
        self.scene = rc.Scene(robot.name, rc.loadUrdfSceneDescription(str(robot.urdf_path),
                                                                       [str(p) for p in robot.package_dirs]))
        if robot.srdf_path is not None:
            self.scene.importSrdf(robot.srdf_path.read_text())
        self.names = list(robot.joint_names)
        self.scene.addGroup("genplan", self.names)
        full = np.asarray(self.scene.getCurrentJointPositions(), dtype=np.float64)
        every = list(self.scene.getJointNames())
        for name, value in (robot.locked_joints or {}).items():
            if name in every:
                full[every.index(name)] = float(value)
        self.full = full
        self.obstacles: list[str] = []

    def _place(self, obstacles: list[Any]) -> None:
        rc, scene = self.rc, self.scene
        for name in self.obstacles:
            scene.removeGeometry(name)
        self.obstacles = []
        colour = np.array([0.5, 0.5, 0.5, 0.5])
        for o in obstacles:
            m = _pose_matrix(o.pose)
            if isinstance(o, Box):
                scene.addBoxGeometry(o.name, "universe", rc.Box(*(2.0 * h for h in o.half_extents)), m, colour)
                self.obstacles.append(o.name)
            elif isinstance(o, Capsule):
                scene.addCylinderGeometry(o.name, "universe", rc.Cylinder(float(o.radius), float(o.length)), m, colour)
                self.obstacles.append(o.name)
                for k, s in enumerate((-0.5, 0.5)):
                    end = m.copy(order="F")
                    end[:3, 3] = m[:3, 3] + m[:3, 2] * s * float(o.length)
                    scene.addSphereGeometry(f"{o.name}_end{k}", "universe", rc.Sphere(float(o.radius)), end, colour)
                    self.obstacles.append(f"{o.name}_end{k}")
            else:
                raise SettingsError(f"obstacle {o.name!r}: roboplan's arm takes boxes and capsules, got {type(o).__name__}")
        # obstacles touching each other (a shelf's boards and walls) are no contact of the robot's
        names = self.obstacles
        scene.setCollisions([(a, b) for i, a in enumerate(names) for b in names[i + 1:]], False)
        scene.setJointPositions(self.full)

    def plan(self, start: NDArray[np.float64], goal: NDArray[np.float64], obstacles: list[Any], seed: int) -> dict[str, Any]:
        rc, rr = self.rc, self.rr
        self._place(obstacles)
        options = rr.RRTOptions(group_name="genplan", rrt_connect=True, max_nodes=MAX_NODES, max_planning_time=TIME_LIMIT)
        rrt = rr.RRT(self.scene, options)
        rrt.setRngSeed(seed)
        shortcutter = rc.PathShortcutter(self.scene, rc.PathShortcuttingOptions(group_name="genplan", seed=seed))
        t0 = time.perf_counter()
        try:
            raw = rrt.plan(rc.JointConfiguration(self.names, np.asarray(start, dtype=np.float64)),
                           rc.JointConfiguration(self.names, np.asarray(goal, dtype=np.float64)))
        except RuntimeError:  # roboplan raises when it finds no path within its budget
            return {"success": False, "plan_ms": (time.perf_counter() - t0) * 1e3, "simplify_ms": math.nan,
                    "length": math.nan, "path": None}
        t1 = time.perf_counter()
        short = shortcutter.shortcut(raw)
        t2 = time.perf_counter()
        path = np.asarray(short.positions, dtype=np.float64)
        ok = len(path) > 0
        return {"success": ok, "plan_ms": (t1 - t0) * 1e3, "simplify_ms": (t2 - t1) * 1e3,
                "length": _length(path) if ok else math.nan, "path": path if ok else None}


class OmplArm:
    """OMPL's RRTConnect on a real vector space, genplan's exact world as its validity checker.
    OMPL's generator is seeded once per process, before its first sample (it cannot be seeded
    again after that): :meth:`plan`'s ``seed`` is not used, and its draws depend on the order the
    problems run in (the benchmark's order is fixed) and on no other OMPL use before it."""

    def __init__(self, robot: genplan.Robot, seed: int = 0) -> None:
        from genplan.experiments.peers.ompl import _ompl  # the OMPL peer's one import of the bindings

        try:
            ob, og, ou = _ompl()
        except ImportError as exc:
            raise MissingExtraError(str(exc)) from None
        _no_continuous(robot, "OMPL's")
        self.ob, self.og, self.ou, self.robot = ob, og, ou, robot
        ou.setLogLevel(ou.LogLevel.LOG_WARN)
        # OMPL seeds its generator once per process, before its first sample (the problems then
        # draw from one stream, in the order they run)
        ou.RNG.setSeed(seed % (2**31 - 1) + 1)
        self.space = ob.RealVectorStateSpace(robot.nq)
        bounds = ob.RealVectorBounds(robot.nq)
        for i, (lo, hi) in enumerate(zip(robot.lower, robot.upper)):
            bounds.setLow(i, float(lo))
            bounds.setHigh(i, float(hi))
        self.space.setBounds(bounds)
        self.nq = robot.nq

    def plan(self, start: NDArray[np.float64], goal: NDArray[np.float64], obstacles: list[Any], seed: int) -> dict[str, Any]:
        ob, og, nq = self.ob, self.og, self.nq
        world = self.robot.collision_world()
        world.add_scene(Scene(name="problem", obstacles=tuple(obstacles)))
        q = np.zeros(nq)

        def valid(state: Any) -> bool:
            for i in range(nq):
                q[i] = state[i]
            return not world.in_collision(q)

        ss = og.SimpleSetup(self.space)
        ss.setStateValidityChecker(valid)
        extent = self.space.getMaximumExtent()
        ss.getSpaceInformation().setStateValidityCheckingResolution(EDGE_RESOLUTION / extent)
        a, b = self.space.allocState(), self.space.allocState()
        for i in range(nq):
            a[i], b[i] = float(start[i]), float(goal[i])
        ss.setStartAndGoalStates(a, b)
        ss.setPlanner(og.RRTConnect(ss.getSpaceInformation()))
        ss.setup()
        t0 = time.perf_counter()
        solved = ss.solve(TIME_LIMIT)
        t1 = time.perf_counter()
        if not solved or not ss.haveExactSolutionPath():
            return {"success": False, "plan_ms": (t1 - t0) * 1e3, "simplify_ms": math.nan, "length": math.nan, "path": None}
        ss.simplifySolution()
        t2 = time.perf_counter()
        states = np.array([[st[i] for i in range(nq)] for st in ss.getSolutionPath().getStates()], dtype=np.float64)
        return {"success": True, "plan_ms": (t1 - t0) * 1e3, "simplify_ms": (t2 - t1) * 1e3, "length": _length(states),
                "path": states}
