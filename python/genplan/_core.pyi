"""Type stub of the private native module ``genplan._core`` (Rust, PyO3)."""

from os import PathLike
from typing import Any

import numpy as np
from numpy.typing import NDArray

__version__: str
ROBOT_NAMES: list[str]
CRATE_VERSIONS: dict[str, str]

_Path = str | PathLike[str]

class KinematicModel:
    @staticmethod
    def from_urdf(
        urdf_path: _Path,
        *,
        floating_base: bool = False,
        locked_joints: dict[str, float] | None = None,
        joint_order: list[str] | None = None,
    ) -> KinematicModel: ...
    @property
    def nq(self) -> int: ...
    @property
    def nv(self) -> int: ...
    @property
    def floating_base(self) -> bool: ...
    @property
    def link_names(self) -> list[str]: ...
    @property
    def active_joints(self) -> list[str]: ...
    @property
    def lower(self) -> NDArray[np.float64]: ...
    @property
    def upper(self) -> NDArray[np.float64]: ...
    def link_index(self, name: str) -> int: ...
    def forward_kinematics(
        self, q: NDArray[np.float64], links: list[str] | None = None
    ) -> NDArray[np.float64]: ...

class CollisionWorld:
    def __init__(
        self,
        model: KinematicModel,
        collision_urdf: _Path,
        package_dirs: list[_Path] = ...,
        srdf_path: _Path | None = None,
    ) -> None: ...
    @property
    def model(self) -> KinematicModel: ...
    @property
    def geometry_names(self) -> list[str]: ...
    @property
    def geometry_links(self) -> list[str]: ...
    @property
    def self_pairs(self) -> list[tuple[str, str]]: ...
    @property
    def obstacle_names(self) -> list[str]: ...
    check_self: bool
    def add_box(
        self,
        name: str,
        half_extents: tuple[float, float, float],
        center: tuple[float, float, float],
        rotation: list[list[float]] | None = None,
    ) -> None: ...
    def add_sphere(self, name: str, radius: float, center: tuple[float, float, float]) -> None: ...
    def add_halfspace(self, name: str, normal: tuple[float, float, float], offset: float) -> None: ...
    def remove_obstacle(self, name: str) -> None: ...
    def clear_obstacles(self) -> None: ...
    def in_collision(self, q: NDArray[np.float64]) -> Any: ...
    def min_distance(self, q: NDArray[np.float64]) -> Any: ...
    def close_pairs(self, q: list[float], margin: float = 0.0) -> list[tuple[str, str, float]]: ...

class Projector:
    """Native damped Gauss-Newton projector; terms are dicts (see genplan.projection)."""

    def __init__(
        self,
        model: KinematicModel,
        primary: list[dict[str, Any]],
        secondary: list[dict[str, Any]] = ...,
        settings: dict[str, Any] | None = None,
    ) -> None: ...
    @property
    def term_names(self) -> list[str]: ...
    def solve_batch(
        self,
        q0: NDArray[np.float64],
        q_nom: NDArray[np.float64] | None = None,
        parallel: bool = True,
        target_term: str | None = None,
        targets: NDArray[np.float64] | None = None,
    ) -> tuple[
        NDArray[np.float64], NDArray[np.bool_], NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]
    ]: ...
    def frame_jacobian_local(self, q: list[float], link: str) -> NDArray[np.float64]: ...
    def center_of_mass(self, q: list[float]) -> tuple[list[float], NDArray[np.float64]]: ...

def robot_spec(name: str) -> dict[str, Any]: ...
def load_robot(name: str, robots_dir: _Path) -> tuple[KinematicModel, CollisionWorld]: ...
def package_dirs(robots_dir: _Path) -> list[str]: ...

# --- constrained planning (genplan_core::planning / gan; genplan.planning) ---

class UniformSampler:
    """Uniform within the joint limits; a free-flyer base held at ``base``."""

    def __init__(self, model: KinematicModel, base: list[float] | None = None, seed: int = 0) -> None: ...
    def sample(self, n: int) -> NDArray[np.float64]: ...

class GanSampler:
    """A trained GAN generator run natively (see genplan.gan.GanModel.native_sampler)."""

    def __init__(
        self,
        noise_dim: int,
        weights: list[NDArray[np.float64]],
        biases: list[NDArray[np.float64]],
        mean: list[float],
        std: list[float],
        floating_base: bool,
        lower: list[float],
        upper: list[float],
        seed: int = 0,
    ) -> None: ...
    @property
    def nq(self) -> int: ...
    def sample(self, n: int) -> NDArray[np.float64]: ...
    def generate(
        self, members: list[int], noise: NDArray[np.float64], targets: NDArray[np.float64]
    ) -> NDArray[np.float64]: ...

class MixtureSampler:
    """``primary`` with probability ``p``, else ``secondary`` (native samplers or objects with sample(n))."""

    def __init__(self, primary: Any, secondary: Any, p: float = 0.8, seed: int = 0) -> None: ...
    @property
    def p(self) -> float: ...

class Planner:
    """The constrained RRT (see genplan.planning.Planner for the typed front end)."""

    def __init__(self, model: KinematicModel, settings: dict[str, Any] | None = None) -> None: ...
    def plan(
        self,
        start: list[float],
        goals: NDArray[np.float64],
        sampler: Any,
        projector: Any,
        checker: Any,
        parallel: bool = False,
    ) -> dict[str, Any]: ...
