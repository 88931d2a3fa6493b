//! Robust statistics, once for the lab: the median, the scale that turns a median absolute
//! deviation into a normal standard deviation, and the one rule for a one-row glitch.
//!
//! One convention: the median of an even count is the mean of its two middle values (the
//! textbook definition, symmetric: the median of `−v` is minus the median of `v`). Found by
//! selection, O(n), since discovery's null draws take it hundreds of times per test.

/// `1 / Φ⁻¹(3/4)`: a normal sample's median absolute deviation times this is its standard
/// deviation (Rousseeuw and Croux, "Alternatives to the median absolute deviation", JASA
/// 88 (1993), the consistency constant of the MAD).
pub const MAD_TO_SD: f64 = 1.482_602_218_505_602;

/// The median of `v`; `None` when `v` is empty. NaN sorts last (`f64::total_cmp`), so a
/// NaN-free input is the caller's to ensure.
#[must_use]
pub fn median(v: &[f64]) -> Option<f64> {
    let n = v.len();
    if n == 0 {
        return None;
    }
    // Selected on integer keys in `total_cmp`'s order, one integer compare per step in
    // place of `total_cmp`'s work on both operands: the same values, and the change-point
    // test's null draws (13 medians of about 5 000 values per draw) take half the time.
    let mut keys: Vec<i64> = v.iter().map(|&x| order_key(x)).collect();
    let (lower, upper, _) = keys.select_nth_unstable(n / 2);
    let upper = from_order_key(*upper);
    if n % 2 == 1 {
        return Some(upper);
    }
    // The other middle value is the largest of the lower part.
    let below = lower.iter().copied().max().map_or(upper, from_order_key);
    Some(0.5 * (below + upper))
}

/// An integer whose order is `f64::total_cmp`'s (the transform that function applies).
fn order_key(x: f64) -> i64 {
    let bits = x.to_bits() as i64;
    bits ^ ((((bits >> 63) as u64) >> 1) as i64)
}

/// The value of an [`order_key`] (the transform is its own inverse).
fn from_order_key(key: i64) -> f64 {
    f64::from_bits((key ^ ((((key >> 63) as u64) >> 1) as i64)) as u64)
}

/// The normal standard deviation whose absolute deviations `abs` are (1.4826 × their
/// median); `None` when `abs` is empty. Every robust scale of the lab is this.
#[must_use]
pub fn sd_from_abs_deviations(abs: &[f64]) -> Option<f64> {
    Some(MAD_TO_SD * median(abs)?)
}

/// The median of `v` and the robust SD about it (1.4826 × the median absolute deviation);
/// `None` when `v` is empty.
#[must_use]
pub fn median_and_sd(v: &[f64]) -> Option<(f64, f64)> {
    let mid = median(v)?;
    let dev: Vec<f64> = v.iter().map(|x| (x - mid).abs()).collect();
    Some((mid, sd_from_abs_deviations(&dev)?))
}

/// The noise of a series from its neighbours: 1.4826 × the median |difference of
/// neighbouring values| / √2, the SD of white noise on it. A step or a slow wander moves
/// one difference, or each a little, so neither counts as noise. `None` with fewer than two
/// values.
#[must_use]
pub fn neighbour_noise(v: &[f64]) -> Option<f64> {
    let diffs: Vec<f64> = v.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    Some(sd_from_abs_deviations(&diffs)? / std::f64::consts::SQRT_2)
}

/// Robust σ above which a one-row deviation is a glitch ([`glitches`]), in every reader.
pub const GLITCH_SIGMAS: f64 = 10.0;

/// Smallest acceleration deviation that counts as a glitch, g, in every reader (2 mg: a
/// quantised output can have a median deviation of 0, and a noise-free cycling log's
/// pulse rate steps with each 1/16-°C step of its reading through the scale factor's
/// temperature slope).
pub const GLITCH_MIN_ACCEL_G: f64 = 0.002;

/// The lab's one rule for a one-row glitch (a spike in one row of a series: a static log's
/// channel, a cycling run's pulse rate): rows (indices into `v`) that deviate from their ±5-row neighbourhood by more than
/// `sigmas` robust σ (and at least `floor`; σ is `MAD_TO_SD` × the median deviation
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
#[must_use]
pub fn glitches(v: &[f64], sigmas: f64, floor: f64) -> Vec<usize> {
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
    let thr = (sigmas * sigma).max(floor);
    (0..n).filter(|&i| best[i] > thr).collect()
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
                assert_eq!(glitches(&v, GLITCH_SIGMAS, 0.05), Vec::<usize>::new(), "rate {rate}, sign {sign}");
                for at in [0, 3, 99, 100, 101, 150, 199] {
                    let mut w = v.clone();
                    w[at] += 5.0;
                    assert_eq!(glitches(&w, GLITCH_SIGMAS, 0.05), vec![at], "rate {rate}, sign {sign}, spike at {at}");
                }
            }
        }
    }

    /// By hand: differences 1, 2, 3 have the median 2; a step of 100 in a longer series
    /// moves one difference and not the median; one value has no neighbour.
    #[test]
    fn neighbour_noise_is_the_median_difference_and_ignores_a_step() {
        let want = MAD_TO_SD * 2.0 / std::f64::consts::SQRT_2;
        assert_eq!(neighbour_noise(&[0.0, 1.0, 3.0, 6.0]), Some(want));
        let stepped = [0.0, 2.0, 0.0, 2.0, 102.0, 100.0, 102.0, 100.0];
        assert_eq!(neighbour_noise(&stepped), Some(want));
        assert_eq!(neighbour_noise(&[1.0]), None);
    }

    /// Against sorting, the definition itself, over random lengths and values, ties included.
    #[test]
    fn the_median_is_the_middle_of_the_sorted_values() {
        let mut rng = qfa_rng::seeded(5);
        for _ in 0..2000 {
            let n = qfa_rng::below(&mut rng, 40) + 1;
            let v: Vec<f64> = (0..n).map(|_| qfa_rng::below(&mut rng, 21) as f64 - 10.0).collect();
            let mut s = v.clone();
            s.sort_by(f64::total_cmp);
            let want = if n % 2 == 1 { s[n / 2] } else { 0.5 * (s[n / 2 - 1] + s[n / 2]) };
            assert_eq!(median(&v), Some(want), "{v:?}");
        }
        assert_eq!(median(&[]), None);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), Some(2.5));
    }

    /// The constant is 1/Φ⁻¹(0.75): Φ(1/MAD_TO_SD) = 0.75, with Φ from erf's series.
    #[test]
    fn the_mad_scale_is_the_normal_quartile() {
        let z = 1.0 / MAD_TO_SD;
        // Φ(z) = ½(1 + erf(z/√2)), erf by its Maclaurin series (converges fast at 0.48).
        let x = z / std::f64::consts::SQRT_2;
        let (mut term, mut sum) = (x, x);
        for k in 1..40 {
            term *= -x * x / k as f64;
            sum += term / (2 * k + 1) as f64;
        }
        let phi = 0.5 * (1.0 + 2.0 / std::f64::consts::PI.sqrt() * sum);
        assert!((phi - 0.75).abs() < 1e-14, "Φ = {phi}");
    }
}
