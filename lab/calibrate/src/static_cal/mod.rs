//! Calibration of a static multi-axis log: per axis, the firmware's bias model (grid with
//! heating/cooling branches and extension slots) fitted through the root crate's estimator
//! and model, scored against the peers on held-out rows, then refitted on every row for the
//! table that is written.
//!
//! # What refuses a log
//! Only a cause in the log itself, checked on all rows before anything is fitted
//! (`check_coverage`):
//! * a temperature span below what the bias grid needs: `grid_points` nodes at least the
//!   root crate's smallest grid step apart (`MIN_GRID_STEP_C`, 0.1 °C: finer steps resolve
//!   nothing the firmware's 1/16-°C readings tell apart), 1.5 °C for 16 nodes;
//! * too few rows per degree: the span cut into the grid's `grid_points − 1` equal
//!   intervals, each must hold `block` rows (one averaged equation per interval, so every
//!   node is set by data, not only by the weak smoothing rows).
//!
//! A held-out scheme the log cannot support, asked for explicitly (`after-max` on a log
//! that ends at its hottest, `blocks:K` with blocks under `block` rows), is refused with
//! that reason; `auto` never is.
//!
//! # Held-out scheme (`--holdout`, [`Holdout`]), the same for every figure of the report
//! * `after-max`: fit on every row up to and including the first row at the log's highest
//!   temperature, evaluate on every row after it: the later leg. For a chamber cycle that
//!   ends cooling (the tofupilot log: 51.6 → −17.6 → 74.0 → 36.3 °C) that is a cooling leg
//!   over a range the training saw only while heating. Needs a tenth of the rows on each
//!   side of that row.
//! * `blocks:K`: blocked cross-validation in time: the rows cut into K contiguous blocks of
//!   equal row count; each block is evaluated on a fit to the other K − 1. For logs with no
//!   later leg: heating only (PX4's and ArduPilot's own procedure, a cold-soaked board
//!   warming up), cooling only, or a maximum near either end.
//! * `none`: nothing held out; no held-out figure exists, and the report says so in each
//!   figure's place.
//! * `auto` (the default): `after-max` when the log has that later leg, else `blocks:5`.
//!   The report states which one ran and why.
//!
//! # Model choice
//! Each axis chooses among [`candidates`] (branch tie × `sensor_lag` τ × `bias_creep` τ) by
//! blocked cross-validation **over every row**: the rows (in time order) are cut into
//! contiguous blocks (`CV_FOLDS`, or K under `blocks:K`); each block is predicted by a fit
//! to the others (the firmware's states still run through every row); the candidate with
//! the lowest RMS over all blocks wins. That one structure is fitted on every row for the
//! table and on each fold's training rows for the held-out figure of ours, so what the
//! report scores is what `table.bin` holds, and `discover` names it. Its path says how it
//! got there: from the simplest candidate that can be fitted, one part at a time (a branch
//! tie loosened one level, a lag, a creep), each step to the structure with the lowest RMS
//! among the choice's remaining parts (every such structure is a candidate, so each has
//! its figure); per fold, each step is also fitted on the training rows and scored on the
//! held-out rows (`heldout_paths`).
//!
//! The choice saw the held-out rows; the coefficients scored did not. Measured against a
//! fresh log of the same unit (`cargo xtask experiment static_table_study`: the
//! simulator's chamber cycle with each hidden effect, seeds 11–19, and the desk generator,
//! 48 axes with a later leg; docs/measurements.md, "Real data"), the held-out figure of the
//! table's structure predicts the table's RMS on the fresh log's later leg with less bias
//! than the figure an earlier rule gave, that of a choice made inside each fold's training
//! rows, a structure the table may not hold (held out over fresh, geometric mean 0.965
//! against 1.193), and as closely (mean |log| 0.405 against 0.384). Choosing the table's
//! structure on the training rows alone instead does as well on the fresh logs (the
//! every-row choice over it: 0.995, ahead on 24 of the 43 axes where they differ), but
//! fewer rows choose simpler tables: on a batch's chamber run it lost the heating/cooling
//! split the fleet is compared by.
//!
//! Other rules were measured on the real log, the simulator's chamber cycles and the desk
//! generator (`cargo xtask experiment selection_study`): a forward-chained
//! cross-validation (each block predicted by the blocks before it only), the
//! one-standard-error rule, a stepwise search that stops when a step's paired gain is
//! within one standard error, and the cubic shape among the candidates. None predicted the
//! later legs better than the lowest blocked cross-validation RMS over the grid's
//! candidates.
//!
//! **One branch.** Rows on which the smaller of the heating and cooling branches holds
//! fewer than a tenth of the rows on a branch (`is_one_branch`: a heating-only or
//! cooling-only log) get one model, not a choice: [`ONE_BRANCH`], a rate-even bias curve
//! shaped as a cubic in T. Every candidate's other terms (branch step, two branches, lag,
//! creep) act differently on the branch those rows never show, and nothing in them can
//! test how; [`ONE_BRANCH`]'s docs give the measurements. For the same reason a fold whose
//! training rows hold one branch cannot score a table of two (a log that heats to its
//! maximum and then cools, under `after-max`): ours is not computed there, with why.
//!
//! # Figures, and the rows each comes from
//! * Held-out bias RMS per axis in mg (ours, the peers, no compensation): the RMS over every
//!   fold's held-out rows of `a − reference − bias`, each row predicted by models fitted
//!   on its fold's training rows (`reference` the axis's mean over them; `bias` the model's
//!   K0 from the root crate's `AxisModel::evaluate`, or the peer's polynomial of the
//!   reading). `binned_mg` is the same over 60-s means (white noise averaged down). A
//!   figure that cannot be formed is [`Figure::NotComputed`] with its reason (`none`, or
//!   the ArduPilot learner on a log with no 2 °C rise), never a number in its place.
//! * The table (`table.bin`/`table.toml`) and the exported peers (`px4_tc.params`,
//!   `ardupilot_tcal_1_enable.parm`, `ardupilot_tcal_2_values.parm`): the chosen structure, and the peers, fitted on **every row**,
//!   the bias measured from the axis's mean over every row. `table_rms_mg` is that
//!   table's RMS over every row (in-sample: not a held-out figure).

pub(crate) mod choice;
pub(crate) mod error;
pub(crate) mod fit;
pub(crate) mod holdout;
pub(crate) mod output;
pub mod report;
mod search;
mod shape;

use std::ops::Range;

use qfa_thermal::Input;

use crate::fit::{fit_static_traced, table_of_axes, StaticFit, StaticSeries, StaticStructure, StaticTraces};
use crate::metrics::rms;
use crate::peers::{ardupilot_reason, PeerKind, Poly};
pub use crate::static_cal::choice::{cv_fold_sums_axes, is_step, CvOrder, FoldSums, SearchStep};
use crate::static_cal::search::{choose_structures, AxisChoice};
use qfa_log::pairing::Trace;
use qfa_log::replay::FirmwareRows;
use qfa_log::static_log::{AxisColumn, StaticLog};

pub use crate::static_cal::choice::is_one_branch;
pub use crate::static_cal::choice::{candidates, cv_rms_axes, CV_FOLDS, ONE_BRANCH};
pub use crate::static_cal::error::{FigureFault, SplitFault, StaticCalError};
pub use crate::static_cal::holdout::Holdout;
pub use crate::static_cal::holdout::{check_coverage, check_outputs, resolve_holdout, split_index, Scheme};
pub use crate::static_cal::output::{
    calibrate_static_into, export_axes, markdown, static_table_toml, write_static, write_static_table, StaticRun,
};
pub use crate::static_cal::output::{static_files, with_verdict, write_static_page};
pub use crate::static_cal::report::{AxisReport, HeldOutStep, HoldoutReport, PathStep, Score, StaticReport};
pub use crate::static_cal::report::{ExportedPeers, Figure, FoldReport, PlotRows, StaticCalibration};

/// Length of the averaging window of `binned_mg`, s.
pub(crate) const BIN_S: f64 = 60.0;

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
    /// Held-out scheme.
    pub holdout: Holdout,
    /// The part's own sensitivity at the range it was logged at, LSB per g, recorded in the
    /// table (`Table::part_lsb_per_g`) so that a firmware reading the part at another range
    /// refuses it; `None`: not recorded (`calibrate --lsb-per-g`).
    pub part_lsb_per_g: Option<f32>,
}

impl Default for StaticCalOptions {
    fn default() -> Self {
        Self {
            grid_points: 16,
            block: 10,
            deadband_c_per_min: qfa_log::replay::branch_deadband_c_per_min(),
            candidates: candidates(),
            holdout: Holdout::Auto,
            part_lsb_per_g: None,
        }
    }
}

pub(crate) fn range(v: &[f64]) -> (f64, f64) {
    (v.iter().copied().fold(f64::INFINITY, f64::min), v.iter().copied().fold(f64::NEG_INFINITY, f64::max))
}

/// Held-out figures of residuals `resid` (g) at times `time_s`: RMS over the rows and over
/// their 60-s means, mg.
///
/// # Errors
/// No residual, or a non-finite one.
pub fn score(resid: &[f64], time_s: &[f64], what: &str) -> Result<Score, StaticCalError> {
    if resid.is_empty() {
        return Err(StaticCalError::Figure(FigureFault::NoModelOutput { figure: what.to_string() }));
    }
    let bins: Vec<f64> =
        crate::metrics::time_bin_means(resid.iter().copied(), time_s, BIN_S).into_iter().map(|b| b.1).collect();
    let out = Score { rms_mg: rms(resid) * 1e3, binned_mg: rms(&bins) * 1e3 };
    if !out.rms_mg.is_finite() || !out.binned_mg.is_finite() {
        return Err(StaticCalError::Figure(FigureFault::NonFinite { figure: what.to_string() }));
    }
    Ok(out)
}

/// One set of rows a structure is chosen and fitted on: every row (the table), or one
/// fold's training rows.
struct RowSet {
    rows: Vec<usize>,
    mask: Vec<bool>,
}

/// What every step of one calibration shares: the log, the settings, the held-out scheme
/// with its folds, the row sets and the rows' branches.
struct Run<'a> {
    log: &'a StaticLog,
    /// The firmware's view of the log's rows, under the options' deadband.
    view: &'a FirmwareRows,
    opts: &'a StaticCalOptions,
    scheme: Scheme,
    /// Held-out rows of each fold.
    folds: Vec<Range<usize>>,
    /// Blocks of the cross-validation that chooses a structure.
    k_sel: usize,
    /// Set 0: every row (the table); set 1 + f: fold f's training rows.
    sets: Vec<RowSet>,
    /// The first axis replayed with no extension: each row's branch as the firmware's branch
    /// logic (deadband included) sees it.
    plain: Trace,
    /// Per set: one branch holds fewer than a tenth of its rows ([`is_one_branch`]).
    one_branch: Vec<bool>,
}

impl<'a> Run<'a> {
    /// The folds of `scheme` on `log`, the row sets they give, and the rows' branches.
    fn new(log: &'a StaticLog, view: &'a FirmwareRows, opts: &'a StaticCalOptions, scheme: Scheme) -> Self {
        let n = log.rows();
        let folds = scheme.folds(n);
        let k_sel = scheme.selection_folds();
        let mut sets = vec![RowSet { rows: (0..n).collect(), mask: vec![true; n] }];
        for f in &folds {
            let mask: Vec<bool> = (0..n).map(|i| !f.contains(&i)).collect();
            sets.push(RowSet { rows: (0..n).filter(|&i| mask[i]).collect(), mask });
        }
        let plain = qfa_log::pairing::trace_view(view, &qfa_thermal::Extensions::default(), opts.deadband_c_per_min);
        let mut run = Self { log, view, opts, scheme, folds, k_sel, sets, plain, one_branch: Vec::new() };
        run.one_branch = run.sets.iter().map(|set| is_one_branch(run.branch_rows(&set.rows))).collect();
        run
    }

    /// Axis `a` of the log.
    fn series(&self, a: usize) -> StaticSeries<'a> {
        StaticSeries { view: self.view, accel_g: &self.log.axes[a].accel_g }
    }

    /// Rows on the heating and on the cooling branch among `rows`.
    fn branch_rows(&self, rows: &[usize]) -> (usize, usize) {
        choice::branch_rows(&self.plain.branch, rows.iter().copied())
    }

    /// The candidates on set `s` (the same for every axis): [`ONE_BRANCH`] alone on rows
    /// with one branch.
    fn candidates(&self, s: usize) -> Vec<StaticStructure> {
        if self.one_branch[s] {
            return vec![ONE_BRANCH];
        }
        self.opts.candidates.clone()
    }

    /// Structure `st` fitted to axis `series` (named `axis`) on set `s`'s rows.
    fn fit_on(
        &self,
        series: &StaticSeries<'_>,
        s: usize,
        st: &StaticStructure,
        axis: &str,
    ) -> Result<StaticFit, StaticCalError> {
        let traces = StaticTraces::new(series, st, self.opts.deadband_c_per_min);
        fit_static_traced(series, &traces, &self.sets[s].mask, self.opts.grid_points, self.opts.block)
            .map_err(|e| StaticCalError::Fit(axis.to_string(), e))
    }
}

/// Calibrate a static log (see the module docs).
///
/// # Errors
/// A log refused by `check_coverage` or `check_outputs`, a held-out scheme the log cannot hold, a failed
/// fit, or a figure that cannot be formed.
pub fn calibrate_static(
    log: &StaticLog,
    opts: &StaticCalOptions,
    progress: bool,
) -> Result<StaticCalibration, StaticCalError> {
    check_coverage(&log.temp_c, opts.grid_points, opts.block)?;
    check_outputs(log)?;
    let (scheme, rule) = resolve_holdout(log, opts.holdout, opts.block)?;
    let view = StaticSeries::view_of(&log.time_s, &log.temp_c, opts.deadband_c_per_min);
    let run = Run::new(log, &view, opts, scheme);
    let choices = choose_structures(&run, progress);
    let n = log.rows();
    let mut fits = Vec::new();
    let mut peers = Vec::new();
    let mut axes = Vec::new();
    let mut plot = PlotRows {
        time_s: log.time_s.clone(),
        temp_c: log.temp_c.clone(),
        branch: run.plain.branch.clone(),
        heldout: (0..n).map(|i| run.folds.iter().any(|f| f.contains(&i))).collect(),
        axes: Vec::new(),
    };
    let paths: Vec<Vec<SearchStep>> = choices.iter().map(|c| c.path.clone()).collect();
    for (a, choice) in choices.into_iter().enumerate() {
        let axis = calibrate_axis(&run, a, choice)?;
        axes.push(axis.report);
        fits.push(axis.fit);
        peers.push(axis.exported);
        plot.axes.push(axis.plot);
    }
    let mut table = table_of_axes(Input::Samples, fits.iter().map(|f| f.axis.clone()))
        .map_err(|e| StaticCalError::Fit("table".to_string(), e))?;
    table.part_lsb_per_g = opts.part_lsb_per_g;
    table.validate().map_err(|e| StaticCalError::Fit("table".to_string(), crate::fit::FitError::Table(e)))?;
    let report = static_report(&run, rule, axes)?;
    Ok(StaticCalibration { table, fits, peers, report, plot, paths })
}

/// One axis calibrated: its report, the table's fit, the exported peers and its plot rows.
struct AxisOutcome {
    report: AxisReport,
    fit: StaticFit,
    exported: ExportedPeers,
    /// Name, residual before and after compensation, mg.
    plot: (String, Vec<f64>, Vec<f64>),
}

/// Calibrate axis `a` on its `choice`: the table's structure fitted on every row and scored
/// there (in-sample), the exported peers, and the held-out figures.
fn calibrate_axis(run: &Run<'_>, a: usize, choice: AxisChoice) -> Result<AxisOutcome, StaticCalError> {
    let (log, n) = (run.log, run.log.rows());
    let ax = &log.axes[a];
    let series = run.series(a);
    // The table: the search's choice, fitted on every row.
    let (cv, structure) = choice.chosen(&ax.name)?;
    let fit = run.fit_on(&series, 0, &structure, &ax.name)?;
    let tr = series.model_trace(&fit.axis);
    let reference = fit.reference_g;
    let all: Vec<f64> = (0..n).filter(|&i| tr.valid[i]).map(|i| ax.accel_g[i] - reference - tr.ext_k0_g[i]).collect();
    let table_rms_mg = rms(&all) * 1e3;
    let before_mg: Vec<f64> = ax.accel_g.iter().map(|a| (a - reference) * 1e3).collect();
    let mut after_mg: Vec<f64> = (0..n).map(|i| resid_mg(&ax.accel_g, &tr, reference, i)).collect();
    let (exported, exported_cubic, exported_ardupilot) = exported_peers(log, ax, reference)?;
    let mut ho = held_out(run, &series, ax, &choice, &mut after_mg)?;
    let (heldout_structures, heldout_paths) = (std::mem::take(&mut ho.structures), std::mem::take(&mut ho.paths));
    let no_folds = run.folds.is_empty();
    let fig = |resid: &[f64], t: &[f64], what: &str, err: &Option<String>| {
        heldout_figure(no_folds, &ax.name, resid, t, what, err)
    };
    let report = AxisReport {
        axis: ax.name.clone(),
        column: ax.column.clone(),
        reference_g: reference,
        structure: structure.name(),
        cv_rms_mg: cv * 1e3,
        search_path: choice.path.iter().map(PathStep::from).collect(),
        table_rms_mg,
        exported_cubic,
        exported_ardupilot,
        heldout_structures,
        heldout_paths,
        ours: fig(&ho.ours, &ho.ours_t, "ours", &ho.ours_err)?,
        cubic: fig(&ho.peers[0], &ho.t, "cubic", &ho.peer_err[0])?,
        ardupilot: fig(&ho.peers[1], &ho.t, "ardupilot", &ho.peer_err[1])?,
        simple: fig(&ho.peers[2], &ho.t, "simple", &ho.peer_err[2])?,
        none: fig(&ho.none, &ho.t, "none", &None)?,
        clamped_rows: ho.clamped,
        refused_candidates: choice.refused.iter().map(|(name, e)| format!("{name}: {e}")).collect(),
    };
    Ok(AxisOutcome { report, fit, exported, plot: (ax.name.clone(), before_mg, after_mg) })
}

/// Row `i`'s residual of an axis (`accel_g`, g) after the reference `r0` and the model's
/// bias (`tr`), mg; NaN where the trace has no temperature yet.
fn resid_mg(accel_g: &[f64], tr: &Trace, r0: f64, i: usize) -> f64 {
    if tr.valid[i] {
        (accel_g[i] - r0 - tr.ext_k0_g[i]) * 1e3
    } else {
        f64::NAN
    }
}

/// The peers exported for an axis, fitted on every row with `reference` (g) removed, and
/// their in-sample figures (cubic, ArduPilot): what the exported files reproduce.
fn exported_peers(
    log: &StaticLog,
    ax: &AxisColumn,
    reference: f64,
) -> Result<(ExportedPeers, Figure, Figure), StaticCalError> {
    let (t_all, y_all): (Vec<f64>, Vec<f64>) = (log.temp_c.clone(), ax.accel_g.iter().map(|v| v - reference).collect());
    let exported = ExportedPeers {
        cubic: PeerKind::Cubic.fit(&t_all, &y_all).map_err(|e| StaticCalError::Fit(format!("{} cubic", ax.name), e))?,
        ardupilot: PeerKind::Ardupilot.fit(&t_all, &y_all),
    };
    // The exported peers over every row, the constant the mean over every row (what the
    // ordinary accelerometer calibration takes up): the figures the files reproduce.
    let in_sample = |p: &Poly, what: &str| -> Result<Figure, StaticCalError> {
        let r: Vec<f64> = t_all.iter().zip(&y_all).map(|(&t, &y)| y - p.eval(t)).collect();
        let mean = r.iter().sum::<f64>() / r.len() as f64;
        let centred: Vec<f64> = r.iter().map(|v| v - mean).collect();
        score(&centred, &log.time_s, &format!("{} exported {what}", ax.name)).map(Figure::Score)
    };
    let exported_cubic = in_sample(&exported.cubic, "cubic")?;
    let exported_ardupilot = match &exported.ardupilot {
        Ok(p) => in_sample(p, "ardupilot")?,
        Err(why) => Figure::not_computed(ardupilot_reason(why)),
    };
    Ok((exported, exported_cubic, exported_ardupilot))
}

/// One axis's held-out residuals pooled over the folds: the table's structure (`choice`,
/// chosen on every row) fitted on each fold's training rows and scored on its held-out
/// rows, with each step of the search's path likewise. Each fold's model residuals, mg, go
/// into `after_mg` on its held-out rows (on every row when there is one fold). A fold that
/// cannot fit the table's structure leaves ours not computed, with why
/// ([`untestable_on`]), and its held-out rows without a residual.
fn held_out(
    run: &Run<'_>,
    series: &StaticSeries<'_>,
    ax: &AxisColumn,
    choice: &AxisChoice,
    after_mg: &mut [f64],
) -> Result<HeldOut, StaticCalError> {
    let (log, folds, n) = (run.log, &run.folds, run.log.rows());
    let (_, table) = choice.chosen(&ax.name)?;
    let mut ho = HeldOut::default();
    for (f, rows) in folds.iter().enumerate() {
        let s = f + 1;
        ho.structures.push(table.name());
        // The axis's mean over the training rows with a temperature: the reference every
        // figure of the fold removes (the fit's own `reference_g`, summed in the same order).
        let train: Vec<usize> = run.sets[s].rows.iter().copied().filter(|&i| run.plain.valid[i]).collect();
        let r0 = train.iter().map(|&i| ax.accel_g[i]).sum::<f64>() / train.len() as f64;
        fold_peers(run, ax, f, rows, r0, &mut ho);
        ho.none.extend(rows.clone().map(|i| ax.accel_g[i] - r0));
        ho.t.extend(rows.clone().map(|i| log.time_s[i]));
        let fit = match untestable_on(run, s, &table) {
            Some(why) => Err(why),
            None => run.fit_on(series, s, &table, &ax.name).map_err(|e| format!("fold {s} of {}: {e}", folds.len())),
        };
        let fit = match fit {
            Ok(fit) => fit,
            Err(why) => {
                ho.ours_err.get_or_insert(why);
                ho.paths.push(Vec::new());
                rows.clone().for_each(|i| after_mg[i] = f64::NAN);
                continue;
            }
        };
        ho.paths.push(held_out_path(run, series, ax, &choice.path, s, rows));
        debug_assert_eq!(fit.reference_g.to_bits(), r0.to_bits());
        let tr = series.model_trace(&fit.axis);
        let drawn = if folds.len() == 1 { 0..n } else { rows.clone() };
        for i in drawn {
            after_mg[i] = resid_mg(&ax.accel_g, &tr, r0, i);
        }
        for i in rows.clone().filter(|&i| tr.valid[i]) {
            ho.ours.push(ax.accel_g[i] - r0 - tr.ext_k0_g[i]);
            ho.ours_t.push(log.time_s[i]);
            ho.clamped += usize::from(tr.clamped[i]);
        }
    }
    Ok(ho)
}

/// Why set `s`'s training rows cannot score `table`: they hold one branch while `table`
/// has terms that act on the other (any structure but [`ONE_BRANCH`]), which those rows
/// cannot fit or test. `None` when they can.
fn untestable_on(run: &Run<'_>, s: usize, table: &StaticStructure) -> Option<String> {
    (run.one_branch[s] && *table != ONE_BRANCH).then(|| {
        let (heating, cooling) = run.branch_rows(&run.sets[s].rows);
        format!(
            "fold {s} of {}: its training rows hold one branch ({heating} heating, {cooling} cooling rows), and \
             table.bin's `{}` has terms that act on the other branch, which those rows cannot fit",
            run.folds.len(),
            table.name()
        )
    })
}

/// Each step of the search's `path` fitted on set `s`'s rows and scored on the fold's
/// held-out `rows`, as the table's structure's own held-out figure is; a step that cannot
/// be fitted there is not computed, with why.
fn held_out_path(
    run: &Run<'_>,
    series: &StaticSeries<'_>,
    ax: &AxisColumn,
    path: &[SearchStep],
    s: usize,
    rows: &Range<usize>,
) -> Vec<HeldOutStep> {
    path.iter()
        .map(|step| {
            let what = format!("{} {} (fold {s})", ax.name, step.structure.name());
            let held_out = match untestable_on(run, s, &step.structure) {
                Some(why) => Figure::not_computed(why),
                None => match run.fit_on(series, s, &step.structure, &ax.name) {
                    Err(e) => Figure::not_computed(format!("fold {s} of {}: {e}", run.folds.len())),
                    Ok(fit) => {
                        let tr = series.model_trace(&fit.axis);
                        let (resid, t): (Vec<f64>, Vec<f64>) = rows
                            .clone()
                            .filter(|&i| tr.valid[i])
                            .map(|i| (ax.accel_g[i] - fit.reference_g - tr.ext_k0_g[i], run.log.time_s[i]))
                            .unzip();
                        score(&resid, &t, &what).map_or_else(|e| Figure::not_computed(e.to_string()), Figure::Score)
                    }
                },
            };
            HeldOutStep { structure: step.structure.name(), cv_rms_mg: step.cv_rms_g * 1e3, held_out }
        })
        .collect()
}

/// The peers fitted on fold `f`'s training rows and scored on its held-out `rows`, with the
/// same reference `r0` (g) removed, pooled into `ho`; for a peer that cannot be fitted, the
/// first fold's reason is kept.
fn fold_peers(run: &Run<'_>, ax: &AxisColumn, f: usize, rows: &Range<usize>, r0: f64, ho: &mut HeldOut) {
    let (log, s) = (run.log, f + 1);
    let tt: Vec<f64> = run.sets[s].rows.iter().map(|&i| log.temp_c[i]).collect();
    let ty: Vec<f64> = run.sets[s].rows.iter().map(|&i| ax.accel_g[i] - r0).collect();
    for (k, kind) in PeerKind::ALL.iter().enumerate() {
        match kind.fit(&tt, &ty) {
            Ok(p) => ho.peers[k].extend(rows.clone().map(|i| ax.accel_g[i] - r0 - p.eval(log.temp_c[i]))),
            Err(e) if ho.peer_err[k].is_none() => {
                ho.peer_err[k] = Some(format!(
                    "fold {} of {}: {}",
                    f + 1,
                    run.folds.len(),
                    if *kind == PeerKind::Ardupilot { ardupilot_reason(&e) } else { e.to_string() }
                ));
            }
            Err(_) => {}
        }
    }
}

/// A held-out figure of axis `axis` (`what`: ours, a peer, none) from its residuals `resid`
/// (g) at times `t`: not computed when nothing is held out (`no_folds`) or the model
/// could not be fitted (`err`).
fn heldout_figure(
    no_folds: bool,
    axis: &str,
    resid: &[f64],
    t: &[f64],
    what: &str,
    err: &Option<String>,
) -> Result<Figure, StaticCalError> {
    if no_folds {
        return Ok(Figure::not_computed(NO_HOLDOUT));
    }
    if let Some(e) = err {
        return Ok(Figure::not_computed(e.clone()));
    }
    score(resid, t, &format!("{axis} {what}")).map(Figure::Score)
}

/// The report of a calibration whose axes are `axes`: the log, the held-out scheme (`rule`:
/// why it was taken) and its folds, the coverage with what to record next, and how each
/// structure was chosen.
fn static_report(run: &Run<'_>, rule: String, axes: Vec<AxisReport>) -> Result<StaticReport, StaticCalError> {
    let (log, opts, folds, n) = (run.log, run.opts, &run.folds, run.log.rows());
    let log_branches = run.branch_rows(&run.sets[0].rows);
    let fold_reports: Vec<FoldReport> = folds
        .iter()
        .enumerate()
        .map(|(f, r)| {
            let train: Vec<f64> = run.sets[f + 1].rows.iter().map(|&i| log.temp_c[i]).collect();
            FoldReport {
                heldout_rows: (r.start + 1, r.end),
                heldout_time_s: (log.time_s[r.start], log.time_s[r.end - 1]),
                heldout_temp_c: range(&log.temp_c[r.clone()]),
                train_rows: train.len(),
                train_branch_rows: run.branch_rows(&run.sets[f + 1].rows),
                train_temp_c: range(&train),
            }
        })
        .collect();
    let (coverage, record_next) = coverage_and_next(run)?;
    Ok(StaticReport {
        coverage,
        record_next,
        kind: "static multi-axis",
        columns: log.columns.clone(),
        rows: n,
        skipped: log.skipped.clone(),
        sampling: log.sampling,
        temp_c: range(&log.temp_c),
        branch_rows: log_branches,
        holdout: HoldoutReport {
            requested: opts.holdout.to_string(),
            scheme: run.scheme.name(),
            rule,
            heldout_rows: folds.iter().map(ExactSizeIterator::len).sum(),
            folds: fold_reports,
        },
        figures: figures_text(&run.scheme, n),
        selection: selection_text(run),
        axes,
    })
}

/// The temperature and rate coverage of the rows with a temperature, and what to record
/// next: the coverage's own list, then a note when the table is the one-branch curve and
/// one when `auto` fell back to blocks.
fn coverage_and_next(run: &Run<'_>) -> Result<(crate::coverage::Coverage, Vec<String>), StaticCalError> {
    let (plain, n) = (&run.plain, run.log.rows());
    let coverage = crate::coverage::Coverage::of_samples(
        (0..n).filter(|&i| plain.valid[i]).map(|i| (plain.temp_c[i], plain.rate_c_per_min[i])),
        f64::from(run.opts.deadband_c_per_min),
    )
    .map_err(StaticCalError::Coverage)?;
    let mut record_next = coverage.record_next();
    if run.one_branch[0] {
        record_next.push(format!(
            "with one leg the table is `{}` (one rate-even curve), and a mission that runs the other way is \
             compensated by a curve fitted on this leg only",
            ONE_BRANCH.name()
        ));
    }
    if matches!(run.scheme, Scheme::Blocks { .. }) && run.opts.holdout == Holdout::Auto {
        record_next.push(
            "the log has no later leg after its highest temperature, so the held-out figures come from blocks in \
             time, each inside the range its neighbours saw; record a cooling leg after the maximum to score the \
             model on a leg it was not fitted on (`after-max`)"
                .to_string(),
        );
    }
    Ok((coverage, record_next))
}

/// How each axis's structure was chosen, in words, with the log's heating and cooling rows
/// when its table is the one-branch curve.
fn selection_text(run: &Run<'_>) -> String {
    let (heating, cooling) = run.branch_rows(&run.sets[0].rows);
    format!(
        "per axis, the lowest {}-fold blocked cross-validation RMS (contiguous blocks in time) among {} \
         candidates (branch tie x sensor_lag tau x bias_creep tau) over every row: the structure table.bin holds, \
         and the one every held-out figure of ours scores, fitted on each fold's training rows (the choice saw \
         the held-out rows; the coefficients scored did not); rows where one branch holds fewer than a tenth of \
         the rows on a branch get `{}` instead (one rate-even curve: terms that act on the other branch cannot be \
         tested there){}",
        run.k_sel,
        run.opts.candidates.len(),
        ONE_BRANCH.name(),
        if run.one_branch[0] {
            format!(
                "; this log holds {heating} heating and {cooling} cooling rows, so its table is `{}`",
                ONE_BRANCH.name()
            )
        } else {
            String::new()
        }
    )
}

/// What stands in every held-out figure's place under `--holdout none`.
pub const NO_HOLDOUT: &str = "--holdout none: no row is held out";

/// Residuals pooled over the folds.
#[derive(Default)]
struct HeldOut {
    ours: Vec<f64>,
    ours_t: Vec<f64>,
    clamped: usize,
    /// Cubic, ArduPilot, simple ([`PeerKind::ALL`]'s order).
    peers: [Vec<f64>; 3],
    peer_err: [Option<String>; 3],
    none: Vec<f64>,
    t: Vec<f64>,
    /// The structure each fold scores (the table's).
    structures: Vec<String>,
    /// Why ours is not computed: the first fold that cannot fit the table's structure.
    ours_err: Option<String>,
    /// Each fold's search path, held out.
    paths: Vec<Vec<HeldOutStep>>,
}

/// Which rows each figure comes from, in words.
fn figures_text(scheme: &Scheme, n: usize) -> String {
    let held = match scheme {
        Scheme::None => "no held-out figure (--holdout none)".to_string(),
        Scheme::AfterMax { last } => format!(
            "held-out figures (ours, peers, none): models fitted on rows 1..={}, scored on rows {}..={n} (ours: \
             table.bin's structure, chosen on every row)",
            last + 1,
            last + 2
        ),
        Scheme::Blocks { k } => format!(
            "held-out figures (ours, peers, none): each of the {k} blocks scored with models fitted on the other {} \
             blocks, pooled over all {n} rows (ours: table.bin's structure, chosen on every row)",
            k - 1
        ),
    };
    format!(
        "{held}; every table written (table.bin, and what else the command writes: table.toml, the PX4 and \
         ArduPilot files): fitted on all {n} rows (bias from each axis's mean over all rows); table_rms_mg: that table \
         on all rows (in-sample)"
    )
}
