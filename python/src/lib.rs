//! `qfa_thermal._native`: the Python extension (PyO3, abi3) behind the `qfa_thermal`
//! package. It calls the lab's reader, calibration, compensation and discovery (`qfa-lab`)
//! and the root crate's compensator (`qfa-thermal`), never copies of them; the Python
//! layer (`python/qfa_thermal/__init__.py`) adds type hints, dataclasses and pandas.
//!
//! Columns cross the boundary as numpy arrays, one copy each way (no per-row Python
//! object); long runs release the GIL. Every failure is a `QfaError` subclass
//! ([`errors`]) carrying `qfa-lab`'s message; nothing panics across the boundary that
//! PyO3 would not turn into `PanicException`.

use std::path::PathBuf;

use numpy::PyReadonlyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

pub mod errors;
pub mod firmware;
pub mod logs;
pub mod tables;

use logs::Log;
use tables::Table;

/// Read a log with the lab's reader (static or cycling, chosen as `qfa-lab` chooses).
#[pyfunction]
#[pyo3(signature = (path, *, columns = None, time_unit = None, accel_unit = None, decimal_comma = false))]
fn read_log(
    path: PathBuf,
    columns: Option<&str>,
    time_unit: Option<&str>,
    accel_unit: Option<&str>,
    decimal_comma: bool,
) -> PyResult<Log> {
    logs::read(path, columns, time_unit, accel_unit, decimal_comma)
}

/// A static log from columns, through the static reader (`accel`: `[(role, column)]`).
#[pyfunction]
#[pyo3(signature = (time, temp_c, accel, *, time_unit = "s", accel_unit = "g"))]
fn log_from_arrays(
    time: PyReadonlyArray1<'_, f64>,
    temp_c: PyReadonlyArray1<'_, f64>,
    accel: Vec<(String, PyReadonlyArray1<'_, f64>)>,
    time_unit: &str,
    accel_unit: &str,
) -> PyResult<Log> {
    logs::from_arrays(time, temp_c, accel, time_unit, accel_unit)
}

/// `qfa-lab calibrate` on a log.
#[pyfunction]
#[pyo3(signature = (log, *, holdout = "auto", fit_programs = None, axis = "x", px4_device_id = None, export_range = None))]
fn calibrate(
    py: Python<'_>,
    log: &Log,
    holdout: &str,
    fit_programs: Option<Vec<String>>,
    axis: &str,
    px4_device_id: Option<i64>,
    export_range: Option<(f64, f64)>,
) -> PyResult<Table> {
    tables::calibrate(py, log, holdout, fit_programs, axis, px4_device_id, export_range)
}

/// Compensate static columns with a samples table: (per-axis outputs in g, status flags).
#[pyfunction]
fn compensate_columns<'py>(
    py: Python<'py>,
    table: &Table,
    time_s: PyReadonlyArray1<'py, f64>,
    temp_c: PyReadonlyArray1<'py, f64>,
    accel: Vec<PyReadonlyArray1<'py, f64>>,
) -> PyResult<tables::AxesAndStatus<'py>> {
    tables::compensate_columns(py, table, time_s, temp_c, accel)
}

/// Compensate a cycling log with a pulse-counts table: (`accel_g`, status flags) per row.
#[pyfunction]
fn compensate_cycling<'py>(py: Python<'py>, table: &Table, log: &Log) -> PyResult<tables::ColumnAndStatus<'py>> {
    tables::compensate_cycling(py, table, log)
}

/// `qfa-lab compensate`'s status text of each flags word of a static log.
#[pyfunction]
fn status_texts(status: PyReadonlyArray1<'_, u16>) -> PyResult<Vec<String>> {
    tables::status_texts(status)
}

/// `qfa-lab discover`: the report as JSON text.
#[pyfunction]
#[pyo3(signature = (log, *, start = "simple", holdout = "auto", out = None))]
fn discover(py: Python<'_>, log: &Log, start: &str, holdout: &str, out: Option<PathBuf>) -> PyResult<String> {
    tables::discover(py, log, start, holdout, out)
}

/// The firmware's status flags as `(name, bit)`.
#[pyfunction]
fn status_flags() -> Vec<(&'static str, u16)> {
    firmware::status_flags()
}

#[pymodule]
#[pyo3(name = "_native")]
fn native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<Log>()?;
    m.add_class::<Table>()?;
    m.add_class::<firmware::Compensator>()?;
    m.add_function(wrap_pyfunction!(read_log, m)?)?;
    m.add_function(wrap_pyfunction!(log_from_arrays, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(compensate_columns, m)?)?;
    m.add_function(wrap_pyfunction!(compensate_cycling, m)?)?;
    m.add_function(wrap_pyfunction!(status_texts, m)?)?;
    m.add_function(wrap_pyfunction!(discover, m)?)?;
    m.add_function(wrap_pyfunction!(status_flags, m)?)?;
    m.add("RATE_WINDOW", firmware::RATE_WINDOW)?;
    m.add("G0", qfa_thermal::G0)?;
    let constants = PyDict::new(m.py());
    constants.set_item("STATIC_LSB_PER_G", qfa_lab::calibrate::fit::STATIC_LSB_PER_G)?;
    m.add("constants", constants)?;
    Ok(())
}
