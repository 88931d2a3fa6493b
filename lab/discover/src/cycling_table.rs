//! A cycling log's table: the one `calibrate` writes, with the extension slots the catalog
//! named when they carry to held-out programs.
//!
//! # One table for one log
//! `calibrate` and `discover` answer the same question for a cycling log, so both write the
//! table of one call, [`qfa_calibrate::calibrate_log`]: Eq. 11 on the scale factor and the
//! bias grid whose branch tie and curve shape its cross-validation chose, on the same
//! programs, with the same held-out figures. What discovery adds is the catalog's
//! extension slots (`sensor_lag`, `bias_branch_hysteresis`, `bias_creep`: what
//! [`qfa_thermal::Extensions`] holds), their parameters as the catalog fitted them on every
//! bin, and only when they carry forward: calibrate's fitter is run on each of discovery's
//! held-out folds with and without them and scored on the fold's held-out programs through
//! the root crate's `AxisModel`, by the rule that decides what is flashed (Σ over the
//! channels of (held-out RMS / noise floor)²). With no slot named, or none that carries,
//! `discover`'s `table.bin` is the bytes `calibrate` writes (`--test discover_table`).
//!
//! The slots' time constants and weights are the catalog's fit on every bin, so the
//! held-out folds have seen them: the judgement is of the slots' shape, not of their
//! parameters. `bias_drift` has no slot, and the catalog's Eq. 11 terms and bias curvature
//! are in every table (Eq. 11 is fitted whole; the grid holds any curve).

use qfa_calibrate::fit::{fit, FitOptions};
use qfa_calibrate::{calibrate_log, CalibrateOptions, Calibration};
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
    /// its Table-4 metric): the figures `calibrate` prints for the same log and slots.
    pub calibrate_heldout: CalibrateFigures,
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
pub fn adopt(log: &Log, ch: &Channels, report: &mut Report) -> Result<Option<Table>> {
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
) -> Result<Option<Table>> {
    let paired = PairedLog::new(log);
    let setup = Setup::new(ch);
    let (masks, trains, _) = folds(ch);
    // A log of one program is held out in time blocks, on which calibrate's fit (of whole
    // programs) has no figure: its table stays the catalog's model, and `calibrate` has
    // no held-out figure of its own there either.
    let Some(programs) = fold_programs(ch, &trains) else {
        return Ok(None);
    };
    let floors = [noise_floor(ch, &report.residuals.1.sf), noise_floor(ch, &report.residuals.1.bias)];
    let score = |r: &Residuals| (rms(&r.sf) / floors[0]).powi(2) + (rms(&r.bias) / floors[1]).powi(2);
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
    for e in &mut report.effects {
        e.not_in_table = why_not_in_table(&e.name, &slots);
        e.in_table = e.not_in_table.is_none();
    }
    let structure = structure_text(&cal, &table);
    report.flashed = flashed(ch, report, &structure, &chosen_res);
    report.table = Some(CyclingTable {
        structure,
        named_slots,
        slots,
        calibrate_heldout: CalibrateFigures {
            fit_programs: cal.report.fit_programs.clone(),
            eval_programs: cal.report.eval_programs.clone(),
            sensitivity_ppm_per_c: cal.report.sensitivity_ppm_per_c.hysteresis,
            bias_residual_ug: cal.report.bias_residual_ug.hysteresis,
        },
    });
    Ok(Some(table))
}

/// Why the effect `name` is not in the table, or `None` when it is.
fn why_not_in_table(name: &str, slots: &Slots) -> Option<String> {
    match name {
        "bias_drift" => Some("no root-crate slot: a bias linear in time is not in the firmware".into()),
        "sensor_lag" | "bias_branch_hysteresis" | "bias_creep" => match slots {
            Slots::Added(_) | Slots::NoneNamed => None,
            Slots::NotAdded(SlotGaps { without, with }) => Some(format!(
                "not added: the slots do not carry to the held-out programs (calibrate's fit on each fold: {} \
                 without them, {} with them)",
                output::gaps_text(BiasUnit::G, without),
                output::gaps_text(BiasUnit::G, with)
            )),
        },
        // Eq. 11's terms and the bias curvature are in every table.
        _ => None,
    }
}

/// The table's structure in words, in static calibration's naming: `Eq. 11 + grid`,
/// `Eq. 11 + cubic-2-branches+lag450s` (the lag rounded to a second, the creep's τ at its
/// reference temperature).
fn structure_text(cal: &Calibration, table: &Table) -> String {
    let ext = table.axes.first().map(|a| a.ext).unwrap_or_default();
    let s = qfa_calibrate::fit::StaticStructure {
        shape: cal.table.branch.shape,
        branches: cal.table.branch.mode,
        lag_tau_s: ext.sensor_lag.map(|l| l.tau_s.round()),
        creep_tau_s: ext.bias_creep.map(|c| c.tau_ref_s.round()),
        play_half_width_c: ext.bias_branch_hysteresis.map(|p| p.half_width_c),
    };
    format!("Eq. 11 + {}", s.name())
}

/// The flashed entry: the table, its held-out gaps on the selection folds, and a peer that predicts the bias better there by more than
/// [`qfa_calibrate::verdict::PEER_TOLERANCE`].
fn flashed(ch: &Channels, report: &Report, structure: &str, r: &Residuals) -> Flashed {
    let heldout = gaps(ch.kind, r);
    let bias = rms(&r.bias);
    let best = report
        .peers
        .iter()
        .filter_map(|p| p.heldout_rms.map(|x| (p.peer.clone(), x)))
        .min_by(|a, b| a.1.total_cmp(&b.1));
    Flashed {
        model: structure.to_string(),
        heldout,
        // `calibrate`'s rule: a peer is better only beyond its tolerance (two fits of one
        // cubic, the grid's and the formula's, differ by up to 0.2 %).
        peer_better: best
            .filter(|p| bias > p.1 * (1.0 + qfa_calibrate::verdict::PEER_TOLERANCE))
            .map(|(peer, x)| PeerBetter { peer, heldout_rms: x }),
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
    for (test, p) in masks.iter().zip(programs) {
        let f = fit(paired, &FitOptions { ext, ..FitOptions::new(p.clone()) }, None)
            .map_err(|e| DiscoverError::Calibrate(Box::new(qfa_calibrate::CalibrateError::Fit(e))))?;
        let model = f.hysteresis.axes.first().ok_or(DiscoverError::NoAxis)?;
        let r = setup.residuals(&setup.predict(model));
        for (i, _) in test.iter().enumerate().filter(|(_, &t)| t) {
            out.sf[i] = r.sf[i];
            out.bias[i] = r.bias[i];
        }
    }
    Ok(out)
}
