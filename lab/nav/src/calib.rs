//! Calibration of each unit through the lab: a simulated four-position test of the same
//! unit ([`qfa_sim::simulate`], the paper's programs) fitted by [`qfa_calibrate::fit::fit`]
//! into the root crate's tables, plus the "none" table derived from the simple fit.
//!
//! Only the +1 g and −1 g positions are simulated (the 0 g positions carry no K1 or K0
//! information: the fit pairs ±1 g by time). Every program of the lab program
//! ([`LabProgram`]) is simulated. With validation on, the structure is first fitted on the
//! fit programs of the lab's held-out rule ([`qfa_calibrate::fit::split_programs`]) and
//! evaluated on the held-out ones through the `Compensator` ([`Validation`]); the table
//! that flies is then refitted on **every** program, so no part of the lab log is
//! thrown away (`CalReport::flown_fit_programs` lists them).

use qfa_log::pairing::PairedLog;
use std::fmt;

use qfa_thermal::model::AxisModel;
use qfa_thermal::table::Table;

use qfa_calibrate::coverage::{CalCoverage, Coverage, CoverageError, TableLimits};
use qfa_calibrate::fit::{fit_held_out, fit_table, split_programs, FitError};
use qfa_discover::{analyze_source, Source, Start};
use qfa_log::cycling::Log;
use qfa_log::open::OpenedLog;
use qfa_sim::profile::{paper_positions, Program, PAPER_RATES};
use qfa_sim::simulate;
use qfa_sim::truth::Truth;

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
    /// The table `discover` writes for the same calibration log (start `paper`): the
    /// hysteresis table with the extension slots the catalog named that carry to held-out
    /// programs; the hysteresis table itself when none does.
    pub discovered: Table,
    /// Effects the discovery workflow added, in order (empty: `none`).
    pub discovered_effects: Vec<String>,
    /// Figures of the fit.
    pub report: CalReport,
}

/// The lab program each unit is calibrated on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LabProgram {
    /// [`Program::covering`]: the paper's staircase at 0.3 and 0.9 °C/min plus 1 and
    /// 2 °C/min triangles, which reach the built-in flight's case rates.
    #[default]
    Covering,
    /// The paper's four staircases (0.3, 0.5, 0.7, 0.9 °C/min): case rates up to 0.28 °C/min
    /// against the built-in flight's 1.62 (`qfa-lab plan --lab-program paper`); kept as the
    /// comparison.
    Paper,
}

impl LabProgram {
    /// Its programs, in the order the held-out rule reads them.
    #[must_use]
    pub fn programs(self) -> Vec<Program> {
        match self {
            Self::Covering => Program::covering(),
            Self::Paper => PAPER_RATES.iter().map(|&r| Program::paper(r)).collect(),
        }
    }

    /// Its name on the command line and in the reports.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::Covering => "covering",
            Self::Paper => "paper",
        }
    }
}

impl std::str::FromStr for LabProgram {
    type Err = CalibError;
    fn from_str(s: &str) -> Result<Self, CalibError> {
        match s {
            "covering" => Ok(Self::Covering),
            "paper" => Ok(Self::Paper),
            _ => Err(CalibError::LabProgram(s.to_string())),
        }
    }
}

/// The held-out validation of the chosen structure: fitted on the held-out rule's fit
/// programs, compensated through `Compensator<1, 32>` on the others.
#[derive(Clone, Debug, serde::Serialize)]
pub enum Validation {
    /// Figures of the held-out evaluation.
    Computed {
        /// Programs the validation table was fitted on.
        fit_programs: Vec<String>,
        /// Programs it was evaluated on.
        held_out_programs: Vec<String>,
        /// Table-4 sensitivity, ppm/°C, held out.
        sensitivity_ppm_per_c: qfa_calibrate::report::Variants,
        /// Bias residual, µg RMS, held out.
        bias_residual_ug: qfa_calibrate::report::Variants,
    },
    /// Not run, with the reason (the Monte Carlo runs skip it: it costs a second fit and
    /// a compensation pass per unit, and it does not change the flown table).
    NotComputed(String),
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
    /// Eq. 11 coefficients [γ, μ, β, ε, η, α] of the flown table.
    pub eq11: Vec<f64>,
    /// The lab program simulated.
    pub lab_program: LabProgram,
    /// Programs the flown table was fitted on: every program of the lab program.
    pub flown_fit_programs: Vec<String>,
    /// Held-out validation of the structure before the refit on every program.
    pub validation: Validation,
    /// What the flown table's programs cover and what the table clamps to.
    pub coverage: CalCoverage,
}

/// Why a unit could not be calibrated, or its tables not joined into one 3-axis table.
#[derive(Debug)]
#[non_exhaustive]
pub enum CalibError {
    /// A lab program other than `covering` or `paper` (the name given).
    LabProgram(String),
    /// A table without axes.
    EmptyTable,
    /// The fit on the fit programs, before the held-out evaluation, failed.
    ValidationFit {
        /// The unit.
        unit: String,
        /// The fit's error.
        source: FitError,
    },
    /// The held-out evaluation through the compensator failed.
    HeldOut {
        /// The unit.
        unit: String,
        /// The compensation's error.
        source: qfa_calibrate::compensate::Error,
    },
    /// A held-out figure that cannot be computed.
    Figures {
        /// The unit.
        unit: String,
        /// Which figure, and why.
        source: qfa_calibrate::CalibrateError,
    },
    /// The fit of the flown tables on every program failed.
    Fit {
        /// The unit.
        unit: String,
        /// The fit's error.
        source: FitError,
    },
    /// A table that no longer validates with the rate limit override.
    RateLimit {
        /// The override, °C/min.
        limit: f32,
        /// The validation's error.
        source: qfa_thermal::table::Error,
    },
    /// The `none` table does not validate.
    NoneTable(qfa_thermal::table::Error),
    /// Discovery could not form its channels from the log.
    Channels(qfa_log::channels::ChannelsError),
    /// Discovery's table (`calibrate`'s with the slots that carry) could not be formed.
    Discover(Box<qfa_discover::DiscoverError>),
    /// A calibration log of one program: discovery's folds are not whole programs, so it
    /// has no table of `calibrate`'s to fly.
    OneProgram,
    /// The coverage of the fitted rows or the table's limits could not be formed.
    Coverage(CoverageError),
    /// A table with other than one axis where one 3-axis table is formed.
    NotOneAxis,
    /// A table whose rate window is not the lab's.
    RateWindow,
    /// The 3-axis table does not validate.
    Table3(FitError),
}

impl fmt::Display for CalibError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::LabProgram(s) => write!(f, "lab program `{s}`: expected covering or paper"),
            Self::EmptyTable => f.write_str("empty table"),
            Self::ValidationFit { unit, .. } => write!(f, "{unit}: validation fit"),
            Self::HeldOut { unit, .. } => write!(f, "{unit}: held-out evaluation"),
            Self::Figures { unit, .. } => f.write_str(unit),
            Self::Fit { unit, .. } => write!(f, "{unit}: fit"),
            Self::RateLimit { limit, .. } => write!(f, "rate limit {limit}"),
            Self::NoneTable(_) => f.write_str("none table"),
            Self::Channels(e) => write!(f, "{e}"),
            Self::Discover(_) => f.write_str("discovery's table"),
            Self::OneProgram => f.write_str("a calibration log of one program has no discovered table"),
            Self::Coverage(e) => write!(f, "{e}"),
            Self::NotOneAxis => f.write_str("expected 1-axis tables"),
            Self::RateWindow => f.write_str("expected the lab's rate window"),
            Self::Table3(_) => f.write_str("3-axis table invalid"),
        }
    }
}

impl std::error::Error for CalibError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::ValidationFit { source, .. } | Self::Fit { source, .. } => Some(source),
            Self::HeldOut { source, .. } => Some(source),
            Self::Figures { source, .. } => Some(source),
            Self::RateLimit { source, .. } => Some(source),
            Self::NoneTable(e) => Some(e),
            Self::Table3(e) => Some(e),
            Self::Discover(e) => Some(e.as_ref()),
            // Printed as they are (above): their causes come next.
            Self::Channels(e) => e.source(),
            Self::Coverage(e) => e.source(),
            Self::LabProgram(_) | Self::EmptyTable | Self::NotOneAxis | Self::RateWindow | Self::OneProgram => None,
        }
    }
}

impl From<CoverageError> for CalibError {
    fn from(e: CoverageError) -> Self {
        Self::Coverage(e)
    }
}

fn axis(t: &Table) -> Result<&AxisModel, CalibError> {
    t.axes.first().ok_or(CalibError::EmptyTable)
}

/// Simulate and fit unit `truth`, with the discovery workflow on its log.
///
/// # Errors
/// A fit or table validation failure.
pub fn calibrate_unit(truth: &Truth, seed: u64, threads: usize) -> Result<UnitTables, CalibError> {
    calibrate_unit_with(truth, seed, threads, true)
}

/// Simulate and fit unit `truth` on the default lab program without validation;
/// `discover` runs the discovery workflow on its log (without it, `discovered` is the
/// hysteresis table and `discovered_effects` is `["not run"]`; the Monte Carlo runs skip
/// it, it costs several seconds per unit).
///
/// # Errors
/// A fit or table validation failure.
pub fn calibrate_unit_with(truth: &Truth, seed: u64, threads: usize, discover: bool) -> Result<UnitTables, CalibError> {
    calibrate_unit_on(truth, seed, threads, &CalibOptions { discover, ..CalibOptions::default() })
}

/// How a unit is calibrated.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CalibOptions {
    /// Run the discovery workflow on the log.
    pub discover: bool,
    /// Validate the structure on the held-out programs before the refit on all.
    pub validate: bool,
    /// The lab program simulated.
    pub lab: LabProgram,
    /// Experiment only: replace every table's rate limit (°C/min) after the fit. Above the
    /// fitted rate range the tables then extrapolate Eq. 11 instead of clamping, and
    /// `RATE_OUT_OF_RANGE` no longer marks rates beyond what the table was fitted on.
    pub rate_limit_override: Option<f32>,
}

/// Simulate unit `truth` on `opts.lab`'s programs, validate (with `opts.validate`) and fit
/// the flown tables on every program.
///
/// # Errors
/// A fit, evaluation or table validation failure.
pub fn calibrate_unit_on(
    truth: &Truth,
    seed: u64,
    threads: usize,
    opts: &CalibOptions,
) -> Result<UnitTables, CalibError> {
    let programs = opts.lab.programs();
    let ids: Vec<String> = programs.iter().map(|p| p.id.clone()).collect();
    let positions: Vec<_> = paper_positions().into_iter().filter(|p| p.input_g != 0.0).collect();
    let log = simulate(truth, &programs, &positions, ROW_S, seed, threads, None);
    let paired = PairedLog::new(&log);
    // The flown table: the structure chosen once on every program of the log, as
    // `calibrate` writes its table (`fit_table`); the validation scores that structure
    // fitted on the fit programs alone (`fit_held_out`), as `calibrate`'s figures do.
    let mut f = fit_table(&paired, &ids, qfa_thermal::Extensions::NONE)
        .map_err(|e| CalibError::Fit { unit: truth.name.clone(), source: e })?;
    let validation = if opts.validate {
        let (fit_ids, held) = split_programs(&ids);
        let v = fit_held_out(&paired, &fit_ids, &f, qfa_thermal::Extensions::NONE, None)
            .map_err(|e| CalibError::ValidationFit { unit: truth.name.clone(), source: e })?;
        let ev = qfa_calibrate::report::evaluate(&paired, &held, &v.simple, &v.hysteresis, None)
            .map_err(|e| CalibError::HeldOut { unit: truth.name.clone(), source: e })?;
        qfa_calibrate::check_figures(&ev).map_err(|e| CalibError::Figures { unit: truth.name.clone(), source: e })?;
        Validation::Computed {
            fit_programs: fit_ids,
            held_out_programs: held,
            sensitivity_ppm_per_c: ev.sensitivity_ppm_per_c,
            bias_residual_ug: ev.bias_residual_ug,
        }
    } else {
        Validation::NotComputed("validation off (Monte Carlo runs and tests skip it)".into())
    };
    if let Some(l) = opts.rate_limit_override {
        for t in [&mut f.simple, &mut f.hysteresis] {
            for a in &mut t.axes {
                a.rate_limit_c_per_min = l;
            }
            t.validate().map_err(|e| CalibError::RateLimit { limit: l, source: e })?;
        }
    }
    let mut none = axis(&f.simple)?.clone();
    none.scale.mu = 0.0;
    let k0 = f.bias_simple.coef[0] as f32;
    for v in none.bias.heating_g.iter_mut().chain(none.bias.cooling_g.iter_mut()) {
        *v = k0;
    }
    let mut none_t = f.simple.clone();
    none_t.axes[0] = none;
    none_t.validate().map_err(CalibError::NoneTable)?;
    let (discovered, discovered_effects) =
        if opts.discover { discover_on(&log)? } else { (f.hysteresis.clone(), vec!["not run".to_string()]) };
    let coverage = CalCoverage {
        covered: Coverage::of_log(&log, &ids, qfa_log::replay::branch_deadband_c_per_min())?,
        table: TableLimits::of(&f.hysteresis)?,
        programs: ids.clone(),
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
            lab_program: opts.lab,
            flown_fit_programs: ids,
            validation,
            coverage,
        },
    })
}

/// Run the discovery workflow (start `paper`) on the calibration log: the table `discover`
/// writes for it (`qfa_discover::cycling_table`: `calibrate`'s table with the extension
/// slots the catalog named that carry to held-out programs; Eq. 11 already holds the rate
/// and temperature terms), and the effects the catalog named.
///
/// # Errors
/// Discovery or its table failed.
pub fn discover_on(log: &Log) -> Result<(Table, Vec<String>), CalibError> {
    let source = Source::from_opened(OpenedLog::Cycling(log.clone()), 60.0).map_err(CalibError::Channels)?;
    let (rep, table) = analyze_source(&source, Start::Paper).map_err(|e| CalibError::Discover(Box::new(e)))?;
    let names: Vec<String> = rep.effects.iter().map(|e| e.name.clone()).collect();
    // A cycling source always has a table (a log of one program: calibrate's, held back).
    Ok((table.ok_or(CalibError::OneProgram)?, names))
}

/// One 3-axis table (x, y, z) from three 1-axis tables, for a `Compensator<3, 32>`.
///
/// # Errors
/// Tables that are not 1-axis, or validation of the result.
pub fn table3(axes: [&Table; 3]) -> Result<Table, CalibError> {
    table3_with(axes, None)
}

/// [`table3`] carrying the misalignment matrix `misalignment` (row-major).
///
/// # Errors
/// As [`table3`], and a matrix outside the table's limits.
pub fn table3_with(axes: [&Table; 3], misalignment: Option<[f32; 9]>) -> Result<Table, CalibError> {
    for t in axes {
        crate::ensure(t.axes.len() == 1, CalibError::NotOneAxis)?;
        crate::ensure(usize::from(t.rate_window) == qfa_log::replay::RATE_WINDOW, CalibError::RateWindow)?;
    }
    qfa_calibrate::fit::table_of_axes_with(
        qfa_thermal::Input::PulseCounts,
        axes.map(|t| t.axes[0].clone()),
        misalignment,
    )
    .map_err(CalibError::Table3)
}
