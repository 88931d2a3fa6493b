//! Why a limits file was refused ([`LimitsError`]).

use std::fmt;
use std::path::PathBuf;

/// Why a limits file was refused.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum LimitsError {
    /// The file cannot be read.
    Read {
        /// The file.
        file: PathBuf,
        /// What the system said, as its kind (`io::Error` is neither `Clone` nor `PartialEq`).
        kind: std::io::ErrorKind,
        /// The OS error code, when the system gave one (printed as the system words it).
        os_code: Option<i32>,
    },
    /// It is not TOML of the documented keys (unknown keys are refused: a typo would
    /// otherwise leave a default in force).
    Parse {
        /// The file, when the text came from one.
        file: Option<PathBuf>,
        /// The `toml` crate's error, with its line and column.
        error: toml::de::Error,
    },
    /// A value outside what the key's unit allows (both sides checked: a limit in the
    /// wrong unit is refused, not quietly made loose or tight).
    OutOfRange {
        /// The key.
        key: &'static str,
        /// Its value.
        value: f64,
        /// The smallest value taken.
        lo: f64,
        /// The largest value taken.
        hi: f64,
        /// The key's unit.
        unit: &'static str,
        /// What the value probably meant.
        hint: &'static str,
    },
    /// The file sets none of the keys this kind of log is checked against.
    NoneApply {
        /// The file.
        file: String,
        /// The kind of log (`static`, `cycling`).
        kind: &'static str,
        /// The keys it sets.
        set: Vec<String>,
        /// The keys this kind of log is checked against.
        checked: Vec<&'static str>,
    },
}

impl fmt::Display for LimitsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Read { file, os_code: Some(code), .. } => {
                write!(f, "{}: {}", file.display(), std::io::Error::from_raw_os_error(*code))
            }
            Self::Read { file, kind, os_code: None } => write!(f, "{}: {kind}", file.display()),
            Self::Parse { file: Some(file), error } => write!(f, "{}: {error}", file.display()),
            Self::Parse { file: None, error } => write!(f, "{error}"),
            Self::OutOfRange { key, value, lo, hi, unit, hint } => {
                // The unit hint explains a value too large; one at or below zero is no unit mistake.
                let why = if *value > 0.0 { *hint } else { "a limit is a positive number" };
                write!(f, "limits: {key} = {value} {unit} is outside {lo}..={hi} {unit}: {why}")
            }
            Self::NoneApply { file, kind, set, checked } => write!(
                f,
                "limits: {file} sets {}, none of the keys a {kind} log is checked against ({}): its verdict would be \
                 the defaults' under your file's name; add the keys for this kind of log",
                if set.is_empty() { "no key".to_string() } else { set.join(", ") },
                checked.join(", ")
            ),
        }
    }
}

impl std::error::Error for LimitsError {}
