//! Study: which rule, applied to static calibration's cross-validation inside the training
//! rows, chooses the structure that predicts the later leg best. For every axis of every
//! case it scores every structure of the lattice (curve shape × branch tie × lag × creep)
//! held out (fitted on the rows up to the highest temperature, scored on the rest), and
//! prints the held-out RMS of what each rule chooses against the best any structure gives.
//!
//! Cases: the real chamber log (`QFA_REAL_LOG`, else the shared folder beside the
//! repository), the simulator's chamber cycle with each hidden effect (seeds 11–13), and the
//! independent desk generator (seeds 1–2; seed 1's log has no later leg and is skipped).
//! `QFA_STUDY_SEEDS=14,15` draws the simulator's cases from other seeds.
//! `cargo xtask experiment selection_study` (about 8 s in release). Prints one line per axis
//! (the oracle, the best any structure gives held out, then each rule's pick), and per rule
//! the geometric mean over axes of its held-out RMS over the oracle's, and on how many clean
//! axes (nothing hidden, the desk logs) it added any part to its start. The figures are in
//! docs/measurements.md ("Real data").

#[path = "../tests/chamber/mod.rs"]
mod chamber;
mod common;
#[path = "../tests/truth/mod.rs"]
mod truth;

use chamber::chamber_log;

use qfa_calibrate::fit::{fit_static_traced, BranchMode, CurveShape, StaticSeries, StaticStructure, StaticTraces};
use qfa_calibrate::static_cal::{
    cv_fold_sums_axes, resolve_holdout, CvOrder, FoldSums, Holdout, Scheme, StaticCalOptions,
};
use qfa_log::static_log::{read_static_from, StaticLog, StaticOptions};

fn lattice() -> Vec<StaticStructure> {
    let mut out = Vec::new();
    for shape in [CurveShape::Cubic, CurveShape::Nodes] {
        for branches in [BranchMode::Single, BranchMode::Offset, BranchMode::Free] {
            for lag in [None, Some(30.0), Some(60.0), Some(120.0), Some(240.0), Some(480.0)] {
                for creep in [None, Some(60.0), Some(180.0), Some(600.0)] {
                    out.push(StaticStructure {
                        shape,
                        branches,
                        lag_tau_s: lag,
                        creep_tau_s: creep,
                        play_half_width_c: None,
                    });
                }
            }
        }
    }
    out
}

/// Per axis and structure: CV fold sums (both orders) on the training rows, and the held-out
/// mean square on the later leg.
struct Scores {
    both: Vec<Vec<Option<FoldSums>>>,
    forward: Vec<Vec<Option<FoldSums>>>,
    held: Vec<Vec<Option<f64>>>,
    /// Leg-forward MSE inside the training rows: fitted on the rows before the training
    /// rows' coldest row (their last turning point), scored on the rows after it inside the
    /// fit's range.
    leg: Vec<Vec<Option<f64>>>,
}

fn scores(log: &StaticLog, lat: &[StaticStructure]) -> Option<Scores> {
    let opts = StaticCalOptions::default();
    let (scheme, _) = resolve_holdout(log, Holdout::Auto, opts.block).ok()?;
    let Scheme::AfterMax { last } = scheme else { return None };
    let n = log.rows();
    let view = StaticSeries::view_of(&log.time_s, &log.temp_c, opts.deadband_c_per_min);
    let axes: Vec<StaticSeries<'_>> =
        log.axes.iter().map(|a| StaticSeries { view: &view, accel_g: &a.accel_g }).collect();
    let train: Vec<usize> = (0..=last).collect();
    let mask: Vec<bool> = (0..n).map(|i| i <= last).collect();
    let na = axes.len();
    let mut s =
        Scores { both: vec![vec![]; na], forward: vec![vec![]; na], held: vec![vec![]; na], leg: vec![vec![]; na] };
    let turn = (0..=last).fold(0, |b, i| if log.temp_c[i] < log.temp_c[b] { i } else { b });
    let leg_ok = turn * 10 >= last && (last - turn) * 10 >= last;
    let before: Vec<bool> = (0..n).map(|i| i < turn).collect();
    for st in lat {
        let traces = StaticTraces::new(&axes[0], st, opts.deadband_c_per_min);
        let b = cv_fold_sums_axes(&axes, &traces, &train, 5, CvOrder::Both, &opts);
        let f = cv_fold_sums_axes(&axes, &traces, &train, 5, CvOrder::Forward, &opts);
        for a in 0..na {
            s.both[a].push(b[a].clone().ok());
            s.forward[a].push(f[a].clone().ok());
            let h = fit_static_traced(&axes[a], &traces, &mask, opts.grid_points, opts.block).ok().map(|fit| {
                let tr = axes[a].model_trace(&fit.axis);
                let r: Vec<f64> = (last + 1..n)
                    .filter(|&i| tr.valid[i])
                    .map(|i| axes[a].accel_g[i] - fit.reference_g - tr.ext_k0_g[i])
                    .collect();
                r.iter().map(|x| x * x).sum::<f64>() / r.len() as f64
            });
            s.held[a].push(h);
            let l = leg_ok
                .then(|| fit_static_traced(&axes[a], &traces, &before, opts.grid_points, opts.block).ok())
                .flatten()
                .and_then(|fit| {
                    let tr = axes[a].model_trace(&fit.axis);
                    let (lo, hi) = (f64::from(fit.axis.bias.t_start_c), f64::from(fit.axis.bias.t_end_c()));
                    let r: Vec<f64> = (turn..=last)
                        .filter(|&i| tr.valid[i] && (lo..=hi).contains(&tr.temp_c[i]))
                        .map(|i| axes[a].accel_g[i] - fit.reference_g - tr.ext_k0_g[i])
                        .collect();
                    (r.len() >= 10).then(|| r.iter().map(|x| x * x).sum::<f64>() / r.len() as f64)
                });
            s.leg[a].push(l);
        }
    }
    Some(s)
}

fn mse(f: &FoldSums) -> f64 {
    f.total.0 / f.total.1 as f64
}

/// Per-fold MSEs of the folds that scored rows (a fold whose rows all lie outside its
/// fit's grid scores none, and has no MSE).
fn fold_mses(f: &FoldSums) -> Vec<f64> {
    f.folds.iter().filter(|&&(_, c)| c > 0).map(|&(s, c)| s / c as f64).collect()
}

fn unknowns(st: &StaticStructure) -> usize {
    let g = 16;
    let shape = match st.shape {
        CurveShape::Nodes => g,
        CurveShape::Cubic => 4,
    };
    let b = match st.branches {
        BranchMode::Single => shape,
        BranchMode::Offset => shape + 1,
        BranchMode::Free => 2 * shape,
    };
    b + usize::from(st.creep_tau_s.is_some()) + usize::from(st.lag_tau_s.is_some())
}

/// Lowest CV.
fn lowest(cv: &[Option<FoldSums>], allowed: &dyn Fn(usize) -> bool) -> Option<usize> {
    (0..cv.len())
        .filter(|&i| allowed(i) && cv[i].is_some())
        .min_by(|&a, &b| mse(cv[a].as_ref().unwrap()).total_cmp(&mse(cv[b].as_ref().unwrap())))
}

/// Classic one-SE (unpaired) over fold MSEs.
fn one_se(cv: &[Option<FoldSums>], lat: &[StaticStructure]) -> Option<usize> {
    let best = lowest(cv, &|_| true)?;
    let fm = fold_mses(cv[best].as_ref().unwrap());
    let k = fm.len() as f64;
    let m = fm.iter().sum::<f64>() / k;
    let se = (fm.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (k - 1.0) / k).sqrt();
    let lim = mse(cv[best].as_ref().unwrap()) + se;
    (0..cv.len()).filter(|&i| cv[i].as_ref().is_some_and(|f| mse(f) <= lim)).min_by(|&a, &b| {
        unknowns(&lat[a])
            .cmp(&unknowns(&lat[b]))
            .then(mse(cv[a].as_ref().unwrap()).total_cmp(&mse(cv[b].as_ref().unwrap())))
    })
}

/// Neighbours of `st` in the lattice: one dimension moved up.
fn is_step(from: &StaticStructure, to: &StaticStructure) -> bool {
    let mut diffs = 0;
    if from.shape != to.shape {
        if !(from.shape == CurveShape::Cubic && to.shape == CurveShape::Nodes) {
            return false;
        }
        diffs += 1;
    }
    if from.branches != to.branches {
        let ord = |b: BranchMode| match b {
            BranchMode::Single => 0,
            BranchMode::Offset => 1,
            BranchMode::Free => 2,
        };
        if ord(to.branches) <= ord(from.branches) {
            return false;
        }
        diffs += 1;
    }
    if from.lag_tau_s != to.lag_tau_s {
        if from.lag_tau_s.is_some() {
            return false;
        }
        diffs += 1;
    }
    if from.creep_tau_s != to.creep_tau_s {
        if from.creep_tau_s.is_some() {
            return false;
        }
        diffs += 1;
    }
    diffs == 1
}

/// Stepwise from `start`: take the neighbour with the lowest CV when its paired gain over
/// the current structure's folds exceeds `z` standard errors of the per-fold gains.
fn stepwise(cv: &[Option<FoldSums>], lat: &[StaticStructure], start: usize, z: f64) -> Option<usize> {
    let mut cur = start;
    cv[cur].as_ref()?;
    loop {
        let c = fold_mses(cv[cur].as_ref().unwrap());
        let mut best: Option<(usize, f64)> = None;
        for j in 0..lat.len() {
            if !is_step(&lat[cur], &lat[j]) {
                continue;
            }
            let Some(fj) = cv[j].as_ref() else { continue };
            let m = mse(fj);
            if best.is_none_or(|(_, b)| m < b) {
                best = Some((j, m));
            }
        }
        let Some((j, _)) = best else { return Some(cur) };
        let g: Vec<f64> = c.iter().zip(fold_mses(cv[j].as_ref().unwrap())).map(|(a, b)| a - b).collect();
        let k = g.len() as f64;
        let mean = g.iter().sum::<f64>() / k;
        let se = (g.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (k - 1.0) / k).sqrt();
        if mean > z * se && mse(cv[j].as_ref().unwrap()) < mse(cv[cur].as_ref().unwrap()) {
            cur = j;
        } else {
            return Some(cur);
        }
    }
}

/// Parts of a structure, as (branch level, lag, creep).
fn parts(st: &StaticStructure) -> (usize, Option<f32>, Option<f32>) {
    let b = match st.branches {
        BranchMode::Single => 0,
        BranchMode::Offset => 1,
        BranchMode::Free => 2,
    };
    (b, st.lag_tau_s, st.creep_tau_s)
}

fn below(x: &StaticStructure, goal: &StaticStructure) -> bool {
    let (xb, xl, xc) = parts(x);
    let (gb, gl, gc) = parts(goal);
    x.shape == goal.shape && xb <= gb && (xl.is_none() || xl == gl) && (xc.is_none() || xc == gc)
}

/// Calibrate's search (lowest blocked CV among grid structures), its path walked from the
/// plain grid one part at a time (lowest CV first); `mode` 0 stops at the first step that
/// raises the leg-forward figure, 1 skips such a step's structure and goes on, 2 takes the
/// path's structure with the lowest leg-forward figure. A step whose figure cannot be
/// computed (a branch the earlier leg lacks) is kept.
fn leg_judged(s: &Scores, a: usize, lat: &[StaticStructure], plain: usize, mode: u8) -> Option<usize> {
    let best = lowest(&s.both[a], &|i| lat[i].shape == CurveShape::Nodes)?;
    let goal = lat[best];
    let cv = |i: usize| s.both[a][i].as_ref().map(mse);
    let mut path = vec![plain];
    while *path.last().unwrap() != best {
        let at = lat[*path.last().unwrap()];
        let next = (0..lat.len())
            .filter(|&j| below(&lat[j], &goal) || j == best)
            .filter(|&j| is_step(&at, &lat[j]) && cv(j).is_some())
            .min_by(|&x, &y| cv(x).unwrap().total_cmp(&cv(y).unwrap()));
        match next {
            Some(j) => path.push(j),
            None => path.push(best),
        }
    }
    let leg = |i: usize| s.leg[a][i];
    match mode {
        0 => {
            let mut cur = path[0];
            for &j in &path[1..] {
                match (leg(cur), leg(j)) {
                    (Some(x), Some(y)) if y > x => return Some(cur),
                    _ => cur = j,
                }
            }
            Some(cur)
        }
        2 => path
            .iter()
            .copied()
            .filter(|&i| leg(i).is_some())
            .min_by(|&x, &y| leg(x).unwrap().total_cmp(&leg(y).unwrap()))
            .or(Some(best)),
        _ => {
            // Skip a raising step: carry on from the current structure with the remaining parts.
            let mut cur = path[0];
            for w in path.windows(2) {
                let (pb, pl, pc) = parts(&lat[w[0]]);
                let (nb, nl, nc) = parts(&lat[w[1]]);
                let (cb, cl, cc) = parts(&lat[cur]);
                let cand = (
                    cb.max(if nb > pb { nb } else { cb }),
                    if nl != pl { nl } else { cl },
                    if nc != pc { nc } else { cc },
                );
                let Some(j) = (0..lat.len()).find(|&j| lat[j].shape == CurveShape::Nodes && parts(&lat[j]) == cand)
                else {
                    continue;
                };
                match (leg(cur), leg(j)) {
                    (Some(x), Some(y)) if y > x => {}
                    _ if cv(j).is_some() => cur = j,
                    _ => {}
                }
            }
            Some(cur)
        }
    }
}

/// A selection rule: the structure it picks for an axis.
type Rule<'a> = Box<dyn Fn(&Scores, usize) -> Option<usize> + 'a>;

fn main() {
    let lat = lattice();
    let nodes_only = |i: usize| lat[i].shape == CurveShape::Nodes;
    let plain = lat.iter().position(|s| s.shape == CurveShape::Nodes && *s == StaticStructure::PLAIN).unwrap();
    let cubic0 = lat
        .iter()
        .position(|s| {
            s.shape == CurveShape::Cubic
                && s.branches == BranchMode::Single
                && s.lag_tau_s.is_none()
                && s.creep_tau_s.is_none()
        })
        .unwrap();
    let mut cases: Vec<(String, StaticLog)> = Vec::new();
    if let Some(log) = common::real_static_log() {
        cases.push(("real".into(), log));
    }
    let seeds: Vec<u64> = std::env::var("QFA_STUDY_SEEDS").map_or_else(
        |_| vec![11, 12, 13],
        |v| v.split(',').map(|x| x.parse().expect("QFA_STUDY_SEEDS: numbers")).collect(),
    );
    for &seed in &seeds {
        for e in [None, Some("sensor_lag"), Some("bias_creep"), Some("bias_branch_hysteresis")] {
            cases.push((format!("sim {} s{seed}", e.unwrap_or("none")), chamber_log(e, seed)));
        }
    }
    for seed in [1, 2] {
        let text = truth::desk(58.0, seed);
        cases.push((format!("desk s{seed}"), read_static_from(text.as_bytes(), &StaticOptions::default()).unwrap()));
    }
    let rules: Vec<(&str, Rule<'_>)> = vec![
        ("lowest CV, grid (calibrate's search)", Box::new(|s: &Scores, a| lowest(&s.both[a], &nodes_only))),
        (
            "search, stop at a step that raises the leg-forward figure",
            Box::new(|s: &Scores, a| leg_judged(s, a, &lat, plain, 0)),
        ),
        (
            "search, skip steps that raise the leg-forward figure",
            Box::new(|s: &Scores, a| leg_judged(s, a, &lat, plain, 1)),
        ),
        ("search path, lowest leg-forward figure", Box::new(|s: &Scores, a| leg_judged(s, a, &lat, plain, 2))),
        ("lowest forward CV, grid", Box::new(|s: &Scores, a| lowest(&s.forward[a], &nodes_only))),
        ("lowest CV, grid and cubic", Box::new(|s: &Scores, a| lowest(&s.both[a], &|_| true))),
        ("lowest forward CV, grid and cubic", Box::new(|s: &Scores, a| lowest(&s.forward[a], &|_| true))),
        ("one-SE rule, grid and cubic", Box::new(|s: &Scores, a| one_se(&s.both[a], &lat))),
        (
            "one-SE rule, grid",
            Box::new(|s: &Scores, a| {
                let g: Vec<Option<FoldSums>> =
                    s.both[a].iter().enumerate().map(|(i, f)| f.clone().filter(|_| nodes_only(i))).collect();
                one_se(&g, &lat)
            }),
        ),
        ("stepwise from the grid, any CV drop", Box::new(|s: &Scores, a| stepwise(&s.both[a], &lat, plain, 0.0))),
        (
            "stepwise from the grid, paired gain > 0.5 SE",
            Box::new(|s: &Scores, a| stepwise(&s.both[a], &lat, plain, 0.5)),
        ),
        (
            "stepwise from the grid, paired gain > 1 SE",
            Box::new(|s: &Scores, a| stepwise(&s.both[a], &lat, plain, 1.0)),
        ),
        (
            "stepwise from the grid, paired gain > 2 SE",
            Box::new(|s: &Scores, a| stepwise(&s.both[a], &lat, plain, 2.0)),
        ),
        (
            "stepwise from the grid, forward CV, > 1 SE",
            Box::new(|s: &Scores, a| stepwise(&s.forward[a], &lat, plain, 1.0)),
        ),
        ("stepwise from the cubic, > 1 SE", Box::new(|s: &Scores, a| stepwise(&s.both[a], &lat, cubic0, 1.0))),
        (
            "stepwise from the cubic, forward CV, > 1 SE",
            Box::new(|s: &Scores, a| stepwise(&s.forward[a], &lat, cubic0, 1.0)),
        ),
        ("stepwise from the cubic, > 2 SE", Box::new(|s: &Scores, a| stepwise(&s.both[a], &lat, cubic0, 2.0))),
        ("stepwise from the cubic, any CV drop", Box::new(|s: &Scores, a| stepwise(&s.both[a], &lat, cubic0, 0.0))),
    ];
    let mut totals = vec![0.0; rules.len()];
    let mut picked = vec![0usize; rules.len()];
    let mut clean_named = vec![0usize; rules.len()];
    let mut clean_axes = 0usize;
    let mut count = 0;
    for (name, log) in &cases {
        let Some(s) = scores(log, &lat) else {
            println!("{name}: no after-max leg");
            continue;
        };
        for (a, ax) in log.axes.iter().enumerate() {
            let oracle =
                (0..lat.len()).filter_map(|i| s.held[a][i].map(|h| (i, h))).min_by(|x, y| x.1.total_cmp(&y.1)).unwrap();
            let mut line =
                format!("{name} {}: oracle {:.4} mg ({})", ax.name, oracle.1.sqrt() * 1e3, lat[oracle.0].name());
            for (r, (rn, rule)) in rules.iter().enumerate() {
                match rule(&s, a) {
                    Some(i) => {
                        let h = s.held[a][i].unwrap_or(f64::NAN).sqrt();
                        totals[r] += (h * h / oracle.1).ln();
                        picked[r] += 1;
                        let clean = name.contains("none") || name.contains("desk");
                        let base = if lat[i].shape == CurveShape::Cubic { cubic0 } else { plain };
                        if clean && i != base {
                            clean_named[r] += 1;
                        }
                        line.push_str(&format!(" | {rn} {:.4} {}", h * 1e3, lat[i].name()));
                    }
                    None => line.push_str(&format!(" | {rn} none")),
                }
            }
            count += 1;
            clean_axes += usize::from(name.contains("none") || name.contains("desk"));
            println!("{line}");
        }
    }
    for (r, (rn, _)) in rules.iter().enumerate() {
        println!(
            "rule=\"{rn}\" geo_mean_ratio_to_oracle={:.4} axes_picked={} of {count} clean_axes_with_a_part_added={} of {clean_axes}",
            (totals[r] / picked[r] as f64 / 2.0).exp(),
            picked[r],
            clean_named[r]
        );
    }
}
