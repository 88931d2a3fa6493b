//! The IMU cycle's timing, from two clocks: TIM7's own count and the DWT cycle counter.

/// IMU cycle: TIM7 update at 400 Hz, µs.
pub const PERIOD_US: u32 = 2_500;
/// DWT cycle counter ticks per µs (the 168 MHz core clock).
pub const CYCLES_PER_US: u32 = 168;

/// One TIM7 handler run's timing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cycle {
    /// µs between this run's TIM7 read and the previous run's: the applier's `dt`.
    pub dt_us: u32,
    /// TIM7 update events since the previous run that got no run of their own.
    pub lost: u32,
}

/// The timing of a handler run that read TIM7's count `lat` (µs since its latest update)
/// and the DWT cycle counter, `elapsed_cycles` after the previous run's reads, which gave
/// `last_lat`.
///
/// Between the two TIM7 reads, k whole periods and `lat − last_lat` passed; TIM7 alone
/// cannot tell k (it wraps every period), so the cycle counter, a second clock from the
/// same crystal, gives it to the nearest period: `k = round((elapsed + last_lat − lat) /
/// PERIOD)`. Then `dt = k·PERIOD + lat − last_lat` is exact in TIM7 ticks, and `k − 1`
/// update events were lost (the interrupt was held off, masked or preempted, past the next
/// update, which merged into the pending one). Good while the two clocks agree within half
/// a period (1 250 µs; they share the crystal, and the reads are a few cycles apart) and
/// the handler runs at least every 2³² cycles (25.6 s).
#[must_use]
pub fn timing(lat: u32, last_lat: u32, elapsed_cycles: u32) -> Cycle {
    let elapsed_us = elapsed_cycles / CYCLES_PER_US;
    // Each run follows an update after the previous run's read: k ≥ 1.
    let periods = ((elapsed_us + last_lat).saturating_sub(lat) + PERIOD_US / 2) / PERIOD_US;
    let periods = periods.max(1);
    Cycle { dt_us: (periods * PERIOD_US).wrapping_add(lat).wrapping_sub(last_lat), lost: periods - 1 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use qfa_rng::{seeded, uniform, LabRng};

    /// The hardware, modelled independently: TIM7 updates at every multiple of the period;
    /// each handler run comes some time after the update that triggered it (at most one
    /// pending: an update while still pending is merged into it) and reads TIM7's count,
    /// `t mod PERIOD`, then the 168 MHz cycle counter (wrapping at 2^32, read up to 2 µs
    /// after TIM7). Delays run up to 3.4 periods, so runs are lost in ones, twos and threes.
    #[test]
    fn overrun_a_late_handler_counts_the_lost_cycles_and_keeps_dt_exact() {
        let mut rng = seeded(0x7137);
        let p = u64::from(PERIOD_US);
        // Start near the cycle counter's wrap (every 25.6 s), so it wraps during the run.
        let cyc0 = u64::from(u32::MAX) - 3_000 * 168;
        let read = |t: u64, rng: &mut LabRng| {
            let lat = (t % p) as u32;
            let cyc = (cyc0 + (t * 168) + (uniform(rng) * 2.0 * 168.0) as u64) as u32;
            (lat, cyc)
        };
        let mut t = 1_000u64;
        let (mut last_lat, mut last_cyc) = read(t, &mut rng);
        let (mut lost_true, mut lost_counted, mut late_runs) = (0u64, 0u64, 0u32);
        for i in 0..20_000 {
            // The next update after this run, and how late its run is.
            let next_update = (t / p + 1) * p;
            let delay = match i % 10 {
                0 => (uniform(&mut rng) * 3.4 * p as f64) as u64,
                _ => (uniform(&mut rng) * 40.0) as u64,
            };
            let run = next_update + delay;
            let updates = run / p - t / p;
            lost_true += updates - 1;
            late_runs += u32::from(updates > 1);
            let (lat, cyc) = read(run, &mut rng);
            let c = timing(lat, last_lat, cyc.wrapping_sub(last_cyc));
            assert_eq!(u64::from(c.dt_us), run - t, "run {i}: dt, {updates} updates since the previous run");
            assert_eq!(u64::from(c.lost), updates - 1, "run {i}: lost");
            lost_counted += u64::from(c.lost);
            (t, last_lat, last_cyc) = (run, lat, cyc);
        }
        assert_eq!(lost_counted, lost_true);
        assert!(late_runs > 1_000 && lost_true > 2_000, "{late_runs} late runs, {lost_true} lost");
        assert!(t * 168 > u64::from(u32::MAX), "the cycle counter wrapped");
    }
}
