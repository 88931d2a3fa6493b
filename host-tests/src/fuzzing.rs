//! Fuzz harnesses, shared by the cargo-fuzz targets (`fuzz/`) and by `tests/fuzz_corpus.rs`,
//! which runs the same harnesses over a fixed corpus under `cargo test` (CI has no nightly
//! toolchain for libFuzzer).
//!
//! Each harness panics only when a property is violated, so a fuzzer crash is a bug.

use qfa_thermal::compensator::{Compensator, Config, Status};
use qfa_thermal::ds18b20;
use qfa_thermal::table::Table;

/// Scratchpad decoding: never panics; an accepted reading has masked low bits, a valid
/// config byte, a matching CRC, and is not the power-on pattern.
pub fn scratchpad(data: &[u8]) {
    let Some(sp) = data.get(..9) else { return };
    let sp: [u8; 9] = sp.try_into().expect("9 bytes");
    if let Ok(r) = ds18b20::decode_scratchpad(&sp) {
        assert_eq!(ds18b20::crc8(&sp), 0, "accepted scratchpad has a valid CRC");
        assert_eq!(r.resolution.config_byte(), sp[4]);
        assert_eq!(r.raw & !r.resolution.raw_mask(), 0, "undefined bits masked");
        assert!(!(i16::from_le_bytes([sp[0], sp[1]]) == 0x0550 && sp[6] == 0x0C));
        assert!(r.celsius().is_finite());
    }
}

/// Table decoding: never panics; whatever decodes also validates and re-encodes to the
/// same bytes.
pub fn table(data: &[u8]) {
    if let Ok(t) = Table::decode(data) {
        t.validate().expect("decoded tables are valid");
        let mut buf = [0u8; qfa_thermal::table::MAX_TABLE_BYTES];
        let bytes = t.encode(&mut buf).expect("re-encodes");
        assert_eq!(bytes, data, "decode∘encode is the identity on accepted tables");
    }
}

/// A valid 3-axis table (JB-KT8 #1 with every slot on) for the stream harness.
#[must_use]
pub fn stream_table() -> Vec<u8> {
    use crate::scenarios;
    let e = qfa_thermal::Extensions {
        sensor_lag: Some(scenarios::LAG),
        bias_branch_hysteresis: Some(scenarios::PLAY),
        bias_creep: Some(scenarios::CREEP),
    };
    let t = scenarios::table(0, [e; 3], Some(scenarios::MISALIGN));
    let mut buf = [0u8; qfa_thermal::table::MAX_TABLE_BYTES];
    t.encode(&mut buf).expect("valid").to_vec()
}

/// What the oracle "a rejection changed nothing" compares, taken from a clone (exact: it
/// copies the shared set word for word, so its next cycles are the original's next cycles)
/// so that the original is not advanced.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Probe {
    /// The next output of the pulse entry (scale, bias per tick, misalignment), as bits.
    pulses: [u32; 3],
    /// The next output of the samples entry (scale, bias in m/s², misalignment), as bits.
    samples: [u32; 3],
    /// Its status without the two flags a rejection may raise: TEMP_INVALID, and TEMP_STALE
    /// (the rejected reading's time advances the slow path's clock).
    status: Status,
    /// TEMP_STALE on that output: a rejection may raise it, never clear it (a rejection that
    /// counted as a good sample would restart the fast path's staleness count).
    stale: bool,
    /// The slow path's estimate and evaluations (the rate window, the branch and slot states).
    estimate: Option<qfa_thermal::rate::Estimate>,
    evaluations: [qfa_thermal::model::Evaluation; 3],
}

fn probe(c: &Compensator<3, 32>) -> Probe {
    let mut c2 = c.clone();
    let p = c2.cycle([1000, -1000, 10], 2500);
    let s = c2.cycle_samples([1 << 20, -(1 << 18), 12_345], 2500);
    Probe {
        pulses: p.dv_mps.map(f32::to_bits),
        samples: s.accel_mps2.map(f32::to_bits),
        status: p.status - (Status::TEMP_INVALID | Status::TEMP_STALE),
        stale: p.status.contains(Status::TEMP_STALE),
        estimate: c.estimate(),
        evaluations: *c.evaluations(),
    }
}

/// A rejected reading left everything but the two flags it may raise as it was.
fn assert_unchanged_by_rejection(before: Probe, after: Probe, what: &str) {
    assert_eq!(Probe { stale: before.stale, ..after }, before, "rejected {what} changed the compensation");
    assert!(after.stale || !before.stale, "rejected {what} made a stale compensator fresh");
}

/// A compensator driven by a byte stream of mixed events: readings (raw and scratchpad),
/// time jumps and stalls, cycles, counters, and table loads of mutated bytes.
///
/// Properties: no panic; every output finite; a rejected reading leaves both fast-path
/// entries' next outputs, the estimate, the evaluations and every flag but TEMP_INVALID and
/// TEMP_STALE unchanged, and never clears TEMP_STALE; a rejected table leaves all of that
/// and the status unchanged; a cycle more than `stale_after_ticks` after the last good
/// reading is flagged stale; after a good reading it is not.
pub fn compensator_stream(data: &[u8]) {
    let good_table = stream_table();
    let mut c = Compensator::<3, 32>::new(Config::default()).expect("the default config is valid");
    let stale_after = u64::from(c.config().stale_after_ticks);
    let mut since_good: u64 = u64::from(u32::MAX);
    // A rejection since the last good reading: its time may have shortened the fast path's
    // countdown (the slow path's clock and the ticks are independent here).
    let mut rejected_since_good = false;
    // Good readings since the last cycle: 256 of them alias the published epoch (documented
    // on `Set::epoch`), after which the countdown may only shorten.
    let mut good_since_cycle = 0u32;
    let mut t_ms: u32 = u32::from_le_bytes([data.first().copied().unwrap_or(0), 0, 0, 0x80]);
    let mut raw: i16 = 352;
    let mut bytes = data.iter().copied();
    let mut next = || bytes.next();
    while let Some(op) = next() {
        let arg = next().unwrap_or(0);
        match op % 8 {
            0 | 1 => {
                // A reading: small step, occasionally a spike or the power-on value.
                t_ms = t_ms.wrapping_add(u32::from(arg) * 40);
                raw = match arg % 16 {
                    0 => 0x0550,
                    1 => raw.wrapping_add(400),
                    _ => raw.wrapping_add(i16::from(arg as i8 % 3)),
                };
                let before = probe(&c);
                match c.on_raw(0, t_ms, raw) {
                    Ok(_) => (since_good, rejected_since_good, good_since_cycle) = (0, false, good_since_cycle + 1),
                    Err(_) => {
                        rejected_since_good = true;
                        assert!(c.status().contains(Status::TEMP_INVALID));
                        assert_unchanged_by_rejection(before, probe(&c), "reading");
                    }
                }
            }
            2 => {
                // A scratchpad, possibly corrupted.
                t_ms = t_ms.wrapping_add(1000);
                let mut sp = ds18b20::encode_scratchpad(raw, ds18b20::Resolution::Bits12, 0x0D);
                if arg & 1 == 1 {
                    sp[usize::from(arg >> 1) % 9] ^= 1 << (arg % 8);
                }
                let before = probe(&c);
                match c.on_scratchpad(0, t_ms, &sp) {
                    Ok(_) => (since_good, rejected_since_good, good_since_cycle) = (0, false, good_since_cycle + 1),
                    Err(_) => {
                        rejected_since_good = true;
                        assert_unchanged_by_rejection(before, probe(&c), "scratchpad");
                    }
                }
            }
            3 => t_ms = t_ms.wrapping_sub(u32::from(arg) * 100), // time goes backwards
            4 | 5 => {
                let dt = u32::from(arg) * 20_000 + u32::from(op);
                let p = [i32::from(arg) * 257 - 30_000, -(i32::from(op) << 20), i32::from(arg as i8) << 23];
                let out = c.cycle(p, dt);
                since_good = (since_good + u64::from(dt)).min(u64::from(u32::MAX));
                assert!(out.dv_mps.iter().all(|v| v.is_finite()), "non-finite output {out:?}");
                // Stale whenever either clock says so; stale otherwise only after a rejection,
                // whose time can only have shortened the countdown.
                let must = since_good > stale_after || c.status().contains(Status::TEMP_STALE);
                let stale = out.status.contains(Status::TEMP_STALE);
                assert!(stale || !must, "not stale {since_good} ticks after the last good reading");
                let aliased = good_since_cycle >= 256;
                assert!(
                    !stale || must || rejected_since_good || aliased,
                    "stale {since_good} ticks after a good reading"
                );
                good_since_cycle = 0;
            }
            6 => {
                let cnt = [u32::from(arg) << 24, u32::from(op) << 28, u32::from(arg) * 3];
                let out = c.cycle_counters(cnt, 2500);
                good_since_cycle = 0;
                since_good = (since_good + 2500).min(u64::from(u32::MAX));
                assert!(out.dv_mps.iter().all(|v| v.is_finite()));
            }
            _ => {
                // Load the good table, possibly with one byte mutated.
                let mut t = good_table.clone();
                if arg != 0 {
                    let i = usize::from(arg) * 7 % t.len();
                    t[i] ^= arg;
                }
                let before = probe(&c);
                let was = c.table().cloned();
                if c.load_table(&t).is_err() {
                    assert_eq!(c.table().cloned(), was, "refused table changed the active one");
                    assert_eq!(probe(&c), before, "refused table changed the compensation or the status");
                }
            }
        }
    }
}
