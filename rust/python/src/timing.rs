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

/// Register the timing functions on `genplan._core`.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(time_optimal, m)?)?;
    m.add_function(wrap_pyfunction!(sample_timed_spline, m)?)
}
