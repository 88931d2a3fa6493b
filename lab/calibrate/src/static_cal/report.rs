//! Static calibration's records: the held-out figures, each axis's and each fold's report,
//! `report.json`, the plot rows and the calibration itself.

use serde::Serialize;

use qfa_thermal::model::Branch;
use qfa_thermal::Table;

use crate::fit::{FitError, StaticFit};
use crate::peers::Poly;
use crate::static_cal::SearchStep;
use qfa_log::static_log::{Sampling, Skipped};

/// Held-out figures of one model on one axis, mg.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Score {
    /// RMS over held-out rows, mg.
    pub rms_mg: f64,
    /// RMS over held-out 60-s means, mg.
    pub binned_mg: f64,
}

/// A held-out figure, or why there is none (in `report.json`: either `{rms_mg, binned_mg}`
/// or `{not_computed: reason}`).
#[derive(Clone, Debug, Serialize, PartialEq)]
#[serde(untagged)]
pub enum Figure {
    /// The figure.
    Score(Score),
    /// Why it cannot be formed.
    NotComputed {
        /// The reason.
        not_computed: String,
    },
}

impl Figure {
    /// The score, if there is one.
    #[must_use]
    pub fn score(&self) -> Option<Score> {
        match self {
            Self::Score(s) => Some(*s),
            Self::NotComputed { .. } => None,
        }
    }

    /// A figure that is not computed, for `reason`.
    #[must_use]
    pub fn not_computed(reason: impl Into<String>) -> Self {
        Self::NotComputed { not_computed: reason.into() }
    }

    /// `rms / binned` in mg, or `not computed (reason)`, for the Markdown tables.
    #[must_use]
    pub fn cell(&self) -> String {
        match self {
            Self::Score(s) => format!("{:.2} / {:.2}", s.rms_mg, s.binned_mg),
            Self::NotComputed { not_computed } => format!("not computed ({not_computed})"),
        }
    }
}

/// One axis of the report.
#[derive(Clone, Debug, Serialize)]
pub struct AxisReport {
    /// Role (`ax`, `ay`, `az`).
    pub axis: String,
    /// Column in the file.
    pub column: String,
    /// The constant the table's bias is measured from, g: the axis's mean over every row.
    pub reference_g: f64,
    /// The table's structure, chosen by cross-validation over every row.
    pub structure: String,
    /// Its cross-validation RMS over every row, mg (the choice's own figure: the lowest of
    /// many, so not a held-out figure).
    pub cv_rms_mg: f64,
    /// How the search reached that structure over every row: the simplest structure that
    /// could be fitted, then one part added per step, each with its cross-validation RMS.
    pub search_path: Vec<PathStep>,
    /// RMS over every row of the table (fitted on every row, through the root crate), mg:
    /// in-sample, what `compensate` with `table.bin` gives back.
    pub table_rms_mg: f64,
    /// The exported PX4 / tofupilot cubic (fitted on every row) over every row, its constant
    /// the mean over every row: in-sample, what the exported file gives back.
    pub exported_cubic: Figure,
    /// The exported ArduPilot cubic over every row, likewise (not computed when its learner
    /// formed no fit).
    pub exported_ardupilot: Figure,
    /// The structure each fold's held-out figure of ours is of: the table's, chosen on every
    /// row, fitted on the fold's training rows.
    pub heldout_structures: Vec<String>,
    /// Per fold, the search's path (on every row, `search_path`), each step fitted on the
    /// fold's training rows and scored on its held-out rows: what each part added to the
    /// model did on rows it never saw (the last step is the table's structure; empty for a
    /// fold that cannot fit it).
    pub heldout_paths: Vec<Vec<HeldOutStep>>,
    /// Ours (the chosen structure through the root crate), held out.
    pub ours: Figure,
    /// PX4 / tofupilot cubic, held out.
    pub cubic: Figure,
    /// ArduPilot TCAL, held out.
    pub ardupilot: Figure,
    /// The paper's simple model, held out.
    pub simple: Figure,
    /// No compensation (the training mean removed), held out.
    pub none: Figure,
    /// Candidates a cross-validation fit refused (a table outside the root crate's limits,
    /// too few rows), with the reason (the table's choice, over every row).
    pub refused_candidates: Vec<String>,
    /// Held-out rows the model flagged as clamped (T or Ṫ outside the range its fold's
    /// training rows calibrated).
    pub clamped_rows: usize,
}

/// One step of the model search's path, as the report gives it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PathStep {
    /// The structure after the step.
    pub structure: String,
    /// Its cross-validation RMS, mg.
    pub cv_rms_mg: f64,
}

impl From<&SearchStep> for PathStep {
    fn from(s: &SearchStep) -> Self {
        Self { structure: s.structure.name(), cv_rms_mg: s.cv_rms_g * 1e3 }
    }
}

/// One step of a fold's search path, with its held-out figure.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HeldOutStep {
    /// The structure after the step.
    pub structure: String,
    /// Its cross-validation RMS inside the fold's training rows, mg.
    pub cv_rms_mg: f64,
    /// That structure fitted on the fold's training rows, on its held-out rows.
    pub held_out: Figure,
}

/// One fold of the held-out scheme.
#[derive(Clone, Debug, Serialize)]
pub struct FoldReport {
    /// Held-out rows, 1-based, inclusive.
    pub heldout_rows: (usize, usize),
    /// Their time range, s.
    pub heldout_time_s: (f64, f64),
    /// Their temperature range, °C.
    pub heldout_temp_c: (f64, f64),
    /// Training rows (every other row).
    pub train_rows: usize,
    /// Of those, rows on the heating and on the cooling branch.
    pub train_branch_rows: (usize, usize),
    /// Their temperature range, °C.
    pub train_temp_c: (f64, f64),
}

/// The held-out scheme that ran.
#[derive(Clone, Debug, Serialize)]
pub struct HoldoutReport {
    /// What was asked for (`--holdout`).
    pub requested: String,
    /// The scheme that ran: `after-max`, `blocks:K` or `none`.
    pub scheme: String,
    /// Why, and what it holds out, in words.
    pub rule: String,
    /// Its folds (none for `none`).
    pub folds: Vec<FoldReport>,
    /// Rows held out over all folds.
    pub heldout_rows: usize,
}

/// `report.json` of a static calibration.
#[derive(Clone, Debug, Serialize)]
pub struct StaticReport {
    /// Kind of log.
    pub kind: &'static str,
    /// Columns used: (role, column, unit).
    pub columns: Vec<(String, String, String)>,
    /// Rows kept.
    pub rows: usize,
    /// Rows skipped by the reader.
    pub skipped: Skipped,
    /// Sampling regularity.
    pub sampling: Sampling,
    /// Temperature range of the log, °C.
    pub temp_c: (f64, f64),
    /// Rows on the heating and on the cooling branch (the firmware's branch logic).
    pub branch_rows: (usize, usize),
    /// The held-out scheme.
    pub holdout: HoldoutReport,
    /// Which rows each figure and output comes from, in words.
    pub figures: String,
    /// How the structure was chosen, in words.
    pub selection: String,
    /// What the log's rows cover (temperature span, heating and cooling legs, rates as the
    /// firmware's estimator sees them).
    pub coverage: crate::coverage::Coverage,
    /// What the chosen models need that the log lacks, and what to record next (empty:
    /// nothing missing).
    pub record_next: Vec<String>,
    /// Per axis.
    pub axes: Vec<AxisReport>,
}

impl StaticReport {
    /// Which cubic the ArduPilot files hold and why, with this log's held-out figures of
    /// both cubics its `INS_TCALn` format could carry; `None` without held-out figures.
    #[must_use]
    pub fn ardupilot_choice(&self) -> Option<String> {
        let pairs: Vec<(&str, f64, f64)> = self
            .axes
            .iter()
            .filter_map(|a| Some((a.axis.as_str(), a.ardupilot.score()?.rms_mg, a.cubic.score()?.rms_mg)))
            .collect();
        if pairs.is_empty() {
            return None;
        }
        let better = pairs.iter().filter(|p| p.1 <= p.2).count();
        Some(format!(
            "The ArduPilot parameter files, where written, hold the cubic ArduPilot's own learner makes of the rows (one averaged point per \
             0.5 °C rise); its INS_TCALn format could hold the least-squares cubic instead (the PX4 file's). Held out \
             here, learner against least squares, mg: {}; the learner's is as good or better on {better} of {} axes. \
             On a simulated vehicle's warm-up and flight it ties the least-squares cubic where the curve is a cubic \
             and leaves 8–9 % less where it is not and the die lags (the lab guide, PX4 and ArduPilot parameter \
             files), so the files keep it.",
            pairs.iter().map(|(a, l, c)| format!("{a} {l:.2} against {c:.2}")).collect::<Vec<_>>().join(", "),
            pairs.len()
        ))
    }
}

/// Per-row residuals for the plots: each axis before and after compensation, with each
/// row's branch and whether it is held out.
#[derive(Clone, Debug, Default)]
pub struct PlotRows {
    /// Time since the first row, s.
    pub time_s: Vec<f64>,
    /// Temperature reading, °C.
    pub temp_c: Vec<f64>,
    /// Branch in force (the firmware's branch logic).
    pub branch: Vec<Branch>,
    /// The row is held out by the scheme (scored on a model that never saw it).
    pub heldout: Vec<bool>,
    /// Per axis: name, `a − reference` in mg (the axis's mean over every row removed), and
    /// the residual after the model in mg (NaN before the first temperature): under
    /// `after-max` the one fold's model on every row (in-sample on its training rows),
    /// under `blocks:K` each row's own fold's model, under `none` the table's.
    pub axes: Vec<(String, Vec<f64>, Vec<f64>)>,
}

/// The peers of one axis fitted on every row, for the exported parameter files.
#[derive(Clone, Debug)]
pub struct ExportedPeers {
    /// PX4 / tofupilot cubic.
    pub cubic: Poly,
    /// ArduPilot TCAL, or why its learner formed no fit (it takes only rises:
    /// `crate::peers::ardupilot_reason` says so in its terms).
    pub ardupilot: Result<Poly, FitError>,
}

/// A static calibration.
#[derive(Clone, Debug)]
pub struct StaticCalibration {
    /// The table (one axis per log axis), fitted on every row.
    pub table: Table,
    /// Per-axis fits on every row (what the table holds).
    pub fits: Vec<StaticFit>,
    /// Per-axis peers on every row (what the parameter files hold).
    pub peers: Vec<ExportedPeers>,
    /// The report.
    pub report: StaticReport,
    /// Per-row residuals for the plots.
    pub plot: PlotRows,
    /// Per axis, the model search's path on every row ([`SearchStep`]): its last step is the
    /// structure the table holds.
    pub paths: Vec<Vec<SearchStep>>,
}
