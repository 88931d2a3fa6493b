//! A cycling log's table: the one `calibrate` writes ([`qfa_calibrate::calibrate_log`],
//! the same call), with the catalog's extension slots only when they carry forward:
//! calibrate's fitter runs on each selection fold with and without them, scored on the
//! fold's held-out programs through the root crate's `AxisModel` by the flash rule (Σ over
//! the channels of (held-out RMS / noise floor)²). With none that carries, `table.bin` is
//! `calibrate`'s bytes (`--test discover_table`). The slots' parameters are the catalog's
//! fit on every bin, so the folds judge their shape, not their values. Eq. 11's terms and a
//! bias curvature are in every table; `bias_drift` has no slot. A log of one program has
//! no held-out program: the table is `calibrate`'s, held back as `calibrate` holds it.

use qfa_calibrate::fit::{fit, FitOptions};
use qfa_calibrate::{calibrate_log, CalibrateOptions};
use qfa_log::cycling::Log;
use qfa_log::pairing::PairedLog;
use qfa_thermal::{Extensions, Table};
use serde::Serialize;

use super::*;

/// What a cycling log's `table.bin` holds, and why.
#[derive(Clone, Debug, Serialize)]
pub struct CyclingTable {
    /// The structure, in words: Eq. 11, the bias grid's tie and shape, and the slots.
    pub structure: String,
    /// The catalog's named effects that are extension slots.
    pub named_slots: Vec<String>,
    /// Whether those slots are in the table, with the figures that decided it.
    pub slots: Slots,
    /// `calibrate`'s held-out figures of this table's structure (its own program split,
    /// its Table-4 metric): the figures `calibrate` prints for the same log and slots;
    /// absent on a log of one program, where `calibrate` holds its table back.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibrate_heldout: Option<CalibrateFigures>,
    /// What `calibrate`'s fit rows cover: the verdict's `covers` and what to record next,
    /// the same lines `calibrate` prints for the log.
    #[serde(skip)]
    pub coverage: qfa_calibrate::coverage::Coverage,
}

/// The decision on the catalog's slots.
#[derive(Clone, Debug, Serialize)]
#[serde(tag = "outcome", rename_all = "snake_case")]
pub enum Slots {
    /// The catalog named no slot effect.
    NoneNamed,
    /// They carry to the held-out programs: in the table.
    Added(SlotGaps),
    /// They do not carry to the held-out programs: left out.
    NotAdded(SlotGaps),
    /// The log has one program: no held-out program to judge them on, so left out.
    OneProgram,
}

/// Held-out gaps on the selection folds of calibrate's fit without the slots and with them.
#[derive(Clone, Debug, Serialize)]
pub struct SlotGaps {
    /// Without the slots.
    pub without: Gaps,
    /// With them.
    pub with: Gaps,
}

/// `calibrate`'s held-out figures of a table.
#[derive(Clone, Debug, Serialize)]
pub struct CalibrateFigures {
    /// Programs fitted.
    pub fit_programs: Vec<String>,
    /// Programs scored.
    pub eval_programs: Vec<String>,
    /// Table-4 sensitivity, ppm/°C.
    pub sensitivity_ppm_per_c: f64,
    /// Bias residual, µg RMS.
    pub bias_residual_ug: f64,
}

/// The table of a cycling log ([`CyclingTable`] says what it holds): the catalog's report
/// `report` is updated to it (its `flashed`, its `table`, each effect's `in_table`).
///
/// # Errors
/// [`DiscoverError::Calibrate`] when calibrate's fit or its held-out figures fail on the
/// log (the table could not be formed).
pub fn adopt(log: &Log, ch: &Channels, report: &mut Report) -> Result<Table> {
    let named_slots: Vec<String> = report
        .effects
        .iter()
        .filter(|e| matches!(e.name.as_str(), "sensor_lag" | "bias_branch_hysteresis" | "bias_creep"))
        .map(|e| e.name.clone())
        .collect();
    let ext = if named_slots.is_empty() { Extensions::NONE } else { report.named_ext };
    adopt_slots(log, ch, report, named_slots, ext)
}

/// [`adopt`] with the slots `ext` as if the catalog had named `named_slots` (a study, or
/// a test that a slot which does not carry is left out).
///
/// # Errors
/// As [`adopt`].
pub fn adopt_slots(
    log: &Log,
    ch: &Channels,
    report: &mut Report,
    named_slots: Vec<String>,
    ext: Extensions,
) -> Result<Table> {
    let paired = PairedLog::new(log);
    let setup = Setup::new(ch);
    let (masks, trains, _) = folds(ch);
    // A log of one program is held out in time blocks, on which calibrate's fit (of whole
    // programs) has no figure: the table is calibrate's, held back as calibrate holds it.
    let Some(programs) = fold_programs(ch, &trains) else {
        return one_program(log, report, named_slots);
    };
    let floors = [noise_floor(ch, &report.residuals.1.sf), noise_floor(ch, &report.residuals.1.bias)];
    let score = |r: &Residuals| flash_score(ch.kind, r, floors);
    let base = fold_residuals(&setup, &paired, &masks, &programs, Extensions::NONE)?;
    let (slots, chosen, chosen_res) = if ext == Extensions::NONE {
        (Slots::NoneNamed, Extensions::NONE, base)
    } else {
        let with = fold_residuals(&setup, &paired, &masks, &programs, ext)?;
        let gaps = SlotGaps { without: gaps(ch.kind, &base), with: gaps(ch.kind, &with) };
        if score(&with) <= score(&base) {
            (Slots::Added(gaps), ext, with)
        } else {
            (Slots::NotAdded(gaps), Extensions::NONE, base)
        }
    };
    let cal = calibrate_log(log, &CalibrateOptions { ext: chosen, ..CalibrateOptions::default() })
        .map_err(|e| DiscoverError::Calibrate(Box::new(e)))?;
    let table = cal.table.hysteresis.clone();
    mark_in_table(report, &slots);
    let ext = table.axes.first().map(|a| a.ext).unwrap_or_default();
    let structure = qfa_calibrate::fit::cycling_structure(cal.table.branch.mode, cal.table.branch.shape, &ext);
    report.flashed = flashed(ch, report, &structure, &chosen_res);
    let calibrate_heldout = Some(CalibrateFigures {
        fit_programs: cal.report.fit_programs.clone(),
        eval_programs: cal.report.eval_programs.clone(),
        sensitivity_ppm_per_c: cal.report.sensitivity_ppm_per_c.hysteresis,
        bias_residual_ug: cal.report.bias_residual_ug.hysteresis,
    });
    let coverage = cal.report.coverage.covered.clone();
    report.table = Some(CyclingTable { structure, named_slots, slots, calibrate_heldout, coverage });
    Ok(table)
}

/// Why a log of one program has no held-out figure of its table.
pub const ONE_PROGRAM: &str = "one program: nothing of calibrate's table is held out (calibrate holds it back for \
                               the same reason); log a second program to judge it";

/// [`adopt_slots`] on a log of one program: calibrate's table without slots, with no
/// held-out figure ([`ONE_PROGRAM`]).
fn one_program(log: &Log, report: &mut Report, named_slots: Vec<String>) -> Result<Table> {
    let cal = calibrate_log(log, &CalibrateOptions::default()).map_err(|e| DiscoverError::Calibrate(Box::new(e)))?;
    let slots = if named_slots.is_empty() { Slots::NoneNamed } else { Slots::OneProgram };
    mark_in_table(report, &slots);
    let b = &cal.table.branch;
    let structure = qfa_calibrate::fit::cycling_structure(b.mode, b.shape, &Extensions::NONE);
    report.flashed =
        Flashed { model: structure.clone(), heldout: None, not_computed: Some(ONE_PROGRAM.into()), peer_better: None };
    let coverage = cal.report.coverage.covered.clone();
    report.table = Some(CyclingTable { structure, named_slots, slots, calibrate_heldout: None, coverage });
    Ok(cal.table.hysteresis)
}

/// Each named effect's `in_table` and `not_in_table` under the decision `slots`.
fn mark_in_table(report: &mut Report, slots: &Slots) {
    for e in &mut report.effects {
        e.not_in_table = why_not_in_table(&e.name, slots);
        e.in_table = e.not_in_table.is_none();
    }
}

/// Why the effect `name` is not in the table, or `None` when it is.
fn why_not_in_table(name: &str, slots: &Slots) -> Option<String> {
    match name {
        "bias_drift" => Some("no root-crate slot: a bias linear in time is not in the firmware".into()),
        "sensor_lag" | "bias_branch_hysteresis" | "bias_creep" => match slots {
            Slots::Added(_) | Slots::NoneNamed => None,
            Slots::OneProgram => Some("not added: one program, no held-out program to judge it on".into()),
            Slots::NotAdded(SlotGaps { without, with }) => Some(format!(
                "not added: the slots do not carry to the held-out programs (calibrate's fit on each fold: {} \
                 without them, {} with them)",
                output::gaps_text(BiasUnit::G, without),
                output::gaps_text(BiasUnit::G, with)
            )),
        },
        _ => None,
    }
}

/// The flashed entry: the table, its held-out gaps on the selection folds, a better peer.
fn flashed(ch: &Channels, report: &Report, structure: &str, r: &Residuals) -> Flashed {
    Flashed {
        model: structure.to_string(),
        heldout: Some(gaps(ch.kind, r)),
        not_computed: None,
        peer_better: peer_better(&report.peers, rms(&r.bias)),
    }
}

/// Per fold, its training programs; `None` when the folds are not whole programs.
fn fold_programs(ch: &Channels, trains: &[Vec<bool>]) -> Option<Vec<Vec<String>>> {
    if ch.traces.len() < 2 {
        return None;
    }
    let mut out = vec![Vec::new(); trains.len()];
    let mut o = 0;
    for t in &ch.traces {
        for (k, train) in trains.iter().enumerate() {
            if !t.bins.is_empty() && train[o] {
                out[k].push(t.program.clone());
            }
        }
        o += t.bins.len();
    }
    out.iter().all(|p| !p.is_empty()).then_some(out)
}

/// Calibrate's fitter on each fold's training programs with `ext` in force, scored on the
/// fold's held-out bins through the root crate's `AxisModel` (what the firmware runs).
fn fold_residuals(
    setup: &Setup,
    paired: &PairedLog<'_>,
    masks: &[Vec<bool>],
    programs: &[Vec<String>],
    ext: Extensions,
) -> Result<Residuals> {
    let n = setup.ch.n_bins();
    let mut out = Residuals { sf: vec![f64::NAN; n], bias: vec![f64::NAN; n] };
    for (k, (test, p)) in masks.iter().zip(programs).enumerate() {
        let f = fit(paired, &FitOptions { ext, ..FitOptions::new(p.clone()) }, None)
            .map_err(|e| DiscoverError::Calibrate(Box::new(qfa_calibrate::CalibrateError::Fit(e))))?;
        let no_model = || DiscoverError::NoModel { axis: "the cycling table".into(), fold: Some(k + 1) };
        let model = f.hysteresis.axes.first().ok_or_else(no_model)?;
        fill_heldout(&mut out, test, &setup.residuals(&setup.predict(model)));
    }
    Ok(out)
}
