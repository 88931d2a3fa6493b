//! The table of a cycling log and its held-out fit: one structure per log, chosen on every
//! program, scored held out as fitted on the fit programs alone.

use qfa_log::pairing::PairedLog;
use qfa_thermal::Extensions;

use super::{fit, FitError, FitOptions, Fitted};

/// The table written for a log, the lab's one rule: the cycling fit on `programs` (every
/// program with a pair) with the extension slots `ext`, its bias grid's branch tie and
/// shape chosen by cross-validation on those programs. That choice is made once per log:
/// the held-out figures are of the same structure ([`fit_held_out`]), so what a report
/// scores is what `table.bin` holds. `calibrate`, `discover` on a cycling log and the
/// navigation study fly this table. Choosing the tie on the fit programs alone (an
/// earlier rule of `calibrate`'s) flew worse: 20 Monte Carlo runs of the navigation study
/// removed a median 92.9 % of the simple model's thermal error (worst run 84.7 %) against
/// 94.3 % (worst 91.4 %) with the tie chosen on every program (on the simulator's earlier
/// run streams).
///
/// # Errors
/// As [`fit`].
pub fn fit_table(paired: &PairedLog<'_>, programs: &[String], ext: Extensions) -> Result<Fitted, FitError> {
    fit(paired, &FitOptions { ext, ..FitOptions::new(programs.to_vec()) }, None)
}

/// The held-out fit of `table` (a [`fit_table`]): its structure (the bias grid's branch
/// tie and curve shape, and the slots `ext`) with coefficients fitted on `fit_programs`
/// alone, to be scored on the programs it never saw. The structure's choice saw every
/// program's rows (the cross-validation among six ties and shapes, one-SE rule); the
/// coefficients scored did not. Scoring instead the tie the fit programs alone would
/// choose judged a structure `table.bin` may not hold (on the demo's JB-KT8 #2 a
/// two-branch grid, 9.04 µg held out, against `table.bin`'s one cubic curve).
///
/// # Errors
/// As [`fit`].
pub fn fit_held_out(
    paired: &PairedLog<'_>,
    fit_programs: &[String],
    table: &Fitted,
    ext: Extensions,
    progress: Option<&indicatif::ProgressBar>,
) -> Result<Fitted, FitError> {
    let opts = FitOptions {
        ext,
        branch_mode: Some(table.branch.mode),
        curve_shape: Some(table.branch.shape),
        ..FitOptions::new(fit_programs.to_vec())
    };
    let mut f = fit(paired, &opts, progress)?;
    f.branch.rule = format!(
        "table.bin's tie and shape ({:?} on {:?} curves, chosen on every program with a pair); the CV figures are \
         the fit programs' own, for reference",
        table.branch.mode, table.branch.shape
    );
    Ok(f)
}
