//! The checks on a cycling log: its programs and their ±1 g pairs, rows before the first
//! reading, what its fitted runs hold (`Log::check_contents`) and its coverage.

use qfa_calibrate::coverage::Coverage;
use qfa_log::cycling::Log;
use qfa_log::replay::branch_deadband_c_per_min;

use crate::{coverage_findings, Finding, Severity};

/// The checks on a cycling log (`qfa-lab lint`; a QFA unit of a batch).
#[must_use]
pub fn lint_cycling(log: &Log) -> Vec<Finding> {
    let mut out = Vec::new();
    let programs = log.programs();
    out.push(Finding::new(
        Severity::Ok,
        "format",
        format!("cycling log, {} rows, {} runs, {} program(s)", log.rows(), log.runs.len(), programs.len()),
        format!("programs {}", programs.join(", ")),
        "",
    ));
    let paired: Vec<&String> = programs
        .iter()
        .filter(|p| {
            let ins: Vec<f64> = log.runs_of(p).map(|r| r.input_g).collect();
            ins.iter().any(|g| *g > 0.5) && ins.iter().any(|g| *g < -0.5)
        })
        .collect();
    if paired.is_empty() {
        out.push(Finding::new(
            Severity::Error,
            "coverage",
            "no program has a +1 g and a −1 g run: calibrate cannot form K1 and K0".into(),
            format!("programs {}", programs.join(", ")),
            "record the 0° and 180° positions (+1 g, −1 g) under each temperature program",
        ));
    } else {
        out.push(Finding::new(
            Severity::Ok,
            "coverage",
            format!("{} of {} program(s) have a ±1 g pair", paired.len(), programs.len()),
            String::new(),
            "",
        ));
    }
    skipped_rows(log, &mut out);
    let no_temp: usize = log.runs.iter().map(|r| r.samples.iter().filter(|s| s.temp_c.is_none()).count()).sum();
    if no_temp > 0 {
        out.push(Finding::new(
            Severity::Note,
            "rows",
            format!("{no_temp} row(s) before the first temperature reading of their run"),
            String::new(),
            "nothing to do: the firmware flags them TEMP_STALE",
        ));
    }
    let paired_programs: Vec<String> = paired.into_iter().cloned().collect();
    if let Err(e) = qfa_calibrate::check_inputs(log, &qfa_log::pairing::PairedLog::new(log), &paired_programs) {
        out.push(Finding::new(
            Severity::Error,
            "outputs",
            e.to_string(),
            "calibrate refuses the log for it".into(),
            "check the converter's count and the temperature sensor, and the columns they are logged in",
        ));
    }
    let deadband = branch_deadband_c_per_min();
    if let Ok(cov) = Coverage::of_log(log, &programs, deadband) {
        coverage_findings(&cov, &mut out);
    }
    out
}

/// The rows the reader skipped (written twice, one-row glitches), by the static log's rule:
/// a warning over 1 % of the rows, a note under.
fn skipped_rows(log: &Log, out: &mut Vec<Finding>) {
    let skipped = log.repeated.count + log.glitches.len();
    if skipped == 0 {
        out.push(Finding::new(Severity::Ok, "rows", "no row skipped".into(), String::new(), ""));
        return;
    }
    let mut detail = Vec::new();
    if log.repeated.count > 0 {
        detail.push(format!(
            "{} row(s) written twice (each repeats its run's previous row exactly) skipped (line {})",
            log.repeated.count,
            log.repeated.listed()
        ));
    }
    detail.extend(qfa_log::cycling::glitches_sentence(&log.glitches));
    let sev = if skipped * 100 > log.rows() { Severity::Warning } else { Severity::Note };
    out.push(Finding::new(
        sev,
        "rows",
        format!("{skipped} row(s) skipped"),
        detail.join("; "),
        if sev == Severity::Warning {
            "more than 1 % of the rows: check the logger and the lines listed"
        } else {
            "nothing to do; the lines are listed if you want to look"
        },
    ));
}
