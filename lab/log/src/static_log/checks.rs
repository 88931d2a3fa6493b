//! Whole-log checks of a static log: robust medians, one-row glitches, and the largest
//! temperature slew (what a wrong time unit shows as).

use serde::Serialize;

use crate::robust::{median, MAD_TO_SD};
use crate::static_log::*;

/// Median of the up-to-5 values centred on `v[i]` (fewer at the ends, always an odd count,
/// so a monotone sequence is its own median).
pub(crate) fn centred_median(v: &[f64], i: usize) -> f64 {
    let h = 2.min(i).min(v.len() - 1 - i);
    median(&v[i - h..=i + h]).unwrap_or(v[i])
}

/// Rows (indices into `v`) that deviate from their ±5-row neighbourhood by more than
/// `GLITCH_SIGMAS` robust σ (and at least `floor`; σ is `MAD_TO_SD` × the median deviation
/// from the window's line). The neighbourhood's prediction for row `i` is
/// `median_j(v[j] − slope·(j − i))`, a robust local line; the row's deviation is the
/// smallest under three slopes: the median of the whole window's differences, of those
/// before row `i` and of those after it. A steady ramp deviates by nothing, also at the ends
/// of the log where the window is one-sided, and so does a corner (a heating ramp turning
/// into a cooling one): the line from its side fits it. A one-row glitch fits none.
///
/// (The window's slope alone, under the median of an even count of differences, is 0 at a
/// symmetric corner: the corner then deviated by the ramp's rate times the window and was
/// dropped as a glitch. The upper median of those differences had hidden this by always
/// taking the later slope.)
pub(crate) fn glitches(v: &[f64], floor: f64) -> Vec<usize> {
    const HALF: usize = 5;
    let n = v.len();
    // Per row: the deviation from the window's line, and the smallest from the three lines.
    let (window, best): (Vec<f64>, Vec<f64>) = (0..n)
        .map(|i| {
            let lo = i.saturating_sub(HALF);
            let hi = (i + HALF + 1).min(n);
            let diffs = |a: usize, b: usize| -> Vec<f64> { v[a..b].windows(2).map(|w| w[1] - w[0]).collect() };
            let off_line = |d: &[f64]| {
                // No difference (a one-row side): no line, nothing to deviate from.
                let Some(slope) = median(d) else { return f64::INFINITY };
                let moved: Vec<f64> = (lo..hi).map(|j| v[j] - slope * (j as f64 - i as f64)).collect();
                // `moved` holds row i itself: never empty.
                (v[i] - median(&moved).unwrap_or(v[i])).abs()
            };
            let window = off_line(&diffs(lo, hi));
            let best = window.min(off_line(&diffs(lo, i + 1))).min(off_line(&diffs(i, hi)));
            let finite = |x: f64| if x.is_finite() { x } else { 0.0 };
            (finite(window), finite(best))
        })
        .unzip();
    // The channel's noise from the window's line (the smallest of three deviations would
    // understate it: 3× on the real log's axes, which took its last row for a glitch).
    let sigma = MAD_TO_SD * median(&window).unwrap_or(0.0);
    let thr = (GLITCH_SIGMAS * sigma).max(floor);
    (0..n).filter(|&i| best[i] > thr).collect()
}

/// The fastest temperature change of a log, see [`max_slew`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub(crate) struct Slew {
    /// The change, °C/min: `range_c` per `window_s`, scaled to a minute.
    pub c_per_min: f64,
    /// Largest temperature range inside one window, °C.
    pub range_c: f64,
    /// Window length, s: [`SLEW_WINDOW_S`], or the whole log when it is shorter.
    pub window_s: f64,
    /// Index of the row where that range starts (its earlier end, the min or the max).
    pub from: usize,
    /// Index of the row where it ends.
    pub to: usize,
}

/// The fastest temperature change in `temp_c` at times `time_s` (increasing): the largest
/// range (max − min) of the temperatures inside any window of [`SLEW_WINDOW_S`] (the whole
/// log if it is shorter), per minute. It is a lower bound of the steepest slope, so a
/// refusal on it is never an overstatement. The temperatures are first passed through a
/// 5-row running median so two bad readings in a row (a DS18B20's 85 °C power-on value)
/// do not make a log look 1000× too fast; a monotone ramp or a hold passes unchanged.
#[must_use]
pub(crate) fn max_slew(time_s: &[f64], temp_c: &[f64]) -> Slew {
    let n = time_s.len().min(temp_c.len());
    let none = Slew { c_per_min: 0.0, range_c: 0.0, window_s: SLEW_WINDOW_S, from: 0, to: 0 };
    if n < 2 {
        return none;
    }
    let m: Vec<f64> = (0..n).map(|i| centred_median(&temp_c[..n], i)).collect();
    let window = SLEW_WINDOW_S.min(time_s[n - 1] - time_s[0]);
    if window <= 0.0 {
        return none;
    }
    // Sliding window [l, r] with t[r] − t[l] ≤ window; monotone deques of the max and min.
    let (mut hi, mut lo) = (std::collections::VecDeque::new(), std::collections::VecDeque::new());
    let mut best = none;
    let mut l = 0;
    for r in 0..n {
        while hi.back().is_some_and(|&j: &usize| m[j] <= m[r]) {
            hi.pop_back();
        }
        hi.push_back(r);
        while lo.back().is_some_and(|&j: &usize| m[j] >= m[r]) {
            lo.pop_back();
        }
        lo.push_back(r);
        while time_s[r] - time_s[l] > window {
            l += 1;
        }
        while hi.front().is_some_and(|&j| j < l) {
            hi.pop_front();
        }
        while lo.front().is_some_and(|&j| j < l) {
            lo.pop_front();
        }
        let range = m[hi[0]] - m[lo[0]];
        if range > best.range_c {
            let (from, to) = (hi[0].min(lo[0]), hi[0].max(lo[0]));
            best = Slew { c_per_min: range / window * 60.0, range_c: range, window_s: window, from, to };
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ramp that turns (heating into cooling, cooling into heating, at any rate) has no
    /// glitch, its corner included; a one-row spike on it, anywhere, is the one glitch.
    #[test]
    fn a_corner_is_no_glitch_and_a_spike_is_one() {
        for rate in [0.01, 0.1, 1.0] {
            for sign in [1.0, -1.0] {
                let v: Vec<f64> = (0..200).map(|i| sign * rate * (100.0 - (f64::from(i) - 100.0).abs())).collect();
                assert_eq!(glitches(&v, 0.05), Vec::<usize>::new(), "rate {rate}, sign {sign}");
                for at in [0, 3, 99, 100, 101, 150, 199] {
                    let mut w = v.clone();
                    w[at] += 5.0;
                    assert_eq!(glitches(&w, 0.05), vec![at], "rate {rate}, sign {sign}, spike at {at}");
                }
            }
        }
    }
}
