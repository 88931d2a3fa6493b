//! The status word: one flag per condition in force, on every output.

#[cfg(doc)]
use super::{Compensator, Config};

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
        /// A model state that depends on the unit's thermal history was started without it,
        /// at power-up or by a reload that added or changed its slot, and may still be off
        /// by more than a sixty-fourth of a degree (sensor lag) or 1 µg (play, creep, or the
        /// bias branch before the first decisive rate, where the branches differ by more
        /// than 2 µg): the output is compensated, but not yet to the table's accuracy.
        /// Cleared as the states converge (`model::AxisState::settling`) and at the first
        /// decisive rate.
        const MODEL_SETTLING = 1 << 8;
        /// This cycle's `dt_ticks · tick_s` is more than
        /// [`IMU_PERIOD_TOLERANCE`](super::IMU_PERIOD_TOLERANCE) times off
        /// [`Config::imu_period_s`]: `dt_ticks` is in another unit than [`Config::tick_s`]
        /// (CPU cycles given as 1-µs ticks), or the IMU missed cycles. The bias term `K0·dt`
        /// and the staleness clock are wrong by that factor; the fast path's own flag, set on
        /// that cycle only.
        const DT_IMPLAUSIBLE = 1 << 9;
    }
}

impl Status {
    /// No condition at all: fully compensated from a fresh, calibrated temperature.
    #[must_use]
    pub const fn is_ok(self) -> bool {
        self.is_empty()
    }
}

/// Over defmt a status prints as its flags' names, `OK` when none is set:
/// `Status(RATE_NOT_READY | MODEL_SETTLING)`, not a hex word to look up.
#[cfg(feature = "defmt")]
impl defmt::Format for Status {
    fn format(&self, f: defmt::Formatter<'_>) {
        if self.is_ok() {
            defmt::write!(f, "Status(OK)");
            return;
        }
        defmt::write!(f, "Status(");
        for (i, (name, _)) in self.iter_names().enumerate() {
            if i > 0 {
                defmt::write!(f, " | ");
            }
            defmt::write!(f, "{=str}", name);
        }
        // Bits no flag names (none today) are shown, never dropped.
        let unnamed = self.bits() & !Self::all().bits();
        if unnamed != 0 {
            defmt::write!(f, " | {=u16:#06x}", unnamed);
        }
        defmt::write!(f, ")");
    }
}
