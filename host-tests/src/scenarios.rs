//! Inputs of the reference vectors: the three JB-KT8 units, every extension slot, faults.
//!
//! Each scenario is a list of event lines (the part before `=>`); `record` replays them
//! through the compensator and writes the outputs next to them.

use qfa_rng::{seeded, uniform, LabRng};
use qfa_thermal::ds18b20::{encode_scratchpad, Resolution};
use qfa_thermal::fixtures::JB_KT8;
use qfa_thermal::model::{AxisModel, BiasGrid, BranchHysteresis, Creep, Extensions, ScaleFactor, SensorLag};
use qfa_thermal::table::{crc32, Table, HEADER_LEN, MAX_TABLE_BYTES};

/// Eq. 11 coefficients of JB-KT8 #`unit + 1` (the paper's Eq. 15–17, from
/// [`qfa_thermal::fixtures::JB_KT8`]), T0 = 22 °C, γ scaled by `gamma_scale` to tell axes apart.
#[must_use]
pub fn unit_scale(unit: usize, gamma_scale: f32) -> ScaleFactor {
    let s = JB_KT8[unit];
    ScaleFactor { gamma: s.gamma * gamma_scale, ..s }
}

/// Bias grid −60..70 °C by 10 °C: K0 = b0 + b1·ΔT + b2·ΔT², heating +split, cooling −split.
#[must_use]
pub fn bias_grid(b0: f32, b1: f32, b2: f32, split: f32) -> BiasGrid {
    let pts: Vec<f32> = (0..14)
        .map(|i| {
            let d = -82.0 + 10.0 * i as f32;
            b0 + b1 * d + b2 * d * d
        })
        .collect();
    let mut g = BiasGrid::single_valued(-60.0, 10.0, &pts).expect("2 to 16 grid values");
    for (h, c) in g.heating_g.iter_mut().zip(g.cooling_g.iter_mut()) {
        *h += split;
        *c -= split;
    }
    g
}

/// A 3-axis table of one unit with per-axis extensions.
#[must_use]
pub fn table(unit: usize, ext: [Extensions; 3], misalignment: Option<[f32; 9]>) -> Table {
    let mut axes = heapless::Vec::new();
    for (i, e) in ext.into_iter().enumerate() {
        let a = AxisModel {
            scale: unit_scale(unit, 1.0 + 0.002 * i as f32),
            bias: bias_grid(1.2e-4 - 4e-5 * i as f32, 8e-6, 2e-8, 1.5e-5),
            rate_limit_c_per_min: 2.0,
            ext: e,
        };
        axes.push(a).expect("3 axes fit");
    }
    Table { input: qfa_thermal::Input::PulseCounts, rate_window: 32, axes, misalignment, part_lsb_per_g: None }
}

/// The part sensitivity the harnesses' samples entries are read at, LSB per g: the QFA
/// tables' own K1 (about 320 000 per g), taken as a MEMS part's.
pub const SAMPLE_PART_LSB_PER_G: f32 = 320_000.0;

/// The configuration the harnesses' samples entries use: `Input::Samples` at
/// [`SAMPLE_PART_LSB_PER_G`].
#[must_use]
pub fn samples_config(base: qfa_thermal::Config) -> qfa_thermal::Config {
    qfa_thermal::Config { input: qfa_thermal::Input::Samples, sample_lsb_per_g: SAMPLE_PART_LSB_PER_G, ..base }
}

/// `t` as a samples table: every K1 coefficient brought from the part's LSB
/// ([`SAMPLE_PART_LSB_PER_G`]) to the 2²⁰ units per g every samples table is in
/// (`table::SAMPLE_UNITS_PER_G`). A compensator reading the part at
/// [`samples_config`] applies the same K1 to its raw samples (to f32 rounding).
#[must_use]
pub fn as_samples(t: &Table) -> Table {
    let k = qfa_thermal::table::SAMPLE_UNITS_PER_G / SAMPLE_PART_LSB_PER_G;
    let mut s = t.clone();
    s.input = qfa_thermal::Input::Samples;
    for a in &mut s.axes {
        a.scale = a.scale.in_units(k);
    }
    s
}

/// Encoded bytes of a table as a hex string.
#[must_use]
pub fn table_hex(t: &Table) -> String {
    let mut buf = [0u8; MAX_TABLE_BYTES];
    hex(t.encode(&mut buf).expect("valid table"))
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// A temperature program: (duration s, rate °C/min) segments from `start_c`.
#[must_use]
pub fn temperature_at(start_c: f64, segments: &[(f64, f64)], t_s: f64) -> f64 {
    let mut temp = start_c;
    let mut t0 = 0.0;
    for &(dur, rate) in segments {
        let dt = (t_s - t0).clamp(0.0, dur);
        temp += rate / 60.0 * dt;
        t0 += dur;
    }
    temp
}

/// The standard profile: hold, cool at 0.9 °C/min, hold, heat at 0.6 °C/min, hold (600 s).
pub const PROFILE: [(f64, f64); 5] = [(60.0, 0.0), (200.0, -0.9), (100.0, 0.0), (180.0, 0.6), (60.0, 0.0)];

/// Readings every ~2 s (jittered) along `PROFILE`, one IMU cycle after every second reading.
/// Every fifth reading goes through a scratchpad, exercising the decoder.
pub fn profile_events(lines: &mut Vec<String>, rng: &mut LabRng, unit: usize, t_start_ms: u32) {
    let mut t_ms = t_start_ms;
    let inputs_g = [1.0, -0.5, 0.25];
    for k in 0..300u32 {
        t_ms = t_ms.wrapping_add(2000 + (uniform(rng) * 200.0) as u32 - 100);
        let t_s = f64::from(k) * 2.0;
        let temp = temperature_at(22.0, &PROFILE, t_s) + 0.01 * (uniform(rng) - 0.5);
        let raw = (temp * 16.0).round() as i16;
        if k % 5 == 4 {
            let sp = encode_scratchpad(raw, Resolution::Bits12, 0x0D);
            lines.push(format!("sp {t_ms} {}", hex(&sp)));
        } else {
            lines.push(format!("raw {t_ms} {raw}"));
        }
        if k % 2 == 1 {
            let dt = 2500 + (uniform(rng) * 40.0) as u32 - 20;
            let k1 = f64::from(JB_KT8[unit].gamma);
            let n: Vec<i32> = inputs_g
                .iter()
                .map(|a| (k1 * (1.2e-4 + a) * f64::from(dt) * 1e-6 + uniform(rng) - 0.5).round() as i32)
                .collect();
            lines.push(format!("cycle {dt} {} {} {}", n[0], n[1], n[2]));
            // The same unit read as MEMS samples: raw = K1·(K0 + a) LSB, one 1 kHz sample,
            // with a fixed dither (not the rng, so the other lines keep their values).
            let dither = f64::from((k * 7919) % 17) / 17.0 - 0.5;
            let s: Vec<i32> = inputs_g.iter().map(|a| (k1 * (1.2e-4 + a) + 8.0 * dither).round() as i32).collect();
            lines.push(format!("samp 1000 {} {} {}", s[0], s[1], s[2]));
        }
    }
}

fn header(lines: &mut Vec<String>, what: &str) {
    lines.push(format!("# {what}"));
    lines.push("# Generated by `cargo run -p host-tests --bin record`; outputs are u32 bit patterns.".into());
    lines.push("# raw/sp  => result status T̂ Ṫ K1[0..3] K0[0..3];  cycle/count => status Δv[0..3]".into());
}

/// Slots used by the extension scenarios.
pub const LAG: SensorLag = SensorLag { tau_s: 40.0 };
/// Play operator used by the extension scenarios.
pub const PLAY: BranchHysteresis = BranchHysteresis { half_width_c: 0.5, weight_g: 3e-5 };
/// Creep used by the extension scenarios (short τ so it shows within 10 minutes).
pub const CREEP: Creep = Creep { gain_g_per_c: 2e-6, tau_ref_s: 120.0, t_ref_c: 22.0, activation_k: 3000.0 };

fn ext(lag: bool, play: bool, creep: bool) -> Extensions {
    Extensions {
        sensor_lag: lag.then_some(LAG),
        bias_branch_hysteresis: play.then_some(PLAY),
        bias_creep: creep.then_some(CREEP),
    }
}

/// Misalignment used by the #3 scenario: small rotation plus cross-axis terms.
pub const MISALIGN: [f32; 9] = [1.0002, 1.5e-4, -2e-4, -1.2e-4, 0.9997, 3e-4, 2.5e-4, -3.1e-4, 1.0001];

/// All scenario files: (name, lines).
#[must_use]
pub fn all() -> Vec<(&'static str, Vec<String>)> {
    let mut files = Vec::new();
    let none = Extensions::default();
    let units: [(&str, usize, Option<[f32; 9]>); 3] =
        [("kt8_1.vec", 0, None), ("kt8_2.vec", 1, None), ("kt8_3_misalign.vec", 2, Some(MISALIGN))];
    for (name, unit, m) in units {
        let mut l = Vec::new();
        header(
            &mut l,
            &format!(
                "JB-KT8 #{} (Eq. {}), all slots off{}",
                unit + 1,
                15 + unit,
                if m.is_some() { ", misalignment" } else { "" }
            ),
        );
        l.push(format!("table {}", table_hex(&table(unit, [none; 3], m))));
        profile_events(&mut l, &mut seeded(11 + unit as u64), unit, 1000);
        files.push((name, l));
    }
    let slots = [
        ("ext_sensor_lag.vec", "sensor_lag τ = 40 s on every axis", ext(true, false, false)),
        ("ext_branch_hysteresis.vec", "bias_branch_hysteresis r = 0.5 °C, w = 30 µg", ext(false, true, false)),
        ("ext_creep.vec", "bias_creep gain 2 µg/°C, τ_ref 120 s at 22 °C, E = 3000 K", ext(false, false, true)),
        ("ext_all.vec", "all three slots on every axis", ext(true, true, true)),
    ];
    for (i, (name, what, e)) in slots.into_iter().enumerate() {
        let mut l = Vec::new();
        header(&mut l, &format!("JB-KT8 #1, {what}"));
        l.push(format!("table {}", table_hex(&table(0, [e; 3], None))));
        // Start near the u32 wrap in one file: timestamps must wrap cleanly.
        let t0 = if i == 3 { u32::MAX - 300_000 } else { 5000 };
        profile_events(&mut l, &mut seeded(100 + i as u64), 0, t0);
        files.push((name, l));
    }
    files.push(("faults.vec", faults()));
    files
}

/// Fault scenario: each bad input must give a typed error or a flag and keep the last good state.
#[must_use]
pub fn faults() -> Vec<String> {
    let mut l = Vec::new();
    header(&mut l, "faults: no table, corrupted tables, bad scratchpads, power-on value, spikes, time faults, dropout, clamps, counters, clock restart");
    let good = table(0, [Extensions::default(); 3], None);
    let good_hex = table_hex(&good);
    l.push("# no table yet: raw counts at the nominal scale, NO_TABLE|STALE|RATE_NOT_READY".into());
    l.push("cycle 2500 800 -400 200".into());
    l.push("samp 1000 320000 -160000 80000".into());
    l.push("# one flipped payload bit: CRC error, still no table".into());
    let mut bytes: Vec<u8> =
        (0..good_hex.len() / 2).map(|i| u8::from_str_radix(&good_hex[2 * i..2 * i + 2], 16).unwrap()).collect();
    bytes[HEADER_LEN + 5] ^= 0x10;
    l.push(format!("table {}", hex(&bytes)));
    bytes[HEADER_LEN + 5] ^= 0x10;
    l.push("# γ of axis 0 set to +inf with a matching CRC: NonFinite".into());
    let mut inf = bytes.clone();
    // Payload: input tag (1 byte), varint window (32 → 1 byte), varint axis count (1 byte),
    // t0 (4), then γ.
    inf[HEADER_LEN + 7..HEADER_LEN + 11].copy_from_slice(&f32::INFINITY.to_le_bytes());
    let crc = crc32(&inf[HEADER_LEN..]);
    inf[12..16].copy_from_slice(&crc.to_le_bytes());
    l.push(format!("table {}", hex(&inf)));
    l.push("# truncated table".into());
    l.push(format!("table {}", hex(&bytes[..bytes.len() - 3])));
    l.push("cycle 2500 800 -400 200".into());
    l.push("# good table: compensation at T0 flagged STALE until a reading arrives".into());
    l.push(format!("table {good_hex}"));
    l.push("cycle 2500 800 -400 200".into());
    l.push("# the real power-up scratchpad as first reading, then raw 0550h as first reading".into());
    l.push("sp 1000 50054b467fff0c101c".into());
    l.push("raw 1500 1360".into());
    let mut t = 2000u32;
    for k in 0..12 {
        l.push(format!("raw {t} {}", 352 - k / 3));
        t += 1000;
    }
    l.push("cycle 2500 800 -400 200".into());
    l.push("# bus faults: CRC, all-zero, all-FF, bad config, bad reserved byte".into());
    let mut sp = encode_scratchpad(350, Resolution::Bits12, 0x0D);
    sp[1] ^= 0x01;
    l.push(format!("sp {t} {}", hex(&sp)));
    t += 1000;
    l.push(format!("sp {t} {}", hex(&[0u8; 9])));
    t += 1000;
    l.push(format!("sp {t} {}", hex(&[0xFFu8; 9])));
    t += 1000;
    let mut sp = encode_scratchpad(350, Resolution::Bits12, 0x0D);
    sp[4] = 0x77;
    sp[8] = qfa_thermal::ds18b20::crc8(&sp[..8]);
    l.push(format!("sp {t} {}", hex(&sp)));
    t += 1000;
    let mut sp = encode_scratchpad(350, Resolution::Bits12, 0x0D);
    sp[5] = 0xFE;
    sp[8] = qfa_thermal::ds18b20::crc8(&sp[..8]);
    l.push(format!("sp {t} {}", hex(&sp)));
    l.push("# last good compensation kept, TEMP_INVALID raised".into());
    l.push("cycle 2500 800 -400 200".into());
    t += 1000;
    l.push(format!("raw {t} 349"));
    l.push("cycle 2500 800 -400 200".into());
    l.push("# spike of +10 °C, then the power-on value as a jump from 21.8 °C".into());
    t += 1000;
    l.push(format!("raw {t} 509"));
    t += 1000;
    l.push(format!("raw {t} 1360"));
    l.push(format!("sp {} {}", t + 500, hex(&encode_scratchpad(0x0550, Resolution::Bits12, 0x0C))));
    t += 1000;
    l.push(format!("raw {t} 349"));
    l.push("# time faults: same timestamp, and one from the past".into());
    l.push(format!("raw {t} 349"));
    l.push(format!("raw {} 349", t - 5000));
    l.push("# dropout: no reading for 4 s of IMU cycles; STALE after 3 s".into());
    for _ in 0..8 {
        l.push("cycle 500000 160000 -80000 40000".into());
    }
    l.push("# reading after a 40 s gap: window restarts, RATE_NOT_READY".into());
    t += 40_000;
    l.push(format!("raw {t} 348"));
    l.push("cycle 2500 800 -400 200".into());
    for _ in 0..9 {
        t += 1000;
        l.push(format!("raw {t} 348"));
    }
    l.push("cycle 2500 800 -400 200".into());
    l.push("# a real step of +3 °C: three consistent readings confirm it".into());
    for _ in 0..3 {
        t += 1000;
        l.push(format!("raw {t} 396"));
    }
    l.push("cycle 2500 800 -400 200".into());
    l.push("# narrow table (0..25 °C, |Ṫ| ≤ 0.5): heating at 3 °C/min leaves both ranges".into());
    let mut narrow = good.clone();
    for a in &mut narrow.axes {
        a.bias = BiasGrid::single_valued(0.0, 5.0, &[1e-4, 1.1e-4, 1.2e-4, 1.3e-4, 1.4e-4, 1.5e-4])
            .expect("2 to 16 grid values");
        a.rate_limit_c_per_min = 0.5;
    }
    l.push(format!("table {}", table_hex(&narrow)));
    let mut raw = 396i32;
    for k in 0..40 {
        t += 1000;
        raw += if k % 5 == 0 { 0 } else { 1 };
        l.push(format!("raw {t} {raw}"));
    }
    l.push("cycle 2500 800 -400 200".into());
    l.push("# wrapping cumulative counters: first call has no base".into());
    l.push("count 2500 4294966000 100 7".into());
    l.push("count 2500 4294966800 4294967000 207".into());
    l.push("count 2500 504 4294966600 407".into());
    l.push("# the clock restarts (a reset time source): refused until three readings agree".into());
    for k in 0..4u32 {
        l.push(format!("raw {} 436", 5_000 + 1000 * k));
    }
    l.push("samp 1000 320000 -160000 80000".into());
    l
}
