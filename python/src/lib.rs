//! `qfa_thermal._native`: the Python extension (PyO3, abi3) behind the `qfa_thermal`
//! package. It calls the lab's reader, calibration, compensation and discovery (`qfa-lab`)
//! and the root crate's compensator (`qfa-thermal`), never copies of them; the Python
//! layer (`python/qfa_thermal/__init__.py`) adds type hints, dataclasses and pandas.
//!
//! Columns cross the boundary as numpy arrays, one copy each way (no per-row Python
//! object); long runs release the GIL. Every failure is a `QfaError` subclass
//! ([`errors`]) carrying `qfa-lab`'s message, with each option named as this package's
//! keyword (`qfa_log::spelling::Spelling::Python`) and a `kind` mapped from the Rust
//! error's type ([`errors::Kind`]); nothing panics across the boundary that PyO3 would not
//! turn into `PanicException`.

use pyo3::prelude::*;
use pyo3::types::PyDict;

pub mod batch;
pub mod errors;
pub mod firmware;
pub mod logs;
pub mod tables;

use logs::Log;
use tables::Table;

#[pymodule]
#[pyo3(name = "_native")]
fn native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<Log>()?;
    m.add_class::<Table>()?;
    m.add_class::<firmware::Compensator>()?;
    m.add_function(wrap_pyfunction!(logs::read, m)?)?;
    m.add_function(wrap_pyfunction!(logs::from_arrays, m)?)?;
    m.add_function(wrap_pyfunction!(tables::calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(tables::compensate_columns, m)?)?;
    m.add_function(wrap_pyfunction!(tables::compensate_cycling, m)?)?;
    m.add_function(wrap_pyfunction!(tables::status_texts, m)?)?;
    m.add_function(wrap_pyfunction!(tables::discover, m)?)?;
    m.add_function(wrap_pyfunction!(firmware::status_flags, m)?)?;
    m.add_function(wrap_pyfunction!(batch::batch_shard, m)?)?;
    m.add_function(wrap_pyfunction!(batch::batch_merge, m)?)?;
    m.add("RATE_WINDOW", firmware::RATE_WINDOW)?;
    m.add("G0", qfa_thermal::G0)?;
    let constants = PyDict::new(m.py());
    constants.set_item("STATIC_LSB_PER_G", qfa_calibrate::compensate::STATIC_LSB_PER_G)?;
    m.add("constants", constants)?;
    Ok(())
}
