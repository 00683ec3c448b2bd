"""Plan a constrained motion for the Panda (gripper kept horizontal) from above the table into the
bookshelf, with the GAN sampler, and save a 3D view of the path.

    python examples/01_plan_with_gan_sampler.py [--out panda_plan.html]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import genplan
from genplan.planning import Planner, PlannerSettings, environment


def main(out: Path | None) -> None:
    robot = genplan.load("panda")
    env = environment("panda_shelf")
    world = env.world(robot)                      # parry: self-collision + table + shelf
    query = env.queries(robot, n=1, seed=0)[0]    # a start and 10 goal configurations (IK)
    planner = Planner(robot, world=world, sampler="gan", settings=PlannerSettings(simplify=True), seed=0)
    result = planner.plan(query.start, query.goals)
    print(f"success {result.success} in {result.time_s * 1e3:.1f} ms: {len(result.waypoints)} waypoints, "
          f"{len(result.path)} dense states, {result.projections} projection steps, {result.extensions} extensions")
    if out is not None:
        from genplan.viewer import export_html

        export_html(robot, result.path, out, boxes=env.boxes, halfspaces=env.halfspaces, title="Panda, GAN sampler")
        print(f"wrote {out}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=None, help="write a self-contained HTML 3D view")
    main(parser.parse_args().out)
