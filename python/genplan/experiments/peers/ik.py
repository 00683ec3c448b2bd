"""One IK problem set for every IK peer of ``genplan bench peers``, and the one success test.

A problem is a genplan IK task with a [condition] (a frame position target): the Panda's (hand
position, "gripper horizontal, yaw free" orientation, joint limits) or Talos' whole-body one (right
hand position, soles, CoM box, left arm posture, joint limits). Every solver gets the same targets
and the same warm starts and says the task its own way (see each adapter); the Panda's orientation
term ``axes * log3(target^T R offset) == 0`` with ``axes = (1, 1, 0)`` is the same set as
``R(q) @ local_axis == world_axis`` with ``local_axis = offset[:, 2]``, ``world_axis =
target[:, 2]`` (:attr:`IKProblems.axis`). The answers of every solver, genplan's included, are
judged by :func:`success`: the task's own test.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

import genplan
from genplan import projection as P

Array = NDArray[np.float64]

#: how to install the peers that share genplan's interpreter
HINT = "pip install 'genplan[peers]'"


def importable(*modules: str) -> bool:
    """Whether every module imports (a peer's availability)."""
    import importlib

    try:
        for m in modules:
            importlib.import_module(m)
    except ImportError:
        return False
    return True


@dataclass
class IKProblems:
    """n IK problems of one robot and task: position targets (n, 3) of the condition frame, the
    configurations they were made from (n, nq: solutions) and the frame's rotation there (n, 3, 3;
    only a peer without a way to free one axis uses it), one warm start per target (n, nq)."""

    robot: genplan.Robot
    task: P.Task
    frame: str  #: the URDF link of the condition term
    positions: Array
    rotations: Array
    solutions: Array
    starts: Array

    def __len__(self) -> int:
        return len(self.positions)

    def take(self, rows: NDArray[np.intp]) -> "IKProblems":
        """The problems ``rows`` only."""
        return replace(self, positions=self.positions[rows], rotations=self.rotations[rows],
                       solutions=self.solutions[rows], starts=self.starts[rows])

    @property
    def position_tol(self) -> float:
        return float(P.condition_term(self.task).tolerance)

    @property
    def orientation(self) -> P.FrameOrientation:
        """The task's one FrameOrientation term, with one free axis (ValueError otherwise)."""
        ori = [t for t in self.task.primary if isinstance(t, P.FrameOrientation)]
        if len(ori) != 1 or sorted(np.asarray(ori[0].axes, dtype=float).tolist()) != [0.0, 1.0, 1.0]:
            raise ValueError(f"task {self.task.name}: expected one FrameOrientation term with one free axis")
        return ori[0]

    @property
    def axis(self) -> tuple[Array, Array]:
        """(local_axis, world_axis): the orientation term as ``R(q) @ local_axis == world_axis``."""
        o = self.orientation
        offset = np.eye(3) if o.offset is None else np.asarray(o.offset, dtype=np.float64)
        target = np.eye(3) if o.target is None else np.asarray(o.target, dtype=np.float64)
        free = int(np.argmin(np.asarray(o.axes, dtype=float)))
        return offset[:, free].copy(), target[:, free].copy()

    @property
    def free_axis(self) -> tuple[int, float]:
        """(index, sign) of the frame's coordinate axis the orientation leaves free."""
        local = self.axis[0]
        i = int(np.argmax(np.abs(local)))
        if abs(abs(local[i]) - 1.0) > 1e-9:
            raise ValueError(f"the free axis {local} is not a coordinate axis of the frame")
        return i, float(np.sign(local[i]))


def problems(robot: genplan.Robot, task: P.Task, valid: Array, starts: Array) -> IKProblems:
    """Problems whose targets are the condition frame's positions at ``valid`` configurations (on
    the task's manifold, hence reachable), warm started at ``starts``."""
    cond = P.condition_term(task)
    frame = robot.frames.get(cond.frame, cond.frame)
    poses = robot.link_poses(valid, [frame])[:, 0]
    return IKProblems(robot=robot, task=task, frame=frame, positions=poses[:, :3, 3].copy(),
                      rotations=poses[:, :3, :3].copy(), solutions=np.asarray(valid, dtype=np.float64).copy(),
                      starts=np.asarray(starts, dtype=np.float64))


def held_joints(pb: IKProblems) -> dict[str, float]:
    """Joints a peer holds fixed (name -> value): those of the task's primary postures (their
    weighted joints at ``q_nom``; Talos' left arm)."""
    held: dict[str, float] = {}
    model = pb.robot.model
    for term in pb.task.primary:
        if isinstance(term, P.Posture):
            weights = np.asarray(term.joint_weights, dtype=float)
            nominal = np.asarray(term.q_nom, dtype=float)
            for jid in range(1, model.njoints):
                j = model.joints[jid]
                if j.nq == 1 and j.nv == 1 and weights[j.idx_v] > 0:
                    held[model.names[jid]] = float(nominal[j.idx_q])
    return held


def success(pb: IKProblems, q: Array) -> NDArray[np.bool_]:
    """The one success test: the task's own, i.e. genplan's solver finds every primary term within
    its tolerance at ``q`` before taking any step (position, orientation, soles, CoM box, joint
    limits, ... whatever the task holds); a row with NaN fails."""
    q = np.asarray(q, dtype=np.float64)
    ok = np.all(np.isfinite(q), axis=1)
    qs = pb.robot.normalize(np.where(ok[:, None], q, pb.robot.q_default))
    solver = P.GaussNewtonProjector(pb.robot, pb.task, P.SolverSettings(max_iterations=1))
    res = solver.solve_batch(qs, targets={P.condition_term(pb.task).name: pb.positions}, parallel=False)
    return ok & res.success & (res.iterations == 0)


@dataclass
class IKOutcome:
    """One solver on the problems: its answers judged by :func:`success`; ``time_s`` per problem
    (its own solve, one problem after the other on one core)."""

    solver: str
    q: Array
    success: NDArray[np.bool_]
    time_s: Array
    note: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    @staticmethod
    def concat(parts: list["IKOutcome"]) -> "IKOutcome":
        """One outcome from the outcomes of consecutive chunks of the problems."""
        return IKOutcome(parts[0].solver, np.concatenate([p.q for p in parts]),
                         np.concatenate([p.success for p in parts]), np.concatenate([p.time_s for p in parts]),
                         parts[0].note, parts[0].extra)

    def summary(self) -> dict[str, Any]:
        solved = int(self.success.sum())
        total = float(self.time_s.sum())
        return {"solver": self.solver, "problems": len(self.success), "solved": solved,
                "success_percent": 100.0 * solved / max(len(self.success), 1),
                "ms_per_problem": 1e3 * total / max(len(self.success), 1),
                "ms_per_solved": 1e3 * total / solved if solved else None,
                "ms_mean_solved_only": 1e3 * float(self.time_s[self.success].mean()) if solved else None,
                "note": self.note, **self.extra}


def per_problem(pb: IKProblems, solver: str, solve_one: Callable[[int], Array], note: str = "") -> IKOutcome:
    """Run ``solve_one(i) -> q`` on every problem, timing each, and judge the answers."""
    q = np.full((len(pb), pb.robot.nq), np.nan)
    t = np.zeros(len(pb))
    for i in range(len(pb)):
        t0 = time.perf_counter()
        q[i] = solve_one(i)
        t[i] = time.perf_counter() - t0
    return IKOutcome(solver, q, success(pb, q), t, note)
