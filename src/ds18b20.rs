//! DS18B20 scratchpad decoding: CRC-8/Maxim, validation and signed temperature.
//!
//! The 9-byte scratchpad is `T_LSB, T_MSB, TH, TL, config, FFh, (byte 6), 10h, CRC`
//! (Maxim DS18B20 datasheet, "Memory map"). The temperature is the signed 16-bit raw
//! value divided by 16 at every resolution; at 11, 10 and 9 bits the undefined low
//! bits (bit 0, bits 1–0, bits 2–0) are masked off. Reading the raw value as unsigned,
//! or dividing by 2/4/8 at lower resolutions, are bugs found in public crates.
//!
//! Checks, in order, each with its own [`Error`]: all-FFh bus, all-zero read (which
//! passes the CRC), CRC mismatch, reserved bytes 5 and 7, config byte, and the
//! power-on value `0550h` with byte 6 = `0Ch` (the Linux `w1_therm` rule). Byte 6
//! varies between parts (real reads show 01h, 0Dh, 0Fh), so it is only used for the
//! power-on rule. Last, the value must lie in −55…+125 °C ([`RAW_RANGE`]).

use core::fmt;

/// CRC-8 Dallas/Maxim (x⁸+x⁵+x⁴+1, reflected 8Ch, init 0) remainders of the 16 nibbles,
/// built at compile time.
const CRC8_NIBBLES: [u8; 16] = {
    let mut t = [0u8; 16];
    let mut n = 0;
    while n < 16 {
        let mut crc = n as u8;
        let mut bit = 0;
        while bit < 4 {
            crc = if crc & 1 == 1 { (crc >> 1) ^ 0x8C } else { crc >> 1 };
            bit += 1;
        }
        t[n] = crc;
        n += 1;
    }
    t
};

/// DS18B20 family code (first ROM byte).
pub const FAMILY_CODE: u8 = 0x28;

/// Raw value the DS18B20 holds after power-on or a brown-out: +85 °C.
pub const POWER_ON_RAW: i16 = 0x0550;

/// Raw values the DS18B20 can report: −55…+125 °C (datasheet, "Operating temperature
/// range"), −880…2 000 in 1/16 °C. Anything else with a good CRC is a clone part or a bus
/// fault, never a temperature.
pub const RAW_RANGE: core::ops::RangeInclusive<i16> = -880..=2_000;

/// CRC-8/Maxim of `bytes`. A message followed by its own CRC gives 0.
#[must_use]
///
/// A nibble at a time from a 16-byte table: 9 bytes a second do not pay for a 256-byte
/// table, and the `crc` crate's table-less variant unrolls to several hundred bytes of
/// Cortex-M4 code. The Maxim application note's check values are asserted in the tests.
pub fn crc8(bytes: &[u8]) -> u8 {
    let mut crc = 0u8;
    for &b in bytes {
        crc = (crc >> 4) ^ CRC8_NIBBLES[usize::from((crc ^ b) & 0xF)];
        crc = (crc >> 4) ^ CRC8_NIBBLES[usize::from((crc ^ (b >> 4)) & 0xF)];
    }
    crc
}

/// Conversion resolution, from the config byte (bits 6–5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Resolution {
    /// 9 bits, 0.5 °C, 93.75 ms max conversion.
    Bits9,
    /// 10 bits, 0.25 °C, 187.5 ms.
    Bits10,
    /// 11 bits, 0.125 °C, 375 ms.
    Bits11,
    /// 12 bits, 0.0625 °C, 750 ms (power-on default).
    Bits12,
}

impl Resolution {
    /// Decode a config byte; only `1Fh`, `3Fh`, `5Fh`, `7Fh` are valid.
    #[must_use]
    pub const fn from_config(config: u8) -> Option<Self> {
        match config {
            0x1F => Some(Self::Bits9),
            0x3F => Some(Self::Bits10),
            0x5F => Some(Self::Bits11),
            0x7F => Some(Self::Bits12),
            _ => None,
        }
    }

    /// The config byte for this resolution.
    #[must_use]
    pub const fn config_byte(self) -> u8 {
        match self {
            Self::Bits9 => 0x1F,
            Self::Bits10 => 0x3F,
            Self::Bits11 => 0x5F,
            Self::Bits12 => 0x7F,
        }
    }

    /// Mask that clears the undefined low bits of the raw value.
    #[must_use]
    pub const fn raw_mask(self) -> i16 {
        match self {
            Self::Bits9 => !0b111,
            Self::Bits10 => !0b11,
            Self::Bits11 => !0b1,
            Self::Bits12 => !0,
        }
    }

    /// Maximum conversion time from the datasheet, in microseconds.
    #[must_use]
    pub const fn max_conversion_us(self) -> u32 {
        match self {
            Self::Bits9 => 93_750,
            Self::Bits10 => 187_500,
            Self::Bits11 => 375_000,
            Self::Bits12 => 750_000,
        }
    }
}

/// Why a scratchpad was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// All nine bytes read FFh: nothing answered on the bus.
    BusAllOnes,
    /// All nine bytes read 00h: passes the CRC but is not a scratchpad (bus held low).
    AllZero,
    /// CRC over bytes 0–7 does not match byte 8.
    Crc {
        /// CRC computed over bytes 0–7.
        computed: u8,
        /// CRC byte that was read.
        read: u8,
    },
    /// Byte 5 is not FFh or byte 7 is not 10h.
    Reserved,
    /// Config byte is not one of 1Fh, 3Fh, 5Fh, 7Fh.
    Config(u8),
    /// Raw 0550h (+85 °C) with byte 6 = 0Ch: the power-on or brown-out value.
    PowerOn,
    /// A value outside −55…+125 °C ([`RAW_RANGE`]), which the sensor cannot report.
    OutOfRange {
        /// The raw value read, 1/16 °C.
        raw: i16,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::BusAllOnes => f.write_str("all bytes FFh: no device answered"),
            Self::AllZero => f.write_str("all bytes 00h: bus held low"),
            Self::Crc { computed, read } => {
                write!(f, "CRC mismatch: computed {computed:02X}h, read {read:02X}h")
            }
            Self::Reserved => f.write_str("reserved bytes are not FFh/10h"),
            Self::Config(c) => write!(f, "config byte {c:02X}h is not 1F/3F/5F/7Fh"),
            Self::PowerOn => f.write_str("power-on value 0550h (+85 °C)"),
            Self::OutOfRange { raw } => write!(f, "raw {raw} is outside -55..125 °C"),
        }
    }
}

impl core::error::Error for Error {}

/// A validated reading.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Reading {
    /// Signed raw temperature in 1/16 °C, undefined low bits masked.
    pub raw: i16,
    /// Resolution from the config byte.
    pub resolution: Resolution,
}

impl Reading {
    /// Temperature in °C (`raw / 16`, exact in f32).
    #[must_use]
    pub fn celsius(self) -> f32 {
        raw_to_celsius(self.raw)
    }
}

/// `raw / 16` in °C. Exact: every i16 divided by 16 is representable in f32.
#[must_use]
pub fn raw_to_celsius(raw: i16) -> f32 {
    f32::from(raw) * 0.0625
}

/// Validate and decode a 9-byte scratchpad.
///
/// # Errors
/// One [`Error`] per failed check, in the order the module docs list.
pub fn decode_scratchpad(sp: &[u8; 9]) -> Result<Reading, Error> {
    if sp.iter().all(|&b| b == 0xFF) {
        return Err(Error::BusAllOnes);
    }
    if sp.iter().all(|&b| b == 0) {
        return Err(Error::AllZero);
    }
    let computed = crc8(&sp[..8]);
    if computed != sp[8] {
        return Err(Error::Crc { computed, read: sp[8] });
    }
    if sp[5] != 0xFF || sp[7] != 0x10 {
        return Err(Error::Reserved);
    }
    let resolution = Resolution::from_config(sp[4]).ok_or(Error::Config(sp[4]))?;
    let unmasked = i16::from_le_bytes([sp[0], sp[1]]);
    if unmasked == POWER_ON_RAW && sp[6] == 0x0C {
        return Err(Error::PowerOn);
    }
    let raw = unmasked & resolution.raw_mask();
    if !RAW_RANGE.contains(&raw) {
        return Err(Error::OutOfRange { raw });
    }
    Ok(Reading { raw, resolution })
}

/// Build a valid scratchpad for `raw` (test and simulation helper; TH/TL as after power-up).
#[must_use]
pub fn encode_scratchpad(raw: i16, resolution: Resolution, byte6: u8) -> [u8; 9] {
    let t = raw.to_le_bytes();
    let mut sp = [t[0], t[1], 0x4B, 0x46, resolution.config_byte(), 0xFF, byte6, 0x10, 0];
    sp[8] = crc8(&sp[..8]);
    sp
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Datasheet Table 1, every row (12-bit).
    const TABLE: [(u16, f32); 10] = [
        (0x07D0, 125.0),
        (0x0550, 85.0),
        (0x0191, 25.0625),
        (0x00A2, 10.125),
        (0x0008, 0.5),
        (0x0000, 0.0),
        (0xFFF8, -0.5),
        (0xFF5E, -10.125),
        (0xFE6F, -25.0625),
        (0xFC90, -55.0),
    ];

    #[test]
    fn datasheet_table_every_row() {
        for (raw, c) in TABLE {
            // byte 6 = 0x0D so the 85 °C row is not the power-on pattern.
            let sp = encode_scratchpad(raw as i16, Resolution::Bits12, 0x0D);
            let r = decode_scratchpad(&sp).unwrap();
            assert_eq!(r.celsius(), c, "raw {raw:04X}");
        }
    }

    #[test]
    fn crc_vectors_from_reference() {
        let v: [(&[u8], u8); 5] = [
            (&[0x02, 0x1C, 0xB8, 0x01, 0x00, 0x00, 0x00], 0xA2),
            (b"123456789", 0xA1),
            (&[0x63, 0x01, 0x4B, 0x46, 0x7F, 0xFF, 0x0D, 0x10], 0x15),
            (&[0x61, 0x01, 0x4B, 0x46, 0x7F, 0xFF, 0x0F, 0x10], 0x02),
            (&[0x5F, 0x01, 0x4B, 0x46, 0x7F, 0xFF, 0x01, 0x10], 0x9B),
        ];
        for (bytes, crc) in v {
            assert_eq!(crc8(bytes), crc, "{bytes:02X?}");
            let mut with = [0u8; 16];
            with[..bytes.len()].copy_from_slice(bytes);
            with[bytes.len()] = crc;
            assert_eq!(crc8(&with[..=bytes.len()]), 0, "message + own CRC gives 0");
        }
    }

    #[test]
    fn real_power_up_scratchpad_is_power_on_error() {
        let sp = [0x50, 0x05, 0x4B, 0x46, 0x7F, 0xFF, 0x0C, 0x10, 0x1C];
        assert_eq!(decode_scratchpad(&sp), Err(Error::PowerOn));
    }

    #[test]
    fn real_reads_decode() {
        let sp = [0x63, 0x01, 0x4B, 0x46, 0x7F, 0xFF, 0x0D, 0x10, 0x15];
        assert_eq!(decode_scratchpad(&sp).unwrap().celsius(), 22.1875);
        let sp = [0x5F, 0x01, 0x4B, 0x46, 0x7F, 0xFF, 0x01, 0x10, 0x9B];
        assert_eq!(decode_scratchpad(&sp).unwrap().celsius(), 21.9375);
    }

    #[test]
    fn bus_faults() {
        assert_eq!(decode_scratchpad(&[0xFF; 9]), Err(Error::BusAllOnes));
        assert_eq!(crc8(&[0u8; 8]), 0, "nine zero bytes pass the CRC");
        assert_eq!(decode_scratchpad(&[0; 9]), Err(Error::AllZero));
        let mut sp = encode_scratchpad(0x0191, Resolution::Bits12, 0x0F);
        sp[0] ^= 0x04;
        assert!(matches!(decode_scratchpad(&sp), Err(Error::Crc { .. })));
    }

    #[test]
    fn reserved_and_config_checked() {
        let mut sp = encode_scratchpad(0x0191, Resolution::Bits12, 0x0F);
        sp[7] = 0x11;
        sp[8] = crc8(&sp[..8]);
        assert_eq!(decode_scratchpad(&sp), Err(Error::Reserved));
        let mut sp = encode_scratchpad(0x0191, Resolution::Bits12, 0x0F);
        sp[4] = 0x7E;
        sp[8] = crc8(&sp[..8]);
        assert_eq!(decode_scratchpad(&sp), Err(Error::Config(0x7E)));
    }

    #[test]
    fn low_resolution_is_signed_and_masked() {
        // -10.125 °C = FF5Eh; at 9 bits the undefined bits 2-0 read as garbage.
        let cases = [
            (Resolution::Bits9, 0xFF5Fu16, -10.5f32),
            (Resolution::Bits10, 0xFF5F, -10.25),
            (Resolution::Bits11, 0xFF5F, -10.125),
            (Resolution::Bits12, 0xFF5F, -10.0625),
            (Resolution::Bits9, 0x0197, 25.0),
            (Resolution::Bits10, 0x0197, 25.25),
        ];
        for (res, raw, c) in cases {
            let sp = encode_scratchpad(raw as i16, res, 0x0F);
            assert_eq!(decode_scratchpad(&sp).unwrap().celsius(), c, "{res:?} {raw:04X}");
        }
    }

    #[test]
    fn real_85_is_accepted_when_byte6_differs() {
        let sp = encode_scratchpad(POWER_ON_RAW, Resolution::Bits12, 0x10);
        assert_eq!(decode_scratchpad(&sp).unwrap().celsius(), 85.0);
    }
}
