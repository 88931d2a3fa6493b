//! Checks of the second independent truth generator (`truth2/`) against its own physical
//! definitions: the log's format, K1 and K0 recovered from the integer pulse counts, the
//! temperature stamp conventions, the sensor lag, the random draws' mix and the glitch
//! rate. Nothing here uses the lab: the log is read with a hand parser.
//!
//! `cargo test --release -p qfa-lab --test truth2_check`

mod truth2;

use std::collections::HashMap;
use std::time::Instant;
use truth2::{
    cycling, cycling_traced, random_draw, CatalogEffect, Counting, Draw, OutOfCatalog, RowTruth, Stamp, Trace, RATES,
};

/// One parsed CSV row.
#[derive(Clone, Debug, PartialEq)]
struct Row {
    program: String,
    run: String,
    time_s: f64,
    input_g: f64,
    temp_c: f64,
    pulses: i64,
    interval_s: f64,
}

/// The hand parser: the exact header, seven fields a row, integer pulses.
fn parse(csv: &str) -> Vec<Row> {
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("program,run,time_s,input_g,temp_c,pulses,interval_s"));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 7, "row {l:?}");
            assert!(f[5].bytes().enumerate().all(|(i, b)| b.is_ascii_digit() || (i == 0 && b == b'-')), "pulses {l:?}");
            Row {
                program: f[0].to_string(),
                run: f[1].to_string(),
                time_s: f[2].parse().unwrap(),
                input_g: f[3].parse().unwrap(),
                temp_c: f[4].parse().unwrap(),
                pulses: f[5].parse().unwrap(),
                interval_s: f[6].parse().unwrap(),
            }
        })
        .collect()
}

/// Rows grouped by (program, run), in log order.
fn runs(rows: &[Row]) -> Vec<((String, String), Vec<Row>)> {
    let mut out: Vec<((String, String), Vec<Row>)> = Vec::new();
    for r in rows {
        let key = (r.program.clone(), r.run.clone());
        match out.last_mut() {
            Some((k, v)) if *k == key => v.push(r.clone()),
            _ => {
                assert!(out.iter().all(|(k, _)| *k != key), "run {key:?} split in two");
                out.push((key, vec![r.clone()]));
            }
        }
    }
    out
}

#[test]
fn format_parses_and_runs_align() {
    for d in [Draw::clean(1), random_draw(7), random_draw(8), Draw { heating_only: true, row_s: 5.0, ..Draw::clean(2) }]
    {
        let rows = parse(&cycling(&d));
        let groups = runs(&rows);
        assert_eq!(groups.len(), 2 * RATES.len(), "4 programs × 2 runs");
        for ((program, run), v) in &groups {
            let rate: f64 = program.rsplit('-').next().unwrap().parse().unwrap();
            assert!(RATES.contains(&rate), "{program}");
            let g = match run.as_str() {
                "pos0" => 1.0,
                "pos2" => -1.0,
                _ => panic!("run {run}"),
            };
            let mut last = 0.0;
            for (i, r) in v.iter().enumerate() {
                assert_eq!(r.input_g, g);
                assert!(r.time_s > last, "time_s increases within {program}/{run}");
                last = r.time_s;
                assert!((r.time_s - (i + 1) as f64 * d.row_s).abs() < 1e-9);
                assert!((r.interval_s - d.row_s).abs() < 1e-9);
                assert_eq!(r.temp_c * 16.0, (r.temp_c * 16.0).round(), "1/16 °C steps");
                assert!((r.pulses.abs() as f64 - 320_000.0 * d.row_s).abs() < 0.25 * 320_000.0 * d.row_s);
            }
        }
        for pair in groups.chunks(2) {
            assert_eq!(pair[0].0 .0, pair[1].0 .0);
            assert_eq!((pair[0].0 .1.as_str(), pair[1].0 .1.as_str()), ("pos0", "pos2"));
            let t0: Vec<f64> = pair[0].1.iter().map(|r| r.time_s).collect();
            let t2: Vec<f64> = pair[1].1.iter().map(|r| r.time_s).collect();
            assert_eq!(t0, t2, "both runs of a program have the same times");
        }
    }
}

/// (pos0 row, pos2 row, truth of pos0, truth of pos2) for every row time of every program.
fn pairs<'a>(rows: &'a [Row], trace: &'a Trace) -> Vec<(&'a Row, &'a Row, &'a RowTruth, &'a RowTruth)> {
    let mut by: HashMap<(usize, usize, u64), usize> = HashMap::new();
    for (i, t) in trace.rows.iter().enumerate() {
        by.insert((t.program, t.run, t.time_s.to_bits()), i);
    }
    trace
        .rows
        .iter()
        .enumerate()
        .filter(|(_, t)| t.run == 0)
        .map(|(i, t)| {
            let j = by[&(t.program, 1, t.time_s.to_bits())];
            assert_eq!(rows[i].time_s, rows[j].time_s);
            (&rows[i], &rows[j], &trace.rows[i], &trace.rows[j])
        })
        .collect()
}

fn with(mut d: Draw, catalog: &[CatalogEffect]) -> Draw {
    d.catalog = catalog.to_vec();
    d
}

#[test]
fn k1_and_k0_from_the_counts() {
    let rich = [
        CatalogEffect::TempQuadSf { beta: 0.12 },
        CatalogEffect::TempQuadBias { b2_g_per_c2: 0.05e-6 },
        CatalogEffect::RateHysteresis { eps: 8.0 },
        CatalogEffect::RateSquared { alpha: 4.0 },
        CatalogEffect::RateTempCoupling { eta: -0.2 },
        CatalogEffect::SensorLag { tau_s: 300.0 },
        CatalogEffect::BiasDrift { g_per_h: 2e-6 },
    ];
    for counting in [Counting::FirstOrderHold, Counting::ZeroOrderHold] {
        for catalog in [&[][..], &rich[..]] {
            let d = with(Draw { counting, ..Draw::clean(3).noise_free() }, catalog);
            let (csv, trace) = cycling_traced(&d);
            let rows = parse(&csv);
            let u = &trace.unit;
            let mut worst_k1 = 0.0f64;
            for (a, b, ta, tb) in pairs(&rows, &trace) {
                assert_eq!((ta.te_c, ta.rate_c_per_min), (tb.te_c, tb.rate_c_per_min), "same thermal path");
                let k1 = (a.pulses - b.pulses) as f64 / (2.0 * a.interval_s);
                let want = u.k1(ta.te_c, ta.rate_c_per_min);
                worst_k1 = worst_k1.max((k1 / want - 1.0).abs());
            }
            // K0 from sums over 30-row blocks: one row's ±1 pulse is 0.3 µg; a block's,
            // with the remainder carried, is 0.01 µg.
            let mut worst_k0 = 0.0f64;
            let mut k0_seen = (f64::MAX, f64::MIN);
            for block in pairs(&rows, &trace).chunks(30) {
                let (mut sum, mut diff, mut num, mut den) = (0.0, 0.0, 0.0, 0.0);
                for (a, b, ta, _) in block {
                    sum += (a.pulses + b.pulses) as f64;
                    diff += (a.pulses - b.pulses) as f64;
                    let k1 = u.k1(ta.te_c, ta.rate_c_per_min);
                    let t_mid_h = (ta.time_s - 0.5 * a.interval_s) / 3600.0;
                    num += k1 * (u.k0_static(ta.te_c) + u.drift_g_per_h * t_mid_h);
                    den += k1;
                }
                let (k0, want) = (sum / diff, num / den);
                worst_k0 = worst_k0.max((k0 - want).abs());
                k0_seen = (k0_seen.0.min(want), k0_seen.1.max(want));
            }
            println!(
                "{counting:?}, {} effects: K1 worst {worst_k1:.2e} relative, K0 worst {:.4} µg (K0 spans {:.1}…{:.1} µg)",
                catalog.len(),
                worst_k0 * 1e6,
                k0_seen.0 * 1e6,
                k0_seen.1 * 1e6
            );
            assert!(worst_k1 < 1e-6, "K1 from the counts off by {worst_k1:e}");
            assert!(worst_k0 < 0.05e-6, "K0 from the counts off by {} µg", worst_k0 * 1e6);
        }
    }
}

/// Play operator and (unactivated) creep on the bias, recomputed here from their definitions
/// on the row centres' element temperatures.
#[test]
fn play_and_creep_follow_their_definitions() {
    let (h, w, gain, tau) = (2.0, 15e-6, 1e-6, 1500.0);
    let d = with(
        Draw::clean(4).noise_free(),
        &[
            CatalogEffect::BiasBranchHysteresis { half_width_c: h, weight_g: w },
            CatalogEffect::BiasCreep { gain_g_per_c: gain, tau_ref_s: tau, activation_k: 0.0 },
        ],
    );
    let (csv, trace) = cycling_traced(&d);
    let rows = parse(&csv);
    let u = &trace.unit;
    let all = pairs(&rows, &trace);
    let mut worst = 0.0f64;
    let mut extra_span = (f64::MAX, f64::MIN);
    let mut program = usize::MAX;
    let (mut p, mut x, mut te_prev) = (22.0f64, 22.0f64, 22.0f64);
    let mut block = (0.0, 0.0, 0.0, 0.0, 0usize);
    for (a, b, ta, _) in &all {
        if ta.program != program {
            program = ta.program;
            (p, x, te_prev) = (22.0, 22.0, 22.0);
            block = (0.0, 0.0, 0.0, 0.0, 0);
        }
        // Exact response of x to Te linear between row centres (10 s apart).
        let dt = a.interval_s;
        let slope = (ta.te_c - te_prev) / dt;
        x = ta.te_c - slope * tau + (x - te_prev + slope * tau) * (-dt / tau).exp();
        te_prev = ta.te_c;
        p = p.clamp(ta.te_c - h, ta.te_c + h);
        let extra = w * (ta.te_c - p) / h + gain * (ta.te_c - x);
        extra_span = (extra_span.0.min(extra), extra_span.1.max(extra));
        let k1 = u.k1(ta.te_c, ta.rate_c_per_min);
        block.0 += (a.pulses + b.pulses) as f64;
        block.1 += (a.pulses - b.pulses) as f64;
        block.2 += k1 * (u.k0_static(ta.te_c) + extra);
        block.3 += k1;
        block.4 += 1;
        if block.4 == 30 {
            worst = worst.max((block.0 / block.1 - block.2 / block.3).abs());
            block = (0.0, 0.0, 0.0, 0.0, 0);
        }
    }
    println!("play + creep: {:.1}…{:.1} µg, worst block {:.3} µg", extra_span.0 * 1e6, extra_span.1 * 1e6, worst * 1e6);
    assert!(extra_span.1 - extra_span.0 > 30e-6, "the effects are large");
    assert!(worst < 0.1e-6, "play + creep off by {} µg", worst * 1e6);
}

/// Σ over rows with the case ramping (|rate| ≥ 0.2 °C/min) of the reading difference
/// between two logs, and Σ of rate × `shift_s` (the expected difference), both signed by
/// the ramp's direction so that cooling and heating ramps add up instead of cancelling.
fn stamp_shift(a: &[Row], b: &[Row], trace: &Trace, shift_s: f64, program: Option<usize>) -> (f64, f64) {
    let (mut got, mut want) = (0.0, 0.0);
    for ((ra, rb), t) in a.iter().zip(b).zip(&trace.rows) {
        if t.rate_c_per_min.abs() >= 0.2 && program.is_none_or(|p| p == t.program) {
            got += t.rate_c_per_min.signum() * (ra.temp_c - rb.temp_c);
            want += t.rate_c_per_min.abs() / 60.0 * shift_s;
        }
    }
    (got, want)
}

#[test]
fn stamp_conventions_and_conversion_delay() {
    let base = Draw { conversion_delay_s: 0.0, ..Draw::clean(5) };
    let log = |stamp: Stamp, delay: f64| parse(&cycling(&Draw { stamp, conversion_delay_s: delay, ..base.clone() }));
    let (_, trace) = cycling_traced(&base);
    let (start, centre, end, late) =
        (log(Stamp::Start, 0.0), log(Stamp::Centre, 0.0), log(Stamp::End, 0.0), log(Stamp::End, 0.75));
    for (label, a, b, shift, tol) in [
        ("end − start", &end, &start, 10.0, 0.01),
        ("centre − start", &centre, &start, 5.0, 0.01),
        ("end − end 0.75 s late", &end, &late, 0.75, 0.05),
    ] {
        let (got, want) = stamp_shift(a, b, &trace, shift, None);
        println!("{label}: {got:.3} °C summed, {want:.3} expected");
        assert!((got / want - 1.0).abs() < tol, "{label}: {got} against {want}");
        for (p, rate) in RATES.iter().enumerate() {
            let (got, want) = stamp_shift(a, b, &trace, shift, Some(p));
            assert!((got / want - 1.0).abs() < 3.0 * tol, "{label}, {rate} °C/min: {got} against {want}");
        }
    }
    // Averaged over the steady half of each ramp the difference is the program's rate × shift.
    for (p, prog) in trace.programs.iter().enumerate() {
        for (i, &ramp_end) in prog.ramp_ends_s.iter().enumerate() {
            let (t0, c0) = prog.knots[2 * i + 1];
            let c1 = prog.knots[2 * i + 2].1;
            let signed = (c1 - c0).signum() * prog.rate_c_per_min / 60.0;
            let mid = 0.5 * (t0 + ramp_end);
            let d: Vec<f64> = end
                .iter()
                .zip(&start)
                .zip(&trace.rows)
                .filter(|(_, t)| t.program == p && t.time_s > mid && t.time_s <= ramp_end)
                .map(|((e, s), _)| e.temp_c - s.temp_c)
                .collect();
            let mean = d.iter().sum::<f64>() / d.len() as f64;
            assert!(
                (mean - signed * 10.0).abs() < 0.1 * signed.abs() * 10.0,
                "{} °C/min ramp {i}: end − start {mean:.4} °C against {:.4}",
                prog.rate_c_per_min,
                signed * 10.0
            );
        }
    }
}

/// Element temperature recovered from a linear unit's counts.
fn te_from_counts(a: &Row, b: &Row, trace: &Trace) -> f64 {
    let k1 = (a.pulses - b.pulses) as f64 / (2.0 * a.interval_s);
    22.0 + (k1 - trace.unit.k10) / trace.unit.mu
}

#[test]
fn sensor_lag_delays_k1_behind_the_reading() {
    for lag in [None, Some(600.0), Some(150.0)] {
        let catalog: Vec<CatalogEffect> = lag.map(|tau_s| CatalogEffect::SensorLag { tau_s }).into_iter().collect();
        let d = with(Draw { stamp: Stamp::Centre, conversion_delay_s: 0.0, ..Draw::clean(9).noise_free() }, &catalog);
        let (csv, trace) = cycling_traced(&d);
        let rows = parse(&csv);
        let all = pairs(&rows, &trace);
        for (p, prog) in trace.programs.iter().enumerate() {
            for &ramp_end in &prog.ramp_ends_s {
                let (a, b, t, _) = all.iter().rfind(|(_, _, t, _)| t.program == p && t.time_s <= ramp_end).unwrap();
                let seen = a.temp_c - te_from_counts(a, b, &trace);
                let want = lag.unwrap_or(0.0) * t.rate_c_per_min / 60.0;
                if p == 0 {
                    println!("lag {lag:?}: ramp end at {ramp_end:.0} s: reading − K1's temperature {seen:.3} °C, τ·rate {want:.3}");
                }
                // Steady once the ramp has lasted several times the case's and the element's
                // time constants; before that the lag is still building.
                let ramp_s = prog.knots.iter().map(|k| k.0).rfind(|&t| t < ramp_end).map_or(0.0, |t0| ramp_end - t0);
                let steady = ramp_s > 6.0 * (400.0 + lag.unwrap_or(0.0));
                match lag {
                    None => assert!(seen.abs() < 0.05, "no lag: {seen}"),
                    Some(_) if steady => {
                        assert!(
                            (seen / want - 1.0).abs() < 0.05,
                            "{} °C/min: lag {seen} against {want}",
                            prog.rate_c_per_min
                        )
                    }
                    // (1.05: the reading's 1/16-°C quantisation, not dithered without noise.)
                    Some(_) => assert!(
                        seen / want > 0.5 && seen / want < 1.05,
                        "{} °C/min, {ramp_s:.0}-s ramp: lag {seen} against {want} in steady state",
                        prog.rate_c_per_min
                    ),
                }
            }
        }
    }
}

#[test]
fn random_draws_mix_and_determinism() {
    let n = 1000;
    let (mut clean, mut cat, mut other) = (0, [0usize; 9], [0usize; 5]);
    for seed in 0..n {
        let d = random_draw(seed);
        assert_eq!(d, random_draw(seed), "deterministic");
        let k = d.catalog.len() + d.other.len();
        assert!(k <= 3);
        if k == 0 {
            clean += 1;
        }
        for (i, e) in d.catalog.iter().enumerate() {
            assert!(d.catalog[..i].iter().all(|f| f.kind() != e.kind()), "distinct");
            assert!(["scale_factor", "bias", "both"].contains(&e.channel()));
            cat[e.kind()] += 1;
        }
        for (i, e) in d.other.iter().enumerate() {
            assert!(d.other[..i].iter().all(|f| f.kind() != e.kind()), "distinct");
            other[e.kind()] += 1;
        }
        assert!([0.0, 0.75].contains(&d.conversion_delay_s));
        assert!(d.bias_instability.0 <= 2e-6 && (600.0..=3600.0).contains(&d.bias_instability.1));
    }
    println!("clean {clean}/{n}; catalog {cat:?}; out of catalog {other:?}");
    assert!((clean as f64 / n as f64 - 0.35).abs() < 0.06, "clean {clean}");
    assert!(cat.iter().chain(&other).all(|&c| c >= 20), "every effect at least 20 times");
    let names: std::collections::BTreeSet<&str> =
        (0..n).flat_map(|s| random_draw(s).catalog.into_iter().map(|e| e.name())).collect();
    assert_eq!(names.len(), 8, "{names:?}");
    assert_eq!(cycling(&random_draw(42)), cycling(&random_draw(42)));
    assert_ne!(cycling(&random_draw(42)), cycling(&random_draw(43)));
    let _ = OutOfCatalog::TempDependentNoise;
}

#[test]
fn glitch_rate() {
    let (mut glitches, mut seconds, mut from_log) = (0usize, 0usize, 0i64);
    for seed in 0..5 {
        let off = Draw { glitches: false, ..Draw::clean(100 + seed) };
        let on = Draw { glitches: true, ..off.clone() };
        let (csv_on, tr) = cycling_traced(&on);
        let (csv_off, tr_off) = cycling_traced(&off);
        assert_eq!(tr_off.glitch_seconds, 0);
        glitches += tr.glitch_seconds;
        seconds += tr.counted_seconds;
        // The same seed draws the same white noise: the logs differ by ±200 pulses in the
        // rows holding a glitch (±1 elsewhere, from the carried remainder).
        for (a, b) in parse(&csv_on).iter().zip(parse(&csv_off).iter()) {
            let diff = a.pulses - b.pulses;
            assert!(diff.abs() <= 1 || diff.abs() >= 199, "diff {diff}");
            from_log += (diff.abs() as f64 / 200.0).round() as i64;
        }
    }
    let per = seconds as f64 / glitches as f64;
    println!("{glitches} glitches in {seconds} s (one in {per:.0} s); {from_log} seen in the pulses");
    assert!((4000.0..6500.0).contains(&per), "one glitch in {per:.0} s");
    assert!((from_log - glitches as i64).abs() <= 2, "log {from_log} against {glitches}");
}

#[test]
fn size_and_speed() {
    let d = Draw::clean(11);
    let t = Instant::now();
    let (csv, trace) = cycling_traced(&d);
    let took = t.elapsed().as_secs_f64();
    let rows = parse(&csv).len();
    let want: usize = trace.programs.iter().map(|p| 2 * (p.duration_s / d.row_s).floor() as usize).sum();
    println!("{rows} rows, {:.1} h of logging, {:.0} ms", trace.counted_seconds as f64 / 3600.0, took * 1e3);
    assert_eq!(rows, want);
    assert!(took < 2.0, "generation took {took} s");
}
