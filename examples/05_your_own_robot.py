"""Your own robot, your constraint, your scene: from a URDF to a learned sampler and a plan.

example-robot-data's xArm7 (not a genplan preset) carries a cup upright: the tool's z axis
points straight down, its yaw is free (examples/xarm7/upright_cup.toml). The script trains a small
GAN sampler for that constraint, compares GAN and uniform starts for projection and IK on
held-out targets, plans around a box on a table (examples/xarm7/table_box.toml) with the hybrid
sampler, and writes the plan's HTML view.

    python examples/05_your_own_robot.py                    # 2,000 iterations, about a minute
    python examples/05_your_own_robot.py --iterations 10000 # the defaults: examples/xarm7/upright_cup_gan.*
    python examples/05_your_own_robot.py --out-dir my_run   # where the model, plan and view go

The same from the command line:

    genplan train gan --robot examples/xarm7/xarm7.toml --task examples/xarm7/upright_cup.toml --out cup.safetensors
    genplan plan --robot examples/xarm7/xarm7.toml --task examples/xarm7/upright_cup.toml \\
        --scene examples/xarm7/table_box.toml --target 0.45 -0.3 0.25 --sampler hybrid \\
        --model cup.safetensors --out plan.json --html plan.html
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import genplan
from genplan.planning import plan
from genplan.projection import Task
from genplan.samplers import default_config, train
from genplan.samplers.evaluate import evaluate, summary_line

HERE = Path(__file__).resolve().parent / "xarm7"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=2000, help="GAN training iterations")
    parser.add_argument("--data-size", type=int, default=25_000, help="valid configurations to train on")
    parser.add_argument("--eval-targets", type=int, default=500, help="held-out targets of the evaluation")
    parser.add_argument("--out-dir", type=Path, default=Path("your_own_robot"))
    args = parser.parse_args()

    # 1. the robot: a robot file naming its URDF and SRDF (or genplan.load(urdf=..., srdf=..., frames=...))
    arm = genplan.load(HERE / "xarm7.toml")
    print(f"{arm.name}: {arm.nq} joints, {len(arm.collision_world().self_pairs)} self-collision pairs checked")

    # 2. the constraint: a task file; its [condition] is the tool position the sampler is conditioned on
    cup = Task.from_file(HERE / "upright_cup.toml", arm)

    # 3. a learned sampler for it: data projected natively, costs from the task's own residuals
    cfg = default_config(arm, cup, iterations=args.iterations, data_size=args.data_size)
    model = train(cfg, robot=arm, task=cup, progress=False)
    model.card["evaluation"] = evaluate(model, cup, n=args.eval_targets)
    weights, _ = model.save(args.out_dir / "cup.safetensors")
    print(f"trained in {model.card['training']['seconds']:.0f} s; " + summary_line(model.card["evaluation"]))

    # 4. a plan around the box with the hybrid sampler (GAN, else uniform: complete)
    outcome = plan(arm, cup, scene=HERE / "table_box.toml", start="default", target=(0.45, -0.3, 0.25),
                   sampler="hybrid", model=weights, seed=0)
    r = outcome.result
    print(f"plan: success {r.success}, {len(r.path)} states, {r.stats.extensions} extensions, {r.time_s * 1e3:.1f} ms")
    (args.out_dir / "plan.json").write_text(json.dumps(outcome.to_dict()) + "\n")

    # 5. the HTML view: robot, scene, and the trail of the cup (the task's condition frame)
    try:
        from genplan.viewer import export_html

        page = export_html(arm, r.path, args.out_dir / "plan.html", scene=outcome.scene,
                           trail_frame=outcome.trail_frame, title="xArm7 carrying a cup upright")
        print(f"wrote {page}")
    except ImportError as exc:  # the viewer is an extra: pip install genplan[viewer]
        print(f"no HTML view: {exc}")


if __name__ == "__main__":
    main()
