//! Calibration, compensation and discovery: the lab's own functions, with the `Table` they
//! produce and consume.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use qfa_calibrate::export::{export_texts, write_exports, ExportAxis, ExportOptions};
use qfa_calibrate::static_cal::{self, Holdout, StaticCalOptions, StaticCalibration};
use qfa_calibrate::{self as cal, CalibrateOptions, Calibration};
use qfa_discover::DiscoverError;
use qfa_log::spelling::{CalibrateOption, Spelling};
use qfa_thermal::table::Input;
use qfa_thermal::{Status, Table as FirmwareTable};

use crate::errors::{with_kind, CalibrationError, CompensationError, DiscoveryError, Kind, TableError};
use crate::logs::{Log, LogData};

/// What a [`Table`] was calibrated from, kept so it can write every file the CLI writes.
enum Origin {
    /// Decoded from bytes or TOML: the table alone.
    Loaded,
    /// `calibrate` on a static log.
    Static(Box<StaticCalibration>),
    /// `calibrate` on a cycling log, with the IMU axis of its exports.
    Cycling(Box<Calibration>, String),
}

/// A coefficient table (what the firmware loads), with the calibration that fitted it.
#[pyclass(frozen, module = "qfa_thermal._native")]
pub struct Table {
    /// The table the firmware loads.
    pub table: FirmwareTable,
    origin: Origin,
    exports: ExportOptions,
}

fn table_err(py: Python<'_>, e: qfa_thermal::table::Error, prefix: Option<&str>) -> PyErr {
    let msg = prefix.map_or_else(|| e.to_string(), |p| format!("{p}: {e}"));
    with_kind::<TableError>(py, msg, e.kind())
}

/// Bytes of a table as `table.bin` holds them (the core's one encoder call).
pub fn encode(py: Python<'_>, t: &FirmwareTable) -> PyResult<Vec<u8>> {
    t.to_bytes().map(|b| b.to_vec()).map_err(|e| table_err(py, e, None))
}

/// A static calibration's error as an exception of type `E`: its message with the
/// held-out option spelled `holdout=`, and its kind.
fn static_cal_err<E: pyo3::PyTypeInfo>(py: Python<'_>, e: &static_cal::StaticCalError) -> PyErr {
    with_kind::<E>(py, e.message(Spelling::Python), e.kind())
}

/// A held-out scheme other than the default on a cycling log, refused as the CLI refuses
/// `--holdout` there.
fn cycling_holdout(holdout: Holdout) -> Result<(), String> {
    if holdout == Holdout::default() {
        Ok(())
    } else {
        Err(format!(
            "{}: static logs only (a cycling log is held out by program)",
            CalibrateOption::Holdout.with(Spelling::Python, &holdout.to_string())
        ))
    }
}

impl Table {
    fn export_axes(&self) -> Vec<ExportAxis> {
        match &self.origin {
            Origin::Loaded => Vec::new(),
            Origin::Static(c) => static_cal::export_axes(c),
            // The axis was checked when the calibration ran.
            Origin::Cycling(c, axis) => cal::cycling_export_axis(c, axis).into_iter().collect(),
        }
    }
}

#[pymethods]
impl Table {
    /// Decode `table.bin` bytes, as the firmware's `Table::decode` does (CRC, version,
    /// ranges).
    #[staticmethod]
    fn from_bytes(py: Python<'_>, data: &[u8]) -> PyResult<Self> {
        let table = FirmwareTable::decode(data).map_err(|e| table_err(py, e, None))?;
        Ok(Self { table, origin: Origin::Loaded, exports: ExportOptions::default() })
    }

    /// Read and decode a `table.bin` file; errors name the file, as `qfa-lab compensate`.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let bytes = std::fs::read(&path).map_err(|e| TableError::new_err(format!("{}: {e}", path.display())))?;
        let table = FirmwareTable::decode(&bytes).map_err(|e| table_err(py, e, Some(&path.display().to_string())))?;
        Ok(Self { table, origin: Origin::Loaded, exports: ExportOptions::default() })
    }

    /// Parse `table.toml` text and validate it as the firmware would.
    #[staticmethod]
    fn from_toml(py: Python<'_>, text: &str) -> PyResult<Self> {
        let table: FirmwareTable = toml::from_str(text).map_err(|e| TableError::new_err(e.to_string()))?;
        table.validate().map_err(|e| table_err(py, e, None))?;
        Ok(Self { table, origin: Origin::Loaded, exports: ExportOptions::default() })
    }

    /// The bytes to flash (`table.bin`).
    fn to_bytes(&self, py: Python<'_>) -> PyResult<Vec<u8>> {
        encode(py, &self.table)
    }

    /// The text of `table.toml`, as the CLI writes it.
    fn to_toml(&self) -> PyResult<String> {
        match &self.origin {
            Origin::Static(c) => static_cal::static_table_toml(c).map_err(|e| TableError::new_err(e.to_string())),
            Origin::Loaded | Origin::Cycling(..) => {
                cal::table_toml(&self.table).map_err(|e| TableError::new_err(e.to_string()))
            }
        }
    }

    /// `"samples"` (a static log's table: MEMS samples) or `"pulse_counts"` (a cycling log's).
    #[getter]
    fn input(&self) -> &'static str {
        match self.table.input {
            Input::Samples => "samples",
            Input::PulseCounts => "pulse_counts",
        }
    }

    /// Number of axes.
    #[getter]
    fn axes(&self) -> usize {
        self.table.axes.len()
    }

    /// `report.json` of the calibration as JSON text, or `None` for a loaded table.
    fn report_json(&self) -> PyResult<Option<String>> {
        let json = match &self.origin {
            Origin::Loaded => return Ok(None),
            Origin::Static(c) => serde_json::to_string_pretty(&c.report),
            Origin::Cycling(c, _) => serde_json::to_string_pretty(&c.report),
        };
        json.map(Some).map_err(|e| CalibrationError::new_err(e.to_string()))
    }

    /// `report.json` of the calibration as a dict (Python's `json.loads` of
    /// [`Self::report_json`]), or `None` for a loaded table.
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let Some(text) = self.report_json()? else { return Ok(None) };
        py.import("json")?.call_method1("loads", (text,)).map(Some)
    }

    /// `report.md` of a static calibration, or `None`.
    fn report_markdown(&self) -> Option<String> {
        match &self.origin {
            Origin::Static(c) => Some(static_cal::markdown(&c.report)),
            _ => None,
        }
    }

    /// The PX4 / ArduPilot parameter files as `{file name: text}`, and why others were
    /// left out (one sentence each, options named as `calibrate`'s keywords), as the CLI
    /// decides. The files' text is the CLI's, byte for byte.
    fn exports<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyDict>, Vec<String>)> {
        let (files, notes) = export_texts(&self.export_axes(), &self.exports);
        let d = PyDict::new(py);
        for (name, text) in files {
            d.set_item(name, text)?;
        }
        Ok((d, notes.iter().map(|n| n.message(Spelling::Python)).collect()))
    }

    /// Write every file `qfa-lab calibrate` writes into `out` (plots aside); returns the
    /// names written.
    fn write(&self, py: Python<'_>, out: PathBuf) -> PyResult<Vec<String>> {
        let io = |e: &dyn std::fmt::Display| CalibrationError::new_err(format!("{}: {e}", out.display()));
        std::fs::create_dir_all(&out).map_err(|e| io(&e))?;
        let mut written: Vec<String> = Vec::new();
        match &self.origin {
            Origin::Loaded => {
                std::fs::write(out.join("table.bin"), encode(py, &self.table)?).map_err(|e| io(&e))?;
                std::fs::write(out.join("table.toml"), self.to_toml()?).map_err(|e| io(&e))?;
                return Ok(vec!["table.bin".into(), "table.toml".into()]);
            }
            Origin::Static(c) => {
                written.extend(["table.toml", "table.bin", "report.json", "report.md"].map(String::from));
                // The CLI's verdict with the default limits, naming the files this call writes.
                let v = qfa_calibrate::verdict::static_verdict(c, &Default::default(), &written, &[]);
                static_cal::write_static(&out, c, &v).map_err(|e| CalibrationError::new_err(e.to_string()))?;
            }
            Origin::Cycling(c, _) => {
                cal::write_table(&out, "table", &c.table.hysteresis).map_err(|e| io(&e))?;
                cal::write_table(&out, "table_simple", &c.table.simple).map_err(|e| io(&e))?;
                let json = serde_json::to_string_pretty(&c.report).map_err(|e| io(&e))?;
                std::fs::write(out.join("report.json"), json).map_err(|e| io(&e))?;
                written.extend(
                    ["table.toml", "table.bin", "table_simple.toml", "table_simple.bin", "report.json"]
                        .map(String::from),
                );
            }
        }
        let ex = write_exports(&out, &self.export_axes(), &self.exports).map_err(|e| io(&e))?;
        written.extend(ex.written.iter().map(|s| (*s).to_string()));
        Ok(written)
    }

    fn __repr__(&self) -> String {
        let from = match self.origin {
            Origin::Loaded => "loaded",
            Origin::Static(_) => "calibrate(static log)",
            Origin::Cycling(..) => "calibrate(cycling log)",
        };
        format!("Table(input={:?}, axes={}, from={from:?})", self.input(), self.axes())
    }
}

/// The export options, with the CLI's checks of `--px4-device-id` and `--export-range`.
fn export_options(px4_device_id: Option<i64>, export_range: Option<(f64, f64)>) -> PyResult<ExportOptions> {
    let id = |v: i64| CalibrateOption::Px4DeviceId.with(Spelling::Python, &v.to_string());
    let px4_device_id = match px4_device_id {
        None => None,
        Some(0) => {
            return Err(CalibrationError::new_err(format!(
                "{} matches no accelerometer: pass the vehicle's CAL_ACC0_ID (or device_id in `listener \
                 sensor_accel`)",
                id(0)
            )))
        }
        Some(v) if !(i64::from(i32::MIN)..=i64::from(u32::MAX)).contains(&v) => {
            return Err(CalibrationError::new_err(format!("{}: not a 32-bit device ID", id(v))))
        }
        // Two's complement: the bits PX4 compares (`device_id == (uint32_t)ID`).
        Some(v) => Some(v as u32 as i32),
    };
    if let Some((lo, hi)) = export_range {
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            let range = CalibrateOption::ExportRange.with(Spelling::Python, &format!("{lo},{hi}"));
            return Err(CalibrationError::new_err(format!("{range}: need finite TMIN < TMAX")));
        }
    }
    Ok(ExportOptions { px4_device_id, range_c: export_range, ..ExportOptions::default() })
}

/// The part's sensitivity, LSB per g, within what a table takes (the CLI's `--lsb-per-g`).
fn part_sensitivity(lsb_per_g: Option<f64>) -> PyResult<Option<f32>> {
    let Some(v) = lsb_per_g else { return Ok(None) };
    let (lo, hi) = qfa_thermal::table::limits::GAMMA;
    if !(v.is_finite() && (f64::from(lo)..=f64::from(hi)).contains(&v)) {
        return Err(CalibrationError::new_err(format!(
            "lsb_per_g={v} is no part's LSB per g: 1 to 1e9, e.g. 4096 (±8 g, 16 bits)"
        )));
    }
    Ok(Some(v as f32))
}

/// `qfa-lab calibrate` on a log already read.
#[pyfunction]
#[pyo3(signature = (log, *, holdout = "auto", fit_programs = None, axis = "x", px4_device_id = None, export_range = None, lsb_per_g = None))]
#[allow(clippy::too_many_arguments)]
pub fn calibrate(
    py: Python<'_>,
    log: &Log,
    holdout: &str,
    fit_programs: Option<Vec<String>>,
    axis: &str,
    px4_device_id: Option<i64>,
    export_range: Option<(f64, f64)>,
    lsb_per_g: Option<f64>,
) -> PyResult<Table> {
    let exports = export_options(px4_device_id, export_range)?;
    let part_lsb_per_g = part_sensitivity(lsb_per_g)?;
    let holdout: Holdout = holdout.parse().map_err(|e| static_cal_err::<CalibrationError>(py, &e))?;
    if !["x", "y", "z"].contains(&axis) {
        return Err(CalibrationError::new_err(format!("axis=\"{axis}\": expected \"x\", \"y\" or \"z\"")));
    }
    match &log.data {
        LogData::Static(l) => {
            let opts = StaticCalOptions { holdout, part_lsb_per_g, ..Default::default() };
            let c = py
                .detach(|| static_cal::calibrate_static(l, &opts, false))
                .map_err(|e| static_cal_err::<CalibrationError>(py, &e))?;
            Ok(Table { table: c.table.clone(), origin: Origin::Static(Box::new(c)), exports })
        }
        LogData::Cycling(l) => {
            cycling_holdout(holdout).map_err(CalibrationError::new_err)?;
            if part_lsb_per_g.is_some() {
                return Err(CalibrationError::new_err("lsb_per_g: static logs only (a cycling log is pulse counts)"));
            }
            let axis = format!("a{axis}");
            let opts = CalibrateOptions {
                fit_programs: fit_programs.filter(|f| !f.is_empty()),
                plots: false,
                title: String::new(),
                progress: false,
                axis: Some(axis.clone()),
                unit: None,
                exports,
                limits: qfa_report::verdict::LimitsChoice::default(),
                reproducible: false,
                notes: Vec::new(),
                ext: qfa_thermal::Extensions::NONE,
            };
            let calibration_err = |e: cal::CalibrateError| with_kind::<CalibrationError>(py, e.to_string(), e.kind());
            let c = py.detach(|| cal::calibrate_log(l, &opts)).map_err(calibration_err)?;
            cal::cycling_export_axis(&c, &axis).map_err(calibration_err)?;
            Ok(Table { table: c.table.hysteresis.clone(), origin: Origin::Cycling(Box::new(c), axis), exports })
        }
    }
}

/// Per-axis output columns and the status flags per row.
pub type AxesAndStatus<'py> = (Vec<Bound<'py, PyArray1<f64>>>, Bound<'py, PyArray1<u16>>);

/// One output column and the status flags per row.
pub type ColumnAndStatus<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<u16>>);

/// Compensate static columns (`compensate_samples`): per axis the output in g, and the
/// status flags per row.
#[pyfunction]
pub fn compensate_columns<'py>(
    py: Python<'py>,
    table: &Table,
    time_s: PyReadonlyArray1<'py, f64>,
    temp_c: PyReadonlyArray1<'py, f64>,
    accel: Vec<PyReadonlyArray1<'py, f64>>,
) -> PyResult<AxesAndStatus<'py>> {
    let time_s = time_s.as_slice()?;
    let temp_c = temp_c.as_slice()?;
    let columns: Vec<&[f64]> = accel.iter().map(|a| a.as_slice()).collect::<Result<_, _>>()?;
    let out = py
        .detach(|| qfa_calibrate::compensate::compensate_samples(&table.table, time_s, temp_c, &columns))
        .map_err(|e| with_kind::<CompensationError>(py, e.to_string(), e.kind()))?;
    let axes = out.accel_g.into_iter().map(|a| PyArray1::from_vec(py, a)).collect();
    let status = PyArray1::from_vec(py, out.status.iter().map(|s| s.bits()).collect());
    Ok((axes, status))
}

/// Compensate a cycling log (`compensate_log`): per row, run after run, `accel_g` and the
/// status flags.
#[pyfunction]
pub fn compensate_cycling<'py>(py: Python<'py>, table: &Table, log: &Log) -> PyResult<ColumnAndStatus<'py>> {
    let LogData::Cycling(l) = &log.data else {
        return Err(CompensationError::new_err("not a cycling log"));
    };
    let runs = py
        .detach(|| qfa_calibrate::compensate::compensate_log(&table.table, l, None))
        .map_err(|e| with_kind::<CompensationError>(py, e.to_string(), e.kind()))?;
    let (mut accel, mut status) = (Vec::with_capacity(l.rows()), Vec::with_capacity(l.rows()));
    for r in runs {
        accel.extend(r.accel_g);
        status.extend(r.status);
    }
    Ok((PyArray1::from_vec(py, accel), PyArray1::from_vec(py, status)))
}

/// The text `qfa-lab compensate` writes in a static log's `status` column for each flags
/// word (`ok`, `no_temperature`, or flags joined by `|`).
#[pyfunction]
pub fn status_texts(status: PyReadonlyArray1<'_, u16>) -> PyResult<Vec<String>> {
    Ok(status
        .as_array()
        .iter()
        .map(|&s| qfa_calibrate::compensate::static_status(Status::from_bits_retain(s)))
        .collect())
}

/// A fresh directory under the system's temporary directory for a discovery run whose
/// caller wants the report only.
fn scratch_dir() -> PathBuf {
    static COUNT: AtomicU64 = AtomicU64::new(0);
    std::env::temp_dir().join(format!(
        "qfa-python-discover-{}-{}",
        std::process::id(),
        COUNT.fetch_add(1, Ordering::Relaxed)
    ))
}

/// `qfa-lab discover`: the report as JSON text; the files go to `out` (or a scratch
/// directory removed afterwards).
#[pyfunction]
#[pyo3(signature = (log, *, start = "simple", holdout = "auto", out = None))]
pub fn discover(py: Python<'_>, log: &Log, start: &str, holdout: &str, out: Option<PathBuf>) -> PyResult<String> {
    let start: qfa_discover::Start =
        start.parse().map_err(|e: DiscoverError| with_kind::<DiscoveryError>(py, e.to_string(), e.kind()))?;
    let holdout: Holdout = holdout.parse().map_err(|e| static_cal_err::<DiscoveryError>(py, &e))?;
    if let LogData::Cycling(_) = &log.data {
        cycling_holdout(holdout).map_err(DiscoveryError::new_err)?;
    }
    let (dir, scratch) = match out {
        Some(d) => (d, false),
        None => (scratch_dir(), true),
    };
    let result = py.detach(|| run_discovery(log, start, holdout, &dir));
    if scratch {
        let _ = std::fs::remove_dir_all(&dir);
    }
    result.map_err(|e| discovery_err(py, &e))
}

/// A failed discovery as a `DiscoveryError`, its kind the variant of the [`DiscoverError`]
/// behind it (none for a failure of this package's own or of the log's channels).
fn discovery_err(py: Python<'_>, e: &anyhow::Error) -> PyErr {
    match e.downcast_ref::<DiscoverError>() {
        // Calibration's own refusal (a held-out scheme the log cannot hold): typed, so
        // its option is spelled for Python and its kind is the variant.
        Some(DiscoverError::StaticCal(s)) => static_cal_err::<DiscoveryError>(py, s),
        Some(d) => with_kind::<DiscoveryError>(py, format!("{e:#}"), d.kind()),
        None => DiscoveryError::new_err(format!("{e:#}")),
    }
}

/// Run discovery into `dir` and return its `report.json` as written (the verdict first),
/// so Python's dict is the CLI's file, not a second serialization of it.
fn run_discovery(log: &Log, start: qfa_discover::Start, holdout: Holdout, dir: &Path) -> anyhow::Result<String> {
    match &log.data {
        LogData::Static(l) => {
            qfa_discover::static_axes::run(l, start, holdout, dir)?;
        }
        LogData::Cycling(_) => {
            let Some(path) = &log.path else {
                anyhow::bail!("discovery of a cycling log reads its file: read it with read_log(path)");
            };
            let source = qfa_discover::Source::read(path, 60.0)?;
            qfa_discover::discover(&source, start, dir)?;
        }
    }
    Ok(std::fs::read_to_string(dir.join("report.json"))?)
}
