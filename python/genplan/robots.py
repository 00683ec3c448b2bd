"""Robots from example-robot-data, described once (the Rust core's presets) and loaded twice:
as a Pinocchio model (projection, IK, dynamics) and as the Rust kinematics and collision world.

>>> import genplan
>>> panda = genplan.robots.load("panda")
>>> panda.nq, panda.frames["hand"]
(7, 'panda_hand')
"""

from __future__ import annotations

import functools
import os
import site
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from genplan import _core
from genplan._arrays import as_configurations
from genplan.collision import CollisionWorld
from genplan.errors import RobotFileError, ShapeError, UnknownNameError

#: Names accepted by :func:`load`.
ROBOT_NAMES: tuple[str, ...] = tuple(_core.ROBOT_NAMES)


def robots_dir() -> Path:
    """example-robot-data's ``robots/`` folder: ``$GENPLAN_ROBOTS_DIR`` or the pip package's."""
    env = os.environ.get("GENPLAN_ROBOTS_DIR")
    if env:
        p = Path(env)
        if not p.is_dir():
            raise FileNotFoundError(f"GENPLAN_ROBOTS_DIR={env} is not a folder")
        return p
    candidates = [*sys.path, *site.getsitepackages(), site.getusersitepackages()]
    for base in candidates:
        p = Path(base) / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if p.is_dir():
            return p
    raise FileNotFoundError(
        "example-robot-data is not installed (its robots/ folder was not found under "
        "site-packages/cmeel.prefix/share): pip install example-robot-data, "
        "or set GENPLAN_ROBOTS_DIR"
    )


class Robot:
    """A robot: Pinocchio model (reduced to the active joints), limits, named frames, and the
    Rust kinematics/collision built from the same files with the same joint order.

    Configurations follow Pinocchio's convention (a free-flyer base is
    ``[x, y, z, qx, qy, qz, qw]`` followed by the joints).
    """

    def __init__(self, name: str, root: Path | None = None) -> None:
        spec = _core.robot_spec(name)  # raises UnknownNameError listing the known robots
        root = robots_dir() if root is None else Path(root)
        self.name: str = name
        self.urdf_path: Path = root / spec["urdf"]
        self.collision_urdf_path: Path = root / spec["collision_urdf"]
        self.srdf_path: Path = root / spec["srdf"]
        self.package_dirs: list[Path] = [Path(p) for p in _core.package_dirs(root)]
        self.floating_base: bool = spec["floating_base"]
        for p in (self.urdf_path, self.collision_urdf_path, self.srdf_path):
            if not p.is_file():
                raise FileNotFoundError(f"robot '{name}': {p} does not exist (example-robot-data too old?)")

        try:
            if self.floating_base:
                full = pin.buildModelFromUrdf(str(self.urdf_path), pin.JointModelFreeFlyer())
            else:
                full = pin.buildModelFromUrdf(str(self.urdf_path))
            pin.loadReferenceConfigurations(full, str(self.srdf_path), False)
        except (ValueError, RuntimeError) as exc:  # Pinocchio's for a URDF, for an SRDF it cannot parse
            bad = self.urdf_path if isinstance(exc, ValueError) else self.srdf_path
            raise RobotFileError(f"robot '{name}': cannot read {bad}: {exc}") from None
        state = spec["reference_state"]
        if state and state in full.referenceConfigurations:
            q_ref = np.array(full.referenceConfigurations[state])
        else:
            q_ref = pin.neutral(full)
        lock_ids = [full.getJointId(j) for j in spec["locked_joints"]]
        self.locked_joints: dict[str, float] = {
            j: float(q_ref[full.joints[full.getJointId(j)].idx_q]) for j in spec["locked_joints"]
        }
        self.model: pin.Model = pin.buildReducedModel(full, lock_ids, q_ref) if lock_ids else full
        self.data: pin.Data = self.model.createData()
        self.q_default: NDArray[np.float64] = self._reduce(full, q_ref)
        self.lower: NDArray[np.float64] = np.array(self.model.lowerPositionLimit)
        self.upper: NDArray[np.float64] = np.array(self.model.upperPositionLimit)
        if self.floating_base:  # Pinocchio leaves the free-flyer unbounded (+-max double)
            self.lower[:7] = -np.inf
            self.upper[:7] = np.inf
        self.frames: dict[str, str] = dict(spec["frames"])
        for role, frame in self.frames.items():
            if not self.model.existFrame(frame):
                raise RobotFileError(f"robot '{name}': frame '{frame}' ({role}) is not in the URDF")
        self.joint_names: list[str] = [
            n for n in list(self.model.names)[1:] if not (self.floating_base and n == "root_joint")
        ]
        self.kinematics: _core.KinematicModel = _core.KinematicModel.from_urdf(
            self.urdf_path,
            floating_base=self.floating_base,
            locked_joints=self.locked_joints,
            joint_order=self.joint_names,
        )

    def _reduce(self, full: pin.Model, q_full: NDArray[np.float64]) -> NDArray[np.float64]:
        q = pin.neutral(self.model)
        for jid in range(1, self.model.njoints):
            jr = self.model.joints[jid]
            jf = full.joints[full.getJointId(self.model.names[jid])]
            q[jr.idx_q : jr.idx_q + jr.nq] = q_full[jf.idx_q : jf.idx_q + jf.nq]
        return q

    @property
    def nq(self) -> int:
        return int(self.model.nq)

    @property
    def nv(self) -> int:
        return int(self.model.nv)

    @functools.cached_property
    def collision_model(self) -> pin.GeometryModel:
        """Pinocchio/coal collision model of the same geometry, with the same pair selection:
        all pairs on different joints, minus the SRDF's disabled pairs."""
        geom = pin.buildGeomFromUrdf(
            self.model,
            str(self.collision_urdf_path),
            pin.GeometryType.COLLISION,
            package_dirs=[str(p) for p in self.package_dirs],
        )
        geom.addAllCollisionPairs()
        pin.removeCollisionPairs(self.model, geom, str(self.srdf_path), False)
        return geom

    def frame_id(self, frame: str) -> int:
        """Pinocchio frame id of a role ("hand", "right_hand", ...) or of a frame name."""
        name = self.frames.get(frame, frame)
        if not self.model.existFrame(name):
            raise UnknownNameError(
                f"robot '{self.name}' has no frame '{frame}' "
                f"(roles: {', '.join(self.frames)}; or any URDF link name)"
            )
        return int(self.model.getFrameId(name))

    def check_configuration(self, q: Any, what: str = "q") -> NDArray[np.float64]:
        """q as a float64 array of shape (nq,) or (n, nq); ShapeError on a wrong shape,
        NonFiniteError on NaN or inf (:mod:`genplan.errors`)."""
        return as_configurations(q, self.nq, what)

    def link_poses(self, q: Any, links: list[str] | None = None) -> NDArray[np.float64]:
        """World poses (4x4) of links from the Rust kinematics: (L, 4, 4) or (n, L, 4, 4)."""
        return np.asarray(self.kinematics.forward_kinematics(self.check_configuration(q), links))

    def frame_placement(self, q: ArrayLike, frame: str) -> pin.SE3:
        """Pinocchio placement of a frame (role or name) at one configuration."""
        fid = self.frame_id(frame)
        qa = self.check_configuration(q)
        if qa.ndim != 1:
            raise ShapeError(f"q: expected one configuration of shape ({self.nq},), got {qa.shape}")
        pin.framesForwardKinematics(self.model, self.data, qa)
        return self.data.oMf[fid].copy()

    def random_configurations(self, n: int, rng: np.random.Generator | int | None = None) -> NDArray[np.float64]:
        """n configurations uniform within the joint limits (a free-flyer base stays at its
        default placement)."""
        rng = np.random.default_rng(rng)
        q = np.repeat(self.q_default[None, :], n, axis=0)
        lo, hi = self.lower.copy(), self.upper.copy()
        bounded = np.isfinite(lo) & np.isfinite(hi)
        q[:, bounded] = rng.uniform(lo[bounded], hi[bounded], size=(n, int(bounded.sum())))
        return q

    def collision_world(self, self_collision: bool = True) -> CollisionWorld:
        """A new collision world (no obstacles) for this robot."""
        native = _core.CollisionWorld(
            self.kinematics,
            self.collision_urdf_path,
            self.package_dirs,
            self.srdf_path,
        )
        native.check_self = self_collision
        return CollisionWorld(native)

    def __repr__(self) -> str:
        return f"Robot('{self.name}', nq={self.nq}, nv={self.nv}, frames={self.frames})"


@functools.lru_cache(maxsize=None)
def load(name: str) -> Robot:
    """Load a robot by name ("panda", "talos", "ur5"). Cached: the same object is returned for
    the same name; an unknown name raises UnknownNameError listing the known ones."""
    if name not in ROBOT_NAMES:
        raise UnknownNameError(f"unknown robot '{name}' (known: {', '.join(ROBOT_NAMES)})")
    return Robot(name)
