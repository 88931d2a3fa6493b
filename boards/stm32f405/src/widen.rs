//! 16-bit hardware pulse counters widened to the wrapping `u32` cumulative counts that
//! `CountingApplier::cycle` takes.
//!
//! # Why not pass `CNT as u32`
//! `CountingApplier::cycle` forms each cycle's pulses as `counters[i].wrapping_sub(previous[i])`,
//! modulo 2³². A 16-bit counter wraps at 2¹⁶: passed as it is, the step 0xFFF0 → 0x0010
//! (32 pulses) would read as `0x10 − 0xFFF0 = −65 504` pulses. [`Widen16`] instead adds each
//! cycle's 16-bit difference (`now.wrapping_sub(last)`, exact modulo 2¹⁶) to a `u32`
//! total, which then wraps at 2³² exactly as `CountingApplier::cycle` expects.
//!
//! # The one bound
//! The 16-bit difference is exact while fewer than 65 536 pulses arrive between two reads:
//! at the board's 400 Hz IMU cycle, below 26.2 MHz. A QFA's I/F converter at 10 g with
//! K1 ≈ 320 000 pulses/(g·s) gives 3.2 MHz, and the ETR inputs' digital filter (4 samples
//! high, 4 low) passes at most f_CK_INT/8: 10.5 MHz on TIM3/TIM4 (84 MHz), 21 MHz on TIM8
//! (168 MHz). The counts of a cycle whose interrupt was missed altogether (masked for a
//! full 2.5 ms) still come out right at 3.2 MHz: 8 000 pulses per cycle, 8 cycles before
//! 65 536. (That cycle's `dt` covers the missed period too; see `cycle.rs`.)

/// One axis: the last 16-bit counter value seen and the widened total.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Widen16 {
    last: u16,
    total: u32,
}

impl Widen16 {
    /// Start from the counter's current value (the total starts there too).
    #[must_use]
    pub const fn new(first: u16) -> Self {
        Self { last: first, total: first as u32 }
    }

    /// The widened total at counter value `now`.
    #[must_use]
    pub const fn total(&self) -> u32 {
        self.total
    }

    /// Take a new counter value and return the widened total.
    pub fn update(&mut self, now: u16) -> u32 {
        let delta = now.wrapping_sub(self.last);
        self.last = now;
        self.total = self.total.wrapping_add(u32::from(delta));
        self.total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Per-cycle pulses as `CountingApplier::cycle` forms them from two cumulative counts.
    fn pulses(now: u32, prev: u32) -> i32 {
        now.wrapping_sub(prev) as i32
    }

    /// Independent check: a u64 pulse count, truncated to 16 bits as the timer holds it,
    /// widened, and differenced as the applier does, gives back every cycle's true count,
    /// across many 16-bit wraps and the 32-bit wrap of the total.
    #[test]
    fn every_cycle_counts_right_across_both_wraps() {
        let mut true_count: u64 = 0x1234;
        let mut w = Widen16::new(true_count as u16);
        let mut prev = w.total();
        let (mut wraps16, mut wraps32) = (0, 0);
        // 200 000 cycles of 0..=65 535 pulses (a deterministic spread including both ends):
        // about 6.5e9 pulses, so the total wraps at 2^32 at least once.
        for cycle in 0..200_000u64 {
            let n = match cycle % 7 {
                0 => 0,
                1 => 65_535,
                _ => (cycle * 7_919) % 65_536,
            };
            let before = true_count as u16;
            true_count += n;
            if (true_count as u16) < before {
                wraps16 += 1;
            }
            let total = w.update(true_count as u16);
            if total < prev {
                wraps32 += 1;
            }
            assert_eq!(pulses(total, prev), n as i32, "cycle {cycle}");
            assert_eq!(u64::from(total), true_count % (1 << 32), "cycle {cycle}");
            prev = total;
        }
        assert!(wraps16 > 10_000, "the 16-bit counter wrapped {wraps16} times");
        assert!(wraps32 >= 1, "the widened total wrapped at 2^32 {wraps32} times");
    }

    /// The bug this module exists for: the raw 16-bit value passed as a u32 count turns a
    /// 16-bit wrap into a huge negative pulse count.
    #[test]
    fn the_raw_counter_as_u32_is_wrong_at_the_16_bit_wrap() {
        let (before, after) = (0xFFF0_u16, 0x0010_u16);
        assert_eq!(pulses(u32::from(after), u32::from(before)), -65_504);
        let mut w = Widen16::new(before);
        let prev = w.total();
        assert_eq!(pulses(w.update(after), prev), 32);
    }
}
