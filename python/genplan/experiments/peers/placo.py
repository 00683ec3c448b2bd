"""The placo peer of ``genplan bench peers``: placo's ``KinematicsSolver`` (a QP per step, hard joint
limits) on the same problems as genplan (:mod:`genplan.experiments.peers.ik`).

placo's wheels pin ``pin==3.8.0`` (compiled against it) while genplan runs on Pinocchio >= 4, so
placo cannot share genplan's interpreter: it runs in its own Python environment, given by
``--placo-python`` or ``$GENPLAN_PLACO_PYTHON`` (e.g. ``python -m venv /opt/placo &&
/opt/placo/bin/pip install placo numpy``), one worker process per call fed the problems through an
``.npz`` file (:data:`WORKER`, a script that imports only numpy and placo). The worker times each
problem itself (the process start and the URDF load are not counted).

Fixed base (the Panda): a position task and an axis-align task (the frame axis the task fixes
along its world vector; the rotation about it free, as in the task), both soft, joint limits hard.
Floating base (Talos' whole-body task): the soles' frame tasks (hard), the CoM inside the task's
box in x, y (``add_com_polygon_constraint``; placo has no bound on its height), the hand's position
task (soft), joint limits hard, the task's locked joints and its primary posture joints (the left
arm) held at their values (``mask_dof``). Each problem steps (``dt = 1``) until the worker's test
of the targets holds or ``iterations`` steps; answers are judged by genplan's
:func:`~genplan.experiments.peers.ik.success` like every solver's.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from genplan.errors import MissingExtraError
from genplan.experiments.peers.ik import IKOutcome, IKProblems, held_joints, success

ENV = "GENPLAN_PLACO_PYTHON"
HINT = (f"placo needs pin==3.8 (genplan: pin>=4): install it in its own environment "
        f"(python -m venv V && V/bin/pip install placo numpy) and give V/bin/python as --placo-python or ${ENV}")

WORKER = r'''
import sys, time
import numpy as np
import placo

d = np.load(sys.argv[1], allow_pickle=False)
out = sys.argv[2]
robot = placo.RobotWrapper(str(d["urdf"]), placo.Flags.ignore_collisions)
names = [str(n) for n in d["joint_names"]]
frame = str(d["frame"])
floating = bool(d["floating"])
solver = placo.KinematicsSolver(robot)
solver.mask_fbase(not floating)
solver.enable_joint_limits(True)
solver.enable_velocity_limits(False)
solver.dt = 1.0
held = {str(k): float(v) for k, v in zip(d["held_names"], d["held_values"])}
for name, value in held.items():
    robot.set_joint(name, value)
    solver.mask_dof(name)
hand = solver.add_position_task(frame, np.zeros(3))
hand.configure("position", "soft", 1.0)
checks = []
if floating:
    for k, (sole, T) in enumerate(zip(d["sole_frames"], d["sole_targets"])):
        task = solver.add_frame_task(str(sole), T)
        task.configure(f"sole{k}", "hard", 1.0, 1.0)
        checks.append((str(sole), T))
    lo, hi = d["com_box"]
    solver.add_com_polygon_constraint([np.array([lo[0], lo[1]]), np.array([hi[0], lo[1]]), np.array([hi[0], hi[1]]),
                                       np.array([lo[0], hi[1]])], 0.0)
else:
    align = solver.add_axisalign_task(frame, d["local_axis"], d["world_axis"])
    align.configure("axis", "soft", 1.0)
solver.add_regularization_task(1e-6)
n = len(d["positions"])
nq = 7 * floating + len(names)
q = np.full((n, nq), np.nan)
t = np.zeros(n)
iterations = int(d["iterations"])
ptol, otol, ftol = float(d["position_tol"]), float(d["orientation_tol"]), float(d["frame_tol"])


def done(i):
    T = robot.get_T_world_frame(frame)
    if np.max(np.abs(T[:3, 3] - d["positions"][i])) > ptol:
        return False
    if not floating:
        return np.linalg.norm(T[:3, :3] @ d["local_axis"] - d["world_axis"]) <= otol
    for sole, target in checks:
        S = robot.get_T_world_frame(sole)
        if np.max(np.abs(S[:3, 3] - target[:3, 3])) > ftol or np.max(np.abs(S[:3, :3] - target[:3, :3])) > ftol:
            return False
    return True


for i in range(n):
    t0 = time.perf_counter()
    start = d["starts"][i]
    if floating:
        state = robot.state.q.copy()
        state[:7] = start[:7]
        robot.state.q = state
    for j, name in enumerate(names):
        if name not in held:
            robot.set_joint(name, float(np.clip(start[7 * floating + j], d["lower"][j], d["upper"][j])))
    robot.update_kinematics()
    hand.target_world = d["positions"][i]
    for _ in range(iterations):
        try:
            solver.solve(True)
        except RuntimeError:  # placo's QPError: an infeasible step (hard constraints); a failure
            break
        robot.update_kinematics()
        if done(i):
            break
    q[i, 7 * floating:] = [robot.get_joint(name) for name in names]
    if floating:
        q[i, :7] = robot.state.q[:7]
    t[i] = time.perf_counter() - t0
np.savez(out, q=q, t=t)
'''


def python(path: str | os.PathLike[str] | None = None) -> Path | None:
    """The interpreter with placo: ``path``, else ``$GENPLAN_PLACO_PYTHON``, else None."""
    value = path if path is not None else os.environ.get(ENV)
    return Path(value) if value else None


def available(path: str | os.PathLike[str] | None = None) -> bool:
    exe = python(path)
    if exe is None or not exe.exists():
        return False
    return subprocess.run([str(exe), "-c", "import placo"], capture_output=True).returncode == 0


def _resolved_urdf(urdf: Path, package_dirs: list[Path], folder: Path) -> Path:
    """The URDF with every ``package://`` mesh path made absolute (placo resolves none)."""
    def absolute(m: re.Match[str]) -> str:
        for root in package_dirs:
            if (root / m.group(1)).exists():
                return str(root / m.group(1))
        return m.group(0)

    out = folder / urdf.name
    out.write_text(re.sub(r"package://([^\"']+)", absolute, urdf.read_text()))
    return out


def solve(pb: IKProblems, iterations: int = 100, placo_python: str | os.PathLike[str] | None = None) -> IKOutcome:
    from genplan import projection as P

    exe = python(placo_python)
    if exe is None or not available(exe):
        raise MissingExtraError(f"the placo peer: {HINT}")
    robot = pb.robot
    joints = [j for j in robot.joint_names]
    lower = robot.lower[7:] if robot.floating_base else robot.lower
    upper = robot.upper[7:] if robot.floating_base else robot.upper
    held = {**robot.locked_joints, **held_joints(pb)}
    soles = [t for t in pb.task.primary if isinstance(t, P.FramePose)]
    boxes = [t for t in pb.task.primary if isinstance(t, P.ComBox)]
    fields: dict[str, Any] = {}
    if robot.floating_base:
        targets = [np.asarray(getattr(t.target, "homogeneous", t.target), dtype=np.float64) for t in soles]
        fields = {"sole_frames": np.array([robot.frames.get(t.frame, t.frame) for t in soles]),
                  "sole_targets": np.array(targets), "frame_tol": min(float(t.tolerance) for t in soles),
                  "com_box": np.array([boxes[0].lower, boxes[0].upper]) if boxes else np.array([[-1e3] * 3, [1e3] * 3]),
                  "local_axis": np.zeros(3), "world_axis": np.zeros(3), "orientation_tol": 0.0}
        note = ("soles hard, CoM polygon (the box's x, y), hand position soft, joint limits hard, "
                f"left arm and locked joints masked, dt 1, <= {iterations} QPs")
    else:
        local, world = pb.axis
        fields = {"local_axis": local, "world_axis": world, "orientation_tol": float(pb.orientation.tolerance),
                  "frame_tol": 0.0}
        note = f"position + axis-align tasks (soft), hard joint limits, dt 1, <= {iterations} QPs"
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        urdf = _resolved_urdf(robot.urdf_path, robot.package_dirs, folder)
        np.savez(folder / "in.npz", urdf=str(urdf), joint_names=np.array(joints), frame=pb.frame,
                 floating=robot.floating_base, held_names=np.array(list(held), dtype=str),
                 held_values=np.array(list(held.values()), dtype=np.float64), positions=pb.positions,
                 starts=pb.starts, lower=lower, upper=upper, iterations=iterations, position_tol=pb.position_tol,
                 **fields)
        (folder / "worker.py").write_text(WORKER)
        env = {**os.environ, "OMP_NUM_THREADS": "1"}
        proc = subprocess.run([str(exe), str(folder / "worker.py"), str(folder / "in.npz"), str(folder / "out.npz")],
                              capture_output=True, text=True, env=env)
        if proc.returncode != 0:
            sys.stderr.write(proc.stderr)
            raise RuntimeError(f"the placo worker failed (exit {proc.returncode}): {proc.stderr.strip()[-300:]}")
        res = np.load(folder / "out.npz")
        q, t = res["q"], res["t"]
    return IKOutcome("placo", q, success(pb, q), t, note=f"{note}; own interpreter {exe}")
