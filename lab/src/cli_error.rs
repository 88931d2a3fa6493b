//! Why a command failed, and the exit status each failure gets.

use super::*;

/// Why a command failed: printed as `error: …`, exit code 1.
#[derive(Debug)]
pub(crate) enum CliError {
    /// The command line asks for what cannot be done.
    Usage(String),
    /// An output that would overwrite something, or cannot be written.
    Out(OutError),
    /// A log that cannot be read (the file, and its reader's error).
    Open(OpenError),
    /// A log of a kind the command does not take.
    WrongLog {
        /// The command.
        command: &'static str,
        /// What the log is.
        format: LogFormat,
        /// What the command takes.
        takes: &'static str,
    },
    /// The work failed (a fit, a simulation, a write), with its cause.
    Failed(String),
    /// Every output is written, and the unit fails a limit given with `--limits` (which:
    /// one line each). Exit status [`EXIT_LIMIT_FAILED`].
    LimitFailed(Vec<String>),
    /// Every output of a batch is written, and units FAIL (not calibrated, or a limit given
    /// with `--limits` failed). Exit status [`EXIT_LIMIT_FAILED`].
    UnitsFailed(usize),
}

impl std::fmt::Display for CliError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Usage(m) | Self::Failed(m) => f.write_str(m),
            Self::Out(e) => write!(f, "{e}"),
            Self::Open(e) => write!(f, "{e}"),
            Self::WrongLog { command, format, takes } => write!(f, "{command} takes {takes}, not a {format}"),
            Self::LimitFailed(which) => write!(f, "the unit fails {} limit(s): {}", which.len(), which.join("; ")),
            Self::UnitsFailed(n) => write!(f, "{n} unit(s) FAIL (each listed above, with why)"),
        }
    }
}

impl CliError {
    /// `calibrate` and `compensate` take cycling and static logs; a single-channel log is
    /// discovery's.
    pub(crate) fn single_not_taken(command: &'static str) -> Self {
        Self::WrongLog { command, format: LogFormat::Single, takes: "a cycling or a static log" }
    }
}

impl From<OutError> for CliError {
    fn from(e: OutError) -> Self {
        Self::Out(e)
    }
}

impl From<OpenError> for CliError {
    fn from(e: OpenError) -> Self {
        Self::Open(e)
    }
}

impl From<qfa_sim::truth::TruthError> for CliError {
    fn from(e: qfa_sim::truth::TruthError) -> Self {
        match e {
            // A name the user typed: the command line asks for what cannot be done.
            qfa_sim::truth::TruthError::UnknownEffect { .. } => Self::Usage(e.to_string()),
            _ => Self::Failed(e.to_string()),
        }
    }
}

impl From<qfa_sim::profile::ProfileError> for CliError {
    fn from(e: qfa_sim::profile::ProfileError) -> Self {
        Self::Failed(e.to_string())
    }
}

impl From<qfa_sim::population::PopulationError> for CliError {
    fn from(e: qfa_sim::population::PopulationError) -> Self {
        Self::Failed(e.to_string())
    }
}

impl From<qfa_lab::demo::DemoError> for CliError {
    fn from(e: qfa_lab::demo::DemoError) -> Self {
        Self::Failed(e.to_string())
    }
}

impl From<qfa_calibrate::CalibrateError> for CliError {
    fn from(e: qfa_calibrate::CalibrateError) -> Self {
        Self::Failed(e.to_string())
    }
}

impl From<qfa_discover::DiscoverError> for CliError {
    fn from(e: qfa_discover::DiscoverError) -> Self {
        // `{:#}`: with its causes (the file and the system's error).
        Self::Failed(format!("{e:#}"))
    }
}

impl From<qfa_log::channels::ChannelsError> for CliError {
    fn from(e: qfa_log::channels::ChannelsError) -> Self {
        Self::Failed(e.to_string())
    }
}

impl From<String> for CliError {
    fn from(e: String) -> Self {
        Self::Failed(e)
    }
}

impl From<anyhow::Error> for CliError {
    fn from(e: anyhow::Error) -> Self {
        Self::Failed(format!("{e:#}"))
    }
}

/// A navigation error with its causes on one line (`context: cause`), as an anyhow error
/// prints.
pub(crate) fn nav_failed(e: impl std::error::Error + Send + Sync + 'static) -> CliError {
    CliError::from(anyhow::Error::from(e))
}

impl From<qfa_nav::NavError> for CliError {
    fn from(e: qfa_nav::NavError) -> Self {
        nav_failed(e)
    }
}

impl From<qfa_nav::scenario::ScenarioError> for CliError {
    fn from(e: qfa_nav::scenario::ScenarioError) -> Self {
        nav_failed(e)
    }
}

impl From<qfa_nav::plan::PlanError> for CliError {
    fn from(e: qfa_nav::plan::PlanError) -> Self {
        nav_failed(e)
    }
}
