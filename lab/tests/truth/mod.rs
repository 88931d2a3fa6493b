//! The independent truth generator: logs written by code that shares nothing with the
//! fitter or the lab simulator (its own temperature programs, its own exact integration of
//! the thermal lags at 1-s steps, its own noise and RNG, its own DS18B20 and pulse counter).
//! The discovery tests read its logs through the lab's readers, as a user's logs are read.
//!
//! Three log shapes:
//! - single-channel `time_s,temp_c,value` logs (a bias in µg), written by
//!   `discover_truth.rs` with this module's RNG and chamber;
//! - [`cycling`]: the four-position test's `program,run,time_s,input_g,temp_c,pulses,interval_s`
//!   at the paper's four ramp rates, +1 g and −1 g runs of each;
//! - [`desk`]: a static three-axis MEMS log of a board on a desk, days of slow room cycles.

#![allow(dead_code)]

/// xorshift64* with Box–Muller normals: the generator's own RNG.
pub struct Xs(u64);

impl Xs {
    /// Seeded.
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x2545_F491_4F6C_DD1D) | 1)
    }
    /// Uniform in (0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let v = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        ((v >> 11) as f64 + 0.5) / 9_007_199_254_740_992.0
    }
    /// Standard normal.
    pub fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// Piecewise-linear chamber temperature at `t_min` from (minute, °C) knots.
pub fn chamber(k: &[(f64, f64)], t_min: f64) -> f64 {
    match k.iter().position(|p| p.0 > t_min) {
        Some(0) => k[0].1,
        Some(i) => {
            let (a, b) = (k[i - 1], k[i]);
            a.1 + (b.1 - a.1) * (t_min - a.0) / (b.0 - a.0)
        }
        None => k[k.len() - 1].1,
    }
}

/// A stepped program: from `start_c`, 1-°C steps at `rate` °C/min with a 3-min dwell at
/// each integer, through each target in turn, after a `hold_min` hold; then `end_hold_min`.
pub fn stepped(start_c: f64, hold_min: f64, legs: &[(f64, f64)], end_hold_min: f64) -> Vec<(f64, f64)> {
    let mut k = vec![(0.0, start_c), (hold_min, start_c)];
    let (mut t, mut temp) = (hold_min, start_c);
    for &(rate, target) in legs {
        while (target - temp).abs() > 1e-9 {
            temp += (target - temp).signum();
            t += 1.0 / rate;
            k.push((t, temp));
            t += 3.0;
            k.push((t, temp));
        }
    }
    k.push((t + end_hold_min, temp));
    k
}

/// First-order lag step weight for a 1-s step (exact for a held input).
pub fn w1(tau_s: f64) -> f64 {
    1.0 - (-1.0 / tau_s).exp()
}

/// A DS18B20 reading of `t` (°C): 0.02 °C noise, 1/16-°C steps.
pub fn ds18b20(t: f64, rng: &mut Xs) -> f64 {
    ((t + 0.02 * rng.normal()) * 16.0).round() / 16.0
}

/// What a [`cycling`] log hides.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CyclingTruth {
    /// The element follows the case (where the DS18B20 sits) through a first-order lag, s.
    pub lag_s: Option<f64>,
    /// Bias ageing in time since each run's power-on, µg/h.
    pub ageing_ug_per_h: f64,
    /// Bias ageing in time since the first run started (the runs follow one another: a
    /// level that steps from run to run, which no catalog effect has), µg/h.
    pub campaign_ageing_ug_per_h: f64,
    /// Row (counting interval) length, s.
    pub row_s: f64,
    /// Coldest and hottest program temperatures, °C.
    pub span_c: (f64, f64),
}

impl Default for CyclingTruth {
    fn default() -> Self {
        Self { lag_s: None, ageing_ug_per_h: 0.0, campaign_ageing_ug_per_h: 0.0, row_s: 10.0, span_c: (-10.0, 50.0) }
    }
}

/// Scale factor of the generated unit, pulses/(g·s), at element temperature `te`: Eq. 11's
/// temperature terms only (no rate terms), JB-KT8-#2-like.
pub fn cycling_k1(te: f64) -> f64 {
    let d = te - 22.0;
    320_000.0 - 30.0 * d + 0.12 * d * d
}

/// Bias of the generated unit, g, at element temperature `te`.
pub fn cycling_k0(te: f64) -> f64 {
    let d = te - 22.0;
    120e-6 + 3e-6 * d + 0.02e-6 * d * d
}

/// A four-rate cycling log (0.3, 0.5, 0.7, 0.9 °C/min), +1 g and −1 g runs of each program
/// (each run a power-on of its own), as CSV text. Noise: 3 µg white per 10 s of counting,
/// a 1-µg Gauss–Markov bias instability (τ 20 min) per run, pulses counted as integers.
pub fn cycling(truth: CyclingTruth, seed: u64) -> String {
    let mut rng = Xs::new(seed.wrapping_add(0x5eed));
    let mut out = String::from("program,run,time_s,input_g,temp_c,pulses,interval_s\n");
    let (lo, hi) = truth.span_c;
    let mut campaign_s = 0.0;
    for rate in [0.3, 0.5, 0.7, 0.9] {
        let k = stepped(22.0, 30.0, &[(rate, lo), (rate, hi), (rate, 22.0)], 30.0);
        let end_s = k[k.len() - 1].0 * 60.0;
        for (run, g) in [("pos0", 1.0f64), ("pos2", -1.0)] {
            let (mut case, mut element, mut gm, mut reading) = (22.0f64, 22.0f64, 0.0f64, 22.0f64);
            let (mut counted, mut carry) = (0.0f64, 0.0f64);
            let (mut t, mut row_t) = (0.0f64, 0.0f64);
            let mut last_rate: Option<f64> = None;
            let phi = (-1.0 / 1200.0f64).exp();
            while t < end_s {
                t += 1.0;
                case += w1(300.0) * (chamber(&k, t / 60.0) - case);
                let te = match truth.lag_s {
                    Some(tau) => {
                        element += w1(tau) * (case - element);
                        element
                    }
                    None => case,
                };
                gm = phi * gm + 1e-6 * (1.0 - phi * phi).sqrt() * rng.normal();
                let ageing = truth.ageing_ug_per_h * t + truth.campaign_ageing_ug_per_h * (campaign_s + t);
                let bias = cycling_k0(te) + 1e-6 * ageing / 3600.0 + gm;
                // White noise: 3 µg per 10 s of counting, so 3·√10 µg per second. The
                // counter integrates continuously: trapezoids over each second.
                let rate_now = cycling_k1(te) * (g + bias);
                counted += 0.5 * (last_rate.unwrap_or(rate_now) + rate_now)
                    + cycling_k1(te) * 3e-6 * 10f64.sqrt() * rng.normal();
                last_rate = Some(rate_now);
                // One DS18B20 conversion per second; the row carries the latest.
                reading = ds18b20(case, &mut rng);
                if t - row_t >= truth.row_s - 1e-9 {
                    let total = counted + carry;
                    let pulses = total.round();
                    carry = total - pulses;
                    out.push_str(&format!("rate-{rate:.1},{run},{t:.1},{g},{reading:.4},{pulses},{:.1}\n", t - row_t));
                    counted = 0.0;
                    row_t = t;
                }
            }
            let _ = reading;
            campaign_s += end_s;
        }
    }
    out
}

/// A static three-axis log of a MEMS board on a desk for `hours` h: room temperature in
/// slow daily cycles (7 °C peak to peak, plus a slow wander), 10-s rows, accelerations in g
/// (`time_s,temp_c,ax_g,ay_g,az_g`). Each axis's bias is a smooth cubic in the board
/// temperature (which follows the room through a 20-min lag); noise 0.3 mg white per row
/// and a 50-µg Gauss–Markov part (τ 1 h).
pub fn desk(hours: f64, seed: u64) -> String {
    let mut rng = Xs::new(seed.wrapping_add(0xde5c));
    let mut out = String::from("time_s,temp_c,ax_g,ay_g,az_g\n");
    let coeff = [(0.8e-3, 0.25e-3, -4e-6, 0.3e-6), (-0.5e-3, -0.15e-3, 6e-6, -0.2e-6), (1.0, 0.1e-3, 2e-6, 0.1e-6)];
    let phase = 2.0 * std::f64::consts::PI * rng.uniform();
    let (mut board, mut wander, mut gm) = (24.0f64, 0.0f64, [0.0f64; 3]);
    let phi = (-1.0 / 3600.0f64).exp();
    let mut t = 0.0;
    while t < hours * 3600.0 {
        t += 1.0;
        wander += 0.002 * rng.normal() - wander / 20_000.0;
        let room = 24.0 + 3.5 * (2.0 * std::f64::consts::PI * t / 86_400.0 + phase).sin() + wander;
        board += w1(1200.0) * (room - board);
        for g in &mut gm {
            *g = phi * *g + 50e-6 * (1.0 - phi * phi).sqrt() * rng.normal();
        }
        if (t as u64).is_multiple_of(10) {
            let d = board - 24.0;
            let mut line = format!("{t:.1},{:.4}", ds18b20(board, &mut rng));
            for (c, g) in coeff.iter().zip(gm) {
                let a = c.0 + c.1 * d + c.2 * d * d + c.3 * d * d * d + g + 0.3e-3 * rng.normal();
                line.push_str(&format!(",{a:.7}"));
            }
            out.push_str(&line);
            out.push('\n');
        }
    }
    out
}
