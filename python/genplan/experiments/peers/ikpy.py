"""The ikpy peer of ``genplan bench peers``: ``Chain.inverse_kinematics`` (scipy least squares with
the joint limits as bounds) on the same problems as genplan (:mod:`genplan.experiments.peers.ik`).

The chain is read from the robot's URDF (base to the condition frame, genplan's joints active);
the orientation is ikpy's single-axis mode: the frame axis the task's constraint fixes
(``orientation_mode`` "X", "Y" or "Z") must point along the target vector, which leaves the
rotation about that axis free, as the task does.
"""

from __future__ import annotations

import warnings

import numpy as np

from genplan.errors import MissingExtraError
from genplan.experiments.peers.ik import HINT, IKOutcome, IKProblems, importable, per_problem


def available() -> bool:
    return importable("ikpy")


def chain(pb: IKProblems) -> tuple[object, list[int]]:
    """The ikpy chain from the URDF's root to ``pb.frame`` and, per genplan joint, its link index."""
    try:
        from ikpy.chain import Chain
    except ImportError:
        raise MissingExtraError(f"the ikpy peer needs ikpy ({HINT})") from None
    root = pb.robot.model.frames[1].name  # the URDF's root link (frame 0 is Pinocchio's universe)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        full = Chain.from_urdf_file(str(pb.robot.urdf_path), base_elements=[root])
    # cut the chain at the joint that carries the frame (the frame's parent link's child joint)
    parent = pb.robot.model.frames[pb.robot.model.frames[pb.robot.frame_id(pb.frame)].parentFrame].name
    names = [link.name for link in full.links]
    end = names.index(parent) + 1 if parent in names else len(names)
    links = full.links[:end]
    index = [names.index(j) for j in pb.robot.joint_names]
    mask = [i in index for i in range(len(links))]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Chain(links, active_links_mask=mask, name=pb.robot.name), index


def solve(pb: IKProblems, max_iter: int = 100) -> IKOutcome:
    ch, index = chain(pb)
    axis, sign = pb.free_axis
    mode = "XYZ"[axis]
    vector = sign * pb.axis[1]
    n_links = len(ch.links)  # type: ignore[attr-defined]

    def one(i: int) -> np.ndarray:
        start = np.zeros(n_links)
        start[index] = np.clip(pb.starts[i], pb.robot.lower, pb.robot.upper)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sol = ch.inverse_kinematics(target_position=pb.positions[i], target_orientation=vector,  # type: ignore[attr-defined]
                                        orientation_mode=mode, initial_position=start, max_iter=max_iter)
        return np.asarray(sol)[index]

    return per_problem(pb, "ikpy", one, note=f"least squares, limits as bounds, axis mode {mode}, max_iter {max_iter}")
