"""genplan: learned, constraint-aware robot motion generation with a Rust core.

Public modules:

* :mod:`genplan.robots` -- ``load("panda" | "talos" | "ur5")``: Pinocchio model, limits, frames,
  and the Rust kinematics / collision world built from the same files.
* :mod:`genplan.collision` -- :class:`~genplan.collision.CollisionWorld`, batched collision and
  distance queries (parry, GIL released).
"""

from genplan._core import CRATE_VERSIONS, __version__
from genplan.collision import CollisionWorld
from genplan.robots import Robot, load

__all__ = ["__version__", "CRATE_VERSIONS", "CollisionWorld", "Robot", "load"]
