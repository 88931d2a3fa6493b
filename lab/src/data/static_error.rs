//! Why a static log, or one of its rows, cannot be used: the static reader's typed errors,
//! each message naming the column, the line or the figure at fault.

use std::fmt;

use super::static_log::{Skipped, Slew, TimeUnit, MAX_SLEW_C_PER_MIN, MIN_ROWS};

/// A row-level error of a static log.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum StaticRowFault {
    /// A field is not a number (names the column and the text).
    NotANumber {
        /// Column.
        column: String,
        /// Text.
        text: String,
    },
    /// Temperature outside −60…130 °C.
    TempOutOfRange(f64),
    /// Time earlier than the previous row's.
    TimeBackwards {
        /// Previous row's time, file units.
        previous: f64,
        /// This row's time, file units.
        time: f64,
    },
    /// Wrong number of fields.
    FieldCount {
        /// Fields found.
        got: usize,
        /// Header fields.
        want: usize,
    },
}

impl fmt::Display for StaticRowFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotANumber { column, text } => write!(f, "column `{column}`: `{text}` is not a number"),
            Self::TempOutOfRange(t) => write!(f, "temperature {t} °C outside -60..130 °C"),
            Self::TimeBackwards { previous, time } => write!(f, "time goes backwards ({time} after {previous})"),
            Self::FieldCount { got, want } => write!(f, "{got} fields, the header has {want}"),
        }
    }
}

/// Why a static log cannot be used.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum StaticError {
    /// The file could not be read.
    Io(String),
    /// No header line (an empty file).
    Empty,
    /// A header but no data rows.
    NoRows,
    /// `--columns` names a column the header lacks.
    UnknownColumn {
        /// Role.
        role: String,
        /// Column asked for.
        column: String,
        /// The header's columns.
        header: Vec<String>,
    },
    /// No column for a role, by common name or `--columns`.
    MissingColumn {
        /// Role (`time`, `temp`, or `ax/ay/az`).
        role: String,
        /// The header's columns.
        header: Vec<String>,
    },
    /// A `--columns` item that is not `role=column` with a known role.
    BadColumnSpec(String),
    /// A unit flag value that is not one of the allowed ones.
    BadUnit {
        /// Flag.
        flag: &'static str,
        /// Value given.
        value: String,
        /// Allowed values.
        allowed: &'static str,
    },
    /// No unit given and none in the column name.
    UnitUnknown {
        /// Flag to pass.
        flag: &'static str,
        /// Column.
        column: String,
    },
    /// The data are implausible in the units given.
    ImplausibleUnit(String),
    /// The temperature changes faster than a chamber can move it in the time unit given.
    ImplausibleSlew {
        /// The time unit the log was read with.
        unit: TimeUnit,
        /// The change, °C/min ([`crate::data::static_checks::max_slew`]).
        slew: Slew,
        /// Line and temperature (as filtered) where the change starts and ends.
        ends: [(u64, f64); 2],
        /// Other time units that give a plausible row interval and slew, with their slew.
        fits: Vec<(TimeUnit, f64)>,
    },
    /// Numbers with a decimal comma, read without [`crate::data::static_log::StaticOptions::decimal_comma`].
    DecimalComma {
        /// Line of the first such field.
        line: u64,
        /// Its column.
        column: String,
        /// Its text.
        text: String,
        /// Rows with such a field.
        rows: usize,
    },
    /// [`crate::data::static_log::StaticOptions::decimal_comma`] with a comma-separated header.
    DecimalCommaDelimiter,
    /// Malformed rows: the first [`crate::data::static_log::KEPT_LINES`] with line numbers, and the count.
    Rows {
        /// `(line, fault)`.
        first: Vec<(u64, StaticRowFault)>,
        /// All malformed rows.
        total: usize,
    },
    /// Too few rows left after the skips.
    TooFewRows {
        /// Rows kept.
        kept: usize,
        /// What was skipped.
        skipped: Skipped,
    },
}

impl fmt::Display for StaticError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Io(e) => write!(f, "cannot read the log: {e}"),
            Self::Empty => f.write_str("empty log: no header line"),
            Self::NoRows => f.write_str("the log has a header but no data rows"),
            Self::UnknownColumn { role, column, header } => {
                write!(f, "unknown column `{column}` for {role}; the header has: {}", header.join(", "))
            }
            Self::MissingColumn { role, header } => write!(
                f,
                "no {role} column found by common names; pass --columns {role}=NAME (the header has: {})",
                header.join(", ")
            ),
            Self::BadColumnSpec(s) => {
                write!(f, "bad --columns item `{s}`: expected role=column with role time, temp, ax, ay or az")
            }
            Self::BadUnit { flag, value, allowed } => write!(f, "{flag} `{value}`: expected {allowed}"),
            Self::UnitUnknown { flag, column } => {
                write!(f, "the unit of column `{column}` is not known: pass {flag}")
            }
            Self::ImplausibleUnit(s) => write!(f, "wrong unit? {s}"),
            Self::ImplausibleSlew { unit, slew, ends, fits } => {
                write!(
                    f,
                    "wrong unit? read with --time-unit {} the temperature changes by {:.0} °C/min ({:.2} °C within \
                     {:.3} s: from {:.2} °C at line {} to {:.2} °C at line {}); a board in a climate chamber changes \
                     by at most {MAX_SLEW_C_PER_MIN:.0} °C/min: check --time-unit",
                    unit.name(),
                    slew.c_per_min,
                    slew.range_c,
                    slew.window_s,
                    ends[0].1,
                    ends[0].0,
                    ends[1].1,
                    ends[1].0
                )?;
                if !fits.is_empty() {
                    let f2: Vec<String> =
                        fits.iter().map(|(u, x)| format!("{} gives {x:.1} °C/min", u.name())).collect();
                    write!(f, " ({})", f2.join(", "))?;
                }
                Ok(())
            }
            Self::DecimalComma { line, column, text, rows } => write!(
                f,
                "column `{column}` holds `{text}` at line {line}: a decimal comma? {rows} row(s) have numbers like it; \
                 pass --decimal-comma to read them"
            ),
            Self::DecimalCommaDelimiter => f.write_str(
                "--decimal-comma needs a `;` or tab delimiter: this header is comma-separated, so a decimal comma \
                 cannot be told from a field separator",
            ),
            Self::Rows { first, total } => {
                write!(f, "{total} malformed row(s)")?;
                for (line, fault) in first {
                    write!(f, "\n  line {line}: {fault}")?;
                }
                if *total > first.len() {
                    write!(f, "\n  ... and {} more", total - first.len())?;
                }
                Ok(())
            }
            Self::TooFewRows { kept, skipped } => {
                write!(f, "only {kept} usable row(s), need {MIN_ROWS}: {skipped}")
            }
        }
    }
}

impl std::error::Error for StaticError {}
