"""Robots as data: a preset name, a robot file (TOML) or a URDF with keywords, described once
(read by the Rust core, ``genplan_core::robot``) and loaded twice: as a Pinocchio model
(projection, IK, dynamics) and as the Rust kinematics and collision world.

>>> import genplan
>>> panda = genplan.robots.load("panda")
>>> panda.nq, panda.frames["hand"]
(7, 'panda_hand')

A robot of one's own, from its URDF (see docs/ROBOTS.md for the robot file's keys)::

    arm = genplan.load(urdf="my_arm/urdf/arm.urdf", package_dirs=["my_arm/.."],
                       frames={"tool": "tool0"})
    arm = genplan.load("my_arm.toml")   # the same keys in a robot file

The presets are robot files in ``genplan/presets/robots/`` (:data:`ROBOT_NAMES`); their
``package://example-robot-data/...`` paths resolve in the example-robot-data package.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import functools
import hashlib
import json
import math
import os
import site
import sys
import tempfile
import warnings
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, DTypeLike, NDArray

from genplan import _core
from genplan._arrays import as_configurations, as_real
from genplan._files import write_text
from genplan.cache import cache_dir, load_text, save_text
from genplan.collision import CollisionWorld
from genplan.errors import (GenplanError, RobotFileError, RobotWarning, SceneFileError, SettingsError, ShapeError,
                            UnknownNameError)
from genplan.scene import Box, Capsule, Cylinder, Mesh, Pose, Sphere

#: The folder of the preset robot files.
PRESETS_DIR: Path = Path(__file__).parent / "presets" / "robots"

#: Names accepted by :func:`load` as presets (the robot files in :data:`PRESETS_DIR`).
ROBOT_NAMES: tuple[str, ...] = tuple(sorted(p.stem for p in PRESETS_DIR.glob("*.toml")))


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


def default_package_dirs() -> list[Path]:
    """Folders searched for ``package://`` URIs after a robot's own: example-robot-data's
    ``share/`` folder (so ``package://example-robot-data/robots/...`` resolves), if installed."""
    try:
        return [robots_dir().parent.parent]
    except FileNotFoundError:
        return []


class Robot:
    """A robot: Pinocchio model (reduced to the active joints), limits, named frames, and the
    Rust kinematics/collision built from the same files with the same joint order.

    Build one with :func:`load`. Configurations follow Pinocchio's convention: a free-flyer base
    is ``[x, y, z, qx, qy, qz, qw]`` followed by the joints, and a continuous (unbounded
    revolute) joint takes two values ``[cos, sin]`` of its angle, which must stay a unit
    complex number (:meth:`random_configurations` draws them so; :meth:`normalize` fixes a
    configuration).
    """

    def __init__(self, description: Mapping[str, Any]) -> None:
        d = dict(description)
        self.description: dict[str, Any] = d
        self.name: str = d["name"]
        self.source: Path | None = Path(d["source"]) if d.get("source") else None
        self.urdf_path: Path = Path(d["urdf"])
        self.collision_urdf_path: Path = Path(d["collision_urdf"])
        self.srdf_path: Path | None = Path(d["srdf"]) if d.get("srdf") else None
        self.package_dirs: list[Path] = [Path(p) for p in d["package_dirs"]]
        self.floating_base: bool = bool(d["floating_base"])
        self.merge_computed_pairs: bool = bool(d.get("merge_computed_pairs"))
        #: what the collision meshes become (a robot file's ``mesh_shape``: genplan.scene.MESH_SHAPES)
        self.mesh_shape: str = str(d.get("mesh_shape", "hull"))
        origin = f"robot file {self.source}" if self.source else f"robot '{self.name}'"

        # The core reads and checks the files first: its errors name the file and the name or
        # value at fault, with the parser's reason for a malformed URDF or SRDF.
        kinematics, q_default, locked, messages = _core.read_robot(d)
        for message in messages:
            warnings.warn(f"{origin}: {message}", RobotWarning, stacklevel=4)
        _check_mimic_limits(self.urdf_path, origin, kinematics.mimic_joints, locked)
        # mimic joints that move follow their masters in Pinocchio as in the core; the others
        # are locked (with their masters, or held where the core cannot follow them), so that
        # Pinocchio reads them as plain joints and the reduced model holds them
        full = _pinocchio_model(self.urdf_path, self.floating_base, origin, bool(kinematics.mimic_joints), set(locked))
        # the locked joints (the mimics of locked joints included, which Pinocchio derives from
        # their masters) at their values; a continuous joint's value is its angle
        q_ref = pin.neutral(full)
        for j, v in locked.items():
            jf = full.joints[full.getJointId(j)]
            if jf.nq == 1:
                q_ref[jf.idx_q] = v
            elif jf.nq == 2:
                q_ref[jf.idx_q : jf.idx_q + 2] = np.cos(v), np.sin(v)
        lock_ids = [full.getJointId(j) for j in locked]
        #: The locked joints and their values (the mimics of locked joints included).
        self.locked_joints: dict[str, float] = dict(locked)
        self.model: pin.Model = pin.buildReducedModel(full, lock_ids, q_ref) if lock_ids else full
        self.data: pin.Data = self.model.createData()
        self.lower: NDArray[np.float64] = np.array(self.model.lowerPositionLimit)
        self.upper: NDArray[np.float64] = np.array(self.model.upperPositionLimit)
        #: q indices of the cos value of each continuous joint (its sin follows).
        self.continuous: list[int] = []
        for jid in range(1, self.model.njoints):
            j = self.model.joints[jid]
            if j.nq == 2 and j.nv == 1:
                self.continuous.append(int(j.idx_q))
                self.lower[j.idx_q : j.idx_q + 2] = -np.inf  # any angle: the limits do not apply
                self.upper[j.idx_q : j.idx_q + 2] = np.inf
        if self.floating_base:  # Pinocchio leaves the free-flyer unbounded (+-max double)
            self.lower[:7] = -np.inf
            self.upper[:7] = np.inf
        self.frames: dict[str, str] = dict(d.get("frames") or [])  # links (checked by the core)
        #: The active joints in q order (a mimic joint has no coordinate: it follows its master).
        self.joint_names: list[str] = [
            str(self.model.names[jid]) for jid in range(1, self.model.njoints)
            if self.model.joints[jid].nq > 0 and not (self.floating_base and self.model.names[jid] == "root_joint")
        ]
        if list(kinematics.active_joints) != self.joint_names:  # the core orders q as Pinocchio does
            kinematics = _core.KinematicModel.from_urdf(
                self.urdf_path, floating_base=self.floating_base, locked_joints=self.locked_joints,
                joint_order=self.joint_names)
        self.kinematics: _core.KinematicModel = kinematics
        #: The default configuration: the reference state's values, else the neutral one.
        self.q_default: NDArray[np.float64] = np.asarray(q_default, dtype=np.float64)
        # the hot call without a Python frame in between: on an instance, link_poses is the
        # native method itself (the same parameters; documented by the method below, which
        # calls it). A frame costs about a third of a one-configuration call (benches/boundary.py)
        self.__dict__["link_poses"] = self.kinematics.forward_kinematics
        #: Self-collision pairs in contact at the default configuration that the SRDF does not
        #: disable: (link_a, link_b, share of random configurations in which they are in contact
        #: too), reported at load with a RobotWarning (:func:`default_contacts`).
        self.default_contacts: tuple[tuple[str, str, float], ...] = ()
        if self.srdf_path is not None and not self.merge_computed_pairs:
            self.default_contacts = default_contacts(self)
            if self.default_contacts:
                warnings.warn(_contacts_message(self, origin), RobotWarning, stacklevel=4)
        #: The objects the robot's links hold, by name (:meth:`with_attached`; a robot file's
        #: ``[[attached]]`` tables).
        self.attached: dict[str, Attached] = {}
        for i, row in enumerate(d.get("attached") or ()):
            where = f"{origin}: [[attached]] {i + 1} ('{row.get('name')}')"
            try:
                a = Attached.from_dict(row)
                self.attached[a.name] = _checked_attached(self, a)
            except GenplanError as exc:
                raise RobotFileError(f"{where}: {exc}") from None

    @property
    def nq(self) -> int:
        return int(self.model.nq)

    @property
    def nv(self) -> int:
        return int(self.model.nv)

    @functools.cached_property
    def kinematic_hash(self) -> str:
        """The sha256 (hex) of what a learned model of this robot depends on, which model cards
        record and loaders compare: the active joints in configuration order (name; type as its
        nq, nv and motion subspace at the neutral configuration, which holds the axis; position
        limits; a mimic joint's multiplier and offset) and the chain between them (each joint's
        parent joint and placement in it).
        Not the robot's name, file paths, collision geometry, frames, or the values of locked
        joints outside that chain (a Panda's fingers, open or closed); a locked joint between
        two active ones shows in the placement of the next one. Every number is rounded to 1e-6
        (a micrometre, a microradian, rotation entries), far below what a learned sampler
        resolves, so that float noise in building the model (or a URDF written with more
        digits) does not change the hash."""

        def rounded(values: Any) -> list[float]:
            # +0.0 turns -0.0 into 0.0; infinite limits stay infinite (JSON "Infinity")
            return [round(float(v), 6) + 0.0 for v in np.ravel(values)]

        m = self.model
        q0 = pin.neutral(m)
        rows = []
        for jid in range(1, m.njoints):
            joint, placement = m.joints[jid], m.jointPlacements[jid]
            data = joint.createData()
            joint.calc(data, q0)
            q = slice(joint.idx_q, joint.idx_q + joint.nq)
            row = [m.names[jid], joint.nq, joint.nv, rounded(np.asarray(data.S)), m.names[int(m.parents[jid])],
                   rounded(placement.translation), rounded(placement.rotation),
                   rounded(self.lower[q]), rounded(self.upper[q])]
            if joint.shortname() == "JointModelMimic":
                # a mimic follows multiplier * master + offset: the motion subspace holds the
                # multiplier, not the offset, which moves every link after it all the same
                mimic = joint.extract()
                row.append(["mimic", rounded([mimic.scaling, mimic.offset])])
            rows.append(row)
        return hashlib.sha256(json.dumps(rows, separators=(",", ":")).encode()).hexdigest()

    @functools.cached_property
    def collision_model(self) -> pin.GeometryModel:
        """Pinocchio/coal collision model of the same geometry, with the same pair selection:
        all pairs on different joints, minus the SRDF's disabled pairs (or, without an SRDF,
        minus :attr:`disabled_pairs`; with ``merge_computed_pairs``, minus both)."""
        geom = pin.buildGeomFromUrdf(
            self.model,
            str(self.collision_urdf_path),
            pin.GeometryType.COLLISION,
            package_dirs=[str(p) for p in self.package_dirs],
        )
        geom.addAllCollisionPairs()
        if self.srdf_path is not None:
            pin.removeCollisionPairs(self.model, geom, str(self.srdf_path), False)
        if self.srdf_path is None or self.merge_computed_pairs:
            skip = {frozenset(p) for p in self.disabled_pairs}
            link = [self.model.frames[g.parentFrame].name for g in geom.geometryObjects]
            pairs = [(int(cp.first), int(cp.second)) for cp in geom.collisionPairs]  # copies: removal shifts
            for a, b in pairs:
                if frozenset((link[a], link[b])) in skip:
                    geom.removeCollisionPair(pin.CollisionPair(a, b))
        return geom

    @functools.cached_property
    def disabled_pairs(self) -> list[tuple[str, str]]:
        """Link pairs skipped in self-collision checks: the SRDF's, or without an SRDF the ones
        computed as MoveIt's setup assistant does (:func:`compute_disabled_pairs`,
        cached on disk); with ``merge_computed_pairs``, both."""
        given = [(a, b) for a, b in _core.srdf_disabled_pairs(self.srdf_path)] if self.srdf_path is not None else []
        if self.srdf_path is not None and not self.merge_computed_pairs:
            return given
        seen = {frozenset(p) for p in given}
        return given + [p for p in compute_disabled_pairs(self).pairs if frozenset(p) not in seen]

    def frame_id(self, frame: str) -> int:
        """Pinocchio frame id of a role ("hand", "right_hand", ...) or of a frame name."""
        name = self.frames.get(frame, frame)
        if not self.model.existFrame(name):
            raise UnknownNameError(
                f"robot '{self.name}' has no frame '{frame}' "
                f"(roles: {', '.join(self.frames) or 'none'}; or any URDF link name)"
            )
        return int(self.model.getFrameId(name))

    def check_configuration(self, q: Any, what: str = "q") -> NDArray[np.float64]:
        """q as a float64 array of shape (nq,) or (n, nq); ShapeError on a wrong shape,
        NonFiniteError on NaN or inf (:mod:`genplan.errors`)."""
        return as_configurations(q, self.nq, what)

    def joint_values(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Configurations (n, nq) of a fixed-base robot as joint values (n, nv): a continuous
        joint's [cos, sin] as its angle, unwrapped along the rows (a path's angle does not jump
        by 2 pi); the same array when nq == nv."""
        if self.nq == self.nv:
            return q
        cols, skip = [], set()
        for i in range(self.nq):
            if i in skip:
                continue
            if i in self.continuous:
                cols.append(np.unwrap(np.arctan2(q[:, i + 1], q[:, i])))
                skip.add(i + 1)
            else:
                cols.append(q[:, i])
        return np.column_stack(cols)

    def from_joint_values(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The inverse of :meth:`joint_values`: joint values (n, nv) as configurations (n, nq)."""
        if self.nq == self.nv:
            return x
        out, k, i = np.empty((len(x), self.nq)), 0, 0
        while i < self.nq:
            if i in self.continuous:
                out[:, i], out[:, i + 1] = np.cos(x[:, k]), np.sin(x[:, k])
                i += 2
            else:
                out[:, i] = x[:, k]
                i += 1
            k += 1
        return out

    def normalize(self, q: Any) -> NDArray[np.float64]:
        """q (one or a batch) with every free-flyer quaternion and every continuous joint's
        (cos, sin) scaled to unit norm, as Pinocchio expects."""
        qa = self.check_configuration(q).copy()
        rows = qa.reshape(-1, self.nq)
        groups = [(i, 2) for i in self.continuous] + ([(3, 4)] if self.floating_base else [])
        for i, k in groups:
            norm = np.linalg.norm(rows[:, i : i + k], axis=1, keepdims=True)
            if np.any(norm == 0):
                raise ShapeError(f"q: the values {i}..{i + k - 1} are all zero: no rotation to normalise")
            rows[:, i : i + k] /= norm
        return qa

    def link_poses(
        self,
        q: Any,
        links: Sequence[str] | None = None,
        *,
        dtype: DTypeLike | None = None,
        out: NDArray[Any] | None = None,
    ) -> NDArray[Any]:
        """World poses (4x4) of links from the Rust kinematics: q of shape (nq,) or (n, nq) gives
        (L, 4, 4) or (n, L, 4, 4), L = ``len(links)`` (link names; UnknownNameError listing the
        known ones for another name) or every link (:attr:`kinematics` ``.link_names``).

        ``q`` is read and checked in Rust, as :meth:`check_configuration` does (ShapeError,
        NonFiniteError; a float64 array is not copied). ``dtype``: float64 (default) or float32.
        ``out``: an array of exactly that shape, C-contiguous, float64 or float32, written in
        place and returned (ShapeError naming ``out`` otherwise). A batch is written from all
        cores with the GIL released.
        """
        return self.kinematics.forward_kinematics(q, links, dtype, out)

    def frame_positions(self, q: Any, frame: str) -> NDArray[np.float64]:
        """World positions of ``frame`` (a role such as "hand", or a link name) from the Rust
        kinematics: q of shape (nq,) gives (3,), (n, nq) gives (n, 3)."""
        return self.link_poses(q, [self.frames.get(frame, frame)])[..., 0, :3, 3]

    def frame_placement(self, q: ArrayLike, frame: str) -> pin.SE3:
        """Pinocchio placement of a frame (role or name) at one configuration."""
        fid = self.frame_id(frame)
        qa = self.check_configuration(q)
        if qa.ndim != 1:
            raise ShapeError(f"q: expected one configuration of shape ({self.nq},), got {qa.shape}")
        pin.framesForwardKinematics(self.model, self.data, qa)
        return self.data.oMf[fid].copy()

    def random_configurations(self, n: int, rng: np.random.Generator | int | None = None) -> NDArray[np.float64]:
        """n configurations uniform within the joint limits; a continuous joint's angle uniform
        in [-pi, pi) (stored as cos, sin); a free-flyer base stays at its default placement."""
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
            raise TypeError(f"n: expected an integer count, got {type(n).__name__}")
        if n < 0:
            raise ShapeError(f"n: expected a count >= 0, got {n}")
        try:
            rng = np.random.default_rng(rng)
        except (ValueError, TypeError) as exc:
            raise SettingsError(f"rng: expected a numpy Generator, a seed >= 0 or None, got {rng!r} ({exc})") from None
        q = np.repeat(self.q_default[None, :], int(n), axis=0)
        lo, hi = self.lower.copy(), self.upper.copy()
        bounded = np.isfinite(lo) & np.isfinite(hi)
        q[:, bounded] = rng.uniform(lo[bounded], hi[bounded], size=(int(n), int(bounded.sum())))
        if self.continuous:
            angle = rng.uniform(-np.pi, np.pi, size=(int(n), len(self.continuous)))
            idx = np.asarray(self.continuous)
            q[:, idx] = np.cos(angle)
            q[:, idx + 1] = np.sin(angle)
        return q

    def collision_world(self, self_collision: bool = True) -> CollisionWorld:
        """A new collision world (no obstacles) for this robot, with its attached objects."""
        native = _core.CollisionWorld(  # the SRDF's pairs, or the computed ones without an SRDF (or merged)
            self.kinematics, self.collision_urdf_path, self.package_dirs, self.srdf_path,
            self.disabled_pairs if self.srdf_path is None or self.merge_computed_pairs else None,
            mesh_shape=self.mesh_shape,
        )
        native.check_self = self_collision
        world = CollisionWorld(native)
        for a in self.attached.values():
            # added as an obstacle at its pose in the link's frame, then moved onto the link
            _add_obstacle(world, dataclasses.replace(a.shape, name=a.name, pose=_compose(a.pose, a.shape.pose)))
            native.attach(a.name, a.link, list(a.touch_links), self.q_default.tolist())
        return world

    def with_attached(
        self,
        name: str,
        shape: Box | Sphere | Cylinder | Capsule | Mesh,
        link: str,
        pose: Pose | ArrayLike | None = None,
        mass: float | None = None,
        com: ArrayLike | None = None,
        inertia: ArrayLike | None = None,
        touch_links: Iterable[str] = (),
    ) -> Robot:
        """A new robot: this one with ``shape`` (a scene shape of :mod:`genplan.scene`: Box,
        Sphere, Cylinder, Capsule, Mesh; its own pose, usually the identity, within the object's
        frame) held by ``link`` (a link name or a frame role) at ``pose`` (the object's frame in the
        link's: a :class:`~genplan.scene.Pose`, a 4x4 matrix, or None for the link's frame).
        This robot is left as it is (robots are cached and shared).

        The object moves with the link and is checked wherever the robot's geometry is (its
        collision worlds: in_collision, min_distance, plans, certified motions, trajectories)
        against the obstacles (with their padding) and the robot's links but its touch links:
        the holding link's rigid body, ``touch_links`` and the links it touches at the default
        configuration (:attr:`CollisionWorld.attached` lists them). ``checker="spheres"``
        covers it with spheres of its own (:func:`genplan.spheres.attached_spheres`).

        ``mass`` (kg), ``com`` (m, in the object's frame; default its shape's centre) and
        ``inertia`` (3x3 about the centre of mass in the object's axes, kg m^2; default the solid
        of uniform density for a box, sphere, cylinder or capsule) make
        :attr:`Attached.payload`, what :func:`genplan.execute` takes as ``payload=``. Errors
        before any work: UnknownNameError (link, touch links: the known ones listed),
        GenplanError naming the field (name taken, NaN pose, a shape that is not one of those).
        """
        a = Attached(name=name, shape=shape, link=link, pose=_as_pose(pose), mass=mass,
                     com=None if com is None else _triple(com, f"attached '{name}' com"),
                     inertia=None if inertia is None else _matrix(inertia, f"attached '{name}' inertia"),
                     touch_links=tuple(touch_links))
        a = _checked_attached(self, a)
        if a.name in self.attached:
            raise SettingsError(f"attached '{a.name}': name: the robot holds an object of that name already")
        new = copy.copy(self)
        new.attached = {**self.attached, a.name: a}
        new.description = {**self.description, "attached": [*(self.description.get("attached") or []), a.to_dict()]}
        new.collision_world()  # the native checks (a name taken by a geometry, a malformed mesh) before returning
        return new

    def write_srdf(self, path: str | os.PathLike[str]) -> Path:
        """Write the robot's disabled self-collision pairs (and its default configuration as the
        group state "default") as an SRDF, atomically; returns the path."""
        return write_srdf(self, path)

    def __repr__(self) -> str:
        return f"Robot('{self.name}', nq={self.nq}, nv={self.nv}, frames={self.frames})"


# --- attached objects --------------------------------------------------------------------------

#: The shapes an attached object may take (the scene file's, less the half-space and the cloud).
ATTACHED_SHAPES: dict[str, type[Any]] = {c.kind: c for c in (Box, Sphere, Cylinder, Capsule, Mesh)}


@dataclass(frozen=True)
class Attached:
    """An object a link holds (:meth:`Robot.with_attached`; a robot file's ``[[attached]]``):
    ``shape`` (a scene shape, its own pose within the object's frame) at ``pose`` in ``link``'s
    frame, with optional ``mass``, ``com`` (object frame) and ``inertia`` (about the centre of
    mass, object axes), and the links it may touch beyond its own."""

    name: str
    shape: Box | Sphere | Cylinder | Capsule | Mesh
    link: str
    pose: Pose = dataclasses.field(default_factory=Pose)
    mass: float | None = None
    com: tuple[float, float, float] | None = None
    inertia: tuple[tuple[float, float, float], ...] | None = None
    touch_links: tuple[str, ...] = ()

    @property
    def payload(self) -> Any:
        """The object as a :class:`genplan.control.Payload` on its link (mass, centre of mass
        and inertia in the link's frame): ``genplan.execute(..., payload=robot.attached["tray"].payload)``.
        SettingsError when it has no mass."""
        if self.mass is None:
            raise SettingsError(f"attached '{self.name}': mass: not given, so it is no payload (give mass=)")
        r, p = self.pose.matrix(), np.asarray(self.pose.position)
        com = np.asarray(self.com) if self.com is not None else np.asarray(self.shape.pose.position)
        inertia = np.asarray(self.inertia) if self.inertia is not None else _solid_inertia(self.shape, self.mass)
        return _core.Payload(link=self.link, mass=float(self.mass), com=(r @ com + p).tolist(),
                             inertia=(r @ inertia @ r.T).tolist())

    def to_dict(self) -> dict[str, Any]:
        """The robot file's ``[[attached]]`` table (:meth:`from_dict` reads it back)."""
        from genplan.scene import _obstacle_dict

        shape = {k: v for k, v in _obstacle_dict(self.shape).items() if k != "name"}
        d: dict[str, Any] = {"name": self.name, "link": self.link, self.shape.kind: shape, **self.pose.to_dict()}
        if self.mass is not None:
            d["mass"] = self.mass
        if self.com is not None:
            d["com"] = list(self.com)
        if self.inertia is not None:
            d["inertia"] = [list(r) for r in self.inertia]
        if self.touch_links:
            d["touch_links"] = list(self.touch_links)
        return d

    @classmethod
    def from_dict(cls, row: Mapping[str, Any]) -> Attached:
        """An ``[[attached]]`` table: ``name``, ``link``, one shape table (``box``, ``sphere``,
        ``cylinder``, ``capsule``, ``mesh``: a scene file's keys but ``name``), the pose keys
        (``position``, ``rpy`` | ``quaternion`` | ``rotation``), optional ``mass``, ``com``,
        ``inertia``, ``touch_links``. Errors name the key."""
        from genplan.scene import _POSE_KEYS, _obstacle_from_dict

        known = ("name", "link", "mass", "com", "inertia", "touch_links", *_POSE_KEYS, *ATTACHED_SHAPES)
        for key in row:
            if key not in known:
                raise SettingsError(f"unknown key '{key}' (known: {', '.join(known)})")
        kinds = [k for k in ATTACHED_SHAPES if k in row]
        if len(kinds) != 1:
            raise SettingsError(f"give exactly one shape table of {', '.join(ATTACHED_SHAPES)}, got {kinds or 'none'}")
        kind, name = kinds[0], str(row.get("name"))
        table = row[kind]
        if not isinstance(table, Mapping):
            raise SettingsError(f"{kind}: expected a table of the shape's keys")
        shape = _obstacle_from_dict(ATTACHED_SHAPES[kind], {"name": name, **table}, kind, None)
        touch = row.get("touch_links", ())
        if isinstance(touch, str) or not isinstance(touch, Sequence):
            raise SettingsError(f"touch_links: expected a list of link names, got {touch!r}")
        return cls(name=name, shape=shape, link=row.get("link"), pose=Pose(**{k: row[k] for k in _POSE_KEYS if k in row}),
                   mass=row.get("mass"), com=None if row.get("com") is None else _triple(row["com"], "com"),
                   inertia=None if row.get("inertia") is None else _matrix(row["inertia"], "inertia"),
                   touch_links=tuple(touch))


def _checked_attached(robot: Robot, a: Attached) -> Attached:
    """``a`` checked against ``robot`` (its link a link name or a role, resolved to the link),
    else a typed error naming the field."""
    what = f"attached '{a.name}'"
    if not isinstance(a.name, str) or not a.name:
        raise SettingsError(f"attached object: name: expected a non-empty string, got {a.name!r}")
    if not isinstance(a.shape, tuple(ATTACHED_SHAPES.values())):
        raise SettingsError(f"{what}: shape: expected one of genplan.scene's {', '.join(c.__name__ for c in ATTACHED_SHAPES.values())}, "
                            f"got {type(a.shape).__name__}")
    if a.shape.padding is not None:
        raise SettingsError(f"{what}: shape: an attached object takes no padding (the obstacles' padding applies to it)")
    links = list(robot.kinematics.link_names)
    link = robot.frames.get(a.link, a.link) if isinstance(a.link, str) else a.link
    if link not in links:
        raise UnknownNameError(f"{what}: link: unknown link {a.link!r} (known: {', '.join(links)})")
    for t in a.touch_links:
        if t not in links:
            raise UnknownNameError(f"{what}: touch_links: unknown link {t!r} (known: {', '.join(links)})")
    if a.mass is not None:
        m = as_real(a.mass, f"{what}: mass", error=SettingsError)
        if not (math.isfinite(m) and m >= 0):
            raise SettingsError(f"{what}: mass: must be a finite mass >= 0 (kg), got {a.mass!r}")
    a = dataclasses.replace(a, link=link, shape=dataclasses.replace(a.shape, name=a.name))  # the shape takes the object's name
    if a.mass is not None:
        if isinstance(a.shape, Mesh) and a.inertia is None:
            raise SettingsError(f"{what}: inertia: a mesh's inertia is not computed: give inertia= with mass=")
        a.payload.to_dict()  # the payload's own checks (mass, centre of mass, inertia)
    return a


def _add_obstacle(world: CollisionWorld, shape: Any) -> None:
    from genplan.collision import _add

    _add(world, shape)


def _as_pose(pose: Any) -> Pose:
    """``pose`` as a :class:`~genplan.scene.Pose`: a Pose, a 4x4 homogeneous matrix, or None
    (the identity); SettingsError naming ``pose`` otherwise (NaN, not a rotation)."""
    if pose is None:
        return Pose()
    if isinstance(pose, Pose):
        return pose
    m = np.asarray(pose, dtype=np.float64)
    if m.shape != (4, 4):
        raise ShapeError(f"pose: expected a Pose or a 4x4 matrix, got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise SettingsError("pose: must be finite, got NaN or inf")
    try:
        return Pose(position=tuple(m[:3, 3]), rotation=tuple(tuple(r) for r in m[:3, :3]))
    except SceneFileError as exc:
        raise SettingsError(f"pose: {exc}") from None


def _compose(a: Pose, b: Pose) -> Pose:
    """The pose ``b`` given in frame ``a``, in ``a``'s parent frame."""
    if not b.rotated and b.position == (0.0, 0.0, 0.0):
        return a
    ra, rb = a.matrix(), b.matrix()
    p = ra @ np.asarray(b.position) + np.asarray(a.position)
    return Pose(position=tuple(p.tolist()), rotation=tuple(tuple(r) for r in (ra @ rb).tolist()))


def _triple(v: Any, what: str) -> tuple[float, float, float]:
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (3,):
        raise ShapeError(f"{what}: expected 3 numbers, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise SettingsError(f"{what}: must be finite, got {a.tolist()}")
    return (float(a[0]), float(a[1]), float(a[2]))


def _matrix(v: Any, what: str) -> tuple[tuple[float, float, float], ...]:
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (3, 3):
        raise ShapeError(f"{what}: expected a 3x3 matrix, got shape {a.shape}")
    return tuple(_triple(r, what) for r in a)


def _solid_inertia(shape: Any, mass: float) -> NDArray[np.float64]:
    """The inertia (about its centre, in the object's axes) of a solid shape of uniform density:
    box, sphere, cylinder, capsule (cylinder and two half-balls); the shape's own rotation
    applied."""
    m = mass
    if isinstance(shape, Box):
        x, y, z = (2 * h for h in shape.half_extents)
        i = np.diag([m * (y * y + z * z), m * (x * x + z * z), m * (x * x + y * y)]) / 12
    elif isinstance(shape, Sphere):
        i = np.eye(3) * 0.4 * m * shape.radius ** 2
    elif isinstance(shape, Cylinder):
        r, h = shape.radius, shape.length
        a = m * (3 * r * r + h * h) / 12
        i = np.diag([a, a, m * r * r / 2])
    else:  # Capsule: masses split by volume
        r, h = shape.radius, shape.length
        vc, vs = math.pi * r * r * h, 4 / 3 * math.pi * r ** 3
        mc, ms = m * vc / (vc + vs), m * vs / (vc + vs)
        a = mc * (3 * r * r + h * h) / 12 + ms * (0.4 * r * r + h * h / 4 + 3 * h * r / 8)
        i = np.diag([a, a, mc * r * r / 2 + 0.4 * ms * r * r])
    rot = shape.pose.matrix()
    return rot @ i @ rot.T


# --- self-collision pairs to skip without an SRDF ---------------------------------------------

#: Why a pair is skipped, in MoveIt's words.
REASONS: tuple[str, ...] = ("Adjacent", "Default", "Always", "Never")


@dataclass(frozen=True)
class DisabledPairs:
    """Link pairs skipped in self-collision checks, each with its reason."""

    entries: tuple[tuple[str, str, str], ...]
    samples: int
    seed: int

    @property
    def pairs(self) -> list[tuple[str, str]]:
        return [(a, b) for a, b, _ in self.entries]

    def counts(self) -> dict[str, int]:
        """How many pairs per reason."""
        return {r: sum(1 for *_, why in self.entries if why == r) for r in REASONS}

    def report(self) -> str:
        c = self.counts()
        return (f"{len(self.entries)} link pairs skipped ({', '.join(f'{k.lower()} {v}' for k, v in c.items())}; "
                f"{self.samples} random configurations, seed {self.seed})")


def _files_digest(robot: Robot, *more: Path | None) -> str:
    h = hashlib.sha256()
    for p in (robot.urdf_path, robot.collision_urdf_path, *(m for m in more if m is not None)):
        h.update(Path(p).read_bytes())
    h.update(json.dumps({"locked": robot.locked_joints, "floating": robot.floating_base,
                         "q": robot.q_default.tolist(), "version": _core.__version__}, sort_keys=True).encode())
    return h.hexdigest()[:16]


def compute_disabled_pairs(robot: Robot, samples: int = 10_000, seed: int = 0, cache: bool = True) -> DisabledPairs:
    """The pairs to skip for ``robot`` (ignoring any SRDF it has), from ``samples`` random
    configurations drawn with ``seed``. Cached in ``$GENPLAN_CACHE/self_collision`` unless
    ``cache=False``; the cache is keyed by the URDF files' contents and the settings."""
    if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples <= 10_000_000:
        raise SettingsError(f"samples: expected an integer in 1..10000000, got {samples!r}")
    path = cache_dir() / "self_collision" / f"{robot.name}_{_files_digest(robot)}_{samples}_{seed}.json"
    if cache:
        cached = _cached_pairs(robot, path, "pairs", REASONS)
        if cached is not None:
            return DisabledPairs(tuple((a, b, str(r)) for a, b, r in cached), samples, seed)
    native = _core.CollisionWorld(robot.kinematics, robot.collision_urdf_path, robot.package_dirs, None)
    entries = tuple(native.compute_disabled_pairs(robot.q_default, samples=samples, seed=seed))
    if cache:
        save_text(path, json.dumps({"robot": robot.name, "samples": samples, "seed": seed,
                                    "pairs": [list(e) for e in entries]}, indent=1))
    return DisabledPairs(entries, samples, seed)


def _cached_pairs(robot: Robot, path: Path, key: str, values: tuple[str, ...] | None) -> list[tuple[str, str, Any]] | None:
    """The link pairs ``(a, b, value)`` of the self-collision cache file ``path`` (its field
    ``key``), or None when it is to be recomputed: missing, not matching its sha256 (a
    RuntimeWarning naming it, :func:`genplan.cache.load_text`), not JSON, or naming a link the
    robot lacks, a value not in ``values`` (the reasons) or, without ``values``, not a count."""
    text = load_text(path)
    if text is None:
        return None
    try:
        rows = json.loads(text)[key]
        links = set(robot.kinematics.link_names)
        pairs = [(a, b, v) for a, b, v in rows]
    except (ValueError, KeyError, TypeError):
        return None  # a broken cache file is recomputed
    for a, b, v in pairs:
        if not (isinstance(a, str) and isinstance(b, str) and a in links and b in links):
            return None
        if values is not None and v not in values:
            return None
        if values is None and (isinstance(v, bool) or not isinstance(v, int) or v < 0):
            return None
    return pairs


#: Random configurations over which the pairs in contact at the default configuration are
#: checked at load (:func:`default_contacts`).
CONTACT_SAMPLES: int = 1000


def default_contacts(robot: Robot, samples: int = CONTACT_SAMPLES, seed: int = 0) -> tuple[tuple[str, str, float], ...]:
    """The self pairs the robot checks (all but its SRDF's disabled pairs) that are in contact at
    its default configuration: (link_a, link_b, share of ``samples`` random configurations in
    which they are in contact too; 1.0: every configuration is invalid). One check when the
    default configuration is free of self-collision; the pairs in contact are sampled. Cached in
    ``$GENPLAN_CACHE/self_collision`` as :func:`compute_disabled_pairs` is, keyed by the URDF and
    SRDF files' contents."""
    digest = _files_digest(robot, robot.srdf_path)
    path = cache_dir() / "self_collision" / f"{robot.name}_{digest}_contacts_{samples}_{seed}.json"
    cached = _cached_pairs(robot, path, "contacts", None)
    if cached is not None and samples > 0 and all(h <= samples for *_, h in cached):
        return tuple((a, b, h / samples) for a, b, h in cached)
    native = _core.CollisionWorld(robot.kinematics, robot.collision_urdf_path, robot.package_dirs, robot.srdf_path)
    found = native.default_contacts(robot.q_default, samples=samples, seed=seed)
    try:
        save_text(path, json.dumps({"robot": robot.name, "samples": samples, "seed": seed,
                                    "contacts": [list(c) for c in found]}, indent=1))
    except OSError:
        pass  # an unwritable cache only costs the check again
    return tuple((a, b, h / samples if samples else 1.0) for a, b, h in found)


def _contacts_message(robot: Robot, origin: str) -> str:
    pairs = ", ".join(f"{a}-{b} (in contact in {round(100 * share, 1):g} % of {CONTACT_SAMPLES} random configurations)"
                      for a, b, share in robot.default_contacts)
    return (f"{origin}: self-collision at the default configuration: {pairs}; {robot.srdf_path} does not "
            "disable these pairs, so the configurations near the default one (for a pair in contact in 100 %, "
            "every configuration) are invalid. Remedy: merge_computed_pairs=True (in a robot file: "
            "merge_computed_pairs = true) also skips the pairs genplan computes as MoveIt's setup assistant does "
            "(robot.write_srdf writes them), or add <disable_collisions> for these pairs to the SRDF")


def _urdf_limits(root: Any) -> dict[str, tuple[float, float, str, float, float]]:
    """Each joint of the URDF ``root``: (lower, upper, master, multiplier, offset), the master ""
    for a joint without a ``<mimic>``; the limits infinite unless it is revolute or prismatic
    (URDF's defaults: limits 0, multiplier 1, offset 0)."""
    out: dict[str, tuple[float, float, str, float, float]] = {}
    for joint in root.findall("joint"):
        limit, mimic = joint.find("limit"), joint.find("mimic")
        bounded = joint.get("type") in ("revolute", "prismatic")
        lo = float(limit.get("lower", 0.0)) if bounded and limit is not None else -np.inf
        hi = float(limit.get("upper", 0.0)) if bounded and limit is not None else np.inf
        if mimic is None:
            out[str(joint.get("name"))] = (lo, hi, "", 1.0, 0.0)
        else:
            out[str(joint.get("name"))] = (lo, hi, str(mimic.get("joint")), float(mimic.get("multiplier", 1.0)),
                                           float(mimic.get("offset", 0.0)))
    return out


def _check_mimic_limits(urdf: Path, origin: str, mimics: Sequence[tuple[str, str, float, float]],
                        locked: Mapping[str, float]) -> None:
    """RobotFileError unless every mimic joint of ``urdf`` stays within its own limits: a mimic of
    a locked master at its value (``locked``, which holds the mimics of locked joints at the values
    they follow), a mimic of a moving master (``mimics``: joint, master, multiplier, offset) over
    its master's whole range. Its value is not a coordinate (it follows its master), so nothing
    else keeps it inside them: a sampler drawing its master within limits would put it outside.
    Limits are inclusive, with a rounding allowance of 1e-9 (relative)."""
    if not (mimics or locked):
        return
    text = urdf.read_bytes()
    if b"<mimic" not in text:
        return
    import xml.etree.ElementTree as ET

    joints = _urdf_limits(ET.fromstring(text))

    def fmt(x: float) -> str:
        return f"{x + 0.0:.6g}"  # + 0.0: no "-0"

    def outside(x: float, lo: float, hi: float) -> bool:
        slack = 1e-9 * max(1.0, abs(x))
        return x < lo - slack or x > hi + slack

    def remedy(name: str, master: str, lo: float, hi: float, mult: float, off: float, locked: bool) -> str:
        """What puts the mimic back inside [lo, hi]: its master's values, within the master's
        own limits, that keep it there (to lock the master within, or to narrow its limits to)."""
        mlo, mhi = joints[master][:2]
        ends = sorted(((lo - off) / mult, (hi - off) / mult)) if mult != 0 else [np.inf, -np.inf]
        a, b = max(ends[0], mlo), min(ends[1], mhi)
        if a > b:
            return (f"no value of '{master}' within its limits puts '{name}' inside them: correct the <mimic> or "
                    "the limits in the URDF")
        if a == b or locked:
            within = f"at {fmt(a)}" if a == b else f"within [{fmt(a)}, {fmt(b)}]"
            only = " (the only value that puts it inside them), or correct the <mimic> or the limits in the URDF"
            return f"lock '{master}' {within}" + (only if a == b else "")
        return f"narrow the limits of '{master}' to [{fmt(a)}, {fmt(b)}] in the URDF"

    for name, value in locked.items():
        info = joints.get(name)
        if info is None or not info[2] or info[2] not in locked:
            continue
        lo, hi, master, mult, off = info
        if outside(value, lo, hi):
            raise RobotFileError(
                f"{origin}: locked joint '{name}' at {fmt(value)} (it mimics '{master}', locked at "
                f"{fmt(locked[master])}: {fmt(mult)} * {fmt(locked[master])} + {fmt(off)}) is outside its limits "
                f"[{fmt(lo)}, {fmt(hi)}] ({urdf}); {remedy(name, master, lo, hi, mult, off, True)}")
    for name, master, mult, off in mimics:
        own, of_master = joints.get(name), joints.get(master)
        if own is None or of_master is None:
            continue
        lo, hi = own[:2]
        mlo, mhi = of_master[:2]
        ends = (mult * mlo + off, mult * mhi + off) if mult != 0 else (off, off)
        flo, fhi = min(ends), max(ends)
        if not (outside(flo, lo, hi) or outside(fhi, lo, hi)):
            continue
        raise RobotFileError(
            f"{origin}: mimic joint '{name}' follows '{master}' ({fmt(mult)} * {master} + {fmt(off)}): over the "
            f"limits of '{master}', [{fmt(mlo)}, {fmt(mhi)}], it ranges over [{fmt(flo)}, {fmt(fhi)}], beyond its own "
            f"limits [{fmt(lo)}, {fmt(hi)}] ({urdf}); {remedy(name, master, lo, hi, mult, off, False)}")


def _pinocchio_model(urdf: Path, floating_base: bool, origin: str, mimic: bool, locked: set[str]) -> pin.Model:
    """Pinocchio's model of the URDF. With ``mimic``, its mimic joints follow their masters,
    but for the ``locked`` ones, whose ``<mimic>`` is left out (they are held at their locked
    values, as plain joints: Pinocchio refuses a model with a mimic it cannot follow even when
    the joint is to be locked). The core has read the file already; should urdfdom still refuse
    it, its reason (which it writes to the process's stderr) is carried into the RobotFileError."""
    text = None
    if mimic and locked:
        import xml.etree.ElementTree as ET

        root = ET.fromstring(urdf.read_bytes())
        for joint in root.findall("joint"):
            if joint.get("name") in locked:
                for m in joint.findall("mimic"):
                    joint.remove(m)
        text = ET.tostring(root, encoding="unicode")
    root_joint = [pin.JointModelFreeFlyer()] if floating_base else []
    error: BaseException | None = None
    with _stderr_captured() as said:
        try:
            if text is not None:
                model = pin.buildModelFromXML(text, *root_joint, mimic=mimic)
            else:
                model = pin.buildModelFromUrdf(str(urdf), *root_joint, mimic=mimic)
        except (ValueError, RuntimeError) as exc:
            error = exc
    if error is None:
        if said:  # not ours to swallow
            print(said[0], file=sys.stderr)
        return model
    raise RobotFileError(f"{origin}: Pinocchio cannot read {urdf}: {error}" + (f" (urdfdom: {said[0]})" if said else ""))


@contextlib.contextmanager
def _stderr_captured() -> Iterator[list[str]]:
    """What the block writes to the process's stderr (file descriptor 2, where C++ libraries
    such as urdfdom write), captured instead of shown: the yielded list holds it (stripped) after
    the block, if anything was written. Without a usable descriptor 2, nothing is captured."""
    said: list[str] = []
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):
        yield said
        return
    with tempfile.TemporaryFile() as captured:
        os.dup2(captured.fileno(), 2)
        try:
            yield said
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            captured.seek(0)
            text = captured.read().decode(errors="replace").strip()
            if text:
                said.append(text)


def write_srdf(robot: Robot, path: str | os.PathLike[str], samples: int = 10_000, seed: int = 0) -> Path:
    """Write an SRDF with the robot's computed disabled pairs (with MoveIt's reasons) and its
    default configuration as the group state "default", atomically. Pass it back as
    ``srdf=`` (or in a robot file) to skip the computation and to edit the pairs by hand."""
    found = compute_disabled_pairs(robot, samples=samples, seed=seed)
    state = []
    for name in robot.joint_names:
        j = robot.model.joints[robot.model.getJointId(name)]
        if j.nq == 1:
            state.append((name, float(robot.q_default[j.idx_q])))
    return write_text(path, _core.disabled_pairs_srdf(robot.name, [tuple(e) for e in found.entries], state))


def _file_key(p: Any) -> tuple[str, int]:
    path = Path(p)
    try:
        return str(path.resolve()), path.stat().st_mtime_ns
    except OSError:
        return str(path), -1


#: load's cache: (description, file keys) as JSON -> the robot.
_LOADED: dict[str, Robot] = {}


def clear_cache() -> None:
    """Forget the robots :func:`load` has cached (the next load reads the files again)."""
    _LOADED.clear()


def _cached(desc: dict[str, Any]) -> Robot:
    files = [desc["urdf"], desc["collision_urdf"], desc.get("srdf"), desc.get("source")]
    key = json.dumps({"description": desc, "files": [_file_key(f) for f in files if f]}, sort_keys=True, default=str)
    robot = _LOADED.get(key)
    if robot is None:  # the description as read (its frames in the file's order)
        robot = _LOADED[key] = Robot(desc)
    return robot


def load(
    robot: str | os.PathLike[str] | None = None,
    /,
    *,
    urdf: str | os.PathLike[str] | None = None,
    srdf: str | os.PathLike[str] | None = None,
    collision_urdf: str | os.PathLike[str] | None = None,
    package_dirs: Iterable[str | os.PathLike[str]] = (),
    floating_base: bool | None = None,
    locked_joints: Iterable[str] | Mapping[str, float] | None = None,
    reference_state: str | None = None,
    frames: Mapping[str, str] | None = None,
    name: str | None = None,
    merge_computed_pairs: bool | None = None,
) -> Robot:
    """Load a robot: a preset name (:data:`ROBOT_NAMES`), a robot file (``.toml``), a URDF path,
    or ``urdf=PATH`` with keywords (the keys of a robot file; see docs/ROBOTS.md).

    A preset or robot file takes the same keywords but ``urdf``: each replaces the file's key,
    e.g. the Panda with its fingers open for a grasp,
    ``load("panda", locked_joints={"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04})``.
    Such a robot keeps the preset's name unless ``name`` is given, and is another robot than the
    preset (cached apart: ``load("panda") is load("panda")``, not the one with keywords). A
    keyword left out (None) keeps the file's value; one given replaces it, ``False`` and an empty
    ``locked_joints`` included (``load("robot.toml", locked_joints=[])`` frees every joint the
    file locks).

    Relative paths in a robot file are relative to the file; in keywords, to the current folder.
    ``package://PKG/...`` resolves against ``package_dirs`` then example-robot-data. Cached: the
    same description of unchanged files gives the same object. Errors: UnknownNameError for an
    unknown preset (the known ones listed) or a name the files lack (a locked joint, a frame's
    link, an SRDF's link or reference state), RobotFileError naming the file and the key for a
    bad robot file, a malformed URDF or SRDF (with the parser's reason), a value outside a
    joint's limits, a mimic joint genplan cannot follow or that its master would take outside
    its own limits. A RobotWarning reports what loads but
    may not be meant: an unused SRDF state naming unknown joints, self-collision pairs in
    contact at the default configuration (``merge_computed_pairs=True`` is the remedy; see
    docs/ROBOTS.md).
    """
    keywords = dict(
        urdf=urdf, srdf=srdf, collision_urdf=collision_urdf, floating_base=floating_base,
        locked_joints=(None if locked_joints is None else
                       dict(locked_joints) if isinstance(locked_joints, Mapping) else list(locked_joints)),
        reference_state=reference_state, frames=None if frames is None else dict(frames), name=name,
        package_dirs=[str(p) for p in package_dirs] or None, merge_computed_pairs=merge_computed_pairs,
    )
    given = sorted(k for k, v in keywords.items() if v is not None)
    defaults = default_package_dirs()
    if robot is not None and isinstance(robot, (str, os.PathLike)) and str(robot).endswith(".urdf"):
        if urdf is not None:
            raise TypeError("load(): give the URDF either as the first argument or as urdf=, not both")
        keywords["urdf"], robot = str(robot), None
    if robot is not None:
        if urdf is not None:
            raise TypeError(f"load(): {robot!r} names its URDF; give urdf= without a preset or robot file")
        if not isinstance(robot, (str, os.PathLike)):
            raise TypeError(f"load(): expected a preset name or a path, got {type(robot).__name__}")
        if isinstance(robot, os.PathLike) or "/" in robot or os.sep in robot or robot.endswith(".toml"):
            path = Path(robot)
            if not path.is_file():
                raise FileNotFoundError(f"robot file {path} does not exist")
        elif str(robot) not in ROBOT_NAMES:
            raise UnknownNameError(
                f"unknown robot '{robot}' (known: {', '.join(ROBOT_NAMES)}; or a robot file .toml, or urdf=PATH)"
            )
        else:
            path = PRESETS_DIR / f"{robot}.toml"
        desc = _core.read_robot_file(path, defaults)
        if not given:
            return _cached(desc)
        # the file's keys (paths as read: absolute; its package folders beyond the defaults), each
        # keyword in place of its own, checked again; the file's values are part of the cache key
        fields: dict[str, Any] = {k: str(v) if isinstance(v, os.PathLike) else v for k, v in desc.items()
                                  if k not in ("source", "package_dirs")}
        own_dirs = [str(p) for p in desc.get("package_dirs") or [] if Path(p) not in defaults]
        fields["package_dirs"] = own_dirs + [str(p) for p in package_dirs]
        fields.update({k: keywords[k] for k in given if k != "package_dirs"})
        # keys the file leaves out stay out; a keyword given (False, [] or {} included) replaces the file's
        fields = {k: v for k, v in fields.items() if v is not None and (k in given or v != [])}
        origin = f"robot '{fields.get('name', desc['name'])}' ({path} with {', '.join(given)})"
        return _cached(_core.robot_description(fields, defaults, origin, str(desc["name"]), Path.cwd()))
    if keywords["urdf"] is None:
        raise TypeError("load(): give a preset name, a robot file, or urdf=PATH")
    fields = {k: v for k, v in keywords.items() if v is not None}
    default_name = Path(str(fields["urdf"])).stem
    desc = _core.robot_description(fields, defaults, f"robot '{name or default_name}'", default_name, Path.cwd())
    return _cached(desc)
