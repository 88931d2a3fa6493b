//! One unit of a batch: read, calibrated exactly as `qfa-lab calibrate` calibrates a static
//! log (the same function writes the same files), then described for the fleet in one
//! common form.
//!
//! Why a common form: each unit's table takes the structure its own cross-validation
//! chose (a grid, a branch step, a lag…), so two tables' numbers need not mean the same
//! thing. The fleet reads the same figures from every unit's own model, per axis: the
//! branches' mean curve as a cubic in `d = T − 25 °C` through the grid's nodes (the output at
//! 25 °C, the slope and the curvature there), the heating/cooling split at 25 °C as the rate
//! goes to zero (the grid's branches and the play; a lag or a creep, whose apparent split
//! grows with the ramp's rate, is the model's own slot and not counted), and the lag.
//! Beside it, one figure is measured on the rows themselves: the heating/cooling step on
//! the log's own ramps, fitted with the unit's die lag (one lag for its axes, searched
//! finely), which holds the hysteresis whatever shape the unit's model gave it (a step, a
//! play or a creep). A split read from a fit with no lag hid a unit with three times the
//! fleet's split inside the spread of the units' lags; read only from the model, it missed
//! units whose models carried the split as a creep. A unit whose rows hold one branch gets
//! neither.

use std::path::Path;

mod steps;
use steps::residual_steps;
pub use steps::{
    ResidualStep, NOT_THERMAL_SHARE, STEP_SHARPNESS, STEP_SHORT_WINDOW_S, STEP_WINDOW_S, STEP_Z, TURN_WINDOW_S,
};

use serde::{Deserialize, Serialize};

use super::input::UnitInput;
use super::{BatchError, UnitFault};
use qfa_calibrate::fit::{
    BranchMode, CurveShape, StaticDesign, StaticFit, StaticSeries, StaticStructure, StaticTraces,
};
use qfa_calibrate::static_cal::{self, is_one_branch, StaticCalOptions};
use qfa_lint::Severity;
use qfa_log::open::{open_bytes, OpenedLog};
use qfa_log::static_log::StaticLog;
use qfa_report::verdict::{LimitsChoice, Measured, Outcome, STATIC_KEYS};

/// What a `unit.json` written before a figure existed holds for it.
fn not_read() -> Measured {
    Measured::NotComputed { not_computed: "not in this unit.json".into() }
}

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
    /// Heating minus cooling at 25 °C as the rate goes to zero, mg (not computed on one
    /// branch): the grid's branches there and twice the play's weight; a lag or a creep is left out.
    pub split_mg: Measured,
    /// Heating minus cooling on the log's own ramps, mg (not computed on one branch): a
    /// free-node curve and a constant step fitted on every row under the die lag that fits
    /// the unit's axes best (the module docs).
    #[serde(default = "not_read")]
    pub ramp_split_mg: Measured,
    /// The model's sensor lag, s (0: it holds none). Shown, not flagged: the search's lags
    /// are 30, 60, 120, 240 and 480 s, so two units with the same die may differ by one step.
    #[serde(default)]
    pub lag_s: f64,
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
    /// Mean temperature reading per minute, per leg of the chamber run the fleet's units
    /// share (a static log: one, on its own clock; a cycling log: each program's run).
    pub temp_minutes: Vec<SensorLeg>,
    /// What the population prior needs of a static unit's rows ([`super::prior`]); `None`
    /// for a QFA unit, whose statistics are `qfa_normal`.
    pub normal: Option<super::prior::UnitNormal>,
    /// What the population prior needs of a QFA unit's rows ([`super::qfa::QfaNormal`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub qfa_normal: Option<super::qfa::QfaNormal>,
    /// The clearest step in each axis's residual after its own table, where one stands
    /// out of the row-to-row noise ([`ResidualStep`] says how it is found).
    #[serde(default)]
    pub steps: Vec<ResidualStep>,
    /// Rows the static reader skipped as one-row glitches (`qfa_log::robust::glitches`), per
    /// hour of the unit's log: a fleet figure of its own, so a unit whose output spikes
    /// more than its peers' is seen, and a spike never moves the held-out figure it is
    /// judged by (the skipped rows are neither fitted nor scored).
    #[serde(default)]
    pub glitches_per_h: f64,
    /// What the log's checks (`qfa-lint`) warn of, one line each: rows the reader skipped
    /// (rows written twice, empty fields), gaps, a unit assumed. Not a reason: the figures
    /// are the rows kept, judged held out; shown on the certificate and the console so the
    /// logger is looked at.
    #[serde(default)]
    pub log_warnings: Vec<String>,
    /// A QFA unit's figures (a cycling log); `None` for a static unit, whose figures are
    /// the `descriptor`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub qfa: Option<super::qfa::QfaFigures>,
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
    /// How a unit's failure names the options it needs: the front end's (`--accel-unit`
    /// for `qfa-lab`, `accel_unit=` for Python); a manifest's unit names the manifest's
    /// keys whichever ([`crate::input::UnitInput::spelling`]).
    pub spelling: qfa_log::spelling::Spelling,
}

/// Calibrate one unit into `dir` (its folder) and describe it; a refusal is a
/// [`UnitOutcome::Failed`], not an error: one bad unit does not stop a batch.
#[must_use]
pub(crate) fn calibrate_unit(input: &UnitInput, dir: &Path, opts: &UnitOptions) -> UnitResult {
    let outcome = match calibrate(input, dir, opts) {
        Ok(c) => UnitOutcome::Calibrated(Box::new(c)),
        // Rows left out of a chamber log's unit may be why (a unit blank on every row).
        Err(e) => {
            let e = e.message(input.spelling.unwrap_or(opts.spelling));
            UnitOutcome::Failed {
                reason: match input.left_out {
                    0 => e,
                    n => format!("{e} ({n} row(s) of the chamber log hold no count of this unit, left out of its log)"),
                },
            }
        }
    };
    UnitResult { serial: input.serial.clone(), source: input.source.clone(), outcome }
}

fn calibrate(input: &UnitInput, dir: &Path, opts: &UnitOptions) -> Result<Calibrated, BatchError> {
    let bytes = input.bytes()?;
    match open_bytes(&bytes, &input.flags).map_err(|e| BatchError::Unit(UnitFault::Open(Box::new(e))))? {
        OpenedLog::Static(log) => calibrate_static(input, &bytes, &log, dir, opts),
        OpenedLog::Cycling(log) => super::qfa::calibrate(input, &log, dir, opts),
        OpenedLog::Single(_) | OpenedLog::Autopilot(_) => Err(BatchError::Unit(UnitFault::NotBatchable)),
    }
}

/// Said on every batch unit's own report: the batch, not the unit's calibration, decides
/// which table is flashed (a unit of partial coverage flashes the population prior's), and
/// the certificate names it.
pub(crate) const CERTIFICATE_NAMES_THE_TABLE: &str = "a unit of a batch: flash the table its certificate \
     (certificate.html) names, which is table_prior.bin when the fleet finds its coverage partial, not table.bin";

/// A static (MEMS) unit: calibrated as `qfa-lab calibrate` calibrates a static log.
fn calibrate_static(
    input: &UnitInput,
    bytes: &[u8],
    log: &StaticLog,
    dir: &Path,
    opts: &UnitOptions,
) -> Result<Calibrated, BatchError> {
    opts.limits.check_applies("static", &STATIC_KEYS).map_err(|e| BatchError::Unit(UnitFault::Limits(e)))?;
    let warnings = log_warnings(&qfa_lint::lint_static(bytes, log));
    let notes: Vec<String> = std::iter::once(CERTIFICATE_NAMES_THE_TABLE.to_string())
        .chain(warnings.iter().map(|w| format!("lint: {w}")))
        .collect();
    let exports = qfa_calibrate::export::ExportOptions::default();
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
    let (cal, v) = static_cal::calibrate_static_into(dir, log, &run, &notes)
        .map_err(|e| BatchError::Unit(UnitFault::Calibration(Box::new(e))))?;
    let (bin, crc) = super::encoded(&cal.table, dir)?;
    let r = &cal.report;
    let descriptor = describe(log, &cal.fits, &opts.cal, is_one_branch(r.branch_rows))?;
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
        glitches_per_h: glitches_per_hour(log),
        log_warnings: warnings,
        table_crc32: format!("{crc:08x}"),
        table_bytes: bin.len(),
        steps: residual_steps(
            &log.time_s,
            &log.temp_c,
            &cal.plot,
            &descriptor.iter().map(|d| d.slope_ug_per_c).collect::<Vec<f64>>(),
        ),
        descriptor,
        temp_minutes: temp_minutes(log),
        normal: Some(normal(log, opts.cal.deadband_c_per_min)),
        qfa_normal: None,
        qfa: None,
    })
}

/// The log checks' warnings (and worse) among `findings`, each as one line: the check,
/// what it found and its evidence (`[warning] rows: 8550 row(s) skipped (8550
/// duplicate timestamp row(s) skipped (line 3, 5, …))`).
pub(crate) fn log_warnings(findings: &[qfa_lint::Finding]) -> Vec<String> {
    findings
        .iter()
        .filter(|f| f.severity >= Severity::Warning)
        .map(|f| match f.evidence.as_str() {
            "" => format!("[{}] {}: {}", f.severity, f.check, f.what),
            e => format!("[{}] {}: {} ({e})", f.severity, f.check, f.what),
        })
        .collect()
}

/// The fleet's common form of every axis, read from the unit's own models `fits` (what its
/// `table.bin` holds, one per axis of `log`; see the module docs).
///
/// # Errors
/// The cubic through an axis's nodes cannot be solved.
pub(crate) fn describe(
    log: &StaticLog,
    fits: &[StaticFit],
    opts: &StaticCalOptions,
    one_branch: bool,
) -> Result<Vec<AxisDescriptor>, BatchError> {
    let ramp_splits = ramp_splits_g(log, opts, one_branch)?;
    log.axes
        .iter()
        .zip(fits)
        .zip(ramp_splits)
        .map(|((a, fit), ramp_split_g)| {
            let model = &fit.axis;
            let b = &model.bias;
            // The branches' mean lies on the curve the element temperature drives (a lag is
            // the model's own slot, not part of the curve): its cubic in d = T − 25 °C by
            // least squares through the nodes.
            let g = b.heating_g.len();
            let mut x = Vec::with_capacity(4 * g);
            let mut y = Vec::with_capacity(g);
            for j in 0..g {
                let d = f64::from(b.t_start_c) + f64::from(b.t_step_c) * j as f64 - DESCRIPTOR_T_C;
                x.extend([1.0, d, d * d, d * d * d]);
                y.push(0.5 * (f64::from(b.heating_g[j]) + f64::from(b.cooling_g[j])));
            }
            let c = qfa_calibrate::solver::lstsq(&x, 4, &y)
                .map_err(|source| {
                    BatchError::Unit(UnitFault::Descriptor { axis: a.name.clone(), source: Box::new(source) })
                })?
                .coef;
            let one = || Measured::NotComputed { not_computed: "the rows hold one branch".into() };
            Ok(AxisDescriptor {
                axis: a.name.clone(),
                level_mg: (fit.reference_g + c[0]) * 1e3,
                slope_ug_per_c: c[1] * 1e6,
                curvature_ug_per_c2: c[2] * 1e6,
                cubic_ug_per_c3: c[3] * 1e6,
                split_mg: if one_branch {
                    one()
                } else {
                    Measured::Value(f64::from(quasi_static_split_g(model)) * 1e3)
                },
                ramp_split_mg: ramp_split_g.map_or_else(one, |s| Measured::Value(s * 1e3)),
                lag_s: model.ext.sensor_lag.map_or(0.0, |l| f64::from(l.tau_s)),
            })
        })
        .collect()
}

/// Each axis's heating-minus-cooling on the log's own ramps with the unit's die lag fitted
/// out, g (`None` on one branch): the constant step of a free-node curve and a step fitted
/// on every row under one lag for all axes (one die), the lag the one that leaves the least
/// squared residual over the axes, searched from 0 to [`RAMP_LAG_MAX_S`] in
/// [`RAMP_LAG_COARSE_S`] steps and then [`RAMP_LAG_FINE_S`] either side of the best.
///
/// Why it is searched here and not read from the unit's model: the model's search tries
/// lags in doublings (30…480 s) beside a creep and a play, and one chamber cycle does not
/// tell those apart, so its split is the part of the hysteresis it did not give to a creep.
/// With no lag a die's lag is read as a split (its apparent split is the slope × τ × the
/// ramp's rate), and the spread of the units' lags hides a unit with three times the split.
/// A lag fitted jointly with the step, from the slope's change with temperature and the
/// turns, leaves the step to the hysteresis. It costs about 15 small solves per unit
/// (13 ms of a unit's 0.77 s calibration, measured on the second generator's fleet).
fn ramp_splits_g(log: &StaticLog, opts: &StaticCalOptions, one_branch: bool) -> Result<Vec<Option<f64>>, BatchError> {
    if one_branch {
        return Ok(vec![None; log.axes.len()]);
    }
    let deadband = opts.deadband_c_per_min;
    let view = StaticSeries::view_of(&log.time_s, &log.temp_c, deadband);
    let series0 = StaticSeries { view: &view, accel_g: &log.axes[0].accel_g };
    let train = vec![true; log.rows()];
    // Every axis under one lag (one die): the sum of the axes' squared residuals, and each
    // axis's step.
    let fit_all = |tau_s: f32| -> Result<(f64, Vec<Option<f64>>), BatchError> {
        let descriptor = |source| BatchError::Unit(UnitFault::RampSplit { lag_s: tau_s, source: Box::new(source) });
        let structure = StaticStructure {
            shape: CurveShape::Nodes,
            branches: BranchMode::Offset,
            lag_tau_s: (tau_s > 0.0).then_some(tau_s),
            creep_tau_s: None,
            play_half_width_c: None,
        };
        let traces = StaticTraces::new(&series0, &structure, deadband);
        let design = StaticDesign::new(&traces, &train, opts.grid_points, opts.block).map_err(descriptor)?;
        let mut score = 0.0;
        let mut steps = Vec::with_capacity(log.axes.len());
        for a in &log.axes {
            let fit = design.fit(&a.accel_g).map_err(descriptor)?;
            score += fit.ls.rms * fit.ls.rms;
            let b = &fit.axis.bias;
            steps.push(Some(f64::from(b.heating_g[0]) - f64::from(b.cooling_g[0])));
        }
        Ok((score, steps))
    };
    // The coarse lags, then the fine step either side of the best of them.
    let mut tried: Vec<(f32, f64, Vec<Option<f64>>)> = Vec::new();
    for k in 0..=RAMP_LAG_MAX_S as usize / RAMP_LAG_COARSE_S as usize {
        let tau = RAMP_LAG_COARSE_S * k as f32;
        let (score, steps) = fit_all(tau)?;
        tried.push((tau, score, steps));
    }
    let best =
        |tried: &[(f32, f64, Vec<Option<f64>>)]| tried.iter().min_by(|a, b| a.1.total_cmp(&b.1)).map_or(0.0, |t| t.0);
    let coarse = best(&tried);
    for tau in [coarse - RAMP_LAG_FINE_S, coarse + RAMP_LAG_FINE_S] {
        if (0.0..=RAMP_LAG_MAX_S).contains(&tau) {
            let (score, steps) = fit_all(tau)?;
            tried.push((tau, score, steps));
        }
    }
    let pick = best(&tried);
    Ok(tried.into_iter().find(|t| t.0 == pick).map_or_else(|| vec![None; log.axes.len()], |t| t.2))
}

/// The longest die lag the ramp split's search tries, s: twice the longest a chamber
/// fixture's units showed in either population generator (240 s).
const RAMP_LAG_MAX_S: f32 = 480.0;
/// The search's coarse step, s.
const RAMP_LAG_COARSE_S: f32 = 40.0;
/// Its fine step, s: either side of the best coarse lag.
const RAMP_LAG_FINE_S: f32 = 20.0;

/// The heating-minus-cooling bias `model` holds at 25 °C as the rate goes to zero, g: the
/// grid's branches there and twice the play's weight. A lag and a creep add to a ramp's
/// apparent split in proportion to its rate (the slope × τ × Ṫ, the creep's gain × τ × Ṫ)
/// and vanish on a slow one, so they are left out: the split is the unit's hysteresis, not
/// its die's lag.
#[must_use]
pub(crate) fn quasi_static_split_g(model: &qfa_thermal::AxisModel) -> f32 {
    use qfa_thermal::model::Branch;
    let b = &model.bias;
    let t = (DESCRIPTOR_T_C as f32).clamp(b.t_start_c, b.t_end_c());
    let play = model.ext.bias_branch_hysteresis.map_or(0.0, |h| 2.0 * h.weight_g);
    b.k0(t, Branch::Heating) - b.k0(t, Branch::Cooling) + play
}

/// The prior's statistics of `log`: its rows with a temperature, each on the branch the
/// firmware's logic puts it (deadband `deadband`, °C/min).
#[must_use]
pub(crate) fn normal(log: &StaticLog, deadband: f32) -> super::prior::UnitNormal {
    let view = StaticSeries::view_of(&log.time_s, &log.temp_c, deadband);
    let tr = qfa_log::pairing::trace_view(&view, &qfa_thermal::Extensions::default(), deadband);
    let rows: Vec<usize> = (0..log.rows()).filter(|&i| tr.valid[i]).collect();
    let pick = |v: &[f64]| rows.iter().map(|&i| v[i]).collect::<Vec<f64>>();
    let (time, temp) = (pick(&log.time_s), pick(&tr.temp_c));
    let branch: Vec<qfa_thermal::model::Branch> = rows.iter().map(|&i| tr.branch[i]).collect();
    let axes: Vec<(String, Vec<f64>)> = log.axes.iter().map(|a| (a.name.clone(), pick(&a.accel_g))).collect();
    let views: Vec<(&str, &[f64])> = axes.iter().map(|(n, v)| (n.as_str(), v.as_slice())).collect();
    super::prior::normal_of(&time, &temp, &branch, &views)
}

/// One leg of a chamber run as a unit's temperature sensor read it: the mean reading per
/// minute (60 s) of the leg's clock, which every unit through that leg shares, and where
/// the leg sits on the unit's own clock (for a drift in °C/h).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensorLeg {
    /// The leg: empty for a static log (one leg, its clock the log's); `PROGRAM/RUN` for a
    /// cycling log's run (its clock restarts with each run, and every unit's run of that
    /// name follows the same program).
    pub leg: String,
    /// The leg's start on the unit's own clock, h (a cycling log's runs back to back in the
    /// log's order, as its ageing takes them; 0 for a static log).
    pub start_h: f64,
    /// `(minute of the leg's clock, mean °C)`.
    pub minutes: Vec<(i64, f64)>,
}

/// A static log's one leg: the mean reading per [`TEMP_MEAN_S`] of the log's own clock
/// (so the logs of one chamber run line up, whichever row each starts at).
#[must_use]
pub(crate) fn temp_minutes(log: &StaticLog) -> Vec<SensorLeg> {
    let clock: Vec<f64> = log.time_s.iter().map(|t| t + log.time_origin_s).collect();
    let minutes = qfa_calibrate::metrics::time_bin_means(log.temp_c.iter().copied(), &clock, TEMP_MEAN_S)
        .into_iter()
        .map(|(k, m, _)| (k, m))
        .collect();
    vec![SensorLeg { leg: String::new(), start_h: 0.0, minutes }]
}

/// A cycling log's legs, one per run: its readings' mean per [`TEMP_MEAN_S`] of the run's
/// clock (rows before the run's first reading left out), each run starting where the one
/// before it ended on the unit's clock ([`qfa_log::cycling::Log::run_starts_s`], the ageing's).
#[must_use]
pub(crate) fn cycling_temp_minutes(log: &qfa_log::cycling::Log) -> Vec<SensorLeg> {
    log.runs
        .iter()
        .zip(log.run_starts_s())
        .map(|(run, start_s)| {
            let read: Vec<(f64, f64)> = run.samples.iter().filter_map(|s| s.temp_c.map(|t| (s.time_s, t))).collect();
            let time: Vec<f64> = read.iter().map(|r| r.0).collect();
            let minutes = qfa_calibrate::metrics::time_bin_means(read.iter().map(|r| r.1), &time, TEMP_MEAN_S)
                .into_iter()
                .map(|(k, m, _)| (k, m))
                .collect();
            SensorLeg { leg: format!("{}/{}", run.program, run.run), start_h: start_s / 3600.0, minutes }
        })
        .collect()
}

/// The rows `log`'s reader skipped as glitches, per hour between its first and last kept
/// rows (0 for a log shorter than a second, which calibration refuses before this).
fn glitches_per_hour(log: &StaticLog) -> f64 {
    let span_h = match (log.time_s.first(), log.time_s.last()) {
        (Some(a), Some(b)) if b - a >= 1.0 => (b - a) / 3600.0,
        _ => return 0.0,
    };
    log.skipped.glitch.count as f64 / span_h
}
