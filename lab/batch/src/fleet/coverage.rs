//! Whether a unit's rows cover what the fleet's do ([`Coverage`]): a unit of partial
//! coverage is compared with the fleet on its sensor only, and gets the population prior.

use serde::{Deserialize, Serialize};

use super::{median, Calibrated, FULL_SPAN_SHARE};

/// Whether a unit's rows cover what the fleet's do, and if not, why: a unit of partial
/// coverage is compared with the fleet on its sensor only, and gets the population prior's
/// table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Coverage {
    /// Its rows cover the fleet's: every figure is compared.
    Full,
    /// Not calibrated: no figure to compare.
    NotCalibrated,
    /// Its rows hold one branch (heating-only or cooling-only).
    OneBranch,
    /// Its temperature span is under 0.8 of the fleet's median span.
    Span {
        /// Its span, °C.
        span_c: f64,
        /// The fleet's median span, °C.
        fleet_span_c: f64,
    },
    /// A QFA unit's log lacks programs that more than half of the fleet's QFA units ran:
    /// its rate terms are fitted on fewer rates, and its bias ageing (a trend over its runs
    /// back to back) cannot be told from what its rate terms leave.
    Programs {
        /// The programs it lacks, in the fleet's order.
        missing: Vec<String>,
    },
}

impl Coverage {
    /// Partial: compared on the sensor only.
    #[must_use]
    pub fn partial(&self) -> bool {
        !matches!(self, Self::Full)
    }

    /// Why the coverage is partial, in words; `None` when it is full.
    #[must_use]
    pub fn words(&self) -> Option<String> {
        Some(match self {
            Self::Full => return None,
            Self::NotCalibrated => "not calibrated".to_string(),
            Self::OneBranch => "its rows hold one branch (heating or cooling only)".to_string(),
            Self::Span { span_c, fleet_span_c } => format!(
                "its rows span {span_c:.1} °C, under {FULL_SPAN_SHARE} of the fleet's median {fleet_span_c:.1} °C"
            ),
            Self::Programs { missing } => format!(
                "its log lacks program(s) {} that most of the fleet's units ran: its rate terms come from fewer \
                 rates, and its bias ageing cannot be told from what they leave",
                missing.join(", ")
            ),
        })
    }
}
/// What a `unit.json` written before [`Coverage`] existed reads as.
pub(super) fn full_coverage() -> Coverage {
    Coverage::Full
}

/// Per unit, whether its coverage is partial: not calibrated, one branch only, or a span
/// short of [`FULL_SPAN_SHARE`] of the median span of the units whose log fits the batch
/// (not `input_fault`).
pub(super) fn partial_units(cal: &[Option<&Calibrated>], input_fault: &[bool]) -> Vec<Coverage> {
    let fitting = || cal.iter().zip(input_fault).filter(|(_, f)| !**f).filter_map(|(c, _)| *c);
    let spans: Vec<f64> = fitting().map(|c| c.temp_c[1] - c.temp_c[0]).collect();
    let median_span = median(&spans).unwrap_or(0.0);
    // The programs more than half of the fleet's QFA units ran, in the order of the first
    // unit that ran the most programs.
    let qfa: Vec<&[String]> = fitting().filter_map(|c| c.qfa.as_ref().map(|q| q.programs.as_slice())).collect();
    let mut by_length = qfa.clone();
    by_length.sort_by_key(|ps| std::cmp::Reverse(ps.len()));
    let mut common: Vec<&String> = Vec::new();
    for p in by_length.iter().flat_map(|ps| ps.iter()) {
        if !common.contains(&p) && 2 * qfa.iter().filter(|ps| ps.contains(p)).count() > qfa.len() {
            common.push(p);
        }
    }
    cal.iter()
        .map(|c| {
            let Some(c) = c else { return Coverage::NotCalibrated };
            let span_c = c.temp_c[1] - c.temp_c[0];
            let missing: Vec<String> = c
                .qfa
                .as_ref()
                .map(|q| common.iter().filter(|p| !q.programs.contains(p)).map(|p| (*p).clone()).collect())
                .unwrap_or_default();
            if c.one_branch {
                Coverage::OneBranch
            } else if span_c < FULL_SPAN_SHARE * median_span {
                Coverage::Span { span_c, fleet_span_c: median_span }
            } else if !missing.is_empty() {
                Coverage::Programs { missing }
            } else {
                Coverage::Full
            }
        })
        .collect()
}
