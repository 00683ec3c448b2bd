"""The learned sampler: configurations from a trained GAN (or flow, :mod:`genplan.samplers.flow`),
conditioned on end-effector targets.

It has ``sample(n) -> (n, nq)`` (a :class:`genplan.protocols.Sampler`) and runs torch; its
:meth:`GanSampler.native` twin runs the same generator in Rust, which is what the planner uses.
Uniform and hybrid sampling are native only: :func:`genplan.planning.make_sampler`.

Large calls run in chunks of :data:`CHUNK_ROWS` to ``2 * CHUNK_ROWS - 1`` rows, so that Ctrl-C
is answered between two chunks (within half a second). The random stream is that of one
unchunked call (:meth:`genplan.samplers.GanModel.sample` with the same generator): the same targets,
noise and ensemble members, whatever the chunking. A call of fewer than ``2 * CHUNK_ROWS`` rows
is one chunk, bit for bit the unchunked call; in larger ones the float32 matrix products of a
chunk may round the last bit differently from one product over all rows (the BLAS kernel for
a row depends on the matrix's size), about 1e-6 relative. A sampler stays deterministic: the
same seed and the same calls give the same samples, bit for bit.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import ArrayLike, NDArray

from genplan._arrays import as_box, as_float_array
from genplan._threads import resolve, torch_threads
from genplan.errors import ModelFileError, SettingsError, ShapeError
from genplan.robots import Robot
from genplan.samplers.base import SamplerModel, check_model_robot
from genplan.samplers.flow import FlowModel
from genplan.samplers.gan import GanModel
from genplan.samplers.loading import load_sampler_model

#: rows per chunk (the last chunk takes the rest, up to ``2 * CHUNK_ROWS - 1`` rows): the shipped
#: Panda GAN takes ~0.1 s for 2048 rows on one thread
CHUNK_ROWS = 2048
#: most samples (or targets) per call: ~90 bytes a row stay in memory (targets, output, member
#: choice; the noise is drawn chunk by chunk)
MAX_SAMPLES = 10_000_000


class GanSampler:
    """Configurations from a trained GAN, conditioned on end-effector targets.

    ``sample(n)`` draws targets uniformly in ``box`` (default: the model's target box);
    ``sample_for(targets)`` conditions on given targets. Targets (and ``box``) must be finite and
    lie inside the model's :meth:`~genplan.samplers.GanModel.target_limits` (its target box widened
    by 1 m): farther ones are refused with an error naming the first bad row, not clipped (clip
    them yourself to sample anyway). Every sample is finite, or NonFiniteError names its target
    row. At most :data:`MAX_SAMPLES` per call (SettingsError naming ``n``, ShapeError naming
    ``targets``). ``threads``: torch threads while sampling (default: genplan's choice, one; see
    genplan._threads).

    The random stream is the model's: ``sample_for(targets)`` gives what
    ``model.sample(targets, sampler.rng)`` would, computed in chunks (Ctrl-C is answered between
    them).
    """

    def __init__(self, robot: Robot, model: GanModel | FlowModel | str | Path | None = None,
                 box: ArrayLike | None = None, seed: int | None = None, *, task: Any = None,
                 threads: int | None = None) -> None:
        self.robot = robot
        self.model = model if isinstance(model, SamplerModel) else load_sampler_model(robot, model, task)
        check_model_robot(self.model, robot)  # by kinematics, not by name
        if task is not None and isinstance(model, SamplerModel):
            from genplan import projection as P

            name = P.load_task(task, robot).name
            if name != model.config.task_name:
                raise ModelFileError(f"the GAN is for task '{model.config.task_name}', not '{name}'")
        self.box = as_box(self.model.config.target_box if box is None else box)
        self.model.check_targets(self.box, "box")
        self.threads = None if threads is None else resolve("small", threads)
        self.rng = np.random.default_rng(seed)

    @classmethod
    def load(cls, path: str | Path, robot: Robot, task: Any = None, **kwargs: Any) -> "GanSampler":
        """The sampler of the GAN file ``path`` for ``robot`` (and ``task``: a Task, a shipped
        task's name or a task file; a GAN trained for another robot or task is refused naming
        both, see :func:`genplan.samplers.load_model`). ``kwargs``: ``box``, ``seed``, ``threads``."""
        return cls(robot, Path(path), task=task, **kwargs)

    def native(self, seed: int | None = None) -> Any:
        """The same sampler run natively (Rust): what the planner uses for ``sampler="gan"``."""
        return self.model.native_sampler(self.box, int(self.rng.integers(2**63)) if seed is None else seed)

    def sample_for(self, targets: ArrayLike) -> NDArray[np.float64]:
        """One configuration per target position (n, 3) -> (n, nq)."""
        t = as_float_array(targets, "targets")
        if t.ndim >= 1 and len(t) > MAX_SAMPLES:
            raise ShapeError(f"targets: at most {MAX_SAMPLES} rows per call, got {len(t)}")
        return self._sample(self.model.check_targets(t))

    def sample(self, n: int) -> NDArray[np.float64]:
        """``n`` configurations for targets drawn uniformly in :attr:`box`: (n, nq)."""
        if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 0:
            raise SettingsError(f"n must be a non-negative integer, got {n!r}")
        n = int(n)
        if n > MAX_SAMPLES:
            raise SettingsError(f"n must be at most {MAX_SAMPLES} per call, got {n}")
        targets = np.empty((n, 3))
        for s in range(0, n, CHUNK_ROWS):  # the same stream as one (n, 3) draw
            targets[s:s + CHUNK_ROWS] = self.rng.uniform(self.box[0], self.box[1], size=(min(CHUNK_ROWS, n - s), 3))
        return self._sample(targets)

    @torch.no_grad()
    def _sample(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`GanModel.sample` (python/genplan/samplers/gan.py: noise (n_net, n, noise_dim), then
        a member per row, from one stream) evaluated ``CHUNK_ROWS`` rows at a time; ``t`` checked."""
        model, rng = self.model, self.rng
        if isinstance(model, FlowModel):  # one noise row per target, from the stream in order
            out = np.empty((len(t), self.robot.nq))
            with torch_threads("small", self.threads):
                for s, e in _chunks(len(t)):
                    out[s:e] = model.generate(rng.standard_normal((e - s, model.codec.dim)), t[s:e])
            return out
        n_net, nd, n = model.config.n_net, model.config.noise_dim, len(t)
        # the noise of member m follows that of member m - 1 in the stream: one pass records the
        # stream's state where each member's noise starts (drawing and dropping it, chunk by chunk)
        starts = []
        for _ in range(n_net):
            starts.append(copy.deepcopy(rng.bit_generator.state))
            for s in range(0, n, CHUNK_ROWS):
                rng.standard_normal((min(CHUNK_ROWS, n - s), nd))
        members = []
        for state in starts:
            g = np.random.Generator(type(rng.bit_generator)())
            g.bit_generator.state = state
            members.append(g)
        pick = np.empty(n, dtype=np.int64)
        for s in range(0, n, CHUNK_ROWS):
            pick[s:s + CHUNK_ROWS] = rng.integers(0, n_net, size=min(CHUNK_ROWS, n - s))
        out = np.empty((n, self.robot.nq))
        with torch_threads("small", self.threads):
            for s, e in _chunks(n):
                m = e - s
                q = model.generate(np.stack([g.standard_normal((m, nd)) for g in members]), t[s:e], offset=s)
                out[s:s + m] = q[pick[s:s + m], np.arange(m)]
        return out


def _chunks(n: int) -> list[tuple[int, int]]:
    """Row ranges ``[s, e)`` of ``CHUNK_ROWS`` rows covering ``range(n)``, the last one taking the
    rest (``CHUNK_ROWS`` to ``2 * CHUNK_ROWS - 1`` rows): fewer than ``2 * CHUNK_ROWS`` rows are
    one chunk, evaluated exactly as one unchunked call."""
    ranges, s = [], 0
    while s < n:
        e = n if n - s < 2 * CHUNK_ROWS else s + CHUNK_ROWS
        ranges.append((s, e))
        s = e
    return ranges
