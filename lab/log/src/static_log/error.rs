//! Why a static log, or one of its rows, cannot be used: the static reader's typed errors,
//! each message naming the column, the line or the figure at fault.

use std::fmt;

use crate::spelling::Spelling;
use crate::static_log::{Skipped, MIN_ROWS};
use crate::units::{ReaderOption, UnitMismatch, UnitParseError};

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
    /// The text could not be read as CSV.
    Csv {
        /// The line, when the parser got that far.
        line: Option<u64>,
        /// What the parser said.
        fault: crate::io_fault::CsvFault,
    },
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
    /// A unit option's value that is none of its units.
    BadUnit(UnitParseError),
    /// No unit given and none in the column name.
    UnitUnknown {
        /// The option to pass.
        option: ReaderOption,
        /// Column.
        column: String,
    },
    /// The data contradict the unit they were read in (the one style of every unit
    /// mistake: the figure, what it must be, and the unit that fits).
    Unit(Box<UnitMismatch>),
    /// Numbers with a decimal comma, read without [`crate::static_log::StaticOptions::decimal_comma`].
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
    /// [`crate::static_log::StaticOptions::decimal_comma`] with a comma-separated header.
    DecimalCommaDelimiter,
    /// Malformed rows: the first `crate::static_log::KEPT_LINES` with line numbers, and the count.
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

impl StaticError {
    /// The message, with every reader option spelled for `sp` (`--accel-unit` for the
    /// CLI, `accel_unit=` for Python).
    #[must_use]
    pub fn message(&self, sp: Spelling) -> String {
        match self {
            Self::Csv { line: Some(line), fault } => format!("cannot read the log: line {line}: {fault}"),
            Self::Csv { line: None, fault } => format!("cannot read the log: {fault}"),
            Self::Empty => "empty log: no header line".to_string(),
            Self::NoRows => "the log has a header but no data rows".to_string(),
            Self::UnknownColumn { role, column, header } => {
                format!("unknown column `{column}` for {role}; the header has: {}", header.join(", "))
            }
            Self::MissingColumn { role, header } => format!(
                "no {role} column found by common names; pass {} (the header has: {})",
                ReaderOption::Columns.with(sp, &format!("{role}=NAME")),
                header.join(", ")
            ),
            Self::BadColumnSpec(s) => format!(
                "bad {} item `{s}`: expected role=column with role time, temp, ax, ay or az",
                ReaderOption::Columns.name(sp)
            ),
            Self::BadUnit(e) => e.message(sp),
            Self::UnitUnknown { option, column } => {
                format!("the unit of column `{column}` is not known: pass {}", option.with(sp, option.allowed()))
            }
            Self::Unit(m) => m.message(sp),
            Self::DecimalComma { line, column, text, rows } => format!(
                "column `{column}` holds `{text}` at line {line}: a decimal comma? {rows} row(s) have numbers like it; \
                 pass {} to read them",
                ReaderOption::DecimalComma.with(sp, "")
            ),
            Self::DecimalCommaDelimiter => format!(
                "{} needs a `;` or tab delimiter: this header is comma-separated, so a decimal comma cannot be told \
                 from a field separator",
                ReaderOption::DecimalComma.with(sp, "")
            ),
            Self::Rows { first, total } => {
                let mut s = format!("{total} malformed row(s)");
                for (line, fault) in first {
                    s.push_str(&format!("\n  line {line}: {fault}"));
                }
                if *total > first.len() {
                    s.push_str(&format!("\n  ... and {} more", total - first.len()));
                }
                s
            }
            Self::TooFewRows { kept, skipped } => format!("only {kept} usable row(s), need {MIN_ROWS}: {skipped}"),
        }
    }
}

impl fmt::Display for StaticError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message(Spelling::Cli))
    }
}

impl std::error::Error for StaticError {}
