//! `KinematicModel`: the core's forward kinematics of a URDF tree (`genplan_core::kinematics`),
//! its link poses for one configuration or a batch, written in place into the returned array.

use std::path::PathBuf;
use std::sync::Arc;

use nalgebra::Isometry3;
use numpy::IntoPyArray;
use pyo3::prelude::*;
use rayon::prelude::*;

use genplan_core::kinematics::{KinematicModel, ModelOptions};
use genplan_core::urdf::Urdf;

use crate::arrays;
use crate::batch::for_chunks;
use crate::errors::to_py;

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

/// Register the kinematics class on `genplan._core`.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyKinematicModel>()
}
