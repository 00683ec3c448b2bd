"""Adjust a spatula trajectory for an objective of your own, by gradient descent on the seq2seq
model's latent vector (the seq2seq paper's Section 3), with the shipped model.

The objective here: end at a given pose, keep the pancake on (the friction cone), and never let
the spatula dip more than 2 cm below where it started (a counter top, say). Any differentiable
function of the batched :class:`genplan.pancake.Rollout` (positions p, velocities v,
accelerations u, cone angle phi; torch tensors) that returns one value per problem will do.

    python examples/03_adjust_a_trajectory.py
"""

from __future__ import annotations

import math

import numpy as np
import torch

from genplan.pancake import Rollout, adjust, s_curve
from genplan.pancake.physics import D_SCALE, cone_limit, f_dyn

TARGET = np.array([0.08, 0.0, -math.pi / 2])   # 8 cm sideways, a quarter turn clockwise
FLOOR = -0.02                                  # lowest allowed height (m) relative to the start


def objective(r: Rollout) -> torch.Tensor:
    """End pose error (eq. 17's scaling) + friction-cone penalty + a soft floor, one per problem."""
    target = torch.as_tensor(TARGET, dtype=r.p.dtype)
    d = torch.as_tensor(D_SCALE, dtype=r.p.dtype)
    end = (((r.p[:, -1] - target) * d) ** 2).sum(-1)
    floor = (torch.relu(FLOOR - r.p[..., 1]) ** 2).sum(-1)
    return end + f_dyn(r.phi) + 100.0 * floor


def main() -> None:
    x_in = s_curve([0.0, 0.0, 0.0], TARGET)          # the naive move: an S-curve in 0.5 s
    res = adjust(x_in, objective, method="latent", updates=60)
    j = res.objective_history[:, 0]
    p = res.p[0]
    end_mm = 1e3 * float(np.hypot(*(p[-1, :2] - TARGET[:2])))
    end_deg = math.degrees(abs(float(p[-1, 2] - TARGET[2])))
    print(f"objective: {j[0]:.3g} before, {j[5]:.3g} after 5 updates, {j[-1]:.3g} after {res.updates}")
    print(f"end pose error: {end_mm:.2f} mm, {end_deg:.2f} deg; lowest height {1e3 * p[:, 1].min():.1f} mm")
    print(f"max |phi| {math.degrees(res.max_abs_phi[0]):.1f} deg (limit {math.degrees(cone_limit()):.0f}); "
          f"inside the friction cone: {bool(res.inside_cone()[0])}")
    print(f"{res.ms_per_update:.2f} ms per update")


if __name__ == "__main__":
    main()
