//! Discovery on a static multi-axis log (a board at rest in a chamber): each axis is a
//! single-channel bias log, on the same held-out scheme as static calibration.
//!
//! # Held-out scheme (the one of [`qfa_calibrate::static_cal`], `--holdout`)
//! `after-max` (fit up to the first row at the highest temperature, hold out the later
//! leg), `blocks:K` (K contiguous blocks in time, each held out from a fit to the others),
//! or `none`; `auto` picks `after-max` when the log has a later leg, else `blocks:5`.
//! Everything discovery decides for a held-out figure (start-model fit, candidates, block
//! tests, the final fit) sees only that fold's training rows: they are cut out as their
//! own single-channel log and run through [`super::analyze`], whose own held-out rule (time
//! blocks inside that log) drives the selection. Under `after-max` the training rows are a
//! prefix, and the model and the estimator are causal, so cutting is the same as masking
//! the later rows; under `blocks:K` a middle block leaves a gap in time, which the rate
//! estimator treats as any gap in a log (it restarts its window after 30 s).
//!
//! # Figures
//! Per axis, on the held-out rows of every fold, in mg (RMS over rows, and over 60-s
//! means): the start model and the discovered model (both fitted on the fold's training
//! bins, run through the root crate's `AxisModel::evaluate` on every row, `bias_drift` added
//! when it was named), and beside them the peers of [`qfa_calibrate::peers`] fitted on
//! the same training rows and scored on the same held-out rows, exactly as `calibrate`
//! scores them. A figure that cannot be formed is an error, or (`none`, an ArduPilot
//! learner with no rise to learn from) a [`Figure::NotComputed`] with its reason.
//!
//! # Table: what is named and what is flashed
//! The block test decides what is *named*: a claim about the physics, made only when it is
//! significant, with the false-discovery rate docs/measurements.md states ("Lab:
//! discovery"). The names in the report are discovery's on **every row** (those of each
//! fold's training rows are listed too).
//! What is *flashed* (`DIR/table.bin`, what `qfa-lab compensate` loads) is a prediction:
//! static calibration's cross-validated choice among its candidates, by the very call
//! `calibrate` makes ([`calibrate_static`]), so `discover` and `calibrate` write the same
//! table for the same log and flags and cannot disagree. The named structure
//! (`structure_of`) is reported beside it with its held-out figure. On a short log the
//! named and the flashed differ: the tofupilot log's 52-min training leg gives the block
//! test 8 blocks, too few to name effects that still predict better. The report gives both, and says which structure was flashed and
//! whether discovery named it. Static tables have K1 = 2²⁰ LSB/g
//! ([`qfa_calibrate::compensate::STATIC_LSB_PER_G`]) and the bias in g from the axis's mean
//! over every row.

use std::fmt::Write as _;
use std::path::Path;

use qfa_thermal::model::AxisModel;
use serde::Serialize;

use super::output::{write_file, write_json, Scope};
use super::verdict::named_is_worse;
use super::{analyze, start_model, Channels, DiscoverError, LogKind, Report, Result, Start};
use qfa_calibrate::fit::{BranchMode, CurveShape, StaticStructure};
use qfa_calibrate::peers::PeerKind;
use qfa_calibrate::static_cal::{
    calibrate_static, check_coverage, resolve_holdout, score, Figure, Holdout, HoldoutReport, StaticCalError,
    StaticCalOptions, NO_HOLDOUT,
};
use qfa_log::channels::{BiasUnit, Trace};
use qfa_log::static_log::StaticLog;
use qfa_report::verdict::Verdict;

/// Bin width for a static log, s: about 400 bins over the log, between 10 and 60 s. A
/// chamber log of a few hours gets the cycling logs' 60-s bins; the tofupilot log (70.7
/// min) gets 10-s bins, since at 60 s its 52 training bins could not hold a 16-node grid
/// and a lag or creep of tens of seconds (what static calibration finds there) would be
/// averaged away. (This rule was fixed before the first run on the real log; widths of
/// 5, 20, 30 and 60 s were tried afterwards only to measure how much the answer depends on
/// it: docs/measurements.md, "Real data".)
#[must_use]
pub(crate) fn bin_width_s(duration_s: f64) -> f64 {
    (duration_s / 400.0).round().clamp(10.0, 60.0)
}

/// One axis under the held-out scheme.
#[derive(Clone, Debug, Serialize)]
pub struct AxisDiscovery {
    /// Role (`ax`, `ay`, `az`).
    pub axis: String,
    /// Column in the file.
    pub column: String,
    /// Mean over every row the table's bias is measured from, g.
    pub reference_g: f64,
    /// Effects named on every row, `name (channel)`, in order (empty: none).
    pub effects: Vec<String>,
    /// Effects named on each fold's training rows.
    pub effects_per_fold: Vec<Vec<String>>,
    /// Effects named on every row but not in `table.bin` (no root-crate slot).
    pub not_in_table: Vec<String>,
    /// Unexplained structure left in the residual on every row, in words.
    pub unexplained: Vec<String>,
    /// Start model, held out.
    pub before: Figure,
    /// Named model (what discovery named on the fold's training rows), held out.
    pub after: Figure,
    /// The structure discovery named on every row, as the one static fitter writes it
    /// (`bias_drift`, which has no slot, and a creep's activation energy dropped).
    pub named_structure: String,
    /// The workflow's model, the one in `table.bin`: the lowest cross-validation RMS over
    /// every row among static calibration's candidates and every axis's named structure
    /// (see the module docs).
    pub final_structure: String,
    /// Whether that is the structure discovery named on this axis (else one of
    /// calibration's candidates or another axis's).
    pub final_is_named: bool,
    /// Its cross-validation RMS over every row, mg.
    pub final_cv_rms_mg: f64,
    /// The workflow's model, held out (chosen and fitted on each fold's training rows).
    pub final_model: Figure,
    /// RMS over every row of the table in `table.bin` (fitted on every row: in-sample), mg.
    pub final_table_rms_mg: f64,
    /// PX4 / tofupilot cubic, held out.
    pub cubic: Figure,
    /// ArduPilot TCAL, held out.
    pub ardupilot: Figure,
    /// The paper's simple model (linear in T), held out.
    pub simple: Figure,
    /// No compensation (training mean removed), held out.
    pub none: Figure,
}

/// `DIR/report.json` of a static discovery.
#[derive(Clone, Debug, Serialize)]
pub struct StaticDiscovery {
    /// Start model.
    pub start: Start,
    /// The held-out scheme (calibration's own).
    pub holdout: HoldoutReport,
    /// Which rows each figure comes from, in words.
    pub figures: String,
    /// Bin width of the discovery channels, s.
    pub bin_s: f64,
    /// Per axis.
    pub axes: Vec<AxisDiscovery>,
    /// Each axis's full discovery report on every row.
    #[serde(skip)]
    pub reports: Vec<Report>,
    /// Each axis's channels on every row (what its report was formed from).
    #[serde(skip)]
    pub channels: Vec<Channels>,
    /// The workflow's table (one axis per log axis), fitted on every row.
    #[serde(skip)]
    pub table: qfa_thermal::Table,
}

/// The static fitter's structure for a discovered model: one bias curve (discovery's grid
/// is single-valued) with its lag, play and creep slots. A creep's activation energy is
/// dropped (the static fitter's creep has a constant τ) and `bias_drift` has no slot.
#[must_use]
pub(crate) fn structure_of(m: &AxisModel) -> StaticStructure {
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

fn rows_of(log: &StaticLog, rows: &[usize]) -> Vec<(f64, f32)> {
    rows.iter().map(|&i| (log.time_s[i], log.temp_c[i] as f32)).collect()
}

/// Per-row K0 (g) of `model` over the whole log, plus `drift_per_h`·(hours since the first
/// row the estimator kept); `None` before the estimator's first output.
fn row_bias(log: &StaticLog, model: &AxisModel, drift_per_h: f64, bin_s: f64) -> Vec<Option<f64>> {
    let n = log.rows();
    let zeros = vec![0.0; n];
    let all: Vec<usize> = (0..n).collect();
    let tr = Trace::new(String::new(), &rows_of(log, &all), None, &zeros, bin_s);
    let mut out = vec![None; n];
    let t0 = tr.time_s.first().copied().unwrap_or(0.0);
    let mut i = 0;
    tr.evaluate_rows(model, |j, _, e| {
        // The trace keeps a subset of the rows, in order, with their times unchanged.
        while i < n && log.time_s[i] != tr.time_s[j] {
            i += 1;
        }
        if i < n {
            out[i] = Some(f64::from(e.k0) + drift_per_h * (tr.time_s[j] - t0) / 3600.0);
        }
    });
    out
}

/// Discovery of one axis on the rows `rows` (ascending): its report (models in g), its
/// channels, the start model (g) and the reference (the rows' mean, g).
fn discover_rows(
    log: &StaticLog,
    axis: usize,
    rows: &[usize],
    start: Start,
    bin_s: f64,
) -> (Report, Channels, AxisModel, f64) {
    let ax = &log.axes[axis];
    let reference = rows.iter().map(|&i| ax.accel_g[i]).sum::<f64>() / rows.len() as f64;
    // Discovery runs in µg, so its per-axis reports read in µg; the models go back to g.
    let value_ug: Vec<f64> = rows.iter().map(|&i| (ax.accel_g[i] - reference) * 1e6).collect();
    let ch = Channels {
        kind: LogKind::Single,
        bias_unit: BiasUnit::Ug,
        traces: vec![Trace::new(ax.name.clone(), &rows_of(log, rows), None, &value_ug, bin_s)],
    };
    let mut r = analyze(&ch, start);
    if let Some(m) = r.model.as_mut() {
        scale_bias(m, 1e-6);
    }
    let mut base = start_model(&ch, start);
    scale_bias(&mut base, 1e-6);
    (r, ch, base, reference)
}

/// Discover each axis of `log` under the held-out scheme `holdout`; see the module docs.
///
/// # Errors
/// A log static calibration refuses, a held-out scheme the log cannot hold, or a figure
/// that cannot be formed ([`DiscoverError::StaticCal`]); a discovery that gives no model
/// ([`DiscoverError::NoModel`]).
pub fn discover_static(log: &StaticLog, start: Start, holdout: Holdout) -> Result<StaticDiscovery> {
    let mut opts = StaticCalOptions { holdout, ..StaticCalOptions::default() };
    check_coverage(&log.temp_c, opts.grid_points, opts.block)?;
    let (scheme, _) = resolve_holdout(log, holdout, opts.block)?;
    let n = log.rows();
    let folds = scheme.folds(n);
    let duration = log.time_s[n - 1] - log.time_s[0];
    let bin_s = bin_width_s(duration);
    let all: Vec<usize> = (0..n).collect();
    let mut axes = Vec::new();
    let mut reports = Vec::new();
    let mut channels = Vec::new();
    for (a, ax) in log.axes.iter().enumerate() {
        let (r, ch, _, reference) = discover_rows(log, a, &all, start, bin_s);
        let disc_all = r.model.clone().ok_or_else(|| DiscoverError::NoModel { axis: ax.name.clone(), fold: None })?;
        let held_out = held_out_residuals(log, a, &folds, start, bin_s)?;
        axes.push(axis_discovery(log, a, &r, &disc_all, reference, held_out, folds.is_empty())?);
        reports.push(r);
        channels.push(ch);
    }
    // The model: static calibration's cross-validated choice, the very call `calibrate`
    // makes, so `discover` and `calibrate` flash the same table and cannot disagree. The
    // block test decides what is *named* (a claim about the physics, with a known
    // false-discovery rate); the cross-validation decides what is *flashed* (a
    // prediction); the report gives both figures.
    opts.holdout = holdout;
    let cal = calibrate_static(log, &opts, false)?;
    adopt_flashed_choice(&mut axes, &cal.report.axes);
    Ok(StaticDiscovery {
        table: cal.table,
        start,
        // The scheme is calibration's own (same `resolve_holdout`), so its words are too.
        holdout: cal.report.holdout.clone(),
        figures: cal.report.figures.clone(),
        bin_s,
        axes,
        reports,
        channels,
    })
}

/// One axis's held-out residuals, pooled over the folds in time order: the start and the
/// discovered model (each with the times of its rows), the peers, and no compensation.
struct HeldOutResiduals {
    before: Vec<f64>,
    after: Vec<f64>,
    t_before: Vec<f64>,
    t_after: Vec<f64>,
    peers: [Vec<f64>; 3],
    peer_err: [Option<String>; 3],
    none: Vec<f64>,
    ho_t: Vec<f64>,
    effects_per_fold: Vec<Vec<String>>,
}

/// Discover axis `a` on each fold's training rows and collect the held-out residuals of
/// the start model, the discovered model, the peers and no compensation.
fn held_out_residuals(
    log: &StaticLog,
    a: usize,
    folds: &[std::ops::Range<usize>],
    start: Start,
    bin_s: f64,
) -> Result<HeldOutResiduals> {
    let ax = &log.axes[a];
    let n = log.rows();
    let mut h = HeldOutResiduals {
        before: Vec::new(),
        after: Vec::new(),
        t_before: Vec::new(),
        t_after: Vec::new(),
        peers: [Vec::new(), Vec::new(), Vec::new()],
        peer_err: [None, None, None],
        none: Vec::new(),
        ho_t: Vec::new(),
        effects_per_fold: Vec::new(),
    };
    for (f, held) in folds.iter().enumerate() {
        let train: Vec<usize> = (0..n).filter(|i| !held.contains(i)).collect();
        let (rf, _, base, r0) = discover_rows(log, a, &train, start, bin_s);
        let disc =
            rf.model.clone().ok_or_else(|| DiscoverError::NoModel { axis: ax.name.clone(), fold: Some(f + 1) })?;
        h.effects_per_fold.push(rf.effect_labels());
        let drift = 1e-6 * rf.effects.iter().find_map(|e| e.params.get("drift_ug_per_h").copied()).unwrap_or(0.0);
        for (m, d, res, t) in
            [(&base, 0.0, &mut h.before, &mut h.t_before), (&disc, drift, &mut h.after, &mut h.t_after)]
        {
            let b = row_bias(log, m, d, bin_s);
            for i in held.clone() {
                if let Some(k0) = b[i] {
                    res.push(ax.accel_g[i] - r0 - k0);
                    t.push(log.time_s[i]);
                }
            }
        }
        held_out_peers(log, a, &train, held, r0, (f, folds.len()), &mut h);
        h.none.extend(held.clone().map(|i| ax.accel_g[i] - r0));
        h.ho_t.extend(held.clone().map(|i| log.time_s[i]));
    }
    Ok(h)
}

/// Fit each peer on fold `f`'s training rows (of `n_folds`) and add its held-out residuals,
/// or note the first fold a peer could not be fitted on.
fn held_out_peers(
    log: &StaticLog,
    a: usize,
    train: &[usize],
    held: &std::ops::Range<usize>,
    r0: f64,
    (f, n_folds): (usize, usize),
    h: &mut HeldOutResiduals,
) {
    let ax = &log.axes[a];
    let tt: Vec<f64> = train.iter().map(|&i| log.temp_c[i]).collect();
    let value: Vec<f64> = train.iter().map(|&i| ax.accel_g[i] - r0).collect();
    for (k, kind) in PeerKind::ALL.iter().enumerate() {
        match kind.fit(&tt, &value) {
            Ok(p) => h.peers[k].extend(held.clone().map(|i| ax.accel_g[i] - r0 - p.eval(log.temp_c[i]))),
            Err(e) if h.peer_err[k].is_none() => {
                h.peer_err[k] = Some(format!("fold {} of {}: {}: {e}", f + 1, n_folds, kind.label()));
            }
            Err(_) => {}
        }
    }
}

/// Axis `a`'s discovery: its named effects and structure from `r` (every row) and its
/// held-out figures; the flashed choice is left to [`adopt_flashed_choice`].
fn axis_discovery(
    log: &StaticLog,
    a: usize,
    r: &Report,
    disc_all: &AxisModel,
    reference: f64,
    h: HeldOutResiduals,
    no_folds: bool,
) -> Result<AxisDiscovery> {
    let ax = &log.axes[a];
    let name = |w: &str| format!("{} {w}", ax.name);
    let fig = |res: &[f64], t: &[f64], what: &str, err: &Option<String>| -> Result<Figure, StaticCalError> {
        if no_folds {
            return Ok(Figure::not_computed(NO_HOLDOUT));
        }
        if let Some(e) = err {
            return Ok(Figure::not_computed(e.clone()));
        }
        Ok(Figure::Score(score(res, t, &name(what))?))
    };
    Ok(AxisDiscovery {
        axis: ax.name.clone(),
        column: ax.column.clone(),
        reference_g: reference,
        effects: r.effect_labels(),
        effects_per_fold: h.effects_per_fold,
        not_in_table: r.effects.iter().filter(|e| !e.in_table).map(|e| e.name.clone()).collect(),
        unexplained: unexplained_lines(r),
        before: fig(&h.before, &h.t_before, "start model", &None)?,
        after: fig(&h.after, &h.t_after, "discovered model", &None)?,
        named_structure: structure_of(disc_all).name(),
        // Filled in by `adopt_flashed_choice`, once every axis's named structure is known.
        final_structure: String::new(),
        final_is_named: false,
        final_cv_rms_mg: f64::NAN,
        final_model: Figure::not_computed("not yet chosen"),
        final_table_rms_mg: f64::NAN,
        cubic: fig(&h.peers[0], &h.ho_t, PeerKind::Cubic.label(), &h.peer_err[0])?,
        ardupilot: fig(&h.peers[1], &h.ho_t, PeerKind::Ardupilot.label(), &h.peer_err[1])?,
        simple: fig(&h.peers[2], &h.ho_t, PeerKind::Simple.label(), &h.peer_err[2])?,
        none: fig(&h.none, &h.ho_t, "none", &None)?,
    })
}

/// One line per unexplained structure: what rejected the fitted noise model
/// ([`super::Unexplained::evidence`]). It gave only the drivers followed and the pinned
/// effects, so a step alone read "" (and the console "follows: no driver tested").
fn unexplained_lines(r: &Report) -> Vec<String> {
    let unit = BiasUnit::Ug.label();
    r.unexplained.iter().map(|u| u.evidence(unit, unit)).collect()
}

/// Record on each axis the structure static calibration flashed, its figures, and whether
/// discovery named it.
fn adopt_flashed_choice(axes: &mut [AxisDiscovery], cal_axes: &[qfa_calibrate::static_cal::AxisReport]) {
    for (a, c) in axes.iter_mut().zip(cal_axes) {
        a.final_is_named = c.structure == a.named_structure;
        a.final_structure.clone_from(&c.structure);
        a.final_cv_rms_mg = c.cv_rms_mg;
        a.final_model = c.ours.clone();
        a.final_table_rms_mg = c.table_rms_mg;
    }
}

/// The title line of one axis's report.
#[must_use]
pub(crate) fn axis_title(a: &AxisDiscovery) -> String {
    format!("# Discovery report: axis {} (column `{}`)", a.axis, a.column)
}

/// One axis's held-out figures on the log's scheme, one row per model: `[model, figure]`
/// (RMS over rows / over 60-s means, mg).
#[must_use]
pub(crate) fn axis_figures(d: &StaticDiscovery, a: &AxisDiscovery) -> Vec<[String; 2]> {
    vec![
        [format!("start model `{}`", d.start.name()), a.before.cell()],
        [
            format!(
                "named model ({}){}",
                if a.effects.is_empty() { "nothing named".to_string() } else { a.effects.join(", ") },
                if named_is_worse(a) { ", worse than the start held out" } else { "" }
            ),
            a.after.cell(),
        ],
        [format!("table.bin of all axes (`../table.bin`, structure {})", a.final_structure), a.final_model.cell()],
        ["PX4/tofupilot cubic".to_string(), a.cubic.cell()],
        ["ArduPilot TCAL".to_string(), a.ardupilot.cell()],
    ]
}

/// What [`axis_figures`] are, in one sentence.
#[must_use]
pub(crate) fn axis_figures_intro(d: &StaticDiscovery) -> String {
    format!(
        "Held-out figures of this axis, scheme `{}` ({}), RMS over rows / over 60-s means, mg: the only held-out \
         figures of this axis.",
        d.holdout.scheme, d.figures
    )
}

/// [`axis_figures`] as Markdown, after [`axis_figures_intro`].
#[must_use]
pub(crate) fn axis_figures_markdown(d: &StaticDiscovery, a: &AxisDiscovery) -> String {
    let mut s = format!("{}\n\n| model | held-out, mg |\n|---|---|\n", axis_figures_intro(d));
    for [m, f] in axis_figures(d, a) {
        let _ = writeln!(s, "| {m} | {f} |");
    }
    s
}

/// The per-axis table's header and rows (mg), for Markdown and the page alike.
#[must_use]
pub(crate) fn table_rows(d: &StaticDiscovery) -> (Vec<&'static str>, Vec<Vec<String>>) {
    let header = vec![
        "axis",
        "effects named (every row)",
        "named on the training rows (the named model's)",
        "start model, held out",
        "named model, held out",
        "table.bin, held out (chosen inside the training rows)",
        "table.bin structure (CV choice on every row)",
        "CV RMS of that structure, mg",
        "PX4/tofupilot cubic, held out",
        "ArduPilot TCAL, held out",
        "paper simple, held out",
        "none, held out",
    ];
    let rows = d
        .axes
        .iter()
        .map(|a| {
            let mut names = if a.effects.is_empty() { "none".to_string() } else { a.effects.join(", ") };
            if !a.unexplained.is_empty() {
                let _ = write!(names, "; unexplained: {}", a.unexplained.join("; "));
            }
            let per_fold = a
                .effects_per_fold
                .iter()
                .map(|f| if f.is_empty() { "none".to_string() } else { f.join(", ") })
                .collect::<Vec<_>>()
                .join(" | ");
            vec![
                a.axis.clone(),
                names,
                per_fold,
                a.before.cell(),
                if named_is_worse(a) { format!("{} (worse than the start)", a.after.cell()) } else { a.after.cell() },
                a.final_model.cell(),
                format!("{}{}", a.final_structure, if a.final_is_named { " (the named structure)" } else { "" }),
                format!("{:.2}", a.final_cv_rms_mg),
                a.cubic.cell(),
                a.ardupilot.cell(),
                a.simple.cell(),
                a.none.cell(),
            ]
        })
        .collect();
    (header, rows)
}

/// Which rows each figure comes from and what decides the names and the table, in words.
#[must_use]
pub(crate) fn how_to_read(d: &StaticDiscovery) -> [String; 3] {
    [
        format!("Which rows each figure comes from: {}.", d.figures),
        "For each held-out figure, discovery sees only that fold's training rows (its own selection folds, time \
         blocks, inside them); every figure called held out is on the held-out rows, RMS over rows / over 60-s \
         means, mg. Peers fitted on the same training rows, as `calibrate` fits them. Effects named: on every row."
            .to_string(),
        "Named: the block test (a claim about the physics). Flashed (`table.bin`): the lowest blocked \
         cross-validation (CV) RMS among static calibration's candidates (a prediction), chosen and fitted on every \
         row by the same call `calibrate` makes, so both write this table; its held-out figure is the same choice \
         made inside each fold's training rows."
            .to_string(),
    ]
}

/// The static discovery's `report.md` after its verdict: the per-axis table (mg) and how
/// to read it.
#[must_use]
pub(crate) fn markdown(d: &StaticDiscovery) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Held-out scheme: `{}` (asked: `{}`): {}. Start model `{}`; {}-s bins; the per-axis reports are in µg.\n",
        d.holdout.scheme,
        d.holdout.requested,
        d.holdout.rule,
        d.start.name(),
        d.bin_s
    );
    let [rows_from, selection, named_flashed] = how_to_read(d);
    let _ = writeln!(s, "{rows_from}\n\n{selection}\n");
    let (header, rows) = table_rows(d);
    let _ = writeln!(s, "| {} |", header.join(" | "));
    let _ = writeln!(s, "|{}", "---|".repeat(header.len()));
    for r in rows {
        let _ = writeln!(s, "| {} |", r.join(" | "));
    }
    let _ = writeln!(s, "\n{named_flashed}");
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
    s.push_str("\nPer-axis discovery reports (candidates, tests, intervals): `ax/`, `ay/`, `az/` (their `model.toml` is the named model, for reading, not a table to flash). `table.bin` (all axes): `qfa-lab compensate --table DIR/table.bin`.\n");
    s
}

/// Run on `log` and write `DIR/report.json`, `DIR/report.md`, `DIR/report.html`,
/// `DIR/table.bin` and each axis's discovery outputs under `DIR/<axis>/`; returns the
/// discovery and the verdict its reports open with.
///
/// # Errors
/// As [`discover_static`], or a file could not be written ([`DiscoverError`]).
pub fn run(log: &StaticLog, start: Start, holdout: Holdout, dir: &Path) -> Result<(StaticDiscovery, Verdict)> {
    let d = discover_static(log, start, holdout)?;
    std::fs::create_dir_all(dir).map_err(|source| DiscoverError::CreateDir { path: dir.into(), source })?;
    for ((a, r), ch) in d.axes.iter().zip(&d.reports).zip(&d.channels) {
        // Not flashable: the table of all axes is DIR/table.bin (see `output`'s docs).
        super::output::write(ch, r, &dir.join(&a.axis), Scope::StaticAxis { discovery: &d, axis: a })?;
    }
    write_file(&dir.join("table.bin"), d.table.to_bytes().map_err(DiscoverError::Table)?)?;
    let files: Vec<String> = ["table.bin", "report.json", "report.md", "report.html"].map(String::from).to_vec();
    let v = super::verdict::static_verdict(&d, &files);
    write_json(&dir.join("report.json"), &v, &d)?;
    write_file(&dir.join("report.md"), format!("# Discovery on a static log\n\n{}{}", v.markdown(), markdown(&d)))?;
    super::page::static_page(&d, &v, dir).and_then(|p| p.write(dir)).map_err(DiscoverError::Page)?;
    Ok((d, v))
}
