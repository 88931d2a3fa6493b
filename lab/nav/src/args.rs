//! The arguments of `qfa-lab navigate` and the scenario they select.

use std::path::PathBuf;

use super::*;

/// Arguments of `qfa-lab navigate`.
#[derive(Clone, Debug, Default)]
pub struct NavigateArgs {
    /// Scenario TOML; the built-in §3.2 flight when absent.
    pub scenario: Option<PathBuf>,
    /// Output directory (created).
    pub out: PathBuf,
    /// Tables for the `discovered` variant, one per axis x, y, z (postcard `.bin` or
    /// TOML, 1-axis, e.g. the discovery workflow's output for JB-KT8 #1, #2, #3); the
    /// hysteresis tables when absent.
    pub discovered_tables: Option<[PathBuf; 3]>,
    /// Override the scenario's IMU rate, Hz.
    pub imu_rate_hz: Option<f64>,
    /// Fly only the first seconds of the scenario.
    pub duration_s: Option<f64>,
    /// Print the summary to stderr.
    pub verbose: bool,
    /// Skip `nav_errors.png`.
    pub no_plots: bool,
    /// Monte Carlo runs (0: the single nominal run only).
    pub runs: u64,
    /// Monte Carlo base seed; the scenario's seed when absent.
    pub mc_seed: Option<u64>,
    /// Monte Carlo worker threads (0: all cores).
    pub jobs: usize,
    /// `(k, n)`: run only the runs `i` with `i mod n = k` and write a partial result.
    pub shard: Option<(u64, u64)>,
    /// Leave the `discovered` variant out of the Monte Carlo runs (no discovery per run).
    pub no_mc_discovered: bool,
    /// The lab program each unit is calibrated on (default: the one covering the flight).
    pub lab_program: calib::LabProgram,
    /// Experiment only: every table's rate limit, °C/min, in place of the fitted one
    /// ([`calib::CalibOptions::rate_limit_override`]).
    pub rate_limit_override: Option<f32>,
}

/// Load the scenario of `args` with its overrides.
///
/// # Errors
/// Scenario file errors.
pub fn scenario_of(args: &NavigateArgs) -> Result<Scenario, scenario::ScenarioError> {
    let mut sc = match &args.scenario {
        Some(p) => Scenario::load(p)?,
        None => Scenario::builtin(),
    };
    if let Some(r) = args.imu_rate_hz {
        sc.imu_rate_hz = r;
    }
    if let Some(d) = args.duration_s {
        sc = sc.truncated(d);
    }
    Ok(sc)
}
