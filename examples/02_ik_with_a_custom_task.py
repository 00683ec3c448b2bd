"""Inverse kinematics with a task of your own: Talos reaches a point with its right hand while both
feet stay where they are, its centre of mass stays over the feet, and its left hand keeps a fixed
height; warm-started from the shipped GAN.

    python examples/02_ik_with_a_custom_task.py
"""

from __future__ import annotations

import numpy as np

import genplan
from genplan import projection as P
from genplan.samplers import GanSampler


def main() -> None:
    robot = genplan.load("talos")
    targets = np.array([[0.45, -0.35, 0.95], [0.5, -0.2, 1.1], [0.35, -0.45, 0.8]])
    base = P.paper_task(robot, "ik")  # feet, CoM box, joint limits, left arm (the paper's IK task)
    left_hand_height = robot.frame_placement(robot.q_default, "gripper_left_base_link").translation
    task = P.Task(
        primary=[
            P.FramePosition(name="right_hand", frame="right_hand", target=targets[0], weight=50, tolerance=1e-3),
            *[t for t in base.primary if t.name not in ("right_hand_position", "left_arm")],
            # a new term: only the height (z) of the left gripper is constrained
            P.FramePosition(name="left_hand_height", frame="gripper_left_base_link", target=left_hand_height,
                            axes=(0.0, 0.0, 1.0), weight=20, tolerance=1e-3),
        ],
        secondary=[P.Posture(name="posture")],
        name="talos_reach_keep_left_hand_height",
    )
    solver = P.GaussNewtonProjector(robot, task)
    q0 = GanSampler(robot, seed=0).sample_for(targets)        # GAN initial guesses, one per target
    res = solver.solve_batch(q0, targets={"right_hand": targets})
    for i, t in enumerate(targets):
        hand = robot.frame_placement(res.q[i], "right_hand").translation
        print(f"target {t}: success {bool(res.success[i])} in {res.iterations[i]} steps, "
              f"{res.time_s[i] * 1e3:.2f} ms, hand error {np.linalg.norm(hand - t) * 1e3:.2f} mm")
    uniform = solver.solve_batch(robot.random_configurations(len(targets), 0), targets={"right_hand": targets})
    print(f"from uniform guesses instead: {int(uniform.success.sum())}/{len(targets)} in "
          f"{uniform.iterations.mean():.1f} steps on average")


if __name__ == "__main__":
    main()
