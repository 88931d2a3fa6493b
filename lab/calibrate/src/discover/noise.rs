//! The residual's noise, fitted rather than assumed: white noise plus a first-order
//! Gauss–Markov process, estimated robustly from the residual's own differences, and the
//! tests that decide whether that noise model explains what is left.
//!
//! # The model
//! A channel's held-out residual, bin by bin within each run, is modelled as
//! `e_i = w_i + g_i`: white noise of variance `W` plus a Gauss–Markov process of variance
//! `Q` and correlation time `τ` (φ = exp(−Δt/τ) per bin of Δt). Its structure function
//! is `D(k) = E[(e_{i+k} − e_i)²] = 2W + 2Q(1 − φ^k)`; a random walk is the long-τ end of
//! the same family (2Q(1 − φ^k) ≈ 2Q·kΔt/τ while kΔt ≪ τ).
//!
//! # The fit (robust)
//! `D(k)` is estimated at 12 lags from 1 to 64 bins as (1.4826 × the median of
//! |e_{i+k} − e_i|)² over pairs inside one run, and `D(∞) = 2(W + Q)` from 1.4826 × the
//! median absolute deviation of each run about its median, so that the model never claims
//! more variance than the runs show: medians, not mean squares, so rare glitches, a step,
//! or the jumps at a hysteresis loop's reversals move it by the share of pairs they touch,
//! not by their size. `W` and `Q` are fitted by
//! non-negative least squares on the relative error of `D(k)` for each `τ` on a 48-point
//! log grid from 2 to 2 000 bins (a shorter correlation time is white noise at this
//! bin width, and the two cannot be told apart), and the best `τ` is kept.
//!
//! # The noise floor
//! The channel's noise floor is the model's bin-to-bin noise, `√(D(1)/2) = √(W + Q(1 − φ))`
//! ([`NoiseModel::floor`]): the SD of one bin's noise against its neighbour. It is not the
//! white part alone. On a residual whose bin-to-bin variation the slow part explains
//! entirely, the fit puts `W` at its bound 0, and a floor of `√W` made the report print a
//! held-out residual of 10¹⁵ times its floor (a real log's z axis) and gave that channel
//! an almost infinite weight in the parameter search.
//!
//! # The tests the model must pass ([`NoiseTest`])
//! "Slow noise can explain it" is only said when the fitted model is not rejected against
//! a structured alternative. The alternatives tested here:
//! * **a change point per run**: for every run and every split with at least
//!   [`MIN_SEGMENT_BINS`] bins each side, the difference of the two segments' means over
//!   its SD under the fitted model (exact for white + Gauss–Markov, from closed-form
//!   sums of φ^|i−j|); the statistic is the largest |z| over all runs and splits. Its
//!   critical value is the (1 − α) quantile of the same maximum over [`NULL_DRAWS`] series
//!   drawn from the fitted model with the same run lengths, each refitted and tested
//!   against its own fit as the log is: the multiplicity of the search (every split of
//!   every run) and the fit's own error are in the null distribution, not assumed away.
//!   Tested against the model that drew them instead, 50 of 200 Gauss–Markov series
//!   (τ 30 bins, the lab simulator's bias instability) were rejected at level 0.1: a
//!   series whose slow part is fitted low reads its own wander as a step. Residuals
//!   are clipped at 4 SD of the model's total before the test (and so are the draws), so a
//!   single glitch cannot pose as a step; and the step must be at least
//!   [`STEP_MIN_FLOORS`] noise floors (the bin-to-bin noise; why: its doc).
//!
//!   On a cycling log the search also runs on each position's reading: `+1 g reading` =
//!   bias + scale-factor residual and `−1 g reading` = bias − scale-factor residual, in
//!   the bias unit (with `A = K1·(K0 + a)`, a change δ in one position's reading moves K1
//!   by ±δ/2 as a fraction and K0 by δ/2). A bias step in one position's run (a shock, a
//!   pendulum settling) is whole there and half in each channel, where it can pass the
//!   z test and fail the size rule (a 10.7-µg step with noise that grows with
//!   temperature: |z| 7.5 and 6.6, each half under 3 floors, nothing reported). Each
//!   reading has its own fitted model, and the change-point and run-noise tests share
//!   the level over the four series (the branch test over the two channels).
//!
//!   The same split search also runs by generalized least squares ([`max_split_gls`]):
//!   at each split, the step's coefficient in the regression of the run on a level and a
//!   step, both whitened by the model's Kalman filter. Where the slow part is large, the
//!   difference of the segments' means spends a step's evidence on its wander: a 7.1-µg
//!   bias step alone (the second generator's draw 1448; its +1 g reading fitted white
//!   1.4 + Gauss–Markov 2.3 µg, τ 68 min) reached |z| 2.9 against 4.9 by means and 7.0
//!   against 4.9 whitened. The whitened search places no split within [`CORNER_SKIP_S`]
//!   after a corner of the temperature program. The two searches share the level: their
//!   critical values are the k-th largest of each over the same null draws, k the largest
//!   for which at most α of the draws exceed either ([`joint_criticals`]), and a step is
//!   reported from the search further past its critical value ([`ChangePoint::search`]),
//!   sized by the difference of the segments' means at its split.
//! * **a level per run**: the runs' clipped mean residuals against the model's SE of a
//!   run mean (`unexplained::run_levels`).
//! * **a run noisier than the others**: the largest run's bin-to-bin noise (1.4826 × the
//!   median |difference of neighbouring bins| / √2) over the median run's, against the
//!   same maximum over the [`NULL_DRAWS`] series, and at least [`RUN_NOISE_MIN_RATIO`]
//!   (why: its doc). From differences, so that a step or a wander inside a run, which the
//!   other alternatives test, is not read as noise.
//! * **a scale-factor level by ramp branch** (cycling logs; [`branch_test`]): the
//!   generalized-least-squares slope of the residual on the branch (±1, a dwell with the
//!   ramp before it) under the fitted model, the 10 minutes after each reversal left out
//!   so that corner transients do not pose as a level; |z| against z(1 − α/2). No size
//!   is asked of the level, unlike a step: the test holds its level on clean logs (the
//!   second generator's 100: 4 over the two-sided 2.5 % critical value, all 0.09–0.14
//!   ppm), and a rule of 3 white SDs left scale-factor hystereses of 3.3 to 8.8 ppm silent
//!   at |z| 4.7 to 5.4 (the white part grows with temperature-dependent noise; the z
//!   already counts how long a level lasts). The catalog has no scale-factor term by
//!   branch, and the timing offset takes part of one on the ramps (a 9.9-ppm hysteresis
//!   moved it from +11.1 to −1.3 s with nothing reported).
//! * **a trend, the branch, temperature, Ṫ, time since a reversal**: the drivers' block
//!   test (`unexplained::find_unexplained`).

use serde::Serialize;

use super::Channels;
use qfa_log::robust::{median, neighbour_noise, MAD_TO_SD};
use qfa_rng::{normal, seeded};

/// Lags of the structure function, bins.
const LAGS: [usize; 12] = [1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64];
/// Fewest pairs a lag needs to enter the fit.
const MIN_PAIRS: usize = 30;
/// Shortest segment either side of a change point, bins (5 min of 60-s bins: a step must
/// hold for that long to be told from a burst of noise).
pub(crate) const MIN_SEGMENT_BINS: usize = 5;
/// Series drawn from the fitted model for the change-point test's critical value.
pub(crate) const NULL_DRAWS: usize = 400;
/// A change point is structure only when its step is also at least this many noise floors
/// ([`NoiseModel::floor`], the bin-to-bin noise). Set after the first study: on 40 clean
/// logs of the first independent generator the fitted model's null alone rejected 7 times
/// (|z| 3.6–4.4 against 3.5–3.9), every time for a step of 1.1–2.4 white SDs; the 40-µg
/// step of the second generator's test is 18 (the held-out residual's departures from
/// white + Gauss–Markov near ramp corners make the null's tail too light, so a size is
/// asked of a step as of a run level). The yardstick was the white part at first, which the
/// fit puts at 0 when a short-τ slow part takes the bin-to-bin noise (a real MEMS log's y
/// and z axes): the rule then asked nothing. Where white noise dominates the floor is the
/// white SD within a few per cent. Measured again once the null refitted each draw (so that
/// it holds its level on the lab simulator): without the rule 18 of 100 clean logs of the
/// second generator and 7 of 100 of the first were reported unexplained, at 2 floors 9
/// and 1, at 3 floors 7 and 1; kept at 3, the value set before that.
pub(crate) const STEP_MIN_FLOORS: f64 = 3.0;
/// Residuals are clipped at this many SDs of the model's total before the change-point
/// and run-level tests.
pub(crate) const CLIP_SD: f64 = 4.0;

/// A channel's fitted noise: white plus Gauss–Markov (see the module docs).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct NoiseModel {
    /// SD of the white part per bin, residual unit (0 when the fit puts it at its bound;
    /// stored as at least 10⁻¹²).
    pub white: f64,
    /// SD of the Gauss–Markov part, residual unit.
    pub slow_sd: f64,
    /// Correlation time of the Gauss–Markov part, s.
    pub tau_s: f64,
    /// Bin spacing the model was fitted on, s.
    pub bin_s: f64,
    /// Lags that entered the fit.
    pub lags: usize,
}

impl NoiseModel {
    /// Per-bin correlation of the slow part.
    #[must_use]
    pub(crate) fn phi(&self) -> f64 {
        (-self.bin_s / self.tau_s).exp()
    }

    /// The channel's noise floor: the bin-to-bin noise `√(W + Q(1 − φ))` (see the module
    /// docs), residual unit; positive whenever the residual varies.
    #[must_use]
    pub fn floor(&self) -> f64 {
        (self.white.powi(2) + self.slow_sd.powi(2) * (1.0 - self.phi())).sqrt()
    }

    /// SD of one bin's total noise.
    #[must_use]
    pub(crate) fn total_sd(&self) -> f64 {
        (self.white.powi(2) + self.slow_sd.powi(2)).sqrt()
    }

    /// Variance of the sum of `n` consecutive bins.
    #[must_use]
    pub(crate) fn var_sum(&self, n: usize) -> f64 {
        self.powers(n).var_sum(n)
    }

    /// Variance of the mean of `n` consecutive bins.
    #[must_use]
    pub(crate) fn var_mean(&self, n: usize) -> f64 {
        self.var_sum(n) / (n as f64).powi(2).max(1.0)
    }

    /// φ^k for k = 0..=`n`, for the segment sums' variances of a search over splits.
    fn powers(&self, n: usize) -> Powers<'_> {
        let phi = self.phi();
        Powers { model: self, phi, pow: (0..=n).map(|k| phi.powf(k as f64)).collect() }
    }

    /// The innovations form of the model: white + Gauss–Markov is ARMA(1, 1),
    /// `e_i − φ·e_{i−1} = u_i − θ·u_{i−1}` with `u` white. Returns (θ, SD of `u`), θ the
    /// invertible root of θ/(1 + θ²) = φW/γ₀, γ₀ = W(1 + φ²) + Q(1 − φ²) the variance of
    /// `e_i − φ·e_{i−1}` (its lag-1 covariance is −φW, and later ones vanish).
    #[must_use]
    fn innovations(&self) -> (f64, f64) {
        let (w, q, phi) = (self.white.powi(2), self.slow_sd.powi(2), self.phi());
        let g0 = w * (1.0 + phi * phi) + q * (1.0 - phi * phi);
        let c = if g0 > 0.0 { phi * w / g0 } else { 0.0 };
        let theta = if c < 1e-12 { 0.0 } else { (1.0 - (1.0 - 4.0 * c * c).max(0.0).sqrt()) / (2.0 * c) };
        (theta, (g0 / (1.0 + theta * theta)).max(1e-300).sqrt())
    }

    /// `v` whitened under this model, run by run: the innovations `u` of the ARMA(1, 1)
    /// form ([`Self::innovations`]), each in SDs of `u`, clipped at ±[`CLIP_SD`] so that a
    /// glitch weighs as one large bin, not as its size. A run's first bin, and the first
    /// after a missing one, restarts the filter at the model's stationary SD. Missing
    /// bins stay NaN.
    ///
    /// Why: a selection test on the raw residual counts slow noise as evidence and needs
    /// blocks longer than its correlation time, which leaves 6 to 8 blocks on a cycling
    /// log; in the whitened residual the same held-out gain is generalized least squares
    /// under the fitted model, and blocks can be short.
    #[must_use]
    pub(crate) fn whiten(&self, ch: &Channels, v: &[f64]) -> Vec<f64> {
        let (theta, sd_u) = self.innovations();
        let (phi, sd0) = (self.phi(), self.total_sd().max(1e-300));
        let mut out = vec![f64::NAN; v.len()];
        let mut o = 0;
        for t in &ch.traces {
            let mut prev: Option<(f64, f64)> = None;
            for i in o..o + t.bins.len() {
                let e = v[i];
                if !e.is_finite() {
                    prev = None;
                    continue;
                }
                let u = match prev {
                    None => e * sd_u / sd0,
                    Some((e1, u1)) => e - phi * e1 + theta * u1,
                };
                prev = Some((e, u));
                out[i] = (u / sd_u).clamp(-CLIP_SD, CLIP_SD);
            }
            o += t.bins.len();
        }
        out
    }

    /// In words, with `unit`.
    #[must_use]
    pub(crate) fn text(&self, unit: &str) -> String {
        format!(
            "white {:.3} {unit} per bin + Gauss–Markov {:.3} {unit} (τ {:.0} min)",
            self.white,
            self.slow_sd,
            self.tau_s / 60.0
        )
    }
}

/// The runs of `r` (one per trace), finite values only, in time order, with their bins'
/// times (s).
pub(crate) fn runs_of(ch: &Channels, r: &[f64]) -> Vec<(usize, Vec<f64>, Vec<f64>)> {
    let mut out = Vec::new();
    let mut o = 0;
    for (k, t) in ch.traces.iter().enumerate() {
        let m = t.bins.len();
        let (mut v, mut time) = (Vec::new(), Vec::new());
        for (i, b) in t.bins.iter().enumerate() {
            if r[o + i].is_finite() {
                v.push(r[o + i]);
                time.push(b.time_s);
            }
        }
        o += m;
        out.push((k, v, time));
    }
    out
}

/// |x − median| for each value of a non-empty run (the median absolute deviation's terms:
/// the long-lag level of the fit takes its SD from them).
fn abs_deviations(v: &[f64]) -> Vec<f64> {
    // An empty run has no deviations, whatever the centre.
    let mid = median(v).unwrap_or(0.0);
    v.iter().map(|x| (x - mid).abs()).collect()
}

/// Fit the noise model to residual `r` (see the module docs).
#[must_use]
pub(crate) fn fit(ch: &Channels, r: &[f64]) -> NoiseModel {
    let runs = runs_of(ch, r);
    let spacing: Vec<f64> =
        runs.iter().flat_map(|(_, _, t)| t.windows(2).map(|w| w[1] - w[0])).filter(|d| *d > 0.0).collect();
    let bin_s = median(&spacing).unwrap_or(60.0);
    let values: Vec<&[f64]> = runs.iter().map(|(_, v, _)| v.as_slice()).collect();
    fit_runs(&values, bin_s)
}

/// [`fit`] on runs of finite values `runs`, bins `bin_s` apart.
fn fit_runs(runs: &[&[f64]], bin_s: f64) -> NoiseModel {
    let mut d = Vec::new();
    for &k in &LAGS {
        let diffs: Vec<f64> = runs.iter().flat_map(|v| v.windows(k + 1).map(|w| (w[k] - w[0]).abs())).collect();
        let (true, Some(mad)) = (diffs.len() >= MIN_PAIRS, median(&diffs)) else { break };
        let s = MAD_TO_SD * mad;
        d.push((k as f64, (s * s).max(1e-300)));
    }
    // The residual's own variance bounds the model's: D(∞) = 2(W + Q), from the runs'
    // median absolute deviations about their medians (robust as the lags are). Without it
    // a residual whose differences still grew at the longest lag took the long-τ end of
    // the family: a scale-factor hysteresis's residual of 5.4 ppm RMS got a slow part of
    // SD 30 ppm (τ 33 h), against which no change point or run level could show. Slow
    // noise with τ near a run's length is then partly a level per run, which the run-level
    // test weighs.
    let dev: Vec<f64> = runs.iter().filter(|v| !v.is_empty()).flat_map(|v| abs_deviations(v)).collect();
    let far = match median(&dev) {
        Some(mad) if !d.is_empty() && dev.len() >= MIN_PAIRS => {
            let s = MAD_TO_SD * mad;
            Some(2.0 * (s * s).max(1e-300))
        }
        _ => None,
    };
    if d.is_empty() {
        let all: Vec<f64> = runs.iter().flat_map(|v| v.iter().copied()).collect();
        let sd = if all.len() > 1 { crate::metrics::rms_of_finite(&all) } else { 1.0 };
        return NoiseModel { white: sd.max(1e-12), slow_sd: 0.0, tau_s: bin_s, bin_s, lags: 0 };
    }
    let mut best: Option<(f64, NoiseModel)> = None;
    for g in 0..48 {
        let tau_bins = 2.0 * (1000.0f64).powf(f64::from(g) / 47.0);
        // Relative least squares: rows (2, 2(1 − φ^k)) / D_k against 1.
        let rows: Vec<(f64, f64)> = d
            .iter()
            .map(|&(k, dk)| (2.0 / dk, 2.0 * (1.0 - (-k / tau_bins).exp()) / dk))
            .chain(far.map(|df| (2.0 / df, 2.0 / df)))
            .collect();
        let (w, q) = nnls2(&rows);
        let sse: f64 = rows.iter().map(|&(a, b)| (a * w + b * q - 1.0).powi(2)).sum();
        if best.as_ref().is_none_or(|b| sse < b.0) {
            best = Some((
                sse,
                NoiseModel {
                    white: w.max(0.0).sqrt().max(1e-12),
                    slow_sd: q.max(0.0).sqrt(),
                    tau_s: tau_bins * bin_s,
                    bin_s,
                    lags: d.len(),
                },
            ));
        }
    }
    best.map(|b| b.1).expect("48 grid points")
}

/// Non-negative least squares of Σ (a·w + b·q − 1)² over w, q ≥ 0.
fn nnls2(rows: &[(f64, f64)]) -> (f64, f64) {
    let (saa, sab, sbb) = rows.iter().fold((0.0, 0.0, 0.0), |s, &(a, b)| (s.0 + a * a, s.1 + a * b, s.2 + b * b));
    let (sa, sb) = rows.iter().fold((0.0, 0.0), |s, &(a, b)| (s.0 + a, s.1 + b));
    let det = saa * sbb - sab * sab;
    if det.abs() > 1e-12 * saa * sbb {
        let w = (sa * sbb - sb * sab) / det;
        let q = (sb * saa - sa * sab) / det;
        if w >= 0.0 && q >= 0.0 {
            return (w, q);
        }
    }
    let only_w = (sa / saa.max(1e-300)).max(0.0);
    let only_q = (sb / sbb.max(1e-300)).max(0.0);
    let cost = |w: f64, q: f64| rows.iter().map(|&(a, b)| (a * w + b * q - 1.0).powi(2)).sum::<f64>();
    if cost(only_w, 0.0) <= cost(0.0, only_q) {
        (only_w, 0.0)
    } else {
        (0.0, only_q)
    }
}

/// The largest change-point |z| of a clipped run, with its split index and the
/// difference of means (after − before).
fn max_split(model: &NoiseModel, v: &[f64]) -> Option<(f64, usize, f64)> {
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
struct Powers<'a> {
    model: &'a NoiseModel,
    phi: f64,
    pow: Vec<f64>,
}

impl Powers<'_> {
    /// Σ_{i,j<n} φ^|i−j|: the slow part's variance of a sum of `n` bins over Q.
    fn sum_corr(&self, n: usize) -> f64 {
        let phi = self.phi;
        if phi < 1e-12 {
            return n as f64;
        }
        n as f64 * (1.0 + phi) / (1.0 - phi) - 2.0 * phi * (1.0 - self.pow[n]) / (1.0 - phi).powi(2)
    }

    /// [`NoiseModel::var_sum`] of `n` bins.
    fn var_sum(&self, n: usize) -> f64 {
        self.model.white.powi(2) * n as f64 + self.model.slow_sd.powi(2) * self.sum_corr(n)
    }

    /// Covariance of the sums of two adjacent segments of `a` and `b` bins.
    fn cov_adjacent(&self, a: usize, b: usize) -> f64 {
        let phi = self.phi;
        if phi < 1e-12 {
            return 0.0;
        }
        self.model.slow_sd.powi(2) * phi * (1.0 - self.pow[a]) * (1.0 - self.pow[b]) / (1.0 - phi).powi(2)
    }
}

/// Clip at [`CLIP_SD`] model SDs around the run's median.
fn clipped(model: &NoiseModel, v: &[f64]) -> Vec<f64> {
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
fn max_split_gls(model: &NoiseModel, v: &[f64], allowed: &[bool]) -> Option<(f64, usize, f64)> {
    let n = v.len();
    if n < 2 * MIN_SEGMENT_BINS {
        return None;
    }
    gls_splits(model, v, (MIN_SEGMENT_BINS..=n - MIN_SEGMENT_BINS).filter(|&m| allowed.get(m).copied().unwrap_or(true)))
}

/// The Kalman filter of a model over `n` bins: each bin's gain and innovation variance.
fn kalman_gains(model: &NoiseModel, n: usize) -> Vec<(f64, f64)> {
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
fn gls_splits(model: &NoiseModel, v: &[f64], splits: impl Iterator<Item = usize>) -> Option<(f64, usize, f64)> {
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
fn split_allowed(ch: &Channels) -> Vec<bool> {
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

/// A change point inside one run.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ChangePoint {
    /// The series it was found in ([`NoiseTest::series`]).
    pub series: String,
    /// The run: its id, and its place in the log (a cycling log's run is a program's pair
    /// of ±1 g runs, whose K1 and K0 each carry half a step in one of them).
    pub run: String,
    /// Time of the change since the run's start, h.
    pub at_h: f64,
    /// Level after minus level before: the difference of the two segments' clipped means
    /// at the split, whichever search found it (residual unit).
    pub size: f64,
    /// Its |z| under the fitted noise model.
    pub z: f64,
    /// The search that found it: `segment means` or `whitened` (see [`NoiseTest`]).
    pub search: String,
    /// That search's critical value (see [`NoiseTest::critical`]).
    pub critical: f64,
}

/// A run counts as noisier only when its noise is at least this many times the median
/// run's. Set after seeing both sides, when a run's noise was its SD about its median:
/// clean logs of the lab simulator reached 1.51× (its scale-factor noise varies with the
/// program's rate) and the second generator's 1.11×; its bad runs (five times the white
/// noise and a 10-µg wander) read 2.26–4.44×. Kept for the bin-to-bin noise that replaced
/// it: the 16 bad runs of the second generator's 600 draws are all still reported, and
/// no clean log of the lab simulator's 120 reports a noisy run. Twice the SD is four
/// times the variance: a run worth a look.
pub(crate) const RUN_NOISE_MIN_RATIO: f64 = 2.0;
/// Fewest values a run needs to enter the run-noise test.
const RUN_NOISE_MIN_BINS: usize = 20;

/// A run noisier than the fitted (stationary) noise model allows.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct NoisyRun {
    /// The series it was found in ([`NoiseTest::series`]).
    pub series: String,
    /// The run: its id, and its place in the log.
    pub run: String,
    /// Its bin-to-bin noise (1.4826 × the median |difference of neighbouring bins| / √2)
    /// over the median run's.
    pub ratio: f64,
}

/// The largest run's bin-to-bin noise over the median run's (runs of
/// [`RUN_NOISE_MIN_BINS`] values or more, at least 3 of them), and that run's index in
/// `runs`. A run's bin-to-bin noise is 1.4826 × the median |difference of neighbouring
/// values| / √2: a step or a slow wander inside the run moves one difference, or each a
/// little, where it moved the run's SD about its median by its size (a 10-µg step in one
/// position's run of the second generator's draw 33 was reported as a noisier bias run,
/// beside the scale factor's change point; the change-point test is the one that asks
/// about steps).
fn max_run_noise(runs: &[&[f64]]) -> Option<(f64, usize)> {
    let sds: Vec<(usize, f64)> = runs
        .iter()
        .enumerate()
        .filter(|(_, v)| v.len() >= RUN_NOISE_MIN_BINS)
        // At least RUN_NOISE_MIN_BINS bins: never `None`.
        .map(|(k, v)| (k, neighbour_noise(v).unwrap_or(0.0)))
        .collect();
    if sds.len() < 3 {
        return None;
    }
    let all: Vec<f64> = sds.iter().map(|x| x.1).collect();
    let mid = median(&all).unwrap_or(0.0).max(1e-300);
    sds.iter().map(|&(k, sd)| (sd / mid, k)).max_by(|a, b| a.0.total_cmp(&b.0))
}

impl NoiseTest {
    /// A fitted model that no alternative was tested against (no run long enough to
    /// search); the tests' fields are filled in by whoever runs them.
    #[must_use]
    pub(crate) fn untested(series: &str, model: NoiseModel, runs_searched: usize) -> Self {
        Self {
            series: series.into(),
            model,
            runs_searched,
            max_z: None,
            critical: None,
            whitened_max_z: None,
            whitened_critical: None,
            change_point: None,
            max_run_noise: None,
            run_noise_critical: None,
            noisy_run: None,
            branch_z: None,
            branch_critical: None,
            branch_level: None,
        }
    }
}

/// Seconds after a ramp reversal left out of the branch test: the rate estimator's delay
/// and the thermal chain's corner transients live there, not a branch's level.
const BRANCH_SKIP_S: f64 = 600.0;

/// A scale-factor level by ramp branch that the fitted noise model rejects.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct BranchLevel {
    /// Half the heating branch's level minus the cooling branch's (a dwell belongs to
    /// the ramp before it), residual unit.
    pub size: f64,
    /// Its z under the fitted model (generalized least squares).
    pub z: f64,
    /// The critical value |z| passed, z(1 − α/2).
    pub critical: f64,
}

/// The noise model against the change-point and branch-level alternatives.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct NoiseTest {
    /// The series tested: a channel (`scale_factor`, `bias`, `value`) or, on a cycling
    /// log, one position's reading (`+1 g reading` = K0 + K1 residual, `−1 g reading` =
    /// K0 − K1 residual, in the bias unit; see the module docs).
    pub series: String,
    /// The fitted model.
    pub model: NoiseModel,
    /// Runs long enough to search (2 × [`MIN_SEGMENT_BINS`] bins or more).
    pub runs_searched: usize,
    /// Largest |z| over every split of every run searched; absent when none was.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_z: Option<f64>,
    /// Its critical value at the test's level, from [`NULL_DRAWS`] series of the model;
    /// absent when no run was searched.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub critical: Option<f64>,
    /// The same search by generalized least squares under the fitted model (a level and a
    /// step, both whitened; no split in the 10 minutes after a corner of the temperature
    /// program): its largest |z|; absent when no run was searched.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub whitened_max_z: Option<f64>,
    /// Its critical value. It and `critical` hold the test's level jointly, from the same
    /// [`NULL_DRAWS`] series: each is a little higher than it would be alone.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub whitened_critical: Option<f64>,
    /// The split that gave `max_z` or `whitened_max_z` (the one further past its critical
    /// value), when the model is rejected.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub change_point: Option<ChangePoint>,
    /// The noisiest run's bin-to-bin noise over the median run's; absent with fewer than 3
    /// runs of [`RUN_NOISE_MIN_BINS`] values.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_run_noise: Option<f64>,
    /// Its critical value at the test's level, from the same [`NULL_DRAWS`] series.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub run_noise_critical: Option<f64>,
    /// That run, when the model is rejected and its ratio is at least
    /// [`RUN_NOISE_MIN_RATIO`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noisy_run: Option<NoisyRun>,
    /// The branch test's |z| (a cycling log's scale factor only: the catalog has no
    /// scale-factor term by branch; the bias has `bias_branch_hysteresis`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub branch_z: Option<f64>,
    /// Its critical value, z(1 − α/2).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub branch_critical: Option<f64>,
    /// The level by branch, when the model is rejected.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub branch_level: Option<BranchLevel>,
}

/// The fitted model against a level by ramp branch: the generalized-least-squares slope
/// of `r` on `branch` (±1, 0 before the first ramp; each centred per run), both whitened
/// by the same Kalman filter of the model over each run's bin times, which carries the
/// state across the bins left out (`keep` false: within [`BRANCH_SKIP_S`] of a reversal)
/// so that a branch's jump at a reversal still counts. Innovations of `r` clipped at
/// [`CLIP_SD`]. Returns (|z|, the level by branch, its z) at level `alpha`, or `None`
/// when no bin is kept.
pub(crate) fn branch_test(
    ch: &Channels,
    r: &[f64],
    branch: &[f64],
    since_reversal_h: &[f64],
    model: &NoiseModel,
    alpha: f64,
) -> Option<(f64, f64, Option<BranchLevel>)> {
    let (w, q) = (model.white.powi(2), model.slow_sd.powi(2));
    let (mut sxy, mut sxx) = (0.0, 0.0);
    let mut o = 0;
    for t in &ch.traces {
        let idx = o..o + t.bins.len();
        o += t.bins.len();
        let keep: Vec<bool> = idx
            .clone()
            .map(|i| r[i].is_finite() && branch[i] != 0.0 && since_reversal_h[i] * 3600.0 >= BRANCH_SKIP_S)
            .collect();
        let n = keep.iter().filter(|&&k| k).count();
        if n < 2 {
            continue;
        }
        let mean = |v: &[f64]| idx.clone().zip(&keep).filter(|x| *x.1).map(|(i, _)| v[i]).sum::<f64>() / n as f64;
        let (mr, mx) = (mean(r), mean(branch));
        let (mut er, mut ex, mut p) = (0.0, 0.0, q);
        let mut prev_t: Option<f64> = None;
        for ((i, b), &k) in idx.clone().zip(&t.bins).zip(&keep) {
            if let Some(t0) = prev_t {
                let phi = (-(b.time_s - t0) / model.tau_s).exp();
                (er, ex) = (er * phi, ex * phi);
                p = phi * phi * p + q * (1.0 - phi * phi);
            }
            prev_t = Some(b.time_s);
            if !k {
                continue;
            }
            let f = (p + w).max(1e-300);
            let vr = (r[i] - mr - er).clamp(-CLIP_SD * f.sqrt(), CLIP_SD * f.sqrt());
            let vx = branch[i] - mx - ex;
            sxy += vr * vx / f;
            sxx += vx * vx / f;
            let gain = p / f;
            er += gain * vr;
            ex += gain * vx;
            p *= 1.0 - gain;
        }
    }
    if sxx <= 0.0 {
        return None;
    }
    let (z, size) = (sxy / sxx.sqrt(), sxy / sxx);
    let critical = super::stats::normal_quantile(1.0 - alpha / 2.0);
    let level = (z.abs() > critical).then_some(BranchLevel { size, z, critical });
    Some((z.abs(), critical, level))
}

/// Fit the noise model to `r` and test it against a change point in any run, at level
/// `alpha`. `seed` fixes the null draws (the same log gives the same answer).
#[must_use]
pub(crate) fn test(ch: &Channels, series: &str, r: &[f64], alpha: f64, seed: u64) -> NoiseTest {
    let model = fit(ch, r);
    let runs = runs_of(ch, r);
    let allowed = split_allowed(ch);
    let mut masks = Vec::with_capacity(runs.len());
    let mut o = 0;
    for t in &ch.traces {
        masks.push((o..o + t.bins.len()).filter(|&i| r[i].is_finite()).map(|i| allowed[i]).collect::<Vec<bool>>());
        o += t.bins.len();
    }
    // The largest split of each search: (|z|, run index in `runs`, split, step).
    let mut obs: Option<(f64, usize, usize, f64)> = None;
    let mut obs_gls: Option<(f64, usize, usize, f64)> = None;
    for (j, ((_, v, _), mask)) in runs.iter().zip(&masks).enumerate() {
        if let Some((z, m, delta)) = max_split(&model, &clipped(&model, v)) {
            if obs.is_none_or(|o| z > o.0) {
                obs = Some((z, j, m, delta));
            }
        }
        if let Some((z, m, _)) = max_split_gls(&model, v, mask) {
            if obs_gls.is_none_or(|o| z > o.0) {
                // The step's size is the difference of the segments' means at the split,
                // as for the other search: the whitened coefficient weighs the jump itself
                // most, and a 40-µg step spread over a few bins (two positions' rows
                // paired) came out at a third of its size.
                let c = clipped(&model, v);
                let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
                obs_gls = Some((z, j, m, mean(&c[m..]) - mean(&c[..m])));
            }
        }
    }
    let lens: Vec<usize> = runs.iter().map(|(_, v, _)| v.len()).collect();
    let runs_searched = lens.iter().filter(|&&n| n >= 2 * MIN_SEGMENT_BINS).count();
    let values: Vec<&[f64]> = runs.iter().map(|(_, v, _)| v.as_slice()).collect();
    let run_noise = max_run_noise(&values);
    let Some(max_z) = obs.map(|o| o.0) else {
        return NoiseTest::untested(series, model, runs_searched);
    };
    let null = null_quantile(&model, &masks, alpha, seed);
    let (critical, run_noise_critical) = (null.means, null.run_noise);
    let run_label = |k: usize| {
        format!(
            "{} ({} {} of {})",
            ch.traces[k].program,
            if ch.kind == super::LogKind::Cycling { "program" } else { "run" },
            k + 1,
            ch.traces.len()
        )
    };
    let noisy_run = run_noise
        .filter(|&(ratio, _)| ratio > run_noise_critical && ratio >= RUN_NOISE_MIN_RATIO)
        .map(|(ratio, k)| NoisyRun { series: series.into(), run: run_label(runs[k].0), ratio });
    // Either search may reject (their critical values hold the level jointly); the one
    // further past its critical value places and sizes the step.
    let floor = model.floor();
    let change_point = [("segment means", obs, critical), ("whitened", obs_gls, null.whitened)]
        .into_iter()
        .filter_map(|(search, o, c)| {
            o.filter(|o| o.0 > c && o.3.abs() > STEP_MIN_FLOORS * floor).map(|o| (search, o, c))
        })
        .max_by(|a, b| (a.1 .0 / a.2).total_cmp(&(b.1 .0 / b.2)))
        .map(|(search, (z, j, m, size), critical)| {
            let (k, _, time) = &runs[j];
            let t0 = ch.traces[*k].time_s.first().copied().unwrap_or(0.0);
            ChangePoint {
                series: series.into(),
                run: run_label(*k),
                at_h: (0.5 * (time[m - 1] + time[m]) - t0) / 3600.0,
                size,
                z,
                search: search.into(),
                critical,
            }
        });
    NoiseTest {
        series: series.into(),
        model,
        runs_searched,
        max_z: Some(max_z),
        critical: Some(critical),
        whitened_max_z: obs_gls.map(|o| o.0),
        whitened_critical: obs_gls.map(|_| null.whitened),
        change_point,
        max_run_noise: run_noise.map(|r| r.0),
        run_noise_critical: run_noise.map(|_| run_noise_critical),
        noisy_run,
        branch_z: None,
        branch_critical: None,
        branch_level: None,
    }
}

/// The critical values of [`test`]'s three statistics under the fitted model.
struct NullCriticals {
    /// The difference of segment means' largest |z|.
    means: f64,
    /// The whitened search's largest |z|.
    whitened: f64,
    /// The noisiest run's bin-to-bin noise over the median run's.
    run_noise: f64,
}

/// Critical values of the two change-point searches that hold level `alpha` jointly over
/// the null draws' maxima `a` and `b` (one pair per draw): the `k`-th largest of each, `k`
/// the largest for which at most `alpha` of the draws exceed either. The two searches are
/// correlated (both look for a step), so this is less strict than `alpha / 2` for each.
fn joint_criticals(a: &[f64], b: &[f64], alpha: f64) -> (f64, f64) {
    let n = a.len();
    let (mut sa, mut sb) = (a.to_vec(), b.to_vec());
    sa.sort_by(f64::total_cmp);
    sb.sort_by(f64::total_cmp);
    let allowed = (alpha * n as f64).floor() as usize;
    let mut best = (sa[n - 1], sb[n - 1]);
    for k in 2..=n {
        let (ca, cb) = (sa[n - k], sb[n - k]);
        let over = a.iter().zip(b).filter(|(x, y)| **x > ca || **y > cb).count();
        if over > allowed {
            break;
        }
        best = (ca, cb);
    }
    best
}

/// The critical values at level `alpha` of the change-point searches (jointly) and of the
/// noisiest run over runs drawn from `model`, one per mask of `masks` (its length the
/// run's, its values where a split may fall).
fn null_quantile(model: &NoiseModel, masks: &[Vec<bool>], alpha: f64, seed: u64) -> NullCriticals {
    let mut rng = seeded(seed ^ 0x6e6f_6973_6521);
    let phi = model.phi();
    let innov = model.slow_sd * (1.0 - phi * phi).max(0.0).sqrt();
    let mut draws: Vec<(f64, f64, f64)> = (0..NULL_DRAWS)
        .map(|_| {
            let series: Vec<Vec<f64>> = masks
                .iter()
                .map(|mask| {
                    let mut g = model.slow_sd * normal(&mut rng);
                    (0..mask.len())
                        .map(|_| {
                            g = phi * g + innov * normal(&mut rng);
                            g + model.white * normal(&mut rng)
                        })
                        .collect()
                })
                .collect();
            let refs: Vec<&[f64]> = series.iter().map(Vec::as_slice).collect();
            // Each draw is tested as the log is: against the model fitted to the draw
            // itself, so that the fit's own error is in the null (see the module docs).
            let refit = fit_runs(&refs, model.bin_s);
            let top =
                refs.iter().filter_map(|v| max_split(&refit, &clipped(&refit, v)).map(|m| m.0)).fold(0.0f64, f64::max);
            let top_gls = refs
                .iter()
                .zip(masks)
                .filter_map(|(v, mask)| max_split_gls(&refit, v, mask).map(|m| m.0))
                .fold(0.0f64, f64::max);
            (top, top_gls, max_run_noise(&refs).map_or(0.0, |r| r.0))
        })
        .collect();
    let (a, b): (Vec<f64>, Vec<f64>) = draws.iter().map(|d| (d.0, d.1)).unzip();
    let (means, whitened) = joint_criticals(&a, &b, alpha);
    draws.sort_by(|x, y| x.2.total_cmp(&y.2));
    let i = (((1.0 - alpha) * NULL_DRAWS as f64).ceil() as usize).min(NULL_DRAWS) - 1;
    NullCriticals { means, whitened, run_noise: draws[i].2 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use qfa_log::channels::{BiasUnit, LogKind, Trace};

    /// A single-channel log of `runs` runs of `n` 60-s bins whose values are `f(run, i)`.
    fn channels(runs: usize, n: usize) -> Channels {
        let traces = (0..runs)
            .map(|k| {
                let rows: Vec<(f64, f32)> = (0..n * 6).map(|i| (10.0 * (i + 1) as f64, 20.0)).collect();
                let bias = vec![0.0; rows.len()];
                Trace::new(format!("r{k}"), &rows, None, &bias, 60.0)
            })
            .collect();
        Channels { kind: LogKind::Single, bias_unit: BiasUnit::Value, traces }
    }

    fn series(ch: &Channels, white: f64, slow: f64, tau_bins: f64, seed: u64) -> Vec<f64> {
        let mut rng = seeded(seed);
        let phi = (-1.0 / tau_bins).exp();
        let mut out = Vec::new();
        for t in &ch.traces {
            let mut g = slow * normal(&mut rng);
            for _ in &t.bins {
                g = phi * g + slow * (1.0 - phi * phi).sqrt() * normal(&mut rng);
                out.push(g + white * normal(&mut rng));
            }
        }
        out
    }

    #[test]
    fn the_floor_is_the_bin_to_bin_noise_even_when_the_white_part_is_zero() {
        // Pure Gauss–Markov, SD 3, τ 30 bins: no white part. The floor the selection
        // weighs and the report divides by is the bin-to-bin noise 3·√(1 − e^(−1/30)) =
        // 0.548; the white part alone (the floor before) came out near zero and the
        // report then printed a residual of 10¹⁵ times its floor.
        let ch = channels(8, 600);
        let expect = 3.0 * (1.0 - (-1.0f64 / 30.0).exp()).sqrt();
        let r = series(&ch, 0.0, 3.0, 30.0, 5);
        let floor = super::super::folds::noise_floor(&ch, &r);
        assert!((floor / expect - 1.0).abs() < 0.15, "floor {floor}, expected {expect}");
        // With a white part of 1 as well: √(1 + 9(1 − e^(−1/30))) = 1.14.
        let r = series(&ch, 1.0, 3.0, 30.0, 6);
        let expect = (1.0 + 9.0 * (1.0 - (-1.0f64 / 30.0).exp())).sqrt();
        let floor = super::super::folds::noise_floor(&ch, &r);
        assert!((floor / expect - 1.0).abs() < 0.1, "floor {floor}, expected {expect}");
    }

    /// Lag-`k` autocorrelation of the finite values of one series (no runs).
    fn autocorr(v: &[f64], k: usize) -> f64 {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>();
        v.windows(k + 1).map(|w| (w[0] - m) * (w[k] - m)).sum::<f64>() / var
    }

    #[test]
    fn whitening_leaves_white_noise_of_unit_sd() {
        // White 1 + Gauss–Markov 3 with τ 30 bins: the raw series' lag-1 and lag-5
        // autocorrelations are about 0.87 and 0.76; whitened by the fitted model, each
        // is within 0.05 of zero (2.4 SEs of an estimate from 4 800 values), and the SD
        // within 5 % of 1.
        let ch = channels(8, 600);
        let r = series(&ch, 1.0, 3.0, 30.0, 11);
        assert!(autocorr(&r, 1) > 0.8 && autocorr(&r, 5) > 0.6);
        let u = fit(&ch, &r).whiten(&ch, &r);
        assert!(u.iter().all(|x| x.is_finite()));
        for k in [1, 2, 5, 20] {
            assert!(autocorr(&u, k).abs() < 0.05, "lag {k}: {}", autocorr(&u, k));
        }
        let sd = (u.iter().map(|x| x * x).sum::<f64>() / u.len() as f64).sqrt();
        assert!((sd - 1.0).abs() < 0.05, "SD {sd}");
        // A wrong φ (white noise assumed) leaves the correlation in.
        let white_only = NoiseModel { slow_sd: 0.0, ..fit(&ch, &r) };
        assert!(autocorr(&white_only.whiten(&ch, &r), 1) > 0.5);
    }

    #[test]
    fn the_fit_recovers_white_and_gauss_markov_parts() {
        let ch = channels(8, 600);
        let n = ch.n_bins();
        assert!(n > 4000, "{n} bins");
        // Over 5 seeds, each part within 15 % and τ within a factor of 2.
        for seed in 1..=5 {
            let r = series(&ch, 1.0, 2.0, 30.0, seed);
            let m = fit(&ch, &r);
            assert!((m.white - 1.0).abs() < 0.15, "{m:?}");
            assert!((m.slow_sd - 2.0).abs() < 0.3 * 2.0, "{m:?}");
            assert!(m.tau_s > 15.0 * 60.0 && m.tau_s < 60.0 * 60.0, "{m:?}");
            // White noise alone: no slow part to speak of.
            let w = fit(&ch, &series(&ch, 1.0, 0.0, 30.0, seed));
            assert!((w.white - 1.0).abs() < 0.1 && w.slow_sd < 0.3, "{w:?}");
        }
    }

    #[test]
    fn the_model_never_claims_more_variance_than_the_residual_has() {
        // A structure that looks like a random walk over the 64 lags fitted but is bounded:
        // a ±5 square wave (half-period 90 bins) plus white noise of SD 1, SD 5.1 in all.
        // The model's total SD must stay within 30 % of that; fitted from the lags alone
        // it took the long-τ end of the family and claimed an SD of 11.2.
        let ch = channels(8, 600);
        let mut rng = seeded(3);
        let r: Vec<f64> =
            (0..ch.n_bins()).map(|i| if (i / 90) % 2 == 0 { 5.0 } else { -5.0 } + normal(&mut rng)).collect();
        let sd = (r.iter().map(|x| x * x).sum::<f64>() / r.len() as f64).sqrt();
        let m = fit(&ch, &r);
        assert!(m.total_sd() < 1.3 * sd && m.total_sd() > 0.7 * sd, "SD {sd}: {m:?}");
    }

    /// A branch (±1, switching every 90 bins) and the hours since its last switch.
    fn branch_of(n_bins: usize) -> (Vec<f64>, Vec<f64>) {
        let branch = (0..n_bins).map(|i| if (i / 90) % 2 == 0 { 1.0 } else { -1.0 }).collect();
        let since = (0..n_bins).map(|i| (i % 90) as f64 / 60.0).collect();
        (branch, since)
    }

    #[test]
    fn a_level_by_branch_is_found_and_noise_or_corner_transients_are_not() {
        let ch = channels(8, 600);
        let (branch, since) = branch_of(ch.n_bins());
        let mut rejected = 0;
        for seed in 1..=20 {
            let r = series(&ch, 1.0, 2.0, 30.0, seed);
            let (z, _, level) = branch_test(&ch, &r, &branch, &since, &fit(&ch, &r), 0.05).expect("bins kept");
            assert!(z.is_finite());
            rejected += usize::from(level.is_some());
        }
        // Level 0.05: at most 3 of 20 (binomial tail below 8 %).
        assert!(rejected <= 3, "{rejected} of 20 rejected");
        // A ±1 level by branch, one white SD: found (a size rule of 3 white SDs, as a step
        // has, left such levels silent at |z| 5), its size within 30 %.
        let r: Vec<f64> = series(&ch, 1.0, 2.0, 30.0, 6).iter().zip(&branch).map(|(e, b)| e + b).collect();
        let (_, _, level) = branch_test(&ch, &r, &branch, &since, &fit(&ch, &r), 0.05).expect("bins kept");
        let level = level.expect("a level of one white SD is found");
        assert!((level.size - 1.0).abs() < 0.3, "{level:?}");
        // A ±4 level by branch (4 white SDs) on the same noise: found, its size within 30 %.
        let r: Vec<f64> = series(&ch, 1.0, 2.0, 30.0, 7).iter().zip(&branch).map(|(e, b)| e + 4.0 * b).collect();
        let (_, _, level) = branch_test(&ch, &r, &branch, &since, &fit(&ch, &r), 0.05).expect("bins kept");
        let level = level.expect("the level by branch is found");
        assert!((level.size - 4.0).abs() < 1.2, "{level:?}");
        // Transients of 10 in the first 8 bins after each switch, of the new branch's sign,
        // and nothing after them: left out with the 10 minutes after a reversal. (Kept in,
        // they read as a level of 3.1 at |z| 39.)
        let r: Vec<f64> = series(&ch, 1.0, 2.0, 30.0, 8)
            .iter()
            .enumerate()
            .map(|(i, e)| e + if i % 90 < 8 { 10.0 * branch[i] } else { 0.0 })
            .collect();
        let (_, _, level) = branch_test(&ch, &r, &branch, &since, &fit(&ch, &r), 0.05).expect("bins kept");
        assert!(level.is_none(), "{level:?}");
    }

    #[test]
    fn a_run_with_five_times_the_noise_is_found_and_noise_is_not() {
        let ch = channels(8, 600);
        let mut rejected = 0;
        for seed in 1..=20 {
            let r = series(&ch, 1.0, 1.0, 20.0, seed);
            rejected += usize::from(test(&ch, "value", &r, 0.05, seed).noisy_run.is_some());
        }
        assert!(rejected <= 3, "{rejected} of 20 rejected");
        // Run 4 with five times the white noise and a 4-SD slow wander on top.
        let mut r = series(&ch, 1.0, 1.0, 20.0, 9);
        let extra = series(&ch, 4.0, 4.0, 60.0, 10);
        for i in 3 * 600..4 * 600 {
            r[i] += extra[i];
        }
        let t = test(&ch, "value", &r, 0.05, 9);
        let run = t.noisy_run.expect("the noisy run is found");
        assert_eq!(run.run, "r3 (run 4 of 8)");
        assert!(run.ratio > 3.0, "{run:?}");
        // A run at 1.5 times the noise is left alone: under the size rule.
        let mut r = series(&ch, 1.0, 0.0, 20.0, 11);
        let extra = series(&ch, 1.1, 0.0, 20.0, 12);
        for i in 3 * 600..4 * 600 {
            r[i] += extra[i];
        }
        let t = test(&ch, "value", &r, 0.05, 11);
        assert!(t.noisy_run.is_none() && t.max_run_noise.is_some_and(|x| x > 1.3), "{t:?}");
        // A step of 6 SDs half-way through run 4 is a change point, not a noisy run (its SD
        // about its median read 4.2 times the others': that statistic called it noise).
        let mut r = series(&ch, 1.0, 0.0, 20.0, 13);
        for x in &mut r[3 * 600 + 300..4 * 600] {
            *x += 6.0;
        }
        let t = test(&ch, "value", &r, 0.05, 13);
        assert!(t.change_point.is_some(), "{t:?}");
        assert!(t.noisy_run.is_none() && t.max_run_noise.is_some_and(|x| x < 1.3), "{t:?}");
    }

    #[test]
    fn glitches_and_a_step_do_not_inflate_the_floor() {
        let ch = channels(8, 600);
        let mut r = series(&ch, 1.0, 0.5, 30.0, 7);
        let clean = fit(&ch, &r);
        // One bin in 80 carries a 30-SD glitch; one run has a 10-SD step.
        for (i, x) in r.iter_mut().enumerate() {
            if i % 80 == 40 {
                *x += if i % 160 == 40 { 30.0 } else { -30.0 };
            }
        }
        for x in &mut r[300..600] {
            *x += 10.0;
        }
        let hit = fit(&ch, &r);
        assert!(hit.white < 1.15 * clean.white, "{clean:?} → {hit:?}");
        // The mean-square floor the robust fit replaces would have grown far more.
        let ms = (r.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum::<f64>() / (2.0 * r.len() as f64)).sqrt();
        assert!(ms > 2.0 * clean.white, "{ms}");
    }

    #[test]
    fn the_change_point_test_holds_its_level_when_the_model_is_fitted_to_the_series_itself() {
        // The lab simulator's bias instability at 60-s bins: Gauss–Markov of SD 1 and τ
        // 30 bins, a small white part, four runs of 6.5 h. The model fitted to one such
        // series is off by its own sampling error, and a series whose slow part came out
        // low reads its own wander as a step. With the critical value from draws of the
        // fitted model tested against that same model (the plug-in null), 50 of 200 such
        // series were rejected at level 0.1; with every draw refitted as the log is, 23
        // (the study below). Here the first 100: the bound, 15, is the 96.0 % point of
        // Binomial(100, 0.1), so a test that holds its level passes 24 times in 25, and one
        // that rejects a quarter of them, as the plug-in null did, fails 99 times in 100
        // (P(Binomial(100, 0.25) ≤ 15) = 0.011).
        let rejected = level_rejections(100);
        assert!(rejected <= 15, "{rejected} of 100 rejected at level 0.1");
    }

    /// The same on 200 series: the bound, 27, is the 95.7 % point of Binomial(200, 0.1).
    #[test]
    #[ignore = "study: 200 series of 400 null draws each, about 40 s in the dev profile"]
    fn the_change_point_test_holds_its_level_on_200_series() {
        let rejected = level_rejections(200);
        assert!(rejected <= 27, "{rejected} of 200 rejected at level 0.1");
    }

    /// Of `n` series of the level study (seeds 0..n), how many the change-point test
    /// rejects at level 0.1.
    fn level_rejections(n: u64) -> usize {
        let ch = channels(4, 390);
        (0..n)
            .filter(|&seed| {
                let r = series(&ch, 0.13, 1.0, 30.0, 77 + seed);
                let t = test(&ch, "value", &r, 0.1, seed);
                t.max_z.zip(t.critical).is_some_and(|(z, c)| z > c)
            })
            .count()
    }

    #[test]
    fn a_step_in_one_run_is_found_where_it_is_and_noise_passes() {
        let ch = channels(8, 600);
        let mut passes = 0;
        for seed in 1..=20 {
            let r = series(&ch, 1.0, 1.0, 20.0, seed);
            if test(&ch, "value", &r, 0.05, seed).change_point.is_none() {
                passes += 1;
            }
        }
        // Level 0.05: 20 clean series give at most 4 rejections (binomial tail < 2 %).
        assert!(passes >= 16, "{passes} of 20 passed");
        // A step of 4 white SDs at bin 250 of run 3.
        let mut r = series(&ch, 1.0, 1.0, 20.0, 99);
        for x in &mut r[3 * 600 + 250..4 * 600] {
            *x += 4.0;
        }
        let t = test(&ch, "value", &r, 0.05, 99);
        let cp = t.change_point.expect("the step is found");
        assert_eq!(cp.run, "r3 (run 4 of 8)");
        assert!((cp.at_h - 250.0 / 60.0).abs() < 0.5, "{cp:?}");
        assert!((cp.size - 4.0).abs() < 1.5, "{cp:?}");
        // Rare glitches alone are not a step.
        let mut g = series(&ch, 1.0, 1.0, 20.0, 5);
        for (i, x) in g.iter_mut().enumerate() {
            if i % 83 == 11 {
                *x += 40.0;
            }
        }
        assert!(test(&ch, "value", &g, 0.05, 5).change_point.is_none());
    }

    #[test]
    fn a_step_is_sized_against_the_bin_to_bin_noise_when_the_fit_has_no_white_part() {
        // Gauss–Markov noise alone with τ 5 bins, as a real MEMS log's axes fit (white 0):
        // a size rule in white SDs then asks nothing of a step. A step of 2.3 floors (9
        // white SDs of this fit) that the z test rejects is held to the rule as a step of
        // 2.3 white SDs on white noise is; one of 4 floors is found.
        let ch = channels(8, 600);
        let with_step = |size: f64| {
            let mut r = series(&ch, 0.0, 1.0, 5.0, 21);
            for x in &mut r[3 * 600 + 300..4 * 600] {
                *x += size;
            }
            test(&ch, "value", &r, 0.05, 21)
        };
        let small = with_step(1.0);
        let floor = small.model.floor();
        println!("{:?} floor {floor}", small.model);
        assert!(small.model.white < 0.3 * floor, "{:?}", small.model);
        assert!(small.max_z.zip(small.critical).is_some_and(|(z, c)| z > c), "{small:?}");
        assert!(small.change_point.is_none(), "{:?} (floor {floor})", small.change_point);
        let large = with_step(4.0 * floor);
        assert!(large.change_point.is_some(), "{large:?}");
    }

    /// A model for the dense-solve checks: white 0.2–1.7, Gauss–Markov 0–3 with τ 2–62
    /// 60-s bins; and τ in bins.
    fn random_model(rng: &mut qfa_rng::LabRng) -> (NoiseModel, f64) {
        let white = 0.2 + 1.5 * qfa_rng::uniform(rng);
        let slow = 3.0 * qfa_rng::uniform(rng);
        let tau_bins = 2.0 + 60.0 * qfa_rng::uniform(rng);
        (NoiseModel { white, slow_sd: slow, tau_s: 60.0 * tau_bins, bin_s: 60.0, lags: 12 }, tau_bins)
    }

    #[test]
    fn the_branch_test_is_generalized_least_squares_by_a_dense_solve() {
        // For random models, two runs of 300 bins and a branch switching every 70 bins, the
        // 10 minutes after each switch left out: the level by branch and its z against
        // nalgebra's Cholesky solve of the model's dense covariance over the bins kept, the
        // residual and the branch centred per run.
        let mut rng = seeded(43);
        for case in 0..8 {
            let (m, tau_bins) = random_model(&mut rng);
            let (white, slow) = (m.white, m.slow_sd);
            let ch = channels(2, 300);
            let n = ch.n_bins();
            let branch: Vec<f64> = (0..n).map(|i| if ((i % 300) / 70) % 2 == 0 { 1.0 } else { -1.0 }).collect();
            let since: Vec<f64> = (0..n).map(|i| ((i % 300) % 70) as f64 / 60.0).collect();
            let noise = series(&ch, white, slow, tau_bins, 200 + case);
            // A level of 0.3 white SDs: its jumps stay inside the 4-SD clip, which the dense
            // solve does not have.
            let r: Vec<f64> = (0..n).map(|i| noise[i] + 0.3 * white * branch[i]).collect();
            let (z, _, level) = branch_test(&ch, &r, &branch, &since, &m, 1.0).expect("bins kept");
            let level = level.expect("at level 1 every z is a level");
            let (mut xtx, mut xty) = (0.0, 0.0);
            for run in 0..2 {
                let kept: Vec<usize> =
                    (run * 300..(run + 1) * 300).filter(|&i| since[i] * 3600.0 >= BRANCH_SKIP_S).collect();
                let k = kept.len();
                let t = |a: usize| ch.traces[run].bins[a - run * 300].time_s;
                let cov = nalgebra::DMatrix::from_fn(k, k, |i, j| {
                    let d = (t(kept[i]) - t(kept[j])).abs();
                    slow * slow * (-d / m.tau_s).exp() + if i == j { white * white } else { 0.0 }
                });
                let chol = cov.cholesky().expect("positive definite");
                let centred = |v: &[f64]| {
                    let mean = kept.iter().map(|&i| v[i]).sum::<f64>() / k as f64;
                    nalgebra::DVector::from_iterator(k, kept.iter().map(|&i| v[i] - mean))
                };
                let x = centred(&branch);
                xtx += x.dot(&chol.solve(&x));
                xty += x.dot(&chol.solve(&centred(&r)));
            }
            let (beta, z_dense) = (xty / xtx, xty / xtx.sqrt());
            assert!((level.size / beta - 1.0).abs() < 1e-6, "case {case}: {} against {beta} ({m:?})", level.size);
            assert!((z / z_dense.abs() - 1.0).abs() < 1e-6, "case {case}: {z} against {z_dense}");
        }
    }

    #[test]
    fn the_split_search_is_generalized_least_squares_by_a_dense_solve() {
        // For random models and splits (before and after the filter's gain settles), the
        // z and step of `gls_splits` against generalized least squares of the run on a level
        // and a step by nalgebra's Cholesky solve of the model's dense covariance.
        let mut rng = seeded(41);
        for case in 0..12 {
            let (m, tau_bins) = random_model(&mut rng);
            let (white, slow) = (m.white, m.slow_sd);
            let ch = channels(1, 400);
            let mut v = series(&ch, white, slow, tau_bins, 100 + case);
            let n = v.len();
            let split = if case % 3 == 0 {
                MIN_SEGMENT_BINS + case as usize
            } else {
                40 + (qfa_rng::uniform(&mut rng) * (n - 80) as f64) as usize
            };
            for x in &mut v[split..] {
                *x += 1.5;
            }
            let phi = m.phi();
            let cov = nalgebra::DMatrix::from_fn(n, n, |i, j| {
                slow * slow * phi.powi((i as i32 - j as i32).abs()) + if i == j { white * white } else { 0.0 }
            });
            let chol = cov.cholesky().expect("positive definite");
            let x = nalgebra::DMatrix::from_fn(n, 2, |i, j| if j == 0 || i >= split { 1.0 } else { 0.0 });
            let y = nalgebra::DVector::from_column_slice(&v);
            let xtx = x.transpose() * chol.solve(&x);
            let xty = x.transpose() * chol.solve(&y);
            let inv = xtx.try_inverse().expect("full rank");
            let beta = (&inv * xty)[1];
            let z_dense = beta / inv[(1, 1)].sqrt();
            // The search's figures at the same split: its maximum over splits is at least
            // this, and at the split itself (searched alone) it matches.
            let (z, at, step) = max_split_gls(&m, &v, &[]).expect("a long run");
            let (z_at, _, step_at) = gls_splits(&m, &v, split..=split).expect("a split inside");
            assert!((z_at / z_dense.abs() - 1.0).abs() < 1e-6, "case {case}: {z_at} against {z_dense} ({m:?})");
            assert!((step_at / beta - 1.0).abs() < 1e-6, "case {case}: {step_at} against {beta}");
            assert!(z >= z_at && at >= MIN_SEGMENT_BINS && step.is_finite());
        }
    }

    #[test]
    fn a_step_in_slow_noise_is_found_by_the_whitened_search_where_segment_means_miss_it() {
        // White 1 + Gauss–Markov 2 (τ 80 bins; floor 1.02): a step of 4 half-way through
        // run 4 of 8, ten noise draws (the second generator's draw 1448 was fitted white
        // 0.88 + Gauss–Markov 1.55, τ 79 min, with a step of 3.7 in its bias). The
        // difference of the segments' means spends the step on the slow part's wander;
        // whitened, the jump and the level after it each count for what the model says
        // they are worth. Measured: 8 of 10 found (9 while a step was sized by its whitened
        // coefficient; sized by the means, it must still be 3 floors), 0 of 10 by segment
        // means alone.
        let ch = channels(8, 600);
        let (mut found, mut by_means) = (0, 0);
        for seed in 1..=10 {
            let mut r = series(&ch, 1.0, 2.0, 80.0, seed);
            for x in &mut r[3 * 600 + 300..4 * 600] {
                *x += 4.0;
            }
            let t = test(&ch, "value", &r, 0.05, seed);
            if t.max_z.zip(t.critical).is_some_and(|(z, c)| z > c) {
                by_means += 1;
            }
            if let Some(cp) = &t.change_point {
                // The size is the difference of the segments' means at the split, whose SD
                // under the true model (300 bins each side) is 1.62: within 3 SDs.
                let truth = NoiseModel { white: 1.0, slow_sd: 2.0, tau_s: 80.0 * 60.0, bin_s: 60.0, lags: 12 };
                let sd = (2.0 * truth.var_mean(300) - 2.0 * truth.powers(300).cov_adjacent(300, 300) / 300f64.powi(2)).sqrt();
                assert_eq!(cp.run, "r3 (run 4 of 8)", "seed {seed}: {cp:?}");
                assert!(
                    (cp.at_h - 5.0).abs() < 0.25 && (cp.size - 4.0).abs() < 3.0 * sd,
                    "seed {seed}: {cp:?}, SD {sd}"
                );
                found += 1;
            }
        }
        println!("found {found} of 10, by segment means {by_means}");
        assert!(found >= 8, "found {found} of 10 (by segment means {by_means})");
    }

    #[test]
    fn the_two_searches_hold_their_level_jointly() {
        // Independent maxima: at most alpha of the draws exceed either critical value, and
        // each critical value is at least its own (1 − alpha) quantile. Identical maxima: both
        // are that quantile, as one search's would be.
        let mut rng = seeded(8);
        let a: Vec<f64> = (0..400).map(|_| normal(&mut rng)).collect();
        let b: Vec<f64> = (0..400).map(|_| normal(&mut rng)).collect();
        let (ca, cb) = joint_criticals(&a, &b, 0.05);
        let over = a.iter().zip(&b).filter(|(x, y)| **x > ca || **y > cb).count();
        assert!((15..=20).contains(&over), "{over} of 400 exceed ({ca}, {cb})");
        let solo = |v: &[f64]| {
            let mut s = v.to_vec();
            s.sort_by(f64::total_cmp);
            s[379]
        };
        assert!(ca > solo(&a) && cb > solo(&b), "{ca} {cb} against {} {}", solo(&a), solo(&b));
        let (c1, c2) = joint_criticals(&a, &a, 0.05);
        assert_eq!((c1, c2), (solo(&a), solo(&a)));
    }

    #[test]
    fn runs_too_short_to_search_give_no_figure() {
        // Runs of 8 bins cannot hold 5 bins either side of a split: no |z|, no critical
        // value, and the count of runs searched says why.
        let ch = channels(3, 8);
        let t = test(&ch, "value", &series(&ch, 1.0, 0.5, 10.0, 3), 0.05, 3);
        assert_eq!((t.runs_searched, t.max_z, t.critical, t.change_point), (0, None, None, None));
        let long = channels(3, 40);
        let t = test(&long, "value", &series(&long, 1.0, 0.5, 10.0, 3), 0.05, 3);
        assert_eq!(t.runs_searched, 3);
        assert!(t.max_z.is_some_and(f64::is_finite) && t.critical.is_some_and(|c| c > 0.0), "{t:?}");
    }

    #[test]
    fn closed_form_sums_match_brute_force() {
        let m = NoiseModel { white: 0.7, slow_sd: 1.3, tau_s: 600.0, bin_s: 60.0, lags: 12 };
        let phi = m.phi();
        for n in [1usize, 2, 7, 40] {
            let brute: f64 =
                (0..n).flat_map(|i| (0..n).map(move |j| phi.powi((i as i32 - j as i32).abs()))).sum::<f64>();
            assert!((m.powers(n).sum_corr(n) - brute).abs() < 1e-9 * brute, "{n}");
        }
        let (a, b) = (5usize, 9usize);
        let brute: f64 = (0..a).flat_map(|i| (a..a + b).map(move |j| phi.powi((j - i) as i32))).sum::<f64>() * 1.69;
        assert!((m.powers(b).cov_adjacent(a, b) - brute).abs() < 1e-9 * brute);
    }
}
