"""``genplan train seq2seq``: train a seq2seq model of a family of trajectories and write it with
its card.

    genplan train seq2seq --data DIR --out M.safetensors [--seed S] [--epochs E] [--held-out F]
    genplan train seq2seq --seed 0 --out PATH [--trajectories N] [--epochs E]      # the pancake's

With ``--data`` (a trajectory data set: ``genplan data trajectories``, or
:func:`genplan.seq2seq.data.write_trajectories`): the joint-space family's model
(:func:`genplan.seq2seq.train.train_family`: the defaults of
:func:`~genplan.seq2seq.config.joint_space_config`, the data set's task residuals as the training
penalty); the card records the data's sha256 and ranges, the held-out reconstruction error, the
decodings' largest residual over the task's tolerance, the training time and the command that
retrains it.

Without ``--data``: the pancake's model. Generates (or reads from the cache) N input trajectories,
trains with a progress bar, then evaluates: deformation quality on held-out inputs and on the
paper's 27 S-curves, and latent adjustment of J1 on those 27 (mean J1 after 0 / 5 / 100 updates,
end RMSE, cone).

Writes ``--out`` (.safetensors) and its card (.json), the model replaced only once both are whole:
never the shipped model inside the installed package.
"""

from __future__ import annotations

import argparse
import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from genplan.cli import args as A

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

    from genplan.seq2seq.config import joint_space_config

    d = Seq2SeqConfig()
    j = joint_space_config(("q",), 2, (0.0,), (1.0,))
    p.add_argument("--data", type=A.existing_folder, default=None,
                   help="a trajectory data set (genplan data trajectories): train a model of its family; without it, "
                        "the pancake's model")
    p.add_argument("--held-out", type=A.positive_float, default=0.05,
                   help="with --data: the share of its trajectories kept out of training for the card's evaluation "
                        "(default 0.05; below 1)")
    p.add_argument("--seed", type=A.seed, default=0, help="training seed (weights, batches, the held-out split)")
    p.add_argument("--data-seed", type=A.seed, default=None,
                   help="the pancake's: seed of the training inputs (default: --seed)")
    p.add_argument("--trajectories", type=A.positive_int, default=None,
                   help=f"the pancake's: training inputs (default {d.trajectories:,}; the paper used 1,638,400)")
    p.add_argument("--epochs", type=A.positive_int, default=None,
                   help=f"default {d.epochs} (the pancake), {j.epochs} (--data)")
    p.add_argument("--batch-size", type=A.positive_int, default=None,
                   help=f"default {d.batch_size} (the pancake), {j.batch_size} (--data)")
    p.add_argument("--lr", type=A.positive_float, default=None,
                   help=f"Adam learning rate, cosine-annealed (default {d.lr} (the pancake), {j.lr} (--data))")
    p.add_argument("--alpha", type=A.non_negative_float, default=None,
                   help=f"weight of the penalty in the loss: f_dyn (the pancake, default {d.alpha}), the task's "
                        f"residuals (--data, default {j.alpha})")
    p.add_argument("--encoder-stride", type=A.positive_int, default=None,
                   help=f"the pancake's: encoder reads every n-th pose (default {d.encoder_stride}; 1 = the paper)")
    p.add_argument("--decoder-stride", type=A.positive_int, default=None,
                   help=f"the pancake's: accelerations per decoder LSTM step (default {d.decoder_stride}; 1 = the paper)")
    p.add_argument("--threads", type=A.positive_int, default=d.threads,
                   help="torch threads (default: genplan's choice for training, one; $GENPLAN_TORCH_THREADS "
                        "overrides it too)")
    p.add_argument("--out", type=A.output_file, default=None,
                   help="model path (required: the shipped model in the installed package is never overwritten; "
                        "folders are created; an existing model is replaced once the new one is complete)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


#: options of the pancake's recipe that a data set's training does not take (its data set fixes them)
PANCAKE_ONLY = {"data_seed": "--data-seed", "trajectories": "--trajectories", "encoder_stride": "--encoder-stride",
                "decoder_stride": "--decoder-stride"}


def main(args: argparse.Namespace) -> int:
    if args.data is not None:
        return _train_data(args)
    if args.held_out != 0.05:
        raise A.UsageError("--held-out: a share of a data set's trajectories; give --data too")
    from genplan.pancake.model import default_config, default_path, retrain_command, train
    from genplan.pancake.config import Seq2SeqConfig

    d = Seq2SeqConfig()
    out = A.model_output(args.out, default_path())  # never inside the package
    given = {k: getattr(args, k) for k in ("trajectories", "epochs", "batch_size", "lr", "alpha", "encoder_stride",
                                           "decoder_stride")}
    recipe = {k: getattr(d, k) if v is None else v for k, v in given.items()}
    cfg = default_config(seed=args.seed, data_seed=args.seed if args.data_seed is None else args.data_seed,
                         threads=args.threads, **recipe)
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


def _train_data(args: argparse.Namespace) -> int:
    """``--data``: the model of a trajectory data set's family, written with its card."""
    import shlex

    from genplan.seq2seq.data import read_trajectories

    given = [option for key, option in PANCAKE_ONLY.items() if getattr(args, key) is not None]
    if given:
        raise A.UsageError(f"{given[0]}: an option of the pancake's model; with --data the data set fixes it")
    if not args.held_out < 1:
        raise A.UsageError(f"--held-out: a share of the trajectories below 1, got {args.held_out}")
    if args.out is None:
        raise A.UsageError("--out: give the model's path (e.g. --out family.safetensors)")
    out = A.model_output(args.out, args.out)
    data = read_trajectories(args.data)  # every shard checked against its sha256, before any training
    if len(data) < 2:
        raise A.UsageError(f"--data {args.data}: {len(data)} trajectory; training needs at least 2 (one held out)")
    overrides = {k: getattr(args, k) for k in ("epochs", "batch_size", "lr", "alpha") if getattr(args, k) is not None}
    A.announce_replacement([out])
    from genplan.seq2seq.train import train_family

    model = train_family(data, seed=args.seed, held_out=args.held_out, progress=not args.no_progress,
                         threads=args.threads, **overrides)
    argv = ["genplan", "train", "seq2seq", "--data", str(args.data), "--out", str(out), "--seed", str(args.seed)]
    if args.held_out != 0.05:
        argv += ["--held-out", repr(args.held_out)]
    for key, value in overrides.items():
        argv += [f"--{key.replace('_', '-')}", str(value)]
    model.card["retrain"] = shlex.join(argv)
    weights, card = model.save(out)
    ev = model.card["evaluation"]
    residual = ev.get("max_residual_ratio")
    print(f"trained in {model.card['training']['total_seconds']:.1f} s on {model.card['data']['training']} "
          f"trajectories of {data.dim} axes x {data.K} samples; held-out ({model.card['data']['held_out']}) "
          f"reconstruction RMSE {ev['rmse']:.4g} (end {ev['end_rmse']:.4g})"
          + (f", decodings' largest residual {residual:.3g} x the task's tolerance" if residual is not None else ""))
    print(f"wrote {weights} and {card}")
    return 0
