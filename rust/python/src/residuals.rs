//! The residual-only check of many configurations (`_core.residual_sizes`): a projector's
//! primary terms evaluated at each row, with no solver step, as a timed trajectory's samples are
//! checked against the task's tolerances.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArrayDyn};
use pyo3::prelude::*;

use crate::batch::{batch, check_rows, for_chunks};
use crate::projection::{has_python_terms, solve_error_to_py, PyProjector};

/// Per row of q ((n, nq) or (nq,)) and primary term of `projector`, the term's residual size:
/// the largest absolute component of its unweighted residual (+inf for a NaN), what
/// `Projector.solve_batch` reports as `residuals`, here with no solver step, no clipping and no
/// Jacobian. Returns (n, terms) float64, the terms in the projector's order. Every row is
/// checked before any work (the error names the row); the rows run in parallel with the GIL
/// released (one after the other with a Python term, whose exception reaches the caller
/// unchanged), in chunks between which Ctrl-C is answered.
#[pyfunction]
pub(crate) fn residual_sizes<'py>(
    py: Python<'py>,
    projector: PyRef<'py, PyProjector>,
    q: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let solver = &projector.inner;
    let model = &*solver.model;
    let b = batch(&q, model.nq, "q")?;
    check_rows(model, &b, "q")?;
    let nq = model.nq.max(1);
    let n = b.data.len() / nq;
    let terms = solver.primary.len();
    let data = b.data;
    let parallel = !has_python_terms(solver);
    let mut out: Vec<f64> = Vec::with_capacity(n * terms);
    let mut failure = None;
    for_chunks(py, n, |rows| {
        // after a failure no further chunk runs (its error becomes a Python one with the GIL held)
        if failure.is_none() {
            // the rows were checked above, once
            match solver.try_residual_sizes_unchecked(&data[rows.start * nq..rows.end * nq], parallel) {
                Ok(sizes) => out.extend(sizes),
                Err(e) => failure = Some(e),
            }
        }
        Ok(())
    })?;
    if let Some(e) = failure {
        return Err(solve_error_to_py(e));
    }
    let sizes = Array2::from_shape_vec((n, terms), out).map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
    Ok(sizes.into_pyarray(py))
}

/// Adds [`residual_sizes`] to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(residual_sizes, m)?)
}
