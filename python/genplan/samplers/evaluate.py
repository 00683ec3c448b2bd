"""How good a learned sampler is for its task, on held-out targets: the numbers of a GAN card.

Targets are drawn uniformly in the task's condition box (a seed of their own, not the training
data's). For each, three starts: the GAN's sample for that target, and a uniform sample in the
joint limits. From each start, two solves (the native Gauss-Newton projector, all cores):

* projection onto the task's manifold (:func:`genplan.samplers.costs.manifold_task`), as Table I's
  projection rows;
* IK: the whole task with its condition term aimed at the target, as Table I's IK rows.

Reported per solve and start: success (%), steps* (mean iterations of the successful solves, the
paper's measure) and T* (mean time of a successful solve, ms); and the GAN samples' target error.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from genplan import projection as P
from genplan.samplers.base import SamplerModel
from genplan.samplers.costs import condition_term, manifold_task


def _summary(res: P.BatchResult) -> dict[str, Any]:
    ok = res.success.astype(bool)
    return {
        "success_rate": 100.0 * float(ok.mean()),
        "steps_star": float(res.iterations[ok].mean()) if ok.any() else None,
        "t_star_ms": float(res.time_s[ok].mean() * 1e3) if ok.any() else None,
    }


def evaluate(model: SamplerModel, task: P.Task, n: int = 500, seed: int = 1, progress: bool = False) -> dict[str, Any]:
    """The card's evaluation of ``model`` on ``task`` (see the module docstring): ``n`` held-out
    targets drawn with ``seed``."""
    robot = model.robot
    cond = condition_term(task)
    assert task.condition is not None
    rng = np.random.default_rng(seed)
    targets: NDArray[np.float64] = rng.uniform(task.condition.low, task.condition.high, size=(n, 3))
    t0 = time.perf_counter()
    starts = {"gan": model.sample(np.clip(targets, *model.target_limits()), rng)}
    sample_ms = (time.perf_counter() - t0) * 1e3 / n
    starts["uniform"] = robot.random_configurations(n, rng)
    reached = robot.frame_positions(starts["gan"], model.config.target_frame)
    err = np.linalg.norm(reached - targets, axis=1)
    projector = P.GaussNewtonProjector(robot, manifold_task(task, robot))
    ik = P.GaussNewtonProjector(robot, task)
    out: dict[str, Any] = {
        "targets": n, "seed": seed, "box": [list(task.condition.low), list(task.condition.high)],
        "gan_sample_ms_per_target": sample_ms,
        "target_error_m": {"median": float(np.median(err)), "p90": float(np.percentile(err, 90))},
    }
    for init, q0 in starts.items():
        out[init] = {
            "projection": _summary(projector.solve_batch(q0, parallel=True, progress=progress)),
            "ik": _summary(ik.solve_batch(q0, targets={cond.name: targets}, parallel=True, progress=progress)),
        }
    for kind in ("projection", "ik"):
        g, u = out["gan"][kind]["steps_star"], out["uniform"][kind]["steps_star"]
        out[f"{kind}_steps_star_gan_over_uniform"] = g / u if g is not None and u else None
    return out


def summary_line(ev: dict[str, Any]) -> str:
    """One line of an evaluation for a terminal."""
    parts = [f"target error median {ev['target_error_m']['median'] * 100:.1f} cm"]
    for kind in ("projection", "ik"):
        g, u = ev["gan"][kind], ev["uniform"][kind]

        def fmt(x: dict[str, Any]) -> str:
            steps = "-" if x["steps_star"] is None else f"{x['steps_star']:.2f}"
            return f"{x['success_rate']:.1f} % in {steps} steps*"

        parts.append(f"{kind}: GAN {fmt(g)}, uniform {fmt(u)}")
    return "; ".join(parts)
