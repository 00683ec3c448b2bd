//! Jerk-limited timing of a path's straight segments, stopping at each state
//! (`genplan_core::jerk`).

use numpy::ndarray::{Array, IxDyn};
use numpy::{IntoPyArray, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors::{err, to_py, Kind};

type Samples<'py> = (
    Bound<'py, numpy::PyArray1<f64>>,
    Bound<'py, numpy::PyArrayDyn<f64>>,
    Bound<'py, numpy::PyArrayDyn<f64>>,
    Bound<'py, numpy::PyArrayDyn<f64>>,
    Bound<'py, numpy::PyArrayDyn<f64>>,
);

/// A piecewise-linear path timed with jerk limits (genplan_core::jerk::JerkPath): `states`
/// ((m, n) C-contiguous float64, m >= 2, consecutive rows distinct), each segment a
/// phase-synchronised rest-to-rest S-curve under the joint limits `vlim`, `alim`, `jlim`
/// (n each), stopping at every state.
#[pyclass(name = "JerkPath", module = "genplan._core", frozen)]
pub(crate) struct PyJerkPath {
    inner: genplan_core::jerk::JerkPath,
}

#[pymethods]
impl PyJerkPath {
    #[new]
    fn new(states: PyReadonlyArrayDyn<'_, f64>, vlim: Vec<f64>, alim: Vec<f64>, jlim: Vec<f64>) -> PyResult<Self> {
        let shape = states.shape().to_vec();
        if shape.len() != 2 || shape[1] != vlim.len() {
            return Err(err(
                Kind::Shape,
                format!("states: expected shape (m, {}) (a column per limit), got {shape:?}", vlim.len()),
            ));
        }
        let inner = genplan_core::jerk::JerkPath::new(states.as_slice()?, &vlim, &alim, &jlim).map_err(to_py)?;
        Ok(PyJerkPath { inner })
    }

    /// Its duration, seconds.
    #[getter]
    fn duration(&self) -> f64 {
        self.inner.duration()
    }

    /// The time each state is reached (m, from 0).
    #[getter]
    fn times<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        self.inner.times.clone().into_pyarray(py)
    }

    /// The samples `(t, q, qd, qdd, qddd)` at `rate` Hz (genplan_core::jerk::JerkPath::sample:
    /// refused before allocating beyond `MAX_TRAJECTORY_BYTES`). The GIL is released while it
    /// runs.
    fn sample<'py>(&self, py: Python<'py>, rate: f64) -> PyResult<Samples<'py>> {
        let n = self.inner.n;
        let (t, q, qd, qdd, qddd) = py.detach(|| self.inner.sample(rate)).map_err(to_py)?;
        let rows = t.len();
        let arr = |v: Vec<f64>| -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
            Ok(Array::from_shape_vec(IxDyn(&[rows, n]), v).map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?.into_pyarray(py))
        };
        Ok((t.into_pyarray(py), arr(q)?, arr(qd)?, arr(qdd)?, arr(qddd)?))
    }
}

/// Register [`PyJerkPath`] on `genplan._core`.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyJerkPath>()
}
