//! The firmware's compensator, step by step: every call the root crate's `Compensator`
//! takes (readings and IMU cycles), on the host build, so a replay from Python gives the
//! firmware's outputs and flags bit for bit.
//!
//! This is the one file that names the root crate's compensator API (its type, const
//! generics, reading and cycle calls, outputs); a rename there is mended here alone.

use numpy::PyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use qfa_thermal::compensator::{
    Compensator as Firmware, Config, PulseOutput, SampleError as FirmwareSampleError, SampleOutput,
};
use qfa_thermal::rate::RateConfig;
use qfa_thermal::{Input, Status};

use crate::errors::{with_kind, ConfigError, Kind, SampleError, TableError};
use crate::tables::Table;

/// The rate window every instance here is built with, samples: the lab's and the
/// reference vectors' `Compensator<_, 32>`.
pub const RATE_WINDOW: usize = qfa_thermal::DEFAULT_RATE_WINDOW;

/// The instantiations Python can pick: axes 1..=3, one temperature stream or one per axis
/// (boxed: their sizes differ by the per-axis state). Three axes have the misalignment
/// stage, so a table with a matrix loads: without a matrix its outputs are the plain
/// type's, bit for bit (the root crate tests it).
enum Inner {
    A1S1(Box<Firmware<1, RATE_WINDOW, 1>>),
    A2S1(Box<Firmware<2, RATE_WINDOW, 1>>),
    A2S2(Box<Firmware<2, RATE_WINDOW, 2>>),
    A3S1(Box<Firmware<3, RATE_WINDOW, 1, qfa_thermal::Table, 3>>),
    A3S3(Box<Firmware<3, RATE_WINDOW, 3, qfa_thermal::Table, 3>>),
}

/// Run `$body` with `$c` bound to whichever instantiation `$inner` holds.
macro_rules! each {
    ($inner:expr, $c:ident => $body:expr) => {
        match $inner {
            Inner::A1S1($c) => $body,
            Inner::A2S1($c) => $body,
            Inner::A2S2($c) => $body,
            Inner::A3S1($c) => $body,
            Inner::A3S3($c) => $body,
        }
    };
}

fn array<T: Copy, const A: usize>(values: &[T], what: &str) -> PyResult<[T; A]> {
    values
        .try_into()
        .map_err(|_| PyValueError::new_err(format!("{what}: {} value(s), the compensator has {A} axes", values.len())))
}

/// An output as Python sees it: the values as float32 (their bits are the firmware's) and
/// the status flags.
fn output<'py, const A: usize>(py: Python<'py>, o: PulseOutput<A>) -> (Bound<'py, PyArray1<f32>>, u16) {
    (PyArray1::from_slice(py, &o.dv_mps), o.status.bits())
}

/// As [`output`], for a MEMS cycle (accelerations in m/s²).
fn sample_output<'py, const A: usize>(py: Python<'py>, o: SampleOutput<A>) -> (Bound<'py, PyArray1<f32>>, u16) {
    (PyArray1::from_slice(py, &o.accel_mps2), o.status.bits())
}

fn sample_err(py: Python<'_>, e: FirmwareSampleError, status: Status) -> PyErr {
    let err = with_kind::<SampleError>(py, e.to_string(), e.kind());
    let _ = err.value(py).setattr("status", status.bits());
    err
}

/// The firmware's compensator (`qfa_thermal::Compensator<AXES, 32, SENSORS>`).
#[pyclass(module = "qfa_thermal._native")]
pub struct Compensator {
    inner: Inner,
}

#[pymethods]
impl Compensator {
    /// A compensator with no table, from `Config::default()` with the fields given changed.
    #[new]
    #[pyo3(signature = (axes = 3, sensors = 1, *, tick_s = None, imu_period_s = None, stale_after_ticks = None, sample_period_ms = None,
        input = None, nominal_k1 = None, sample_lsb_per_g = None, max_step_raw = None, max_slew_raw_per_min = None, confirm_samples = None,
        rate_max_gap_ms = None, rate_min_samples = None, rate_smoothing_alpha = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        axes: usize,
        sensors: usize,
        tick_s: Option<f32>,
        imu_period_s: Option<f32>,
        stale_after_ticks: Option<u32>,
        sample_period_ms: Option<u32>,
        input: Option<&str>,
        nominal_k1: Option<f32>,
        sample_lsb_per_g: Option<f32>,
        max_step_raw: Option<i16>,
        max_slew_raw_per_min: Option<i32>,
        confirm_samples: Option<u8>,
        rate_max_gap_ms: Option<u16>,
        rate_min_samples: Option<u8>,
        rate_smoothing_alpha: Option<f32>,
    ) -> PyResult<Self> {
        let d = Config::default();
        let r = RateConfig::default();
        let input = match input {
            None => d.input,
            Some("pulse_counts") => Input::PulseCounts,
            Some("samples") => Input::Samples,
            Some(other) => {
                return Err(PyValueError::new_err(format!("input `{other}`: expected pulse_counts or samples")))
            }
        };
        let config = Config {
            tick_s: tick_s.unwrap_or(d.tick_s),
            imu_period_s: imu_period_s.unwrap_or(d.imu_period_s),
            stale_after_ticks: stale_after_ticks.unwrap_or(d.stale_after_ticks),
            sample_period_ms: sample_period_ms.unwrap_or(d.sample_period_ms),
            input,
            rate: RateConfig {
                max_gap_ms: rate_max_gap_ms.unwrap_or(r.max_gap_ms),
                min_samples: rate_min_samples.unwrap_or(r.min_samples),
                smoothing_alpha: rate_smoothing_alpha.unwrap_or(r.smoothing_alpha),
            },
            max_step_raw: max_step_raw.unwrap_or(d.max_step_raw),
            max_slew_raw_per_min: max_slew_raw_per_min.unwrap_or(d.max_slew_raw_per_min),
            confirm_samples: confirm_samples.unwrap_or(d.confirm_samples),
            nominal_k1: nominal_k1.unwrap_or(d.nominal_k1),
            sample_lsb_per_g: sample_lsb_per_g.unwrap_or(d.sample_lsb_per_g),
        };
        let cfg = |e: qfa_thermal::ConfigError| with_kind::<ConfigError>(py, e.to_string(), e.kind());
        let inner = match (axes, sensors) {
            (1, 1) => Inner::A1S1(Box::new(Firmware::new(config).map_err(cfg)?)),
            (2, 1) => Inner::A2S1(Box::new(Firmware::new(config).map_err(cfg)?)),
            (2, 2) => Inner::A2S2(Box::new(Firmware::new(config).map_err(cfg)?)),
            (3, 1) => Inner::A3S1(Box::new(Firmware::new(config).map_err(cfg)?)),
            (3, 3) => Inner::A3S3(Box::new(Firmware::new(config).map_err(cfg)?)),
            _ => {
                return Err(PyValueError::new_err(format!(
                    "axes {axes}, sensors {sensors}: axes is 1, 2 or 3 and sensors 1 or axes"
                )))
            }
        };
        Ok(Self { inner })
    }

    /// Number of axes.
    #[getter]
    fn axes(&self) -> usize {
        each!(&self.inner, c => c.evaluations().len())
    }

    /// Load `table.bin` bytes (the firmware's `load_table`: decode, validate, install).
    fn load_table(&mut self, py: Python<'_>, data: &[u8]) -> PyResult<()> {
        let r = each!(&mut self.inner, c => c.load_table(data));
        r.map_err(|e| with_kind::<TableError>(py, e.to_string(), e.kind()))
    }

    /// Install a `Table` (validated, as `set_table`).
    fn set_table(&mut self, py: Python<'_>, table: &Table) -> PyResult<()> {
        let r = each!(&mut self.inner, c => c.set_table(table.table.clone()));
        r.map_err(|e| with_kind::<TableError>(py, e.to_string(), e.kind()))
    }

    /// A DS18B20 reading, raw in 1/16 °C, taken at `t_ms` (wrapping u32 ms), from
    /// temperature stream `sensor`; returns the status flags. A rejected reading raises
    /// `SampleError` (`kind`, `status` attributes) and leaves the last good compensation.
    #[pyo3(signature = (t_ms, raw, sensor = 0))]
    fn on_raw(&mut self, py: Python<'_>, t_ms: u32, raw: i16, sensor: usize) -> PyResult<u16> {
        let r = each!(&mut self.inner, c => c.on_raw(sensor, t_ms, raw).map_err(|e| (e, c.status())));
        r.map(|s| s.bits()).map_err(|(e, s)| sample_err(py, e, s))
    }

    /// A DS18B20 scratchpad (9 bytes) read at `t_ms`; as `on_raw` after decoding it.
    #[pyo3(signature = (t_ms, scratchpad, sensor = 0))]
    fn on_scratchpad(&mut self, py: Python<'_>, t_ms: u32, scratchpad: &[u8], sensor: usize) -> PyResult<u16> {
        let sp: [u8; 9] = scratchpad
            .try_into()
            .map_err(|_| PyValueError::new_err(format!("scratchpad: {} byte(s), expected 9", scratchpad.len())))?;
        let r = each!(&mut self.inner, c => c.on_scratchpad(sensor, t_ms, &sp).map_err(|e| (e, c.status())));
        r.map(|s| s.bits()).map_err(|(e, s)| sample_err(py, e, s))
    }

    /// A reading that never arrived (bus or sensor failure) at `t_ms`.
    #[pyo3(signature = (t_ms, sensor = 0))]
    fn on_missed_reading(&mut self, py: Python<'_>, t_ms: u32, sensor: usize) -> PyResult<u16> {
        let r = each!(&mut self.inner, c => c.on_missed_reading(sensor, t_ms).map_err(|e| (e, c.status())));
        r.map(|s| s.bits()).map_err(|(e, s)| sample_err(py, e, s))
    }

    /// One IMU cycle of signed pulse counts over `dt_ticks`: (Δv per axis in m/s as
    /// float32, status flags).
    fn cycle<'py>(
        &mut self,
        py: Python<'py>,
        pulses: Vec<i32>,
        dt_ticks: u32,
    ) -> PyResult<(Bound<'py, PyArray1<f32>>, u16)> {
        each!(&mut self.inner, c => Ok(output(py, c.cycle(array(&pulses, "pulses")?, dt_ticks))))
    }

    /// One IMU cycle of MEMS samples (LSB): (acceleration per axis in m/s² as float32,
    /// status flags).
    fn cycle_samples<'py>(
        &mut self,
        py: Python<'py>,
        raw: Vec<i32>,
        dt_ticks: u32,
    ) -> PyResult<(Bound<'py, PyArray1<f32>>, u16)> {
        each!(&mut self.inner, c => Ok(sample_output(py, c.cycle_samples(array(&raw, "raw")?, dt_ticks))))
    }

    /// One IMU cycle of cumulative (wrapping u32) pulse counters: as `cycle`.
    fn cycle_counters<'py>(
        &mut self,
        py: Python<'py>,
        counters: Vec<u32>,
        dt_ticks: u32,
    ) -> PyResult<(Bound<'py, PyArray1<f32>>, u16)> {
        each!(&mut self.inner, c => Ok(output(py, c.cycle_counters(array(&counters, "counters")?, dt_ticks))))
    }

    /// Set the counters' base, so the first `cycle_counters` has increments.
    fn prime_counters(&mut self, counters: Vec<u32>) -> PyResult<()> {
        each!(&mut self.inner, c => {
            c.prime_counters(array(&counters, "counters")?);
            Ok(())
        })
    }

    /// The slow path's status flags now.
    #[getter]
    fn status(&self) -> u16 {
        each!(&self.inner, c => c.status().bits())
    }

    /// The rate estimator of stream `sensor`: `(temp_c, rate_c_per_min, ready)` (float32
    /// values as Python floats, exact), or `None` before the first good reading.
    #[pyo3(signature = (sensor = 0))]
    fn estimate(&self, sensor: usize) -> Option<(f32, f32, bool)> {
        each!(&self.inner, c => c.estimate_of(sensor)).map(|e| (e.temp_c, e.rate_c_per_min, e.ready))
    }

    /// Per axis, the model's latest evaluation: `(k1, k0, temp_clamped, rate_clamped)`.
    fn evaluations(&self) -> Vec<(f32, f32, bool, bool)> {
        each!(&self.inner, c => c.evaluations().iter().map(|e| (e.k1, e.k0, e.temp_clamped, e.rate_clamped)).collect())
    }

    /// The configuration in force, by field name.
    fn config<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = *each!(&self.inner, c => c.config());
        let d = PyDict::new(py);
        d.set_item("tick_s", c.tick_s)?;
        d.set_item("imu_period_s", c.imu_period_s)?;
        d.set_item("stale_after_ticks", c.stale_after_ticks)?;
        d.set_item("sample_period_ms", c.sample_period_ms)?;
        d.set_item("input", if c.input == Input::Samples { "samples" } else { "pulse_counts" })?;
        d.set_item("nominal_k1", c.nominal_k1)?;
        d.set_item("sample_lsb_per_g", c.sample_lsb_per_g)?;
        d.set_item("max_step_raw", c.max_step_raw)?;
        d.set_item("max_slew_raw_per_min", c.max_slew_raw_per_min)?;
        d.set_item("confirm_samples", c.confirm_samples)?;
        d.set_item("rate_max_gap_ms", c.rate.max_gap_ms)?;
        d.set_item("rate_min_samples", c.rate.min_samples)?;
        d.set_item("rate_smoothing_alpha", c.rate.smoothing_alpha)?;
        Ok(d)
    }
}

/// The status word's flags as `(name, bit)`, from the firmware's own definition.
#[pyfunction]
pub fn status_flags() -> Vec<(&'static str, u16)> {
    Status::all().iter_names().map(|(n, s)| (n, s.bits())).collect()
}
