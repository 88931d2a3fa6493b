//! The compensation variants flown in lock-step: their names in report order, the tables
//! each is built from, and the oracle that carries the tables' misalignment.

use std::fmt;
use std::path::{Path, PathBuf};

use qfa_thermal::table::Table;

use super::accel::{AccelCompensation, AccelError, OracleCompensation, TableCompensation};
use super::run::Variant;
use super::*;

/// Variant names in report order.
pub const VARIANTS: [&str; 5] = ["none", "simple", "hysteresis", "discovered", "oracle"];

/// Why a variant's table could not be read, or its compensation not built.
#[derive(Debug)]
#[non_exhaustive]
pub enum VariantsError {
    /// A table file that could not be read.
    Read {
        /// The table file.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// A TOML table file that is not UTF-8.
    Utf8 {
        /// The table file.
        path: PathBuf,
        /// Where the text stops being UTF-8.
        source: std::string::FromUtf8Error,
    },
    /// A TOML table file that is not a table.
    Parse {
        /// The table file.
        path: PathBuf,
        /// The TOML parser's error.
        source: toml::de::Error,
    },
    /// A TOML table that does not validate.
    Invalid {
        /// The table file.
        path: PathBuf,
        /// The validation's error.
        source: qfa_thermal::table::Error,
    },
    /// A postcard table file that does not decode (or validate).
    Decode {
        /// The table file.
        path: PathBuf,
        /// The decoder's error.
        source: qfa_thermal::table::Error,
    },
    /// A variant's compensation could not be built from its tables.
    Compensation(AccelError),
}

impl fmt::Display for VariantsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Read { path, .. } => write!(f, "reading {}", path.display()),
            Self::Parse { path, .. } => write!(f, "parsing {}", path.display()),
            Self::Utf8 { path, .. } | Self::Invalid { path, .. } | Self::Decode { path, .. } => {
                write!(f, "{}", path.display())
            }
            Self::Compensation(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for VariantsError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Read { source, .. } => Some(source),
            Self::Utf8 { source, .. } => Some(source),
            Self::Parse { source, .. } => Some(source),
            Self::Invalid { source, .. } | Self::Decode { source, .. } => Some(source),
            // Printed as it is (above): its cause comes next.
            Self::Compensation(e) => e.source(),
        }
    }
}

impl From<AccelError> for VariantsError {
    fn from(e: AccelError) -> Self {
        Self::Compensation(e)
    }
}

/// Read a table for the discovered variant: root-crate postcard (`.bin`) or TOML.
///
/// # Errors
/// I/O, decode or validation errors.
pub fn read_table(path: &Path) -> Result<Table, VariantsError> {
    let bytes = std::fs::read(path).map_err(|e| VariantsError::Read { path: path.into(), source: e })?;
    if path.extension().is_some_and(|e| e == "toml") {
        let text = String::from_utf8(bytes).map_err(|e| VariantsError::Utf8 { path: path.into(), source: e })?;
        let t: Table = toml::from_str(&text).map_err(|e| VariantsError::Parse { path: path.into(), source: e })?;
        t.validate().map_err(|e| VariantsError::Invalid { path: path.into(), source: e })?;
        Ok(t)
    } else {
        Table::decode(&bytes).map_err(|e| VariantsError::Decode { path: path.into(), source: e })
    }
}

/// Build the five variants in [`VARIANTS`] order. `discovered` holds one 1-axis table per
/// axis; `None` uses the hysteresis tables.
///
/// # Errors
/// A table the compensator refuses.
pub fn variants(t: &Tables, discovered: Option<[Table; 3]>, imu_rate_hz: f64) -> Result<Vec<Variant>, VariantsError> {
    let u = &t.units;
    let m = t.misalignment;
    let tc = |f: &dyn Fn(&calib::UnitTables) -> &Table| -> Result<Box<dyn AccelCompensation>, AccelError> {
        Ok(Box::new(TableCompensation::with_misalignment([f(&u[0]), f(&u[1]), f(&u[2])], m, imu_rate_hz)?))
    };
    let disc: Box<dyn AccelCompensation> = match &discovered {
        Some(d) => Box::new(TableCompensation::with_misalignment([&d[0], &d[1], &d[2]], m, imu_rate_hz)?),
        None => tc(&|x| &x.hysteresis)?,
    };
    Ok(vec![
        Variant { name: "none".into(), comp: tc(&|x| &x.none)? },
        Variant { name: "simple".into(), comp: tc(&|x| &x.simple)? },
        Variant { name: "hysteresis".into(), comp: tc(&|x| &x.hysteresis)? },
        Variant { name: "discovered".into(), comp: disc },
        Variant { name: "oracle".into(), comp: Box::new(oracle_of(t)) },
    ])
}

/// The oracle carrying the same misalignment as the tables (in f64).
fn oracle_of(t: &Tables) -> OracleCompensation {
    let m = t.misalignment.map(|m| nalgebra::Matrix3::from_fn(|r, c| f64::from(m[r * 3 + c])));
    OracleCompensation::carrying(m)
}

/// The variants flown in the Monte Carlo runs: `none`, `simple`, `hysteresis`,
/// `discovered` (each unit's own discovery run on its calibration log, when the tables
/// were calibrated with discovery; otherwise it is the hysteresis table and is left out)
/// and `oracle`.
///
/// # Errors
/// A table the compensator refuses.
pub fn mc_variants(t: &Tables, imu_rate_hz: f64) -> Result<Vec<Variant>, VariantsError> {
    let u = &t.units;
    let m = t.misalignment;
    let tc = |f: &dyn Fn(&calib::UnitTables) -> &Table| -> Result<Box<dyn AccelCompensation>, AccelError> {
        Ok(Box::new(TableCompensation::with_misalignment([f(&u[0]), f(&u[1]), f(&u[2])], m, imu_rate_hz)?))
    };
    let mut v = vec![
        Variant { name: "none".into(), comp: tc(&|x| &x.none)? },
        Variant { name: "simple".into(), comp: tc(&|x| &x.simple)? },
        Variant { name: "hysteresis".into(), comp: tc(&|x| &x.hysteresis)? },
    ];
    if u.iter().all(|x| x.discovered_effects.iter().all(|e| e != "not run")) {
        v.push(Variant { name: "discovered".into(), comp: tc(&|x| &x.discovered)? });
    }
    v.push(Variant { name: "oracle".into(), comp: Box::new(oracle_of(t)) });
    Ok(v)
}
