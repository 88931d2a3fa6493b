//! Compensator settings and their validation.

#[cfg(doc)]
use super::{Compensator, Status};
use core::fmt;

use crate::rate::RateConfig;
use crate::table;

/// Why a [`Config`] was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ConfigError {
    /// A field is NaN or infinite.
    NonFinite(&'static str),
    /// A field is outside its allowed range (the field's doc gives the range).
    OutOfRange(&'static str),
    /// `stale_after_ticks` is not longer than one sample period: every cycle would be stale.
    StaleShorterThanSamplePeriod,
    /// The rate window restarts after a gap shorter than one sample period.
    GapShorterThanSamplePeriod,
    /// `rate.min_samples` exceeds the window `RATE_WINDOW`: the rate would never be ready.
    MinSamplesAboveWindow,
    /// [`Input::Samples`](table::Input::Samples) without [`Config::sample_lsb_per_g`]: the
    /// part's raw LSB could not be brought to the table's scale.
    SampleScaleNotStated,
    /// [`Config::imu_period_s`] is under [`IMU_PERIOD_TOLERANCE`] ticks of
    /// [`Config::tick_s`], or its band reaches past 2³⁰ ticks.
    ImuPeriodInTicks,
}

/// How far a cycle's `dt_ticks` may be from [`Config::imu_period_s`] before
/// [`Status::DT_IMPLAUSIBLE`]: a factor of 4 either way. The mistakes it is for are
/// factors of 10 or more (CPU cycles at 168 MHz given as 1-µs ticks: 168×; milliseconds as
/// microseconds: 1 000×); a cycle three IMU interrupts late (4×) is still accepted.
pub const IMU_PERIOD_TOLERANCE: u32 = 4;

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFinite(what) => write!(f, "{what} is not finite"),
            Self::OutOfRange(what) => write!(f, "{what} is out of range"),
            Self::StaleShorterThanSamplePeriod => f.write_str("stale threshold not longer than one sample period"),
            Self::GapShorterThanSamplePeriod => f.write_str("rate max_gap_ms shorter than one sample period"),
            Self::MinSamplesAboveWindow => f.write_str("rate min_samples above the window length"),
            Self::ImuPeriodInTicks => f.write_str("imu_period_s out of range in ticks"),
            Self::SampleScaleNotStated => f.write_str("samples need sample_lsb_per_g, the part's LSB per g"),
        }
    }
}

impl core::error::Error for ConfigError {}

/// Compensator settings. Checked by [`Config::validate`]; [`Compensator::new`] refuses a
/// config that fails it.
///
/// Start from [`Config::default`] (1 µs ticks, a 2.5-ms IMU cycle, 1 Hz readings, stale
/// after 3 s, pulse counts, a JB-KT8-class nominal scale) and change what your hardware
/// differs in:
///
/// ```
/// use qfa_thermal::{Compensator, Config, ConfigError, Input};
///
/// // A ±8 g 16-bit MEMS accelerometer (4 096 LSB/g), read at 1 kHz on a 100 ns timer.
/// let config = Config {
///     input: Input::Samples,
///     sample_lsb_per_g: 4_096.0,
///     tick_s: 1e-7,
///     imu_period_s: 1e-3,
///     stale_after_ticks: 30_000_000,
///     ..Config::default()
/// };
/// assert_eq!(config.validate(), Ok(()));
///
/// // One reading confirming itself would switch the plausibility checks off: refused.
/// let bad = Config { confirm_samples: 1, ..Config::default() };
/// assert_eq!(bad.validate(), Err(ConfigError::OutOfRange("confirm_samples")));
/// assert!(Compensator::<3>::new(bad).is_err());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Config {
    /// Length of one fast-path tick, s (default 1 µs; 1 ns..1 s).
    pub tick_s: f32,
    /// The IMU's cycle period, s (default 2.5 ms, 400 Hz): the `dt_ticks` the fast path
    /// expects (up to 60 s), in seconds so that it does not share a unit mistake with
    /// `dt_ticks`. A cycle
    /// whose `dt_ticks · tick_s` is more than [`IMU_PERIOD_TOLERANCE`] times off it raises
    /// [`Status::DT_IMPLAUSIBLE`]: its bias term `K0·dt` and the staleness clock would be
    /// wrong by that factor. With the default, cycles of 0.625..10 ms pass: set your IMU's
    /// own period.
    pub imu_period_s: f32,
    /// Ticks without a good temperature before [`Status::TEMP_STALE`] (default 3 s); must
    /// be longer than [`sample_period_ms`](Self::sample_period_ms) and below 2³¹ − 1.
    pub stale_after_ticks: u32,
    /// Nominal period of each sensor's readings, ms (default 1 000; 1..=60 000).
    pub sample_period_ms: u32,
    /// The input the fast path is given (default pulse counts). A table fitted for another
    /// input is refused ([`table::Error::Input`]), and a fast-path call of the other kind
    /// raises [`Status::WRONG_INPUT`].
    pub input: table::Input,
    /// Rate estimator settings.
    pub rate: RateConfig,
    /// Step allowed between good readings regardless of time, 1/16 °C (default 16 = 1 °C; ≥ 0).
    pub max_step_raw: i16,
    /// Slew allowed between good readings, 1/16 °C per minute (default 160 = 10 °C/min; ≥ 0).
    pub max_slew_raw_per_min: i32,
    /// Consecutive mutually consistent readings that are accepted as a real step or a
    /// restarted clock (default 3; 2..=16: one reading confirming itself would switch off
    /// both the plausibility and the restart checks).
    pub confirm_samples: u8,
    /// Pulse counts: the scale factor used while no table is loaded, pulses/(g·s). Default
    /// 320 000, a JB-KT8-class QFA (Zhang et al. 2021, Eq. 15–17: γ = 308 000…328 000); set
    /// the nominal of your own sensor. A table's γ must be within a factor of 2 of it
    /// ([`table::Error::Scale`]). Not used for samples: see `sample_lsb_per_g`.
    pub nominal_k1: f32,
    /// Samples: the part's own sensitivity at the range it is set to, LSB per g, from its
    /// datasheet (4 096 for a ±8 g 16-bit part, 2 048 at ±16 g). Required with
    /// [`Input::Samples`](table::Input::Samples) (default 0, not stated: refused with
    /// [`ConfigError::SampleScaleNotStated`]); not used for pulse counts. The fast path takes
    /// the part's raw LSB as it gives them, and the slow path brings them to the table's
    /// [`table::SAMPLE_UNITS_PER_G`] once per reading, so no hand-written multiplier can be
    /// left out or be the wrong range's. A table that records the sensitivity it was
    /// calibrated at ([`Table::part_lsb_per_g`](crate::Table::part_lsb_per_g)) is refused
    /// unless this equals it ([`table::Error::PartScale`]).
    pub sample_lsb_per_g: f32,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            tick_s: 1e-6,
            imu_period_s: 2.5e-3,
            stale_after_ticks: 3_000_000,
            sample_period_ms: 1_000,
            input: table::Input::PulseCounts,
            rate: RateConfig::default(),
            max_step_raw: 16,
            max_slew_raw_per_min: 160,
            confirm_samples: 3,
            nominal_k1: 320_000.0,
            sample_lsb_per_g: 0.0,
        }
    }
}

impl Config {
    /// Check every field and their relations.
    ///
    /// # Errors
    /// The first [`ConfigError`] found.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !self.tick_s.is_finite() {
            return Err(ConfigError::NonFinite("tick_s"));
        }
        if !(1e-9..=1.0).contains(&self.tick_s) {
            return Err(ConfigError::OutOfRange("tick_s"));
        }
        if !self.imu_period_s.is_finite() {
            return Err(ConfigError::NonFinite("imu_period_s"));
        }
        if !(self.imu_period_s > 0.0 && self.imu_period_s <= 60.0) {
            return Err(ConfigError::OutOfRange("imu_period_s"));
        }
        if self.dt_band().is_none() {
            return Err(ConfigError::ImuPeriodInTicks);
        }
        if !self.nominal_k1.is_finite() {
            return Err(ConfigError::NonFinite("nominal_k1"));
        }
        if !(table::limits::GAMMA.0..=table::limits::GAMMA.1).contains(&self.nominal_k1) {
            return Err(ConfigError::OutOfRange("nominal_k1"));
        }
        if self.input == table::Input::Samples {
            if self.sample_lsb_per_g == 0.0 {
                return Err(ConfigError::SampleScaleNotStated);
            }
            if !self.sample_lsb_per_g.is_finite() {
                return Err(ConfigError::NonFinite("sample_lsb_per_g"));
            }
            if !(table::limits::GAMMA.0..=table::limits::GAMMA.1).contains(&self.sample_lsb_per_g) {
                return Err(ConfigError::OutOfRange("sample_lsb_per_g"));
            }
        }
        let a = self.rate.smoothing_alpha;
        if !a.is_finite() {
            return Err(ConfigError::NonFinite("rate.smoothing_alpha"));
        }
        if !(a > 0.0 && a <= 1.0) {
            return Err(ConfigError::OutOfRange("rate.smoothing_alpha"));
        }
        if self.rate.min_samples < 3 {
            return Err(ConfigError::OutOfRange("rate.min_samples"));
        }
        if !(1..=60_000).contains(&self.sample_period_ms) {
            return Err(ConfigError::OutOfRange("sample_period_ms"));
        }
        if u32::from(self.rate.max_gap_ms) <= self.sample_period_ms {
            return Err(ConfigError::GapShorterThanSamplePeriod);
        }
        if self.stale_after_ticks >= i32::MAX as u32 {
            // The fast path's countdown starts at stale_after_ticks + 1 and needs it ≤ 2³¹.
            return Err(ConfigError::OutOfRange("stale_after_ticks"));
        }
        let stale_s = self.stale_after_ticks as f32 * self.tick_s;
        if stale_s * 1000.0 <= self.sample_period_ms as f32 {
            return Err(ConfigError::StaleShorterThanSamplePeriod);
        }
        if self.max_step_raw < 0 {
            return Err(ConfigError::OutOfRange("max_step_raw"));
        }
        if self.max_slew_raw_per_min < 0 {
            return Err(ConfigError::OutOfRange("max_slew_raw_per_min"));
        }
        if !(2..=16).contains(&self.confirm_samples) {
            return Err(ConfigError::OutOfRange("confirm_samples"));
        }
        Ok(())
    }

    /// The `dt_ticks` a cycle may take without [`Status::DT_IMPLAUSIBLE`], as
    /// `(lowest, highest − lowest)`: with `P` the IMU period rounded to whole ticks, every
    /// `dt` with `P ≤ 4·dt` and `dt ≤ 4·P`. `None` when `P` is under
    /// [`IMU_PERIOD_TOLERANCE`] ticks (the band would start at 0) or `4·P` passes 2³⁰.
    pub(super) fn dt_band(&self) -> Option<(u32, u32)> {
        // Formed once, at construction: a division here costs the fast path nothing.
        // Rounded to whole ticks by adding a half before the cast (the period is positive).
        let period = self.imu_period_s / self.tick_s + 0.5;
        let k = IMU_PERIOD_TOLERANCE;
        if !(period >= k as f32 && period < ((1u32 << 30) / k) as f32) {
            return None;
        }
        let p = period as u32;
        let lowest = p.div_ceil(k);
        Some((lowest, p * k - lowest))
    }

    /// The input's units per g: [`nominal_k1`](Self::nominal_k1) for pulse counts (per
    /// second), the part's [`sample_lsb_per_g`](Self::sample_lsb_per_g) for samples.
    pub(super) fn input_per_g(&self) -> f32 {
        match self.input {
            table::Input::PulseCounts => self.nominal_k1,
            table::Input::Samples => self.sample_lsb_per_g,
        }
    }

    /// What a table's K1 is multiplied by to be in the input's units: 1 for pulse counts
    /// (the table is in them), the part's LSB per 2²⁰ units for samples.
    pub(super) fn table_to_input(&self) -> f32 {
        match self.input {
            table::Input::PulseCounts => 1.0,
            table::Input::Samples => self.sample_lsb_per_g * (1.0 / table::SAMPLE_UNITS_PER_G),
        }
    }

    /// The stale threshold in ms (for comparing sensors' timestamps in the slow path).
    pub(super) fn stale_after_ms(&self) -> u32 {
        let ms = self.stale_after_ticks as f32 * self.tick_s * 1000.0;
        if ms >= u32::MAX as f32 {
            u32::MAX
        } else {
            ms as u32
        }
    }
}
