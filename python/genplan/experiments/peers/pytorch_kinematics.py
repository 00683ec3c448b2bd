"""The pytorch-kinematics peer of ``genplan bench peers``: ``PseudoInverseIK`` (damped
least squares, batched in torch, float64 on the CPU) on the same problems as genplan
(:mod:`genplan.experiments.peers.ik`).

pytorch-kinematics has no way to free one rotation axis, so its target is the full pose of the
condition frame at the configuration the target was made from (a solution of the task; a
stricter problem than the others'). All problems go in one batched call, one retry each, warm
started at the problems' starts, joint limits enforced (clamped each step); the time per
problem is the call's wall time over the number of problems.
"""

from __future__ import annotations

import time

import numpy as np

from genplan.errors import MissingExtraError
from genplan.experiments.peers.ik import HINT, IKOutcome, IKProblems, importable, success


def available() -> bool:
    return importable("pytorch_kinematics")


def solve(pb: IKProblems, iterations: int = 100, threads: int = 1) -> IKOutcome:
    try:
        import pytorch_kinematics as pk
        import torch
    except ImportError:
        raise MissingExtraError(f"the pytorch-kinematics peer needs pytorch-kinematics ({HINT})") from None
    from genplan._threads import torch_threads

    with torch_threads("small", threads):
        chain = pk.build_serial_chain_from_urdf(pb.robot.urdf_path.read_bytes(), pb.frame).to(dtype=torch.float64)
        names = chain.get_joint_parameter_names()
        order = [pb.robot.joint_names.index(n) for n in names]
        lo, hi = pb.robot.lower[order], pb.robot.upper[order]
        starts = np.clip(pb.starts[:, order], lo, hi)
        m = len(pb)
        goal = np.tile(np.eye(4), (m, 1, 1))
        goal[:, :3, :3] = pb.rotations
        goal[:, :3, 3] = pb.positions
        t0 = time.perf_counter()
        ik = pk.PseudoInverseIK(chain, pos_tolerance=pb.position_tol, rot_tolerance=float(pb.orientation.tolerance),
                                retry_configs=torch.from_numpy(starts[:1]), joint_limits=torch.from_numpy(
                                    np.stack([lo, hi], axis=1)), max_iterations=iterations,
                                early_stopping_any_converged=True, early_stopping_no_improvement=None)
        ik.initial_config = torch.from_numpy(starts).reshape(m, 1, -1)  # one start per problem (solve accepts (M, 1, dof))
        sol = ik.solve(pk.Transform3d(matrix=torch.from_numpy(goal)))
        wall = time.perf_counter() - t0
        q_pk = sol.solutions.reshape(m, -1).numpy()
    q = np.empty((m, pb.robot.nq))
    q[:, order] = q_pk
    return IKOutcome("pytorch-kinematics", q, success(pb, q), np.full(m, wall / m),
                     note=f"PseudoInverseIK, full pose target, one batched call, <= {iterations} iterations, "
                          f"{threads} torch thread(s)")
