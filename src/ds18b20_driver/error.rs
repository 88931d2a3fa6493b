//! Why a DS18B20 operation failed ([`Error`]), and a failed read with the bytes at fault
//! ([`ReadFailure`]).

use core::fmt;

use crate::ds18b20::{self, Resolution};
use crate::onewire;

/// Why a DS18B20 operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// The bus failed: no presence, stuck low, pin error, bad ROM.
    Bus(onewire::Error),
    /// The scratchpad was rejected by the decoder (after the retries).
    Scratchpad(ds18b20::Error),
    /// The ROM's family code is not 28h.
    WrongFamily(u8),
    /// After writing the scratchpad, TH, TL or config read back differently; holds
    /// the config byte read.
    Verify(u8),
    /// The scratchpad holds another resolution than the one set (a brown-out
    /// reloaded the EEPROM); holds the one read.
    ResolutionChanged(Resolution),
    /// `is_ready` or `read` without a conversion started.
    NotStarted,
    /// `read` before `is_ready` returned true.
    NotReady,
    /// The read slot right after Convert T read 1: the sensor is not converting, so the
    /// command was lost (a glitch on the bus, a brown-out between the reset and the
    /// command). Its scratchpad still holds the previous conversion, CRC good, so it is
    /// not read. Only seen with read slots ([`Ds18b20::use_read_slots`](super::Ds18b20::use_read_slots)).
    ConversionNotStarted,
    /// The read slot still reads 0 (converting) [`OVERDUE_MARGIN_PERCENT`](super::OVERDUE_MARGIN_PERCENT) % past the
    /// datasheet maximum: the conversion will not end, and the scratchpad holds the
    /// previous one. Only seen with read slots.
    ConversionOverdue,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Bus(e) => write!(f, "1-Wire: {e}"),
            Self::Scratchpad(e) => write!(f, "scratchpad: {e}"),
            Self::WrongFamily(fc) => write!(f, "family code {fc:02X}h is not a DS18B20"),
            Self::Verify(c) => write!(f, "scratchpad write not verified (config {c:02X}h)"),
            Self::ResolutionChanged(r) => write!(f, "sensor reports {r:?}, not the one set"),
            Self::NotStarted => f.write_str("no conversion started"),
            Self::NotReady => f.write_str("conversion not finished"),
            Self::ConversionNotStarted => f.write_str("Convert T lost: the sensor is not converting"),
            Self::ConversionOverdue => f.write_str("conversion still running past the datasheet maximum"),
        }
    }
}

impl core::error::Error for Error {}

impl From<onewire::Error> for Error {
    fn from(e: onewire::Error) -> Self {
        Self::Bus(e)
    }
}

impl From<ds18b20::Error> for Error {
    fn from(e: ds18b20::Error) -> Self {
        Self::Scratchpad(e)
    }
}

/// A failed [`Ds18b20::read_keeping_bytes`](super::Ds18b20::read_keeping_bytes): the error and, when the bytes were at fault,
/// the bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReadFailure {
    /// The error, as [`Ds18b20::read`](super::Ds18b20::read) returns it.
    pub error: Error,
    /// For [`Error::Scratchpad`], the last scratchpad read, which failed
    /// [`decode_scratchpad`](crate::ds18b20::decode_scratchpad): `Updater::on_scratchpad` rejects these bytes with the
    /// same typed decode error. `None` for every other error (bus, not ready, changed
    /// resolution): nothing usable was read.
    pub scratchpad: Option<[u8; 9]>,
}
