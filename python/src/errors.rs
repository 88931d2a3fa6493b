//! The exception hierarchy: one base, one class per kind of failure, each carrying the
//! message `qfa-lab` prints after `error: ` for the same failure (options named as this
//! package's keywords) and a `kind` taken from the Rust error's type ([`Kind`]).

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

use qfa_calibrate::fit::FitError;
use qfa_calibrate::static_cal::StaticCalError;
use qfa_calibrate::CalibrateError;
use qfa_discover::DiscoverError;
use qfa_log::open::{OpenError, ReadError};
use qfa_log::static_log::StaticError;
use qfa_log::units::UnitParseError;
use qfa_thermal::compensator::SampleError as FirmwareSampleError;

create_exception!(_native, QfaError, PyException, "Base of every qfa_thermal error.");
create_exception!(_native, LogError, QfaError, "A log the lab's reader refuses (bad rows, columns, units).");
create_exception!(_native, CalibrationError, QfaError, "A calibration that cannot be fitted or evaluated.");
create_exception!(_native, TableError, QfaError, "A table that does not decode, validate or load.");
create_exception!(_native, CompensationError, QfaError, "A log the table cannot compensate.");
create_exception!(_native, DiscoveryError, QfaError, "A discovery run that failed.");
create_exception!(_native, ConfigError, QfaError, "A compensator configuration the firmware refuses.");
create_exception!(_native, SampleError, QfaError, "A temperature reading the firmware's compensator rejected.");
create_exception!(_native, BatchError, QfaError, "A production batch that cannot be read, run or merged.");

/// Register the classes on the module; `QfaError.kind` is `None` for a failure no Rust
/// error type stands behind (an argument this package checks itself).
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    py.get_type::<QfaError>().setattr("kind", py.None())?;
    m.add("QfaError", py.get_type::<QfaError>())?;
    m.add("LogError", py.get_type::<LogError>())?;
    m.add("CalibrationError", py.get_type::<CalibrationError>())?;
    m.add("TableError", py.get_type::<TableError>())?;
    m.add("CompensationError", py.get_type::<CompensationError>())?;
    m.add("DiscoveryError", py.get_type::<DiscoveryError>())?;
    m.add("ConfigError", py.get_type::<ConfigError>())?;
    m.add("SampleError", py.get_type::<SampleError>())?;
    m.add("BatchError", py.get_type::<BatchError>())?;
    Ok(())
}

/// An exception of type `E` with `message` and a `kind` attribute.
pub fn with_kind<E: pyo3::PyTypeInfo>(py: Python<'_>, message: String, kind: &str) -> PyErr {
    let err = PyErr::new::<E, _>(message);
    // Setting an attribute on a fresh exception instance cannot fail short of memory
    // exhaustion; the message is then still raised.
    let _ = err.value(py).setattr("kind", kind);
    err
}

/// A Rust error's `kind` for Python: its variant's name, written out here, so a Python
/// caller can branch on it and no rename of `Debug` output changes it.
///
/// Every error enum behind it is `#[non_exhaustive]`, so each `match` ends in a wildcard
/// arm: a variant added later reads `Other` until it is named here.
pub trait Kind {
    /// The variant's name (`Crc`, `Unit`, `UnknownHoldout`).
    fn kind(&self) -> &'static str;
}

/// The kind of a variant this file does not name yet.
const OTHER: &str = "Other";

impl Kind for StaticError {
    fn kind(&self) -> &'static str {
        match self {
            Self::Csv { .. } => "Csv",
            Self::Empty => "Empty",
            Self::NoRows => "NoRows",
            Self::UnknownColumn { .. } => "UnknownColumn",
            Self::MissingColumn { .. } => "MissingColumn",
            Self::BadColumnSpec(_) => "BadColumnSpec",
            Self::BadUnit(e) => e.kind(),
            Self::UnitUnknown { .. } => "UnitUnknown",
            Self::Unit(_) => "Unit",
            Self::DecimalComma { .. } => "DecimalComma",
            Self::DecimalCommaDelimiter => "DecimalCommaDelimiter",
            Self::Rows { .. } => "Rows",
            Self::TooFewRows { .. } => "TooFewRows",
            _ => OTHER,
        }
    }
}

impl Kind for UnitParseError {
    fn kind(&self) -> &'static str {
        "BadUnit"
    }
}

/// The file that cannot be read is `Io`; a log its reader refused is the static reader's
/// variant, or the reader's name for the readers whose errors are not broken out.
impl Kind for OpenError {
    fn kind(&self) -> &'static str {
        match self {
            Self::Io { .. } => "Io",
            Self::Read { error: ReadError::Static(e), .. } => e.kind(),
            Self::Read { error: ReadError::Cycling(_), .. } => "Cycling",
            Self::Read { error: ReadError::Single(_), .. } => "Single",
            Self::Read { error: ReadError::Ulog(_), .. } => "Ulog",
            Self::Read { error: ReadError::Dataflash(_), .. } => "Dataflash",
            Self::Read { error: ReadError::OptionsOnCyclingLog, .. } => "OptionsOnCyclingLog",
        }
    }
}

impl Kind for StaticCalError {
    fn kind(&self) -> &'static str {
        match self {
            Self::Split(_) => "Split",
            Self::UnknownHoldout(_) => "UnknownHoldout",
            Self::BlocksTooShort { .. } => "BlocksTooShort",
            Self::SpanTooSmall { .. } => "SpanTooSmall",
            Self::TooFewRowsPerDegree { .. } => "TooFewRowsPerDegree",
            Self::StuckAxis { .. } => "StuckAxis",
            Self::Fit(..) => "Fit",
            Self::Figure(_) => "Figure",
            Self::Coverage(_) => "Coverage",
            Self::Output(_) => "Io",
            _ => OTHER,
        }
    }
}

/// What a cycling log's fitted runs hold that no fit can be right on.
impl Kind for qfa_log::cycling::ContentFault {
    fn kind(&self) -> &'static str {
        match self {
            Self::NoRows => "NoRows",
            Self::StuckPulses { .. } => "StuckPulses",
            Self::IntervalUnit { .. } => "IntervalUnit",
            Self::NegativeScaleFactor { .. } => "NegativeScaleFactor",
            Self::SpanTooSmall { .. } => "SpanTooSmall",
            _ => OTHER,
        }
    }
}

/// A cycling calibration's kind: the fit's or the compensation's own kind when one of them
/// failed, else the stage that did.
impl Kind for CalibrateError {
    fn kind(&self) -> &'static str {
        match self {
            Self::Read(_) => "Cycling",
            Self::Fit(e) => e.kind(),
            Self::Evaluate(e) => e.kind(),
            Self::NotComputable(_) => "NotComputable",
            Self::NoPeerPair | Self::PeerFit(_) => "Peers",
            Self::Coverage(_) => "Coverage",
            Self::Table(_) => "Table",
            Self::Toml(_) => "Toml",
            Self::Axis(_) => "Axis",
            Self::Output(_) => "Output",
            Self::Contents(e) => e.kind(),
            _ => OTHER,
        }
    }
}

/// A discovery's kind: static calibration's own when it refused the log, else the stage
/// that failed.
impl Kind for DiscoverError {
    fn kind(&self) -> &'static str {
        match self {
            Self::UnknownStart(_) => "UnknownStart",
            Self::Channels(_) => "Channels",
            Self::StaticCal(e) => e.kind(),
            Self::NoModel { .. } => "NoModel",
            Self::CreateDir { .. } => "CreateDir",
            Self::Io { .. } => "Io",
            Self::Toml { .. } => "Toml",
            Self::Json { .. } => "Json",
            Self::Table(_) => "Table",
            Self::Page(_) => "Page",
            Self::Plot(_) => "Plot",
            _ => OTHER,
        }
    }
}

impl Kind for FitError {
    fn kind(&self) -> &'static str {
        match self {
            Self::NoPair(_) => "NoPair",
            Self::TooFewRows { .. } => "TooFewRows",
            Self::TooManyAxes => "TooManyAxes",
            Self::Table(_) => "Table",
            Self::Cv(_) => "Cv",
            Self::BranchUnidentified { .. } => "BranchUnidentified",
            _ => OTHER,
        }
    }
}

impl Kind for qfa_calibrate::compensate::Error {
    fn kind(&self) -> &'static str {
        match self {
            Self::Table(_) => "Table",
            Self::Config(_) => "Config",
            _ => OTHER,
        }
    }
}

impl Kind for qfa_calibrate::compensate::StaticCompensateError {
    fn kind(&self) -> &'static str {
        match self {
            Self::AxisCount { .. } => "AxisCount",
            Self::Length { .. } => "Length",
            Self::Table(_) => "Table",
            Self::Config(_) => "Config",
            Self::Write(_) => "Io",
            _ => OTHER,
        }
    }
}

impl Kind for qfa_thermal::table::Error {
    fn kind(&self) -> &'static str {
        match self {
            Self::Truncated => "Truncated",
            Self::BadMagic => "BadMagic",
            Self::Version(_) => "Version",
            Self::AxisCount { .. } => "AxisCount",
            Self::Crc => "Crc",
            Self::Decode => "Decode",
            Self::TrailingBytes => "TrailingBytes",
            Self::BufferTooSmall => "BufferTooSmall",
            Self::NonFinite(_) => "NonFinite",
            Self::OutOfRange(_) => "OutOfRange",
            Self::Grid => "Grid",
            Self::ScaleFactorNotPositive => "ScaleFactorNotPositive",
            Self::NoInputRecorded => "NoInputRecorded",
            Self::Input { .. } => "Input",
            Self::Scale { .. } => "Scale",
            Self::RateWindow { .. } => "RateWindow",
            Self::PartScale { .. } => "PartScale",
            _ => OTHER,
        }
    }
}

impl Kind for qfa_thermal::ConfigError {
    fn kind(&self) -> &'static str {
        match self {
            Self::NonFinite(_) => "NonFinite",
            Self::OutOfRange(_) => "OutOfRange",
            Self::StaleShorterThanSamplePeriod => "StaleShorterThanSamplePeriod",
            Self::GapShorterThanSamplePeriod => "GapShorterThanSamplePeriod",
            Self::MinSamplesAboveWindow => "MinSamplesAboveWindow",
            Self::ImuPeriodInTicks => "ImuPeriodInTicks",
            Self::SampleScaleNotStated => "SampleScaleNotStated",
            _ => OTHER,
        }
    }
}

impl Kind for qfa_thermal::ds18b20::Error {
    fn kind(&self) -> &'static str {
        match self {
            Self::BusAllOnes => "BusAllOnes",
            Self::AllZero => "AllZero",
            Self::Crc { .. } => "Crc",
            Self::Reserved => "Reserved",
            Self::Config(_) => "Config",
            Self::PowerOn => "PowerOn",
            Self::OutOfRange { .. } => "OutOfRange",
            _ => OTHER,
        }
    }
}

/// A scratchpad that failed decoding is tagged by the decoder's reason (`Crc`, `PowerOn`).
impl Kind for FirmwareSampleError {
    fn kind(&self) -> &'static str {
        match self {
            Self::Decode(e) => e.kind(),
            Self::Time(_) => "Time",
            Self::PowerOnJump => "PowerOnJump",
            Self::Implausible { .. } => "Implausible",
            Self::Missed => "Missed",
            Self::NoSuchSensor { .. } => "NoSuchSensor",
            _ => OTHER,
        }
    }
}
