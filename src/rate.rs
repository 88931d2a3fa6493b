//! Filtered differentiator: temperature T̂ and rate Ṫ (°C/min) from timestamped readings.
//!
//! # Design
//! A least-squares line over a sliding window of the last `RATE_WINDOW` readings. Readings are
//! integers (1/16 °C) and timestamps are integer milliseconds, so the five running sums
//! (n, Σt, Σt², Σy, Σty) are kept **exactly**, with times relative to the oldest sample in
//! the window: Σt² and Σty in `i64`, Σt and Σy in `i32`, which the bounds below allow (8 B
//! less per estimator, with the alignment). Adding a sample and evicting the oldest (then moving the time
//! origin to the new oldest) are O(1) integer updates, so the estimate is bit-identical on
//! every platform and cannot drift, however long it runs. Only the final slope and
//! intercept are formed in f32.
//!
//! Why this and not an IIR differentiator: least squares with the real timestamps handles
//! irregular spacing and missing samples without special cases, its noise is the
//! Cramér–Rao bound of a slope fit over the window for white noise, and its response is
//! finite (a rate step is fully seen after `RATE_WINDOW` samples, no long tail). An optional
//! first-order smoother after the slope trades lag for noise.
//!
//! Figures (`cargo run --release -p host-tests --bin rate-bench`, a 32-sample window, 1 Hz, 12-bit
//! quantization plus 0.02 °C noise) are in the repository's `docs/measurements.md`.
//!
//! # Bounds
//! `RATE_WINDOW` is 3..=128 and a gap between samples above [`RateConfig::max_gap_ms`] (at most
//! 65 535 ms) restarts the window, so relative times stay below 2²³ ms and every product
//! in the sums stays below 2⁶⁰: no overflow is possible.

use core::fmt;

/// Tuning of the estimator.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RateConfig {
    /// A gap longer than this restarts the window (a dropout). At most 65 535.
    pub max_gap_ms: u16,
    /// Samples needed before the estimate is reported ready (at least 3).
    pub min_samples: u8,
    /// Smoothing after the slope: `s += alpha·(slope − s)` per sample. 1.0 is off.
    pub smoothing_alpha: f32,
}

impl Default for RateConfig {
    fn default() -> Self {
        Self { max_gap_ms: 30_000, min_samples: 8, smoothing_alpha: 1.0 }
    }
}

/// Why a sample was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// The timestamp equals or precedes the previous one (modulo 2³² wrap).
    NonMonotonic,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonMonotonic => f.write_str("timestamp not after the previous sample"),
        }
    }
}

impl core::error::Error for Error {}

/// What happened to an accepted sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Accepted {
    /// Added to the running window.
    Added,
    /// The gap was longer than `max_gap_ms`: the window restarted from this sample.
    Restarted,
}

/// Current estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Estimate {
    /// Temperature at the newest sample's time, from the fitted line, °C.
    pub temp_c: f32,
    /// Rate of change, °C/min (0 until ready).
    pub rate_c_per_min: f32,
    /// At least `min_samples` samples are in the window.
    pub ready: bool,
}

/// Seconds of readings at rest over which the bias branch should not flip on flicker (1 h).
pub const FLICKER_HOLD_S: f32 = 3600.0;

/// Probability allowed for such a flip (a false heating/cooling switch) over
/// [`FLICKER_HOLD_S`].
pub const FLICKER_FALSE_SWITCH: f32 = 0.01;

/// The smallest heating/cooling branch deadband (°C/min) that one-LSB DS18B20 flicker at a
/// constant temperature crosses, with probability at most [`FLICKER_FALSE_SWITCH`] in
/// [`FLICKER_HOLD_S`] of readings, for an `window`-sample slope at one reading every
/// `period_ms`.
///
/// # Derivation
/// At rest a 12-bit reading near a code edge flickers between two adjacent codes
/// (q = 1/16 °C; the DS18B20's own noise, ≈ 0.01 °C, is well under one LSB). The slope is
/// `Ṫ = Σ wᵢ·yᵢ` with `wᵢ = 60·(tᵢ − t̄)/S` (°C/min per °C) and `S = Σ(tᵢ − t̄)² =
/// P²·N(N² − 1)/12` for N readings P seconds apart; `Σ wᵢ = 0`, so its mean is 0 whatever
/// the flicker probability. Each term is bounded in a range of `|wᵢ|·q`, so Hoeffding's
/// inequality gives, for any flicker probability,
/// `Pr(Ṫ < −d) ≤ exp(−d²/(2σ²))`, `σ = 60·q/(2·√S)`
/// (σ is also the largest standard deviation flicker can give: a fair coin per reading).
/// A union bound over the `M = FLICKER_HOLD_S/P` estimates of the hold asks
/// `M·exp(−d²/(2σ²)) ≤ α`, so `d = σ·√(2·ln(M/α))`. For N = 32 at 1 s: σ = 0.0359 °C/min,
/// √(2 ln(3.6·10⁵)) = 5.06, d = 0.182 °C/min. The union bound ignores that consecutive
/// windows share N − 1 readings, so the real flip rate is far lower.
///
/// The hold (1 h) and α (1 %) were set before any navigation run with this rule (an
/// earlier what-if at 0.15 °C/min was known); d moves only with √ln of either (10 min at
/// 5 %: 0.156; 10 h at 0.1 %: 0.212 °C/min). Lower
/// resolutions have a larger q: scale the table's deadband by `2^(12 − bits)`.
///
/// Computed once, at construction (a square root and a logarithm), as
/// `d = (60·q/2)·√(2·ln(M/α)/S)`.
#[must_use]
pub fn flicker_deadband_c_per_min(window: usize, period_ms: u32) -> f32 {
    let n = window as f32;
    let p_s = period_ms.max(1) as f32 * 1e-3;
    let s = p_s * p_s * n * (n * n - 1.0) / 12.0;
    let m = FLICKER_HOLD_S / p_s;
    60.0 * 0.0625 / 2.0 * sqrt(2.0 * libm::logf(m / FLICKER_FALSE_SWITCH) / s)
}

/// √x for x > 0, to about one ulp: Newton's iteration from the halved exponent (within 4 %),
/// four steps (4 % → 0.08 % → 3·10⁻⁷ → one ulp). Written out because `libm::sqrtf` costs
/// 476 B of flash on a Cortex-M4 (its generic code and a 256-byte table) for one call at
/// construction, and `f32::sqrt` is not in `core`.
fn sqrt(x: f32) -> f32 {
    let mut y = f32::from_bits((x.to_bits() >> 1) + 0x1FC0_0000);
    for _ in 0..4 {
        y = 0.5 * (y + x / y);
    }
    y
}

/// `x as f32`, bit for bit (to nearest, ties to even), through the FPU's 32-bit conversion.
/// A 64-bit value is first narrowed to its top 32 significant bits, any bit shifted out kept
/// as a sticky bit 0: f32's 24 bits round the same from 32 bits as from 64, since the
/// guard bit and everything below it stay decided. Written here because the library's
/// `__aeabi_ul2f` is generic soft-float code, about 35 instructions a call on a Cortex-M4;
/// this takes about 12. Host tests compare it with `as` over random and edge values.
pub(crate) fn u64_to_f32(x: u64) -> f32 {
    let hi = (x >> 32) as u32;
    if hi == 0 {
        return x as u32 as f32;
    }
    // 1..=32: the top bit moves to bit 31.
    let shift = 32 - hi.leading_zeros();
    let sticky = u32::from(x << (64 - shift) != 0);
    let top = (x >> shift) as u32 | sticky;
    // × 2^shift is exact: top < 2³², so the product stays below 2⁶⁴.
    top as f32 * f32::from_bits((127 + shift) << 23)
}

/// `x as f32`, bit for bit: [`u64_to_f32`] of the magnitude, with the sign (rounding to
/// nearest is symmetric).
pub(crate) fn i64_to_f32(x: i64) -> f32 {
    let m = u64_to_f32(x.unsigned_abs());
    if x < 0 {
        -m
    } else {
        m
    }
}

/// The state of a sliding-window least-squares differentiator over `RATE_WINDOW` samples
/// (3..=128), without its configuration: each call takes the [`RateConfig`], so a
/// compensator's streams share the one in its `Config` instead of a copy each (8 B per
/// stream). [`RateEstimator`] is the same with its configuration kept beside it.
#[derive(Clone, Debug)]
pub struct RateWindow<const RATE_WINDOW: usize> {
    /// `gap[i]`: ms from the previous sample to sample `i`.
    gap: [u16; RATE_WINDOW],
    raw: [i16; RATE_WINDOW],
    /// Index of the oldest sample (`RATE_WINDOW` ≤ 128, so a byte holds it and `len`).
    head: u8,
    len: u8,
    /// Absolute timestamp of the newest sample.
    last_ms: u32,
    /// Newest sample's time relative to the oldest (below 2²³ ms: the module's bounds).
    newest_rel: i32,
    /// Σt, below 2³⁰; Σt², below 2⁶⁰.
    s_t: i32,
    s_tt: Sum64,
    /// Σy, below 2²² in magnitude; Σty, below 2⁶⁰.
    s_y: i32,
    s_ty: Sum64,
    /// The least-squares slope of the window, raw units per ms: formed once per sample
    /// (two 64-bit → f32 conversions and a division), read by `estimate`.
    slope: f32,
    smoothed: f32,
}

/// An i64 kept as two 32-bit words: 4-byte aligned, where an `i64` field makes the whole
/// window (and every struct holding one) 8-byte aligned, with up to 7 bytes of padding at
/// each level. On a Cortex-M4 the two words load and store as one `ldrd`/`strd` either way.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Sum64([u32; 2]);

impl Sum64 {
    const ZERO: Self = Self([0; 2]);

    fn get(self) -> i64 {
        (u64::from(self.0[1]) << 32 | u64::from(self.0[0])) as i64
    }

    fn set(&mut self, v: i64) {
        self.0 = [v as u32, (v >> 32) as u32];
    }
}

/// Raw units per ms → °C/min: 60 000 ms/min ÷ 16 raw/°C.
const RAW_PER_MS_TO_C_PER_MIN: f32 = 3750.0;

impl<const RATE_WINDOW: usize> Default for RateWindow<RATE_WINDOW> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const RATE_WINDOW: usize> RateWindow<RATE_WINDOW> {
    const BOUNDS: () = assert!(RATE_WINDOW >= 3 && RATE_WINDOW <= 128, "RATE_WINDOW must be 3..=128");

    /// Empty window.
    #[must_use]
    pub const fn new() -> Self {
        let () = Self::BOUNDS;
        Self {
            gap: [0; RATE_WINDOW],
            raw: [0; RATE_WINDOW],
            head: 0,
            len: 0,
            last_ms: 0,
            newest_rel: 0,
            s_t: 0,
            s_tt: Sum64::ZERO,
            s_y: 0,
            s_ty: Sum64::ZERO,
            slope: 0.0,
            smoothed: 0.0,
        }
    }

    /// Forget every sample (after a fault).
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// Samples in the window.
    #[must_use]
    pub const fn len(&self) -> usize {
        self.len as usize
    }

    /// No samples.
    #[must_use]
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The newest sample's timestamp (ms) and reading (1/16 °C); `None` while empty.
    #[must_use]
    pub fn newest(&self) -> Option<(u32, i16)> {
        let newest = (usize::from(self.head) + self.len().max(1) - 1) % RATE_WINDOW;
        (self.len > 0).then_some((self.last_ms, self.raw[newest]))
    }

    /// Enough samples for a rate under `config`.
    #[must_use]
    pub fn ready(&self, config: &RateConfig) -> bool {
        self.len >= config.min_samples.max(3)
    }

    /// The flicker floor of the window as it is filled now, °C/min, from `full`, the floor
    /// of a full window ([`flicker_deadband_c_per_min`]): `full·√(N(N² − 1)/(n(n² − 1)))`
    /// for n of N readings, since the floor goes as `1/√S` and `S ∝ n(n² − 1)` at the
    /// nominal period (a missed reading only widens S, so this stays on the safe side).
    /// 1.47 °C/min for 8 of 32 readings against 0.182 full: a branch decided on a partial
    /// window at the full window's floor was decided on its noise (the physics oracle found
    /// such a history, power-up at rest). `full` itself once the window is full, so the
    /// steady state costs one compare; `f32::MAX` below two readings (no slope).
    #[must_use]
    pub fn flicker_floor(&self, full: f32) -> f32 {
        let n = u32::from(self.len);
        // The mutants decide on the full window's floor whatever the window holds (the old
        // rule; with an unready window's slope too).
        if n as usize >= RATE_WINDOW
            || cfg!(qfa_mutant = "full_window_floor")
            || cfg!(qfa_mutant = "branch_on_unready_rate")
        {
            return full;
        }
        if n < 2 {
            return f32::MAX;
        }
        // N ≤ 128: N(N² − 1) < 2²¹, exact in u32 and in f32.
        let big = RATE_WINDOW as u32;
        let ratio = (big * (big * big - 1)) as f32 / (n * (n * n - 1)) as f32;
        full * sqrt(ratio)
    }

    /// Add a reading `raw` (1/16 °C) taken at `t_ms` (wrapping u32 ms) under `config`. O(1).
    ///
    /// # Errors
    /// [`Error::NonMonotonic`] if `t_ms` is not after the previous sample; the state is unchanged.
    pub fn push(&mut self, config: &RateConfig, t_ms: u32, raw: i16) -> Result<Accepted, Error> {
        let mut outcome = Accepted::Added;
        if self.len > 0 {
            let d = t_ms.wrapping_sub(self.last_ms);
            if d == 0 || d > i32::MAX as u32 {
                return Err(Error::NonMonotonic);
            }
            if d > u32::from(config.max_gap_ms) {
                self.reset();
                outcome = Accepted::Restarted;
            } else {
                if self.len() == RATE_WINDOW {
                    self.evict_oldest();
                }
                // d <= max_gap_ms <= u16::MAX, checked above.
                let d16 = d as u16;
                let idx = (usize::from(self.head) + self.len()) % RATE_WINDOW;
                self.gap[idx] = d16;
                self.raw[idx] = raw;
                self.len += 1;
                self.newest_rel += i32::from(d16);
                self.add_to_sums(self.newest_rel, raw);
                self.last_ms = t_ms;
                self.slope = self.slope_raw_per_ms();
                self.update_smoothing(config);
                return Ok(outcome);
            }
        }
        // First sample: it is the time origin. `head < RATE_WINDOW` always; `% RATE_WINDOW` shows the compiler,
        // so no bounds check (and no panic path) is emitted.
        let head = usize::from(self.head) % RATE_WINDOW;
        self.gap[head] = 0;
        self.raw[head] = raw;
        self.len = 1;
        self.newest_rel = 0;
        self.add_to_sums(0, raw);
        self.last_ms = t_ms;
        // One sample has no slope (`slope_raw_per_ms` gives 0 for it).
        self.slope = 0.0;
        Ok(outcome)
    }

    fn add_to_sums(&mut self, t: i32, raw: i16) {
        self.s_t += t;
        self.s_tt.set(self.s_tt.get() + i64::from(t) * i64::from(t));
        self.s_y += i32::from(raw);
        self.s_ty.set(self.s_ty.get() + i64::from(t) * i64::from(raw));
    }

    /// Remove the oldest sample (at relative time 0) and move the origin to the next one.
    fn evict_oldest(&mut self) {
        let head = usize::from(self.head) % RATE_WINDOW;
        self.s_y -= i32::from(self.raw[head]);
        let head = (head + 1) % RATE_WINDOW;
        // < RATE_WINDOW ≤ 128.
        self.head = head as u8;
        self.len -= 1;
        let d = i64::from(self.gap[head]);
        let n = i64::from(self.len);
        // Σ(t−d)² = Σt² − 2dΣt + nd², Σ(t−d) = Σt − nd, Σ(t−d)y = Σty − dΣy; exact. n·d is
        // below 2²³ (at most 127 gaps of at most 65 535 ms).
        self.s_tt.set(self.s_tt.get() - 2 * d * i64::from(self.s_t) + n * d * d);
        self.s_t -= i32::from(self.len) * i32::from(self.gap[head]);
        self.s_ty.set(self.s_ty.get() - d * i64::from(self.s_y));
        self.newest_rel -= i32::from(self.gap[head]);
        self.gap[head] = 0;
    }

    /// Least-squares slope in raw units per ms, from the exact sums.
    fn slope_raw_per_ms(&self) -> f32 {
        let n = i64::from(self.len);
        let s_t = i64::from(self.s_t);
        let den = n * self.s_tt.get() - s_t * s_t;
        if den <= 0 {
            return 0.0;
        }
        let num = n * self.s_ty.get() - s_t * i64::from(self.s_y);
        i64_to_f32(num) / u64_to_f32(den as u64)
    }

    fn update_smoothing(&mut self, config: &RateConfig) {
        let rate = self.slope * RAW_PER_MS_TO_C_PER_MIN;
        if self.ready(config) {
            let a = config.smoothing_alpha;
            self.smoothed += a * (rate - self.smoothed);
        } else {
            self.smoothed = rate;
        }
    }

    /// Current estimate under `config`, or `None` before the first sample: "no estimate
    /// yet" is not a number. Before it is ready, `temp_c` is the newest reading and the rate
    /// is 0.
    #[must_use]
    pub fn estimate(&self, config: &RateConfig) -> Option<Estimate> {
        if self.len == 0 {
            return None;
        }
        if !self.ready(config) {
            let newest = self.raw[(usize::from(self.head) + self.len() - 1) % RATE_WINDOW];
            #[cfg(qfa_mutant = "branch_on_unready_rate")]
            let rate_c_per_min = self.slope * RAW_PER_MS_TO_C_PER_MIN;
            #[cfg(not(qfa_mutant = "branch_on_unready_rate"))]
            let rate_c_per_min = 0.0;
            return Some(Estimate { temp_c: crate::ds18b20::raw_to_celsius(newest), rate_c_per_min, ready: false });
        }
        let n = i64::from(self.len);
        let slope = self.slope;
        // T̂(t_new) = (Σy + slope·(n·t_new − Σt)) / n, the fitted line at the newest time.
        // Through i32, which is exact here (the bounds in the module doc: the lever is at most
        // n·2²³ ≤ 2³⁰ and |Σy| at most n·2¹⁵ ≤ 2²²), so each is one `vcvt` on a Cortex-M4
        // instead of a 64-bit conversion call (about 30 instructions), with the same bits.
        let lever = (n * i64::from(self.newest_rel) - i64::from(self.s_t)) as i32 as f32;
        let raw_fit = (self.s_y as f32 + slope * lever) / f32::from(self.len);
        Some(Estimate { temp_c: raw_fit * 0.0625, rate_c_per_min: self.smoothed, ready: true })
    }
}

/// Sliding-window least-squares differentiator over `RATE_WINDOW` samples (3..=128): a
/// [`RateWindow`] with its [`RateConfig`] kept beside it.
#[derive(Clone, Debug)]
pub struct RateEstimator<const RATE_WINDOW: usize> {
    config: RateConfig,
    window: RateWindow<RATE_WINDOW>,
}

impl<const RATE_WINDOW: usize> RateEstimator<RATE_WINDOW> {
    /// Empty estimator.
    #[must_use]
    pub const fn new(config: RateConfig) -> Self {
        Self { config, window: RateWindow::new() }
    }

    /// Forget every sample (after a fault).
    pub fn reset(&mut self) {
        self.window.reset();
    }

    /// The configuration.
    #[must_use]
    pub const fn config(&self) -> RateConfig {
        self.config
    }

    /// Samples in the window.
    #[must_use]
    pub const fn len(&self) -> usize {
        self.window.len()
    }

    /// No samples.
    #[must_use]
    pub const fn is_empty(&self) -> bool {
        self.window.is_empty()
    }

    /// Enough samples for a rate.
    #[must_use]
    pub fn ready(&self) -> bool {
        self.window.ready(&self.config)
    }

    /// The flicker floor of the window as it is filled now: see
    /// [`RateWindow::flicker_floor`].
    #[must_use]
    pub fn flicker_floor(&self, full: f32) -> f32 {
        self.window.flicker_floor(full)
    }

    /// Add a reading `raw` (1/16 °C) taken at `t_ms` (wrapping u32 ms). O(1).
    ///
    /// # Errors
    /// [`Error::NonMonotonic`] if `t_ms` is not after the previous sample; the state is unchanged.
    pub fn push(&mut self, t_ms: u32, raw: i16) -> Result<Accepted, Error> {
        self.window.push(&self.config, t_ms, raw)
    }

    /// Current estimate, or `None` before the first sample: see [`RateWindow::estimate`].
    #[must_use]
    pub fn estimate(&self) -> Option<Estimate> {
        self.window.estimate(&self.config)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 64-bit conversions against Rust's own `as` (the library's correctly rounded
    /// conversion): every power of two and its neighbours, every tie pattern at each
    /// magnitude (a halfway value with an even and an odd kept bit, one below and one above),
    /// and two million xorshift values spread over every bit length.
    #[test]
    fn the_64_bit_conversions_round_as_the_library_does() {
        let check = |x: u64| {
            assert_eq!(u64_to_f32(x).to_bits(), (x as f32).to_bits(), "{x:#x}");
            let i = x as i64;
            assert_eq!(i64_to_f32(i).to_bits(), (i as f32).to_bits(), "{i}");
            assert_eq!(i64_to_f32(i.wrapping_neg()).to_bits(), (i.wrapping_neg() as f32).to_bits(), "-{i}");
        };
        for b in 0..64 {
            let p = 1u64 << b;
            for x in [p, p - 1, p + 1, p.wrapping_sub(2), p + 2, u64::MAX >> (63 - b)] {
                check(x);
            }
            // Above 2²⁴ a value with a half-ulp tail is a tie; its kept bit decides the rounding.
            if b >= 25 {
                let half = 1u64 << (b - 25);
                for kept in [p, p + 2 * half, p + 4 * half] {
                    for x in [kept + half, kept + half - 1, kept + half + 1] {
                        check(x);
                    }
                }
            }
        }
        let mut r = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..2_000_000 {
            r ^= r << 13;
            r ^= r >> 7;
            r ^= r << 17;
            check(r >> (r % 64));
        }
        check(i64::MIN as u64);
    }

    fn ramp(est: &mut RateEstimator<32>, t0: u32, n: u32, step_ms: u32, raw_per_step: i16) {
        for i in 0..n {
            est.push(t0.wrapping_add(i * step_ms), (i as i16) * raw_per_step).unwrap();
        }
    }

    #[test]
    fn exact_ramp_gives_exact_rate() {
        let mut e = RateEstimator::<32>::new(RateConfig::default());
        // 1 raw per second = 1/16 °C/s = 3.75 °C/min, exactly.
        ramp(&mut e, 1000, 100, 1000, 1);
        let est = e.estimate().unwrap();
        assert!(est.ready);
        // Exact integer sums; only the final int→f32 conversions and one division round.
        assert!((est.rate_c_per_min - 3.75).abs() <= 2.0 * f32::EPSILON * 3.75, "{}", est.rate_c_per_min);
        assert!((est.temp_c - 99.0 / 16.0).abs() <= 4.0 * f32::EPSILON * 7.0, "{}", est.temp_c);
    }

    #[test]
    fn time_origin_and_wrap_do_not_matter() {
        let mut a = RateEstimator::<32>::new(RateConfig::default());
        let mut b = RateEstimator::<32>::new(RateConfig::default());
        let ys = [3i16, 5, 4, 8, 9, 7, 12, 15, 14, 13, 18, 21, 20, 25, 24, 29, 30, 33, 31, 36];
        let mut t = 0u32;
        for (i, &y) in ys.iter().cycle().take(90).enumerate() {
            t += 700 + (i as u32 % 5) * 300; // irregular spacing
            a.push(t, y + i as i16).unwrap();
            b.push(t.wrapping_add(u32::MAX - 40_000), y + i as i16).unwrap();
        }
        assert_eq!(a.estimate(), b.estimate());
    }

    #[test]
    fn matches_f64_least_squares_with_irregular_spacing() {
        let mut e = RateEstimator::<16>::new(RateConfig::default());
        let mut samples = [(0i64, 0i64); 40];
        let mut t = 5u32;
        for (i, s) in samples.iter_mut().enumerate() {
            t += 400 + ((i * 7919) % 1300) as u32;
            let y = (i as i64 * 3) / 2 + ((i * 31) % 5) as i64;
            e.push(t, y as i16).unwrap();
            *s = (i64::from(t), y);
        }
        let w = &samples[samples.len() - 16..];
        let n = w.len() as f64;
        let mt = w.iter().map(|s| s.0 as f64).sum::<f64>() / n;
        let my = w.iter().map(|s| s.1 as f64).sum::<f64>() / n;
        let sxy: f64 = w.iter().map(|s| (s.0 as f64 - mt) * (s.1 as f64 - my)).sum();
        let sxx: f64 = w.iter().map(|s| (s.0 as f64 - mt).powi(2)).sum();
        let slope = sxy / sxx;
        let want_rate = slope * 3750.0;
        let want_t = (my + slope * (w[15].0 as f64 - mt)) / 16.0;
        let got = e.estimate().unwrap();
        assert!((f64::from(got.rate_c_per_min) - want_rate).abs() < 1e-5 * want_rate.abs().max(1.0));
        assert!((f64::from(got.temp_c) - want_t).abs() < 1e-5);
    }

    #[test]
    fn rejects_backwards_and_equal_time_without_change() {
        let mut e = RateEstimator::<32>::new(RateConfig::default());
        ramp(&mut e, 0, 20, 1000, 1);
        let before = e.estimate();
        assert_eq!(e.push(19_000, 5), Err(Error::NonMonotonic));
        assert_eq!(e.push(10_000, 5), Err(Error::NonMonotonic));
        assert_eq!(e.estimate(), before);
    }

    #[test]
    fn long_gap_restarts_and_reports_not_ready() {
        let mut e = RateEstimator::<32>::new(RateConfig::default());
        ramp(&mut e, 0, 20, 1000, 1);
        assert_eq!(e.push(19_000 + 31_000, 400), Ok(Accepted::Restarted));
        let est = e.estimate().unwrap();
        assert!(!est.ready);
        assert_eq!(est.temp_c, 25.0);
        assert_eq!(est.rate_c_per_min, 0.0);
    }

    #[test]
    fn no_estimate_before_the_first_sample() {
        let mut e = RateEstimator::<32>::new(RateConfig::default());
        assert_eq!(e.estimate(), None);
        e.push(0, 0).unwrap();
        assert_eq!(e.estimate().map(|x| x.temp_c), Some(0.0), "a real 0 °C reading");
        e.reset();
        assert_eq!(e.estimate(), None);
    }

    /// Worst-case flicker (a fair coin between two codes every second, 20 h): the rate's
    /// standard deviation is the σ of the derivation, and the derived deadband is never
    /// crossed, while the old 0.05 °C/min is crossed hundreds of times.
    /// Within one ulp of the correctly rounded f64 root across the floats the deadband
    /// formula meets (and far beyond it).
    #[test]
    fn newton_sqrt_is_within_one_ulp() {
        let mut x = 1e-12f32;
        while x < 1e12 {
            let want = f64::from(x).sqrt();
            let got = f64::from(sqrt(x));
            let ulp = f64::from(f32::EPSILON) * want;
            assert!((got - want).abs() <= ulp, "√{x}: {got} vs {want}");
            x *= 1.013;
        }
    }

    #[test]
    fn flicker_never_crosses_the_derived_deadband() {
        let mut e = RateEstimator::<32>::new(RateConfig::default());
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        let d = flicker_deadband_c_per_min(32, 1000);
        // Independent f64 figures: S = 32·1023/12 s², σ = 3.75/(2√S) °C/min.
        let sigma = 3.75 / (2.0 * (32.0f64 * 1023.0 / 12.0).sqrt());
        let want_d = sigma * (2.0 * (3600.0f64 / 0.01).ln()).sqrt();
        assert!((f64::from(d) - want_d).abs() < 1e-5, "{d} vs {want_d}");
        assert!((want_d - 0.1816).abs() < 1e-3, "{want_d}");
        let (mut n, mut s2, mut over_d, mut over_old) = (0u32, 0.0f64, 0u32, 0u32);
        for i in 0..72_000u32 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            e.push(i * 1000, 320 + (x >> 63) as i16).unwrap();
            let r = e.estimate().unwrap();
            if r.ready && e.len() == 32 {
                let v = f64::from(r.rate_c_per_min);
                n += 1;
                s2 += v * v;
                over_d += u32::from(v.abs() >= f64::from(d));
                over_old += u32::from(v.abs() > 0.05);
            }
        }
        let sd = (s2 / f64::from(n)).sqrt();
        println!(
            "flicker: σ(Ṫ) {sd:.4} °C/min (derived {sigma:.4}), |Ṫ| ≥ {d:.3}: {over_d}, > 0.05: {over_old} of {n}"
        );
        assert!((sd / sigma - 1.0).abs() < 0.05, "σ {sd} vs {sigma}");
        assert_eq!(over_d, 0);
        assert!(over_old > 1000, "{over_old}");
    }

    #[test]
    fn readiness_follows_min_samples() {
        let mut e = RateEstimator::<32>::new(RateConfig { min_samples: 5, ..RateConfig::default() });
        for i in 0..4 {
            e.push(i * 1000, 0).unwrap();
            assert!(!e.ready());
        }
        e.push(4000, 0).unwrap();
        assert!(e.ready());
    }
}
