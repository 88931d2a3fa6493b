//! Discovery on a static multi-axis log (a board at rest in a chamber): each axis is a
//! single-channel bias log, on the same documented split as static calibration.
//!
//! # Split (the one of [`crate::calibrate::static_cal`])
//! Fit on every row up to the first row at the log's highest temperature, hold out the
//! rest. Everything discovery decides (start-model fit, candidates, block tests, the final
//! fit) sees only the training rows: the training rows are cut out as their own
//! single-channel log and run through [`super::analyze`], whose own held-out rule (time
//! blocks inside that log) drives the selection. The model and the estimator are causal,
//! so cutting the log at the split is the same as masking the later rows.
//!
//! # Figures
//! Per axis, on the held-out rows, in mg (RMS over rows, and over 60-s means): the start
//! model and the discovered model (both fitted on every training bin, run through the root
//! crate's `AxisModel::evaluate` on every row, `bias_drift` added when it was named), and
//! beside them the peers of [`crate::calibrate::peers`] fitted on the same training rows
//! and scored on the same held-out rows, exactly as `calibrate` scores them. A figure that
//! cannot be formed is an error.
//!
//! # Table: what is named and what is flashed
//! The block test decides what is *named*: a claim about the physics, made only when it is
//! significant, with the false-discovery rate the README states. What is *flashed*
//! (`DIR/table.bin`, what `qfa-lab compensate` loads) is a prediction: static
//! calibration's cross-validated choice (the same 5-fold blocked CV inside the training
//! rows, the same one fitter) among its candidates plus every structure discovery named
//! on any axis ([`structure_of`]). On a short log the two differ: the tofupilot log's
//! 52-min training leg gives the block test 8 blocks, too few to name effects that still
//! predict better. The report gives both, and says which structure was flashed and
//! whether discovery named it. Static tables have K1 = 2²⁰ LSB/g
//! ([`crate::calibrate::fit::STATIC_LSB_PER_G`]) and the bias in g from the axis's
//! training mean.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use qfa_thermal::model::{AxisModel, AxisState};
use serde::Serialize;

use super::{analyze, start_model, Channels, LogKind, Report, Start};
use crate::calibrate::fit::{encode, BranchMode, CurveShape, StaticStructure};
use crate::calibrate::peers::{PeerKind, Poly};
use crate::calibrate::static_cal::{calibrate_static, StaticCalOptions};
use crate::calibrate::static_cal::{score, split_index, Score};
use crate::data::channels::Trace;
use crate::data::static_log::StaticLog;

/// Bin width for a static log, s: about 400 bins over the log, between 10 and 60 s. A
/// chamber log of a few hours gets the cycling logs' 60-s bins; the tofupilot log (70.7
/// min) gets 10-s bins, since at 60 s its 52 training bins could not hold a 16-node grid
/// and a lag or creep of tens of seconds (what static calibration finds there) would be
/// averaged away. (This rule was fixed before the first run on the real log; widths of
/// 5, 20, 30 and 60 s were tried afterwards only to measure how much the answer depends on
/// it: see the README.)
#[must_use]
pub fn bin_width_s(duration_s: f64) -> f64 {
    (duration_s / 400.0).round().clamp(10.0, 60.0)
}

/// One axis on the documented split.
#[derive(Clone, Debug, Serialize)]
pub struct AxisDiscovery {
    /// Role (`ax`, `ay`, `az`).
    pub axis: String,
    /// Column in the file.
    pub column: String,
    /// Training mean the bias is measured from, g.
    pub reference_g: f64,
    /// Effects named, `name (channel)`, in order (empty: none).
    pub effects: Vec<String>,
    /// Effects named but not in `table.bin` (no root-crate slot).
    pub not_in_table: Vec<String>,
    /// Unexplained structure left in the training residual, in words.
    pub unexplained: Vec<String>,
    /// Start model on the held-out rows.
    pub before: Score,
    /// Discovered model on the held-out rows.
    pub after: Score,
    /// The structure discovery named, as the one static fitter writes it (`bias_drift`,
    /// which has no slot, and a creep's activation energy dropped).
    pub named_structure: String,
    /// The workflow's model, the one in `table.bin`: the lowest cross-validation RMS inside
    /// the training rows among static calibration's candidates and every axis's named
    /// structure (see the module docs).
    pub final_structure: String,
    /// Whether that is a structure discovery named (else one of calibration's candidates).
    pub final_is_named: bool,
    /// Its cross-validation RMS on the training rows, mg.
    pub final_cv_rms_mg: f64,
    /// The workflow's model on the held-out rows.
    pub final_model: Score,
    /// PX4 / tofupilot cubic.
    pub cubic: Score,
    /// ArduPilot TCAL.
    pub ardupilot: Score,
    /// The paper's simple model (linear in T).
    pub simple: Score,
    /// No compensation (training mean removed).
    pub none: Score,
}

/// `DIR/report.json` of a static discovery.
#[derive(Clone, Debug, Serialize)]
pub struct StaticDiscovery {
    /// Start model.
    pub start: Start,
    /// The split, in words.
    pub split: String,
    /// Time of the last training row, s.
    pub split_time_s: f64,
    /// Bin width of the discovery channels, s.
    pub bin_s: f64,
    /// Per axis.
    pub axes: Vec<AxisDiscovery>,
    /// Each axis's full discovery report (selection inside the training rows).
    #[serde(skip)]
    pub reports: Vec<Report>,
    /// Each axis's training channels (what its report was formed from).
    #[serde(skip)]
    pub channels: Vec<Channels>,
    /// The workflow's table (one axis per log axis).
    #[serde(skip)]
    pub table: qfa_thermal::Table,
}

/// The static fitter's structure for a discovered model: one bias curve (discovery's grid
/// is single-valued) with its lag, play and creep slots. A creep's activation energy is
/// dropped (the static fitter's creep has a constant τ) and `bias_drift` has no slot.
#[must_use]
pub fn structure_of(m: &AxisModel) -> StaticStructure {
    StaticStructure {
        shape: CurveShape::Nodes,
        branches: BranchMode::Single,
        lag_tau_s: m.ext.sensor_lag.map(|l| l.tau_s),
        creep_tau_s: m.ext.bias_creep.map(|c| c.tau_ref_s),
        play_half_width_c: m.ext.bias_branch_hysteresis.map(|h| h.half_width_c),
    }
}

/// Multiply every bias term of `m` (grid, play weight, creep gain) by `k`.
fn scale_bias(m: &mut AxisModel, k: f32) {
    for v in m.bias.heating_g.iter_mut().chain(m.bias.cooling_g.iter_mut()) {
        *v *= k;
    }
    if let Some(h) = m.ext.bias_branch_hysteresis.as_mut() {
        h.weight_g *= k;
    }
    if let Some(c) = m.ext.bias_creep.as_mut() {
        c.gain_g_per_c *= k;
    }
}

fn rows_of(log: &StaticLog, end: usize) -> Vec<(f64, f32)> {
    log.time_s[..end].iter().zip(&log.temp_c[..end]).map(|(&t, &c)| (t, c as f32)).collect()
}

/// Per-row K0 (g) of `model` over the whole log, plus `drift_per_h`·(hours since the first
/// row the estimator kept); `None` before the estimator's first output.
fn row_bias(log: &StaticLog, model: &AxisModel, drift_per_h: f64, bin_s: f64) -> Vec<Option<f64>> {
    let n = log.rows();
    let zeros = vec![0.0; n];
    let tr = Trace::new(String::new(), &rows_of(log, n), None, &zeros, bin_s);
    let mut out = vec![None; n];
    let mut st = AxisState::default();
    let t0 = tr.time_s.first().copied().unwrap_or(0.0);
    let mut i = 0;
    for j in 0..tr.time_s.len() {
        let e = model.evaluate(&mut st, tr.est_t[j], tr.est_rate[j], tr.dt_s[j]);
        // The trace keeps a subset of the rows, in order, with their times unchanged.
        while i < n && log.time_s[i] != tr.time_s[j] {
            i += 1;
        }
        if i < n {
            out[i] = Some(f64::from(e.k0) + drift_per_h * (tr.time_s[j] - t0) / 3600.0);
        }
    }
    out
}

/// Discover each axis of `log` on the documented split; see the module docs.
///
/// # Errors
/// A split that leaves nothing to evaluate, a peer that cannot be fitted, or a figure that
/// cannot be formed.
pub fn discover_static(log: &StaticLog, start: Start) -> Result<StaticDiscovery> {
    let last = split_index(log)?;
    let n = log.rows();
    let duration = log.time_s[n - 1] - log.time_s[0];
    let bin_s = bin_width_s(duration);
    let ho: Vec<usize> = (last + 1..n).collect();
    let ho_t: Vec<f64> = ho.iter().map(|&i| log.time_s[i]).collect();
    let mut axes = Vec::new();
    let mut reports = Vec::new();
    let mut channels = Vec::new();
    for ax in &log.axes {
        let reference = ax.accel_g[..=last].iter().sum::<f64>() / (last + 1) as f64;
        let value: Vec<f64> = ax.accel_g[..=last].iter().map(|a| a - reference).collect();
        // Discovery runs in µg, so its per-axis reports read in µg; the models go back to g.
        let value_ug: Vec<f64> = value.iter().map(|v| v * 1e6).collect();
        let ch = Channels {
            kind: LogKind::Single,
            traces: vec![Trace::new(ax.name.clone(), &rows_of(log, last + 1), None, &value_ug, bin_s)],
        };
        let mut r = analyze(&ch, start);
        if let Some(m) = r.model.as_mut() {
            scale_bias(m, 1e-6);
        }
        let mut base = start_model(&ch, start);
        scale_bias(&mut base, 1e-6);
        let disc = r.model.clone().context("discovery gave no model")?;
        let drift = 1e-6 * r.effects.iter().find_map(|e| e.params.get("drift_g_per_h").copied()).unwrap_or(0.0);
        let name = |w: &str| format!("{} {w}", ax.name);
        let ours = |m: &AxisModel, d: f64, what: &str| -> Result<Score> {
            let b = row_bias(log, m, d, bin_s);
            let (res, t): (Vec<f64>, Vec<f64>) =
                ho.iter().filter_map(|&i| b[i].map(|k0| (ax.accel_g[i] - reference - k0, log.time_s[i]))).unzip();
            Ok(score(&res, &t, &name(what))?)
        };
        let tt = &log.temp_c[..=last];
        let peer = |k: PeerKind| -> Result<Score> {
            let p: Poly = k.fit(tt, &value).map_err(|e| anyhow::anyhow!("{}: {e}", name(k.label())))?;
            let res: Vec<f64> = ho.iter().map(|&i| ax.accel_g[i] - reference - p.eval(log.temp_c[i])).collect();
            Ok(score(&res, &ho_t, &name(k.label()))?)
        };
        let none: Vec<f64> = ho.iter().map(|&i| ax.accel_g[i] - reference).collect();
        axes.push(AxisDiscovery {
            axis: ax.name.clone(),
            column: ax.column.clone(),
            reference_g: reference,
            effects: r.effect_labels(),
            not_in_table: r.effects.iter().filter(|e| !e.in_table).map(|e| e.name.clone()).collect(),
            unexplained: r
                .unexplained
                .iter()
                .map(|u| {
                    let mut s = u.correlates_with.join(", ");
                    if !u.pinned.is_empty() {
                        let _ = write!(s, "{}pinned: {}", if s.is_empty() { "" } else { "; " }, u.pinned.join("; "));
                    }
                    s
                })
                .collect(),
            before: ours(&base, 0.0, "start model")?,
            after: ours(&disc, drift, "discovered model")?,
            named_structure: structure_of(&disc).name(),
            // Filled in below, once every axis's named structure is known.
            final_structure: String::new(),
            final_is_named: false,
            final_cv_rms_mg: 0.0,
            final_model: Score { rms_mg: 0.0, binned_mg: 0.0 },
            cubic: peer(PeerKind::Cubic)?,
            ardupilot: peer(PeerKind::Ardupilot)?,
            simple: peer(PeerKind::Simple)?,
            none: score(&none, &ho_t, &name("none"))?,
        });
        reports.push(r);
        channels.push(ch);
    }
    // The model: static calibration's cross-validated choice, with every structure
    // discovery named on any axis added to its candidates. The block test decides what is
    // *named* (a claim about the physics, with a known false-discovery rate); the
    // cross-validation decides what is *flashed* (a prediction). On a short log the two
    // differ: the test may lack the power to name what still predicts better.
    let mut opts = StaticCalOptions::default();
    for r in &reports {
        let st = structure_of(r.model.as_ref().context("discovery gave no model")?);
        if !opts.candidates.contains(&st) {
            opts.candidates.push(st);
        }
    }
    let cal = calibrate_static(log, &opts, false).map_err(|e| anyhow::anyhow!("{e}"))?;
    for (a, c) in axes.iter_mut().zip(&cal.report.axes) {
        a.final_is_named = c.structure == a.named_structure;
        a.final_structure.clone_from(&c.structure);
        a.final_cv_rms_mg = c.cv_rms_mg;
        a.final_model = c.ours;
    }
    Ok(StaticDiscovery {
        table: cal.table,
        start,
        // The split is calibration's own (same `split_index`), so its words are too.
        split: cal.report.split.clone(),
        split_time_s: cal.report.split_time_s,
        bin_s,
        axes,
        reports,
        channels,
    })
}

/// The per-axis table in Markdown (mg).
#[must_use]
pub fn markdown(d: &StaticDiscovery) -> String {
    let mut s = String::from("# Discovery on a static log\n\n");
    let _ = writeln!(
        s,
        "Split: {}. Start model `{}`; {}-s bins; the per-axis reports are in µg.\n",
        d.split,
        d.start.name(),
        d.bin_s
    );
    s.push_str(
        "Selection sees only the training rows (its own time-block held-out rule inside them); every figure \
         below is on the held-out rows, RMS over rows / over 60-s means, mg. Peers fitted on the same training \
         rows, as `calibrate` fits them.\n\n",
    );
    s.push_str("| axis | effects named | start model | discovered | model in `table.bin` (structure) | PX4/tofupilot cubic | ArduPilot TCAL | paper simple | none |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|\n");
    let f = |x: &Score| format!("{:.2} / {:.2}", x.rms_mg, x.binned_mg);
    for a in &d.axes {
        let mut names = if a.effects.is_empty() { "none".to_string() } else { a.effects.join(", ") };
        if !a.unexplained.is_empty() {
            let _ = write!(names, "; unexplained: {}", a.unexplained.join("; "));
        }
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} ({}{}) | {} | {} | {} | {} |",
            a.axis,
            names,
            f(&a.before),
            f(&a.after),
            f(&a.final_model),
            a.final_structure,
            if a.final_is_named { ", the named structure" } else { "" },
            f(&a.cubic),
            f(&a.ardupilot),
            f(&a.simple),
            f(&a.none)
        );
    }
    s.push_str(
        "\nNamed: the block test inside the training rows (a claim about the physics). Flashed (`table.bin`): the \
         lowest 5-fold cross-validation RMS inside the training rows among static calibration's candidates and the \
         named structures (a prediction).\n",
    );
    let missing: Vec<String> = d
        .axes
        .iter()
        .filter(|a| !a.not_in_table.is_empty())
        .map(|a| format!("{}: {}", a.axis, a.not_in_table.join(", ")))
        .collect();
    if !missing.is_empty() {
        let _ =
            writeln!(s, "\nNamed but with no root-crate slot (not in any flashed structure): {}.", missing.join("; "));
    }
    s.push_str("\nPer-axis discovery reports (candidates, tests, intervals): `ax/`, `ay/`, `az/`. `table.bin`: `qfa-lab compensate --table DIR/table.bin`.\n");
    s
}

/// Run on `log` and write `DIR/report.json`, `DIR/report.md`, `DIR/table.bin` and each
/// axis's discovery outputs under `DIR/<axis>/`.
///
/// # Errors
/// As [`discover_static`], or a file could not be written.
pub fn run(log: &StaticLog, start: Start, dir: &Path) -> Result<StaticDiscovery> {
    let d = discover_static(log, start)?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for ((a, r), ch) in d.axes.iter().zip(&d.reports).zip(&d.channels) {
        super::output::write(ch, r, &dir.join(&a.axis))?;
    }
    std::fs::write(dir.join("table.bin"), encode(&d.table).map_err(|e| anyhow::anyhow!("{e}"))?)?;
    std::fs::write(dir.join("report.json"), serde_json::to_string_pretty(&d)? + "\n")?;
    std::fs::write(dir.join("report.md"), markdown(&d))?;
    Ok(d)
}
