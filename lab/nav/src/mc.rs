//! Monte Carlo study: N seeds of the same scenario, in parallel, summarized by median and
//! 10th / 90th percentiles.
//!
//! Run `i` of base seed `S` draws from named streams of its seed
//! [`super::seeds::monte_carlo_run`] (the lab's one seed derivation),
//! whatever the shard or thread that flies it, so a study split into shards and merged gives the same numbers as one process. Each run draws, from its seed:
//!
//! * the temperature variation within the scenario's `[monte_carlo]` bounds: the drive
//!   profile and ground temperature shifted by U(−`temp_offset_c`, +`temp_offset_c`), the
//!   excursion from the ground temperature scaled by U(1 ∓ `temp_scale`);
//! * unit-to-unit spread: each thermal coefficient of each of the three accelerometers
//!   multiplied by `1 + unit_spread·N(0,1)`, each DS18B20 offset moved by
//!   `sensor_offset_c·N(0,1)`; each varied unit is **recalibrated** from its own
//!   simulated four-position test (the lab's fit), as a real unit would be;
//! * the non-thermal IMU errors ([`super::errors`]) and every noise sequence.
//!
//! Every run aligns (if the scenario does) and flies `none`, `simple`, `hysteresis`,
//! `discovered` (each varied unit's own discovery run on its calibration log; off with
//! `--no-mc-discovered`) and `oracle` in lock-step ([`super::mc_variants`]). The thermal share removed by a variant
//! is `(simple − variant)/(simple − oracle)` on that run's **thermal-only** CEP rate (the
//! radial growth of variant − oracle position, same sensor data; the oracle's is 0 by
//! construction), so the gyro error's sign cannot flip it. The share on total CEP is kept
//! per run in `mc_runs.csv` for comparison.
//!
//! The statistics over the runs, the merge of shards and the study's outputs are in
//! [`super::mc_summary`], re-exported here so `mc::merge` and `mc::Summary` keep their paths.

use std::collections::BTreeMap;
use std::fmt;
use std::time::Instant;

use rand::{Rng, RngExt};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::align::AlignErrors;
use super::calib::CalibError;
use super::flight_report::ReportError;
use super::run::{self, Figures, RunError};
use super::scenario::{Scenario, Variation};
use super::variants::VariantsError;
use super::{mc_variants, share, thermal_ceps, truths_seeded, units, NavigateArgs, Tables};
use qfa_sim::truth::Truth;

pub use super::mc_summary::{
    merge, summarize, table, write_outputs, AlignStats, ShardTiming, Stats, Summary, SummaryError,
};

/// Why a Monte Carlo run (or the runs of a shard) failed.
#[derive(Debug)]
#[non_exhaustive]
pub enum McError {
    /// A run's units could not be calibrated.
    Calibration {
        /// The run.
        run: u64,
        /// The calibration's error.
        source: CalibError,
    },
    /// A run's flight failed.
    Flight {
        /// The run.
        run: u64,
        /// The flight's error.
        source: RunError,
    },
    /// A run's shares removed or flag shares could not be computed.
    Figures {
        /// The run.
        run: u64,
        /// Which, and why.
        source: ReportError,
    },
    /// The variants could not be built from the tables.
    Variants(VariantsError),
    /// A draw's flight failed ([`hysteresis_share`]).
    Fly(RunError),
    /// The thermal-only CEP rates or a share could not be computed.
    Report(ReportError),
    /// The worker threads could not be started.
    ThreadPool(rayon::ThreadPoolBuildError),
    /// The scenario could not be written into the partial result.
    Toml(toml::ser::Error),
}

impl fmt::Display for McError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Calibration { run, .. } => write!(f, "run {run}: calibration"),
            Self::Flight { run, .. } => write!(f, "run {run}: flight"),
            Self::Figures { run, .. } => write!(f, "run {run}"),
            Self::Variants(e) => write!(f, "{e}"),
            Self::Fly(e) => write!(f, "{e}"),
            Self::Report(e) => write!(f, "{e}"),
            Self::ThreadPool(_) => f.write_str("thread pool"),
            Self::Toml(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for McError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Calibration { source, .. } => Some(source),
            Self::Flight { source, .. } => Some(source),
            Self::Figures { source, .. } => Some(source),
            Self::ThreadPool(e) => Some(e),
            // Printed as they are (above): their causes come next.
            Self::Variants(e) => e.source(),
            Self::Fly(e) => e.source(),
            Self::Report(e) => e.source(),
            Self::Toml(e) => e.source(),
        }
    }
}

impl From<VariantsError> for McError {
    fn from(e: VariantsError) -> Self {
        Self::Variants(e)
    }
}

impl From<RunError> for McError {
    fn from(e: RunError) -> Self {
        Self::Fly(e)
    }
}

impl From<ReportError> for McError {
    fn from(e: ReportError) -> Self {
        Self::Report(e)
    }
}

/// What to run.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// Runs in the whole study.
    pub runs: u64,
    /// Base seed.
    pub seed: u64,
    /// Worker threads (0: all cores).
    pub jobs: usize,
    /// This shard `(k, n)`: the runs `i` with `i mod n = k`.
    pub shard: (u64, u64),
    /// Run the discovery workflow on each unit's calibration log and fly `discovered`
    /// (about doubles a run's cost).
    pub discover: bool,
    /// The lab program each run's units are calibrated on.
    pub lab: super::calib::LabProgram,
    /// Experiment only: every table's rate limit, °C/min, in place of the fitted one.
    pub rate_limit_override: Option<f32>,
}

impl Plan {
    /// From the command-line arguments.
    #[must_use]
    pub fn of(args: &NavigateArgs, sc: &Scenario, shard: (u64, u64)) -> Self {
        Self {
            runs: args.runs,
            seed: args.mc_seed.unwrap_or(sc.seed),
            jobs: args.jobs,
            shard,
            discover: !args.no_mc_discovered,
            lab: args.lab_program,
            rate_limit_override: args.rate_limit_override,
        }
    }

    /// Run indices of this shard.
    #[must_use]
    pub fn indices(&self) -> Vec<u64> {
        (0..self.runs).filter(|i| i % self.shard.1.max(1) == self.shard.0).collect()
    }
}

/// One run's figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Outcome {
    /// Run index.
    pub run: u64,
    /// Its seed.
    pub seed: u64,
    /// Temperature shift drawn, °C.
    pub temp_offset_c: f64,
    /// Excursion scale drawn.
    pub temp_scale: f64,
    /// Case temperature range flown, °C.
    pub case_temp_range_c: [f64; 2],
    /// Total CEP rate per variant, nmile/h.
    pub cep_nmi_per_h: BTreeMap<String, f64>,
    /// Thermal-only CEP rate per variant (variant − oracle), nmile/h.
    pub thermal_cep_nmi_per_h: BTreeMap<String, f64>,
    /// Thermal share removed per variant (on the thermal-only CEP rate).
    pub thermal_share_removed: BTreeMap<String, f64>,
    /// The same share on total CEP rate (sign-sensitive: for comparison only).
    pub share_removed_total_cep: BTreeMap<String, f64>,
    /// Alignment errors per variant (empty: alignment off).
    pub alignment: BTreeMap<String, AlignErrors>,
    /// Share of the flight's IMU cycles with `RATE_OUT_OF_RANGE`, per table variant.
    #[serde(default)]
    pub rate_clamped_share: BTreeMap<String, f64>,
    /// Share of the flight's IMU cycles with `TEMP_OUT_OF_RANGE`, per table variant.
    #[serde(default)]
    pub temp_clamped_share: BTreeMap<String, f64>,
    /// Wall time of the run (calibration and flight), s.
    pub wall_s: f64,
}

/// A shard's result, `mc_partial_K_of_N.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Partial {
    /// Scenario name.
    pub scenario: String,
    /// The scenario itself (TOML), so merge can refuse mixed studies.
    pub scenario_toml: String,
    /// Runs in the whole study.
    pub runs: u64,
    /// Base seed.
    pub seed: u64,
    /// `(k, n)`.
    pub shard: (u64, u64),
    /// Worker threads used.
    pub jobs: usize,
    /// Wall time of this shard's runs, s.
    pub wall_s: f64,
    /// The runs.
    pub outcomes: Vec<Outcome>,
    /// The nominal single-run report (shard 0 only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nominal: Option<serde_json::Value>,
}

/// The three units with their unit-to-unit spread drawn from `rng`.
pub fn varied_units<R: Rng + ?Sized>(v: &Variation, rng: &mut R) -> [Truth; 3] {
    let mut us = units();
    let mut f = |x: &mut f64| {
        let z = qfa_rng::normal(rng);
        *x *= 1.0 + v.unit_spread * z;
    };
    for u in &mut us {
        let s = &mut u.scale;
        for c in [&mut s.mu, &mut s.beta, &mut s.epsilon, &mut s.eta, &mut s.alpha] {
            let mut x = f64::from(*c);
            f(&mut x);
            *c = x as f32;
        }
        let b = &mut u.bias;
        for c in [&mut b.k0_g, &mut b.b1_g_per_c, &mut b.b2_g_per_c2] {
            f(c);
        }
    }
    for u in &mut us {
        let z = qfa_rng::normal(rng);
        u.sensor.offset_c += v.sensor_offset_c * z;
    }
    us
}

/// What run `i` of a study flies.
#[derive(Clone, Debug)]
pub struct Draw {
    /// The scenario with the run's seed and temperature variation.
    pub scenario: Scenario,
    /// The three units with their spread.
    pub units: [Truth; 3],
    /// The run's seed: stream `i` of the base seed's `monte carlo: runs` family.
    pub seed: u64,
    /// Temperature shift, °C.
    pub temp_offset_c: f64,
    /// Excursion scale.
    pub temp_scale: f64,
}

/// The draws of run `i` of base seed `seed` (see the module doc).
#[must_use]
pub fn draw(sc: &Scenario, seed: u64, i: u64) -> Draw {
    let rs = super::seeds::monte_carlo_run(seed, i);
    let mut rng = qfa_rng::seeded(super::seeds::variation(rs));
    let v = sc.monte_carlo;
    let off = if v.temp_offset_c > 0.0 { rng.random_range(-v.temp_offset_c..=v.temp_offset_c) } else { 0.0 };
    let scale = if v.temp_scale > 0.0 { 1.0 + rng.random_range(-v.temp_scale..=v.temp_scale) } else { 1.0 };
    let mut s = sc.clone().with_temperature_variation(off, scale);
    s.seed = rs;
    let units = varied_units(&v, &mut rng);
    Draw { scenario: s, units, seed: rs, temp_offset_c: off, temp_scale: scale }
}

/// The tables run `d` flies: its units calibrated (`discover` adds the `discovered`
/// variant), carrying the triad's known misalignment matrix.
///
/// # Errors
/// Calibration.
pub fn tables_of(d: &Draw, discover: bool) -> Result<Tables, CalibError> {
    tables_on(d, &super::calib::CalibOptions { discover, ..super::calib::CalibOptions::default() })
}

/// [`tables_of`] with the calibration options `opts`.
///
/// # Errors
/// Calibration.
pub fn tables_on(d: &Draw, opts: &super::calib::CalibOptions) -> Result<Tables, CalibError> {
    let mut tables = super::calibrate_opts(&d.units, d.seed, 1, opts)?;
    tables.misalignment = d.scenario.imu.accel.carried_misalignment();
    Ok(tables)
}

/// Fly draw `d` with `tables` (possibly edited, for an experiment) and return the
/// hysteresis variant's thermal share removed, `(simple − hysteresis)/(simple − oracle)`.
///
/// # Errors
/// Flight, or a share that cannot be computed.
pub fn hysteresis_share(d: &Draw, tables: &Tables) -> Result<f64, McError> {
    let r = run::fly(&d.scenario, &mut truths_seeded(&d.units, d.seed), mc_variants(tables, d.scenario.imu_rate_hz)?)?;
    let th = thermal_ceps(&r)?;
    share(th["simple"], th["hysteresis"], th["oracle"]).map_err(McError::Report)
}

/// Fly run `i` of base seed `seed`; `discover` adds the `discovered` variant.
///
/// # Errors
/// Calibration, flight, or a share that cannot be computed.
pub fn one(sc: &Scenario, seed: u64, i: u64, discover: bool) -> Result<Outcome, McError> {
    one_on(sc, seed, i, &super::calib::CalibOptions { discover, ..super::calib::CalibOptions::default() })
}

/// [`one`] with the units calibrated with `opts` (validation is never run here).
///
/// # Errors
/// Calibration, flight, or a share that cannot be computed.
pub fn one_on(sc: &Scenario, seed: u64, i: u64, opts: &super::calib::CalibOptions) -> Result<Outcome, McError> {
    let t0 = Instant::now();
    let d = draw(sc, seed, i);
    let tables = tables_on(&d, opts).map_err(|e| McError::Calibration { run: i, source: e })?;
    let Draw { scenario: s, units: us, seed: rs, temp_offset_c: off, temp_scale: scale } = d;
    let res = run::fly(&s, &mut truths_seeded(&us, rs), mc_variants(&tables, s.imu_rate_hz)?)
        .map_err(|e| McError::Flight { run: i, source: e })?;
    let cep: BTreeMap<String, f64> =
        res.names.iter().zip(&res.tracks).map(|(n, tr)| (n.clone(), Figures::of(&res.t, tr).cep_nmi_per_h)).collect();
    let thermal = thermal_ceps(&res)?;
    let at_run = |e| McError::Figures { run: i, source: e };
    let mut ts = BTreeMap::new();
    let mut tot = BTreeMap::new();
    for n in cep.keys() {
        ts.insert(n.clone(), share(thermal["simple"], thermal[n], thermal["oracle"]).map_err(at_run)?);
        tot.insert(n.clone(), share(cep["simple"], cep[n], cep["oracle"]).map_err(at_run)?);
    }
    let lo = res.temps.iter().map(|t| t[1]).fold(f64::INFINITY, f64::min);
    let hi = res.temps.iter().map(|t| t[1]).fold(f64::NEG_INFINITY, f64::max);
    let flags = super::flag_shares(&res).map_err(at_run)?;
    Ok(Outcome {
        rate_clamped_share: flags.iter().map(|(n, f)| (n.clone(), f.rate_clamped)).collect(),
        temp_clamped_share: flags.iter().map(|(n, f)| (n.clone(), f.temp_clamped)).collect(),
        run: i,
        seed: rs,
        temp_offset_c: off,
        temp_scale: scale,
        case_temp_range_c: [lo, hi],
        cep_nmi_per_h: cep,
        thermal_cep_nmi_per_h: thermal,
        thermal_share_removed: ts,
        share_removed_total_cep: tot,
        alignment: res.names.iter().cloned().zip(res.alignment.iter().copied()).collect(),
        wall_s: t0.elapsed().as_secs_f64(),
    })
}

/// Fly the runs of `plan`'s shard on `plan.jobs` threads (rayon), with a progress bar
/// when `progress`.
///
/// # Errors
/// Thread pool, or the first failed run.
pub fn run(sc: &Scenario, plan: &Plan, progress: bool) -> Result<Partial, McError> {
    let idx = plan.indices();
    let mut b = rayon::ThreadPoolBuilder::new();
    if plan.jobs > 0 {
        b = b.num_threads(plan.jobs);
    }
    let pool = b.build().map_err(McError::ThreadPool)?;
    let jobs = pool.current_num_threads();
    let pb = if progress { indicatif::ProgressBar::new(idx.len() as u64) } else { indicatif::ProgressBar::hidden() };
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "monte carlo {pos}/{len} runs [{elapsed_precise} < {eta_precise}] {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    pb.set_message(format!("{jobs} jobs"));
    let t0 = Instant::now();
    let outcomes: Vec<Result<Outcome, McError>> = pool.install(|| {
        idx.par_iter()
            .map(|&i| {
                let opts = super::calib::CalibOptions {
                    discover: plan.discover,
                    validate: false,
                    lab: plan.lab,
                    rate_limit_override: plan.rate_limit_override,
                };
                let r = one_on(sc, plan.seed, i, &opts);
                pb.inc(1);
                r
            })
            .collect()
    });
    pb.finish_and_clear();
    let wall_s = t0.elapsed().as_secs_f64();
    let outcomes = outcomes.into_iter().collect::<Result<Vec<_>, _>>()?;
    Ok(Partial {
        scenario: sc.name.clone(),
        scenario_toml: toml::to_string(sc).map_err(McError::Toml)?,
        runs: plan.runs,
        seed: plan.seed,
        shard: plan.shard,
        jobs,
        wall_s,
        outcomes,
        nominal: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_the_runs() {
        let mut all = Vec::new();
        for k in 0..3 {
            all.extend(
                Plan {
                    runs: 10,
                    seed: 1,
                    jobs: 1,
                    shard: (k, 3),
                    discover: false,
                    lab: super::super::calib::LabProgram::Paper,
                    rate_limit_override: None,
                }
                .indices(),
            );
        }
        all.sort_unstable();
        assert_eq!(all, (0..10).collect::<Vec<_>>());
    }
}
