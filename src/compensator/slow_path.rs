//! The slow path: temperature readings, their plausibility, the rate estimators, the model
//! evaluations and the publication of each coefficient set.

#[cfg(doc)]
use super::Compensator;
use core::borrow::Borrow;
use core::fmt;

use super::seqlock::{Changes, Published, Set, AGE_STALE, AGE_STEPS};
use super::{Config, Status, G0};
use crate::ds18b20::{self, POWER_ON_RAW};
use crate::model::{AxisState, Evaluation};
use crate::rate::{self, Estimate, RateWindow};
use crate::table::{self, Table};

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
        /// The index given, as given.
        sensor: usize,
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

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Timed {
    pub(super) t_ms: u32,
    pub(super) raw: i16,
}

/// One temperature stream: its estimator, plausibility state and flags.
#[derive(Clone, Debug)]
pub(super) struct Stream<const RATE_WINDOW: usize> {
    /// Its rate window, under the compensator's `Config::rate`. Its newest sample is the
    /// stream's last good reading (every good reading is pushed, and a restart empties it
    /// only to push the reading that restarted it): kept once, there.
    pub(super) rate: RateWindow<RATE_WINDOW>,
    /// The latest rejected reading's time and value, counted towards a confirmed step;
    /// meaningful only while `pending_count > 0` (no `Option`, and two fields rather than a
    /// `Timed`, whose padding cost 2 B: 8 B less per stream in all).
    pub(super) pending_t_ms: u32,
    pub(super) pending_raw: i16,
    /// Consecutive mutually consistent rejected readings, the latest being `pending`.
    pub(super) pending_count: u8,
    /// The latest reading was rejected.
    pub(super) invalid: bool,
    /// ms since the last good reading, summed from the slow path's own calls and
    /// saturating: unlike a wrapping difference of timestamps it never reads fresh again.
    pub(super) age_ms: u32,
}

impl<const RATE_WINDOW: usize> Stream<RATE_WINDOW> {
    fn last_good(&self) -> Option<Timed> {
        self.rate.newest().map(|(t_ms, raw)| Timed { t_ms, raw })
    }

    fn has_good(&self) -> bool {
        !self.rate.is_empty()
    }
}

/// Slow-path state (the updater's own, never touched by the applier).
#[derive(Clone, Debug)]
pub(super) struct SlowState<const AXES: usize, const RATE_WINDOW: usize, const SENSORS: usize, T> {
    pub(super) config: Config,
    /// `config.stale_after_ms()`, formed once (an f32 expression the slow path needed at
    /// each reading four times).
    pub(super) stale_ms: u32,
    /// The latest slow-path time seen (readings, rejections and missed readings alike): the
    /// clock that advances every stream's `age_ms`. Starts at 0: ages before a stream's
    /// first good reading do not matter, since it is stale until then.
    pub(super) clock_ms: u32,
    /// Good readings published, wrapping (see `Set::epoch`).
    pub(super) epoch: u8,
    /// Smallest branch deadband, °C/min: the flicker floor of `RATE_WINDOW` and the sample period.
    pub(super) deadband_floor: f32,
    pub(super) table: Option<T>,
    pub(super) streams: [Stream<RATE_WINDOW>; SENSORS],
    pub(super) states: [AxisState; AXES],
    pub(super) evals: [Evaluation; AXES],
    /// The status last published.
    pub(super) status: Status,
    /// The estimate before the newest reading (the one-reading-delay mutant only).
    #[cfg(qfa_mutant = "one_reading_delay")]
    pub(super) delayed: Option<Estimate>,
}

impl<const AXES: usize, const RATE_WINDOW: usize, const SENSORS: usize, T: Borrow<Table>>
    SlowState<AXES, RATE_WINDOW, SENSORS, T>
{
    /// The status of the streams, the table and the evaluations as they stand, and the
    /// oldest stream's age (see `Set::age`): one pass over the streams.
    pub(super) fn summary(&self) -> (Status, u16) {
        let mut st = Status::empty();
        let stale_ms = self.stale_ms;
        // The oldest good reading's age, ms; above `stale_ms` once any stream is stale.
        let mut oldest_ms = 0u32;
        for s in &self.streams {
            if !s.rate.ready(&self.config.rate) {
                st |= Status::RATE_NOT_READY;
            }
            let age_ms = if s.has_good() { s.age_ms } else { u32::MAX };
            oldest_ms = oldest_ms.max(age_ms);
            if s.invalid {
                st |= Status::TEMP_INVALID;
            }
        }
        let age = if oldest_ms > stale_ms {
            st |= Status::TEMP_STALE;
            AGE_STALE
        } else {
            // In 1/AGE_STEPS of the stale threshold, rounded down, in f32 (a 64-bit integer
            // division would link 900 B of library code): within one unit, 0.18 ms at 3 s.
            // Once, for the oldest: the rounding is monotonic, so it is the largest of the
            // streams' ages rounded each.
            // Through u32, one saturating `vcvt` (to u16 it is clamped twice more).
            let units_per_ms = f32::from(AGE_STEPS) / stale_ms as f32;
            ((oldest_ms as f32 * units_per_ms) as u32).min(u32::from(AGE_STEPS)) as u16
        };
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
                if e.settling {
                    st |= Status::MODEL_SETTLING;
                }
            }
        }
        (st, age)
    }

    /// The coefficient set of the current table, evaluations and [`Self::summary`], formed
    /// for what `changes` names only: the words not published are left at 0 here. Rebuilt at every publication (a division per
    /// changed axis, in the slow path) rather than kept beside the published one: that copy
    /// would cost RAM.
    pub(super) fn set<const MATRIX: usize>(&self, changes: Changes) -> Set<AXES, MATRIX> {
        let (status, age) = self.summary();
        let mut set = Set { status, age, epoch: self.epoch, ..Set::EMPTY };
        let Some(t) = &self.table else {
            let nominal = G0 / self.config.input_per_g();
            set.scale = [nominal; AXES];
            return set;
        };
        let table: &Table = t.borrow();
        // 1 for pulse counts (K1 · 1 is K1, bit for bit); the part's LSB per 2²⁰ for samples.
        let to_input = self.config.table_to_input();
        let pulses = self.config.input == table::Input::PulseCounts;
        if changes.coefficients {
            for (i, e) in self.evals.iter().enumerate() {
                set.scale[i] = G0 / (e.k1 * to_input);
                set.bias[i] = if pulses { (e.k0 * G0) * self.config.tick_s } else { e.k0 * G0 };
            }
        }
        if changes.matrix && MATRIX > 0 {
            // Validation allows a matrix only with 3 axes, and `set_table` one only with a
            // misalignment stage (MATRIX == AXES == 3): every index is in the 9 values.
            set.misalign = table.misalignment.map(|m| core::array::from_fn(|r| core::array::from_fn(|c| m[r * 3 + c])));
        }
        set
    }
}

/// The slow path of a split compensator: temperature readings and tables. Never runs in
/// the IMU interrupt.
///
/// Every reading reaches it, good or not: a scratchpad as read
/// ([`on_scratchpad`](Self::on_scratchpad)), or a read that failed on the bus
/// ([`on_missed_reading`](Self::on_missed_reading)).
///
/// ```
/// use qfa_thermal::ds18b20::{encode_scratchpad, Resolution};
/// use qfa_thermal::{Config, SampleError, Status, Table, ThreeAxisSensorPerAxis};
///
/// let mut comp = ThreeAxisSensorPerAxis::<&'static Table>::new(Config::default()).unwrap();
/// let (mut updater, _applier) = comp.split();
/// let sp = encode_scratchpad(400, Resolution::Bits12, 0x10); // 25.0 °C, CRC good
/// assert!(updater.on_scratchpad(0, 1_000, &sp).is_ok());
/// assert_eq!(updater.on_missed_reading(1, 1_000), Err(SampleError::Missed));
/// assert!(updater.status().contains(Status::TEMP_INVALID));
/// let mut corrupt = sp;
/// corrupt[0] ^= 1; // a flipped bit on the bus: the CRC refuses it
/// assert!(matches!(updater.on_scratchpad(2, 1_000, &corrupt), Err(SampleError::Decode(_))));
/// ```
#[derive(Debug)]
pub struct Updater<'a, const AXES: usize, const RATE_WINDOW: usize, const SENSORS: usize, T, const MATRIX: usize = 0> {
    pub(super) slow: &'a mut SlowState<AXES, RATE_WINDOW, SENSORS, T>,
    pub(super) shared: &'a Published<AXES, MATRIX>,
}

impl<const AXES: usize, const RATE_WINDOW: usize, const SENSORS: usize, T: Borrow<Table>, const MATRIX: usize>
    Updater<'_, AXES, RATE_WINDOW, SENSORS, T, MATRIX>
{
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
        self.slow.streams.get(sensor).and_then(|s| s.rate.estimate(&self.slow.config.rate))
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
        if usize::from(tb.rate_window) != RATE_WINDOW {
            return Err(table::Error::RateWindow { table: tb.rate_window, firmware: RATE_WINDOW as u16 });
        }
        // A matrix the compensator cannot apply is refused, never dropped with the status OK.
        if tb.misalignment.is_some() && MATRIX == 0 {
            return Err(table::Error::NoMisalignmentStage);
        }
        // Every axis's γ within a factor of 2 of the nominal scale: a table in another unit
        // scale is refused, never applied 256 (or 9.8) times off with the status OK.
        let config = &self.slow.config;
        let nominal = match tb.input {
            table::Input::PulseCounts => config.nominal_k1,
            table::Input::Samples => table::SAMPLE_UNITS_PER_G,
        };
        if let Some(a) = tb.axes.iter().find(|a| !(0.5..=2.0).contains(&(a.scale.gamma / nominal))) {
            return Err(table::Error::Scale { table_k1: a.scale.gamma as u32, nominal_k1: nominal as u32 });
        }
        // A table that knows the part's range refuses a firmware that reads it at another.
        if let Some(part) = tb.part_lsb_per_g {
            let stated = config.sample_lsb_per_g;
            // Both finite: the configuration and the table were validated.
            if libm::fabsf(stated / part - 1.0) > 1e-3 {
                return Err(table::Error::PartScale { table_lsb_per_g: part as u32, config_lsb_per_g: stated as u32 });
            }
        }
        // The model's running states carry over (`AxisState::carried_over`): a reload of the
        // table in force is a no-op, a changed slot restarts alone.
        if let Some(old) = &self.slow.table {
            let old: &Table = old.borrow();
            // Zipped, not indexed: validation made both AXES long, but no index may panic here.
            for ((state, o), n) in self.slow.states.iter_mut().zip(&old.axes).zip(&tb.axes) {
                *state = state.carried_over(o, n);
            }
        } else {
            self.slow.states = [AxisState::default(); AXES];
        }
        self.slow.table = Some(t);
        self.refresh_all(0.0);
        Ok(())
    }

    /// Slow path: see [`Compensator::on_scratchpad`].
    ///
    /// # Errors
    /// As [`Compensator::on_scratchpad`].
    pub fn on_scratchpad(&mut self, sensor: usize, t_ms: u32, sp: &[u8; 9]) -> Result<Status, SampleError> {
        if sensor >= SENSORS {
            return Err(SampleError::NoSuchSensor { sensor });
        }
        match ds18b20::decode_scratchpad(sp) {
            // `on_raw` advances the clock itself (advancing it here as well walked every
            // stream's age a second time, by zero).
            Ok(r) => self.on_raw(sensor, t_ms, r.raw),
            Err(e) => {
                self.advance_clock(t_ms);
                self.reject(sensor, SampleError::Decode(e))
            }
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
            return Err(SampleError::NoSuchSensor { sensor });
        }
        self.advance_clock(t_ms);
        self.reject(sensor, SampleError::Missed)
    }

    /// Slow path: see [`Compensator::on_raw`].
    ///
    /// # Errors
    /// As [`Compensator::on_raw`].
    pub fn on_raw(&mut self, sensor: usize, t_ms: u32, raw: i16) -> Result<Status, SampleError> {
        let Some(s) = self.slow.streams.get(sensor) else {
            return Err(SampleError::NoSuchSensor { sensor });
        };
        let (last_good, age_ms) = (s.last_good(), s.age_ms);
        self.advance_clock(t_ms);
        let age_ms = self.slow.streams[sensor].age_ms.max(age_ms);
        if !ds18b20::RAW_RANGE.contains(&raw) {
            return self.reject(sensor, SampleError::Decode(ds18b20::Error::OutOfRange { raw }));
        }
        let stale_ms = self.slow.stale_ms;
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
        #[cfg(qfa_mutant = "one_reading_delay")]
        let delayed = self.slow.streams[sensor].rate.estimate(&self.slow.config.rate);
        let rate_config = self.slow.config.rate;
        let s = &mut self.slow.streams[sensor];
        if restart {
            s.rate.reset();
        }
        if let Err(e) = s.rate.push(&rate_config, t_ms, raw) {
            return self.reject(sensor, SampleError::Time(e));
        }
        s.pending_count = 0;
        s.invalid = false;
        s.age_ms = 0;
        // Across a restarted clock the elapsed time is unknown: the slot states hold.
        let dt_s = elapsed_ms.map_or(0.0, |ms| ms as f32 * 1e-3);
        #[cfg(qfa_mutant = "one_reading_delay")]
        {
            self.slow.delayed = delayed;
        }
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
            if d.wrapping_neg() > slow.stale_ms {
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
        let pending = Timed { t_ms: s.pending_t_ms, raw: s.pending_raw };
        let consistent = match (s.pending_count > 0).then_some(pending) {
            Some(p) => {
                let d = t_ms.wrapping_sub(p.t_ms);
                d != 0 && d < i32::MAX as u32 && self.plausible(p, d, raw)
            }
            None => false,
        };
        let s = &mut self.slow.streams[sensor];
        s.pending_count = if consistent { s.pending_count.saturating_add(1) } else { 1 };
        (s.pending_t_ms, s.pending_raw) = (t_ms, raw);
        s.pending_count >= self.slow.config.confirm_samples
    }

    // Cold and out of line: a rejected reading is rare, and kept apart it leaves the accepted
    // reading's path the only one `publish` is laid out for.
    #[cold]
    #[inline(never)]
    fn reject(&mut self, sensor: usize, e: SampleError) -> Result<Status, SampleError> {
        self.slow.streams[sensor].invalid = true;
        // No coefficient changed: the status, the epoch and the age only.
        self.publish(false, Changes::FLAGS);
        Err(e)
    }

    /// Rebuild the status and publish what `changes` names, with the flags. One
    /// out-of-line copy for the accepted and the rejected reading: inlined into both it cost
    /// about 300 B of Cortex-M4 flash.
    #[inline(never)]
    fn publish(&mut self, good_sample: bool, changes: Changes) {
        if good_sample {
            self.slow.epoch = self.slow.epoch.wrapping_add(1);
        }
        let set = self.slow.set(changes);
        self.slow.status = set.status;
        self.shared.publish_with(&set, changes, || {});
    }

    pub(super) fn refresh_all(&mut self, dt_s: f32) {
        self.refresh(None, dt_s, false);
    }

    /// Re-evaluate the axes served by `sensor` (every axis for `None`) at their stream's
    /// estimate (or at T0 before its first reading), rebuild the status and publish the
    /// coefficients (and the matrix for `None`: a table or a construction).
    fn refresh(&mut self, sensor: Option<usize>, dt_s: f32, good_sample: bool) {
        let changes = if sensor.is_some() { Changes::COEFFICIENTS } else { Changes::ALL };
        let slow = &mut *self.slow;
        if let Some(t) = &slow.table {
            {
                let table: &Table = t.borrow();
                // Each stream's estimate once, however many axes it serves: an estimate is
                // seven 64-bit → f32 conversions, about 250 instructions on a Cortex-M4.
                let estimates: [Option<Estimate>; SENSORS] = core::array::from_fn(|j| {
                    let s = &slow.streams[j];
                    #[cfg(qfa_mutant = "one_reading_delay")]
                    if sensor == Some(j) && slow.delayed.is_some() {
                        return slow.delayed;
                    }
                    (s.has_good() && sensor.is_none_or(|k| k == j))
                        .then(|| s.rate.estimate(&slow.config.rate))
                        .flatten()
                });
                for (i, axis) in table.axes.iter().take(AXES).enumerate() {
                    let j = Self::sensor_of(i);
                    if sensor.is_some_and(|s| s != j) {
                        continue;
                    }
                    let e = match estimates[j] {
                        Some(est) => {
                            // The floor of the window as filled now: on a partial window the
                            // full window's floor would let flicker decide the branch.
                            let floor = slow.streams[j].rate.flicker_floor(slow.deadband_floor);
                            let db = crate::model::larger(axis.bias.deadband_c_per_min, floor);
                            axis.evaluate_with_deadband(&mut slow.states[i], est.temp_c, est.rate_c_per_min, dt_s, db)
                        }
                        // No reading yet: T0 and Ṫ = 0, without touching the state; flagged stale.
                        _ => axis.evaluate(&mut AxisState::default(), axis.scale.t0_c, 0.0, 0.0),
                    };
                    slow.evals[i] = e;
                }
            }
        }
        self.publish(good_sample, changes);
    }
}
