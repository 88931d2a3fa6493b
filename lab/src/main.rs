//! `qfa-lab`: simulate thermal tests, calibrate tables, compensate logs, run the demo.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand, ValueEnum};

use qfa_calibrate::compensate::compensate_log;
use qfa_calibrate::discover::{static_axes, Start};
use qfa_calibrate::export::ExportOptions;
use qfa_calibrate::lint::Severity;
use qfa_calibrate::static_cal::{self, Holdout};
use qfa_calibrate::{calibrate_into, CalibrateOptions};
use qfa_lab::out_path::OutError;
use qfa_log::channels::Channels;
use qfa_log::cycling::{write_compensated, write_log};
use qfa_log::open::{open, LogFormat, OpenError, OpenedLog, ReadFlags};
use qfa_log::static_log::columns::{AccelUnit, ColumnMap, TimeUnit};
use qfa_log::units::TempUnit;
use qfa_nav::calib::LabProgram;
use qfa_nav::scenario::Scenario;
use qfa_report::verdict::{json_with_verdict, LimitsChoice, Verdict, CYCLING_KEYS, EXIT_LIMIT_FAILED, STATIC_KEYS};
use qfa_sim::profile::{paper_positions, Program, PAPER_RATES};
use qfa_sim::simulate;
use qfa_sim::truth::Truth;

#[derive(Parser)]
#[command(name = "qfa-lab", version, about = "Thermal-test simulator, calibration and compensation for QFA tables")]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Clone, Copy, ValueEnum)]
enum ProfileKind {
    /// The paper's Steps 1–6: four rates × four positions.
    Paper,
    /// A flight-like profile (§3.2), four positions.
    Flight,
}

/// How to read a static multi-axis log (CSV/TSV with a header); any flag, or a header
/// without a `pulses` column, selects the static-log path (`qfa_log::open`).
#[derive(clap::Args, Clone, Default)]
struct StaticFlags {
    /// Column choices, e.g. `time=timestamp,temp=imu.temperature,ax=imu.acc.x,ay=imu.acc.y,az=imu.acc.z`.
    #[arg(long, value_parser = str::parse::<ColumnMap>)]
    columns: Option<ColumnMap>,
    /// Unit of the time column: s, ms, us or ns.
    #[arg(long, value_parser = str::parse::<TimeUnit>)]
    time_unit: Option<TimeUnit>,
    /// Unit of the acceleration columns: g, mg or m/s2.
    #[arg(long, value_parser = str::parse::<AccelUnit>)]
    accel_unit: Option<AccelUnit>,
    /// Unit of the temperature column: C, F or K (default: from the column name, else C).
    #[arg(long, value_parser = str::parse::<TempUnit>)]
    temp_unit: Option<TempUnit>,
    /// Numbers use a decimal comma (`20,5`); the file must be `;`- or tab-separated.
    #[arg(long)]
    decimal_comma: bool,
}

impl StaticFlags {
    fn flags(&self) -> ReadFlags {
        ReadFlags {
            columns: self.columns.clone(),
            time_unit: self.time_unit,
            accel_unit: self.accel_unit,
            temp_unit: self.temp_unit,
            decimal_comma: self.decimal_comma,
        }
    }
}

#[derive(Subcommand)]
enum Cmd {
    /// Simulate a cycling log (CSV) and write its truth (TOML) next to it.
    Simulate(SimulateArgs),
    /// Fit the simple and hysteresis models; write table.toml, table.bin, report.json, plots.
    Calibrate(CalibrateArgs),
    /// Discovery workflow: name the missing effect, add it, show the held-out gap shrink.
    Discover {
        /// Cycling log or single-channel log (time_s,temp_c,value).
        #[arg(long)]
        log: PathBuf,
        /// Start model: simple or paper.
        #[arg(long, default_value = "simple")]
        start: Start,
        /// Output directory (a static log: one subdirectory per axis).
        #[arg(long)]
        out: PathBuf,
        /// Static logs: the held-out scheme, auto | after-max | blocks:K | none (the lab guide's "Static logs").
        #[arg(long, default_value = "auto")]
        holdout: Holdout,
        /// Print report.json on stdout (the verdict then goes to stderr).
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        fmt: StaticFlags,
    },
    /// Compensate a log through the root crate's compensator; adds an accel_g column.
    Compensate {
        /// Cycling log.
        #[arg(long)]
        log: PathBuf,
        /// Flashable table (.bin).
        #[arg(long)]
        table: PathBuf,
        /// Output CSV.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        fmt: StaticFlags,
    },
    /// Write a table.bin as the Rust source of a `static` in flash (what a board's build.rs
    /// writes): `pub static TABLE: qfa_thermal::Table = …;`, every number exact.
    TableRs {
        /// Flashable table (.bin).
        #[arg(long)]
        table: PathBuf,
        /// Output .rs file.
        #[arg(long)]
        out: PathBuf,
        /// Name of the static.
        #[arg(long, default_value = "TABLE")]
        name: String,
    },
    /// Every check the lab makes on a log before a fit, each with its evidence and fix;
    /// exit code 1 when the lab would refuse the log.
    Lint {
        /// The log (cycling or static).
        #[arg(long)]
        log: PathBuf,
        #[command(flatten)]
        fmt: StaticFlags,
    },
    /// The paper's full test for JB-KT8 #1–#3: simulate, calibrate, compensate, compare.
    Demo {
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Row length, s.
        #[arg(long, default_value_t = 1)]
        row_s: u32,
        /// Seed.
        #[arg(long, default_value_t = 2021)]
        seed: u64,
        /// Simulation threads.
        #[arg(long, default_value_t = 2)]
        threads: usize,
        /// Keep each unit's log.csv (about 47 MB each at 1-s rows); without it the logs are
        /// deleted once used and the outputs stay under 20 MB.
        #[arg(long)]
        full_logs: bool,
        /// Fly only the first this many seconds of the navigation flight (a quicker demo).
        #[arg(long)]
        nav_duration_s: Option<f64>,
    },
    /// Calibrate many units from one chamber run: a certificate per serial and the fleet
    /// page; `batch merge OUT` forms the fleet of a sharded run.
    Batch(BatchCli),
    /// Simulate a production batch of static units (one chamber log and a manifest of
    /// one-unit logs), with each unit's truth.
    SimulateBatch {
        /// Units.
        #[arg(long, default_value_t = 100)]
        units: usize,
        /// Seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// No deliberately bad units (default: one of each defect per started 50 units).
        #[arg(long)]
        no_bad: bool,
        /// Good units whose own log (manifest run) is truncated: heating only, or the first half.
        #[arg(long, default_value_t = 0)]
        truncated: usize,
        /// Output directory: chamber.tsv, batch.toml with units/, truth.toml.
        #[arg(long)]
        out: PathBuf,
    },
    /// Pure-inertial navigation error of each compensation variant, with
    /// alignment and an optional Monte Carlo study; `navigate merge DIR…` combines shards.
    Navigate(NavigateCli),
    /// The temperature and rate coverage a lab program must reach for a mission (the
    /// scenario's thermal profile) and whether a lab program reaches it; exit code 1 when
    /// it does not cover the nominal mission.
    Plan {
        /// Scenario TOML (default: the built-in §3.2 flight).
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Lab program judged: `covering` or `paper`.
        #[arg(long, default_value = "covering")]
        lab_program: LabProgram,
        /// Also write the plan as JSON here.
        #[arg(long)]
        json: Option<PathBuf>,
    },
}

/// `qfa-lab simulate`'s arguments.
#[derive(clap::Args)]
struct SimulateArgs {
    /// Output log, e.g. log.csv; the truth goes to log.truth.toml.
    #[arg(long)]
    out: PathBuf,
    /// Unit preset: kt8-1, kt8-2 or kt8-3.
    #[arg(long, default_value = "kt8-1")]
    unit: String,
    /// A truth TOML instead of a preset.
    #[arg(long)]
    truth: Option<PathBuf>,
    /// Extension effects to switch on (sensor_lag, bias_branch_hysteresis, bias_creep).
    #[arg(long, value_delimiter = ',')]
    effects: Vec<String>,
    /// Built-in profile.
    #[arg(long, value_enum, default_value = "paper")]
    profile: ProfileKind,
    /// Chamber-air profile file (`time_s,temp_c`) instead of the built-in one.
    #[arg(long)]
    profile_file: Option<PathBuf>,
    /// Only these paper rates, °C/min (default all four).
    #[arg(long, value_delimiter = ',')]
    rates: Vec<f64>,
    /// Row length, s (integer).
    #[arg(long, default_value_t = 1)]
    row_s: u32,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Simulation threads.
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// No noise (accelerometer and DS18B20).
    #[arg(long)]
    noiseless: bool,
}

/// `qfa-lab calibrate`'s arguments.
#[derive(clap::Args)]
struct CalibrateArgs {
    /// Cycling log.
    #[arg(long)]
    log: PathBuf,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    /// Programs to fit on (default: first and last; the rest are held out).
    #[arg(long, value_delimiter = ',')]
    fit_programs: Vec<String>,
    /// Skip the plots.
    #[arg(long)]
    no_plots: bool,
    /// Cycling log: the IMU axis this accelerometer is, for the PX4 / ArduPilot
    /// parameter files (a one-axis export: needs --export-range).
    #[arg(long, default_value = "x", value_parser = ["x", "y", "z"])]
    axis: String,
    /// PX4 TC_A0_ID: the device ID of the accelerometer (CAL_ACC0_ID, or device_id in
    /// `listener sensor_accel`); without it no px4_tc.params is written.
    #[arg(long, value_name = "ID", value_parser = parse_device_id)]
    px4_device_id: Option<i32>,
    /// TMIN,TMAX (°C) for the fields the axes share (PX4 TC_A0_TREF/TMIN/TMAX, ArduPilot
    /// INS_TCAL1_TMIN/TMAX), the same for every axis exported; needed for a one-axis
    /// export, inside the training temperatures.
    #[arg(long, value_name = "TMIN,TMAX", allow_hyphen_values = true, value_parser = parse_range)]
    export_range: Option<(f64, f64)>,
    /// Static logs: the held-out scheme, auto | after-max | blocks:K | none (the lab guide's "Static logs").
    #[arg(long, default_value = "auto")]
    holdout: Holdout,
    /// Static logs: the part's sensitivity at the range it was logged at, LSB per g (4096
    /// for ±8 g at 16 bits), recorded in table.bin so that a firmware stating another
    /// `Config::sample_lsb_per_g` refuses the table.
    #[arg(long, value_name = "LSB", value_parser = parse_lsb_per_g)]
    lsb_per_g: Option<f32>,
    /// Pass/fail limits (TOML; the lab guide's "Limits" lists the keys and defaults): a
    /// unit that fails one exits with status 3 after writing every file.
    #[arg(long, value_name = "FILE")]
    limits: Option<PathBuf>,
    #[command(flatten)]
    fmt: StaticFlags,
}

/// `qfa-lab batch`'s arguments.
#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
struct BatchCli {
    #[command(subcommand)]
    sub: Option<BatchCmd>,
    /// One chamber log holding every unit: `time`, then SERIAL.temp, SERIAL.ax, SERIAL.ay,
    /// SERIAL.az per unit.
    #[arg(long, conflicts_with = "manifest")]
    log: Option<PathBuf>,
    /// A manifest naming one log per serial (`batch.toml`; the lab guide's "Production batches").
    #[arg(long)]
    manifest: Option<PathBuf>,
    /// Output directory: one folder per serial, and the fleet page.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Pass/fail limits (TOML, as `calibrate --limits`).
    #[arg(long)]
    limits: Option<PathBuf>,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Run only shard K of N (0 ≤ K < N: units i with i mod N = K), all shards writing into
    /// the same --out; then `qfa-lab batch merge OUT`.
    #[arg(long, value_parser = str::parse::<qfa_calibrate::batch::Shard>)]
    shard: Option<qfa_calibrate::batch::Shard>,
    /// Draw each unit's bias plot (off: a batch's pages are its certificates and the fleet).
    #[arg(long)]
    plots: bool,
    /// The held-out scheme, as `calibrate --holdout`.
    #[arg(long, default_value = "auto")]
    holdout: Holdout,
    #[command(flatten)]
    fmt: StaticFlags,
}

#[derive(Subcommand)]
enum BatchCmd {
    /// Form the fleet and the certificates from every SERIAL/unit.json under OUT (the shards
    /// of one batch).
    Merge {
        /// The --out every shard wrote into.
        out: PathBuf,
        /// Pass/fail limits (the same file the shards were given).
        #[arg(long)]
        limits: Option<PathBuf>,
    },
}

/// `qfa-lab navigate`'s arguments.
#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
struct NavigateCli {
    #[command(subcommand)]
    sub: Option<NavCmd>,
    /// Scenario TOML (default: the built-in §3.2 flight).
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Output directory.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Discovered tables for x,y,z (three files, .bin or .toml).
    #[arg(long, value_delimiter = ',', num_args = 3)]
    discovered_tables: Option<Vec<PathBuf>>,
    /// IMU rate override, Hz.
    #[arg(long)]
    imu_rate_hz: Option<f64>,
    /// Monte Carlo runs (0: the nominal run only).
    #[arg(long, default_value_t = 0)]
    runs: u64,
    /// Monte Carlo base seed (default: the scenario's seed).
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads for the Monte Carlo runs (0: all cores).
    #[arg(long, default_value_t = 0)]
    jobs: usize,
    /// Run only shard K of N (0 ≤ K < N: runs i with i mod N = K) and write
    /// DIR/mc_partial_K_of_N.json; shard 0 also flies the nominal run.
    #[arg(long, value_parser = parse_shard)]
    shard: Option<(u64, u64)>,
    /// Skip the plots.
    #[arg(long)]
    no_plots: bool,
    /// Leave `discovered` out of the Monte Carlo runs (skips discovery per run, about
    /// half the cost).
    #[arg(long)]
    no_mc_discovered: bool,
    /// Lab program the units are calibrated on: `covering` (paper 0.3/0.9 + 1 and
    /// 2 °C/min ramps, covers the built-in flight) or `paper` (the four staircases).
    #[arg(long, default_value = "covering")]
    lab_program: LabProgram,
    /// Experiment only: every table's rate limit, °C/min, in place of the fitted one
    /// (the tables then extrapolate above the fitted rates, unflagged).
    #[arg(long)]
    rate_limit_override: Option<f32>,
}

#[derive(Subcommand)]
enum NavCmd {
    /// Combine the mc_partial_*.json of shards into report.json, mc_runs.csv and plots.
    Merge {
        /// Directories (or partial files) to read.
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// Output directory (default: the first DIR).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Skip the plots.
        #[arg(long)]
        no_plots: bool,
    },
}

fn parse_shard(s: &str) -> Result<(u64, u64), String> {
    let (k, n) = s.split_once('/').ok_or_else(|| format!("`{s}`: expected K/N"))?;
    let k: u64 = k.trim().parse().map_err(|e| format!("`{s}`: K: {e}"))?;
    let n: u64 = n.trim().parse().map_err(|e| format!("`{s}`: N: {e}"))?;
    if n == 0 || k >= n {
        return Err(format!("`{s}`: need 0 ≤ K < N"));
    }
    Ok((k, n))
}

/// A PX4 device ID: PX4 keeps the (unsigned) ID in an int32 parameter; `listener` prints it
/// unsigned, a ground station may show it signed: either is taken, the int32 is written.
/// A part's sensitivity, LSB per g, within what a table takes (1..1e9), refused before any work.
fn parse_lsb_per_g(s: &str) -> Result<f32, String> {
    let v: f32 =
        s.trim().parse().map_err(|e| format!("{e}: expected the part's LSB per g, e.g. 4096 (±8 g, 16 bits)"))?;
    let (lo, hi) = qfa_thermal::table::limits::GAMMA;
    if !(v.is_finite() && (lo..=hi).contains(&v)) {
        return Err(format!("{v} is no part's LSB per g: 1 to 1e9, e.g. 4096 (±8 g, 16 bits)"));
    }
    Ok(v)
}

fn parse_device_id(s: &str) -> Result<i32, String> {
    let v: i64 = s.trim().parse().map_err(|e| format!("{e}: expected the accelerometer's device ID, e.g. 1310988"))?;
    if v == 0 {
        return Err("0 matches no accelerometer: pass the vehicle's CAL_ACC0_ID (or device_id in `listener \
                    sensor_accel`)"
            .to_string());
    }
    if !(i64::from(i32::MIN)..=i64::from(u32::MAX)).contains(&v) {
        return Err(format!("{v} is not a 32-bit device ID"));
    }
    // Two's complement: the bits PX4 compares (`device_id == (uint32_t)ID`).
    Ok(v as u32 as i32)
}

fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s.split_once(',').ok_or_else(|| format!("`{s}`: expected TMIN,TMAX in °C"))?;
    let lo: f64 = a.trim().parse().map_err(|e| format!("`{s}`: TMIN: {e}"))?;
    let hi: f64 = b.trim().parse().map_err(|e| format!("`{s}`: TMAX: {e}"))?;
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return Err(format!("`{s}`: need finite TMIN < TMAX"));
    }
    Ok((lo, hi))
}

/// Why a command failed: printed as `error: …`, exit code 1.
#[derive(Debug)]
enum CliError {
    /// The command line asks for what cannot be done.
    Usage(String),
    /// An output that would overwrite something, or cannot be written.
    Out(OutError),
    /// A log that cannot be read (the file, and its reader's error).
    Open(OpenError),
    /// A log of a kind the command does not take.
    WrongLog {
        /// The command.
        command: &'static str,
        /// What the log is.
        format: LogFormat,
        /// What the command takes.
        takes: &'static str,
    },
    /// The work failed (a fit, a simulation, a write), with its cause.
    Failed(String),
    /// Every output is written, and the unit fails a limit given with `--limits` (which:
    /// one line each). Exit status [`EXIT_LIMIT_FAILED`].
    LimitFailed(Vec<String>),
    /// Every output of a batch is written, and units FAIL (not calibrated, or a limit given
    /// with `--limits` failed). Exit status [`EXIT_LIMIT_FAILED`].
    UnitsFailed(usize),
}

impl std::fmt::Display for CliError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Usage(m) | Self::Failed(m) => f.write_str(m),
            Self::Out(e) => write!(f, "{e}"),
            Self::Open(e) => write!(f, "{e}"),
            Self::WrongLog { command, format, takes } => write!(f, "{command} takes {takes}, not a {format}"),
            Self::LimitFailed(which) => write!(f, "the unit fails {} limit(s): {}", which.len(), which.join("; ")),
            Self::UnitsFailed(n) => write!(f, "{n} unit(s) FAIL (each listed above, with why)"),
        }
    }
}

impl CliError {
    /// `calibrate` and `compensate` take cycling and static logs; a single-channel log is
    /// discovery's.
    fn single_not_taken(command: &'static str) -> Self {
        Self::WrongLog { command, format: LogFormat::Single, takes: "a cycling or a static log" }
    }
}

impl From<OutError> for CliError {
    fn from(e: OutError) -> Self {
        Self::Out(e)
    }
}

impl From<OpenError> for CliError {
    fn from(e: OpenError) -> Self {
        Self::Open(e)
    }
}

impl From<qfa_sim::truth::TruthError> for CliError {
    fn from(e: qfa_sim::truth::TruthError) -> Self {
        match e {
            // A name the user typed: the command line asks for what cannot be done.
            qfa_sim::truth::TruthError::UnknownEffect { .. } => Self::Usage(e.to_string()),
            _ => Self::Failed(e.to_string()),
        }
    }
}

impl From<qfa_sim::profile::ProfileError> for CliError {
    fn from(e: qfa_sim::profile::ProfileError) -> Self {
        Self::Failed(e.to_string())
    }
}

impl From<qfa_sim::population::PopulationError> for CliError {
    fn from(e: qfa_sim::population::PopulationError) -> Self {
        Self::Failed(e.to_string())
    }
}

impl From<qfa_lab::demo::DemoError> for CliError {
    fn from(e: qfa_lab::demo::DemoError) -> Self {
        Self::Failed(e.to_string())
    }
}

impl From<qfa_calibrate::CalibrateError> for CliError {
    fn from(e: qfa_calibrate::CalibrateError) -> Self {
        Self::Failed(e.to_string())
    }
}

impl From<qfa_calibrate::discover::DiscoverError> for CliError {
    fn from(e: qfa_calibrate::discover::DiscoverError) -> Self {
        // `{:#}`: with its causes (the file and the system's error).
        Self::Failed(format!("{e:#}"))
    }
}

impl From<qfa_log::channels::ChannelsError> for CliError {
    fn from(e: qfa_log::channels::ChannelsError) -> Self {
        Self::Failed(e.to_string())
    }
}

impl From<String> for CliError {
    fn from(e: String) -> Self {
        Self::Failed(e)
    }
}

impl From<anyhow::Error> for CliError {
    fn from(e: anyhow::Error) -> Self {
        Self::Failed(format!("{e:#}"))
    }
}

/// A navigation error with its causes on one line (`context: cause`), as an anyhow error
/// prints.
fn nav_failed(e: impl std::error::Error + Send + Sync + 'static) -> CliError {
    CliError::from(anyhow::Error::from(e))
}

impl From<qfa_nav::NavError> for CliError {
    fn from(e: qfa_nav::NavError) -> Self {
        nav_failed(e)
    }
}

impl From<qfa_nav::scenario::ScenarioError> for CliError {
    fn from(e: qfa_nav::scenario::ScenarioError) -> Self {
        nav_failed(e)
    }
}

impl From<qfa_nav::plan::PlanError> for CliError {
    fn from(e: qfa_nav::plan::PlanError) -> Self {
        nav_failed(e)
    }
}

/// Every `--out` checked before any work (a log is read, a fit runs).
fn check_out(cmd: &Cmd) -> Result<(), OutError> {
    use qfa_lab::out_path::{check_dir, check_file};
    match cmd {
        Cmd::Simulate(a) => check_file(&a.out, "simulate"),
        Cmd::Calibrate(a) => check_dir(&a.out, "calibrate"),
        Cmd::Discover { out, .. } => check_dir(out, "discover"),
        Cmd::Compensate { out, .. } => check_file(out, "compensate"),
        Cmd::TableRs { out, .. } => check_file(out, "table-rs"),
        Cmd::Demo { out, .. } => check_dir(out, "demo"),
        Cmd::Navigate(NavigateCli { out: Some(out), sub: None, .. }) => check_dir(out, "navigate"),
        Cmd::Navigate(_) => Ok(()),
        Cmd::Batch(BatchCli { out: Some(out), sub: None, .. }) => check_dir(out, "batch"),
        Cmd::Batch(_) => Ok(()),
        Cmd::SimulateBatch { out, .. } => check_dir(out, "simulate-batch"),
        Cmd::Plan { json: Some(j), .. } => check_file(j, "plan"),
        Cmd::Plan { .. } | Cmd::Lint { .. } => Ok(()),
    }
}

/// A cycling log's programs are its held-out scheme: `--holdout` is for static logs.
fn cycling_holdout(holdout: Holdout) -> Result<(), CliError> {
    if holdout == Holdout::default() {
        Ok(())
    } else {
        Err(CliError::Usage(format!("--holdout {holdout}: static logs only (a cycling log is held out by program)")))
    }
}

fn io_at(path: &Path) -> impl Fn(std::io::Error) -> CliError + '_ {
    move |e| CliError::Failed(format!("{}: {e}", path.display()))
}

/// `table` (validated by decoding) as `pub static NAME: qfa_thermal::Table = …;` in `out`.
fn table_rs_cmd(table: &Path, out: &Path, name: &str) -> Result<(), CliError> {
    let ident = !name.is_empty()
        && name.chars().all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
        && !name.starts_with(|c: char| c.is_ascii_digit());
    if !ident {
        return Err(CliError::Usage(format!("--name {name:?}: a static's name, upper case (TABLE, Z_AXIS_TABLE)")));
    }
    let t = read_table(table)?;
    let source = format!(
        "/// Generated by `qfa-lab table-rs` from {}: {} axes, {}.\npub static {name}: qfa_thermal::Table = {};\n",
        table.file_name().map_or_else(|| table.display().to_string(), |f| f.to_string_lossy().into_owned()),
        t.axes.len(),
        t.input,
        qfa_thermal::table::RustSource(&t)
    );
    std::fs::write(out, source).map_err(io_at(out))?;
    eprintln!("{} → {} (`{name}`; `set_table(&{name})` validates it where it lies)", table.display(), out.display());
    Ok(())
}

fn read_table(path: &Path) -> Result<qfa_thermal::Table, CliError> {
    let bytes = std::fs::read(path).map_err(io_at(path))?;
    qfa_thermal::Table::decode(&bytes).map_err(|e| CliError::Failed(format!("{}: {e}", path.display())))
}

fn simulate_cmd(a: SimulateArgs) -> Result<(), CliError> {
    let mut t = match &a.truth {
        Some(p) => Truth::from_toml(&std::fs::read_to_string(p).map_err(io_at(p))?)?,
        None => Truth::preset(&a.unit)
            .ok_or_else(|| CliError::Usage(format!("unknown unit `{}` (kt8-1, kt8-2, kt8-3)", a.unit)))?,
    };
    for e in &a.effects {
        t = t.with_effect(e)?;
    }
    if a.noiseless {
        t = t.noiseless();
    }
    let programs: Vec<Program> = if let Some(f) = &a.profile_file {
        let id = f.file_stem().map_or("user".to_string(), |s| s.to_string_lossy().into_owned());
        vec![Program::from_file(f, &id)?]
    } else {
        match a.profile {
            ProfileKind::Paper => {
                let rs: &[f64] = if a.rates.is_empty() { &PAPER_RATES } else { &a.rates };
                rs.iter().map(|&r| Program::paper(r)).collect()
            }
            ProfileKind::Flight => vec![Program::flight()],
        }
    };
    let pb = indicatif::ProgressBar::new((programs.len() * 4) as u64);
    pb.set_message("simulating runs");
    let t0 = Instant::now();
    let log = simulate(&t, &programs, &paper_positions(), a.row_s, a.seed, a.threads, Some(&pb));
    pb.finish_and_clear();
    write_log(&a.out, &log).map_err(io_at(&a.out))?;
    let truth_path = a.out.with_extension("truth.toml");
    std::fs::write(&truth_path, t.to_toml()?).map_err(io_at(&truth_path))?;
    eprintln!(
        "{} rows in {:.1} s → {} (truth: {})",
        log.rows(),
        t0.elapsed().as_secs_f64(),
        a.out.display(),
        truth_path.display()
    );
    Ok(())
}

fn calibrate_cmd(a: CalibrateArgs) -> Result<(), CliError> {
    let t0 = Instant::now();
    let limits = LimitsChoice::from_arg(a.limits.as_deref()).map_err(|e| CliError::Usage(e.to_string()))?;
    let exports = ExportOptions { px4_device_id: a.px4_device_id, range_c: a.export_range, ..ExportOptions::default() };
    // Lint first: its warnings on the console, then the log it read (a refused log is the
    // error itself).
    let lint = qfa_calibrate::lint::lint(&a.log, &a.fmt.flags());
    let warnings: Vec<String> = lint.at_least(Severity::Warning).map(ToString::to_string).collect();
    if !warnings.is_empty() && lint.log.is_ok() {
        eprintln!("lint: {} finding(s) to act on (`qfa-lab lint` lists every check):", warnings.len());
        for w in &warnings {
            eprintln!("{w}");
        }
    }
    let opened = lint.log?;
    // A limits file must set at least one key this kind of log is checked against.
    let applies = match &opened {
        OpenedLog::Static(_) | OpenedLog::Autopilot(_) => limits.check_applies("static", &STATIC_KEYS),
        OpenedLog::Cycling(_) => limits.check_applies("cycling", &CYCLING_KEYS),
        OpenedLog::Single(_) => Ok(()),
    };
    applies.map_err(|e| CliError::Usage(e.to_string()))?;
    match opened {
        OpenedLog::Static(l) => {
            eprintln!("{} rows read; {}; {}", l.rows(), l.skipped, l.sampling);
            let opts =
                static_cal::StaticCalOptions { holdout: a.holdout, part_lsb_per_g: a.lsb_per_g, ..Default::default() };
            if a.lsb_per_g.is_none() {
                eprintln!(
                    "note: table.bin does not record the part's sensitivity (--lsb-per-g): a firmware that states \
                     the wrong Config::sample_lsb_per_g cannot be refused"
                );
            }
            let notes = lint_notes(&warnings);
            let run = static_cal::StaticRun {
                opts: &opts,
                exports: &exports,
                limits: &limits,
                plots: !a.no_plots,
                progress: true,
                command: None,
            };
            let (_, v) = static_cal::calibrate_static_into(&a.out, &l, &run, &notes).map_err(|e| e.to_string())?;
            finish(&v, &limits, &a.out)
        }
        OpenedLog::Cycling(l) => {
            cycling_holdout(a.holdout)?;
            if a.lsb_per_g.is_some() {
                return Err(CliError::Usage("--lsb-per-g: static logs only (a cycling log is pulse counts)".into()));
            }
            let opts = CalibrateOptions {
                fit_programs: if a.fit_programs.is_empty() { None } else { Some(a.fit_programs) },
                plots: !a.no_plots,
                title: a.log.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default(),
                progress: true,
                axis: Some(format!("a{}", a.axis)),
                exports,
                limits: limits.clone(),
            };
            let cal = calibrate_into(&l, &a.out, &opts, t0.elapsed().as_secs_f64())?;
            let v = cal.verdict.as_ref().ok_or_else(|| CliError::Failed("no verdict written".into()))?;
            finish(v, &limits, &a.out)
        }
        OpenedLog::Autopilot(l) => {
            if a.px4_device_id.is_some() || a.export_range.is_some() {
                return Err(CliError::Usage(format!(
                    "--px4-device-id and --export-range are not taken for a {}: the log holds each accelerometer's \
                     device ID and instance, and each instance is exported over its own range",
                    l.stack
                )));
            }
            let opts = static_cal::StaticCalOptions { holdout: a.holdout, ..Default::default() };
            let cal = qfa_calibrate::autopilot_cal::calibrate_autopilot(&l, &a.out, &opts, !a.no_plots, true, &limits)
                .map_err(|e| e.to_string())?;
            finish(&cal.verdict, &limits, &a.out)
        }
        OpenedLog::Single(_) => Err(CliError::single_not_taken("calibrate")),
    }
}

/// The first line of each lint finding, for the verdict (the console printed them whole).
fn lint_notes(findings: &[String]) -> Vec<String> {
    findings.iter().filter_map(|f| f.lines().next()).map(|l| format!("lint: {l}")).collect()
}

/// Print the verdict (the console's summary: the same lines as the reports' verdict) and
/// where the detail is; a failure against `--limits` ends with [`EXIT_LIMIT_FAILED`].
fn finish(v: &Verdict, limits: &LimitsChoice, out: &Path) -> Result<(), CliError> {
    print_verdict(v, out, None);
    if limits.enforced_failure(v) {
        return Err(CliError::LimitFailed(v.failed()));
    }
    Ok(())
}

/// The verdict's lines and where the detail is, on stdout; with `json` (the report), the
/// JSON alone on stdout and the lines on stderr, so stdout parses.
fn print_verdict(v: &Verdict, out: &Path, json: Option<&str>) {
    let detail = format!("detail: {}/report.md, report.html, report.json", out.display());
    match json {
        None => {
            print!("{}", v.console());
            println!("{detail}");
        }
        Some(j) => {
            eprint!("{}", v.console());
            eprintln!("{detail}");
            println!("{j}");
        }
    }
}

fn discover_cmd(
    log: &Path,
    start: Start,
    out: &Path,
    fmt: &StaticFlags,
    holdout: Holdout,
    json: bool,
) -> Result<(), CliError> {
    let to_json = |e: serde_json::Error| CliError::Failed(e.to_string());
    let (v, report) = match open(log, &fmt.flags())? {
        OpenedLog::Static(l) => {
            // A static log: each axis is a single-channel (bias) log, on static calibration's split.
            eprintln!("{} rows read; {}", l.rows(), l.skipped);
            let pb = qfa_lab::demo::spinner("discovery on each axis", true);
            let d = static_axes::run(&l, start, holdout, out);
            pb.finish_and_clear();
            let (d, v) = d?;
            let j = if json { Some(json_with_verdict(&v, &d).map_err(to_json)?) } else { None };
            (v, j)
        }
        opened => {
            cycling_holdout(holdout)?;
            let ch = Channels::from_opened(&opened, 60.0)?;
            let pb = qfa_lab::demo::spinner("discovery", true);
            let r = qfa_calibrate::discover::discover_with_verdict(&ch, start, out);
            pb.finish_and_clear();
            let (r, v) = r?;
            let j = if json { Some(json_with_verdict(&v, &r).map_err(to_json)?) } else { None };
            (v, j)
        }
    };
    print_verdict(&v, out, report.as_deref());
    Ok(())
}

fn compensate_cmd(log: &Path, table: &Path, out: &Path, fmt: &StaticFlags) -> Result<(), CliError> {
    // The table is read and the output created only for a log compensate takes.
    let table_and_out = || -> Result<_, CliError> {
        let t = read_table(table)?;
        Ok((t, std::fs::File::create(out).map_err(io_at(out))?))
    };
    match open(log, &fmt.flags())? {
        OpenedLog::Static(l) => {
            let (t, f) = table_and_out()?;
            let flags = qfa_calibrate::compensate::compensate_static(&t, &l, std::io::BufWriter::new(f))
                .map_err(|e| e.to_string())?;
            // The counts go beside the CSV, which stays plain for pandas and Python's csv.
            let sidecar = out.with_extension("flags.json");
            let text = serde_json::to_string_pretty(&flags.json()).map_err(|e| e.to_string())?;
            std::fs::write(&sidecar, text + "\n").map_err(io_at(&sidecar))?;
            eprintln!("{} rows ({}) → {}", l.rows(), l.skipped, out.display());
            eprintln!("status flags (also in {}):", sidecar.display());
            for line in flags.lines() {
                eprintln!("  {line}");
            }
        }
        OpenedLog::Cycling(l) => {
            let (t, f) = table_and_out()?;
            let pb = indicatif::ProgressBar::new(l.runs.len() as u64);
            let c = compensate_log(&t, &l, Some(&pb)).map_err(|e| e.to_string())?;
            pb.finish_and_clear();
            let flags = qfa_calibrate::compensate::FlagSummary::of(
                c.iter().flat_map(|r| r.status.iter().map(|&s| qfa_thermal::Status::from_bits_retain(s))),
            );
            let acc: Vec<Vec<f64>> = c.into_iter().map(|c| c.accel_g).collect();
            write_compensated(f, &l, &acc).map_err(io_at(out))?;
            eprintln!("{} rows → {}", l.rows(), out.display());
            eprintln!("status flags (the firmware's, per row; the output has no status column):");
            for line in flags.lines() {
                eprintln!("  {line}");
            }
        }
        OpenedLog::Autopilot(l) => {
            return Err(CliError::WrongLog {
                command: "compensate",
                format: LogFormat::Autopilot(l.stack),
                takes: "a cycling or a static log",
            })
        }
        OpenedLog::Single(_) => return Err(CliError::single_not_taken("compensate")),
    }
    Ok(())
}

fn lint_cmd(log: &Path, fmt: &StaticFlags) -> Result<(), CliError> {
    let lint = qfa_calibrate::lint::lint(log, &fmt.flags());
    println!("lint {}:", log.display());
    for f in &lint.findings {
        println!("{f}");
    }
    let count = |s: Severity| lint.findings.iter().filter(|f| f.severity == s).count();
    println!(
        "{} error(s), {} warning(s), {} note(s), {} ok",
        count(Severity::Error),
        count(Severity::Warning),
        count(Severity::Note),
        count(Severity::Ok)
    );
    if lint.worst() == Severity::Error {
        Err(CliError::Failed(format!("{}: the lab refuses this log (see the errors above)", log.display())))
    } else {
        Ok(())
    }
}

fn plan_cmd(scenario: Option<PathBuf>, lab_program: LabProgram, json: Option<PathBuf>) -> Result<(), CliError> {
    let sc = match scenario {
        Some(p) => Scenario::load(&p)?,
        None => Scenario::builtin(),
    };
    let p = qfa_nav::plan::plan(&sc, lab_program)?;
    print!("{}", qfa_nav::plan::text(&p));
    if let Some(j) = json {
        std::fs::write(&j, serde_json::to_string_pretty(&p).map_err(|e| e.to_string())?).map_err(io_at(&j))?;
    }
    if p.shortfalls.is_empty() {
        Ok(())
    } else {
        Err(CliError::Failed(format!("lab program `{}` does not cover the mission", p.lab_program)))
    }
}

fn navigate_cmd(a: NavigateCli) -> Result<(), CliError> {
    let out = a.out.ok_or_else(|| CliError::Usage("navigate: --out DIR is required".to_string()))?;
    let args = qfa_nav::NavigateArgs {
        scenario: a.scenario,
        out,
        discovered_tables: a.discovered_tables.map(|v| [v[0].clone(), v[1].clone(), v[2].clone()]),
        imu_rate_hz: a.imu_rate_hz,
        verbose: true,
        no_plots: a.no_plots,
        runs: a.runs,
        mc_seed: a.seed,
        jobs: a.jobs,
        shard: a.shard,
        no_mc_discovered: a.no_mc_discovered,
        lab_program: a.lab_program,
        rate_limit_override: a.rate_limit_override,
        ..Default::default()
    };
    if a.shard.is_some() {
        // A shard's partial result has no verdict: `navigate merge` judges the whole study.
        let p = qfa_nav::navigate_shard(&args)?;
        eprintln!("wrote {} (`navigate merge` writes the study's report and verdict)", p.display());
        Ok(())
    } else {
        let pb = qfa_lab::demo::spinner("navigation (calibrate, align, fly)", a.runs == 0);
        let r = qfa_nav::navigate(&args);
        pb.finish_and_clear();
        let v = r?.verdict.ok_or_else(|| CliError::Failed("navigate wrote no verdict".into()))?;
        finish(&v, &LimitsChoice::default(), &args.out)
    }
}

fn run(cli: Cli) -> Result<(), CliError> {
    check_out(&cli.cmd)?;
    match cli.cmd {
        Cmd::Simulate(a) => simulate_cmd(a),
        Cmd::Calibrate(a) => calibrate_cmd(a),
        Cmd::Discover { log, start, out, fmt, holdout, json } => discover_cmd(&log, start, &out, &fmt, holdout, json),
        Cmd::Compensate { log, table, out, fmt } => compensate_cmd(&log, &table, &out, &fmt),
        Cmd::TableRs { table, out, name } => table_rs_cmd(&table, &out, &name),
        Cmd::Demo { out, row_s, seed, threads, full_logs, nav_duration_s } => {
            let opts =
                qfa_lab::demo::DemoOptions { out, row_s, seed, threads, progress: true, full_logs, nav_duration_s };
            // Discovery (on unit #1) and navigation run inside the demo.
            qfa_lab::demo::run(&opts, Some(qfa_calibrate::discover::demo_hook), Some(qfa_nav::demo_hook))?;
            Ok(())
        }
        Cmd::Plan { scenario, lab_program, json } => plan_cmd(scenario, lab_program, json),
        Cmd::Lint { log, fmt } => lint_cmd(&log, &fmt),
        Cmd::Navigate(NavigateCli { sub: Some(NavCmd::Merge { dirs, out, no_plots }), .. }) => {
            let out = out.unwrap_or_else(|| dirs[0].clone());
            let (sum, v) = qfa_nav::merge(&dirs, &out, !no_plots)?;
            eprintln!("{}", qfa_nav::mc::table(&sum));
            // A study: no limit applies, so the defaults never change the exit status.
            finish(&v, &LimitsChoice::default(), &out)
        }
        Cmd::Navigate(a) => navigate_cmd(a),
        Cmd::Batch(a) => batch_cmd(a),
        Cmd::SimulateBatch { units, seed, no_bad, truncated, out } => {
            use qfa_sim::population::{draw, write_chamber, write_manifest_run, PopulationSpec};
            let t0 = Instant::now();
            let truth = draw(&PopulationSpec { units, seed, bad: !no_bad, truncated });
            write_chamber(&out, &truth)?;
            write_manifest_run(&out, &truth)?;
            let bad = truth.unit.iter().filter(|u| u.defect.is_some()).count();
            eprintln!(
                "{units} units ({bad} deliberately bad, {truncated} truncated in the manifest run) in {:.1} s → {}: \
                 chamber.tsv (every unit, full run), batch.toml with units/ (one log per unit), truth.toml",
                t0.elapsed().as_secs_f64(),
                out.display()
            );
            Ok(())
        }
    }
}

fn batch_cmd(a: BatchCli) -> Result<(), CliError> {
    use qfa_calibrate::batch::{self, input, unit::UnitOptions, BatchOptions};
    let limits = LimitsChoice::from_arg(match &a.sub {
        Some(BatchCmd::Merge { limits, .. }) => limits.as_deref(),
        None => a.limits.as_deref(),
    })
    .map_err(|e| CliError::Usage(e.to_string()))?;
    limits.check_applies("static", &STATIC_KEYS).map_err(|e| CliError::Usage(e.to_string()))?;
    let cal = static_cal::StaticCalOptions { holdout: a.holdout, ..Default::default() };
    let unit = UnitOptions { cal, limits: limits.clone(), plots: a.plots };
    let fail_status = |fleet: &batch::fleet::Fleet| -> Result<(), CliError> {
        // As `calibrate`: the default limits are reported but change no exit status; a unit
        // that could not be calibrated always does.
        let [_, _, fail] = fleet.counts;
        let uncalibrated = fleet.unit.iter().filter(|u| !u.calibrated).count();
        if (fail > 0 && limits.file.is_some()) || uncalibrated > 0 {
            return Err(CliError::UnitsFailed(if limits.file.is_some() { fail } else { uncalibrated }));
        }
        Ok(())
    };
    if let Some(BatchCmd::Merge { out, .. }) = &a.sub {
        let (_, fleet) = batch::merge(out, &unit).map_err(|e| CliError::Failed(e.to_string()))?;
        print!("{}", batch::console(&fleet, out));
        return fail_status(&fleet);
    }
    let out = a.out.clone().ok_or_else(|| CliError::Usage("batch needs --out DIR".into()))?;
    let flags = a.fmt.flags();
    let units = match (&a.log, &a.manifest) {
        (Some(log), None) => {
            let bytes = std::fs::read(log).map_err(io_at(log))?;
            input::from_chamber_log(log, &bytes, &flags)
        }
        (None, Some(m)) => input::from_manifest(m, &flags),
        _ => return Err(CliError::Usage("batch needs --log CHAMBER_LOG or --manifest batch.toml".into())),
    }
    .map_err(|e| CliError::Usage(e.to_string()))?;
    eprintln!("{} units; calibrating into {}", units.len(), out.display());
    let t0 = Instant::now();
    let opts = BatchOptions { unit, threads: a.threads, shard: a.shard, progress: true };
    let run = batch::run(&units, &out, &opts).map_err(|e| CliError::Failed(e.to_string()))?;
    let secs = t0.elapsed().as_secs_f64();
    eprintln!("{} units in {secs:.1} s ({:.1} units/min)", run.results.len(), run.results.len() as f64 * 60.0 / secs);
    match &run.fleet {
        Some(fleet) => {
            print!("{}", batch::console(fleet, &out));
            fail_status(fleet)
        }
        None => {
            println!(
                "shard done: {} unit(s) in {}; when every shard is done: qfa-lab batch merge {}",
                run.results.len(),
                out.display(),
                out.display()
            );
            Ok(())
        }
    }
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            // The lab guide's exit statuses: 2 a usage error, as clap's own; 3 a limit failed.
            match e {
                CliError::LimitFailed(_) | CliError::UnitsFailed(_) => ExitCode::from(EXIT_LIMIT_FAILED),
                CliError::Usage(_) => ExitCode::from(2),
                _ => ExitCode::FAILURE,
            }
        }
    }
}
