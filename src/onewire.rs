//! 1-Wire bus master, bit-banged on one open-drain pin with embedded-hal 1.0.
//!
//! The pin is a single open-drain GPIO with an external pull-up (4.7 kΩ typical):
//! `set_low` drives the line low, `set_high` releases it, and `is_high`/`is_low` read
//! the line. Delays come from [`DelayNs`]. Timing is standard speed, from the Maxim
//! DS18B20 datasheet ("1-Wire Signaling") with the slot split of Maxim application
//! note 126; each constant states the datasheet limit it meets, and the limits are
//! checked at compile time.
//!
//! Every slot lasts at most [`SLOT_MAX_US`] and a reset at most [`RESET_US`] of delay,
//! plus the pin calls themselves. No function loops without a compile-time bound:
//! byte transfers are 8 slots, a ROM is 64 bits, and [`OneWire::search`] makes at most
//! [`SEARCH_MAX_PASSES`] passes.
//!
//! # Interrupts
//!
//! An interrupt between a slot's falling edge and its sample stretches the slot: a read
//! slot samples 10 µs after the edge and the device's data is valid only until 15 µs, so
//! a handler of more than about 5 µs there reads a 0 as 1; a write-1 held low past 15 µs
//! is written as 0. [`OneWire::with_slot_lock`] runs the timing-critical part of each such
//! slot inside a lock the caller gives (a critical section, say): for a read slot, pull
//! low, 2 µs, release, 8 µs, sample (10 µs of delay and three pin calls); for a write-1
//! slot, pull low, 6 µs, release (6 µs and two pin calls). An interrupt that comes during
//! that part waits at most that long, then runs. The rest is left open to interrupts, as
//! it tolerates them: a write-0 is judged by a low time of 60–120 µs (written with 60),
//! and the slots' recovery times are minimums. The reset's presence sample (70 µs after
//! release, in a window that ends at 75 µs for the slowest conforming device) is not
//! locked either, since that would mask interrupts for 70 µs: a longer interrupt there
//! gives [`Error::NoPresence`], a typed error, never a wrong bit.
//!
//! A ROM is accepted only with a matching CRC-8 (shared with the scratchpad decoder,
//! [`crate::ds18b20::crc8`]) and not all zero (eight 00h bytes pass the CRC, and are
//! what a bus held low reads).

use core::fmt;

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{InputPin, OutputPin};
use heapless::Vec;

use crate::ds18b20::crc8;

/// Reset pulse, master drives low. Datasheet t_RSTL ≥ 480 µs.
pub const RESET_LOW_US: u32 = 480;
/// From releasing the reset pulse to sampling presence. The device waits 15–60 µs
/// (t_PDHIGH) and then holds low 60–240 µs (t_PDLOW): at 70 µs the line is low for
/// every conforming device (latest start 60 µs, earliest end 75 µs).
pub const PRESENCE_SAMPLE_US: u32 = 70;
/// Rest of the presence window after sampling. Datasheet t_RSTH ≥ 480 µs in total,
/// so 70 + 410 = 480 µs; the presence pulse ends by 60 + 240 = 300 µs.
pub const RESET_RECOVERY_US: u32 = 410;
/// Write-1 slot, master low time. Datasheet t_LOW1 1–15 µs.
pub const WRITE_1_LOW_US: u32 = 6;
/// Write-1 slot, released time to the end of the slot and recovery. Datasheet slot
/// t_SLOT 60–120 µs plus t_REC ≥ 1 µs.
pub const WRITE_1_RELEASE_US: u32 = 64;
/// Write-0 slot, master low time. Datasheet t_LOW0 60–120 µs.
pub const WRITE_0_LOW_US: u32 = 60;
/// Write-0 slot, recovery after release. Datasheet t_REC ≥ 1 µs.
pub const WRITE_0_RECOVERY_US: u32 = 10;
/// Read slot, master low time that starts the slot. Datasheet t_INIT ≥ 1 µs.
pub const READ_LOW_US: u32 = 2;
/// Read slot, from release to sampling. The device's data is valid only until 15 µs
/// (t_RDV) after the falling edge: sampling at 2 + 8 = 10 µs leaves 5 µs for the
/// pin-call latency.
pub const READ_SAMPLE_US: u32 = 8;
/// Read slot, from sampling to the end of the slot and recovery (t_SLOT ≥ 60 µs, t_REC ≥ 1 µs).
pub const READ_RELEASE_US: u32 = 55;
/// Upper bound of the delay in any one slot (read or write), in µs.
pub const SLOT_MAX_US: u32 = 70;
/// Delay of one reset and presence detection, in µs.
pub const RESET_US: u32 = RESET_LOW_US + PRESENCE_SAMPLE_US + RESET_RECOVERY_US;
/// Most passes [`OneWire::search`] makes: one device is found per pass.
pub const SEARCH_MAX_PASSES: usize = 64;

// The datasheet limits, checked at compile time.
const _: () = {
    assert!(RESET_LOW_US >= 480);
    assert!(PRESENCE_SAMPLE_US > 60 && PRESENCE_SAMPLE_US < 75);
    assert!(PRESENCE_SAMPLE_US + RESET_RECOVERY_US >= 480);
    assert!(WRITE_1_LOW_US >= 1 && WRITE_1_LOW_US <= 15);
    assert!(WRITE_1_LOW_US + WRITE_1_RELEASE_US >= 61);
    assert!(WRITE_0_LOW_US >= 60 && WRITE_0_LOW_US <= 120);
    assert!(WRITE_0_RECOVERY_US >= 1);
    assert!(READ_LOW_US >= 1 && READ_LOW_US + READ_SAMPLE_US < 15);
    assert!(READ_LOW_US + READ_SAMPLE_US + READ_RELEASE_US >= 61);
    assert!(WRITE_1_LOW_US + WRITE_1_RELEASE_US <= SLOT_MAX_US);
    assert!(WRITE_0_LOW_US + WRITE_0_RECOVERY_US <= SLOT_MAX_US);
    assert!(READ_LOW_US + READ_SAMPLE_US + READ_RELEASE_US <= SLOT_MAX_US);
};

/// ROM command: read the ROM of the only device on the bus.
pub const READ_ROM: u8 = 0x33;
/// ROM command: address one device by its ROM.
pub const MATCH_ROM: u8 = 0x55;
/// ROM command: address every device.
pub const SKIP_ROM: u8 = 0xCC;
/// ROM command: enumerate the devices (binary tree search).
pub const SEARCH_ROM: u8 = 0xF0;

/// Why a bus operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// No device answered the reset pulse with a presence pulse.
    NoPresence,
    /// The line read low while released (before the reset pulse or after the
    /// presence window): shorted, or a device is stuck.
    BusStuckLow,
    /// The pin driver returned an error.
    Pin,
    /// A ROM failed its CRC-8.
    RomCrc {
        /// CRC computed over bytes 0–6.
        computed: u8,
        /// CRC byte that was read.
        read: u8,
    },
    /// A ROM read as eight 00h bytes (passes the CRC, but is a bus held low).
    RomAllZero,
    /// A ROM has another family code than the one required.
    WrongFamily(u8),
    /// During SEARCH ROM, no device answered a bit (both the bit and its complement
    /// read 1): a device left the bus or a slot was corrupted.
    SearchNoResponse,
    /// SEARCH ROM found more devices than the result can hold or than
    /// [`SEARCH_MAX_PASSES`].
    TooManyDevices,
    /// SEARCH ROM answers changed between passes (a branch taken before vanished, or
    /// a ROM was found twice): a slot was corrupted.
    SearchInconsistent,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoPresence => f.write_str("no presence pulse"),
            Self::BusStuckLow => f.write_str("1-Wire bus stuck low"),
            Self::Pin => f.write_str("pin error"),
            Self::RomCrc { computed, read } => {
                write!(f, "ROM CRC mismatch: computed {computed:02X}h, read {read:02X}h")
            }
            Self::RomAllZero => f.write_str("ROM reads all zero"),
            Self::WrongFamily(fc) => write!(f, "wrong family code {fc:02X}h"),
            Self::SearchNoResponse => f.write_str("no device answered during SEARCH ROM"),
            Self::TooManyDevices => f.write_str("more devices than the search result holds"),
            Self::SearchInconsistent => f.write_str("SEARCH ROM answers changed between passes"),
        }
    }
}

impl core::error::Error for Error {}

/// A 64-bit ROM code, `family, serial[6], CRC`, whose CRC has been checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Rom([u8; 8]);

impl Rom {
    /// Check a ROM read from the bus (byte 0 first, as sent).
    ///
    /// # Errors
    /// [`Error::RomAllZero`] for eight 00h bytes, [`Error::RomCrc`] on a CRC mismatch.
    pub fn from_bytes(bytes: [u8; 8]) -> Result<Self, Error> {
        if bytes == [0; 8] {
            return Err(Error::RomAllZero);
        }
        let computed = crc8(&bytes[..7]);
        if computed != bytes[7] {
            return Err(Error::RomCrc { computed, read: bytes[7] });
        }
        Ok(Self(bytes))
    }

    /// The eight bytes, in bus order.
    #[must_use]
    pub const fn bytes(&self) -> [u8; 8] {
        self.0
    }

    /// Family code (byte 0); 28h for a DS18B20.
    #[must_use]
    pub const fn family(&self) -> u8 {
        self.0[0]
    }

    /// This ROM if its family code is `family`.
    ///
    /// # Errors
    /// [`Error::WrongFamily`] with the family code read.
    pub const fn require_family(self, family: u8) -> Result<Self, Error> {
        if self.0[0] == family {
            Ok(self)
        } else {
            Err(Error::WrongFamily(self.0[0]))
        }
    }
}

impl fmt::Display for Rom {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for b in self.0 {
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}

/// Runs the timing-critical part of a slot, `f`, exactly once, with interrupts held off
/// (see [`OneWire::with_slot_lock`]); e.g. `|f| critical_section::with(|_| f())`.
pub type SlotLock = fn(&mut dyn FnMut());

/// A 1-Wire bus master on one open-drain pin.
#[derive(Debug)]
pub struct OneWire<P, D> {
    pin: P,
    delay: D,
    resets: u32,
    elapsed_us: u32,
    lock: Option<SlotLock>,
}

impl<P, D> OneWire<P, D>
where
    P: InputPin + OutputPin,
    D: DelayNs,
{
    /// A bus on `pin` (open drain, externally pulled up). Does no I/O.
    pub const fn new(pin: P, delay: D) -> Self {
        Self { pin, delay, resets: 0, elapsed_us: 0, lock: None }
    }

    /// Run the timing-critical part of every read slot and write-1 slot inside `lock`, so
    /// an interrupt cannot stretch it (see [Interrupts](self#interrupts)): at most 10 µs
    /// of delay and three pin calls per slot. `lock` must call its argument once; one that
    /// does not is bypassed (the part then runs unlocked).
    #[must_use]
    pub const fn with_slot_lock(mut self, lock: SlotLock) -> Self {
        self.lock = Some(lock);
        self
    }

    /// Give back the pin and the delay.
    pub fn free(self) -> (P, D) {
        (self.pin, self.delay)
    }

    /// Number of successful resets so far (wrapping). A device state that lives
    /// until the next reset, such as conversion polling, compares this.
    #[must_use]
    pub const fn reset_count(&self) -> u32 {
        self.resets
    }

    /// Sum of every delay this bus has issued, in µs (wrapping): the nominal bus
    /// time, without the pin-call latency.
    #[must_use]
    pub const fn elapsed_us(&self) -> u32 {
        self.elapsed_us
    }

    /// Wait `us` with the bus released, counted in [`Self::elapsed_us`].
    pub fn delay_us(&mut self, us: u32) {
        self.delay.delay_us(us);
        self.elapsed_us = self.elapsed_us.wrapping_add(us);
    }

    fn low(&mut self) -> Result<(), Error> {
        self.pin.set_low().map_err(|_| Error::Pin)
    }

    fn release(&mut self) -> Result<(), Error> {
        self.pin.set_high().map_err(|_| Error::Pin)
    }

    fn line_is_low(&mut self) -> Result<bool, Error> {
        self.pin.is_low().map_err(|_| Error::Pin)
    }

    /// Run `part` inside the slot lock, if there is one.
    fn locked(&mut self, part: fn(&mut Self) -> Result<bool, Error>) -> Result<bool, Error> {
        let Some(lock) = self.lock else {
            return part(self);
        };
        let mut out = None;
        lock(&mut || out = Some(part(self)));
        match out {
            Some(r) => r,
            // A lock that did not call its argument: run the part rather than skip the slot.
            None => part(self),
        }
    }

    /// Reset pulse and presence detection.
    ///
    /// # Errors
    /// [`Error::BusStuckLow`] if the released line reads low before the pulse or at
    /// the end of the presence window, [`Error::NoPresence`], [`Error::Pin`].
    pub fn reset(&mut self) -> Result<(), Error> {
        self.release()?;
        if self.line_is_low()? {
            return Err(Error::BusStuckLow);
        }
        self.low()?;
        self.delay_us(RESET_LOW_US);
        self.release()?;
        self.delay_us(PRESENCE_SAMPLE_US);
        let presence = self.line_is_low()?;
        self.delay_us(RESET_RECOVERY_US);
        if self.line_is_low()? {
            return Err(Error::BusStuckLow);
        }
        if !presence {
            return Err(Error::NoPresence);
        }
        self.resets = self.resets.wrapping_add(1);
        Ok(())
    }

    /// Write one bit (one write slot).
    ///
    /// # Errors
    /// [`Error::Pin`].
    pub fn write_bit(&mut self, bit: bool) -> Result<(), Error> {
        if bit {
            // A 1 is a low time of at most 15 µs: locked.
            self.locked(|bus| {
                bus.low()?;
                bus.delay_us(WRITE_1_LOW_US);
                bus.release()?;
                Ok(true)
            })?;
            self.delay_us(WRITE_1_RELEASE_US);
        } else {
            // A 0 is a low time of 60–120 µs, written with 60: an interrupt stretching it
            // by up to 60 µs still writes 0, so it is not locked.
            self.low()?;
            self.delay_us(WRITE_0_LOW_US);
            self.release()?;
            self.delay_us(WRITE_0_RECOVERY_US);
        }
        Ok(())
    }

    /// Read one bit (one read slot).
    ///
    /// # Errors
    /// [`Error::Pin`].
    pub fn read_bit(&mut self) -> Result<bool, Error> {
        // The sample must fall within 15 µs of the falling edge: locked.
        let bit = self.locked(|bus| {
            bus.low()?;
            bus.delay_us(READ_LOW_US);
            bus.release()?;
            bus.delay_us(READ_SAMPLE_US);
            Ok(!bus.line_is_low()?)
        })?;
        self.delay_us(READ_RELEASE_US);
        Ok(bit)
    }

    /// Write one byte, least significant bit first.
    ///
    /// # Errors
    /// [`Error::Pin`].
    pub fn write_byte(&mut self, byte: u8) -> Result<(), Error> {
        for i in 0..8 {
            self.write_bit(byte & (1 << i) != 0)?;
        }
        Ok(())
    }

    /// Read one byte, least significant bit first.
    ///
    /// # Errors
    /// [`Error::Pin`].
    pub fn read_byte(&mut self) -> Result<u8, Error> {
        let mut byte = 0;
        for i in 0..8 {
            if self.read_bit()? {
                byte |= 1 << i;
            }
        }
        Ok(byte)
    }

    /// Write `bytes` in order.
    ///
    /// # Errors
    /// [`Error::Pin`].
    pub fn write_bytes(&mut self, bytes: &[u8]) -> Result<(), Error> {
        for &b in bytes {
            self.write_byte(b)?;
        }
        Ok(())
    }

    /// Fill `buf` with bytes read in order.
    ///
    /// # Errors
    /// [`Error::Pin`].
    pub fn read_bytes(&mut self, buf: &mut [u8]) -> Result<(), Error> {
        for b in buf {
            *b = self.read_byte()?;
        }
        Ok(())
    }

    /// Reset, READ ROM (33h) and check the ROM. Only valid with one device on the
    /// bus: with several, the wired-AND of their ROMs fails the CRC.
    ///
    /// # Errors
    /// Reset errors, [`Error::RomCrc`], [`Error::RomAllZero`], [`Error::Pin`].
    pub fn read_rom(&mut self) -> Result<Rom, Error> {
        self.reset()?;
        self.write_byte(READ_ROM)?;
        let mut bytes = [0; 8];
        self.read_bytes(&mut bytes)?;
        Rom::from_bytes(bytes)
    }

    /// Reset and MATCH ROM (55h): the next function command goes to `rom` only.
    ///
    /// # Errors
    /// Reset errors, [`Error::Pin`].
    pub fn match_rom(&mut self, rom: &Rom) -> Result<(), Error> {
        self.reset()?;
        self.write_byte(MATCH_ROM)?;
        self.write_bytes(&rom.0)
    }

    /// Reset and SKIP ROM (CCh): the next function command goes to every device.
    ///
    /// # Errors
    /// Reset errors, [`Error::Pin`].
    pub fn skip_rom(&mut self) -> Result<(), Error> {
        self.reset()?;
        self.write_byte(SKIP_ROM)
    }

    /// [`Self::match_rom`] for `Some`, [`Self::skip_rom`] for `None`.
    ///
    /// # Errors
    /// As those.
    pub fn select(&mut self, rom: Option<&Rom>) -> Result<(), Error> {
        match rom {
            Some(rom) => self.match_rom(rom),
            None => self.skip_rom(),
        }
    }

    /// SEARCH ROM (F0h): every device on the bus, in ascending ROM bit order, keeping
    /// those whose family code is `family` (all when `None`). Each ROM's CRC is checked.
    ///
    /// Makes at most [`SEARCH_MAX_PASSES`] passes of one reset and 64 × 3 slots.
    ///
    /// # Errors
    /// Reset errors (an empty bus gives [`Error::NoPresence`]),
    /// [`Error::SearchNoResponse`], [`Error::SearchInconsistent`], [`Error::RomCrc`], [`Error::RomAllZero`],
    /// [`Error::TooManyDevices`], [`Error::Pin`].
    pub fn search<const N: usize>(&mut self, family: Option<u8>) -> Result<Vec<Rom, N>, Error> {
        let mut found = Vec::new();
        let mut rom = [0u8; 8];
        // 1-based bit position of the last branch where 0 was taken; 0 = none left.
        let mut last_discrepancy = 0usize;
        for _ in 0..SEARCH_MAX_PASSES {
            self.reset()?;
            self.write_byte(SEARCH_ROM)?;
            let mut last_zero = 0usize;
            for pos in 1..=64usize {
                let (byte, mask) = ((pos - 1) / 8, 1u8 << ((pos - 1) % 8));
                let id = self.read_bit()?;
                let complement = self.read_bit()?;
                let dir = match (id, complement) {
                    (true, true) => return Err(Error::SearchNoResponse),
                    // This pass must take the 1 branch of the last discrepancy.
                    _ if pos == last_discrepancy && (id || complement) => return Err(Error::SearchInconsistent),
                    (false, false) => {
                        let dir = if pos < last_discrepancy { rom[byte] & mask != 0 } else { pos == last_discrepancy };
                        if !dir {
                            last_zero = pos;
                        }
                        dir
                    }
                    (id, _) => id,
                };
                if dir {
                    rom[byte] |= mask;
                } else {
                    rom[byte] &= !mask;
                }
                self.write_bit(dir)?;
            }
            let rom = Rom::from_bytes(rom)?;
            if found.contains(&rom) {
                return Err(Error::SearchInconsistent);
            }
            if family.is_none_or(|fc| fc == rom.family()) {
                found.push(rom).map_err(|_| Error::TooManyDevices)?;
            }
            last_discrepancy = last_zero;
            if last_discrepancy == 0 {
                return Ok(found);
            }
        }
        Err(Error::TooManyDevices)
    }
}
