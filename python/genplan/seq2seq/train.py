"""Training a seq2seq model on a family of trajectories (the seq2seq paper's eq. 4).

:func:`fit` runs the training loop on trajectories in memory: Adam with a cosine learning-rate
schedule, the beta-NLL warm-up and the penalty weight's ramp of the config, gradient clipping,
a validation pass after every epoch, a progress bar, and a card holding the loss curve, the
validation log and the time. :func:`evaluate` is the generic held-out evaluation (reconstruction
error per axis, at the end, and the penalty); a family may pass its own.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any
import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

from genplan._threads import torch_threads
from genplan.errors import NonFiniteError, SettingsError, ShapeError
from genplan.seq2seq.config import Seq2SeqConfig
from genplan.seq2seq.model import Penalty, Seq2SeqModel, Seq2SeqNet, nll

__all__ = ["fit", "evaluate", "train_family", "TaskPenalty", "residual_ratio"]

#: an evaluation: (model, held-out trajectories) -> numbers for the card
Evaluation = Callable[[Seq2SeqModel, NDArray[np.float32]], dict[str, float]]


@torch.no_grad()
def evaluate(model: Seq2SeqModel, x: NDArray[np.float32], penalty: Penalty | None = None,
             batch: int = 512) -> dict[str, float]:
    """Reconstruction quality on held-out trajectories: RMS error per axis and at the last sample
    (in the space's units), the largest error, the NLL per sample (models with variances) and the
    penalty's mean."""
    cfg = model.config
    n = len(x)
    sq = np.zeros(cfg.dim)
    sq_end = np.zeros(cfg.dim)
    worst = 0.0
    tot_nll = tot_pen = 0.0
    for i in range(0, n, batch):
        xb = torch.as_tensor(x[i:i + batch])
        _, out = model.forward(xb)
        if out.var_p is not None:
            d = torch.tensor(cfg.nll_scale, dtype=xb.dtype)
            tot_nll += float(nll(xb, out, cfg.var_floor, d).sum()) / xb.shape[1]
        err = (out.p - xb).double()
        sq += (err ** 2).mean(1).sum(0).numpy()
        sq_end += (err[:, -1] ** 2).sum(0).numpy()
        worst = max(worst, float(err.abs().max()))
        if penalty is not None:
            tot_pen += float(penalty(out, 0.0).sum())
    rms = np.sqrt(sq / max(n, 1))
    out_d: dict[str, float] = {"max_abs_error": worst,
                               "rmse": float(np.sqrt(np.mean(rms ** 2))),
                               "end_rmse": float(np.sqrt(np.mean(sq_end / max(n, 1))))}
    out_d.update({f"rmse_{a}": float(v) for a, v in zip(cfg.axes, rms)})
    if cfg.loss == "nll":
        out_d["nll_per_step"] = tot_nll / max(n, 1)
    if penalty is not None:
        out_d["penalty_mean"] = tot_pen / max(n, 1)
    return out_d


def fit(cfg: Seq2SeqConfig, data: NDArray[np.float32], validation: NDArray[np.float32], *,
        penalty: Penalty | None = None, evaluation: Evaluation | None = None, progress: bool = True,
        log_every: int = 50, describe: Callable[[dict[str, float]], str] | None = None) -> Seq2SeqModel:
    """Train a model of ``cfg`` on ``data`` (n, K, d), validating on ``validation`` after every
    epoch; returns it with a card holding the loss log, the validation log, the time and the
    thread count (the caller adds what it knows: the data's source, the retraining command).

    ``penalty(rollout, margin)``: the constraint penalty per trajectory (the config's
    ``penalty``), None for none. ``evaluation``: the validation pass (default :func:`evaluate`).
    torch runs on ``cfg.threads`` threads (None: genplan's choice for training, see
    genplan._threads)."""
    cfg.validate()
    for name, arr in (("data", data), ("validation", validation)):
        if arr.ndim != 3 or arr.shape[1:] != (cfg.K, cfg.dim):
            raise ShapeError(f"training {name} must have shape (n, {cfg.K}, {cfg.dim}), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise NonFiniteError(f"training {name}: element {tuple(int(i) for i in np.argwhere(~np.isfinite(arr))[0])} "
                                 "is NaN or inf")
    with torch_threads("training", cfg.threads) as threads:
        return _fit(cfg, np.ascontiguousarray(data, dtype=np.float32),
                    np.ascontiguousarray(validation, dtype=np.float32), penalty,
                    evaluation or (lambda m, v: evaluate(m, v, penalty)), progress, log_every, threads, describe)


def _fit(cfg: Seq2SeqConfig, data: NDArray[np.float32], val: NDArray[np.float32], penalty: Penalty | None,
         evaluation: Evaluation, progress: bool, log_every: int, threads: int,
         describe: Callable[[dict[str, float]], str] | None) -> Seq2SeqModel:
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    net = Seq2SeqNet(cfg)
    model = Seq2SeqModel(cfg, net)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    n = len(data)
    batch = min(cfg.batch_size, n)
    steps_per_epoch = max(1, n // batch)
    total_steps = steps_per_epoch * cfg.epochs
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, total_steps, eta_min=cfg.lr_final)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=total_steps, desc="seq2seq training", unit="batch")
    log: list[dict[str, float]] = []
    val_log: list[dict[str, float]] = []
    acc = {"loss": 0.0, cfg.loss: 0.0, "penalty": 0.0, "m": 0}
    t0 = time.perf_counter()
    step = 0
    for epoch in range(cfg.epochs):
        net.train()
        perm = rng.permutation(n)
        for i in range(steps_per_epoch):
            idx = np.sort(perm[i * batch:(i + 1) * batch])
            x = torch.from_numpy(data[idx])
            frac_b = min(1.0, step / max(1.0, cfg.nll_beta_fraction * total_steps))
            beta = cfg.nll_beta + (cfg.nll_beta_final - cfg.nll_beta) * frac_b
            frac_a = min(1.0, step / max(1.0, cfg.alpha_ramp_fraction * total_steps))
            alpha = cfg.alpha_start * (cfg.alpha / cfg.alpha_start) ** frac_a
            loss, parts = model.loss(x, penalty, beta, alpha)
            if not torch.isfinite(loss):
                raise FloatingPointError(f"training diverged at step {step} (loss {float(loss)})")
            opt.zero_grad(set_to_none=True)
            loss.backward()
            nn.utils.clip_grad_norm_(net.parameters(), cfg.grad_clip)
            opt.step()
            sched.step()
            step += 1
            acc["loss"] += float(loss.detach())
            acc[cfg.loss] += parts[cfg.loss]
            acc["penalty"] += parts["penalty"]
            acc["m"] += 1
            if step % log_every == 0 or step == total_steps:
                m = acc.pop("m")
                entry = {"step": step, "seconds": time.perf_counter() - t0, "lr": sched.get_last_lr()[0], "beta": beta,
                         "alpha": alpha, **{k: v / m for k, v in acc.items()}}
                log.append(entry)
                acc = {"loss": 0.0, cfg.loss: 0.0, "penalty": 0.0, "m": 0}
                if bar is not None:
                    bar.set_postfix(loss=f"{entry['loss']:.3f}", penalty=f"{entry['penalty']:.3g}")
            if bar is not None:
                bar.update(1)
        net.eval()
        ev = evaluation(model, val)
        ev.update({"epoch": epoch + 1, "step": step, "seconds": time.perf_counter() - t0})
        val_log.append(ev)
        if bar is not None:
            bar.write(f"epoch {epoch + 1}: " + (describe(ev) if describe is not None else
                                                ", ".join(f"{k} {v:.4g}" for k, v in ev.items()
                                                          if k not in ("epoch", "step", "seconds"))))
    if bar is not None:
        bar.close()
    model.card = {"training": {"seconds": time.perf_counter() - t0, "steps": step, "threads": threads,
                               "torch": torch.__version__, "loss_log": log, "validation_log": val_log}}
    return model


class TaskPenalty:
    """The training penalty of a robot's joint-space family with a task: ``sum_k ||r(q[k])||^2``
    over the decoded trajectory, ``r`` the task's weighted constraint residuals (its primary
    terms but the condition and the joint limits, evaluated natively:
    :class:`genplan.samplers.costs.NativeCost`). ``margin`` is unused (a residual has no cone to
    tighten)."""

    def __init__(self, robot: Any, task: Any) -> None:
        from genplan.samplers.costs import NativeCost
        from genplan.seq2seq.objectives import constraint_terms

        self.cost = NativeCost(robot, constraint_terms(task, robot))

    def __call__(self, r: Any, margin: float) -> torch.Tensor:
        b, k, n = r.p.shape
        res = self.cost(r.p.reshape(b * k, n))
        return (res ** 2).sum(-1).reshape(b, k).sum(-1)


@torch.no_grad()
def residual_ratio(model: Seq2SeqModel, x: NDArray[np.float32], robot: Any, task: Any, batch: int = 256) -> float:
    """The largest constraint residual over its tolerance along the decodings of ``x`` (the card's
    measure of how far the decoded trajectories stray from the task's manifold)."""
    from genplan.projection import GaussNewtonProjector, SolverSettings, Task
    from genplan.seq2seq.objectives import constraint_terms

    terms = constraint_terms(task, robot)
    if not terms:
        return 0.0
    check = GaussNewtonProjector(robot, Task(primary=terms, name="check"),
                                 SolverSettings(max_iterations=0, clip_to_limits=False))
    tol = {t.label(): float(t.tolerance) for t in terms}
    worst = 0.0
    for i in range(0, len(x), batch):
        _, out = model.forward(torch.as_tensor(x[i:i + batch]))
        q = out.p.double().reshape(-1, out.p.shape[-1]).numpy()
        res = check.solve_batch(q).residuals
        worst = max(worst, max(float(np.max(v)) / tol[k] for k, v in res.items()))
    return worst


def train_family(data: Any, *, robot: Any = None, seed: int = 0, held_out: float = 0.05, progress: bool = True,
                 **overrides: Any) -> Seq2SeqModel:
    """A model of the joint-space family ``data`` (a :class:`~genplan.seq2seq.data.TrajectorySet`):
    the config from :func:`~genplan.seq2seq.config.joint_space_config` (the robot's joint ranges,
    the data's K) with ``overrides``; the task's residuals as the penalty when the set has a task;
    ``held_out`` of the trajectories kept for the card's evaluation (reconstruction error, the
    largest residual along the decodings). The card records the data's hash and ranges, the robot,
    the task and the evaluation."""
    from genplan.projection import Task
    from genplan.robots import load
    from genplan.seq2seq.config import joint_space_config

    if data.space != "joint":
        raise SettingsError(f"train_family: a {data.space}-space data set; joint-space families only (the pancake's "
                            "task space trains with genplan.pancake.model.train)")
    if robot is None:
        if data.robot is None:
            raise SettingsError("train_family: the data set names no robot: pass robot=")
        robot = load(_robot_source(data.robot))
    data.check_robot(robot, "training data")
    task = Task.from_dict(data.task, robot) if data.task is not None else None
    penalty_name = "task" if task is not None else "none"
    cfg = joint_space_config(robot.joint_names, data.K, robot.lower, robot.upper, seed=seed,
                             penalty=overrides.pop("penalty", penalty_name), **overrides)
    train_set, val_set = data.split(held_out, seed)
    cfg = cfg.replace(trajectories=len(train_set), validation=len(val_set))
    penalty = TaskPenalty(robot, task) if (task is not None and cfg.penalty == "task") else None
    t0 = time.perf_counter()
    model = fit(cfg, train_set.positions.astype(np.float32), val_set.positions.astype(np.float32), penalty=penalty,
                progress=progress, log_every=20)
    evaluation = evaluate(model, val_set.positions.astype(np.float32), penalty)
    if task is not None:
        evaluation["max_residual_ratio"] = residual_ratio(model, val_set.positions.astype(np.float32), robot, task)
    model.card.update({
        "description": f"seq2seq model of a joint-space family of {robot.name} trajectories",
        "data": {"sha256": data.sha256, "trajectories": len(data), "training": len(train_set),
                 "held_out": len(val_set), "K": data.K, "source": data.source, "ranges": data.ranges()},
        "robot": {**{k: v for k, v in data.robot.items() if k != "description"}, "source": _robot_source(data.robot)}
        if data.robot is not None else {"name": robot.name, "source": robot.source or robot.name},
        "task": {"name": task.name, "terms": task.to_dict()} if task is not None else None,
        "scene": data.scene,
        "space": {"kind": "joint", "axes": list(robot.joint_names)},
        "evaluation": evaluation,
    })
    model.card["training"]["total_seconds"] = time.perf_counter() - t0
    return model


def _robot_source(record: dict[str, Any]) -> str:
    """What genplan.load takes to load the robot of a manifest record: its robot file, else its
    preset name."""
    files = record.get("files") or {}
    if "source" in files and Path(files["source"]["path"]).is_file():
        return str(files["source"]["path"])
    return str(record.get("name"))
