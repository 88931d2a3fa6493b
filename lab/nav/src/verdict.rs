//! The navigation study's verdict ([`qfa_report::verdict::Verdict`]): what compensation did to
//! the navigation error, what the tables were calibrated on (the flight never is), the
//! figures to expect in use, and what looks alarming, in words. A study: no limit applies,
//! so the outcome is [`qfa_report::verdict::Outcome::Study`].

use super::flight_report::Report;
use super::mc::Summary;
use super::plan::Plan;
use qfa_report::verdict::{Covers, Expected, FileUse, Verdict};

/// The variant the verdict speaks for: the model `calibrate` writes into `table.bin`.
pub const FLOWN: &str = "hysteresis";

/// Below this flight length, h, the verdict says the thermal error had little time to
/// grow (the built-in flight is 2.33 h; the demo and the tests fly its first minutes).
const SHORT_FLIGHT_H: f64 = 1.0;

/// `removed 84 %`, or `added 12 %` for a negative share.
fn removed(share: f64) -> String {
    if !share.is_finite() {
        "removed an uncomputed share".to_string()
    } else if share >= 0.0 {
        format!("removed {:.0} %", 100.0 * share)
    } else {
        format!("added {:.0} %", -100.0 * share)
    }
}

/// A share as a signed percentage, or `not computed`.
fn percent(share: f64) -> String {
    if share.is_finite() {
        format!("{:.0} %", 100.0 * share)
    } else {
        "not computed".to_string()
    }
}

/// `1 run`, `20 runs`.
fn runs(n: u64) -> String {
    format!("{n} run{}", if n == 1 { "" } else { "s" })
}

/// A rate in nmile/h to three decimals, or `not computed`.
fn nmi(x: Option<f64>) -> String {
    x.filter(|v| v.is_finite()).map_or_else(|| "not computed".to_string(), |v| format!("{v:.3}"))
}

fn expected(axis: &str, what: &str, value: f64, unit: &str) -> Expected {
    Expected { axis: axis.to_string(), what: what.to_string(), value, unit: unit.to_string() }
}

/// What every unit's fit rows cover: the narrowest of the three (a flight beyond it is
/// clamped on at least one axis).
fn covers_of(r: &Report) -> Option<Covers> {
    let cs: Vec<&qfa_calibrate::coverage::Coverage> = r.meta.calibration.iter().map(|c| &c.coverage.covered).collect();
    if cs.is_empty() {
        return None;
    }
    let min_rate = |f: &dyn Fn(&qfa_calibrate::coverage::Coverage) -> Option<f64>| -> Option<f64> {
        cs.iter().map(|c| f(c)).collect::<Option<Vec<f64>>>().map(|v| v.into_iter().fold(f64::INFINITY, f64::min))
    };
    Some(Covers {
        temp_c: [
            cs.iter().map(|c| c.temp_c[0]).fold(f64::NEG_INFINITY, f64::max),
            cs.iter().map(|c| c.temp_c[1]).fold(f64::INFINITY, f64::min),
        ],
        heating_c_per_min: min_rate(&|c| c.heating.map(|b| b.max_abs_rate_c_per_min)),
        cooling_c_per_min: min_rate(&|c| c.cooling.map(|b| b.max_abs_rate_c_per_min)),
    })
}

/// The Monte Carlo clause of an answer: the median share removed and its spread.
fn mc_clause(s: &Summary) -> Option<String> {
    let share = s.thermal_share_removed.get(FLOWN)?;
    let th = |n: &str| s.thermal_cep_nmi_per_h.get(n).map(|x| x.median);
    Some(format!(
        "over {} of the Monte Carlo study (seed {}) {FLOWN} removed a median {:.0} % [p10 {:.0}, p90 {:.0}] of the \
         simple model's thermal error (thermal-only CEP median simple {} → {FLOWN} {} nmile/h)",
        runs(s.runs),
        s.seed,
        100.0 * share.median,
        100.0 * share.p10,
        100.0 * share.p90,
        nmi(th("simple")),
        nmi(th(FLOWN))
    ))
}

fn mc_expect(s: &Summary) -> Vec<Expected> {
    let mut e = Vec::new();
    if let Some(c) = s.cep_nmi_per_h.get(FLOWN) {
        let what = format!("Monte Carlo CEP rate ({})", runs(s.runs));
        e.push(expected(&format!("{FLOWN} median"), &what, c.median, "nmile/h"));
        e.push(expected(&format!("{FLOWN} p90"), &what, c.p90, "nmile/h"));
    }
    if let Some(x) = s.thermal_share_removed.get(FLOWN) {
        let what = format!("Monte Carlo thermal error removed, of the simple model's ({})", runs(s.runs));
        e.push(expected(&format!("{FLOWN} median"), &what, 100.0 * x.median, "%"));
        e.push(expected(&format!("{FLOWN} p10"), &what, 100.0 * x.p10, "%"));
    }
    e
}

fn mc_warnings(s: &Summary) -> Vec<String> {
    s.rate_clamped_share
        .iter()
        .filter(|(_, r)| r.median > super::accel::CLAMPED_WARN_SHARE)
        .map(|(n, r)| {
            format!(
                "{n}: rate clamped on a median {:.0} % of the flight's cycles over the Monte Carlo runs: the flights \
                 heat or cool faster than the lab program did, so the table's rate terms are held at their limit",
                100.0 * r.median
            )
        })
        .collect()
}

/// Why the flight plot can look alarming, in words (the page's caption and the verdict's
/// warnings say the same): empty when nothing does.
#[must_use]
pub fn alarms(r: &Report) -> Vec<String> {
    let mut w = Vec::new();
    let cep = |n: &str| r.get(n).map(|f| f.cep_nmi_per_h);
    let th = |n: &str| r.meta.thermal_cep_nmi_per_h.get(n).copied();
    if r.meta.duration_h < SHORT_FLIGHT_H {
        w.push(format!(
            "the flight is only {:.0} min: the thermal error has had little time to grow, so these figures are not a \
             full mission's",
            60.0 * r.meta.duration_h
        ));
    }
    if let (Some(hc), Some(sc), Some(ht), Some(st)) = (cep(FLOWN), cep("simple"), th(FLOWN), th("simple")) {
        if hc > sc && ht < st {
            w.push(format!(
                "{FLOWN}'s total CEP ({hc:.3} nmile/h) is above simple's ({sc:.3}) although its thermal-only error is \
                 lower ({ht:.3} against {st:.3}): one trajectory's total adds the gyro and alignment errors with the \
                 accelerometer error's sign; compare the thermal-only figures"
            ));
        }
    }
    if let Some(s) = r.meta.share_removed_thermal.get(FLOWN).filter(|s| **s < 0.0) {
        w.push(format!("{FLOWN} added {:.0} % to the simple model's thermal error on this flight", -100.0 * s));
    }
    w.extend(r.meta.clamped_warnings.iter().map(|x| x.trim_start_matches("WARNING: ").to_string()));
    w
}

/// The verdict of a `navigate` run: its nominal flight, the Monte Carlo study when it has
/// one, judged against `plan` (what the lab program covers against what the flight needs),
/// in a folder holding `files`.
#[must_use]
pub fn of_flight(r: &Report, plan: &Plan, files: Vec<FileUse>) -> Verdict {
    let m = &r.meta;
    let cep = |n: &str| r.get(n).map(|f| f.cep_nmi_per_h);
    let th = |n: &str| m.thermal_cep_nmi_per_h.get(n).copied();
    let share_simple = m.share_removed_thermal.get(FLOWN).copied().unwrap_or(f64::NAN);
    let share_none = match (th(FLOWN), th("none")) {
        (Some(h), Some(n)) if n > 0.0 => 1.0 - h / n,
        _ => f64::NAN,
    };
    let mut answer = format!(
        "{FLOWN} compensation {} of the thermal position error the simple model leaves ({} of what room-temperature \
         constants leave; thermal-only CEP none {} / simple {} / {FLOWN} {} nmile/h); total CEP none {} / simple {} / \
         {FLOWN} {} / oracle {} nmile/h over {:.2} h (paper, flight: simple 1.54 → hysteresis 1.29)",
        removed(share_simple),
        percent(share_none),
        nmi(th("none")),
        nmi(th("simple")),
        nmi(th(FLOWN)),
        nmi(cep("none")),
        nmi(cep("simple")),
        nmi(cep(FLOWN)),
        nmi(cep("oracle")),
        m.duration_h
    );
    if let Some(c) = r.monte_carlo.as_ref().and_then(mc_clause) {
        answer = format!("{answer}; {c}");
    }
    let c0 = m.calibration.first();
    let programs = c0.map_or_else(|| "no program recorded".to_string(), |c| c.flown_fit_programs.join(", "));
    let validation = match c0.map(|c| &c.validation) {
        Some(super::calib::Validation::Computed { fit_programs, held_out_programs, .. }) => format!(
            "; the {FLOWN} structure first validated fitted on {} and scored on {}",
            fit_programs.join(", "),
            held_out_programs.join(", ")
        ),
        _ => String::new(),
    };
    let mc = if r.monte_carlo.is_some() {
        "; each Monte Carlo run recalibrates its own units on their own lab log and flies its own flight"
    } else {
        ""
    };
    let held_out = format!(
        "tables fitted on the lab program `{}` ({programs}: each unit's simulated chamber log, every program in the \
         flown tables){validation}; scored on the flight `{}` ({:.2} h, case {:.1}…{:.1} °C), which no table saw{mc}; \
         discovered tables: {}",
        m.lab_program, m.scenario, m.duration_h, m.case_temp_range_c[0], m.case_temp_range_c[1], m.discovered_source
    );
    let mut v = Verdict::new(answer, held_out, Vec::new());
    if let Some(f) = r.get(FLOWN) {
        v.expect = vec![
            expected(FLOWN, "CEP rate (radial error growth, this flight)", f.cep_nmi_per_h, "nmile/h"),
            expected(&format!("{FLOWN} East"), "RMS velocity error", f.rms_ve_mps, "m/s"),
            expected(&format!("{FLOWN} North"), "RMS velocity error", f.rms_vn_mps, "m/s"),
        ];
        if share_simple.is_finite() {
            v.expect.push(expected(FLOWN, "thermal error removed, of the simple model's", 100.0 * share_simple, "%"));
        }
    }
    v.covers = covers_of(r);
    v.warnings = alarms(r);
    for s in &plan.shortfalls {
        v.warnings.push(format!("the lab program does not cover the flight: {s}; record it before flying the table"));
        v.advice.push(format!(
            "a lab program that reaches the flight ({s}): `qfa-lab plan` judges one; `--lab-program covering` \
             reaches the built-in flight"
        ));
    }
    if let Some(s) = &r.monte_carlo {
        for x in &plan.shortfalls_mc_extreme {
            v.warnings.push(format!("the lab program does not cover the Monte Carlo's hottest and fastest runs: {x}"));
        }
        v.warnings.extend(mc_warnings(s));
        v.expect.extend(mc_expect(s));
    }
    v.files = files;
    v
}

/// The verdict of `navigate merge`: the merged Monte Carlo study `s` and the nominal
/// run's `report.json` keys `nominal` (shard 0's), in a folder holding `files`.
#[must_use]
pub fn of_study(s: &Summary, nominal: &serde_json::Value, files: Vec<FileUse>) -> Verdict {
    let meta = &nominal["meta"];
    let text = |v: &serde_json::Value| v.as_str().unwrap_or("not recorded").to_string();
    let cep = |n: &str| s.cep_nmi_per_h.get(n).map(|x| x.median);
    let nominal_share = meta["share_removed_thermal"][FLOWN].as_f64().unwrap_or(f64::NAN);
    let answer = match mc_clause(s) {
        Some(c) => format!(
            "{c}; total CEP median none {} / simple {} / {FLOWN} {} / oracle {} nmile/h; on the nominal flight \
             (shard 0) it {}",
            nmi(cep("none")),
            nmi(cep("simple")),
            nmi(cep(FLOWN)),
            nmi(cep("oracle")),
            removed(nominal_share)
        ),
        None => format!("no {FLOWN} variant in the Monte Carlo runs: nothing to say what compensation did"),
    };
    let programs = meta["calibration"][0]["flown_fit_programs"]
        .as_array()
        .map(|a| a.iter().filter_map(|p| p.as_str()).collect::<Vec<_>>().join(", "))
        .unwrap_or_else(|| "no program recorded".to_string());
    let held_out = format!(
        "each run's tables fitted on its own simulated lab program `{}` ({programs}) and scored on its own flight `{}`, \
         which no table saw",
        text(&meta["lab_program"]),
        text(&meta["scenario"])
    );
    let mut v = Verdict::new(answer, held_out, Vec::new());
    v.expect = mc_expect(s);
    v.warnings = mc_warnings(s);
    v.files = files;
    v
}

/// The files `navigate` writes into its folder, with what to do with each.
#[must_use]
pub fn flight_files(plots: bool, runs: u64) -> Vec<FileUse> {
    let mut f: Vec<FileUse> =
        ["report.md", "report.html", "report.json", "nav_timeseries.csv"].into_iter().map(FileUse::of).collect();
    f.push(FileUse {
        file: "nav_table_{x,y,z}_{none,simple,hysteresis}.toml".into(),
        action: "keep: the tables each variant flew, as text (`calibrate` writes the table to flash)".into(),
    });
    if plots {
        f.push(FileUse::of("nav_errors.png"));
    }
    if runs > 0 {
        f.extend(study_files(plots).into_iter().filter(|x| !x.file.starts_with("report.")));
    }
    f
}

/// The files `navigate merge` writes into its folder.
#[must_use]
pub fn study_files(plots: bool) -> Vec<FileUse> {
    let mut names = vec!["report.md", "report.html", "report.json", "mc_runs.csv"];
    if plots {
        names.extend(["mc_cep.png", "mc_thermal_cep.png", "mc_thermal_share.png"]);
    }
    names.into_iter().map(FileUse::of).collect()
}

/// Said under every distribution plot: its x axis is fitted to the values drawn.
const NARROW_AXIS: &str = " The x axis spans only the values drawn: with few runs or a tight study a small \
                           spread fills the width, so read the axis numbers before the shape.";

/// The caption of plot `name` on a navigation page: what it shows, what to look for and,
/// where it looks alarming for a reason, why.
#[must_use]
pub fn caption(name: &str, alarms: &[String]) -> String {
    let why =
        if alarms.is_empty() { String::new() } else { format!(" Why it may look alarming: {}.", alarms.join("; ")) };
    match name {
        "nav_errors.png" => format!(
            "Top left the IMU temperatures; then each variant's radial position, East and North velocity and East and \
             North position errors against time. Look for: {FLOWN} and discovered hidden under the oracle's blue line \
             (drawn last), simple a little off it, none far off (room-temperature constants only: its error sets the \
             scale). The oscillation every variant shares (Schuler, 84 min) and the slow growth under it come from \
             the gyros and the alignment, not from temperature.{why}"
        ),
        "mc_thermal_share.png" => format!(
            "Fraction of the Monte Carlo runs (y) whose share of the simple model's thermal error removed is at most \
             x; a dot at each curve's median. Look for: curves far to the right (100 % is the oracle). none, simple \
             and the oracle are left out: their shares are set by construction (several hundred % negative, 0 % and \
             100 %).{NARROW_AXIS}"
        ),
        "mc_thermal_cep.png" => format!(
            "Fraction of the runs (y) whose thermal-only CEP rate (variant − oracle, same sensor data) is at most x. \
             Look for: hysteresis well left of simple. none (far right) and the oracle (0 by construction) are left \
             out.{NARROW_AXIS}"
        ),
        "mc_cep.png" => format!(
            "Fraction of the runs (y) whose total CEP rate is at most x, every variant. The curves overlap: the gyro \
             and non-thermal errors, the same for every variant, dominate the total; the thermal difference is in \
             mc_thermal_cep.png.{NARROW_AXIS}"
        ),
        _ => format!("navigation plot {name}"),
    }
}
