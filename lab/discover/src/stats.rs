//! Statistics for autocorrelated held-out residuals: block lengths from the residual
//! autocorrelation, a paired block test of a held-out gain, its block-bootstrap
//! uncertainty, and the variance inflation N/N_eff used by the parameter intervals.
//!
//! Why blocks: the 60-s bins of a thermal test are not independent (the lab simulator's
//! bias instability is Gauss–Markov with a 30-min correlation time, a real unit drifts
//! more slowly still). A per-bin test counts every bin as evidence and finds any random
//! wiggle "significant"; sums over blocks longer than the correlation time are close to
//! independent, so their spread gives an honest standard error of the gain.

use serde::Serialize;

use qfa_log::channels::Channels;
use qfa_rng::{seeded, uniform};

/// Blocks of consecutive bins within each trace (a block never spans two programs).
#[derive(Clone, Debug)]
pub(crate) struct Blocks {
    /// Block index of every bin.
    pub of_bin: Vec<usize>,
    /// Number of blocks.
    pub n: usize,
    /// Nominal block length, bins.
    pub len: usize,
}

/// Lag-`k` autocorrelations (k = 0..=`max_lag`) of `v` within each trace, NaNs skipped.
fn acf(ch: &Channels, v: &[f64], max_lag: usize) -> Vec<f64> {
    let fin: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if fin.len() < 4 {
        return vec![1.0];
    }
    let mean = fin.iter().sum::<f64>() / fin.len() as f64;
    let var = fin.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / fin.len() as f64;
    if var <= 0.0 {
        return vec![1.0];
    }
    let mut out = vec![1.0];
    for k in 1..=max_lag {
        let (mut s, mut n) = (0.0, 0usize);
        let mut o = 0;
        for t in &ch.traces {
            let m = t.bins.len();
            for i in o + k..o + m {
                let (a, b) = (v[i], v[i - k]);
                if a.is_finite() && b.is_finite() {
                    s += (a - mean) * (b - mean);
                    n += 1;
                }
            }
            o += m;
        }
        if n < 10 {
            break;
        }
        out.push(s / n as f64 / var);
    }
    out
}

/// Variance inflation N/N_eff = 1 + 2·Σρ_k of a residual series (initial positive
/// sequence: the sum stops at the first ρ_k below 0.05), at least 1.
#[must_use]
pub(crate) fn inflation(ch: &Channels, v: &[f64]) -> f64 {
    let n = v.iter().filter(|x| x.is_finite()).count();
    let r = acf(ch, v, (n / 4).min(400));
    let mut s = 1.0;
    for &x in r.iter().skip(1) {
        if x < 0.05 {
            break;
        }
        s += 2.0 * x;
    }
    s.max(1.0)
}

/// Block length for residual channels `chans`: four times the first lag at which any
/// channel's autocorrelation falls below 1/e, at least 10 bins, and short enough to leave
/// at least 8 blocks. (Twice that lag was tried first: adjacent block sums of a
/// Gauss–Markov residual are then still correlated, the SE comes out too small, and on
/// this file's clean single-channel test logs a drift was "found" at t = 2.8.)
#[must_use]
pub(crate) fn block_len(ch: &Channels, chans: &[&[f64]]) -> usize {
    let n = ch.n_bins();
    let mut k_e = 1;
    for v in chans {
        if v.iter().all(|x| !x.is_finite()) {
            continue;
        }
        let r = acf(ch, v, (n / 4).min(400));
        let k = r.iter().position(|&x| x < (-1.0f64).exp()).unwrap_or(r.len());
        k_e = k_e.max(k);
    }
    let mut len = (4 * k_e).max(10).min((n / 8).max(2));
    // Blocks do not cross traces ([`blocks`]), so n/8 alone left 6 or 7 blocks on logs
    // whose programs differ in length, and the unwhitened test's critical value was then
    // t(0.95, 5) = 2.01 on an SE from six sums.
    while len > 2 && ch.traces.iter().map(|t| (t.bins.len() / len).max(1)).sum::<usize>() < 8 {
        len -= 1;
    }
    len
}

/// Blocks of `len` bins per trace; a trace's remainder joins its last block.
#[must_use]
pub(crate) fn blocks(ch: &Channels, len: usize) -> Blocks {
    let mut of_bin = Vec::with_capacity(ch.n_bins());
    let mut next = 0;
    for t in &ch.traces {
        let m = t.bins.len();
        let nb = (m / len).max(1);
        for i in 0..m {
            of_bin.push(next + (i / len).min(nb - 1));
        }
        next += nb;
    }
    Blocks { of_bin, n: next, len }
}

/// A held-out gain with its block statistics.
#[derive(Clone, Debug, Serialize)]
pub struct GainStat {
    /// Gain: drop of the held-out Σ(residual/σ)² (σ: each channel's held-out RMS
    /// before the candidate), in units of one bin's variance.
    pub gain: f64,
    /// Standard error from the spread of the block sums (batch means).
    pub se: f64,
    /// Block-bootstrap standard error (2000 resamples of the block sums).
    pub bootstrap_se: f64,
    /// Block-bootstrap 95 % interval (2.5th and 97.5th percentiles).
    pub ci95: [f64; 2],
    /// gain / se.
    pub t: f64,
    /// Critical value it had to exceed.
    pub critical: f64,
    /// Blocks and their nominal length in bins.
    pub blocks: usize,
    /// Block length, bins.
    pub block_bins: usize,
}

impl GainStat {
    /// The gain is positive and its t exceeds the critical value.
    #[must_use]
    pub fn passes(&self) -> bool {
        self.gain > 0.0 && self.t > self.critical
    }
}

/// Per-block sums of `d` (NaNs skipped).
#[must_use]
pub(crate) fn block_sums(b: &Blocks, d: &[f64]) -> Vec<f64> {
    let mut s = vec![0.0; b.n];
    for (i, &x) in d.iter().enumerate() {
        if x.is_finite() {
            s[b.of_bin[i]] += x;
        }
    }
    s
}

/// Paired block test of the per-bin gains `d` against the one-sided critical value for
/// level `alpha` (Student t with blocks − 1 degrees of freedom).
#[must_use]
pub(crate) fn gain_stat(b: &Blocks, d: &[f64], alpha: f64) -> GainStat {
    let g = block_sums(b, d);
    let n = g.len().max(1) as f64;
    let total: f64 = g.iter().sum();
    let mean = total / n;
    let var = g.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    let se = (n * var).sqrt().max(1e-300);
    // Block bootstrap of the sum (fixed seed: the report is reproducible).
    let mut rng = seeded(0xB007_5742);
    let mut boot: Vec<f64> =
        (0..2000).map(|_| (0..g.len()).map(|_| g[((uniform(&mut rng) * n) as usize).min(g.len() - 1)]).sum()).collect();
    boot.sort_by(f64::total_cmp);
    let bm = boot.iter().sum::<f64>() / boot.len() as f64;
    let bse = (boot.iter().map(|x| (x - bm).powi(2)).sum::<f64>() / (boot.len() - 1) as f64).sqrt();
    let critical = t_quantile(1.0 - alpha, (n - 1.0).max(1.0));
    GainStat {
        gain: total,
        se,
        bootstrap_se: bse,
        ci95: [boot[50], boot[1949]],
        t: total / se,
        critical,
        blocks: g.len(),
        block_bins: b.len,
    }
}

/// Standard normal quantile (Acklam's rational approximation, |error| < 1.2e-9).
#[must_use]
pub(crate) fn normal_quantile(p: f64) -> f64 {
    let p = p.clamp(1e-300, 1.0 - 1e-16);
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.38357751867269e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] =
        [-5.447609879822406e1, 1.615858368580409e2, -1.556989798598866e2, 6.680131188771972e1, -1.328068155288572e1];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [7.784695709041462e-3, 3.224671290700398e-1, 2.445134137142996, 3.754408661907416];
    let pl = 0.02425;
    if p < pl {
        let q = (-2.0 * p.ln()).sqrt();
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    } else if p <= 1.0 - pl {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    } else {
        -normal_quantile(1.0 - p)
    }
}

/// Student-t quantile with `nu` degrees of freedom (Cornish–Fisher expansion around the
/// normal quantile; within 1 % of the exact value for ν ≥ 5 and p ≤ 0.999).
#[must_use]
pub(crate) fn t_quantile(p: f64, nu: f64) -> f64 {
    let z = normal_quantile(p);
    let (z3, z5, z7) = (z.powi(3), z.powi(5), z.powi(7));
    z + (z3 + z) / (4.0 * nu)
        + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * nu * nu)
        + (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / (384.0 * nu.powi(3))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_are_at_least_eight_when_traces_differ_in_length() {
        use qfa_log::channels::{BiasUnit, LogKind, Trace};
        // Four runs of 3 000, 1 000, 1 000 and 1 000 bins, and a residual slow enough
        // that four times its 1/e lag exceeds n/8: the cap alone gave 4 + 1 + 1 + 1 blocks.
        let traces = [3000usize, 1000, 1000, 1000]
            .iter()
            .enumerate()
            .map(|(k, &n)| {
                let rows: Vec<(f64, f32)> = (0..n * 6).map(|i| (10.0 * (i + 1) as f64, 20.0)).collect();
                Trace::new(format!("r{k}"), &rows, None, &vec![0.0; rows.len()], 60.0)
            })
            .collect();
        let ch = Channels { kind: LogKind::Single, bias_unit: BiasUnit::Value, traces, skipped_glitches: Vec::new() };
        let slow: Vec<f64> = (0..ch.n_bins()).map(|i| (i as f64 / 900.0).sin()).collect();
        let len = block_len(&ch, &[&slow]);
        let n_blocks = blocks(&ch, len).n;
        assert!(n_blocks >= 8, "{n_blocks} blocks of {len} bins");
        assert!(len >= 400, "{len}: no shorter than eight blocks need");
    }

    #[test]
    fn quantiles_match_tables() {
        // Independent reference values from printed tables.
        assert!((normal_quantile(0.975) - 1.959_964).abs() < 1e-5);
        assert!((normal_quantile(0.05) + 1.644_854).abs() < 1e-5);
        assert!((t_quantile(0.975, 10.0) - 2.228).abs() < 0.01);
        assert!((t_quantile(0.99, 20.0) - 2.528).abs() < 0.01);
        assert!((t_quantile(0.995, 9.0) - 3.250).abs() < 0.04);
    }
}
