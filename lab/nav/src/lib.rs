//! Navigation impact: pure-inertial navigation error with compensated accelerometers.
//!
//! `navigate` flies a scenario (built-in: the paper's §3.2 flight, ~2.3 h) through a
//! local-level NED strapdown mechanisation ([`strapdown`]) with WGS84 gravity and radii
//! ([`earth`]), once per accelerometer compensation variant, all in lock-step on the same
//! corrupted sensor data:
//!
//! | variant | accelerometer compensation |
//! |---|---|
//! | `none` | room-temperature constants only (γ and K0 at T0 from the simple fit) |
//! | `simple` | paper Eq. 3–4 (K1, K0 linear in ΔT) through the root crate's `Compensator` |
//! | `hysteresis` | Eq. 11 + heating / cooling bias tables, calibrated from a simulated four-position test of the same unit, through the `Compensator` |
//! | `discovered` | tables with the discovery workflow's extension effects, one per axis (postcard `.bin` or TOML, [`NavigateArgs::discovered_tables`]); by default, the table `discover` writes for each unit's own calibration log (start `paper`: the hysteresis table with the extension slots the catalog named that carry to held-out programs); `meta.discovered_source` names them |
//! | `oracle` | the truth model itself (true K1, K0 each cycle, f64): the limit |
//!
//! The three accelerometer axes are the paper's three units, the lab's presets
//! ([`qfa_sim::truth::Truth::jb_kt8`]): x = JB-KT8 #1, y = #2, z = #3. Each axis's truth
//! model turns the ideal Δv into integer I/F pulses with carry ([`accel::LabAccel`]);
//! the DS18B20 on each case (the unit's offset and noise, 12-bit) is read once a second
//! into that axis's stream of one `Compensator<3, 32, 3>` (the firmware's recommended
//! configuration: one stream per case, one 3-axis table); the pulses of each 5 ms cycle go
//! to `Compensator::cycle`. The fault runs ([`crate::faults`]) fly the same configuration. Each unit's tables come from the lab's simulation and fit of its
//! own four-position test ([`calib`]). Non-thermal IMU errors come from the scenario's
//! `[imu]` table ([`errors`]): gyro turn-on bias σ = 0.01 °/h, bias instability, ARW,
//! scale factor and misalignment; accelerometer turn-on bias σ = 50 µg, scale factor and
//! misalignment beside the thermal truth model. Before take-off every variant aligns on
//! the ground on its own compensated output ([`align`]: coarse leveling and
//! gyrocompassing, then an eight-state Kalman fine alignment), and navigates from that
//! attitude; `meta.alignment` gives the errors it left. Altitude is held by the reference.
//!
//! `--runs N` adds a Monte Carlo study ([`mc`]): N seeds varying the noise, the IMU error
//! draws, the temperature profile within the scenario's `[monte_carlo]` bounds and the
//! units' thermal coefficients, each unit recalibrated; `report.json` gains `monte_carlo`.
//!
//! # Figures
//! * RMS East / North velocity error over the whole flight, sampled at 1 Hz.
//! * **CEP rate** (`cep_nmi_per_h`). PSINS's `cep.m` forms CEP = 0.5887·(σ_N + σ_E) from
//!   an ensemble of runs; one simulated trajectory has no ensemble, so we use the
//!   radial error growth per hour: the least-squares slope through the origin of the
//!   radial position error r(t) = √(δN² + δE²) over the flight, `Σ t·r / Σ t²`, in
//!   nmile/h. This is robust to the Schuler oscillation, unlike the end point. The end
//!   point r(T)/T and the PSINS form over the flight's time series divided by T are also
//!   reported.
//! * Share of the thermally induced error removed: `(simple − variant)/(simple − oracle)`
//!   on the total CEP rate (`meta.share_removed_cep`), and, because one trajectory's total
//!   radial error mixes the gyro and accelerometer errors with their signs, also on the
//!   isolated thermal error: the radial growth of (variant − oracle) position, the same
//!   sensor data in both (`meta.thermal_cep_nmi_per_h`, `meta.share_removed_thermal`).
//!
//! The thermal chain (bay air → case → element) is the lab's
//! ([`qfa_sim::thermal::ThermalChain`]), driven by the scenario's breakpoints.

pub mod accel;
pub mod align;
pub mod args;
pub mod calib;
pub mod clock;
pub mod earth;
pub mod errors;
pub mod fault_injection;
pub mod faults;
pub mod flight_report;
pub mod mc;
pub mod mc_summary;
pub mod page;
pub mod plan;
pub mod plot;
pub mod run;
pub mod scenario;
pub mod seeds;
pub mod strapdown;
pub mod tables;
pub mod thermal;
pub mod variants;
pub mod verdict;

use std::fmt::{self, Write as _};
use std::path::{Path, PathBuf};
use std::time::Instant;

use calib::CalibError;
use flight_report::ReportError;
use mc::{McError, SummaryError};
use plan::PlanError;
use plot::PlotError;
use qfa_report::verdict::Verdict;
use run::{FlightResult, RunError};
use scenario::{Scenario, ScenarioError};
use variants::VariantsError;

pub use args::{scenario_of, NavigateArgs};
pub use flight_report::{
    clamped_warnings, flag_shares, report, share, summary, thermal_ceps, Meta, PaperFigures, Report,
};
pub use page::{markdown, merge_markdown, merge_page, page};
pub use tables::{calibrate, calibrate_on, calibrate_opts, calibrate_with, truths_seeded, units, Tables};
pub use variants::{mc_variants, read_table, variants, VARIANTS};

/// Why `navigate`, a shard or a merge failed. Each module has its own error; those that
/// pass another on print it as it is and hand on its cause, those that add a context
/// (a file, a run) print the context and hand on the error, so a chain printed
/// `context: cause` (as `qfa-lab` prints it) names each step once.
#[derive(Debug)]
#[non_exhaustive]
pub enum NavError {
    /// [`navigate`] given a shard: a shard writes a partial result.
    ShardGiven,
    /// [`navigate_shard`] given no shard.
    NoShard,
    /// A shard `k/n` with `n = 0` or `k ≥ n`.
    Shard {
        /// This shard's index.
        k: u64,
        /// The number of shards.
        n: u64,
    },
    /// A shard with no Monte Carlo run.
    ShardRuns,
    /// The scenario could not be loaded.
    Scenario(ScenarioError),
    /// The units could not be calibrated.
    Calibration(CalibError),
    /// A table could not be read, or a variant not built.
    Variants(VariantsError),
    /// The flight failed.
    Flight(RunError),
    /// The report's figures could not be computed.
    Report(ReportError),
    /// The Monte Carlo runs failed.
    Mc(McError),
    /// The Monte Carlo runs could not be summarized, merged or written.
    Summary(SummaryError),
    /// The lab program's coverage of the flight could not be formed.
    Plan(PlanError),
    /// `nav_errors.png` could not be drawn.
    Plot(PlotError),
    /// `report.html` could not be written; the error names the file.
    Page(std::io::Error),
    /// A report or a partial result could not be turned into JSON.
    Json(serde_json::Error),
    /// A table could not be turned into TOML.
    Toml(toml::ser::Error),
    /// An output folder could not be created.
    CreateDir {
        /// The folder.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// An output file could not be written.
    Write {
        /// The file.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// The study flew but wrote no verdict (the demo needs one to merge).
    NoVerdict,
}

impl fmt::Display for NavError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::ShardGiven => f.write_str("a shard writes a partial result: use navigate_shard"),
            Self::NoShard => f.write_str("no shard given"),
            Self::Shard { k, n } => write!(f, "shard {k}/{n}: need 0 ≤ K < N"),
            Self::ShardRuns => f.write_str("a shard needs --runs N > 0"),
            Self::Scenario(e) => write!(f, "{e}"),
            Self::Calibration(e) => write!(f, "{e}"),
            Self::Variants(e) => write!(f, "{e}"),
            Self::Flight(e) => write!(f, "{e}"),
            Self::Report(e) => write!(f, "{e}"),
            Self::Mc(e) => write!(f, "{e}"),
            Self::Summary(e) => write!(f, "{e}"),
            Self::Plan(e) => write!(f, "{e}"),
            Self::Plot(_) => f.write_str("plot"),
            Self::Page(e) => write!(f, "{e}"),
            Self::Json(e) => write!(f, "{e}"),
            Self::Toml(e) => write!(f, "{e}"),
            Self::CreateDir { path, .. } => write!(f, "creating {}", path.display()),
            Self::Write { path, .. } => write!(f, "writing {}", path.display()),
            Self::NoVerdict => f.write_str("navigate wrote no verdict"),
        }
    }
}

impl std::error::Error for NavError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::ShardGiven | Self::NoShard | Self::Shard { .. } | Self::ShardRuns | Self::NoVerdict => None,
            Self::Plot(e) => Some(e),
            Self::CreateDir { source, .. } | Self::Write { source, .. } => Some(source),
            // Printed as they are (above): their causes come next.
            Self::Scenario(e) => e.source(),
            Self::Calibration(e) => e.source(),
            Self::Variants(e) => e.source(),
            Self::Flight(e) => e.source(),
            Self::Report(e) => e.source(),
            Self::Mc(e) => e.source(),
            Self::Summary(e) => e.source(),
            Self::Plan(e) => e.source(),
            Self::Page(e) => e.source(),
            Self::Json(e) => e.source(),
            Self::Toml(e) => e.source(),
        }
    }
}

impl From<ScenarioError> for NavError {
    fn from(e: ScenarioError) -> Self {
        Self::Scenario(e)
    }
}

impl From<CalibError> for NavError {
    fn from(e: CalibError) -> Self {
        Self::Calibration(e)
    }
}

impl From<VariantsError> for NavError {
    fn from(e: VariantsError) -> Self {
        Self::Variants(e)
    }
}

impl From<RunError> for NavError {
    fn from(e: RunError) -> Self {
        Self::Flight(e)
    }
}

impl From<ReportError> for NavError {
    fn from(e: ReportError) -> Self {
        Self::Report(e)
    }
}

impl From<McError> for NavError {
    fn from(e: McError) -> Self {
        Self::Mc(e)
    }
}

impl From<SummaryError> for NavError {
    fn from(e: SummaryError) -> Self {
        Self::Summary(e)
    }
}

impl From<PlanError> for NavError {
    fn from(e: PlanError) -> Self {
        Self::Plan(e)
    }
}

impl From<serde_json::Error> for NavError {
    fn from(e: serde_json::Error) -> Self {
        Self::Json(e)
    }
}

impl From<toml::ser::Error> for NavError {
    fn from(e: toml::ser::Error) -> Self {
        Self::Toml(e)
    }
}

/// `Err(e)` unless `ok`: each check stays one line.
fn ensure<E>(ok: bool, e: E) -> Result<(), E> {
    if ok {
        Ok(())
    } else {
        Err(e)
    }
}

/// Write `text` to `path`, the error naming the file.
fn write_file(path: &Path, text: &str) -> Result<(), NavError> {
    std::fs::write(path, text).map_err(|e| NavError::Write { path: path.into(), source: e })
}

/// `e` and its causes on one line, `context: cause`, as `qfa-lab` prints them.
#[cfg(test)]
fn chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        let _ = write!(s, ": {c}");
        cause = c.source();
    }
    s
}

/// Write the error time series (every 10 s) as CSV.
///
/// # Errors
/// I/O.
pub fn write_timeseries(path: &Path, res: &FlightResult) -> Result<(), NavError> {
    let mut s = String::from("time_s,drive_c,case_c,element_c");
    for n in &res.names {
        for q in ["ve_mps", "vn_mps", "de_m", "dn_m"] {
            let _ = write!(s, ",{n}_{q}");
        }
    }
    s.push('\n');
    for i in (0..res.t.len()).step_by(10) {
        let [d, c, e] = res.temps[i];
        let _ = write!(s, "{:.0},{d:.3},{c:.3},{e:.3}", res.t[i]);
        for tr in &res.tracks {
            let _ = write!(s, ",{:.4},{:.4},{:.2},{:.2}", tr.ve[i], tr.vn[i], tr.de[i], tr.dn[i]);
        }
        s.push('\n');
    }
    write_file(path, &s)
}

/// The nominal single run: calibrate (with discovery), align and fly every variant on the
/// scenario's own seed; writes `nav_timeseries.csv`, the calibrated tables
/// (`nav_table_*.toml`) and `nav_errors.png` to `args.out`.
///
/// # Errors
/// Scenario, table or I/O errors.
pub fn nominal(args: &NavigateArgs, sc: &Scenario) -> Result<Report, NavError> {
    let units = units();
    let t0 = Instant::now();
    let mut tables = calibrate_on(&units, sc, args.lab_program, args.rate_limit_override)?;
    tables.misalignment = sc.imu.accel.carried_misalignment();
    let t_cal = t0.elapsed().as_secs_f64();
    let (disc, source) = match &args.discovered_tables {
        Some(p) => {
            let t = [read_table(&p[0])?, read_table(&p[1])?, read_table(&p[2])?];
            (Some(t), p.iter().map(|x| x.display().to_string()).collect::<Vec<_>>().join(", "))
        }
        None => {
            let u = &tables.units;
            let t = [u[0].discovered.clone(), u[1].discovered.clone(), u[2].discovered.clone()];
            let effects: Vec<String> = u
                .iter()
                .map(|x| if x.discovered_effects.is_empty() { "none".into() } else { x.discovered_effects.join("+") })
                .collect();
            (
                Some(t),
                format!(
                    "discovery (start paper) on each unit's calibration log: x [{}], y [{}], z [{}]",
                    effects[0], effects[1], effects[2]
                ),
            )
        }
    };
    let t1 = Instant::now();
    let res = run::fly(sc, &mut truths_seeded(&units, sc.seed), variants(&tables, disc, sc.imu_rate_hz)?)?;
    let t_fly = t1.elapsed().as_secs_f64();
    let mut rep = report(sc, &res, &tables, source, [t_cal, t_fly])?;
    std::fs::create_dir_all(&args.out).map_err(|e| NavError::CreateDir { path: args.out.clone(), source: e })?;
    write_timeseries(&args.out.join("nav_timeseries.csv"), &res)?;
    if !args.no_plots {
        let plot = plot::plot_flight(
            &format!("pure-inertial errors: {} (held out: the tables never saw the flight)", sc.name),
            &res,
        )
        .map_err(NavError::Plot)?;
        let path = args.out.join(&plot.file);
        std::fs::write(&path, plot.png()).map_err(|e| NavError::Write { path, source: e })?;
        rep.plots.push(plot);
    }
    for (i, u) in tables.units.iter().enumerate() {
        for (n, t) in [("none", &u.none), ("simple", &u.simple), ("hysteresis", &u.hysteresis)] {
            write_file(&args.out.join(format!("nav_table_{}_{n}.toml", ["x", "y", "z"][i])), &toml::to_string(t)?)?;
        }
    }
    Ok(rep)
}

/// `qfa-lab navigate`: the nominal run ([`nominal`]), then with `args.runs > 0` the Monte
/// Carlo study ([`mc::run`]); judges it ([`verdict::of_flight`], returned in
/// [`Report::verdict`]) and writes `report.json` (the verdict first), `report.md`,
/// `report.html` and the Monte Carlo outputs to `args.out`. With `args.shard` use
/// [`navigate_shard`] instead.
///
/// # Errors
/// Scenario, table, Monte Carlo or I/O errors.
pub fn navigate(args: &NavigateArgs) -> Result<Report, NavError> {
    ensure(args.shard.is_none(), NavError::ShardGiven)?;
    let sc = scenario_of(args)?;
    let mut rep = nominal(args, &sc)?;
    if args.verbose {
        eprintln!("{}", summary(&rep));
    }
    if args.runs > 0 {
        let part = mc::run(&sc, &mc::Plan::of(args, &sc, (0, 1)), args.verbose)?;
        let (sum, drawn) = mc::write_outputs(&args.out, std::slice::from_ref(&part), !args.no_plots)?;
        if args.verbose {
            eprintln!("{}", mc::table(&sum));
        }
        rep.monte_carlo = Some(sum);
        // The study's plots first: the page's order, by file name.
        rep.plots.splice(0..0, drawn);
    }
    let plan = plan::plan(&sc, args.lab_program)?;
    let v = verdict::of_flight(&rep, &plan, verdict::flight_files(!args.no_plots, args.runs));
    write_reports(&args.out, &v, &rep, &markdown(&rep, &v), &page(&rep, &plan, &v))?;
    rep.verdict = Some(v);
    Ok(rep)
}

/// `qfa-lab navigate merge DIR…`: combine the shards' partial results ([`mc::merge`]) and
/// write the study's `report.json` (its verdict first), `report.md` and `report.html` to
/// `out`; returns the merged study and its verdict.
///
/// # Errors
/// As [`mc::merge`], and I/O.
pub fn merge(dirs: &[PathBuf], out: &Path, plots: bool) -> Result<(mc::Summary, Verdict), NavError> {
    let (sum, report, drawn) = mc::merge(dirs, out, plots)?;
    let v = verdict::of_study(&sum, &report, verdict::study_files(plots));
    write_reports(out, &v, &report, &merge_markdown(&sum, &v), &merge_page(&sum, &v, &drawn))?;
    Ok((sum, v))
}

/// Write `report.json` (the verdict as its first key, then `report`'s), `report.md` and
/// `report.html` into `out`.
fn write_reports<T: serde::Serialize>(
    out: &Path,
    v: &qfa_report::verdict::Verdict,
    report: &T,
    markdown: &str,
    page: &qfa_report::html_report::Page,
) -> Result<(), NavError> {
    write_file(&out.join("report.json"), &qfa_report::verdict::json_with_verdict(v, report)?)?;
    write_file(&out.join("report.md"), markdown)?;
    page.write(out).map_err(NavError::Page)?;
    Ok(())
}

/// `qfa-lab navigate --runs N --shard K/N`: the Monte Carlo runs of shard K (and, for
/// K = 0, the nominal run) into `args.out/mc_partial_K_of_N.json`, for
/// [`mc::merge`].
///
/// # Errors
/// Scenario, table, Monte Carlo or I/O errors.
pub fn navigate_shard(args: &NavigateArgs) -> Result<PathBuf, NavError> {
    let (k, n) = args.shard.ok_or(NavError::NoShard)?;
    ensure(n > 0 && k < n, NavError::Shard { k, n })?;
    ensure(args.runs > 0, NavError::ShardRuns)?;
    let sc = scenario_of(args)?;
    let mut part = mc::run(&sc, &mc::Plan::of(args, &sc, (k, n)), args.verbose)?;
    if k == 0 {
        part.nominal = Some(serde_json::to_value(nominal(args, &sc)?)?);
    }
    std::fs::create_dir_all(&args.out).map_err(|e| NavError::CreateDir { path: args.out.clone(), source: e })?;
    let path = args.out.join(format!("mc_partial_{k}_of_{n}.json"));
    write_file(&path, &serde_json::to_string(&part)?)?;
    Ok(path)
}

/// What the navigation study hands the demo.
#[derive(Clone, Debug)]
pub struct NavigationOutcome {
    /// The study's verdict (merged into the demo's).
    pub verdict: qfa_report::verdict::Verdict,
    /// The caption of `nav_errors.png`: what to look for, and why it may look alarming.
    pub plot_caption: String,
    /// `nav_errors.png` as the study drew it (none without plots).
    pub plot: Option<qfa_report::plot_png::Plot>,
}

/// The lab demo's navigation hook (the CLI's `demo::NavigationHook`): `navigate` on the
/// built-in flight (its first `duration_s` when given) into `out`; returns its verdict and
/// the caption of its flight plot.
///
/// # Errors
/// The study's failure (the demo fails with it).
pub fn demo_hook(out: &Path, duration_s: Option<f64>) -> Result<NavigationOutcome, NavError> {
    let args = NavigateArgs { out: out.to_path_buf(), duration_s, ..NavigateArgs::default() };
    let r = navigate(&args)?;
    let plot_caption = verdict::caption(plot::FLIGHT_PLOT, &verdict::alarms(&r));
    let plot = r.plots.iter().find(|p| p.file == plot::FLIGHT_PLOT).cloned();
    let verdict = r.verdict.ok_or(NavError::NoVerdict)?;
    Ok(NavigationOutcome { verdict, plot_caption, plot })
}
