//! What a calibration covers: the temperature and rate ranges its fit rows span, per
//! branch (heating, cooling), beside the limits the table it produces will clamp to.
//!
//! The firmware clamps T̂ to the bias grid and Ṫ to `rate_limit_c_per_min` and flags it
//! (`TEMP_OUT_OF_RANGE`, `RATE_OUT_OF_RANGE`); this is the lab-side view of the same
//! ranges, so a user can compare them with a mission before flying the table.

use qfa_thermal::table::Table;
use serde::Serialize;

use qfa_log::cycling::Log;
use qfa_log::pairing::trace_run;
use qfa_log::replay::Motion;

/// Range of one branch: rows whose rate is beyond the branch deadband in that direction.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct BranchRange {
    /// Rows in the branch.
    pub rows: usize,
    /// Temperature range, °C.
    pub temp_c: [f64; 2],
    /// Largest |Ṫ| in the branch, °C/min.
    pub max_abs_rate_c_per_min: f64,
}

/// Coverage of a set of (temperature, rate) samples.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Coverage {
    /// Rows counted (valid temperature).
    pub rows: usize,
    /// Temperature range over every row, °C.
    pub temp_c: [f64; 2],
    /// Heating rows (Ṫ > deadband); `None`: no heating row.
    pub heating: Option<BranchRange>,
    /// Cooling rows (Ṫ < −deadband); `None`: no cooling row.
    pub cooling: Option<BranchRange>,
    /// Deadband used to split the branches, °C/min.
    pub deadband_c_per_min: f64,
}

/// Why a coverage or a table's limits could not be formed.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum CoverageError {
    /// No sample with a finite temperature and rate (in these programs, when given).
    NoValidRow {
        /// The programs the rows were taken from, when they came from a log.
        programs: Option<Vec<String>>,
    },
    /// A table without axes.
    EmptyTable,
}

impl std::fmt::Display for CoverageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NoValidRow { programs: Some(p) } => write!(f, "programs {p:?}: no valid row: coverage not computed"),
            Self::NoValidRow { programs: None } => f.write_str("no valid row: coverage not computed"),
            Self::EmptyTable => f.write_str("empty table"),
        }
    }
}

impl std::error::Error for CoverageError {}

impl Coverage {
    /// Of `(temp_c, rate_c_per_min)` samples.
    ///
    /// # Errors
    /// No finite sample: the coverage is not computed.
    pub fn of_samples(samples: impl Iterator<Item = (f64, f64)>, deadband: f64) -> Result<Self, CoverageError> {
        let mut rows = 0;
        let mut t = [f64::INFINITY, f64::NEG_INFINITY];
        let mut br: [Option<BranchRange>; 2] = [None, None];
        for (tc, r) in samples {
            if !(tc.is_finite() && r.is_finite()) {
                continue;
            }
            rows += 1;
            t = [t[0].min(tc), t[1].max(tc)];
            let k = match Motion::against(r, deadband) {
                Motion::Heating => 0,
                Motion::Cooling => 1,
                Motion::Holding => continue,
            };
            let b = br[k].get_or_insert(BranchRange {
                rows: 0,
                temp_c: [f64::INFINITY, f64::NEG_INFINITY],
                max_abs_rate_c_per_min: 0.0,
            });
            b.rows += 1;
            b.temp_c = [b.temp_c[0].min(tc), b.temp_c[1].max(tc)];
            b.max_abs_rate_c_per_min = b.max_abs_rate_c_per_min.max(r.abs());
        }
        if rows == 0 {
            return Err(CoverageError::NoValidRow { programs: None });
        }
        Ok(Self { rows, temp_c: t, heating: br[0], cooling: br[1], deadband_c_per_min: deadband })
    }

    /// Of the runs of `programs` in `log`, replayed through the firmware's estimator
    /// (T̂ and Ṫ as the fit sees them).
    ///
    /// # Errors
    /// No valid row in those programs.
    pub fn of_log(log: &Log, programs: &[String], deadband: f32) -> Result<Self, CoverageError> {
        let ext = qfa_thermal::Extensions::default();
        let mut s = Vec::new();
        for run in log.runs.iter().filter(|r| programs.contains(&r.program)) {
            let tr = trace_run(run, &ext, deadband);
            s.extend((0..tr.valid.len()).filter(|&i| tr.valid[i]).map(|i| (tr.temp_c[i], tr.rate_c_per_min[i])));
        }
        Self::of_samples(s.into_iter(), f64::from(deadband))
            .map_err(|_| CoverageError::NoValidRow { programs: Some(programs.to_vec()) })
    }

    /// Largest |Ṫ| over both branches, °C/min (0 when neither has a row).
    #[must_use]
    pub fn max_abs_rate(&self) -> f64 {
        [self.heating, self.cooling].iter().flatten().map(|b| b.max_abs_rate_c_per_min).fold(0.0, f64::max)
    }

    /// Whether this coverage reaches `need`'s: its temperature range contains `need`'s
    /// and, per branch, its largest |Ṫ| is at least `need`'s. Returns the shortfalls.
    #[must_use]
    pub fn shortfalls(&self, need: &Self) -> Vec<String> {
        let mut out = Vec::new();
        if self.temp_c[0] > need.temp_c[0] || self.temp_c[1] < need.temp_c[1] {
            out.push(format!(
                "temperature {:.1}…{:.1} °C does not contain {:.1}…{:.1} °C",
                self.temp_c[0], self.temp_c[1], need.temp_c[0], need.temp_c[1]
            ));
        }
        for (name, have, want) in [("heating", self.heating, need.heating), ("cooling", self.cooling, need.cooling)] {
            if let Some(w) = want {
                let h = have.map_or(0.0, |b| b.max_abs_rate_c_per_min);
                if h < w.max_abs_rate_c_per_min {
                    out.push(format!(
                        "{name} rate reaches {h:.2} °C/min, the mission needs {:.2}",
                        w.max_abs_rate_c_per_min
                    ));
                }
            }
        }
        out
    }
}

impl Coverage {
    /// The coverage as name/value rows for a report: rows, temperature span, each leg's
    /// rows, span and fastest rate.
    #[must_use]
    pub fn rows(&self) -> Vec<(String, String)> {
        let leg = |b: Option<BranchRange>| {
            b.map_or_else(
                || "none".to_string(),
                |b| {
                    format!(
                        "{} rows, {:.1}…{:.1} °C, up to {:.2} °C/min",
                        b.rows, b.temp_c[0], b.temp_c[1], b.max_abs_rate_c_per_min
                    )
                },
            )
        };
        vec![
            ("rows with a temperature".to_string(), self.rows.to_string()),
            ("temperature span".to_string(), format!("{:.1}…{:.1} °C", self.temp_c[0], self.temp_c[1])),
            (format!("heating leg (Ṫ > {:.2} °C/min)", self.deadband_c_per_min), leg(self.heating)),
            (format!("cooling leg (Ṫ < −{:.2} °C/min)", self.deadband_c_per_min), leg(self.cooling)),
        ]
    }

    /// What a model with heating and cooling branches needs that these rows lack, and what
    /// to record next: each branch must hold at least a tenth of the rows on a branch (the
    /// rule under which static calibration falls back to one curve,
    /// [`crate::static_cal::is_one_branch`]). Empty when nothing is missing.
    #[must_use]
    pub fn record_next(&self) -> Vec<String> {
        let rows = |b: Option<BranchRange>| b.map_or(0, |b| b.rows);
        let (h, c) = (rows(self.heating), rows(self.cooling));
        let mut out = Vec::new();
        for (name, have, other, o) in [("heating", h, c, self.cooling), ("cooling", c, h, self.heating)] {
            if have * 10 < have + other {
                let rate = o.map_or(0.0, |b| b.max_abs_rate_c_per_min);
                out.push(format!(
                    "the {name} leg holds {have} rows of {}: the heating/cooling branch terms cannot be fitted or                      tested; record a {name} leg over {:.1}…{:.1} °C at about {rate:.2} °C/min (the rate the other                      leg reached)",
                    have + other,
                    self.temp_c[0],
                    self.temp_c[1]
                ));
            }
        }
        out
    }
}

/// The limits a table clamps to (first axis).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TableLimits {
    /// Bias-grid temperature range, °C (T̂ outside: `TEMP_OUT_OF_RANGE`).
    pub temp_c: [f64; 2],
    /// |Ṫ| limit, °C/min (above: `RATE_OUT_OF_RANGE`).
    pub rate_limit_c_per_min: f64,
}

impl TableLimits {
    /// Of `table`'s first axis.
    ///
    /// # Errors
    /// An empty table.
    pub fn of(table: &Table) -> Result<Self, CoverageError> {
        let a = table.axes.first().ok_or(CoverageError::EmptyTable)?;
        Ok(Self {
            temp_c: [f64::from(a.bias.t_start_c), f64::from(a.bias.t_end_c())],
            rate_limit_c_per_min: f64::from(a.rate_limit_c_per_min),
        })
    }
}

/// A calibration's coverage and its table's limits, for the reports.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CalCoverage {
    /// Programs the coverage is of: those the table written was fitted on.
    pub programs: Vec<String>,
    /// What their rows span.
    pub covered: Coverage,
    /// What the table clamps to.
    pub table: TableLimits,
}

impl CalCoverage {
    /// Coverage, the table's limits, and what to record next, as a report section.
    pub fn to_page(&self, page: &mut qfa_report::html_report::Page) {
        page.section("What the table's rows cover, against what the model needs");
        let mut rows = vec![("the table's programs".to_string(), self.programs.join(", "))];
        rows.extend(self.covered.rows());
        rows.push((
            "table clamps to".to_string(),
            format!(
                "{:.1}…{:.1} °C (beyond: TEMP_OUT_OF_RANGE), |Ṫ| ≤ {:.2} °C/min (beyond: RATE_OUT_OF_RANGE)",
                self.table.temp_c[0], self.table.temp_c[1], self.table.rate_limit_c_per_min
            ),
        ));
        page.kv(&rows);
        page.para(
            "The hysteresis model (Eq. 11 plus heating and cooling bias grids) needs both legs, over the temperatures and at the rates the unit will see: outside them the firmware clamps and flags. Compare the limits with a mission (`qfa-lab plan`).",
        );
        let next = self.covered.record_next();
        if next.is_empty() {
            page.para("Both legs are present: nothing is missing for the model's branch terms.");
        }
        for n in next {
            page.warning(&format!("What to record next: {n}."));
        }
    }
}

impl Coverage {
    /// What a verdict states this coverage covers.
    #[must_use]
    pub fn covers(&self) -> qfa_report::verdict::Covers {
        qfa_report::verdict::Covers {
            temp_c: self.temp_c,
            heating_c_per_min: self.heating.map(|b| b.max_abs_rate_c_per_min),
            cooling_c_per_min: self.cooling.map(|b| b.max_abs_rate_c_per_min),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// No finite sample is an error, never a coverage of infinities; from a log it names
    /// the programs.
    #[test]
    fn no_valid_row_is_an_error_naming_its_programs() {
        let nan = [(f64::NAN, 0.0), (20.0, f64::INFINITY)];
        assert_eq!(Coverage::of_samples(nan.into_iter(), 0.05), Err(CoverageError::NoValidRow { programs: None }));
        let log = Log::default();
        let e = Coverage::of_log(&log, &["p1".to_string()], 0.05).unwrap_err();
        assert_eq!(e.to_string(), "programs [\"p1\"]: no valid row: coverage not computed");
    }

    #[test]
    fn branches_split_at_the_deadband_and_shortfalls_name_what_is_missing() {
        let s = [(10.0, 0.1), (20.0, 1.0), (30.0, 2.0), (5.0, -0.5), (-5.0, -1.5)];
        let c = Coverage::of_samples(s.into_iter(), 0.2).unwrap();
        assert_eq!(c.rows, 5);
        assert_eq!(c.temp_c, [-5.0, 30.0]);
        let h = c.heating.unwrap();
        assert_eq!((h.rows, h.temp_c, h.max_abs_rate_c_per_min), (2, [20.0, 30.0], 2.0));
        let k = c.cooling.unwrap();
        assert_eq!((k.rows, k.temp_c, k.max_abs_rate_c_per_min), (2, [-5.0, 5.0], 1.5));
        let need = Coverage::of_samples([(0.0, 1.0), (25.0, -1.6)].into_iter(), 0.2).unwrap();
        let sf = c.shortfalls(&need);
        assert_eq!(sf.len(), 1, "{sf:?}");
        assert!(sf[0].contains("cooling"), "{sf:?}");
        assert!(Coverage::of_samples([(f64::NAN, 0.0)].into_iter(), 0.2).is_err());
    }
}
