//! `report.md` of a log's discovery: the opening, the gaps and the summary, then the peers,
//! the effects, what is unexplained, where the models disagree, the rounds and the files.

use std::fmt::Write as _;

use super::*;

/// `report.md`: the opening, the gaps and the summary, then the peers, the effects, what
/// is unexplained, where the models disagree, the rounds and the files.
pub(super) fn markdown(ch: &Channels, r: &Report, scope: Scope<'_>, v: &Verdict) -> String {
    let held = &scope.folds_word();
    let mut s = String::new();
    markdown_opening(&mut s, r, scope, v);
    markdown_gaps(&mut s, ch, r, scope);
    let _ = writeln!(s, "Summary: {}.\n", summary_text(ch, r, held));
    if scope.flashable() {
        flashed_line(&mut s, ch, r);
    }
    let _ = writeln!(s, "Selection: {}.\n", scope.relabel(&r.selection_rule));
    markdown_peers(&mut s, ch, r, scope);
    markdown_effects(&mut s, r, scope);
    markdown_unexplained(&mut s, ch, r, held);
    markdown_where(&mut s, ch, r, held);
    markdown_rounds(&mut s, ch, r, held);
    markdown_files(&mut s, scope);
    s
}

/// The title and verdict, then the start model and the rule its figures come from: the
/// log's own held-out rule, or a static axis's figures and its selection folds.
fn markdown_opening(s: &mut String, r: &Report, scope: Scope<'_>, v: &Verdict) {
    match scope {
        Scope::Own => {
            let _ = write!(s, "# Discovery report\n\n{}", v.markdown());
            let _ = writeln!(s, "Start model: `{}`. Held-out rule: {}.\n", r.start.name(), r.heldout_rule);
        }
        Scope::StaticAxis { discovery, axis } => {
            let _ = write!(s, "{}\n\n{}", crate::static_axes::axis_title(axis), v.markdown());
            s.push_str(&crate::static_axes::axis_figures_markdown(discovery, axis));
            let _ = writeln!(s, "\n## How discovery chose (selection folds)\n");
            let _ = writeln!(
                s,
                "The figures in this section come from the block test's own folds inside the rows it saw (they \
                 decide what the block test names), so they are called selection-fold figures; its model is called \
                 the block test's model (the named model is the table's, above); the held-out figures of the axis \
                 are the ones above.\n"
            );
            let _ = writeln!(
                s,
                "Start model: `{}`. Selection folds: {}.\n",
                r.start.name(),
                scope.relabel(&r.heldout_rule)
            );
        }
    }
}

/// The gaps of the start and the named model, the noise floor, the noise model, the
/// change points and the timing offset, as a list.
fn markdown_gaps(s: &mut String, ch: &Channels, r: &Report, scope: Scope<'_>) {
    let (held, held_cap) = (&scope.folds_word(), &scope.folds_word_capital());
    let _ = writeln!(s, "- {held_cap} gap, start model: {}", gaps_text(ch.bias_unit, &r.heldout_gap_before));
    let _ = writeln!(
        s,
        "- {held_cap} gap, {}{}: {}",
        scope.model_name(r),
        if worse(r) { " (worse than the start)" } else { "" },
        gaps_text(ch.bias_unit, &r.heldout_gap_after)
    );
    let _ = writeln!(
        s,
        "- Noise floor (bin-to-bin noise of the model fitted to the final {held} residual): {}",
        gaps_text(ch.bias_unit, &r.noise_floor)
    );
    let _ = writeln!(
        s,
        "- Noise model: {}; change points: {}; noise by run: {}{}",
        noise_models_text(ch, r),
        change_point_tests_text(r),
        run_noise_tests_text(r),
        branch_test_text(r).map_or_else(String::new, |b| format!("; level by ramp branch: {b}"))
    );
    if let Some(line) = timing_offset_text(ch, r) {
        let _ = writeln!(s, "- Timing offset between the temperature readings and the counts: {line}");
    }
    let _ = writeln!(s);
}

/// The summary's words after "Summary: ": the effects added, then what is left of the
/// residual against its noise floor.
fn summary_text(ch: &Channels, r: &Report, held: &str) -> String {
    let labels = r.effect_labels();
    format!(
        "added {}; {}",
        if labels.is_empty() { "none".to_string() } else { labels.join(", ") },
        if r.unexplained.is_empty() {
            let ratios = r
                .residual_vs_floor
                .iter()
                .map(|f| format!("{} {:.1}× [{:.1}, {:.1}]", f.channel, f.ratio, f.ratio_ci95[0], f.ratio_ci95[1]))
                .collect::<Vec<_>>()
                .join(", ");
            if r.residual_vs_floor.iter().any(|f| f.ratio > 2.0) {
                format!(
                    "the {held} residual is {ratios} its bin-to-bin noise floor, and the noise model fitted to it ({}) is \
                     not rejected: no step inside any run ({}), no run noisier than it allows ({}){}, run levels \
                     within its noise, no driver followed; slow noise of that size explains it, and the catalog's \
                     effects cannot be told from it",
                    noise_models_text(ch, r),
                    change_point_tests_text(r),
                    run_noise_tests_text(r),
                    branch_test_text(r).map_or_else(String::new, |b| format!(", no scale-factor level by ramp branch ({b})"))
                )
            } else {
                format!(
                    "no structure left that the catalog fails to explain ({held} residual {ratios} its noise floor)"
                )
            }
        } else {
            format!(
                "unexplained structure left on {}",
                r.unexplained.iter().map(|u| u.channel.as_str()).collect::<Vec<_>>().join(", ")
            )
        }
    )
}

/// The peers' table: every model's held-out RMS of the bias channel on the same split.
fn markdown_peers(s: &mut String, ch: &Channels, r: &Report, scope: Scope<'_>) {
    let held = &scope.folds_word();
    let unit = ch.bias_unit.label();
    let _ = writeln!(
        s,
        "## Peers on the same {held} split (bias channel, {unit})\n\nEach fitted per fold on the training bins (bin means of the raw temperature reading) and scored on the bins its fold left out.\n\n| model | {held} RMS |\n|---|---|"
    );
    let bias_gap = |g: &Gaps| match g {
        Gaps::Cycling { bias_ug, .. } => *bias_ug,
        Gaps::Single { value_rms } => *value_rms,
    };
    let _ = writeln!(s, "| start model (`{}`) | {:.4} |", r.start.name(), bias_gap(&r.heldout_gap_before));
    let _ = writeln!(s, "| {} | {:.4} |", scope.model_name(r), bias_gap(&r.heldout_gap_after));
    for p in &r.peers {
        match (&p.heldout_rms, &p.error) {
            (Some(x), _) => {
                let _ = writeln!(s, "| {} | {x:.4} |", p.peer);
            }
            (None, e) => {
                let _ = writeln!(s, "| {} | not computed: {} |", p.peer, e.as_deref().unwrap_or("no figure"));
            }
        }
    }
    let _ = writeln!(s);
}

/// The effects added, one row each, or a line saying none was.
fn markdown_effects(s: &mut String, r: &Report, scope: Scope<'_>) {
    let held = &scope.folds_word();
    if r.effects.is_empty() {
        let _ = writeln!(s, "## Effects added: none\n\nNo candidate improved the {held} fit significantly.\n");
    } else {
        let _ = writeln!(
            s,
            "## Effects added\n\n| # | effect | channel | parameters (95 % interval) | {held} gain ± block-bootstrap SE | {held} gap before → after | {} |\n|---|---|---|---|---|---|---|",
            if scope.flashable() { "in table.bin" } else { "root-crate slot" }
        );
        for (i, e) in r.effects.iter().enumerate() {
            let p: Vec<String> = e.params_text(" **at search limit**");
            let _ = writeln!(
                s,
                "| {} | `{}` | {} | {} | {:.1} ± {:.1} | {:.3} → {:.3} | {} |",
                i + 1,
                e.name,
                e.channel,
                p.join("; "),
                e.gain.gain,
                e.gain.bootstrap_se,
                e.heldout_gap_before,
                e.heldout_gap_after,
                e.not_in_table.as_deref().map_or_else(|| "yes".to_string(), |w| format!("no ({w})"))
            );
        }
        let _ = writeln!(s);
    }
}

/// The "Unexplained" section, one paragraph per channel with structure left (none when
/// every channel is explained).
fn markdown_unexplained(s: &mut String, ch: &Channels, r: &Report, held: &str) {
    if !r.unexplained.is_empty() {
        let _ = writeln!(s, "## Unexplained\n");
        for u in &r.unexplained {
            let line = unexplained_line(ch, r, u, held);
            let _ = writeln!(s, "{line}");
        }
        let _ = writeln!(s);
    }
}

/// One channel's unexplained structure in words: its size against the noise floor, run
/// levels, a change point, what it follows, its time scale, where it is largest and the
/// effects pinned at a search limit.
fn unexplained_line(ch: &Channels, r: &Report, u: &crate::Unexplained, held: &str) -> String {
    let mut line =
        format!("- The {} channel keeps structure that no catalog effect explains ({held} RMS {:.3}", u.channel, u.rms);
    let _ = write!(
        line,
        ", {:.1}× its noise floor of {:.3}, 95 % interval [{:.1}, {:.1}]",
        u.floor.ratio, u.floor.floor, u.floor.ratio_ci95[0], u.floor.ratio_ci95[1]
    );
    if let Some(l) = u.run_levels.as_ref().filter(|l| l.significant) {
        let _ = write!(
            line,
            "; its mean differs between runs more than noise allows (χ² {:.1} on {} runs, critical {:.1})",
            l.q, l.runs, l.critical
        );
    }
    if let Some(c) = &u.change_point {
        let _ = write!(
            line,
            "; {} steps by {:+.3} {} at {:.2} h into {}{}, which the fitted noise model ({}) rejects (|z| {:.1} \
             against {:.1}, {} search)",
            if c.series == u.channel { "its level".to_string() } else { format!("the {}", c.series) },
            c.size,
            channel_unit(ch, &c.series),
            c.at_h,
            c.run,
            if c.series == u.channel { "" } else { " (K1 and K0 each carry half of it)" },
            noise_model_of(r, &c.series).map_or_else(String::new, |n| n.model.text(channel_unit(ch, &c.series))),
            c.z,
            c.critical,
            c.search
        );
    }
    if let Some(b) = &u.branch_level {
        let _ = write!(
            line,
            "; its level differs by ramp branch, {:+.3} on heating and {:+.3} on cooling (a dwell with the ramp \
             before it, 10 min after each reversal left out), which the fitted noise model rejects (|z| {:.1} \
             against {:.2}); the timing offset fitted alongside takes such a level's share on the ramps, so read \
             the offset with it",
            b.size,
            -b.size,
            b.z.abs(),
            b.critical
        );
    }
    if let Some(n) = &u.noisy_run {
        let _ = write!(
            line,
            "; {} noise in {} is {:.1}× the median run's, more than the fitted noise model gives any run",
            if n.series == u.channel { "its".to_string() } else { format!("the {}'s", n.series) },
            n.run,
            n.ratio
        );
    }
    match u.structure_rms {
        Some(x) if !u.correlates_with.is_empty() => {
            let _ = write!(line, "; about {x:.3} of it follows {}).", u.correlates_with.join(", then "));
        }
        _ if u.branch_level.is_some() => line.push_str("; no cross-fitted driver passes its block test)."),
        _ => line.push_str("; it follows none of the drivers tested)."),
    }
    let ts = &u.time_scales;
    let _ = write!(
        line,
        " It lives mostly {} (RMS across runs {:.3}, slow within runs {:.3}, fast {:.3}).",
        ts.dominant(),
        ts.across_runs,
        ts.within_run_slow,
        ts.fast
    );
    if !u.where_.is_empty() {
        let _ = write!(line, " It is largest on {}.", u.where_);
    }
    if !u.pinned.is_empty() {
        let _ = write!(
            line,
            " Catalog effects that would fit only with a parameter at a search limit, so are not named: {}.",
            u.pinned.join("; ")
        );
    }
    line
}

/// Where the start model and where the final model disagree, one table each.
fn markdown_where(s: &mut String, ch: &Channels, r: &Report, held: &str) {
    let unit = if ch.kind == LogKind::Cycling { "ppm / µg".to_string() } else { ch.bias_unit.label().to_string() };
    let _ = writeln!(
        s,
        "## Where the start model disagrees ({held} RMS, {unit})\n\n| channel | segment | RMS |\n|---|---|---|"
    );
    for w in &r.where_ {
        let _ = writeln!(s, "| {} | {} | {:.3} |", w.channel, w.segment, w.rms);
    }
    let _ = writeln!(
        s,
        "\n## Where the final model disagrees ({held} RMS, {unit})\n\n| channel | segment | RMS |\n|---|---|---|"
    );
    for w in &r.where_after {
        let _ = writeln!(s, "| {} | {} | {:.3} |", w.channel, w.segment, w.rms);
    }
}

/// Every round's candidates, one table per round.
fn markdown_rounds(s: &mut String, ch: &Channels, r: &Report, held: &str) {
    let _ = writeln!(s, "\n## Candidates per round\n\nGain: drop of the {held} Σ(residual/RMS)² (units of one bin's variance); SE from the block sums; significant when gain/SE exceeds the critical value and the raw gain and the effect's weight pass their tests too; a \"no\" names the first that did not.\n");
    for (i, round) in r.rounds.iter().enumerate() {
        let cols = super::ROUND_HEADER.join(" | ");
        let _ =
            writeln!(s, "### Round {}\n\n| {cols} | {held} gaps |\n|---|---|---|---|---|---|---|---|---|---|", i + 1);
        for t in round {
            let _ = writeln!(s, "| `{} |", round_row(ch, t).join(" | ").replacen(" | ", "` | ", 1));
        }
        let _ = writeln!(s);
    }
}

/// The closing line naming the files beside the report.
fn markdown_files(s: &mut String, scope: Scope<'_>) {
    if scope.flashable() {
        let _ = writeln!(s, "Files: `report.json`, `table.bin` (root-crate table, 1 axis, rate window 32: `qfa-lab compensate --table DIR/table.bin`), `model.bin` (same bytes), `model.toml`, `residuals.csv`, `residual_*.png`.");
    } else {
        let _ = writeln!(s, "Files: `report.json`, `model.toml` (the block test's model, for reading: its K1 is 1 and `bias_drift` has no slot, so it is not a table to flash; the flashable table of all axes is `../table.bin`), `residuals.csv`, `residual_*.png`.");
    }
}
