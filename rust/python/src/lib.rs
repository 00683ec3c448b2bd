//! `genplan._core`: the private native module. Thin wrappers around `genplan-core`, one file per
//! core module: [`kinematics`], [`collision`], [`projection`] (and [`residuals`], its
//! residual-only check), [`robot`] (robot files and descriptions), [`timing`], [`jerk`], [`planning`],
//! [`control`]; [`batch`] runs their batched calls, [`arrays`] reads their configurations,
//! [`settings`] makes their typed settings classes and [`errors`] their error classes; this
//! file only registers them.
//!
//! Inputs are float64 C-contiguous numpy arrays (the Python layer converts), except for the
//! per-configuration calls (forward kinematics, collision, distance), which read and check q
//! themselves ([`arrays`]: one call costs the Rust work plus a fixed overhead) and write batched
//! outputs in place; batched calls release the GIL and run in parallel, in chunks of ~50 ms
//! between which Ctrl-C is answered ([`batch::for_chunks`]); empty batches give empty arrays;
//! every error is a Python exception, never a panic.

use pyo3::prelude::*;
use pyo3::types::PyDict;

mod arrays;
mod batch;
mod errors;
mod settings;

mod collision;
mod control;
mod jerk;
mod kinematics;
mod planning;
mod residuals;
mod dense;
mod projection;
mod robot;
mod timing;

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    let crates = PyDict::new(m.py());
    for (name, version) in env!("GENPLAN_CRATE_VERSIONS").split(',').filter_map(|kv| kv.split_once('=')) {
        crates.set_item(name, version)?;
    }
    m.add("CRATE_VERSIONS", crates)?;
    errors::register(m)?;
    kinematics::register(m)?;
    collision::register(m)?;
    projection::register(m)?;
    robot::register(m)?;
    timing::register(m)?;
    jerk::register(m)?;
    planning::register(m)?;
    control::register(m)?;
    residuals::register(m)?;
    dense::register(m)?;
    Ok(())
}
