//! Calibration: log → fitted tables → held-out report, and its files.
//!
//! Files written to the output directory:
//! `table.toml` / `table.bin` (the hysteresis model, the table to flash),
//! `table_simple.toml` / `table_simple.bin` (the simple model, for comparison),
//! `report.json`, `sf_vs_temp.png`, `residual_vs_time.png`, and the cubic peer as PX4
//! (`px4_tc.params`) and ArduPilot (`ardupilot_tcal_1_enable.parm`,
//! `ardupilot_tcal_2_values.parm`) parameters for the IMU axis [`CalibrateOptions::axis`]
//! names, when they can be loaded as written (see [`export::write_exports`]: a one-axis
//! export needs [`export::ExportOptions::range_c`]).
//!
//! Which rows each comes from: one structure per log, the bias grid's branch tie and shape
//! chosen once by cross-validation on **every** program with a ±1 g pair
//! ([`fit::fit_table`]), so no program's rows are left out of what is flashed; the
//! held-out figures (and the plots) are of that structure fitted on the fit programs
//! alone ([`fit::fit_held_out`]) and compensated on the others. With one program, both
//! are the same fit.

pub mod compensate;
pub mod coverage;
pub mod export;
pub mod fit;
pub mod metrics;
pub mod output_error;
pub mod peers;
pub mod report;
pub mod select;
pub mod solver;
pub mod static_cal;
pub mod verdict;

use std::fmt;
use std::path::Path;
use std::time::Instant;

use crate::fit::{fit, split_programs, FitError, FitOptions, Fitted};
use crate::output_error::OutputError;
use crate::report::{
    evaluate, plot_residual_vs_time, plot_sf_vs_temp, Evaluation, FitSummary, Report, Timings, METRIC_TEXT,
};
use qfa_log::cycling::{read_log, Log};
use qfa_log::pairing::PairedLog;

/// Calibration settings.
#[derive(Clone, Debug, Default)]
pub struct CalibrateOptions {
    /// Programs to fit on; `None` applies [`split_programs`].
    pub fit_programs: Option<Vec<String>>,
    /// Draw the plots.
    pub plots: bool,
    /// Title for plots and messages.
    pub title: String,
    /// Show progress bars.
    pub progress: bool,
    /// IMU axis this accelerometer is (`ax`, `ay` or `az`) in the PX4 / ArduPilot
    /// parameter files; `None` is `ax`.
    pub axis: Option<String>,
    /// What the verdict's lines call the accelerometer: a batch gives its serial; `None`
    /// names its IMU axis (`axis`).
    pub unit: Option<String>,
    /// How to write those files.
    pub exports: export::ExportOptions,
    /// The limits the verdict checks.
    pub limits: qfa_report::verdict::LimitsChoice,
    /// Leave the step timings out of the reports, so every file's bytes depend on the log
    /// alone (a batch's units, whatever thread or shard ran them).
    pub reproducible: bool,
    /// Lines the verdict carries as warnings, before the exports' (a batch's word on which
    /// table its certificate names).
    pub notes: Vec<String>,
    /// Extension slots in force in every fit, their parameters fixed (their bias is
    /// subtracted before the bias grid is fitted): none for `calibrate`; on a cycling log
    /// `discover` passes the slots its catalog named that carry to held-out programs, so
    /// both commands' tables come from this one call.
    pub ext: qfa_thermal::Extensions,
}

/// Result of a calibration.
#[derive(Clone, Debug)]
pub struct Calibration {
    /// Fits and tables on the fit programs (what the held-out figures are of).
    pub fitted: Fitted,
    /// Fits and tables on every program (what is written and flashed).
    pub table: Fitted,
    /// Held-out evaluation.
    pub eval: Evaluation,
    /// The report as written.
    pub report: Report,
    /// The peers fitted on every program's pairs (what the parameter files hold).
    pub peers: crate::peers::Peers,
    /// The PX4 / ArduPilot files written, and why others were not.
    pub exports: export::Exports,
    /// The verdict the reports open with (`None` until [`calibrate_into`] writes them).
    pub verdict: Option<qfa_report::verdict::Verdict>,
    /// The plots [`calibrate_into`] drew and wrote (none without `plots`): the page inlines
    /// these bytes, and a caller's page (the demo's) can too.
    pub plots: Vec<qfa_report::plot_png::Plot>,
}

fn bar(len: u64, msg: &str, show: bool) -> indicatif::ProgressBar {
    if !show {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new(len);
    pb.set_style(
        indicatif::ProgressStyle::with_template("{msg:>22} [{bar:30}] {pos}/{len} {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    pb.set_message(msg.to_string());
    pb
}

/// Why a cycling calibration failed: each cause its own variant, with the message the
/// command line prints.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum CalibrateError {
    /// The log could not be read (every bad row with its line).
    Read(qfa_log::cycling::LogError),
    /// A fit failed.
    Fit(FitError),
    /// The held-out compensation failed.
    Evaluate(crate::compensate::Error),
    /// A held-out figure that cannot be computed, and why (never NaN, `null` or 0.0).
    NotComputable(NotComputable),
    /// The peers could not be fitted: no ±1 g pair with temperatures in the programs.
    NoPeerPair,
    /// The peers' fit failed.
    PeerFit(FitError),
    /// The coverage of the fitted rows or of the table could not be formed.
    Coverage(crate::coverage::CoverageError),
    /// A table the root crate refuses to encode.
    Table(qfa_thermal::table::Error),
    /// A table that does not serialize as TOML.
    Toml(toml::ser::Error),
    /// An accelerometer axis other than `ax`, `ay` or `az`.
    Axis(String),
    /// An output file, folder or plot that could not be written.
    Output(output_error::OutputError),
    /// The runs to be fitted hold what no fit can be right on (a stuck counter or sensor).
    Contents(qfa_log::cycling::ContentFault),
}

impl fmt::Display for CalibrateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Read(e) => write!(f, "{e}"),
            Self::Fit(e) => write!(f, "{e}"),
            Self::Evaluate(e) => write!(f, "{e}"),
            Self::Table(e) => write!(f, "{e}"),
            Self::Axis(axis) => write!(f, "axis `{axis}`: expected ax, ay or az"),
            Self::NotComputable(e) => write!(f, "{e}"),
            Self::NoPeerPair => f.write_str("peers: no +1 g / -1 g pair with temperatures in the fit programs"),
            Self::PeerFit(e) => write!(f, "peers: {e}"),
            Self::Coverage(e) => write!(f, "{e}"),
            Self::Toml(e) => write!(f, "{e}"),
            Self::Output(e) => write!(f, "{e}"),
            Self::Contents(e) => write!(f, "{e}"),
        }
    }
}

/// Refuse the rows a cycling fit is about to be made on when it cannot be right on them,
/// naming what they hold: a run of the fit programs whose pulse count never moves, or
/// readings that span less than the bias grid needs. Without this a stuck counter failed
/// as "cross-validation: non-finite fold MSE NaN" and a stuck sensor as "table rejected:
/// bias.t_step_c out of range". A fit program without a ±1 g pair is the fit's to refuse
/// (`FitError::NoPair`): the log's shape comes before its contents.
///
/// # Errors
/// [`CalibrateError::Contents`] ([`qfa_log::cycling::Log::check_contents`]).
pub fn check_inputs(log: &Log, paired: &PairedLog, fit_programs: &[String]) -> Result<(), CalibrateError> {
    // No program to fit at all (a log with its header alone): said as such, where the fit
    // said "0 equations for 2 unknowns".
    if !fit_programs.is_empty() && fit_programs.iter().any(|p| paired.program(p).is_none()) {
        return Ok(());
    }
    log.check_contents(fit_programs).map_err(CalibrateError::Contents)
}

impl std::error::Error for CalibrateError {}

/// A held-out figure that cannot be formed (it is an error, never NaN, `null` or 0.0).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum NotComputable {
    /// No held-out bin qualified for the bias residual of a model.
    NoBiasBin {
        /// `no compensation`, `simple` or `hysteresis`.
        model: &'static str,
    },
    /// Fewer than two held-out scale-factor bins for a model.
    TooFewSfBins {
        /// `no compensation`, `simple` or `hysteresis`.
        model: &'static str,
        /// The bins there were.
        bins: usize,
    },
    /// A figure whose held-out bins span no temperature range.
    NoTemperatureSpan {
        /// The figure, e.g. `sensitivity (simple)`.
        figure: &'static str,
    },
    /// No held-out bin qualified for the peers' bias residual.
    NoPeerBiasBin,
}

impl fmt::Display for NotComputable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let min_s = crate::metrics::MIN_BIN_S;
        match self {
            Self::NoBiasBin { model } => write!(
                f,
                "bias residual ({model}) not computable: no held-out bin qualified (a bin is one program, branch \
                 segment and 1 °C of T-hat with at least {min_s} s of rows the compensator marked compensated)"
            ),
            Self::TooFewSfBins { model, bins } => write!(
                f,
                "sensitivity ({model}) not computable: {bins} held-out scale-factor bin(s); needs 2 or more (held-out \
                 programs need both +1 g and -1 g runs, and bins at least {min_s} s of compensated rows)"
            ),
            Self::NoTemperatureSpan { figure } => {
                write!(f, "{figure} not computable: the held-out bins span no temperature range")
            }
            Self::NoPeerBiasBin => {
                write!(f, "peer bias residual not computable: no held-out bin qualified (bins need {min_s} s of rows)")
            }
        }
    }
}

impl From<output_error::OutputError> for CalibrateError {
    fn from(e: output_error::OutputError) -> Self {
        Self::Output(e)
    }
}

/// Fit and evaluate an in-memory log (no files).
///
/// # Errors
/// A message describing the failure.
pub fn calibrate_log(log: &Log, opts: &CalibrateOptions) -> Result<Calibration, CalibrateError> {
    let programs = log.programs();
    // Paired once; the fit, the evaluation, the peers and the table's refit read these pairs.
    let paired = PairedLog::new(log);
    let (fit_p, eval_p) = fit_and_eval_programs(&programs, opts.fit_programs.as_deref());
    check_inputs(log, &paired, &fit_p)?;
    // The table written: the structure chosen once, on every program with a pair
    // (`fit_table`); the held-out figures are of that structure fitted on the fit programs
    // (`fit_held_out`), so the figures score what is flashed. With no program beyond the
    // fit programs, both are one fit.
    let table_p: Vec<String> = programs.iter().filter(|p| paired.program(p).is_some()).cloned().collect();
    let one_fit = table_p.iter().all(|p| fit_p.contains(p));
    let t = Instant::now();
    let pb = bar(fit_p.len() as u64, "fitting", opts.progress);
    let (table, fitted) = if one_fit {
        let f = fit(&paired, &FitOptions { ext: opts.ext, ..FitOptions::new(fit_p.clone()) }, Some(&pb))
            .map_err(CalibrateError::Fit)?;
        (f.clone(), f)
    } else {
        let table = crate::fit::fit_table(&paired, &table_p, opts.ext).map_err(CalibrateError::Fit)?;
        let f = crate::fit::fit_held_out(&paired, &fit_p, &table, opts.ext, Some(&pb)).map_err(CalibrateError::Fit)?;
        (table, f)
    };
    pb.finish_and_clear();
    let t_fit = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let n_eval = log.runs.iter().filter(|r| eval_p.contains(&r.program)).count();
    let pb = bar(n_eval as u64, "held-out compensation", opts.progress);
    let eval =
        evaluate(&paired, &eval_p, &fitted.simple, &fitted.hysteresis, Some(&pb)).map_err(CalibrateError::Evaluate)?;
    pb.finish_and_clear();
    let t_eval = t.elapsed().as_secs_f64();
    check_figures(&eval)?;
    let (peers, fit_peers) = crate::report::peer_bias(&paired, &fit_p, &eval_p, &fitted.hysteresis)?;
    // The peers written: fitted on the table's programs.
    let peer_fits = if one_fit {
        fit_peers
    } else {
        let deadband = table.hysteresis.axes[0].bias.deadband_c_per_min;
        crate::report::peer_fit(&paired, &table_p, deadband)?
    };
    // What the table written covers and clamps to: its own programs and limits (the
    // held-out figures' fit programs are a part of them).
    let coverage = cal_coverage(log, &table_p, &table)?;
    // Held out when no fit program is scored (a log of one program scores its own rows).
    let held_out = fit_p.iter().all(|p| !eval_p.contains(p));
    let report = Report {
        coverage,
        rows: log.rows(),
        held_out,
        figures: figures_text(&fit_p, &eval_p, &table_p, held_out),
        table_programs: table_p,
        fit_programs: fit_p,
        eval_programs: eval_p,
        sensitivity_ppm_per_c: eval.sensitivity_ppm_per_c,
        bias_residual_ug: eval.bias_residual_ug,
        peers_bias_residual_ug: peers,
        metric: METRIC_TEXT.to_string(),
        fit: fit_summary(&table),
        rejected_readings: eval.rejected_readings,
        skipped_glitches: log.glitches.clone(),
        timings_s: Some(Timings { fit: t_fit, evaluate: t_eval, ..Timings::default() }),
    };
    Ok(Calibration {
        fitted,
        table,
        eval,
        report,
        peers: peer_fits,
        exports: export::Exports::default(),
        verdict: None,
        plots: Vec::new(),
    })
}

/// The fit programs (`fit_programs`, else [`split_programs`]'s) and the held-out ones
/// (the others; the fit programs themselves when there are none).
fn fit_and_eval_programs(programs: &[String], fit_programs: Option<&[String]>) -> (Vec<String>, Vec<String>) {
    let (fit_p, eval_p) = match fit_programs {
        Some(f) => (f.to_vec(), programs.iter().filter(|p| !f.contains(p)).cloned().collect::<Vec<_>>()),
        None => split_programs(programs),
    };
    let eval_p = if eval_p.is_empty() { fit_p.clone() } else { eval_p };
    (fit_p, eval_p)
}

/// What the table's programs `table_p` cover and what its hysteresis table claims.
fn cal_coverage(log: &Log, table_p: &[String], table: &Fitted) -> Result<crate::coverage::CalCoverage, CalibrateError> {
    let deadband = qfa_log::replay::branch_deadband_c_per_min();
    Ok(crate::coverage::CalCoverage {
        covered: crate::coverage::Coverage::of_log(log, table_p, deadband).map_err(CalibrateError::Coverage)?,
        table: crate::coverage::TableLimits::of(&table.hysteresis).map_err(CalibrateError::Coverage)?,
        programs: table_p.to_vec(),
    })
}

/// Which rows each output comes from, in words.
fn figures_text(fit_p: &[String], eval_p: &[String], table_p: &[String], held_out: bool) -> String {
    format!(
        "{} figures and plots: tables fitted on {fit}, compensated on {}; table.*, table_simple.*, \
         px4_tc.params, ardupilot_tcal_*.parm: fitted on {} (every program with a +1 g / -1 g pair), the bias \
         grid's branch tie and shape chosen there by cross-validation{}",
        if held_out { "held-out" } else { "in-sample (nothing held out)" },
        eval_p.join(", "),
        table_p.join(", "),
        if held_out { ", the figures' tables of that structure" } else { "" },
        fit = fit_p.join(", ")
    )
}

/// The figures of `table`, the fit `table.bin` holds, for the report's "Fit".
fn fit_summary(table: &Fitted) -> FitSummary {
    let h = &table.sf_hysteresis.coef;
    FitSummary {
        pairs: table.pairs,
        cond_sf_simple: table.sf_simple.cond,
        cond_sf_hysteresis: table.sf_hysteresis.cond,
        cond_bias_grid: table.bias_hysteresis.cond,
        eq11: [h[0], h[1], h[2], h[3], h[4], h[5]],
        simple_sf: [table.sf_simple.coef[0], table.sf_simple.coef[1]],
        simple_bias: [table.bias_simple.coef[0], table.bias_simple.coef[1]],
        rms_sf_hysteresis: table.sf_hysteresis.rms,
        branch: table.branch.clone(),
    }
}

/// Every held-out figure must exist: a figure with no bins behind it is an error with its
/// reason, never NaN, `null` or 0.0.
///
/// # Errors
/// The first figure that could not be formed, and why.
pub fn check_figures(ev: &crate::report::Evaluation) -> Result<(), CalibrateError> {
    let names = ["no compensation", "simple", "hysteresis"];
    for (v, &name) in names.iter().enumerate() {
        if ev.bins[v].bias.is_empty() {
            return Err(CalibrateError::NotComputable(NotComputable::NoBiasBin { model: name }));
        }
        if ev.bins[v].sf.len() < 2 {
            let bins = ev.bins[v].sf.len();
            return Err(CalibrateError::NotComputable(NotComputable::TooFewSfBins { model: name, bins }));
        }
    }
    let s = ev.sensitivity_ppm_per_c;
    let b = ev.bias_residual_ug;
    for (x, what) in [
        (s.none, "sensitivity (none)"),
        (s.simple, "sensitivity (simple)"),
        (s.hysteresis, "sensitivity (hysteresis)"),
        (b.none, "bias residual (none)"),
        (b.simple, "bias residual (simple)"),
        (b.hysteresis, "bias residual (hysteresis)"),
    ] {
        if !x.is_finite() {
            return Err(CalibrateError::NotComputable(NotComputable::NoTemperatureSpan { figure: what }));
        }
    }
    Ok(())
}

/// The text of a cycling calibration's `table.toml`: a comment line with the units, then
/// the table as TOML.
///
/// # Errors
/// The table does not serialize.
pub fn table_toml(table: &qfa_thermal::Table) -> Result<String, CalibrateError> {
    let toml = toml::to_string_pretty(table).map_err(CalibrateError::Toml)?;
    let header = "# qfa-thermal coefficient table (K1 pulses/(g*s), K0 g, T degC, rate degC/min)\n";
    Ok(format!("{header}{toml}"))
}

/// The accelerometer of a cycling calibration as the PX4 / ArduPilot exports see it: IMU
/// axis `axis` (`ax`, `ay` or `az`), a one-axis export.
///
/// # Errors
/// An axis other than `ax`, `ay` or `az`.
pub fn cycling_export_axis(cal: &Calibration, axis: &str) -> Result<export::ExportAxis, CalibrateError> {
    if !["ax", "ay", "az"].contains(&axis) {
        return Err(CalibrateError::Axis(axis.to_string()));
    }
    Ok(export::ExportAxis {
        source: format!("accelerometer (--axis {})", axis.trim_start_matches('a')),
        axis: axis.to_string(),
        cubic: cal.peers.cubic.clone(),
        ardupilot: Ok(cal.peers.ardupilot.clone()),
    })
}

/// Every file a calibration of one log may write into its folder, of any kind of log (a
/// cycling log's two tables and plots, a static log's plot, the reports, the PX4 and
/// ArduPilot files). [`clear_outputs`] removes them before a calibration writes its own.
pub const OUTPUT_FILES: [&str; 14] = [
    "table.bin",
    "table.toml",
    "table_simple.bin",
    "table_simple.toml",
    "report.json",
    "report.md",
    "report.html",
    static_cal::output::BIAS_PLOT,
    report::SF_PLOT,
    report::RESIDUAL_PLOT,
    export::EXPORT_FILES[0],
    export::EXPORT_FILES[1],
    export::EXPORT_FILES[2],
    export::EXPORT_FILES[3],
];

/// Remove every [`OUTPUT_FILES`] from `dir`, so the folder holds this calibration's files
/// only: a static run into a folder where a cycling run wrote left its `table_simple.bin`
/// (another unit's kind of table) and plots beside the new `table.bin`.
///
/// # Errors
/// A file that is there and cannot be removed.
pub fn clear_outputs(dir: &Path) -> Result<(), OutputError> {
    for name in OUTPUT_FILES {
        let path = dir.join(name);
        qfa_log::io_fault::remove_if_present(&path).map_err(OutputError::io(&path))?;
    }
    Ok(())
}

/// Write a table as TOML and postcard `.bin` under `dir/stem.{toml,bin}`.
///
/// # Errors
/// Encoding or I/O errors.
pub fn write_table(dir: &Path, stem: &str, table: &qfa_thermal::Table) -> Result<(), CalibrateError> {
    let toml_path = dir.join(format!("{stem}.toml"));
    std::fs::write(&toml_path, table_toml(table)?).map_err(OutputError::io(&toml_path))?;
    let bin = table.to_bytes().map_err(CalibrateError::Table)?;
    let bin_path = dir.join(format!("{stem}.bin"));
    Ok(std::fs::write(&bin_path, bin).map_err(OutputError::io(&bin_path))?)
}

/// Calibrate an in-memory log and write every output file into `out`.
///
/// # Errors
/// A message describing the failure.
pub fn calibrate_into(
    log: &Log,
    out: &Path,
    opts: &CalibrateOptions,
    read_s: f64,
) -> Result<Calibration, CalibrateError> {
    let t0 = Instant::now();
    std::fs::create_dir_all(out).map_err(OutputError::io(out))?;
    let mut cal = calibrate_log(log, opts)?;
    clear_outputs(out)?;
    write_table(out, "table", &cal.table.hysteresis)?;
    write_table(out, "table_simple", &cal.table.simple)?;
    // One accelerometer: a one-axis export, so the shared fields need opts.exports.range_c.
    let one = cycling_export_axis(&cal, opts.axis.as_deref().unwrap_or("ax"))?;
    cal.exports = export::write_exports(out, &[one], &opts.exports).map_err(OutputError::io(out))?;
    let t = Instant::now();
    if opts.plots {
        let held = format!(
            "{}: programs {} (tables fitted on {})",
            if cal.report.held_out { "held out" } else { "in-sample" },
            cal.report.eval_programs.join(", "),
            cal.report.fit_programs.join(", ")
        );
        let bins = if cal.report.held_out { "held-out bins" } else { "in-sample bins" };
        let title = if opts.title.is_empty() { held } else { format!("{}, {held}", opts.title) };
        let (sf, residual) = (out.join(report::SF_PLOT), out.join(report::RESIDUAL_PLOT));
        cal.plots = vec![
            plot_sf_vs_temp(&title, &cal.eval, bins).map_err(OutputError::plot(&sf))?,
            plot_residual_vs_time(&title, &cal.eval, bins).map_err(OutputError::plot(&residual))?,
        ];
        qfa_report::plot_png::write_all(&cal.plots, out).map_err(OutputError::io(out))?;
    }
    if opts.reproducible {
        cal.report.timings_s = None;
    } else if let Some(timings) = cal.report.timings_s.as_mut() {
        timings.plots = t.elapsed().as_secs_f64();
        timings.read = read_s;
        timings.total = read_s + t0.elapsed().as_secs_f64();
    }
    let mut files: Vec<String> = ["table.bin", "table.toml", "table_simple.bin", "table_simple.toml"]
        .into_iter()
        .chain(["report.json", "report.md", "report.html"])
        .map(String::from)
        .collect();
    files.extend(cal.plots.iter().map(|p| p.file.clone()));
    files.extend(cal.exports.written.iter().map(|f| (*f).to_string()));
    let who = opts.unit.as_deref().or(opts.axis.as_deref()).unwrap_or("ax");
    let notes: Vec<String> =
        opts.notes.iter().cloned().chain(cal.exports.notes.iter().map(ToString::to_string)).collect();
    let v = verdict::cycling_verdict(&cal.report, who, &opts.limits, &files, &notes);
    let json_path = out.join("report.json");
    let json = qfa_report::verdict::json_with_verdict(&v, &cal.report).map_err(OutputError::json(&json_path))?;
    std::fs::write(&json_path, json).map_err(OutputError::io(&json_path))?;
    let md = format!("# Calibration report\n\n{}{}", v.markdown(), report::markdown(&cal.report));
    let md_path = out.join("report.md");
    std::fs::write(&md_path, md).map_err(OutputError::io(&md_path))?;
    cal.verdict = Some(v);
    page(&cal, opts).write(out).map_err(OutputError::io(out))?;
    Ok(cal)
}

/// The calibration's `report.html` (see [`qfa_report::html_report`]), with the plots it drew.
pub(crate) fn page(cal: &Calibration, opts: &CalibrateOptions) -> qfa_report::html_report::Page {
    let r = &cal.report;
    let mut p = qfa_report::html_report::Page::new(&if opts.title.is_empty() {
        "Calibration report".to_string()
    } else {
        format!("Calibration report: {}", opts.title)
    });
    if let Some(v) = &cal.verdict {
        v.to_page(&mut p);
    }
    p.section("Held-out scheme").kv(&[
        ("fitted on (programs)", r.fit_programs.join(", ")),
        (
            if r.held_out { "held out, figures from (programs)" } else { "in-sample, figures from (programs)" },
            r.eval_programs.join(", "),
        ),
        ("written tables fitted on (programs)", r.table_programs.join(", ")),
        ("which rows each output comes from", r.figures.clone()),
        ("log rows", r.rows.to_string()),
    ]);
    if !r.held_out {
        p.warning(r.in_sample_reason());
    }
    held_out_figures_section(&mut p, r);
    p.para(&format!("Metric: {}.", r.metric));
    r.coverage.to_page(&mut p);
    fit_section(&mut p, &r.fit);
    plots_section(&mut p, &cal.plots, r.held_out);
    if let Some(t) = r.timings_s {
        p.section("Timings").para(&format!(
            "read {:.2} s, fit {:.2} s, held-out compensation {:.2} s, plots {:.2} s",
            t.read, t.fit, t.evaluate, t.plots
        ));
    }
    p
}

/// The structure the held-out figures are of, which `table.bin` holds.
pub(crate) fn held_out_structure(f: &FitSummary) -> String {
    fit::cycling_structure(f.branch.mode, f.branch.shape, &qfa_thermal::Extensions::NONE)
}

/// The held-out figures of each model and peer.
fn held_out_figures_section(p: &mut qfa_report::html_report::Page, r: &Report) {
    let (s, b, pb) = (r.sensitivity_ppm_per_c, r.bias_residual_ug, r.peers_bias_residual_ug);
    p.section(&format!("{} figures", r.scored())).table(
        &["model", "scale-factor sensitivity, ppm/°C", "bias residual, µg RMS"],
        &[
            vec!["no compensation".to_string(), format!("{:.2}", s.none), format!("{:.2}", b.none)],
            vec!["simple (Eq. 3–4)".to_string(), format!("{:.2}", s.simple), format!("{:.2}", b.simple)],
            vec![
                format!("hysteresis ({}), table.bin", held_out_structure(&r.fit)),
                format!("{:.2}", s.hysteresis),
                format!("{:.2}", b.hysteresis),
            ],
            vec![
                "PX4 / tofupilot cubic (bias only, in the table's place)".into(),
                "-".into(),
                format!("{:.2}", pb.cubic),
            ],
            vec!["ArduPilot TCAL (bias only, in the table's place)".into(), "-".into(), format!("{:.2}", pb.ardupilot)],
        ],
    );
}

/// The fit: its rows, condition numbers, Eq. 11 coefficients and the branch tie's
/// cross-validation.
fn fit_section(p: &mut qfa_report::html_report::Page, f: &FitSummary) {
    p.section("Fit (table.bin: every program with a pair)").kv(&[
        ("paired rows", f.pairs.to_string()),
        (
            "condition numbers (simple, Eq. 11, bias grid)",
            format!("{:.1}, {:.1}, {:.1}", f.cond_sf_simple, f.cond_sf_hysteresis, f.cond_bias_grid),
        ),
        ("Eq. 11 [γ, μ, β, ε, η, α]", f.eq11.iter().map(|c| format!("{c:.6e}")).collect::<Vec<_>>().join(", ")),
        (
            "bias grid branch tie (table.bin's, and the held-out figures')",
            format!("{:?} on {:?} curves: {}", f.branch.mode, f.branch.shape, f.branch.rule),
        ),
    ]);
    let branch_rows: Vec<Vec<String>> = f
        .branch
        .candidates
        .iter()
        .map(|c| {
            vec![
                format!("{:?}", c.mode),
                format!("{:?}", c.shape),
                c.unknowns.to_string(),
                format!("{:.2}", c.cv_rms_ug),
                format!("{:.3}", c.cv_mse_ug2),
                format!("{:.3}", c.cv_se_ug2),
            ]
        })
        .collect();
    p.table(&["branch tie", "curves", "unknowns", "CV RMS, µg", "CV MSE, µg²", "SE, µg²"], &branch_rows);
    p.para(&format!("Limit (best CV MSE + its SE): {:.3} µg² over {} folds.", f.branch.limit_ug2, f.branch.folds));
}

/// The held-out plots, each with what to read in it (no section without plots).
fn plots_section(p: &mut qfa_report::html_report::Page, plots: &[qfa_report::plot_png::Plot], held_out: bool) {
    if plots.is_empty() {
        return;
    }
    p.section(if held_out {
        "Plots (held-out bins only: the fit programs are not drawn)"
    } else {
        "Plots (in-sample: the rows the tables were fitted on)"
    });
    p.plots(plots, |file| plot_caption(file).to_string());
}

/// What to read in the cycling calibration's plot `file`.
#[must_use]
pub fn plot_caption(file: &str) -> &'static str {
    match file {
        report::SF_PLOT => {
            "Scale factor against temperature on the programs scored (held out; a one-program log's own), per model. Left, uncompensated: the \
         drift and the gap between heating (red) and cooling (blue) are what the table must remove. Right, \
         the table (hysteresis): the points should lie flat, the two colours on one band; a slope left is \
         sensitivity, a gap left is hysteresis the model did not carry."
        }
        _ => {
            "Held-out residuals against time since each program's start, scale factor (top) and bias (bottom): \
         green (the table) should stay closer to zero than orange (the simple model) and show no trend; a \
         jump that both models share is in the unit or the log, not in either model."
        }
    }
}

/// Read the cycling log at `log_path` and calibrate it into `out`: the demo's entry, for
/// the log it wrote (`qfa-lab calibrate` goes through `open` and [`calibrate_into`]).
///
/// # Errors
/// The failure (for a malformed log: every bad row with its line).
pub fn calibrate_file(log_path: &Path, out: &Path, opts: &CalibrateOptions) -> Result<Calibration, CalibrateError> {
    let t = Instant::now();
    let log = read_log(log_path).map_err(CalibrateError::Read)?;
    calibrate_into(&log, out, opts, t.elapsed().as_secs_f64())
}
