"""Which network and loss a robot's joint-space seq2seq family trains best with on a CPU budget:
the paper's LSTM encoder/decoder against multilayer perceptrons over the whole sequence, each with
the paper's Gaussian NLL (learned variances) and with the squared error, on the same data set,
the same held-out trajectories and the same number of epochs.

    python benches/seq2seq_architectures.py --data DIR --epochs 100 --out benches/results/seq2seq_architectures.json

Prints per variant: held-out RMS error over all samples and at the last sample (rad), the largest
error, the largest constraint residual along the decodings over its tolerance, the training time,
and the time of one decode of a batch of 200 (forward and backward: what one latent update
costs). The defaults of genplan.seq2seq.config.joint_space_config follow this table.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

VARIANTS = {"lstm_nll": dict(network="lstm", loss="nll", hidden=128, latent=None, nll_beta=0.5, nll_beta_final=0.0),
            "lstm_mse": dict(network="lstm", loss="mse", hidden=128, latent=None),
            "mlp_nll": dict(network="mlp", loss="nll", nll_beta=0.5, nll_beta_final=0.0),
            "mlp_mse": dict(network="mlp", loss="mse")}


def decode_ms(model, x: np.ndarray) -> float:
    """Median time of a decode of ``x`` with its gradient with respect to z (ms)."""
    xt = torch.as_tensor(x, dtype=torch.float32)
    z = model.encode(xt).detach().requires_grad_(True)
    x0 = model.start(xt)
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        r = model.decode(z, x0)
        (g,) = torch.autograd.grad(r.p.sum(), z)
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", type=Path, required=True, help="a trajectory data set (genplan data trajectories)")
    p.add_argument("--epochs", type=int, default=100)
    p.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args()
    from genplan.experiments.common import machine
    from genplan.seq2seq.data import read_trajectories
    from genplan.seq2seq.train import train_family

    torch.set_num_threads(1)
    data = read_trajectories(args.data)
    rows = {}
    for name in args.variants:
        t0 = time.perf_counter()
        model = train_family(data, seed=args.seed, epochs=args.epochs, progress=False, **VARIANTS[name])
        seconds = time.perf_counter() - t0
        ev = model.card["evaluation"]
        rows[name] = {"rmse_rad": ev["rmse"], "end_rmse_rad": ev["end_rmse"], "max_abs_error_rad": ev["max_abs_error"],
                      "max_residual_ratio": ev.get("max_residual_ratio"), "train_seconds": seconds,
                      "decode_200_ms": decode_ms(model, data.positions[np.arange(200) % len(data)]),
                      "config": model.config.to_dict()}
        r = rows[name]
        print(f"{name:<9} rmse {r['rmse_rad']:.4f} rad, end {r['end_rmse_rad']:.4f}, max {r['max_abs_error_rad']:.3f}, "
              f"residual {r['max_residual_ratio']:.3g} x tol, train {seconds:.0f} s, decode+grad (200) "
              f"{r['decode_200_ms']:.1f} ms", flush=True)
    out = {"data": str(args.data), "trajectories": len(data), "K": data.K, "epochs": args.epochs, "seed": args.seed,
           "machine": machine(), "torch_threads": 1, "variants": rows}
    from genplan._files import write_text

    write_text(args.out, json.dumps(out, indent=1))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
