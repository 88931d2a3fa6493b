//! The main demo: the paper's full test for JB-KT8 #1–#3, calibrated and compensated
//! through the root crate, with a Table-4-style comparison.
//!
//! Per unit `N` it writes `out/kt8-N/`: `log.csv` (1-s rows, about 1.355 M), `truth.toml`,
//! `table.toml`, `table.bin`, `table_simple.*`, `report.json` and the plots; and
//! `out/table4.json` with all three units beside the paper's numbers.

use std::path::Path;
use std::time::Instant;

use serde::Serialize;

use crate::calibrate::report::Variants;
use crate::calibrate::{calibrate_file, CalibrateOptions};
use crate::data::cycling::write_log;
use crate::simulate::simulate_paper;
use crate::simulate::truth::Truth;

/// The paper's Table 4: (none, simple, hysteresis) ppm/°C for #1, #2, #3.
pub const PAPER_TABLE4: [[f64; 3]; 3] = [[74.14, 12.78, 2.48], [104.22, 14.14, 4.23], [105.79, 14.46, 5.19]];

/// Demo settings.
#[derive(Clone, Debug)]
pub struct DemoOptions {
    /// Output directory.
    pub out: std::path::PathBuf,
    /// Row length, s.
    pub row_s: u32,
    /// Seed.
    pub seed: u64,
    /// Threads for the simulation.
    pub threads: usize,
    /// Progress bars.
    pub progress: bool,
}

/// One unit's demo result.
#[derive(Clone, Debug, Serialize)]
pub struct UnitResult {
    /// Unit name.
    pub unit: String,
    /// Ours, held out.
    pub ours: Variants,
    /// The paper's Table 4.
    pub paper: Variants,
    /// Bias residual, µg, held out.
    pub bias_residual_ug: Variants,
    /// Rows in the log.
    pub rows: usize,
    /// Simulation, s.
    pub simulate_s: f64,
    /// Writing the log, s.
    pub write_s: f64,
    /// Calibration from the CSV file (read + fit + held-out compensation + plots), s.
    pub calibrate_s: f64,
}

/// Where the discovery workflow (issue 4) plugs in: called with each unit's log and
/// output directory after calibration. Returns a one-line summary to print, if any.
pub type DiscoveryHook = fn(log: &Path, out: &Path) -> Option<String>;
/// Where the navigation study (issue 5) plugs in: called once with the demo's output
/// directory after all units are calibrated. Returns a one-line summary to print.
pub type NavigationHook = fn(out: &Path) -> Option<String>;

/// Run the demo. `discovery` and `navigation` are the hooks for issues 4 and 5.
///
/// # Errors
/// A message describing the failure.
pub fn run(
    opts: &DemoOptions,
    discovery: Option<DiscoveryHook>,
    navigation: Option<NavigationHook>,
) -> Result<Vec<UnitResult>, String> {
    let t_all = Instant::now();
    std::fs::create_dir_all(&opts.out).map_err(|e| e.to_string())?;
    let mut results = Vec::new();
    for unit in 1..=3u8 {
        let truth = Truth::jb_kt8(unit);
        let dir = opts.out.join(format!("kt8-{unit}"));
        std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
        eprintln!("== {} ==", truth.name);
        let t = Instant::now();
        let pb = if opts.progress { indicatif::ProgressBar::new(16) } else { indicatif::ProgressBar::hidden() };
        pb.set_style(
            indicatif::ProgressStyle::with_template("{msg:>22} [{bar:30}] {pos}/{len} {elapsed}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        pb.set_message("simulating runs");
        let log = simulate_paper(&truth, opts.row_s, opts.seed + u64::from(unit), opts.threads, Some(&pb));
        pb.finish_and_clear();
        let simulate_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let log_path = dir.join("log.csv");
        write_log(&log_path, &log).map_err(|e| e.to_string())?;
        std::fs::write(dir.join("truth.toml"), truth.to_toml()?).map_err(|e| e.to_string())?;
        let write_s = t.elapsed().as_secs_f64();
        let rows = log.rows();
        drop(log);
        let t = Instant::now();
        let cal = calibrate_file(
            &log_path,
            &dir,
            &CalibrateOptions {
                fit_programs: None,
                plots: true,
                title: truth.name.clone(),
                progress: opts.progress,
                axis: None,
                exports: crate::calibrate::peers::ExportOptions::default(),
            },
        )?;
        let calibrate_s = t.elapsed().as_secs_f64();
        let p = PAPER_TABLE4[usize::from(unit) - 1];
        eprintln!(
            "   {rows} rows: simulate {simulate_s:.1} s, write {write_s:.1} s, calibrate {calibrate_s:.1} s \
             (read {:.1}, fit {:.1}, held-out compensation {:.1}); Eq. 11 cond {:.1}",
            cal.report.timings_s.read,
            cal.report.timings_s.fit,
            cal.report.timings_s.evaluate,
            cal.report.fit.cond_sf_hysteresis
        );
        // One discovery run, on the first unit: enough to show the workflow, and it keeps
        // the demo well inside its two minutes.
        if let Some(hook) = discovery.filter(|_| unit == 1) {
            if let Some(s) = hook(&log_path, &dir.join("discover")) {
                eprintln!("   discovery: {s}");
            }
        }
        results.push(UnitResult {
            unit: truth.name.clone(),
            ours: cal.report.sensitivity_ppm_per_c,
            paper: Variants { none: p[0], simple: p[1], hysteresis: p[2] },
            bias_residual_ug: cal.report.bias_residual_ug,
            rows,
            simulate_s,
            write_s,
            calibrate_s,
        });
    }
    if let Some(hook) = navigation {
        if let Some(s) = hook(&opts.out.join("navigation")) {
            eprintln!("navigation: {s}");
        }
    }
    println!("{}", table4_text(&results));
    println!("demo total {:.1} s; outputs in {}", t_all.elapsed().as_secs_f64(), opts.out.display());
    let json = serde_json::to_string_pretty(&results).map_err(|e| e.to_string())?;
    std::fs::write(opts.out.join("table4.json"), json).map_err(|e| e.to_string())?;
    Ok(results)
}

/// The Table-4-style comparison as text.
#[must_use]
pub fn table4_text(results: &[UnitResult]) -> String {
    let mut s = String::new();
    s.push_str("Scale-factor temperature sensitivity, ppm/degC (Table 4; ours held out: fit 0.3+0.9, evaluated 0.5+0.7 degC/min)\n");
    s.push_str("unit        |   none: paper    ours | simple: paper    ours | hysteresis: paper    ours | bias resid. ug simple/hyst\n");
    for r in results {
        s.push_str(&format!(
            "{:<11} | {:>13.2} {:>7.2} | {:>13.2} {:>7.2} | {:>17.2} {:>7.2} | {:>8.1} / {:.1}\n",
            r.unit,
            r.paper.none,
            r.ours.none,
            r.paper.simple,
            r.ours.simple,
            r.paper.hysteresis,
            r.ours.hysteresis,
            r.bias_residual_ug.simple,
            r.bias_residual_ug.hysteresis
        ));
    }
    s
}
