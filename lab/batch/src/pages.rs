//! What a batch writes for people: a certificate per serial (`SERIAL/certificate.json`
//! and `certificate.html`) and the fleet page (`fleet.json`, `fleet.html`, with
//! `fleet_figures.png` and `fleet_held_out.png`).

use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;

use super::fleet::{Decision, Fleet, FleetUnit};
use super::unit::{UnitOutcome, UnitResult};
use super::BatchError;
use qfa_calibrate::output_error::OutputError;
use qfa_report::html_report::{escape, Page};
use qfa_report::plot_png::{Area, Plot, PlotError};
use qfa_report::verdict::Measured;

/// A unit's certificate: what was calibrated from what, the figures, the decision, and the
/// table's CRC so a table found on a unit leads back here.
#[derive(Clone, Debug, Serialize)]
pub(crate) struct Certificate<'a> {
    /// Serial.
    pub serial: &'a str,
    /// Decision.
    pub decision: Decision,
    /// Why (empty on PASS).
    pub reasons: &'a [String],
    /// Where the rows came from.
    pub source: &'a str,
    /// The unit's result (figures, model chosen, table CRC).
    pub unit: &'a UnitOutcome,
    /// Sensor offset against the fleet, °C.
    pub sensor_offset_c: &'a Measured,
    /// Sensor drift against the fleet, °C/h.
    pub sensor_drift_c_per_h: &'a Measured,
    /// Shape compared with the fleet (false: partial coverage).
    pub shape_compared: bool,
    /// Whether its rows cover the fleet's, and if not, why.
    pub coverage: &'a super::fleet::Coverage,
    /// The table to flash under this serial and its header's CRC-32 (`None`: not calibrated).
    pub flash: Option<(String, String)>,
    /// For a unit with partial coverage, the population prior's table.
    pub prior: &'a Option<super::prior::PriorUse>,
    /// Where the limits came from.
    pub limits_from: &'a str,
    /// The program that wrote it.
    pub written_by: String,
}

fn m(v: &Measured, digits: usize) -> String {
    match v {
        // No "-0.000": a figure that rounds to zero reads as zero.
        Measured::Value(x) if (x.abs() * 10f64.powi(digits as i32)).round() == 0.0 => format!("{:.digits$}", 0.0),
        Measured::Value(x) => format!("{x:.digits$}"),
        Measured::NotComputed { not_computed } => format!("not computed ({not_computed})"),
    }
}

/// Write `certificate.json` and `certificate.html` into `dir`.
///
/// # Errors
/// I/O or encoding errors.
pub(crate) fn write_certificate(
    dir: &Path,
    r: &UnitResult,
    f: &FleetUnit,
    limits_from: &str,
) -> Result<(), BatchError> {
    std::fs::create_dir_all(dir).map_err(OutputError::io(dir))?;
    let cert = certificate_of(r, f, limits_from);
    let json_path = dir.join("certificate.json");
    let json = serde_json::to_string_pretty(&cert).map_err(OutputError::json(&json_path))?;
    std::fs::write(&json_path, json + "\n").map_err(OutputError::io(&json_path))?;
    // A certificate reads the same however the batch was run (one process, shards, a
    // cluster): it names the batch, not the command line of the process that merged it.
    let mut p = Page::with_command(
        &format!("Certificate {}", r.serial),
        &format!("qfa-lab batch: certificate of unit {} (the batch's command is on fleet.html)", r.serial),
    );
    p.raw(&certificate_verdict_html(f));
    p.section("Certificate").kv(&certificate_rows(r, f, limits_from, &cert.flash));
    let mut files =
        vec![("table.bin", "table.bin"), ("report.html", "report.html"), ("certificate.json", "certificate.json")];
    if f.prior.is_some() {
        files.insert(0, ("table_prior.bin (flash this)", "table_prior.bin"));
    }
    p.section("Files").links(&files);
    let html = dir.join("certificate.html");
    std::fs::write(&html, p.html()).map_err(OutputError::io(&html))?;
    Ok(())
}

/// The certificate of unit `r` with its fleet decision `f`.
fn certificate_of<'a>(r: &'a UnitResult, f: &'a FleetUnit, limits_from: &'a str) -> Certificate<'a> {
    Certificate {
        serial: &r.serial,
        decision: f.decision,
        reasons: &f.reasons,
        source: &r.source,
        unit: &r.outcome,
        sensor_offset_c: &f.sensor_offset_c,
        sensor_drift_c_per_h: &f.sensor_drift_c_per_h,
        shape_compared: !f.partial,
        coverage: &f.coverage,
        flash: table_to_flash(r, f),
        prior: &f.prior,
        limits_from,
        written_by: format!("qfa-lab {}", env!("CARGO_PKG_VERSION")),
    }
}

/// The table to flash under unit `r`'s serial and its header's CRC-32, as every page
/// names it: the prior's table for a unit of partial coverage, else its own `table.bin`;
/// none for a unit that FAILs (its tables are held back) or was not calibrated.
fn table_to_flash(r: &UnitResult, f: &FleetUnit) -> Option<(String, String)> {
    if !f.flashable() {
        return None;
    }
    match (&r.outcome, &f.prior) {
        (_, Some(p)) => Some((p.table.clone(), p.table_crc32.clone())),
        (UnitOutcome::Calibrated(c), None) => Some(("table.bin".into(), c.table_crc32.clone())),
        (UnitOutcome::Failed { .. }, None) => None,
    }
}

/// The certificate page's verdict section: the decision in words and its reasons.
fn certificate_verdict_html(f: &FleetUnit) -> String {
    let class = match f.decision {
        Decision::Pass => "pass",
        Decision::Review => "warn",
        Decision::Fail => "fail",
    };
    let mut v = format!(
        "<section id=\"verdict\"><h2>Verdict</h2><ul><li class=\"{class}\">verdict: {} ({})</li>",
        f.decision,
        match f.decision {
            // A unit of partial coverage was compared with the fleet on its sensor alone.
            Decision::Pass if f.partial => {
                "every limit met held out, its sensor inside the population (partial coverage: its other figures not \
                 compared, below): flash the table named below under this serial"
            }
            Decision::Pass =>
                "every limit met held out, inside the population: flash the table named below under this serial",
            Decision::Review => "every limit met, but outside the population: a person looks before it ships",
            Decision::Fail => "held back: do not flash",
        }
    );
    for reason in &f.reasons {
        let _ = write!(v, "<li class=\"{class}\">{}</li>", escape(reason));
    }
    v.push_str("</ul></section>\n");
    v
}

/// The certificate's rows: the unit, the table to flash (`flash`), the prior, the unit's
/// own fit or why it failed, and its sensor against the fleet.
fn certificate_rows(
    r: &UnitResult,
    f: &FleetUnit,
    limits_from: &str,
    flash: &Option<(String, String)>,
) -> Vec<(String, String)> {
    let mut kv: Vec<(String, String)> = vec![
        ("serial".into(), r.serial.clone()),
        ("source".into(), r.source.clone()),
        ("limits".into(), limits_from.to_string()),
        (
            "coverage".into(),
            f.coverage.words().map_or_else(
                || "full: every figure compared with the fleet".to_string(),
                |why| format!("partial: {why}; compared with the fleet on its sensor only"),
            ),
        ),
    ];
    match flash {
        Some((file, crc)) => {
            kv.push(("table to flash".into(), format!("{file}, CRC-32 {crc} (its header's, what the firmware checks)")))
        }
        None if matches!(r.outcome, UnitOutcome::Calibrated(_)) => {
            kv.push(("table to flash".into(), "none: the unit FAILs, so its tables are held back".into()));
        }
        None => {}
    }
    if let Some(p) = &f.prior {
        kv.push((
            "population prior".into(),
            format!(
                "partial coverage: {} is the unit's rows and the fleet's population together; its own rows cover {:.0} % \
                 of the fleet's span × both branches{}",
                p.table,
                100.0 * p.covered_share,
                if p.mostly_prior { ", so the prior decided most of it" } else { "" }
            ),
        ));
        // The held-out figures below, and the limits the decision checked, are of the
        // unit's own fit: the prior's table is not held out (its gain is measured against
        // the simulator's truth in the lab's studies).
        kv.push((
            "held-out figures below".into(),
            format!(
                "of table.bin, the unit's own fit: {} has none of its own (the prior's gain is measured against a \
                 known truth in the lab guide's studies)",
                p.table
            ),
        ));
    }
    match &r.outcome {
        UnitOutcome::Calibrated(c) => {
            kv.push(("table.bin CRC-32 (the unit's own fit)".into(), c.table_crc32.clone()));
            kv.push(("table.bin bytes".into(), c.table_bytes.to_string()));
            kv.push(("rows".into(), c.rows.to_string()));
            kv.push(("temperature span".into(), format!("{:.1}..{:.1} °C", c.temp_c[0], c.temp_c[1])));
            kv.push(("branches".into(), if c.one_branch { "one (heating or cooling only)" } else { "both" }.into()));
            for (a, h) in &c.held_out_mg {
                kv.push((format!("{a}: held-out bias RMS (mg)"), m(h, 2)));
            }
            for (a, s) in &c.structures {
                kv.push((format!("{a}: model"), s.clone()));
            }
            if let Some(q) = &c.qfa {
                kv.push((
                    "held-out scale-factor sensitivity (Table 4, ppm/°C)".into(),
                    m(&q.held_out_sensitivity_ppm_per_c, 3),
                ));
                kv.push(("held-out bias residual (µg RMS)".into(), m(&q.held_out_bias_ug, 1)));
                kv.push(("scale factor γ at T0 (pulses/(g·s))".into(), format!("{:.1} at {:.1} °C", q.gamma, q.t0_c)));
                kv.push(("temperature coefficient μ/γ (ppm/°C)".into(), format!("{:.2}", q.mu_ppm_per_c)));
                kv.push((
                    "heating/cooling split of the scale factor at 0.5 °C/min (ppm)".into(),
                    format!("{:.1}", q.sf_split_ppm),
                ));
                kv.push((
                    "bias at T0 (µg); its slope (µg/°C)".into(),
                    format!("{:.1}; {:.2}", q.bias_level_ug, q.bias_slope_ug_per_c),
                ));
                kv.push(("bias ageing on the log's clock (µg/h)".into(), m(&q.ageing_ug_per_h, 3)));
            }
        }
        UnitOutcome::Failed { reason } => kv.push(("not calibrated".into(), reason.clone())),
    }
    if let Some(l) = f.lot {
        kv.push((
            "lot".into(),
            format!(
                "lot {} of the fleet's two (probability {:.3}); compared with {}",
                l.lot + 1,
                l.probability,
                if l.compared_within {
                    "its own lot's units".to_string()
                } else {
                    format!("the whole fleet (a lot under {} units)", super::fleet::MIN_FLEET)
                }
            ),
        ));
    }
    for w in &f.log_warnings {
        kv.push(("the log's checks warn".into(), w.clone()));
    }
    kv.push(("sensor offset against the fleet (°C)".into(), m(&f.sensor_offset_c, 2)));
    kv.push(("sensor drift against the fleet (°C/h)".into(), m(&f.sensor_drift_c_per_h, 3)));
    kv
}

/// Write `fleet.json`, `fleet.html` and its two plots into `out`.
///
/// # Errors
/// I/O, drawing or encoding errors.
pub(crate) fn write_fleet(
    out: &Path,
    fleet: &Fleet,
    results: &[UnitResult],
    limits_from: &str,
) -> Result<(), BatchError> {
    let json_path = out.join("fleet.json");
    let json = serde_json::to_string_pretty(fleet).map_err(OutputError::json(&json_path))?;
    std::fs::write(&json_path, json + "\n").map_err(OutputError::io(&json_path))?;
    let plots = replace_plots(out, fleet, results)?;
    let mut p = Page::new("Fleet");
    p.raw(&verdict_html(fleet, limits_from));
    capability_section(&mut p, fleet);
    figures_section(&mut p, fleet, &plots);
    lots_section(&mut p, fleet);
    prior_section(&mut p, fleet);
    units_section(&mut p, fleet, results);
    let html = out.join("fleet.html");
    std::fs::write(&html, p.html()).map_err(OutputError::io(&html))?;
    Ok(())
}

/// File names of the fleet's plots: [`plot_figures`]'s and [`plot_held_out`]'s.
const FLEET_PLOTS: [&str; 2] = ["fleet_figures.png", "fleet_held_out.png"];

/// Remove an older batch's plots from `out`, then draw this fleet's and write them; none
/// without a calibrated unit.
fn replace_plots(out: &Path, fleet: &Fleet, results: &[UnitResult]) -> Result<Vec<Plot>, BatchError> {
    // Without a calibrated unit there is nothing to draw: the plots are not written (an
    // old batch's plots in the folder are removed, so none is taken for this one's).
    for name in FLEET_PLOTS {
        let path = out.join(name);
        qfa_log::io_fault::remove_if_present(&path).map_err(OutputError::io(&path))?;
    }
    if fleet.stats.is_empty() {
        return Ok(Vec::new());
    }
    let (figures, held_out) = (out.join(FLEET_PLOTS[0]), out.join(FLEET_PLOTS[1]));
    let plots = vec![
        plot_figures(fleet).map_err(OutputError::plot(&figures))?,
        plot_held_out(fleet, results).map_err(OutputError::plot(&held_out))?,
    ];
    qfa_report::plot_png::write_all(&plots, out).map_err(OutputError::io(out))?;
    Ok(plots)
}

/// The page's verdict section: the counts, then each group of units held back with its
/// reasons, then where the limits came from.
fn verdict_html(fleet: &Fleet, limits_from: &str) -> String {
    let [pass, review, fail] = fleet.counts;
    let class = if fail > 0 {
        "fail"
    } else if review > 0 {
        "warn"
    } else {
        "pass"
    };
    let mut v = format!(
        "<section id=\"verdict\"><h2>Verdict</h2><ul><li class=\"{class}\">verdict: {} units: {pass} PASS, \
         {review} REVIEW (limits met, outside the population), {fail} FAIL</li>",
        fleet.units
    );
    if let Some(why) = fleet.not_compared() {
        let _ = write!(v, "<li class=\"warn\">fleet: {}</li>", escape(&why));
    }
    for (decision, reasons, serials) in super::grouped(fleet) {
        let c = if decision == Decision::Fail { "fail" } else { "warn" };
        let links: Vec<String> =
            serials.iter().map(|s| format!("<a href=\"{s}/certificate.html\">{s}</a>", s = escape(s))).collect();
        let who =
            if links.len() == 1 { links[0].clone() } else { format!("{} units: {}", links.len(), links.join(", ")) };
        let _ = write!(v, "<li class=\"{c}\">{who} {decision}: {}</li>", escape(&reasons));
    }
    let _ = writeln!(v, "<li>limits: {}</li></ul></section>", escape(limits_from));
    v
}

/// Cpk of the fleet against each limit.
fn capability_section(p: &mut Page, fleet: &Fleet) {
    p.section("Capability against each limit").para(
        "Cpk = (limit − mean) / 3s for a maximum, (mean − limit) / 3s for a minimum, s the batch's standard deviation \
         (Ppk in AIAG terms: one batch, no subgroups). Every limit is one-sided, so Cp is not computed.",
    );
    let rows: Vec<Vec<String>> = fleet
        .capability
        .iter()
        .map(|c| {
            vec![
                c.limit.clone(),
                c.axis.clone(),
                format!("{} {}", c.sense, c.bound),
                c.n.to_string(),
                m(&c.mean, 3),
                m(&c.sd, 3),
                m(&c.cpk, 2),
            ]
        })
        .collect();
    p.table(&["limit", "axis", "bound", "units", "mean", "s", "Cpk"], &rows);
}

/// Each figure's spread across the fleet: the plots (or why there are none) and the
/// robust statistics.
fn figures_section(p: &mut Page, fleet: &Fleet, plots: &[Plot]) {
    p.section("Figures across the fleet").para(&format!(
        "Robust distance z = (x − median) / ({:.4}·MAD) over the units with full coverage (over its own lot's, when \
         the fleet holds two lots: below); a unit is flagged beyond ±{} (held-out RMS: above only). Red: flagged.{}",
        qfa_log::robust::MAD_TO_SD,
        fleet.z_flag,
        if fleet.compared {
            ""
        } else {
            " This fleet is too small to flag a unit (the verdict says why): the distances below are shown, not judged."
        }
    ));
    if plots.is_empty() {
        p.warning("No unit was calibrated, so no figure can be compared: the verdict above says why.");
    } else {
        p.plots(plots, |file| {
            if file == FLEET_PLOTS[0] {
                "each figure's robust distance, one dot per unit"
            } else {
                "held-out bias RMS per axis against its limit"
            }
            .to_string()
        });
    }
    let rows: Vec<Vec<String>> = fleet
        .stats
        .iter()
        .map(|s| {
            vec![
                s.feature.name.clone(),
                s.feature.unit.clone(),
                s.n.to_string(),
                s.yardstick_n.to_string(),
                format!("{:.4}", s.median),
                format!("{:.4}", s.scale),
            ]
        })
        .collect();
    p.table(&["figure", "unit", "units", "of them in the yardstick", "median", "robust SD"], &rows);
}

/// Two lots, what tells them apart and which units are in each; or why the fleet is one.
fn lots_section(p: &mut Page, fleet: &Fleet) {
    use super::lots::{BIC_MARGIN, MIN_LOT};
    p.section("Lots");
    let Some(lots) = &fleet.lots else {
        p.para(&if fleet.reference_units < 2 * MIN_LOT {
            format!(
                "Not looked for: two lots need {MIN_LOT} units of full coverage each, and this fleet has {}.",
                fleet.reference_units
            )
        } else {
            format!(
                "One lot: no split of the units of full coverage into two lots of at least {MIN_LOT} units, shifted \
                 together on the figures of the units' curves and sensors, is preferred to one lot by more than \
                 {BIC_MARGIN} (Bayesian information criterion)."
            )
        });
        return;
    };
    p.para(&format!(
        "The units of full coverage form two lots ({} and {} units; two lots preferred to one by {:.0}, Bayesian \
         information criterion): {} What tells them apart, the most first (the difference of the lots' means in \
         their shared SD):",
        lots.sizes[0],
        lots.sizes[1],
        lots.bic_preference,
        if lots.compared_within {
            "each unit is compared with its own lot's median and robust SD, not flagged for the lot it is in."
                .to_string()
        } else {
            format!(
                "a lot of fewer than {} units is too unsteady a yardstick, so each unit is compared with the whole \
                 fleet: a flag on a figure that tells the lots apart may be the unit's lot, not the unit.",
                super::fleet::MIN_FLEET
            )
        }
    ));
    let rows: Vec<Vec<String>> = lots
        .figures
        .iter()
        .take(6)
        .map(|f| {
            vec![
                f.name.clone(),
                f.unit.clone(),
                format!("{:.4}", f.mean[0]),
                format!("{:.4}", f.mean[1]),
                format!("{:+.1}", f.separation_sd),
            ]
        })
        .collect();
    p.table(&["figure", "unit", "lot 1 mean", "lot 2 mean", "lot 2 − lot 1 (SD)"], &rows);
    let in_lot = |k: usize| -> String {
        let s: Vec<String> =
            fleet.unit.iter().filter(|u| u.lot.is_some_and(|l| l.lot == k)).map(|u| u.serial.clone()).collect();
        s.join(", ")
    };
    p.para(&format!("Lot 1: {}.", in_lot(0))).para(&format!("Lot 2: {}.", in_lot(1)));
}

/// The units with partial coverage and the population prior's table each gets.
fn prior_section(p: &mut Page, fleet: &Fleet) {
    let partial: Vec<Vec<String>> = fleet
        .unit
        .iter()
        .filter_map(|u| {
            u.prior.as_ref().map(|p| {
                vec![
                    u.serial.clone(),
                    if u.flashable() {
                        format!("{} {}", p.table, p.table_crc32)
                    } else {
                        format!("none: held back, the unit FAILs ({} {})", p.table, p.table_crc32)
                    },
                    format!("{:.0} %", 100.0 * p.covered_share),
                    if p.mostly_prior { "the prior" } else { "its rows" }.to_string(),
                ]
            })
        })
        .collect();
    if fleet.population.is_empty() && partial.is_empty() {
        p.section("Population prior")
            .para("No population prior: it is formed from the units with full coverage, and this batch has none.");
        return;
    }
    p.section("Population prior").para(&format!(
        "Units with partial coverage (one branch, under 0.8 of the fleet's median span, or a QFA log without a program \
         most units ran) get a table from their rows \
         and the population together (empirical Bayes over the units with full coverage: {}), over the fleet's span \
         {:.1}..{:.1} °C. Under half the span × both branches covered, the prior decided most of it.",
        fleet.population.iter().map(|p| format!("{} from {} units", p.axis, p.units)).collect::<Vec<_>>().join(", "),
        fleet.span_c[0],
        fleet.span_c[1]
    ));
    if partial.is_empty() {
        p.para("No unit has partial coverage.");
    } else {
        p.table(&["serial", "table to flash, CRC-32", "own rows cover", "decided mostly by"], &partial);
    }
}

/// Every unit's decision, table to flash and reasons, with links to the certificates.
fn units_section(p: &mut Page, fleet: &Fleet, results: &[UnitResult]) {
    p.section("Units");
    let rows: Vec<Vec<String>> = fleet
        .unit
        .iter()
        .zip(results)
        .map(|(u, r)| {
            let crc = match table_to_flash(r, u) {
                Some((table, crc)) => format!("{table} {crc}"),
                None if matches!(r.outcome, UnitOutcome::Calibrated(_)) => "none: held back".into(),
                None => "—".into(),
            };
            vec![u.serial.clone(), u.decision.to_string(), crc, u.reasons.join("; ")]
        })
        .collect();
    p.table(&["serial", "decision", "table to flash, CRC-32", "why"], &rows);
    let links: Vec<(String, String)> =
        fleet.unit.iter().map(|u| (u.serial.clone(), format!("{}/certificate.html", u.serial))).collect();
    p.links(&links);
}

fn plot_figures(fleet: &Fleet) -> Result<Plot, PlotError> {
    let rows = fleet.stats.len().max(1);
    Plot::draw(FLEET_PLOTS[0], (1200, 80 + 26 * rows as u32), |root| draw_figures(root, fleet))
}

fn draw_figures(root: &Area<'_>, fleet: &Fleet) -> Result<(), qfa_report::plot_legend::DrawError> {
    use plotters::prelude::*;
    let rows = fleet.stats.len().max(1);
    root.fill(&WHITE)?;
    let lim = 3.0 * fleet.z_flag;
    let mut chart = ChartBuilder::on(root)
        .caption(
            "Each figure against the fleet, or its unit's lot (robust SDs; clipped at ±3× the flag line)",
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(230)
        .build_cartesian_2d(-lim..lim, (0..rows).into_segmented())?;
    let names: Vec<String> = fleet.stats.iter().map(|s| s.feature.name.clone()).collect();
    chart
        .configure_mesh()
        .x_desc("robust distance z")
        .y_labels(rows)
        .y_label_formatter(&|y| match y {
            SegmentValue::CenterOf(k) => names.get(*k).cloned().unwrap_or_default(),
            _ => String::new(),
        })
        .disable_y_mesh()
        .draw()?;
    for x in [-fleet.z_flag, fleet.z_flag] {
        chart.draw_series(LineSeries::new(
            [(x, SegmentValue::Exact(0)), (x, SegmentValue::Exact(rows))],
            RED.mix(0.5),
        ))?;
    }
    for (k, s) in fleet.stats.iter().enumerate() {
        for (serial, v) in &s.values {
            let z = s.distance(*v, fleet.lot_of(serial)).clamp(-lim, lim);
            let flagged =
                fleet.unit.iter().any(|u| &u.serial == serial && u.flags.iter().any(|f| f.feature == s.feature.name));
            let y = SegmentValue::CenterOf(k);
            if flagged {
                chart.draw_series([Circle::new((z, y), 5, RED.filled())])?;
            } else {
                chart.draw_series([Circle::new((z, y), 3, BLUE.mix(0.4).filled())])?;
            }
        }
    }
    Ok(())
}

/// The capability rows [`plot_held_out`] draws: a static unit's held-out bias per axis in
/// mg, a QFA unit's in µg (each row says its unit).
fn held_out_rows(fleet: &Fleet) -> Vec<&crate::fleet::Capability> {
    fleet.capability.iter().filter(|c| c.limit == "held_out_bias_mg" || c.limit == "held_out_bias_ug").collect()
}

fn plot_held_out(fleet: &Fleet, results: &[UnitResult]) -> Result<Plot, PlotError> {
    let rows = held_out_rows(fleet).len().max(1);
    Plot::draw(FLEET_PLOTS[1], (1200, 120 + 60 * rows as u32), |root| draw_held_out(root, fleet, results))
}

fn draw_held_out(
    root: &Area<'_>,
    fleet: &Fleet,
    results: &[UnitResult],
) -> Result<(), qfa_report::plot_legend::DrawError> {
    use plotters::prelude::*;
    let caps = held_out_rows(fleet);
    root.fill(&WHITE)?;
    let mut hi: f64 = 0.0;
    let mut pts: Vec<(usize, f64, bool)> = Vec::new();
    for (k, c) in caps.iter().enumerate() {
        hi = hi.max(c.bound);
        for (r, u) in results.iter().zip(&fleet.unit) {
            if let UnitOutcome::Calibrated(cal) = &r.outcome {
                let qfa = cal.qfa.as_ref().map(|q| &q.held_out_bias_ug);
                let v = match (qfa, cal.held_out_mg.iter().find(|(a, _)| *a == c.axis)) {
                    (Some(Measured::Value(v)), _) if c.limit == "held_out_bias_ug" => Some(*v),
                    (None, Some((_, Measured::Value(v)))) if c.limit == "held_out_bias_mg" => Some(*v),
                    _ => None,
                };
                if let Some(v) = v {
                    hi = hi.max(v);
                    pts.push((k, v, u.decision != Decision::Pass));
                }
            }
        }
    }
    let mut chart = ChartBuilder::on(root)
        .caption(
            "Held-out bias RMS per unit, with the limit (red line); red dots: units not passed",
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..hi * 1.1, (0..caps.len().max(1)).into_segmented())?;
    let names: Vec<String> = caps
        .iter()
        .map(|c| format!("{} ({})", c.axis, if c.limit == "held_out_bias_ug" { "µg" } else { "mg" }))
        .collect();
    chart
        .configure_mesh()
        .x_desc("held-out bias RMS (each row's unit)")
        .y_labels(caps.len().max(1))
        .y_label_formatter(&|y| match y {
            SegmentValue::CenterOf(k) => names.get(*k).cloned().unwrap_or_default(),
            _ => String::new(),
        })
        .disable_y_mesh()
        .draw()?;
    for (k, c) in caps.iter().enumerate() {
        chart.draw_series(LineSeries::new(
            [(c.bound, SegmentValue::Exact(k)), (c.bound, SegmentValue::Exact(k + 1))],
            RED.stroke_width(2),
        ))?;
    }
    for (k, v, bad) in pts {
        let y = SegmentValue::CenterOf(k);
        if bad {
            chart.draw_series([Circle::new((v, y), 5, RED.filled())])?;
        } else {
            chart.draw_series([Circle::new((v, y), 3, BLUE.mix(0.4).filled())])?;
        }
    }
    Ok(())
}
