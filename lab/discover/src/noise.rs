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
use null::null_quantile;
pub(crate) use split::CORNER_SKIP_S;
use split::{clipped, max_split, max_split_gls, split_allowed, Powers};

mod null;
mod split;
use qfa_log::robust::{median, neighbour_noise, sd_from_abs_deviations};

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
        let (true, Some(s)) = (diffs.len() >= MIN_PAIRS, sd_from_abs_deviations(&diffs)) else { break };
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
    let far = match sd_from_abs_deviations(&dev) {
        Some(s) if !d.is_empty() && dev.len() >= MIN_PAIRS => Some(2.0 * (s * s).max(1e-300)),
        _ => None,
    };
    if d.is_empty() {
        let all: Vec<f64> = runs.iter().flat_map(|v| v.iter().copied()).collect();
        let sd = if all.len() > 1 { qfa_calibrate::metrics::rms_of_finite(&all) } else { 1.0 };
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
/// `alpha`. `null_stream` picks the null draws' stream (the same log gives the same answer).
#[must_use]
pub(crate) fn test(ch: &Channels, series: &str, r: &[f64], alpha: f64, null_stream: u64) -> NoiseTest {
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
    let null = null_quantile(&model, &masks, alpha, null_stream);
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

#[cfg(test)]
mod tests;
