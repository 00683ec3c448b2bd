"""``genplan train seq2seq``: train the pancake seq2seq model and write it with its card.

    genplan train seq2seq --seed 0 --out PATH [--trajectories N] [--epochs E]

Generates (or reads from the cache) N input trajectories, trains with a progress bar, then
evaluates: deformation quality on held-out inputs and on the paper's 27 S-curves, and latent
adjustment of J1 on those 27 (mean J1 after 0 / 5 / 100 updates, end RMSE, cone). Writes ``--out``
(.safetensors) and its card (.json): never the shipped model inside the installed package.
"""

from __future__ import annotations

import argparse
import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from genplan import _cli_args as A

if TYPE_CHECKING:
    from genplan.pancake.model import Seq2SeqModel


def evaluate(model: Seq2SeqModel, updates: int = 100) -> dict[str, Any]:
    """The card's evaluation: deformation of held-out inputs and of the 27 S-curves, and J1
    latent adjustment on the 27 (plain gradient descent, the paper's eta = 200)."""
    from genplan.pancake.adjustment import adjust
    from genplan.pancake.data import generate_chunk
    from genplan.pancake.model import evaluate as deform_quality
    from genplan.pancake.trajectories import j1_problems

    held_out = generate_chunk(1024, np.random.default_rng([model.config.data_seed, 2]), model.config.K)
    x_in, p_end = j1_problems()
    out: dict[str, Any] = {
        "held_out_inputs": {"n": len(held_out), **deform_quality(model, held_out)},
        "paper_27_s_curves": deform_quality(model, x_in.astype(np.float32)),
    }
    for step in ("gd", "adaptive"):
        key = f"latent_adjustment_j1_{step}"
        try:
            res = adjust(x_in, "j1", "latent", updates, model=model, p_end=p_end, step=step)
        except FloatingPointError as exc:
            out[key] = {"diverged": str(exc)}
            continue
        h = res.objective_history.mean(1)
        err_pos = np.hypot(*(res.p[:, -1, :2] - p_end[:, :2]).T)
        err_ang = np.abs(res.p[:, -1, 2] - p_end[:, 2])
        out[key] = {
            "updates": updates, "lr": res.lr,
            "mean_j1": {"0": float(h[0]), "5": float(h[min(5, updates)]), str(updates): float(h[-1])},
            "end_rmse_pos_mm": 1e3 * float(np.sqrt(np.mean(err_pos**2))),
            "end_rmse_ang_deg": math.degrees(float(np.sqrt(np.mean(err_ang**2)))),
            "max_abs_phi_deg": math.degrees(float(np.abs(res.phi).max())),
            "all_inside_cone": bool(res.inside_cone().all()),
        }
    return out


def add_arguments(p: argparse.ArgumentParser) -> None:
    from genplan.pancake.config import Seq2SeqConfig

    d = Seq2SeqConfig()
    p.add_argument("--seed", type=A.seed, default=0, help="training seed (weights, batches)")
    p.add_argument("--data-seed", type=A.seed, default=None, help="seed of the training inputs (default: --seed)")
    p.add_argument("--trajectories", type=A.positive_int, default=d.trajectories,
                   help=f"training inputs (default {d.trajectories:,}; the paper used 1,638,400)")
    p.add_argument("--epochs", type=A.positive_int, default=d.epochs, help=f"default {d.epochs}")
    p.add_argument("--batch-size", type=A.positive_int, default=d.batch_size, help=f"default {d.batch_size}")
    p.add_argument("--lr", type=A.positive_float, default=d.lr,
                   help=f"Adam learning rate, cosine-annealed (default {d.lr})")
    p.add_argument("--alpha", type=A.non_negative_float, default=d.alpha,
                   help=f"weight of f_dyn in the loss (default {d.alpha})")
    p.add_argument("--encoder-stride", type=A.positive_int, default=d.encoder_stride,
                   help=f"encoder reads every n-th pose (default {d.encoder_stride}; 1 = the paper)")
    p.add_argument("--decoder-stride", type=A.positive_int, default=d.decoder_stride,
                   help=f"accelerations per decoder LSTM step (default {d.decoder_stride}; 1 = the paper)")
    p.add_argument("--threads", type=A.positive_int, default=d.threads,
                   help="torch threads (default: genplan's choice for training, one; $GENPLAN_TORCH_THREADS "
                        "overrides it too)")
    p.add_argument("--out", type=A.output_file, default=None,
                   help="model path (required: the shipped model in the installed package is never overwritten; "
                        "folders are created; an existing model is replaced once the new one is complete)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def main(args: argparse.Namespace) -> int:
    from genplan.pancake.model import default_config, default_path, retrain_command, train

    out = A.model_output(args.out, default_path())  # never inside the package
    cfg = default_config(seed=args.seed, data_seed=args.seed if args.data_seed is None else args.data_seed,
                         trajectories=args.trajectories, epochs=args.epochs, batch_size=args.batch_size,
                         lr=args.lr, alpha=args.alpha, encoder_stride=args.encoder_stride,
                         decoder_stride=args.decoder_stride, threads=args.threads)
    if cfg.trajectories < cfg.batch_size:
        raise A.UsageError(f"--trajectories ({cfg.trajectories}) must be at least --batch-size ({cfg.batch_size})")
    A.announce_replacement([out])
    t0 = time.perf_counter()
    model = train(cfg, progress=not args.no_progress)
    t_eval = time.perf_counter()
    model.card["evaluation"] = evaluate(model)
    model.card["evaluation"]["seconds"] = time.perf_counter() - t_eval
    model.card["training"]["total_seconds_including_data_and_evaluation"] = time.perf_counter() - t0
    model.card["retrain"] = retrain_command(cfg, out, data_seed=args.data_seed is not None)
    weights, card = model.save(out)
    ev = model.card["evaluation"]
    lat = ev["latent_adjustment_j1_adaptive"]
    print(f"trained in {model.card['training']['seconds'] / 60:.1f} min on {cfg.trajectories:,} trajectories; "
          f"held-out reproduction RMSE {ev['held_out_inputs']['rmse_pos_mm']:.2f} mm / "
          f"{ev['held_out_inputs']['rmse_ang_deg']:.2f} deg; J1 latent (adaptive) mean {lat.get('mean_j1')}")
    print(f"wrote {weights} and {card}")
    return 0
