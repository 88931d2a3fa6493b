//! A QFA unit of a batch: a cycling log (pulse counts through the paper's four-position
//! program) calibrated exactly as `qfa-lab calibrate` calibrates one (the same function
//! writes the same files), and the figures the fleet compares, read from the unit's own
//! flashed model.
//!
//! Why the unit's own model: a cycling calibration fits one structure for every QFA (Eq. 11
//! and a bias grid per branch), so each unit's coefficients already mean the same thing
//! across the fleet, and a figure fitted beside the model could contradict it. The
//! scale-factor terms are given relative to the unit's γ (ppm), so units whose γ differs
//! by a fraction of a percent compare on their thermal behaviour alone.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::input::UnitInput;
use super::unit::{Calibrated, UnitOptions};
use super::{BatchError, UnitFault};
use qfa_calibrate::{calibrate_into, CalibrateOptions};
use qfa_log::cycling::Log;
use qfa_report::verdict::{Measured, CYCLING_KEYS};
use qfa_thermal::model::Branch;

/// The rate the scale factor's heating/cooling split is read at, °C/min (the middle of the
/// paper's 0.3–0.9 °C/min programs).
pub const SPLIT_RATE_C_PER_MIN: f64 = 0.5;
/// Half the span the bias slope is read over, either side of T0, °C.
pub const SLOPE_HALF_SPAN_C: f64 = 10.0;

/// What the fleet compares of a QFA unit: the held-out figures of its certificate, and its
/// flashed model's coefficients.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct QfaFigures {
    /// Held-out Table-4 scale-factor sensitivity of the table's model, ppm/°C (not computed
    /// for a log of one program, whose figures are in-sample).
    pub held_out_sensitivity_ppm_per_c: Measured,
    /// Held-out bias residual of the table's model, µg RMS (not computed as the above).
    pub held_out_bias_ug: Measured,
    /// Eq. 11's reference temperature T0, °C.
    pub t0_c: f64,
    /// γ: K1 at T0 and Ṫ = 0, pulses/(g·s).
    pub gamma: f64,
    /// μ/γ: the scale factor's temperature coefficient, ppm/°C.
    pub mu_ppm_per_c: f64,
    /// β/γ, ppm/°C².
    pub beta_ppm_per_c2: f64,
    /// η/γ, the rate-by-temperature term, ppm per °C·°C/min.
    pub eta_ppm_per_c2_per_min: f64,
    /// α/γ, the rate-squared term, ppm per (°C/min)².
    pub alpha_ppm_per_c2_per_min2: f64,
    /// The scale factor's heating/cooling split at T0: K1 heating at
    /// [`SPLIT_RATE_C_PER_MIN`] minus cooling at the same rate, over γ, ppm (2·ε·r/γ, Eq. 11's
    /// rate term ε as the thermal hysteresis the paper models; at 0.5 °C/min it equals ε/γ
    /// in ppm per °C/min).
    pub sf_split_ppm: f64,
    /// The bias at T0 between the branches, µg.
    pub bias_level_ug: f64,
    /// The bias's slope at T0 (over ±[`SLOPE_HALF_SPAN_C`]), µg/°C.
    pub bias_slope_ug_per_c: f64,
    /// The bias grid's heating minus cooling, mean over its nodes, µg (not computed when the
    /// fit tied the branches).
    pub bias_split_ug: Measured,
    /// The bias's ageing on the log's clock ([`super::ageing`]), µg/h.
    pub ageing_ug_per_h: Measured,
    /// The programs its log holds, in the log's order: a unit that lacks a program most of
    /// the fleet's units ran is compared on its sensor only (`fleet::Coverage::Programs`).
    #[serde(default)]
    pub programs: Vec<String>,
}

/// The figures the fleet compares, with their units, robust-scale floors (a resolution far
/// under any population's spread), which way each is bad and what it is in words: `(name,
/// unit, floor, high only, words)`. Names are `qfa.` and the field's name.
pub(crate) const FLEET_FIGURES: [(&str, &str, f64, bool, &str); 12] = [
    ("held_out_sensitivity_ppm_per_c", "ppm/°C", 0.02, true, "held-out scale-factor sensitivity"),
    ("held_out_bias_ug", "µg", 0.5, true, "held-out bias residual"),
    ("gamma", "pulses/(g·s)", 1.0, false, "scale factor at T0"),
    ("mu_ppm_per_c", "ppm/°C", 0.5, false, "scale-factor temperature coefficient"),
    ("beta_ppm_per_c2", "ppm/°C²", 0.005, false, "scale-factor temperature curvature"),
    ("sf_split_ppm", "ppm", 2.0, false, "scale-factor heating/cooling split (thermal hysteresis)"),
    ("eta_ppm_per_c2_per_min", "ppm/(°C·°C/min)", 0.005, false, "scale-factor rate-by-temperature term"),
    ("alpha_ppm_per_c2_per_min2", "ppm/(°C/min)²", 2.0, false, "scale-factor rate-squared term"),
    ("bias_level_ug", "µg", 1.0, false, "bias at T0"),
    ("bias_slope_ug_per_c", "µg/°C", 0.05, false, "bias temperature slope"),
    ("bias_split_ug", "µg", 0.5, false, "bias heating/cooling split"),
    ("ageing_ug_per_h", "µg/h", 0.005, false, "bias ageing over the run (not thermal)"),
];

impl QfaFigures {
    /// The figure [`FLEET_FIGURES`] names `what` (without `qfa.`); `None` when it was not
    /// computed for this unit.
    #[must_use]
    pub(crate) fn value(&self, what: &str) -> Option<f64> {
        let num = |m: &Measured| match m {
            Measured::Value(v) => Some(*v),
            Measured::NotComputed { .. } => None,
        };
        Some(match what {
            "held_out_sensitivity_ppm_per_c" => return num(&self.held_out_sensitivity_ppm_per_c),
            "held_out_bias_ug" => return num(&self.held_out_bias_ug),
            "gamma" => self.gamma,
            "mu_ppm_per_c" => self.mu_ppm_per_c,
            "beta_ppm_per_c2" => self.beta_ppm_per_c2,
            "sf_split_ppm" => self.sf_split_ppm,
            "eta_ppm_per_c2_per_min" => self.eta_ppm_per_c2_per_min,
            "alpha_ppm_per_c2_per_min2" => self.alpha_ppm_per_c2_per_min2,
            "bias_level_ug" => self.bias_level_ug,
            "bias_slope_ug_per_c" => self.bias_slope_ug_per_c,
            "bias_split_ug" => return num(&self.bias_split_ug),
            "ageing_ug_per_h" => return num(&self.ageing_ug_per_h),
            _ => return None,
        })
    }
}

/// Calibrate the cycling log `log` of `input` into `dir`, as `qfa-lab calibrate` would.
///
/// # Errors
/// The limits set none of a cycling log's keys, or the calibration refused the log.
pub(crate) fn calibrate(
    input: &UnitInput,
    log: &Log,
    dir: &Path,
    opts: &UnitOptions,
) -> Result<Calibrated, BatchError> {
    opts.limits.check_applies("cycling", &CYCLING_KEYS).map_err(|e| BatchError::Unit(UnitFault::Limits(e)))?;
    let copts = CalibrateOptions {
        plots: opts.plots,
        title: input.serial.clone(),
        // The verdict's lines name the unit, not the IMU axis `calibrate` defaults to.
        unit: Some(input.serial.clone()),
        limits: opts.limits.clone(),
        reproducible: true,
        notes: vec![super::unit::CERTIFICATE_NAMES_THE_TABLE.to_string()],
        ..CalibrateOptions::default()
    };
    let cal = calibrate_into(log, dir, &copts, 0.0).map_err(|e| BatchError::Unit(UnitFault::Cycling(Box::new(e))))?;
    let v = cal.verdict.as_ref().ok_or(BatchError::Unit(UnitFault::NoVerdict))?;
    let (bin, crc) = super::encoded(&cal.table.hysteresis, dir)?;
    let r = &cal.report;
    let ageing = match super::ageing::ageing(log, &cal.table.hysteresis) {
        Ok(a) => Measured::Value(a.ug_per_h),
        Err(e) => Measured::NotComputed { not_computed: e.to_string() },
    };
    let covered = r.coverage.covered.temp_c;
    let rows = &cal.table.rows;
    let (heating, cooling) = rows.temps().fold((0, 0), |(h, c), (_, b)| match b {
        Branch::Heating => (h + 1, c),
        Branch::Cooling => (h, c + 1),
        Branch::Unknown => (h, c),
    });
    let rate_limit = cal.table.hysteresis.axes[0].rate_limit_c_per_min;
    let (sensitivity, bias_ug) = r.held_out_table_figures();
    Ok(Calibrated {
        outcome: v.outcome,
        failed_limits: v.failed(),
        held_out_mg: Vec::new(),
        structures: vec![("qfa".into(), structure(r.fit.branch.mode, r.fit.branch.shape))],
        temp_c: covered,
        one_branch: qfa_calibrate::static_cal::is_one_branch((heating, cooling)),
        rows: r.rows,
        table_crc32: format!("{crc:08x}"),
        table_bytes: bin.len(),
        descriptor: Vec::new(),
        temp_minutes: super::unit::cycling_temp_minutes(log),
        normal: None,
        qfa_normal: Some(normal(rows, rate_limit)),
        steps: Vec::new(),
        glitches_per_h: glitches_per_hour(log),
        log_warnings: left_out_warning(input)
            .into_iter()
            .chain(super::unit::log_warnings(&qfa_lint::lint_cycling(log)))
            .collect(),
        qfa: Some(QfaFigures {
            programs: programs_of(log),
            ..figures(&cal.table.hysteresis.axes[0], sensitivity, bias_ug, ageing)
        }),
    })
}

/// The rows of a chamber log left out of the unit's log ([`UnitInput::left_out`]), in the
/// words of the log's other warnings.
fn left_out_warning(input: &UnitInput) -> Option<String> {
    (input.left_out > 0).then(|| {
        format!(
            "[warning] rows: {} row(s) of the chamber log hold no count of this unit (its `pulses` cell empty), left out \
             of its log: it is calibrated on the rows it has (the unit taken off the head, or its counter not logged?)",
            input.left_out
        )
    })
}

/// Eq. 11's regressors over these are the prior's basis, `[1, δ, δ², Ṫ, Ṫ·δ, Ṫ²]` with
/// δ = ΔT / 50 °C (so the basis's columns are of one size, as the static prior's
/// `U_SCALE_C`); the basis's coefficients over them are Eq. 11's.
const EQ11_BASIS_SCALE: [f64; 6] = [1.0, 50.0, 2500.0, 1.0, 50.0, 1.0];

/// A QFA unit's statistics for the population prior ([`super::prior`]): the equations its
/// table was fitted on (every program, 30-row blocks), reduced.
///
/// * `scale` (axis `k1`): K1 in Eq. 11's regressors `[1, δ, δ², Ṫ, Ṫ·δ, Ṫ²]`, δ = ΔT / 50 °C.
/// * `bias` (axis `k0`): K0 (g, absolute) in the static prior's cubic and split,
///   `[1, u, u², u³, ±½]`, from both runs' branches as the firmware classified them.
///
/// The noise variance is the mean square of the block equations' residuals: the blocks
/// are 5 min at the paper's 10-s rows, longer than the static prior's 60-s means.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct QfaNormal {
    /// The scale factor's statistics (axis `k1`).
    pub scale: super::prior::UnitNormal,
    /// The bias's statistics (axis `k0`).
    pub bias: super::prior::UnitNormal,
    /// The unit's own table's rate limit, °C/min, which its prior table keeps.
    pub rate_limit_c_per_min: f32,
}

fn mean_square(resid: &[f64]) -> f64 {
    resid.iter().map(|r| r * r).sum::<f64>() / resid.len().max(1) as f64
}

/// [`QfaNormal`] of a table's fit rows.
fn normal(rows: &qfa_calibrate::fit::FitRows, rate_limit_c_per_min: f32) -> QfaNormal {
    let (eq11, k1) = rows.eq11_equations();
    let scaled: Vec<[f64; 6]> = eq11.iter().map(|x| std::array::from_fn(|j| x[j] / EQ11_BASIS_SCALE[j])).collect();
    let scale = super::prior::reduced_normal(&scaled, &[("k1", &k1)], rows.temps(), mean_square);
    let (xb, k0) = rows.bias_equations(super::prior::basis);
    let bias = super::prior::reduced_normal(&xb, &[("k0", &k0)], rows.temps(), mean_square);
    QfaNormal { scale, bias, rate_limit_c_per_min }
}

/// The prior's table of a QFA unit over the fleet's `span`: Eq. 11 from the `k1`
/// population's posterior, the bias grid from the `k0` one's (see [`super::prior`]).
///
/// # Errors
/// No population for `k1` or `k0`, a posterior that cannot be formed, or a table the root
/// crate refuses ([`PriorError`](super::prior::PriorError)).
pub fn qfa_prior_table(
    unit: &QfaNormal,
    pops: &[super::prior::Population],
    span: (f64, f64),
    deadband: f32,
) -> Result<qfa_thermal::Table, super::prior::PriorError> {
    use super::prior::{posterior, PriorError};
    let post = |n: &super::prior::UnitNormal| -> Result<Vec<f64>, PriorError> {
        let axis = n.axes.first().map_or_else(String::new, |a| a.axis.clone());
        let pop = pops.iter().find(|p| p.axis == axis).ok_or_else(|| PriorError::NoPopulation(axis.clone()))?;
        posterior(n, 0, pop).ok_or(PriorError::NotInvertible(axis))
    };
    let s = post(&unit.scale)?;
    let b = post(&unit.bias)?;
    let eq11: [f64; 6] = std::array::from_fn(|j| s[j] / EQ11_BASIS_SCALE[j]);
    let scale = qfa_calibrate::fit::scale_of_eq11(&eq11);
    let axis = super::prior::axis_model(&b, span, 0.0, deadband, scale, unit.rate_limit_c_per_min);
    qfa_calibrate::fit::table_of(axis).map_err(PriorError::Table)
}

/// The flashed model's structure in words.
fn structure(mode: qfa_calibrate::fit::BranchMode, shape: qfa_calibrate::fit::CurveShape) -> String {
    use qfa_calibrate::fit::{BranchMode, CurveShape};
    let bias = match mode {
        BranchMode::Single => "one bias curve for both branches",
        BranchMode::Offset => "a bias curve and a constant heating/cooling step",
        BranchMode::Free => "a bias curve per branch",
    };
    let on = match shape {
        CurveShape::Nodes => "",
        CurveShape::Cubic => ", each curve a cubic in temperature",
    };
    format!("Eq. 11 scale factor, {bias}{on}")
}

/// The fleet's figures of one flashed axis model and its held-out figures.
fn figures(axis: &qfa_thermal::AxisModel, sensitivity: Measured, bias_ug: Measured, ageing: Measured) -> QfaFigures {
    let s = &axis.scale;
    let gamma = f64::from(s.gamma);
    let ppm = |x: f32| f64::from(x) / gamma * 1e6;
    let b = &axis.bias;
    let t0 = f64::from(s.t0_c);
    let mean_at = |t: f64| 1e6 * f64::from(b.k0(t as f32, Branch::Unknown));
    let splits: Vec<f64> = b.heating_g.iter().zip(&b.cooling_g).map(|(h, c)| f64::from(h - c) * 1e6).collect();
    let tied = splits.iter().all(|d| *d == 0.0);
    QfaFigures {
        held_out_sensitivity_ppm_per_c: sensitivity,
        held_out_bias_ug: bias_ug,
        t0_c: t0,
        gamma,
        mu_ppm_per_c: ppm(s.mu),
        beta_ppm_per_c2: ppm(s.beta),
        eta_ppm_per_c2_per_min: ppm(s.eta),
        alpha_ppm_per_c2_per_min2: ppm(s.alpha),
        sf_split_ppm: 2.0 * SPLIT_RATE_C_PER_MIN * ppm(s.epsilon),
        bias_level_ug: mean_at(t0),
        bias_slope_ug_per_c: (mean_at(t0 + SLOPE_HALF_SPAN_C) - mean_at(t0 - SLOPE_HALF_SPAN_C))
            / (2.0 * SLOPE_HALF_SPAN_C),
        bias_split_ug: if tied {
            Measured::NotComputed { not_computed: "the fit tied the bias grid's branches".into() }
        } else {
            Measured::Value(splits.iter().sum::<f64>() / splits.len() as f64)
        },
        ageing_ug_per_h: ageing,
        programs: Vec::new(),
    }
}

/// The programs `log` holds, each once, in the log's order.
fn programs_of(log: &Log) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for r in &log.runs {
        if !out.contains(&r.program) {
            out.push(r.program.clone());
        }
    }
    out
}

/// The rows the cycling reader skipped as one-row glitches, per hour of the log's runs.
fn glitches_per_hour(log: &Log) -> f64 {
    let hours: f64 = log.runs.iter().filter_map(|r| r.samples.last()).map(|s| s.time_s / 3600.0).sum();
    if hours > 0.0 {
        log.glitches.len() as f64 / hours
    } else {
        0.0
    }
}
