//! Why an output file could not be written ([`OutputError`]): the file or folder, and the
//! error it came from, typed, so callers decide by matching, never by reading the text.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use qfa_log::IoFault;
use qfa_report::plot_png::PlotError;

/// An output that could not be written. The sources that are neither `Clone` nor
/// `PartialEq` are shared (`Arc`); two errors are equal when the same file failed the
/// same way (the same variant and path, and an equal source where the source compares).
#[derive(Clone, Debug)]
#[non_exhaustive]
pub enum OutputError {
    /// A file or folder: the system's error.
    Io(IoFault),
    /// A report that did not serialize as JSON.
    Json {
        /// The file.
        path: PathBuf,
        /// The writer's error.
        source: Arc<serde_json::Error>,
    },
    /// A table the core refused to encode.
    Table {
        /// The folder the table was for.
        path: PathBuf,
        /// The encoder's error.
        source: qfa_thermal::table::Error,
    },
    /// A table that did not serialize as TOML.
    Toml {
        /// The folder the table was for.
        path: PathBuf,
        /// The writer's error.
        source: toml::ser::Error,
    },
    /// A plot that could not be drawn or encoded (writing it is [`OutputError::Io`]).
    Plot {
        /// The image file it was for.
        path: PathBuf,
        /// The drawing's or the encoder's error.
        source: Arc<PlotError>,
    },
}

impl OutputError {
    /// For `map_err`: an I/O error met on `path`.
    pub fn io(path: &Path) -> impl Fn(std::io::Error) -> Self + '_ {
        move |e| Self::Io(IoFault::new(path, &e))
    }

    /// For `map_err`: a JSON error writing `path`.
    pub fn json(path: &Path) -> impl Fn(serde_json::Error) -> Self + '_ {
        move |e| Self::Json { path: path.to_path_buf(), source: Arc::new(e) }
    }

    /// For `map_err`: a table refused for `path`.
    pub fn table(path: &Path) -> impl Fn(qfa_thermal::table::Error) -> Self + '_ {
        move |source| Self::Table { path: path.to_path_buf(), source }
    }

    /// For `map_err`: a TOML error writing `path`.
    pub fn toml(path: &Path) -> impl Fn(toml::ser::Error) -> Self + '_ {
        move |source| Self::Toml { path: path.to_path_buf(), source }
    }

    /// For `map_err`: a plot of `path` that failed.
    pub fn plot(path: &Path) -> impl Fn(PlotError) -> Self + '_ {
        move |e| Self::Plot { path: path.to_path_buf(), source: Arc::new(e) }
    }

    /// The file or folder.
    #[must_use]
    pub fn path(&self) -> &Path {
        match self {
            Self::Io(e) => &e.path,
            Self::Json { path, .. } | Self::Table { path, .. } | Self::Toml { path, .. } | Self::Plot { path, .. } => {
                path
            }
        }
    }
}

impl PartialEq for OutputError {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Self::Io(a), Self::Io(b)) => a == b,
            (Self::Table { path: p, source: a }, Self::Table { path: q, source: b }) => p == q && a == b,
            (Self::Toml { path: p, source: a }, Self::Toml { path: q, source: b }) => p == q && a == b,
            (Self::Json { path: p, source: a }, Self::Json { path: q, source: b }) => {
                p == q && a.classify() == b.classify()
            }
            (Self::Plot { path: p, .. }, Self::Plot { path: q, .. }) => p == q,
            _ => false,
        }
    }
}

impl fmt::Display for OutputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Io(e) => write!(f, "{e}"),
            Self::Json { path, source } => write!(f, "{}: {source}", path.display()),
            Self::Table { path, source } => write!(f, "{}: {source}", path.display()),
            Self::Toml { path, source } => write!(f, "{}: {source}", path.display()),
            Self::Plot { path, source } => write!(f, "{}: {source}", path.display()),
        }
    }
}

impl std::error::Error for OutputError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Io(e) => Some(e),
            Self::Json { source, .. } => Some(source.as_ref()),
            Self::Table { .. } => None,
            Self::Toml { source, .. } => Some(source),
            Self::Plot { source, .. } => Some(source.as_ref()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_that_cannot_be_made_is_an_io_error_naming_it() {
        let file = std::env::temp_dir().join(format!("qfa-output-error-{}", std::process::id()));
        std::fs::write(&file, b"a file, not a folder").expect("a temporary file");
        let inside = file.join("out");
        let e = std::fs::create_dir_all(&inside).map_err(OutputError::io(&inside)).expect_err("a file is in the way");
        std::fs::remove_file(&file).expect("removed");
        assert!(matches!(&e, OutputError::Io(f) if f.path == inside), "{e:?}");
        assert_eq!(e.path(), inside);
        assert!(e.to_string().starts_with(&inside.display().to_string()), "{e}");
        assert_eq!(e, e.clone());
    }
}
