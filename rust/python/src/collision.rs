//! `CollisionWorld`: the robot's collision geometry and the obstacles (`genplan_core::collision`),
//! collision and distance queries for one configuration or a batch.

use std::path::PathBuf;
use std::sync::Arc;

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};
use numpy::ndarray::{Array, IxDyn};
use numpy::{IntoPyArray, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::IntoPyObjectExt;

use genplan_core::collision::spheres::{AttachedSpheres, SphereModel, SphereScratch, SphereWorld};
use genplan_core::collision::{allowed, CollisionWorld, MeshShape};
use genplan_core::srdf::Srdf;
use genplan_core::urdf::Urdf;
use genplan_core::Scratch;

use crate::arrays;
use crate::batch::rows_map;
use crate::errors::{err, to_py, to_py_in, Kind};
use crate::kinematics::PyKinematicModel;

thread_local! {
    /// Collision buffers of a one-row call.
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// The pose at `center` with `rotation` (a 3x3 matrix; None: the identity), a GenplanError naming
/// `what` for a matrix that is not a proper rotation.
fn pose_from(center: [f64; 3], rotation: Option<[[f64; 3]; 3]>, what: &str) -> PyResult<Isometry3<f64>> {
    let rot = match rotation {
        None => UnitQuaternion::identity(),
        Some(r) => {
            let m = Matrix3::from_fn(|i, j| r[i][j]);
            let off = (m.transpose() * m - Matrix3::identity()).amax();
            if !off.is_finite() || off > 1e-6 || (m.determinant() - 1.0).abs() > 1e-6 {
                return Err(err(Kind::Generic, format!(
                    "{what}: rotation is not a proper rotation matrix (|R^T R - I| = {off:e})"
                )));
            }
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m))
        }
    };
    Ok(Isometry3::from_parts(Translation3::from(center), rot))
}

/// The robot's collision geometry and environment obstacles (parry).
#[pyclass(name = "CollisionWorld", module = "genplan._core")]
pub(crate) struct PyCollisionWorld {
    /// Shared with the planners and sphere checkers built from it, so a plan call does not copy
    /// the world; a change after that copies it once (`Arc::make_mut`) and leaves theirs as it was.
    pub(crate) inner: Arc<CollisionWorld>,
}

impl PyCollisionWorld {
    /// The world to change (copied first if a planner or checker still holds it).
    fn world_mut(&mut self) -> &mut CollisionWorld {
        Arc::make_mut(&mut self.inner)
    }

    /// Read and check q (one row or a batch: [`arrays::read_configurations`]), run `f` per row
    /// without the GIL (in parallel for a batch), return a scalar for one row and a numpy array
    /// for a batch.
    fn per_configuration<'py, T>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        f: fn(&CollisionWorld, &[f64], &mut Scratch) -> T,
    ) -> PyResult<Py<PyAny>>
    where
        T: Send + numpy::Element + for<'a> IntoPyObject<'a>,
    {
        let w = &self.inner;
        let c = arrays::read_configurations(q, &w.model, "q")?;
        let data = c.data();
        if c.rows.is_none() {
            // the row copied (it may be read in place: see arrays::read_configurations) before
            // the GIL is released
            let mut buf = [0.0; 64];
            let owned;
            let q: &[f64] = if data.len() <= buf.len() {
                buf[..data.len()].copy_from_slice(data);
                &buf[..data.len()]
            } else {
                owned = data.to_vec();
                &owned
            };
            let v = py.detach(|| SCRATCH.with_borrow_mut(|s| f(w, q, s)));
            return v.into_py_any(py);
        }
        let out: Vec<T> = rows_map(py, data, w.model.nq, |q, s| f(w, q, s))?;
        Ok(out.into_pyarray(py).into_any().unbind())
    }
}

#[pymethods]
impl PyCollisionWorld {
    /// Build from the model, the URDF that holds the collision geometry, the package dirs
    /// for `package://` meshes, an optional SRDF (its disabled pairs are not checked) and more
    /// link pairs not to check (`disabled_pairs`, e.g. computed by `compute_disabled_pairs`);
    /// `mesh_shape`: what the robot's meshes become (`MESH_SHAPES`).
    #[new]
    #[pyo3(signature = (model, collision_urdf, package_dirs=Vec::new(), srdf_path=None, disabled_pairs=None, mesh_shape="hull"))]
    fn new(
        py: Python<'_>,
        model: &PyKinematicModel,
        collision_urdf: PathBuf,
        package_dirs: Vec<PathBuf>,
        srdf_path: Option<PathBuf>,
        disabled_pairs: Option<Vec<(String, String)>>,
        mesh_shape: &str,
    ) -> PyResult<Self> {
        let meshes = MeshShape::from_name(mesh_shape).map_err(|e| to_py_in("mesh_shape", e))?;
        let urdf = Urdf::from_file(&collision_urdf).map_err(to_py)?;
        let mut srdf = match srdf_path {
            Some(p) => Some(Srdf::from_file(&p).map_err(to_py)?),
            None => None,
        };
        if let Some(extra) = disabled_pairs {
            for (a, b) in &extra {
                for l in [a, b] {
                    model.inner.link_index(l).map_err(|e| to_py_in("disabled_pairs", e))?;
                }
            }
            srdf.get_or_insert_with(Srdf::default).disabled_pairs.extend(extra);
        }
        let model = model.inner.clone();
        let inner = py
            .detach(|| CollisionWorld::from_urdf_with(model, &urdf, &package_dirs, srdf.as_ref(), meshes))
            .map_err(to_py)?;
        Ok(Self { inner: Arc::new(inner) })
    }

    /// The link pairs to skip in self-collision checks, computed as MoveIt's setup assistant
    /// does (`genplan_core::collision::allowed`): a list of (link_a, link_b, reason) with reason
    /// "Adjacent", "Default", "Always" or "Never". Independent of the pairs this world skips.
    #[pyo3(signature = (q_default, samples=10_000, always_fraction=0.95, seed=0))]
    fn compute_disabled_pairs(
        &self,
        py: Python<'_>,
        q_default: Vec<f64>,
        samples: usize,
        always_fraction: f64,
        seed: u64,
    ) -> PyResult<Vec<(String, String, &'static str)>> {
        let options = allowed::Options { samples, always_fraction, seed };
        let pairs = py.detach(|| allowed::disabled_pairs(&self.inner, &q_default, &options)).map_err(to_py)?;
        Ok(pairs.into_iter().map(|p| (p.a, p.b, p.reason.as_str())).collect())
    }

    /// The self pairs this world checks that are in contact at `q_default`, each with the number
    /// of `samples` random configurations (seeded) in which it is in contact too:
    /// (link_a, link_b, hits) (`genplan_core::collision::allowed::default_contacts`).
    #[pyo3(signature = (q_default, samples=1000, seed=0))]
    fn default_contacts(&self, py: Python<'_>, q_default: Vec<f64>, samples: usize, seed: u64) -> PyResult<Vec<(String, String, usize)>> {
        let found = py.detach(|| allowed::default_contacts(&self.inner, &q_default, samples, seed)).map_err(to_py)?;
        Ok(found.into_iter().map(|c| (c.a, c.b, c.hits)).collect())
    }

    #[getter]
    fn model(&self) -> PyKinematicModel {
        PyKinematicModel { inner: self.inner.model.clone() }
    }
    #[getter]
    fn geometry_names(&self) -> Vec<String> {
        self.inner.geometries().iter().map(|g| g.name.clone()).collect()
    }
    /// Link name of each geometry.
    #[getter]
    fn geometry_links(&self) -> Vec<String> {
        self.inner
            .geometries()
            .iter()
            .map(|g| self.inner.model.link_names[g.link].clone())
            .collect()
    }
    #[getter]
    fn self_pairs(&self) -> Vec<(String, String)> {
        self.inner.self_pair_names()
    }
    #[getter]
    fn obstacle_names(&self) -> Vec<String> {
        self.inner.obstacles.iter().map(|o| o.name.clone()).collect()
    }
    #[getter]
    fn get_check_self(&self) -> bool {
        self.inner.check_self
    }
    #[setter]
    fn set_check_self(&mut self, value: bool) {
        self.world_mut().check_self = value;
    }

    /// Add a box obstacle (half extents, centre, optional 3x3 rotation).
    #[pyo3(signature = (name, half_extents, center, rotation=None))]
    fn add_box(&mut self, name: &str, half_extents: [f64; 3], center: [f64; 3], rotation: Option<[[f64; 3]; 3]>) -> PyResult<()> {
        let pose = pose_from(center, rotation, &format!("box '{name}'"))?;
        self.world_mut().add_box(name, half_extents, pose).map_err(to_py)
    }
    fn add_sphere(&mut self, name: &str, radius: f64, center: [f64; 3]) -> PyResult<()> {
        self.world_mut().add_sphere(name, radius, center).map_err(to_py)
    }
    /// Add a cylinder obstacle whose axis is its local z (radius, half height, centre, optional
    /// 3x3 rotation).
    #[pyo3(signature = (name, radius, half_height, center, rotation=None))]
    fn add_cylinder(&mut self, name: &str, radius: f64, half_height: f64, center: [f64; 3], rotation: Option<[[f64; 3]; 3]>) -> PyResult<()> {
        let pose = pose_from(center, rotation, &format!("cylinder '{name}'"))?;
        self.world_mut().add_cylinder(name, radius, half_height, pose).map_err(to_py)
    }
    /// Add a capsule obstacle whose segment runs along its local z (radius, half length of the
    /// segment, centre, optional 3x3 rotation).
    #[pyo3(signature = (name, radius, half_length, center, rotation=None))]
    fn add_capsule(&mut self, name: &str, radius: f64, half_length: f64, center: [f64; 3], rotation: Option<[[f64; 3]; 3]>) -> PyResult<()> {
        let pose = pose_from(center, rotation, &format!("capsule '{name}'"))?;
        self.world_mut().add_capsule(name, radius, half_length, pose).map_err(to_py)
    }
    /// Add a mesh file (STL, OBJ, DAE) scaled per axis, at centre and optional 3x3 rotation, as
    /// `shape` says (`MESH_SHAPES`: its convex hull, the triangles, or convex parts). The file
    /// is read (and decomposed) without the GIL.
    #[pyo3(signature = (name, path, scale, center, rotation=None, shape="hull"))]
    #[allow(clippy::too_many_arguments)]
    fn add_mesh(
        &mut self,
        py: Python<'_>,
        name: &str,
        path: PathBuf,
        scale: [f64; 3],
        center: [f64; 3],
        rotation: Option<[[f64; 3]; 3]>,
        shape: &str,
    ) -> PyResult<()> {
        let kind = MeshShape::from_name(shape).map_err(|e| to_py_in(&format!("mesh '{name}' shape"), e))?;
        let pose = pose_from(center, rotation, &format!("mesh '{name}'"))?;
        let inner = self.world_mut();
        py.detach(|| inner.add_mesh_as(name, &path, scale, pose, kind)).map_err(to_py)
    }
    /// Add the half-space below the plane normal . x = offset.
    fn add_halfspace(&mut self, name: &str, normal: [f64; 3], offset: f64) -> PyResult<()> {
        self.world_mut().add_halfspace(name, normal, offset).map_err(to_py)
    }
    /// The clearance (m) the robot keeps from every obstacle without a padding of its own.
    #[getter]
    fn get_padding(&self) -> f64 {
        self.inner.padding()
    }

    #[setter]
    fn set_padding(&mut self, value: f64) -> PyResult<()> {
        self.world_mut().set_padding(value).map_err(to_py)
    }

    /// Set obstacle `name`'s own padding (m; None: the world's).
    #[pyo3(signature = (name, padding=None))]
    fn set_obstacle_padding(&mut self, name: &str, padding: Option<f64>) -> PyResult<()> {
        self.world_mut().set_obstacle_padding(name, padding).map_err(to_py)
    }

    /// The obstacles' own paddings: {name: padding or None (the world's)}.
    #[getter]
    fn obstacle_paddings(&self) -> std::collections::BTreeMap<String, Option<f64>> {
        self.inner.obstacles.iter().map(|o| (o.name.clone(), o.padding)).collect()
    }

    /// Attach obstacle `name` (its pose read in the link's frame) to `link`
    /// (`genplan_core::collision::CollisionWorld::attach`); returns its touch links.
    #[pyo3(signature = (name, link, touch_links=Vec::new(), q=None))]
    fn attach(&mut self, name: &str, link: &str, touch_links: Vec<String>, q: Option<Vec<f64>>) -> PyResult<Vec<String>> {
        self.world_mut().attach(name, link, &touch_links, q.as_deref()).map_err(to_py)
    }

    /// The attached objects: (name, link, touch links), in the order attached.
    #[getter]
    fn attached(&self) -> Vec<(String, String, Vec<String>)> {
        let names = &self.inner.model.link_names;
        self.inner
            .attached()
            .iter()
            .map(|a| (a.name.clone(), names[a.link].clone(), a.touch_links.iter().map(|&l| names[l].clone()).collect()))
            .collect()
    }

    fn remove_obstacle(&mut self, name: &str) -> PyResult<()> {
        self.world_mut().remove_obstacle(name).map_err(to_py)
    }
    fn clear_obstacles(&mut self) {
        self.world_mut().clear_obstacles();
    }

    /// True where a configuration collides: q (nq,) -> bool; q (n, nq) -> bool array (n,).
    fn in_collision<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Py<PyAny>> {
        self.per_configuration(py, q, CollisionWorld::in_collision_unchecked)
    }

    /// Minimum signed distance (m, negative = penetration depth): q (nq,) -> float; (n, nq) -> (n,).
    fn min_distance<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Py<PyAny>> {
        self.per_configuration(py, q, CollisionWorld::min_distance_unchecked)
    }

    /// Pairs closer than `margin` for one configuration: [(a, b, signed distance)], closest first.
    #[pyo3(signature = (q, margin=0.0))]
    fn close_pairs(&self, q: Vec<f64>, margin: f64) -> PyResult<Vec<(String, String, f64)>> {
        let pairs = self.inner.close_pairs(&q, margin).map_err(to_py)?;
        Ok(pairs.into_iter().map(|p| (p.a, p.b, p.distance)).collect())
    }

    /// Signed distances of points (a contiguous float64 array, last axis 3) to the nearest
    /// obstacle and their gradients (`genplan_core::collision` `point_distances`): arrays of the
    /// points' shape without its last axis, and of the points' shape. Obstacles `cutoff` or more
    /// away are skipped (distance `cutoff`, gradient 0). The GIL is released.
    fn point_distances<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArrayDyn<'py, f64>,
        cutoff: f64,
    ) -> PyResult<(Bound<'py, numpy::PyArrayDyn<f64>>, Bound<'py, numpy::PyArrayDyn<f64>>)> {
        let shape = points.shape().to_vec();
        if shape.last() != Some(&3) {
            return Err(err(Kind::Shape, format!("points: expected a last axis of 3 (x, y, z), got shape {shape:?}")));
        }
        let flat: Vec<f64> = points.as_array().iter().copied().collect();
        let n = flat.len() / 3;
        let (mut d, mut g) = (vec![0.0; n], vec![0.0; 3 * n]);
        py.detach(|| self.inner.point_distances(&flat, cutoff, &mut d, &mut g)).map_err(to_py)?;
        let dshape = IxDyn(&shape[..shape.len() - 1]);
        let d = Array::from_shape_vec(dshape, d).map_err(|e| err(Kind::Shape, e.to_string()))?;
        let g = Array::from_shape_vec(IxDyn(&shape), g).map_err(|e| err(Kind::Shape, e.to_string()))?;
        Ok((d.into_pyarray(py), g.into_pyarray(py)))
    }

    /// Add a point cloud (an (n, 3) float64 array in the world frame), each point a ball of
    /// `radius`, down-sampled to one point per `voxel` (m) when given. The GIL is released.
    #[pyo3(signature = (name, points, radius, voxel=None))]
    fn add_points(&mut self, py: Python<'_>, name: &str, points: PyReadonlyArrayDyn<'_, f64>, radius: f64, voxel: Option<f64>) -> PyResult<()> {
        let flat = cloud_rows(&points, &format!("points '{name}'"))?;
        let inner = self.world_mut();
        py.detach(|| inner.add_points(name, &flat, radius, voxel)).map_err(to_py)
    }

    /// Replace the points of cloud `name` (an (n, 3) float64 array) with a new frame, keeping its
    /// radius, voxel and place. The GIL is released.
    fn replace_points(&mut self, py: Python<'_>, name: &str, points: PyReadonlyArrayDyn<'_, f64>) -> PyResult<()> {
        let flat = cloud_rows(&points, &format!("points '{name}'"))?;
        let inner = self.world_mut();
        py.detach(|| inner.replace_points(name, &flat)).map_err(to_py)
    }

    /// The point clouds: {name: (radius, voxel or None, number of balls)}.
    #[getter]
    fn clouds(&self) -> std::collections::BTreeMap<String, (f64, Option<f64>, usize)> {
        self.inner.obstacles.iter().filter_map(|o| o.cloud.map(|c| (o.name.clone(), (c.radius, c.voxel, c.points)))).collect()
    }

    /// Which points (an (n, 3) float64 array) lie within `margin` of the robot's geometry at `q`:
    /// a bool array (n,). The GIL is released.
    fn robot_points<'py>(&self, py: Python<'py>, q: Vec<f64>, points: PyReadonlyArrayDyn<'py, f64>, margin: f64) -> PyResult<Bound<'py, numpy::PyArray1<bool>>> {
        let flat = cloud_rows(&points, "points")?;
        let w = &self.inner;
        let mask = py.detach(|| w.robot_points(&q, &flat, margin)).map_err(to_py)?;
        Ok(mask.into_pyarray(py))
    }

    fn __repr__(&self) -> String {
        format!(
            "CollisionWorld(geometries={}, self_pairs={}, obstacles={}, check_self={})",
            self.inner.geometries().len(),
            self.inner.self_pairs().len(),
            self.inner.obstacles.len(),
            self.inner.check_self
        )
    }
}

/// The rows of an (n, 3) array of points, flat (a ShapeError naming `what` for another shape).
fn cloud_rows(points: &PyReadonlyArrayDyn<'_, f64>, what: &str) -> PyResult<Vec<f64>> {
    let shape = points.shape();
    if shape.len() != 2 || shape[1] != 3 {
        return Err(err(Kind::Shape, format!("{what}: expected an array of shape (n, 3), got shape {shape:?}")));
    }
    Ok(match points.as_slice() {
        Ok(s) => s.to_vec(),
        Err(_) => points.as_array().iter().copied().collect(),
    })
}

/// Register the collision class on `genplan._core`.
/// The robot's covering spheres against a collision world's obstacles
/// (`genplan_core::collision::spheres`): a fast, conservative collision check (free by the
/// spheres is free by the exact geometry), and a validity checker for `Planner.plan`.
#[pyclass(name = "SphereChecker", module = "genplan._core", frozen)]
pub(crate) struct PySphereChecker {
    pub(crate) inner: Arc<SphereWorld>,
    /// A planner checks each collision the spheres find again by the exact geometry.
    pub(crate) confirm: bool,
}

#[pymethods]
impl PySphereChecker {
    /// Sphere i on link `links[i]` (a link name), centre `centers[i]` in that link's frame,
    /// radius `radii[i]`; the obstacles (point clouds included, each sphere against the balls
    /// near it), their paddings and the self pairs of `world` as they are now. `attached`: per
    /// object attached to the robot in `world`, (its name, its spheres' centres in the holding
    /// link's frame, their radii), each object exactly once (refused otherwise, naming it).
    /// `confirm`: a planner given this checker checks each collision the spheres find again by
    /// the exact geometry of `world`, whose answer stands (`in_collision` stays the spheres').
    #[new]
    #[pyo3(signature = (world, links, centers, radii, attached=None, confirm=false))]
    fn new(
        world: &PyCollisionWorld,
        links: Vec<String>,
        centers: Vec<[f64; 3]>,
        radii: Vec<f64>,
        attached: Option<Vec<(String, Vec<[f64; 3]>, Vec<f64>)>>,
        confirm: bool,
    ) -> PyResult<Self> {
        let w = &world.inner;
        let names: Vec<&str> = links.iter().map(String::as_str).collect();
        let spheres = SphereModel::new(&w.model, &names, &centers, &radii).map_err(to_py)?;
        let objects: Vec<AttachedSpheres> = attached
            .unwrap_or_default()
            .into_iter()
            .map(|(name, centers, radii)| AttachedSpheres { name, centers, radii })
            .collect();
        let inner = SphereWorld::with_attached(Arc::clone(w), spheres, &objects).map_err(to_py)?;
        Ok(Self { inner: Arc::new(inner), confirm })
    }

    /// Whether a planner confirms the spheres' collisions by the exact geometry.
    #[getter]
    fn confirm(&self) -> bool {
        self.confirm
    }

    /// The number of spheres.
    #[getter]
    fn n_spheres(&self) -> usize {
        self.inner.spheres().len()
    }

    /// The pairs checked for self-collision (link names; an attached object's name for its
    /// spheres).
    #[getter]
    fn self_pairs(&self) -> Vec<(String, String)> {
        self.inner.self_pair_names()
    }

    /// True where the spheres collide: q (nq,) -> bool; q (n, nq) -> bool array (n,), checked
    /// 8 configurations at a time on the calling thread. Joint limits are not part of it.
    fn in_collision<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Py<PyAny>> {
        let w = &self.inner;
        let c = arrays::read_configurations(q, &w.world.model, "q")?;
        let data = c.data().to_vec();
        if c.rows.is_none() {
            let v = py.detach(|| w.in_collision_unchecked(&data, &mut SphereScratch::default()));
            return v.into_py_any(py);
        }
        let mut out = vec![false; data.len() / w.world.model.nq.max(1)];
        py.detach(|| w.in_collision_batch(&data, &mut out, &mut SphereScratch::default()));
        Ok(out.into_pyarray(py).into_any().unbind())
    }

    /// True when every state of the motion from `a` to `b` at `resolution` (the largest step of
    /// a coordinate, rad or m) is free by the spheres: the states checked 8 at a time, stopping
    /// at the first block with a collision.
    fn motion_free(&self, py: Python<'_>, a: Vec<f64>, b: Vec<f64>, resolution: f64) -> PyResult<bool> {
        let w = &self.inner;
        let m = &w.world.model;
        m.check_configuration(&a).map_err(|e| to_py_in("a", e))?;
        m.check_configuration(&b).map_err(|e| to_py_in("b", e))?;
        if !(resolution > 0.0 && resolution.is_finite()) {
            return Err(err(Kind::Generic, format!("resolution: must be positive and finite, got {resolution}")));
        }
        Ok(py.detach(|| w.motion_free(&a, &b, resolution, &mut SphereScratch::default())))
    }
}

/// Keep V-HACD's convex decompositions of meshes in folder `dir` (None: keep none):
/// `genplan_core::collision::set_decomposition_cache`.
#[pyfunction]
#[pyo3(signature = (dir))]
fn set_decomposition_cache(dir: Option<PathBuf>) {
    genplan_core::collision::set_decomposition_cache(dir);
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyCollisionWorld>()?;
    m.add("MESH_SHAPES", pyo3::types::PyTuple::new(m.py(), MeshShape::NAMES)?)?;
    m.add_function(wrap_pyfunction!(set_decomposition_cache, m)?)?;
    m.add_class::<PySphereChecker>()
}
