//! Why a discovery run failed ([`DiscoverError`]): a start model not known, a log without
//! channels, a static log its calibration refuses, or an output not written.

use std::fmt;
use std::io;
use std::path::PathBuf;

use qfa_calibrate::static_cal::StaticCalError;
use qfa_log::channels::ChannelsError;

// What drawing a residual plot fails with.
use qfa_report::plot_png::PlotError;

/// Why a discovery run failed.
///
/// `{}` prints this error's own message; `{:#}` adds its causes, each after `: `, the
/// whole chain the command line prints. The variants that wrap an error without adding to
/// it (`Channels`, `StaticCal`, `Plot`) print its message and continue the chain from its
/// source, so no message is printed twice.
#[derive(Debug)]
#[non_exhaustive]
pub enum DiscoverError {
    /// A start model other than `simple` or `paper` (the name given).
    UnknownStart(String),
    /// The log gives no discovery channels.
    Channels(ChannelsError),
    /// A static log its calibration refuses (span, rows per degree, held-out scheme), or a
    /// held-out figure or fit of it that failed.
    StaticCal(StaticCalError),
    /// Discovery on an axis of a static log, or calibrate's fit on a cycling log's fold
    /// (`axis` then names the cycling table), gave no model.
    NoModel {
        /// The axis.
        axis: String,
        /// The fold (1-based) whose training rows gave none; `None`: every row.
        fold: Option<usize>,
    },
    /// An output directory that could not be created.
    CreateDir {
        /// The directory.
        path: PathBuf,
        /// The system's error.
        source: io::Error,
    },
    /// An output file that could not be written (or an older one removed).
    Io {
        /// The file.
        path: PathBuf,
        /// The system's error.
        source: io::Error,
    },
    /// A model that does not serialize as TOML.
    Toml {
        /// The file it was for.
        path: PathBuf,
        /// The `toml` crate's error.
        source: toml::ser::Error,
    },
    /// A report that does not serialize as JSON.
    Json {
        /// The file it was for.
        path: PathBuf,
        /// `serde_json`'s error.
        source: serde_json::Error,
    },
    /// A table the root crate refuses to encode.
    Table(qfa_thermal::table::Error),
    /// `report.html` not written (the error names the file).
    Page(io::Error),
    /// A cycling log's table: calibrate's fit or its held-out figures failed on the log.
    Calibrate(Box<qfa_calibrate::CalibrateError>),
    /// A residual plot (its chart, title or legend) that could not be drawn or encoded.
    Plot(PlotError),
}

impl fmt::Display for DiscoverError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::UnknownStart(s) => write!(f, "start must be simple or paper, not {s:?}")?,
            Self::Channels(e) => write!(f, "{e}")?,
            Self::StaticCal(e) => write!(f, "{e}")?,
            Self::NoModel { axis, fold: None } => write!(f, "{axis}: discovery gave no model")?,
            Self::NoModel { axis, fold: Some(k) } => write!(f, "{axis}: discovery gave no model in fold {k}")?,
            Self::CreateDir { path, .. } => write!(f, "creating {}", path.display())?,
            Self::Io { path, .. } | Self::Toml { path, .. } | Self::Json { path, .. } => {
                write!(f, "{}", path.display())?;
            }
            Self::Table(_) => f.write_str("encoding table.bin")?,
            Self::Page(_) => f.write_str("writing report.html")?,
            Self::Plot(e) => write!(f, "{e}")?,
            Self::Calibrate(_) => f.write_str("fitting the cycling log's table")?,
        }
        if f.alternate() {
            let mut cause = std::error::Error::source(self);
            while let Some(c) = cause {
                write!(f, ": {c}")?;
                cause = c.source();
            }
        }
        Ok(())
    }
}

impl std::error::Error for DiscoverError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            // Their message is the wrapped error's own: the chain goes on from its source.
            Self::Channels(e) => e.source(),
            Self::StaticCal(e) => e.source(),
            Self::Plot(e) => e.source(),
            Self::CreateDir { source, .. } | Self::Io { source, .. } | Self::Page(source) => Some(source),
            Self::Toml { source, .. } => Some(source),
            Self::Json { source, .. } => Some(source),
            Self::Table(e) => Some(e),
            Self::Calibrate(e) => Some(e.as_ref()),
            Self::UnknownStart(_) | Self::NoModel { .. } => None,
        }
    }
}

impl From<ChannelsError> for DiscoverError {
    fn from(e: ChannelsError) -> Self {
        Self::Channels(e)
    }
}

impl From<StaticCalError> for DiscoverError {
    fn from(e: StaticCalError) -> Self {
        Self::StaticCal(e)
    }
}

impl From<PlotError> for DiscoverError {
    fn from(e: PlotError) -> Self {
        Self::Plot(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Start;

    #[test]
    fn a_bad_start_and_an_unwritable_file_reach_the_caller_as_their_variants() {
        let e = "sideways".parse::<Start>().unwrap_err();
        assert!(matches!(&e, DiscoverError::UnknownStart(s) if s == "sideways"), "{e:?}");
        assert_eq!(e.to_string(), "start must be simple or paper, not \"sideways\"");
        // A file under a file: the write fails, and the error names it and keeps the cause.
        let file = std::env::temp_dir().join(format!("qfa-discover-error-{}", std::process::id()));
        std::fs::write(&file, "").unwrap();
        let e = crate::output::write_file(&file.join("report.md"), "x").unwrap_err();
        let _ = std::fs::remove_file(&file);
        assert!(matches!(&e, DiscoverError::Io { path, .. } if path.ends_with("report.md")), "{e:?}");
        assert!(std::error::Error::source(&e).is_some());
        assert!(format!("{e:#}").starts_with(&format!("{}: ", file.join("report.md").display())), "{e:#}");
    }
}
