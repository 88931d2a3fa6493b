//! The entry points: the workflow with its outputs written ([`discover`],
//! [`discover_with_verdict`]) and the lab demo's hook.

use super::*;
pub use qfa_log::channels::Source;
use qfa_report::verdict::Verdict;

/// Run the workflow on `input` from `start` and write the outputs to `out_dir`.
///
/// # Errors
/// A cycling log's table not fitted, or an output not written ([`DiscoverError`]).
pub fn discover(input: &Source, start: Start, out_dir: &Path) -> Result<Report> {
    Ok(discover_with_verdict(input, start, out_dir)?.0)
}

/// The catalog's report on `input` and, for a cycling log, the table `calibrate` writes
/// too ([`crate::cycling_table`]; `None`: a single-channel log's is the catalog's model).
///
/// # Errors
/// A cycling log's table could not be fitted.
pub fn analyze_source(input: &Source, start: Start) -> Result<(Report, Option<qfa_thermal::Table>)> {
    let mut report = analyze(input.channels(), start);
    let table = match input {
        Source::Cycling { log, channels } => Some(crate::cycling_table::adopt(log, channels, &mut report)?),
        Source::Single(_) => None,
    };
    Ok((report, table))
}

/// [`discover`], with the verdict its reports open with (what `qfa-lab discover` prints).
///
/// # Errors
/// As [`discover`].
pub fn discover_with_verdict(input: &Source, start: Start, out_dir: &Path) -> Result<(Report, Verdict)> {
    let (report, table) = analyze_source(input, start)?;
    let (v, _) = output::write(input.channels(), &report, table.as_ref(), out_dir, output::Scope::Own)?;
    Ok((report, v))
}

/// Demo hook: start `simple` on a unit's cycling log, which should rediscover the paper's
/// Eq. 11 terms. Returns a one-line summary.
///
/// # Errors
/// The log gives no channels, or an output could not be written (the demo fails with it).
pub fn demo_hook(log: &Path, out: &Path) -> Result<String, DiscoverError> {
    let r = discover(&Source::read(log, 60.0)?, Start::Simple, out)?;
    let names = r.effect_labels();
    let gap = |g: &Gaps| match g {
        Gaps::Cycling { scale_factor_ppm, bias_ug } => format!("{scale_factor_ppm:.1} ppm / {bias_ug:.1} µg"),
        Gaps::Single { value_rms } => format!("{value_rms:.3}"),
    };
    Ok(format!(
        "start simple → added [{}]; held-out gap (scale factor / bias) {} → {}; {}",
        if names.is_empty() { "none".to_string() } else { names.join(", ") },
        gap(&r.heldout_gap_before),
        gap(&r.heldout_gap_after),
        out.join("report.md").display()
    ))
}
