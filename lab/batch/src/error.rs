//! Why a batch, or one of its units, could not go on: typed down to the leaves, each
//! variant holding what its message names (a path, a column, a serial) and the error it
//! came from, so a caller decides by matching, never by reading the text.

use std::fmt;
use std::path::PathBuf;

use qfa_calibrate::fit::FitError;
use qfa_calibrate::output_error::OutputError;
use qfa_calibrate::static_cal::StaticCalError;

/// Why a batch (or one of its units) could not go on.
#[derive(Debug)]
#[non_exhaustive]
pub enum BatchError {
    /// The manifest cannot be used.
    Manifest {
        /// The manifest file.
        path: PathBuf,
        /// What is wrong with it.
        fault: ManifestFault,
    },
    /// Neither a chamber log nor a manifest was given, or both were (the Python call).
    NoInput,
    /// The chamber log cannot be split into units.
    Chamber {
        /// The chamber log.
        path: PathBuf,
        /// What is wrong with it.
        fault: ChamberFault,
    },
    /// A serial cannot name a folder, or two units share one.
    Serial(SerialFault),
    /// One unit's calibration failed (the batch goes on).
    Unit(UnitFault),
    /// `--shard` is not `K/N` with 0 ≤ K < N.
    Shard {
        /// What was given.
        given: String,
    },
    /// `batch merge` found no `unit.json` under `out`.
    NothingToMerge {
        /// The folder searched.
        out: PathBuf,
    },
    /// `batch merge` found two units at one place in the batch.
    MergeClash {
        /// The two serials.
        serials: [String; 2],
        /// Their place.
        place: usize,
    },
    /// A file or folder could not be read (a unit's log, the manifest, a shard's folder or
    /// its `unit.json`).
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// A shard's `unit.json` could not be read as JSON.
    Json {
        /// The file.
        path: PathBuf,
        /// The parser's error.
        source: serde_json::Error,
    },
    /// An output could not be written (the file, and the error it came from; the same type
    /// calibration's outputs fail with).
    Output(OutputError),
    /// The worker threads could not be started.
    ThreadPool(rayon::ThreadPoolBuildError),
    /// The limits file sets no key that a kind of unit in the batch checks.
    Limits(qfa_report::verdict::LimitsError),
}

/// What is wrong with a manifest.
#[derive(Debug)]
#[non_exhaustive]
pub enum ManifestFault {
    /// Not TOML, or a key the manifest does not have (a typo is refused, never ignored).
    Toml(toml::de::Error),
    /// A log given as the manifest: its first line is a header of comma- or tab-separated
    /// columns, not TOML.
    IsALog {
        /// How many columns that first line has.
        columns: usize,
    },
    /// No `[[unit]]` entry.
    NoUnits,
    /// A reader setting's value is refused.
    Setting {
        /// The unit it is set for (`None`: the manifest's default).
        serial: Option<String>,
        /// The key (`columns`, `time_unit`, `accel_unit`, `temp_unit`).
        key: &'static str,
        /// The reader's own error.
        source: Box<qfa_log::static_log::StaticError>,
    },
    /// The command line gives a reader option that the manifest's own key (for every unit)
    /// sets otherwise: the key would win and the flag change nothing.
    OverridesFlag {
        /// The option.
        option: qfa_log::units::ReaderOption,
        /// The flag's value.
        flag: String,
        /// The manifest key's value.
        key: String,
    },
    /// A unit's log does not exist.
    NoLog {
        /// The unit.
        serial: String,
        /// Where its log was looked for.
        log: PathBuf,
    },
}

/// What is wrong with a chamber log.
#[derive(Debug)]
#[non_exhaustive]
pub enum ChamberFault {
    /// The CSV reader refused a line.
    Csv(csv::Error),
    /// A `SERIAL.ROLE` column appears twice.
    DuplicateColumn(String),
    /// No `SERIAL.ROLE` column.
    NoUnitColumns,
    /// `--columns time=NAME` names a column the header lacks.
    NoNamedTimeColumn(String),
    /// No column without a serial to read the time from.
    NoTimeColumn,
    /// Several columns without a serial: which is the time is not known.
    SeveralTimeColumns(Vec<String>),
    /// A multi-unit cycling log without one of the cycling log's shared columns.
    CyclingColumns {
        /// The shared columns it lacks.
        missing: Vec<&'static str>,
    },
    /// Static reader options given with a multi-unit cycling log.
    OptionsOnCyclingLog,
    /// A unit of a multi-unit cycling log without `SERIAL.temp_c` or `SERIAL.pulses`.
    CyclingUnit {
        /// The unit.
        serial: String,
        /// The roles it has.
        roles: Vec<&'static str>,
    },
    /// A unit without `SERIAL.temp` or without any axis.
    UnitColumns {
        /// The unit.
        serial: String,
        /// The roles it has.
        roles: Vec<&'static str>,
    },
}

/// A serial that cannot be used.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum SerialFault {
    /// It cannot name a folder.
    NotAFolderName(String),
    /// Two units share it (1-based places).
    Shared {
        /// The serial.
        serial: String,
        /// The units' places in the batch, from 1.
        units: [usize; 2],
    },
}

/// Why one unit was not calibrated.
#[derive(Debug)]
#[non_exhaustive]
pub enum UnitFault {
    /// The log cannot be read.
    Open(Box<qfa_log::open::ReadError>),
    /// The log is neither a static log nor a cycling log.
    NotBatchable,
    /// The limits file sets none of the keys this unit's kind of log is checked against.
    Limits(qfa_report::verdict::LimitsError),
    /// The static calibration refused it.
    Calibration(Box<StaticCalError>),
    /// The cycling calibration refused it.
    Cycling(Box<qfa_calibrate::CalibrateError>),
    /// The cycling calibration wrote no verdict.
    NoVerdict,
    /// The fleet's descriptor of an axis cannot be fitted.
    Descriptor {
        /// The axis.
        axis: String,
        /// The fitter's error.
        source: Box<FitError>,
    },
    /// The ramp split's fit under one die lag cannot be solved.
    RampSplit {
        /// The lag tried, s.
        lag_s: f32,
        /// The fitter's error.
        source: Box<FitError>,
    },
}

impl From<OutputError> for BatchError {
    fn from(e: OutputError) -> Self {
        Self::Output(e)
    }
}

impl fmt::Display for BatchError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Manifest { path, fault } => write!(f, "manifest: {}: {fault}", path.display()),
            Self::NoInput => f.write_str("give log= (a chamber log) or manifest= (batch.toml), one of them"),
            Self::Chamber { path, fault } => write!(f, "chamber log: {}: {fault}", path.display()),
            Self::Serial(s) => write!(f, "serial {s}"),
            Self::Unit(u) => write!(f, "{u}"),
            Self::Shard { given } => write!(f, "--shard `{given}`: give K/N with 0 ≤ K < N (units i with i mod N = K)"),
            Self::NothingToMerge { out } => write!(
                f,
                "merge: no SERIAL/unit.json under {}: run `qfa-lab batch … --shard K/N --out {}` for every K first",
                out.display(),
                out.display()
            ),
            Self::MergeClash { serials, place } => write!(
                f,
                "merge: {} and {} both hold batch place {place}: the folder mixes two batches",
                serials[0], serials[1]
            ),
            Self::Io { path, source } => write!(f, "{}: {source}", path.display()),
            Self::Json { path, source } => write!(f, "{}: {source}", path.display()),
            Self::Output(e) => write!(f, "{e}"),
            Self::ThreadPool(e) => write!(f, "thread pool: {e}"),
            Self::Limits(e) => write!(f, "{e}"),
        }
    }
}

impl fmt::Display for ManifestFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Toml(e) => write!(f, "{e}"),
            Self::IsALog { columns } => write!(
                f,
                "this is a log, not a manifest: its first line is a header of {columns} columns; a chamber log of \
                 every unit goes to --log, a manifest (batch.toml) names one log per [[unit]]"
            ),
            Self::NoUnits => f.write_str("no [[unit]] entries: each unit is a [[unit]] table with `serial` and `log`"),
            Self::Setting { serial: Some(s), key, source } => write!(f, "unit {s}: {key}: {source}"),
            Self::Setting { serial: None, key, source } => write!(f, "{key}: {source}"),
            Self::NoLog { serial, log } => write!(f, "unit {serial}: {}: no such file", log.display()),
            Self::OverridesFlag { option, flag, key } => {
                let name = option.name(qfa_log::spelling::Spelling::Python);
                // TOML: a flag's value is a boolean, the others are text.
                let key = if *option == qfa_log::units::ReaderOption::DecimalComma {
                    key.clone()
                } else {
                    format!("\"{key}\"")
                };
                write!(
                    f,
                    "{} on the command line, and `{name} = {key}` here for every unit: the manifest's keys override \
                     the command line's, so the flag would change nothing; set `{name}` on the [[unit]] entries it is \
                     for (a unit's key overrides the manifest's), or change the manifest's `{name}`",
                    option.with(qfa_log::spelling::Spelling::Cli, flag)
                )
            }
        }
    }
}

impl fmt::Display for ChamberFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Csv(e) => write!(f, "{e}"),
            Self::DuplicateColumn(h) => write!(f, "column `{h}` appears twice"),
            Self::NoUnitColumns => f.write_str(
                "no unit columns: a chamber log names each unit's columns SERIAL.temp, SERIAL.ax, SERIAL.ay, \
                 SERIAL.az, a multi-unit cycling log SERIAL.temp_c and SERIAL.pulses (for one log per unit, use \
                 --manifest)",
            ),
            Self::NoNamedTimeColumn(name) => write!(f, "no column `{name}` (from --columns time=…)"),
            Self::NoTimeColumn => f.write_str("no time column (a column without a serial)"),
            Self::SeveralTimeColumns(cols) => write!(
                f,
                "{} columns without a serial ({}): name the time column with --columns time=NAME",
                cols.len(),
                cols.iter().map(|c| format!("`{c}`")).collect::<Vec<_>>().join(", ")
            ),
            Self::CyclingColumns { missing } => write!(
                f,
                "a multi-unit cycling log (SERIAL.pulses columns) needs the shared columns program, run, time_s, \
                 input_g and interval_s; missing: {}",
                missing.join(", ")
            ),
            Self::OptionsOnCyclingLog => f.write_str(
                "a multi-unit cycling log (SERIAL.pulses columns): its columns and units are fixed, so the static \
                 reader's options (--columns, --time-unit, --accel-unit, --temp-unit, --decimal-comma) do not apply: \
                 give none",
            ),
            Self::CyclingUnit { serial, roles } => write!(
                f,
                "unit {serial} has {}: each unit of a cycling log needs {serial}.temp_c and {serial}.pulses",
                if roles.is_empty() { "neither".to_string() } else { format!("only {serial}.{}", roles.join(", ")) }
            ),
            Self::UnitColumns { serial, roles } => write!(
                f,
                "unit {serial} has columns {}: each unit needs SERIAL.temp and at least one of SERIAL.ax, .ay, .az",
                roles.join(", ")
            ),
        }
    }
}

impl fmt::Display for SerialFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotAFolderName(s) => write!(
                f,
                "`{s}`: a serial names its unit's output folder, so it may hold only letters, digits, `-`, `_` and \
                 `.`, not start with a dot, and be at most 64 characters"
            ),
            Self::Shared { serial, units } => write!(
                f,
                "`{serial}` is given to units {} and {}: every unit needs its own serial (its table is flashed under it)",
                units[0], units[1]
            ),
        }
    }
}

impl UnitFault {
    /// The message, with every option spelled for `sp`; `Display` is the command line's.
    #[must_use]
    pub fn message(&self, sp: qfa_log::spelling::Spelling) -> String {
        match self {
            Self::Open(e) => e.message(sp),
            Self::Calibration(e) => e.message(sp),
            e => e.to_string(),
        }
    }
}

impl BatchError {
    /// The message, with a unit's reader and calibration options spelled for `sp`;
    /// `Display` is the command line's.
    #[must_use]
    pub fn message(&self, sp: qfa_log::spelling::Spelling) -> String {
        match self {
            Self::Unit(u) => u.message(sp),
            e => e.to_string(),
        }
    }
}

impl fmt::Display for UnitFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Open(e) => write!(f, "{e}"),
            Self::NotBatchable => f.write_str(
                "neither a static log (time, temperature and acceleration columns) nor a cycling log (program, run, \
                 time_s, input_g, temp_c, pulses, interval_s): a batch calibrates those two",
            ),
            Self::Limits(e) => write!(f, "{e}"),
            Self::Calibration(e) => write!(f, "{e}"),
            Self::Cycling(e) => write!(f, "{e}"),
            Self::NoVerdict => f.write_str("the cycling calibration wrote no verdict"),
            Self::Descriptor { axis, source } => write!(f, "{axis}: descriptor: {source}"),
            Self::RampSplit { lag_s, source } => write!(f, "ramp split under a {lag_s:.0}-s die lag: {source}"),
        }
    }
}

impl std::error::Error for BatchError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        // Each message already ends with its cause's own text: the chain goes on from the
        // cause's source, so a printer walking it does not repeat a line.
        match self {
            Self::Io { source, .. } => source.source(),
            Self::Json { source, .. } => source.source(),
            Self::Output(e) => std::error::Error::source(e).and_then(std::error::Error::source),
            Self::ThreadPool(e) => e.source(),
            _ => None,
        }
    }
}
