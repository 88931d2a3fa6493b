//! Whole-log checks of a static log: robust medians and the largest temperature slew (what
//! a wrong time unit shows as). Its one-row glitches are [`crate::robust::glitches`].

use serde::Serialize;

use crate::robust::median;
use crate::static_log::*;

/// Median of the up-to-5 values centred on `v[i]` (fewer at the ends, always an odd count,
/// so a monotone sequence is its own median).
pub(crate) fn centred_median(v: &[f64], i: usize) -> f64 {
    let h = 2.min(i).min(v.len() - 1 - i);
    median(&v[i - h..=i + h]).unwrap_or(v[i])
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
