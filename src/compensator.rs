//! The compensator: a per-temperature-sample path and a per-IMU-cycle path.
//!
//! * **Slow path** ([`Compensator::on_scratchpad`], [`Compensator::on_raw`], about 1 Hz per
//!   sensor): validate the reading, update that sensor's rate estimator, evaluate the
//!   models of the axes it serves and publish `g0/K1` (m/s per pulse), `K0·g0·tick` (m/s
//!   per tick) and `K0·g0` (m/s²) for the fast path.
//! * **Fast path** ([`Compensator::cycle`], 200 Hz–2 kHz): per axis
//!   `Δv = N·(g0/K1) − (K0·g0·tick)·dt_ticks`, then the optional misalignment matrix; or,
//!   for MEMS samples, [`Compensator::cycle_samples`]: `a = raw·(g0/K1) − K0·g0`, the
//!   paper's `a = E/K1 − K0` with the division done in the slow path.
//!   No division, no transcendental function, no search, loops bounded by `AXES`.
//!   Measured cost under QEMU (`cargo xtask bench-target`) is in the repository's `docs/measurements.md`.
//!
//! # Interrupt-safe split
//! [`Compensator::split`] gives an [`Updater`] (slow path, thread mode or a 1 Hz task) and
//! an [`Applier`] (fast path, the IMU interrupt). They share only a [`Published`]
//! coefficient set: one buffer of 32-bit atomics behind a sequence number, a seqlock. The
//! updater makes the sequence odd, writes the set and makes the sequence even again. The
//! applier keeps its own copy of the last whole set; per cycle it loads the sequence (one
//! Relaxed load and a compare), and when it has moved (once per publication) it copies the
//! set and loads the sequence again, in a `#[cold]` function. It never blocks and never
//! waits, and no half-written set is ever used, whichever context preempts which, on one
//! core or several:
//! * the updater preempts the applier in the middle of its copy: the sequence has moved at
//!   the re-check, the torn copy is dropped, the previous whole set is used for that cycle,
//!   and the copy is tried again on the next cycle;
//! * the applier preempts the updater in the middle of a publication: it sees an odd
//!   sequence and keeps its last set, for every cycle until the publication is finished.
//!
//! There is one updater: the slow path is `&mut`, so two publications never overlap.
//! `compensator::tests::reader_preempting_the_writer_at_every_store_sees_whole_sets` runs the
//! applier after every single store of a publication, and
//! `a_copy_torn_by_the_writer_is_dropped` runs a publication in the middle of the applier's
//! copy. The memory orderings are checked by loom (`compensator::seqlock::model`, run by
//! `cargo xtask loom` and `cargo xtask test`): one writer thread and one reader thread
//! through every interleaving and every store each load may read under loom's memory model
//! (three tests, 627 592 executions, 33 s under CI load; up to 3 preemptions in the one with two
//! publications), with the sequence wrapping past `u32::MAX` in one of them.
//! `cargo xtask loom` also checks that the model fails on each of six mutants that weaken
//! one ordering or drop one step of the seqlock (`mutants_caught=6 of 6`). Only 32-bit
//! atomic loads and stores are used, which every Cortex-M has (no compare-and-swap, so no
//! `portable-atomic` is needed).
//!
//! # Sensors
//! `SENSORS` is 1 (one temperature stream for every axis) or `AXES` (one DS18B20 per
//! accelerometer case, as in the paper): each stream has its own rate estimator,
//! plausibility rules and staleness, and one misalignment matrix still spans the axes.
//!
//! # Faults
//! Faults never produce a silent wrong answer:
//! * A rejected reading returns a typed [`SampleError`], raises [`Status::TEMP_INVALID`]
//!   and keeps the last good compensation. So does a reading that never arrived, reported
//!   with [`Compensator::on_missed_reading`]: report every failed read.
//! * A stream with no good reading for the stale threshold raises [`Status::TEMP_STALE`]:
//!   the fast path counts its own ticks, and the slow path keeps a saturating age per
//!   stream that no clock wrap resets (see [`crate::time`]).
//! * A reading that jumps further than `max_step_raw` plus `max_slew_raw_per_min` times the
//!   elapsed time (counted at most up to the rate window's gap) is used only once
//!   [`Config::confirm_samples`] readings agree. The DS18B20's power-on value 0550h
//!   (+85 °C) is used only as the continuation of a stream already there (within one step,
//!   no gap); after a dropout or as a jump it is refused, whether or not the scratchpad's
//!   byte 6 gives it away. Values outside −55…+125 °C are refused.
//! * A table records the [`Input`](table::Input) it converts; [`Config::input`] names the
//!   compensator's, a table of the other kind is refused, and the fast-path entry of the
//!   other kind raises [`Status::WRONG_INPUT`].
//! * With no table the raw input passes through at the nominal scale
//!   [`Config::nominal_k1`], flagged [`Status::NO_TABLE`], so an INS that ignores the
//!   status still sees gravity, not free fall.
//! * Outputs are always finite and bounded: table validation bounds `g0/K1` and `K0` (the
//!   bias grid never extrapolates), [`Config::validate`] bounds the nominal scale, and the
//!   inputs are integers.

use core::borrow::Borrow;
use core::fmt;
use core::sync::atomic::Ordering;

use crate::ds18b20::{self, POWER_ON_RAW};
use crate::model::{AxisState, Evaluation};
use crate::rate::{self, Estimate, RateConfig, RateEstimator};
use crate::table::{self, Table};

mod seqlock;

pub use seqlock::Published;
use seqlock::{Set, AGE_STALE, AGE_STEPS};

/// Standard gravity, m/s² (the unit the tables' g refers to).
pub const G0: f32 = 9.806_65;

bitflags::bitflags! {
    /// Status word: one flag per condition. [`Status::is_ok`] when none is set.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Hash)]
    pub struct Status: u16 {
        /// No good temperature for longer than `stale_after_ticks`, or none yet (any sensor).
        const TEMP_STALE = 1 << 0;
        /// A sensor's latest reading was rejected; the last good compensation is in use.
        const TEMP_INVALID = 1 << 1;
        /// A rate estimator has too few samples; Ṫ = 0 is used.
        const RATE_NOT_READY = 1 << 2;
        /// Temperature outside the calibrated range: clamped.
        const TEMP_OUT_OF_RANGE = 1 << 3;
        /// |Ṫ| above the calibrated limit: clamped.
        const RATE_OUT_OF_RANGE = 1 << 4;
        /// No table loaded: the raw input passes through at [`Config::nominal_k1`], no bias.
        const NO_TABLE = 1 << 5;
        /// Cumulative counters had no previous value: increments of this cycle are zero.
        const NO_COUNTER_BASE = 1 << 6;
        /// The fast-path call does not match [`Config::input`] (pulse counts through
        /// [`Compensator::cycle_samples`], or samples through [`Compensator::cycle`]): the
        /// output is in the wrong unit and must not be used.
        const WRONG_INPUT = 1 << 7;
    }
}

impl Status {
    /// No condition at all: fully compensated from a fresh, calibrated temperature.
    #[must_use]
    pub const fn is_ok(self) -> bool {
        self.is_empty()
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for Status {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(f, "Status({=u16:#06x})", self.bits());
    }
}

/// Why a temperature sample was not used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SampleError {
    /// The scratchpad failed decoding.
    Decode(ds18b20::Error),
    /// Timestamp not after the previous good sample (and not yet confirmed as a restart).
    Time(rate::Error),
    /// The power-on value 0550h (+85 °C) arrived as a jump, or as the first reading.
    PowerOnJump,
    /// The reading jumped further from the last good one than physically plausible.
    Implausible {
        /// The rejected raw value, 1/16 °C.
        raw: i16,
    },
    /// The reading never arrived: the bus or the sensor failed (see
    /// [`Updater::on_missed_reading`]).
    Missed,
    /// No temperature stream with this index (`SENSORS` streams exist).
    NoSuchSensor {
        /// The index given.
        sensor: u8,
    },
}

impl fmt::Display for SampleError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Decode(e) => write!(f, "scratchpad: {e}"),
            Self::Time(e) => write!(f, "time: {e}"),
            Self::PowerOnJump => f.write_str("power-on value 0550h arrived as a jump"),
            Self::Implausible { raw } => write!(f, "implausible jump to raw {raw}"),
            Self::Missed => f.write_str("reading missed: bus or sensor failure"),
            Self::NoSuchSensor { sensor } => write!(f, "no temperature sensor {sensor}"),
        }
    }
}

impl core::error::Error for SampleError {}

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
    /// `rate.min_samples` exceeds the window `N`: the rate would never be ready.
    MinSamplesAboveWindow,
    /// `SENSORS` is neither 1 nor `AXES`.
    SensorCount,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFinite(what) => write!(f, "{what} is not finite"),
            Self::OutOfRange(what) => write!(f, "{what} is out of range"),
            Self::StaleShorterThanSamplePeriod => f.write_str("stale threshold not longer than one sample period"),
            Self::GapShorterThanSamplePeriod => f.write_str("rate max_gap_ms shorter than one sample period"),
            Self::MinSamplesAboveWindow => f.write_str("rate min_samples above the window length"),
            Self::SensorCount => f.write_str("SENSORS must be 1 or AXES"),
        }
    }
}

impl core::error::Error for ConfigError {}

/// Compensator settings. Checked by [`Config::validate`]; [`Compensator::new`] refuses a
/// config that fails it.
///
/// Start from [`Config::default`] (1 µs ticks, 1 Hz readings, stale after 3 s, pulse
/// counts, a JB-KT8-class nominal scale) and change what your hardware differs in:
///
/// ```
/// use qfa_thermal::{Compensator, Config, ConfigError, Input};
///
/// // A MEMS accelerometer at 2²⁰ LSB/g nominal, read on a 100 ns timer.
/// let config = Config { input: Input::Samples, nominal_k1: 1_048_576.0, tick_s: 1e-7, stale_after_ticks: 30_000_000, ..Config::default() };
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
    /// Scale factor used while no table is loaded, in the sensor's own unit: pulses/(g·s)
    /// for pulse counts, LSB/g for samples. Default 320 000, a JB-KT8-class QFA (Zhang et
    /// al. 2021, Eq. 15–17: γ = 308 000…328 000); set the nominal of your own sensor.
    pub nominal_k1: f32,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            tick_s: 1e-6,
            stale_after_ticks: 3_000_000,
            sample_period_ms: 1_000,
            input: table::Input::PulseCounts,
            rate: RateConfig::default(),
            max_step_raw: 16,
            max_slew_raw_per_min: 160,
            confirm_samples: 3,
            nominal_k1: 320_000.0,
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
        if !self.nominal_k1.is_finite() {
            return Err(ConfigError::NonFinite("nominal_k1"));
        }
        if !(table::limits::GAMMA.0..=table::limits::GAMMA.1).contains(&self.nominal_k1) {
            return Err(ConfigError::OutOfRange("nominal_k1"));
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

    /// The stale threshold in ms (for comparing sensors' timestamps in the slow path).
    fn stale_after_ms(&self) -> u32 {
        let ms = self.stale_after_ticks as f32 * self.tick_s * 1000.0;
        if ms >= u32::MAX as f32 {
            u32::MAX
        } else {
            ms as u32
        }
    }
}

/// Output of one IMU cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Output<const AXES: usize> {
    /// Compensated velocity increment per axis, m/s ([`Compensator::cycle`]), or
    /// acceleration, m/s² ([`Compensator::cycle_samples`]).
    pub dv_mps: [f32; AXES],
    /// Conditions in force.
    pub status: Status,
}

/// Fast-path state: the applier's own copy of the last whole coefficient set, its
/// staleness clock and its counter base. Never touched by the updater.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FastState<const AXES: usize> {
    stale_after_ticks: u32,
    /// Ticks per age unit (`stale_after_ticks / AGE_STEPS`): turns a set's age into ticks.
    ticks_per_age: f32,
    /// Ticks left before the set is stale, counted down and held at 0. At each copy, the
    /// budget `stale_after_ticks + 1` less the oldest stream's age: taken when a good
    /// reading came since the last copy, otherwise only if shorter. A countdown costs two
    /// instructions per cycle less than counting up and comparing.
    ticks_left: u32,
    /// Sequence of the set copied into `set`.
    seen_seq: u32,
    set: Set<AXES>,
    /// The set's status as each entry sees it, `[pulses, samples]`: the entry that does not
    /// match [`Config::input`] carries [`Status::WRONG_INPUT`] from construction on (the
    /// bit is kept at each copy, so it needs no field of its own). Formed when a set is
    /// copied, so the per-cycle path only picks a field.
    path_status: [Status; 2],
    counters: Option<[u32; AXES]>,
}

/// The fast path of a split compensator: owns the IMU-cycle state and a copy of the
/// coefficients, refreshed from the [`Published`] set when its sequence changes. Put it
/// where the IMU interrupt can reach it.
///
/// Per cycle it loads one shared word (the sequence) and otherwise reads only its own
/// memory. When the sequence has moved (once per temperature reading), it copies the set
/// and checks the sequence again: a set read while the updater was writing it (an odd or
/// changed sequence) is dropped, the previous whole set stays in use for this cycle, and
/// the copy is tried again on the next. It never waits and never uses a half-written set,
/// whichever context preempts which, on one core or several.
///
/// Here the two halves run on two threads, as they would in thread mode and an interrupt
/// on a multi-core part; the applier never waits for the updater:
///
/// ```
/// use qfa_thermal::{AxisModel, BiasGrid, Compensator, Config, Extensions, Input, ScaleFactor, Table};
///
/// let bias = BiasGrid::single_valued(-40.0, 10.0, &[1e-4; 13]);
/// let axis = AxisModel { scale: ScaleFactor::JB_KT8_1, bias, rate_limit_c_per_min: 2.0, ext: Extensions::default() };
/// let table = Table { input: Input::PulseCounts, rate_window: 32, axes: core::iter::repeat_n(axis, 3).collect(), misalignment: None };
/// let mut comp = Compensator::<3, 32, 3>::new(Config::default()).unwrap();
/// comp.set_table(table).unwrap();
/// let (mut updater, mut applier) = comp.split();
/// applier.prime_counters([0; 3]);
///
/// std::thread::scope(|s| {
///     s.spawn(move || {
///         for t in 0..20u32 {
///             for sensor in 0..3 {
///                 updater.on_raw_from(sensor, t * 1_000, 352 + (t / 4) as i16).unwrap(); // a slow ramp
///             }
///         }
///     });
///     s.spawn(move || {
///         let mut counters = [0u32; 3];
///         for _ in 0..10_000 {
///             counters[2] = counters[2].wrapping_add(1_601);
///             let out = applier.cycle_counters(counters, 5_000);
///             assert!(out.dv_mps.iter().all(|v| v.is_finite())); // always, whatever it raced
///         }
///     });
/// });
/// ```
#[derive(Debug)]
pub struct Applier<'a, const AXES: usize> {
    fast: &'a mut FastState<AXES>,
    shared: &'a Published<AXES>,
}

impl<const AXES: usize> Applier<'_, AXES> {
    /// Copy the published set if it is whole (seqlock reader); the rare path.
    #[cold]
    #[inline(never)]
    fn refresh(&mut self) {
        self.refresh_with(|| {});
    }

    /// [`Self::refresh`] with `mid` run between the copy and the re-check (a test hook:
    /// the updater preempting the applier there).
    #[inline(always)]
    fn refresh_with(&mut self, mid: impl FnOnce()) {
        let Some(s) = self.shared.read_with(mid) else {
            return; // being written, or written meanwhile: keep the last whole set this cycle
        };
        let f = &mut *self.fast;
        let [pulses, samples] = f.path_status.map(|st| st & Status::WRONG_INPUT);
        f.path_status = [s.set.status | pulses, s.set.status | samples];
        let budget = if s.set.age >= AGE_STALE {
            0
        } else {
            // Rounded down, like the age: the countdown ends at most one age unit late (0.09 ms
            // at the 3-s default), never early.
            let age_ticks = (f32::from(s.set.age) * f.ticks_per_age) as u32;
            f.stale_after_ticks.saturating_add(1).saturating_sub(age_ticks)
        };
        // A good reading since the last copy restarts the countdown; any other publication
        // (a rejection, a missed reading: the slow path's clock moved; a table load) can only
        // shorten it, so its own tick count and the slow path's clock never make a stale set
        // fresh between them.
        f.ticks_left = if s.set.epoch != f.set.epoch { budget } else { f.ticks_left.min(budget) };
        f.set = s.set;
        f.seen_seq = s.seq;
    }

    /// Refresh the copy if a publication happened; advance the staleness clock; the
    /// status of this cycle for the pulse (`SAMPLES = false`) or sample entry.
    #[inline(always)]
    fn begin<const SAMPLES: bool>(&mut self, dt_ticks: u32) -> Status {
        if self.shared.seq.load(Ordering::Relaxed) != self.fast.seen_seq {
            self.refresh();
        }
        let f = &mut *self.fast;
        f.ticks_left = f.ticks_left.saturating_sub(dt_ticks);
        // TEMP_STALE (bit 0) exactly when ticks_left == 0: `validate` keeps it ≤ 2³¹, so
        // `ticks_left − 1` has its top bit set only at 0. Two instructions, no branch.
        let stale = (f.ticks_left.wrapping_sub(1) >> 31) as u16;
        Status::from_bits_retain(f.path_status[usize::from(SAMPLES)].bits() | stale)
    }

    /// Fast path: signed pulse counts of this cycle and its length in ticks.
    ///
    /// `Δv[i] = N[i]·(g0/K1[i]) − (K0[i]·g0·tick)·dt`, then `Δv = M·Δv` with a
    /// misalignment matrix. Always finite. Never blocks.
    #[inline]
    pub fn cycle(&mut self, pulses: [i32; AXES], dt_ticks: u32) -> Output<AXES> {
        let status = self.begin::<false>(dt_ticks);
        let s = &self.fast.set;
        let dt = dt_ticks as f32;
        let mut dv = [0.0f32; AXES];
        for i in 0..AXES {
            dv[i] = pulses[i] as f32 * s.scale[i] - s.bias_tick[i] * dt;
        }
        if let Some(m) = &s.misalign {
            dv = misalign(m, dv);
        }
        Output { dv_mps: dv, status }
    }

    /// Fast path for MEMS samples: raw readings (LSB) of this cycle and the ticks since
    /// the previous one (for staleness only).
    ///
    /// `a[i] = raw[i]·(g0/K1[i]) − K0[i]·g0`, m/s², then `a = M·a` with a misalignment
    /// matrix: the paper's `a = E/K1 − K0`, with `1/K1` formed in the slow path.
    #[inline]
    pub fn cycle_samples(&mut self, raw: [i32; AXES], dt_ticks: u32) -> Output<AXES> {
        let status = self.begin::<true>(dt_ticks);
        let s = &self.fast.set;
        let mut a = [0.0f32; AXES];
        for i in 0..AXES {
            a[i] = raw[i] as f32 * s.scale[i] - s.bias_acc[i];
        }
        if let Some(m) = &s.misalign {
            a = misalign(m, a);
        }
        Output { dv_mps: a, status }
    }

    /// Fast path from wrapping cumulative u32 counters. The first call has no base: it
    /// returns zero increments with [`Status::NO_COUNTER_BASE`]; call
    /// [`prime_counters`](Self::prime_counters) to avoid it.
    #[inline]
    pub fn cycle_counters(&mut self, counters: [u32; AXES], dt_ticks: u32) -> Output<AXES> {
        let Some(prev) = self.fast.counters.replace(counters) else {
            let mut out = self.cycle([0; AXES], dt_ticks);
            out.dv_mps = [0.0; AXES];
            out.status |= Status::NO_COUNTER_BASE;
            return out;
        };
        let pulses: [i32; AXES] = core::array::from_fn(|i| counters[i].wrapping_sub(prev[i]) as i32);
        self.cycle(pulses, dt_ticks)
    }

    /// Set the cumulative counters' base without producing output.
    pub fn prime_counters(&mut self, counters: [u32; AXES]) {
        self.fast.counters = Some(counters);
    }
}

#[inline(always)]
fn misalign<const AXES: usize>(m: &[[f32; AXES]; AXES], v: [f32; AXES]) -> [f32; AXES] {
    let mut out = [0.0f32; AXES];
    for (o, row) in out.iter_mut().zip(m.iter()) {
        let mut acc = 0.0f32;
        for (a, b) in row.iter().zip(v.iter()) {
            acc += a * b;
        }
        *o = acc;
    }
    out
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Timed {
    t_ms: u32,
    raw: i16,
}

/// One temperature stream: its estimator, plausibility state and flags.
#[derive(Clone, Debug)]
struct Stream<const N: usize> {
    rate: RateEstimator<N>,
    /// The last good reading, meaningful once `has_good` (no `Option`: with the rate
    /// window's 8-byte alignment it would cost 8 B per stream).
    last: Timed,
    has_good: bool,
    /// The latest rejected reading, counted towards a confirmed step; meaningful only while
    /// `pending_count > 0` (no `Option`: 4 B less per stream).
    pending: Timed,
    /// Consecutive mutually consistent rejected readings, the latest being `pending`.
    pending_count: u8,
    /// The latest reading was rejected.
    invalid: bool,
    /// ms since the last good reading, summed from the slow path's own calls and
    /// saturating: unlike a wrapping difference of timestamps it never reads fresh again.
    age_ms: u32,
}

impl<const N: usize> Stream<N> {
    fn last_good(&self) -> Option<Timed> {
        self.has_good.then_some(self.last)
    }
}

/// Slow-path state (the updater's own, never touched by the applier).
#[derive(Clone, Debug)]
struct SlowState<const AXES: usize, const N: usize, const SENSORS: usize, T> {
    config: Config,
    /// The latest slow-path time seen (readings, rejections and missed readings alike): the
    /// clock that advances every stream's `age_ms`. Starts at 0: ages before a stream's
    /// first good reading do not matter, since it is stale until then.
    clock_ms: u32,
    /// Good readings published, wrapping (see `Set::epoch`).
    epoch: u8,
    /// Smallest branch deadband, °C/min: the flicker floor of `N` and the sample period.
    deadband_floor: f32,
    table: Option<T>,
    streams: [Stream<N>; SENSORS],
    states: [AxisState; AXES],
    evals: [Evaluation; AXES],
    /// The status last published.
    status: Status,
}

impl<const AXES: usize, const N: usize, const SENSORS: usize, T: Borrow<Table>> SlowState<AXES, N, SENSORS, T> {
    /// The status of the streams, the table and the evaluations as they stand.
    fn status(&self) -> Status {
        let mut st = Status::empty();
        for s in &self.streams {
            if !s.rate.ready() {
                st |= Status::RATE_NOT_READY;
            }
            if !s.has_good || s.age_ms > self.config.stale_after_ms() {
                st |= Status::TEMP_STALE;
            }
            if s.invalid {
                st |= Status::TEMP_INVALID;
            }
        }
        if self.table.is_none() {
            st |= Status::NO_TABLE;
        } else {
            for e in &self.evals {
                if e.temp_clamped {
                    st |= Status::TEMP_OUT_OF_RANGE;
                }
                if e.rate_clamped {
                    st |= Status::RATE_OUT_OF_RANGE;
                }
            }
        }
        st
    }

    /// The coefficient set of the current table, evaluations and status. Rebuilt at every
    /// publication (three divisions, in the slow path) rather than kept beside the
    /// published one: that copy would cost 80 B of RAM.
    fn set(&self) -> Set<AXES> {
        // In 1/AGE_STEPS of the stale threshold, rounded down, in f32 (a 64-bit integer
        // division would link 900 B of library code): within one unit, 0.09 ms at 3 s.
        let stale_ms = self.config.stale_after_ms().max(1);
        let units_per_ms = f32::from(AGE_STEPS) / stale_ms as f32;
        let age = self.streams.iter().fold(0u16, |oldest, s| {
            let age = if !s.has_good || s.age_ms > stale_ms {
                AGE_STALE
            } else {
                ((s.age_ms as f32 * units_per_ms) as u16).min(AGE_STEPS)
            };
            oldest.max(age)
        });
        let Some(t) = &self.table else {
            let nominal = G0 / self.config.nominal_k1;
            return Set {
                scale: [nominal; AXES],
                bias_tick: [0.0; AXES],
                bias_acc: [0.0; AXES],
                misalign: None,
                status: self.status,
                age,
                epoch: self.epoch,
            };
        };
        let table: &Table = t.borrow();
        Set {
            scale: core::array::from_fn(|i| G0 / self.evals[i].k1),
            bias_tick: core::array::from_fn(|i| (self.evals[i].k0 * G0) * self.config.tick_s),
            bias_acc: core::array::from_fn(|i| self.evals[i].k0 * G0),
            // Validation allows a matrix only with 3 axes, so AXES == 3 here.
            misalign: table.misalignment.map(|m| core::array::from_fn(|r| core::array::from_fn(|c| m[r * 3 + c]))),
            status: self.status,
            age,
            epoch: self.epoch,
        }
    }
}

/// The slow path of a split compensator: temperature readings and tables. Never runs in
/// the IMU interrupt.
///
/// Every reading reaches it, good or not: a scratchpad as read
/// ([`on_scratchpad_from`](Self::on_scratchpad_from)), or a read that failed on the bus
/// ([`on_missed_reading`](Self::on_missed_reading)).
///
/// ```
/// use qfa_thermal::ds18b20::{encode_scratchpad, Resolution};
/// use qfa_thermal::{Compensator, Config, SampleError, Status};
///
/// let mut comp = Compensator::<3, 32, 3>::new(Config::default()).unwrap();
/// let (mut updater, _applier) = comp.split();
/// let sp = encode_scratchpad(400, Resolution::Bits12, 0x10); // 25.0 °C, CRC good
/// assert!(updater.on_scratchpad_from(0, 1_000, &sp).is_ok());
/// assert_eq!(updater.on_missed_reading(1, 1_000), Err(SampleError::Missed));
/// assert!(updater.status().contains(Status::TEMP_INVALID));
/// let mut corrupt = sp;
/// corrupt[0] ^= 1; // a flipped bit on the bus: the CRC refuses it
/// assert!(matches!(updater.on_scratchpad_from(2, 1_000, &corrupt), Err(SampleError::Decode(_))));
/// ```
#[derive(Debug)]
pub struct Updater<'a, const AXES: usize, const N: usize, const SENSORS: usize, T> {
    slow: &'a mut SlowState<AXES, N, SENSORS, T>,
    shared: &'a Published<AXES>,
}

/// Temperature compensation for `AXES` accelerometers with an `N`-sample rate window and
/// `SENSORS` temperature streams (1, or one per axis). The table is held as `T`: an owned
/// [`Table`] (708 B, loadable from bytes at run time) or a `&'static Table` in flash.
///
/// Unsplit, it is one value with both paths (`&mut self` each); [`split`](Self::split)
/// hands the two paths to two execution contexts.
///
/// Unsplit, one value with both paths; here one axis whose temperature steps from 22 to
/// 40 °C, with every reading and every refusal visible in the status:
///
/// ```
/// use qfa_thermal::{AxisModel, BiasGrid, Compensator, Config, Extensions, Input, SampleError, ScaleFactor, Status, Table};
///
/// let bias = BiasGrid::single_valued(-40.0, 10.0, &[0.0; 13]);
/// let axis = AxisModel { scale: ScaleFactor::JB_KT8_1, bias, rate_limit_c_per_min: 2.0, ext: Extensions::default() };
/// let table = Table { input: Input::PulseCounts, rate_window: 32, axes: [axis].into_iter().collect(), misalignment: None };
///
/// let mut comp = Compensator::<1, 32>::new(Config::default()).unwrap();
/// // Before a table: raw pass-through at the nominal scale, flagged.
/// assert!(comp.cycle([1_600], 5_000).status.contains(Status::NO_TABLE));
/// comp.set_table(table).unwrap();
/// for s in 0..8 {
///     comp.on_raw(s * 1_000, 352).unwrap(); // 22.0 °C at 1 Hz
/// }
/// assert!(comp.cycle([1_600], 5_000).status.is_ok());
/// // A jump of 18 °C in one second is refused (a glitch, until confirmed by more readings);
/// // the last good compensation stays in force and the status says so.
/// assert!(matches!(comp.on_raw(8_000, 640), Err(SampleError::Implausible { .. })));
/// assert!(comp.cycle([1_600], 5_000).status.contains(Status::TEMP_INVALID));
/// ```
#[derive(Debug)]
pub struct Compensator<const AXES: usize = 3, const N: usize = 32, const SENSORS: usize = 1, T = Table> {
    slow: SlowState<AXES, N, SENSORS, T>,
    shared: Published<AXES>,
    fast: FastState<AXES>,
}

impl<const AXES: usize, const N: usize, const SENSORS: usize, T: Clone + Borrow<Table>> Clone
    for Compensator<AXES, N, SENSORS, T>
{
    /// An independent copy in the same state: its own [`Published`] set holds every word
    /// of the original's, the sequence included, so its applier sees exactly what the
    /// original's sees (a publication it has not copied yet included).
    fn clone(&self) -> Self {
        Self { slow: self.slow.clone(), shared: self.shared.snapshot(), fast: self.fast }
    }
}

/// The status before the applier's first copy of a set.
const NOT_YET: Status = Status::NO_TABLE.union(Status::TEMP_STALE);

const NO_EVAL: Evaluation = Evaluation { k1: 0.0, k0: 0.0, temp_clamped: false, rate_clamped: false };

impl<const AXES: usize, const N: usize, const SENSORS: usize, T: Borrow<Table>> Compensator<AXES, N, SENSORS, T> {
    const BOUNDS: () = assert!(AXES >= 1 && AXES <= table::MAX_AXES, "AXES must be 1..=3");

    /// A compensator with no table: the raw input passes through at
    /// [`Config::nominal_k1`] with [`Status::NO_TABLE`] until a table is set.
    ///
    /// # Errors
    /// [`Config::validate`]'s error, [`ConfigError::MinSamplesAboveWindow`] or
    /// [`ConfigError::SensorCount`].
    pub fn new(config: Config) -> Result<Self, ConfigError> {
        let () = Self::BOUNDS;
        config.validate()?;
        if usize::from(config.rate.min_samples) > N {
            return Err(ConfigError::MinSamplesAboveWindow);
        }
        if SENSORS != 1 && SENSORS != AXES {
            return Err(ConfigError::SensorCount);
        }
        let stream = Stream {
            rate: RateEstimator::new(config.rate),
            last: Timed { t_ms: 0, raw: 0 },
            has_good: false,
            pending: Timed { t_ms: 0, raw: 0 },
            pending_count: 0,
            invalid: false,
            age_ms: 0,
        };
        let mut c = Self {
            slow: SlowState {
                config,
                clock_ms: 0,
                epoch: 0,
                deadband_floor: rate::flicker_deadband_c_per_min(N, config.sample_period_ms),
                table: None,
                streams: core::array::from_fn(|_| stream.clone()),
                states: [AxisState::default(); AXES],
                evals: [NO_EVAL; AXES],
                status: Status::empty(),
            },
            shared: Published::new(),
            fast: FastState {
                stale_after_ticks: config.stale_after_ticks,
                ticks_per_age: config.stale_after_ticks as f32 / f32::from(AGE_STEPS),
                ticks_left: 0,
                seen_seq: 0,
                set: Set::EMPTY,
                // Until the first set is copied, nothing is calibrated.
                path_status: match config.input {
                    table::Input::PulseCounts => [NOT_YET, NOT_YET | Status::WRONG_INPUT],
                    table::Input::Samples => [NOT_YET | Status::WRONG_INPUT, NOT_YET],
                },
                counters: None,
            },
        };
        c.updater().refresh_all(0.0);
        Ok(c)
    }

    fn updater(&mut self) -> Updater<'_, AXES, N, SENSORS, T> {
        Updater { slow: &mut self.slow, shared: &self.shared }
    }

    fn applier(&mut self) -> Applier<'_, AXES> {
        Applier { fast: &mut self.fast, shared: &self.shared }
    }

    /// The two paths, for two execution contexts: the [`Updater`] for thread mode or a
    /// task, the [`Applier`] for the IMU interrupt. With a `&'static mut Compensator`
    /// (from a `static_cell::StaticCell`, say) both halves are `'static`.
    pub fn split(&mut self) -> (Updater<'_, AXES, N, SENSORS, T>, Applier<'_, AXES>) {
        (Updater { slow: &mut self.slow, shared: &self.shared }, Applier { fast: &mut self.fast, shared: &self.shared })
    }

    /// Validate and activate a table. Atomic: on any error the active table and every
    /// state are unchanged; on success the fast path switches to the new coefficients in
    /// one publication.
    ///
    /// # Errors
    /// Any [`table::Error`], including an axis count other than `AXES` and a rate window
    /// other than `N`.
    pub fn set_table(&mut self, t: T) -> table::Result<()> {
        self.updater().set_table(t)
    }

    /// The active table.
    #[must_use]
    pub fn table(&self) -> Option<&Table> {
        self.slow.table.as_ref().map(Borrow::borrow)
    }

    /// Settings.
    #[must_use]
    pub const fn config(&self) -> &Config {
        &self.slow.config
    }

    /// Sensor 0's current estimate; `None` before its first good reading.
    #[must_use]
    pub fn estimate(&self) -> Option<Estimate> {
        self.slow.streams[0].rate.estimate()
    }

    /// Sensor `sensor`'s current estimate; `None` before its first good reading or for an
    /// index ≥ `SENSORS`.
    #[must_use]
    pub fn estimate_of(&self, sensor: usize) -> Option<Estimate> {
        self.slow.streams.get(sensor).and_then(|s| s.rate.estimate())
    }

    /// The model evaluated at each axis's last good sample (K1 in pulses/(g·s), K0 in g).
    #[must_use]
    pub const fn evaluations(&self) -> &[Evaluation; AXES] {
        &self.slow.evals
    }

    /// Status as of the last slow-path call (the fast path adds its own staleness).
    #[must_use]
    pub const fn status(&self) -> Status {
        self.slow.status
    }

    /// Slow path, sensor 0: a 9-byte scratchpad read at `t_ms` (the time base of
    /// [`crate::time`], taken when the conversion completed).
    ///
    /// # Errors
    /// A [`SampleError`]; the last good compensation stays in force and
    /// [`Status::TEMP_INVALID`] is raised.
    pub fn on_scratchpad(&mut self, t_ms: u32, scratchpad: &[u8; 9]) -> Result<Status, SampleError> {
        self.updater().on_scratchpad_from(0, t_ms, scratchpad)
    }

    /// Slow path, sensor 0: a raw reading (1/16 °C, already masked) taken at `t_ms`.
    ///
    /// # Errors
    /// As [`on_scratchpad`](Self::on_scratchpad).
    pub fn on_raw(&mut self, t_ms: u32, raw: i16) -> Result<Status, SampleError> {
        self.updater().on_raw_from(0, t_ms, raw)
    }

    /// Slow path for sensor `sensor` (0..`SENSORS`): a scratchpad read at `t_ms`.
    ///
    /// # Errors
    /// As [`on_scratchpad`](Self::on_scratchpad), and [`SampleError::NoSuchSensor`].
    pub fn on_scratchpad_from(&mut self, sensor: usize, t_ms: u32, sp: &[u8; 9]) -> Result<Status, SampleError> {
        self.updater().on_scratchpad_from(sensor, t_ms, sp)
    }

    /// Slow path: a reading of sensor `sensor` that never arrived; see
    /// [`Updater::on_missed_reading`].
    ///
    /// # Errors
    /// As [`Updater::on_missed_reading`].
    pub fn on_missed_reading(&mut self, sensor: usize, t_ms: u32) -> Result<Status, SampleError> {
        self.updater().on_missed_reading(sensor, t_ms)
    }

    /// Slow path for sensor `sensor` (0..`SENSORS`): a raw reading at `t_ms`.
    ///
    /// # Errors
    /// As [`on_scratchpad_from`](Self::on_scratchpad_from).
    pub fn on_raw_from(&mut self, sensor: usize, t_ms: u32, raw: i16) -> Result<Status, SampleError> {
        self.updater().on_raw_from(sensor, t_ms, raw)
    }

    /// Fast path: see [`Applier::cycle`].
    #[inline]
    pub fn cycle(&mut self, pulses: [i32; AXES], dt_ticks: u32) -> Output<AXES> {
        self.applier().cycle(pulses, dt_ticks)
    }

    /// Fast path for MEMS samples: see [`Applier::cycle_samples`].
    #[inline]
    pub fn cycle_samples(&mut self, raw: [i32; AXES], dt_ticks: u32) -> Output<AXES> {
        self.applier().cycle_samples(raw, dt_ticks)
    }

    /// Fast path from cumulative counters: see [`Applier::cycle_counters`].
    #[inline]
    pub fn cycle_counters(&mut self, counters: [u32; AXES], dt_ticks: u32) -> Output<AXES> {
        self.applier().cycle_counters(counters, dt_ticks)
    }

    /// Set the cumulative counters' base without producing output.
    pub fn prime_counters(&mut self, counters: [u32; AXES]) {
        self.applier().prime_counters(counters);
    }
}

impl<const AXES: usize, const N: usize, const SENSORS: usize> Compensator<AXES, N, SENSORS, Table> {
    /// Decode, validate and activate a table from its wire bytes. Atomic: on any error
    /// the active table and every state are unchanged.
    ///
    /// # Errors
    /// Any [`table::Error`], including an axis count other than `AXES` and a rate window
    /// other than `N`.
    pub fn load_table(&mut self, bytes: &[u8]) -> table::Result<()> {
        let t = Table::decode(bytes)?;
        self.set_table(t)
    }
}

impl<const AXES: usize, const N: usize, const SENSORS: usize, T: Borrow<Table>> Updater<'_, AXES, N, SENSORS, T> {
    /// The stream serving axis `axis`.
    const fn sensor_of(axis: usize) -> usize {
        if SENSORS == 1 {
            0
        } else {
            axis
        }
    }

    /// Sensor `sensor`'s current estimate; `None` before its first good reading or for an
    /// index ≥ `SENSORS`.
    #[must_use]
    pub fn estimate_of(&self, sensor: usize) -> Option<Estimate> {
        self.slow.streams.get(sensor).and_then(|s| s.rate.estimate())
    }

    /// Status as of the last slow-path call.
    #[must_use]
    pub const fn status(&self) -> Status {
        self.slow.status
    }

    /// Validate and activate a table: see [`Compensator::set_table`].
    ///
    /// # Errors
    /// As [`Compensator::set_table`].
    pub fn set_table(&mut self, t: T) -> table::Result<()> {
        let tb: &Table = t.borrow();
        tb.validate()?;
        if tb.axes.len() != AXES {
            return Err(table::Error::AxisCount { table: tb.axes.len() as u8, expected: AXES as u8 });
        }
        if tb.input != self.slow.config.input {
            return Err(table::Error::Input { table: tb.input, compensator: self.slow.config.input });
        }
        if usize::from(tb.rate_window) != N {
            return Err(table::Error::RateWindow { table: tb.rate_window, firmware: N as u16 });
        }
        self.slow.table = Some(t);
        self.slow.states = [AxisState::default(); AXES];
        self.refresh_all(0.0);
        Ok(())
    }

    /// Slow path: see [`Compensator::on_scratchpad_from`].
    ///
    /// # Errors
    /// As [`Compensator::on_scratchpad_from`].
    pub fn on_scratchpad_from(&mut self, sensor: usize, t_ms: u32, sp: &[u8; 9]) -> Result<Status, SampleError> {
        if sensor >= SENSORS {
            return Err(SampleError::NoSuchSensor { sensor: sensor as u8 });
        }
        self.advance_clock(t_ms);
        match ds18b20::decode_scratchpad(sp) {
            Ok(r) => self.on_raw_from(sensor, t_ms, r.raw),
            Err(e) => self.reject(sensor, SampleError::Decode(e)),
        }
    }

    /// Slow path: sensor `sensor`'s reading, due at `t_ms`, did not arrive (no presence
    /// pulse, a CRC failure on every retry, a conversion that never started). Raises
    /// [`Status::TEMP_INVALID`], keeps the last good compensation and advances the
    /// staleness clock, so a sensor that is dead for weeks is stale for weeks. Call it
    /// for every reading that fails: the slow path must hear of each sensor, good or bad,
    /// at least once every 2³¹ ms (24.8 days) to measure how long a sensor was away.
    ///
    /// # Errors
    /// [`SampleError::NoSuchSensor`]; otherwise always [`SampleError::Missed`], with the
    /// flag raised.
    pub fn on_missed_reading(&mut self, sensor: usize, t_ms: u32) -> Result<Status, SampleError> {
        if sensor >= SENSORS {
            return Err(SampleError::NoSuchSensor { sensor: sensor as u8 });
        }
        self.advance_clock(t_ms);
        self.reject(sensor, SampleError::Missed)
    }

    /// Slow path: see [`Compensator::on_raw_from`].
    ///
    /// # Errors
    /// As [`Compensator::on_raw_from`].
    pub fn on_raw_from(&mut self, sensor: usize, t_ms: u32, raw: i16) -> Result<Status, SampleError> {
        let Some(s) = self.slow.streams.get(sensor) else {
            return Err(SampleError::NoSuchSensor { sensor: sensor as u8 });
        };
        let (last_good, age_ms) = (s.last_good(), s.age_ms);
        self.advance_clock(t_ms);
        let age_ms = self.slow.streams[sensor].age_ms.max(age_ms);
        if !ds18b20::RAW_RANGE.contains(&raw) {
            return self.reject(sensor, SampleError::Decode(ds18b20::Error::OutOfRange { raw }));
        }
        let stale_ms = self.slow.config.stale_after_ms();
        let mut restart = false;
        let mut clock_restart = false;
        // ms since this stream's last good reading, `None` across a restarted clock.
        let mut elapsed_ms = None;
        match last_good {
            None if raw == POWER_ON_RAW => return self.reject(sensor, SampleError::PowerOnJump),
            None => {}
            Some(last) => {
                let d = t_ms.wrapping_sub(last.t_ms);
                // Away for more than half a wrap: the wrapped difference means nothing (it
                // reads 2 s after 49.7 days), the saturated age is the elapsed time.
                let long_gap = age_ms > i32::MAX as u32;
                let elapsed = if long_gap { age_ms } else { d };
                if !long_gap && (d == 0 || d > i32::MAX as u32) {
                    // A clock that restarted: accepted once `confirm_samples` readings
                    // agree with each other.
                    if raw == POWER_ON_RAW || !self.confirm_step(sensor, t_ms, raw) {
                        return self.reject(sensor, SampleError::Time(rate::Error::NonMonotonic));
                    }
                    restart = true;
                    clock_restart = true;
                } else if raw == POWER_ON_RAW
                    && !(elapsed <= stale_ms
                        && i32::from(raw).abs_diff(i32::from(last.raw)) <= self.slow.config.max_step_raw as u32)
                {
                    // A brown-out reads 0550h: taken only as the continuation of a stream
                    // that was already there, never after a gap or a step.
                    return self.reject(sensor, SampleError::PowerOnJump);
                } else if !self.plausible(last, elapsed, raw) {
                    if !self.confirm_step(sensor, t_ms, raw) {
                        return self.reject(sensor, SampleError::Implausible { raw });
                    }
                    restart = true;
                } else if long_gap {
                    restart = true;
                }
                elapsed_ms = (!clock_restart).then_some(elapsed);
            }
        }
        let s = &mut self.slow.streams[sensor];
        if restart {
            s.rate.reset();
        }
        if let Err(e) = s.rate.push(t_ms, raw) {
            return self.reject(sensor, SampleError::Time(e));
        }
        s.pending_count = 0;
        s.invalid = false;
        s.age_ms = 0;
        s.last = Timed { t_ms, raw };
        s.has_good = true;
        // Across a restarted clock the elapsed time is unknown: the slot states hold.
        let dt_s = elapsed_ms.map_or(0.0, |ms| ms as f32 * 1e-3);
        self.refresh(Some(sensor), dt_s, true);
        Ok(self.slow.status)
    }

    /// Advance every stream's age by the time since the previous slow-path call. A time
    /// before that call (a conversion that completed before the previous poll) adds
    /// nothing; one more than the stale threshold before it is a restarted clock, which
    /// restarts the count from here.
    fn advance_clock(&mut self, t_ms: u32) {
        let slow = &mut *self.slow;
        let d = t_ms.wrapping_sub(slow.clock_ms);
        if d > i32::MAX as u32 {
            if d.wrapping_neg() > slow.config.stale_after_ms() {
                slow.clock_ms = t_ms;
            }
            return;
        }
        slow.clock_ms = t_ms;
        for s in &mut slow.streams {
            s.age_ms = s.age_ms.saturating_add(d);
        }
    }

    /// |raw − last.raw| within step + slew·elapsed, the elapsed time counted at most up to
    /// the rate window's gap (`rate.max_gap_ms`, 30 s: 1 + 5 °C by default). Beyond it the
    /// bound stops growing, so after a long dropout a step larger than that waits for
    /// `confirm_samples` readings that agree (the bound used to grow without limit, taking
    /// any value after a long enough gap).
    ///
    /// `step + ⌊slew·d/60 000⌋ ≥ |Δ|` is tested as `(|Δ| − step)·60 000 ≤ slew·d` in u64:
    /// the same integer rule without a 64-bit division (about 1 KB of library code on a
    /// Cortex-M4, which has no such instruction).
    fn plausible(&self, last: Timed, elapsed_ms: u32, raw: i16) -> bool {
        let c = &self.slow.config;
        let d_ms = u64::from(elapsed_ms.min(u32::from(self.slow.config.rate.max_gap_ms)));
        // Both validated ≥ 0.
        let (step, slew) = (c.max_step_raw as u32, c.max_slew_raw_per_min as u32);
        let Some(excess) = i32::from(raw).abs_diff(i32::from(last.raw)).checked_sub(step) else {
            return true;
        };
        u64::from(excess) * 60_000 <= u64::from(slew) * d_ms
    }

    /// Count consecutive rejected readings consistent with each other (later in time and
    /// plausible); true once there are `confirm_samples` of them: a real step (e.g. a
    /// replaced sensor) or a restarted clock.
    fn confirm_step(&mut self, sensor: usize, t_ms: u32, raw: i16) -> bool {
        let s = &self.slow.streams[sensor];
        let consistent = match (s.pending_count > 0).then_some(s.pending) {
            Some(p) => {
                let d = t_ms.wrapping_sub(p.t_ms);
                d != 0 && d < i32::MAX as u32 && self.plausible(p, d, raw)
            }
            None => false,
        };
        let s = &mut self.slow.streams[sensor];
        s.pending_count = if consistent { s.pending_count.saturating_add(1) } else { 1 };
        s.pending = Timed { t_ms, raw };
        s.pending_count >= self.slow.config.confirm_samples
    }

    fn reject(&mut self, sensor: usize, e: SampleError) -> Result<Status, SampleError> {
        self.slow.streams[sensor].invalid = true;
        self.publish(false);
        Err(e)
    }

    /// Rebuild the status and publish the set. One out-of-line copy for the accepted and the
    /// rejected reading: inlined into both it cost about 300 B of Cortex-M4 flash.
    #[inline(never)]
    fn publish(&mut self, good_sample: bool) {
        self.slow.status = self.slow.status();
        if good_sample {
            self.slow.epoch = self.slow.epoch.wrapping_add(1);
        }
        self.shared.publish_with(&self.slow.set(), || {});
    }

    fn refresh_all(&mut self, dt_s: f32) {
        self.refresh(None, dt_s, false);
    }

    /// Re-evaluate the axes served by `sensor` (every axis for `None`) at their stream's
    /// estimate (or at T0 before its first reading), rebuild the status and publish.
    fn refresh(&mut self, sensor: Option<usize>, dt_s: f32, good_sample: bool) {
        let slow = &mut *self.slow;
        if let Some(t) = &slow.table {
            {
                let table: &Table = t.borrow();
                // Each stream's estimate once, however many axes it serves: an estimate is
                // seven 64-bit → f32 conversions, about 250 instructions on a Cortex-M4.
                let estimates: [Option<Estimate>; SENSORS] = core::array::from_fn(|j| {
                    let s = &slow.streams[j];
                    (s.has_good && sensor.is_none_or(|k| k == j)).then(|| s.rate.estimate()).flatten()
                });
                for (i, axis) in table.axes.iter().take(AXES).enumerate() {
                    let j = Self::sensor_of(i);
                    if sensor.is_some_and(|s| s != j) {
                        continue;
                    }
                    let e = match estimates[j] {
                        Some(est) => {
                            let db = axis.bias.deadband_c_per_min.max(slow.deadband_floor);
                            axis.evaluate_with_deadband(&mut slow.states[i], est.temp_c, est.rate_c_per_min, dt_s, db)
                        }
                        // No reading yet: T0 and Ṫ = 0, without touching the state; flagged stale.
                        _ => axis.evaluate(&mut AxisState::default(), axis.scale.t0_c, 0.0, 0.0),
                    };
                    slow.evals[i] = e;
                }
            }
        }
        self.publish(good_sample);
    }
}

// loom's atomics work only inside `loom::model`: under `--cfg loom` only the seqlock's
// model runs (`cargo xtask loom`).
#[cfg(all(test, not(loom)))]
mod tests {
    use super::*;
    use crate::model::{AxisModel, BiasGrid, Extensions, ScaleFactor};

    fn table(axes: usize, window: u16) -> Table {
        let mut t = Table {
            input: table::Input::PulseCounts,
            rate_window: window,
            axes: heapless::Vec::new(),
            misalignment: None,
        };
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

    fn comp3() -> Compensator<3, 32> {
        Compensator::new(Config::default()).unwrap()
    }

    fn warm(c: &mut Compensator<3, 32>, n: u32) {
        for k in 0..n {
            c.on_raw(1000 * k, 352).unwrap();
        }
    }

    /// At rest on a code edge the DS18B20 flickers by one LSB; with the table's 0.05 °C/min
    /// deadband the branch would flip (the plain `AxisModel::evaluate` path shows it does),
    /// but the compensator's flicker floor keeps it: K0 stays the mean of the branches.
    #[test]
    fn flicker_at_rest_does_not_flip_the_branch() {
        let mut t = table(1, 32);
        t.axes[0].bias.cooling_g = heapless::Vec::from_slice(&[2e-4, 2.5e-4, 4e-4]).unwrap();
        assert_eq!(t.axes[0].bias.deadband_c_per_min, 0.05);
        let mut c: Compensator<1, 32> = Compensator::new(Config::default()).unwrap();
        c.set_table(t.clone()).unwrap();
        let mut est = RateEstimator::<32>::new(RateConfig::default());
        let mut plain = AxisState::default();
        let mut x: u64 = 0x2545_F491_4F6C_DD1D;
        let (mut plain_flips, mut k0s) = (0u32, [f32::INFINITY, f32::NEG_INFINITY]);
        let mut last = None;
        for k in 0..7200u32 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let raw = 352 + (x >> 63) as i16;
            c.on_raw(1000 * k, raw).unwrap();
            est.push(1000 * k, raw).unwrap();
            let e = est.estimate().unwrap();
            t.axes[0].evaluate(&mut plain, e.temp_c, e.rate_c_per_min, 1.0);
            if e.ready {
                plain_flips += u32::from(last.is_some_and(|b| b != plain.branch));
                last = Some(plain.branch);
                let k0 = c.evaluations()[0].k0;
                k0s = [k0s[0].min(k0), k0s[1].max(k0)];
            }
        }
        assert!(plain_flips > 10, "the 0.05 °C/min deadband flips on flicker: {plain_flips}");
        // Unknown branch at T̂ ≈ 22.0–22.06 °C (±0.1 °C for the fitted line's scatter): the
        // mean of the branches, which are 1e-4 g apart, so one flip would leave the band.
        let mean = |t: f32| 0.5 * ((1.5e-4 + 1.5e-4 * (t - 5.0) / 65.0) + (2.5e-4 + 1.5e-4 * (t - 5.0) / 65.0));
        assert!(k0s[0] >= mean(21.9) && k0s[1] <= mean(22.2), "{k0s:?}");
    }

    #[test]
    fn recovers_the_applied_specific_force() {
        let mut c = comp3();
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
        // Samples through the pulse compensator: flagged, never status OK.
        assert!(c.cycle_samples([n, n, n], 1_000_000).status.contains(Status::WRONG_INPUT));
        // The same model on samples: raw = K1·(K0 + a) LSB gives a in m/s².
        let mut m = Compensator::<3, 32>::new(Config { input: table::Input::Samples, ..Config::default() }).unwrap();
        m.set_table(Table { input: table::Input::Samples, ..table(3, 32) }).unwrap();
        warm(&mut m, 21);
        let samples = m.cycle_samples([n, n, n], 1_000_000);
        let a = f64::from(samples.dv_mps[0]) / 9.806_65;
        assert!((a - 0.5).abs() < 5e-6, "{a}");
        assert!(samples.status.is_ok(), "{samples:?}");
        assert!(m.cycle([n, n, n], 1_000_000).status.contains(Status::WRONG_INPUT));
    }

    #[test]
    fn stale_after_timeout_keeps_last_compensation() {
        let mut c = comp3();
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
        let mut c = comp3();
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
        let mut c = comp3();
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
    fn a_table_in_flash_is_held_by_reference() {
        static TABLE: std::sync::OnceLock<Table> = std::sync::OnceLock::new();
        let t: &'static Table = TABLE.get_or_init(|| table(3, 32));
        let mut flash = Compensator::<3, 32, 1, &'static Table>::new(Config::default()).unwrap();
        let mut owned = comp3();
        flash.set_table(t).unwrap();
        owned.set_table(t.clone()).unwrap();
        for k in 0..12 {
            flash.on_raw(1000 * k, 352).unwrap();
            owned.on_raw(1000 * k, 352).unwrap();
        }
        assert_eq!(flash.cycle([800, 1, -3], 2500), owned.cycle([800, 1, -3], 2500));
        assert!(core::mem::size_of_val(&flash) + 600 < core::mem::size_of_val(&owned));
    }

    /// No table: the counts pass through at the nominal scale, never as zero (free fall).
    #[test]
    fn no_table_passes_raw_through_at_nominal_scale_flagged() {
        let mut c = comp3();
        let out = c.cycle([320_000, -320_000, 5], 2500);
        assert!(out.status.contains(Status::NO_TABLE));
        assert!(out.status.contains(Status::TEMP_STALE));
        // 320 000 pulses at the default nominal 320 000 pulses/(g·s) is 1 g·s = g0 m/s.
        assert!((out.dv_mps[0] - 9.806_65).abs() < 1e-5, "{out:?}");
        assert!((out.dv_mps[1] + 9.806_65).abs() < 1e-5, "{out:?}");
        let s = c.cycle_samples([160_000, 0, 0], 2500);
        assert!((s.dv_mps[0] - 4.903_325).abs() < 1e-5, "{s:?}");
    }

    #[test]
    fn bad_configs_are_refused_with_their_reason() {
        let d = Config::default();
        let cases = [
            (Config { tick_s: f32::NAN, ..d }, ConfigError::NonFinite("tick_s")),
            (Config { tick_s: 0.0, ..d }, ConfigError::OutOfRange("tick_s")),
            (Config { nominal_k1: f32::INFINITY, ..d }, ConfigError::NonFinite("nominal_k1")),
            (Config { nominal_k1: -1.0, ..d }, ConfigError::OutOfRange("nominal_k1")),
            (
                Config { rate: RateConfig { smoothing_alpha: f32::NAN, ..d.rate }, ..d },
                ConfigError::NonFinite("rate.smoothing_alpha"),
            ),
            (
                Config { rate: RateConfig { smoothing_alpha: 0.0, ..d.rate }, ..d },
                ConfigError::OutOfRange("rate.smoothing_alpha"),
            ),
            (
                Config { rate: RateConfig { min_samples: 2, ..d.rate }, ..d },
                ConfigError::OutOfRange("rate.min_samples"),
            ),
            (Config { confirm_samples: 0, ..d }, ConfigError::OutOfRange("confirm_samples")),
            (Config { stale_after_ticks: 999_999, ..d }, ConfigError::StaleShorterThanSamplePeriod),
            (Config { stale_after_ticks: i32::MAX as u32, ..d }, ConfigError::OutOfRange("stale_after_ticks")),
            (Config { confirm_samples: 1, ..d }, ConfigError::OutOfRange("confirm_samples")),
            (Config { rate: RateConfig { max_gap_ms: 1000, ..d.rate }, ..d }, ConfigError::GapShorterThanSamplePeriod),
            (Config { sample_period_ms: 0, ..d }, ConfigError::OutOfRange("sample_period_ms")),
            (Config { max_step_raw: -1, ..d }, ConfigError::OutOfRange("max_step_raw")),
            (Config { max_slew_raw_per_min: -1, ..d }, ConfigError::OutOfRange("max_slew_raw_per_min")),
        ];
        for (cfg, want) in cases {
            assert_eq!(cfg.validate(), Err(want), "{cfg:?}");
            assert_eq!(Compensator::<3, 32>::new(cfg).err(), Some(want));
        }
        assert_eq!(d.validate(), Ok(()));
        let min40 = Config { rate: RateConfig { min_samples: 40, ..d.rate }, ..d };
        assert_eq!(Compensator::<3, 32>::new(min40).err(), Some(ConfigError::MinSamplesAboveWindow));
        assert_eq!(Compensator::<3, 32, 2>::new(d).err(), Some(ConfigError::SensorCount));
    }

    #[test]
    fn extreme_inputs_stay_finite() {
        let mut c = comp3();
        let mut t = table(3, 32);
        t.misalignment = Some([1.049, 0.049, -0.049, -0.049, 0.951, 0.049, 0.049, -0.049, 1.049]);
        c.set_table(t).unwrap();
        warm(&mut c, 12);
        for (p, dt) in [([i32::MAX, i32::MIN, 0], u32::MAX), ([i32::MIN; 3], 0), ([0; 3], u32::MAX)] {
            let out = c.cycle(p, dt);
            assert!(out.dv_mps.iter().all(|v| v.is_finite()), "{out:?}");
            let out = c.cycle_samples(p, dt);
            assert!(out.dv_mps.iter().all(|v| v.is_finite()), "{out:?}");
        }
    }

    #[test]
    fn wrapping_counters_give_signed_increments() {
        let mut c = Compensator::<1, 32>::new(Config::default()).unwrap();
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

    /// A clock that jumps back (a reset time source) is refused, then accepted as a restart
    /// once `confirm_samples` readings agree: never stuck for half a wrap.
    #[test]
    fn a_restarted_clock_is_confirmed_not_rejected_forever() {
        let mut c = comp3();
        c.set_table(table(3, 32)).unwrap();
        warm(&mut c, 20);
        let err = Err(SampleError::Time(rate::Error::NonMonotonic));
        assert_eq!(c.on_raw(500, 352), err);
        assert_eq!(c.on_raw(1_500, 353), err);
        assert!(c.on_raw(2_500, 353).is_ok(), "third consistent reading: restart");
        assert_eq!(c.estimate().map(|e| e.ready), Some(false), "window restarted");
        assert!(c.on_raw(3_500, 353).is_ok());
    }

    /// One sensor per axis: each axis follows its own stream; a dead sensor is flagged stale
    /// by the others' timestamps, and its axis keeps its last good compensation.
    #[test]
    fn one_sensor_per_axis() {
        let mut c = Compensator::<3, 32, 3>::new(Config::default()).unwrap();
        c.set_table(table(3, 32)).unwrap();
        let mut one = Compensator::<1, 32>::new(Config::default()).unwrap();
        let mut t1 = table(1, 32);
        t1.axes[0] = table(3, 32).axes[2].clone();
        one.set_table(t1).unwrap();
        for k in 0..20u32 {
            for s in 0..3 {
                c.on_raw_from(s, 1000 * k + 10 * s as u32, 320 + 16 * s as i16 + (k / 4) as i16).unwrap();
            }
            one.on_raw(1000 * k + 20, 352 + (k / 4) as i16).unwrap();
        }
        let e: [f32; 3] = core::array::from_fn(|s| c.estimate_of(s).unwrap().temp_c);
        assert!((e[1] - e[0] - 1.0).abs() < 1e-4 && (e[2] - e[0] - 2.0).abs() < 1e-4, "{e:?}");
        let out = c.cycle([800, 800, 800], 2500);
        assert!(out.status.is_ok(), "{out:?}");
        // Axis 2 equals a one-axis compensator fed axis 2's stream alone.
        assert_eq!(out.dv_mps[2], one.cycle([800], 2500).dv_mps[0]);
        // Sensor 1 dies: after 3 s of the others' readings it is stale; axis 1 unchanged.
        for k in 20..25u32 {
            c.on_raw_from(0, 1000 * k, 320 + (k / 4) as i16).unwrap();
            c.on_raw_from(2, 1000 * k + 20, 352 + (k / 4) as i16).unwrap();
        }
        let later = c.cycle([800, 800, 800], 2500);
        assert!(later.status.contains(Status::TEMP_STALE), "{later:?}");
        assert_eq!(later.dv_mps[1], out.dv_mps[1]);
        assert_eq!(c.on_raw_from(3, 0, 0), Err(SampleError::NoSuchSensor { sensor: 3 }));
    }

    /// The split halves give the same outputs as the unsplit compensator.
    #[test]
    fn split_halves_match_the_whole() {
        let mut a = comp3();
        let mut b = comp3();
        a.set_table(table(3, 32)).unwrap();
        b.set_table(table(3, 32)).unwrap();
        let (mut up, mut ap) = b.split();
        for k in 0..40u32 {
            let raw = 352 + (k / 4) as i16;
            assert_eq!(a.on_raw(1000 * k, raw), up.on_raw_from(0, 1000 * k, raw));
            for _ in 0..3 {
                assert_eq!(a.cycle([800, -7, 3], 2500), ap.cycle([800, -7, 3], 2500));
            }
        }
    }

    /// Deterministic interleaving: the writer is preempted after every single store, and
    /// the reader runs there. Every output must equal the output of the old set or of the
    /// new set, never a mixture.
    #[test]
    fn reader_preempting_the_writer_at_every_store_sees_whole_sets() {
        let mut c = comp3();
        let mut t = table(3, 32);
        t.misalignment = Some([1.049, 0.049, -0.049, -0.049, 0.951, 0.049, 0.049, -0.049, 1.049]);
        c.set_table(t).unwrap();
        warm(&mut c, 12);
        // The applier holds the old set before the new publication starts.
        c.cycle([0; 3], 2500);
        let old = c.slow.set();
        let mut new = old;
        new.scale = [1.0, 2.0, 3.0];
        new.bias_tick = [0.5, 0.25, 0.125];
        new.bias_acc = [4.0, 5.0, 6.0];
        new.status = Status::TEMP_OUT_OF_RANGE;
        let pulses = [800, -7, 3];
        let reference = |s: &Set<3>| {
            let shared = Published::new();
            shared.publish_with(s, || {});
            // An odd `seen_seq` never matches a whole set's sequence: the reference copies it.
            let mut fast = FastState { seen_seq: 1, ..c.fast };
            let mut ap = Applier { fast: &mut fast, shared: &shared };
            (ap.cycle(pulses, 2500), ap.cycle_samples(pulses, 2500))
        };
        let (want_old, want_new) = (reference(&old), reference(&new));
        assert_ne!(want_old.0.dv_mps, want_new.0.dv_mps);
        let mut fast = c.fast;
        let mut stores = 0;
        let mut seen_new = false;
        c.shared.publish_with(&new, || {
            stores += 1;
            let mut ap = Applier { fast: &mut fast, shared: &c.shared };
            let got = (ap.cycle(pulses, 2500), ap.cycle_samples(pulses, 2500));
            let strip = |o: Output<3>| (o.dv_mps, o.status - Status::TEMP_STALE);
            let same = |a: &(Output<3>, Output<3>), b: &(Output<3>, Output<3>)| {
                strip(a.0) == strip(b.0) && strip(a.1) == strip(b.1)
            };
            if same(&got, &want_new) {
                seen_new = true;
            } else {
                assert!(!seen_new, "went back to the old set after store {stores}");
                assert!(same(&got, &want_old), "mixed set after store {stores}: {got:?}");
            }
        });
        assert_eq!(stores, 1 + 3 * 3 + 9 + 1 + 1, "every store was preempted");
        assert!(seen_new, "the last store publishes the new set");
    }

    /// The other direction: the updater preempts the applier in the middle of its copy.
    /// The copy is dropped, the old set stays in force, and the next cycle takes the new one.
    #[test]
    fn a_copy_torn_by_the_writer_is_dropped() {
        let mut c = comp3();
        c.set_table(table(3, 32)).unwrap();
        warm(&mut c, 12);
        let before = c.cycle([800, -7, 3], 2500);
        let old_scale = c.fast.set.scale;
        let mut new = c.slow.set();
        new.scale = [1.0, 2.0, 3.0];
        c.shared.publish_with(&new, || {});
        let shared = &c.shared;
        let mut fast = c.fast;
        let mut ap = Applier { fast: &mut fast, shared };
        let old_seq = ap.fast.seen_seq;
        ap.refresh_with(|| shared.publish_with(&new, || {}));
        assert_eq!(ap.fast.seen_seq, old_seq, "torn copy dropped");
        assert_eq!(ap.fast.set.scale, old_scale, "old set kept");
        let after = ap.cycle([800, -7, 3], 2500);
        assert_eq!(after.dv_mps[0], 800.0 * 1.0 - new.bias_tick[0] * 2500.0);
        // A sequence left odd (a writer stopped mid-publication) keeps the old set too.
        shared.seq.store(shared.seq.load(Ordering::Relaxed) + 1, Ordering::Relaxed);
        let mut fast2 = c.fast;
        let mut ap2 = Applier { fast: &mut fast2, shared };
        assert_eq!(ap2.cycle([800, -7, 3], 2500).dv_mps, before.dv_mps);
    }
}
