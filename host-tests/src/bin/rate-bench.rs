//! Rate estimator benchmark: `cargo run --release -p host-tests --bin rate-bench`.
//!
//! For ramps of 0.2–1 °C/min sampled at 1 Hz with 12-bit quantization (0.0625 °C) and
//! white sensor noise σₙ, it reports the RMS error of Ṫ from `RateEstimator<N>` and the
//! Cramér–Rao bound of a slope fit over the same window,
//! `σ(Ṫ) = σ/√Σ(tᵢ − t̄)²` with `σ² = σₙ² + q²/12`, and their ratio (target ≤ 1.25).
//! It then reports the lag after a rate step from 0 to 1 °C/min: samples until the
//! estimate reaches 50 % and 90 % of the new rate.
//!
//! A report, not a test: it prints figures and asserts nothing about them.

use qfa_rng::{normal, seeded, uniform, LabRng};
use qfa_thermal::rate::{RateConfig, RateEstimator};

const Q: f64 = 0.0625;

/// RMS error of Ṫ (°C/min) over `trials` independent windows.
fn rms_error<const N: usize>(rate: f64, sigma_n: f64, trials: usize, rng: &mut LabRng) -> f64 {
    let mut sum2 = 0.0;
    for _ in 0..trials {
        let mut e = RateEstimator::<N>::new(RateConfig { min_samples: N as u8, ..RateConfig::default() });
        let offset = uniform(rng) * 10.0 + 15.0;
        for k in 0..N {
            let t_s = k as f64;
            let temp = offset + rate / 60.0 * t_s + sigma_n * normal(rng);
            let raw = (temp / Q).round() as i16;
            e.push(1000 * k as u32 + 7, raw).expect("monotonic");
        }
        let err = f64::from(e.estimate().expect("N samples pushed").rate_c_per_min) - rate;
        sum2 += err * err;
    }
    (sum2 / trials as f64).sqrt()
}

fn crb(n: usize, sigma_n: f64) -> f64 {
    let nf = n as f64;
    let sxx = nf * (nf * nf - 1.0) / 12.0; // Σ(t − t̄)² for t = 0..n−1 s
    let sigma = (sigma_n * sigma_n + Q * Q / 12.0).sqrt();
    sigma / sxx.sqrt() * 60.0
}

fn step_lag<const N: usize>() -> (usize, usize) {
    let mut e = RateEstimator::<N>::new(RateConfig::default());
    let mut t = 20.0;
    let (mut half, mut ninety) = (0, 0);
    for k in 0..(4 * N) {
        if k >= N {
            t += 1.0 / 60.0; // 1 °C/min after N samples of hold
        }
        e.push(1000 * k as u32, (t / Q).round() as i16).expect("monotonic");
        let r = f64::from(e.estimate().expect("a sample was pushed").rate_c_per_min);
        if k >= N {
            if half == 0 && r >= 0.5 {
                half = k - N + 1;
            }
            if ninety == 0 && r >= 0.9 {
                ninety = k - N + 1;
            }
        }
    }
    (half, ninety)
}

fn run<const N: usize>(rng: &mut LabRng) {
    println!("window N = {N} samples at 1 Hz");
    println!("  sigma_n °C | rate °C/min | RMS(Ṫ) °C/min | CRB °C/min | ratio");
    let mut worst: f64 = 0.0;
    for sigma_n in [0.01, 0.02, 0.05] {
        for rate in [0.2, 0.4, 0.6, 0.8, 1.0] {
            let rms = rms_error::<N>(rate, sigma_n, 4000, rng);
            let bound = crb(N, sigma_n);
            worst = worst.max(rms / bound);
            println!("  {sigma_n:10.3} | {rate:11.1} | {rms:13.5} | {bound:10.5} | {:.3}", rms / bound);
        }
    }
    let (h, n) = step_lag::<N>();
    println!("rate_rms_to_crb_worst_n{N}={worst:.3}");
    println!("rate_step_lag_50pct_samples_n{N}={h}");
    println!("rate_step_lag_90pct_samples_n{N}={n}");
}

fn main() {
    let mut rng = seeded(2024);
    run::<32>(&mut rng);
    run::<64>(&mut rng);
}
