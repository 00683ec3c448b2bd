//! Collision world in parry: the robot's collision geometry, self-collision pairs, obstacles.
//!
//! Robot geometry comes from the URDF's `<collision>` elements: boxes, spheres, cylinders and
//! capsules become parry primitives; meshes (STL, OBJ, Collada: [`crate::mesh`]) become the convex
//! hull of their vertices, or the shape a robot file's `mesh_shape` names ([`MeshShape`]). Self-
//! collision pairs are all pairs of geometries on different rigid bodies (links joined by fixed
//! or locked joints form one body, as in Pinocchio's `addAllCollisionPairs`), minus the SRDF's
//! disabled link pairs.
//!
//! The files, one concept each: `geometry` (URDF and mesh geometry to parry shapes), `hull`
//! ([`Hull`]: a convex hull whose GJK support point climbs its vertex graph),
//! `broad_phase` (the pair lists and the bounding-volume filters that rule pairs out before the
//! exact test), `obstacles` ([`Obstacles`]: the obstacle list and the bounding-volume hierarchy
//! over it that finds the obstacles near a robot shape), `motion` ([`MotionBounds`]: how far
//! each geometry can move along a motion, to certify motions with `CollisionWorld::clear_by`), `world` ([`CollisionWorld`]: obstacles and the queries), `attached` ([`Attached`]: objects held by the robot's links, as robot geometry), `cloud` ([`Cloud`]: point clouds as
//! obstacles, each point a ball, and their voxel down-sampling), `cloud_grid` ([`CloudGrid`]: a
//! cloud's balls in a dense grid of cells, the shape its queries ask), `points` (signed distances of
//! points to the obstacles), `spheres` (the robot's covering spheres tested against the obstacles,
//! configurations as f32 lanes: the fast path of a planner's checks). Everything is
//! re-exported here: the paths are `genplan_core::collision::X`.

pub mod allowed;
mod attached;
mod broad_phase;
mod cloud;
mod cloud_grid;
mod geometry;
mod groups;
mod hull;
mod motion;
mod obstacles;
mod points;
pub mod spheres;
mod world;

pub use attached::Attached;
pub use cloud::{voxel_downsample, Cloud, MIN_VOXEL};
pub use cloud_grid::{CloudGrid, CELL_RADII, MAX_CELLS_PER_BALL, MIN_CELLS};
pub use geometry::{decompose, load_mesh_vertices, mesh_shape, set_decomposition_cache, MeshShape, RobotGeometry, DECOMPOSITION};
pub use hull::Hull;
pub use motion::{Levers, MotionBounds, Sweep};
pub use obstacles::Obstacles;
pub use world::{CollisionWorld, Obstacle, PairDistance, Scratch, MAX_OBSTACLE_EXTENT, MAX_PADDING, MIN_NORMAL_NORM, QUATERNION_TOLERANCE};
