"""Type stub of the private native module ``genplan._core`` (Rust, PyO3)."""

from collections.abc import Sequence
from os import PathLike
from typing import Any, ClassVar, final

from typing_extensions import Self

import numpy as np
from numpy.typing import ArrayLike, DTypeLike, NDArray

from genplan import protocols

__all__ = [
    "__version__", "CRATE_VERSIONS", "KinematicModel", "CollisionWorld", "Projector",
    "SolverSettings", "read_robot_file", "robot_description", "load_robot", "srdf_disabled_pairs",
    "disabled_pairs_srdf", "time_optimal", "sample_timed_spline", "Planner", "PlannerSettings", "PlanStats",
    "PlanResult", "UniformSampler", "DataSampler", "MixtureSampler", "GanSampler", "FlowSampler", "Dynamics", "SpatulaSimulation",
    "spatula_defaults", "pancake_phi",
]

__version__: str
CRATE_VERSIONS: dict[str, str]

_Path = str | PathLike[str]

@final
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
        self,
        q: ArrayLike,
        links: Sequence[str] | None = None,
        dtype: DTypeLike | None = None,
        out: NDArray[Any] | None = None,
    ) -> NDArray[Any]: ...

@final
class CollisionWorld:
    def __new__(
        cls,
        model: KinematicModel,
        collision_urdf: _Path,
        package_dirs: list[_Path] = ...,
        srdf_path: _Path | None = None,
        disabled_pairs: list[tuple[str, str]] | None = None,
    ) -> Self: ...
    def compute_disabled_pairs(
        self, q_default: list[float] | NDArray[np.float64], samples: int = 10000, always_fraction: float = 0.95, seed: int = 0
    ) -> list[tuple[str, str, str]]: ...
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
    def add_cylinder(
        self,
        name: str,
        radius: float,
        half_height: float,
        center: tuple[float, float, float],
        rotation: list[list[float]] | None = None,
    ) -> None: ...
    def add_capsule(
        self,
        name: str,
        radius: float,
        half_length: float,
        center: tuple[float, float, float],
        rotation: list[list[float]] | None = None,
    ) -> None: ...
    def add_mesh(
        self,
        name: str,
        path: _Path,
        scale: tuple[float, float, float],
        center: tuple[float, float, float],
        rotation: list[list[float]] | None = None,
    ) -> None: ...
    def add_halfspace(self, name: str, normal: tuple[float, float, float], offset: float) -> None: ...
    def remove_obstacle(self, name: str) -> None: ...
    def clear_obstacles(self) -> None: ...
    def in_collision(self, q: ArrayLike) -> bool | NDArray[np.bool_]: ...
    def min_distance(self, q: ArrayLike) -> float | NDArray[np.float64]: ...
    def close_pairs(self, q: list[float], margin: float = 0.0) -> list[tuple[str, str, float]]: ...

@final
class SolverSettings:
    """Damped Gauss-Newton settings (genplan_core::projection::Settings); immutable."""

    fields: ClassVar[list[str]]
    def __new__(
        cls,
        *,
        max_iterations: int = 50,
        mu: float = 1e-4,
        mu_bar: float = 1e-6,
        armijo_c1: float = 1e-4,
        backtrack: float = 0.2,
        max_backtracks: int = 20,
        clip_to_limits: bool = True,
        active_set: bool = False,
        secondary_backtracks: int = 3,
        secondary_slack: float = 1e-6,
    ) -> Self: ...
    @property
    def max_iterations(self) -> int: ...
    @property
    def mu(self) -> float: ...
    @property
    def mu_bar(self) -> float: ...
    @property
    def armijo_c1(self) -> float: ...
    @property
    def backtrack(self) -> float: ...
    @property
    def max_backtracks(self) -> int: ...
    @property
    def clip_to_limits(self) -> bool: ...
    @property
    def active_set(self) -> bool: ...
    @property
    def secondary_backtracks(self) -> int: ...
    @property
    def secondary_slack(self) -> float: ...
    def replace(self, **changes: Any) -> SolverSettings: ...
    def to_dict(self) -> dict[str, Any]: ...
    def __eq__(self, value: object, /) -> bool: ...
    def __getnewargs_ex__(self) -> tuple[tuple[()], dict[str, Any]]: ...

@final
class Projector:
    """Native damped Gauss-Newton projector; terms are dicts (see genplan.projection). A dict of
    type "custom" holds a Python term under "term" (genplan.projection.CustomTerm: dim,
    residual(q), jacobian(q) on batches), called back with the GIL per call; an exception it
    raises propagates unchanged out of solve_batch and primary_residuals."""

    def __new__(
        cls,
        model: KinematicModel,
        primary: list[dict[str, Any]],
        secondary: list[dict[str, Any]] = ...,
        settings: SolverSettings | None = None,
    ) -> Self: ...
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
    def primary_residuals(
        self, q: NDArray[np.float64], jacobian: bool = True
    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]: ...
    def frame_jacobian_local(self, q: list[float], link: str) -> NDArray[np.float64]: ...
    def center_of_mass(self, q: list[float]) -> tuple[list[float], NDArray[np.float64]]: ...

def read_robot_file(path: _Path, package_dirs: list[_Path]) -> dict[str, Any]: ...
def robot_description(
    fields: dict[str, Any], package_dirs: list[_Path], origin: str, default_name: str, base_dir: _Path | None = None
) -> dict[str, Any]: ...
def srdf_disabled_pairs(path: _Path) -> list[tuple[str, str]]: ...
def disabled_pairs_srdf(
    robot_name: str, pairs: list[tuple[str, str, str]], default_state: list[tuple[str, float]] | None = None
) -> str: ...
def load_robot(path: _Path, package_dirs: list[_Path]) -> tuple[KinematicModel, CollisionWorld]: ...
def time_optimal(
    grid: Sequence[float], d1: NDArray[np.float64], d2: NDArray[np.float64], vlim: Sequence[float], alim: Sequence[float]
) -> NDArray[np.float64]: ...
def sample_timed_spline(
    x: Sequence[float],
    c: NDArray[np.float64],
    grid: Sequence[float],
    knots: Sequence[float],
    sdot: Sequence[float],
    sdd: Sequence[float],
    rate: float,
    scale: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]: ...

# --- constrained planning (genplan_core::planning / gan; genplan.planning) ---

@final
class UniformSampler:
    """Uniform within the joint limits; a free-flyer base held at ``base``, its position drawn
    uniformly in ``base_box`` ([lower, upper]) when given."""

    def __new__(cls, model: KinematicModel, base: list[float] | None = None, seed: int = 0,
                 base_box: list[list[float]] | None = None) -> Self: ...
    def sample(self, n: int) -> NDArray[np.float64]: ...

@final
class DataSampler:
    """Rows of a data set (n, nq), each drawn uniformly at random (genplan.planning.data_sampler)."""

    def __new__(cls, rows: NDArray[np.float64], seed: int = 0) -> Self: ...
    def sample(self, n: int) -> NDArray[np.float64]: ...
    def __len__(self) -> int: ...

@final
class GanSampler:
    """A trained GAN generator run natively (see genplan.gan.GanModel.native_sampler)."""

    def __new__(
        cls,
        noise_dim: int,
        weights: list[NDArray[np.float64]],
        biases: list[NDArray[np.float64]],
        mean: list[float],
        std: list[float],
        floating_base: bool,
        lower: list[float],
        upper: list[float],
        seed: int = 0,
    ) -> Self: ...
    @property
    def nq(self) -> int: ...
    def sample(self, n: int) -> NDArray[np.float64]: ...
    def generate(
        self, members: list[int], noise: NDArray[np.float64], targets: NDArray[np.float64]
    ) -> NDArray[np.float64]: ...

@final
class FlowSampler:
    """A trained flow-matching sampler run natively (see genplan.gan.flow.FlowModel.native_sampler)."""

    def __new__(
        cls,
        weights: list[NDArray[np.float32]],
        biases: list[NDArray[np.float32]],
        steps: int,
        target_mean: list[float],
        target_std: list[float],
        mean: list[float],
        std: list[float],
        floating_base: bool,
        lower: list[float],
        upper: list[float],
        seed: int = 0,
    ) -> Self: ...
    @property
    def nq(self) -> int: ...
    def sample(self, n: int) -> NDArray[np.float64]: ...
    def generate(self, noise: NDArray[np.float64], targets: NDArray[np.float64]) -> NDArray[np.float64]: ...

@final
class MixtureSampler:
    """``primary`` with probability ``p``, else ``secondary`` (native samplers or objects with
    sample(n)); with ``half_life``, the probability halves every ``half_life`` rows of a plan."""

    def __new__(
        cls,
        primary: UniformSampler | GanSampler | FlowSampler | MixtureSampler | protocols.Sampler,
        secondary: UniformSampler | GanSampler | FlowSampler | MixtureSampler | protocols.Sampler,
        p: float = 0.8,
        seed: int = 0,
        half_life: float | None = None,
    ) -> Self: ...
    @property
    def p(self) -> float: ...
    @property
    def half_life(self) -> float | None: ...

@final
class PlannerSettings:
    """Settings of the constrained planner (genplan_core::planning::Settings; ``algorithm``:
    "crrt" or "rrt_connect"; ``edge_check``: "sampled" or "certified"); immutable."""

    fields: ClassVar[list[str]]
    def __new__(
        cls,
        *,
        step: float = 0.3,
        max_increments: int = 10,
        max_jump: float = 3.0,
        goal_tolerance: float = 1e-3,
        max_extensions: int = 500,
        retries: int = 2,
        project_samples: bool = True,
        sample_batch: int = 16,
        edge_resolution: float = 0.025,
        lazy_edges: bool = True,
        simplify: bool = False,
        neighbors: str = "auto",
        max_empty_batches: int = 100,
        algorithm: str = "crrt",
        edge_check: str = "sampled",
    ) -> Self: ...
    @property
    def step(self) -> float: ...
    @property
    def max_increments(self) -> int: ...
    @property
    def max_jump(self) -> float: ...
    @property
    def goal_tolerance(self) -> float: ...
    @property
    def max_extensions(self) -> int: ...
    @property
    def retries(self) -> int: ...
    @property
    def project_samples(self) -> bool: ...
    @property
    def sample_batch(self) -> int: ...
    @property
    def edge_resolution(self) -> float: ...
    @property
    def lazy_edges(self) -> bool: ...
    @property
    def simplify(self) -> bool: ...
    @property
    def neighbors(self) -> str: ...
    @property
    def max_empty_batches(self) -> int: ...
    @property
    def algorithm(self) -> str: ...
    @property
    def edge_check(self) -> str: ...
    def replace(self, **changes: Any) -> PlannerSettings: ...
    def to_dict(self) -> dict[str, Any]: ...
    def __eq__(self, value: object, /) -> bool: ...
    def __getnewargs_ex__(self) -> tuple[tuple[()], dict[str, Any]]: ...

@final
class PlanStats:
    """What a plan cost (genplan_core::planning::Stats); read-only."""

    fields: ClassVar[list[str]]
    @property
    def success(self) -> bool: ...
    @property
    def retries(self) -> int: ...
    @property
    def extensions(self) -> int: ...
    @property
    def projections(self) -> int: ...
    @property
    def projection_calls(self) -> int: ...
    @property
    def edge_projections(self) -> int: ...
    @property
    def samples(self) -> int: ...
    @property
    def samples_rejected(self) -> int: ...
    @property
    def validity_checks(self) -> int: ...
    @property
    def motion_certificates(self) -> int: ...
    @property
    def nodes(self) -> int: ...
    @property
    def pruned(self) -> int: ...
    @property
    def shortcuts(self) -> int: ...
    @property
    def time_s(self) -> float: ...
    @property
    def sampler_s(self) -> float: ...
    @property
    def projector_s(self) -> float: ...
    @property
    def checker_s(self) -> float: ...
    def to_dict(self) -> dict[str, Any]: ...
    def __getitem__(self, key: str, /) -> Any: ...

@final
class PlanResult:
    """A plan's outcome (see genplan.planning)."""

    @property
    def success(self) -> bool: ...
    @property
    def path(self) -> NDArray[np.float64]: ...
    @property
    def waypoints(self) -> NDArray[np.float64]: ...
    @property
    def goal_index(self) -> int | None: ...
    @property
    def stats(self) -> PlanStats: ...
    @property
    def time_s(self) -> float: ...
    @property
    def projections(self) -> int: ...
    @property
    def extensions(self) -> int: ...
    @property
    def retries(self) -> int: ...

_NativeSampler = UniformSampler | GanSampler | FlowSampler | MixtureSampler

@final
class Planner:
    """The constrained planner, cRRT or RRT-Connect (see genplan.planning.Planner for the typed
    front end)."""

    def __new__(cls, model: KinematicModel, settings: PlannerSettings | None = None) -> Self: ...
    def plan(
        self,
        start: list[float],
        goals: NDArray[np.float64],
        sampler: _NativeSampler | protocols.Sampler,
        projector: Projector | protocols.Projector,
        checker: CollisionWorld | protocols.ValidityChecker,
        parallel: bool = False,
    ) -> PlanResult: ...

# --- dynamics and the spatula controller (genplan_core::dynamics / control; genplan.control) ---

_Offset = list[list[float]] | None  # a 4x4 placement in the link frame

@final
class Dynamics:
    """Rigid-body dynamics of a fixed-base arm; q in Pinocchio's convention and joint order.
    Jacobians are LOCAL_WORLD_ALIGNED (rows [v; w] of the frame origin, world axes)."""

    @staticmethod
    def from_description(description: dict[str, Any]) -> Dynamics: ...
    @staticmethod
    def from_urdf(urdf_path: _Path, locked_joints: dict[str, float] | None = None) -> Dynamics: ...
    @property
    def nq(self) -> int: ...
    @property
    def nv(self) -> int: ...
    @property
    def joint_names(self) -> list[str]: ...
    gravity: list[float]
    @property
    def moving_mass(self) -> float: ...
    def add_inertia(
        self, link: str, mass: float, com: list[float], inertia: list[list[float]], offset: _Offset = None
    ) -> None: ...
    def mass_matrix(self, q: NDArray[np.float64]) -> NDArray[np.float64]: ...
    def nonlinear_effects(self, q: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]: ...
    def gravity_torque(self, q: NDArray[np.float64]) -> NDArray[np.float64]: ...
    def rnea(
        self, q: NDArray[np.float64], v: NDArray[np.float64], a: NDArray[np.float64]
    ) -> NDArray[np.float64]: ...
    def forward_dynamics(
        self, q: NDArray[np.float64], v: NDArray[np.float64], tau: NDArray[np.float64]
    ) -> NDArray[np.float64]: ...
    def frame_placement(self, q: NDArray[np.float64], link: str, offset: _Offset = None) -> NDArray[np.float64]: ...
    def frame_jacobian(self, q: NDArray[np.float64], link: str, offset: _Offset = None) -> NDArray[np.float64]: ...
    def frame_jacobian_time_variation(
        self, q: NDArray[np.float64], v: NDArray[np.float64], link: str, offset: _Offset = None
    ) -> NDArray[np.float64]: ...
    def energy(self, q: NDArray[np.float64], v: NDArray[np.float64]) -> tuple[float, float]: ...

@final
class SpatulaSimulation:
    """The seq2seq paper's 1 kHz spatula controller + simulated arm + pancake (see genplan.control)."""

    def __new__(cls, robot: dict[str, Any], config: dict[str, Any] | None = None) -> Self: ...
    @property
    def config(self) -> dict[str, Any]: ...
    @property
    def joint_names(self) -> list[str]: ...
    @property
    def limits(self) -> dict[str, list[float]]: ...
    def command_pose(self, p: list[float]) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...
    def spatula_pose(self, q: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...
    def check_trajectory(self, trajectory: NDArray[np.float64]) -> NDArray[np.float64]: ...
    def run(
        self,
        trajectory: NDArray[np.float64],
        motion_len: int | None = None,
        paced: bool = False,
        stop_at_limit: bool = False,
    ) -> dict[str, Any]: ...

def spatula_defaults() -> tuple[dict[str, Any], dict[str, Any]]: ...
def pancake_phi(theta: NDArray[np.float64], acc: NDArray[np.float64], g: float = 9.8) -> NDArray[np.float64]: ...
