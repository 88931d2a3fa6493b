//! The nominal flight's `report.json` ([`Report`]): its records, the figures computed from a
//! flight for it (the shares removed, the thermal-only CEP, the flag shares and their
//! warnings), and its console table ([`summary`]).

use std::collections::BTreeMap;
use std::fmt::{self, Write as _};

use serde::Serialize;

use super::align::AlignErrors;
use super::run::Figures;
use super::*;

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
    /// The run's verdict, once [`navigate`] has judged it (`report.json` carries it as its
    /// first key, [`qfa_report::verdict::json_with_verdict`], not here).
    #[serde(skip)]
    pub verdict: Option<qfa_report::verdict::Verdict>,
    /// The plots the run drew and wrote, in the order its page shows them (its page inlines
    /// these bytes; so can a caller's, the demo's).
    #[serde(skip)]
    pub plots: Vec<qfa_report::plot_png::Plot>,
}

impl Report {
    /// Figures of `name`.
    #[must_use]
    pub fn get(&self, name: &str) -> Option<&Figures> {
        self.variants.get(name)
    }
}

/// Why a flight's report figures could not be computed.
#[derive(Debug)]
#[non_exhaustive]
pub enum ReportError {
    /// `simple` and `oracle` coincide (or the variant's figure is not finite): no share.
    Share {
        /// The `simple` variant's figure.
        simple: f64,
        /// The `oracle` variant's figure.
        oracle: f64,
    },
    /// A variant the report needs is not in the flight.
    NoVariant {
        /// Its name.
        name: &'static str,
    },
    /// A variant's flag shares could not be computed.
    Flags {
        /// The variant.
        variant: String,
        /// Why.
        source: accel::AccelError,
    },
}

impl fmt::Display for ReportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Share { simple, oracle } => {
                write!(f, "share undefined: simple {simple} and oracle {oracle} coincide")
            }
            Self::NoVariant { name } => write!(f, "no `{name}` variant"),
            Self::Flags { variant, .. } => write!(f, "variant {variant}"),
        }
    }
}

impl std::error::Error for ReportError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Flags { source, .. } => Some(source),
            Self::Share { .. } | Self::NoVariant { .. } => None,
        }
    }
}

/// `(simple − v)/(simple − oracle)`.
///
/// # Errors
/// A zero denominator (simple and oracle equal): the share cannot be computed.
pub fn share(simple: f64, v: f64, oracle: f64) -> Result<f64, ReportError> {
    let den = simple - oracle;
    crate::ensure(den.abs() > 1e-12 && v.is_finite(), ReportError::Share { simple, oracle })?;
    Ok((simple - v) / den)
}

/// Thermally induced CEP rate of each variant, nmile/h: the radial growth of its position
/// minus the oracle's (same sensor data), the same least-squares slope as `cep_nmi_per_h`.
///
/// # Errors
/// No `oracle` variant in the flight.
pub fn thermal_ceps(res: &FlightResult) -> Result<BTreeMap<String, f64>, ReportError> {
    let oi = res.names.iter().position(|n| n == "oracle").ok_or(ReportError::NoVariant { name: "oracle" })?;
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
pub fn flag_shares(res: &FlightResult) -> Result<BTreeMap<String, accel::FlagShares>, ReportError> {
    let mut m = BTreeMap::new();
    for (n, f) in res.names.iter().zip(&res.flags) {
        if let Some(f) = f {
            m.insert(n.clone(), f.shares().map_err(|e| ReportError::Flags { variant: n.clone(), source: e })?);
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
) -> Result<Report, ReportError> {
    let variants: BTreeMap<String, Figures> =
        res.names.iter().zip(&res.tracks).map(|(n, tr)| (n.clone(), Figures::of(&res.t, tr))).collect();
    let get = |n: &'static str| variants.get(n).copied().ok_or(ReportError::NoVariant { name: n });
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
        verdict: None,
        plots: Vec::new(),
    })
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
