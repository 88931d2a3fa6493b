//! Calibration of a static multi-axis log: per axis, the firmware's bias model (grid with
//! heating/cooling branches and extension slots) fitted through the root crate's estimator
//! and model, scored against the peers on held-out rows.
//!
//! # Held-out split (the same for every row of the report)
//! Fit on every row up to and including the first row with the log's highest temperature
//! reading; evaluate on every row after it. For a chamber cycle that ends with a cooling
//! leg (the tofupilot log: 51.6 → −17.6 → 74.0 → 36.3 °C) this holds out the last leg, a
//! cooling leg over a range the training saw only while heating. A log whose maximum is in
//! its last tenth leaves too little to evaluate: that is an error, not a figure.
//!
//! # Model choice (no held-out data involved)
//! Each axis chooses among [`candidates`] (branch tie × `sensor_lag` τ × `bias_creep` τ)
//! by blocked cross-validation **inside the training rows**: the training rows are cut into
//! [`CV_FOLDS`] contiguous blocks; each block is predicted by a fit to the others (the
//! firmware's states still run through every row); the candidate with the lowest RMS over
//! all blocks wins, then is refitted on all training rows. The same rule runs on every log.
//!
//! # Figures
//! Held-out bias RMS per axis in mg: the RMS over held-out rows of `a − reference − bias`,
//! where `bias` is the model's K0 from the root crate's `AxisModel::evaluate` (ours) or the
//! peer's polynomial of the reading. `binned_mg` is the same over 60-s means (white noise
//! averaged down). A figure that cannot be formed is an error.

use std::fmt;
use std::path::Path;

use serde::Serialize;

use qfa_thermal::{Input, Table};

use crate::calibrate::fit::{
    encode, fit_static_axis, table_of_axes, BranchMode, CurveShape, FitError, StaticFit, StaticSeries, StaticStructure,
};
use crate::calibrate::metrics::rms;
use crate::calibrate::peers::{ardupilot_params, fit_peers, px4_params, Peers, Poly};
use crate::data::static_log::{Sampling, Skipped, StaticLog};

/// Contiguous cross-validation blocks in the training rows.
pub const CV_FOLDS: usize = 5;

/// Length of the averaging window of `binned_mg`, s.
pub const BIN_S: f64 = 60.0;

/// Why a static calibration failed.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum StaticCalError {
    /// The split leaves too few rows on one side.
    Split(String),
    /// A fit failed.
    Fit(String, FitError),
    /// A figure could not be computed.
    Figure(String),
    /// Writing an output failed.
    Io(String),
}

impl fmt::Display for StaticCalError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Split(s) => write!(f, "held-out split: {s}"),
            Self::Fit(axis, e) => write!(f, "fit of {axis}: {e}"),
            Self::Figure(s) => write!(f, "figure not computable: {s}"),
            Self::Io(s) => write!(f, "{s}"),
        }
    }
}

impl std::error::Error for StaticCalError {}

/// Settings.
#[derive(Clone, Debug)]
pub struct StaticCalOptions {
    /// Bias grid nodes.
    pub grid_points: usize,
    /// Rows averaged per equation.
    pub block: usize,
    /// Branch deadband, °C/min.
    pub deadband_c_per_min: f32,
    /// Candidate structures (default [`candidates`]).
    pub candidates: Vec<StaticStructure>,
}

impl Default for StaticCalOptions {
    fn default() -> Self {
        Self {
            grid_points: 16,
            block: 10,
            deadband_c_per_min: crate::data::pairing::branch_deadband_c_per_min(),
            candidates: candidates(),
        }
    }
}

/// The candidate structures: branch tie (single, constant step, free) × `sensor_lag` τ
/// (none, 30…480 s) × `bias_creep` τ (none, 60…600 s).
#[must_use]
pub fn candidates() -> Vec<StaticStructure> {
    let mut out = Vec::new();
    for branches in [BranchMode::Single, BranchMode::Offset, BranchMode::Free] {
        for lag in [None, Some(30.0), Some(60.0), Some(120.0), Some(240.0), Some(480.0)] {
            for creep in [None, Some(60.0), Some(180.0), Some(600.0)] {
                out.push(StaticStructure {
                    shape: CurveShape::Nodes,
                    branches,
                    lag_tau_s: lag,
                    creep_tau_s: creep,
                    play_half_width_c: None,
                });
            }
        }
    }
    out
}

/// Held-out figures of one model on one axis, mg.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Score {
    /// RMS over held-out rows, mg.
    pub rms_mg: f64,
    /// RMS over held-out 60-s means, mg.
    pub binned_mg: f64,
}

/// One axis of the report.
#[derive(Clone, Debug, Serialize)]
pub struct AxisReport {
    /// Role (`ax`, `ay`, `az`).
    pub axis: String,
    /// Column in the file.
    pub column: String,
    /// The constant the bias is measured from, g (training mean).
    pub reference_g: f64,
    /// The chosen structure.
    pub structure: String,
    /// Its cross-validation RMS on the training rows, mg.
    pub cv_rms_mg: f64,
    /// RMS over the training rows of the final fit (through the root crate), mg.
    pub train_rms_mg: f64,
    /// Ours (the flashed table through the root crate).
    pub ours: Score,
    /// PX4 / tofupilot cubic.
    pub cubic: Score,
    /// ArduPilot TCAL.
    pub ardupilot: Score,
    /// The paper's simple model.
    pub simple: Score,
    /// No compensation (the training mean removed).
    pub none: Score,
    /// Candidates a cross-validation fit refused (a table outside the root crate's limits,
    /// too few rows), with the reason.
    pub refused_candidates: Vec<String>,
    /// Held-out rows the model flagged as clamped (T or Ṫ outside the calibrated range).
    pub clamped_rows: usize,
}

/// `report.json` of a static calibration.
#[derive(Clone, Debug, Serialize)]
pub struct StaticReport {
    /// Kind of log.
    pub kind: &'static str,
    /// Columns used: (role, column, unit).
    pub columns: Vec<(String, String, String)>,
    /// Rows kept.
    pub rows: usize,
    /// Rows skipped by the reader.
    pub skipped: Skipped,
    /// Sampling regularity.
    pub sampling: Sampling,
    /// The split, in words.
    pub split: String,
    /// Time of the last training row, s (held-out rows come after it).
    pub split_time_s: f64,
    /// Training rows.
    pub train_rows: usize,
    /// Held-out rows.
    pub heldout_rows: usize,
    /// Training temperature range, °C.
    pub train_temp_c: (f64, f64),
    /// Held-out temperature range, °C.
    pub heldout_temp_c: (f64, f64),
    /// How the structure was chosen, in words.
    pub selection: String,
    /// Per axis.
    pub axes: Vec<AxisReport>,
}

/// A static calibration.
#[derive(Clone, Debug)]
pub struct StaticCalibration {
    /// The table (one axis per log axis).
    pub table: Table,
    /// Per-axis fits.
    pub fits: Vec<StaticFit>,
    /// Per-axis peers.
    pub peers: Vec<Peers>,
    /// The report.
    pub report: StaticReport,
}

/// Index of the last training row: the first row with the highest temperature.
/// Index of the last training row: the first row at the log's highest temperature (see the
/// module docs). Static discovery uses the same split.
///
/// # Errors
/// Fewer than a tenth of the rows on either side.
pub fn split_index(log: &StaticLog) -> Result<usize, StaticCalError> {
    let n = log.rows();
    let imax = (0..n).fold(0, |b, i| if log.temp_c[i] > log.temp_c[b] { i } else { b });
    let tenth = (n / 10).max(1);
    if n - imax - 1 < tenth {
        return Err(StaticCalError::Split(format!(
            "the highest temperature ({:.2} °C) is at row {} of {n}: fewer than a tenth of the rows lie after it, \
             nothing to evaluate on",
            log.temp_c[imax],
            imax + 1
        )));
    }
    if imax + 1 < tenth {
        return Err(StaticCalError::Split(format!(
            "the highest temperature is at row {} of {n}: fewer than a tenth of the rows to fit on",
            imax + 1
        )));
    }
    Ok(imax)
}

/// Held-out figures of residuals `resid` (g) at times `time_s`: RMS over the rows and over
/// their 60-s means, mg.
///
/// # Errors
/// No residual, or a non-finite one.
pub fn score(resid: &[f64], time_s: &[f64], what: &str) -> Result<Score, StaticCalError> {
    if resid.is_empty() {
        return Err(StaticCalError::Figure(format!("{what}: no held-out row had a model output")));
    }
    let mut bins: Vec<f64> = Vec::new();
    let (mut s, mut n, mut key) = (0.0, 0usize, (time_s[0] / BIN_S).floor());
    for (&r, &t) in resid.iter().zip(time_s) {
        let k = (t / BIN_S).floor();
        if k != key && n > 0 {
            bins.push(s / n as f64);
            s = 0.0;
            n = 0;
        }
        key = k;
        s += r;
        n += 1;
    }
    if n > 0 {
        bins.push(s / n as f64);
    }
    let out = Score { rms_mg: rms(resid) * 1e3, binned_mg: rms(&bins) * 1e3 };
    if !out.rms_mg.is_finite() || !out.binned_mg.is_finite() {
        return Err(StaticCalError::Figure(format!("{what}: non-finite residual")));
    }
    Ok(out)
}

/// Blocked cross-validation RMS (g) of `s` on the training rows `0..=last`.
fn cv_rms(
    series: &StaticSeries<'_>,
    last: usize,
    s: &StaticStructure,
    opts: &StaticCalOptions,
) -> Result<f64, FitError> {
    let n = last + 1;
    let mut sum = 0.0;
    let mut count = 0usize;
    for f in 0..CV_FOLDS {
        let (lo, hi) = (n * f / CV_FOLDS, n * (f + 1) / CV_FOLDS);
        let train: Vec<bool> = (0..series.time_s.len()).map(|i| i < n && !(lo..hi).contains(&i)).collect();
        let fit = fit_static_axis(series, &train, s, opts.grid_points, opts.deadband_c_per_min, opts.block)?;
        let tr = series.model_trace(&fit.axis);
        for i in lo..hi {
            if tr.valid[i] {
                let r = series.accel_g[i] - fit.reference_g - tr.ext_k0_g[i];
                sum += r * r;
                count += 1;
            }
        }
    }
    if count == 0 {
        return Err(FitError::TooFewRows { rows: 0, unknowns: s.unknowns(opts.grid_points) });
    }
    Ok((sum / count as f64).sqrt())
}

/// Calibrate a static log (see the module docs).
///
/// # Errors
/// A split that leaves nothing to evaluate, a failed fit, or a figure that cannot be formed.
pub fn calibrate_static(
    log: &StaticLog,
    opts: &StaticCalOptions,
    progress: bool,
) -> Result<StaticCalibration, StaticCalError> {
    let last = split_index(log)?;
    let n = log.rows();
    let train: Vec<bool> = (0..n).map(|i| i <= last).collect();
    let pb = if progress {
        indicatif::ProgressBar::new((log.axes.len() * opts.candidates.len()) as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    let mut fits = Vec::new();
    let mut peers = Vec::new();
    let mut axes = Vec::new();
    let ho_time: Vec<f64> = log.time_s[last + 1..].to_vec();
    for ax in &log.axes {
        let series = StaticSeries { time_s: &log.time_s, temp_c: &log.temp_c, accel_g: &ax.accel_g };
        // Model choice by cross-validation inside the training rows.
        let mut best: Option<(f64, StaticStructure)> = None;
        let mut refused: Vec<String> = Vec::new();
        for s in &opts.candidates {
            match cv_rms(&series, last, s, opts) {
                Ok(r) if best.is_none_or(|(b, _)| r < b) => best = Some((r, *s)),
                Ok(_) => {}
                Err(e) => refused.push(format!("{}: {e}", s.name())),
            }
            pb.inc(1);
        }
        let (cv, structure) = best.ok_or_else(|| {
            StaticCalError::Figure(format!(
                "{}: no candidate model could be fitted in cross-validation (first refusal: {})",
                ax.name,
                refused.first().map_or("none", String::as_str)
            ))
        })?;
        let fit = fit_static_axis(&series, &train, &structure, opts.grid_points, opts.deadband_c_per_min, opts.block)
            .map_err(|e| StaticCalError::Fit(ax.name.clone(), e))?;
        let tr = series.model_trace(&fit.axis);
        let reference = fit.reference_g;
        let ho: Vec<usize> = (last + 1..n).filter(|&i| tr.valid[i]).collect();
        let ours: Vec<f64> = ho.iter().map(|&i| ax.accel_g[i] - reference - tr.ext_k0_g[i]).collect();
        let ours_t: Vec<f64> = ho.iter().map(|&i| log.time_s[i]).collect();
        let clamped_rows = ho.iter().filter(|&&i| tr.clamped[i]).count();
        let tr_rows: Vec<f64> =
            (0..=last).filter(|&i| tr.valid[i]).map(|i| ax.accel_g[i] - reference - tr.ext_k0_g[i]).collect();
        // Peers on the same training rows (reference removed) and the same held-out rows.
        let tt: Vec<f64> = log.temp_c[..=last].to_vec();
        let ty: Vec<f64> = ax.accel_g[..=last].iter().map(|a| a - reference).collect();
        let p = fit_peers(&tt, &ty).map_err(|e| StaticCalError::Fit(format!("{} peers", ax.name), e))?;
        let peer_resid = |poly: &Poly| -> Vec<f64> {
            (last + 1..n).map(|i| ax.accel_g[i] - reference - poly.eval(log.temp_c[i])).collect()
        };
        let none: Vec<f64> = (last + 1..n).map(|i| ax.accel_g[i] - reference).collect();
        let name = |w: &str| format!("{} {w}", ax.name);
        axes.push(AxisReport {
            axis: ax.name.clone(),
            column: ax.column.clone(),
            reference_g: reference,
            structure: structure.name(),
            cv_rms_mg: cv * 1e3,
            train_rms_mg: rms(&tr_rows) * 1e3,
            ours: score(&ours, &ours_t, &name("ours"))?,
            cubic: score(&peer_resid(&p.cubic), &ho_time, &name("cubic"))?,
            ardupilot: score(&peer_resid(&p.ardupilot), &ho_time, &name("ardupilot"))?,
            simple: score(&peer_resid(&p.simple), &ho_time, &name("simple"))?,
            none: score(&none, &ho_time, &name("none"))?,
            clamped_rows,
            refused_candidates: refused,
        });
        fits.push(fit);
        peers.push(p);
    }
    pb.finish_and_clear();
    let table = table_of_axes(Input::Samples, fits.iter().map(|f| f.axis.clone()))
        .map_err(|e| StaticCalError::Fit("table".to_string(), e))?;
    let range = |r: &[f64]| {
        (r.iter().copied().fold(f64::INFINITY, f64::min), r.iter().copied().fold(f64::NEG_INFINITY, f64::max))
    };
    let report = StaticReport {
        kind: "static multi-axis",
        columns: log.columns.clone(),
        rows: n,
        skipped: log.skipped.clone(),
        sampling: log.sampling,
        split: format!(
            "fit on rows 1..={} (up to the first row at the highest temperature, t = {:.1} s), evaluate on rows {}..={}",
            last + 1,
            log.time_s[last],
            last + 2,
            n
        ),
        split_time_s: log.time_s[last],
        train_rows: last + 1,
        heldout_rows: n - last - 1,
        train_temp_c: range(&log.temp_c[..=last]),
        heldout_temp_c: range(&log.temp_c[last + 1..]),
        selection: format!(
            "per axis, the lowest {CV_FOLDS}-fold blocked cross-validation RMS inside the training rows among {} \
             candidates (branch tie x sensor_lag tau x bias_creep tau)",
            opts.candidates.len()
        ),
        axes,
    };
    Ok(StaticCalibration { table, fits, peers, report })
}

/// The held-out table in Markdown (mg, per axis).
#[must_use]
pub fn markdown(r: &StaticReport) -> String {
    let mut s = String::new();
    s.push_str("# Static calibration report\n\n");
    s.push_str(&format!("Split: {}.\n\n", r.split));
    s.push_str(&format!(
        "Training {} rows, {:.1}..{:.1} °C; held out {} rows, {:.1}..{:.1} °C. Reader: {}.\n\n",
        r.train_rows,
        r.train_temp_c.0,
        r.train_temp_c.1,
        r.heldout_rows,
        r.heldout_temp_c.0,
        r.heldout_temp_c.1,
        r.skipped
    ));
    s.push_str(&format!("Model choice: {}.\n\n", r.selection));
    s.push_str("Held-out bias RMS, mg (rows / 60-s means):\n\n");
    s.push_str(
        "| axis | ours | PX4/tofupilot cubic | ArduPilot TCAL | paper simple (linear) | none | our structure |\n",
    );
    s.push_str("|---|---|---|---|---|---|---|\n");
    let f = |x: &Score| format!("{:.2} / {:.2}", x.rms_mg, x.binned_mg);
    for a in &r.axes {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} |\n",
            a.axis,
            f(&a.ours),
            f(&a.cubic),
            f(&a.ardupilot),
            f(&a.simple),
            f(&a.none),
            a.structure
        ));
    }
    s
}

/// Write `table.toml`, `table.bin`, `report.json`, `report.md`, `px4_tc.params` and
/// `ardupilot_tcal.parm` into `out`.
///
/// # Errors
/// I/O or encoding errors.
pub fn write_static(out: &Path, cal: &StaticCalibration) -> Result<(), StaticCalError> {
    let io = |e: &dyn fmt::Display| StaticCalError::Io(format!("{}: {e}", out.display()));
    std::fs::create_dir_all(out).map_err(|e| io(&e))?;
    let toml = toml::to_string_pretty(&cal.table).map_err(|e| io(&e))?;
    let header = "# qfa-thermal coefficient table from a static log (per axis: bias K0 in g relative to the \
                  axis's training mean; scale factor 2^20 LSB/g, the pseudo-LSB `compensate` feeds the firmware's sample path)\n";
    std::fs::write(out.join("table.toml"), format!("{header}{toml}")).map_err(|e| io(&e))?;
    std::fs::write(out.join("table.bin"), encode(&cal.table).map_err(|e| io(&e))?).map_err(|e| io(&e))?;
    let json = serde_json::to_string_pretty(&cal.report).map_err(|e| io(&e))?;
    std::fs::write(out.join("report.json"), json).map_err(|e| io(&e))?;
    std::fs::write(out.join("report.md"), markdown(&cal.report)).map_err(|e| io(&e))?;
    let cubics: Vec<(String, Poly)> =
        cal.report.axes.iter().zip(&cal.peers).map(|(a, p)| (a.axis.clone(), p.cubic.clone())).collect();
    std::fs::write(out.join("px4_tc.params"), px4_params(&cubics)).map_err(|e| io(&e))?;
    let ap: Vec<(String, Poly)> =
        cal.report.axes.iter().zip(&cal.peers).map(|(a, p)| (a.axis.clone(), p.ardupilot.clone())).collect();
    std::fs::write(out.join("ardupilot_tcal.parm"), ardupilot_params(&ap)).map_err(|e| io(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::static_log::{read_static_from, AccelUnit, StaticOptions, TimeUnit};

    #[test]
    fn a_log_that_ends_at_its_hottest_has_nothing_to_evaluate() {
        // Heating only: the maximum is the last row, so no held-out rows: an error, no figure.
        let mut text = String::from("time,temp,az\n");
        for i in 0..200 {
            text.push_str(&format!("{i},{},-1.0\n", 20.0 + 0.1 * f64::from(i)));
        }
        let opts = StaticOptions { time_unit: Some(TimeUnit::S), accel_unit: Some(AccelUnit::G), ..Default::default() };
        let log = read_static_from(text.as_bytes(), &opts).unwrap();
        let e = calibrate_static(&log, &StaticCalOptions::default(), false).unwrap_err();
        assert_eq!(
            e.to_string(),
            "held-out split: the highest temperature (39.90 °C) is at row 200 of 200: fewer than a tenth of the \
             rows lie after it, nothing to evaluate on"
        );
    }
}
