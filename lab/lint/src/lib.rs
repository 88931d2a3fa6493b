//! qfa-lint, `qfa-lab lint`: every check the lab makes on a log before a fit, as a list of findings a
//! person acts on (what, the evidence, the fix), for a log the reader takes and for one it
//! refuses. `calibrate` runs it first and prints its warnings.
//!
//! The checks, in order: the format and the columns found; each unit and its evidence
//! (from the option, the column name or assumed; the figure checked against it); the
//! instances (several columns that could be one role, an ID column with several values);
//! the temperature resolution; the coverage of the heating and cooling legs and their rates
//! against what the model needs (a span for the bias grid, rows per degree, both legs for
//! two branches, a later leg to hold out); glitches, gaps and skipped rows; and signs that
//! compensation was already on when the log was recorded.

use std::fmt;
use std::path::Path;

use serde::Serialize;

use qfa_calibrate::coverage::Coverage;
use qfa_calibrate::static_cal::{check_coverage, check_outputs, is_one_branch, split_index, StaticCalOptions};
use qfa_log::open::{open_bytes, OpenError, OpenedLog, ReadError, ReadFlags};
use qfa_log::pairing::trace_view;
use qfa_log::replay::branch_deadband_c_per_min;
use qfa_log::robust::{median, neighbour_noise};
use qfa_log::spelling::Spelling;
use qfa_log::static_log::{StaticError, StaticLog, COMMON_NAMES};
use qfa_log::units::{ReaderOption, UnitSource};

mod cycling;
pub use cycling::lint_cycling;

/// How much a finding matters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub enum Severity {
    /// Checked, nothing to do.
    Ok,
    /// Worth knowing; nothing is wrong.
    Note,
    /// The fit runs, but its result is weaker or less certain than it could be: act on it.
    Warning,
    /// The lab refuses the log (or the fit would): act on it before anything else.
    Error,
}

impl fmt::Display for Severity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Ok => "ok",
            Self::Note => "note",
            Self::Warning => "warning",
            Self::Error => "error",
        })
    }
}

/// One finding.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Finding {
    /// How much it matters.
    pub severity: Severity,
    /// The check (`format`, `units`, `instances`, `resolution`, `coverage`, `rows`,
    /// `gaps`, `compensation`).
    pub check: &'static str,
    /// What was found.
    pub what: String,
    /// The figures behind it.
    pub evidence: String,
    /// What to do; empty when nothing is to be done.
    pub fix: String,
}

impl Finding {
    fn new(severity: Severity, check: &'static str, what: String, evidence: String, fix: &str) -> Self {
        Self { severity, check, what, evidence, fix: fix.to_string() }
    }
}

impl fmt::Display for Finding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "[{}] {}: {}", self.severity, self.check, self.what)?;
        if !self.evidence.is_empty() {
            write!(f, "\n    evidence: {}", self.evidence)?;
        }
        if !self.fix.is_empty() {
            write!(f, "\n    fix: {}", self.fix)?;
        }
        Ok(())
    }
}

/// A lint run: the findings, and the log as its reader returned it (so `calibrate` reads
/// the file once).
#[derive(Debug)]
pub struct Lint {
    /// Findings, in check order.
    pub findings: Vec<Finding>,
    /// The log, or why it was refused.
    pub log: Result<OpenedLog, OpenError>,
}

impl Lint {
    /// The worst severity found.
    #[must_use]
    pub fn worst(&self) -> Severity {
        self.findings.iter().map(|f| f.severity).max().unwrap_or(Severity::Ok)
    }

    /// Findings of at least `severity`.
    pub fn at_least(&self, severity: Severity) -> impl Iterator<Item = &Finding> {
        self.findings.iter().filter(move |f| f.severity >= severity)
    }
}

/// Lint the log at `path`, read with `flags` (the reader's flags, as `calibrate` takes them).
#[must_use]
pub fn lint(path: &Path, flags: &ReadFlags) -> Lint {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(error) => {
            let e = OpenError::Io { path: path.to_path_buf(), error };
            let f = Finding::new(Severity::Error, "format", "the file cannot be read".into(), e.to_string(), "");
            return Lint { findings: vec![f], log: Err(e) };
        }
    };
    let opened = open_bytes(&bytes, flags);
    let findings = match &opened {
        Ok(OpenedLog::Static(l)) => lint_static(&bytes, l),
        Ok(OpenedLog::Cycling(l)) => lint_cycling(l),
        Ok(OpenedLog::Autopilot(l)) => lint_autopilot(l),
        Ok(OpenedLog::Single(_)) => vec![Finding::new(
            Severity::Note,
            "format",
            "a single-channel log (time_s,temp_c,value): `discover` reads it, `calibrate` does not".into(),
            String::new(),
            "",
        )],
        Err(e) => vec![refused(e)],
    };
    Lint { findings, log: opened.map_err(|error| OpenError::Read { path: path.to_path_buf(), error }) }
}

/// An autopilot log: each accelerometer instance as `calibrate` will treat it (the checks
/// are the reader's own, `qfa_log::autopilot::check`), and what the reader left unread.
fn lint_autopilot(l: &qfa_log::autopilot::AutopilotLog) -> Vec<Finding> {
    let mut out = vec![Finding::new(
        Severity::Ok,
        "format",
        format!("{:?} log with {} accelerometer instance(s)", l.stack, l.instances.len()),
        String::new(),
        "",
    )];
    for c in qfa_log::autopilot::check(l) {
        let id = c.device_id.map_or_else(|| "no device ID".to_string(), |id| format!("device ID {id}"));
        match &c.refused {
            Some(why) => out.push(Finding::new(
                Severity::Error,
                "instances",
                format!("{} is refused", c.name()),
                why.clone(),
                "see the evidence: it says what to record or set",
            )),
            None => out.push(Finding::new(
                Severity::Ok,
                "instances",
                format!("{} ({id}, {} samples) is calibrated", c.name(), c.samples),
                String::new(),
                "",
            )),
        }
        for w in &c.warnings {
            out.push(Finding::new(
                Severity::Warning,
                "instances",
                format!("{}: see the evidence", c.name()),
                w.clone(),
                "",
            ));
        }
    }
    for n in &l.reader_notes {
        out.push(Finding::new(Severity::Note, "gaps", n.clone(), String::new(), ""));
    }
    out
}

/// The finding for a log its reader refuses: the reader's message, and the fix its type
/// names.
fn refused(e: &ReadError) -> Finding {
    let (check, fix) = match e {
        ReadError::Static(s) => match s.as_ref() {
            StaticError::Unit(m) => {
                let fix = if m.fits.is_empty() {
                    format!("check {} against the logger's documentation", m.option.name(Spelling::Cli))
                } else {
                    let v: Vec<String> = m.fits.iter().map(|(u, _)| m.option.with(Spelling::Cli, u)).collect();
                    format!("pass {}", v.join(" or "))
                };
                ("units", fix)
            }
            StaticError::BadUnit(p) => ("units", format!("pass one of {}", p.option.allowed())),
            StaticError::UnitUnknown { option, .. } => {
                ("units", format!("pass {} (the logger's unit)", option.with(Spelling::Cli, option.allowed())))
            }
            StaticError::UnknownColumn { role, .. } | StaticError::MissingColumn { role, .. } => {
                ("format", format!("pass {}", ReaderOption::Columns.with(Spelling::Cli, &format!("{role}=NAME"))))
            }
            StaticError::DecimalComma { .. } => ("format", "pass --decimal-comma".to_string()),
            StaticError::Rows { .. } => ("format", "correct or delete the lines listed".to_string()),
            StaticError::TooFewRows { .. } | StaticError::NoRows | StaticError::Empty => {
                ("format", "log more rows (the lab needs 16 after the skips)".to_string())
            }
            _ => ("format", "see the evidence".to_string()),
        },
        ReadError::Cycling(_) => ("format", "correct or delete the lines listed".to_string()),
        ReadError::Single(_) => ("format", "correct or delete the lines listed".to_string()),
        ReadError::Ulog(_) | ReadError::Dataflash(_) => {
            ("format", "re-download the log from the vehicle; a truncated file is refused whole".to_string())
        }
        ReadError::OptionsOnCyclingLog => ("format", "drop the reader options: a cycling log takes none".to_string()),
    };
    Finding {
        severity: Severity::Error,
        check,
        what: "the reader refuses the log".into(),
        evidence: e.to_string(),
        fix,
    }
}

/// Resolution of a reading: the smallest step between distinct values, and how many
/// distinct values.
fn resolution(v: &[f64]) -> (f64, usize) {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s.dedup();
    let step = s.windows(2).map(|w| w[1] - w[0]).filter(|d| *d > 1e-9).fold(f64::INFINITY, f64::min);
    (step, s.len())
}

/// Coarsest temperature step that lint passes without a warning, °C: the rate estimator
/// fits a line through 32 readings, so steps of 0.5 °C turn a 1 °C/min ramp into a
/// staircase of 30-s treads. Chosen from that arithmetic, before any log was linted.
pub(crate) const COARSE_TEMP_STEP_C: f64 = 0.5;

/// The bias must change by at least this many times its per-degree noise over the log's
/// span, on some axis, before lint takes the log as raw output: a flatter log was likely
/// recorded with compensation on. Chosen before any log was linted; the real tofupilot log
/// changes by 100× and more.
pub(crate) const FLAT_FACTOR: f64 = 5.0;

/// The checks on a static log.
#[must_use]
pub fn lint_static(bytes: &[u8], log: &StaticLog) -> Vec<Finding> {
    let mut out = Vec::new();
    let n = log.rows();
    // Format and columns.
    let cols: Vec<String> = log.columns.iter().map(|(r, c, _)| format!("{r}=`{c}`")).collect();
    out.push(Finding::new(
        Severity::Ok,
        "format",
        format!("static multi-axis log, {n} rows kept, {} axis(es)", log.axes.len()),
        format!("columns {}", cols.join(", ")),
        "",
    ));
    units(log, &mut out);
    instances(bytes, log, &mut out);
    // Temperature resolution.
    let (step, distinct) = resolution(&log.temp_c);
    let step_s = if step < 1e-3 { format!("{step:.1e}") } else { format!("{step:.4}") };
    let ev = format!(
        "smallest step between readings {step_s} °C, {distinct} distinct readings; the firmware reads 1/16 °C \
         (0.0625)"
    );
    if step > COARSE_TEMP_STEP_C {
        out.push(Finding::new(
            Severity::Warning,
            "resolution",
            format!("temperature readings are coarse (steps of {step:.2} °C)"),
            ev,
            "log the sensor's full resolution (a DS18B20 gives 0.0625 °C)",
        ));
    } else {
        out.push(Finding::new(Severity::Ok, "resolution", format!("temperature step {step_s} °C"), ev, ""));
    }
    coverage_static(log, &mut out);
    skipped_rows(log, &mut out);
    if let Err(e) = check_outputs(log) {
        out.push(Finding::new(
            Severity::Error,
            "outputs",
            e.to_string(),
            "every row of that column holds the same number".into(),
            "check the sensor (a stuck output fails the unit) and --columns (a column the logger filled with a \
             constant is not an axis)",
        ));
    }
    compensation_on(log, &mut out);
    out
}

fn units(log: &StaticLog, out: &mut Vec<Finding>) {
    let u = &log.units;
    for (option, unit, source, figure) in &u.units {
        let src = source.describe(&option.with(Spelling::Cli, unit));
        let evidence = format!("{src}; {figure}");
        let f = match option {
            ReaderOption::AccelUnit if !u.all_axes => Finding::new(
                Severity::Warning,
                "units",
                format!("acceleration in {unit}, checked from above only: {} of 3 axes", log.axes.len()),
                format!("{evidence}; with one or two axes |a| is a projection of 1 g, so a unit that makes the values too small cannot be seen"),
                "log all three axes (|a| = 1 g at rest then checks the unit from both sides), and make sure of the unit",
            ),
            ReaderOption::AccelUnit => Finding::new(
                Severity::Ok,
                "units",
                format!("acceleration in {unit}: |a| at rest is 1 g"),
                format!("{evidence} (accepted: {:.2}..{:.2} g)", qfa_log::units::REST_G.0, qfa_log::units::REST_G.1),
                "",
            ),
            ReaderOption::TempUnit if !u.temp_also_plausible.is_empty() && *source == UnitSource::Assumed => {
                let alt: Vec<String> = u
                    .temp_also_plausible
                    .iter()
                    .map(|(a, (lo, hi))| format!("read in {a} it spans {lo:.1}..{hi:.1} °C"))
                    .collect();
                Finding::new(
                    Severity::Warning,
                    "units",
                    format!("temperature unit assumed {unit}: the readings cannot tell"),
                    format!("{evidence}; {}, also plausible", alt.join(", ")),
                    &format!(
                        "pass {} (or the logger's unit) to state it, or name the column for its unit (`temp_c`, `temp_f`)",
                        option.with(Spelling::Cli, unit)
                    ),
                )
            }
            ReaderOption::TempUnit if !u.temp_also_plausible.is_empty() => {
                let alt: Vec<String> =
                    u.temp_also_plausible.iter().map(|(a, (lo, hi))| format!("{a} gives {lo:.1}..{hi:.1} °C")).collect();
                Finding::new(
                    Severity::Note,
                    "units",
                    format!("temperature in {unit}, as stated; the readings alone could not tell"),
                    format!("{evidence}; {}", alt.join(", ")),
                    "",
                )
            }
            ReaderOption::TimeUnit => Finding::new(
                Severity::Ok,
                "units",
                format!("time in {unit}: row interval and fastest temperature change plausible"),
                evidence,
                "",
            ),
            _ => Finding::new(Severity::Ok, "units", format!("temperature in {unit}"), evidence, ""),
        };
        out.push(f);
    }
}

/// Words that mark a column as a device or instance ID.
fn is_id_column(c: &str) -> bool {
    let c = c.to_ascii_lowercase();
    let last = c.rsplit(['.', '_']).next().unwrap_or(&c);
    matches!(last, "id" | "instance" | "device" | "serial") || c.ends_with("device_id")
}

fn instances(bytes: &[u8], log: &StaticLog, out: &mut Vec<Finding>) {
    let first = bytes.split(|b| *b == b'\n').next().unwrap_or_default();
    let delim =
        [b'\t', b',', b';'].into_iter().max_by_key(|d| first.iter().filter(|c| *c == d).count()).unwrap_or(b',');
    let mut rdr = csv::ReaderBuilder::new().delimiter(delim).flexible(true).from_reader(bytes);
    let header: Vec<String> =
        rdr.headers().map(|h| h.iter().map(|s| s.trim().to_string()).collect()).unwrap_or_default();
    let mut found = false;
    for (role, names) in COMMON_NAMES.iter().filter(|(r, _)| *r != "time") {
        let used = log.columns.iter().find(|(r, _, _)| r == role).map(|(_, c, _)| c.as_str());
        let cands: Vec<&String> = header
            .iter()
            .filter(|h| names.iter().any(|n| qfa_log::static_log::matches_common(h, n)) || Some(h.as_str()) == used)
            .collect();
        if cands.len() > 1 {
            found = true;
            out.push(Finding::new(
                Severity::Warning,
                "instances",
                format!("{} columns could be {role}; read `{}`", cands.len(), used.unwrap_or("none")),
                format!("the header has {}", cands.iter().map(|c| format!("`{c}`")).collect::<Vec<_>>().join(", ")),
                &format!(
                    "calibrate one sensor instance at a time: pass --columns {role}=NAME (and the other roles) for each"
                ),
            ));
        }
    }
    for (k, col) in header.iter().enumerate().filter(|(_, c)| is_id_column(c)) {
        let mut values: Vec<String> = Vec::new();
        for r in rdr.records().flatten() {
            if let Some(v) = r.get(k) {
                if !values.iter().any(|x| x == v) {
                    values.push(v.to_string());
                }
            }
            if values.len() > 20 {
                break;
            }
        }
        found = true;
        if values.len() > 1 {
            out.push(Finding::new(
                Severity::Error,
                "instances",
                format!("column `{col}` holds {} different IDs: rows of several devices", values.len()),
                format!("values {}", values.iter().take(5).cloned().collect::<Vec<_>>().join(", ")),
                "split the log by device and calibrate each on its own",
            ));
        } else {
            out.push(Finding::new(
                Severity::Ok,
                "instances",
                format!("one device: column `{col}` = {}", values.first().map_or("(empty)", String::as_str)),
                String::new(),
                "",
            ));
        }
    }
    if !found {
        out.push(Finding::new(
            Severity::Ok,
            "instances",
            "one instance: no second column for any role, no ID column".into(),
            String::new(),
            "",
        ));
    }
    out.push(Finding::new(
        Severity::Note,
        "instances",
        "the PX4 parameter file needs the accelerometer's device ID".into(),
        "PX4 applies TC_A0_* only to the accelerometer whose device ID equals TC_A0_ID".into(),
        "pass --px4-device-id ID to calibrate (the vehicle's CAL_ACC0_ID)",
    ));
}

fn coverage_static(log: &StaticLog, out: &mut Vec<Finding>) {
    let opts = StaticCalOptions::default();
    if let Err(e) = check_coverage(&log.temp_c, opts.grid_points, opts.block) {
        out.push(Finding::new(
            Severity::Error,
            "coverage",
            "calibrate refuses: the temperatures cannot hold the bias grid".into(),
            e.to_string(),
            "record a wider temperature span with rows throughout it (a ramp, not a jump)",
        ));
    }
    let deadband = branch_deadband_c_per_min();
    let view = qfa_calibrate::fit::StaticSeries::view_of(&log.time_s, &log.temp_c, deadband);
    let tr = trace_view(&view, &qfa_thermal::Extensions::default(), deadband);
    let samples = (0..tr.valid.len()).filter(|&i| tr.valid[i]).map(|i| (tr.temp_c[i], tr.rate_c_per_min[i]));
    let Ok(cov) = Coverage::of_samples(samples, f64::from(deadband)) else {
        return;
    };
    coverage_findings(&cov, out);
    if let Err(e) = split_index(log) {
        out.push(Finding::new(
            Severity::Note,
            "coverage",
            "no later leg after the highest temperature: the held-out figures come from time blocks".into(),
            e.to_string(),
            "end the log with a cooling leg from its highest temperature, the leg `after-max` holds out",
        ));
    }
}

/// The legs and rates of `cov`, against what the model needs.
fn coverage_findings(cov: &Coverage, out: &mut Vec<Finding>) {
    let leg = |b: Option<qfa_calibrate::coverage::BranchRange>| {
        b.map_or("none".to_string(), |b| {
            format!(
                "{} rows, {:.1}..{:.1} °C, fastest {:.2} °C/min",
                b.rows, b.temp_c[0], b.temp_c[1], b.max_abs_rate_c_per_min
            )
        })
    };
    let (h, c) = (cov.heating.map_or(0, |b| b.rows), cov.cooling.map_or(0, |b| b.rows));
    let evidence = format!(
        "T̂ {:.1}..{:.1} °C; heating: {}; cooling: {} (Ṫ beyond ±{:.2} °C/min, as the firmware's estimator sees it)",
        cov.temp_c[0],
        cov.temp_c[1],
        leg(cov.heating),
        leg(cov.cooling),
        cov.deadband_c_per_min
    );
    if is_one_branch((h, c)) {
        let missing = if h < c { "heating" } else { "cooling" };
        out.push(Finding::new(
            Severity::Warning,
            "coverage",
            format!("one leg: fewer than a tenth of the rows are on the {missing} branch, so the table is one curve for both"),
            evidence,
            &format!(
                "record a {missing} leg across {:.0}..{:.0} °C at the rates the flight will see (this log reaches {:.2} °C/min)",
                cov.temp_c[0],
                cov.temp_c[1],
                cov.max_abs_rate()
            ),
        ));
    } else {
        out.push(Finding::new(
            Severity::Ok,
            "coverage",
            "heating and cooling legs: two branches can be fitted".into(),
            evidence,
            "",
        ));
    }
    out.push(Finding::new(
        Severity::Note,
        "coverage",
        format!(
            "the table will cover {:.0}..{:.0} °C and ±{:.2} °C/min; beyond, the firmware clamps and flags \
             TEMP_OUT_OF_RANGE / RATE_OUT_OF_RANGE",
            cov.temp_c[0].floor(),
            cov.temp_c[1].ceil(),
            1.25 * cov.max_abs_rate()
        ),
        "the grid spans every T̂ of the log; the rate limit is 1.25 × the fastest |Ṫ| fitted".into(),
        "record the temperatures and rates the flight will reach (`qfa-lab plan` compares a mission with a program)",
    ));
}

fn skipped_rows(log: &StaticLog, out: &mut Vec<Finding>) {
    let s = &log.skipped;
    let sampling = log.sampling.to_string();
    if s.total() > 0 {
        let sev = if s.total() * 100 > log.rows() { Severity::Warning } else { Severity::Note };
        out.push(Finding::new(
            sev,
            "rows",
            format!("{} row(s) skipped", s.total()),
            s.to_string(),
            if sev == Severity::Warning {
                "more than 1 % of the rows: check the logger and the lines listed"
            } else {
                "nothing to do; the lines are listed if you want to look"
            },
        ));
    } else {
        out.push(Finding::new(Severity::Ok, "rows", "no row skipped".into(), String::new(), ""));
    }
    if log.sampling.gaps_over_30s > 0 {
        out.push(Finding::new(
            Severity::Warning,
            "gaps",
            format!("{} gap(s) over 30 s: the rate estimator restarts after each", log.sampling.gaps_over_30s),
            sampling,
            "log without pauses (after a gap the firmware flags RATE_NOT_READY until 32 readings are in)",
        ));
    } else {
        out.push(Finding::new(Severity::Ok, "gaps", "no gap over 30 s".into(), sampling, ""));
    }
}

/// How much each axis's output changes over temperature (range of 1-°C bin medians) against
/// its noise per bin: a log whose every axis is flat was likely recorded compensated.
fn compensation_on(log: &StaticLog, out: &mut Vec<Finding>) {
    let lo = log.temp_c.iter().copied().fold(f64::INFINITY, f64::min);
    let mut per_axis = Vec::new();
    let mut flat = true;
    for a in &log.axes {
        let mut bins: Vec<Vec<f64>> = Vec::new();
        for (t, &v) in log.temp_c.iter().zip(&a.accel_g) {
            let k = (t - lo).floor() as usize;
            if bins.len() <= k {
                bins.resize(k + 1, Vec::new());
            }
            bins[k].push(v);
        }
        let meds: Vec<(f64, usize)> =
            bins.iter().filter(|b| b.len() >= 5).filter_map(|b| Some((median(b)?, b.len()))).collect();
        if meds.len() < 2 {
            return;
        }
        let range = meds.iter().map(|m| m.0).fold(f64::NEG_INFINITY, f64::max)
            - meds.iter().map(|m| m.0).fold(f64::INFINITY, f64::min);
        let (Some(sigma), Some(per_bin)) =
            (neighbour_noise(&a.accel_g), median(&meds.iter().map(|m| m.1 as f64).collect::<Vec<_>>()))
        else {
            return;
        };
        let noise = (1.25 * sigma / per_bin.sqrt()).max(1e-7);
        flat &= range < FLAT_FACTOR * noise;
        per_axis.push(format!("{} changes {:.3} mg (noise per 1-°C bin {:.4} mg)", a.name, range * 1e3, noise * 1e3));
    }
    let named: Vec<&str> = log
        .axes
        .iter()
        .map(|a| a.column.as_str())
        .filter(|c| {
            let c = c.to_ascii_lowercase();
            ["comp", "corr", "calib", "tcal"].iter().any(|w| c.contains(w))
        })
        .collect();
    let evidence = per_axis.join("; ");
    if flat || !named.is_empty() {
        let what = if flat {
            "no axis changes with temperature beyond its noise: compensation may have been on when this was logged"
                .to_string()
        } else {
            format!("column(s) {} are named as if already compensated", named.join(", "))
        };
        out.push(Finding::new(
            Severity::Warning,
            "compensation",
            what,
            evidence,
            "log the raw sensor output with the autopilot's thermal compensation off (PX4 TC_A_ENABLE 0, ArduPilot \
             INS_TCAL1_ENABLE 0): a fit on compensated output fits the residual",
        ));
    } else {
        out.push(Finding::new(
            Severity::Ok,
            "compensation",
            "the output changes with temperature: raw, not already compensated".into(),
            evidence,
            "",
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolution_is_the_smallest_step() {
        let (s, n) = resolution(&[20.0, 20.0625, 20.125, 20.0]);
        assert!((s - 0.0625).abs() < 1e-12 && n == 3);
        assert!(is_id_column("imu.device_id") && is_id_column("id") && !is_id_column("imu.acc.x"));
    }
}
