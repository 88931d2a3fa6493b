//! Discovery's `report.html` ([`qfa_report::html_report`]): the verdict, the report's fields as
//! tables (every table a [`Page::table`] or [`Page::kv`]), what the log covers, and every
//! PNG in the output folder with a caption saying what to look for.

use super::output::{gaps_text, Scope};
use super::static_axes::StaticDiscovery;
use super::{Channels, Gaps, Report};
use qfa_calibrate::coverage::{Coverage, CoverageError};
use qfa_report::html_report::Page;
use qfa_report::plot_png::Plot;
use qfa_report::verdict::Verdict;

/// What the log's traces cover, as the rate estimator sees them.
///
/// # Errors
/// No row with a temperature.
pub(crate) fn coverage(ch: &Channels) -> Result<Coverage, CoverageError> {
    let s = ch.traces.iter().flat_map(|t| t.est_t.iter().zip(&t.est_rate).map(|(&a, &r)| (f64::from(a), f64::from(r))));
    Coverage::of_samples(s, f64::from(qfa_log::replay::branch_deadband_c_per_min()))
}

/// The caption's sentence for a `channel` whose residual wanders more than twice its noise
/// floor (bin to bin) while its fitted noise model is not rejected: slow noise explains it.
fn slow_noise_sentence(ch: &Channels, r: &Report, channel: &str) -> Option<String> {
    let f = r.residual_vs_floor.iter().find(|f| f.channel == channel && f.ratio > 2.0)?;
    if r.unexplained.iter().any(|u| u.channel == channel) {
        return None;
    }
    Some(format!(
        " The lower panel wanders {:.1}× wider than its bin-to-bin noise floor, and the noise model fitted to it ({}) \
         is not rejected (no step inside a run, run levels within its noise, no driver followed): slow \
         noise of that size explains it, and the catalog's effects cannot be told from it.",
        f.ratio,
        super::output::noise_model_of(r, channel)
            .map_or_else(String::new, |n| n.model.text(super::output::channel_unit(ch, channel)))
    ))
}

/// What to look for in one of [`super::output`]'s residual plots (`file`), and why it may
/// look alarming.
#[must_use]
pub(crate) fn caption(file: &str, ch: &Channels, r: &Report, scope: Scope<'_>) -> String {
    let held = &scope.folds_word();
    let vs_time = file.ends_with("_vs_time.png");
    let (name, pick): (&str, fn(&Gaps) -> f64) = if file.starts_with("residual_scale_factor") {
        ("Scale-factor", |g| if let Gaps::Cycling { scale_factor_ppm, .. } = g { *scale_factor_ppm } else { f64::NAN })
    } else {
        ("Bias", |g| match g {
            Gaps::Cycling { bias_ug, .. } => *bias_ug,
            Gaps::Single { value_rms } => *value_rms,
        })
    };
    let unit = if name == "Scale-factor" { "ppm" } else { ch.bias_unit.label() };
    let (start, named, floor) = (pick(&r.heldout_gap_before), pick(&r.heldout_gap_after), pick(&r.noise_floor));
    let mut s = format!(
        "{name} residual of every bin, each from a fit that never saw it ({}): start model above, {} below, on \
         one scale, against {}; red heating, blue cooling, grey hold.",
        scope.folds_name(),
        scope.model_name(r),
        if vs_time { "time" } else { "temperature" }
    );
    if vs_time {
        s.push_str(&format!(
            " Look at the lower panel: a band about as wide as the noise ({floor:.2} {unit} bin to bin) means nothing \
             is left; steps between runs, slow trends, or heating sitting apart from cooling are what the {} \
             misses.",
            scope.model_name(r)
        ));
    } else {
        s.push_str(
            " Look at the lower panel: a curve left means the temperature shape is wrong; heating apart from cooling \
             at one temperature is a lag or a hysteresis left.",
        );
        if super::output::hold_bins(ch) > 0 {
            s.push_str(
                " Grey points stack in columns at the hold temperatures: their spread is how far the output moves \
                 while the temperature stands still.",
            );
        }
    }
    let channel = if name == "Scale-factor" {
        "scale_factor"
    } else if ch.kind == super::LogKind::Cycling {
        "bias"
    } else {
        "value"
    };
    if let Some(sentence) = slow_noise_sentence(ch, r, channel) {
        s.push_str(&sentence);
    }
    if start > 2.0 * named {
        s.push_str(&format!(
            " The upper panel's large swings are the start model's, which lacks what was named ({held} RMS \
             {start:.2} against {named:.2} {unit}); the shared scale keeps the lower panel comparable."
        ));
    } else if format!("{named:.2}") != format!("{start:.2}") && named > start {
        s.push_str(&format!(
            " The lower panel is the worse one: on this channel the {}'s {held} RMS ({named:.2} {unit}) is \
             above the start model's ({start:.2} {unit}); the verdict says what to expect.",
            scope.model_name(r)
        ));
    }
    if let Scope::StaticAxis { axis, .. } = scope {
        if let (Some(b), Some(n)) =
            (axis.before.score().map(|x| x.rms_mg), axis.block_test_model.score().map(|x| x.rms_mg))
        {
            if n > b {
                s.push_str(&format!(
                    " These selection folds are the rows the block test chose on, so they flatter its model: held \
                     out on the log's scheme it is worse than the start model ({n:.2} mg against {b:.2} mg). The \
                     named model is the search's, the verdict's figures."
                ));
            }
        }
    }
    s
}

/// The page of one discovery run, opening with its verdict, with the plots it drew.
pub(crate) fn page(ch: &Channels, r: &Report, scope: Scope<'_>, v: &Verdict, plots: &[Plot]) -> Page {
    let held = &scope.folds_word();
    let mut p = match scope {
        Scope::Own => Page::new("Discovery report"),
        Scope::StaticAxis { axis, .. } => {
            Page::new(&format!("Discovery report: axis {} (column {})", axis.axis, axis.column))
        }
    };
    v.to_page(&mut p);
    page_scheme(&mut p, r, scope);
    page_gaps(&mut p, ch, r, scope);
    page_effects(&mut p, r, scope);
    page_unexplained(&mut p, ch, r, held);
    page_peers(&mut p, ch, r, scope);
    page_coverage(&mut p, ch);
    page_where(&mut p, ch, r, held);
    page_rounds(&mut p, ch, r, held);
    p.section(&format!("Plots ({held} residuals)"));
    p.plots(plots, |name| caption(name, ch, r, scope));
    p.para("Every figure on this page is also in report.md and report.json beside it.");
    p
}

/// The held-out scheme: the log's own, or a static axis's held-out figures followed by
/// the selection folds discovery chose on.
fn page_scheme(p: &mut Page, r: &Report, scope: Scope<'_>) {
    if let Scope::StaticAxis { discovery, axis } = scope {
        p.section("Held-out figures of this axis, mg (RMS over rows / over 60-s means)");
        p.para(&super::static_axes::axis_figures_intro(discovery));
        let rows: Vec<Vec<String>> =
            super::static_axes::axis_figures(discovery, axis).into_iter().map(Vec::from).collect();
        p.table(&["model", "held-out, mg"], &rows);
        p.section("How discovery chose (selection folds)").para(
            "Everything below comes from the block test's own folds over every row of this axis: they decided what \
             the block test names, so their figures are called selection-fold figures (in µg), and its model the \
             block test's model (the named model is the table's, above).",
        );
        p.kv(&[
            ("start model", r.start.name().to_string()),
            ("selection folds", scope.relabel(&r.heldout_rule)),
            ("selection", scope.relabel(&r.selection_rule)),
        ]);
    } else {
        p.section("Held-out scheme").kv(&[
            ("start model", r.start.name().to_string()),
            ("held-out rule", r.heldout_rule.clone()),
            ("selection", r.selection_rule.clone()),
        ]);
    }
}

/// The gaps section: the start, named and flashed models' gaps, the noise floor and
/// model, the change points, the timing offset and the residual against the floor.
fn page_gaps(p: &mut Page, ch: &Channels, r: &Report, scope: Scope<'_>) {
    let (held, held_cap) = (&scope.folds_word(), &scope.folds_word_capital());
    let mut gap_rows = vec![
        ("start model".to_string(), gaps_text(ch.bias_unit, &r.heldout_gap_before)),
        (scope.model_name(r).to_string(), gaps_text(ch.bias_unit, &r.heldout_gap_after)),
    ];
    if let Scope::Own = scope {
        gap_rows.push((
            "flashed (table.bin)".to_string(),
            format!(
                "{}: {}{}",
                r.flashed.model,
                super::output::flashed_text(ch.bias_unit, &r.flashed),
                r.flashed.peer_better.as_ref().map_or_else(String::new, |b| format!(
                    "; {} predicts the bias better ({:.3})",
                    b.peer, b.heldout_rms
                ))
            ),
        ));
    }
    gap_rows.push((
        format!("noise floor (bin-to-bin noise of the noise model of the final {held} residual)"),
        gaps_text(ch.bias_unit, &r.noise_floor),
    ));
    gap_rows.push(("noise model".to_string(), super::output::noise_models_text(ch, r)));
    gap_rows.push(("change points".to_string(), super::output::change_point_tests_text(r)));
    gap_rows.push(("noise by run".to_string(), super::output::run_noise_tests_text(r)));
    if let Some(b) = super::output::branch_test_text(r) {
        gap_rows.push(("level by ramp branch".to_string(), b));
    }
    if let Some(t) = super::output::timing_offset_text(ch, r) {
        gap_rows.push(("timing offset (temperature vs counts)".to_string(), t));
    }
    gap_rows.push((
        format!("{held} residual / noise floor (95 % interval)"),
        r.residual_vs_floor
            .iter()
            .map(|f| format!("{} {:.1}× [{:.1}, {:.1}]", f.channel, f.ratio, f.ratio_ci95[0], f.ratio_ci95[1]))
            .collect::<Vec<_>>()
            .join(", "),
    ));
    p.section(&format!("{held_cap} gaps")).kv(&gap_rows);
}

/// The effects added, one row each, or a line saying none was.
fn page_effects(p: &mut Page, r: &Report, scope: Scope<'_>) {
    let held = &scope.folds_word();
    let effects: Vec<Vec<String>> = r
        .effects
        .iter()
        .map(|e| {
            let params: Vec<String> = e.params_text(" at search limit");
            vec![
                e.name.clone(),
                e.channel.clone(),
                params.join("; "),
                format!("{:.1} ± {:.1}", e.gain.gain, e.gain.bootstrap_se),
                format!("{:.3} → {:.3}", e.heldout_gap_before, e.heldout_gap_after),
                e.not_in_table.as_deref().map_or_else(|| "yes".to_string(), |w| format!("no: {w}")),
                e.confusable_with.join(", "),
            ]
        })
        .collect();
    p.section("Effects added");
    if effects.is_empty() {
        p.para(&format!("none: no candidate improved the {held} fit significantly"));
    } else {
        p.table(
            &[
                "effect".to_string(),
                "channel".to_string(),
                "parameters (95 % interval)".to_string(),
                format!("{held} gain ± SE"),
                format!("{held} gap before → after"),
                if scope.flashable() { "in table.bin" } else { "root-crate slot" }.to_string(),
                "as good as".to_string(),
            ],
            &effects,
        );
    }
}

/// A warning for each channel that keeps structure no catalog effect explains, with what
/// rejected the fitted noise model ([`super::Unexplained::evidence`]).
fn page_unexplained(p: &mut Page, ch: &Channels, r: &Report, held: &str) {
    for u in &r.unexplained {
        let unit = super::output::channel_unit(ch, &u.channel);
        p.warning(&format!(
            "the {} channel keeps structure no catalog effect explains ({held} RMS {:.3} {unit}, {:.1}× its noise \
             floor, mostly {}): {}{}",
            u.channel,
            u.rms,
            u.floor.ratio,
            u.time_scales.dominant(),
            u.evidence(unit, ch.bias_unit.label()),
            if u.where_.is_empty() { String::new() } else { format!("; largest on {}", u.where_) }
        ));
    }
}

/// The peers' table: every model's held-out RMS of the bias channel on the same split.
fn page_peers(p: &mut Page, ch: &Channels, r: &Report, scope: Scope<'_>) {
    let held = &scope.folds_word();
    let bias_gap = |g: &Gaps| match g {
        Gaps::Cycling { bias_ug, .. } => *bias_ug,
        Gaps::Single { value_rms } => *value_rms,
    };
    let mut peers: Vec<Vec<String>> = vec![
        vec![format!("start model ({})", r.start.name()), format!("{:.4}", bias_gap(&r.heldout_gap_before))],
        vec![scope.model_name(r).to_string(), format!("{:.4}", bias_gap(&r.heldout_gap_after))],
    ];
    peers.extend(r.peers.iter().map(|x| {
        vec![
            x.peer.clone(),
            x.heldout_rms.map_or_else(
                || format!("not computed: {}", x.error.as_deref().unwrap_or("no figure")),
                |v| format!("{v:.4}"),
            ),
        ]
    }));
    p.section(&format!("Peers on the same {held} split (bias channel, {})", ch.bias_unit.label()))
        .table(&["model".to_string(), format!("{held} RMS")], &peers);
}

/// What the log covers against what the models need, and what to record next.
fn page_coverage(p: &mut Page, ch: &Channels) {
    p.section("What the log covers, against what the models need");
    match coverage(ch) {
        Ok(c) => {
            p.kv(&c.rows());
            p.para(
                "The rate and branch effects (sensor_lag, rate_hysteresis, bias_branch_hysteresis, bias_creep) are \
                 told apart by heating and cooling legs at more than one rate; a log without one leg cannot name them.",
            );
            for n in c.record_next() {
                p.warning(&format!("What to record next: {n}."));
            }
        }
        Err(e) => {
            p.warning(&format!("coverage not computed: {e:#}"));
        }
    }
}

/// Where the start model and where the final model disagree, one table each.
fn page_where(p: &mut Page, ch: &Channels, r: &Report, held: &str) {
    let unit = if ch.kind == super::LogKind::Cycling { "ppm / µg" } else { ch.bias_unit.label() };
    let where_rows = |w: &[super::Where]| -> Vec<Vec<String>> {
        w.iter().map(|w| vec![w.channel.clone(), w.segment.clone(), format!("{:.3}", w.rms)]).collect()
    };
    p.section(&format!("Where the start model disagrees ({held} RMS, {unit})"))
        .table(&["channel", "segment", "RMS"], &where_rows(&r.where_));
    p.section(&format!("Where the final model disagrees ({held} RMS, {unit})"))
        .table(&["channel", "segment", "RMS"], &where_rows(&r.where_after));
}

/// Every round's candidates, one table per round.
fn page_rounds(p: &mut Page, ch: &Channels, r: &Report, held: &str) {
    p.section("Candidates per round").para(&format!(
        "Gain: drop of the {held} Σ(residual/RMS)² (units of one bin's variance); SE from the block sums; \
         significant when gain/SE exceeds the critical value and the raw gain and the effect's weight pass their \
         tests too; a \"no\" names the first that did not."
    ));
    let mut header: Vec<String> = super::output::ROUND_HEADER.map(String::from).to_vec();
    header.push(format!("{held} gaps"));
    for (i, round) in r.rounds.iter().enumerate() {
        p.para(&format!("Round {}", i + 1));
        let rows: Vec<Vec<String>> = round.iter().map(|t| super::output::round_row(ch, t)).collect();
        p.table(&header, &rows);
    }
}

/// The page of a static log's discovery: its verdict, the per-axis figures as tables, what
/// the log covers, then each axis's plots (each axis also has its own `report.html`).
pub(crate) fn static_page(d: &StaticDiscovery, v: &Verdict, axis_plots: &[Vec<Plot>]) -> Page {
    let mut p = Page::new("Discovery report, static multi-axis log");
    v.to_page(&mut p);
    let h = &d.holdout;
    p.section("Held-out scheme").kv(&[
        ("asked (--holdout)", h.requested.clone()),
        ("ran", h.scheme.clone()),
        ("rule", h.rule.clone()),
        ("which rows each figure comes from", d.figures.clone()),
        ("start model", d.start.name().to_string()),
        ("discovery's bins", format!("{} s (the per-axis reports are in µg)", d.bin_s)),
    ]);
    let [_, selection, named_flashed] = super::static_axes::how_to_read(d);
    p.section("Per axis, mg (RMS over held-out rows / over 60-s means)");
    p.para(&selection);
    let (header, rows) = super::static_axes::table_rows(d);
    p.table(&header, &rows);
    p.para(&named_flashed);
    for a in &d.axes {
        p.section(&format!("{}: the search, step by step, held out", a.axis));
        let rows: Vec<Vec<String>> = super::static_axes::step_rows(a).into_iter().map(Vec::from).collect();
        p.table(&["step", "structure", "CV RMS over every row, mg", "held out, mg", "change held out, mg"], &rows);
        for n in &a.not_added {
            p.warning(&format!("{}: named by the block test, not added: {n}", a.axis));
        }
    }
    if let Some(ch) = d.channels.first() {
        p.section("What the log covers, against what the models need");
        match coverage(ch) {
            Ok(c) => {
                p.kv(&c.rows());
                for n in c.record_next() {
                    p.warning(&format!("What to record next: {n}."));
                }
            }
            Err(e) => {
                p.warning(&format!("coverage not computed: {e:#}"));
            }
        }
    }
    for (((a, r), ch), plots) in d.axes.iter().zip(&d.reports).zip(&d.channels).zip(axis_plots) {
        p.section(&format!(
            "{} ({}): selection-fold residual plots (its own page: {}/report.html)",
            a.axis, a.column, a.axis
        ));
        let scope = Scope::StaticAxis { discovery: d, axis: a };
        p.plots(plots, |name| format!("{}: {}", a.axis, caption(name, ch, r, scope)));
    }
    p
}
