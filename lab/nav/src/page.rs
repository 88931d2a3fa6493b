//! The `report.html` and `report.md` pages of `navigate` and of `navigate merge`, each
//! opening with its verdict ([`super::verdict`]).

use std::collections::BTreeMap;
use std::fmt::Write as _;

use super::*;
use qfa_report::plot_png::Plot;
use qfa_report::verdict::Verdict;

/// `navigate`'s `report.html` ([`qfa_report::html_report`]): the verdict, the figures per
/// variant, the warnings, what the lab program covers against what the flight needs
/// (`plan`), and every plot the run drew, each captioned with what to look for.
#[must_use]
pub fn page(r: &Report, plan: &plan::Plan, v: &Verdict) -> qfa_report::html_report::Page {
    let mut p = qfa_report::html_report::Page::new(&format!("Navigation report: {}", r.meta.scenario));
    v.to_page(&mut p);
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
                pct(&r.meta.share_removed_thermal),
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
            "thermal error removed, of simple's",
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
    p.pre(&plan::text(plan));
    for s in &plan.shortfalls {
        p.warning(&format!("the lab program does not cover the flight: {s}; record it before flying the table"));
    }
    p.section("Console summary").pre(&summary(r));
    if let Some(mc) = &r.monte_carlo {
        p.section("Monte Carlo").pre(&mc::table(mc));
    }
    p.section("Plots (the flight: held out from every fit)");
    let alarms = verdict::alarms(r);
    p.plots(&r.plots, |name| verdict::caption(name, &alarms));
    p
}

/// The rows of the figures table: variant, CEP, RMS vE and vN, thermal-only CEP and the
/// share of the simple model's thermal error removed.
fn figure_rows(r: &Report) -> Vec<Vec<String>> {
    VARIANTS
        .iter()
        .filter_map(|n| r.get(n).map(|f| (n, f)))
        .map(|(n, f)| {
            let m = &r.meta;
            vec![
                (*n).to_string(),
                format!("{:.3}", f.cep_nmi_per_h),
                format!("{:.3}", f.rms_ve_mps),
                format!("{:.3}", f.rms_vn_mps),
                format!("{:.4}", m.thermal_cep_nmi_per_h.get(*n).copied().unwrap_or(f64::NAN)),
                format!("{:.0} %", 100.0 * m.share_removed_thermal.get(*n).copied().unwrap_or(f64::NAN)),
            ]
        })
        .collect()
}

fn markdown_table(header: &[&str], rows: &[Vec<String>]) -> String {
    let mut s = format!("| {} |\n|{}\n", header.join(" | "), "---|".repeat(header.len()));
    for r in rows {
        let _ = writeln!(s, "| {} |", r.join(" | "));
    }
    s
}

/// `navigate`'s `report.md`: the title, the verdict, and the headline figures per variant
/// (the Monte Carlo table too, with `--runs`); the page has the rest.
#[must_use]
pub fn markdown(r: &Report, v: &Verdict) -> String {
    let mut s = format!("# Navigation report: {}\n\n{}## Figures per variant\n\n", r.meta.scenario, v.markdown());
    s += &markdown_table(
        &[
            "variant",
            "CEP, nmile/h",
            "RMS vE, m/s",
            "RMS vN, m/s",
            "thermal-only CEP, nmile/h",
            "thermal error removed, of simple's",
        ],
        &figure_rows(r),
    );
    if let Some(mc) = &r.monte_carlo {
        let _ = write!(s, "\n## Monte Carlo\n\n```text\n{}```\n", mc::table(mc));
    }
    s += "\nreport.html has the plots, what the lab program covers and the alignment; report.json every figure.\n";
    s
}

/// `navigate merge`'s `report.md`: the title, the verdict and the Monte Carlo table.
#[must_use]
pub fn merge_markdown(sum: &mc::Summary, v: &Verdict) -> String {
    format!(
        "# Navigation Monte Carlo study (merged shards)\n\n{}## Monte Carlo\n\n```text\n{}```\n",
        v.markdown(),
        mc::table(sum)
    )
}

/// `navigate merge`'s `report.html`: the verdict, the merged Monte Carlo table and every
/// plot the merge drew (the nominal run's figures are in `report.json`; its page is the one
/// shard 0's `navigate` run would write).
#[must_use]
pub fn merge_page(sum: &mc::Summary, v: &Verdict, plots: &[Plot]) -> qfa_report::html_report::Page {
    let mut p = qfa_report::html_report::Page::new("Navigation Monte Carlo study (merged shards)");
    v.to_page(&mut p);
    p.section("Held-out scheme").para(
        "Each run's tables are fitted on that run's own simulated lab program and scored on that run's own flight: \
         no flight row is fitted on.",
    );
    p.section("Monte Carlo").pre(&mc::table(sum));
    p.section("Plots");
    p.plots(plots, |name| verdict::caption(name, &[]));
    p
}
