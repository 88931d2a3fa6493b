//! The single-channel log, `time_s,temp_c,value` (columns in any order, names in any
//! case): discovery's format for any one channel against temperature, a bias or a drift in
//! the user's own unit. Read with the `csv` crate like the other logs, every malformed row
//! reported with its line as an editor shows it (CRLF included).

use std::fmt;
use std::io::Read;
use std::num::ParseFloatError;

use crate::lines::LineCounter;

/// The columns a single-channel log must have.
pub(crate) const COLUMNS: [&str; 3] = ["time_s", "temp_c", "value"];

/// Fewest rows a single-channel log is read with.
pub(crate) const MIN_ROWS: usize = 8;

/// A single-channel log: one row per reading; rows whose `temp_c` is empty (no reading
/// yet) are left out.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SingleLog {
    /// Time, s.
    pub time_s: Vec<f64>,
    /// DS18B20 reading, °C.
    pub temp_c: Vec<f32>,
    /// The channel, in the user's unit.
    pub value: Vec<f64>,
}

/// Why a single-channel log was not read.
///
/// `{}` prints this error's own message; `{:#}` adds its cause (a field's parse error).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum SingleError {
    /// The file is not readable text.
    Csv(crate::io_fault::CsvFault),
    /// The header lacks a column.
    MissingColumn(&'static str),
    /// Malformed rows: the first [`SingleError::KEPT`] with their lines, and the count.
    Rows {
        /// Each row's line and why, in line order.
        errors: Vec<(u64, SingleError)>,
        /// How many rows were malformed in all.
        total: usize,
    },
    /// Fewer than [`MIN_ROWS`] rows with a reading.
    TooFewRows(usize),
    /// A field that is not a finite number: one of the rows [`SingleError::Rows`] lists.
    Field {
        /// Its column.
        column: &'static str,
        /// Why its text is not a number; `None`: a number, but not finite.
        parse: Option<ParseFloatError>,
    },
}

impl SingleError {
    /// Malformed rows listed in detail (all are counted).
    pub(crate) const KEPT: usize = 20;
}

impl fmt::Display for SingleError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Csv(e) => write!(f, "{e}")?,
            Self::MissingColumn(c) => write!(f, "single-channel log without a `{c}` column")?,
            Self::Rows { errors, total } => {
                write!(f, "{total} malformed row(s):")?;
                for (line, e) in errors {
                    write!(f, "\nline {line}: {e:#}")?;
                }
            }
            Self::TooFewRows(n) => write!(f, "too few rows: {n} with a reading, {MIN_ROWS} needed")?,
            Self::Field { column, parse: Some(_) } => f.write_str(column)?,
            Self::Field { column, parse: None } => write!(f, "{column}: not finite")?,
        }
        if let Some(cause) = std::error::Error::source(self).filter(|_| f.alternate()) {
            write!(f, ": {cause}")?;
        }
        Ok(())
    }
}

impl std::error::Error for SingleError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Field { parse: Some(e), .. } => Some(e),
            _ => None,
        }
    }
}

/// The field `text` of `column` as a finite number.
fn number(text: &str, column: &'static str) -> Result<f64, SingleError> {
    let v: f64 = text.parse().map_err(|e| SingleError::Field { column, parse: Some(e) })?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(SingleError::Field { column, parse: None })
    }
}

/// Read a single-channel log.
///
/// # Errors
/// [`SingleError`]: unreadable text, a missing column, malformed rows (each with its
/// line), too few rows.
pub(crate) fn read_single_from<R: Read>(mut reader: R) -> Result<SingleLog, SingleError> {
    let mut text = Vec::new();
    reader.read_to_end(&mut text).map_err(|e| SingleError::Csv(crate::io_fault::CsvFault::Io(e.kind())))?;
    let mut rdr =
        csv::ReaderBuilder::new().has_headers(false).flexible(true).trim(csv::Trim::All).from_reader(&text[..]);
    let mut lines = LineCounter::new(&text);
    let mut rec = csv::StringRecord::new();
    let next = |rdr: &mut csv::Reader<&[u8]>, rec: &mut csv::StringRecord| -> Result<bool, SingleError> {
        rdr.read_record(rec).map_err(|e| SingleError::Csv(crate::io_fault::CsvFault::of(&e)))
    };
    // The header: the first record (the csv crate skips blank lines).
    if !next(&mut rdr, &mut rec)? {
        return Err(SingleError::MissingColumn(COLUMNS[0]));
    }
    let col = |name: &'static str| {
        rec.iter().position(|h| h.eq_ignore_ascii_case(name)).ok_or(SingleError::MissingColumn(name))
    };
    let (ti, tc, vi) = (col(COLUMNS[0])?, col(COLUMNS[1])?, col(COLUMNS[2])?);
    let mut log = SingleLog::default();
    let (mut errors, mut total) = (Vec::new(), 0usize);
    while next(&mut rdr, &mut rec)? {
        let line = rec.position().map_or(0, |p| lines.line_of(p.byte()));
        let get = |i: usize| rec.get(i).unwrap_or("");
        let row = || -> Result<Option<(f64, f32, f64)>, SingleError> {
            let t = number(get(ti), COLUMNS[0])?;
            if get(tc).is_empty() {
                return Ok(None); // no reading yet
            }
            let temp = number(get(tc), COLUMNS[1])? as f32;
            Ok(Some((t, temp, number(get(vi), COLUMNS[2])?)))
        };
        match row() {
            Ok(Some((t, temp, v))) => {
                log.time_s.push(t);
                log.temp_c.push(temp);
                log.value.push(v);
            }
            Ok(None) => {}
            Err(e) => {
                total += 1;
                if errors.len() < SingleError::KEPT {
                    errors.push((line, e));
                }
            }
        }
    }
    if total > 0 {
        return Err(SingleError::Rows { errors, total });
    }
    if log.time_s.len() < MIN_ROWS {
        return Err(SingleError::TooFewRows(log.time_s.len()));
    }
    Ok(log)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows(n: usize) -> String {
        (0..n).map(|i| format!("{},{}.5,{}\n", i * 10, 20 + i, i)).collect()
    }

    #[test]
    fn columns_in_any_order_and_case_and_empty_readings_left_out() {
        let text = format!(
            "VALUE, Temp_C ,time_s\n7,,0\n{}",
            rows(9)
                .lines()
                .map(|l| {
                    let f: Vec<&str> = l.split(',').collect();
                    format!("{},{},{}\n", f[2], f[1], f[0])
                })
                .collect::<String>()
        );
        let log = read_single_from(text.as_bytes()).unwrap();
        assert_eq!(log.time_s.len(), 9);
        assert_eq!((log.time_s[1], log.temp_c[1], log.value[1]), (10.0, 21.5, 1.0));
    }

    #[test]
    fn malformed_rows_get_their_editor_lines_on_crlf_too() {
        for end in ["\n", "\r\n"] {
            let text = format!("time_s,temp_c,value\n{}x,20,1\n\n5,20,NaN\n", rows(9)).replace('\n', end);
            let e = read_single_from(text.as_bytes()).unwrap_err();
            assert_eq!(
                e.to_string(),
                "2 malformed row(s):\nline 11: time_s: invalid float literal\nline 13: value: not finite",
                "{end:?}"
            );
        }
    }

    #[test]
    fn too_few_rows_and_missing_columns_are_named() {
        let e = read_single_from(format!("time_s,temp_c,value\n{}", rows(3)).as_bytes()).unwrap_err();
        assert_eq!(e, SingleError::TooFewRows(3));
        let e = read_single_from("time_s,temp_c,val\n1,2,3\n".as_bytes()).unwrap_err();
        assert_eq!(e.to_string(), "single-channel log without a `value` column");
    }

    #[test]
    fn a_bad_field_is_typed_with_its_column_and_parse_error() {
        let e = number("x", "time_s").unwrap_err();
        assert!(matches!(&e, SingleError::Field { column: "time_s", parse: Some(_) }), "{e:?}");
        assert_eq!(format!("{e:#}"), "time_s: invalid float literal");
        assert!(std::error::Error::source(&e).is_some());
        let e = number("inf", "value").unwrap_err();
        assert!(matches!(&e, SingleError::Field { column: "value", parse: None }), "{e:?}");
        assert_eq!(format!("{e:#}"), "value: not finite");
    }
}
