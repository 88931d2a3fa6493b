//! Replays checked-in reference vectors through the compensator and compares bit patterns.
//!
//! no_std and allocation-free so the very same code runs on the host (`host-tests`) and on
//! the Cortex-M4F under QEMU (the root crate's example `examples/qemu_vectors.rs`).
//!
//! # Vector files (`replay/vectors/*.vec`)
//! One event per line; `#` starts a comment. Inputs, then `=>`, then the expected outputs
//! as 8-digit hex u32 words (f32 values as their bit patterns):
//!
//! ```text
//! table <hex bytes>              => <result>
//! raw   <t_ms> <raw i16>         => <result> <status> <T̂> <Ṫ> <K1 ×3> <K0 ×3>
//! sp    <t_ms> <18 hex digits>   => <result> <status> <T̂> <Ṫ> <K1 ×3> <K0 ×3>
//! cycle <dt_ticks> <n0> <n1> <n2> => <status> <Δv0> <Δv1> <Δv2>
//! count <dt_ticks> <c0> <c1> <c2> => <status> <Δv0> <Δv1> <Δv2>     (wrapping u32 counters)
//! samp  <dt_ticks> <r0> <r1> <r2> => <status> <a0> <a1> <a2>        (MEMS samples, m/s²)
//! ```
//! `<result>` is 0 for success or an error code ([`sample_error_code`], [`table_error_code`]).
//! Every file starts from `Compensator::<3, 32>::new(Config::default())`, without a
//! misalignment stage, except those in [`WITH_MATRIX`], which load a table with a matrix and
//! start from `Compensator::<3, 32, 1, Table, 3>`: both fast paths run on every target.
#![no_std]

use qfa_thermal::compensator::{Compensator, Config, SampleError};
use qfa_thermal::ds18b20;
use qfa_thermal::table::{self, MAX_TABLE_BYTES};

/// The checked-in vector files, embedded so the target needs no file system.
pub const FILES: &[(&str, &str)] = &[
    ("kt8_1.vec", include_str!("../vectors/kt8_1.vec")),
    ("kt8_2.vec", include_str!("../vectors/kt8_2.vec")),
    ("kt8_3_misalign.vec", include_str!("../vectors/kt8_3_misalign.vec")),
    ("ext_sensor_lag.vec", include_str!("../vectors/ext_sensor_lag.vec")),
    ("ext_branch_hysteresis.vec", include_str!("../vectors/ext_branch_hysteresis.vec")),
    ("ext_creep.vec", include_str!("../vectors/ext_creep.vec")),
    ("ext_all.vec", include_str!("../vectors/ext_all.vec")),
    ("faults.vec", include_str!("../vectors/faults.vec")),
];

/// The files replayed on a compensator with a misalignment stage (`MATRIX` 3).
pub const WITH_MATRIX: &[&str] = &["kt8_3_misalign.vec"];

/// Most output words on one line.
pub const MAX_WORDS: usize = 12;

/// Why a replay stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Error {
    /// A computed word differs from the recorded one.
    Mismatch {
        /// Vector file name.
        file: &'static str,
        /// 1-based line number.
        line: u32,
        /// Index of the differing word.
        field: u8,
        /// Bits computed now.
        got: u32,
        /// Bits recorded in the file.
        want: u32,
    },
    /// The line could not be parsed (or its expected part has the wrong word count).
    Parse {
        /// Vector file name.
        file: &'static str,
        /// 1-based line number.
        line: u32,
    },
}

/// Kind of event on a line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Table load.
    Table,
    /// Raw reading.
    Raw,
    /// Scratchpad reading.
    Scratchpad,
    /// IMU cycle with signed counts.
    Cycle,
    /// IMU cycle with cumulative counters.
    Counters,
    /// IMU cycle of MEMS samples.
    Samples,
}

/// One replayed line: what was fed and what came out.
#[derive(Clone, Copy, Debug)]
pub struct Step<'a> {
    /// 1-based line number.
    pub line: u32,
    /// Event kind.
    pub kind: Kind,
    /// The input part of the line (before `=>`), trimmed.
    pub input: &'a str,
    /// Computed output words.
    pub computed: &'a [u32],
}

/// Stable code of a sample error in the vectors.
#[must_use]
pub fn sample_error_code(e: SampleError) -> u32 {
    match e {
        SampleError::Decode(d) => match d {
            ds18b20::Error::BusAllOnes => 0x11,
            ds18b20::Error::AllZero => 0x12,
            ds18b20::Error::Crc { .. } => 0x13,
            ds18b20::Error::Reserved => 0x14,
            ds18b20::Error::Config(_) => 0x15,
            ds18b20::Error::PowerOn => 0x16,
            ds18b20::Error::OutOfRange { .. } => 0x17,
            _ => 0x1F,
        },
        SampleError::Time(_) => 0x21,
        SampleError::PowerOnJump => 0x22,
        SampleError::Implausible { .. } => 0x23,
        SampleError::Missed => 0x24,
        _ => 0x2F,
    }
}

/// Stable code of a table error in the vectors.
#[must_use]
pub fn table_error_code(e: table::Error) -> u32 {
    match e {
        table::Error::Truncated => 0x31,
        table::Error::BadMagic => 0x32,
        table::Error::Version(_) => 0x33,
        table::Error::AxisCount { .. } => 0x34,
        table::Error::Crc => 0x35,
        table::Error::Decode => 0x36,
        table::Error::TrailingBytes => 0x37,
        table::Error::NonFinite(_) => 0x38,
        table::Error::OutOfRange(_) => 0x39,
        table::Error::Grid => 0x3A,
        table::Error::ScaleFactorNotPositive => 0x3B,
        table::Error::RateWindow { .. } => 0x3C,
        table::Error::NoInputRecorded => 0x3D,
        table::Error::Input { .. } => 0x3E,
        _ => 0x3F,
    }
}

fn hex_nibble(c: u8) -> Option<u8> {
    match c {
        b'0'..=b'9' => Some(c - b'0'),
        b'a'..=b'f' => Some(c - b'a' + 10),
        b'A'..=b'F' => Some(c - b'A' + 10),
        _ => None,
    }
}

fn hex_bytes<'b>(s: &str, out: &'b mut [u8]) -> Option<&'b [u8]> {
    let b = s.as_bytes();
    if !b.len().is_multiple_of(2) || b.len() / 2 > out.len() {
        return None;
    }
    for (i, pair) in b.chunks_exact(2).enumerate() {
        out[i] = (hex_nibble(pair[0])? << 4) | hex_nibble(pair[1])?;
    }
    Some(&out[..b.len() / 2])
}

fn hex_u32(s: &str) -> Option<u32> {
    u32::from_str_radix(s, 16).ok()
}

fn three<T: core::str::FromStr>(it: &mut core::str::SplitAsciiWhitespace<'_>) -> Option<[T; 3]> {
    let a = it.next()?.parse().ok()?;
    let b = it.next()?.parse().ok()?;
    let c = it.next()?.parse().ok()?;
    Some([a, b, c])
}

type Comp<const MATRIX: usize> = Compensator<3, 32, 1, qfa_thermal::Table, MATRIX>;

fn sample_words<const MATRIX: usize>(
    comp: &Comp<MATRIX>,
    result: Result<(), SampleError>,
    out: &mut heapless::Vec<u32, MAX_WORDS>,
) {
    let status = u32::from(comp.status().bits());
    match result {
        Ok(()) => {
            // A good reading always leaves an estimate; none would be a bug, shown as a
            // word no f32 result can have here (a NaN pattern is never a computed value).
            let Some(est) = comp.estimate() else {
                let _ = out.push(0xFFFF_FFFF);
                return;
            };
            let ev = comp.evaluations();
            let _ = out.push(0);
            let _ = out.push(status);
            let _ = out.push(est.temp_c.to_bits());
            let _ = out.push(est.rate_c_per_min.to_bits());
            for e in ev {
                let _ = out.push(e.k1.to_bits());
            }
            for e in ev {
                let _ = out.push(e.k0.to_bits());
            }
        }
        Err(e) => {
            let _ = out.push(sample_error_code(e));
            let _ = out.push(status);
        }
    }
}

/// Run one line's event; returns its kind and computed words, or `None` if unparsable.
fn step<const MATRIX: usize>(
    comp: &mut Comp<MATRIX>,
    input: &str,
    out: &mut heapless::Vec<u32, MAX_WORDS>,
) -> Option<Kind> {
    let mut it = input.split_ascii_whitespace();
    let kind = it.next()?;
    let kind = match kind {
        "table" => {
            let mut buf = [0u8; MAX_TABLE_BYTES];
            let bytes = hex_bytes(it.next()?, &mut buf)?;
            let r = comp.load_table(bytes);
            let _ = out.push(r.err().map_or(0, table_error_code));
            Kind::Table
        }
        "raw" => {
            let t: u32 = it.next()?.parse().ok()?;
            let raw: i16 = it.next()?.parse().ok()?;
            let r = comp.on_raw(0, t, raw).map(|_| ());
            sample_words(comp, r, out);
            Kind::Raw
        }
        "sp" => {
            let t: u32 = it.next()?.parse().ok()?;
            let mut sp = [0u8; 9];
            let bytes = hex_bytes(it.next()?, &mut sp)?;
            let sp: [u8; 9] = bytes.try_into().ok()?;
            let r = comp.on_scratchpad(0, t, &sp).map(|_| ());
            sample_words(comp, r, out);
            Kind::Scratchpad
        }
        "cycle" | "count" | "samp" => {
            let dt: u32 = it.next()?.parse().ok()?;
            // Δv in m/s from pulses, a in m/s² from samples: recorded alike, as bit patterns.
            let (status, values, k) = match kind {
                "cycle" => {
                    let o = comp.cycle(three::<i32>(&mut it)?, dt);
                    (o.status, o.dv_mps, Kind::Cycle)
                }
                "count" => {
                    let o = comp.cycle_counters(three::<u32>(&mut it)?, dt);
                    (o.status, o.dv_mps, Kind::Counters)
                }
                _ => {
                    let o = comp.cycle_samples(three::<i32>(&mut it)?, dt);
                    (o.status, o.accel_mps2, Kind::Samples)
                }
            };
            let _ = out.push(u32::from(status.bits()));
            for v in values {
                let _ = out.push(v.to_bits());
            }
            k
        }
        _ => return None,
    };
    if it.next().is_some() {
        return None;
    }
    Some(kind)
}

/// Replay `text`. Each event line is run and passed to `visit`; with `check`, the
/// computed words must equal the recorded ones. Returns the number of event lines.
///
/// # Errors
/// The first parse error or (with `check`) mismatch.
pub fn replay(file: &'static str, text: &str, check: bool, visit: &mut dyn FnMut(Step<'_>)) -> Result<usize, Error> {
    if WITH_MATRIX.contains(&file) {
        replay_on::<3>(file, text, check, visit)
    } else {
        replay_on::<0>(file, text, check, visit)
    }
}

fn replay_on<const MATRIX: usize>(
    file: &'static str,
    text: &str,
    check: bool,
    visit: &mut dyn FnMut(Step<'_>),
) -> Result<usize, Error> {
    let Ok(mut comp) = Comp::<MATRIX>::new(Config::default()) else {
        return Err(Error::Parse { file, line: 0 });
    };
    let mut count = 0;
    for (i, raw_line) in text.lines().enumerate() {
        let line = i as u32 + 1;
        let content = raw_line.split('#').next().unwrap_or("").trim();
        if content.is_empty() {
            continue;
        }
        let (input, expected) = match content.split_once("=>") {
            Some((a, b)) => (a.trim(), Some(b.trim())),
            None => (content, None),
        };
        let mut out = heapless::Vec::<u32, MAX_WORDS>::new();
        let kind = step(&mut comp, input, &mut out).ok_or(Error::Parse { file, line })?;
        if check {
            let expected = expected.ok_or(Error::Parse { file, line })?;
            let mut n = 0usize;
            for (field, word) in expected.split_ascii_whitespace().enumerate() {
                let want = hex_u32(word).ok_or(Error::Parse { file, line })?;
                let got = *out.get(field).ok_or(Error::Parse { file, line })?;
                if got != want {
                    return Err(Error::Mismatch { file, line, field: field as u8, got, want });
                }
                n += 1;
            }
            if n != out.len() {
                return Err(Error::Parse { file, line });
            }
        }
        visit(Step { line, kind, input, computed: &out });
        count += 1;
    }
    Ok(count)
}

/// Replay and check every file in [`FILES`]; returns the number of vectors (event lines).
///
/// # Errors
/// The first [`Error`].
pub fn replay_all() -> Result<usize, Error> {
    let mut total = 0;
    for (name, text) in FILES {
        total += replay(name, text, true, &mut |_| {})?;
    }
    Ok(total)
}

/// Former name of [`Error`], kept for callers written against it.
pub type Mismatch = Error;
