//! The population prior on QFA batches: each cut unit's table with the prior against its
//! own, both against the truth the simulator wrote.

mod common;
mod qfa_units;

use qfa_batch::unit::UnitOutcome;
use qfa_sim::population::Truncation;
use qfa_sim::qfa_population::{draw_qfa, write_qfa_manifest, QfaPopulationSpec};
use qfa_units::{calibrate, keep_programs, run, scratch};

/// A QFA table's error against its unit's truth ([`common::qfa_table_error`]).
fn qfa_table_error(table: &qfa_thermal::Table, truth: &qfa_sim::truth::Truth, span: [f64; 2]) -> (f64, f64) {
    let s = &truth.scale;
    let t0 = f64::from(s.t0_c);
    let k1 = |t: f64, r: f64| common::eq11_k1(s, t - t0, r);
    common::qfa_table_error(table, truth.sensor.offset_c, span, k1, |t| truth.bias.at(t - t0))
}

/// One good unit's errors against its truth: how its log was cut, and its own table's and
/// the prior's, each `(scale factor ppm, bias µg)`.
struct QfaPriorRow {
    serial: String,
    cut: Option<Truncation>,
    own: (f64, f64),
    prior: (f64, f64),
}

/// Each good unit of a `units`-unit QFA batch, `truncated` of them with cut logs (heating
/// only, or the first half of every run), against its truth: its own table and the prior's
/// (formed in memory for a full unit, from the population it is part of; for a cut unit,
/// checked byte for byte against the `table_prior.bin` the batch wrote).
fn qfa_prior_study(units: usize, truncated: usize, seed: u64, name: &str) -> Vec<QfaPriorRow> {
    let dir = scratch(name);
    let (truth, results, fleet) = run(&dir, &QfaPopulationSpec { units, seed, bad: false, truncated });
    // The prior's tables too are among the files a later batch clears.
    common::assert_unit_files_are_listed(&dir.join("out"));
    let span = (fleet.span_c[0], fleet.span_c[1]);
    let deadband = qfa_log::replay::branch_deadband_c_per_min();
    let mut rows = Vec::new();
    for (u, (r, f)) in truth.unit.iter().zip(results.iter().zip(&fleet.unit)) {
        let UnitOutcome::Calibrated(c) = &r.outcome else { panic!("{}: not calibrated", r.serial) };
        assert_eq!(f.partial, u.truncation.is_some(), "{}: partial as its log was cut", u.serial);
        let folder = dir.join("out").join(&r.serial);
        let own = qfa_thermal::Table::decode(&std::fs::read(folder.join("table.bin")).unwrap()).unwrap();
        let normal = c.qfa_normal.as_ref().expect("a QFA unit's statistics");
        let prior = qfa_batch::qfa::qfa_prior_table(normal, &fleet.population, span, deadband).unwrap();
        if u.truncation.is_some() {
            let p = f.prior.as_ref().expect("a partial unit gets the prior's table");
            let written = std::fs::read(folder.join(&p.table)).unwrap();
            assert_eq!(written.as_slice(), prior.to_bytes().unwrap().as_slice(), "{}", u.serial);
        }
        rows.push(QfaPriorRow {
            serial: u.serial.clone(),
            cut: u.truncation,
            own: qfa_table_error(&own, &u.truth, fleet.span_c),
            prior: qfa_table_error(&prior, &u.truth, fleet.span_c),
        });
    }
    rows
}

/// RMS over `rows`: own and prior, scale factor (ppm) and bias (µg); and the worst
/// prior/own ratio of each.
fn qfa_prior_summary(rows: &[&QfaPriorRow]) -> ([f64; 4], [f64; 2]) {
    let rms =
        |f: &dyn Fn(&QfaPriorRow) -> f64| (rows.iter().map(|r| f(r).powi(2)).sum::<f64>() / rows.len() as f64).sqrt();
    let worst = |f: &dyn Fn(&QfaPriorRow) -> f64| rows.iter().map(|r| f(r)).fold(0.0, f64::max);
    (
        [rms(&|r| r.own.0), rms(&|r| r.prior.0), rms(&|r| r.own.1), rms(&|r| r.prior.1)],
        [worst(&|r| r.prior.0 / r.own.0), worst(&|r| r.prior.1 / r.own.1)],
    )
}

/// The population prior on a QFA batch of 12 good units, 4 with cut logs (2 heating-only,
/// 2 the first half of every run): the cut units' tables come out closer to their truth
/// with the prior than without, on the scale factor and on the bias. A full unit, whose
/// own table it does not replace, loses little by it: each within 1 ppm of its own scale
/// factor error, and the full units' bias error RMS within 25 % of their own tables'.
/// The margins were set after seeing two draws: full units within 0.1 ppm and 0.6 µg on
/// the first; on the simulator's next streams one unit's own table read 0.83 µg against
/// its prior's 2.20 (2.21 on the draw after; the full units' RMS 2.51 → 2.78 µg on both,
/// 10 % apart), and the 120 full
/// units of `qfa_prior_study_50` read 2–5 % apart. With the population's sample
/// covariance unshrunk, the cut units' scale factor came out worse with the prior on the
/// earlier streams (17.9 → 27.4 ppm) and this test failed; on the next draw it read
/// 34.4 → 19.1 ppm (8.7 shrunk) and passed, so the shrinkage itself is checked where it
/// is computed (`prior::tests::the_population_shrinks_noise_correlations_and_keeps_real_ones`,
/// which fails unshrunk).
#[test]
fn the_qfa_prior_helps_units_with_cut_logs() {
    let rows = qfa_prior_study(12, 4, 5, "qfa_prior_12");
    for r in &rows {
        println!(
            "{} cut={:?} own=({:.2} ppm, {:.2} µg) prior=({:.2} ppm, {:.2} µg)",
            r.serial, r.cut, r.own.0, r.own.1, r.prior.0, r.prior.1
        );
    }
    let cut: Vec<&QfaPriorRow> = rows.iter().filter(|r| r.cut.is_some()).collect();
    let ([own_sf, prior_sf, own_b, prior_b], _) = qfa_prior_summary(&cut);
    println!("cut units: scale factor own {own_sf:.2} → prior {prior_sf:.2} ppm, bias own {own_b:.2} → prior {prior_b:.2} µg");
    assert!(prior_sf < own_sf, "scale factor: own {own_sf:.2} ppm, prior {prior_sf:.2} ppm");
    assert!(prior_b < 0.5 * own_b, "bias: own {own_b:.2} µg, prior {prior_b:.2} µg");
    let full: Vec<&QfaPriorRow> = rows.iter().filter(|r| r.cut.is_none()).collect();
    for r in &full {
        assert!(r.prior.0 < r.own.0 + 1.0, "{}: own {:?}, prior {:?}", r.serial, r.own, r.prior);
    }
    let ([_, _, own_b, prior_b], _) = qfa_prior_summary(&full);
    assert!(prior_b < 1.25 * own_b, "full units' bias: own {own_b:.2} µg, prior {prior_b:.2} µg");
}

/// The study behind docs/measurements.md's QFA prior: 50 good units, 10 with cut logs, three
/// seeds (`cargo test --release -p qfa-lab --test batch_qfa_prior -- --ignored qfa_prior_study_50 --nocapture`).
#[test]
#[ignore = "a study: about a minute in release"]
fn qfa_prior_study_50() {
    for seed in [1, 2, 3] {
        let rows = qfa_prior_study(50, 10, seed, &format!("qfa_prior_study_{seed}"));
        for (name, pick) in [
            ("full", None),
            ("heating_only", Some(Truncation::HeatingOnly)),
            ("first_half", Some(Truncation::FirstHalf)),
        ] {
            let of: Vec<&QfaPriorRow> = rows.iter().filter(|r| r.cut == pick).collect();
            let ([own_sf, prior_sf, own_b, prior_b], [worst_sf, worst_b]) = qfa_prior_summary(&of);
            println!(
                "seed={seed} units={name}:{} sf_ppm={own_sf:.2}->{prior_sf:.2} worst_sf_ratio={worst_sf:.2} \
                 bias_ug={own_b:.2}->{prior_b:.2} worst_bias_ratio={worst_b:.2}",
                of.len()
            );
        }
    }
}

/// A unit's own table's and the prior's errors against its truth, each `(ppm, µg)`.
type OwnAndPrior = ((f64, f64), (f64, f64));

/// Units logged through two of the four programs: their own table against the population
/// prior's (the table a unit of partial coverage flashes), each against its truth, 20-unit
/// batches of three seeds, four good units of each cut to a pair of programs
/// (`cargo test --release -p qfa-lab --test batch_qfa_prior -- --ignored qfa_programs_prior_study --nocapture`).
/// Measured: the 12 cut units' scale factor 4.78 → 4.71 ppm RMS, bias 2.16 → 2.33 µg with
/// the prior; the worst single unit's bias 1.62 → 2.50 µg (docs/measurements.md).
#[test]
#[ignore = "a study: about a minute in release"]
fn qfa_programs_prior_study() {
    const PAIRS: [[&str; 2]; 4] = [
        ["paper-0.3", "paper-0.5"],
        ["paper-0.3", "paper-0.9"],
        ["paper-0.7", "paper-0.9"],
        ["paper-0.5", "paper-0.7"],
    ];
    let mut cut_rows = Vec::new();
    let mut full_rows = Vec::new();
    for seed in [1, 2, 3] {
        let dir = scratch(&format!("qfa_programs_prior_{seed}"));
        let truth = draw_qfa(&QfaPopulationSpec { units: 20, seed, bad: false, truncated: 0 });
        write_qfa_manifest(&dir, &truth, 2).unwrap();
        for (u, pair) in truth.unit.iter().zip(PAIRS) {
            keep_programs(&dir.join("units").join(format!("{}.csv", u.serial)), &pair);
        }
        let (results, fleet) = calibrate(&dir, "out", 2);
        let span = (fleet.span_c[0], fleet.span_c[1]);
        let deadband = qfa_log::replay::branch_deadband_c_per_min();
        for (k, (u, (r, f))) in truth.unit.iter().zip(results.iter().zip(&fleet.unit)).enumerate() {
            let UnitOutcome::Calibrated(c) = &r.outcome else { panic!("{}: not calibrated", r.serial) };
            let folder = dir.join("out").join(&r.serial);
            let own = qfa_thermal::Table::decode(&std::fs::read(folder.join("table.bin")).unwrap()).unwrap();
            let normal = c.qfa_normal.as_ref().expect("a QFA unit's statistics");
            let prior = qfa_batch::qfa::qfa_prior_table(normal, &fleet.population, span, deadband).unwrap();
            let row = (qfa_table_error(&own, &u.truth, fleet.span_c), qfa_table_error(&prior, &u.truth, fleet.span_c));
            if k < PAIRS.len() {
                println!(
                    "seed={seed} {} programs={:?} decision={:?} coverage={:?} own=({:.2} ppm, {:.2} µg) prior=({:.2} ppm, {:.2} µg)",
                    u.serial, PAIRS[k], f.decision, f.coverage, row.0 .0, row.0 .1, row.1 .0, row.1 .1
                );
                cut_rows.push(row);
            } else {
                full_rows.push(row);
            }
        }
    }
    for (name, rows) in [("cut", &cut_rows), ("full", &full_rows)] {
        let rms = |f: &dyn Fn(&OwnAndPrior) -> f64| {
            (rows.iter().map(|r| f(r).powi(2)).sum::<f64>() / rows.len() as f64).sqrt()
        };
        println!(
            "units={name}:{} sf_ppm={:.2}->{:.2} bias_ug={:.2}->{:.2}",
            rows.len(),
            rms(&|r| r.0 .0),
            rms(&|r| r.1 .0),
            rms(&|r| r.0 .1),
            rms(&|r| r.1 .1)
        );
    }
}
