//! `qfa-lab plan`: the temperature and rate coverage a lab program must reach for a
//! mission, and whether a given lab program reaches it.
//!
//! Both sides go through the lab's thermal chain at 1 s with the exact case rate (the
//! lag equation's), the quantity the truth model and, after the estimator, the table see:
//! the mission's bay-air profile through the scenario's chain (from the ground
//! temperature, over the alignment and the flight), each lab program's chamber air
//! through the simulator's chain ([`ThermalChain::default`]). The mission's need is also
//! given at the Monte Carlo's largest excursion scale (`1 + temp_scale`), which is what a
//! table must cover for every run of the study.

use std::fmt;

use serde::Serialize;

use super::calib::LabProgram;
use super::scenario::Scenario;
use super::thermal::{Profile, ProfileError};
use qfa_calibrate::coverage::{Coverage, CoverageError};
use qfa_sim::profile::Program;
use qfa_sim::thermal::ThermalChain;

/// The coverage of a mission and of a lab program, and the verdict.
#[derive(Clone, Debug, Serialize)]
pub struct Plan {
    /// Scenario name.
    pub scenario: String,
    /// What the nominal mission spans at the case.
    pub mission: Coverage,
    /// What the mission spans at the Monte Carlo's largest excursion scale.
    pub mission_mc_extreme: Coverage,
    /// The lab program judged.
    pub lab_program: String,
    /// What the lab program spans at the case.
    pub lab: Coverage,
    /// Where the lab program falls short of the nominal mission (empty: it covers it).
    pub shortfalls: Vec<String>,
    /// Where it falls short of the Monte Carlo's extreme (empty: it covers it).
    pub shortfalls_mc_extreme: Vec<String>,
}

/// Why a mission's or a lab program's coverage could not be formed.
#[derive(Debug)]
#[non_exhaustive]
pub enum PlanError {
    /// The scenario's drive temperature profile.
    Profile(ProfileError),
    /// No sample to form a coverage from.
    Coverage(CoverageError),
}

impl fmt::Display for PlanError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Profile(e) => write!(f, "{e}"),
            Self::Coverage(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for PlanError {
    // Both are printed as they are (above): their causes come next.
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Profile(e) => e.source(),
            Self::Coverage(e) => e.source(),
        }
    }
}

impl From<ProfileError> for PlanError {
    fn from(e: ProfileError) -> Self {
        Self::Profile(e)
    }
}

impl From<CoverageError> for PlanError {
    fn from(e: CoverageError) -> Self {
        Self::Coverage(e)
    }
}

/// The case temperature and exact rate of `sc`'s mission at 1 s.
///
/// # Errors
/// A bad temperature profile, or no sample.
pub fn mission_coverage(sc: &Scenario) -> Result<Coverage, PlanError> {
    let profile = Profile::new(sc.temperature.clone())?;
    let ground = sc.ground_temp_c();
    let align_s = if sc.alignment.enabled { sc.alignment.duration_s } else { 0.0 };
    let start = if align_s > 0.0 { ground } else { profile.at(0.0) };
    let mut chain = sc.thermal.start(start, 1.0, sc.thermal.element_tau_s);
    let mut s = Vec::new();
    for _ in 0..align_s.round() as u64 {
        let t = chain.step(ground);
        s.push((t.case_c, t.case_rate_c_per_min));
    }
    for k in 1..=sc.duration_s().round() as u64 {
        let t = chain.step(profile.at(k as f64));
        s.push((t.case_c, t.case_rate_c_per_min));
    }
    Ok(Coverage::of_samples(s.into_iter(), f64::from(qfa_log::replay::branch_deadband_c_per_min()))?)
}

/// The case temperature and exact rate of `programs` through the simulator's chain.
///
/// # Errors
/// No sample.
pub fn program_coverage(programs: &[Program]) -> Result<Coverage, PlanError> {
    let mut s = Vec::new();
    for p in programs {
        let mut chain = ThermalChain::default().start(p.temp_at(0.0), 1.0, 180.0);
        for k in 1..=p.duration_s().round() as u64 {
            let t = chain.step(p.temp_at(k as f64));
            s.push((t.case_c, t.case_rate_c_per_min));
        }
    }
    Ok(Coverage::of_samples(s.into_iter(), f64::from(qfa_log::replay::branch_deadband_c_per_min()))?)
}

/// Judge `lab` against `sc`'s mission.
///
/// # Errors
/// As [`mission_coverage`] and [`program_coverage`].
pub fn plan(sc: &Scenario, lab: LabProgram) -> Result<Plan, PlanError> {
    let mission = mission_coverage(sc)?;
    let v = sc.monte_carlo;
    let extreme = sc.clone().with_temperature_variation(0.0, 1.0 + v.temp_scale);
    let mut mission_mc_extreme = mission_coverage(&extreme)?;
    // The offset shifts the whole profile: widen the temperature range by it both ways.
    mission_mc_extreme.temp_c =
        [mission_mc_extreme.temp_c[0] - v.temp_offset_c, mission_mc_extreme.temp_c[1] + v.temp_offset_c];
    let have = program_coverage(&lab.programs())?;
    Ok(Plan {
        scenario: sc.name.clone(),
        shortfalls: have.shortfalls(&mission),
        shortfalls_mc_extreme: have.shortfalls(&mission_mc_extreme),
        mission,
        mission_mc_extreme,
        lab_program: lab.name().to_string(),
        lab: have,
    })
}

fn line(name: &str, c: &Coverage) -> String {
    let b = |x: Option<qfa_calibrate::coverage::BranchRange>| {
        x.map_or("none".to_string(), |b| {
            format!("{:.2} °C/min over {:.1}…{:.1} °C", b.max_abs_rate_c_per_min, b.temp_c[0], b.temp_c[1])
        })
    };
    format!(
        "{name:<24} case {:.1}…{:.1} °C; heating up to {}; cooling up to {}",
        c.temp_c[0],
        c.temp_c[1],
        b(c.heating),
        b(c.cooling)
    )
}

/// The plan as text.
#[must_use]
pub fn text(p: &Plan) -> String {
    let mut s = format!("plan for `{}` (case temperature and exact case rate, 1 s)\n", p.scenario);
    s += &line("mission (nominal)", &p.mission);
    s.push('\n');
    s += &line("mission (MC extreme)", &p.mission_mc_extreme);
    s.push('\n');
    s += &line(&format!("lab program `{}`", p.lab_program), &p.lab);
    s.push('\n');
    for (what, sf) in [("nominal mission", &p.shortfalls), ("Monte Carlo extreme", &p.shortfalls_mc_extreme)] {
        if sf.is_empty() {
            s += &format!("covers the {what}: yes\n");
        } else {
            s += &format!("covers the {what}: NO: {}\n", sf.join("; "));
        }
    }
    s
}
