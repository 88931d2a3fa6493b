//! Bias ageing of a cycling log: how fast the bias moves with the unit's powered time, not
//! with its temperature.
//!
//! The table (fitted on every program) compensates every run through the root crate's
//! compensator; what is left on the rows it marks compensated is the bias the table does not
//! explain: a zero-g run's output itself, and on each ±1 g pair's matched rows the mean of
//! the two outputs less the mean of their inputs (a scale-factor error cancels there, and
//! for a bias linear in time the mean is the bias at the mean of the two rows' times). Its
//! least-squares slope against the log's clock is the ageing, µg/h. A log of ±1 g runs only
//! (a two-position test) has a figure too.
//! A thermal misfit repeats in every program; a level that moves from program to program,
//! hours apart, does not, and the held-out figure cannot see it when the held-out programs
//! sit between the fit programs in time (the paper's 0.5 and 0.7 °C/min between 0.3 and
//! 0.9: a linear ageing averages out of their table).
//!
//! The clock: a cycling log's times restart with each run, so the runs are taken back to
//! back in the log's order, each starting where the one before it ended. A pause between
//! runs stretches the real clock, so the figure is then too high by the pauses' share: a
//! log with absolute times would tell exactly.

use std::fmt;

use qfa_log::cycling::Log;
use qfa_thermal::Table;

use qfa_calibrate::compensate::{compensate_run, not_compensated};

/// Rows spread over less than this many hours give no ageing figure: within one run the
/// ageing cannot be told from the run's own thermal history.
pub const MIN_SPAN_H: f64 = 24.0;

/// A log's ageing figure.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Ageing {
    /// The bias's slope on the log's clock, µg/h.
    pub ug_per_h: f64,
    /// Rows it is fitted on (zero-g rows and matched ±1 g row pairs).
    pub rows: usize,
    /// Hours between the first and last of them on the log's clock.
    pub span_h: f64,
}

/// Why a log gives no ageing figure.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum AgeingError {
    /// Its compensated zero-g rows and ±1 g pairs span under [`MIN_SPAN_H`] hours (or
    /// there are none).
    TooShort {
        /// Their span, h.
        span_h: f64,
    },
    /// The table does not load into the compensator.
    Compensate(qfa_calibrate::compensate::Error),
    /// The level and slope cannot be solved.
    Fit(qfa_calibrate::fit::FitError),
}

impl fmt::Display for AgeingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooShort { span_h } => write!(
                f,
                "ageing not computable: the zero-g rows and ±1 g pairs the table compensates span {span_h:.1} h of the \
                 log's clock; \
                 {MIN_SPAN_H} h needed (runs hours apart at the same temperatures)"
            ),
            Self::Compensate(e) => write!(f, "ageing: {e}"),
            Self::Fit(e) => write!(f, "ageing: {e}"),
        }
    }
}

impl std::error::Error for AgeingError {}

/// The ageing of `log`'s bias after `table` (the module docs say how).
///
/// # Errors
/// [`AgeingError`]: too short a span of zero-g rows, or a table the compensator refuses.
pub fn ageing(log: &Log, table: &Table) -> Result<Ageing, AgeingError> {
    // Each run's start on the log's clock, and its rows' outputs where compensated.
    let start_s = log.run_starts_s();
    let compensated = |k: usize| -> Result<Vec<Option<f64>>, AgeingError> {
        let c = compensate_run(table, &log.runs[k]).map_err(AgeingError::Compensate)?;
        Ok(c.accel_g
            .iter()
            .zip(&c.status)
            .map(|(a, st)| (!not_compensated(*st) && a.is_finite()).then_some(*a))
            .collect())
    };
    let hours = |k: usize, i: usize| {
        let s = &log.runs[k].samples[i];
        (start_s[k] + s.time_s - 0.5 * s.interval_s) / 3600.0
    };
    let mut points = Vec::<(f64, f64)>::new();
    for (k, run) in log.runs.iter().enumerate() {
        if run.input_g == 0.0 {
            for (i, a) in compensated(k)?.into_iter().enumerate() {
                if let Some(a) = a {
                    points.push((hours(k, i), a * 1e6));
                }
            }
        }
    }
    let paired = qfa_log::pairing::PairedLog::new(log);
    for pp in log.programs().iter().filter_map(|p| paired.program(p)) {
        let (plus, minus) = (compensated(pp.plus)?, compensated(pp.minus)?);
        let input = 0.5 * (log.runs[pp.plus].input_g + log.runs[pp.minus].input_g);
        for &(i, j) in &pp.rows {
            if let (Some(a), Some(b)) = (plus[i], minus[j]) {
                points.push((0.5 * (hours(pp.plus, i) + hours(pp.minus, j)), (0.5 * (a + b) - input) * 1e6));
            }
        }
    }
    let (lo, hi) = points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let span_h = if points.is_empty() { 0.0 } else { hi - lo };
    if span_h < MIN_SPAN_H {
        return Err(AgeingError::TooShort { span_h });
    }
    // A level and a slope by the lab's one solver, time measured from the span's middle.
    let mid = 0.5 * (lo + hi);
    let x: Vec<f64> = points.iter().flat_map(|p| [1.0, p.0 - mid]).collect();
    let y: Vec<f64> = points.iter().map(|p| p.1).collect();
    let fit = qfa_calibrate::solver::lstsq(&x, 2, &y).map_err(AgeingError::Fit)?;
    Ok(Ageing { ug_per_h: fit.coef[1], rows: points.len(), span_h })
}

#[cfg(test)]
mod tests {
    use super::*;
    use qfa_log::cycling::{Run, Sample};

    /// A unit whose output is exactly the table's bias plus `rate × t` on the log's clock
    /// reads `rate` back, whatever the runs' lengths, from its zero-g runs and ±1 g pairs
    /// together or from the pairs alone (a two-position test).
    #[test]
    fn a_bias_that_moves_on_the_logs_clock_reads_back_its_rate() {
        let axis = qfa_thermal::AxisModel {
            scale: qfa_thermal::ScaleFactor::simple(22.0, 320_320.0, 0.0),
            bias: qfa_thermal::BiasGrid::flat(-60.0, 10.0, [0.0; 14]),
            rate_limit_c_per_min: 5.0,
            ext: qfa_thermal::Extensions::NONE,
        };
        let table = qfa_calibrate::fit::table_of(axis).unwrap();
        let gamma = f64::from(table.axes[0].scale.gamma);
        // Two programs of four positions each, runs of different lengths.
        for (rate, lengths) in [
            (0.3, [30_000, 50_000, 70_000, 20_000, 40_000, 20_000, 30_000, 60_000]),
            (-1.2, [90_000, 10_000, 40_000, 60_000, 20_000, 30_000, 50_000, 10_000]),
        ] {
            let (mut start, mut runs) = (0.0, Vec::new());
            for (k, len) in lengths.into_iter().enumerate() {
                let g = [1.0, 0.0, -1.0, 0.0][k % 4];
                let samples: Vec<Sample> = (1..=len / 10)
                    .map(|i| {
                        let t = f64::from(i) * 10.0;
                        let bias = rate * 1e-6 * (start + t - 5.0) / 3600.0;
                        let pulses = (gamma * (g + bias) * 10.0).round() as i64;
                        Sample { time_s: t, temp_c: Some(22.0), pulses, interval_s: 10.0 }
                    })
                    .collect();
                start += f64::from(len);
                let program = if k < 4 { "p" } else { "q" };
                runs.push(Run { program: program.into(), run: (k % 4).to_string(), input_g: g, samples });
            }
            let a = ageing(&Log { runs: runs.clone(), ..Log::default() }, &table).unwrap();
            // One pulse in 10 s is 0.31 µg: the rounding's share of the slope is far under 1 %.
            assert!((a.ug_per_h - rate).abs() < 0.01 * rate.abs(), "{a:?} against {rate}");
            // The pairs alone: the zero-g runs turned into runs at 2 g, which the figure does
            // not use, so they keep their place on the clock only.
            let pairs_only: Vec<Run> = runs
                .into_iter()
                .map(|mut r| {
                    if r.input_g == 0.0 {
                        r.input_g = 2.0;
                    }
                    r
                })
                .collect();
            let a = ageing(&Log { runs: pairs_only, ..Log::default() }, &table).unwrap();
            assert!((a.ug_per_h - rate).abs() < 0.01 * rate.abs(), "pairs only: {a:?} against {rate}");
        }
    }
}
