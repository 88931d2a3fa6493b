//! An I/O failure ([`IoFault`]) and a CSV parser's failure ([`CsvFault`]) as values, so the
//! lab's error enums hold them typed and stay `Clone` and `PartialEq` (`std::io::Error`
//! and `csv::Error` are neither).

use std::fmt;
use std::io;
use std::path::{Path, PathBuf};

/// Remove an earlier run's output at `path`, if there is one, so what a folder holds is
/// this run's (a file that is not there is no error). The one rule for every stale output
/// the lab clears: a batch unit's folder, its fleet plots, the export files, discovery's
/// tables.
///
/// # Errors
/// The file is there and cannot be removed.
pub fn remove_if_present(path: &Path) -> io::Result<()> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != io::ErrorKind::NotFound => Err(e),
        _ => Ok(()),
    }
}

/// A file or folder the lab could not read or write, and what the system said: its error
/// kind, and the OS error code when there was one (then it prints as `std::io::Error`
/// prints that code, e.g. `No such file or directory (os error 2)`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IoFault {
    /// The file or folder.
    pub path: PathBuf,
    /// The error's kind.
    pub kind: io::ErrorKind,
    /// The OS error code, when the system gave one.
    pub os_code: Option<i32>,
}

impl IoFault {
    /// `error`, met on `path`.
    #[must_use]
    pub fn new(path: &Path, error: &io::Error) -> Self {
        Self { path: path.to_path_buf(), kind: error.kind(), os_code: error.raw_os_error() }
    }

    /// A closure for `map_err` that records `path`.
    pub fn at(path: &Path) -> impl Fn(io::Error) -> Self + '_ {
        move |e| Self::new(path, &e)
    }
}

impl fmt::Display for IoFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.os_code {
            Some(code) => write!(f, "{}: {}", self.path.display(), io::Error::from_raw_os_error(code)),
            None => write!(f, "{}: {}", self.path.display(), self.kind),
        }
    }
}

impl std::error::Error for IoFault {}

/// Why the `csv` crate refused a record, as a value.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum CsvFault {
    /// Reading the bytes failed.
    Io(io::ErrorKind),
    /// A field is not UTF-8 text (field index from 0).
    NotUtf8 {
        /// The field.
        field: usize,
    },
    /// A record with another number of fields than the first.
    FieldCount {
        /// Fields of the first record.
        expected: u64,
        /// Fields of this one.
        found: u64,
    },
    /// Any other refusal of the parser.
    Other,
}

impl CsvFault {
    /// The fault of a `csv` error.
    #[must_use]
    pub fn of(e: &csv::Error) -> Self {
        match e.kind() {
            csv::ErrorKind::Io(e) => Self::Io(e.kind()),
            csv::ErrorKind::Utf8 { err, .. } => Self::NotUtf8 { field: err.field() },
            csv::ErrorKind::UnequalLengths { expected_len, len, .. } => {
                Self::FieldCount { expected: *expected_len, found: *len }
            }
            _ => Self::Other,
        }
    }
}

impl fmt::Display for CsvFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Io(kind) => write!(f, "cannot read the text: {kind}"),
            Self::NotUtf8 { field } => write!(f, "field {} is not UTF-8 text", field + 1),
            Self::FieldCount { expected, found } => write!(f, "{found} fields where the first record has {expected}"),
            Self::Other => f.write_str("not CSV the parser can read"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_os_error_prints_as_the_system_said_it() {
        let path = Path::new("/nonexistent-qfa-dir/x.csv");
        let e = std::fs::read(path).expect_err("the folder does not exist");
        let fault = IoFault::new(path, &e);
        assert_eq!(fault.to_string(), format!("{}: {e}", path.display()));
        assert_eq!(fault.kind, io::ErrorKind::NotFound);
        let custom = io::Error::new(io::ErrorKind::InvalidData, "bad");
        assert_eq!(IoFault::new(path, &custom).to_string(), format!("{}: invalid data", path.display()));
    }

    #[test]
    fn a_field_that_is_not_text_is_named() {
        let mut rdr = csv::ReaderBuilder::new().has_headers(false).from_reader(&b"a,b\nc,\xff\n"[..]);
        let mut rec = csv::StringRecord::new();
        assert!(rdr.read_record(&mut rec).expect("the first record is text"));
        let e = rdr.read_record(&mut rec).expect_err("the second is not");
        assert_eq!(CsvFault::of(&e), CsvFault::NotUtf8 { field: 1 });
        assert_eq!(CsvFault::of(&e).to_string(), "field 2 is not UTF-8 text");
    }
}
