//! The entry points: the workflow with its outputs written ([`discover`]), the command
//! line, and the lab demo's hook.

use super::*;

/// Run the workflow on `input` from `start` and write the outputs to `out_dir`.
///
/// # Errors
/// Output files could not be written.
pub fn discover(input: &Channels, start: Start, out_dir: &Path) -> Result<Report> {
    let report = analyze(input, start);
    output::write(input, &report, out_dir, true, None)?;
    Ok(report)
}

/// CLI entry: `qfa-lab discover --log LOG.csv --start simple|paper --out DIR`.
///
/// # Errors
/// Reading the log or writing the outputs failed.
pub fn run_cli(log: &Path, start: Start, out_dir: &Path) -> Result<Report> {
    let ch = Channels::read(log, 60.0)?;
    let r = discover(&ch, start, out_dir)?;
    println!("{}", serde_json::to_string_pretty(&r)?);
    Ok(r)
}

/// Demo hook (the demo runs one discovery): start `simple` on a unit's cycling log.
/// With the simulator's Eq. 11 truth this should rediscover the paper's structure
/// (`temp_quadratic` and the rate terms). Returns a one-line summary.
///
/// # Errors
/// The discovery's failure, as text (the demo fails with it).
pub fn demo_hook(log: &Path, out: &Path) -> std::result::Result<String, String> {
    let run = || -> Result<Report> {
        let ch = Channels::read(log, 60.0)?;
        discover(&ch, Start::Simple, out)
    };
    let r = run().map_err(|e| format!("{e:#}"))?;
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
