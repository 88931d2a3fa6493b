//! The change-point searches of a run ([`super::test`]): the difference of segment means
//! and the search whitened by the fitted model's Kalman filter, and where a split may fall.

use super::{Channels, NoiseModel, CLIP_SD, MIN_SEGMENT_BINS};
use qfa_log::robust::median;

/// The largest change-point |z| of a clipped run, with its split index and the
/// difference of means (after − before).
pub(super) fn max_split(model: &NoiseModel, v: &[f64]) -> Option<(f64, usize, f64)> {
    let n = v.len();
    if n < 2 * MIN_SEGMENT_BINS {
        return None;
    }
    let total: f64 = v.iter().sum();
    let mut s1 = v[..MIN_SEGMENT_BINS - 1].iter().sum::<f64>();
    let powers = model.powers(n);
    let mut best: Option<(f64, usize, f64)> = None;
    for m in MIN_SEGMENT_BINS..=n - MIN_SEGMENT_BINS {
        s1 += v[m - 1];
        let (a, b) = (m as f64, (n - m) as f64);
        let delta = (total - s1) / b - s1 / a;
        let var = powers.var_sum(n - m) / (b * b) + powers.var_sum(m) / (a * a)
            - 2.0 * powers.cov_adjacent(m, n - m) / (a * b);
        let z = delta.abs() / var.max(1e-300).sqrt();
        if best.is_none_or(|x| z > x.0) {
            best = Some((z, m, delta));
        }
    }
    best
}

/// A model's φ^k for k up to a run's length ([`NoiseModel::powers`]): the segment sums'
/// variances a split search asks for at every split, without a power per question.
pub(super) struct Powers<'a> {
    pub(super) model: &'a NoiseModel,
    pub(super) phi: f64,
    pub(super) pow: Vec<f64>,
}

impl Powers<'_> {
    /// Σ_{i,j<n} φ^|i−j|: the slow part's variance of a sum of `n` bins over Q.
    pub(super) fn sum_corr(&self, n: usize) -> f64 {
        let phi = self.phi;
        if phi < 1e-12 {
            return n as f64;
        }
        n as f64 * (1.0 + phi) / (1.0 - phi) - 2.0 * phi * (1.0 - self.pow[n]) / (1.0 - phi).powi(2)
    }

    /// [`NoiseModel::var_sum`] of `n` bins.
    pub(super) fn var_sum(&self, n: usize) -> f64 {
        self.model.white.powi(2) * n as f64 + self.model.slow_sd.powi(2) * self.sum_corr(n)
    }

    /// Covariance of the sums of two adjacent segments of `a` and `b` bins.
    pub(super) fn cov_adjacent(&self, a: usize, b: usize) -> f64 {
        let phi = self.phi;
        if phi < 1e-12 {
            return 0.0;
        }
        self.model.slow_sd.powi(2) * phi * (1.0 - self.pow[a]) * (1.0 - self.pow[b]) / (1.0 - phi).powi(2)
    }
}

/// Clip at [`CLIP_SD`] model SDs around the run's median.
pub(super) fn clipped(model: &NoiseModel, v: &[f64]) -> Vec<f64> {
    // An empty run has nothing to clip.
    let mid = median(v).unwrap_or(0.0);
    let c = CLIP_SD * model.total_sd();
    v.iter().map(|&x| x.clamp(mid - c, mid + c)).collect()
}

/// The largest change-point |z| of a run by generalized least squares under the model,
/// with its split index and the step (after − before): for each split `m`, the step's
/// coefficient in the regression of the run on a level and a step at `m`, both whitened by
/// the model's Kalman filter (state: the Gauss–Markov part, started at its stationary
/// variance; the run's innovations clipped at ±[`CLIP_SD`] SDs, the filter carried on with
/// the clipped value so that a glitch does not echo through its memory).
///
/// Under slow noise the difference of the two segments' means spends most of a step's
/// evidence on the slow part's wander; whitened, the jump at the split and the level after
/// it each count for what the model says they are worth.
///
/// O(n) per run for all its splits together (see [`gls_splits`]).
pub(super) fn max_split_gls(model: &NoiseModel, v: &[f64], allowed: &[bool]) -> Option<(f64, usize, f64)> {
    let n = v.len();
    if n < 2 * MIN_SEGMENT_BINS {
        return None;
    }
    gls_splits(model, v, (MIN_SEGMENT_BINS..=n - MIN_SEGMENT_BINS).filter(|&m| allowed.get(m).copied().unwrap_or(true)))
}

/// The Kalman filter of a model over `n` bins: each bin's gain and innovation variance.
pub(super) fn kalman_gains(model: &NoiseModel, n: usize) -> Vec<(f64, f64)> {
    let (w, q, phi) = (model.white.powi(2), model.slow_sd.powi(2), model.phi());
    let mut p = q;
    (0..n)
        .map(|_| {
            let f = (p + w).max(1e-300);
            let k = p / f;
            p = phi * phi * p * (1.0 - k) + q * (1.0 - phi * phi);
            (k, f)
        })
        .collect()
}

/// [`max_split_gls`] over the splits `splits` (each inside the run).
///
/// With `a_i = φ(1 − K_i)` and `P_i` the filter's prediction of the whitened level (a
/// column of ones from bin 0), a unit step entering at bin `m` is predicted at
/// `P_i − P_m·a_m·…·a_{i−1}` for `i ≥ m`, so its whitened column is the level's column
/// `c_i` plus `P_m·a_m·…·a_{i−1}/√F_i`. Its products with the innovations `u`, with `c` and
/// with itself are then suffix sums and three backward recursions, O(n) for all splits
/// together.
pub(super) fn gls_splits(
    model: &NoiseModel,
    v: &[f64],
    splits: impl Iterator<Item = usize>,
) -> Option<(f64, usize, f64)> {
    let n = v.len();
    let phi = model.phi();
    let gains = kalman_gains(model, n);
    let sd: Vec<f64> = gains.iter().map(|g| g.1.sqrt()).collect();
    // The run's innovations, clipped, in SDs; the filter goes on with the clipped value.
    let mut u = Vec::with_capacity(n);
    let mut pred = 0.0;
    for (i, &e) in v.iter().enumerate() {
        let k = gains[i].0;
        let nu = (e - pred).clamp(-CLIP_SD * sd[i], CLIP_SD * sd[i]);
        pred = phi * (pred + k * nu);
        u.push(nu / sd[i]);
    }
    // The level's prediction P_i and whitened column c_i.
    let (mut level_pred, mut c) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut pred = 0.0;
    for (i, &(k, _)) in gains.iter().enumerate() {
        level_pred.push(pred);
        let nu = 1.0 - pred;
        pred = phi * (pred + k * nu);
        c.push(nu / sd[i]);
    }
    // From bin m on: Σ c·u, Σ c², and the homogeneous response's products with u, with c
    // and with itself.
    let (mut cu_from, mut cc_from) = (vec![0.0; n + 1], vec![0.0; n + 1]);
    let (mut hu, mut hc, mut hh) = (vec![0.0; n + 1], vec![0.0; n + 1], vec![0.0; n + 1]);
    for i in (0..n).rev() {
        let a = phi * (1.0 - gains[i].0);
        cu_from[i] = cu_from[i + 1] + c[i] * u[i];
        cc_from[i] = cc_from[i + 1] + c[i] * c[i];
        hu[i] = u[i] / sd[i] + a * hu[i + 1];
        hc[i] = c[i] / sd[i] + a * hc[i + 1];
        hh[i] = 1.0 / gains[i].1 + a * a * hh[i + 1];
    }
    let (cc, cu) = (cc_from[0], cu_from[0]);
    let mut best: Option<(f64, usize, f64)> = None;
    for m in splits.filter(|&m| m > 0 && m < n) {
        let p = level_pred[m];
        let xu = cu_from[m] + p * hu[m];
        let xc = cc_from[m] + p * hc[m];
        let xx = cc_from[m] + 2.0 * p * hc[m] + p * p * hh[m];
        let num = xu - xc * cu / cc;
        let den = (xx - xc * xc / cc).max(1e-300);
        let z = num.abs() / den.sqrt();
        if best.is_none_or(|b| z > b.0) {
            best = Some((z, m, num / den));
        }
    }
    best
}

/// Seconds after a corner of the temperature program (its rate moving among heating,
/// hold and cooling, beyond the branch deadband) in which the whitened search places no
/// split: the start model's misfit at a corner is a transient that lasts a few of the
/// thermal chain's time constants (the lab simulator's case lags the air by 600 s, the
/// second generator's by 400 s), and whitened it weighs as a step's jump. Measured with
/// 10 minutes: 6 of the lab simulator's 120 clean logs reported a step 10 to 14 minutes
/// after a reversal of its slowest program (|z| 4.1 to 4.8), 9 of the second generator's
/// 100 clean logs were unexplained, and the real MEMS log had a step on two axes (steps
/// then sized by the whitened coefficient); with 30 minutes (three of the simulator's case
/// time constants; set after seeing those) and steps sized by the segments' means, 1, 6
/// and none, and the second generator's steps of draws 1448 and 1249 are still found. The
/// segment-means search has no such gap.
pub(crate) const CORNER_SKIP_S: f64 = 1800.0;

/// Per bin, in the order of the log's bins: whether a split may fall before it, i.e. it is
/// [`CORNER_SKIP_S`] or more after the last corner of its trace.
pub(super) fn split_allowed(ch: &Channels) -> Vec<bool> {
    let mut out = Vec::with_capacity(ch.n_bins());
    for t in &ch.traces {
        let (mut last, mut class, mut row) = (f64::NEG_INFINITY, None::<i8>, 0);
        for b in &t.bins {
            while row < b.hi {
                let c = qfa_log::replay::Motion::of(f64::from(t.est_rate[row])).sign();
                if class.is_some_and(|k| k != c) {
                    last = t.time_s[row];
                }
                class = Some(c);
                row += 1;
            }
            out.push(b.time_s - last >= CORNER_SKIP_S);
        }
    }
    out
}
