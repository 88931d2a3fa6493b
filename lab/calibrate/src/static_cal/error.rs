//! Why a static calibration fails ([`StaticCalError`]): a log the bias grid cannot be fitted
//! on, a held-out scheme the log cannot hold, a failed fit or figure, or an output not written.

use std::fmt;

use qfa_thermal::table::limits::MIN_GRID_STEP_C;

use crate::fit::FitError;
use qfa_log::spelling::{CalibrateOption, Spelling};

/// Why a static calibration failed.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum StaticCalError {
    /// `--holdout after-max` on a log without a later leg.
    Split(SplitFault),
    /// A `--holdout` value that is none of the schemes (the value given).
    UnknownHoldout(String),
    /// `--holdout blocks:K` cuts the log into blocks shorter than a held-out block needs.
    BlocksTooShort {
        /// Blocks asked for (K).
        blocks: usize,
        /// Rows of the log.
        rows: usize,
        /// Rows a held-out block needs (one averaged equation).
        needed: usize,
    },
    /// The temperature span is below what the bias grid needs.
    SpanTooSmall {
        /// Lowest reading, °C.
        lo_c: f64,
        /// Highest reading, °C.
        hi_c: f64,
        /// Span needed, °C.
        needed_c: f64,
        /// Grid nodes.
        nodes: usize,
    },
    /// A part of the span holds too few rows for the grid.
    TooFewRowsPerDegree {
        /// The sparsest grid interval, °C.
        interval_c: (f64, f64),
        /// Rows in it.
        rows: usize,
        /// Rows it needs.
        needed: usize,
        /// The log's span, °C.
        span_c: (f64, f64),
        /// Intervals the span is cut into.
        intervals: usize,
    },
    /// An axis reads one value on every row: a stuck output or a constant column, whose
    /// flat table would meet every limit.
    StuckAxis {
        /// Axis (`ax`, `ay` or `az`).
        axis: String,
        /// Its column in the log.
        column: String,
        /// The one value, g.
        value_g: f64,
        /// Rows.
        rows: usize,
    },
    /// A fit failed.
    Fit(String, FitError),
    /// A figure could not be computed.
    Figure(FigureFault),
    /// The coverage of the fitted rows could not be formed.
    Coverage(crate::coverage::CoverageError),
    /// Writing an output failed.
    Output(crate::output_error::OutputError),
}

impl StaticCalError {
    /// The message, with the held-out option spelled for `sp` (`--holdout` for the CLI,
    /// `holdout=` for Python); the other variants name no option and read as `Display`.
    #[must_use]
    pub fn message(&self, sp: Spelling) -> String {
        let holdout = CalibrateOption::Holdout;
        match self {
            Self::UnknownHoldout(s) => {
                format!("{}: expected auto, after-max, blocks:K (K ≥ 2) or none", holdout.refused(sp, s))
            }
            Self::BlocksTooShort { blocks, rows, needed } => format!(
                "{}: {rows} rows make blocks of {} rows; a held-out block needs at least {needed} (one averaged \
                 equation)",
                holdout.with(sp, &format!("blocks:{blocks}")),
                rows / blocks
            ),
            e => e.to_string(),
        }
    }
}

impl fmt::Display for StaticCalError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Split(s) => write!(f, "held-out split: {s}"),
            Self::UnknownHoldout(_) | Self::BlocksTooShort { .. } => f.write_str(&self.message(Spelling::Cli)),
            Self::SpanTooSmall { lo_c, hi_c, needed_c, nodes } => write!(
                f,
                "the temperature span is too small: {:.2} °C ({lo_c:.2}..{hi_c:.2} °C); the model needs at least \
                 {needed_c:.2} °C ({nodes} bias-grid nodes at least {MIN_GRID_STEP_C} °C apart, the root crate's \
                 smallest grid step)",
                hi_c - lo_c
            ),
            Self::TooFewRowsPerDegree { interval_c: (a, b), rows, needed, span_c: (lo, hi), intervals } => write!(
                f,
                "too few rows per degree: {rows} row(s) between {a:.2} and {b:.2} °C ({:.2} per °C); the model needs \
                 {needed} there ({:.2} per °C): one {needed}-row averaged equation in each of the {intervals} \
                 bias-grid intervals over {lo:.2}..{hi:.2} °C",
                *rows as f64 / (b - a),
                *needed as f64 / (b - a)
            ),
            Self::StuckAxis { axis, column, value_g, rows } => write!(
                f,
                "{axis} (column `{column}`) reads {value_g} g on every one of its {rows} rows: a stuck output or a \
                 constant column, whose flat table would meet every limit (an accelerometer's output moves with its \
                 noise and its temperature); check the sensor and the column mapping"
            ),
            Self::Fit(axis, e) => write!(f, "fit of {axis}: {e}"),
            Self::Figure(s) => write!(f, "figure not computable: {s}"),
            Self::Coverage(e) => write!(f, "figure not computable: coverage: {e}"),
            Self::Output(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for StaticCalError {}

/// Why a log has no later leg to hold out (`--holdout after-max`, and `auto`'s test of it).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum SplitFault {
    /// Fewer than a tenth of the rows lie after the highest temperature.
    NoLaterLeg {
        /// The highest temperature, °C.
        max_c: f64,
        /// Its row, from 1.
        row: usize,
        /// Rows of the log.
        rows: usize,
    },
    /// Fewer than a tenth of the rows lie up to the highest temperature.
    TooFewToFit {
        /// The highest temperature, °C.
        max_c: f64,
        /// Its row, from 1.
        row: usize,
        /// Rows of the log.
        rows: usize,
    },
    /// The rows up to the highest temperature cannot hold the bias grid.
    TrainingCannotHoldTheGrid(Box<StaticCalError>),
    /// More than a tenth of the later leg lies outside the temperatures before it.
    LaterLegOutside {
        /// Later rows outside.
        outside: usize,
        /// Rows of the later leg.
        later: usize,
        /// The lowest temperature before it, °C.
        lo_c: f64,
        /// The highest, °C.
        hi_c: f64,
    },
    /// The rows up to the highest temperature hold one branch while the log holds both.
    OneBranchBefore {
        /// Heating rows up to the highest temperature.
        heating: usize,
        /// Cooling rows up to it.
        cooling: usize,
    },
}

impl fmt::Display for SplitFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoLaterLeg { max_c, row, rows } => write!(
                f,
                "the highest temperature ({max_c:.2} °C) is at row {row} of {rows}: fewer than a tenth of the rows lie \
                 after it, no later leg to evaluate on"
            ),
            Self::TooFewToFit { max_c, row, rows } => write!(
                f,
                "the highest temperature ({max_c:.2} °C) is at row {row} of {rows}: fewer than a tenth of the rows to \
                 fit on"
            ),
            Self::TrainingCannotHoldTheGrid(e) => {
                write!(f, "the rows up to the highest temperature cannot hold the bias grid ({e})")
            }
            Self::LaterLegOutside { outside, later, lo_c, hi_c } => write!(
                f,
                "{outside} of the {later} rows after the highest temperature lie outside the {lo_c:.1}..{hi_c:.1} °C \
                 the rows before it cover: the later leg would score an extrapolation"
            ),
            Self::OneBranchBefore { heating, cooling } => write!(
                f,
                "the rows up to the highest temperature hold one branch ({heating} heating, {cooling} cooling rows) \
                 while the log holds both: fitted on them, a table with heating/cooling terms could not be scored on \
                 the later leg"
            ),
        }
    }
}

impl From<crate::output_error::OutputError> for StaticCalError {
    fn from(e: crate::output_error::OutputError) -> Self {
        Self::Output(e)
    }
}

/// Why a static calibration's figure could not be computed.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum FigureFault {
    /// No held-out row had a model output.
    NoModelOutput {
        /// The figure (axis and model).
        figure: String,
    },
    /// A residual that is not finite.
    NonFinite {
        /// The figure (axis and model).
        figure: String,
    },
    /// No candidate model could be fitted in cross-validation.
    NoCandidate {
        /// The axis.
        axis: String,
        /// The first candidate refused (its name) and why.
        first_refusal: Option<Box<(String, FitError)>>,
    },
}

impl fmt::Display for FigureFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoModelOutput { figure } => write!(f, "{figure}: no held-out row had a model output"),
            Self::NonFinite { figure } => write!(f, "{figure}: non-finite residual"),
            Self::NoCandidate { axis, first_refusal } => {
                write!(f, "{axis}: no candidate model could be fitted in cross-validation")?;
                match first_refusal.as_deref() {
                    Some((name, e)) => write!(f, " (first refusal: {name}: {e})"),
                    None => f.write_str(" (first refusal: none)"),
                }
            }
        }
    }
}
