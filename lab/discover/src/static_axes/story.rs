//! The one search's story on a static axis: the parts of the named structure in the search's
//! order, what the block test says of each, what it names that the table does not hold, and
//! each fold's steps held out.

use crate::verdict::{compare, rms, Compared};
use qfa_calibrate::fit::{BranchMode, StaticStructure};

use super::{AxisDiscovery, Step};
use crate::Report;

/// The part `to` adds to `from` (one search step, [`qfa_calibrate::static_cal::is_step`]):
/// its catalog effect and its form. A loosened branch tie is the catalog's
/// `bias_branch_hysteresis` (heating and cooling curves apart), in the static fitter's form.
#[must_use]
pub(crate) fn part_added(from: &StaticStructure, to: &StaticStructure) -> (&'static str, String) {
    if from.branches != to.branches {
        let form = match to.branches {
            BranchMode::Offset => "a constant heating/cooling step",
            _ => "free heating and cooling curves",
        };
        return ("bias_branch_hysteresis", form.to_string());
    }
    if let (None, Some(t)) = (from.lag_tau_s, to.lag_tau_s) {
        return ("sensor_lag", format!("tau {t} s"));
    }
    if let (None, Some(t)) = (from.creep_tau_s, to.creep_tau_s) {
        return ("bias_creep", format!("tau {t} s"));
    }
    if let (None, Some(r)) = (from.play_half_width_c, to.play_half_width_c) {
        return ("bias_branch_hysteresis", format!("play, half-width {r} °C"));
    }
    if from.shape != to.shape {
        return ("temp_curve", "free grid nodes".to_string());
    }
    ("start", to.name())
}

/// What the block test (`r`, every row) says of `effect`: whether it names it and tells it
/// from the others, and that in words.
fn evidence_for(r: &Report, effect: &str) -> (bool, String) {
    if let Some(e) = r.effects.iter().find(|e| e.name == effect) {
        if e.confusable_with.is_empty() {
            return (true, "identified".to_string());
        }
        return (false, format!("not identified: as good as {}", e.confusable_with.join(", ")));
    }
    match r.effects.iter().find(|e| e.confusable_with.iter().any(|c| c == effect)) {
        Some(e) => (false, format!("not identified: the block test named {} as good", e.name)),
        None => (false, "not named by the block test".to_string()),
    }
}

/// A path's steps as labels, `effect (form)`, its start left out.
fn path_labels(path: &[StaticStructure]) -> Vec<String> {
    path.windows(2)
        .map(|w| {
            let (e, form) = part_added(&w[0], &w[1]);
            format!("{e} ({form})")
        })
        .collect()
}

/// Record on axis `x` what the one search found (`c`, its `path` on every row): the named
/// structure and its steps, their figures (each step held out on every fold), which of them
/// the block test (`r`, every row) identifies, and which of its names the model does not
/// hold, with why.
pub(super) fn adopt_search(
    x: &mut AxisDiscovery,
    r: &Report,
    c: &qfa_calibrate::static_cal::AxisReport,
    p: &[qfa_calibrate::static_cal::SearchStep],
) {
    x.effects = path_labels(&p.iter().map(|s| s.structure).collect::<Vec<_>>());
    x.steps = p
        .iter()
        .enumerate()
        .map(|(i, st)| {
            let (effect, (identified, evidence)) = match i {
                0 => ("start".to_string(), (true, "the search's start".to_string())),
                _ => {
                    let (e, form) = part_added(&p[i - 1].structure, &st.structure);
                    (format!("{e} ({form})"), evidence_for(r, e))
                }
            };
            Step { effect, structure: st.structure.name(), cv_rms_mg: st.cv_rms_g * 1e3, identified, evidence }
        })
        .collect();
    x.named_structure.clone_from(&c.structure);
    x.after = c.ours.clone();
    x.cv_rms_mg = c.cv_rms_mg;
    x.heldout_steps.clone_from(&c.heldout_paths);
    x.table_rms_mg = c.table_rms_mg;
    let (block, after) = (rms(&x.block_test_model), rms(&x.after));
    let folds = &x.block_test_effects_per_fold;
    x.not_added = r
        .effects
        .iter()
        // The bias curve's shape is the grid's (or the cubic's) own: every structure holds it.
        .filter(|e| e.name != "temp_quadratic")
        .filter(|e| !x.effects.iter().any(|l| l.starts_with(&format!("{} (", e.name))))
        .map(|e| {
            let why = if e.in_table {
                "the search's lowest cross-validation does not hold it"
            } else {
                "the table has no slot for it (a trend in time, extrapolated past the log)"
            };
            let in_block_model = folds.iter().any(|f| f.iter().any(|l| l.starts_with(&format!("{} (", e.name))));
            let carry = match (block, after) {
                (Some(b), Some(n)) if in_block_model && compare(n, b) == Compared::Worse => format!(
                    "; the block test's model, which holds it, holds out {b:.2} mg against the named model's {n:.2} \
                     mg: it does not carry forward"
                ),
                _ => String::new(),
            };
            format!("{}: {why}{carry}", e.name)
        })
        .collect();
}

/// The search, step by step, held out on each fold: `[step, structure, CV mg, held-out mg]`.
#[must_use]
pub(crate) fn step_rows(a: &AxisDiscovery) -> Vec<[String; 5]> {
    let mut out = Vec::new();
    let labels = &a.effects;
    for (f, steps) in a.heldout_steps.iter().enumerate() {
        for (i, st) in steps.iter().enumerate() {
            let label = if i == 0 { "start of the search".to_string() } else { labels[i - 1].clone() };
            let fold = if a.heldout_steps.len() > 1 { format!("fold {}: ", f + 1) } else { String::new() };
            let change = match (i.checked_sub(1).map(|j| rms(&steps[j].held_out)), rms(&st.held_out)) {
                (Some(Some(b)), Some(n)) => match compare(b, n) {
                    Compared::Same => "0.00".to_string(),
                    Compared::Better => format!("{:+.2}", n - b),
                    Compared::Worse => format!("{:+.2}: does not carry forward", n - b),
                },
                _ => String::new(),
            };
            out.push([
                format!("{fold}{label}"),
                st.structure.clone(),
                format!("{:.3}", st.cv_rms_mg),
                st.held_out.cell(),
                change,
            ]);
        }
    }
    out
}

/// The search's steps that raised the held-out RMS (each fitted on the training rows), in
/// words: `effect (form) raised … → … mg`, with its fold when there are several.
#[must_use]
pub(crate) fn steps_not_carried(a: &AxisDiscovery) -> Vec<String> {
    let mut out = Vec::new();
    let labels = &a.effects;
    for (f, steps) in a.heldout_steps.iter().enumerate() {
        for (i, w) in steps.windows(2).enumerate() {
            if let (Some(b), Some(n)) = (rms(&w[0].held_out), rms(&w[1].held_out)) {
                if compare(b, n) == Compared::Worse {
                    let fold = if a.heldout_steps.len() > 1 { format!(" (fold {})", f + 1) } else { String::new() };
                    out.push(format!("{}{fold} raised the RMS on the held-out rows {b:.2} → {n:.2} mg", labels[i]));
                }
            }
        }
    }
    out
}
