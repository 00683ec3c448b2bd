"""genplan: learned, constraint-aware robot motion generation with a Rust core.

Public modules:

* :mod:`genplan.robots` -- ``load("panda" | "talos" | "ur5")``: Pinocchio model, limits, frames,
  and the Rust kinematics / collision world built from the same files.
* :mod:`genplan.collision` -- :class:`~genplan.collision.CollisionWorld`, batched collision and
  distance queries (parry, GIL released).
* :func:`solve_ik` (:mod:`genplan.ik`) -- IK for a task's [condition] targets, retried from new
  warm starts (GAN, then uniform) until success or a time budget.
* :func:`execute` (:mod:`genplan.control`) -- a trajectory run on the simulated robot at 1 kHz
  (P-D + disturbance observer): tracking, torques, limits.
* :func:`adjust` (:mod:`genplan.seq2seq.adjust`) -- trajectories of a learned family adjusted to
  an objective in the seq2seq model's latent space; ``result.finish()`` makes them executable.
"""

from typing import TYPE_CHECKING

from genplan._core import CRATE_VERSIONS, __version__
from genplan.collision import CollisionWorld
from genplan.robots import Robot, load

__all__ = ["__version__", "CRATE_VERSIONS", "CollisionWorld", "IKResult", "Robot", "adjust", "execute", "load",
           "solve_ik"]

if TYPE_CHECKING:  # the lazy names' types, for type checkers (imported on first use at run time)
    from genplan.control import execute
    from genplan.ik import IKResult, solve_ik
    from genplan.seq2seq.adjust import adjust

#: Names imported on first use (``genplan.solve_ik``), so that ``import genplan`` stays light.
_LAZY = {"solve_ik": "genplan.ik", "IKResult": "genplan.ik", "execute": "genplan.control",
         "adjust": "genplan.seq2seq.adjust"}


def __getattr__(name: str) -> object:
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'genplan' has no attribute {name!r}")
