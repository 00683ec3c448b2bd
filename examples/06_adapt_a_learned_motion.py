"""Adapt a learned family of motions to new goals and to a new obstacle (the seq2seq paper's latent
adjustment, on a robot of one's own).

The Panda moves its hand, kept level (task ``panda_projection``), from the front of the shelf
scene to its side shelf. genplan's planner makes the family (start and goal hand positions in two
boxes), a small seq2seq model learns it, and new motions come from gradient descent on the
model's latent vector:

1. new end targets: each input is the data's motion whose end lies nearest the target; the
   objective asks for the hand at the target, within the joint limits, near the input's shape;
2. a new obstacle: a 5 cm ball on a motion's own path at mid-time; the objective adds its
   clearance, the scene's and the arm's own (spheres on the links), and the task's residuals.

Each adjusted motion is finished (``result.finish()``: projected onto the task's manifold with
the end target, every dense state checked against the scene, timed by TOPP-RA) and counted as
a success only when it passes those checks.

    python examples/06_adapt_a_learned_motion.py                       # 300 motions, about 4 minutes
    python examples/06_adapt_a_learned_motion.py --count 60 --epochs 30  # a smaller model, under a minute

``--out-dir`` gets the model (``family.safetensors`` + card) and, with genplan[viewer], the
views of both cases (``new_goal.html``, ``obstacle.html``).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

import genplan
from genplan.scene import Pose, Sphere, load_scene
from genplan.seq2seq.data import plan_trajectories
from genplan.seq2seq.objectives import (AvoidSpheres, Clearance, Constraint, EndPosition, JointLimits, Objective,
                                        SelfClearance, StayNear)
from genplan.seq2seq.train import train_family

START_BOX = [[0.45, -0.3, 0.15], [0.75, 0.3, 0.3]]  # the hand at the start (m, base frame)
GOAL_BOX = [[-0.4, 0.62, 0.15], [-0.05, 0.7, 0.25]]  # and at the goal: on the side shelf


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--count", type=int, default=300, help="planned motions in the family")
    p.add_argument("--epochs", type=int, default=100)
    p.add_argument("--problems", type=int, default=5, help="new end targets")
    p.add_argument("--out-dir", type=Path, default=Path("out/adapt"))
    args = p.parse_args()

    robot = genplan.load("panda")
    scene = load_scene("panda_shelf")
    t0 = time.perf_counter()
    data = plan_trajectories(robot, "panda_projection", scene, count=args.count, steps=32, seed=0, start_box=START_BOX,
                             goal_box=GOAL_BOX, frame="hand", spread=0.3, progress=False)
    print(f"family: {len(data)} planned motions of {data.K} samples in {time.perf_counter() - t0:.0f} s")
    t0 = time.perf_counter()
    model = train_family(data, seed=0, epochs=args.epochs, progress=False)
    model.save(args.out_dir / "family.safetensors")
    ev = model.card["evaluation"]
    print(f"model trained in {time.perf_counter() - t0:.0f} s: held-out rms error {ev['rmse']:.3f} rad")

    # 1. new end targets inside the goal box
    rng = np.random.default_rng(1)
    lo, hi = np.array(GOAL_BOX)
    targets = lo + (hi - lo) * rng.random((args.problems, 3))
    ends = robot.frame_positions(data.positions[:, -1], "hand")
    nearest = np.argmin(np.linalg.norm(ends[None] - targets[:, None], axis=-1), axis=1)
    reach = Objective([EndPosition(1e4, frame="hand"), JointLimits(100.0, margin=0.01), StayNear(0.1)])
    res = genplan.adjust(model, data.positions[nearest], reach, targets={"end_position": targets}, updates=40,
                         scene=scene)
    fin = res.finish()
    print(f"new goals: {fin.success.sum()} of {fin.batch} finished, end error "
          f"{1e3 * np.nanmax(fin.end_error_m):.3f} mm (max), residual {np.nanmax(fin.max_residual_ratio):.2f} x tolerance "
          f"(max), {1e3 * res.time_total_s / fin.batch:.1f} ms per problem adjusting")

    # 2. a 5 cm ball on the first motion's path at mid-time
    x_in = data.positions[:1]
    mid = robot.frame_positions(x_in[:, data.K // 2], "hand")[0]
    ball = np.array([[[*mid, 0.05]]])
    blocked = dataclasses.replace(scene, name="panda_shelf_ball",
                                  obstacles=(*scene.obstacles, Sphere("ball", 0.05, Pose(position=tuple(mid)))))
    world = robot.collision_world()
    world.add_scene(blocked)
    avoid = Objective([EndPosition(1e4, frame="hand"), JointLimits(100.0, margin=0.01), StayNear(0.1), Constraint(10.0),
                       AvoidSpheres(1e4, margin=0.04), Clearance(1e4, margin=0.03), SelfClearance(1e4, margin=0.01)])
    own_end = robot.frame_positions(x_in[:, -1], "hand")
    # left in the ball, it is adjusted again from the family's members near it (the pool)
    obs = genplan.adjust(model, x_in, avoid, targets={"end_position": own_end, "avoid_spheres": ball}, updates=400,
                         step="adam", lr=0.02, scene=scene, pool=data.positions)
    fin_obs = obs.finish(world=world)
    hit = bool(np.any(world.in_collision(x_in[0])))
    print(f"obstacle: the original motion {'hits' if hit else 'misses'} the ball; adjusted: "
          f"{'finished, clear of it' if fin_obs.success[0] else 'failed: ' + str(fin_obs.reasons[0])}")

    from genplan.viewer import export_html

    try:
        if fin.success[0]:
            export_html(robot, fin.trajectories[0], args.out_dir / "new_goal.html", scene=scene, trail_frame="hand")
        if fin_obs.success[0]:
            export_html(robot, fin_obs.trajectories[0], args.out_dir / "obstacle.html", scene=blocked,
                        trail_frame="hand")
    except ImportError as exc:  # the viewer is an extra
        print(f"views: {exc}")
        return
    print(f"views in {args.out_dir}")


if __name__ == "__main__":
    main()
