"""The pink peer of ``genplan bench peers``: differential IK as a QP (pin-pink, solver daqp) on the
same problems as genplan (:mod:`genplan.experiments.peers.ik`).

A :class:`pink.tasks.FrameTask` on the condition frame: its position target, and its orientation
target (the frame's rotation at the configuration the target was made from) with cost 0 on the
frame axis the task leaves free (pink's orientation error is in the frame's own axes, so that
axis's rotation is free, as in genplan's task). The joint limits are hard constraints of every
QP (``pink.limits.ConfigurationLimit``; no velocity limit: ``dt = 1`` makes each QP a
Gauss-Newton step). Iterate until :func:`~genplan.experiments.peers.ik.success` holds or
``iterations`` steps.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from genplan.errors import MissingExtraError
from genplan.experiments.peers.ik import HINT, IKOutcome, IKProblems, held_joints, importable, per_problem


def available() -> bool:
    return importable("pink", "daqp")


def solve(pb: IKProblems, iterations: int = 100, damping: float = 1e-6) -> IKOutcome:
    try:
        import pink  # noqa: F401
    except ImportError:
        raise MissingExtraError(f"the pink peer needs pin-pink and daqp ({HINT})") from None
    return _whole_body(pb, iterations, damping) if pb.robot.floating_base else _arm(pb, iterations, damping)


def _arm(pb: IKProblems, iterations: int, damping: float) -> IKOutcome:
    import pink
    from pink.limits import ConfigurationLimit
    from pink.tasks import FrameTask

    model = pb.robot.model
    data = model.createData()
    axis, _ = pb.free_axis
    cost = np.ones(3)
    cost[axis] = 0.0
    limits = [ConfigurationLimit(model)]
    lo, hi = pb.robot.lower, pb.robot.upper
    fid = model.getFrameId(pb.frame)
    otol = float(pb.orientation.tolerance)

    def one(i: int) -> np.ndarray:
        task = FrameTask(pb.frame, position_cost=1.0, orientation_cost=cost.tolist())
        task.set_target(pin.SE3(pb.rotations[i], pb.positions[i]))
        config = pink.Configuration(model, data, np.clip(pb.starts[i], lo, hi))
        for _ in range(iterations):
            v = pink.solve_ik(config, [task], dt=1.0, solver="daqp", damping=damping, limits=limits,
                              safety_break=False)
            config.integrate_inplace(v, 1.0)
            oMf = config.data.oMf[fid]
            if (np.max(np.abs(oMf.translation - pb.positions[i])) <= pb.position_tol
                    and np.max(np.abs(cost * pin.log3(pb.rotations[i].T @ oMf.rotation))) <= otol):
                break
        return np.array(config.q)

    return per_problem(pb, "pink (daqp)", one,
                       note=f"FrameTask, free axis cost 0, hard joint limits, dt 1, <= {iterations} QPs")


def _whole_body(pb: IKProblems, iterations: int, damping: float) -> IKOutcome:
    """Talos' task: the hand's position a task, the soles' poses equality constraints of every QP,
    the held joints (the task's primary posture) fixed by their limits, joint limits hard; pink
    has no CoM inequality (the CoM box is left to the success test)."""
    import pink
    from pink.limits import ConfigurationLimit
    from pink.tasks import FrameTask

    from genplan import projection as P

    model = pb.robot.model.copy()
    held = held_joints(pb)
    for name, value in held.items():
        j = model.joints[model.getJointId(name)]
        model.lowerPositionLimit[j.idx_q] = model.upperPositionLimit[j.idx_q] = value
    data = model.createData()
    limits = [ConfigurationLimit(model)]
    soles = []
    for term in pb.task.primary:
        if isinstance(term, P.FramePose):
            frame = pb.robot.frames.get(term.frame, term.frame)
            target = term.target if isinstance(term.target, pin.SE3) else pin.SE3(np.asarray(term.target))
            sole = FrameTask(frame, position_cost=1.0, orientation_cost=1.0)
            sole.set_target(target)
            soles.append((sole, model.getFrameId(frame), target, float(term.tolerance)))
    fid = model.getFrameId(pb.frame)
    held_q = [(model.joints[model.getJointId(n)].idx_q, v) for n, v in held.items()]

    def one(i: int) -> np.ndarray:
        hand = FrameTask(pb.frame, position_cost=1.0, orientation_cost=0.0)
        hand.set_target(pin.SE3(np.eye(3), pb.positions[i]))
        q0 = np.clip(pb.robot.normalize(pb.starts[i]), pb.robot.lower, pb.robot.upper)
        for k, v in held_q:
            q0[k] = v
        config = pink.Configuration(model, data, q0)
        for _ in range(iterations):
            try:
                v = pink.solve_ik(config, [hand], dt=1.0, solver="daqp", damping=damping, limits=limits,
                                  constraints=[s for s, *_ in soles], safety_break=False)
            except Exception:  # noqa: BLE001 - pink's NoSolutionFound: an infeasible QP is a failure
                break
            config.integrate_inplace(v, 1.0)
            d = config.data
            if np.max(np.abs(d.oMf[fid].translation - pb.positions[i])) <= pb.position_tol and all(
                    np.max(np.abs(pin.log6(t.actInv(d.oMf[f])).vector)) <= tol for _, f, t, tol in soles):
                break
        return np.array(config.q)

    return per_problem(pb, "pink (daqp)", one,
                       note="hand position task, soles as equality constraints, held joints and joint limits hard, "
                            f"no CoM bound, dt 1, <= {iterations} QPs")
