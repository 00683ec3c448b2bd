"""``genplan train gan``: train the conditional ensemble GAN for a robot and task, evaluate it on
held-out targets (:mod:`genplan.gan.evaluate`) and write the model and its card.

    genplan train gan --robot panda --seed 0                      # the paper's, shipped
    genplan train gan --robot my_robot.toml --task my_task.toml --out my_gan.safetensors
"""

from __future__ import annotations

import argparse
import time
from typing import Any

from genplan import _cli_args as A


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robot", required=True,
                   help="a preset name (genplan info lists them) or a robot file (.toml) or a URDF")
    p.add_argument("--task", default=None,
                   help="a task with a [condition] (shipped name or task file .toml); default: the robot's "
                        "shipped <robot>_ik")
    p.add_argument("--seed", type=A.seed, default=0, help="training seed (torch and numpy)")
    p.add_argument("--iterations", type=A.positive_int, default=None, help="generator steps (default: the paper's 10,000)")
    p.add_argument("--n-net", type=A.positive_int, default=None,
                   help="ensemble size (default: 10 for up to 12 configuration features, else 5)")
    p.add_argument("--no-discriminator", action="store_true", help="train on the costs only (ablation)")
    p.add_argument("--data-size", type=A.positive_int, default=None, help="valid configurations (default 25,000)")
    p.add_argument("--eval-targets", type=A.positive_int, default=500,
                   help="held-out targets of the card's evaluation (default 500)")
    p.add_argument("--out", type=A.output_file, default=None,
                   help="model path (default for a shipped task: models/<robot>_gan.safetensors; folders are created)")
    p.add_argument("--threads", type=A.positive_int, default=None,
                   help="torch threads (default: genplan's choice for training, one -- batches of 100 gain "
                        "little from more, and on a busy machine extra threads contend and run many times "
                        "slower; $GENPLAN_TORCH_THREADS overrides it too)")


def main(args: argparse.Namespace) -> int:
    from genplan import projection as P
    from genplan.gan.evaluate import evaluate, summary_line
    from genplan.gan.costs import default_task_name
    from genplan.gan.model import default_config, models_dir, train, train_command
    from genplan.robots import load

    robot = load(args.robot)
    task = P.load_task(args.task if args.task is not None else default_task_name(robot), robot)
    shipped = args.task is None or args.task in P.task_names()
    if args.out is None and not shipped:
        raise A.UsageError("--out: give the model's path (a task file's GAN has no shipped place)")
    overrides: dict[str, Any] = {"seed": args.seed}
    if args.iterations is not None:
        overrides["iterations"] = args.iterations
    if args.n_net is not None:
        overrides["n_net"] = args.n_net
    if args.data_size is not None:
        overrides["data_size"] = args.data_size
    if args.no_discriminator:
        overrides["use_discriminator"] = False
    cfg = default_config(robot, task, **overrides)  # errors (no [condition], ...) before any work
    out = args.out or A.check_output_file(models_dir() / f"{robot.name}_gan.safetensors", "--out")
    t0 = time.perf_counter()
    model = train(cfg, robot=robot, task=task, threads=args.threads)
    model.card["command"] = train_command(args.robot, args.task, args.seed) + "".join(
        f" --{k} {getattr(args, k.replace('-', '_'))}" for k in ("iterations", "n-net", "data-size")
        if getattr(args, k.replace("-", "_")) is not None) + (" --no-discriminator" if args.no_discriminator else "")
    model.card["evaluation"] = evaluate(model, task, n=args.eval_targets, progress=True)
    model.card["training"]["total_seconds_including_data"] = time.perf_counter() - t0
    weights, card = model.save(out)
    print(f"trained in {model.card['training']['seconds']:.0f} s "
          f"({model.card['training']['total_seconds_including_data']:.0f} s with data and evaluation); "
          + summary_line(model.card["evaluation"]))
    print(f"wrote {weights} and {card}")
    return 0
