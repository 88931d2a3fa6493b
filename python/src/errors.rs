//! The exception hierarchy: one base, one class per kind of failure, each carrying the
//! message `qfa-lab` prints after `error: ` for the same failure.

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

create_exception!(_native, QfaError, PyException, "Base of every qfa_thermal error.");
create_exception!(_native, LogError, QfaError, "A log the lab's reader refuses (bad rows, columns, units).");
create_exception!(_native, CalibrationError, QfaError, "A calibration that cannot be fitted or evaluated.");
create_exception!(_native, TableError, QfaError, "A table that does not decode, validate or load.");
create_exception!(_native, CompensationError, QfaError, "A log the table cannot compensate.");
create_exception!(_native, DiscoveryError, QfaError, "A discovery run that failed.");
create_exception!(_native, ConfigError, QfaError, "A compensator configuration the firmware refuses.");
create_exception!(_native, SampleError, QfaError, "A temperature reading the firmware's compensator rejected.");

/// Register the classes on the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("QfaError", py.get_type::<QfaError>())?;
    m.add("LogError", py.get_type::<LogError>())?;
    m.add("CalibrationError", py.get_type::<CalibrationError>())?;
    m.add("TableError", py.get_type::<TableError>())?;
    m.add("CompensationError", py.get_type::<CompensationError>())?;
    m.add("DiscoveryError", py.get_type::<DiscoveryError>())?;
    m.add("ConfigError", py.get_type::<ConfigError>())?;
    m.add("SampleError", py.get_type::<SampleError>())?;
    Ok(())
}

/// The name of an enum value's variant from its `Debug` text (`Crc`, `NonFinite`): a
/// stable tag for a Python caller to branch on.
pub fn variant_name(debug: &str) -> String {
    debug.split(['(', ' ', '{']).next().unwrap_or(debug).to_string()
}

/// An exception of type `E` with `message` and a `kind` attribute (the Rust variant name).
pub fn with_kind<E: pyo3::PyTypeInfo>(py: Python<'_>, message: String, kind: &str) -> PyErr {
    let err = PyErr::new::<E, _>(message);
    // Setting an attribute on a fresh exception instance cannot fail short of memory
    // exhaustion; the message is then still raised.
    let _ = err.value(py).setattr("kind", kind);
    err
}
