//! The compensator: a per-temperature-sample path and a per-IMU-cycle path.
//!
//! * **Slow path** ([`Compensator::on_scratchpad`], [`Compensator::on_raw`], about 1 Hz):
//!   validate the reading, update the rate estimator, evaluate each axis's model and cache
//!   `g0/K1` (m/s per pulse) and `K0·g0·tick` (m/s per tick) for the fast path.
//! * **Fast path** ([`Compensator::cycle`], 200 Hz–2 kHz): per axis
//!   `Δv = N·(g0/K1) − (K0·g0·tick)·dt_ticks`, then the optional misalignment matrix.
//!   No division, no transcendental function, no search, loops bounded by `AXES`.
//!   Measured cost under QEMU (`cargo xtask bench-target`) is in the README.
//!
//! Faults never produce a silent wrong answer: a rejected reading returns a typed
//! [`SampleError`], raises [`Status::TEMP_INVALID`] and keeps the last good compensation;
//! no reading for `stale_after_ticks` raises [`Status::TEMP_STALE`]. Outputs are always
//! finite: table validation bounds `g0/K1` and `K0`, and the inputs are integers.

use core::fmt;

use crate::ds18b20::{self, POWER_ON_RAW};
use crate::model::{AxisState, Evaluation};
use crate::rate::{self, RateConfig, RateEstimator};
use crate::table::{self, Table};

/// Standard gravity, m/s² (the unit the tables' g refers to).
pub const G0: f32 = 9.806_65;

/// Status word: one bit per condition, OR-ed together.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Status(pub u16);

impl Status {
    /// No good temperature for longer than `stale_after_ticks` (or none yet).
    pub const TEMP_STALE: u16 = 1 << 0;
    /// The latest reading was rejected; the last good compensation is in use.
    pub const TEMP_INVALID: u16 = 1 << 1;
    /// The rate estimator has too few samples; Ṫ = 0 is used.
    pub const RATE_NOT_READY: u16 = 1 << 2;
    /// Temperature outside the calibrated range: clamped.
    pub const TEMP_OUT_OF_RANGE: u16 = 1 << 3;
    /// |Ṫ| above the calibrated limit: clamped.
    pub const RATE_OUT_OF_RANGE: u16 = 1 << 4;
    /// No table loaded: outputs are zero.
    pub const NO_TABLE: u16 = 1 << 5;
    /// Cumulative counters had no previous value: increments of this cycle are zero.
    pub const NO_COUNTER_BASE: u16 = 1 << 6;

    /// Whether `bit` is set.
    #[must_use]
    pub const fn contains(self, bit: u16) -> bool {
        self.0 & bit != 0
    }

    /// No condition at all: fully compensated from a fresh, calibrated temperature.
    #[must_use]
    pub const fn is_ok(self) -> bool {
        self.0 == 0
    }
}

/// Why a temperature sample was not used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SampleError {
    /// The scratchpad failed decoding.
    Decode(ds18b20::Error),
    /// Timestamp not after the previous good sample.
    Time(rate::Error),
    /// The power-on value 0550h (+85 °C) arrived as a jump, or as the first reading.
    PowerOnJump,
    /// The reading jumped further from the last good one than physically plausible.
    Implausible {
        /// The rejected raw value, 1/16 °C.
        raw: i16,
    },
}

impl fmt::Display for SampleError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Decode(e) => write!(f, "scratchpad: {e}"),
            Self::Time(e) => write!(f, "time: {e}"),
            Self::PowerOnJump => f.write_str("power-on value 0550h arrived as a jump"),
            Self::Implausible { raw } => write!(f, "implausible jump to raw {raw}"),
        }
    }
}

impl core::error::Error for SampleError {}

/// Compensator settings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Config {
    /// Length of one fast-path tick, s (default 1 µs).
    pub tick_s: f32,
    /// Ticks without a good temperature before [`Status::TEMP_STALE`] (default 3 s).
    pub stale_after_ticks: u32,
    /// Rate estimator settings.
    pub rate: RateConfig,
    /// Step allowed between good readings regardless of time, 1/16 °C (default 16 = 1 °C).
    pub max_step_raw: i16,
    /// Slew allowed between good readings, 1/16 °C per minute (default 160 = 10 °C/min).
    pub max_slew_raw_per_min: i32,
    /// Consecutive mutually consistent jumped readings that are accepted as a real step.
    pub confirm_samples: u8,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            tick_s: 1e-6,
            stale_after_ticks: 3_000_000,
            rate: RateConfig::default(),
            max_step_raw: 16,
            max_slew_raw_per_min: 160,
            confirm_samples: 3,
        }
    }
}

/// Output of one IMU cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Output<const AXES: usize> {
    /// Compensated velocity increment per axis, m/s.
    pub dv_mps: [f32; AXES],
    /// Conditions in force.
    pub status: Status,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Timed {
    t_ms: u32,
    raw: i16,
}

/// Temperature compensation for `AXES` accelerometers with an `N`-sample rate window.
#[derive(Clone, Debug)]
pub struct Compensator<const AXES: usize = 3, const N: usize = 32> {
    config: Config,
    table: Option<Table>,
    rate: RateEstimator<N>,
    states: [AxisState; AXES],
    evals: [Evaluation; AXES],
    // Fast-path cache, written only by the slow path and table loads.
    scale: [f32; AXES],
    bias: [f32; AXES],
    misalign: Option<[[f32; AXES]; AXES]>,
    status: u16,
    since_sample_ticks: u32,
    counters: Option<[u32; AXES]>,
    // Plausibility of readings.
    last_good: Option<Timed>,
    pending: Option<Timed>,
    pending_count: u8,
}

const NO_EVAL: Evaluation = Evaluation { k1: 0.0, k0: 0.0, temp_clamped: false, rate_clamped: false };

impl<const AXES: usize, const N: usize> Compensator<AXES, N> {
    const BOUNDS: () = assert!(AXES >= 1 && AXES <= table::MAX_AXES, "AXES must be 1..=3");

    /// A compensator with no table: outputs are zero with [`Status::NO_TABLE`] until
    /// [`load_table`](Self::load_table) succeeds.
    #[must_use]
    pub fn new(config: Config) -> Self {
        let () = Self::BOUNDS;
        Self {
            config,
            table: None,
            rate: RateEstimator::new(config.rate),
            states: [AxisState::default(); AXES],
            evals: [NO_EVAL; AXES],
            scale: [0.0; AXES],
            bias: [0.0; AXES],
            misalign: None,
            status: Status::NO_TABLE | Status::TEMP_STALE | Status::RATE_NOT_READY,
            since_sample_ticks: u32::MAX,
            counters: None,
            last_good: None,
            pending: None,
            pending_count: 0,
        }
    }

    /// Decode, validate and activate a table from its wire bytes. Atomic: on any error the
    /// active table and every state are unchanged.
    ///
    /// # Errors
    /// Any [`table::Error`], including an axis count other than `AXES` and a rate window
    /// other than `N`.
    pub fn load_table(&mut self, bytes: &[u8]) -> table::Result<()> {
        let t = Table::decode(bytes)?;
        self.set_table(t)
    }

    /// Validate and activate an already decoded table. Atomic like [`load_table`](Self::load_table).
    ///
    /// # Errors
    /// As [`load_table`](Self::load_table).
    pub fn set_table(&mut self, t: Table) -> table::Result<()> {
        t.validate()?;
        if t.axes.len() != AXES {
            return Err(table::Error::AxisCount { table: t.axes.len() as u8, expected: AXES as u8 });
        }
        if usize::from(t.rate_window) != N {
            return Err(table::Error::RateWindow { table: t.rate_window, firmware: N as u16 });
        }
        self.misalign = t.misalignment.map(|m| {
            // Validation allows a matrix only with 3 axes, so AXES == 3 here.
            core::array::from_fn(|r| core::array::from_fn(|c| m[r * 3 + c]))
        });
        self.table = Some(t);
        self.states = [AxisState::default(); AXES];
        self.refresh(0.0);
        Ok(())
    }

    /// The active table.
    #[must_use]
    pub fn table(&self) -> Option<&Table> {
        self.table.as_ref()
    }

    /// Settings.
    #[must_use]
    pub const fn config(&self) -> &Config {
        &self.config
    }

    /// The rate estimator's current estimate.
    #[must_use]
    pub fn estimate(&self) -> rate::Estimate {
        self.rate.estimate()
    }

    /// The model evaluated at the last good sample, per axis (K1 in pulses/(g·s), K0 in g).
    #[must_use]
    pub const fn evaluations(&self) -> &[Evaluation; AXES] {
        &self.evals
    }

    /// Status as of the last slow-path call (the fast path adds staleness).
    #[must_use]
    pub const fn status(&self) -> Status {
        Status(self.status)
    }

    /// Slow path: a 9-byte scratchpad read at `t_ms` (wrapping ms, taken when the
    /// conversion completed).
    ///
    /// # Errors
    /// A [`SampleError`]; the last good compensation stays in force and
    /// [`Status::TEMP_INVALID`] is raised.
    pub fn on_scratchpad(&mut self, t_ms: u32, scratchpad: &[u8; 9]) -> Result<Status, SampleError> {
        match ds18b20::decode_scratchpad(scratchpad) {
            Ok(r) => self.on_raw(t_ms, r.raw),
            Err(e) => self.reject(SampleError::Decode(e)),
        }
    }

    /// Slow path: a raw reading (1/16 °C, already masked) taken at `t_ms`.
    ///
    /// # Errors
    /// As [`on_scratchpad`](Self::on_scratchpad).
    pub fn on_raw(&mut self, t_ms: u32, raw: i16) -> Result<Status, SampleError> {
        let mut restart = false;
        match self.last_good {
            None if raw == POWER_ON_RAW => return self.reject(SampleError::PowerOnJump),
            None => {}
            Some(last) => {
                let d = t_ms.wrapping_sub(last.t_ms);
                if d == 0 || d > i32::MAX as u32 {
                    return self.reject(SampleError::Time(rate::Error::NonMonotonic));
                }
                if !self.plausible(last, t_ms, raw) {
                    if raw == POWER_ON_RAW {
                        return self.reject(SampleError::PowerOnJump);
                    }
                    if !self.confirm_step(t_ms, raw) {
                        return self.reject(SampleError::Implausible { raw });
                    }
                    restart = true;
                }
            }
        }
        if restart {
            self.rate.reset();
        }
        let prev_ms = self.last_good.map(|l| l.t_ms);
        if let Err(e) = self.rate.push(t_ms, raw) {
            return self.reject(SampleError::Time(e));
        }
        self.pending = None;
        self.pending_count = 0;
        self.last_good = Some(Timed { t_ms, raw });
        self.since_sample_ticks = 0;
        let dt_s = prev_ms.map_or(0.0, |p| t_ms.wrapping_sub(p) as f32 * 1e-3);
        self.refresh(dt_s);
        Ok(Status(self.status))
    }

    /// |raw − last.raw| within step + slew·elapsed.
    fn plausible(&self, last: Timed, t_ms: u32, raw: i16) -> bool {
        let d_ms = i64::from(t_ms.wrapping_sub(last.t_ms));
        let allowed =
            i64::from(self.config.max_step_raw) + i64::from(self.config.max_slew_raw_per_min) * d_ms / 60_000;
        (i64::from(raw) - i64::from(last.raw)).abs() <= allowed
    }

    /// Count consecutive jumped readings consistent with each other; true once there are
    /// `confirm_samples` of them (a real step, e.g. after the sensor was replaced).
    fn confirm_step(&mut self, t_ms: u32, raw: i16) -> bool {
        match self.pending {
            Some(p) if t_ms.wrapping_sub(p.t_ms) < i32::MAX as u32 && self.plausible(p, t_ms, raw) => {
                self.pending_count = self.pending_count.saturating_add(1);
            }
            _ => self.pending_count = 1,
        }
        self.pending = Some(Timed { t_ms, raw });
        self.pending_count >= self.config.confirm_samples
    }

    fn reject(&mut self, e: SampleError) -> Result<Status, SampleError> {
        self.status |= Status::TEMP_INVALID;
        Err(e)
    }

    /// Re-evaluate every axis at the current estimate (or at T0 before the first reading)
    /// and rebuild the fast-path cache.
    fn refresh(&mut self, dt_s: f32) {
        let est = self.rate.estimate();
        let mut st = 0u16;
        if !est.ready {
            st |= Status::RATE_NOT_READY;
        }
        let Some(table) = &self.table else {
            self.scale = [0.0; AXES];
            self.bias = [0.0; AXES];
            self.status = st | Status::NO_TABLE;
            return;
        };
        let have_temp = self.last_good.is_some();
        for (i, axis) in table.axes.iter().take(AXES).enumerate() {
            let e = if have_temp {
                axis.evaluate(&mut self.states[i], est.temp_c, est.rate_c_per_min, dt_s)
            } else {
                // No reading yet: T0 and Ṫ = 0, without touching the state; flagged stale.
                axis.evaluate(&mut AxisState::default(), axis.scale.t0_c, 0.0, 0.0)
            };
            if e.temp_clamped {
                st |= Status::TEMP_OUT_OF_RANGE;
            }
            if e.rate_clamped {
                st |= Status::RATE_OUT_OF_RANGE;
            }
            self.evals[i] = e;
            self.scale[i] = G0 / e.k1;
            self.bias[i] = (e.k0 * G0) * self.config.tick_s;
        }
        if !have_temp {
            st |= Status::TEMP_STALE;
        }
        self.status = st;
    }

    /// Fast path: signed pulse counts of this cycle and its length in ticks.
    ///
    /// `Δv[i] = N[i]·(g0/K1[i]) − (K0[i]·g0·tick)·dt`, then `Δv = M·Δv` with a
    /// misalignment matrix. Always finite.
    #[inline]
    pub fn cycle(&mut self, pulses: [i32; AXES], dt_ticks: u32) -> Output<AXES> {
        self.since_sample_ticks = self.since_sample_ticks.saturating_add(dt_ticks);
        let stale = if self.since_sample_ticks > self.config.stale_after_ticks { Status::TEMP_STALE } else { 0 };
        let dt = dt_ticks as f32;
        let mut dv = [0.0f32; AXES];
        for i in 0..AXES {
            dv[i] = pulses[i] as f32 * self.scale[i] - self.bias[i] * dt;
        }
        if let Some(m) = &self.misalign {
            let raw = dv;
            for (out, row) in dv.iter_mut().zip(m.iter()) {
                let mut acc = 0.0f32;
                for (a, b) in row.iter().zip(raw.iter()) {
                    acc += a * b;
                }
                *out = acc;
            }
        }
        Output { dv_mps: dv, status: Status(self.status | stale) }
    }

    /// Fast path from wrapping cumulative u32 counters. The first call after
    /// [`new`](Self::new) has no base: it returns zero increments with
    /// [`Status::NO_COUNTER_BASE`]; call [`prime_counters`](Self::prime_counters) to avoid it.
    #[inline]
    pub fn cycle_counters(&mut self, counters: [u32; AXES], dt_ticks: u32) -> Output<AXES> {
        let Some(prev) = self.counters.replace(counters) else {
            let mut out = self.cycle([0; AXES], dt_ticks);
            out.dv_mps = [0.0; AXES];
            out.status.0 |= Status::NO_COUNTER_BASE;
            return out;
        };
        let pulses: [i32; AXES] = core::array::from_fn(|i| counters[i].wrapping_sub(prev[i]) as i32);
        self.cycle(pulses, dt_ticks)
    }

    /// Set the cumulative counters' base without producing output.
    pub fn prime_counters(&mut self, counters: [u32; AXES]) {
        self.counters = Some(counters);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{AxisModel, BiasGrid, Extensions, ScaleFactor};

    fn table(axes: usize, window: u16) -> Table {
        let mut t = Table { rate_window: window, axes: heapless::Vec::new(), misalignment: None };
        for i in 0..axes {
            let a = AxisModel {
                scale: ScaleFactor {
                    t0_c: 22.0,
                    gamma: 320_320.0 + 100.0 * i as f32,
                    mu: -32.76,
                    beta: 0.1008,
                    epsilon: 88.14,
                    eta: -0.02409,
                    alpha: 273.0,
                },
                bias: BiasGrid::single_valued(-60.0, 65.0, &[1e-4, 1.5e-4, 3e-4]),
                rate_limit_c_per_min: 2.0,
                ext: Extensions::default(),
            };
            t.axes.push(a).unwrap();
        }
        t
    }

    fn warm(c: &mut Compensator<3, 32>, n: u32) {
        for k in 0..n {
            c.on_raw(1000 * k, 352).unwrap();
        }
    }

    #[test]
    fn recovers_the_applied_specific_force() {
        let mut c = Compensator::<3, 32>::new(Config::default());
        c.set_table(table(3, 32)).unwrap();
        warm(&mut c, 20);
        let s = c.on_raw(20_000, 352).unwrap();
        assert!(s.is_ok(), "{s:?}");
        // 22 °C, Ṫ = 0: K1 = γ, K0 = grid at 22 °C. Pulses for a = 0.5 g over 1 s (1e6 ticks).
        // Grid points at −60, 5, 70 °C: 22 °C is 17/65 of the way from 1.5e-4 to 3e-4 g.
        let k0 = 1.5e-4 + (3e-4 - 1.5e-4) * (17.0 / 65.0);
        let n = (320_320.0f64 * (k0 + 0.5)).round() as i32;
        let out = c.cycle([n, n, n], 1_000_000);
        let a = f64::from(out.dv_mps[0]) / 9.806_65;
        assert!((a - 0.5).abs() < 5e-6, "{a}");
        assert!(out.status.is_ok());
    }

    #[test]
    fn stale_after_timeout_keeps_last_compensation() {
        let mut c = Compensator::<3, 32>::new(Config::default());
        c.set_table(table(3, 32)).unwrap();
        warm(&mut c, 12);
        let fresh = c.cycle([800, 800, 800], 2500);
        assert!(!fresh.status.contains(Status::TEMP_STALE));
        let mut last = fresh;
        for _ in 0..1300 {
            last = c.cycle([800, 800, 800], 2500);
        }
        assert!(last.status.contains(Status::TEMP_STALE), "3.25 s without a reading");
        assert_eq!(last.dv_mps, fresh.dv_mps, "same compensation, only flagged");
        c.on_raw(12_000 + 3_250, 352).unwrap();
        assert!(!c.cycle([800, 800, 800], 2500).status.contains(Status::TEMP_STALE));
    }

    #[test]
    fn rejected_reading_flags_and_keeps_state() {
        let mut c = Compensator::<3, 32>::new(Config::default());
        c.set_table(table(3, 32)).unwrap();
        warm(&mut c, 12);
        let before = c.cycle([800, 800, 800], 2500);
        let est = c.estimate();
        assert_eq!(c.on_raw(12_000, 352 + 200), Err(SampleError::Implausible { raw: 552 }));
        assert_eq!(c.on_scratchpad(12_500, &[0u8; 9]), Err(SampleError::Decode(ds18b20::Error::AllZero)));
        let after = c.cycle([800, 800, 800], 2500);
        assert!(after.status.contains(Status::TEMP_INVALID));
        assert_eq!(after.dv_mps, before.dv_mps);
        assert_eq!(c.estimate(), est);
        c.on_raw(13_000, 352).unwrap();
        assert!(!c.status().contains(Status::TEMP_INVALID));
    }

    #[test]
    fn table_load_is_atomic() {
        let mut c = Compensator::<3, 32>::new(Config::default());
        c.set_table(table(3, 32)).unwrap();
        warm(&mut c, 12);
        let before = c.cycle([800, 800, 800], 2500);
        let mut buf = [0u8; table::MAX_TABLE_BYTES];
        let mut other = table(3, 32);
        other.axes[0].scale.gamma = 300_000.0;
        let len = other.encode(&mut buf).unwrap().len();
        buf[len - 2] ^= 0x40;
        assert_eq!(c.load_table(&buf[..len]), Err(table::Error::Crc));
        assert_eq!(c.set_table(table(3, 64)), Err(table::Error::RateWindow { table: 64, firmware: 32 }));
        assert!(matches!(c.set_table(table(2, 32)), Err(table::Error::AxisCount { .. })));
        let mut nan = table(3, 32);
        nan.axes[2].bias.cooling_g[1] = f32::NAN;
        assert!(matches!(c.set_table(nan), Err(table::Error::NonFinite(_))));
        assert_eq!(c.cycle([800, 800, 800], 2500).dv_mps, before.dv_mps);
        assert_eq!(c.table().unwrap().axes[0].scale.gamma, 320_320.0);
    }

    #[test]
    fn no_table_gives_zero_flagged_output() {
        let mut c = Compensator::<3, 32>::new(Config::default());
        let out = c.cycle([1000, -1000, 5], 2500);
        assert_eq!(out.dv_mps, [0.0; 3]);
        assert!(out.status.contains(Status::NO_TABLE));
        assert!(out.status.contains(Status::TEMP_STALE));
    }

    #[test]
    fn extreme_inputs_stay_finite() {
        let mut c = Compensator::<3, 32>::new(Config::default());
        let mut t = table(3, 32);
        t.misalignment = Some([1.049, 0.049, -0.049, -0.049, 0.951, 0.049, 0.049, -0.049, 1.049]);
        c.set_table(t).unwrap();
        warm(&mut c, 12);
        for (p, dt) in [([i32::MAX, i32::MIN, 0], u32::MAX), ([i32::MIN; 3], 0), ([0; 3], u32::MAX)] {
            let out = c.cycle(p, dt);
            assert!(out.dv_mps.iter().all(|v| v.is_finite()), "{out:?}");
        }
    }

    #[test]
    fn wrapping_counters_give_signed_increments() {
        let mut c = Compensator::<1, 32>::new(Config::default());
        c.set_table(table(1, 32)).unwrap();
        for k in 0..12 {
            c.on_raw(1000 * k, 352).unwrap();
        }
        let first = c.cycle_counters([u32::MAX - 99], 2500);
        assert!(first.status.contains(Status::NO_COUNTER_BASE));
        assert_eq!(first.dv_mps, [0.0]);
        let wrapped = c.cycle_counters([700], 2500);
        let direct = c.cycle([800], 2500);
        assert_eq!(wrapped.dv_mps, direct.dv_mps);
    }
}
