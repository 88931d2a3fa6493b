//! The main demo: the paper's full test for JB-KT8 #1–#3, calibrated and compensated
//! through the root crate, with a Table-4-style comparison.
//!
//! Per unit `N` it writes `out/kt8-N/`: `truth.toml`, `table.toml`, `table.bin`,
//! `table_simple.*`, `report.json`, `report.html` and the plots (and, with
//! [`DemoOptions::full_logs`], `log.csv`: 1-s rows, about 1.355 M, 47 MB per unit; without
//! it the log is deleted once calibrated and discovered); `out/table4.json` with all three
//! units beside the paper's numbers; and `out/report.html`, the page that ties them together
//! and links every sub-page, with `out/report.md` and `out/report.json`. All three open
//! with one verdict, the units' calibration verdicts and the navigation verdict merged
//! ([`Verdict::merge`]); the console ends with the same lines.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use qfa_calibrate::output_error::OutputError;
use qfa_calibrate::report::Variants;
use qfa_calibrate::{calibrate_file, CalibrateOptions};
use qfa_log::cycling::write_log;
use qfa_report::verdict::{FileUse, LimitsChoice, Verdict};
use qfa_sim::simulate_paper;
use qfa_sim::truth::Truth;

/// The family each demo unit's log is drawn from (stream `u` for unit `u`), so no two
/// units, and no unit and another command's log of the same seed, share noise.
const UNIT_LOGS: qfa_rng::Stream = qfa_rng::Stream::named("demo: unit logs");

/// The paper's Table 4: (none, simple, hysteresis) ppm/°C for #1, #2, #3.
pub const PAPER_TABLE4: [[f64; 3]; 3] = [[74.14, 12.78, 2.48], [104.22, 14.14, 4.23], [105.79, 14.46, 5.19]];

/// Demo settings.
#[derive(Clone, Debug)]
pub struct DemoOptions {
    /// Output directory.
    pub out: std::path::PathBuf,
    /// Row length, s.
    pub row_s: u32,
    /// Base seed: unit `u`'s log is drawn from stream `u` of its `demo: unit logs` family.
    pub seed: u64,
    /// Threads for the simulation.
    pub threads: usize,
    /// Progress bars.
    pub progress: bool,
    /// Keep each unit's `log.csv` (about 47 MB each at 1-s rows).
    pub full_logs: bool,
    /// Fly only the first this many seconds of the navigation flight (a quicker demo).
    pub nav_duration_s: Option<f64>,
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

/// Where the discovery workflow plugs in: called with a unit's log and output directory
/// after calibration. Returns a one-line summary to print; an error fails the demo.
pub type DiscoveryHook = fn(log: &Path, out: &Path) -> Result<String, qfa_discover::DiscoverError>;
/// Where the navigation study plugs in: called once with its output directory after all
/// units are calibrated, and the flight's length limit, s. Returns its verdict and the
/// caption of its flight plot; an error fails the demo.
pub type NavigationHook =
    fn(out: &Path, duration_s: Option<f64>) -> Result<qfa_nav::NavigationOutcome, qfa_nav::NavError>;

/// The demo's `report.json`: the verdict (first, [`qfa_report::verdict::json_with_verdict`])
/// and every unit's Table-4 figures.
#[derive(Serialize)]
struct DemoReport<'a> {
    units: &'a [UnitResult],
}

/// A spinner on stderr for a step that runs longer than a few seconds (hidden when
/// `show` is false or stderr is not a terminal).
#[must_use]
pub fn spinner(msg: &str, show: bool) -> indicatif::ProgressBar {
    if !show {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new_spinner();
    pb.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {msg} {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
    );
    pb.set_message(msg.to_string());
    pb.enable_steady_tick(std::time::Duration::from_millis(200));
    pb
}

/// Bytes of every file under `dir`.
///
/// # Errors
/// A directory that cannot be read.
pub fn dir_bytes(dir: &Path) -> std::io::Result<u64> {
    let mut n = 0;
    for e in std::fs::read_dir(dir)? {
        let e = e?;
        let m = e.metadata()?;
        n += if m.is_dir() { dir_bytes(&e.path())? } else { m.len() };
    }
    Ok(n)
}

/// Why the demo stopped: the step, the file or unit it was on, and the error it came from.
#[derive(Debug)]
#[non_exhaustive]
pub enum DemoError {
    /// A file or folder could not be written, read or removed, or a report could not be
    /// written as JSON: the type calibration's and the batch's outputs fail with.
    Output(OutputError),
    /// A unit's truth could not be written as TOML.
    Truth {
        /// The unit.
        unit: String,
        /// The writer's error.
        source: qfa_sim::truth::TruthError,
    },
    /// A unit's calibration failed.
    Calibrate {
        /// The unit.
        unit: String,
        /// The calibration's error.
        source: qfa_calibrate::CalibrateError,
    },
    /// A unit's calibration wrote no verdict.
    NoVerdict {
        /// The unit.
        unit: String,
    },
    /// The discovery workflow failed on a unit's log.
    Discover {
        /// The unit.
        unit: String,
        /// Discovery's error.
        source: qfa_discover::DiscoverError,
    },
    /// The navigation study failed.
    Navigation(qfa_nav::NavError),
}

impl DemoError {
    fn io(path: &Path) -> impl FnOnce(std::io::Error) -> Self + '_ {
        move |e| Self::Output(OutputError::io(path)(e))
    }
}

impl std::fmt::Display for DemoError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Output(e) => write!(f, "{e}"),
            Self::Truth { unit, source } => write!(f, "{unit}: truth.toml: {source}"),
            Self::Calibrate { unit, source } => write!(f, "{unit}: calibration: {source}"),
            Self::NoVerdict { unit } => write!(f, "{unit}: calibration wrote no verdict"),
            // `{:#}`: with its causes (the file and the system's error).
            Self::Discover { unit, source } => write!(f, "discovery on {unit}: {source:#}"),
            Self::Navigation(e) => write!(f, "navigation: {}", error_chain(e)),
        }
    }
}

impl std::error::Error for DemoError {}

/// Run the demo. `discovery` and `navigation` are the hooks for the discovery workflow and
/// the navigation study.
///
/// # Errors
/// A step that failed, with the file or unit it was on ([`DemoError`]; a failed hook
/// included).
pub fn run(
    opts: &DemoOptions,
    discovery: Option<DiscoveryHook>,
    navigation: Option<NavigationHook>,
) -> Result<Vec<UnitResult>, DemoError> {
    let t_all = Instant::now();
    std::fs::create_dir_all(&opts.out).map_err(DemoError::io(&opts.out))?;
    let mut results = Vec::new();
    let mut pages: Vec<UnitPage> = Vec::new();
    for unit in 1..=3u8 {
        let (page, result) = run_unit(opts, unit, discovery)?;
        pages.push(page);
        results.push(result);
    }
    let nav = navigate(opts, navigation)?;
    let v = write_reports(opts, &results, &pages, nav.as_ref())?;
    let bytes = dir_bytes(&opts.out).map_err(DemoError::io(&opts.out))?;
    let total_s = t_all.elapsed().as_secs_f64();
    page(opts, &results, &pages, nav.as_ref(), &v, bytes, total_s)
        .write(&opts.out)
        .map_err(DemoError::io(&opts.out))?;
    let bytes = dir_bytes(&opts.out).map_err(DemoError::io(&opts.out))?;
    println!(
        "demo total {total_s:.1} s; outputs in {}: {:.2} MB{}",
        opts.out.display(),
        bytes as f64 / 1e6,
        if opts.full_logs { " (with the logs)" } else { " (logs deleted; --full-logs keeps them)" }
    );
    print!("{}", v.console());
    println!("detail: {}/report.md, report.html, report.json", opts.out.display());
    Ok(results)
}

/// One of the paper's units: simulated and written, calibrated, discovered (unit #1 only)
/// and its log removed unless kept; its entry on the page and its Table 4 row.
fn run_unit(
    opts: &DemoOptions,
    unit: u8,
    discovery: Option<DiscoveryHook>,
) -> Result<(UnitPage, UnitResult), DemoError> {
    let truth = Truth::jb_kt8(unit);
    let dir = opts.out.join(format!("kt8-{unit}"));
    std::fs::create_dir_all(&dir).map_err(DemoError::io(&dir))?;
    eprintln!("== {} ==", truth.name);
    let (log_path, rows, simulate_s, write_s) = simulate_unit(opts, unit, &truth, &dir)?;
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
            unit: None,
            exports: qfa_calibrate::export::ExportOptions::default(),
            limits: LimitsChoice::default(),
            reproducible: false,
            notes: Vec::new(),
            ext: qfa_thermal::Extensions::NONE,
        },
    )
    .map_err(|source| DemoError::Calibrate { unit: truth.name.clone(), source })?;
    let verdict = cal.verdict.clone().ok_or_else(|| DemoError::NoVerdict { unit: truth.name.clone() })?;
    let calibrate_s = t.elapsed().as_secs_f64();
    let p = PAPER_TABLE4[usize::from(unit) - 1];
    let steps = cal.report.timings_s.map_or_else(
        || "steps not timed".to_string(),
        |t| format!("read {:.1}, fit {:.1}, held-out compensation {:.1}", t.read, t.fit, t.evaluate),
    );
    eprintln!(
        "   {rows} rows: simulate {simulate_s:.1} s, write {write_s:.1} s, calibrate {calibrate_s:.1} s \
         ({steps}); Eq. 11 cond {:.1}",
        cal.report.fit.cond_sf_hysteresis
    );
    // One discovery run, on the first unit: enough to show the workflow, and it keeps
    // the demo well inside its two minutes.
    let discovery_line = match discovery.filter(|_| unit == 1) {
        Some(hook) => Some(discover_unit(hook, opts, &truth, &log_path, &dir)?),
        None => None,
    };
    if !opts.full_logs {
        std::fs::remove_file(&log_path).map_err(DemoError::io(&log_path))?;
    }
    let sf_plot = cal.plots.iter().find(|p| p.file == qfa_calibrate::report::SF_PLOT).cloned();
    let page = UnitPage {
        dir: dir.clone(),
        coverage: cal.report.coverage.clone(),
        discovery: discovery_line,
        verdict,
        sf_plot,
    };
    let result = UnitResult {
        unit: truth.name.clone(),
        ours: cal.report.sensitivity_ppm_per_c,
        paper: Variants { none: p[0], simple: p[1], hysteresis: p[2] },
        bias_residual_ug: cal.report.bias_residual_ug,
        rows,
        simulate_s,
        write_s,
        calibrate_s,
    };
    Ok((page, result))
}

/// Simulate the unit's paper runs and write its `log.csv` and `truth.toml` into `dir`:
/// the log's path, its rows, and the seconds each step took.
fn simulate_unit(
    opts: &DemoOptions,
    unit: u8,
    truth: &Truth,
    dir: &Path,
) -> Result<(PathBuf, usize, f64, f64), DemoError> {
    let t = Instant::now();
    let pb = if opts.progress { indicatif::ProgressBar::new(16) } else { indicatif::ProgressBar::hidden() };
    pb.set_style(
        indicatif::ProgressStyle::with_template("{msg:>22} [{bar:30}] {pos}/{len} {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    pb.set_message("simulating runs");
    let unit_seed = qfa_rng::stream_seed(opts.seed, UNIT_LOGS, u64::from(unit));
    let log = simulate_paper(truth, opts.row_s, unit_seed, opts.threads, Some(&pb));
    pb.finish_and_clear();
    let simulate_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let log_path = dir.join("log.csv");
    write_log(&log_path, &log).map_err(DemoError::io(&log_path))?;
    let toml = truth.to_toml().map_err(|source| DemoError::Truth { unit: truth.name.clone(), source })?;
    let truth_path = dir.join("truth.toml");
    std::fs::write(&truth_path, toml).map_err(DemoError::io(&truth_path))?;
    let write_s = t.elapsed().as_secs_f64();
    let rows = log.rows();
    drop(log);
    Ok((log_path, rows, simulate_s, write_s))
}

/// The discovery workflow on the unit's log, into `dir/discover`: its one-line summary.
fn discover_unit(
    hook: DiscoveryHook,
    opts: &DemoOptions,
    truth: &Truth,
    log_path: &Path,
    dir: &Path,
) -> Result<String, DemoError> {
    let pb = spinner("discovery on unit #1's log", opts.progress);
    let s = hook(log_path, &dir.join("discover"))
        .map_err(|source| DemoError::Discover { unit: truth.name.clone(), source });
    pb.finish_and_clear();
    let s = s?;
    eprintln!("   discovery: {s}");
    Ok(s)
}

/// The navigation study, when there is a hook for it, into `out/navigation`.
fn navigate(
    opts: &DemoOptions,
    navigation: Option<NavigationHook>,
) -> Result<Option<qfa_nav::NavigationOutcome>, DemoError> {
    let mut nav = None;
    if let Some(hook) = navigation {
        let pb = spinner("navigation study (calibrate, align, fly)", opts.progress);
        let s = hook(&opts.out.join(NAVIGATION_DIR), opts.nav_duration_s).map_err(DemoError::Navigation);
        pb.finish_and_clear();
        let s = s?;
        eprintln!("navigation: {}", s.verdict.answer);
        nav = Some(s);
    }
    Ok(nav)
}

/// Print Table 4 and write `table4.json`, then the verdict's `report.json` and
/// `report.md`; the verdict.
fn write_reports(
    opts: &DemoOptions,
    results: &[UnitResult],
    pages: &[UnitPage],
    nav: Option<&qfa_nav::NavigationOutcome>,
) -> Result<Verdict, DemoError> {
    println!("{}", table4_text(results));
    let table4 = opts.out.join("table4.json");
    let json = serde_json::to_string_pretty(results).map_err(|e| DemoError::Output(OutputError::json(&table4)(e)))?;
    std::fs::write(&table4, json).map_err(DemoError::io(&table4))?;
    let v = verdict(results, pages, nav);
    let report = opts.out.join("report.json");
    let json = qfa_report::verdict::json_with_verdict(&v, &DemoReport { units: results })
        .map_err(|e| DemoError::Output(OutputError::json(&report)(e)))?;
    std::fs::write(&report, json).map_err(DemoError::io(&report))?;
    let md = opts.out.join("report.md");
    std::fs::write(&md, markdown(results, pages, nav.is_some(), &v)).map_err(DemoError::io(&md))?;
    Ok(v)
}

/// The navigation study's folder in the demo's output.
const NAVIGATION_DIR: &str = "navigation";

/// A unit's folder name (`kt8-1`).
fn dir_name(u: &UnitPage) -> String {
    u.dir.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

/// The demo's verdict: every unit's calibration verdict and the navigation study's, merged
/// (a unit that fails a limit fails the demo's verdict), with the demo's own files.
fn verdict(results: &[UnitResult], units: &[UnitPage], nav: Option<&qfa_nav::NavigationOutcome>) -> Verdict {
    let mut parts: Vec<(String, Verdict)> =
        results.iter().zip(units).map(|(r, u)| (r.unit.clone(), u.verdict.clone())).collect();
    if let Some(n) = nav {
        parts.push(("navigation".to_string(), n.verdict.clone()));
    }
    let mut files: Vec<FileUse> = ["report.html", "report.md", "report.json", "table4.json"].map(FileUse::of).to_vec();
    files[3].action = "keep: the Table-4 comparison, every unit beside the paper".into();
    for (r, u) in results.iter().zip(units) {
        let name = dir_name(u);
        files.push(FileUse::of(&format!("{name}/table.bin")));
        files.push(FileUse {
            file: format!("{name}/report.html"),
            action: format!("read: {}'s calibration, with every file it wrote and what to do with each", r.unit),
        });
    }
    if nav.is_some() {
        files.push(FileUse {
            file: format!("{NAVIGATION_DIR}/report.html"),
            action: "read: the navigation study, every variant's figures and plots".into(),
        });
    }
    Verdict::merge(&parts, &LimitsChoice::default().source(), files)
}

/// Every sub-page and data file the demo's page links, `(text, path relative to the
/// demo's folder)`.
fn links(results: &[UnitResult], units: &[UnitPage], navigation: bool) -> Vec<(String, String)> {
    let mut l = Vec::new();
    for (r, u) in results.iter().zip(units) {
        let name = dir_name(u);
        l.push((format!("{}: calibration report", r.unit), format!("{name}/{}", qfa_report::html_report::FILE)));
        if u.discovery.is_some() {
            l.push((
                format!("{}: discovery report", r.unit),
                format!("{name}/discover/{}", qfa_report::html_report::FILE),
            ));
        }
    }
    if navigation {
        l.push(("Navigation study report".to_string(), format!("{NAVIGATION_DIR}/{}", qfa_report::html_report::FILE)));
    }
    l.push(("This report as Markdown".to_string(), "report.md".to_string()));
    l.push(("This report's figures (JSON, the verdict first)".to_string(), "report.json".to_string()));
    l.push(("Table 4, every unit beside the paper (JSON)".to_string(), "table4.json".to_string()));
    l
}

/// The demo's `report.md`: the title, the verdict, Table 4 and the pages to read next.
fn markdown(results: &[UnitResult], units: &[UnitPage], navigation: bool, v: &Verdict) -> String {
    let mut s = format!("# {TITLE}\n\n{}## Table 4 (paper / ours, held out)\n\n", v.markdown());
    s += "| unit | none, ppm/°C | simple, ppm/°C | hysteresis, ppm/°C | bias residual simple / hysteresis, µg |\n";
    s += "|---|---|---|---|---|\n";
    for r in results {
        s += &format!(
            "| {} | {:.2} / {:.2} | {:.2} / {:.2} | {:.2} / {:.2} | {:.1} / {:.1} |\n",
            r.unit,
            r.paper.none,
            r.ours.none,
            r.paper.simple,
            r.ours.simple,
            r.paper.hysteresis,
            r.ours.hysteresis,
            r.bias_residual_ug.simple,
            r.bias_residual_ug.hysteresis
        );
    }
    s += "\n## Pages\n\n";
    for (text, href) in links(results, units, navigation) {
        s += &format!("- [{text}]({})\n", qfa_report::html_report::percent_encode(&href));
    }
    s
}

/// The demo page's title.
const TITLE: &str = "Demo: the paper's thermal test for JB-KT8 #1–#3";

/// What the demo's page shows of one unit besides its [`UnitResult`].
struct UnitPage {
    dir: std::path::PathBuf,
    coverage: qfa_calibrate::coverage::CalCoverage,
    discovery: Option<String>,
    verdict: Verdict,
    /// The unit's `sf_vs_temp.png` as its calibration drew it.
    sf_plot: Option<qfa_report::plot_png::Plot>,
}

/// The demo's `report.html`: the verdict, links to every sub-page, then each unit and the
/// navigation study.
fn page(
    opts: &DemoOptions,
    results: &[UnitResult],
    units: &[UnitPage],
    navigation: Option<&qfa_nav::NavigationOutcome>,
    v: &Verdict,
    bytes: u64,
    total_s: f64,
) -> qfa_report::html_report::Page {
    let mut p = qfa_report::html_report::Page::new(TITLE);
    v.to_page(&mut p);
    p.section("Pages of this run").links(&links(results, units, navigation.is_some()));
    p.section("Held-out scheme").para(
        "Each unit's tables are fitted on the 0.3 and 0.9 °C/min programs and every figure is of the 0.5 and \
         0.7 °C/min programs, compensated through the root crate's compensator; the navigation flight is never \
         fitted on.",
    );
    let rows: Vec<Vec<String>> = results
        .iter()
        .map(|r| {
            vec![
                r.unit.clone(),
                format!("{:.2} / {:.2}", r.paper.none, r.ours.none),
                format!("{:.2} / {:.2}", r.paper.simple, r.ours.simple),
                format!("{:.2} / {:.2}", r.paper.hysteresis, r.ours.hysteresis),
                format!("{:.1} / {:.1}", r.bias_residual_ug.simple, r.bias_residual_ug.hysteresis),
                r.rows.to_string(),
                format!("{:.1} / {:.1} / {:.1}", r.simulate_s, r.write_s, r.calibrate_s),
            ]
        })
        .collect();
    p.section("Scale-factor temperature sensitivity, ppm/°C (Table 4: paper / ours, held out)").table(
        &[
            "unit",
            "none",
            "simple",
            "hysteresis",
            "bias residual, µg (simple / hysteresis)",
            "log rows",
            "simulate / write / calibrate, s",
        ],
        &rows,
    );
    p.section("Run").kv(&[
        ("row length", format!("{} s", opts.row_s)),
        ("seed", opts.seed.to_string()),
        ("total time", format!("{total_s:.1} s")),
        (
            "outputs before this page",
            format!(
                "{:.2} MB{}",
                bytes as f64 / 1e6,
                if opts.full_logs {
                    " (logs kept: --full-logs)"
                } else {
                    " (each log.csv deleted once used; --full-logs keeps them)"
                }
            ),
        ),
        ("navigation flight", opts.nav_duration_s.map_or("full".to_string(), |d| format!("first {d:.0} s"))),
    ]);
    for (r, u) in results.iter().zip(units) {
        unit_section(&mut p, r, u);
    }
    if let Some(n) = navigation {
        navigation_section(&mut p, n);
    }
    p.section("Console table").pre(&table4_text(results));
    p
}

/// One unit's section: its pages, its verdict, its coverage, its scale-factor plot and
/// its discovery line.
fn unit_section(p: &mut qfa_report::html_report::Page, r: &UnitResult, u: &UnitPage) {
    let name = dir_name(u);
    p.section(&r.unit);
    let mut own =
        vec![(format!("{}: calibration report", r.unit), format!("{name}/{}", qfa_report::html_report::FILE))];
    if u.discovery.is_some() {
        own.push((
            format!("{}: discovery report", r.unit),
            format!("{name}/discover/{}", qfa_report::html_report::FILE),
        ));
    }
    p.links(&own);
    p.para(&format!("{}: {}", u.verdict.outcome, u.verdict.answer));
    u.coverage.to_page(p);
    if let Some(plot) = &u.sf_plot {
        p.plot(
            plot,
            &format!(
                "{}: compensated scale factor against temperature, held-out bins (programs the fit never saw), one \
                 panel per model. Look for: the no-compensation panel's slope ({:.1} ppm/°C held out) gone in the \
                 hysteresis panel ({:.2} ppm/°C), where heating (red) and cooling (blue) bins lie in one band; their \
                 split in the simple panel is the rate (hysteresis) effect the simple model lacks.",
                r.unit, r.ours.none, r.ours.hysteresis
            ),
        );
    }
    if let Some(d) = &u.discovery {
        p.para(&format!("Discovery: {d}"));
    }
}

/// The navigation study's section: its page, its verdict and its error plot.
fn navigation_section(p: &mut qfa_report::html_report::Page, n: &qfa_nav::NavigationOutcome) {
    p.section("Navigation");
    p.links(&[("Navigation study report", format!("{NAVIGATION_DIR}/{}", qfa_report::html_report::FILE))]);
    p.para(&format!("{}: {}", n.verdict.outcome, n.verdict.answer));
    if let Some(plot) = &n.plot {
        p.plot(plot, &n.plot_caption);
    }
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

/// An error and its causes on one line, `e: cause: cause`, as the command line prints them.
fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        s.push_str(": ");
        s.push_str(&c.to_string());
        cause = c.source();
    }
    s
}
