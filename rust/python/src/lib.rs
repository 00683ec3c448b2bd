//! `genplan._core`: the private native module. Thin wrappers around `genplan-core`.
//!
//! Inputs are float64 C-contiguous numpy arrays (the Python layer converts), except for the
//! per-configuration calls (forward kinematics, collision, distance), which read and check q
//! themselves ([`arrays`]: one call costs the Rust work plus a fixed overhead) and write batched
//! outputs in place; batched calls release the GIL and run in parallel, in chunks of ~50 ms
//! between which Ctrl-C is answered ([`for_chunks`]); empty batches give empty arrays; every
//! error is a Python exception, never a panic.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};
use numpy::ndarray::{Array, IxDyn};
use numpy::{IntoPyArray, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::IntoPyObjectExt;
use pyo3::types::{PyAnyMethods, PyDict};
use rayon::prelude::*;

use genplan_core::collision::{allowed, CollisionWorld};
use genplan_core::projection::{Projector, Settings, Term, TermKind};
use genplan_core::kinematics::{KinematicModel, ModelOptions};
use genplan_core::robot::{LockedJoints, RobotDescription};
use genplan_core::srdf::Srdf;
use genplan_core::urdf::Urdf;
use genplan_core::Scratch;

mod arrays;
mod settings;

mod control;
mod errors;
mod planning;

pub(crate) use errors::{err, to_py, to_py_in, Kind};
use settings::settings_class;

settings_class!(
    /// Damped Gauss-Newton settings (defaults: the GAN paper and its public code). Immutable:
    /// `replace(**changes)` makes a changed copy.
    PySolverSettings,
    "SolverSettings",
    Settings,
    |s: &Settings| s.validate().map_err(to_py),
    [max_iterations, mu, mu_bar, armijo_c1, backtrack, max_backtracks, clip_to_limits, active_set, secondary_backtracks, secondary_slack]
);

/// A batch of configurations: leading dims and the flat data, rows of `nq`.
struct Batch<'a> {
    lead: Vec<usize>,
    data: &'a [f64],
}

fn batch<'a>(arr: &'a PyReadonlyArrayDyn<'_, f64>, nq: usize, what: &str) -> PyResult<Batch<'a>> {
    let shape = arr.shape();
    if shape.is_empty() || shape[shape.len() - 1] != nq || shape.len() > 2 {
        return Err(err(Kind::Shape, format!(
            "{what}: expected shape ({nq},) or (n, {nq}), got {shape:?}"
        )));
    }
    let data = arr
        .as_slice()
        .map_err(|_| err(Kind::Shape, format!("{what}: array must be C-contiguous")))?;
    Ok(Batch {
        lead: shape[..shape.len() - 1].to_vec(),
        data,
    })
}

/// Check every row up front so that an error names the row and nothing runs on bad input.
fn check_rows(model: &KinematicModel, b: &Batch, what: &str) -> PyResult<()> {
    for (i, q) in b.data.chunks(model.nq.max(1)).enumerate() {
        model.check_configuration(q).map_err(|e| {
            if b.lead.is_empty() {
                to_py_in(what, e)
            } else {
                to_py_in(&format!("{what}[{i}]"), e)
            }
        })?;
    }
    Ok(())
}

/// Work per chunk of a batched call ([`for_chunks`]): long enough that what each chunk costs
/// beyond its rows (releasing and taking the GIL, a rayon fork-join, a signal check, caches
/// warmed again) stays within the noise of a throughput measurement (a few percent with 20 ms
/// chunks on the fastest rows, collision checks; none measurable with 50 ms), short enough that
/// Ctrl-C is answered within a tenth of a second.
const CHUNK_TARGET_S: f64 = 0.05;
/// Rows of the first chunk; the next ones are sized from the time the previous one took.
const FIRST_CHUNK: usize = 64;

/// Run `work` over the rows 0..n in consecutive ranges (chunks), each without the GIL, sized
/// to take about [`CHUNK_TARGET_S`] at the pace of the previous one, with Python's signal
/// handlers run between chunks: a long batch answers Ctrl-C (KeyboardInterrupt) within a
/// fraction of a second, as the planner does. Every batched call over rows goes through here.
pub(crate) fn for_chunks(py: Python<'_>, n: usize, mut work: impl FnMut(std::ops::Range<usize>) -> PyResult<()> + Send) -> PyResult<()> {
    let mut size = FIRST_CHUNK;
    let mut start = 0;
    while start < n {
        let end = n.min(start + size);
        let t = Instant::now();
        py.detach(|| work(start..end))?;
        if end < n {
            py.check_signals()?;
            // the next chunk: CHUNK_TARGET_S at this chunk's pace, at most 8x larger
            let per_row = t.elapsed().as_secs_f64() / (end - start) as f64;
            let want = if per_row > 0.0 { CHUNK_TARGET_S / per_row } else { f64::INFINITY };
            size = want.clamp(1.0, 8.0 * size as f64) as usize;
        }
        start = end;
    }
    Ok(())
}

/// `f(scratch, i)` for every row i of 0..n, in order, through [`for_chunks`]: each chunk on
/// rayon's threads when `parallel` (one scratch per thread).
pub(crate) fn chunked<T: Send, S>(
    py: Python<'_>,
    n: usize,
    parallel: bool,
    init: impl Fn() -> S + Sync + Send,
    f: impl Fn(&mut S, usize) -> T + Sync + Send,
) -> PyResult<Vec<T>> {
    let mut out = Vec::with_capacity(n);
    for_chunks(py, n, |rows| {
        if parallel && rows.len() > 1 {
            out.par_extend(rows.into_par_iter().map_init(&init, &f));
        } else {
            let mut s = init();
            out.extend(rows.map(|i| f(&mut s, i)));
        }
        Ok(())
    })?;
    Ok(out)
}

/// [`chunked`] over the rows of `data` (rows of `nq`), in parallel unless there is one row.
fn rows_map<T: Send>(py: Python<'_>, data: &[f64], nq: usize, f: impl Fn(&[f64], &mut Scratch) -> T + Sync + Send) -> PyResult<Vec<T>> {
    let nq = nq.max(1);
    chunked(py, data.len() / nq, true, Scratch::default, |s, i| f(&data[i * nq..(i + 1) * nq], s))
}

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

/// Forward kinematics of a URDF tree (q in Pinocchio's convention).
#[pyclass(name = "KinematicModel", module = "genplan._core", frozen)]
pub(crate) struct PyKinematicModel {
    pub(crate) inner: Arc<KinematicModel>,
}

#[pymethods]
impl PyKinematicModel {
    /// Load from a URDF file.
    #[staticmethod]
    #[pyo3(signature = (urdf_path, *, floating_base=false, locked_joints=None, joint_order=None))]
    fn from_urdf(
        urdf_path: PathBuf,
        floating_base: bool,
        locked_joints: Option<std::collections::HashMap<String, f64>>,
        joint_order: Option<Vec<String>>,
    ) -> PyResult<Self> {
        let urdf = Urdf::from_file(&urdf_path).map_err(to_py)?;
        let options = ModelOptions {
            floating_base,
            locked_joints: locked_joints.unwrap_or_default(),
            joint_order,
        };
        let inner = KinematicModel::from_urdf(&urdf, &options).map_err(to_py)?;
        Ok(Self { inner: Arc::new(inner) })
    }

    #[getter]
    fn nq(&self) -> usize {
        self.inner.nq
    }
    #[getter]
    fn nv(&self) -> usize {
        self.inner.nv
    }
    #[getter]
    fn floating_base(&self) -> bool {
        self.inner.floating_base
    }
    #[getter]
    fn link_names(&self) -> Vec<String> {
        self.inner.link_names.clone()
    }
    #[getter]
    fn active_joints(&self) -> Vec<String> {
        self.inner.active_joints.clone()
    }
    /// The locked joints and their values, sorted by name (the mimics of locked joints
    /// included, at the values they follow).
    #[getter]
    fn locked(&self) -> Vec<(String, f64)> {
        self.inner.locked.clone()
    }
    /// The mimic joints that follow an active joint: (joint, master, multiplier, offset).
    #[getter]
    fn mimic_joints(&self) -> Vec<(String, String, f64, f64)> {
        let m = &self.inner;
        m.joints
            .iter()
            .filter_map(|j| j.mimic.map(|f| (j.name.clone(), m.joints[f.joint].name.clone(), f.multiplier, f.offset)))
            .collect()
    }
    #[getter]
    fn lower<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        self.inner.lower.clone().into_pyarray(py)
    }
    #[getter]
    fn upper<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        self.inner.upper.clone().into_pyarray(py)
    }

    fn link_index(&self, name: &str) -> PyResult<usize> {
        self.inner.link_index(name).map_err(to_py)
    }

    /// World poses of links as 4x4 matrices: q of shape (nq,) or (n, nq) gives
    /// (L, 4, 4) or (n, L, 4, 4), L = len(links) or every link. q: a float array or a list,
    /// checked here ([`arrays::read_configurations`]); `dtype` float64 (default) or float32;
    /// `out`: an array of that shape to write into (returned). Rows of a batch are written in
    /// place from rayon's threads, without the GIL; one row is computed with it held.
    #[pyo3(signature = (q, links=None, dtype=None, out=None))]
    fn forward_kinematics<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        links: Option<&Bound<'py, PyAny>>,
        dtype: Option<&Bound<'py, PyAny>>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let m = &*self.inner;
        let c = arrays::read_configurations(q, m, "q")?;
        let idx = link_indices(m, links)?;
        let idx = idx.as_slice();
        let shape = [c.rows.unwrap_or(0), idx.len(), 4, 4];
        let shape = if c.rows.is_some() { &shape[..] } else { &shape[1..] };
        let output = arrays::Output::new(py, shape, arrays::out_type(dtype)?, out)?;
        let (mut data, one) = (c.data(), c.rows.is_none());
        let copy;
        if one && out.is_some_and(|o| !o.is_none()) {
            // a row read in place (arrays::Data::Row) is copied before `out` is written: the two
            // may share memory
            copy = data.to_vec();
            data = &copy;
        }
        output.write(|slot| match slot {
            arrays::Slot::F64(o) => fk_into(py, m, data, idx, o, one),
            arrays::Slot::F32(o) => fk_into(py, m, data, idx, o, one),
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "KinematicModel(nq={}, nv={}, links={}, floating_base={})",
            self.inner.nq,
            self.inner.nv,
            self.inner.n_links(),
            self.inner.floating_base
        )
    }
}

/// Link indices, without a heap allocation for a few (a one-configuration call's hand).
#[derive(Default)]
struct Links {
    few: [usize; 4],
    n: usize,
    many: Vec<usize>,
}

impl Links {
    fn push(&mut self, i: usize) {
        if self.many.is_empty() && self.n < self.few.len() {
            self.few[self.n] = i;
        } else {
            if self.many.is_empty() {
                self.many.extend_from_slice(&self.few[..self.n]);
            }
            self.many.push(i);
        }
        self.n += 1;
    }
    fn as_slice(&self) -> &[usize] {
        if self.many.is_empty() {
            &self.few[..self.n]
        } else {
            &self.many
        }
    }
}

/// Link indices of `links` (a sequence of link names; None: every link), UnknownNameError
/// listing the known links for a name that is not one.
fn link_indices(m: &KinematicModel, links: Option<&Bound<'_, PyAny>>) -> PyResult<Links> {
    use pyo3::types::PyString;
    let mut idx = Links::default();
    let Some(links) = links.filter(|l| !l.is_none()) else {
        (0..m.n_links()).for_each(|i| idx.push(i));
        return Ok(idx);
    };
    if links.is_instance_of::<PyString>() {
        return Err(pyo3::exceptions::PyTypeError::new_err("links: expected a list of link names, got a str"));
    }
    for name in links.try_iter()? {
        let name = name?;
        let name = name.cast::<PyString>().map_err(|_| {
            let ty = name.get_type().name().map(|n| n.to_string()).unwrap_or_default();
            pyo3::exceptions::PyTypeError::new_err(format!("links: expected link names (str), got {ty}"))
        })?;
        idx.push(m.link_index(name.to_str()?).map_err(to_py)?);
    }
    Ok(idx)
}

thread_local! {
    /// Link poses of a one-row call (no allocation per call).
    static POSES: std::cell::RefCell<Vec<Isometry3<f64>>> = const { std::cell::RefCell::new(Vec::new()) };
    /// Collision buffers of a one-row call.
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// A pose as a row-major 4x4 matrix into `o` (16 values).
#[inline]
fn write_pose<T: arrays::OutElement>(p: &Isometry3<f64>, o: &mut [T]) {
    let r = p.rotation.to_rotation_matrix();
    let t = &p.translation.vector;
    for i in 0..3 {
        for j in 0..3 {
            o[4 * i + j] = T::from_f64(r[(i, j)]);
        }
        o[4 * i + 3] = T::from_f64(t[i]);
    }
    o[12] = T::from_f64(0.0);
    o[13] = T::from_f64(0.0);
    o[14] = T::from_f64(0.0);
    o[15] = T::from_f64(1.0);
}

/// The poses of links `idx` at every row of `data` (checked) into `out` (rows of
/// `idx.len() * 16`): one row with the GIL held, a batch in place from rayon's threads through
/// [`for_chunks`].
fn fk_into<T: arrays::OutElement>(py: Python<'_>, m: &KinematicModel, data: &[f64], idx: &[usize], out: &mut [T], one: bool) -> PyResult<()> {
    let nq = m.nq.max(1);
    let stride = idx.len() * 16;
    let joints = m.joints_placing(idx); // only the joints above the links asked for
    let row = |q: &[f64], poses: &mut Vec<Isometry3<f64>>, o: &mut [T]| {
        m.forward_kinematics_prefix(q, poses, joints);
        for (k, &i) in idx.iter().enumerate() {
            write_pose(&poses[i], &mut o[k * 16..(k + 1) * 16]);
        }
    };
    if one {
        POSES.with_borrow_mut(|poses| row(data, poses, out));
        return Ok(());
    }
    if stride == 0 {
        return Ok(());
    }
    let n = data.len() / nq;
    let mut rest = out;
    for_chunks(py, n, |rows| {
        let (chunk, tail) = std::mem::take(&mut rest).split_at_mut(rows.len() * stride);
        rest = tail;
        let qs = &data[rows.start * nq..rows.end * nq];
        if rows.len() > 1 {
            chunk.par_chunks_mut(stride).zip(qs.par_chunks(nq)).for_each_init(Vec::new, |poses, (o, q)| row(q, poses, o));
        } else {
            POSES.with_borrow_mut(|poses| row(qs, poses, chunk));
        }
        Ok(())
    })
}

/// The robot's collision geometry and environment obstacles (parry).
#[pyclass(name = "CollisionWorld", module = "genplan._core")]
pub(crate) struct PyCollisionWorld {
    pub(crate) inner: CollisionWorld,
}

impl PyCollisionWorld {
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
    /// link pairs not to check (`disabled_pairs`, e.g. computed by `compute_disabled_pairs`).
    #[new]
    #[pyo3(signature = (model, collision_urdf, package_dirs=Vec::new(), srdf_path=None, disabled_pairs=None))]
    fn new(
        py: Python<'_>,
        model: &PyKinematicModel,
        collision_urdf: PathBuf,
        package_dirs: Vec<PathBuf>,
        srdf_path: Option<PathBuf>,
        disabled_pairs: Option<Vec<(String, String)>>,
    ) -> PyResult<Self> {
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
            .detach(|| CollisionWorld::from_urdf(model, &urdf, &package_dirs, srdf.as_ref()))
            .map_err(to_py)?;
        Ok(Self { inner })
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
        self.inner.check_self = value;
    }

    /// Add a box obstacle (half extents, centre, optional 3x3 rotation).
    #[pyo3(signature = (name, half_extents, center, rotation=None))]
    fn add_box(&mut self, name: &str, half_extents: [f64; 3], center: [f64; 3], rotation: Option<[[f64; 3]; 3]>) -> PyResult<()> {
        let pose = pose_from(center, rotation, &format!("box '{name}'"))?;
        self.inner.add_box(name, half_extents, pose).map_err(to_py)
    }
    fn add_sphere(&mut self, name: &str, radius: f64, center: [f64; 3]) -> PyResult<()> {
        self.inner.add_sphere(name, radius, center).map_err(to_py)
    }
    /// Add a cylinder obstacle whose axis is its local z (radius, half height, centre, optional
    /// 3x3 rotation).
    #[pyo3(signature = (name, radius, half_height, center, rotation=None))]
    fn add_cylinder(&mut self, name: &str, radius: f64, half_height: f64, center: [f64; 3], rotation: Option<[[f64; 3]; 3]>) -> PyResult<()> {
        let pose = pose_from(center, rotation, &format!("cylinder '{name}'"))?;
        self.inner.add_cylinder(name, radius, half_height, pose).map_err(to_py)
    }
    /// Add a capsule obstacle whose segment runs along its local z (radius, half length of the
    /// segment, centre, optional 3x3 rotation).
    #[pyo3(signature = (name, radius, half_length, center, rotation=None))]
    fn add_capsule(&mut self, name: &str, radius: f64, half_length: f64, center: [f64; 3], rotation: Option<[[f64; 3]; 3]>) -> PyResult<()> {
        let pose = pose_from(center, rotation, &format!("capsule '{name}'"))?;
        self.inner.add_capsule(name, radius, half_length, pose).map_err(to_py)
    }
    /// Add the convex hull of a mesh file (STL, OBJ, DAE) scaled per axis, at centre and
    /// optional 3x3 rotation. The file is read without the GIL.
    #[pyo3(signature = (name, path, scale, center, rotation=None))]
    fn add_mesh(
        &mut self,
        py: Python<'_>,
        name: &str,
        path: PathBuf,
        scale: [f64; 3],
        center: [f64; 3],
        rotation: Option<[[f64; 3]; 3]>,
    ) -> PyResult<()> {
        let pose = pose_from(center, rotation, &format!("mesh '{name}'"))?;
        let inner = &mut self.inner;
        py.detach(|| inner.add_mesh(name, &path, scale, pose)).map_err(to_py)
    }
    /// Add the half-space below the plane normal . x = offset.
    fn add_halfspace(&mut self, name: &str, normal: [f64; 3], offset: f64) -> PyResult<()> {
        self.inner.add_halfspace(name, normal, offset).map_err(to_py)
    }
    fn remove_obstacle(&mut self, name: &str) -> PyResult<()> {
        self.inner.remove_obstacle(name).map_err(to_py)
    }
    fn clear_obstacles(&mut self) {
        self.inner.clear_obstacles();
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

pub(crate) fn get<'py, T: pyo3::conversion::FromPyObjectOwned<'py>>(d: &Bound<'py, PyDict>, key: &str, what: &str) -> PyResult<T> {
    match d.get_item(key)? {
        Some(v) => v.extract::<T>().map_err(|e| err(Kind::Settings, format!("{what}: '{key}': {}", Into::<PyErr>::into(e)))),
        None => Err(err(Kind::Settings, format!("{what}: missing '{key}'"))),
    }
}

pub(crate) fn get_or<'py, T: pyo3::conversion::FromPyObjectOwned<'py>>(d: &Bound<'py, PyDict>, key: &str, default: T, what: &str) -> PyResult<T> {
    match d.get_item(key)? {
        Some(v) if !v.is_none() => v.extract::<T>().map_err(|e| err(Kind::Settings, format!("{what}: '{key}': {}", Into::<PyErr>::into(e)))),
        _ => Ok(default),
    }
}

/// A Python term behind the core's `projection::CustomTerm` (docs/TASKS.md, "Terms of your
/// own"): an object with `dim` (int), `residual(q)` ((n, nq) -> (n, dim)) and `jacobian(q)`
/// ((n, nq) -> (n, dim, nv)), and optionally `residual_and_jacobian(q)` returning both, called
/// where the solver needs both (unless the term dict's "combined" is false: what
/// `genplan.projection.CustomTerm` passes when a subclass keeps the default). The solver asks for one configuration at a time, so
/// each call passes a batch of one row (q of shape (1, nq)); each call takes the GIL for its own
/// duration only. Outputs of another shape raise ShapeError naming the term; non-finite ones are
/// refused by the core (NonFiniteError naming the term); an exception the object raises is
/// carried through the core's `TermFailure` and raised again unchanged ([`solve_error_to_py`]).
#[derive(Debug)]
struct PyCustomTerm {
    obj: Py<PyAny>,
    name: String,
    dim: usize,
    nq: usize,
    nv: usize,
    /// The object has `residual_and_jacobian`: one call where the solver needs both.
    combined: bool,
}

impl PyCustomTerm {
    /// `combined`: call `residual_and_jacobian` where both are needed (None: when the object has it).
    fn new(obj: &Bound<'_, PyAny>, name: &str, nq: usize, nv: usize, combined: Option<bool>) -> PyResult<Self> {
        let what = format!("custom term '{name}'");
        let dim = obj.getattr("dim").map_err(|e| err(Kind::Generic, format!("{what}: needs an attribute dim (int): {e}")))?;
        let dim: usize = dim
            .extract()
            .map_err(|_| err(Kind::Generic, format!("{what}: dim must be a positive int, got {}", dim.repr().map(|r| r.to_string()).unwrap_or_default())))?;
        let callable = |m: &str| obj.getattr(m).map(|a| a.is_callable()).unwrap_or(false);
        let combined = combined.unwrap_or(true) && callable("residual_and_jacobian");
        if !callable("residual") || !(combined || callable("jacobian")) {
            return Err(err(Kind::Generic, format!("{what}: needs methods residual(q) and jacobian(q) on batches (q of shape (n, nq))")));
        }
        Ok(PyCustomTerm { obj: obj.clone().unbind(), name: name.to_string(), dim, nq, nv, combined })
    }

    /// `value` as float64 numbers of shape `shape`, copied to `out` (row-major); `call` names the
    /// method in errors.
    fn copy_out(&self, py: Python<'_>, value: &Bound<'_, PyAny>, call: &str, shape: &[usize], out: &mut [f64]) -> PyResult<()> {
        let shown = arrays::shape_str; // as Python prints a shape: (2,) (1, 2)
        let bad = |got: String| {
            err(Kind::Shape, format!(
                "term '{}': {call} must return an array of shape {} for q of shape (1, {}), got {got}",
                self.name,
                shown(shape),
                self.nq
            ))
        };
        let arr = match value.extract::<PyReadonlyArrayDyn<'_, f64>>() {
            Ok(a) => a,
            Err(_) => py
                .import("numpy")?
                .call_method1("asarray", (value, "float64"))
                .and_then(|a| a.extract::<PyReadonlyArrayDyn<'_, f64>>())
                .map_err(|e| bad(format!("{} ({e})", value.get_type().name().map(|n| n.to_string()).unwrap_or_default())))?,
        };
        if arr.shape() != shape {
            return Err(bad(format!("shape {}", shown(arr.shape()))));
        }
        for (o, v) in out.iter_mut().zip(arr.as_array().iter()) {
            *o = *v;
        }
        Ok(())
    }
}

impl genplan_core::projection::CustomTerm for PyCustomTerm {
    fn dim(&self) -> usize {
        self.dim
    }

    fn evaluate(&self, q: &[f64], residual: &mut [f64], jacobian: Option<&mut [f64]>) -> Result<(), genplan_core::projection::TermError> {
        Python::attach(|py| -> PyResult<()> {
            let obj = self.obj.bind(py);
            let qa = Array::from_shape_vec(IxDyn(&[1, self.nq]), q.to_vec())
                .map_err(|e| PyValueError::new_err(e.to_string()))?
                .into_pyarray(py);
            let (d, nv) = (self.dim, self.nv);
            match jacobian {
                None => {
                    let r = obj.call_method1("residual", (qa,))?;
                    self.copy_out(py, &r, "residual(q)", &[1, d], residual)
                }
                Some(jac) => {
                    let (r, j) = if self.combined {
                        let both = obj.call_method1("residual_and_jacobian", (qa,))?;
                        let pair: (Bound<'_, PyAny>, Bound<'_, PyAny>) = both.extract().map_err(|_| {
                            err(Kind::Shape, format!("term '{}': residual_and_jacobian(q) must return a pair (residual, jacobian)", self.name))
                        })?;
                        pair
                    } else {
                        (obj.call_method1("residual", (qa.clone(),))?, obj.call_method1("jacobian", (qa,))?)
                    };
                    let what = if self.combined { ["residual_and_jacobian(q)[0]", "residual_and_jacobian(q)[1]"] } else { ["residual(q)", "jacobian(q)"] };
                    self.copy_out(py, &r, what[0], &[1, d], residual)?;
                    self.copy_out(py, &j, what[1], &[1, d, nv], jac)
                }
            }
        })
        .map_err(|e| Box::new(e) as genplan_core::projection::TermError)
    }
}

/// The projector holds a custom term (in these bindings, a Python one: [`PyCustomTerm`]).
fn has_python_terms(p: &Projector) -> bool {
    p.has_custom_terms()
}

/// The Python error of a failed solve: a custom term's own exception unchanged, a core error as
/// its `genplan.errors` class.
fn solve_error_to_py(e: genplan_core::projection::SolveError) -> PyErr {
    use genplan_core::projection::{SolveError, TermFailure};
    match e {
        SolveError::Input(e) => to_py(e),
        SolveError::Term(TermFailure { term, source }) => match source.downcast::<PyErr>() {
            Ok(py_err) => *py_err,
            Err(source) => to_py(TermFailure { term, source }.into_error()),
        },
    }
}

fn term_from_dict(model: &genplan_core::KinematicModel, d: &Bound<'_, PyDict>) -> PyResult<Term> {
    let kind_name: String = get(d, "type", "term")?;
    let name: String = get_or(d, "name", kind_name.clone(), "term")?;
    let what = format!("term '{name}'");
    let link = |d: &Bound<'_, PyDict>| -> PyResult<usize> {
        let l: String = get(d, "link", &what)?;
        model.link_index(&l).map_err(to_py)
    };
    let mat3 = |m: [[f64; 3]; 3]| Matrix3::from_fn(|i, j| m[i][j]);
    let kind = match kind_name.as_str() {
        "frame_pose" => {
            let t: [[f64; 4]; 4] = get(d, "target", &what)?;
            let rot = Rotation3::from_matrix_unchecked(Matrix3::from_fn(|i, j| t[i][j]));
            TermKind::FramePose {
                link: link(d)?,
                target: Isometry3::from_parts(Translation3::new(t[0][3], t[1][3], t[2][3]), UnitQuaternion::from_rotation_matrix(&rot)),
                mask: get_or(d, "mask", [1.0; 6], &what)?,
            }
        }
        "frame_position" => TermKind::FramePosition {
            link: link(d)?,
            target: nalgebra::Vector3::from(get::<[f64; 3]>(d, "target", &what)?),
            mask: get_or(d, "mask", [1.0; 3], &what)?,
        },
        "frame_orientation" => TermKind::FrameOrientation {
            link: link(d)?,
            target: mat3(get_or(d, "target", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], &what)?),
            offset: mat3(get_or(d, "offset", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], &what)?),
            mask: get_or(d, "mask", [1.0; 3], &what)?,
        },
        "joint_limits" => TermKind::JointLimits { margin: get_or(d, "margin", 1e-3, &what)? },
        "com_box" => TermKind::ComBox {
            lower: nalgebra::Vector3::from(get::<[f64; 3]>(d, "lower", &what)?),
            upper: nalgebra::Vector3::from(get::<[f64; 3]>(d, "upper", &what)?),
            margin: get_or(d, "margin", 1e-3, &what)?,
        },
        "posture" => TermKind::Posture {
            q_nom: get_or(d, "q_nom", None::<Vec<f64>>, &what)?,
            weights: get_or(d, "weights", vec![1.0; model.nv], &what)?,
            overrides: get_or(d, "overrides", Vec::<(usize, f64)>::new(), &what)?,
        },
        "custom" => {
            let obj = d.get_item("term")?.ok_or_else(|| err(Kind::Settings, format!("{what}: missing 'term' (the Python object)")))?;
            let combined: Option<bool> = get_or(d, "combined", None, &what)?;
            TermKind::Custom(Arc::new(PyCustomTerm::new(&obj, &name, model.nq, model.nv, combined)?))
        }
        other => {
            return Err(err(Kind::UnknownName, format!(
                "unknown term type '{other}' (known: frame_pose, frame_position, frame_orientation, joint_limits, com_box, posture, custom)"
            )))
        }
    };
    Ok(Term {
        name,
        kind,
        weight: get_or(d, "weight", 1.0, &what)?,
        tolerance: get_or(d, "tolerance", 1e-3, &what)?,
    })
}

/// Native damped Gauss-Newton projector (see genplan.projection for the Python front end).
#[pyclass(name = "Projector", module = "genplan._core", frozen)]
pub(crate) struct PyProjector {
    pub(crate) inner: Projector,
}

#[pymethods]
impl PyProjector {
    #[new]
    #[pyo3(signature = (model, primary, secondary=Vec::new(), settings=None))]
    fn new(
        model: &PyKinematicModel,
        primary: Vec<Bound<'_, PyDict>>,
        secondary: Vec<Bound<'_, PyDict>>,
        settings: Option<PyRef<'_, PySolverSettings>>,
    ) -> PyResult<Self> {
        let m = &*model.inner;
        let primary = primary.iter().map(|d| term_from_dict(m, d)).collect::<PyResult<Vec<_>>>()?;
        let secondary = secondary.iter().map(|d| term_from_dict(m, d)).collect::<PyResult<Vec<_>>>()?;
        let st = settings.map(|s| s.inner.clone()).unwrap_or_default();
        let inner = Projector::new(model.inner.clone(), primary, secondary, st).map_err(to_py)?;
        Ok(Self { inner })
    }

    #[getter]
    fn term_names(&self) -> Vec<String> {
        self.inner.primary.iter().map(|t| t.name.clone()).collect()
    }

    /// Solve from each row of q0 ((n, nq)); q_nom likewise or None. Returns
    /// (q (n, nq), success (n,), iterations (n,), residuals (n, terms), time_s (n,)).
    /// The rows run in parallel (GIL released) when `parallel`, unless a term is a Python one
    /// (then one after the other: see the comment in the body).
    #[pyo3(signature = (q0, q_nom=None, parallel=true, target_term=None, targets=None))]
    #[allow(clippy::type_complexity, clippy::too_many_arguments)]
    fn solve_batch<'py>(
        &self,
        py: Python<'py>,
        q0: PyReadonlyArrayDyn<'py, f64>,
        q_nom: Option<PyReadonlyArrayDyn<'py, f64>>,
        parallel: bool,
        target_term: Option<String>,
        targets: Option<PyReadonlyArrayDyn<'py, f64>>,
    ) -> PyResult<(
        Bound<'py, numpy::PyArrayDyn<f64>>,
        Bound<'py, numpy::PyArray1<bool>>,
        Bound<'py, numpy::PyArray1<i64>>,
        Bound<'py, numpy::PyArrayDyn<f64>>,
        Bound<'py, numpy::PyArray1<f64>>,
    )> {
        let m = &*self.inner.model;
        let b = batch(&q0, m.nq, "q0")?;
        check_rows(m, &b, "q0")?;
        let noms = match &q_nom {
            Some(a) => {
                let nb = batch(a, m.nq, "q_nom")?;
                if nb.lead != b.lead {
                    return Err(err(Kind::Shape, format!("q_nom: expected {} rows like q0, got {:?}", b.lead.first().copied().unwrap_or(1), nb.lead)));
                }
                check_rows(m, &nb, "q_nom")?; // configurations like q0 (finite, joint values bounded)
                Some(nb.data)
            }
            None => None,
        };
        let nq = m.nq;
        let n = b.data.len() / nq.max(1);
        let data = b.data;
        let solver = &self.inner;
        // per-row targets of one primary term: checked up front (the term, the numbers per row,
        // finite values), so that errors surface before any work; each worker retargets its own
        // copy of the solver row by row
        let retarget: Option<(usize, &[f64], usize)> = match (&target_term, &targets) {
            (None, None) => None,
            (Some(name), Some(arr)) => {
                let ti = solver.primary.iter().position(|t| &t.name == name).ok_or_else(|| {
                    err(Kind::UnknownName, format!("unknown target term '{name}' (primary terms: {:?})", solver.primary.iter().map(|t| &t.name).collect::<Vec<_>>()))
                })?;
                let tdata = arr.as_slice().map_err(|_| err(Kind::Shape, "targets: array must be C-contiguous"))?;
                if arr.shape().first().copied() != Some(n) {
                    return Err(err(Kind::Shape, format!("targets: expected {n} rows, got shape {:?}", arr.shape())));
                }
                let k: usize = arr.shape()[1..].iter().product();
                // every row as the solver takes it (length, finite, bounded, a rotation), before any work
                let mut probe = solver.clone();
                for i in 0..n {
                    probe.retarget(ti, &tdata[i * k..(i + 1) * k]).map_err(|e| to_py_in(&format!("targets[{i}]"), e))?;
                }
                Some((ti, tdata, k))
            }
            _ => return Err(err(Kind::Generic, "give both target_term and targets, or neither")),
        };
        // with a Python term the rows run one after the other: its calls serialise on the GIL, and
        // threads contending for it made batches slower, not faster (2 cores: 200 Panda rows with
        // a numpy-only term 0.12 s sequential vs 0.46 s parallel; with a Pinocchio-based term
        // 1.3-2.1 s vs 2.5-2.6 s). One retargeted copy of the solver per worker (not per row).
        // A custom term's failure
        // stops the batch: the rows after it are skipped (None) and its error is raised
        let failed = std::sync::atomic::AtomicBool::new(false);
        let parallel = parallel && !has_python_terms(solver);
        let outs = chunked(py, n, parallel, || retarget.map(|_| solver.clone()), |own, i| {
            use genplan_core::projection::SolveError;
            if failed.load(std::sync::atomic::Ordering::Relaxed) {
                return None;
            }
            let (q, nom) = (&data[i * nq..(i + 1) * nq], noms.map(|d| &d[i * nq..(i + 1) * nq]));
            let out = match (own, retarget) {
                (Some(p), Some((ti, t, k))) => p
                    .retarget(ti, &t[i * k..(i + 1) * k])
                    .map_err(SolveError::from)
                    .and_then(|()| p.try_solve_unchecked(q, nom).map_err(SolveError::from)),
                _ => solver.try_solve_unchecked(q, nom).map_err(SolveError::from),
            };
            if out.is_err() {
                failed.store(true, std::sync::atomic::Ordering::Relaxed);
            }
            Some(out)
        })?;
        if let Some(e) = outs.iter().position(|o| matches!(o, Some(Err(_)))) {
            let Some(Some(Err(e))) = outs.into_iter().nth(e) else { unreachable!("position found an error") };
            return Err(solve_error_to_py(e));
        }
        let outs: Vec<genplan_core::projection::Outcome> = outs.into_iter().flatten().flatten().collect();
        let nt = solver.primary.len();
        let q = Array::from_shape_vec(IxDyn(&[n, nq]), outs.iter().flat_map(|o| o.q.iter().copied()).collect())
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let res = Array::from_shape_vec(IxDyn(&[n, nt]), outs.iter().flat_map(|o| o.residuals.iter().copied()).collect())
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok((
            q.into_pyarray(py),
            outs.iter().map(|o| o.success).collect::<Vec<_>>().into_pyarray(py),
            outs.iter().map(|o| o.iterations as i64).collect::<Vec<_>>().into_pyarray(py),
            res.into_pyarray(py),
            outs.iter().map(|o| o.time_s).collect::<Vec<_>>().into_pyarray(py),
        ))
    }

    /// The primary terms' weighted residuals stacked, at each row of q ((n, nq)): r (n, m) and,
    /// when `jacobian`, their Jacobians J (n, m, nv) in the tangent space (a Posture term's
    /// nominal is the row itself). Rows run in parallel, GIL released (one after the other with a
    /// Python term, as in `solve_batch`).
    #[pyo3(signature = (q, jacobian=true))]
    #[allow(clippy::type_complexity)]
    fn primary_residuals<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArrayDyn<'py, f64>,
        jacobian: bool,
    ) -> PyResult<(Bound<'py, numpy::PyArrayDyn<f64>>, Option<Bound<'py, numpy::PyArrayDyn<f64>>>)> {
        let m = &*self.inner.model;
        let b = batch(&q, m.nq, "q")?;
        check_rows(m, &b, "q")?;
        let (nq, nv, dim) = (m.nq, m.nv, self.inner.primary_dim());
        let n = b.data.len() / nq.max(1);
        let data = b.data;
        let solver = &self.inner;
        let parallel = !has_python_terms(solver); // as in solve_batch
        let outs = chunked(py, n, parallel, || (), |_, i| solver.try_primary_residuals(&data[i * nq..(i + 1) * nq], jacobian))?;
        let outs = outs.into_iter().collect::<Result<Vec<_>, _>>().map_err(solve_error_to_py)?;
        let r = Array::from_shape_vec(IxDyn(&[n, dim]), outs.iter().flat_map(|(r, _)| r.iter().copied()).collect())
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let j = if jacobian {
            let flat: Vec<f64> = outs
                .iter()
                .flat_map(|(_, j)| {
                    let j = j.as_ref().expect("jacobian computed");
                    (0..dim).flat_map(move |a| (0..nv).map(move |c| j[(a, c)]))
                })
                .collect();
            Some(Array::from_shape_vec(IxDyn(&[n, dim, nv]), flat).map_err(|e| PyValueError::new_err(e.to_string()))?.into_pyarray(py))
        } else {
            None
        };
        Ok((r.into_pyarray(py), j))
    }

    /// Frame Jacobian in the frame's own axes (6 x nv) at q: for cross-checks.
    fn frame_jacobian_local<'py>(&self, py: Python<'py>, q: Vec<f64>, link: &str) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
        let m = &*self.inner.model;
        let li = m.link_index(link).map_err(to_py)?;
        let mut poses = Vec::new();
        m.forward_kinematics(&q, &mut poses).map_err(to_py)?;
        let mut j = nalgebra::DMatrix::zeros(6, m.nv);
        m.frame_jacobian_local(&poses, li, &mut j);
        dmatrix_to_py(py, &j)
    }

    /// Centre of mass (3,) and its Jacobian (3 x nv) at q: for cross-checks.
    fn center_of_mass<'py>(&self, py: Python<'py>, q: Vec<f64>) -> PyResult<(Vec<f64>, Bound<'py, numpy::PyArrayDyn<f64>>)> {
        let m = &*self.inner.model;
        let mut poses = Vec::new();
        m.forward_kinematics(&q, &mut poses).map_err(to_py)?;
        let mut j = nalgebra::DMatrix::zeros(3, m.nv);
        let c = m.center_of_mass(&poses, Some(&mut j));
        Ok((vec![c.x, c.y, c.z], dmatrix_to_py(py, &j)?))
    }
}

fn dmatrix_to_py<'py>(py: Python<'py>, j: &nalgebra::DMatrix<f64>) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
    let (r, c) = j.shape();
    let data: Vec<f64> = (0..r).flat_map(|i| (0..c).map(move |k| j[(i, k)])).collect();
    Ok(Array::from_shape_vec(IxDyn(&[r, c]), data)
        .map_err(|e| PyValueError::new_err(e.to_string()))?
        .into_pyarray(py))
}

/// A Python value (str, bool, int, float, list, dict) as a TOML value, for
/// [`RobotDescription::from_table`]; `key` names it in errors.
fn toml_value(v: &Bound<'_, PyAny>, key: &str) -> PyResult<toml::Value> {
    use pyo3::types::{PyBool, PyFloat, PyInt, PyList, PyString, PyTuple};
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return Ok(toml::Value::Integer(v.extract()?));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        return Ok(toml::Value::Table(toml_table(d, key)?));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let items: Vec<Bound<'_, PyAny>> = v.try_iter()?.collect::<PyResult<_>>()?;
        return items.iter().map(|x| toml_value(x, key)).collect::<PyResult<Vec<_>>>().map(toml::Value::Array);
    }
    if let Ok(p) = v.extract::<PathBuf>() {
        return Ok(toml::Value::String(p.to_string_lossy().into_owned()));
    }
    Err(pyo3::exceptions::PyTypeError::new_err(format!(
        "{key}: expected a string, number, boolean, list or dict, got {}",
        v.get_type().name()?
    )))
}

fn toml_table(d: &Bound<'_, PyDict>, key: &str) -> PyResult<toml::Table> {
    let mut t = toml::Table::new();
    for (k, v) in d.iter() {
        let k: String = k.extract().map_err(|_| {
            pyo3::exceptions::PyTypeError::new_err(format!("{key}: keys must be strings"))
        })?;
        if v.is_none() {
            continue;
        }
        let sub = if key.is_empty() { k.clone() } else { format!("{key}.{k}") };
        t.insert(k, toml_value(&v, &sub)?);
    }
    Ok(t)
}

fn description_to_py<'py>(py: Python<'py>, r: &RobotDescription) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("name", &r.name)?;
    d.set_item("urdf", &r.urdf)?;
    d.set_item("collision_urdf", &r.collision_urdf)?;
    d.set_item("srdf", &r.srdf)?;
    d.set_item("package_dirs", &r.package_dirs)?;
    d.set_item("floating_base", r.floating_base)?;
    match &r.locked_joints {
        LockedJoints::FromReference(names) => d.set_item("locked_joints", names)?,
        LockedJoints::Values(v) => d.set_item("locked_joints", v.iter().cloned().collect::<std::collections::BTreeMap<_, _>>())?,
    }
    d.set_item("reference_state", &r.reference_state)?;
    if r.merge_computed_pairs {
        // only when asked for: a description without it is the one it was before the key existed
        // (data sets and caches identify a robot by its description)
        d.set_item("merge_computed_pairs", true)?;
    }
    let frames = PyDict::new(py);
    for (role, link) in &r.frames {
        frames.set_item(role, link)?;
    }
    d.set_item("frames", frames)?;
    d.set_item("source", &r.source)?;
    Ok(d)
}

/// A description dict (as [`description_to_py`] makes it: absolute paths) back to Rust.
pub(crate) fn description_from_py(d: &Bound<'_, PyDict>) -> PyResult<RobotDescription> {
    let fields = d.copy()?;
    let source: Option<PathBuf> = match fields.get_item("source")? {
        Some(v) if !v.is_none() => Some(v.extract()?),
        _ => None,
    };
    if fields.contains("source")? {
        fields.del_item("source")?;
    }
    let name: String = fields.get_item("name")?.map(|v| v.extract()).transpose()?.unwrap_or_default();
    let table = toml_table(&fields, "")?;
    let origin = source.as_ref().map(|p| format!("robot file {}", p.display())).unwrap_or_else(|| format!("robot '{name}'"));
    let mut r = RobotDescription::from_table(&table, None, &[], &origin, &name).map_err(to_py)?;
    r.source = source;
    Ok(r)
}

/// Read a robot file (TOML): its description as a dict with absolute paths
/// (`genplan_core::robot::RobotDescription`). `package_dirs` are searched after the file's own.
#[pyfunction]
fn read_robot_file<'py>(py: Python<'py>, path: PathBuf, package_dirs: Vec<PathBuf>) -> PyResult<Bound<'py, PyDict>> {
    let r = RobotDescription::from_file(&path, &package_dirs).map_err(to_py)?;
    description_to_py(py, &r)
}

/// A robot description from the keys of a robot file given as a dict (relative paths against
/// `base_dir`); `origin` names the input in errors, `default_name` is used without `name`.
#[pyfunction]
#[pyo3(signature = (fields, package_dirs, origin, default_name, base_dir=None))]
fn robot_description<'py>(
    py: Python<'py>,
    fields: &Bound<'py, PyDict>,
    package_dirs: Vec<PathBuf>,
    origin: &str,
    default_name: &str,
    base_dir: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let table = toml_table(fields, "")?;
    let r = RobotDescription::from_table(&table, base_dir.as_deref(), &package_dirs, origin, default_name).map_err(to_py)?;
    description_to_py(py, &r)
}

/// What [`read_robot`] gives: (model, default configuration, locked values, warnings).
type RobotRead<'py> = (PyKinematicModel, Bound<'py, numpy::PyArray1<f64>>, Bound<'py, PyDict>, Vec<String>);

/// Read a robot description's files and check it against them
/// (`genplan_core::robot::RobotDescription::read`), before Pinocchio reads them: the kinematic
/// model (active joints in Pinocchio's order), the default configuration (nq), the locked
/// values (the mimics of locked joints included) and the warnings (messages). Every error
/// names the file and the name or value at fault.
#[pyfunction]
fn read_robot<'py>(py: Python<'py>, description: &Bound<'py, PyDict>) -> PyResult<RobotRead<'py>> {
    let r = description_from_py(description)?;
    let files = py.detach(|| r.read()).map_err(to_py)?;
    let locked = PyDict::new(py);
    for (name, value) in &files.model.locked {
        locked.set_item(name, value)?;
    }
    Ok((PyKinematicModel { inner: files.model }, files.q_default.into_pyarray(py), locked, files.warnings))
}

/// The `<disable_collisions>` link pairs of an SRDF file.
/// `s'^2` at each grid point of the time-optimal parameterisation from rest to rest
/// (genplan_core::timing::time_optimal: TOPP-RA under joint velocity and acceleration box
/// limits); `d1`, `d2`: (N + 1, n) C-contiguous float64 arrays of q', q'' at the grid points.
/// The GIL is released while it runs.
#[pyfunction]
fn time_optimal<'py>(
    py: Python<'py>,
    grid: Vec<f64>,
    d1: PyReadonlyArrayDyn<'py, f64>,
    d2: PyReadonlyArrayDyn<'py, f64>,
    vlim: Vec<f64>,
    alim: Vec<f64>,
) -> PyResult<Bound<'py, numpy::PyArray1<f64>>> {
    let (a, b) = (d1.as_slice()?, d2.as_slice()?);
    let x = py.detach(|| genplan_core::timing::time_optimal(&grid, a, b, &vlim, &alim)).map_err(to_py)?;
    Ok(x.into_pyarray(py))
}

type Samples<'py> = (
    Bound<'py, numpy::PyArray1<f64>>,
    Bound<'py, numpy::PyArrayDyn<f64>>,
    Bound<'py, numpy::PyArrayDyn<f64>>,
    Bound<'py, numpy::PyArrayDyn<f64>>,
);

/// The samples `(t, q, qd, qdd)` of a timed cubic spline at `rate` Hz, stretched by `scale`
/// (genplan_core::timing::sample): `c` the (m, 4, n) C-contiguous coefficients (scipy's
/// `CubicSpline.c` with its first two axes swapped), `x` its m + 1 breakpoints; `grid`, `knots`,
/// `sdot` at the N + 1 grid points, `sdd` on the N intervals. The GIL is released while it runs.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn sample_timed_spline<'py>(
    py: Python<'py>,
    x: Vec<f64>,
    c: PyReadonlyArrayDyn<'py, f64>,
    grid: Vec<f64>,
    knots: Vec<f64>,
    sdot: Vec<f64>,
    sdd: Vec<f64>,
    rate: f64,
    scale: f64,
) -> PyResult<Samples<'py>> {
    let shape = c.shape().to_vec();
    if shape.len() != 3 || shape[1] != 4 {
        return Err(err(Kind::Shape, format!("c: expected shape (m, 4, n), got {shape:?}")));
    }
    let n = shape[2];
    let cs = c.as_slice()?;
    let p = genplan_core::timing::TimedSpline { x: &x, c: cs, grid: &grid, knots: &knots, sdot: &sdot, sdd: &sdd };
    let (t, q, qd, qdd) = py.detach(|| genplan_core::timing::sample(&p, n, rate, scale)).map_err(to_py)?;
    let rows = t.len();
    let arr = |v: Vec<f64>| -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
        Ok(Array::from_shape_vec(IxDyn(&[rows, n]), v).map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?.into_pyarray(py))
    };
    Ok((t.into_pyarray(py), arr(q)?, arr(qd)?, arr(qdd)?))
}

#[pyfunction]
fn srdf_disabled_pairs(path: PathBuf) -> PyResult<Vec<(String, String)>> {
    Ok(Srdf::from_file(&path).map_err(to_py)?.disabled_pairs)
}

/// SRDF text holding `pairs` (link_a, link_b, reason) as `<disable_collisions>` and, if given,
/// the group state "default" (joint name, value).
#[pyfunction]
#[pyo3(signature = (robot_name, pairs, default_state=None))]
fn disabled_pairs_srdf(
    robot_name: &str,
    pairs: Vec<(String, String, String)>,
    default_state: Option<Vec<(String, f64)>>,
) -> PyResult<String> {
    let pairs = pairs
        .into_iter()
        .map(|(a, b, r)| {
            let reason = allowed::Reason::parse(&r).ok_or_else(|| {
                let known: Vec<&str> = allowed::Reason::ALL.iter().map(|r| r.as_str()).collect();
                err(Kind::UnknownName, format!("pairs: unknown reason '{r}' (known: {})", known.join(", ")))
            })?;
            Ok(allowed::DisabledPair { a, b, reason })
        })
        .collect::<PyResult<Vec<_>>>()?;
    Ok(allowed::srdf_text(robot_name, &pairs, default_state.as_deref()))
}

/// Load a robot file with the Rust core alone: (KinematicModel, CollisionWorld) (for tests).
#[pyfunction]
fn load_robot(py: Python<'_>, path: PathBuf, package_dirs: Vec<PathBuf>) -> PyResult<(PyKinematicModel, PyCollisionWorld)> {
    let (model, world) = py
        .detach(|| RobotDescription::from_file(&path, &package_dirs).and_then(|r| r.load()))
        .map_err(to_py)?;
    Ok((PyKinematicModel { inner: model }, PyCollisionWorld { inner: world }))
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    let crates: Vec<(String, String)> = env!("GENPLAN_CRATE_VERSIONS")
        .split(',')
        .filter_map(|kv| kv.split_once('=').map(|(k, v)| (k.to_string(), v.to_string())))
        .collect();
    m.add("CRATE_VERSIONS", crates.into_py_dict_compat(m.py())?)?;
    m.add_class::<PyKinematicModel>()?;
    m.add_class::<PyCollisionWorld>()?;
    m.add_class::<PyProjector>()?;
    m.add_class::<PySolverSettings>()?;
    m.add_function(wrap_pyfunction!(read_robot_file, m)?)?;
    m.add_function(wrap_pyfunction!(robot_description, m)?)?;
    m.add_function(wrap_pyfunction!(read_robot, m)?)?;
    m.add_function(wrap_pyfunction!(load_robot, m)?)?;
    m.add_function(wrap_pyfunction!(srdf_disabled_pairs, m)?)?;
    m.add_function(wrap_pyfunction!(time_optimal, m)?)?;
    m.add_function(wrap_pyfunction!(sample_timed_spline, m)?)?;
    m.add_function(wrap_pyfunction!(disabled_pairs_srdf, m)?)?;
    planning::register(m)?;
    control::register(m)?;
    Ok(())
}

trait IntoPyDictCompat {
    fn into_py_dict_compat<'py>(self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>>;
}

impl IntoPyDictCompat for Vec<(String, String)> {
    fn into_py_dict_compat<'py>(self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (k, v) in self {
            d.set_item(k, v)?;
        }
        Ok(d)
    }
}
