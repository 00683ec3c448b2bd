//! Dense paths on a task's manifold for a batch of paths (`_core.dense_paths`): the core's
//! `projection::dense_path` on each path, the paths on rayon's threads with the GIL released.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

use genplan_core::projection::{dense_path, DenseSettings};

use crate::batch::chunked;
use crate::errors::{err, to_py, to_py_in, Kind};
use crate::projection::{first_failure, has_python_terms, PyProjector};

/// One path's answer: the dense path (m, n) and None, or the path so far and why it failed
/// (the failure's name and number, NaN for the kinds without one).
type DensePath<'py> = (Bound<'py, PyArray2<f64>>, Option<(&'static str, f64)>);

/// Per path of `paths` ((B, K, n) float64, C-contiguous; only those whose `todo` entry is true,
/// all by default): the path with every step at most `resolution` (max over the joints),
/// interpolated states projected with `projector` (None: kept as interpolated), when `densify`;
/// then, with both projectors, the chords between consecutive states held to `chord_fraction` of
/// the tolerances of `chords`' primary terms, straying ones split at their midpoint projected
/// with `projector` (genplan_core::projection::dense_path; `max_jump`, `max_rounds`,
/// `chord_rounds`: its settings). Returns a list of B entries: None for a path not to do, else
/// (path (m, n), None or (failure name, number)). Every row of the paths to do is checked before
/// any work (the error names it); the paths run in parallel with the GIL released (one after
/// the other with a Python term, whose exception reaches the caller unchanged).
#[pyfunction]
#[pyo3(signature = (paths, resolution, *, max_jump, max_rounds, chord_rounds, chord_fraction, projector=None, chords=None, todo=None, densify=true))]
#[allow(clippy::too_many_arguments)]
fn dense_paths<'py>(
    py: Python<'py>,
    paths: PyReadonlyArrayDyn<'py, f64>,
    resolution: f64,
    max_jump: f64,
    max_rounds: usize,
    chord_rounds: usize,
    chord_fraction: f64,
    projector: Option<PyRef<'py, PyProjector>>,
    chords: Option<PyRef<'py, PyProjector>>,
    todo: Option<Vec<bool>>,
    densify: bool,
) -> PyResult<Vec<Option<DensePath<'py>>>> {
    let settings = DenseSettings { resolution, max_jump, max_rounds, chord_rounds, chord_fraction };
    settings.validate().map_err(to_py)?;
    let shape = paths.shape().to_vec();
    if shape.len() != 3 || shape[2] == 0 {
        return Err(err(Kind::Shape, format!("paths: expected shape (B, K, n) with n >= 1, got {shape:?}")));
    }
    let (b, k, n) = (shape[0], shape[1], shape[2]);
    let data = paths.as_slice().map_err(|_| err(Kind::Shape, "paths: array must be C-contiguous"))?;
    let todo = todo.unwrap_or_else(|| vec![true; b]);
    if todo.len() != b {
        return Err(err(Kind::Shape, format!("todo: expected {b} flags (one per path), got {}", todo.len())));
    }
    let project = projector.as_ref().map(|p| &p.inner);
    let chords = chords.as_ref().map(|p| &p.inner);
    for (what, p) in [("projector", project), ("chords", chords)] {
        if let Some(p) = p {
            if p.model.nq != n {
                return Err(err(Kind::Shape, format!("paths: rows of {n}, but the {what}'s robot has {} joints", p.model.nq)));
            }
        }
    }
    // every row checked once, here: a configuration of the projectors' robot, else finite
    for i in (0..b).filter(|&i| todo[i]) {
        for r in 0..k {
            let row = &data[(i * k + r) * n..(i * k + r + 1) * n];
            match project.or(chords) {
                Some(p) => p.model.check_configuration(row).map_err(|e| to_py_in(&format!("paths[{i}][{r}]"), e))?,
                None => {
                    if let Some(j) = row.iter().position(|x| !x.is_finite()) {
                        return Err(err(Kind::NonFinite, format!("paths[{i}][{r}][{j}]: expected a finite number, got {}", row[j])));
                    }
                }
            }
        }
    }
    let parallel = !project.is_some_and(has_python_terms) && !chords.is_some_and(has_python_terms);
    // a custom term's failure stops the batch: the paths after it are skipped and its error raised
    let failed = std::sync::atomic::AtomicBool::new(false);
    let outs = chunked(py, b, parallel, || (), |_, i| {
        if !todo[i] || failed.load(std::sync::atomic::Ordering::Relaxed) {
            return None;
        }
        let out = dense_path(&data[i * k * n..(i + 1) * k * n], n, &settings, project, chords, densify);
        if out.is_err() {
            failed.store(true, std::sync::atomic::Ordering::Relaxed);
        }
        Some(out)
    })?;
    let mut answer = Vec::with_capacity(b);
    for out in first_failure(outs)? {
        answer.push(match out {
            None => None,
            Some(d) => {
                let rows = d.path.len() / n;
                let path = Array2::from_shape_vec((rows, n), d.path).map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
                Some((path.into_pyarray(py), d.failure.map(|f| f.parts())))
            }
        });
    }
    Ok(answer)
}

/// Adds [`dense_paths`] to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(dense_paths, m)?)
}
