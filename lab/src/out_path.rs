//! `--out` checked before any work: a calibration that runs for minutes must not find
//! out at the end that it cannot write its files.

use std::fmt;
use std::path::{Path, PathBuf};

/// Why an `--out` path cannot be used.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum OutError {
    /// A directory is wanted and a file of that name exists.
    FileWhereDirectory {
        /// The `--out` path.
        out: PathBuf,
        /// The command, for the message.
        command: &'static str,
    },
    /// A directory is wanted and one of its ancestors is a file.
    AncestorIsFile {
        /// The `--out` path.
        out: PathBuf,
        /// The ancestor that is a file.
        file: PathBuf,
    },
    /// A file is wanted and a directory of that name exists.
    DirectoryWhereFile {
        /// The `--out` path.
        out: PathBuf,
        /// The command, for the message.
        command: &'static str,
    },
    /// A file is wanted in a directory that does not exist.
    NoDirectory {
        /// The `--out` path.
        out: PathBuf,
        /// Its directory.
        dir: PathBuf,
    },
}

impl fmt::Display for OutError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::FileWhereDirectory { out, command } => write!(
                f,
                "--out {}: a file of that name exists; {command} writes a directory of files there: pass a new or \
                 existing directory",
                out.display()
            ),
            Self::AncestorIsFile { out, file } => {
                write!(f, "--out {}: {} is a file, so the directory cannot be created", out.display(), file.display())
            }
            Self::DirectoryWhereFile { out, command } => {
                write!(f, "--out {}: a directory; {command} writes one CSV file: pass a file name", out.display())
            }
            Self::NoDirectory { out, dir } => {
                write!(f, "--out {}: the directory {} does not exist", out.display(), dir.display())
            }
        }
    }
}

impl std::error::Error for OutError {}

/// `out` can be a directory of outputs: it is one, or it can be created (no file in the
/// way, at `out` or above it).
///
/// # Errors
/// A file at `out` or at one of its ancestors.
pub fn check_dir(out: &Path, command: &'static str) -> Result<(), OutError> {
    if out.exists() {
        return if out.is_dir() {
            Ok(())
        } else {
            Err(OutError::FileWhereDirectory { out: out.to_path_buf(), command })
        };
    }
    match out.ancestors().skip(1).find(|a| a.exists()) {
        Some(a) if !a.is_dir() => Err(OutError::AncestorIsFile { out: out.to_path_buf(), file: a.to_path_buf() }),
        _ => Ok(()),
    }
}

/// `out` can be written as one file: not a directory, in a directory that exists (an
/// existing file is replaced, as any output is).
///
/// # Errors
/// `out` is a directory, or its directory does not exist.
pub fn check_file(out: &Path, command: &'static str) -> Result<(), OutError> {
    if out.is_dir() {
        return Err(OutError::DirectoryWhereFile { out: out.to_path_buf(), command });
    }
    match out.parent() {
        Some(dir) if !dir.as_os_str().is_empty() && !dir.is_dir() => {
            Err(OutError::NoDirectory { out: out.to_path_buf(), dir: dir.to_path_buf() })
        }
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn files_and_directories_in_the_way_are_named() {
        let d = std::env::temp_dir().join(format!("qfa-out-path-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let f = d.join("f");
        std::fs::write(&f, "").unwrap();
        assert_eq!(check_dir(&d, "calibrate"), Ok(()));
        assert_eq!(check_dir(&d.join("new/deeper"), "calibrate"), Ok(()));
        assert!(matches!(check_dir(&f, "calibrate"), Err(OutError::FileWhereDirectory { .. })));
        assert_eq!(
            check_dir(&f.join("x"), "calibrate"),
            Err(OutError::AncestorIsFile { out: f.join("x"), file: f.clone() })
        );
        assert_eq!(check_file(&f, "compensate"), Ok(()));
        assert_eq!(check_file(Path::new("relative.csv"), "compensate"), Ok(()));
        assert!(matches!(check_file(&d, "compensate"), Err(OutError::DirectoryWhereFile { .. })));
        assert_eq!(
            check_file(&d.join("no/x.csv"), "compensate"),
            Err(OutError::NoDirectory { out: d.join("no/x.csv"), dir: d.join("no") })
        );
        let _ = std::fs::remove_dir_all(&d);
    }
}
