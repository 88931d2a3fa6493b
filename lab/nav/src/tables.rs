//! The three units flown and their tables, each calibrated from the unit's own simulated
//! lab test, and the truth models that turn their motion into pulses.

use qfa_thermal::table::Table;

use super::accel::{AccelTruth, LabAccel};
use super::calib::CalibError;
use super::*;
use qfa_sim::truth::Truth;

/// Tables for the four table-driven variants, per axis x, y, z.
pub struct Tables {
    /// Per unit: none, simple, hysteresis (1-axis tables) and the fit figures.
    pub units: Vec<calib::UnitTables>,
    /// The hysteresis tables as one 3-axis table (for a single `Compensator<3, 32>`).
    pub hysteresis: Table,
    /// The simple tables as one 3-axis table.
    pub simple: Table,
    /// Per-axis calibration figures.
    pub reports: Vec<calib::CalReport>,
    /// The triad's misalignment matrix every table variant carries (row-major; `None`:
    /// none). [`calibrate_with`] leaves it `None`; the flights set the scenario's
    /// ([`errors::AccelErrors::carried_misalignment`]).
    pub misalignment: Option<[f32; 9]>,
}

/// The three units on the x, y, z axes: the lab's JB-KT8 #1, #2, #3 presets.
#[must_use]
pub fn units() -> [Truth; 3] {
    [Truth::jb_kt8(1), Truth::jb_kt8(2), Truth::jb_kt8(3)]
}

/// Calibrate each unit from its simulated four-position test (two threads).
///
/// # Errors
/// A fit or validation failure.
pub fn calibrate(units: &[Truth; 3], sc: &Scenario) -> Result<Tables, CalibError> {
    calibrate_opts(
        units,
        sc.seed,
        2,
        &calib::CalibOptions { discover: true, validate: true, ..calib::CalibOptions::default() },
    )
}

/// [`calibrate`] on the lab program `lab`.
///
/// # Errors
/// A fit or validation failure.
pub fn calibrate_on(
    units: &[Truth; 3],
    sc: &Scenario,
    lab: calib::LabProgram,
    rate_limit_override: Option<f32>,
) -> Result<Tables, CalibError> {
    calibrate_opts(units, sc.seed, 2, &calib::CalibOptions { discover: true, validate: true, lab, rate_limit_override })
}

/// Calibrate each unit (its log's seed [`super::seeds::calibration_log`]) on `threads` threads; `discover` runs
/// the discovery workflow for the `discovered` variant.
///
/// # Errors
/// A fit or validation failure.
pub fn calibrate_with(units: &[Truth; 3], seed: u64, threads: usize, discover: bool) -> Result<Tables, CalibError> {
    calibrate_opts(units, seed, threads, &calib::CalibOptions { discover, ..calib::CalibOptions::default() })
}

/// Calibrate each unit with `opts` (lab program, validation, discovery).
///
/// # Errors
/// A fit or validation failure.
pub fn calibrate_opts(
    units: &[Truth; 3],
    seed: u64,
    threads: usize,
    opts: &calib::CalibOptions,
) -> Result<Tables, CalibError> {
    let mut out = Vec::new();
    for (i, u) in units.iter().enumerate() {
        out.push(calib::calibrate_unit_on(u, super::seeds::calibration_log(seed, i), threads, opts)?);
    }
    let reports = out.iter().map(|u| u.report.clone()).collect();
    let hysteresis = calib::table3([&out[0].hysteresis, &out[1].hysteresis, &out[2].hysteresis])?;
    let simple = calib::table3([&out[0].simple, &out[1].simple, &out[2].simple])?;
    Ok(Tables { units: out, hysteresis, simple, reports, misalignment: None })
}

/// Truth models of the three axes, noise drawn from `seed`'s accelerometer streams (the
/// flight's seed: a fixed default seed here let the fault study fly every scenario's
/// accelerometers on seed 2019's noise).
#[must_use]
pub fn truths_seeded(units: &[Truth; 3], seed: u64) -> [Box<dyn AccelTruth>; 3] {
    [0, 1, 2].map(|i| Box::new(LabAccel::new(&units[i], super::seeds::accelerometer(seed, i))) as Box<dyn AccelTruth>)
}
