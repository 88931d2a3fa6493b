//! One unit of a batch: read, calibrated exactly as `qfa-lab calibrate` calibrates a static
//! log (the same function writes the same files), then described for the fleet in one
//! common form.
//!
//! Why a common form: each unit's table takes the structure its own cross-validation
//! chose (a grid, a branch step, a lag…), so two tables' numbers need not mean the same
//! thing. The fleet compares units through one descriptor fitted to every unit alike: per
//! axis, a cubic in `d = T − 25 °C` plus a constant heating/cooling step (the lab's one
//! static fitter with that structure, on every row), read as the output at 25 °C, the
//! slope and curvature there, and the split. A unit whose rows hold one branch gets the
//! cubic alone; its split is not computed.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::input::UnitInput;
use super::{BatchError, UnitFault};
use crate::fit::{fit_static_traced, BranchMode, CurveShape, StaticSeries, StaticStructure, StaticTraces};
use crate::lint::Severity;
use crate::static_cal::{self, is_one_branch, StaticCalOptions};
use qfa_log::open::{open_bytes, OpenedLog};
use qfa_log::static_log::StaticLog;
use qfa_report::verdict::{LimitsChoice, Measured, Outcome};

/// Temperature the descriptor is read at, °C.
pub(crate) const DESCRIPTOR_T_C: f64 = 25.0;
/// Length of the temperature means kept for the fleet's sensor comparison, s.
pub(crate) const TEMP_MEAN_S: f64 = 60.0;

/// One axis in the fleet's common form.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AxisDescriptor {
    /// Axis (`ax`, `ay`, `az`).
    pub axis: String,
    /// Output at 25 °C between the branches, mg (gravity's share on the axis included).
    pub level_mg: f64,
    /// Slope at 25 °C, µg/°C.
    pub slope_ug_per_c: f64,
    /// Curvature at 25 °C (the `d²` coefficient), µg/°C².
    pub curvature_ug_per_c2: f64,
    /// The `d³` coefficient, µg/°C³.
    pub cubic_ug_per_c3: f64,
    /// Heating minus cooling, mg (not computed on one branch).
    pub split_mg: Measured,
}

/// Everything the fleet needs of a calibrated unit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Calibrated {
    /// The unit's verdict against the limits.
    pub outcome: Outcome,
    /// Each limit failed, in words (empty on PASS).
    pub failed_limits: Vec<String>,
    /// Held-out bias RMS per axis, mg.
    pub held_out_mg: Vec<(String, Measured)>,
    /// The structure each axis's table took.
    pub structures: Vec<(String, String)>,
    /// Temperature span of its rows, °C.
    pub temp_c: [f64; 2],
    /// Its rows hold one branch only (heating-only or cooling-only).
    pub one_branch: bool,
    /// Rows read.
    pub rows: usize,
    /// The CRC-32 in `table.bin`'s header (what the firmware checks when it loads it).
    pub table_crc32: String,
    /// Bytes of `table.bin`.
    pub table_bytes: usize,
    /// The common form, per axis.
    pub descriptor: Vec<AxisDescriptor>,
    /// Mean temperature reading per minute of its clock: `(minute, °C)`.
    pub temp_minutes: Vec<(i64, f64)>,
    /// What the population prior needs of its rows ([`super::prior`]).
    pub normal: super::prior::UnitNormal,
}

/// A unit's result: calibrated, or why not.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UnitOutcome {
    /// Calibrated; its files are in its folder.
    Calibrated(Box<Calibrated>),
    /// Refused or failed, with the reason (the last good state: nothing written for it
    /// beyond `unit.json`).
    Failed {
        /// Why.
        reason: String,
    },
}

/// One unit's result as `unit.json` holds it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct UnitResult {
    /// Serial number.
    pub serial: String,
    /// Where its rows came from.
    pub source: String,
    /// The outcome.
    pub outcome: UnitOutcome,
}

/// Settings every unit shares.
#[derive(Clone, Debug, Default)]
pub struct UnitOptions {
    /// Static calibration settings.
    pub cal: StaticCalOptions,
    /// Limits.
    pub limits: LimitsChoice,
    /// Draw each unit's plot.
    pub plots: bool,
}

/// Calibrate one unit into `dir` (its folder) and describe it; a refusal is a
/// [`UnitOutcome::Failed`], not an error: one bad unit does not stop a batch.
#[must_use]
pub(crate) fn calibrate_unit(input: &UnitInput, dir: &Path, opts: &UnitOptions) -> UnitResult {
    let outcome = match calibrate(input, dir, opts) {
        Ok(c) => UnitOutcome::Calibrated(Box::new(c)),
        Err(e) => UnitOutcome::Failed { reason: e.to_string() },
    };
    UnitResult { serial: input.serial.clone(), source: input.source.clone(), outcome }
}

fn calibrate(input: &UnitInput, dir: &Path, opts: &UnitOptions) -> Result<Calibrated, BatchError> {
    let bytes = input.bytes()?;
    let log = match open_bytes(&bytes, &input.flags).map_err(|e| BatchError::Unit(UnitFault::Open(Box::new(e))))? {
        OpenedLog::Static(l) => l,
        _ => return Err(BatchError::Unit(UnitFault::NotStatic)),
    };
    let notes: Vec<String> = crate::lint::lint_static(&bytes, &log)
        .iter()
        .filter(|f| f.severity >= Severity::Warning)
        .filter_map(|f| f.to_string().lines().next().map(|l| format!("lint: {l}")))
        .collect();
    let exports = crate::export::ExportOptions::default();
    // The page names the batch, not the worker process that wrote it (a thread, a shard,
    // a Dask worker), so every way of running the batch writes the same bytes.
    let command = format!("qfa-lab batch: unit {} (the batch's command is on fleet.html)", input.serial);
    let run = static_cal::StaticRun {
        opts: &opts.cal,
        exports: &exports,
        limits: &opts.limits,
        plots: opts.plots,
        progress: false,
        command: Some(&command),
    };
    let (cal, v) = static_cal::calibrate_static_into(dir, &log, &run, &notes)
        .map_err(|e| BatchError::Unit(UnitFault::Calibration(Box::new(e))))?;
    let (bin, crc) = super::encoded(&cal.table, dir)?;
    let r = &cal.report;
    Ok(Calibrated {
        outcome: v.outcome,
        failed_limits: v.failed(),
        held_out_mg: r
            .axes
            .iter()
            .map(|a| {
                let m = match a.ours.score() {
                    Some(s) => Measured::Value(s.rms_mg),
                    None => Measured::NotComputed { not_computed: format!("{}: no held-out figure", a.axis) },
                };
                (a.axis.clone(), m)
            })
            .collect(),
        structures: r.axes.iter().map(|a| (a.axis.clone(), a.structure.clone())).collect(),
        temp_c: [r.coverage.temp_c[0], r.coverage.temp_c[1]],
        one_branch: is_one_branch(r.branch_rows),
        rows: r.rows,
        table_crc32: format!("{crc:08x}"),
        table_bytes: bin.len(),
        descriptor: describe(&log, &opts.cal, is_one_branch(r.branch_rows))?,
        temp_minutes: temp_minutes(&log),
        normal: normal(&log, opts.cal.deadband_c_per_min),
    })
}

/// The fleet's common form of every axis of `log` (see the module docs).
///
/// # Errors
/// The descriptor fit failed.
pub(crate) fn describe(
    log: &StaticLog,
    opts: &StaticCalOptions,
    one_branch: bool,
) -> Result<Vec<AxisDescriptor>, BatchError> {
    let structure = StaticStructure {
        shape: CurveShape::Cubic,
        branches: if one_branch { BranchMode::Single } else { BranchMode::Offset },
        lag_tau_s: None,
        creep_tau_s: None,
        play_half_width_c: None,
    };
    let series0 = StaticSeries { time_s: &log.time_s, temp_c: &log.temp_c, accel_g: &log.axes[0].accel_g };
    let traces = StaticTraces::new(&series0, &structure, opts.deadband_c_per_min);
    let train = vec![true; log.rows()];
    log.axes
        .iter()
        .map(|a| {
            let series = StaticSeries { time_s: &log.time_s, temp_c: &log.temp_c, accel_g: &a.accel_g };
            let fit = fit_static_traced(&series, &traces, &train, opts.grid_points, opts.block).map_err(|source| {
                BatchError::Unit(UnitFault::Descriptor { axis: a.name.clone(), source: Box::new(source) })
            })?;
            let b = &fit.axis.bias;
            // The nodes lie on a cubic in T: fit it back in d = T − 25 °C, exactly.
            let g = b.heating_g.len();
            let mut x = Vec::with_capacity(4 * g);
            let mut y = Vec::with_capacity(g);
            for j in 0..g {
                let d = f64::from(b.t_start_c) + f64::from(b.t_step_c) * j as f64 - DESCRIPTOR_T_C;
                x.extend([1.0, d, d * d, d * d * d]);
                y.push(0.5 * (f64::from(b.heating_g[j]) + f64::from(b.cooling_g[j])));
            }
            let c = crate::solver::lstsq(&x, 4, &y)
                .map_err(|source| {
                    BatchError::Unit(UnitFault::Descriptor { axis: a.name.clone(), source: Box::new(source) })
                })?
                .coef;
            let split = f64::from(b.heating_g[0]) - f64::from(b.cooling_g[0]);
            Ok(AxisDescriptor {
                axis: a.name.clone(),
                level_mg: (fit.reference_g + c[0]) * 1e3,
                slope_ug_per_c: c[1] * 1e6,
                curvature_ug_per_c2: c[2] * 1e6,
                cubic_ug_per_c3: c[3] * 1e6,
                split_mg: if one_branch {
                    Measured::NotComputed { not_computed: "the rows hold one branch".into() }
                } else {
                    Measured::Value(split * 1e3)
                },
            })
        })
        .collect()
}

/// The prior's statistics of `log`: its rows with a temperature, each on the branch the
/// firmware's logic puts it (deadband `deadband`, °C/min).
#[must_use]
pub(crate) fn normal(log: &StaticLog, deadband: f32) -> super::prior::UnitNormal {
    let series = StaticSeries { time_s: &log.time_s, temp_c: &log.temp_c, accel_g: &log.axes[0].accel_g };
    let tr = series.trace(&qfa_thermal::Extensions::default(), deadband);
    let rows: Vec<usize> = (0..log.rows()).filter(|&i| tr.valid[i]).collect();
    let pick = |v: &[f64]| rows.iter().map(|&i| v[i]).collect::<Vec<f64>>();
    let (time, temp) = (pick(&log.time_s), pick(&tr.temp_c));
    let branch: Vec<qfa_thermal::model::Branch> = rows.iter().map(|&i| tr.branch[i]).collect();
    let axes: Vec<(String, Vec<f64>)> = log.axes.iter().map(|a| (a.name.clone(), pick(&a.accel_g))).collect();
    let views: Vec<(&str, &[f64])> = axes.iter().map(|(n, v)| (n.as_str(), v.as_slice())).collect();
    super::prior::normal_of(&time, &temp, &branch, &views)
}

/// Mean temperature reading per [`TEMP_MEAN_S`] of the log's own clock (so the logs of
/// one chamber run line up, whichever row each starts at).
#[must_use]
pub(crate) fn temp_minutes(log: &StaticLog) -> Vec<(i64, f64)> {
    let clock: Vec<f64> = log.time_s.iter().map(|t| t + log.time_origin_s).collect();
    crate::metrics::time_bin_means(log.temp_c.iter().copied(), &clock, TEMP_MEAN_S)
        .into_iter()
        .map(|(k, m, _)| (k, m))
        .collect()
}
