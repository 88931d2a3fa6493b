//! DS18B20 driver over a [`OneWire`] bus: resolution, conversions and validated reads.
//!
//! A [`Ds18b20`] is a handle for one sensor (by ROM, or the only one on the bus with
//! SKIP ROM); it does not own the bus, so several sensors share one [`OneWire`].
//! Scratchpads are validated and decoded by [`crate::ds18b20::decode_scratchpad`].
//!
//! # Conversion without blocking
//!
//! [`Ds18b20::start`] issues Convert T (44h) and returns; [`Ds18b20::is_ready`] answers
//! from the elapsed time against the datasheet maximum for the resolution, or, after
//! [`Ds18b20::use_read_slots`] found the sensor externally powered, from one read slot
//! (the sensor answers 0 while converting; see [Lost conversions](#lost-conversions));
//! [`Ds18b20::read`] then reads and validates the scratchpad. [`Ds18b20::start_all`] converts every sensor at once with SKIP ROM.
//! Each step blocks only for its own bus transaction:
//!
//! | call | blocks at most (µs, delays only) |
//! |---|---|
//! | `start` | [`START_US`] = 6 630 (the check slot included) |
//! | `is_ready` | one read slot, 70 |
//! | `read` | (retries + 1) × [`READ_ATTEMPT_US`] = (retries + 1) × 11 600 |
//! | `measure` (blocking) | [`Ds18b20::max_blocking_measure_us`]: (retries + 1) × (6 630 + conversion + 70 + 11 600) |
//!
//! At 12 bits with the default 1 retry, `measure` blocks at most 2 × 768 300 µs ≈ 1.54 s.
//! The pin calls add their own latency (a few per slot) on top.
//!
//! # Retries
//!
//! A bad scratchpad read (CRC, all ones, all zero, reserved or config bytes) is re-read
//! up to `retries` times ([`Ds18b20::with_retries`], at most [`MAX_RETRIES`]): the
//! conversion result stays in the scratchpad. The power-on value (a brown-out) is not
//! re-read, since reading again gives the same bytes: `read` returns it and the caller
//! starts a new conversion; `measure` does that itself within its retry budget. Bus
//! errors (no presence, stuck low, pin) are returned at once. A wrong temperature is
//! never returned: every failure is a typed [`Error`].
//!
//! A scratchpad whose resolution differs from the one set ([`Error::ResolutionChanged`])
//! means the sensor lost its configuration (a brown-out reloads it from EEPROM): the
//! conversion time assumed was wrong, so the value may be stale. Call
//! [`Ds18b20::set_resolution`] again.
//!
//! Parasite power needs a strong pull-up during conversions, which an open-drain pin
//! cannot give; [`Ds18b20::read_power_supply`] tells which mode a sensor is in.
//!
//! # Lost conversions
//!
//! A Convert T the sensor never takes (a glitch on the command byte or on MATCH ROM, a
//! brown-out between the reset and the command) leaves the previous conversion in the
//! scratchpad, CRC good: read after the timer, it is a new-looking sample with a fresh
//! timestamp, and a sensor that keeps losing them freezes with a good status. The same
//! holds for a conversion that starts and never ends. Judged by the clock alone, neither
//! can be seen. Judged by the bus, both can: with [`Ds18b20::use_read_slots`] on an
//! externally powered sensor,
//!
//! * the read slot right after Convert T must read 0 (converting); a 1 is
//!   [`Error::ConversionNotStarted`] from [`Ds18b20::start`], and nothing is read;
//! * readiness is the sensor's own read slot, and one still converting
//!   [`OVERDUE_MARGIN_PERCENT`] % past the datasheet maximum is
//!   [`Error::ConversionOverdue`];
//! * [`Ds18b20::measure`] checks both, and starts again within its retry budget.
//!
//! **A parasite-powered sensor cannot be checked**: it does not drive read slots while
//! converting, so `use_read_slots` leaves it on the timer, and a lost conversion is
//! delivered as the previous value. A system that must not run on a frozen temperature
//! refuses such a sensor (the STM32F405 board does: it flags that axis instead). A part
//! that does not answer read slots during a conversion although externally powered
//! (some clones) fails every start with `ConversionNotStarted`: an error, never a stale
//! value.
//!
//! # Feeding the compensator
//!
//! Take the timestamp when the conversion completes, not when it is read:
//! [`Sample::completed_us`] is the start time plus the maximum conversion time
//! (timer), or the time of the read slot that saw the conversion done (read slots).
//! Pass the raw scratchpad, so the compensator applies its own checks (such as a
//! 0550h that arrives as a jump):
//!
//! The compensator's time base is wrapping `u32` milliseconds ([`crate::time`]). Convert
//! the µs timestamp with one [`MsClock`](crate::time::MsClock) for the whole system, never
//! with `completed_us / 1000`, which jumps back to 0 every 71.6 min when the µs clock
//! wraps:
//!
//! ```text
//! let mut clock = MsClock::new();            // one for every sensor
//! let started = now_us();
//! sensor.start(&mut bus, started)?;          // ConversionNotStarted: a missed reading too
//! // ... IMU cycles run; each scheduler tick:
//! let due_ms = clock.ms(started.wrapping_add(resolution.max_conversion_us()));
//! match sensor.is_ready(&mut bus, now_us()) {
//!     Ok(false) => {}
//!     Ok(true) => match sensor.read_keeping_bytes(&mut bus) {
//!         Ok(s) => {
//!             let t_ms = clock.ms(s.completed_us);
//!             let status = updater.on_scratchpad(axis, t_ms, &s.scratchpad);
//!         }
//!         // Every failure reaches the compensator, which raises TEMP_INVALID: the bytes
//!         // that failed decoding (a typed decode error), or a reading that never came.
//!         Err(ReadFailure { scratchpad: Some(sp), .. }) => { updater.on_scratchpad(axis, due_ms, &sp); }
//!         Err(_) => { updater.on_missed_reading(axis, due_ms); }
//!     },
//!     Err(_) => { updater.on_missed_reading(axis, due_ms); }  // bus, ConversionOverdue
//! }
//! ```
//!
//! `updater.on_raw(axis, t_ms, s.reading.raw)` is the path for an already
//! validated reading; both return the compensator's own `Result`. The soak benchmark
//! (`cargo run --release -p host-tests --bin soak -- --hours 1200`) runs the non-blocking
//! recipe across 1 200 simulated hours, past the ms wrap. The STM32F405 board's
//! `poll.rs` is this recipe with a 1 s period, tested on the simulated bus.
//!
//! # Flash
//!
//! The bus and this driver (search, set resolution, read slots, start, is_ready, read,
//! measure, start_all, read ROM) add 8 948 bytes of `.text` for `thumbv7em-none-eabihf`
//! with the release profile (opt-level 3, LTO), 3 500 bytes at opt-level `s`: the
//! difference of `llvm-size` between a minimal cortex-m-rt binary that calls them and
//! the same binary calling only [`decode_scratchpad`] (which is counted with the core).
//! Measured before the lost-conversion checks, `read_keeping_bytes` and the slot lock,
//! not since; the whole STM32F405 image grew by 3 772 bytes with those and the board's
//! own changes.

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{InputPin, OutputPin};
use heapless::Vec;

use crate::ds18b20::{self, decode_scratchpad, Reading, Resolution, FAMILY_CODE};
use crate::onewire::{self, OneWire, Rom, RESET_US, SLOT_MAX_US};

pub use error::{Error, ReadFailure};

mod error;

/// Function command: start a temperature conversion.
pub const CONVERT_T: u8 = 0x44;
/// Function command: read the 9-byte scratchpad.
pub const READ_SCRATCHPAD: u8 = 0xBE;
/// Function command: write TH, TL and config.
pub const WRITE_SCRATCHPAD: u8 = 0x4E;
/// Function command: read the power supply mode (one read slot, 0 = parasite).
pub const READ_POWER_SUPPLY: u8 = 0xB4;

/// Most retries a sensor can be configured with.
pub const MAX_RETRIES: u8 = 8;
/// Retries of a new [`Ds18b20`].
pub const DEFAULT_RETRIES: u8 = 1;

/// Delay bound of selecting a sensor (reset, MATCH ROM + 8 ROM bytes), sending one
/// command byte and, with read slots, the slot that checks the conversion started, in µs.
pub const START_US: u32 = RESET_US + (10 * 8 + 1) * SLOT_MAX_US;
/// With read slots, a conversion still running this far past the datasheet maximum is
/// [`Error::ConversionOverdue`]: 75 ms at 12 bits. The margin covers the caller's clock,
/// which `start` takes before the command's own bus time (up to [`START_US`], 6.6 ms).
pub const OVERDUE_MARGIN_PERCENT: u32 = 10;
/// Delay bound of one scratchpad read (selection, BEh, 9 bytes), in µs.
pub const READ_ATTEMPT_US: u32 = RESET_US + 19 * 8 * SLOT_MAX_US;

/// How a sensor is powered (READ POWER SUPPLY, B4h).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PowerSupply {
    /// V_DD connected.
    External,
    /// Powered from the data line.
    Parasite,
}

/// A validated reading and when its conversion completed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sample {
    /// The scratchpad as read (it passed [`decode_scratchpad`]).
    pub scratchpad: [u8; 9],
    /// The decoded reading.
    pub reading: Reading,
    /// Caller's clock, in µs, when the conversion completed (an upper bound).
    pub completed_us: u32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
enum State {
    Idle,
    Converting { started_us: u32, resets: u32 },
    Done { completed_us: u32 },
}

/// One DS18B20 on a 1-Wire bus.
///
/// A handle holds no bus: pass the [`OneWire`] to each call. Every failure is a typed
/// [`Error`], never a stale temperature. Here the bus has no sensor on it (the line stays
/// pulled up), and the worst case of the blocking [`Ds18b20::measure`] at 12 bits:
///
/// ```
/// use core::convert::Infallible;
/// use embedded_hal::delay::DelayNs;
/// use embedded_hal::digital::{ErrorType, InputPin, OutputPin};
/// use qfa_thermal::ds18b20::Resolution;
/// use qfa_thermal::ds18b20_driver::{Ds18b20, Error};
/// use qfa_thermal::onewire::{self, OneWire};
///
/// /// An open-drain pin with a pull-up and nothing else on the line.
/// struct PulledUp;
/// impl ErrorType for PulledUp { type Error = Infallible; }
/// impl InputPin for PulledUp {
///     fn is_high(&mut self) -> Result<bool, Infallible> { Ok(true) }
///     fn is_low(&mut self) -> Result<bool, Infallible> { Ok(false) }
/// }
/// impl OutputPin for PulledUp {
///     fn set_low(&mut self) -> Result<(), Infallible> { Ok(()) }
///     fn set_high(&mut self) -> Result<(), Infallible> { Ok(()) }
/// }
/// struct NoDelay;
/// impl DelayNs for NoDelay { fn delay_ns(&mut self, _: u32) {} }
///
/// let mut bus = OneWire::new(PulledUp, NoDelay);
/// let mut sensor = Ds18b20::single(); // the only sensor on its pin, SKIP ROM
/// assert_eq!(sensor.start(&mut bus, 0), Err(Error::Bus(onewire::Error::NoPresence)));
/// // A blocking measure at 12 bits with one retry can take 1.54 s: use start / is_ready / read.
/// assert_eq!(Ds18b20::max_blocking_measure_us(Resolution::Bits12, 1), 1_536_600);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Ds18b20 {
    rom: Option<Rom>,
    resolution: Resolution,
    retries: u8,
    read_slots: bool,
    state: State,
}

impl Ds18b20 {
    /// The sensor with `rom`, assumed at 12 bits (the factory setting) until
    /// [`Self::set_resolution`].
    ///
    /// # Errors
    /// [`Error::WrongFamily`] unless the family code is 28h.
    pub const fn new(rom: Rom) -> Result<Self, Error> {
        if rom.family() != FAMILY_CODE {
            return Err(Error::WrongFamily(rom.family()));
        }
        Ok(Self::with_rom(Some(rom)))
    }

    /// The only sensor on the bus, addressed with SKIP ROM.
    #[must_use]
    pub const fn single() -> Self {
        Self::with_rom(None)
    }

    const fn with_rom(rom: Option<Rom>) -> Self {
        Self { rom, resolution: Resolution::Bits12, retries: DEFAULT_RETRIES, read_slots: false, state: State::Idle }
    }

    /// Set how many times a bad scratchpad read is retried (capped at [`MAX_RETRIES`]).
    #[must_use]
    pub const fn with_retries(mut self, retries: u8) -> Self {
        self.retries = if retries > MAX_RETRIES { MAX_RETRIES } else { retries };
        self
    }

    /// Every DS18B20 (family 28h) on the bus, by SEARCH ROM; other families are skipped.
    ///
    /// # Errors
    /// [`Error::Bus`] with the [`OneWire::search`] error.
    pub fn search<P, D, const N: usize>(bus: &mut OneWire<P, D>) -> Result<Vec<Self, N>, Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        let roms = bus.search::<N>(Some(FAMILY_CODE))?;
        let mut sensors = Vec::new();
        for rom in roms {
            // Same capacity as `roms`: never full.
            sensors.push(Self::with_rom(Some(rom))).map_err(|_| onewire::Error::TooManyDevices)?;
        }
        Ok(sensors)
    }

    /// The ROM, or `None` when addressed with SKIP ROM.
    #[must_use]
    pub const fn rom(&self) -> Option<Rom> {
        self.rom
    }

    /// The resolution the driver expects.
    #[must_use]
    pub const fn resolution(&self) -> Resolution {
        self.resolution
    }

    /// Worst-case delay of [`Self::measure`] in µs, from the datasheet conversion time
    /// and the slot timing (with read slots, one more slot before the read), without
    /// pin-call latency.
    #[must_use]
    pub const fn max_blocking_measure_us(resolution: Resolution, retries: u8) -> u32 {
        let retries = if retries > MAX_RETRIES { MAX_RETRIES } else { retries };
        (retries as u32 + 1) * (START_US + resolution.max_conversion_us() + SLOT_MAX_US + READ_ATTEMPT_US)
    }

    fn command<P, D>(&self, bus: &mut OneWire<P, D>, cmd: u8) -> Result<(), Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        bus.select(self.rom.as_ref())?;
        bus.write_byte(cmd)?;
        Ok(())
    }

    /// READ POWER SUPPLY (B4h). With SKIP ROM on a bus of several sensors, `Parasite`
    /// means at least one is.
    ///
    /// # Errors
    /// [`Error::Bus`].
    pub fn read_power_supply<P, D>(&self, bus: &mut OneWire<P, D>) -> Result<PowerSupply, Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        self.command(bus, READ_POWER_SUPPLY)?;
        Ok(if bus.read_bit()? { PowerSupply::External } else { PowerSupply::Parasite })
    }

    /// Read the power supply and, if external, let [`Self::is_ready`] poll read slots
    /// instead of waiting the full conversion time. Parasite sensors do not answer read
    /// slots during a conversion, so they keep the timer.
    ///
    /// # Errors
    /// As [`Self::read_power_supply`].
    pub fn use_read_slots<P, D>(&mut self, bus: &mut OneWire<P, D>) -> Result<PowerSupply, Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        let power = self.read_power_supply(bus)?;
        self.read_slots = power == PowerSupply::External;
        Ok(power)
    }

    /// The 9 scratchpad bytes, unvalidated (one attempt).
    ///
    /// # Errors
    /// [`Error::Bus`].
    pub fn read_scratchpad_raw<P, D>(&self, bus: &mut OneWire<P, D>) -> Result<[u8; 9], Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        self.command(bus, READ_SCRATCHPAD)?;
        let mut sp = [0; 9];
        bus.read_bytes(&mut sp)?;
        Ok(sp)
    }

    /// A good read ends the conversion; a resolution other than the one set means the
    /// sensor lost its configuration, so the value may come from the wrong conversion time.
    fn finish(&mut self, scratchpad: [u8; 9], reading: Reading, completed_us: u32) -> Result<Sample, Error> {
        self.state = State::Idle;
        if reading.resolution != self.resolution {
            return Err(Error::ResolutionChanged(reading.resolution));
        }
        Ok(Sample { scratchpad, reading, completed_us })
    }

    /// Read and decode the scratchpad (one attempt, no retry).
    ///
    /// # Errors
    /// [`Error::Bus`], [`Error::Scratchpad`].
    pub fn read_scratchpad<P, D>(&self, bus: &mut OneWire<P, D>) -> Result<([u8; 9], Reading), Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        let sp = self.read_scratchpad_raw(bus)?;
        Ok((sp, decode_scratchpad(&sp)?))
    }

    /// A scratchpad that passed every check but may hold the power-on temperature,
    /// which is normal before the first conversion. Retried like [`Self::read`].
    fn read_intact<P, D>(&self, bus: &mut OneWire<P, D>) -> Result<[u8; 9], Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        let mut last = Error::NotReady;
        for attempt in 0..=MAX_RETRIES {
            if attempt > self.retries {
                break;
            }
            let sp = self.read_scratchpad_raw(bus)?;
            match decode_scratchpad(&sp) {
                Ok(_) | Err(ds18b20::Error::PowerOn) => return Ok(sp),
                Err(e) => last = e.into(),
            }
        }
        Err(last)
    }

    /// Set the resolution: read the scratchpad to keep TH and TL, write TH, TL and the
    /// config byte (4Eh), read back and compare. The setting lives in the scratchpad
    /// only (not copied to EEPROM), so a brown-out reverts it; see
    /// [`Error::ResolutionChanged`]. Cancels a conversion in progress.
    ///
    /// # Errors
    /// [`Error::Bus`], [`Error::Scratchpad`], [`Error::Verify`].
    pub fn set_resolution<P, D>(&mut self, bus: &mut OneWire<P, D>, resolution: Resolution) -> Result<(), Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        self.state = State::Idle;
        let sp = self.read_intact(bus)?;
        let written = [sp[2], sp[3], resolution.config_byte()];
        self.command(bus, WRITE_SCRATCHPAD)?;
        bus.write_bytes(&written)?;
        let back = self.read_intact(bus)?;
        if back[2..5] != written {
            return Err(Error::Verify(back[4]));
        }
        self.resolution = resolution;
        Ok(())
    }

    /// Start a conversion on this sensor (44h) at `now_us` on the caller's clock.
    ///
    /// # Errors
    /// [`Error::Bus`].
    pub fn start<P, D>(&mut self, bus: &mut OneWire<P, D>, now_us: u32) -> Result<(), Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        self.state = State::Idle;
        self.command(bus, CONVERT_T)?;
        // An externally powered sensor answers 0 while converting; conversions take tens of
        // ms and this slot follows the command within 70 µs, so a 1 means no conversion.
        if self.read_slots && bus.read_bit()? {
            return Err(Error::ConversionNotStarted);
        }
        self.state = State::Converting { started_us: now_us, resets: bus.reset_count() };
        Ok(())
    }

    /// Start a conversion on every sensor at once (SKIP ROM, 44h) and mark each of
    /// `sensors` as converting since `now_us`.
    ///
    /// When every one of `sensors` uses read slots, the slot after the command must read 0:
    /// a 1 means none of them is converting. One lost command among several cannot be
    /// seen here (the others drive the slot to 0); give each sensor its own [`Self::start`]
    /// when that matters.
    ///
    /// # Errors
    /// [`Error::Bus`], [`Error::ConversionNotStarted`] (every sensor left idle).
    pub fn start_all<P, D>(bus: &mut OneWire<P, D>, sensors: &mut [Self], now_us: u32) -> Result<(), Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        for s in sensors.iter_mut() {
            s.state = State::Idle;
        }
        bus.skip_rom()?;
        bus.write_byte(CONVERT_T)?;
        if !sensors.is_empty() && sensors.iter().all(|s| s.read_slots) && bus.read_bit()? {
            return Err(Error::ConversionNotStarted);
        }
        let resets = bus.reset_count();
        for s in sensors.iter_mut() {
            s.state = State::Converting { started_us: now_us, resets };
        }
        Ok(())
    }

    /// Whether the conversion has completed at `now_us` (same clock as `start`,
    /// wrapping; call within 71 minutes of the start).
    ///
    /// With read slots enabled and no bus reset since the start, from one read slot: the
    /// sensor, not the clock, says when it is done (with SKIP ROM the slot reads 1 only
    /// when every sensor is done), and one still converting [`OVERDUE_MARGIN_PERCENT`] %
    /// past the datasheet maximum is an error rather than a read of the previous
    /// conversion. Otherwise from the elapsed time against the datasheet maximum.
    ///
    /// # Errors
    /// [`Error::NotStarted`], [`Error::Bus`], [`Error::ConversionOverdue`] (the
    /// conversion is abandoned).
    pub fn is_ready<P, D>(&mut self, bus: &mut OneWire<P, D>, now_us: u32) -> Result<bool, Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        match self.state {
            State::Idle => Err(Error::NotStarted),
            State::Done { .. } => Ok(true),
            State::Converting { started_us, resets } => {
                let max = self.resolution.max_conversion_us();
                let elapsed = now_us.wrapping_sub(started_us);
                let by_slot = self.read_slots && bus.reset_count() == resets;
                let done = if by_slot { bus.read_bit()? } else { elapsed >= max };
                if !done {
                    if by_slot && elapsed >= max + max / 100 * OVERDUE_MARGIN_PERCENT {
                        self.state = State::Idle;
                        return Err(Error::ConversionOverdue);
                    }
                    return Ok(false);
                }
                // Both are upper bounds of the completion; the datasheet's is the tighter
                // one when the poll comes late.
                let completed_us = if elapsed >= max { started_us.wrapping_add(max) } else { now_us };
                self.state = State::Done { completed_us };
                Ok(true)
            }
        }
    }

    /// Read the completed conversion, re-reading a bad scratchpad up to `retries` times.
    ///
    /// # Errors
    /// [`Error::NotStarted`], [`Error::NotReady`], [`Error::Bus`] (not retried),
    /// [`Error::Scratchpad`] (the last error after the retries; `PowerOn` at once, and
    /// the conversion must be started again), [`Error::ResolutionChanged`].
    pub fn read<P, D>(&mut self, bus: &mut OneWire<P, D>) -> Result<Sample, Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        self.read_keeping_bytes(bus).map_err(|f| f.error)
    }

    /// [`Self::read`], keeping the bytes of a scratchpad that failed decoding, so a caller
    /// can hand every failed read to the compensator: the bytes to
    /// `Updater::on_scratchpad` (a typed decode error), or, with no bytes,
    /// `Updater::on_missed_reading`.
    ///
    /// # Errors
    /// As [`Self::read`], in [`ReadFailure::error`].
    pub fn read_keeping_bytes<P, D>(&mut self, bus: &mut OneWire<P, D>) -> Result<Sample, ReadFailure>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        let fail = |error| ReadFailure { error, scratchpad: None };
        let completed_us = match self.state {
            State::Idle => return Err(fail(Error::NotStarted)),
            State::Converting { .. } => return Err(fail(Error::NotReady)),
            State::Done { completed_us } => completed_us,
        };
        let mut last = fail(Error::NotReady);
        for attempt in 0..=MAX_RETRIES {
            if attempt > self.retries {
                break;
            }
            // A bus error is not retried.
            let sp = self.read_scratchpad_raw(bus).map_err(fail)?;
            match decode_scratchpad(&sp) {
                Ok(reading) => return self.finish(sp, reading, completed_us).map_err(fail),
                Err(e) => {
                    last = ReadFailure { error: e.into(), scratchpad: Some(sp) };
                    if e == ds18b20::Error::PowerOn {
                        self.state = State::Idle;
                        return Err(last);
                    }
                }
            }
        }
        Err(last)
    }

    /// Blocking convenience: start, wait the datasheet conversion time, read. A
    /// power-on value, a lost Convert T or an overdue conversion starts a new conversion,
    /// within the same `retries` budget, so the call blocks at most
    /// [`Self::max_blocking_measure_us`]. `now_us` is the
    /// caller's clock at the call; the sample's `completed_us` adds the bus time.
    ///
    /// # Errors
    /// As [`Self::start`] and [`Self::read`].
    pub fn measure<P, D>(&mut self, bus: &mut OneWire<P, D>, now_us: u32) -> Result<Sample, Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        let bus_t0 = bus.elapsed_us();
        let mut last = Error::NotReady;
        for attempt in 0..=MAX_RETRIES {
            if attempt > self.retries {
                break;
            }
            match self.start(bus, now_us) {
                Ok(()) => {}
                Err(e @ Error::ConversionNotStarted) => {
                    last = e;
                    continue;
                }
                Err(e) => return Err(e),
            }
            bus.delay_us(self.resolution.max_conversion_us());
            let completed_us = now_us.wrapping_add(bus.elapsed_us().wrapping_sub(bus_t0));
            match self.read_converted(bus, completed_us)? {
                Ok(sample) => return Ok(sample),
                Err(e) => last = e,
            }
        }
        self.state = State::Idle;
        Err(last)
    }

    /// [`Self::measure`] for async executors (embassy): the conversion wait, 94–750 ms and
    /// almost all of the call, is awaited on `wait` (`embedded_hal_async::delay::DelayNs`,
    /// e.g. `embassy_time::Delay`) instead of blocking. The bus transactions before and
    /// after it stay blocking on the bus's own delay: 1-Wire slots need 1–15 µs
    /// precision, which an executor's wake-up latency cannot give, and a whole scratchpad
    /// read takes about 6 ms. Same protocol, retries and errors as `measure` (both call
    /// [`Self::start`] and the same read step); `now_us` is the caller's clock at the call.
    ///
    /// # Errors
    /// As [`Self::measure`].
    pub async fn measure_async<P, D, W>(
        &mut self,
        bus: &mut OneWire<P, D>,
        wait: &mut W,
        now_us: u32,
    ) -> Result<Sample, Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
        W: embedded_hal_async::delay::DelayNs,
    {
        let bus_t0 = bus.elapsed_us();
        let mut waited_us = 0u32;
        let mut last = Error::NotReady;
        for attempt in 0..=MAX_RETRIES {
            if attempt > self.retries {
                break;
            }
            match self.start(bus, now_us) {
                Ok(()) => {}
                Err(e @ Error::ConversionNotStarted) => {
                    last = e;
                    continue;
                }
                Err(e) => return Err(e),
            }
            let conversion = self.resolution.max_conversion_us();
            wait.delay_us(conversion).await;
            waited_us = waited_us.wrapping_add(conversion);
            let completed_us = now_us.wrapping_add(bus.elapsed_us().wrapping_sub(bus_t0)).wrapping_add(waited_us);
            match self.read_converted(bus, completed_us)? {
                Ok(sample) => return Ok(sample),
                Err(e) => last = e,
            }
        }
        self.state = State::Idle;
        Err(last)
    }

    /// The read step shared by [`Self::measure`] and [`Self::measure_async`]: the
    /// conversion ended at `completed_us`; `Ok(Ok)` a sample, `Ok(Err)` a scratchpad error
    /// or an overdue conversion, worth a new one, `Err` an error that ends the call (bus,
    /// changed resolution). With read slots the sensor must say it is done (one slot)
    /// before its scratchpad is read: after the full datasheet wait, a 0 is overdue.
    fn read_converted<P, D>(
        &mut self,
        bus: &mut OneWire<P, D>,
        completed_us: u32,
    ) -> Result<Result<Sample, Error>, Error>
    where
        P: InputPin + OutputPin,
        D: DelayNs,
    {
        if self.read_slots && !bus.read_bit()? {
            self.state = State::Idle;
            return Ok(Err(Error::ConversionOverdue));
        }
        self.state = State::Done { completed_us };
        match self.read_scratchpad(bus) {
            Ok((scratchpad, reading)) => self.finish(scratchpad, reading, completed_us).map(Ok),
            Err(e @ Error::Scratchpad(_)) => Ok(Err(e)),
            Err(e) => Err(e),
        }
    }
}
