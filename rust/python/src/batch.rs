//! Batches of configurations: reading a float64 array of rows of `nq`, checking every row before
//! any work, and running a batched call over its rows in chunks without the GIL, between which
//! Ctrl-C is answered.

use std::time::Instant;

use numpy::{PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use rayon::prelude::*;

use genplan_core::kinematics::KinematicModel;
use genplan_core::Scratch;

use crate::errors::{err, to_py_in, Kind};

/// A batch of configurations: leading dims and the flat data, rows of `nq`.
pub(crate) struct Batch<'a> {
    pub(crate) lead: Vec<usize>,
    pub(crate) data: &'a [f64],
}

/// `arr` as a [`Batch`] of rows of `nq` (shape (nq,) or (n, nq), C-contiguous), a ShapeError
/// naming `what` otherwise.
pub(crate) fn batch<'a>(arr: &'a PyReadonlyArrayDyn<'_, f64>, nq: usize, what: &str) -> PyResult<Batch<'a>> {
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
pub(crate) fn check_rows(model: &KinematicModel, b: &Batch, what: &str) -> PyResult<()> {
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
pub(crate) fn rows_map<T: Send>(py: Python<'_>, data: &[f64], nq: usize, f: impl Fn(&[f64], &mut Scratch) -> T + Sync + Send) -> PyResult<Vec<T>> {
    let nq = nq.max(1);
    chunked(py, data.len() / nq, true, Scratch::default, |s, i| f(&data[i * nq..(i + 1) * nq], s))
}
