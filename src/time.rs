//! The slow path's time base: wrapping `u32` milliseconds, and a wrap-safe µs → ms clock.
//!
//! # One time base
//! Every slow-path call ([`Compensator::on_raw`](crate::Compensator::on_raw) and friends)
//! takes `t_ms`, a **wrapping `u32` count of milliseconds** from one clock shared by all
//! temperature sensors. It wraps every 2³² ms = 49.7 days. The rate estimator only uses
//! `t_ms.wrapping_sub(previous)` within its window (gaps of at most 65.5 s). How long a
//! sensor has been silent is not read from a wrapped difference, which says "2 s" for a
//! sensor that died 49.7 days and 2 s ago: the slow path sums the forward steps of `t_ms`
//! over all its calls (readings, rejections, [`on_missed_reading`]) into a saturating age per
//! sensor. That age drives [`Status::TEMP_STALE`](crate::Status::TEMP_STALE), restarts a
//! returning sensor's rate window, and caps the plausibility slew, however many wraps
//! passed. Its one requirement: the slow path hears of some sensor at least once every 2³¹
//! ms (24.8 days), which a 1 Hz loop that reports every failed read through
//! [`on_missed_reading`] does 2 million times over. A clock that was reset (a step back of
//! more than the stale threshold) restarts the count; the readings that follow are first
//! rejected as [`SampleError::Time`](crate::SampleError::Time) and then, once
//! [`Config::confirm_samples`](crate::Config::confirm_samples) consecutive readings agree
//! with each other, accepted as a restart of that sensor's stream.
//!
//! [`on_missed_reading`]: crate::Compensator::on_missed_reading
//!
//! The fast path counts its own ticks as deltas (`dt_ticks`, a `u32` per IMU cycle); it
//! never sees an absolute time, so it has no wrap.
//!
//! # Why a clock type
//! Most timers give a wrapping `u32` of **microseconds**, which wraps every 71.6 min.
//! `now_us / 1000` is *not* a millisecond clock: it jumps back by 4 294 967 ms at every µs
//! wrap. The compensator takes the jump as a restarted clock: it refuses the readings until
//! `confirm_samples` of them agree, then restarts the rate window, so at the default
//! settings each wrap costs 2 refused readings and 9 s without status OK (flagged, never
//! silent; `compensator::tests::dividing_the_us_clock_costs_seconds_of_flags_at_each_wrap_not_an_hour`),
//! and the rate window starts over every 71.6 min. [`MsClock`]
//! extends the µs clock instead: it keeps the
//! milliseconds (and the sub-millisecond remainder) across wraps, so its output wraps only
//! at 2³² ms. Its one requirement: [`MsClock::ms`] is called at least once every 2³¹ µs
//! (35.8 min), which any 1 Hz temperature loop does 2 000 times over.
//!
//! ```
//! use qfa_thermal::time::MsClock;
//! let mut clock = MsClock::new();
//! let a = clock.ms(u32::MAX - 499_999); // 0.5 s before the µs clock wraps
//! let b = clock.ms(500_000);            // 0.5 s after it
//! assert_eq!(b.wrapping_sub(a), 1_000);
//! ```
//!
//! `fugit` was considered for typed instants. Its `Instant<u32, 1, 1_000_000>` compares
//! across one wrap but cannot convert a wrapping µs instant into a longer-lived ms one,
//! which is the whole problem here; the two integers above carry no cost on the fast path.

/// Extends a wrapping `u32` µs clock into a wrapping `u32` ms clock (wraps at 49.7 days).
///
/// 16 bytes. Times older than the newest one seen (a conversion that completed before the
/// last poll) convert correctly within ±35.8 min of it.
///
/// One clock for every sensor, fed the wrapping µs timer each time a conversion completes:
///
/// ```
/// use qfa_thermal::time::MsClock;
///
/// let mut clock = MsClock::new();
/// let mut us: u32 = 0;
/// let mut last = clock.ms(us);
/// // Two hours of 1 Hz readings: the µs timer wraps at 71.6 min, the ms time never steps back.
/// for _ in 0..7_200 {
///     us = us.wrapping_add(1_000_000);
///     let ms = clock.ms(us);
///     assert_eq!(ms.wrapping_sub(last), 1_000);
///     last = ms;
/// }
/// assert_eq!(last, 7_200_000);
/// assert_eq!(u64::from(us), 7_200_000_000 % (1 << 32)); // while the µs timer wrapped
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MsClock {
    /// Newest µs value seen.
    last_us: u32,
    /// Milliseconds at `last_us`.
    ms: u32,
    /// µs past `ms` at `last_us`, 0..1000.
    rem_us: u32,
    started: bool,
    /// `ms` was given by [`MsClock::starting_at`] rather than taken from the first µs value.
    origin_given: bool,
}

impl Default for MsClock {
    fn default() -> Self {
        Self::new()
    }
}

impl MsClock {
    /// A clock whose ms value starts at the first µs value seen, divided by 1000.
    #[must_use]
    pub const fn new() -> Self {
        Self { last_us: 0, ms: 0, rem_us: 0, started: false, origin_given: false }
    }

    /// A clock whose first µs value seen maps to `ms` (e.g. to start near the ms wrap in a
    /// test, or to continue a time base kept across a reset).
    #[must_use]
    pub const fn starting_at(ms: u32) -> Self {
        Self { last_us: 0, ms, rem_us: 0, started: false, origin_given: true }
    }

    /// The ms time of `now_us`. A value after the newest one seen advances the clock; one
    /// before it (up to 2³¹ µs earlier) is converted without moving the clock back.
    pub fn ms(&mut self, now_us: u32) -> u32 {
        if !self.started {
            self.started = true;
            self.last_us = now_us;
            if !self.origin_given {
                self.ms = now_us / 1000;
                self.rem_us = now_us % 1000;
            }
            return self.ms;
        }
        let d = now_us.wrapping_sub(self.last_us);
        if d <= i32::MAX as u32 {
            let total = self.rem_us + d % 1000;
            self.ms = self.ms.wrapping_add(d / 1000 + total / 1000);
            self.rem_us = total % 1000;
            self.last_us = now_us;
            self.ms
        } else {
            // Earlier than the newest value: floor((rem − back)/1000) ms relative to `ms`.
            let back = self.last_us.wrapping_sub(now_us);
            let back_ms = if back > self.rem_us { (back - self.rem_us).div_ceil(1000) } else { 0 };
            self.ms.wrapping_sub(back_ms)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Independent check: an i64 µs counter, floored to ms, against the clock fed the same
    /// times modulo 2³², across several µs wraps and the ms wrap.
    #[test]
    fn matches_an_unwrapped_counter_across_every_wrap() {
        let start_ms: u32 = u32::MAX - 3_000_000; // 50 min before the ms wrap
        let mut clock = MsClock::starting_at(start_ms);
        let start_us: i64 = i64::from(u32::MAX) - 7_000_000; // 7 s before a µs wrap
        let mut t: i64 = start_us;
        let mut wraps = 0;
        let mut prev_ms = None;
        // 4 h in steps of 997 003 µs, so the sub-ms remainder walks through every phase.
        while t < start_us + 4 * 3_600_000_000 {
            let got = clock.ms(t as u32);
            let elapsed_ms = (t - start_us) / 1000;
            let want = (i64::from(start_ms) + elapsed_ms).rem_euclid(1 << 32) as u32;
            assert_eq!(got, want, "t = {t}");
            if let Some(p) = prev_ms {
                if got < p {
                    wraps += 1;
                }
            }
            prev_ms = Some(got);
            t += 997_003;
        }
        assert_eq!(wraps, 1, "the ms value wrapped once");
    }

    #[test]
    fn earlier_times_convert_without_moving_the_clock() {
        let mut c = MsClock::new();
        assert_eq!(c.ms(5_000_500), 5_000);
        assert_eq!(c.ms(4_999_400), 4_999);
        assert_eq!(c.ms(4_000_000), 4_000);
        assert_eq!(c.ms(5_001_499), 5_001);
        // Across the µs wrap backwards.
        let mut c = MsClock::starting_at(10_000);
        c.ms(100);
        assert_eq!(c.ms(u32::MAX - 899), 9_999);
    }

    #[test]
    fn dividing_the_us_clock_is_the_bug_this_fixes() {
        let mut c = MsClock::new();
        let before = u32::MAX - 999_999;
        let after = 1_000;
        assert!((after / 1000) < (before / 1000), "µs/1000 jumps back at the µs wrap");
        let a = c.ms(before);
        assert_eq!(c.ms(after).wrapping_sub(a), 1_001);
    }
}
