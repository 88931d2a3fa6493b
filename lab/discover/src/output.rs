//! Outputs: `report.json`, `report.md`, `table.bin` (root-crate `Table`, 1 axis, rate
//! window 32, new slots on: what `qfa-lab compensate --table DIR/table.bin` loads, so
//! "discover, then compensate" is the workflow), the same bytes as `model.bin` (older
//! name), `model.toml`, `residuals.csv` and residual plots (PNG).
//!
//! The per-axis directories of a static log's discovery ([`super::static_axes`]) get no
//! `table.bin`/`model.bin`: their model is the named one in the axis's own units (K1 = 1,
//! `bias_drift` without a slot), and `compensate` takes a table of all the log's axes, the
//! one in the parent directory. Their `model.toml` is for reading and says so.
//!
//! Every `report.md`, `report.json` and `report.html` opens with the run's verdict
//! ([`super::verdict`]), the same lines in each.

use std::fmt::Write as _;
use std::path::Path;

use plotters::prelude::*;
use qfa_thermal::table::{Input, Table};
use serde::Serialize;

use super::static_axes::{AxisDiscovery, StaticDiscovery};
use super::{BiasUnit, Channels, DiscoverError, Gaps, LogKind, Report, Result};
use markdown::markdown;
use qfa_calibrate::metrics::rms_of_finite;
use qfa_report::plot_png::{Plot, PlotError};
use qfa_report::verdict::{json_with_verdict, Verdict};

mod markdown;

/// The named model's held-out gap is above the start model's on some channel.
#[must_use]
pub(crate) fn worse(r: &Report) -> bool {
    match (&r.heldout_gap_before, &r.heldout_gap_after) {
        (Gaps::Cycling { scale_factor_ppm: s0, bias_ug: b0 }, Gaps::Cycling { scale_factor_ppm: s1, bias_ug: b1 }) => {
            s1 > s0 || b1 > b0
        }
        (Gaps::Single { value_rms: a }, Gaps::Single { value_rms: b }) => b > a,
        _ => false,
    }
}

/// A report's gaps in words with their units.
#[must_use]
/// The flashed model's held-out figure in words, or why it has none.
pub(crate) fn flashed_text(unit: BiasUnit, f: &super::Flashed) -> String {
    f.heldout.as_ref().map_or_else(|| f.not_computed.clone().unwrap_or_default(), |g| gaps_text(unit, g))
}

pub(crate) fn gaps_text(unit: BiasUnit, g: &Gaps) -> String {
    match g {
        Gaps::Cycling { scale_factor_ppm, bias_ug } => {
            format!("scale factor {scale_factor_ppm:.2} ppm, bias {bias_ug:.2} µg")
        }
        Gaps::Single { value_rms } => format!("value {value_rms:.4} {}", unit.label()),
    }
}

/// The root-crate table of the report's final model, for `input`: pulse counts for a
/// cycling log's scale-factor model, samples for a single-output log.
#[must_use]
pub(crate) fn table(report: &Report, input: Input) -> Option<Table> {
    // Not validated here: a single-channel log's model is in the log's own units (often
    // µg), which the root crate refuses as a table. `model.toml` is written either way;
    // `write` validates before `table.bin` and says why when it cannot.
    let mut t = Table {
        input,
        rate_window: qfa_log::replay::RATE_WINDOW as u16,
        axes: Default::default(),
        misalignment: None,
        part_lsb_per_g: None,
    };
    t.axes.push(report.model.clone()?).ok()?;
    Some(t)
}

/// Which run a discovery's outputs belong to.
#[derive(Clone, Copy)]
pub(crate) enum Scope<'a> {
    /// A discovery of its own log (cycling or single-channel): its folds give the held-out
    /// figures, and its `table.bin` is flashable.
    Own,
    /// One axis of a static log ([`super::static_axes`]): the held-out figures are the
    /// log's scheme's (in the axis's record), discovery's own folds only chose what to name
    /// (their figures are called selection-fold figures), and the table to flash is the
    /// parent folder's, so this folder gets no `table.bin`/`model.bin`.
    StaticAxis {
        /// The whole static discovery.
        discovery: &'a StaticDiscovery,
        /// This axis.
        axis: &'a AxisDiscovery,
    },
}

impl Scope<'_> {
    /// What this run's reports call the figures of discovery's own folds.
    #[must_use]
    pub(crate) fn folds_word(self) -> String {
        self.relabel("held-out")
    }

    /// [`Scope::folds_word`] opening a sentence.
    #[must_use]
    pub(crate) fn folds_word_capital(self) -> String {
        self.relabel("Held-out")
    }

    /// The folds this run's own figures come from, by name.
    #[must_use]
    pub(crate) fn folds_name(self) -> &'static str {
        match self {
            Self::Own => "held-out folds",
            Self::StaticAxis { .. } => "selection folds",
        }
    }

    /// A sentence written for a discovery of its own log (the selection rule, the folds'
    /// rule), in this run's words: on a static axis "held-out" there means selection-fold.
    #[must_use]
    pub(crate) fn relabel(self, text: &str) -> String {
        match self {
            Self::Own => text.to_string(),
            Self::StaticAxis { .. } => text.replace("held-out", "selection-fold").replace("Held-out", "Selection-fold"),
        }
    }

    /// What this run's reports call the model its own search added effects to: the named
    /// model of a single-channel log's discovery; the block test's own model on a static
    /// axis or a cycling log with a table (the named model there is calibration's,
    /// `table.bin`).
    #[must_use]
    pub(crate) fn model_name(self, r: &Report) -> &'static str {
        match self {
            Self::Own if r.table.is_none() => "named model",
            _ => "block test's model",
        }
    }

    /// Whether this folder gets a `table.bin` of its own.
    #[must_use]
    pub(crate) fn flashable(self) -> bool {
        matches!(self, Self::Own)
    }
}

/// Write every output into `dir` and return the verdict they open with, and the plots drawn
/// (written, and inlined in the page from these bytes). A static axis
/// ([`Scope::StaticAxis`]) gets no `table.bin`/`model.bin` (see the module docs), and older
/// ones there are removed.
///
/// # Errors
/// A file could not be written ([`DiscoverError`]).
pub(crate) fn write(
    ch: &Channels,
    report: &Report,
    flashed: Option<&Table>,
    dir: &Path,
    scope: Scope<'_>,
) -> Result<(Verdict, Vec<Plot>)> {
    std::fs::create_dir_all(dir).map_err(|source| DiscoverError::CreateDir { path: dir.into(), source })?;
    let mut tables: Vec<String> = Vec::new();
    let mut rest: Vec<String> = Vec::new();
    let mut notes: Vec<String> = Vec::new();
    let input = match ch.kind {
        LogKind::Cycling => Input::PulseCounts,
        LogKind::Single => Input::Samples,
    };
    if !scope.flashable() {
        for f in ["table.bin", "model.bin"] {
            remove_stale(&dir.join(f))?;
        }
    }
    // A cycling log's table is calibrate's ([`super::cycling_table`]); else the catalog's model.
    let table = || flashed.cloned().or_else(|| table(report, input));
    if let Some(t) = table().filter(|_| scope.flashable()) {
        match t.to_bytes() {
            Ok(b) => {
                write_file(&dir.join("table.bin"), &b)?;
                write_file(&dir.join("model.bin"), &b)?;
                tables.extend(["table.bin".to_string(), "model.bin".to_string()]);
            }
            Err(e) => notes.push(format!("the table did not validate ({e:?}), so no table.bin was written")),
        }
    }
    if let Some(t) = table() {
        let path = dir.join("model.toml");
        write_file(&path, toml::to_string(&t).map_err(|source| DiscoverError::Toml { path: path.clone(), source })?)?;
        tables.push("model.toml".to_string());
    }
    write_csv(ch, report, &dir.join("residuals.csv"))?;
    rest.push("residuals.csv".to_string());
    let mut drawn = match plots(ch, report, scope) {
        Ok(drawn) => drawn,
        Err(e) => {
            notes.push(format!("plots failed: {e:#}"));
            Vec::new()
        }
    };
    for plot in &drawn {
        write_file(&dir.join(&plot.file), plot.png())?;
        rest.push(plot.file.clone());
    }
    // The page shows them by file name.
    drawn.sort_unstable_by(|a, b| a.file.cmp(&b.file));
    let files: Vec<String> =
        tables.into_iter().chain(["report.json", "report.md", "report.html"].map(String::from)).chain(rest).collect();
    let v = match scope {
        Scope::Own => super::verdict::discovery_verdict(ch, report, &files, &notes),
        Scope::StaticAxis { discovery, axis } => {
            let mut v = super::verdict::axis_verdict(discovery, axis, ch);
            v.warnings.extend(notes);
            v.files = super::verdict::axis_files(&files);
            v
        }
    };
    write_json(&dir.join("report.json"), &v, report)?;
    write_file(&dir.join("report.md"), markdown(ch, report, scope, &v))?;
    super::page::page(ch, report, scope, &v, &drawn).write(dir).map_err(DiscoverError::Page)?;
    Ok((v, drawn))
}

/// Remove an older output at `path`, if there is one.
fn remove_stale(path: &Path) -> Result<()> {
    qfa_log::io_fault::remove_if_present(path).map_err(|source| DiscoverError::Io { path: path.to_path_buf(), source })
}

/// Write `bytes` to `path`; the error names the file.
pub(super) fn write_file(path: &Path, bytes: impl AsRef<[u8]>) -> Result<()> {
    std::fs::write(path, bytes).map_err(|source| DiscoverError::Io { path: path.to_path_buf(), source })
}

/// Write a `report.json` to `path`: the verdict first, then `report`.
pub(super) fn write_json<T: Serialize>(path: &Path, v: &Verdict, report: &T) -> Result<()> {
    let json =
        json_with_verdict(v, report).map_err(|source| DiscoverError::Json { path: path.to_path_buf(), source })?;
    write_file(path, json + "\n")
}

/// The line saying what `table.bin` holds and what it scores held out (on a cycling log,
/// also `calibrate`'s own held-out figures of it and what was done with the catalog's slots).
fn flashed_line(s: &mut String, ch: &Channels, r: &Report) {
    if let Some(t) = &r.table {
        let slots = match &t.slots {
            super::cycling_table::Slots::NoneNamed => "the block test named no extension slot".to_string(),
            super::cycling_table::Slots::Added(super::cycling_table::SlotGaps { without, with }) => format!(
                "the block test's slots ({}) are in it: held out on the selection folds {} with them, {} without",
                t.named_slots.join(", "),
                gaps_text(ch.bias_unit, with),
                gaps_text(ch.bias_unit, without)
            ),
            super::cycling_table::Slots::NotAdded(super::cycling_table::SlotGaps { without, with }) => format!(
                "the block test's slots ({}) are not: they do not carry to the held-out programs (held out on the \
                 selection folds {} with them, {} without)",
                t.named_slots.join(", "),
                gaps_text(ch.bias_unit, with),
                gaps_text(ch.bias_unit, without)
            ),
            super::cycling_table::Slots::OneProgram => {
                format!("the block test's slots ({}) are not: one program", t.named_slots.join(", "))
            }
        };
        let figures = t.calibrate_heldout.as_ref().map_or_else(
            || super::cycling_table::ONE_PROGRAM.to_string(),
            |c| {
                format!(
                    "`calibrate`'s own held-out figures of it (fitted on {}, scored on {}): sensitivity {:.2} ppm/°C, \
                     bias {:.2} µg",
                    c.fit_programs.join(", "),
                    c.eval_programs.join(", "),
                    c.sensitivity_ppm_per_c,
                    c.bias_residual_ug
                )
            },
        );
        let _ = writeln!(
            s,
            "The table (`table.bin`) is the one `calibrate` writes for this log: {}; {slots}. {figures}.\n",
            t.structure
        );
    }
    let _ = writeln!(
        s,
        "Flashed (`table.bin`): the {}, held out {}{}.\n",
        r.flashed.model,
        flashed_text(ch.bias_unit, &r.flashed),
        r.flashed.peer_better.as_ref().map_or_else(String::new, |p| format!(
            "; **{} predicts the bias better held out ({:.3} {})**{}",
            p.peer,
            p.heldout_rms,
            ch.bias_unit.label(),
            if ch.kind == LogKind::Cycling { ", but has no scale-factor model to flash" } else { "" }
        ))
    );
}

/// One candidate trial as the cells of the rounds' tables (Markdown and the page).
#[must_use]
pub(crate) fn round_row(ch: &Channels, t: &super::CandidateTrial) -> Vec<String> {
    vec![
        t.name.clone(),
        t.channel.clone(),
        format!("{:.1}", t.gain.gain),
        format!("{:.1}", t.gain.se),
        format!("{:.2}", t.gain.t),
        format!("{:.2}", t.gain.critical),
        format!("{} × {}", t.gain.blocks, t.gain.block_bins),
        // The first test that refused it: the whitened gain, the raw gain, the weight's z.
        match &t.weight {
            _ if t.significant => "yes".into(),
            _ if !t.gain.passes() => "no: gain/SE".into(),
            _ if !t.raw_gain.passes() => format!("no: raw gain/SE {:.2} ≤ {:.2}", t.raw_gain.t, t.raw_gain.critical),
            Some(w) => format!("no: weight z {:.2} ({} ± {:.3e})", w.z, w.param, w.se),
            None => "no".into(),
        },
        if t.at_bound.is_empty() { "-".to_string() } else { t.at_bound.join(", ") },
        gaps_text(ch.bias_unit, &t.gaps),
    ]
}

/// The columns of a round's candidate table before its gaps (`round_row`'s order).
pub(crate) const ROUND_HEADER: [&str; 9] =
    ["candidate", "channel", "gain", "SE", "gain/SE", "critical", "blocks × bins", "significant", "at search limit"];

struct Row {
    trace: usize,
    time_s: f64,
    temp_c: f64,
    dir: i8,
}

fn rows(ch: &Channels) -> Vec<Row> {
    let mut v = Vec::new();
    for (ti, t) in ch.traces.iter().enumerate() {
        for b in &t.bins {
            let (tm, rm) = t.bin_means(b);
            let dir = qfa_log::replay::Motion::direction(rm).sign();
            v.push(Row { trace: ti, time_s: b.time_s, temp_c: tm, dir });
        }
    }
    v
}

fn write_csv(ch: &Channels, r: &Report, path: &Path) -> Result<()> {
    write_file(path, residuals_csv(ch, r))
}

/// `residuals.csv`: one line per bin, its first line the header, each figure's unit in its
/// column's name (`pandas.read_csv` reads it without options). A static log has no scale
/// factor, so no scale-factor columns (never a column of NaN); a bias in the log's own units
/// is `bias_*_value`.
fn residuals_csv(ch: &Channels, r: &Report) -> String {
    let (b, a) = &r.residuals;
    let cycling = ch.kind == LogKind::Cycling;
    let unit = if ch.bias_unit == BiasUnit::Value { "value" } else { "ug" };
    let mut s = String::from("program,time_s,temp_c,direction,");
    if cycling {
        s.push_str("sf_before_ppm,sf_after_ppm,");
    }
    let _ = writeln!(s, "bias_before_{unit},bias_after_{unit}");
    for (i, row) in rows(ch).iter().enumerate() {
        let d = ["cooling", "hold", "heating"][(row.dir + 1) as usize];
        let _ = write!(s, "{},{:.1},{:.3},{d},", ch.traces[row.trace].program, row.time_s, row.temp_c);
        if cycling {
            let _ = write!(s, "{:.4},{:.4},", b.sf[i], a.sf[i]);
        }
        let _ = writeln!(s, "{:.6},{:.6}", b.bias[i], a.bias[i]);
    }
    s
}

/// The channels plotted: `(file stem, name in a title, axis label, unit)`.
fn plotted(ch: &Channels) -> Vec<(&'static str, &'static str, &'static str, &'static str)> {
    if ch.kind == LogKind::Cycling {
        vec![
            ("scale_factor", "scale factor", "scale-factor residual, ppm", "ppm"),
            ("bias", "bias", "bias residual, µg", "µg"),
        ]
    } else if ch.bias_unit == BiasUnit::Value {
        vec![("value", "value", "residual, value units", "value units")]
    } else {
        vec![("value", "bias", "bias residual, µg", "µg")]
    }
}

/// Bins of `ch` on a hold (neither heating nor cooling).
#[must_use]
pub(crate) fn hold_bins(ch: &Channels) -> usize {
    rows(ch).iter().filter(|r| r.dir == 0).count()
}

/// `residual_<channel>_vs_{time,temp}.png`: each channel's residual of every bin, start
/// model above, named model below, on one shared scale; heating red, cooling blue, hold
/// grey. The legend sits in a band above the data (the y range runs to 1.6× the largest
/// residual), so it covers none of it. Returns the plots, drawn in memory.
fn plots(ch: &Channels, r: &Report, scope: Scope<'_>) -> std::result::Result<Vec<Plot>, PlotError> {
    let rows = rows(ch);
    let (b, a) = &r.residuals;
    let held = &scope.folds_word();
    let mut written = Vec::new();
    // Program offsets so time runs on across programs.
    let mut off = vec![0.0; ch.traces.len()];
    let mut acc = 0.0;
    for (i, t) in ch.traces.iter().enumerate() {
        off[i] = acc;
        acc += t.time_s.last().copied().unwrap_or(0.0) / 3600.0 + 0.5;
    }
    for (stem, name, label, unit) in plotted(ch) {
        let (before, after) = if stem == "scale_factor" { (&b.sf, &a.sf) } else { (&b.bias, &a.bias) };
        for vs_time in [true, false] {
            let file_name = format!("residual_{stem}_vs_{}.png", if vs_time { "time" } else { "temp" });
            let plot = Plot::draw(file_name, (1200, 800), |root| {
                root.fill(&WHITE)?;
                let panels = root.split_evenly((2, 1));
                let x_of =
                    |i: usize| if vs_time { off[rows[i].trace] + rows[i].time_s / 3600.0 } else { rows[i].temp_c };
                let (xlo, xhi) = (0..rows.len())
                    .map(x_of)
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| (l.min(x), h.max(x)));
                let ymax =
                    before.iter().chain(after.iter()).filter(|v| v.is_finite()).fold(1e-12f64, |m, v| m.max(v.abs()));
                let named = if worse(r) {
                    format!("{}, worse than the start", scope.model_name(r))
                } else {
                    scope.model_name(r).to_string()
                };
                let titles = [
                    format!("start model {}: {held} RMS {:.2} {unit}", r.start.name(), rms_of_finite(before)),
                    format!("{named}: {held} RMS {:.2} {unit}", rms_of_finite(after)),
                ];
                let branches = [
                    (1, "heating", RGBColor(230, 60, 60)),
                    (-1, "cooling", RGBColor(60, 60, 230)),
                    (0, "hold", RGBColor(160, 160, 160)),
                ];
                for (p, (title, v)) in panels.iter().zip([(&titles[0], before), (&titles[1], after)]) {
                    // The legend in a strip above the chart: inside, it sat on the hottest bins.
                    let entries: Vec<qfa_report::plot_legend::Entry> = branches
                        .iter()
                        .filter(|(dir, _, _)| (0..rows.len()).any(|i| rows[i].dir == *dir && v[i].is_finite()))
                        .map(|(_, what, c)| ((*what).to_string(), *c, qfa_report::plot_legend::Mark::Dot))
                        .collect();
                    let area = qfa_report::plot_legend::heading(
                        p,
                        &format!("{name}, every bin from a fit that never saw it: {title}"),
                        &entries,
                    )?;
                    let mut chart = ChartBuilder::on(&area)
                        .margin(8)
                        .x_label_area_size(30)
                        .y_label_area_size(60)
                        .build_cartesian_2d(xlo..xhi.max(xlo + 1e-9), -ymax..1.1 * ymax)?;
                    chart
                        .configure_mesh()
                        .x_desc(if vs_time { "time, h (programs in sequence)" } else { "temperature, °C" })
                        .y_desc(label)
                        .draw()?;
                    for (dir, _, c) in branches {
                        let pts: Vec<(f64, f64)> = (0..rows.len())
                            .filter(|&i| rows[i].dir == dir && v[i].is_finite())
                            .map(|i| (x_of(i), v[i]))
                            .collect();
                        chart.draw_series(pts.into_iter().map(|p| Circle::new(p, 1, c.mix(0.7).filled())))?;
                    }
                }
                Ok(())
            })?;
            written.push(plot);
        }
    }
    Ok(written)
}

/// The residual unit of a channel in words.
pub(super) fn channel_unit(ch: &Channels, channel: &str) -> &'static str {
    if channel == "scale_factor" {
        "ppm"
    } else {
        ch.bias_unit.label()
    }
}

/// The noise test of `series` (a channel or a position's reading), if the report has one.
pub(super) fn noise_model_of<'a>(r: &'a Report, series: &str) -> Option<&'a super::noise::NoiseTest> {
    r.noise.iter().find(|n| n.series == series)
}

/// Every series' fitted noise model, in words.
pub(super) fn noise_models_text(ch: &Channels, r: &Report) -> String {
    r.noise
        .iter()
        .map(|n| format!("{}: {}", n.series, n.model.text(channel_unit(ch, &n.series))))
        .collect::<Vec<_>>()
        .join("; ")
}

/// Every series' change-point search against its critical value, in words.
pub(super) fn change_point_tests_text(r: &Report) -> String {
    r.noise
        .iter()
        .map(|n| match (n.max_z, n.critical) {
            (Some(z), Some(c)) => format!(
                "{} largest |z| {z:.1} against {c:.1} by segment means and {}, from {} series of the model ({} runs \
                 searched)",
                n.series,
                match (n.whitened_max_z, n.whitened_critical) {
                    (Some(wz), Some(wc)) => format!("{wz:.1} against {wc:.1} whitened"),
                    _ => format!(
                        "no split whitened (every split within {:.0} min after a corner)",
                        super::noise::CORNER_SKIP_S / 60.0
                    ),
                },
                super::noise::NULL_DRAWS,
                n.runs_searched
            ),
            _ => format!("{}: not searched, no run of {} bins or more", n.series, 2 * super::noise::MIN_SEGMENT_BINS),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Every series' run-noise test (the noisiest run's SD over the median run's) against
/// its critical value, in words.
pub(super) fn run_noise_tests_text(r: &Report) -> String {
    r.noise
        .iter()
        .map(|n| match (n.max_run_noise, n.run_noise_critical) {
            (Some(x), Some(c)) => format!(
                "{} noisiest run {x:.2}× the median run against {c:.2}× (and {:.1}× at least)",
                n.series,
                super::noise::RUN_NOISE_MIN_RATIO
            ),
            _ => format!("{}: not tested, fewer than 3 runs long enough", n.series),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The branch test in words (a cycling log's scale factor), or `None` where none ran.
pub(super) fn branch_test_text(r: &Report) -> Option<String> {
    r.noise.iter().find_map(|n| match (n.branch_z, n.branch_critical) {
        (Some(z), Some(c)) => Some(format!("{} |z| {z:.1} against {c:.1}", n.series)),
        _ => None,
    })
}

/// The timing offset in words (cycling logs; `None` for a single-channel log).
pub(super) fn timing_offset_text(ch: &Channels, r: &Report) -> Option<String> {
    match &r.timing_offset {
        Some(o) => Some(format!(
            "{:+.2} s, 95 % interval [{:+.2}, {:+.2}] s (fitted with every model){}{}",
            o.seconds,
            o.ci95[0],
            o.ci95[1],
            if o.at_limit {
                format!(", at its limit of ±{:.1} s: a longer delay than any timestamp convention", o.limit_s)
            } else {
                String::new()
            },
            if o.shares_a_branch_level {
                "; not the log's timing alone: a scale-factor level by ramp branch is left unexplained, and the \
                 offset takes its share on the ramps"
            } else {
                ""
            }
        )),
        None if ch.kind == LogKind::Cycling => Some(
            "not fitted, since the model holds ε·Ṫ (the `paper` start, or `rate_hysteresis` named): the two are one \
             signal on the scale factor, and ε carries any offset"
                .into(),
        ),
        None => None,
    }
}
