//! A discovery's verdict ([`qfa_report::verdict::Verdict`], a study: no limit applies): what was
//! named, whether the named model beats the start model held out (both figures, in one
//! sentence), which model `table.bin` holds, and the figures to expect, for a discovery of
//! its own log (cycling or single-channel) and for a static log, whole or one axis.
//!
//! The words follow the printed figures: a model "beats" or "is worse than" another only
//! when their figures differ at the precision printed (two decimals), so no sentence
//! contradicts the numbers beside it.

use super::page::coverage;
use super::static_axes::{AxisDiscovery, StaticDiscovery};
use super::{BiasUnit, Channels, Gaps, LogKind, Report};
use qfa_calibrate::static_cal::report::Figure;
use qfa_report::verdict::{Expected, FileUse, Verdict};

/// One figure of one channel: `(channel, value, unit)`.
type ChannelFigure = (&'static str, f64, &'static str);

/// How a figure compares with the one before it (the named model's with the start model's,
/// a search step's with the step before), at the printed precision.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Compared {
    Better,
    Same,
    Worse,
}

pub(crate) fn compare(start: f64, named: f64) -> Compared {
    if format!("{named:.2}") == format!("{start:.2}") {
        Compared::Same
    } else if named < start {
        Compared::Better
    } else {
        Compared::Worse
    }
}

/// A report's channel gaps as named figures (a static axis's and a cycling log's bias in
/// µg, a single-channel log's value in its own unit).
fn channel_figures(g: &Gaps, unit: BiasUnit) -> Vec<ChannelFigure> {
    match g {
        Gaps::Cycling { scale_factor_ppm, bias_ug } => {
            vec![("scale factor", *scale_factor_ppm, "ppm"), ("bias", *bias_ug, "µg")]
        }
        Gaps::Single { value_rms } => {
            vec![(if unit == BiasUnit::Value { "value" } else { "bias" }, *value_rms, unit.label())]
        }
    }
}

/// `named model N unit, start model S unit` per channel (`; ` between channels).
fn both_figures(start: &[ChannelFigure], named: &[ChannelFigure]) -> String {
    let one = start.len() == 1;
    start
        .iter()
        .zip(named)
        .map(|((c, s, u), (_, n, _))| {
            let head = if one { String::new() } else { format!("{c}: ") };
            format!("{head}named {n:.2} {u}, start {s:.2} {u}")
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// How the named model stands against the start model over the channels, in words
/// (`beats the start model `simple` held out`, `is worse held out than …`, or which
/// channels go which way).
fn standing(start_name: &str, start: &[ChannelFigure], named: &[ChannelFigure]) -> (String, Vec<&'static str>) {
    let cmp: Vec<(&'static str, Compared)> =
        start.iter().zip(named).map(|((c, s, _), (_, n, _))| (*c, compare(*s, *n))).collect();
    let pick = |k: Compared| cmp.iter().filter(|(_, x)| *x == k).map(|(c, _)| *c).collect::<Vec<_>>();
    let (better, worse) = (pick(Compared::Better), pick(Compared::Worse));
    let start = format!("the start model `{start_name}`");
    let words = match (better.is_empty(), worse.is_empty()) {
        (true, true) => format!("holds out the same as {start}"),
        (false, true) => format!("beats {start} held out"),
        (true, false) => format!("is worse held out than {start}"),
        (false, false) => format!(
            "beats {start} held out on {} but is worse held out on {}",
            better.join(" and "),
            worse.join(" and ")
        ),
    };
    (words, worse)
}

/// The files of a discovery folder, each with what to do with it (`axis`: a static log's
/// axis folder, whose `model.toml` is for reading only).
fn file_uses(files: &[String], axis: bool) -> Vec<FileUse> {
    files
        .iter()
        .map(|f| match f.as_str() {
            "model.bin" => FileUse { file: f.clone(), action: "the same bytes as table.bin (its older name)".into() },
            "model.toml" if axis => FileUse {
                file: f.clone(),
                action: "read only: the block test's own model in µg (K1 = 1, `bias_drift` without a slot), not \
                         a table to flash; the named model is the table of all axes, ../table.bin"
                    .into(),
            },
            "model.toml" => FileUse { file: f.clone(), action: "keep: table.bin as text, to read and diff".into() },
            _ => FileUse::of(f),
        })
        .collect()
}

/// Coverage of `ch` for the verdict: what the table covers and what to record next.
fn covers_and_advice(v: &mut Verdict, ch: &Channels, table: Option<&crate::cycling_table::CyclingTable>) {
    if let Some(t) = table {
        v.covers = Some(t.coverage.covers());
        v.advice = t.coverage.record_next();
    } else if let Ok(c) = coverage(ch) {
        v.covers = Some(c.covers());
        v.advice = c.record_next();
    }
}

/// The verdict of a discovery of its own log (cycling or single-channel) written into a
/// folder holding `files`; `notes` are what the run must say in words (a table that did
/// not validate, plots that failed).
#[must_use]
pub(crate) fn discovery_verdict(ch: &Channels, r: &Report, files: &[String], notes: &[String]) -> Verdict {
    let start = channel_figures(&r.heldout_gap_before, ch.bias_unit);
    // A cycling log's named model is its table ([`super::cycling_table`]); a single-channel
    // log's is the catalog's.
    let named = match (&r.table, &r.flashed.heldout) {
        (None, _) => channel_figures(&r.heldout_gap_after, ch.bias_unit),
        (Some(_), Some(g)) => channel_figures(g, ch.bias_unit),
        (Some(_), None) => Vec::new(),
    };
    let (words, worse) = standing(r.start.name(), &start, &named);
    let wrote = files.iter().any(|f| f == "table.bin");
    let table = if wrote {
        format!("table.bin holds the {}", r.flashed.model)
    } else {
        "no table.bin was written (see the warnings)".to_string()
    };
    let answer = if let Some(t) = &r.table {
        let caught = if r.effects.is_empty() {
            "nothing beyond the start model".to_string()
        } else {
            r.effect_labels().join(", ")
        };
        let left: Vec<String> = r.effects.iter().filter(|e| e.not_in_table.is_some()).map(|e| e.name.clone()).collect();
        let standing = match &r.flashed.not_computed {
            Some(why) => format!("held back: {why}"),
            None => format!("which {words} ({})", both_figures(&start, &named)),
        };
        format!(
            "named {} = {}, the table `calibrate` writes for this log, {standing}; the block test named {caught}{}",
            t.structure,
            if wrote { "table.bin" } else { "the table (not written: see the warnings)" },
            if left.is_empty() {
                String::new()
            } else {
                format!("; not in table.bin: {} (see the warnings)", left.join(", "))
            }
        )
    } else if r.effects.is_empty() {
        let figs: Vec<String> = start.iter().map(|(c, s, u)| format!("{c} {s:.2} {u}")).collect();
        format!(
            "nothing named, so the named model is the start model `{}` (held out {}); {table}",
            r.start.name(),
            figs.join(", ")
        )
    } else {
        format!("named {}, which {words} ({}); {table}", r.effect_labels().join(", "), both_figures(&start, &named))
    };
    let held_out = format!("{}; every figure called held-out comes from a fit that never saw its bins", r.heldout_rule);
    let mut v = Verdict::new(answer, held_out, Vec::new());
    // What to expect in use: a cycling table's figures are `calibrate`'s, one per quantity
    // (its selection-fold figures compare it with the start model and the peers); a
    // single-channel log's are the flashed model's.
    if let Some(t) = &r.table {
        if let Some(c) = &t.calibrate_heldout {
            let what = format!(
                "calibrate's held-out figures of table.bin (fitted on {}, scored on {})",
                c.fit_programs.join(", "),
                c.eval_programs.join(", ")
            );
            let (s, b) = (c.sensitivity_ppm_per_c, c.bias_residual_ug);
            v.expect
                .push(Expected { axis: "sensitivity".into(), what: what.clone(), value: s, unit: "ppm/°C".into() });
            v.expect.push(Expected { axis: "bias".into(), what, value: b, unit: "µg".into() });
        }
    } else if let Some(g) = &r.flashed.heldout {
        v.expect = channel_figures(g, ch.bias_unit)
            .iter()
            .map(|(c, x, u)| Expected {
                axis: (*c).to_string(),
                what: format!("held-out RMS of the {}", r.flashed.model),
                value: *x,
                unit: (*u).to_string(),
            })
            .collect();
    }
    if !r.effects.is_empty() || r.table.is_some() {
        for ((c, s, u), (_, n, _)) in start.iter().zip(&named) {
            if worse.contains(c) {
                v.warnings.push(format!(
                    "the named model is worse held out than the start model `{}` on {c}: {n:.2} {u} against {s:.2} \
                     {u}{}",
                    r.start.name(),
                    if r.flashed.model == "start model" {
                        "; table.bin holds the start model, and its figures are the ones to expect"
                    } else {
                        ""
                    }
                ));
            }
        }
    }
    if let Some(p) = &r.flashed.peer_better {
        v.warnings.push(format!(
            "{} predicts the bias better held out ({:.2} {}) than the {}{}",
            p.peer,
            p.heldout_rms,
            ch.bias_unit.label(),
            r.flashed.model,
            if ch.kind == LogKind::Cycling { ", but has no scale-factor model to flash" } else { "" }
        ));
    }
    for e in r.effects.iter().filter(|e| !e.in_table) {
        let why = e.not_in_table.as_deref().unwrap_or("no root-crate slot yet");
        v.warnings.push(format!("{} is named by the block test but not in table.bin: {why}", e.name));
    }
    for u in &r.unexplained {
        let unit = super::output::channel_unit(ch, &u.channel);
        v.warnings.push(format!(
            "the {} channel keeps structure no catalog effect explains (held-out RMS {:.2} {unit}, {:.1}× its noise \
             floor): {}",
            u.channel,
            u.rms,
            u.floor.ratio,
            u.evidence(unit, ch.bias_unit.label())
        ));
    }
    v.warnings.extend(qfa_log::cycling::glitches_sentence(&ch.skipped_glitches));
    v.warnings.extend(notes.iter().cloned());
    v.files = file_uses(files, false);
    if let Some(why) = r.flashed.not_computed.as_ref().filter(|_| r.table.is_some()) {
        for f in v.files.iter_mut().filter(|f| f.file == "table.bin" || f.file == "model.bin") {
            f.action = format!("held back: {why}");
        }
    }
    covers_and_advice(&mut v, ch, r.table.as_ref());
    v
}

/// A figure's held-out RMS over rows, mg, when it was computed.
pub(crate) fn rms(f: &Figure) -> Option<f64> {
    f.score().map(|s| s.rms_mg)
}

/// The named model of `a` is worse than the start model held out (at the printed precision).
#[must_use]
pub(crate) fn named_is_worse(a: &AxisDiscovery) -> bool {
    matches!((rms(&a.before), rms(&a.after)), (Some(s), Some(n)) if compare(s, n) == Compared::Worse)
}

/// One axis's answer: what the search named (the structure `table.bin` holds) and its
/// parts, which of them the block test identifies, how it stands held out against the start
/// model, and what the block test names that it does not hold.
fn axis_answer(d: &StaticDiscovery, a: &AxisDiscovery) -> String {
    let parts: Vec<String> = a.steps.iter().skip(1).map(|st| format!("{}, {}", st.effect, st.evidence)).collect();
    let mut s = format!("{}: named {} = table.bin", a.axis, a.named_structure);
    if !parts.is_empty() {
        s.push_str(&format!(" ({})", parts.join("; ")));
    }
    let start = d.start.name();
    match (rms(&a.before), rms(&a.after)) {
        (Some(b), Some(n)) => {
            let (words, _) = standing(start, &[("bias", b, "mg")], &[("bias", n, "mg")]);
            s.push_str(&format!(", which {words} (named {n:.2} mg, start {b:.2} mg)"));
        }
        _ => s.push_str(", with no held-out figure (see the held-out scheme)"),
    }
    if !a.not_added.is_empty() {
        s.push_str(&format!("; not added: {}", a.not_added.join("; ")));
    }
    s
}

/// The figures to expect on `axes`: each axis's named model's, `table.bin`.
fn expect(axes: &[AxisDiscovery]) -> Vec<Expected> {
    axes.iter()
        .filter_map(|a| {
            rms(&a.after).map(|x| Expected {
                axis: a.axis.clone(),
                what: "held-out bias RMS of the named model (table.bin)".into(),
                value: x,
                unit: "mg".into(),
            })
        })
        .collect()
}

/// One axis's warnings, each starting with the axis.
fn axis_warnings(d: &StaticDiscovery, a: &AxisDiscovery) -> Vec<String> {
    let mut w = Vec::new();
    if let (true, Some(b), Some(n)) = (named_is_worse(a), rms(&a.before), rms(&a.after)) {
        w.push(format!(
            "{}: the named model (table.bin) is worse held out than the start model `{}` ({n:.2} mg against {b:.2} \
             mg): the structure the search picks, fitted on the training rows, does worse on the held-out rows",
            a.axis,
            d.start.name()
        ));
    }
    for s in crate::static_axes::steps_not_carried(a) {
        w.push(format!(
            "{}: the search's step {s} (fitted on the training rows): it lowered the search's cross-validation but \
             does not carry forward to the held-out rows",
            a.axis
        ));
    }
    for n in &a.not_added {
        w.push(format!("{}: named by the block test, not added: {n}", a.axis));
    }
    for u in &a.unexplained {
        w.push(format!("{}: structure left that no catalog effect explains: {u}", a.axis));
    }
    w.extend(a.later_leg.clone());
    w
}

/// What "held-out" means on a static log's pages: the log's scheme; the figures of
/// discovery's own folds and of the structure choice are named for what they are.
fn static_held_out(d: &StaticDiscovery) -> String {
    format!(
        "scheme `{}` (asked `{}`), {}; figures of the block test's own folds inside the rows it saw are called \
         selection-fold figures, and those of the cross-validation that chose the named structure (table.bin's) \
         CV figures",
        d.holdout.scheme, d.holdout.requested, d.holdout.rule
    )
}

/// The verdict of a static log's discovery, written into a folder holding `files` (and a
/// folder per axis).
#[must_use]
pub(crate) fn static_verdict(d: &StaticDiscovery, files: &[String]) -> Verdict {
    let answer = d.axes.iter().map(|a| axis_answer(d, a)).collect::<Vec<_>>().join("; ");
    let mut v = Verdict::new(answer, static_held_out(d), Vec::new());
    v.expect = expect(&d.axes);
    v.warnings = d.axes.iter().flat_map(|a| axis_warnings(d, a)).collect();
    v.files = file_uses(files, false);
    v.files.extend(d.axes.iter().map(|a| FileUse {
        file: format!("{}/report.html", a.axis),
        action: format!(
            "read: axis {}'s discovery (candidates, tests, selection-fold plots), with report.md and report.json \
             beside it",
            a.axis
        ),
    }));
    if let Some(ch) = d.channels.first() {
        covers_and_advice(&mut v, ch, None);
    }
    v
}

/// The verdict of one axis of a static log (its own folder's reports), before its files.
#[must_use]
pub(crate) fn axis_verdict(d: &StaticDiscovery, a: &AxisDiscovery, ch: &Channels) -> Verdict {
    let mut v = Verdict::new(axis_answer(d, a), static_held_out(d), Vec::new());
    v.expect = expect(std::slice::from_ref(a));
    v.warnings = axis_warnings(d, a);
    covers_and_advice(&mut v, ch, None);
    v
}

/// The files of a static axis's folder, each with what to do with it.
#[must_use]
pub(crate) fn axis_files(files: &[String]) -> Vec<FileUse> {
    file_uses(files, true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_follow_the_printed_figures() {
        assert_eq!(compare(1.15, 1.99), Compared::Worse);
        assert_eq!(compare(1.15, 0.55), Compared::Better);
        // Equal at two decimals: neither better nor worse, whatever the third decimal says.
        assert_eq!(compare(6.451, 6.449), Compared::Same);
        let s = [("scale factor", 400.0, "ppm"), ("bias", 27.0, "µg")];
        let (w, worse) = standing("simple", &s, &[("scale factor", 24.0, "ppm"), ("bias", 30.0, "µg")]);
        assert_eq!(w, "beats the start model `simple` held out on scale factor but is worse held out on bias");
        assert_eq!(worse, ["bias"]);
        let (w, _) = standing("paper", &[("bias", 1.15, "mg")], &[("bias", 1.99, "mg")]);
        assert_eq!(w, "is worse held out than the start model `paper`");
        assert_eq!(
            both_figures(&s, &[("scale factor", 24.0, "ppm"), ("bias", 30.0, "µg")]),
            "scale factor: named 24.00 ppm, start 400.00 ppm; bias: named 30.00 µg, start 27.00 µg"
        );
    }
}
