"""``genplan adjust``: adjust trajectories to an objective in a seq2seq model's latent space
(:func:`genplan.seq2seq.adjust.adjust`), then make each executable: projected onto the task's
manifold, checked against the scene and timed (:func:`genplan.seq2seq.finish.finish`).

    genplan adjust --model shelf.safetensors --input start.npz --objective reach.toml \\
        --targets goals.npz --out adjusted/ [--method latent] [--updates 40] [--scene panda_shelf] [--starts 4]

Inputs, each checked (a typed error naming the file and the field, before any work):

* ``--model``: a joint-space family's model (``genplan train seq2seq --data``);
* ``--input``: the trajectories to start from: a ``.npz`` with ``q`` of shape (B, K, n) or (K, n)
  in the model's axes (``joint_names``, when given, must be the model's; a single trajectory
  of another length with its times ``t`` is resampled onto the model's K samples, as a
  ``Trajectory.save`` file is), or a trajectory data set's folder (``genplan data
  trajectories``) of the model's robot;
* ``--objective``: an objective file (TOML: ``[[term]]`` tables, see genplan.seq2seq.objectives);
* ``--targets``: a ``.npz`` of per-problem targets keyed by the objective's term names (e.g.
  ``end_position``: (B, 3)); optional when every term's target is written in the file.

``--starts K``: a problem whose first start leaves a clearance term of the objective positive is
adjusted again from K - 1 other starts and finished from the first start that passes (see
:func:`genplan.seq2seq.adjust.adjust`); default 8 for an objective with a clearance term, else 1.
``--pool DIR``: trajectories of the family (the model's training data, say) those restarts start
from: the pool's members near the problem's input that score best on the objective.

Writes to ``--out`` (a folder): ``adjusted.npz`` (the adjusted trajectories ``p``, ``v``, ``u`` of
the start each problem kept, the latent ``z``, per problem ``success``, ``end_error_m``,
``max_residual_ratio``, ``starts_run`` (the starts it ran) and ``start_index`` (the start its
finished trajectory came from, 0 the input's encoding), and the objective per update
``objective_history`` (updates + 1, B)); ``objective.json`` (the objective per update, per problem
and its mean); ``summary.json`` (per problem: success or the reason it failed, end error, largest
residual over the task's tolerance, the starts it ran and the one it finished from, its trajectory
file; the run's settings and times); and ``trajectory_NNNNN.npz`` for each problem that finished (a
:class:`~genplan.trajectory.Trajectory`, as a plan gives: ``genplan execute --trajectory``). A
``trajectory_NNNNN.npz`` of an earlier run into the same folder whose problem did not finish this
time is removed, so the folder holds this run's results only. Every file is written whole or not
at all.

Exit code 0 when every problem finished (within the task's tolerance, collision-free, timed), 1
when any did not (the summary says how many and why); never a success for a trajectory that fails
its check.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from genplan.cli import args as A

#: the trajectory files of a run (what a later run into the same folder replaces)
TRAJECTORY_FILE = re.compile(r"trajectory_\d{5}\.npz")


def add_arguments(p: argparse.ArgumentParser) -> None:
    # --method and --step are checked by main against genplan.seq2seq.adjust's METHODS and STEPS
    # (importing it here would import torch into every command's parser)
    p.add_argument("--model", type=A.existing_file, required=True,
                   help="a seq2seq model of a robot's joint-space family (.safetensors with its .json card)")
    p.add_argument("--input", required=True,
                   help="the trajectories to start from: a .npz with q (B, K, n) or (K, n), or a trajectory data set's "
                        "folder")
    p.add_argument("--objective", type=A.existing_file, required=True, help="an objective file (.toml)")
    p.add_argument("--targets", type=A.existing_file, default=None,
                   help="a .npz of per-problem targets keyed by the objective's term names (e.g. end_position: (B, 3))")
    p.add_argument("--out", type=A.output_folder, required=True, help="the folder the results are written to")
    p.add_argument("--method", default="latent",
                   help="latent (from the input's encoding, the paper's), random-latent, or direct (the decoder's "
                        "output itself); default latent")
    p.add_argument("--updates", type=A.non_negative_int, default=100, help="gradient updates (default 100)")
    p.add_argument("--lr", type=A.positive_float, default=None,
                   help="the step's learning rate (default: 1 for gd and adaptive, the method's for adam)")
    p.add_argument("--step", default="adaptive",
                   help="the step rule: adaptive (eq. 7 in a trust radius; default), gd (eq. 7), adam")
    p.add_argument("--scene", default=None,
                   help="the scene (a shipped scene's name or a scene file) of the objective's clearance terms and "
                        "of the finished trajectories' collision checks (default: the --input data set's scene; "
                        "none for a .npz input)")
    p.add_argument("--seed", type=A.seed, default=0,
                   help="the seed of random-latent's starting z and of the restarts' starts (default 0)")
    p.add_argument("--pool", default=None,
                   help="trajectories the restarts may start from (as --input: a data set's folder, e.g. the model's "
                        "training data, or a .npz): the restarts of a problem start from the encodings of the pool's "
                        "members near its input that score best on the objective (genplan.adjust's pool)")
    p.add_argument("--starts", type=A.positive_int, default=None,
                   help="starts per problem: a problem whose adjusted trajectory leaves a clearance term of the "
                        "objective positive is adjusted again from the others, and the finish falls back on them "
                        "(default: genplan.seq2seq.adjust's, see genplan.adjust)")
    A.add_allow_python(p, "--objective")
    p.add_argument("--threads", type=A.positive_int, default=None,
                   help="torch threads (default: genplan's choice, one; $GENPLAN_TORCH_THREADS overrides it too)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _model_robot(model: Any) -> dict[str, Any]:
    robot = model.card.get("robot")
    return robot if isinstance(robot, dict) else {}


def _inputs(path_text: str, model: Any, model_path: Path, option: str = "--input") -> tuple[np.ndarray, dict[str, Any]]:
    """The trajectories (B, K, n) of ``option`` (``--input`` or ``--pool``) and where they came
    from, checked against the model."""
    from genplan._files import read_npz
    from genplan.errors import GenplanError, NonFiniteError, ShapeError, UnknownNameError
    from genplan.seq2seq.data import read_trajectories, resample
    from genplan.seq2seq.model import check_trajectories

    cfg = model.config
    axes = list(cfg.axes)
    path = Path(path_text)
    if path.is_dir():
        data = read_trajectories(path)
        if list(data.axes) != axes:
            raise UnknownNameError(f"{option} {path}: a data set of the axes {list(data.axes)}; the model {model_path} "
                                   f"is of {axes}")
        theirs, mine = (data.robot or {}).get("sha256"), _model_robot(model).get("sha256")
        if theirs is not None and mine is not None and theirs != mine:
            raise GenplanError(f"{option} {path}: a data set of robot '{(data.robot or {}).get('name')}' (sha256 "
                               f"{str(theirs)[:12]}), the model {model_path} is of robot "
                               f"'{_model_robot(model).get('name')}' (sha256 {str(mine)[:12]}): their files differ")
        if data.K != cfg.K:
            raise ShapeError(f"{option} {path}: trajectories of {data.K} samples, the model {model_path} takes {cfg.K}")
        return data.positions, {"data_set": str(path), "sha256": data.sha256, "scene": data.scene}
    if not path.is_file():
        raise FileNotFoundError(f"{option} {path}: no such file or folder")
    arrays = read_npz(path, option)
    if "q" not in arrays:
        raise GenplanError(f"{option} {path}: no array 'q' (the trajectories, shape (B, {cfg.K}, {cfg.dim})); it holds "
                           f"{sorted(arrays)}")
    if "joint_names" in arrays:
        names = [str(n) for n in np.atleast_1d(arrays["joint_names"])]
        if names != axes:
            raise UnknownNameError(f"{option} {path}: joint_names {names}, the model {model_path} is of {axes}")
    q = arrays["q"]
    if q.dtype.kind not in "iuf":
        raise GenplanError(f"{option} {path}: q holds {q.dtype} values, expected numbers")
    q = q.astype(np.float64)
    if q.ndim == 2 and len(q) != cfg.K and "t" in arrays:  # a timed trajectory: onto the model's K samples
        if not np.all(np.isfinite(q)):
            raise NonFiniteError(f"{option} {path}: q contains NaN or inf (first at index "
                                 f"{tuple(int(i) for i in np.argwhere(~np.isfinite(q))[0])})")
        q = resample(np.asarray(arrays["t"], dtype=np.float64), q, cfg.K, f"{option} {path}")
    try:
        x = check_trajectories(q, cfg.K, cfg.dim, name=f"{option} {path}: q")
    except GenplanError as exc:
        raise type(exc)(str(exc)) from None
    return x, {"file": str(path)}


def _targets(path: Path | None, objective: Any, batch: int) -> dict[str, np.ndarray]:
    """The per-problem targets of ``path``, keyed by the objective's term names."""
    from genplan._files import read_npz
    from genplan.errors import GenplanError, NonFiniteError, ShapeError, UnknownNameError

    if path is None:
        return {}
    targets = read_npz(path, "--targets")
    names = [t.name for t in objective.terms]
    unknown = sorted(set(targets) - set(names))
    if unknown:
        raise UnknownNameError(f"--targets {path}: {unknown} name no term of the objective '{objective.name}'; its "
                               f"terms: {names}")
    out = {}
    for key, a in targets.items():
        if a.dtype.kind not in "iuf":
            raise GenplanError(f"--targets {path}: {key} holds {a.dtype} values, expected numbers")
        a = a.astype(np.float64)
        if a.ndim == 0 or len(a) != batch:
            raise ShapeError(f"--targets {path}: {key} has shape {a.shape}, expected one target per problem "
                             f"({batch}, ...)")
        if not np.all(np.isfinite(a)):
            raise NonFiniteError(f"--targets {path}: {key} contains NaN or inf (first at index "
                                 f"{tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])})")
        out[key] = a
    return out


def main(args: argparse.Namespace) -> int:
    from genplan._files import atomic_path, write_text
    from genplan.errors import GenplanError
    from genplan.model_files import json_default
    from genplan.seq2seq.adjust import METHODS, STEPS, adjust
    from genplan.seq2seq.model import load_model
    from genplan.seq2seq.objectives import load_objective

    for option, value, known in (("--method", args.method, METHODS), ("--step", args.step, STEPS)):
        if value not in known:
            raise A.UsageError(f"argument {option}: invalid choice: {value!r} (choose from {', '.join(known)})")
    model = load_model(args.model)
    if model.config.plant != "position" or not _model_robot(model):
        raise A.UsageError(f"--model {args.model}: not a model of a robot's joint-space family (its plant is "
                           f"{model.config.plant!r}): genplan adjust finishes joint trajectories of a robot; the "
                           "pancake's model adjusts with genplan.pancake.adjust")
    x, source = _inputs(args.input, model, args.model)
    objective = load_objective(args.objective, allow_python=args.allow_python)
    targets = _targets(args.targets, objective, len(x))
    pool = None if args.pool is None else _inputs(args.pool, model, args.model, "--pool")[0]
    scene: Any = args.scene
    if scene is None and source.get("scene") is not None:  # an input data set's scene
        from genplan.scene import Scene

        scene = Scene.from_dict(source["scene"])
    try:  # every argument is checked before any update: errors name the files
        result = adjust(model, x, objective, targets=targets, method=args.method, updates=args.updates, lr=args.lr,
                        step=args.step, seed=args.seed, scene=scene, allow_python=args.allow_python,
                        progress=not args.no_progress, threads=args.threads, starts=args.starts,
                        pool=pool)
    except GenplanError as exc:
        if isinstance(exc, A.UsageError):
            raise
        raise type(exc)(f"--objective {args.objective}" + (f" with --targets {args.targets}" if args.targets else "")
                        + f": {exc}") from None
    fin = result.finish()
    out = Path(args.out)
    b = result.batch
    files: list[str | None] = [None] * b
    for i in range(b):
        traj = fin.trajectories[i]
        if fin.success[i] and traj is not None:
            name = f"trajectory_{i:05d}.npz"
            traj.save(out / name)
            files[i] = name
    for f in out.iterdir():  # an earlier run's trajectories whose problem did not finish now
        if TRAJECTORY_FILE.fullmatch(f.name) and f.name not in files:
            f.unlink(missing_ok=True)
    success = np.asarray(fin.success, dtype=bool)
    with atomic_path(out / "adjusted.npz") as tmp:
        with open(tmp, "wb") as fh:
            arrays = {"p": result.p, "v": result.v, "u": result.u, "objective_history": result.objective_history,
                      "success": success, "start_index": fin.start_index, "starts_run": result.starts_run,
                      "end_error_m": fin.end_error_m, "max_residual_ratio": fin.max_residual_ratio,
                      "axes": np.array(model.config.axes)}
            if result.z is not None:
                arrays["z"] = result.z
            np.savez(fh, **arrays)
    hist = result.objective_history
    write_text(out / "objective.json", json.dumps({
        "objective": objective.name, "updates": result.updates, "per_problem": hist.tolist(),
        "mean": hist.mean(1).tolist() if b else []}, default=json_default) + "\n")
    reasons = _reasons(fin.reasons)
    summary = {
        "problems": b, "succeeded": int(success.sum()), "failed": int(b - success.sum()), "failure_reasons": reasons,
        "model": {"path": str(args.model), "robot": _model_robot(model).get("name"),
                  "weights_sha256": model.card.get("weights_sha256")},
        "input": {k: v for k, v in source.items() if k != "scene"}, "objective": str(args.objective), "targets": None if args.targets is None else str(args.targets),
        "scene": scene if scene is None or isinstance(scene, str) else getattr(scene, "name", str(scene)),
        "method": result.method, "step": result.step, "lr": result.lr, "updates": result.updates, "seed": args.seed,
        "starts": result.starts, "restarted": int((result.starts_run > 1).sum()),
        "seconds": {"adjust": result.time_total_s, **{f"finish_{k}": v for k, v in fin.seconds.items()}},
        "objective_first": hist[0].tolist() if b else [], "objective_last": hist[-1].tolist() if b else [],
        "results": [{"problem": i, "success": bool(success[i]), "reason": fin.reasons[i],
                     "end_error_m": _number(fin.end_error_m[i]), "max_residual_ratio": _number(fin.max_residual_ratio[i]),
                     "starts_run": int(result.starts_run[i]), "start": int(fin.start_index[i]),
                     "trajectory": files[i]} for i in range(b)],
    }
    write_text(out / "summary.json", json.dumps(summary, indent=1, default=json_default) + "\n")
    end = fin.end_error_m[success]
    print(f"{args.out}: {int(success.sum())} of {b} problems adjusted ({result.method}, {result.updates} updates, "
          f"{1e3 * result.time_total_s / max(b, 1):.1f} ms per problem) and finished"
          + (f"; end error max {1e3 * float(np.nanmax(end)):.3f} mm" if end.size and np.isfinite(end).any() else ""))
    if not success.all():
        print(f"{b - int(success.sum())} of {b} problems failed: "
              + "; ".join(f"{n} x {why}" for why, n in sorted(reasons.items(), key=lambda kv: -kv[1])))
        return A.FAILED
    return 0


def _number(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


def _reasons(reasons: list[str | None]) -> dict[str, int]:
    """How many problems failed for each reason (the numbers in a reason, its sample indices,
    left out, so that problems failing the same way count together)."""
    out: dict[str, int] = {}
    for r in reasons:
        if r is not None:
            key = " ".join(re.sub(r"\d+(\.\d+)?(e-?\d+)?", "#", r).split())
            out[key] = out.get(key, 0) + 1
    return out
