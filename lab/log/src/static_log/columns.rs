//! A static log's columns and units: the common names each role is found by, the time and
//! acceleration units, and the `--columns` map.

use std::str::FromStr;

use serde::Serialize;

use crate::static_log::{StaticError, G0_MPS2};
use crate::units::{ReaderOption, UnitParseError};

/// Common column names, lower case, per role. A header column matches a role when its
/// lower-cased name equals one of these or ends with `.`/`_` + one of them.
pub const COMMON_NAMES: [(&str, &[&str]); 5] = [
    (
        "time",
        &[
            "time_s",
            "time_ms",
            "time_us",
            "time_ns",
            "timestamp_s",
            "timestamp_ms",
            "timestamp_us",
            "timestamp_ns",
            "timestamp",
            "time",
            "t",
        ],
    ),
    (
        "temp",
        &[
            "temp_c",
            "temperature",
            "temp",
            "temperature_c",
            "imu_temp",
            "temp_f",
            "temperature_f",
            "temp_k",
            "temperature_k",
            "temp_degc",
            "temp_degf",
        ],
    ),
    (
        "ax",
        &["ax", "ax_g", "ax_mg", "ax_mps2", "acc.x", "accel.x", "acc_x", "accel_x", "acc_x_g", "acc_x_mps2", "accx"],
    ),
    (
        "ay",
        &["ay", "ay_g", "ay_mg", "ay_mps2", "acc.y", "accel.y", "acc_y", "accel_y", "acc_y_g", "acc_y_mps2", "accy"],
    ),
    (
        "az",
        &["az", "az_g", "az_mg", "az_mps2", "acc.z", "accel.z", "acc_z", "accel_z", "acc_z_g", "acc_z_mps2", "accz"],
    ),
];

/// Unit of the time column.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum TimeUnit {
    /// Seconds.
    S,
    /// Milliseconds.
    Ms,
    /// Microseconds.
    Us,
    /// Nanoseconds.
    Ns,
}

impl TimeUnit {
    /// Seconds per unit.
    #[must_use]
    pub(crate) fn seconds(self) -> f64 {
        match self {
            Self::S => 1.0,
            Self::Ms => 1e-3,
            Self::Us => 1e-6,
            Self::Ns => 1e-9,
        }
    }

    pub(crate) fn from_suffix(col: &str) -> Option<Self> {
        let c = col.to_ascii_lowercase();
        [("_s", Self::S), ("_ms", Self::Ms), ("_us", Self::Us), ("_ns", Self::Ns)]
            .into_iter()
            .find(|(s, _)| c.ends_with(s))
            .map(|(_, u)| u)
    }
}

impl TimeUnit {
    /// Every unit, coarse to fine.
    pub(crate) const ALL: [TimeUnit; 4] = [TimeUnit::S, TimeUnit::Ms, TimeUnit::Us, TimeUnit::Ns];

    /// The name `--time-unit` takes.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::S => "s",
            Self::Ms => "ms",
            Self::Us => "us",
            Self::Ns => "ns",
        }
    }
}

impl FromStr for TimeUnit {
    type Err = UnitParseError;
    fn from_str(s: &str) -> Result<Self, UnitParseError> {
        match s {
            "s" => Ok(Self::S),
            "ms" => Ok(Self::Ms),
            "us" | "µs" => Ok(Self::Us),
            "ns" => Ok(Self::Ns),
            _ => Err(UnitParseError { option: ReaderOption::TimeUnit, value: s.to_string() }),
        }
    }
}

/// Unit of the acceleration columns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum AccelUnit {
    /// Standard gravity.
    G,
    /// Milli-g.
    Mg,
    /// m/s² (divided by [`G0_MPS2`]).
    Mps2,
}

impl AccelUnit {
    /// Every unit.
    pub(crate) const ALL: [AccelUnit; 3] = [AccelUnit::G, AccelUnit::Mg, AccelUnit::Mps2];

    /// The name `--accel-unit` takes.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::G => "g",
            Self::Mg => "mg",
            Self::Mps2 => "m/s2",
        }
    }

    /// g per unit.
    #[must_use]
    pub(crate) fn g(self) -> f64 {
        match self {
            Self::G => 1.0,
            Self::Mg => 1e-3,
            Self::Mps2 => 1.0 / G0_MPS2,
        }
    }

    pub(crate) fn from_suffix(col: &str) -> Option<Self> {
        let c = col.to_ascii_lowercase();
        [("_mps2", Self::Mps2), ("_mg", Self::Mg), ("_g", Self::G)]
            .into_iter()
            .find(|(s, _)| c.ends_with(s))
            .map(|(_, u)| u)
    }
}

impl FromStr for AccelUnit {
    type Err = UnitParseError;
    fn from_str(s: &str) -> Result<Self, UnitParseError> {
        match s {
            "g" => Ok(Self::G),
            "mg" => Ok(Self::Mg),
            "m/s2" | "m/s^2" | "mps2" => Ok(Self::Mps2),
            _ => Err(UnitParseError { option: ReaderOption::AccelUnit, value: s.to_string() }),
        }
    }
}

/// Explicit column choices (`--columns time=...,temp=...,ax=...`); unset roles are found by
/// common names, but for the acceleration axes when the map names one of them (it names the
/// axes then).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ColumnMap {
    /// `(role, column)`; roles are `time`, `temp`, `ax`, `ay`, `az`.
    pub roles: Vec<(String, String)>,
}

/// As the option is written: `time=timestamp,temp=imu.temperature`.
impl std::fmt::Display for ColumnMap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let parts: Vec<String> = self.roles.iter().map(|(role, col)| format!("{role}={col}")).collect();
        f.write_str(&parts.join(","))
    }
}

impl FromStr for ColumnMap {
    type Err = StaticError;
    fn from_str(s: &str) -> Result<Self, StaticError> {
        let mut roles = Vec::new();
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let Some((role, col)) = part.split_once('=') else {
                return Err(StaticError::BadColumnSpec(part.to_string()));
            };
            let role = role.trim();
            if !COMMON_NAMES.iter().any(|(r, _)| *r == role) {
                return Err(StaticError::BadColumnSpec(part.to_string()));
            }
            roles.push((role.to_string(), col.trim().to_string()));
        }
        Ok(Self { roles })
    }
}
