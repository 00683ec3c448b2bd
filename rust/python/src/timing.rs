//! Time-optimal parameterisation of a path and the samples of a timed spline
//! (`genplan_core::timing`).

use numpy::ndarray::{Array, IxDyn};
use numpy::{IntoPyArray, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors::{err, to_py, Kind};

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

/// A path timed by TOPP-RA from rest to rest (genplan_core::timing::TimedPath): the not-a-knot
/// cubic spline through `states` ((m, n) C-contiguous float64, distinct consecutive rows) at the
/// path parameters `s` (m, increasing), TOPP-RA's grid on it (at most `grid_base` points evenly
/// over the states, plus the states whose curvature could call for more than `grid_critical` of
/// an acceleration limit) and the time-optimal speed profile under the joint limits `vlim` and
/// `alim` (n each). The GIL is released while it is computed.
#[pyclass(name = "TimedPath", module = "genplan._core", frozen)]
pub(crate) struct PyTimedPath {
    inner: genplan_core::timing::TimedPath,
}

#[pymethods]
impl PyTimedPath {
    #[new]
    fn new(
        py: Python<'_>,
        s: Vec<f64>,
        states: PyReadonlyArrayDyn<'_, f64>,
        vlim: Vec<f64>,
        alim: Vec<f64>,
        grid_base: usize,
        grid_critical: f64,
    ) -> PyResult<Self> {
        let shape = states.shape().to_vec();
        if shape.len() != 2 || shape[0] != s.len() || shape[1] != vlim.len() {
            return Err(err(
                Kind::Shape,
                format!("states: expected shape ({}, {}) (a row per path parameter, a column per limit), got {shape:?}", s.len(), vlim.len()),
            ));
        }
        let y = states.as_slice()?;
        let rule = genplan_core::timing::GridRule { base: grid_base, critical: grid_critical };
        let inner = py.detach(|| genplan_core::timing::TimedPath::new(&s, y, &vlim, &alim, rule)).map_err(to_py)?;
        Ok(PyTimedPath { inner })
    }

    /// Its duration at the time-optimal speed (no stretch), seconds.
    #[getter]
    fn duration(&self) -> f64 {
        self.inner.duration()
    }

    /// TOPP-RA's grid points (path parameters, increasing).
    #[getter]
    fn grid<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        self.inner.grid.clone().into_pyarray(py)
    }

    /// s' at each grid point.
    #[getter]
    fn sdot<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        self.inner.sdot.clone().into_pyarray(py)
    }

    /// The uniform stretch of the timing that keeps every sample at `rate` Hz within the
    /// limits (genplan_core::timing::TimedPath::stretch: 1.0 when none is needed; the samples
    /// taken with it are still to be checked). The GIL is released while it runs.
    fn stretch(&self, py: Python<'_>, rate: f64) -> PyResult<f64> {
        py.detach(|| self.inner.stretch(rate)).map_err(to_py)
    }

    /// The samples `(t, q, qd, qdd)` at `rate` Hz, the timing stretched by `scale`
    /// (genplan_core::timing::sample: refused before allocating beyond
    /// `MAX_TRAJECTORY_BYTES`). The GIL is released while it runs.
    fn sample<'py>(&self, py: Python<'py>, rate: f64, scale: f64) -> PyResult<Samples<'py>> {
        let n = self.inner.spline.n;
        let (t, q, qd, qdd) = py.detach(|| self.inner.sample(rate, scale)).map_err(to_py)?;
        let rows = t.len();
        let arr = |v: Vec<f64>| -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
            Ok(Array::from_shape_vec(IxDyn(&[rows, n]), v).map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?.into_pyarray(py))
        };
        Ok((t.into_pyarray(py), arr(q)?, arr(qd)?, arr(qdd)?))
    }
}

/// Register the timing functions and [`PyTimedPath`] on `genplan._core`.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(time_optimal, m)?)?;
    m.add_class::<PyTimedPath>()
}
