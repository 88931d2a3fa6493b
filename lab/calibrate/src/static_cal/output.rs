//! Static calibration's outputs: `report.md`, `table.toml`, the bias plot, `report.html`
//! and the per-axis export coefficients.

use std::path::Path;

use qfa_thermal::model::Branch;

use crate::static_cal::*;
use qfa_report::plot_png::{Area, Plot, PlotError};
use qfa_report::verdict::Verdict;

use crate::output_error::OutputError;

/// The report in Markdown: the scheme, the held-out table (mg, per axis) and the table's
/// own figures.
#[must_use]
pub fn markdown(r: &StaticReport) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    s.push_str("# Static calibration report\n\n");
    let h = &r.holdout;
    let _ = writeln!(s, "Held-out scheme: `{}` (asked: `{}`): {}.\n", h.scheme, h.requested, h.rule);
    let _ = writeln!(
        s,
        "Rows: {}, {:.1}..{:.1} °C ({} heating, {} cooling). Reader: {}.\n",
        r.rows, r.temp_c.0, r.temp_c.1, r.branch_rows.0, r.branch_rows.1, r.skipped
    );
    if !h.folds.is_empty() {
        s.push_str("| fold | held-out rows | held-out °C | training rows | training °C |\n|---|---|---|---|---|\n");
        for (f, x) in h.folds.iter().enumerate() {
            let _ = writeln!(
                s,
                "| {} | {}..={} | {:.1}..{:.1} | {} | {:.1}..{:.1} |",
                f + 1,
                x.heldout_rows.0,
                x.heldout_rows.1,
                x.heldout_temp_c.0,
                x.heldout_temp_c.1,
                x.train_rows,
                x.train_temp_c.0,
                x.train_temp_c.1
            );
        }
        s.push('\n');
    }
    let _ = writeln!(s, "Which rows each figure comes from: {}.\n", r.figures);
    let _ = writeln!(s, "Model choice: {}.\n", r.selection);
    if h.folds.is_empty() {
        let _ = writeln!(s, "Held-out bias RMS: not computed ({NO_HOLDOUT}).\n");
    } else {
        s.push_str("Held-out bias RMS, mg (rows / 60-s means):\n\n");
        s.push_str(
            "| axis | ours | PX4/tofupilot cubic | ArduPilot TCAL | paper simple (linear) | none | ours: the structure scored (table.bin's) |\n",
        );
        s.push_str("|---|---|---|---|---|---|---|\n");
        for a in &r.axes {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} |",
                a.axis,
                a.ours.cell(),
                a.cubic.cell(),
                a.ardupilot.cell(),
                a.simple.cell(),
                a.none.cell(),
                scored_structures(a)
            );
        }
        s.push('\n');
        if let Some(why) = r.ardupilot_choice() {
            let _ = writeln!(s, "{why}\n");
        }
    }
    let _ = writeln!(s, "Table (`table.bin`), fitted on all {} rows:\n", r.rows);
    s.push_str("| axis | structure | CV RMS, mg (its choice) | RMS on all rows, mg (in-sample) |\n|---|---|---|---|\n");
    for a in &r.axes {
        let _ = writeln!(s, "| {} | {} | {:.2} | {:.2} |", a.axis, a.structure, a.cv_rms_mg, a.table_rms_mg);
    }
    s
}

/// The text of `table.toml`: a comment line saying what the table was fitted on, then the
/// table as TOML.
///
/// # Errors
/// The table does not serialize.
pub fn static_table_toml(cal: &StaticCalibration) -> Result<String, toml::ser::Error> {
    let toml = toml::to_string_pretty(&cal.table)?;
    let header = format!(
        "# qfa-thermal coefficient table from a static log, fitted on all {} rows (per axis: bias K0 in g relative \
         to the axis's mean over all rows; scale factor 2^20 LSB/g, the pseudo-LSB `compensate` feeds the firmware's \
         sample path)\n",
        cal.report.rows
    );
    Ok(format!("{header}{toml}"))
}

/// The files [`write_static`] and [`write_static_page`] write, before the plot and the
/// exports.
pub(crate) const STATIC_FILES: [&str; 5] = ["table.bin", "table.toml", "report.json", "report.md", "report.html"];

/// The files a static calibration writes into its folder, in the verdict's order: the
/// table, the reports, the plot (with `plots`), then the exports written.
#[must_use]
pub fn static_files(plots: bool, exports: &[&str]) -> Vec<String> {
    let mut f: Vec<String> = STATIC_FILES.iter().map(|s| (*s).to_string()).collect();
    if plots {
        f.push(BIAS_PLOT.to_string());
    }
    f.extend(exports.iter().map(|s| (*s).to_string()));
    f
}

/// What a static calibration into a folder is asked for.
#[derive(Clone, Copy, Debug)]
pub struct StaticRun<'a> {
    /// Calibration settings.
    pub opts: &'a crate::static_cal::StaticCalOptions,
    /// Which PX4 / ArduPilot files to write, and how.
    pub exports: &'a crate::export::ExportOptions,
    /// The limits the verdict checks.
    pub limits: &'a qfa_report::verdict::LimitsChoice,
    /// Draw the plot.
    pub plots: bool,
    /// Show progress.
    pub progress: bool,
    /// What `report.html` names as its command (`None`: this process's command line).
    pub command: Option<&'a str>,
}

/// Calibrate a static log into `out`, as `qfa-lab calibrate` does for one and `qfa-lab
/// batch` for each unit: the table, the PX4 / ArduPilot files `run.exports` allows, the
/// verdict against `run.limits` (with `notes` in words: the lint's first lines),
/// `report.json`, `report.md` and `report.html` (with the plot when `run.plots`).
///
/// # Errors
/// A refused log or failed fit ([`calibrate_static`]), or an I/O error.
pub fn calibrate_static_into(
    out: &Path,
    log: &qfa_log::static_log::StaticLog,
    run: &StaticRun<'_>,
    notes: &[String],
) -> Result<(StaticCalibration, Verdict), StaticCalError> {
    let StaticRun { opts, exports, limits, plots, progress, command } = *run;
    let cal = crate::static_cal::calibrate_static(log, opts, progress)?;
    std::fs::create_dir_all(out).map_err(OutputError::io(out))?;
    crate::clear_outputs(out)?;
    write_static_table(out, &cal)?;
    let ex = crate::export::write_exports(out, &export_axes(&cal), exports)
        .map_err(|e| StaticCalError::Output(OutputError::io(out)(e)))?;
    let files = static_files(plots, &ex.written);
    let notes: Vec<String> = notes.iter().cloned().chain(ex.notes.iter().map(ToString::to_string)).collect();
    let v = crate::verdict::static_verdict(&cal, limits, &files, &notes);
    write_static(out, &cal, &v)?;
    write_static_page_as(out, &cal, plots, &v, command)?;
    Ok((cal, v))
}

/// Write `table.toml` and `table.bin` into `out`.
///
/// # Errors
/// I/O or encoding errors.
pub fn write_static_table(out: &Path, cal: &StaticCalibration) -> Result<(), StaticCalError> {
    let (toml_path, bin_path) = (out.join("table.toml"), out.join("table.bin"));
    std::fs::create_dir_all(out).map_err(OutputError::io(out))?;
    std::fs::write(&toml_path, static_table_toml(cal).map_err(OutputError::toml(out))?)
        .map_err(OutputError::io(&toml_path))?;
    std::fs::write(&bin_path, cal.table.to_bytes().map_err(OutputError::table(out))?)
        .map_err(OutputError::io(&bin_path))?;
    Ok(())
}

/// Write `table.toml`, `table.bin`, `report.json` and `report.md` into `out`, each report
/// opening with `verdict` (the PX4 / ArduPilot files:
/// [`crate::export::write_exports`] with [`export_axes`]).
///
/// # Errors
/// I/O or encoding errors.
pub fn write_static(out: &Path, cal: &StaticCalibration, verdict: &Verdict) -> Result<(), StaticCalError> {
    write_static_table(out, cal)?;
    let (json_path, md_path) = (out.join("report.json"), out.join("report.md"));
    let json = qfa_report::verdict::json_with_verdict(verdict, &cal.report).map_err(OutputError::json(&json_path))?;
    std::fs::write(&json_path, json).map_err(OutputError::io(&json_path))?;
    std::fs::write(&md_path, with_verdict(verdict, &markdown(&cal.report))).map_err(OutputError::io(&md_path))?;
    Ok(())
}

/// A Markdown report with the verdict after its title line.
#[must_use]
pub fn with_verdict(verdict: &Verdict, md: &str) -> String {
    match md.split_once('\n') {
        Some((title, rest)) if title.starts_with("# ") => {
            format!("{title}\n\n{}{}", verdict.markdown(), rest.trim_start())
        }
        _ => format!("{}{md}", verdict.markdown()),
    }
}

/// File name of the static calibration's plot.
pub const BIAS_PLOT: &str = "bias_vs_temp.png";

/// `bias_vs_temp.png`: per axis (a row), the bias against temperature before compensation
/// (the axis's mean removed) and after (see [`PlotRows::axes`]), mg; heating red, cooling
/// blue, hold grey; training rows as dots, held-out rows as crosses.
///
/// # Errors
/// Drawing or encoding errors.
pub(crate) fn plot_bias_vs_temp(title: &str, rows: &PlotRows) -> Result<Plot, PlotError> {
    let na = rows.axes.len().max(1);
    Plot::draw(BIAS_PLOT, (1400, 70 + 360 * na as u32), |root| draw_bias_vs_temp(root, title, rows))
}

fn draw_bias_vs_temp(root: &Area<'_>, title: &str, rows: &PlotRows) -> Result<(), qfa_report::plot_legend::DrawError> {
    use plotters::prelude::*;
    let na = rows.axes.len().max(1);
    root.fill(&WHITE)?;
    let (top, body) = root.split_vertically(70);
    let top = top.titled(title, ("sans-serif", 20))?;
    // One legend for every panel, above them: a legend inside a panel covers its data.
    let series =
        [("heating", RGBColor(200, 30, 30)), ("cooling", RGBColor(30, 60, 200)), ("hold", RGBColor(120, 120, 120))];
    let mut x = 160;
    for (name, c) in series {
        for held in [false, true] {
            let y = 15;
            if held {
                top.draw(&Cross::new((x, y), 5, c.stroke_width(2)))?;
            } else {
                top.draw(&Circle::new((x, y), 4, c.filled()))?;
            }
            let label = format!("{name}, {}", if held { "held out" } else { "training" });
            top.draw(&Text::new(label.clone(), (x + 12, y - 8), ("sans-serif", 15)))?;
            x += 40 + 8 * i32::try_from(label.chars().count()).unwrap_or(20);
        }
    }
    let panels = body.split_evenly((na, 2));
    let n = rows.temp_c.len();
    // Every row up to 6 000 per panel: a denser cloud draws the same picture.
    let step = n.div_ceil(6000).max(1);
    let (tlo, thi) = range(&rows.temp_c);
    for (a, (name, before, after)) in rows.axes.iter().enumerate() {
        for (k, (what, y)) in
            [("before compensation: a − mean", before), ("after: a − mean − model bias", after)].into_iter().enumerate()
        {
            let finite = y.iter().copied().filter(|v| v.is_finite());
            let lo = finite.clone().fold(f64::INFINITY, f64::min);
            let hi = finite.fold(f64::NEG_INFINITY, f64::max);
            if !(lo.is_finite() && hi.is_finite()) {
                continue;
            }
            let pad = ((hi - lo) * 0.05).max(1e-3);
            let mut chart = ChartBuilder::on(&panels[2 * a + k])
                .caption(format!("{name}, {what}"), ("sans-serif", 16))
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(65)
                .build_cartesian_2d((tlo - 1.0)..(thi + 1.0), (lo - pad)..(hi + pad))?;
            chart.configure_mesh().x_desc("temperature (°C, the log's sensor)").y_desc("bias (mg)").draw()?;
            for (branch, c) in [
                (Branch::Heating, RGBColor(200, 30, 30)),
                (Branch::Cooling, RGBColor(30, 60, 200)),
                (Branch::Unknown, RGBColor(120, 120, 120)),
            ] {
                for held in [false, true] {
                    let pts: Vec<(f64, f64)> = (0..n)
                        .step_by(step)
                        .filter(|&i| rows.branch[i] == branch && rows.heldout[i] == held && y[i].is_finite())
                        .map(|i| (rows.temp_c[i], y[i]))
                        .collect();
                    if pts.is_empty() {
                        continue;
                    }
                    if held {
                        chart.draw_series(pts.into_iter().map(|p| Cross::new(p, 3, c.mix(0.7))))?;
                    } else {
                        chart.draw_series(pts.into_iter().map(|p| Circle::new(p, 1, c.mix(0.5).filled())))?;
                    }
                }
            }
        }
    }
    Ok(())
}

/// Write `bias_vs_temp.png` (with `plots`) and `report.html` into `out`, the page opening
/// with `verdict` (which carries every warning in words).
///
/// # Errors
/// Drawing, encoding or I/O errors.
pub fn write_static_page(
    out: &Path,
    cal: &StaticCalibration,
    plots: bool,
    verdict: &Verdict,
) -> Result<(), StaticCalError> {
    write_static_page_as(out, cal, plots, verdict, None)
}

/// [`write_static_page`] opening with `command` instead of this process's command line.
///
/// # Errors
/// As [`write_static_page`].
pub(crate) fn write_static_page_as(
    out: &Path,
    cal: &StaticCalibration,
    plots: bool,
    verdict: &Verdict,
    command: Option<&str>,
) -> Result<(), StaticCalError> {
    let r = &cal.report;
    let plot = if plots {
        let title = format!("bias against temperature per axis; held-out scheme {}", r.holdout.scheme);
        let plot = plot_bias_vs_temp(&title, &cal.plot).map_err(OutputError::plot(&out.join(BIAS_PLOT)))?;
        plot.write_into(out).map_err(OutputError::io(&out.join(BIAS_PLOT)))?;
        Some(plot)
    } else {
        None
    };
    let mut p = match command {
        Some(c) => qfa_report::html_report::Page::with_command("Static calibration report", c),
        None => qfa_report::html_report::Page::new("Static calibration report"),
    };
    verdict.to_page(&mut p);
    scheme_section(&mut p, r);
    log_section(&mut p, r);
    coverage_section(&mut p, r);
    heldout_section(&mut p, r);
    table_section(&mut p, r);
    if let Some(plot) = &plot {
        p.section("Plots");
        p.plot(plot, &bias_plot_caption(verdict));
    }
    p.write(out).map_err(OutputError::io(out))?;
    Ok(())
}

/// The held-out scheme asked for and run, and its folds' rows and temperatures.
fn scheme_section(p: &mut qfa_report::html_report::Page, r: &StaticReport) {
    let h = &r.holdout;
    p.section("Held-out scheme").kv(&[
        ("asked (--holdout)", h.requested.clone()),
        ("ran", h.scheme.clone()),
        ("rule", h.rule.clone()),
        ("rows held out", format!("{} of {}", h.heldout_rows, r.rows)),
        ("which rows each figure comes from", r.figures.clone()),
        ("model choice", r.selection.clone()),
    ]);
    if !h.folds.is_empty() {
        let folds: Vec<Vec<String>> = h
            .folds
            .iter()
            .enumerate()
            .map(|(f, x)| {
                vec![
                    (f + 1).to_string(),
                    format!("{}..={}", x.heldout_rows.0, x.heldout_rows.1),
                    format!("{:.1}..{:.1}", x.heldout_temp_c.0, x.heldout_temp_c.1),
                    x.train_rows.to_string(),
                    format!("{} / {}", x.train_branch_rows.0, x.train_branch_rows.1),
                    format!("{:.1}..{:.1}", x.train_temp_c.0, x.train_temp_c.1),
                ]
            })
            .collect();
        p.table(&["fold", "held-out rows", "held-out °C", "training rows", "heating / cooling", "training °C"], &folds);
    }
}

/// The log as read: its columns, the rows kept, what the reader skipped, the sampling.
fn log_section(p: &mut qfa_report::html_report::Page, r: &StaticReport) {
    p.section("The log").kv(&[
        (
            "columns",
            r.columns
                .iter()
                .map(|(role, col, unit)| format!("{role} = `{col}` ({unit})"))
                .collect::<Vec<_>>()
                .join(", "),
        ),
        ("rows kept", r.rows.to_string()),
        ("reader", r.skipped.to_string()),
        ("sampling", r.sampling.to_string()),
    ]);
}

/// What the log covers against what the model needs, and what to record next.
fn coverage_section(p: &mut qfa_report::html_report::Page, r: &StaticReport) {
    p.section("What the log covers, against what the model needs");
    p.kv(&r.coverage.rows());
    p.para(&format!(
        "The model's bias grid needs the span cut into {} intervals with rows in each (checked before the fit); its \
         heating/cooling terms (branch step, two branches, sensor_lag, bias_creep) need both legs, each at least a \
         tenth of the rows on a leg; the held-out figure of the later leg (`after-max`) needs a leg after the \
         highest temperature.",
        StaticCalOptions::default().grid_points - 1
    ));
    if r.record_next.is_empty() {
        p.para("Nothing the model needs is missing from this log.");
    }
    for n in &r.record_next {
        p.warning(&format!("What to record next: {n}."));
    }
}

/// The held-out bias RMS of each axis under our model and its peers, and the held-out
/// rows clamped.
fn heldout_section(p: &mut qfa_report::html_report::Page, r: &StaticReport) {
    p.section("Held-out bias RMS, mg (rows / 60-s means)");
    if r.holdout.folds.is_empty() {
        p.warning(&format!("not computed ({NO_HOLDOUT})"));
    } else {
        let t: Vec<Vec<String>> = r
            .axes
            .iter()
            .map(|a| {
                vec![
                    a.axis.clone(),
                    a.ours.cell(),
                    a.cubic.cell(),
                    a.ardupilot.cell(),
                    a.simple.cell(),
                    a.none.cell(),
                    scored_structures(a),
                ]
            })
            .collect();
        p.table(
            &[
                "axis",
                "ours",
                "PX4/tofupilot cubic",
                "ArduPilot TCAL",
                "paper simple (linear)",
                "none",
                "ours: the structure scored (table.bin's)",
            ],
            &t,
        );
        if let Some(why) = r.ardupilot_choice() {
            p.para(&why);
        }
    }
    for a in &r.axes {
        if a.clamped_rows > 0 {
            p.warning(&format!(
                "{}: {} held-out rows clamped (T or Ṫ outside what the fold's training rows calibrated)",
                a.axis, a.clamped_rows
            ));
        }
    }
}

/// The table written: each axis's structure and its figures on all rows.
fn table_section(p: &mut qfa_report::html_report::Page, r: &StaticReport) {
    p.section(&format!("Table (table.bin), fitted on all {} rows", r.rows));
    let t: Vec<Vec<String>> = r
        .axes
        .iter()
        .map(|a| {
            vec![
                a.axis.clone(),
                a.column.clone(),
                a.structure.clone(),
                format!("{:.2}", a.cv_rms_mg),
                format!("{:.2}", a.table_rms_mg),
                a.refused_candidates.len().to_string(),
            ]
        })
        .collect();
    p.table(
        &[
            "axis",
            "column",
            "structure",
            "CV RMS, mg (its choice)",
            "RMS on all rows, mg (in-sample)",
            "candidates refused",
        ],
        &t,
    );
}

/// What to look for in `bias_vs_temp.png`, with the verdict's warnings about held-out
/// steps repeated where the step is drawn.
fn bias_plot_caption(verdict: &Verdict) -> String {
    let mut c = "Left, each axis before compensation: the gap between the red (heating) and blue (cooling) \
                 curves is the hysteresis the model must carry. Right, what is left after the model: held-out \
                 crosses (rows scored by a model that never saw them) should scatter about zero like the \
                 training dots; a band of crosses off zero is a held-out step, which the table will carry into use."
        .to_string();
    let steps: Vec<&str> =
        verdict.warnings.iter().filter(|w| w.contains("held-out rows sit")).map(String::as_str).collect();
    if !steps.is_empty() {
        c.push_str(" Here: ");
        c.push_str(&steps.join("; "));
        c.push('.');
    }
    c
}

/// The axes of a static calibration as PX4 / ArduPilot exports see them.
#[must_use]
pub fn export_axes(cal: &StaticCalibration) -> Vec<crate::export::ExportAxis> {
    cal.report
        .axes
        .iter()
        .zip(&cal.peers)
        .map(|(a, p)| crate::export::ExportAxis {
            axis: a.axis.clone(),
            source: a.column.clone(),
            cubic: p.cubic.clone(),
            ardupilot: p.ardupilot.clone(),
        })
        .collect()
}

/// The structures an axis's held-out figure of ours scores, each once (the table's, in
/// every fold).
fn scored_structures(a: &AxisReport) -> String {
    let mut seen: Vec<&str> = Vec::new();
    for s in &a.heldout_structures {
        if !seen.contains(&s.as_str()) {
            seen.push(s);
        }
    }
    seen.join(", ")
}
