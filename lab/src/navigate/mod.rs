//! Navigation impact: pure-inertial navigation error with compensated accelerometers.
//!
//! `navigate` flies a scenario (built-in: the paper's §3.2 flight, ~2.3 h) through a
//! local-level NED strapdown mechanisation ([`strapdown`]) with WGS84 gravity and radii
//! ([`earth`]), once per accelerometer compensation variant, all in lock-step on the same
//! corrupted sensor data:
//!
//! | variant | accelerometer compensation |
//! |---|---|
//! | `none` | room-temperature constants only (γ and K0 at T0 from the simple fit) |
//! | `simple` | paper Eq. 3–4 (K1, K0 linear in ΔT) through the root crate's `Compensator` |
//! | `hysteresis` | Eq. 11 + heating / cooling bias tables, calibrated from a simulated four-position test of the same unit, through the `Compensator` |
//! | `discovered` | tables with the discovery workflow's extension effects, one per axis (postcard `.bin` or TOML, [`NavigateArgs::discovered_tables`]); by default, the hysteresis model refitted with the extension slots the discovery workflow (start `paper`) finds on each unit's own calibration log; `meta.discovered_source` names them |
//! | `oracle` | the truth model itself (true K1, K0 each cycle, f64): the limit |
//!
//! The three accelerometer axes are the paper's three units, the lab's presets
//! ([`crate::simulate::truth::Truth::jb_kt8`]): x = JB-KT8 #1, y = #2, z = #3. Each axis's truth
//! model turns the ideal Δv into integer I/F pulses with carry ([`accel::LabAccel`]);
//! the DS18B20 on each case (the unit's offset and noise, 12-bit) is read once a second
//! into that axis's stream of one `Compensator<3, 32, 3>` (the firmware's recommended
//! configuration: one stream per case, one 3-axis table); the pulses of each 5 ms cycle go
//! to `Compensator::cycle`. The fault runs ([`crate::navigate::faults`]) fly the same configuration. Each unit's tables come from the lab's simulation and fit of its
//! own four-position test ([`calib`]). Non-thermal IMU errors come from the scenario's
//! `[imu]` table ([`errors`]): gyro turn-on bias σ = 0.01 °/h, bias instability, ARW,
//! scale factor and misalignment; accelerometer turn-on bias σ = 50 µg, scale factor and
//! misalignment beside the thermal truth model. Before take-off every variant aligns on
//! the ground on its own compensated output ([`align`]: coarse leveling and
//! gyrocompassing, then an eight-state Kalman fine alignment), and navigates from that
//! attitude; `meta.alignment` gives the errors it left. Altitude is held by the reference.
//!
//! `--runs N` adds a Monte Carlo study ([`mc`]): N seeds varying the noise, the IMU error
//! draws, the temperature profile within the scenario's `[monte_carlo]` bounds and the
//! units' thermal coefficients, each unit recalibrated; `report.json` gains `monte_carlo`.
//!
//! # Figures
//! * RMS East / North velocity error over the whole flight, sampled at 1 Hz.
//! * **CEP rate** (`cep_nmi_per_h`). PSINS's `cep.m` forms CEP = 0.5887·(σ_N + σ_E) from
//!   an ensemble of runs; one simulated trajectory has no ensemble, so we use the
//!   radial error growth per hour: the least-squares slope through the origin of the
//!   radial position error r(t) = √(δN² + δE²) over the flight, `Σ t·r / Σ t²`, in
//!   nmile/h. This is robust to the Schuler oscillation, unlike the end point. The end
//!   point r(T)/T and the PSINS form over the flight's time series divided by T are also
//!   reported.
//! * Share of the thermally induced error removed: `(simple − variant)/(simple − oracle)`
//!   on the total CEP rate (`meta.share_removed_cep`), and, because one trajectory's total
//!   radial error mixes the gyro and accelerometer errors with their signs, also on the
//!   isolated thermal error: the radial growth of (variant − oracle) position, the same
//!   sensor data in both (`meta.thermal_cep_nmi_per_h`, `meta.share_removed_thermal`).
//!
//! The thermal chain (bay air → case → element) is the lab's
//! ([`crate::simulate::thermal::ThermalChain`]), driven by the scenario's breakpoints.

pub mod accel;
pub mod align;
pub mod calib;
pub mod clock;
pub mod earth;
pub mod errors;
pub mod fault_injection;
pub mod faults;
pub mod mc;
pub mod mc_summary;
pub mod plan;
pub mod plot;
pub mod run;
pub mod scenario;
pub mod strapdown;
pub mod thermal;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use qfa_thermal::table::Table;
use serde::Serialize;

use crate::simulate::truth::Truth;
use accel::{AccelCompensation, AccelTruth, LabAccel, OracleCompensation, TableCompensation};
use align::AlignErrors;
use run::{Figures, FlightResult, Variant};
use scenario::Scenario;

/// Variant names in report order.
pub const VARIANTS: [&str; 5] = ["none", "simple", "hysteresis", "discovered", "oracle"];

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

/// The paper's flight figures (Table 7 and §3.2).
#[derive(Clone, Debug, Serialize)]
pub struct PaperFigures {
    /// CEP, simple → hysteresis, nmile/h.
    pub cep_nmi_per_h: [f64; 2],
    /// RMS East velocity error, simple → hysteresis, m/s.
    pub rms_ve_mps: [f64; 2],
    /// RMS North velocity error, simple → hysteresis, m/s.
    pub rms_vn_mps: [f64; 2],
}

/// Metadata of a run.
#[derive(Clone, Debug, Serialize)]
pub struct Meta {
    /// Scenario name.
    pub scenario: String,
    /// Flight duration, h.
    pub duration_h: f64,
    /// IMU rate, Hz.
    pub imu_rate_hz: f64,
    /// Gyro biases drawn, °/h.
    pub gyro_bias_dph: [f64; 3],
    /// Alignment errors each variant's navigation started from (empty: alignment off).
    pub alignment: BTreeMap<String, AlignErrors>,
    /// The alignment settings and ground temperature, °C.
    pub alignment_config: align::AlignConfig,
    /// The non-thermal IMU error model flown.
    pub imu_errors: errors::ImuErrors,
    /// Temperature range of the case, °C.
    pub case_temp_range_c: [f64; 2],
    /// Share of the thermally induced CEP removed, `(simple − v)/(simple − oracle)`.
    pub share_removed_cep: BTreeMap<String, f64>,
    /// Thermally induced CEP rate of each variant, nmile/h: the radial growth (same
    /// least-squares slope as `cep_nmi_per_h`) of its position minus the oracle's position
    /// (same gyros, same noise, so only the accelerometer thermal residual is left).
    pub thermal_cep_nmi_per_h: BTreeMap<String, f64>,
    /// `1 − thermal(variant)/thermal(simple)`: the share of simple's thermally induced
    /// error that the variant removes, measured on the isolated thermal error (robust to
    /// the gyro error's sign, unlike the share of total CEP).
    pub share_removed_thermal: BTreeMap<String, f64>,
    /// Same for RMS East and North velocity error (mean of the two shares).
    pub share_removed_rms_v: BTreeMap<String, f64>,
    /// Share of the flight's IMU cycles on which each table variant's compensator raised
    /// a flag (`rate_clamped`: `RATE_OUT_OF_RANGE`, `temp_clamped`: `TEMP_OUT_OF_RANGE`);
    /// the oracle has no status word and no entry.
    pub compensation_flags: BTreeMap<String, accel::FlagShares>,
    /// One line per variant whose rate or temperature was clamped on more than
    /// [`accel::CLAMPED_WARN_SHARE`] of the flight's cycles (empty: none).
    pub clamped_warnings: Vec<String>,
    /// Where the discovered table came from.
    pub discovered_source: String,
    /// The lab program the tables were calibrated on (`covering` or `paper`).
    pub lab_program: String,
    /// Calibration fit figures per axis.
    pub calibration: Vec<calib::CalReport>,
    /// The paper's figures.
    pub paper: PaperFigures,
    /// Wall time of calibration and flight, s.
    pub runtime_s: [f64; 2],
}

/// `report.json`: one entry per variant plus `meta`.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Figures per variant, keyed by name.
    #[serde(flatten)]
    pub variants: BTreeMap<String, Figures>,
    /// Everything else.
    pub meta: Meta,
    /// The Monte Carlo study, with `--runs N`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub monte_carlo: Option<mc::Summary>,
}

impl Report {
    /// Figures of `name`.
    #[must_use]
    pub fn get(&self, name: &str) -> Option<&Figures> {
        self.variants.get(name)
    }
}

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
pub fn calibrate(units: &[Truth; 3], sc: &Scenario) -> anyhow::Result<Tables> {
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
) -> anyhow::Result<Tables> {
    calibrate_opts(units, sc.seed, 2, &calib::CalibOptions { discover: true, validate: true, lab, rate_limit_override })
}

/// Calibrate each unit (seeds `seed + 1000 + i`) on `threads` threads; `discover` runs
/// the discovery workflow for the `discovered` variant.
///
/// # Errors
/// A fit or validation failure.
pub fn calibrate_with(units: &[Truth; 3], seed: u64, threads: usize, discover: bool) -> anyhow::Result<Tables> {
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
) -> anyhow::Result<Tables> {
    let mut out = Vec::new();
    for (i, u) in units.iter().enumerate() {
        out.push(calib::calibrate_unit_on(u, seed.wrapping_add(1000 + i as u64), threads, opts)?);
    }
    let reports = out.iter().map(|u| u.report.clone()).collect();
    let hysteresis = calib::table3([&out[0].hysteresis, &out[1].hysteresis, &out[2].hysteresis])?;
    let simple = calib::table3([&out[0].simple, &out[1].simple, &out[2].simple])?;
    Ok(Tables { units: out, hysteresis, simple, reports, misalignment: None })
}

/// Read a table for the discovered variant: root-crate postcard (`.bin`) or TOML.
///
/// # Errors
/// I/O, decode or validation errors.
pub fn read_table(path: &Path) -> anyhow::Result<Table> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    if path.extension().is_some_and(|e| e == "toml") {
        let text = String::from_utf8(bytes)?;
        let t: Table = toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
        t.validate().map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        Ok(t)
    } else {
        Table::decode(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
    }
}

/// Build the five variants in [`VARIANTS`] order. `discovered` holds one 1-axis table per
/// axis; `None` uses the hysteresis tables.
///
/// # Errors
/// A table the compensator refuses.
pub fn variants(t: &Tables, discovered: Option<[Table; 3]>) -> anyhow::Result<Vec<Variant>> {
    let u = &t.units;
    let m = t.misalignment;
    let tc = |f: &dyn Fn(&calib::UnitTables) -> &Table| -> anyhow::Result<Box<dyn AccelCompensation>> {
        Ok(Box::new(TableCompensation::with_misalignment([f(&u[0]), f(&u[1]), f(&u[2])], m)?))
    };
    let disc: Box<dyn AccelCompensation> = match &discovered {
        Some(d) => Box::new(TableCompensation::with_misalignment([&d[0], &d[1], &d[2]], m)?),
        None => tc(&|x| &x.hysteresis)?,
    };
    Ok(vec![
        Variant { name: "none".into(), comp: tc(&|x| &x.none)? },
        Variant { name: "simple".into(), comp: tc(&|x| &x.simple)? },
        Variant { name: "hysteresis".into(), comp: tc(&|x| &x.hysteresis)? },
        Variant { name: "discovered".into(), comp: disc },
        Variant { name: "oracle".into(), comp: Box::new(oracle_of(t)) },
    ])
}

/// The oracle carrying the same misalignment as the tables (in f64).
fn oracle_of(t: &Tables) -> OracleCompensation {
    let m = t.misalignment.map(|m| nalgebra::Matrix3::from_fn(|r, c| f64::from(m[r * 3 + c])));
    OracleCompensation::carrying(m)
}

/// Truth models of the three axes with the default noise seed.
#[must_use]
pub fn truths(units: &[Truth; 3]) -> [Box<dyn AccelTruth>; 3] {
    truths_seeded(units, 2019)
}

/// Truth models of the three axes, noise seeded from `seed`.
#[must_use]
pub fn truths_seeded(units: &[Truth; 3], seed: u64) -> [Box<dyn AccelTruth>; 3] {
    [0, 1, 2].map(|i| Box::new(LabAccel::new(&units[i], seed.wrapping_add(77 + i as u64))) as Box<dyn AccelTruth>)
}

/// `(simple − v)/(simple − oracle)`.
///
/// # Errors
/// A zero denominator (simple and oracle equal): the share cannot be computed.
pub fn share(simple: f64, v: f64, oracle: f64) -> anyhow::Result<f64> {
    let den = simple - oracle;
    anyhow::ensure!(
        den.abs() > 1e-12 && v.is_finite(),
        "share undefined: simple {simple} and oracle {oracle} coincide"
    );
    Ok((simple - v) / den)
}

/// Thermally induced CEP rate of each variant, nmile/h: the radial growth of its position
/// minus the oracle's (same sensor data), the same least-squares slope as `cep_nmi_per_h`.
///
/// # Errors
/// No `oracle` variant in the flight.
pub fn thermal_ceps(res: &FlightResult) -> anyhow::Result<BTreeMap<String, f64>> {
    let oi = res.names.iter().position(|n| n == "oracle").ok_or_else(|| anyhow::anyhow!("no oracle variant"))?;
    let o = &res.tracks[oi];
    let diff = |a: &[f64], b: &[f64]| -> Vec<f64> { a.iter().zip(b).map(|(x, y)| x - y).collect() };
    Ok(res
        .names
        .iter()
        .zip(&res.tracks)
        .map(|(n, tr)| {
            let d = run::Track {
                dn: diff(&tr.dn, &o.dn),
                de: diff(&tr.de, &o.de),
                vn: diff(&tr.vn, &o.vn),
                ve: diff(&tr.ve, &o.ve),
            };
            (n.clone(), Figures::of(&res.t, &d).cep_nmi_per_h)
        })
        .collect())
}

/// The flag shares of every variant that has a status word.
///
/// # Errors
/// A variant that counted no cycle (the shares cannot be computed).
pub fn flag_shares(res: &FlightResult) -> anyhow::Result<BTreeMap<String, accel::FlagShares>> {
    let mut m = BTreeMap::new();
    for (n, f) in res.names.iter().zip(&res.flags) {
        if let Some(f) = f {
            m.insert(n.clone(), f.shares().with_context(|| format!("variant {n}"))?);
        }
    }
    Ok(m)
}

/// A warning per variant clamped on more than [`accel::CLAMPED_WARN_SHARE`] of the cycles.
#[must_use]
pub fn clamped_warnings(flags: &BTreeMap<String, accel::FlagShares>) -> Vec<String> {
    let mut w = Vec::new();
    for (n, f) in flags {
        for (what, x) in
            [("rate (RATE_OUT_OF_RANGE)", f.rate_clamped), ("temperature (TEMP_OUT_OF_RANGE)", f.temp_clamped)]
        {
            if x > accel::CLAMPED_WARN_SHARE {
                w.push(format!(
                    "WARNING: {n}: {what} clamped on {:.1}% of the flight's IMU cycles: the flight leaves the table's \
                     calibrated range",
                    100.0 * x
                ));
            }
        }
    }
    w
}

/// Assemble the report from a flight.
///
/// # Errors
/// A share that cannot be computed (see [`share`]), or no oracle.
pub fn report(
    sc: &Scenario,
    res: &FlightResult,
    tables: &Tables,
    discovered_source: String,
    runtime_s: [f64; 2],
) -> anyhow::Result<Report> {
    let variants: BTreeMap<String, Figures> =
        res.names.iter().zip(&res.tracks).map(|(n, tr)| (n.clone(), Figures::of(&res.t, tr))).collect();
    let get = |n: &str| variants.get(n).copied().ok_or_else(|| anyhow::anyhow!("no `{n}` variant"));
    let (s, o) = (get("simple")?, get("oracle")?);
    let mut share_cep = BTreeMap::new();
    let mut share_v = BTreeMap::new();
    for (n, f) in &variants {
        share_cep.insert(n.clone(), share(s.cep_nmi_per_h, f.cep_nmi_per_h, o.cep_nmi_per_h)?);
        let sv =
            0.5 * (share(s.rms_ve_mps, f.rms_ve_mps, o.rms_ve_mps)? + share(s.rms_vn_mps, f.rms_vn_mps, o.rms_vn_mps)?);
        share_v.insert(n.clone(), sv);
    }
    let thermal = thermal_ceps(res)?;
    let ts = thermal["simple"];
    let mut share_thermal = BTreeMap::new();
    for (n, v) in &thermal {
        share_thermal.insert(n.clone(), share(ts, *v, 0.0)?);
    }
    let lo = res.temps.iter().map(|t| t[1]).fold(f64::INFINITY, f64::min);
    let hi = res.temps.iter().map(|t| t[1]).fold(f64::NEG_INFINITY, f64::max);
    let mut alignment_config = sc.alignment;
    alignment_config.ground_temp_c = Some(sc.ground_temp_c());
    let compensation_flags = flag_shares(res)?;
    Ok(Report {
        variants,
        meta: Meta {
            scenario: sc.name.clone(),
            duration_h: res.t.last().copied().unwrap_or(0.0) / 3600.0,
            imu_rate_hz: sc.imu_rate_hz,
            gyro_bias_dph: res.gyro_bias_dph,
            alignment: res.names.iter().cloned().zip(res.alignment.iter().copied()).collect(),
            alignment_config,
            imu_errors: sc.imu,
            case_temp_range_c: [lo, hi],
            share_removed_cep: share_cep,
            share_removed_rms_v: share_v,
            thermal_cep_nmi_per_h: thermal,
            share_removed_thermal: share_thermal,
            clamped_warnings: clamped_warnings(&compensation_flags),
            compensation_flags,
            discovered_source,
            lab_program: tables.reports.first().map_or("none", |r| r.lab_program.name()).to_string(),
            calibration: tables.reports.clone(),
            paper: PaperFigures { cep_nmi_per_h: [1.54, 1.29], rms_ve_mps: [1.36, 1.09], rms_vn_mps: [1.40, 1.19] },
            runtime_s,
        },
        monte_carlo: None,
    })
}

/// Write the error time series (every 10 s) as CSV.
///
/// # Errors
/// I/O.
pub fn write_timeseries(path: &Path, res: &FlightResult) -> anyhow::Result<()> {
    let mut s = String::from("time_s,drive_c,case_c,element_c");
    for n in &res.names {
        for q in ["ve_mps", "vn_mps", "de_m", "dn_m"] {
            let _ = write!(s, ",{n}_{q}");
        }
    }
    s.push('\n');
    for i in (0..res.t.len()).step_by(10) {
        let [d, c, e] = res.temps[i];
        let _ = write!(s, "{:.0},{d:.3},{c:.3},{e:.3}", res.t[i]);
        for tr in &res.tracks {
            let _ = write!(s, ",{:.4},{:.4},{:.2},{:.2}", tr.ve[i], tr.vn[i], tr.de[i], tr.dn[i]);
        }
        s.push('\n');
    }
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

/// Load the scenario of `args` with its overrides.
///
/// # Errors
/// Scenario file errors.
pub fn scenario_of(args: &NavigateArgs) -> anyhow::Result<Scenario> {
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

/// The nominal single run: calibrate (with discovery), align and fly every variant on the
/// scenario's own seed; writes `nav_timeseries.csv`, the calibrated tables
/// (`nav_table_*.toml`) and `nav_errors.png` to `args.out`.
///
/// # Errors
/// Scenario, table or I/O errors.
pub fn nominal(args: &NavigateArgs, sc: &Scenario) -> anyhow::Result<Report> {
    let units = units();
    let t0 = Instant::now();
    let mut tables = calibrate_on(&units, sc, args.lab_program, args.rate_limit_override)?;
    tables.misalignment = sc.imu.accel.carried_misalignment();
    let t_cal = t0.elapsed().as_secs_f64();
    let (disc, source) = match &args.discovered_tables {
        Some(p) => {
            let t = [read_table(&p[0])?, read_table(&p[1])?, read_table(&p[2])?];
            (Some(t), p.iter().map(|x| x.display().to_string()).collect::<Vec<_>>().join(", "))
        }
        None => {
            let u = &tables.units;
            let t = [u[0].discovered.clone(), u[1].discovered.clone(), u[2].discovered.clone()];
            let effects: Vec<String> = u
                .iter()
                .map(|x| if x.discovered_effects.is_empty() { "none".into() } else { x.discovered_effects.join("+") })
                .collect();
            (
                Some(t),
                format!(
                    "discovery (start paper) on each unit's calibration log: x [{}], y [{}], z [{}]",
                    effects[0], effects[1], effects[2]
                ),
            )
        }
    };
    let t1 = Instant::now();
    let res = run::fly(sc, &mut truths_seeded(&units, sc.seed), variants(&tables, disc)?)?;
    let t_fly = t1.elapsed().as_secs_f64();
    let rep = report(sc, &res, &tables, source, [t_cal, t_fly])?;
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    write_timeseries(&args.out.join("nav_timeseries.csv"), &res)?;
    if !args.no_plots {
        plot::plot_flight(
            &args.out.join("nav_errors.png"),
            &format!("pure-inertial errors: {} (held out: the tables never saw the flight)", sc.name),
            &res,
        )
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    }
    for (i, u) in tables.units.iter().enumerate() {
        for (n, t) in [("none", &u.none), ("simple", &u.simple), ("hysteresis", &u.hysteresis)] {
            std::fs::write(args.out.join(format!("nav_table_{}_{n}.toml", ["x", "y", "z"][i])), toml::to_string(t)?)?;
        }
    }
    Ok(rep)
}

/// `qfa-lab navigate`: the nominal run ([`nominal`]), then with `args.runs > 0` the Monte
/// Carlo study ([`mc::run`]); writes `report.json` (and the Monte Carlo outputs) to
/// `args.out`. With `args.shard` use [`navigate_shard`] instead.
///
/// # Errors
/// Scenario, table, Monte Carlo or I/O errors.
pub fn navigate(args: &NavigateArgs) -> anyhow::Result<Report> {
    anyhow::ensure!(args.shard.is_none(), "a shard writes a partial result: use navigate_shard");
    let sc = scenario_of(args)?;
    let mut rep = nominal(args, &sc)?;
    if args.verbose {
        eprintln!("{}", summary(&rep));
    }
    if args.runs > 0 {
        let part = mc::run(&sc, &mc::Plan::of(args, &sc, (0, 1)), args.verbose)?;
        let sum = mc::write_outputs(&args.out, std::slice::from_ref(&part), !args.no_plots)?;
        if args.verbose {
            eprintln!("{}", mc::table(&sum));
        }
        rep.monte_carlo = Some(sum);
    }
    std::fs::write(args.out.join("report.json"), serde_json::to_string_pretty(&rep)?)?;
    page(args, &sc, &rep)?.write(&args.out)?;
    Ok(rep)
}

/// `navigate`'s `report.html` ([`crate::html_report`]): the figures per variant, the
/// warnings, what the lab program covers against what the flight needs, and every plot in
/// `args.out`.
///
/// # Errors
/// The plan cannot be formed, or a plot cannot be read.
pub fn page(args: &NavigateArgs, sc: &Scenario, r: &Report) -> anyhow::Result<crate::html_report::Page> {
    let mut p = crate::html_report::Page::new(&format!("Navigation report: {}", r.meta.scenario));
    p.section("Held-out scheme").para(&format!(
        "Every table is fitted on the lab program `{}` (simulated chamber logs of each unit) and scored on the flight \
         `{}` ({:.2} h at {} Hz, case {:.1}…{:.1} °C): no flight row is fitted on. Discovered tables: {}.",
        r.meta.lab_program,
        r.meta.scenario,
        r.meta.duration_h,
        r.meta.imu_rate_hz,
        r.meta.case_temp_range_c[0],
        r.meta.case_temp_range_c[1],
        r.meta.discovered_source
    ));
    for w in &r.meta.clamped_warnings {
        p.warning(w.trim_start_matches("WARNING: "));
    }
    let rows: Vec<Vec<String>> = VARIANTS
        .iter()
        .filter_map(|n| r.get(n).map(|f| (n, f)))
        .map(|(n, f)| {
            let pct = |m: &BTreeMap<String, f64>| format!("{:.0}%", 100.0 * m.get(*n).copied().unwrap_or(f64::NAN));
            vec![
                (*n).to_string(),
                format!("{:.3}", f.cep_nmi_per_h),
                format!("{:.3}", f.rms_ve_mps),
                format!("{:.3}", f.rms_vn_mps),
                format!("{:.3}", f.end_radial_nmi_per_h),
                pct(&r.meta.share_removed_cep),
                format!("{:.4}", r.meta.thermal_cep_nmi_per_h.get(*n).copied().unwrap_or(f64::NAN)),
            ]
        })
        .collect();
    p.section("Figures per variant").table(
        &[
            "variant",
            "CEP, nmile/h",
            "RMS vE, m/s",
            "RMS vN, m/s",
            "end radial, nmile/h",
            "of simple − oracle removed",
            "thermal CEP, nmile/h",
        ],
        &rows,
    );
    let pf = &r.meta.paper;
    p.para(&format!(
        "The paper (flight, Table 7): CEP {} → {} nmile/h; RMS vE {} → {} m/s; RMS vN {} → {} m/s (simple → \
         hysteresis).",
        pf.cep_nmi_per_h[0],
        pf.cep_nmi_per_h[1],
        pf.rms_ve_mps[0],
        pf.rms_ve_mps[1],
        pf.rms_vn_mps[0],
        pf.rms_vn_mps[1]
    ));
    p.section("What the lab program covers, against what the flight needs");
    let plan = plan::plan(sc, args.lab_program)?;
    p.pre(&plan::text(&plan));
    for s in &plan.shortfalls {
        p.warning(&format!("the lab program does not cover the flight: {s}; record it before flying the table"));
    }
    p.section("Console summary").pre(&summary(r));
    if let Some(mc) = &r.monte_carlo {
        p.section("Monte Carlo").pre(&mc::table(mc));
    }
    p.section("Plots (the flight: held out from every fit)");
    p.images_in(&args.out, |name| format!("navigation plot {name}"))?;
    Ok(p)
}

/// `qfa-lab navigate --runs N --shard K/N`: the Monte Carlo runs of shard K (and, for
/// K = 0, the nominal run) into `args.out/mc_partial_K_of_N.json`, for
/// [`mc::merge`].
///
/// # Errors
/// Scenario, table, Monte Carlo or I/O errors.
pub fn navigate_shard(args: &NavigateArgs) -> anyhow::Result<PathBuf> {
    let (k, n) = args.shard.ok_or_else(|| anyhow::anyhow!("no shard given"))?;
    anyhow::ensure!(n > 0 && k < n, "shard {k}/{n}: need 0 ≤ K < N");
    anyhow::ensure!(args.runs > 0, "a shard needs --runs N > 0");
    let sc = scenario_of(args)?;
    let mut part = mc::run(&sc, &mc::Plan::of(args, &sc, (k, n)), args.verbose)?;
    if k == 0 {
        part.nominal = Some(serde_json::to_value(nominal(args, &sc)?)?);
    }
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let path = args.out.join(format!("mc_partial_{k}_of_{n}.json"));
    std::fs::write(&path, serde_json::to_string(&part)?).with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}

/// A human-readable table of the report, with the paper's figures beside ours.
#[must_use]
pub fn summary(r: &Report) -> String {
    let mut s = format!(
        "navigation ({}, {:.2} h at {} Hz; case {:.1}…{:.1} °C)\n{:<11} {:>8} {:>8} {:>8} {:>9} {:>8}\n",
        r.meta.scenario,
        r.meta.duration_h,
        r.meta.imu_rate_hz,
        r.meta.case_temp_range_c[0],
        r.meta.case_temp_range_c[1],
        "variant",
        "CEP nmi/h",
        "RMS vE",
        "RMS vN",
        "r(T)/T",
        "removed"
    );
    s = s.trim_end().to_string() + "  thermal nmi/h  removed\n";
    for n in VARIANTS {
        if let Some(f) = r.get(n) {
            let _ = writeln!(
                s,
                "{n:<11} {:>8.3} {:>8.3} {:>8.3} {:>9.3} {:>7.0}% {:>13.4} {:>7.0}%",
                f.cep_nmi_per_h,
                f.rms_ve_mps,
                f.rms_vn_mps,
                f.end_radial_nmi_per_h,
                100.0 * r.meta.share_removed_cep.get(n).copied().unwrap_or(f64::NAN),
                r.meta.thermal_cep_nmi_per_h.get(n).copied().unwrap_or(f64::NAN),
                100.0 * r.meta.share_removed_thermal.get(n).copied().unwrap_or(f64::NAN)
            );
        }
    }
    for (n, f) in &r.meta.compensation_flags {
        let _ = writeln!(
            s,
            "flags {n:<11} over {} cycles: rate clamped {:.1}%, temperature clamped {:.1}%, any flag {:.1}%",
            f.cycles,
            100.0 * f.rate_clamped,
            100.0 * f.temp_clamped,
            100.0 * f.any_flag
        );
    }
    for w in &r.meta.clamped_warnings {
        let _ = writeln!(s, "{w}");
    }
    for (n, a) in &r.meta.alignment {
        let _ = writeln!(
            s,
            "alignment {n:<11} roll {:+8.1}″ pitch {:+8.1}″ heading {:+7.3} mrad",
            a.roll_arcsec, a.pitch_arcsec, a.heading_mrad
        );
    }
    let p = &r.meta.paper;
    let _ = writeln!(
        s,
        "paper (flight, Table 7): CEP {} → {} nmile/h; RMS vE {} → {} m/s; RMS vN {} → {} m/s (simple → hysteresis)",
        p.cep_nmi_per_h[0], p.cep_nmi_per_h[1], p.rms_ve_mps[0], p.rms_ve_mps[1], p.rms_vn_mps[0], p.rms_vn_mps[1]
    );
    s
}

/// `navigate merge`'s `report.html`: the merged Monte Carlo table and every plot in `out`
/// (the nominal run's figures are in `report.json`; its page is the one shard 0's
/// `navigate` run would write).
///
/// # Errors
/// A plot that cannot be read.
pub fn merge_page(out: &Path, sum: &mc::Summary) -> anyhow::Result<crate::html_report::Page> {
    let mut p = crate::html_report::Page::new("Navigation Monte Carlo study (merged shards)");
    p.section("Held-out scheme").para(
        "Each run's tables are fitted on that run's own simulated lab program and scored on that run's own flight: \
         no flight row is fitted on.",
    );
    p.section("Monte Carlo").pre(&mc::table(sum));
    p.section("Plots");
    p.images_in(out, |name| format!("Monte Carlo plot {name}"))?;
    Ok(p)
}

/// The variants flown in the Monte Carlo runs: `none`, `simple`, `hysteresis`,
/// `discovered` (each unit's own discovery run on its calibration log, when the tables
/// were calibrated with discovery; otherwise it is the hysteresis table and is left out)
/// and `oracle`.
///
/// # Errors
/// A table the compensator refuses.
pub fn mc_variants(t: &Tables) -> anyhow::Result<Vec<Variant>> {
    let u = &t.units;
    let m = t.misalignment;
    let tc = |f: &dyn Fn(&calib::UnitTables) -> &Table| -> anyhow::Result<Box<dyn AccelCompensation>> {
        Ok(Box::new(TableCompensation::with_misalignment([f(&u[0]), f(&u[1]), f(&u[2])], m)?))
    };
    let mut v = vec![
        Variant { name: "none".into(), comp: tc(&|x| &x.none)? },
        Variant { name: "simple".into(), comp: tc(&|x| &x.simple)? },
        Variant { name: "hysteresis".into(), comp: tc(&|x| &x.hysteresis)? },
    ];
    if u.iter().all(|x| x.discovered_effects.iter().all(|e| e != "not run")) {
        v.push(Variant { name: "discovered".into(), comp: tc(&|x| &x.discovered)? });
    }
    v.push(Variant { name: "oracle".into(), comp: Box::new(oracle_of(t)) });
    Ok(v)
}

/// The lab demo's navigation hook ([`crate::demo::NavigationHook`]): `navigate` on the
/// built-in flight (its first `duration_s` when given) into `out`; returns the one-line
/// summary.
///
/// # Errors
/// The study's failure, as text (the demo fails with it).
pub fn demo_hook(out: &Path, duration_s: Option<f64>) -> Result<String, String> {
    let args = NavigateArgs { out: out.to_path_buf(), duration_s, ..NavigateArgs::default() };
    let r = navigate(&args).map_err(|e| format!("{e:#}"))?;
    let f = |n: &str| r.get(n).map_or(f64::NAN, |x| x.cep_nmi_per_h);
    Ok(format!(
        "CEP none {:.2} / simple {:.2} / hysteresis {:.2} / oracle {:.2} nmile/h (paper 1.54 → 1.29); \
         hysteresis removes {:.0}% of simple − oracle; {}",
        f("none"),
        f("simple"),
        f("hysteresis"),
        f("oracle"),
        100.0 * r.meta.share_removed_cep.get("hysteresis").copied().unwrap_or(f64::NAN),
        out.join("report.json").display()
    ))
}
