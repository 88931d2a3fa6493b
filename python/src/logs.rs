//! Logs read by the lab's own readers: a static multi-axis log (`data::static_log`) or a
//! four-position cycling log (`data::cycling`), kept as the lab's structures and handed to
//! Python as numpy columns.

use std::fmt::Write as _;
use std::path::PathBuf;

use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use qfa_log::cycling::Log as CyclingLog;
use qfa_log::open::{open, OpenError, OpenedLog, ReadFlags};
use qfa_log::spelling::Spelling;
use qfa_log::static_log::{read_static_from, StaticError, StaticLog};
use qfa_log::units::UnitParseError;

use crate::errors::{with_kind, Kind, LogError};

/// The lab's structure behind a [`Log`].
pub enum LogData {
    /// A static multi-axis log (a board at one orientation).
    Static(Box<StaticLog>),
    /// A four-position cycling log (`program,run,time_s,input_g,temp_c,pulses,interval_s`).
    Cycling(CyclingLog),
}

/// A log as the lab's reader read it.
#[pyclass(frozen, module = "qfa_thermal._native")]
pub struct Log {
    /// What the reader returned.
    pub data: LogData,
    /// The file it was read from (discovery of a cycling log reads it again).
    pub path: Option<PathBuf>,
}

/// A static reader's error as a `LogError`: the CLI's message with every reader option
/// spelled as this package's keyword (`accel_unit="m/s2"`, not `--accel-unit m/s2`), and
/// `kind` the error's variant (`Unit`, `Rows`, ...).
pub fn static_error(py: Python<'_>, e: &StaticError) -> PyErr {
    with_kind::<LogError>(py, e.message(Spelling::Python), e.kind())
}

/// [`static_error`] for any log: the file and its reader's error (only the static reader
/// takes options).
pub fn open_error(py: Python<'_>, e: &OpenError) -> PyErr {
    with_kind::<LogError>(py, e.message(Spelling::Python), e.kind())
}

fn unit_error(py: Python<'_>, e: &UnitParseError) -> PyErr {
    with_kind::<LogError>(py, e.message(Spelling::Python), e.kind())
}

/// The reader flags from the keyword arguments' strings.
pub fn read_flags(
    py: Python<'_>,
    columns: Option<&str>,
    time_unit: Option<&str>,
    accel_unit: Option<&str>,
    temp_unit: Option<&str>,
    decimal_comma: bool,
) -> PyResult<ReadFlags> {
    let u = |e: UnitParseError| unit_error(py, &e);
    Ok(ReadFlags {
        columns: columns.map(str::parse).transpose().map_err(|e: StaticError| static_error(py, &e))?,
        time_unit: time_unit.map(str::parse).transpose().map_err(u)?,
        accel_unit: accel_unit.map(str::parse).transpose().map_err(u)?,
        temp_unit: temp_unit.map(str::parse).transpose().map_err(u)?,
        decimal_comma,
    })
}

/// Read a log file the way `qfa-lab` does (`qfa_log::open`: any reader flag, or a
/// header without a `pulses` or `value` column, selects the static reader).
#[pyfunction]
#[pyo3(name = "read_log", signature = (path, *, columns = None, time_unit = None, accel_unit = None, temp_unit = None, decimal_comma = false))]
pub fn read(
    py: Python<'_>,
    path: PathBuf,
    columns: Option<&str>,
    time_unit: Option<&str>,
    accel_unit: Option<&str>,
    temp_unit: Option<&str>,
    decimal_comma: bool,
) -> PyResult<Log> {
    let flags = read_flags(py, columns, time_unit, accel_unit, temp_unit, decimal_comma)?;
    let data = match open(&path, &flags).map_err(|e| open_error(py, &e))? {
        OpenedLog::Static(l) => LogData::Static(l),
        OpenedLog::Cycling(l) => LogData::Cycling(l),
        OpenedLog::Autopilot(l) => {
            return Err(LogError::new_err(format!(
                "{}: a {}: `qfa-lab calibrate` reads it; this package reads cycling and static logs",
                path.display(),
                l.stack
            )))
        }
        OpenedLog::Single(_) => {
            return Err(LogError::new_err(format!(
                "{}: a single-channel log (time_s,temp_c,value): `qfa-lab discover` reads it; this package reads \
                 cycling and static logs",
                path.display()
            )))
        }
    };
    Ok(Log { data, path: Some(path) })
}

fn f64_column<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_vec(py, v)
}

#[pymethods]
impl Log {
    /// `"static"` or `"cycling"`.
    #[getter]
    fn kind(&self) -> &'static str {
        match self.data {
            LogData::Static(_) => "static",
            LogData::Cycling(_) => "cycling",
        }
    }

    /// Rows kept by the reader.
    #[getter]
    fn rows(&self) -> usize {
        match &self.data {
            LogData::Static(l) => l.rows(),
            LogData::Cycling(l) => l.rows(),
        }
    }

    /// The file read, or `None` for a log made from arrays.
    #[getter]
    fn path(&self) -> Option<PathBuf> {
        self.path.clone()
    }

    /// Acceleration axis roles of a static log (`ax`, `ay`, `az`), in column order; empty
    /// for a cycling log.
    #[getter]
    fn axes(&self) -> Vec<String> {
        match &self.data {
            LogData::Static(l) => l.axes.iter().map(|a| a.name.clone()).collect(),
            LogData::Cycling(_) => Vec::new(),
        }
    }

    /// The columns as numpy arrays, by name.
    ///
    /// Static: `time_s` (from the first kept row), `temp_c`, one array per axis in g, and
    /// `line` (each row's line in the file). Cycling, run after run: `program`, `run`
    /// (lists of str), `time_s`, `input_g`, `temp_c` (NaN before the first reading),
    /// `pulses` (int64), `interval_s`.
    fn columns<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        match &self.data {
            LogData::Static(l) => {
                d.set_item("time_s", f64_column(py, l.time_s.clone()))?;
                d.set_item("temp_c", f64_column(py, l.temp_c.clone()))?;
                for a in &l.axes {
                    d.set_item(&a.name, f64_column(py, a.accel_g.clone()))?;
                }
                d.set_item("line", PyArray1::from_vec(py, l.line.clone()))?;
            }
            LogData::Cycling(l) => {
                let n = l.rows();
                let (mut program, mut run) = (Vec::with_capacity(n), Vec::with_capacity(n));
                let (mut time_s, mut input_g, mut temp_c) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::new());
                let (mut pulses, mut interval_s) = (Vec::with_capacity(n), Vec::with_capacity(n));
                for r in &l.runs {
                    for s in &r.samples {
                        program.push(r.program.as_str());
                        run.push(r.run.as_str());
                        time_s.push(s.time_s);
                        input_g.push(r.input_g);
                        temp_c.push(s.temp_c.unwrap_or(f64::NAN));
                        pulses.push(s.pulses);
                        interval_s.push(s.interval_s);
                    }
                }
                d.set_item("program", program)?;
                d.set_item("run", run)?;
                d.set_item("time_s", f64_column(py, time_s))?;
                d.set_item("input_g", f64_column(py, input_g))?;
                d.set_item("temp_c", f64_column(py, temp_c))?;
                d.set_item("pulses", PyArray1::from_vec(py, pulses))?;
                d.set_item("interval_s", f64_column(py, interval_s))?;
            }
        }
        Ok(d)
    }

    /// What the static reader skipped and how the log is sampled, as JSON text (`skipped`,
    /// `sampling`, `columns`: role, column, unit); for a cycling log `null` fields, its
    /// programs and the rows its reader skipped as glitches (`glitches`) and as written
    /// twice (`repeated`: count and lines).
    fn reader_json(&self) -> String {
        match &self.data {
            LogData::Static(l) => serde_json::json!({
                "skipped": l.skipped,
                "sampling": l.sampling,
                "columns": l.columns,
                "skipped_text": l.skipped.to_string(),
                "sampling_text": l.sampling.to_string(),
            })
            .to_string(),
            LogData::Cycling(l) => serde_json::json!({
                "skipped": null,
                "sampling": null,
                "columns": null,
                "programs": l.programs(),
                "glitches": l.glitches,
                "repeated": l.repeated,
            })
            .to_string(),
        }
    }

    fn __repr__(&self) -> String {
        let from = self.path.as_ref().map_or_else(|| "arrays".to_string(), |p| p.display().to_string());
        format!("Log(kind={:?}, rows={}, from={from:?})", self.kind(), self.rows())
    }
}

/// A static log from columns, through the static reader itself, so the rows get the checks
/// a file gets (NaN rows and glitches skipped, time going backwards refused, unit
/// plausibility): the columns are written as CSV text with Rust's shortest round-trip
/// formatting (every f64 read back bit for bit) and read with `time=time,temp=temp,<axes>`.
#[pyfunction]
#[pyo3(name = "log_from_arrays", signature = (time, temp_c, accel, *, time_unit = "s", accel_unit = "g"))]
pub fn from_arrays(
    py: Python<'_>,
    time: PyReadonlyArray1<'_, f64>,
    temp_c: PyReadonlyArray1<'_, f64>,
    accel: Vec<(String, PyReadonlyArray1<'_, f64>)>,
    time_unit: &str,
    accel_unit: &str,
) -> PyResult<Log> {
    let time = time.as_array();
    let temp_c = temp_c.as_array();
    let accel: Vec<(String, numpy::ndarray::ArrayView1<'_, f64>)> =
        accel.iter().map(|(n, a)| (n.clone(), a.as_array())).collect();
    let n = time.len();
    if temp_c.len() != n || accel.iter().any(|(_, a)| a.len() != n) {
        let lens: Vec<String> = accel.iter().map(|(name, a)| format!("{name} {}", a.len())).collect();
        return Err(LogError::new_err(format!(
            "columns of unequal length: time {n}, temperature {}, {} rows",
            temp_c.len(),
            lens.join(", ")
        )));
    }
    let mut spec = String::from("time=time,temp=temp");
    let mut text = String::from("time,temp");
    for (name, _) in &accel {
        let _ = write!(spec, ",{name}={name}");
        let _ = write!(text, ",{name}");
    }
    text.push('\n');
    text.reserve(n * 24 * (2 + accel.len()));
    for i in 0..n {
        let _ = write!(text, "{},{}", time[i], temp_c[i]);
        for (_, a) in &accel {
            let _ = write!(text, ",{}", a[i]);
        }
        text.push('\n');
    }
    let opts = read_flags(py, Some(&spec), Some(time_unit), Some(accel_unit), Some("C"), false)?.static_options();
    let log = read_static_from(text.as_bytes(), &opts).map_err(|e| static_error(py, &e))?;
    Ok(Log { data: LogData::Static(Box::new(log)), path: None })
}
