//! Compensation of a log through the root crate's `Compensator<1, 32>`, as the firmware runs it.
//!
//! Per row, in order: if the row has a reading, `on_raw(time_s·1000 ms, round(temp_c·16))`
//! (a rejected reading leaves the last good compensation in force, as on target); then
//! `cycle([pulses], interval_s·10⁶ ticks)` with the default 1-µs tick. The reading is
//! applied before the row's pulses because it was taken inside that interval (the same
//! alignment the fit uses, see [`crate::pairing::trace_run`]).
//! `accel_g = Δv / (g0 · interval_s)`: the compensated mean specific force of the interval.
//! Each run starts a fresh compensator (each run is a fresh power-up in the test).

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
    let mut c = Compensator::<1, RATE_WINDOW>::new(Config::default()).expect("the default config is valid");
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
        out.status.push(o.status.bits());
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
    Status::from_bits_retain(status).intersects(Status::NO_TABLE | Status::TEMP_STALE)
}
