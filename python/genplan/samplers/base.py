"""What the learned samplers share (the GAN, :mod:`genplan.samplers.gan`, and the flow,
:mod:`genplan.samplers.flow`): the feature space of configurations and its standardisation
(:class:`Codec`), the model interface the planner and ``solve_ik`` use (:class:`SamplerModel`),
how a model file is matched to a robot and a task (:func:`check_model_fits`), the command that
retrains a model (:func:`train_command`), and the checked inputs of a training run
(:func:`prepare_training`).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pinocchio as pin
import torch
from numpy.typing import ArrayLike, NDArray

from genplan import projection as P
from genplan._arrays import as_box, as_configurations, as_float_array, error_class
from genplan.errors import GenplanError, ModelFileError, SettingsError, ShapeError
from genplan.model_files import inside_package, models_dir, out_option
from genplan.robots import PRESETS_DIR, Robot, load

__all__ = ["NATIVE_NOISE_MAX", "ROBOT_HASH_KEY", "STD_FLOOR", "TARGET_MARGIN", "Codec", "SamplerConfig", "SamplerModel",
           "TrainingData",
           "check_model_fits", "check_model_robot", "feature_dim", "missing_model", "models_dir", "prepare_training",
           "retrain_hint", "task_option",
           "robot_origin", "train_command"]

#: the card key holding the kinematic hash of the robot a model was trained for
#: (:attr:`genplan.robots.Robot.kinematic_hash`), what a loader matches the robot given against
ROBOT_HASH_KEY = "robot_kinematic_hash"
#: targets are accepted up to this far (m) outside the model's target box (:meth:`SamplerModel.target_limits`):
#: beyond every target a shipped model is trained on (end-effector positions of valid
#: configurations, which reach past the boxes by less than a metre), not so far that the
#: generator's float32 arithmetic overflows (farther targets are out of reach anyway).
TARGET_MARGIN = 1.0
#: bound on the native sampler's Gaussian noise: Box-Muller from 53-bit uniforms, sqrt(106 ln 2) = 8.57
NATIVE_NOISE_MAX = 8.6
#: smallest feature scale used for standardisation (rad or m)
STD_FLOOR = 0.05


class SamplerConfig:
    """What the learned samplers' configurations (:class:`~genplan.samplers.gan.GanConfig`,
    :class:`~genplan.samplers.flow.FlowConfig`, frozen dataclasses) share: the robot, the task,
    the target frame and the target box are fields of each; each is checked when made
    (``validate``, SettingsError naming the field)."""

    robot: str
    task: str
    target_box: Any

    @property
    def task_name(self) -> str:
        """The task's name (a card written before tasks were files has none: ``<robot>_ik``)."""
        return self.task or f"{self.robot}_ik"

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """SettingsError naming the first field with a value training or sampling cannot use."""
        raise NotImplementedError

    def check_target_box(self) -> None:
        """SettingsError unless :attr:`target_box` is a box ``[[low], [high]]`` of 3-D positions."""
        try:
            as_box(self.target_box, f"{type(self).__name__}.target_box")
        except GenplanError as exc:
            raise SettingsError(str(exc)) from None


def feature_dim(robot: Robot) -> int:
    """The generator's output size: nq, less one for a free-flyer's quaternion (a rotation vector)."""
    return robot.nq - int(robot.floating_base)


class Codec:
    """Maps configurations to the generator's feature space and back.

    Panda: the 7 joint angles. Talos: base position (3), base rotation vector (3), 28 joints.
    A continuous joint (Kinova) is its [cos, sin] pair as q holds it: two features, which
    :meth:`decode` scales back to unit norm (no angle wraps around, no limit to respect).
    Features are standardised with the data's mean and standard deviation.
    """

    def __init__(self, robot: Robot, mean: NDArray[np.float64], std: NDArray[np.float64]) -> None:
        self.robot = robot
        self.floating = robot.floating_base
        self.mean = torch.tensor(mean, dtype=torch.float32)
        self.std = torch.tensor(std, dtype=torch.float32)
        self.dim = len(mean)
        #: q indices of each continuous joint's cos (its sin follows): the pairs decode normalises
        self.continuous = [int(i) for i in robot.continuous]

    @staticmethod
    def features(robot: Robot, q: NDArray[np.float64]) -> NDArray[np.float64]:
        if not robot.floating_base:
            return np.array(q, dtype=np.float64)
        rotvec = np.array([pin.log3(pin.Quaternion(*qq[[6, 3, 4, 5]]).toRotationMatrix()) for qq in q])
        return np.concatenate([q[:, :3], rotvec, q[:, 7:]], axis=1)

    def decode(self, x: torch.Tensor) -> torch.Tensor:
        """Standardised features (..., dim) to configurations (..., nq)."""
        f = x * self.std + self.mean
        if self.floating:
            rv = f[..., 3:6]
            angle = torch.sqrt((rv * rv).sum(-1, keepdim=True) + 1e-12)
            xyz = rv * (torch.sin(angle / 2) / angle)
            quat = torch.cat([xyz, torch.cos(angle / 2)], -1)
            f = torch.cat([f[..., :3], quat, f[..., 6:]], -1)
        if not self.continuous:
            return f
        parts, start = [], 0
        for i in self.continuous:
            pair = f[..., i:i + 2]
            # floored as the rotation vector's angle above, and as the native codec does
            # (rust/core/src/codec.rs): no division by zero
            norm = torch.sqrt((pair * pair).sum(-1, keepdim=True) + 1e-12)
            parts += [f[..., start:i], pair / norm]
            start = i + 2
        parts.append(f[..., start:])
        return torch.cat(parts, -1)


class SamplerModel:
    """What the learned samplers (:class:`genplan.samplers.gan.GanModel`, :class:`genplan.samplers.flow.FlowModel`) share:
    configurations of ``robot`` conditioned on targets, answered for targets in the config's
    ``target_box`` widened by :data:`TARGET_MARGIN`."""

    config: Any
    robot: Robot
    card: dict[str, Any]
    #: the model's kind in messages ("GAN", "flow")
    KIND: ClassVar[str] = "model"

    def card_to_write(self) -> dict[str, Any]:
        """The card as saved: :attr:`card` with the kinematic hash of :attr:`robot`, which a
        loader matches the robot it is given against (:func:`check_model_fits`)."""
        return {**self.card, ROBOT_HASH_KEY: self.robot.kinematic_hash}

    def sample(self, targets: ArrayLike, rng: np.random.Generator | int | None = None, *,
               threads: int | None = None) -> NDArray[np.float64]:
        """One configuration per target (n, 3) -> (n, nq)."""
        raise NotImplementedError

    def native_sampler(self, box: Any = None, seed: int = 0) -> Any:
        """The model run natively (Rust): what the planner uses."""
        raise NotImplementedError

    def draw_native(self, native: Any, targets: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.float64]:
        """One configuration per target (n, 3), from ``native`` (this model's
        :meth:`native_sampler`) with its random inputs (noise clipped to :data:`NATIVE_NOISE_MAX`)
        drawn from ``rng``: (n, nq)."""
        raise NotImplementedError

    def target_limits(self) -> NDArray[np.float64]:
        """The box of targets the model answers for, [[xmin, ymin, zmin], [xmax, ymax, zmax]]: its
        target box widened by :data:`TARGET_MARGIN` on every side. Farther targets are refused
        (clip them yourself, e.g. ``np.clip(targets, *model.target_limits())``, to sample anyway)."""
        box = as_box(self.config.target_box)
        return np.stack([box[0] - TARGET_MARGIN, box[1] + TARGET_MARGIN])

    def check_targets(self, targets: Any, what: str = "targets") -> NDArray[np.float64]:
        """``targets`` as finite positions (n, 3) inside :meth:`target_limits`, else ShapeError,
        NonFiniteError or GenplanError naming the first bad row."""
        t = as_float_array(targets, what)  # strings, None, complex: refused naming `what`
        shape_ok = t.ndim == 2 and t.shape[1] == 3
        if not shape_ok or not np.all(np.isfinite(t)):
            row = "" if not shape_ok else f" (row {int(np.argwhere(~np.isfinite(t))[0, 0])} is not)"
            raise error_class(t, shape_ok)(f"{what}: expected finite positions of shape (n, 3), got {t.shape}{row}")
        lim = self.target_limits()
        outside = np.flatnonzero(((t < lim[0]) | (t > lim[1])).any(1))
        if len(outside):
            i = int(outside[0])
            raise GenplanError(
                f"{what}: row {i} {t[i].tolist()} lies outside the region this model answers for, "
                f"{lim.round(3).tolist()} (its target box widened by {TARGET_MARGIN} m; {len(outside)} row(s) "
                f"outside); clip the targets into it to sample anyway")
        return t


def robot_origin(robot: Robot) -> str:
    """Where ``robot`` comes from, for messages: "preset", "robot file PATH" or "URDF PATH"."""
    if robot.source is None:
        return f"URDF {robot.urdf_path}"
    return "preset" if robot.source.parent == PRESETS_DIR else f"robot file {robot.source}"


def _differ(recorded: str, given: Robot) -> str:
    return (f"the active joints or the kinematic chain between them differ (kinematic hash {recorded[:12]}... "
            f"recorded, {given.kinematic_hash[:12]}... of the robot given)")


def check_model_robot(model: SamplerModel, robot: Robot) -> None:
    """ModelFileError unless the model in memory ``model`` was made for ``robot``'s kinematics
    (:attr:`~genplan.robots.Robot.kinematic_hash`; the name does not matter), naming both robots."""
    if model.robot is not robot and model.robot.kinematic_hash != robot.kinematic_hash:
        raise ModelFileError(f"the {model.KIND} is for robot '{model.robot.name}' ({robot_origin(model.robot)}), not "
                             f"'{robot.name}' ({robot_origin(robot)}): {_differ(model.robot.kinematic_hash, robot)}")


def check_model_fits(path: Path, kind: str, cfg: Any, card: dict[str, Any], rob: Robot,
                     task: "str | os.PathLike[str] | P.Task | None") -> None:
    """ModelFileError unless the model file ``path`` (a ``kind``, "GAN" or "flow", of config
    ``cfg`` and card ``card``) is for robot ``rob``, for ``task`` (when given: by name, and by its
    terms: those the card records, else those of the shipped task of the card's task name, which
    a card written before tasks were files was trained for), and its target frame is a frame of
    ``rob``.

    The robot is matched by the kinematic hash its card records
    (:attr:`~genplan.robots.Robot.kinematic_hash`: the active joints and the chain between them),
    not by name: another robot of the same name is refused, the same robot under another name or
    with other values of locked joints off the chain (a Panda's fingers) is accepted. A card
    written before the hash existed is matched by name, with a
    :class:`~genplan.model_files.ModelCardWarning` (once per file)."""
    from genplan.model_files import check_sha256, warn_once

    card_path = path.with_suffix(".json")
    if card.get("robot", cfg.robot) != cfg.robot:
        raise ModelFileError(f"{path} is a {kind} for robot '{cfg.robot}', not '{rob.name}' (and its card also says "
                             f"'{card['robot']}')")
    recorded = card.get(ROBOT_HASH_KEY)
    if recorded is None:
        if cfg.robot != rob.name:
            raise ModelFileError(f"{path} is a {kind} for robot '{cfg.robot}', not '{rob.name}'")
        warn_once(card_path, card, f"{card_path} records no robot kinematic hash (written before genplan recorded "
                                   f"one): the {kind} is matched to robot '{rob.name}' by its name only; save it again "
                                   "(load it, then .save(path)) to record the hash of this robot")
    elif check_sha256(recorded, f"{kind} model card {card_path}: {ROBOT_HASH_KEY}") != rob.kinematic_hash:
        source = card.get("robot_source")
        trained = f"; it was trained for {source}" if isinstance(source, str) and source else ""
        raise ModelFileError(f"{path} is a {kind} for robot '{cfg.robot}', not '{rob.name}' ({robot_origin(rob)}): "
                             f"{_differ(recorded, rob)}{trained}; give the model trained for this robot, or "
                             f"train one: `{train_command(rob, model=kind.lower())}`")
    if task is not None:
        t = P.load_task(task, rob)
        if t.name != cfg.task_name:
            raise ModelFileError(f"{path} is a {kind} for task '{cfg.task_name}', not '{t.name}' (robot '{rob.name}')")
        terms = card["task"] if "task" in card else _shipped_task(path, kind, cfg, rob)
        if _comparable(terms) != _comparable(t.to_dict()):
            raise ModelFileError(f"{path} is a {kind} for another task '{cfg.task_name}' than the one given (same "
                                 "name, other terms: retrain it for this task)")
    if cfg.target_frame not in rob.frames and not rob.model.existFrame(cfg.target_frame):
        raise ModelFileError(f"{path}: the {kind}'s target frame '{cfg.target_frame}' is not a frame of "
                             f"'{rob.name}' (roles: {sorted(rob.frames)}, or any link name)")


def _shipped_task(path: Path, kind: str, cfg: Any, rob: Robot) -> dict[str, Any]:
    """The terms (:meth:`~genplan.projection.Task.to_dict`) of the task a model whose card records
    none was trained for: the shipped task of its task name (``<robot>_ik`` for a card written
    before tasks were files). ModelFileError when no shipped task has that name: the terms the
    model was trained for are then unknown, and a task given cannot be matched to them."""
    name = cfg.task_name
    if name not in P.task_names():
        raise ModelFileError(f"{path}: its card records no task, and '{name}' (the task it names) is not a shipped "
                             f"task, so the terms the {kind} was trained for are unknown; retrain it for the task given")
    return P.load_task(name, rob).to_dict()


def _comparable(task: dict[str, Any]) -> str:
    import json

    return json.dumps(task, sort_keys=True, default=str)


def train_command(robot: "Robot | str", task: str | None = None, seed: int = 0, model: str = "gan", *,
                  options: str = "", out: "str | os.PathLike[str] | None" = None) -> str:
    """The CLI command that trains a ``model`` ("gan", or "flow": :mod:`genplan.samplers.flow`) for
    ``robot`` (a Robot: its preset name or robot file; or the --robot argument as given) and
    ``task`` (the --task argument, None for the default), with further ``options`` as typed
    (e.g. ``" --iterations 5"``), writing ``out``. A command always names ``--out`` (training never
    writes into the installed package: :func:`genplan.cli.args.model_output`); without ``out``,
    ``<robot>_<model>.safetensors`` in the current folder."""
    if isinstance(robot, str):
        target, name = robot, Path(robot).stem
    else:
        target = robot.name if robot.source is None or robot.source.parent == PRESETS_DIR else str(robot.source)
        name = robot.name
    return (f"genplan train {model} --robot {target}" + (f" --task {task}" if task else "") + f" --seed {seed}"
            + options + out_option(Path(out) if out is not None else Path(f"{name}_{model}.safetensors")))


def retrain_hint(robot: Robot, path: Path, model: str = "gan",
                 task: "str | os.PathLike[str] | P.Task | None" = None) -> str:
    """The command a missing model file's error names: one writing ``path``, or, for a path
    inside the installed package (a shipped model missing: reinstall genplan), one writing
    ``<robot>_<model>.safetensors`` in the current folder; for ``task`` (the task the model was
    asked for, as the caller gave it: :func:`task_option`)."""
    return train_command(robot, task_option(robot, task), seed=0, model=model,
                         out=None if inside_package(path) else path)


def task_option(robot: Robot, task: "str | os.PathLike[str] | P.Task | None") -> str | None:
    """The ``--task`` of a command training a model of ``robot`` for ``task``: None for the
    robot's shipped ``<robot>_ik`` (the default); a shipped task's name or a task file as given; a
    Task by its shipped name. A task known by no name or file here (a Task built in Python, none
    for a robot without a shipped task) is ``TASK.toml``, a file the user writes (docs/TASKS.md):
    without it, the command would fail for want of a task."""
    default = f"{robot.name}_ik"
    if isinstance(task, P.Task):
        task = task.name if task.name in P.task_names() else None
        if task is None:
            return "TASK.toml"
    if task is None:
        return None if default in P.task_names() else "TASK.toml"
    return None if str(task) == default else str(task)


def missing_model(robot: Robot, kind: str, model: str, shipped: tuple[str, ...],
                  task: "str | os.PathLike[str] | P.Task | None") -> FileNotFoundError:
    """The error of a model asked for without a file (the shipped one) for a robot genplan ships
    none for: what to give instead, and the command training one (not the package's path, which
    is no place for the user's models)."""
    cmd = train_command(robot, task_option(robot, task), seed=0, model=model)
    where = " (TASK.toml: a task file with a [condition], docs/TASKS.md)" if "TASK.toml" in cmd else ""
    return FileNotFoundError(f"robot '{robot.name}' has no shipped {kind} (genplan ships {kind}s for "
                             f"{', '.join(shipped) or 'no robot'}): give a {kind} file (--model M.safetensors, "
                             f"path=M.safetensors), or train one with `{cmd}`{where}")


@dataclass
class TrainingData:
    """What a learned sampler trains on (:func:`prepare_training`)."""

    robot: Robot
    task: P.Task
    #: valid configurations (n, nq)
    data: NDArray[np.float64]
    #: "given", "cache" or "generated"
    data_source: str
    data_seconds: float
    #: the data's features (n, dim), not standardised
    features: NDArray[np.float64]
    #: standardisation of the features (scales floored at :data:`STD_FLOOR`)
    codec: Codec


def prepare_training(cfg: Any, data: NDArray[np.float64] | None, progress: bool, robot: Robot | None,
                     task: "P.Task | None", kind: str) -> TrainingData:
    """The robot, task, data and codec of a training run of ``cfg`` (a GanConfig or FlowConfig:
    ``robot``, ``task_name``, ``data_size``, ``data_seed``, ``target_frame``), checked: a robot or
    task other than the config's, misshapen data, a target frame the robot
    lacks, or a task that the card or its evaluation could not use
    (:func:`genplan.projection.check_task_use`) raise before any work. ``kind`` names the model
    in messages."""
    from genplan.samplers.data import cache_path, valid_configurations

    robot = load(cfg.robot) if robot is None else robot  # cfg is valid: a frozen config validates when made
    if robot.name != cfg.robot:
        raise SettingsError(f"{type(cfg).__name__}.robot is '{cfg.robot}', the robot given '{robot.name}'")
    task = P.load_task(cfg.task_name, robot) if task is None else task
    if task.name != cfg.task_name:
        raise SettingsError(f"{type(cfg).__name__}.task is '{cfg.task_name}', the task given '{task.name}'")
    P.check_task_use(task, robot)  # what the card and its evaluation do with the task, tried before training
    if getattr(cfg, "target_frame", None) is not None:
        robot.frame_positions(robot.q_default, cfg.target_frame)
    if data is not None:
        data = as_configurations(data, robot.nq, "data")
        if data.ndim != 2:
            raise ShapeError(f"data: expected configurations of shape (n, {robot.nq}), got {data.shape}")
    t_data = time.perf_counter()
    data_source = "given"
    if data is None:
        in_box = getattr(cfg, "data_in_box", 0.0)  # a GAN's share of rows in the condition's box
        cached = cache_path(robot, cfg.data_size, cfg.data_seed, task, in_box=in_box).is_file()
        data_source = "cache" if cached else "generated"
        data = valid_configurations(robot, cfg.data_size, cfg.data_seed, progress=progress, task=task, in_box=in_box)
    t_data = time.perf_counter() - t_data
    feats = Codec.features(robot, data)
    # Scales are floored: a feature the constraints pin (Talos' left arm, the Panda hand's axis)
    # has a near-zero spread, and dividing by it would turn any deviation into a huge input.
    codec = Codec(robot, feats.mean(0), np.maximum(feats.std(0), STD_FLOOR))
    return TrainingData(robot, task, data, data_source, t_data, feats, codec)


