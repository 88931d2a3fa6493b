//! Study: which structure a static log's held-out figure should score, and which one
//! `table.bin` should hold. Static calibration chooses a structure on every row (the
//! table's, set 0) and, under `after-max`, again on the training rows alone (the fold's).
//! Three ways to pair a table with a held-out figure:
//!
//! * A: the table holds set 0's choice; the held-out figure scores the fold's own choice
//!   fitted on the training rows (the choice never saw the later leg, but it may not be the
//!   structure the table holds);
//! * B: the table holds set 0's choice; the held-out figure scores that structure fitted on
//!   the training rows (the structure the table holds; its choice saw the later leg);
//! * C: the table holds the fold's choice refitted on every row; the held-out figure scores
//!   it fitted on the training rows (one structure, chosen without the later leg).
//!
//! The judge is a fresh log of the same unit (the simulator's chamber cycle with each hidden
//! effect, another seed; the independent desk generator, another seed): each table fitted on
//! every row of the first log and applied to the fresh log's later leg (rows after its
//! hottest; every row when it has none), inside the table's grid, about its own mean (each
//! run's turn-on constant is the ordinary accelerometer calibration's). Printed per axis, and as
//! geometric means: each table's fresh RMS, and each held-out figure over its table's fresh
//! RMS (how well the report predicts what the table does on a new log).
//!
//! `cargo xtask experiment static_table_study` (about 20 s in release);
//! `QFA_STUDY_SEEDS=11,12` picks the simulator's seeds (default 11–19). The figures are in
//! docs/measurements.md ("Real data").

#[path = "../tests/chamber/mod.rs"]
mod chamber;
mod common;
#[path = "../tests/truth/mod.rs"]
mod truth;

use chamber::chamber_log;

use qfa_calibrate::fit::{fit_static_traced, StaticFit, StaticSeries, StaticStructure, StaticTraces};
use qfa_calibrate::static_cal::{
    calibrate_static, candidates, cv_rms_axes, resolve_holdout, Holdout, Scheme, StaticCalOptions, CV_FOLDS,
};
use qfa_log::static_log::{read_static_from, StaticLog, StaticOptions};

/// `st` fitted on axis `a` of `log` on the rows `mask` holds.
fn fit(log: &StaticLog, a: usize, st: &StaticStructure, mask: &[bool]) -> Option<StaticFit> {
    let opts = StaticCalOptions::default();
    let view = StaticSeries::view_of(&log.time_s, &log.temp_c, opts.deadband_c_per_min);
    let series = StaticSeries { view: &view, accel_g: &log.axes[a].accel_g };
    let traces = StaticTraces::new(&series, st, opts.deadband_c_per_min);
    fit_static_traced(&series, &traces, mask, opts.grid_points, opts.block).ok()
}

/// The fold's own choice on axis `a`: the lowest blocked cross-validation RMS among the
/// candidates on the training rows `train` (the rule the held-out figures once scored).
fn fold_choice(log: &StaticLog, a: usize, train: &[usize]) -> Option<StaticStructure> {
    let opts = StaticCalOptions::default();
    let view = StaticSeries::view_of(&log.time_s, &log.temp_c, opts.deadband_c_per_min);
    let axes: Vec<StaticSeries<'_>> =
        log.axes.iter().map(|x| StaticSeries { view: &view, accel_g: &x.accel_g }).collect();
    candidates()
        .into_iter()
        .filter_map(|st| {
            let traces = StaticTraces::new(&axes[0], &st, opts.deadband_c_per_min);
            cv_rms_axes(&axes, &traces, train, CV_FOLDS, &opts)[a].as_ref().ok().map(|&r| (st, r))
        })
        .min_by(|x, y| x.1.total_cmp(&y.1))
        .map(|x| x.0)
}

/// RMS (mg) of `fit` applied to axis `a` of `log` on `rows`, inside its grid; about the
/// residuals' own mean when `centred` (a fresh run's constant, which the simulator draws
/// afresh for each run and the ordinary accelerometer calibration takes up).
fn rms_on(log: &StaticLog, a: usize, fit: &StaticFit, rows: std::ops::Range<usize>, centred: bool) -> Option<f64> {
    let opts = StaticCalOptions::default();
    let view = StaticSeries::view_of(&log.time_s, &log.temp_c, opts.deadband_c_per_min);
    let series = StaticSeries { view: &view, accel_g: &log.axes[a].accel_g };
    let tr = series.model_trace(&fit.axis);
    let (lo, hi) = (f64::from(fit.axis.bias.t_start_c), f64::from(fit.axis.bias.t_end_c()));
    let r: Vec<f64> = rows
        .filter(|&i| tr.valid[i] && (lo..=hi).contains(&tr.temp_c[i]))
        .map(|i| log.axes[a].accel_g[i] - fit.reference_g - tr.ext_k0_g[i])
        .collect();
    let m = if centred { r.iter().sum::<f64>() / r.len().max(1) as f64 } else { 0.0 };
    (r.len() >= 10).then(|| (r.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / r.len() as f64).sqrt() * 1e3)
}

/// The rows after the first row at the log's highest temperature, when `after-max` holds
/// there; else every row. With the last training row.
fn later_leg(log: &StaticLog) -> (std::ops::Range<usize>, Option<usize>) {
    let opts = StaticCalOptions::default();
    match resolve_holdout(log, Holdout::Auto, opts.block) {
        Ok((Scheme::AfterMax { last }, _)) => (last + 1..log.rows(), Some(last)),
        _ => (0..log.rows(), None),
    }
}

fn geo(v: &[f64]) -> f64 {
    (v.iter().map(|x| x.ln()).sum::<f64>() / v.len() as f64).exp()
}

fn main() {
    let seeds: Vec<u64> = std::env::var("QFA_STUDY_SEEDS").map_or_else(
        |_| (11..=19).collect(),
        |v| v.split(',').map(|x| x.parse().expect("QFA_STUDY_SEEDS: numbers")).collect(),
    );
    let mut cases: Vec<(String, StaticLog, Option<StaticLog>)> = Vec::new();
    if let Some(log) = common::real_static_log() {
        cases.push(("real".into(), log, None));
    }
    for &seed in &seeds {
        for e in [None, Some("sensor_lag"), Some("bias_creep"), Some("bias_branch_hysteresis")] {
            let fresh = chamber_log(e, seed + 1000);
            cases.push((format!("sim {} s{seed}", e.unwrap_or("none")), chamber_log(e, seed), Some(fresh)));
        }
    }
    let desk = |seed: u64| read_static_from(truth::desk(58.0, seed).as_bytes(), &StaticOptions::default()).unwrap();
    for seed in 2..=6 {
        cases.push((format!("desk s{seed}"), desk(seed), Some(desk(seed + 1000))));
    }
    println!("case axis | table (set 0) | fold's choice | held out A / B / C mg | fresh: table A=B / C mg");
    let (mut fresh_ratio, mut pred) = (Vec::new(), [Vec::new(), Vec::new(), Vec::new()]);
    let (mut differ, mut axes, mut b_better, mut c_better) = (0usize, 0usize, 0usize, 0usize);
    for (name, log, fresh) in &cases {
        let (leg, last) = later_leg(log);
        let Some(last) = last else {
            println!("{name}: no later leg, skipped");
            continue;
        };
        let cal = calibrate_static(log, &StaticCalOptions::default(), false).expect("calibrate");
        let train: Vec<bool> = (0..log.rows()).map(|i| i <= last).collect();
        let train_rows: Vec<usize> = (0..=last).collect();
        let every = vec![true; log.rows()];
        for (a, ax) in log.axes.iter().enumerate() {
            let (Some(t0), Some(t1)) = (cal.paths[a].last(), fold_choice(log, a, &train_rows)) else { continue };
            let t0 = t0.structure;
            let held =
                |st: &StaticStructure| fit(log, a, st, &train).and_then(|f| rms_on(log, a, &f, leg.clone(), false));
            let (Some(ha), Some(hb)) = (held(&t1), held(&t0)) else { continue };
            let hc = ha;
            let fresh_fig = |st: &StaticStructure| {
                let f = fit(log, a, st, &every)?;
                let fr = fresh.as_ref()?;
                rms_on(fr, a, &f, later_leg(fr).0, true)
            };
            let (fa, fc) = (fresh_fig(&t0), fresh_fig(&t1));
            let show = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{v:.4}"));
            println!(
                "{name} {} | {} | {} | {ha:.4} / {hb:.4} / {hc:.4} | {} / {}",
                ax.name,
                t0.name(),
                t1.name(),
                show(fa),
                show(fc)
            );
            let (Some(fa), Some(fc)) = (fa, fc) else { continue };
            axes += 1;
            pred[0].push(ha / fa);
            pred[1].push(hb / fa);
            pred[2].push(hc / fc);
            if t0 != t1 {
                differ += 1;
                fresh_ratio.push(fa / fc);
                b_better += usize::from(fa < fc);
                c_better += usize::from(fc < fa);
            }
        }
    }
    println!("axes with a fresh log: {axes}; the two choices differ on {differ}");
    if !fresh_ratio.is_empty() {
        println!(
            "where they differ, fresh RMS of the set-0 table over the fold-choice table: geometric mean {:.3}; \
             set 0 better on {b_better}, the fold's choice on {c_better}",
            geo(&fresh_ratio)
        );
    }
    for (k, rule) in
        ["A (fold's own choice)", "B (table's structure on the training rows)", "C (fold's choice as the table)"]
            .iter()
            .enumerate()
    {
        let logs: Vec<f64> = pred[k].iter().map(|x| x.ln().abs()).collect();
        println!(
            "{rule}: held out / fresh, geometric mean {:.3}, mean |log| {:.3}",
            geo(&pred[k]),
            logs.iter().sum::<f64>() / logs.len().max(1) as f64
        );
    }
}
