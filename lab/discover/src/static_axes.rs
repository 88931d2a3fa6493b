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
//! means): the start model, the named model and the block test's own model (each chosen and
//! fitted on the fold's training rows, run through the root crate's `AxisModel::evaluate`
//! on every row), and beside them the peers of [`qfa_calibrate::peers`] fitted on the same
//! training rows and scored on the same held-out rows, exactly as `calibrate` scores them.
//! A figure that cannot be formed is an error, or (`none`, an ArduPilot learner with no rise
//! to learn from) a [`Figure::NotComputed`] with its reason.
//!
//! # One search: what is named is what is flashed
//! The model is named by one search, the one `calibrate` runs ([`calibrate_static`]):
//! every candidate structure's blocked cross-validation RMS over every row, the lowest
//! chosen. So the named structure is the one `DIR/table.bin` holds, byte for byte the table
//! `calibrate` writes, and its held-out figure is the one `calibrate` reports: that
//! structure fitted on each fold's training rows. The search's path explains it: from the simplest structure, one part at a time
//! (a branch tie loosened, a lag, a creep), each step to the lowest cross-validation RMS,
//! each with its figure over every row and, per fold, its held-out figure
//! ([`AxisDiscovery::heldout_steps`]). A step that raises the figure is shown as one (a part
//! that pays only with a later one).
//!
//! The block test (discovery's catalog search, [`super::analyze`], on single-channel bins
//! of the axis) no longer names the model. It says which of the search's parts it
//! identifies (a claim about the physics, with the false-discovery rate
//! docs/measurements.md states, "Lab: discovery"), which effects it names that the model
//! does not hold and why (`bias_drift`: no slot; a trend in time fitted inside the training
//! rows is extrapolated past them), what is left unexplained, and where. Its own model is
//! scored held out beside the named one. On the tofupilot log it was worse than the start
//! model on two axes (x 1.99 against 1.15 mg, z 15.57 against 6.45: a drift fitted inside
//! the training rows, extrapolated over the later leg), which is why it does not name the
//! model. Static tables have K1 = 2²⁰ LSB/g
//! ([`qfa_calibrate::compensate::STATIC_LSB_PER_G`]) and the bias in g from the axis's mean
//! over every row.

mod story;

use std::fmt::Write as _;
use std::path::Path;

use story::adopt_search;
pub(crate) use story::{step_rows, steps_not_carried};

use qfa_thermal::model::AxisModel;
use serde::Serialize;

use super::output::{write_file, write_json, Scope};
use super::verdict::named_is_worse;
use super::{analyze, start_model, Channels, DiscoverError, LogKind, Report, Result, Start};
use qfa_calibrate::peers::PeerKind;
use qfa_calibrate::static_cal::{
    calibrate_static, check_coverage, resolve_holdout, score, Figure, HeldOutStep, Holdout, HoldoutReport,
    StaticCalError, StaticCalOptions, NO_HOLDOUT,
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
    /// What the model search added over every row, one part per step, as `effect (form)`
    /// (empty: the simplest structure): the parts of `named_structure`, the table's.
    pub effects: Vec<String>,
    /// The search's steps over every row, each with its cross-validation figure and whether
    /// the block test identifies its effect.
    pub steps: Vec<Step>,
    /// Effects the block test names on every row (a claim about the physics, with the
    /// false-discovery rate docs/measurements.md states), as its report labels them.
    pub block_test_names: Vec<String>,
    /// Effects the block test names that the model does not hold, each with why.
    pub not_added: Vec<String>,
    /// Unexplained structure left in the residual on every row, in words.
    pub unexplained: Vec<String>,
    /// Start model, held out.
    pub before: Figure,
    /// The named model, held out: `named_structure`'s search made and fitted inside each
    /// fold's training rows (the figure `calibrate` reports for `table.bin`).
    pub after: Figure,
    /// The structure the search named over every row: the one `table.bin` holds.
    pub named_structure: String,
    /// Its cross-validation RMS over every row, mg.
    pub cv_rms_mg: f64,
    /// Per fold, the search inside its training rows, each step fitted there and scored on
    /// the fold's held-out rows (the last step's figure is `after`'s, on one fold).
    pub heldout_steps: Vec<Vec<HeldOutStep>>,
    /// RMS over every row of the table in `table.bin` (fitted on every row: in-sample), mg.
    pub table_rms_mg: f64,
    /// The block test's own model (its catalog search inside each fold's training rows,
    /// drift included), held out: what naming by the block test alone would predict.
    pub block_test_model: Figure,
    /// The effects that model holds, per fold.
    pub block_test_effects_per_fold: Vec<Vec<String>>,
    /// PX4 / tofupilot cubic, held out.
    pub cubic: Figure,
    /// ArduPilot TCAL, held out.
    pub ardupilot: Figure,
    /// The paper's simple model (linear in T), held out.
    pub simple: Figure,
    /// No compensation (training mean removed), held out.
    pub none: Figure,
    /// When the named model's held-out rows sit off its training rows by most of their
    /// error: that warning, with what the later leg looks like (calibration's words, from
    /// the same fit: `qfa_calibrate::verdict::later_leg_warnings`).
    pub later_leg: Option<String>,
}

/// One step of the model search over every row.
#[derive(Clone, Debug, Serialize)]
pub struct Step {
    /// The part added, `effect (form)`; `start` for the search's first structure.
    pub effect: String,
    /// The structure after the step.
    pub structure: String,
    /// Its cross-validation RMS over every row, mg.
    pub cv_rms_mg: f64,
    /// Whether the block test names the step's effect on every row and tells it from every
    /// other effect.
    pub identified: bool,
    /// What the block test says of it, in words: `identified`, `not identified: as good as
    /// …`, or `not named by the block test`.
    pub evidence: String,
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
        // The static reader skips its own glitch rows and counts them (`Skipped::glitch`).
        skipped_glitches: Vec::new(),
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
        r.model.as_ref().ok_or_else(|| DiscoverError::NoModel { axis: ax.name.clone(), fold: None })?;
        let held_out = held_out_residuals(log, a, &folds, start, bin_s)?;
        axes.push(axis_discovery(log, a, &r, reference, held_out, folds.is_empty())?);
        reports.push(r);
        channels.push(ch);
    }
    // The model: static calibration's cross-validated choice, the very call `calibrate`
    // makes, so `discover` and `calibrate` flash the same table and cannot disagree. The
    // block test decides what is *named* (a claim about the physics, with a known
    // false-discovery rate); the cross-validation decides what is *flashed* (a
    // prediction); the report gives both figures.
    // The model: the one search, the very call `calibrate` makes, so `discover` names what
    // `calibrate` flashes. The block test says which of its parts it identifies, and which
    // effects it names that the model does not hold.
    opts.holdout = holdout;
    let cal = calibrate_static(log, &opts, false)?;
    let later = qfa_calibrate::verdict::later_leg_warnings(&cal.plot);
    for (a, (x, r)) in axes.iter_mut().zip(&reports).enumerate() {
        adopt_search(x, r, &cal.report.axes[a], &cal.paths[a]);
        x.later_leg = later.iter().find(|(axis, _)| *axis == x.axis).map(|(_, w)| w.clone());
    }
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
/// block test's model (each with the times of its rows), the peers, and no compensation.
struct HeldOutResiduals {
    before: Vec<f64>,
    block: Vec<f64>,
    t_before: Vec<f64>,
    t_block: Vec<f64>,
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
        block: Vec::new(),
        t_before: Vec::new(),
        t_block: Vec::new(),
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
            [(&base, 0.0, &mut h.before, &mut h.t_before), (&disc, drift, &mut h.block, &mut h.t_block)]
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
        // Filled in by `adopt_search`, once the search has run.
        effects: Vec::new(),
        steps: Vec::new(),
        block_test_names: r.effect_labels(),
        not_added: Vec::new(),
        unexplained: unexplained_lines(r),
        before: fig(&h.before, &h.t_before, "start model", &None)?,
        after: Figure::not_computed("not yet searched"),
        named_structure: String::new(),
        cv_rms_mg: f64::NAN,
        heldout_steps: Vec::new(),
        table_rms_mg: f64::NAN,
        block_test_model: fig(&h.block, &h.t_block, "block test's model", &None)?,
        block_test_effects_per_fold: h.effects_per_fold,
        cubic: fig(&h.peers[0], &h.ho_t, PeerKind::Cubic.label(), &h.peer_err[0])?,
        ardupilot: fig(&h.peers[1], &h.ho_t, PeerKind::Ardupilot.label(), &h.peer_err[1])?,
        simple: fig(&h.peers[2], &h.ho_t, PeerKind::Simple.label(), &h.peer_err[2])?,
        none: fig(&h.none, &h.ho_t, "none", &None)?,
        // Filled in with the search's result.
        later_leg: None,
    })
}

/// One line per unexplained structure: what rejected the fitted noise model
/// ([`super::Unexplained::evidence`]). It gave only the drivers followed and the pinned
/// effects, so a step alone read "" (and the console "follows: no driver tested").
fn unexplained_lines(r: &Report) -> Vec<String> {
    let unit = BiasUnit::Ug.label();
    r.unexplained.iter().map(|u| u.evidence(unit, unit)).collect()
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
    let list = |v: &[String], none: &str| if v.is_empty() { none.to_string() } else { v.join(", ") };
    vec![
        [format!("start model `{}`", d.start.name()), a.before.cell()],
        [
            format!(
                "named model = table.bin (`../table.bin`, {}: {}){}",
                a.named_structure,
                list(&a.effects, "nothing added"),
                if named_is_worse(a) { ", worse than the start held out" } else { "" }
            ),
            a.after.cell(),
        ],
        [
            format!(
                "the block test's own model ({}), for comparison",
                a.block_test_effects_per_fold.iter().map(|f| list(f, "nothing")).collect::<Vec<_>>().join(" | ")
            ),
            a.block_test_model.cell(),
        ],
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
        "named = table.bin structure (every row)",
        "its parts, in the search's order: what the block test says of each",
        "the block test names (every row)",
        "not added, and why",
        "start model, held out",
        "named model = table.bin, held out",
        "CV RMS of the named structure, mg",
        "the block test's own model, held out",
        "PX4/tofupilot cubic, held out",
        "ArduPilot TCAL, held out",
        "paper simple, held out",
        "none, held out",
    ];
    let list = |v: &[String]| if v.is_empty() { "none".to_string() } else { v.join(", ") };
    let rows = d
        .axes
        .iter()
        .map(|a| {
            let mut parts = a
                .steps
                .iter()
                .skip(1)
                .map(|st| format!("{}: {}", st.effect, st.evidence))
                .collect::<Vec<_>>()
                .join("; ");
            if parts.is_empty() {
                parts = "nothing added".to_string();
            }
            let mut identified = list(&a.block_test_names);
            if !a.unexplained.is_empty() {
                let _ = write!(identified, "; unexplained: {}", a.unexplained.join("; "));
            }
            vec![
                a.axis.clone(),
                a.named_structure.clone(),
                parts,
                identified,
                list(&a.not_added),
                a.before.cell(),
                if named_is_worse(a) { format!("{} (worse than the start)", a.after.cell()) } else { a.after.cell() },
                format!("{:.2}", a.cv_rms_mg),
                a.block_test_model.cell(),
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
        "Every figure called held out is on the held-out rows, RMS over rows / over 60-s means, mg, from models \
         fitted on each fold's training rows only (the named model: table.bin's structure, chosen over every \
         row); peers are fitted on the same training rows, as `calibrate` fits them."
            .to_string(),
        "Named is flashed: one model search, the one `calibrate` runs (every candidate structure's blocked \
         cross-validation (CV) RMS over every row, the lowest chosen), names the structure, `table.bin` holds it \
         and the held-out figures score it. Its parts are listed in the order a path from the simplest structure adds them, \
         one at a time, each to the lowest CV. A part is identified when the block test, a claim about the \
         physics with a known false-discovery rate, names its effect on every row; the block test's own model \
         is shown held out beside it, and what it names that the table does not hold is listed under not added, \
         with why."
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
    for a in &d.axes {
        let _ = writeln!(
            s,
            "\n**{}: the search, step by step, held out** (each step fitted on the training rows, scored on the \
             held-out rows):\n\n| step | structure | CV RMS over every row, mg | held out, mg | change held out, mg |\n|---|---|---|---|---|",
            a.axis
        );
        for r in step_rows(a) {
            let _ = writeln!(s, "| {} |", r.join(" | "));
        }
    }
    s.push_str("\nPer-axis discovery reports (candidates, tests, intervals): `ax/`, `ay/`, `az/` (their `model.toml` is the block test's own model, for reading, not a table to flash). `table.bin` (all axes): `qfa-lab compensate --table DIR/table.bin`.\n");
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
    let mut axis_plots = Vec::with_capacity(d.axes.len());
    for ((a, r), ch) in d.axes.iter().zip(&d.reports).zip(&d.channels) {
        // Not flashable: the table of all axes is DIR/table.bin (see `output`'s docs).
        let (_, plots) =
            super::output::write(ch, r, None, &dir.join(&a.axis), Scope::StaticAxis { discovery: &d, axis: a })?;
        axis_plots.push(plots);
    }
    write_file(&dir.join("table.bin"), d.table.to_bytes().map_err(DiscoverError::Table)?)?;
    let files: Vec<String> = ["table.bin", "report.json", "report.md", "report.html"].map(String::from).to_vec();
    let v = super::verdict::static_verdict(&d, &files);
    write_json(&dir.join("report.json"), &v, &d)?;
    write_file(&dir.join("report.md"), format!("# Discovery on a static log\n\n{}{}", v.markdown(), markdown(&d)))?;
    super::page::static_page(&d, &v, &axis_plots).write(dir).map_err(DiscoverError::Page)?;
    Ok((d, v))
}
