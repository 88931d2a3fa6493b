//! The command line's arguments (clap) and their value parsers.

use super::*;

#[derive(Parser)]
#[command(name = "qfa-lab", version, about = "Thermal-test simulator, calibration and compensation for QFA tables")]
pub(crate) struct Cli {
    #[command(subcommand)]
    pub(crate) cmd: Cmd,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum ProfileKind {
    /// The paper's Steps 1–6: four rates × four positions.
    Paper,
    /// A flight-like profile (§3.2), four positions.
    Flight,
}

/// How to read a static multi-axis log (CSV/TSV with a header); any flag, or a header
/// without a `pulses` column, selects the static-log path (`qfa_log::open`).
#[derive(clap::Args, Clone, Default)]
pub(crate) struct StaticFlags {
    /// Column choices, e.g. `time=timestamp,temp=imu.temperature,ax=imu.acc.x,ay=imu.acc.y,az=imu.acc.z`.
    #[arg(long, value_parser = str::parse::<ColumnMap>)]
    pub(crate) columns: Option<ColumnMap>,
    /// Unit of the time column: s, ms, us or ns.
    #[arg(long, value_parser = str::parse::<TimeUnit>)]
    pub(crate) time_unit: Option<TimeUnit>,
    /// Unit of the acceleration columns: g, mg or m/s2.
    #[arg(long, value_parser = str::parse::<AccelUnit>)]
    pub(crate) accel_unit: Option<AccelUnit>,
    /// Unit of the temperature column: C, F or K (default: from the column name, else C).
    #[arg(long, value_parser = str::parse::<TempUnit>)]
    pub(crate) temp_unit: Option<TempUnit>,
    /// Numbers use a decimal comma (`20,5`); the file must be `;`- or tab-separated.
    #[arg(long)]
    pub(crate) decimal_comma: bool,
}

impl StaticFlags {
    pub(crate) fn flags(&self) -> ReadFlags {
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
pub(crate) enum Cmd {
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
    /// one-unit logs), or with --qfa of QFA units (a manifest of cycling logs), with each
    /// unit's truth.
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
        /// Good units whose own log (manifest run) is truncated: heating only, or the first
        /// half (with --qfa, every run of the unit's cycling log cut alike).
        #[arg(long, default_value_t = 0)]
        truncated: usize,
        /// Each static unit's die lags its case (the sensor) by its own time constant,
        /// 0–240 s: its output shows an apparent heating/cooling split that its own split
        /// is not.
        #[arg(long, conflicts_with = "qfa")]
        die_lags: bool,
        /// QFA units through the paper's four-position cycling test (pulse counts), drawn
        /// around JB-KT8 #1: chamber.csv (every unit), batch.toml with units/SN….csv,
        /// truth.toml.
        #[arg(long)]
        qfa: bool,
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
pub(crate) struct SimulateArgs {
    /// Output log, e.g. log.csv; the truth goes to log.truth.toml.
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Unit preset: kt8-1, kt8-2 or kt8-3.
    #[arg(long, default_value = "kt8-1")]
    pub(crate) unit: String,
    /// A truth TOML instead of a preset.
    #[arg(long)]
    pub(crate) truth: Option<PathBuf>,
    /// Extension effects to switch on (sensor_lag, bias_branch_hysteresis, bias_creep).
    #[arg(long, value_delimiter = ',')]
    pub(crate) effects: Vec<String>,
    /// Built-in profile.
    #[arg(long, value_enum, default_value = "paper")]
    pub(crate) profile: ProfileKind,
    /// Chamber-air profile file (`time_s,temp_c`) instead of the built-in one.
    #[arg(long)]
    pub(crate) profile_file: Option<PathBuf>,
    /// Only these paper rates, °C/min (default all four).
    #[arg(long, value_delimiter = ',')]
    pub(crate) rates: Vec<f64>,
    /// Row length, s (integer).
    #[arg(long, default_value_t = 1)]
    pub(crate) row_s: u32,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// Simulation threads.
    #[arg(long, default_value_t = 2)]
    pub(crate) threads: usize,
    /// No noise (accelerometer and DS18B20).
    #[arg(long)]
    pub(crate) noiseless: bool,
}

/// `qfa-lab calibrate`'s arguments.
#[derive(clap::Args)]
pub(crate) struct CalibrateArgs {
    /// Cycling log.
    #[arg(long)]
    pub(crate) log: PathBuf,
    /// Output directory.
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Programs to fit on (default: first and last; the rest are held out).
    #[arg(long, value_delimiter = ',')]
    pub(crate) fit_programs: Vec<String>,
    /// Skip the plots.
    #[arg(long)]
    pub(crate) no_plots: bool,
    /// Cycling log: the IMU axis this accelerometer is, for the PX4 / ArduPilot
    /// parameter files (a one-axis export: needs --export-range).
    #[arg(long, default_value = "x", value_parser = ["x", "y", "z"])]
    pub(crate) axis: String,
    /// PX4 TC_A0_ID: the device ID of the accelerometer (CAL_ACC0_ID, or device_id in
    /// `listener sensor_accel`); without it no px4_tc.params is written.
    #[arg(long, value_name = "ID", value_parser = parse_device_id)]
    pub(crate) px4_device_id: Option<i32>,
    /// TMIN,TMAX (°C) for the fields the axes share (PX4 TC_A0_TREF/TMIN/TMAX, ArduPilot
    /// INS_TCAL1_TMIN/TMAX), the same for every axis exported; needed for a one-axis
    /// export, inside the training temperatures.
    #[arg(long, value_name = "TMIN,TMAX", allow_hyphen_values = true, value_parser = parse_range)]
    pub(crate) export_range: Option<(f64, f64)>,
    /// Static logs: the held-out scheme, auto | after-max | blocks:K | none (the lab guide's "Static logs").
    #[arg(long, default_value = "auto")]
    pub(crate) holdout: Holdout,
    /// Static logs: the part's sensitivity at the range it was logged at, LSB per g (4096
    /// for ±8 g at 16 bits), recorded in table.bin so that a firmware stating another
    /// `Config::sample_lsb_per_g` refuses the table.
    #[arg(long, value_name = "LSB", value_parser = parse_lsb_per_g)]
    pub(crate) lsb_per_g: Option<f32>,
    /// Pass/fail limits (TOML; the lab guide's "Limits" lists the keys and defaults): a
    /// unit that fails one exits with status 3 after writing every file.
    #[arg(long, value_name = "FILE")]
    pub(crate) limits: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) fmt: StaticFlags,
}

/// `qfa-lab batch`'s arguments.
#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub(crate) struct BatchCli {
    #[command(subcommand)]
    pub(crate) sub: Option<BatchCmd>,
    /// One chamber log holding every unit: `time`, then SERIAL.temp, SERIAL.ax, SERIAL.ay,
    /// SERIAL.az per unit; or a multi-unit cycling log: program, run, time_s, input_g,
    /// interval_s, then SERIAL.temp_c and SERIAL.pulses per unit.
    #[arg(long, conflicts_with = "manifest")]
    pub(crate) log: Option<PathBuf>,
    /// A manifest naming one log per serial (`batch.toml`; the lab guide's "Production batches").
    #[arg(long)]
    pub(crate) manifest: Option<PathBuf>,
    /// Output directory: one folder per serial, and the fleet page.
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
    /// Pass/fail limits (TOML, as `calibrate --limits`).
    #[arg(long)]
    pub(crate) limits: Option<PathBuf>,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    pub(crate) threads: usize,
    /// Run only shard K of N (0 ≤ K < N: units i with i mod N = K), all shards writing into
    /// the same --out; then `qfa-lab batch merge OUT`.
    #[arg(long, value_parser = str::parse::<qfa_batch::Shard>)]
    pub(crate) shard: Option<qfa_batch::Shard>,
    /// Draw each unit's bias plot (off: a batch's pages are its certificates and the fleet).
    #[arg(long)]
    pub(crate) plots: bool,
    /// The held-out scheme, as `calibrate --holdout`.
    #[arg(long, default_value = "auto")]
    pub(crate) holdout: Holdout,
    #[command(flatten)]
    pub(crate) fmt: StaticFlags,
}

#[derive(Subcommand)]
pub(crate) enum BatchCmd {
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
pub(crate) struct NavigateCli {
    #[command(subcommand)]
    pub(crate) sub: Option<NavCmd>,
    /// Scenario TOML (default: the built-in §3.2 flight).
    #[arg(long)]
    pub(crate) scenario: Option<PathBuf>,
    /// Output directory.
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
    /// Discovered tables for x,y,z (three files, .bin or .toml).
    #[arg(long, value_delimiter = ',', num_args = 3)]
    pub(crate) discovered_tables: Option<Vec<PathBuf>>,
    /// IMU rate override, Hz.
    #[arg(long)]
    pub(crate) imu_rate_hz: Option<f64>,
    /// Monte Carlo runs (0: the nominal run only).
    #[arg(long, default_value_t = 0)]
    pub(crate) runs: u64,
    /// Monte Carlo base seed (default: the scenario's seed).
    #[arg(long)]
    pub(crate) seed: Option<u64>,
    /// Worker threads for the Monte Carlo runs (0: all cores).
    #[arg(long, default_value_t = 0)]
    pub(crate) jobs: usize,
    /// Run only shard K of N (0 ≤ K < N: runs i with i mod N = K) and write
    /// DIR/mc_partial_K_of_N.json; shard 0 also flies the nominal run.
    #[arg(long, value_parser = parse_shard)]
    pub(crate) shard: Option<(u64, u64)>,
    /// Skip the plots.
    #[arg(long)]
    pub(crate) no_plots: bool,
    /// Leave `discovered` out of the Monte Carlo runs (skips discovery per run, about
    /// half the cost).
    #[arg(long)]
    pub(crate) no_mc_discovered: bool,
    /// Lab program the units are calibrated on: `covering` (paper 0.3/0.9 + 1 and
    /// 2 °C/min ramps, covers the built-in flight) or `paper` (the four staircases).
    #[arg(long, default_value = "covering")]
    pub(crate) lab_program: LabProgram,
    /// Experiment only: every table's rate limit, °C/min, in place of the fitted one
    /// (the tables then extrapolate above the fitted rates, unflagged).
    #[arg(long)]
    pub(crate) rate_limit_override: Option<f32>,
}

#[derive(Subcommand)]
pub(crate) enum NavCmd {
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

pub(crate) fn parse_shard(s: &str) -> Result<(u64, u64), String> {
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
pub(crate) fn parse_lsb_per_g(s: &str) -> Result<f32, String> {
    let v: f32 =
        s.trim().parse().map_err(|e| format!("{e}: expected the part's LSB per g, e.g. 4096 (±8 g, 16 bits)"))?;
    let (lo, hi) = qfa_thermal::table::limits::GAMMA;
    if !(v.is_finite() && (lo..=hi).contains(&v)) {
        return Err(format!("{v} is no part's LSB per g: 1 to 1e9, e.g. 4096 (±8 g, 16 bits)"));
    }
    Ok(v)
}

pub(crate) fn parse_device_id(s: &str) -> Result<i32, String> {
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

pub(crate) fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s.split_once(',').ok_or_else(|| format!("`{s}`: expected TMIN,TMAX in °C"))?;
    let lo: f64 = a.trim().parse().map_err(|e| format!("`{s}`: TMIN: {e}"))?;
    let hi: f64 = b.trim().parse().map_err(|e| format!("`{s}`: TMAX: {e}"))?;
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return Err(format!("`{s}`: need finite TMIN < TMAX"));
    }
    Ok((lo, hi))
}
