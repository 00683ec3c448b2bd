"""``genplan train flow``: train the conditional flow-matching sampler (:mod:`genplan.samplers.flow`)
for a robot and task, evaluate it on held-out targets as a GAN card is (:mod:`genplan.samplers.evaluate`)
and write the model and its card. The file goes wherever a GAN file does (``--model``).

    genplan train flow --robot talos --seed 0 --steps 8 --w-cost 0 --iterations 10000 --out teacher.safetensors
    genplan train flow --robot my_robot.toml --task my_task.toml --out my_flow.safetensors

``--distill-from TEACHER`` trains a one-step student of a flow file instead
(:func:`genplan.samplers.flow.distill`), regressed on the teacher's samples; the student costs one
network pass per sample.

    genplan train flow --robot talos --seed 0 --distill-from teacher.safetensors --out student.safetensors
"""

from __future__ import annotations

import argparse
import time

from genplan.cli import args as A


def hidden_list(text: str) -> tuple[int, ...]:
    """``--hidden``: comma-separated positive layer widths."""
    try:
        widths = tuple(int(v) for v in text.split(","))
    except ValueError:
        widths = ()
    if not widths or any(w < 1 for w in widths):
        raise argparse.ArgumentTypeError(f"expected comma-separated positive widths such as 256,256,256, got {text!r}")
    return widths


def add_arguments(p: argparse.ArgumentParser) -> None:
    A.add_robot_and_task(p, "the robot's shipped <robot>_ik")
    A.add_allow_python(p)
    p.add_argument("--seed", type=A.seed, default=0, help="training seed (torch and numpy)")
    p.add_argument("--iterations", type=A.positive_int, default=None, help="training steps (default 4,000)")
    p.add_argument("--hidden", type=hidden_list, default=None, help="hidden layer widths (default 256,256,256)")
    p.add_argument("--steps", type=A.positive_int, default=None,
                   help="Euler steps per sample (default 4; sampling costs one network pass per step)")
    p.add_argument("--w-cost", type=A.non_negative_float, default=None,
                   help="weight of the GAN's target, limit and constraint costs on generated samples against "
                        "the flow-matching loss (default 0.05; 0: pure flow matching, widest coverage)")
    p.add_argument("--distill-from", type=A.existing_file, default=None, metavar="TEACHER",
                   help="distil a student of --steps Euler steps (default 1) from this flow file (its robot's and "
                        "task's) instead of training by flow matching; --w-cost then weighs the task's costs "
                        "against the regression (default 0)")
    p.add_argument("--pairs", type=A.positive_int, default=None,
                   help="with --distill-from: teacher samples (noise, target, configuration) to regress on (default 100,000)")
    p.add_argument("--data-size", type=A.positive_int, default=None, help="valid configurations (default 25,000)")
    p.add_argument("--eval-targets", type=A.eval_targets, default=500,
                   help="held-out targets of the card's evaluation (default 500, at most 100,000)")
    A.add_model_out(p)
    p.add_argument("--threads", type=A.positive_int, default=None,
                   help="torch threads (default: genplan's choice for training, one; $GENPLAN_TORCH_THREADS "
                        "overrides it too)")


def main(args: argparse.Namespace) -> int:
    from genplan import projection as P
    from genplan.robots import load
    from genplan.samplers.costs import default_task_name
    from genplan.samplers.evaluate import evaluate, summary_line
    from genplan.samplers.flow import default_config, shipped_path, train, train_command

    robot = load(args.robot)
    task = P.load_task(args.task if args.task is not None else default_task_name(robot), robot,
                       allow_python=args.allow_python)
    if args.out is None and not (args.task is None or args.task in P.task_names()):
        raise A.UsageError("--out: give the model's path (a task file's flow has no shipped place)")
    out = A.model_output(args.out, shipped_path(robot))  # never inside the package
    given = {k: getattr(args, k) for k in ("iterations", "hidden", "steps", "w_cost", "data_size", "pairs")
             if getattr(args, k) is not None}
    overrides = dict(given)
    if args.pairs is not None and args.distill_from is None:
        raise A.UsageError("--pairs: only with --distill-from (the pairs a student is regressed on)")
    teacher = None
    if args.distill_from is not None:
        from genplan.model_files import peek_card
        from genplan.samplers.flow import load_flow
        from genplan.samplers.gan import FORMAT as GAN_FORMAT

        if (peek_card(args.distill_from) or {}).get("format") == GAN_FORMAT:
            raise A.UsageError(f"--distill-from {args.distill_from}: a teacher is a flow file (genplan train flow), "
                               "this is a GAN's")
        teacher = load_flow(robot, args.distill_from, task)  # another robot's or task's flow: refused here
        if "data_size" in given:
            raise A.UsageError("--data-size: a student's data are its teacher's (it has "
                               f"{teacher.config.data_size:,} configurations)")
        overrides = {"steps": 1, "w_cost": 0.0, **overrides, "teacher": str(args.distill_from),
                     "data_size": teacher.config.data_size, "data_seed": teacher.config.data_seed}
    cfg = default_config(robot, task, **overrides, seed=args.seed)  # errors (no [condition], ...) before any work
    A.announce_replacement([out])
    t0 = time.perf_counter()
    if teacher is not None:
        from genplan.samplers.flow import distill

        model = distill(cfg, teacher, progress=True, task=task, threads=args.threads)
    else:
        model = train(cfg, progress=True, robot=robot, task=task, threads=args.threads)
    extra = (f" --distill-from {args.distill_from}" if teacher is not None else "") + "".join(
        f" --{k.replace('_', '-')} {','.join(map(str, v)) if isinstance(v, tuple) else v}" for k, v in given.items())
    model.card["command"] = train_command(args.robot, args.task, args.seed, options=extra, out=out)
    model.card["evaluation"] = evaluate(model, task, n=args.eval_targets, progress=True)
    model.card["training"]["total_seconds_including_data"] = time.perf_counter() - t0
    weights, card = model.save(out)
    print(f"trained in {model.card['training']['seconds']:.0f} s; " + summary_line(model.card["evaluation"])
          + f"\nwrote {weights} and {card}")
    return 0
