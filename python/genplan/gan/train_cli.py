"""``genplan train gan``: train the conditional ensemble GAN and write the model and its card."""

from __future__ import annotations

import argparse
import time
from typing import Any

from typing import TYPE_CHECKING

import numpy as np

from genplan import _cli_args as A

if TYPE_CHECKING:
    from genplan.gan.model import GanModel


def evaluate(model: GanModel, n: int = 500, seed: int = 1) -> dict[str, Any]:
    """How good the samples are: target error, and projection from GAN samples (success, steps)."""
    from genplan import projection as P

    robot = model.robot
    rng = np.random.default_rng(seed)
    box = np.asarray(model.config.target_box)
    targets = rng.uniform(box[0], box[1], size=(n, 3))
    q = model.sample(targets, rng)
    hands = robot.link_poses(q, [robot.frames[model.config.target_frame]])[:, 0, :3, 3]
    err = np.linalg.norm(hands - targets, axis=1)
    res = P.GaussNewtonProjector(robot, P.paper_task(robot, "projection")).solve_batch(q, parallel=False)
    return {
        "samples": n,
        "target_error_m": {"median": float(np.median(err)), "p90": float(np.percentile(err, 90))},
        "projection_from_samples": {
            "success_rate": 100.0 * float(res.success.mean()),
            "steps_mean": float(res.iterations[res.success].mean()) if res.success.any() else None,
            "t_ave_ms": float(res.time_s.mean() * 1e3),
        },
    }


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--robot", choices=["panda", "talos"], required=True)
    p.add_argument("--seed", type=A.seed, default=0, help="training seed (torch and numpy)")
    p.add_argument("--iterations", type=A.positive_int, default=None, help="generator steps (default: the paper's 10,000)")
    p.add_argument("--n-net", type=A.positive_int, default=None, help="ensemble size (default: 10 Panda, 5 Talos)")
    p.add_argument("--no-discriminator", action="store_true", help="train on the costs only (ablation)")
    p.add_argument("--data-size", type=A.positive_int, default=None, help="valid configurations (default 25,000)")
    p.add_argument("--out", type=A.output_file, default=None,
                   help="model path (default models/<robot>_gan.safetensors; folders are created)")
    p.add_argument("--threads", type=A.positive_int, default=None,
                   help="torch threads (default: genplan's choice for training, one -- batches of 100 gain "
                        "little from more, and on a busy machine extra threads contend and run many times "
                        "slower; $GENPLAN_TORCH_THREADS overrides it too)")


def main(args: argparse.Namespace) -> int:
    from genplan.gan.model import default_config, models_dir, train

    overrides: dict[str, Any] = {"seed": args.seed}
    if args.iterations is not None:
        overrides["iterations"] = args.iterations
    if args.n_net is not None:
        overrides["n_net"] = args.n_net
    if args.data_size is not None:
        overrides["data_size"] = args.data_size
    if args.no_discriminator:
        overrides["use_discriminator"] = False
    cfg = default_config(args.robot, **overrides)
    out = args.out or A.check_output_file(models_dir() / f"{args.robot}_gan.safetensors", "--out")
    t0 = time.perf_counter()
    model = train(cfg, threads=args.threads)
    model.card["evaluation"] = evaluate(model)
    model.card["training"]["total_seconds_including_data"] = time.perf_counter() - t0
    weights, card = model.save(out)
    ev = model.card["evaluation"]
    print(f"trained in {model.card['training']['seconds']:.0f} s; target error median "
          f"{ev['target_error_m']['median'] * 100:.1f} cm; projection from samples: "
          f"{ev['projection_from_samples']['success_rate']:.1f} % in {ev['projection_from_samples']['steps_mean']} steps")
    print(f"wrote {weights} and {card}")
    return 0
