//! Opening a log file: the one place the lab decides what kind of log a file is, from the
//! reader flags and the header line, and reads it with that kind's one reader. The CLI,
//! discovery and the Python package all open logs here.
//!
//! The rule, in order: a file that starts with the PX4 ULog magic or an ArduPilot
//! DataFlash `FMT` record is that autopilot's log (`ulog`, `dataflash`); any static-reader
//! flag means a static log; an empty first line is
//! left to the cycling reader (whose message names the header it expects); a header with
//! a `pulses` or `program` column is a cycling log, one with a `value` column a
//! single-channel log; any other header is a static multi-axis log.

use std::fmt;
use std::path::{Path, PathBuf};

use crate::autopilot::{AutopilotLog, Stack};
use crate::cycling::{read_log_from, Log, LogError};
use crate::dataflash::{read_dataflash, DataflashError};
use crate::single::{read_single_from, SingleError, SingleLog};
use crate::spelling::Spelling;
use crate::static_log::columns::{AccelUnit, ColumnMap, TimeUnit};
use crate::static_log::{read_static_from, StaticError, StaticLog, StaticOptions};
use crate::ulog::{read_ulog, UlogError};
use crate::units::TempUnit;

/// The kinds of log the lab reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LogFormat {
    /// Four-position cycling log (`program,run,time_s,input_g,temp_c,pulses,interval_s`).
    Cycling,
    /// Static multi-axis log: a board at one orientation, any logger's columns.
    Static,
    /// Single-channel log (`time_s,temp_c,value`), for discovery.
    Single,
    /// An autopilot's own log (PX4 ULog, ArduPilot DataFlash).
    Autopilot(Stack),
}

impl fmt::Display for LogFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Cycling => "cycling log",
            Self::Static => "static multi-axis log",
            Self::Single => "single-channel log (time_s,temp_c,value)",
            Self::Autopilot(Stack::Px4) => "PX4 ULog",
            Self::Autopilot(Stack::ArduPilot) => "ArduPilot DataFlash log",
        })
    }
}

/// The static reader's flags (`--columns`, `--time-unit`, `--accel-unit`, `--temp-unit`,
/// `--decimal-comma`); any of them selects the static reader.
#[derive(Clone, Debug, Default)]
pub struct ReadFlags {
    /// Column choices.
    pub columns: Option<ColumnMap>,
    /// Unit of the time column.
    pub time_unit: Option<TimeUnit>,
    /// Unit of the acceleration columns.
    pub accel_unit: Option<AccelUnit>,
    /// Unit of the temperature column.
    pub temp_unit: Option<TempUnit>,
    /// Numbers use a decimal comma.
    pub decimal_comma: bool,
}

impl ReadFlags {
    /// Whether any flag was given.
    #[must_use]
    pub fn any(&self) -> bool {
        self.columns.is_some()
            || self.time_unit.is_some()
            || self.accel_unit.is_some()
            || self.temp_unit.is_some()
            || self.decimal_comma
    }

    /// The static reader's options.
    #[must_use]
    pub fn static_options(&self) -> StaticOptions {
        StaticOptions {
            columns: self.columns.clone().unwrap_or_default(),
            time_unit: self.time_unit,
            accel_unit: self.accel_unit,
            temp_unit: self.temp_unit,
            decimal_comma: self.decimal_comma,
        }
    }
}

/// A log as its reader returned it.
#[derive(Clone, Debug)]
pub enum OpenedLog {
    /// A cycling log.
    Cycling(Log),
    /// A static multi-axis log.
    Static(Box<StaticLog>),
    /// A single-channel log.
    Single(SingleLog),
    /// A PX4 ULog or an ArduPilot DataFlash log.
    Autopilot(Box<AutopilotLog>),
}

impl OpenedLog {
    /// Its format.
    #[cfg(test)]
    #[must_use]
    pub(crate) fn format(&self) -> LogFormat {
        match self {
            Self::Cycling(_) => LogFormat::Cycling,
            Self::Static(_) => LogFormat::Static,
            Self::Single(_) => LogFormat::Single,
            Self::Autopilot(l) => LogFormat::Autopilot(l.stack),
        }
    }
}

/// Why a log was not opened: the file, and why it could not be read or what its reader
/// refused.
#[derive(Debug)]
pub enum OpenError {
    /// The file cannot be read.
    Io {
        /// The file.
        path: PathBuf,
        /// The system's message.
        error: std::io::Error,
    },
    /// Its reader refused it.
    Read {
        /// The file.
        path: PathBuf,
        /// The reader's own error.
        error: ReadError,
    },
}

impl OpenError {
    /// The message, with every reader option spelled for `sp`.
    #[must_use]
    pub fn message(&self, sp: Spelling) -> String {
        match self {
            Self::Io { path, error } => format!("{}: {error}", path.display()),
            Self::Read { path, error } => format!("{}: {}", path.display(), error.message(sp)),
        }
    }
}

impl fmt::Display for OpenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message(Spelling::Cli))
    }
}

impl std::error::Error for OpenError {}

/// The format of a log whose first line is `header`, read with `flags`.
#[must_use]
pub(crate) fn format_of_header(header: &str, flags: &ReadFlags) -> LogFormat {
    if flags.any() {
        return LogFormat::Static;
    }
    let names: Vec<String> = header.split([',', '\t', ';']).map(|c| c.trim().to_ascii_lowercase()).collect();
    let has = |n: &str| names.iter().any(|c| c == n);
    if header.trim().is_empty() || has("pulses") || has("program") {
        LogFormat::Cycling
    } else if has("value") {
        LogFormat::Single
    } else {
        LogFormat::Static
    }
}

/// The first line that is not blank (lossily as text).
fn first_line(bytes: &[u8]) -> std::borrow::Cow<'_, str> {
    let first = bytes.split(|b| *b == b'\n').find(|l| !l.iter().all(u8::is_ascii_whitespace));
    String::from_utf8_lossy(first.unwrap_or_default())
}

/// The format of a log that starts with `head` (its first few kilobytes are enough: the
/// magic bytes and the first line), read with `flags`: the one decision [`open_bytes`]
/// takes, for a caller that must know a log's kind before reading it.
#[must_use]
pub fn format_of_bytes(head: &[u8], flags: &ReadFlags) -> LogFormat {
    if head.starts_with(&crate::ulog::MAGIC) {
        LogFormat::Autopilot(Stack::Px4)
    } else if head.starts_with(&crate::dataflash::MAGIC) {
        LogFormat::Autopilot(Stack::ArduPilot)
    } else {
        format_of_header(&first_line(head), flags)
    }
}

/// Whether `header` is a cycling log's: it names both `program` and `pulses`.
fn is_cycling_header(header: &str) -> bool {
    let names: Vec<String> = header.split([',', '\t', ';']).map(|c| c.trim().to_ascii_lowercase()).collect();
    ["program", "pulses"].iter().all(|n| names.iter().any(|c| c == n))
}

/// Open the log at `path`: its format from `format_of_header`, read by that format's
/// reader.
///
/// # Errors
/// [`OpenError`]: the file, and the reader's own error.
pub fn open(path: &Path, flags: &ReadFlags) -> Result<OpenedLog, OpenError> {
    let bytes = std::fs::read(path).map_err(|error| OpenError::Io { path: path.to_path_buf(), error })?;
    open_bytes(&bytes, flags).map_err(|error| OpenError::Read { path: path.to_path_buf(), error })
}

/// Why a reader refused a log: each reader's own typed error.
#[derive(Debug)]
pub enum ReadError {
    /// The cycling reader's error.
    Cycling(LogError),
    /// The static reader's error (boxed: it is the largest).
    Static(Box<StaticError>),
    /// The single-channel reader's error.
    Single(SingleError),
    /// The ULog reader's error.
    Ulog(UlogError),
    /// The DataFlash reader's error.
    Dataflash(DataflashError),
    /// The static reader's options given for a log whose header is a cycling log's (it
    /// has `program` and `pulses`): its columns and units are fixed, so an option meant for
    /// a static log would read it as one and fail on a column it does not have.
    OptionsOnCyclingLog,
}

impl ReadError {
    /// The message, with every reader option spelled for `sp` (only the static reader
    /// takes options).
    #[must_use]
    pub fn message(&self, sp: Spelling) -> String {
        match self {
            Self::Cycling(e) => e.to_string(),
            Self::Static(e) => e.message(sp),
            Self::Single(e) => e.to_string(),
            Self::Ulog(e) => e.to_string(),
            Self::Dataflash(e) => e.to_string(),
            Self::OptionsOnCyclingLog => "this is a cycling log (its header has program and pulses: time_s in s, \
                 input_g in g, temp_c in °C), and the static reader's options (columns, time, accel and temp units, \
                 decimal comma) do not apply to it: give none"
                .to_string(),
        }
    }
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message(Spelling::Cli))
    }
}

impl std::error::Error for ReadError {}

/// Read a log from its bytes, as [`open`] reads a file.
///
/// # Errors
/// [`ReadError`]: the reader's own error.
pub fn open_bytes(bytes: &[u8], flags: &ReadFlags) -> Result<OpenedLog, ReadError> {
    let header = first_line(bytes);
    Ok(match format_of_bytes(bytes, flags) {
        LogFormat::Autopilot(Stack::Px4) => OpenedLog::Autopilot(Box::new(read_ulog(bytes).map_err(ReadError::Ulog)?)),
        LogFormat::Autopilot(Stack::ArduPilot) => {
            OpenedLog::Autopilot(Box::new(read_dataflash(bytes).map_err(ReadError::Dataflash)?))
        }
        LogFormat::Cycling => OpenedLog::Cycling(read_log_from(bytes).map_err(ReadError::Cycling)?),
        LogFormat::Static if flags.any() && is_cycling_header(&header) => return Err(ReadError::OptionsOnCyclingLog),
        LogFormat::Static => OpenedLog::Static(Box::new(
            read_static_from(bytes, &flags.static_options()).map_err(|e| ReadError::Static(Box::new(e)))?,
        )),
        LogFormat::Single => OpenedLog::Single(read_single_from(bytes).map_err(ReadError::Single)?),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_header_decides_and_any_flag_means_static() {
        let none = ReadFlags::default();
        let cases = [
            ("program,run,time_s,input_g,temp_c,pulses,interval_s", LogFormat::Cycling),
            ("program,run,time,input_g,temp_c", LogFormat::Cycling),
            ("", LogFormat::Cycling),
            ("time_s,temp_c,value", LogFormat::Single),
            ("Time_S;Temp_C;Value", LogFormat::Single),
            ("timestamp,imu.temperature,imu.acc.x", LogFormat::Static),
            ("time\ttemp\taz", LogFormat::Static),
        ];
        for (h, want) in cases {
            assert_eq!(format_of_header(h, &none), want, "{h:?}");
        }
        let flags = ReadFlags { decimal_comma: true, ..ReadFlags::default() };
        assert_eq!(format_of_header("program,run,time_s,input_g,temp_c,pulses,interval_s", &flags), LogFormat::Static);
    }

    #[test]
    fn each_format_reaches_its_reader() {
        let none = ReadFlags::default();
        let single: String =
            std::iter::once("time_s,temp_c,value\n".to_string()).chain((0..9).map(|i| format!("{i},20,1\n"))).collect();
        assert_eq!(open_bytes(single.as_bytes(), &none).unwrap().format(), LogFormat::Single);
        let e = open_bytes(b"program,run,time_s,input_g,temp_c,pulses,interval_s\np,a,1,1,NaN,1,1\n", &none);
        assert!(matches!(e, Err(ReadError::Cycling(_))), "{e:?}");
        let e = open_bytes(b"time,temp,az\n", &none).unwrap_err();
        assert!(matches!(e, ReadError::Static(_)), "{e:?}");
        // A static reader's option on a cycling log: refused as that, not as a static log
        // without axes.
        let unit = ReadFlags { time_unit: Some(crate::static_log::columns::TimeUnit::S), ..ReadFlags::default() };
        let e = open_bytes(b"program,run,time_s,input_g,temp_c,pulses,interval_s\np,a,1,1,20,1,1\n", &unit);
        assert!(matches!(e, Err(ReadError::OptionsOnCyclingLog)), "{e:?}");
    }
}
