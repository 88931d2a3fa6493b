//! The reference vectors: bit-exact replay, and every value against the f64 reference.
//!
//! Tolerances (f32 result vs f64 reference), with reasons:
//! * T̂: 2e-4 °C. The f32 line fit at the newest sample loses ≈ 1e-6 relative on sums of
//!   ~10⁴ raw·samples; 2e-4 °C is 1/300 of the DS18B20's 0.0625 °C LSB.
//! * Ṫ: 1e-4 °C/min + 1e-5 relative: the slope is one f32 division of exactly converted
//!   integer sums (≈ 1e-7 relative) and the T̂ lever arm.
//! * K1: 2e-6 relative (≈ 0.6 pulse/(g·s) on 3.2·10⁵): f32 has 24 bits, Eq. 11 adds terms
//!   up to 10³ to γ ≈ 3.2·10⁵ (ulp 0.03) and Ṫ enters through ε ≈ 88.
//! * K0: 2e-9 g + 1e-5 relative (0.002 µg): the lag/play/creep states accumulate f32 rounding.
//! * Δv and sample-mode a: 3e-6 relative + 1e-9 m/s (m/s²): one count times `g0/K1` and
//!   the bias term.

use host_tests::reference::{Predicted, Reference};
use qfa_replay::{replay, Kind, FILES};

fn close(got: f32, want: f64, abs: f64, rel: f64) -> bool {
    (f64::from(got) - want).abs() <= abs + rel * want.abs()
}

fn hexbytes(s: &str) -> Vec<u8> {
    (0..s.len() / 2).map(|i| u8::from_str_radix(&s[2 * i..2 * i + 2], 16).unwrap()).collect()
}

/// Feed one input line to the reference.
fn predict(r: &mut Reference, kind: Kind, input: &str) -> Predicted {
    let tok: Vec<&str> = input.split_ascii_whitespace().collect();
    match kind {
        Kind::Table => r.table(&hexbytes(tok[1])),
        Kind::Raw => r.raw(tok[1].parse().unwrap(), tok[2].parse().unwrap()),
        Kind::Scratchpad => r.scratchpad(tok[1].parse().unwrap(), &hexbytes(tok[2]).try_into().unwrap()),
        Kind::Cycle => r.cycle(
            [tok[2].parse().unwrap(), tok[3].parse().unwrap(), tok[4].parse().unwrap()],
            tok[1].parse().unwrap(),
        ),
        Kind::Samples => r.samples(
            [tok[2].parse().unwrap(), tok[3].parse().unwrap(), tok[4].parse().unwrap()],
            tok[1].parse().unwrap(),
        ),
        Kind::Counters => r.counters(
            [tok[2].parse().unwrap(), tok[3].parse().unwrap(), tok[4].parse().unwrap()],
            tok[1].parse().unwrap(),
        ),
    }
}

#[test]
fn every_vector_is_bit_exact() {
    let n = qfa_replay::replay_all().unwrap_or_else(|e| panic!("{e:?}"));
    println!("{n} vectors bit-exact on host");
    let lines: usize = FILES
        .iter()
        .map(|(_, t)| t.lines().filter(|l| !l.trim_start().starts_with('#') && l.contains("=>")).count())
        .sum();
    assert_eq!(n, lines, "every event line is a vector");
    assert!(n > 2000, "the vectors cover the scenarios ({n})");
}

#[test]
fn every_vector_matches_the_f64_reference() {
    let mut checked = 0usize;
    let mut worst = [0.0f64; 5];
    for (name, text) in FILES {
        let mut r = Reference::new();
        let mut fails: Vec<String> = Vec::new();
        replay(name, text, true, &mut |s| {
            let p = predict(&mut r, s.kind, s.input);
            let w = s.computed;
            let f = |i: usize| f32::from_bits(w[i]);
            let ok = match &p {
                Predicted::Table(accepted) => (w[0] == 0) == *accepted,
                Predicted::SampleErr { code, status } => w[0] == *code && w[1] == u32::from(*status),
                Predicted::SampleOk { status, temp, rate, k1, k0 } => {
                    let mut ok = w[0] == 0 && w[1] == u32::from(*status);
                    ok &= close(f(2), *temp, 2e-4, 0.0);
                    ok &= close(f(3), *rate, 1e-4, 1e-5);
                    worst[0] = worst[0].max((f64::from(f(2)) - temp).abs());
                    worst[1] = worst[1].max((f64::from(f(3)) - rate).abs());
                    for a in 0..3 {
                        ok &= close(f(4 + a), k1[a], 0.0, 2e-6);
                        ok &= close(f(7 + a), k0[a], 2e-9, 1e-5);
                        worst[2] = worst[2].max(((f64::from(f(4 + a)) - k1[a]) / k1[a]).abs());
                        worst[3] = worst[3].max((f64::from(f(7 + a)) - k0[a]).abs());
                    }
                    ok
                }
                Predicted::Cycle { status, dv } => {
                    let mut ok = w[0] == u32::from(*status);
                    for (a, &want) in dv.iter().enumerate() {
                        ok &= f(1 + a).is_finite() && close(f(1 + a), want, 1e-9, 3e-6);
                        let scale = want.abs().max(1e-3);
                        worst[4] = worst[4].max((f64::from(f(1 + a)) - want).abs() / scale);
                    }
                    ok
                }
            };
            if !ok {
                fails.push(format!("{name}:{} `{}`\n  got  {:08x?}\n  want {p:?}", s.line, s.input, w));
            }
            checked += 1;
        })
        .unwrap_or_else(|e| panic!("{e:?}"));
        assert!(
            fails.is_empty(),
            "{} lines differ from the f64 reference:\n{}",
            fails.len(),
            fails[..fails.len().min(5)].join("\n")
        );
    }
    println!(
        "{checked} vectors within tolerance of the f64 reference; worst |ΔT̂| {:.2e} °C, |ΔṪ| {:.2e} °C/min, K1 {:.2e} rel, |ΔK0| {:.2e} g, Δv {:.2e} rel",
        worst[0], worst[1], worst[2], worst[3], worst[4]
    );
    assert!(checked > 2000);
}

#[test]
fn vectors_cover_every_fault_kind_and_flag() {
    use qfa_thermal::Status;
    let mut codes = std::collections::BTreeSet::new();
    let mut flags = 0u32;
    for (name, text) in FILES {
        replay(name, text, true, &mut |s| match s.kind {
            Kind::Raw | Kind::Scratchpad | Kind::Table if s.computed[0] != 0 => {
                codes.insert(s.computed[0]);
            }
            Kind::Cycle | Kind::Counters | Kind::Samples => flags |= s.computed[0],
            _ => {}
        })
        .unwrap();
    }
    let kinds: std::collections::BTreeSet<_> =
        FILES.iter().flat_map(|(_, t)| t.lines().filter_map(|l| l.split_ascii_whitespace().next())).collect();
    for k in ["table", "raw", "sp", "cycle", "count", "samp"] {
        assert!(kinds.contains(k), "no `{k}` line in the vectors");
    }
    for c in [0x11, 0x12, 0x13, 0x14, 0x15, 0x16, 0x21, 0x22, 0x23, 0x31, 0x35, 0x38] {
        assert!(codes.contains(&c), "error code {c:#x} not covered: {codes:x?}");
    }
    for f in [
        Status::TEMP_STALE,
        Status::TEMP_INVALID,
        Status::RATE_NOT_READY,
        Status::TEMP_OUT_OF_RANGE,
        Status::RATE_OUT_OF_RANGE,
        Status::NO_TABLE,
        Status::NO_COUNTER_BASE,
    ] {
        assert!(flags & u32::from(f.bits()) != 0, "status bit {f:?} never reaches the fast path");
    }
}
