//! Which cubic the ArduPilot file should hold, judged on a log shaped like use.
//!
//! `INS_TCALn` holds a cubic in T about 35 °C. Two cubics fit it: the one ArduPilot's own
//! learner makes of a log (one averaged point per 0.5 °C rise, its constant from the
//! ordinary calibration) and the least-squares cubic over every row (what the PX4 file
//! holds). The exports write the learner's, because it predicts the real log's later
//! leg better. A later leg of a chamber cycle is not a vehicle, so here both are fitted on
//! a simulated unit's chamber log (the full cycle, and its heating leg alone, as a
//! cold-soaked warm-up is recorded for PX4 and ArduPilot) and scored on the same unit
//! warming up in a vehicle and flying: soaked at 10 °C, its air rising to about 40 °C with
//! a 10-min time constant over 30 min, then an hour at 40 ± 4 °C (a 20-min swing). The
//! score is the RMS of what each cubic leaves of the output about its own mean (the
//! ordinary calibration takes up a constant), over the use log's rows after its first
//! minute in 60-s means, mg.
//!
//! Units from both population generators: the lab's simulator (a cubic curve, a step
//! between branches, a die lag) and the independent one in `population2` (an S-curve, a
//! play, every die lagging, Student-t noise and spikes). The study is
//! `cargo test --release -p qfa-lab --test exports_use -- --ignored --nocapture`
//! (`UNITS` per generator, default 40; `SEED`, default 11).

#![allow(clippy::cast_precision_loss)]

mod population2;

use qfa_calibrate::peers::{PeerKind, Poly};
use qfa_sim::population::{self, PopulationSpec};

/// Rows (1 s) of the use log: 30 min of warm-up, then an hour of flight.
const USE_ROWS: usize = 5400;
/// Rows left out of the score at the start of the use log.
const SETTLE_ROWS: usize = 60;

/// The air about the unit in the vehicle at `t_s`, °C.
fn use_air_c(t_s: f64) -> f64 {
    const WARM_UP_S: f64 = 1800.0;
    if t_s < WARM_UP_S {
        10.0 + 30.0 * (1.0 - (-t_s / 600.0).exp())
    } else {
        let settled = 10.0 + 30.0 * (1.0 - (-WARM_UP_S / 600.0).exp());
        settled
            + (40.0 - settled) * ((t_s - WARM_UP_S) / 600.0).min(1.0)
            + 4.0 * (2.0 * std::f64::consts::PI * (t_s - WARM_UP_S) / 1200.0).sin()
    }
}

/// One axis of one unit: its chamber rows (reading °C, output g) to fit, the heating leg's
/// range of them, and its use rows to score.
struct Axis {
    fit_t: Vec<f64>,
    fit_y: Vec<f64>,
    heating: std::ops::Range<usize>,
    use_t: Vec<f64>,
    use_y: Vec<f64>,
}

/// The RMS about its mean of `y − model(t)` over the use rows after [`SETTLE_ROWS`], in
/// 60-s means (the white noise, 0.15–0.3 mg a sample, would hide what the models differ
/// by), mg.
fn use_rms_mg(a: &Axis, model: Option<&Poly>) -> f64 {
    let rows = a.use_t.iter().zip(&a.use_y).skip(SETTLE_ROWS).map(|(&t, &y)| y - model.map_or(0.0, |m| m.eval(t)));
    // 1-s rows: row i is at i s, so the 60-s bins are whole minutes of the flight.
    let time_s: Vec<f64> = (SETTLE_ROWS..a.use_t.len()).map(|i| i as f64).collect();
    let r: Vec<f64> = qfa_calibrate::metrics::time_bin_means(rows, &time_s, 60.0).into_iter().map(|b| b.1).collect();
    let mean = r.iter().sum::<f64>() / r.len() as f64;
    1e3 * (r.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / r.len() as f64).sqrt()
}

/// The lab simulator's good units, die lags drawn, each axis.
fn lab_axes(units: usize, seed: u64) -> Vec<Axis> {
    let truth = population::draw(&PopulationSpec { units, seed, bad: false, truncated: 0, die_lags: true });
    let air = population::chamber_air();
    let use_air: Vec<f64> = (0..USE_ROWS).map(|i| use_air_c(i as f64)).collect();
    let heating = population::kept_rows(Some(population::Truncation::HeatingOnly), &air);
    let mut out = Vec::new();
    for (i, u) in truth.unit.iter().enumerate() {
        let chamber = population::unit_rows(u, &air, seed, i);
        // Another stream for the use log: its noise is not the chamber's.
        let flight = population::unit_rows(u, &use_air, seed ^ 0x5EED_F11E, i);
        for k in 0..3 {
            out.push(Axis {
                fit_t: chamber.iter().map(|r| r.0).collect(),
                fit_y: chamber.iter().map(|r| r.1[k]).collect(),
                heating: heating.clone(),
                use_t: flight.iter().map(|r| r.0).collect(),
                use_y: flight.iter().map(|r| r.1[k]).collect(),
            });
        }
    }
    out
}

/// The second generator's good units, each axis.
fn second_axes(units: usize, seed: u64) -> Vec<Axis> {
    let drawn = population2::draw(&population2::Spec { units, seed, bad: false, truncated: 0 });
    let heating = population2::kept(Some(population2::Truncation::HeatingOnly));
    let mut out = Vec::new();
    for (i, u) in drawn.iter().enumerate() {
        let chamber = population2::unit_rows(u, seed, i);
        let flight = population2::unit_rows_under(u, seed ^ 0x5EED_F11E, i, &use_air_c, USE_ROWS);
        for k in 0..3 {
            out.push(Axis {
                fit_t: chamber.iter().map(|r| r.1).collect(),
                fit_y: chamber.iter().map(|r| r.2[k]).collect(),
                heating: heating.clone(),
                use_t: flight.iter().map(|r| r.1).collect(),
                use_y: flight.iter().map(|r| r.2[k]).collect(),
            });
        }
    }
    out
}

/// The mean of `y` in each 0.5-°C bin of `t` that holds rows: every half degree weighed
/// alike, whichever way the temperature moved (the learner's weighting without its
/// rises-only rule).
fn half_degree_means(t: &[f64], y: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut bins: std::collections::BTreeMap<i64, (f64, f64, usize)> = std::collections::BTreeMap::new();
    for (&ti, &yi) in t.iter().zip(y) {
        let b = bins.entry((ti / 0.5).floor() as i64).or_insert((0.0, 0.0, 0));
        *b = (b.0 + ti, b.1 + yi, b.2 + 1);
    }
    bins.values().map(|&(st, sy, n)| (st / n as f64, sy / n as f64)).unzip()
}

/// Per axis: (none, learner, least squares, least squares on half-degree means) on the use
/// log, mg, each cubic fitted on the full chamber cycle (`heating_only` false) or its
/// heating leg.
fn scores(axes: &[Axis], heating_only: bool) -> Vec<[f64; 4]> {
    axes.iter()
        .map(|a| {
            let range = if heating_only { a.heating.clone() } else { 0..a.fit_t.len() };
            let (t, y) = (&a.fit_t[range.clone()], &a.fit_y[range]);
            let learner = PeerKind::Ardupilot.fit(t, y).expect("the learner's cubic");
            let least = PeerKind::Cubic.fit(t, y).expect("the least-squares cubic");
            let (bt, by) = half_degree_means(t, y);
            let binned = PeerKind::Cubic.fit(&bt, &by).expect("the half-degree cubic");
            [
                use_rms_mg(a, None),
                use_rms_mg(a, Some(&learner)),
                use_rms_mg(a, Some(&least)),
                use_rms_mg(a, Some(&binned)),
            ]
        })
        .collect()
}

fn geomean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x.ln(), n + 1));
    (s / n as f64).exp()
}

/// The summary line of one generator and fit: the geometric means and on how many axes
/// the least-squares cubic leaves less than the learner's.
fn summary(name: &str, fit: &str, s: &[[f64; 4]]) -> (f64, f64, usize) {
    let (learner, least) = (geomean(s.iter().map(|x| x[1])), geomean(s.iter().map(|x| x[2])));
    let wins = s.iter().filter(|x| x[2] < x[1]).count();
    println!(
        "generator={name} fit={fit} axes={} none_mg={:.4} learner_mg={learner:.4} least_squares_mg={least:.4} \
         half_degree_means_mg={:.4} least_squares_better_on={wins}",
        s.len(),
        geomean(s.iter().map(|x| x[0])),
        geomean(s.iter().map(|x| x[3])),
    );
    (learner, least, wins)
}

#[test]
#[ignore = "a study: about a second in release; prints key=value lines"]
fn ardupilot_learner_against_least_squares_on_a_use_shaped_log_study() {
    let units: usize = std::env::var("UNITS").ok().and_then(|s| s.parse().ok()).unwrap_or(40);
    let seed: u64 = std::env::var("SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(11);
    for (name, axes) in [("lab", lab_axes(units, seed)), ("population2", second_axes(units, seed))] {
        for heating_only in [false, true] {
            summary(name, if heating_only { "heating_leg" } else { "chamber_cycle" }, &scores(&axes, heating_only));
        }
    }
}

/// `candidate` leaves no more than `reference` on the use log, geometric mean over axes,
/// within 2 % (a margin set after the study above: the two tie on the lab's generator,
/// 0.078–0.080 mg each, and the learner's is 8–10 % lower on the second generator's).
fn no_worse(candidate: &[f64], reference: &[f64]) -> bool {
    geomean(candidate.iter().copied()) <= 1.02 * geomean(reference.iter().copied())
}

/// The study's finding on a few units, as CI can afford: what the ArduPilot file holds (the
/// learner's cubic) is no worse on a use-shaped log than the least-squares cubic the
/// format could carry, on both generators, fitted on a chamber cycle or a heating leg.
/// The same check refuses a straight line (the paper's simple model) in the cubic's place.
#[test]
fn the_learners_cubic_is_no_worse_than_least_squares_on_a_use_shaped_log() {
    for (name, axes) in [("lab", lab_axes(5, 11)), ("population2", second_axes(5, 11))] {
        for heating_only in [false, true] {
            let s = scores(&axes, heating_only);
            let (learner, least): (Vec<f64>, Vec<f64>) = s.iter().map(|x| (x[1], x[2])).unzip();
            assert!(no_worse(&learner, &least), "{name}, heating only {heating_only}: {s:?}");
            let line: Vec<f64> = axes
                .iter()
                .map(|a| {
                    let range = if heating_only { a.heating.clone() } else { 0..a.fit_t.len() };
                    let simple = PeerKind::Simple.fit(&a.fit_t[range.clone()], &a.fit_y[range]).expect("a line");
                    use_rms_mg(a, Some(&simple))
                })
                .collect();
            assert!(!no_worse(&line, &least), "{name}: a straight line passed the check ({line:?} against {least:?})");
        }
    }
}
