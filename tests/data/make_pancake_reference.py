"""Writes tests/data/pancake_reference.npz: the shipped pancake model's deformations and latent
adjustments (J1, J2, J2Executable; every method and step rule) and a small training run as computed by the code at commit
ba28c80, before the seq2seq method moved out of genplan.pancake. tests/test_seq2seq_pancake.py
checks that today's code gives the same numbers.

    .venv/bin/python tests/data/make_pancake_reference.py [OUT.npz]

torch's float32 bits depend on the processor (MKL's and oneDNN's kernels differ between the AMD
EPYC hosts the first reference was written on and AVX-512 Intel Xeon hosts), so a second
reference, tests/data/pancake_reference_avx512.npz, was written by this script (the same calls,
today's code) on such a host; the test compares with the one whose deformation matches.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

import numpy as np
import torch

from genplan.pancake.adjustment import J1, J2, J2Executable, adjust
from genplan.pancake.model import load_model
from genplan.pancake.trajectories import linear, s_curve

P_END = np.array([[0.1, -0.1, math.pi], [0.0, 0.1, 0.0], [-0.1, 0.0, -math.pi], [0.05, 0.05, -0.4]])


def main() -> None:
    torch.set_num_threads(1)
    model = load_model()
    x_in = np.stack([s_curve(np.zeros(3), p) for p in P_END])
    x_lin = np.stack([linear(np.zeros(3), [0.0, 0.0, -0.75 * math.pi])] * 2)
    out: dict[str, np.ndarray] = {"x_in": x_in, "x_lin": x_lin}
    d = model.deform(x_in)
    for k in ("p", "u", "phi", "z"):
        out[f"deform_{k}"] = d[k]
    for method in ("latent", "random-latent", "direct-u"):
        for step in ("gd", "adaptive", "adam"):
            r = adjust(x_in, J1(P_END), method, 5, model=model, step=step, seed=3)
            key = f"j1_{method}_{step}"
            out[f"{key}_history"] = r.objective_history
            out[f"{key}_p"] = r.p
            out[f"{key}_phi"] = r.phi
    for name, obj in (("j2", J2()), ("j2exec", J2Executable())):
        r = adjust(x_lin, obj, "latent", 8, model=model, step="adam")
        out[f"{name}_history"] = r.objective_history
        out[f"{name}_p"] = r.p
    from genplan.pancake.model import default_config, train

    cfg = default_config(trajectories=256, validation=64, epochs=1, batch_size=64, seed=5, data_seed=7)
    trained = train(cfg, progress=False, log_every=1)
    digest = hashlib.sha256()
    for name, t in sorted(trained.net.state_dict().items()):
        digest.update(name.encode() + t.numpy().tobytes())
    out["train_weights_sha256"] = np.array(digest.hexdigest())
    out["train_loss"] = np.array([e["loss"] for e in trained.card["training"]["loss_log"]])
    import sys

    path = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("pancake_reference.npz")
    np.savez_compressed(path, **out)
    print(f"wrote {path} ({len(out)} arrays)")


if __name__ == "__main__":
    main()
