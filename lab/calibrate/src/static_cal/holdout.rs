//! Static calibration's held-out schemes (`--holdout auto|after-max|blocks:K|none`), the
//! split at the temperature maximum, and the coverage a log needs before any fit.

use std::fmt;
use std::ops::Range;
use std::str::FromStr;

use qfa_thermal::model::MAX_BIAS_POINTS;

use crate::static_cal::*;
use qfa_log::static_log::StaticLog;

/// The held-out scheme asked for (`--holdout`); see the module docs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Holdout {
    /// `after-max` when the log has a later leg inside the range of the rows before it (see
    /// `later_leg_inside`), else `blocks:5`.
    #[default]
    Auto,
    /// Fit up to the first row at the highest temperature, evaluate on the rows after it.
    AfterMax,
    /// K contiguous blocks in time, each evaluated on a fit to the others (K ≥ 2).
    Blocks(usize),
    /// Nothing held out, no held-out figure.
    None,
}

impl FromStr for Holdout {
    type Err = StaticCalError;
    fn from_str(s: &str) -> Result<Self, StaticCalError> {
        let bad = || StaticCalError::UnknownHoldout(s.to_string());
        match s {
            "auto" => Ok(Self::Auto),
            "after-max" => Ok(Self::AfterMax),
            "none" => Ok(Self::None),
            _ => match s.strip_prefix("blocks:").map(str::parse::<usize>) {
                Some(Ok(k)) if k >= 2 => Ok(Self::Blocks(k)),
                _ => Err(bad()),
            },
        }
    }
}

impl fmt::Display for Holdout {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Auto => f.write_str("auto"),
            Self::AfterMax => f.write_str("after-max"),
            Self::Blocks(k) => write!(f, "blocks:{k}"),
            Self::None => f.write_str("none"),
        }
    }
}

/// The scheme in force on one log (`auto` resolved).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scheme {
    /// Held out: the rows after row `last` (0-based).
    AfterMax {
        /// Last training row.
        last: usize,
    },
    /// K contiguous blocks.
    Blocks {
        /// Blocks.
        k: usize,
    },
    /// Nothing held out.
    None,
}

impl Scheme {
    /// The held-out rows of each fold (0-based, ascending, disjoint); each fold's training
    /// rows are all the others. None for `none`.
    #[must_use]
    pub fn folds(&self, n: usize) -> Vec<Range<usize>> {
        match *self {
            Self::AfterMax { last } => std::iter::once(last + 1..n).collect(),
            Self::Blocks { k } => (0..k).map(|f| n * f / k..n * (f + 1) / k).collect(),
            Self::None => Vec::new(),
        }
    }

    /// Cross-validation blocks of the model choice: the scheme's K under `blocks:K`, else
    /// [`CV_FOLDS`].
    #[must_use]
    pub fn selection_folds(&self) -> usize {
        match *self {
            Self::Blocks { k } => k,
            _ => CV_FOLDS,
        }
    }

    /// Name as `--holdout` spells it.
    #[must_use]
    pub(crate) fn name(&self) -> String {
        match *self {
            Self::AfterMax { .. } => Holdout::AfterMax.to_string(),
            Self::Blocks { k } => Holdout::Blocks(k).to_string(),
            Self::None => Holdout::None.to_string(),
        }
    }
}

/// Index of the last training row of `after-max`: the first row at the log's highest
/// temperature (see the module docs).
///
/// # Errors
/// Fewer than a tenth of the rows on either side: the log has no later leg to evaluate on
/// (or nothing before it to fit on).
pub fn split_index(log: &StaticLog) -> Result<usize, StaticCalError> {
    let n = log.rows();
    let imax = (0..n).fold(0, |b, i| if log.temp_c[i] > log.temp_c[b] { i } else { b });
    let tenth = (n / 10).max(1);
    if n - imax - 1 < tenth {
        return Err(StaticCalError::Split(SplitFault::NoLaterLeg { max_c: log.temp_c[imax], row: imax + 1, rows: n }));
    }
    if imax + 1 < tenth {
        return Err(StaticCalError::Split(SplitFault::TooFewToFit { max_c: log.temp_c[imax], row: imax + 1, rows: n }));
    }
    Ok(imax)
}

/// `auto` holds out the later leg only where that leg is a test of the training rows: they
/// can hold a grid ([`check_coverage`]), at most a tenth of the later leg's rows lie
/// outside their temperature range, and they hold both branches when the log does. A log
/// whose highest reading falls in a hold before any ramp (a run cut short while it warmed
/// up again) would otherwise be fitted on that hold alone and fail, or be scored on
/// extrapolation; a log that heats to its maximum and then cools would be fitted on the
/// heating branch alone, which cannot fit the branch terms its table may hold, so its
/// table would have no held-out figure. The branches are the firmware's (its default
/// deadband), as the model search counts them ([`is_one_branch`]).
///
/// # Errors
/// [`StaticCalError::Split`] saying which condition failed.
fn later_leg_inside(log: &StaticLog, last: usize) -> Result<(), StaticCalError> {
    let (train, later) = log.temp_c.split_at(last + 1);
    let o = StaticCalOptions::default();
    check_coverage(train, o.grid_points, o.block)
        .map_err(|e| StaticCalError::Split(SplitFault::TrainingCannotHoldTheGrid(Box::new(e))))?;
    let (lo, hi) = range(train);
    let outside = later.iter().filter(|t| **t < lo || **t > hi).count();
    if outside * 10 > later.len() {
        return Err(StaticCalError::Split(SplitFault::LaterLegOutside {
            outside,
            later: later.len(),
            lo_c: lo,
            hi_c: hi,
        }));
    }
    let view = crate::fit::StaticSeries::view_of(&log.time_s, &log.temp_c, o.deadband_c_per_min);
    let plain = qfa_log::pairing::trace_view(&view, &qfa_thermal::Extensions::default(), o.deadband_c_per_min);
    let before = crate::static_cal::choice::branch_rows(&plain.branch, 0..last + 1);
    let every = crate::static_cal::choice::branch_rows(&plain.branch, 0..log.rows());
    if is_one_branch(before) && !is_one_branch(every) {
        return Err(StaticCalError::Split(SplitFault::OneBranchBefore { heating: before.0, cooling: before.1 }));
    }
    Ok(())
}

/// The scheme `h` gives on `log`, and why, in words.
///
/// # Errors
/// `after-max` on a log without a later leg; `blocks:K` with a block under `block` rows.
pub fn resolve_holdout(log: &StaticLog, h: Holdout, block: usize) -> Result<(Scheme, String), StaticCalError> {
    let n = log.rows();
    let blocks = |k: usize, why: &str| -> Result<(Scheme, String), StaticCalError> {
        if n / k < block {
            return Err(StaticCalError::BlocksTooShort { blocks: k, rows: n, needed: block });
        }
        Ok((
            Scheme::Blocks { k },
            format!(
                "{why}blocked cross-validation in time: the {n} rows cut into {k} contiguous blocks of equal row \
                 count, each block evaluated on models fitted on the other {}",
                k - 1
            ),
        ))
    };
    let after = |last: usize, why: &str| {
        (
            Scheme::AfterMax { last },
            format!(
                "{why}the later leg: fit on rows 1..={} (up to the first row at the highest temperature, {:.2} °C at \
                 t = {:.1} s), evaluate on rows {}..={n}",
                last + 1,
                log.temp_c[last],
                log.time_s[last],
                last + 2
            ),
        )
    };
    match h {
        Holdout::AfterMax => Ok(after(split_index(log)?, "")),
        Holdout::Blocks(k) => blocks(k, ""),
        Holdout::None => Ok((Scheme::None, "none: no row is held out, so no held-out figure exists".to_string())),
        Holdout::Auto => match split_index(log).and_then(|last| later_leg_inside(log, last).map(|()| last)) {
            Ok(last) => Ok(after(last, "auto: the log has a later leg after its highest temperature, so ")),
            Err(StaticCalError::Split(why)) => blocks(CV_FOLDS, &format!("auto: {why}; so ")),
            Err(e) => Err(e),
        },
    }
}

/// Refuse an axis of `log` that reads one value on every row: a stuck output, or a column
/// the logger filled with a constant. An accelerometer's output moves with its noise and with
/// its temperature, so no axis of a chamber log holds one value throughout; calibrated, such
/// an axis gets a flat table and a held-out residual of zero, which meets every limit.
///
/// # Errors
/// [`StaticCalError::StuckAxis`] for the first such axis.
pub fn check_outputs(log: &qfa_log::static_log::StaticLog) -> Result<(), StaticCalError> {
    for a in &log.axes {
        let Some(&first) = a.accel_g.first() else { continue };
        if a.accel_g.len() > 1 && a.accel_g.iter().all(|v| v.to_bits() == first.to_bits()) {
            return Err(StaticCalError::StuckAxis {
                axis: a.name.clone(),
                column: a.column.clone(),
                value_g: first,
                rows: a.accel_g.len(),
            });
        }
    }
    Ok(())
}

/// Refuse a log whose temperatures cannot hold the bias grid (see the module docs).
///
/// # Errors
/// [`StaticCalError::SpanTooSmall`] or [`StaticCalError::TooFewRowsPerDegree`].
pub fn check_coverage(temp_c: &[f64], grid_points: usize, block: usize) -> Result<(), StaticCalError> {
    let (lo, hi) = range(temp_c);
    let g = grid_points.clamp(2, MAX_BIAS_POINTS);
    let needed = qfa_log::grid_span_needed_c(g);
    if hi - lo < needed {
        return Err(StaticCalError::SpanTooSmall { lo_c: lo, hi_c: hi, needed_c: needed, nodes: g });
    }
    let intervals = g - 1;
    let w = (hi - lo) / intervals as f64;
    let mut count = vec![0usize; intervals];
    for &t in temp_c {
        count[(((t - lo) / w).floor() as usize).min(intervals - 1)] += 1;
    }
    let (i, &rows) = count.iter().enumerate().min_by_key(|&(_, c)| *c).unwrap_or((0, &0));
    if rows < block {
        let a = lo + w * i as f64;
        return Err(StaticCalError::TooFewRowsPerDegree {
            interval_c: (a, a + w),
            rows,
            needed: block,
            span_c: (lo, hi),
            intervals,
        });
    }
    Ok(())
}
