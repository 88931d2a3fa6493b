//! Discovery's `report.html` ([`crate::html_report`]): the report's fields as tables, what
//! the log covers, every PNG in the output folder, and `report.md` folded in full.

use std::path::Path;

use anyhow::Result;

use super::{Channels, Gaps, Report};
use crate::calibrate::coverage::Coverage;
use crate::html_report::Page;

fn gaps(g: &Gaps) -> String {
    match g {
        Gaps::Cycling { scale_factor_ppm, bias_ug } => {
            format!("scale factor {scale_factor_ppm:.2} ppm, bias {bias_ug:.2} µg")
        }
        Gaps::Single { value_rms } => format!("value {value_rms:.4}"),
    }
}

/// What the log's traces cover, as the rate estimator sees them.
///
/// # Errors
/// No row with a temperature.
pub fn coverage(ch: &Channels) -> Result<Coverage> {
    let s = ch.traces.iter().flat_map(|t| t.est_t.iter().zip(&t.est_rate).map(|(&a, &r)| (f64::from(a), f64::from(r))));
    Coverage::of_samples(s, f64::from(crate::data::pairing::branch_deadband_c_per_min()))
}

/// The page of one discovery run whose files are in `dir` (`report.md` and the plots
/// already written).
///
/// # Errors
/// A file in `dir` that cannot be read.
pub fn page(ch: &Channels, r: &Report, dir: &Path) -> Result<Page> {
    let mut p = Page::new("Discovery report");
    p.section("Held-out scheme").kv(&[
        ("start model", r.start.name().to_string()),
        ("held-out rule", r.heldout_rule.clone()),
        ("selection", r.selection_rule.clone()),
    ]);
    p.section("Held-out gaps").kv(&[
        ("start model", gaps(&r.heldout_gap_before)),
        ("named model", gaps(&r.heldout_gap_after)),
        (
            "flashed (table.bin)",
            format!(
                "{}: {}{}",
                r.flashed.model,
                gaps(&r.flashed.heldout),
                r.flashed.peer_better.as_ref().map_or_else(String::new, |b| format!(
                    "; {} predicts the bias better ({:.3})",
                    b.peer, b.heldout_rms
                ))
            ),
        ),
        ("noise floor (bin-to-bin part of the final residual)", gaps(&r.noise_floor)),
        (
            "held-out residual / noise floor (95 % interval)",
            r.residual_vs_floor
                .iter()
                .map(|f| format!("{} {:.1}× [{:.1}, {:.1}]", f.channel, f.ratio, f.ratio_ci95[0], f.ratio_ci95[1]))
                .collect::<Vec<_>>()
                .join(", "),
        ),
    ]);
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
                if e.in_table { "yes" } else { "no" }.to_string(),
                e.confusable_with.join(", "),
            ]
        })
        .collect();
    p.section("Effects added");
    if effects.is_empty() {
        p.para("none: no candidate improved the held-out fit significantly");
    } else {
        p.table(
            &[
                "effect",
                "channel",
                "parameters (95 % interval)",
                "held-out gain ± SE",
                "held-out gap before → after",
                "in table",
                "as good as",
            ],
            &effects,
        );
    }
    for u in &r.unexplained {
        p.warning(&format!(
            "the {} channel keeps structure no catalog effect explains (held-out RMS {:.3}, {:.1}× its noise floor, \
             mostly {}{}{})",
            u.channel,
            u.rms,
            u.floor.ratio,
            u.time_scales.dominant(),
            if u.correlates_with.is_empty() {
                String::new()
            } else {
                format!("; follows {}", u.correlates_with.join(", then "))
            },
            if u.where_.is_empty() { String::new() } else { format!("; largest on {}", u.where_) }
        ));
    }
    let peers: Vec<Vec<String>> = r
        .peers
        .iter()
        .map(|x| {
            vec![
                x.peer.clone(),
                x.heldout_rms.map_or_else(
                    || format!("not computed: {}", x.error.as_deref().unwrap_or("no figure")),
                    |v| format!("{v:.4}"),
                ),
            ]
        })
        .collect();
    p.section("Peers on the same held-out split (bias channel)").table(&["model", "held-out RMS"], &peers);
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
    let where_rows = |w: &[super::Where]| -> Vec<Vec<String>> {
        w.iter().map(|w| vec![w.channel.clone(), w.segment.clone(), format!("{:.3}", w.rms)]).collect()
    };
    p.section("Where the start model disagrees (held-out RMS)")
        .table(&["channel", "segment", "RMS"], &where_rows(&r.where_));
    p.section("Where the final model disagrees (held-out RMS)")
        .table(&["channel", "segment", "RMS"], &where_rows(&r.where_after));
    p.section("Plots (held-out residuals)");
    p.images_in(dir, |name| format!("discovery plot {name}"))?;
    if let Ok(md) = std::fs::read_to_string(dir.join("report.md")) {
        p.section("Full report").details("report.md", &md);
    }
    Ok(p)
}

/// The page of a static log's discovery in `dir`: the Markdown report, then each axis's
/// plots from its own folder (each also has its own `report.html`).
///
/// # Errors
/// A file in `dir` that cannot be read.
pub fn static_page(d: &super::static_axes::StaticDiscovery, dir: &Path) -> Result<Page> {
    let mut p = Page::new("Discovery report, static multi-axis log");
    p.pre(&super::static_axes::markdown(d));
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
    for a in &d.axes {
        let sub = dir.join(&a.axis);
        if sub.is_dir() {
            p.section(&format!(
                "{} ({}): held-out residual plots (its own page: {}/report.html)",
                a.axis, a.column, a.axis
            ));
            p.images_in(&sub, |name| format!("{} {name}", a.axis))?;
        }
    }
    Ok(p)
}
