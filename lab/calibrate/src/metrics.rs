//! Figures of merit: the paper's Table-4 sensitivity and the bias residual.
//!
//! **Table 4 sensitivity** (paper §3.1): `(max − min)/(mean · span) · 10⁶` ppm/°C, where
//! max, min and mean are of the scale factor and `span` is the temperature span covered.
//!
//! **How the compensated scale factor is formed here.** Rows of the held-out ±1 g runs are
//! compensated by the root crate's compensator (accel in g). For each matched pair of rows
//! the compensated scale factor is `(a₊ − a₋)/2` (1 for a perfect model; for no
//! compensation, `a = A/γ̂` with a constant γ̂, i.e. the raw K1). These are averaged in
//! bins: one bin per (program, monotonic segment, 1 °C of T̂), where a segment is a
//! maximal stretch with one branch (hold, cooling, heating, cooling). Bins shorter than
//! `MIN_BIN_S` of data are dropped (edges). Max, min and mean are over all held-out bins
//! pooled, and `span` is the spread of the bins' mean temperatures. Averaging per 1 °C
//! per segment keeps heating/cooling loops (the hysteresis the paper's figure shows) but
//! removes the row-level noise the paper's figure also smooths away.
//!
//! **Bias residual** (µg): RMS over the same bins of the compensated bias
//! `(a₊ + a₋)/2` of the pairs and of the compensated output of the 0 g runs.

use std::collections::BTreeMap;

use qfa_thermal::model::Branch;

/// Bins with less data than this are dropped, s.
pub(crate) const MIN_BIN_S: f64 = 60.0;

/// Table-4 temperature sensitivity, ppm/°C, of scale-factor values `sf` observed at
/// temperatures `temps`. `None` with fewer than two points or no temperature span.
#[must_use]
pub(crate) fn sensitivity_ppm_per_c(sf: &[f64], temps: &[f64]) -> Option<f64> {
    if sf.len() < 2 || sf.len() != temps.len() {
        return None;
    }
    let max = sf.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min = sf.iter().copied().fold(f64::INFINITY, f64::min);
    let mean = sf.iter().sum::<f64>() / sf.len() as f64;
    let tmax = temps.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let tmin = temps.iter().copied().fold(f64::INFINITY, f64::min);
    let span = tmax - tmin;
    if span <= 0.0 || mean == 0.0 {
        return None;
    }
    Some((max - min) / (mean * span) * 1e6)
}

/// Means of `values` over consecutive time bins of `bin_s` (row times `time_s`, s): one
/// `(bin, mean, rows)` per run of rows whose `floor(t / bin_s)` is the same, in row order.
/// The one binning of the held-out 60-s figure, the fleet's per-minute temperatures and
/// the population prior's noise.
#[must_use]
pub fn time_bin_means(values: impl IntoIterator<Item = f64>, time_s: &[f64], bin_s: f64) -> Vec<(i64, f64, usize)> {
    let mut out = Vec::new();
    let (mut key, mut s, mut n) = (i64::MIN, 0.0, 0usize);
    for (v, &t) in values.into_iter().zip(time_s) {
        let k = (t / bin_s).floor() as i64;
        if k != key && n > 0 {
            out.push((key, s / n as f64, n));
            s = 0.0;
            n = 0;
        }
        key = k;
        s += v;
        n += 1;
    }
    if n > 0 {
        out.push((key, s / n as f64, n));
    }
    out
}

/// RMS of `v`.
#[must_use]
pub fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

/// RMS of the finite values of `v` (0 when none is): for series where NaN marks a bin
/// without that channel (a single-channel log has no scale-factor channel), as the
/// discovery's residuals do.
#[must_use]
pub fn rms_of_finite(v: &[f64]) -> f64 {
    let (s, n) = v.iter().filter(|x| x.is_finite()).fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    if n == 0 {
        0.0
    } else {
        (s / n as f64).sqrt()
    }
}

/// One temperature bin of one segment.
#[derive(Clone, Debug, PartialEq)]
pub struct Bin {
    /// Program id.
    pub program: String,
    /// Segment index within the run (0 = first branch stretch).
    pub segment: usize,
    /// Branch of the segment.
    pub branch: Branch,
    /// Mean T̂, °C.
    pub temp_c: f64,
    /// Mean time, s.
    pub time_s: f64,
    /// Mean value (scale factor or bias).
    pub value: f64,
    /// Seconds of data.
    pub seconds: f64,
}

/// Bin accumulator: Σw, Σw·T, Σw·t, Σw·v, branch.
type Acc = (f64, f64, f64, f64, Branch);

/// Bin a per-row series by (segment, 1 °C of temperature); rows where `use_row` is false
/// are skipped. `interval_s[i]` weights row `i`.
#[must_use]
#[allow(clippy::too_many_arguments)]
pub(crate) fn bin_series(
    program: &str,
    temp_c: &[f64],
    branch: &[Branch],
    time_s: &[f64],
    interval_s: &[f64],
    value: &[f64],
    use_row: &[bool],
) -> Vec<Bin> {
    let mut seg = 0usize;
    let mut prev: Option<Branch> = None;
    // (segment, bin) → (Σw, Σw·T, Σw·t, Σw·v, branch)
    let mut acc: BTreeMap<(usize, i64), Acc> = BTreeMap::new();
    for i in 0..value.len() {
        if prev.is_some_and(|p| p != branch[i]) {
            seg += 1;
        }
        prev = Some(branch[i]);
        if !use_row[i] || !temp_c[i].is_finite() || !value[i].is_finite() {
            continue;
        }
        let w = interval_s[i];
        let e = acc.entry((seg, temp_c[i].floor() as i64)).or_insert((0.0, 0.0, 0.0, 0.0, branch[i]));
        e.0 += w;
        e.1 += w * temp_c[i];
        e.2 += w * time_s[i];
        e.3 += w * value[i];
    }
    acc.into_iter()
        .filter(|(_, a)| a.0 >= MIN_BIN_S)
        .map(|((segment, _), a)| Bin {
            program: program.to_string(),
            segment,
            branch: a.4,
            temp_c: a.1 / a.0,
            time_s: a.2 / a.0,
            value: a.3 / a.0,
            seconds: a.0,
        })
        .collect()
}

/// Table-4 sensitivity of a set of scale-factor bins.
#[must_use]
pub(crate) fn bins_sensitivity(bins: &[Bin]) -> Option<f64> {
    let v: Vec<f64> = bins.iter().map(|b| b.value).collect();
    let t: Vec<f64> = bins.iter().map(|b| b.temp_c).collect();
    sensitivity_ppm_per_c(&v, &t)
}

#[cfg(test)]
mod tests {

    /// Bins follow the rows' times, a run of rows per bin, means and counts exact.
    #[test]
    fn time_bin_means_cut_where_the_bin_changes() {
        let b = time_bin_means([1.0, 2.0, 3.0, 4.0, 5.0], &[0.0, 30.0, 60.0, 61.0, 185.0], 60.0);
        assert_eq!(b, vec![(0, 1.5, 2), (1, 3.5, 2), (3, 5.0, 1)]);
        assert!(time_bin_means([], &[], 60.0).is_empty());
    }
    use super::*;

    #[test]
    fn sensitivity_hand_computed() {
        // Values 99, 100, 101 (mean 100) over 0..10 °C: (101 − 99)/(100·10)·1e6 = 2000.
        let s = sensitivity_ppm_per_c(&[100.0, 99.0, 101.0], &[0.0, 5.0, 10.0]).unwrap();
        assert!((s - 2000.0).abs() < 1e-9, "{s}");
        // The paper's own example: X − Y = 10 010 ppm of A over 135 °C ⇒ 74.15 ppm/°C.
        let a = 320_000.0;
        let x = a * (1.0 + 5005e-6);
        let y = a * (1.0 - 5005e-6);
        let s = sensitivity_ppm_per_c(&[x, a, y], &[-54.0, 10.0, 81.0]).unwrap();
        assert!((s - 10_010.0 / 135.0).abs() < 1e-6, "{s}");
        // A constant scale factor has zero sensitivity; no span is undefined.
        assert_eq!(sensitivity_ppm_per_c(&[5.0, 5.0], &[0.0, 1.0]), Some(0.0));
        assert_eq!(sensitivity_ppm_per_c(&[5.0, 6.0], &[1.0, 1.0]), None);
        assert_eq!(sensitivity_ppm_per_c(&[5.0], &[1.0]), None);
    }

    #[test]
    fn bins_split_segments_and_drop_short_bins() {
        // 200 s heating through 0.0..1.99 °C, then 200 s cooling back: 2 segments × 2 bins.
        let n = 400;
        let temp: Vec<f64> =
            (0..n).map(|i| if i < 200 { i as f64 / 100.0 } else { (399 - i) as f64 / 100.0 }).collect();
        let br: Vec<Branch> = (0..n).map(|i| if i < 200 { Branch::Heating } else { Branch::Cooling }).collect();
        let time: Vec<f64> = (0..n).map(f64::from).collect();
        let ones = vec![1.0; n as usize];
        let val: Vec<f64> = (0..n).map(|i| if i < 200 { 1.0 } else { 3.0 }).collect();
        let mut use_row = vec![true; n as usize];
        use_row[0] = false;
        let bins = bin_series("p", &temp, &br, &time, &ones, &val, &use_row);
        assert_eq!(bins.len(), 4);
        assert_eq!(bins[0].seconds, 99.0);
        assert_eq!((bins[0].segment, bins[2].segment), (0, 1));
        assert_eq!(bins[1].value, 1.0);
        assert_eq!(bins[3].value, 3.0);
        assert_eq!(bins[2].branch, Branch::Cooling);
        // Hand: heating bin 1 holds 1.00..1.99 °C → mean 1.495.
        assert!((bins[1].temp_c - 1.495).abs() < 1e-12);
        let s = bins_sensitivity(&bins).unwrap();
        // Bin means: heating 0.5 (0.01..0.99), 1.495; cooling 1.495, 0.495 (0.99..0.00).
        // Values 1, 1, 3, 3 → mean 2; span 1.495 − 0.495 = 1.0 ⇒ (3 − 1)/(2 · 1.0) · 1e6.
        let want = 1.0e6;
        assert!((s - want).abs() < 1e-6, "{s} vs {want}");
    }
}
