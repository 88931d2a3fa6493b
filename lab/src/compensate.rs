//! Compensation of a log through the root crate's `Compensator<1, 32>`, as the firmware runs it.
//!
//! Per row, in order: if the row has a reading, `on_raw(time_s·1000 ms, round(temp_c·16))`
//! (a rejected reading leaves the last good compensation in force, as on target); then
//! `cycle([pulses], interval_s·10⁶ ticks)` with the default 1-µs tick. The reading is
//! applied before the row's pulses because it was taken inside that interval (the same
//! alignment the fit uses, see [`crate::pairing::trace_run`]).
//! `accel_g = Δv / (g0 · interval_s)`: the compensated mean specific force of the interval.
//! Each run starts a fresh compensator (each run is a fresh power-up in the test).
//! The staleness limit is at least 1.5 rows (see [`compensate_run`]).

use qfa_thermal::compensator::{Compensator, Config, Status, G0};
use qfa_thermal::Table;

use crate::log::{Log, Run};
use crate::pairing::RATE_WINDOW;

/// Compensated output of one run.
#[derive(Clone, Debug, Default)]
pub struct Compensated {
    /// Specific force per row, g.
    pub accel_g: Vec<f64>,
    /// Status word per row.
    pub status: Vec<u16>,
    /// Readings the compensator rejected.
    pub rejected: usize,
}

/// Compensate one run with `table`.
///
/// # Errors
/// The table does not load into a `Compensator<1, 32>`.
pub fn compensate_run(table: &Table, run: &Run) -> Result<Compensated, qfa_thermal::table::Error> {
    // One row is one fast-path cycle; a log's rows may be longer than the default 3-s
    // staleness limit (the project's 10-s rows), although each row carries a fresh reading.
    // Staleness then means "no reading for 1.5 rows", else every row of such a log would be
    // flagged stale and no held-out figure could be formed.
    let default = Config::default();
    let max_interval_s = run.samples.iter().map(|s| s.interval_s).fold(0.0, f64::max);
    let row_ticks = (1.5 * max_interval_s / f64::from(default.tick_s)).ceil().min(f64::from(u32::MAX)) as u32;
    let config = Config { stale_after_ticks: default.stale_after_ticks.max(row_ticks), ..default };
    let mut c = Compensator::<1, RATE_WINDOW>::new(config);
    c.set_table(table.clone())?;
    let tick_s = f64::from(c.config().tick_s);
    let mut out = Compensated {
        accel_g: Vec::with_capacity(run.samples.len()),
        status: Vec::with_capacity(run.samples.len()),
        rejected: 0,
    };
    for s in &run.samples {
        if let Some(t) = s.temp_c {
            let raw = (t * 16.0).round() as i16;
            if c.on_raw((s.time_s * 1000.0).round() as u32, raw).is_err() {
                out.rejected += 1;
            }
        }
        let ticks = (s.interval_s / tick_s).round() as u32;
        let o = c.cycle([s.pulses as i32], ticks);
        out.accel_g.push(f64::from(o.dv_mps[0]) / (f64::from(G0) * s.interval_s));
        out.status.push(o.status.0);
    }
    Ok(out)
}

/// Compensate every run of a log.
///
/// # Errors
/// As [`compensate_run`].
pub fn compensate_log(
    table: &Table,
    log: &Log,
    progress: Option<&indicatif::ProgressBar>,
) -> Result<Vec<Compensated>, qfa_thermal::table::Error> {
    log.runs
        .iter()
        .map(|r| {
            let c = compensate_run(table, r);
            if let Some(pb) = progress {
                pb.inc(1);
            }
            c
        })
        .collect()
}

/// Whether a status word means "no temperature-based compensation yet".
#[must_use]
pub fn not_compensated(status: u16) -> bool {
    Status(status).contains(Status::NO_TABLE) || Status(status).contains(Status::TEMP_STALE)
}

/// Why a static log cannot be compensated.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum StaticCompensateError {
    /// The table has a different number of axes than the log.
    AxisCount {
        /// Table axes.
        table: usize,
        /// Log axes.
        log: usize,
    },
    /// Writing failed.
    Io(String),
}

impl std::fmt::Display for StaticCompensateError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::AxisCount { table, log } => {
                write!(f, "the table has {table} axis(es), the log {log}: use the table calibrated on this kind of log")
            }
            Self::Io(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for StaticCompensateError {}

/// Status of a compensated static row.
#[must_use]
pub fn static_status(valid: bool, clamped: bool) -> &'static str {
    match (valid, clamped) {
        (false, _) => "no_temperature",
        (true, true) => "clamped",
        (true, false) => "ok",
    }
}

/// Compensate a static log with a table of the same axes: per axis, `a − K0(T̂, Ṫ, slots)`
/// with K0 from the root crate's `AxisModel::evaluate` fed by its `RateEstimator<32>`
/// (until the firmware has a sample-mode path). Writes `time_s,temp_c,<axes…>,status`
/// in g; `status` is `ok`, `clamped` (T or Ṫ outside the calibrated range on some axis) or
/// `no_temperature` (no estimate yet: the output is then the raw reading).
///
/// # Errors
/// Axis count mismatch or I/O.
pub fn compensate_static<W: std::io::Write>(
    table: &Table,
    log: &crate::log::static_log::StaticLog,
    w: W,
) -> Result<(), StaticCompensateError> {
    if table.axes.len() != log.axes.len() {
        return Err(StaticCompensateError::AxisCount { table: table.axes.len(), log: log.axes.len() });
    }
    let traces: Vec<crate::pairing::Trace> = log
        .axes
        .iter()
        .zip(&table.axes)
        .map(|(ax, model)| {
            let s = crate::fit::StaticSeries { time_s: &log.time_s, temp_c: &log.temp_c, accel_g: &ax.accel_g };
            s.model_trace(model)
        })
        .collect();
    let io = |e: &dyn std::fmt::Display| StaticCompensateError::Io(e.to_string());
    let mut wr = csv::Writer::from_writer(w);
    let mut head = vec!["time_s".to_string(), "temp_c".to_string()];
    head.extend(log.axes.iter().map(|a| a.name.clone()));
    head.push("status".to_string());
    wr.write_record(&head).map_err(|e| io(&e))?;
    for i in 0..log.rows() {
        let mut rec = vec![format!("{:.6}", log.time_s[i]), format!("{:.4}", log.temp_c[i])];
        let valid = traces.iter().all(|t| t.valid[i]);
        let clamped = traces.iter().any(|t| t.clamped[i]);
        for (ax, tr) in log.axes.iter().zip(&traces) {
            let k0 = if tr.valid[i] { tr.ext_k0_g[i] } else { 0.0 };
            rec.push(format!("{:.9}", ax.accel_g[i] - k0));
        }
        rec.push(static_status(valid, clamped).to_string());
        wr.write_record(&rec).map_err(|e| io(&e))?;
    }
    wr.flush().map_err(|e| io(&e))
}
