//! Calibration of each unit through the lab: a simulated four-position test of the same
//! unit ([`crate::simulate::simulate`], the paper's programs) fitted by [`crate::calibrate::fit::fit`]
//! into the root crate's tables, plus the "none" table derived from the simple fit.
//!
//! Only the +1 g and −1 g positions are simulated (the 0 g positions carry no K1 or K0
//! information: the fit pairs ±1 g by time), and only the fit programs of the lab's
//! held-out rule ([`crate::calibrate::fit::split_programs`]: the extreme rates 0.3 and 0.9 °C/min),
//! so the tables are exactly the ones the lab's `calibrate` would flash for that log.

use qfa_thermal::model::AxisModel;
use qfa_thermal::table::Table;

use crate::calibrate::fit::{fit, split_programs, FitOptions};
use crate::data::cycling::{write_log_to, Log};
use crate::discover::{analyze, Channels, Start};
use crate::simulate::profile::{paper_positions, Program, PAPER_RATES};
use crate::simulate::simulate;
use crate::simulate::truth::Truth;

/// Row length of the simulated log, s (the lab's default).
pub const ROW_S: u32 = 1;

/// The three tables of one unit and its fit figures.
#[derive(Clone, Debug)]
pub struct UnitTables {
    /// Room-temperature constants: the simple fit's γ and K0 at T0, no temperature terms.
    pub none: Table,
    /// Paper Eq. 3–4.
    pub simple: Table,
    /// Eq. 11 plus heating / cooling bias grids.
    pub hysteresis: Table,
    /// The hysteresis model refitted with the extension slots the discovery workflow
    /// found on the same calibration log (start `paper`); the hysteresis table itself
    /// when discovery finds nothing missing.
    pub discovered: Table,
    /// Effects the discovery workflow added, in order (empty: `none`).
    pub discovered_effects: Vec<String>,
    /// Figures of the fit.
    pub report: CalReport,
}

/// Fit figures of one unit.
#[derive(Clone, Debug, serde::Serialize)]
pub struct CalReport {
    /// Unit.
    pub unit: String,
    /// Rows simulated.
    pub rows: usize,
    /// Condition number of the Eq. 11 design (column-scaled).
    pub eq11_condition: f64,
    /// RMS K1 residual of the Eq. 11 fit, ppm of γ.
    pub k1_rms_ppm_hysteresis: f64,
    /// Eq. 11 coefficients [γ, μ, β, ε, η, α].
    pub eq11: Vec<f64>,
}

fn axis(t: &Table) -> anyhow::Result<&AxisModel> {
    t.axes.first().ok_or_else(|| anyhow::anyhow!("empty table"))
}

/// Simulate and fit unit `truth`, with the discovery workflow on its log.
///
/// # Errors
/// A fit or table validation failure.
pub fn calibrate_unit(truth: &Truth, seed: u64, threads: usize) -> anyhow::Result<UnitTables> {
    calibrate_unit_with(truth, seed, threads, true)
}

/// Simulate and fit unit `truth`; `discover` runs the discovery workflow on its log
/// (without it, `discovered` is the hysteresis table and `discovered_effects` is
/// `["not run"]`; the Monte Carlo runs skip it, it costs several seconds per unit).
///
/// # Errors
/// A fit or table validation failure.
pub fn calibrate_unit_with(truth: &Truth, seed: u64, threads: usize, discover: bool) -> anyhow::Result<UnitTables> {
    let programs: Vec<Program> = PAPER_RATES.iter().map(|&r| Program::paper(r)).collect();
    let ids: Vec<String> = programs.iter().map(|p| p.id.clone()).collect();
    let (fit_ids, _) = split_programs(&ids);
    let used: Vec<Program> = programs.into_iter().filter(|p| fit_ids.contains(&p.id)).collect();
    let positions: Vec<_> = paper_positions().into_iter().filter(|p| p.input_g != 0.0).collect();
    let log = simulate(truth, &used, &positions, ROW_S, seed, threads, None);
    let f =
        fit(&log, &FitOptions::new(fit_ids.clone()), None).map_err(|e| anyhow::anyhow!("{}: fit: {e}", truth.name))?;
    let mut none = axis(&f.simple)?.clone();
    none.scale.mu = 0.0;
    let k0 = f.bias_simple.coef[0] as f32;
    for v in none.bias.heating_g.iter_mut().chain(none.bias.cooling_g.iter_mut()) {
        *v = k0;
    }
    let mut none_t = f.simple.clone();
    none_t.axes[0] = none;
    none_t.validate().map_err(|e| anyhow::anyhow!("none table: {e}"))?;
    let (discovered, discovered_effects) = if discover {
        discover_on(&log, &fit_ids, &f.hysteresis)?
    } else {
        (f.hysteresis.clone(), vec!["not run".to_string()])
    };
    Ok(UnitTables {
        none: none_t,
        simple: f.simple,
        hysteresis: f.hysteresis,
        discovered,
        discovered_effects,
        report: CalReport {
            unit: truth.name.clone(),
            rows: log.rows(),
            eq11_condition: f.sf_hysteresis.cond,
            k1_rms_ppm_hysteresis: f.sf_hysteresis.rms / f.sf_hysteresis.coef[0] * 1e6,
            eq11: f.sf_hysteresis.coef.clone(),
        },
    })
}

/// Run the discovery workflow (start `paper`) on the calibration log; refit the
/// hysteresis model with the slots it switched on. Rate and temperature terms it may add
/// are already in Eq. 11, so only the extension slots change the table.
///
/// # Errors
/// Discovery or the refit failed.
pub fn discover_on(log: &Log, fit_ids: &[String], hysteresis: &Table) -> anyhow::Result<(Table, Vec<String>)> {
    let mut csv = Vec::new();
    write_log_to(&mut csv, log)?;
    let ch = Channels::parse(std::str::from_utf8(&csv)?, 60.0)?;
    drop(csv);
    let rep = analyze(&ch, Start::Paper);
    let names: Vec<String> = rep.effects.iter().map(|e| e.name.clone()).collect();
    let ext = rep.model.map(|m| m.ext).unwrap_or_default();
    if ext == qfa_thermal::Extensions::default() {
        return Ok((hysteresis.clone(), names));
    }
    let f = fit(log, &FitOptions { ext, ..FitOptions::new(fit_ids.to_vec()) }, None)
        .map_err(|e| anyhow::anyhow!("refit with discovered slots: {e}"))?;
    Ok((f.hysteresis, names))
}

/// One 3-axis table (x, y, z) from three 1-axis tables, for a `Compensator<3, 32>`.
///
/// # Errors
/// Tables that are not 1-axis, or validation of the result.
pub fn table3(axes: [&Table; 3]) -> anyhow::Result<Table> {
    table3_with(axes, None)
}

/// [`table3`] carrying the misalignment matrix `misalignment` (row-major).
///
/// # Errors
/// As [`table3`], and a matrix outside the table's limits.
pub fn table3_with(axes: [&Table; 3], misalignment: Option<[f32; 9]>) -> anyhow::Result<Table> {
    for t in axes {
        anyhow::ensure!(t.axes.len() == 1, "expected 1-axis tables");
        anyhow::ensure!(
            usize::from(t.rate_window) == crate::data::pairing::RATE_WINDOW,
            "expected the lab's rate window"
        );
    }
    crate::calibrate::fit::table_of_axes_with(
        qfa_thermal::Input::PulseCounts,
        axes.map(|t| t.axes[0].clone()),
        misalignment,
    )
    .map_err(|e| anyhow::anyhow!("3-axis table invalid: {e}"))
}
