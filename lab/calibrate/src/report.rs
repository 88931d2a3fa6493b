//! Held-out evaluation, `report.json`, and plots.
//!
//! Every figure in the report is **held out**: the tables are fitted on the fit programs
//! ([`crate::fit::split_programs`]: for the paper's test, 0.3 and 0.9 °C/min) and the
//! figures come from compensating the other programs (0.5 and 0.7 °C/min) through the
//! root crate's compensator. Metric definitions are in [`crate::metrics`].

use serde::Serialize;

use qfa_thermal::model::Branch;
use qfa_thermal::Table;

use crate::compensate::{compensate_run, not_compensated};
use crate::metrics::{bin_series, bins_sensitivity, rms, Bin};
use qfa_log::cycling::Run;
use qfa_log::pairing::{trace_run, PairedLog, Trace};
use qfa_report::verdict::Measured;

/// Figures per compensation variant.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Variants {
    /// No compensation (constant K1 = fitted γ, no bias removed).
    pub none: f64,
    /// Simple model (Eq. 3–4).
    pub simple: f64,
    /// Hysteresis model (Eq. 11 + branched bias grid).
    pub hysteresis: f64,
}

/// Held-out bins of one variant.
#[derive(Clone, Debug, Default)]
pub struct VariantBins {
    /// Scale-factor bins (value: compensated scale factor, 1 = perfect).
    pub sf: Vec<Bin>,
    /// Bias bins (value: g).
    pub bias: Vec<Bin>,
}

/// The held-out evaluation.
#[derive(Clone, Debug, Default)]
pub struct Evaluation {
    /// Table-4 sensitivity, ppm/°C.
    pub sensitivity_ppm_per_c: Variants,
    /// Bias residual, µg RMS.
    pub bias_residual_ug: Variants,
    /// Bins per variant: none, simple, hysteresis.
    pub bins: [VariantBins; 3],
    /// Readings the compensator rejected, by reason.
    pub rejected_readings: crate::compensate::Rejections,
}

fn valid_rows(tr: &Trace, status: Option<&[u16]>) -> Vec<bool> {
    (0..tr.valid.len()).map(|i| tr.valid[i] && status.is_none_or(|s| !not_compensated(s[i]))).collect()
}

/// A variant's per-row output and, when compensated, its status words.
type Output = (Vec<f64>, Option<Vec<u16>>);

/// Compensate `programs` of `log` with each table and form the held-out bins and figures.
/// `none` uses `gamma_none` as its constant scale factor.
///
/// # Errors
/// A table that does not load into the compensator.
#[allow(clippy::needless_range_loop)]
pub fn evaluate(
    paired: &PairedLog<'_>,
    programs: &[String],
    simple: &Table,
    hysteresis: &Table,
    progress: Option<&indicatif::ProgressBar>,
) -> Result<Evaluation, crate::compensate::Error> {
    let log = paired.log;
    let gamma_none = f64::from(hysteresis.axes[0].scale.gamma);
    let mut ev = Evaluation::default();
    let ext = qfa_thermal::Extensions::default();
    for prog in programs {
        // Runs of this program: their compensated outputs under each variant.
        let idx: Vec<usize> = (0..log.runs.len()).filter(|&i| log.runs[i].program == *prog).collect();
        let mut outs: Vec<[Output; 3]> = Vec::new();
        let mut traces: Vec<Trace> = Vec::new();
        for &i in &idx {
            let run = &log.runs[i];
            let none: Vec<f64> = run.samples.iter().map(|s| s.pulses as f64 / (s.interval_s * gamma_none)).collect();
            let cs = compensate_run(simple, run)?;
            let ch = compensate_run(hysteresis, run)?;
            ev.rejected_readings.add(ch.rejected);
            outs.push([(none, None), (cs.accel_g, Some(cs.status)), (ch.accel_g, Some(ch.status))]);
            traces.push(trace_run(run, &ext, hysteresis.axes[0].bias.deadband_c_per_min));
            if let Some(pb) = progress {
                pb.inc(1);
            }
        }
        let pos = |run_idx: usize| idx.iter().position(|&i| i == run_idx);
        // Pairs: scale factor and bias.
        if let Some(pp) = paired.program(prog) {
            let (ip, im) = (pos(pp.plus).unwrap_or(0), pos(pp.minus).unwrap_or(0));
            let (tp, tm) = (&traces[ip], &traces[im]);
            let sp = &log.runs[pp.plus].samples;
            let n = pp.rows.len();
            let temp: Vec<f64> = pp.rows.iter().map(|&(i, j)| 0.5 * (tp.temp_c[i] + tm.temp_c[j])).collect();
            let br: Vec<Branch> = pp.rows.iter().map(|&(i, _)| tp.branch[i]).collect();
            let time: Vec<f64> = pp.rows.iter().map(|&(i, _)| sp[i].time_s).collect();
            let ivl: Vec<f64> = pp.rows.iter().map(|&(i, _)| sp[i].interval_s).collect();
            for v in 0..3 {
                let (ap, sp_st) = &outs[ip][v];
                let (am, sm_st) = &outs[im][v];
                let okp = valid_rows(tp, sp_st.as_deref());
                let okm = valid_rows(tm, sm_st.as_deref());
                let use_row: Vec<bool> = pp.rows.iter().map(|&(i, j)| okp[i] && okm[j]).collect();
                let g = log.runs[pp.plus].input_g - log.runs[pp.minus].input_g;
                let sf: Vec<f64> = pp.rows.iter().map(|&(i, j)| (ap[i] - am[j]) / g).collect();
                let bias: Vec<f64> = pp
                    .rows
                    .iter()
                    .map(|&(i, j)| {
                        0.5 * (ap[i] + am[j]) - 0.5 * (log.runs[pp.plus].input_g + log.runs[pp.minus].input_g)
                    })
                    .collect();
                debug_assert_eq!(sf.len(), n);
                ev.bins[v].sf.extend(bin_series(prog, &temp, &br, &time, &ivl, &sf, &use_row));
                ev.bins[v].bias.extend(bin_series(prog, &temp, &br, &time, &ivl, &bias, &use_row));
            }
        }
        bin_zero_g_runs(&mut ev, prog, idx.iter().map(|&i| &log.runs[i]), &traces, &outs);
    }
    let sens = |v: usize| bins_sensitivity(&ev.bins[v].sf).unwrap_or(f64::NAN);
    let bres = |v: usize| rms(&ev.bins[v].bias.iter().map(|b| b.value * 1e6).collect::<Vec<_>>());
    ev.sensitivity_ppm_per_c = Variants { none: sens(0), simple: sens(1), hysteresis: sens(2) };
    ev.bias_residual_ug = Variants { none: bres(0), simple: bres(1), hysteresis: bres(2) };
    Ok(ev)
}

/// The zero-g runs among a program's `runs` (with their `traces` and each variant's
/// `outs`, in the same order): their output is the bias directly, binned into `ev`.
fn bin_zero_g_runs<'a>(
    ev: &mut Evaluation,
    prog: &str,
    runs: impl Iterator<Item = &'a Run>,
    traces: &[Trace],
    outs: &[[Output; 3]],
) {
    for (k, run) in runs.enumerate() {
        if run.input_g != 0.0 {
            continue;
        }
        let tr = &traces[k];
        let time: Vec<f64> = run.samples.iter().map(|s| s.time_s).collect();
        let ivl: Vec<f64> = run.samples.iter().map(|s| s.interval_s).collect();
        for (v, (a, st)) in outs[k].iter().enumerate() {
            let ok = valid_rows(tr, st.as_deref());
            ev.bins[v].bias.extend(bin_series(prog, &tr.temp_c, &tr.branch, &time, &ivl, a, &ok));
        }
    }
}

/// Fit diagnostics in the report.
#[derive(Clone, Debug, Serialize)]
pub struct FitSummary {
    /// Paired rows fitted (every program with a pair: `table.bin`'s fit, whose figures
    /// these all are).
    pub pairs: usize,
    /// Condition number (column-scaled) of the simple scale-factor fit.
    pub cond_sf_simple: f64,
    /// Condition number (column-scaled) of the Eq. 11 fit.
    pub cond_sf_hysteresis: f64,
    /// Condition number (column-scaled) of the bias-grid fit.
    pub cond_bias_grid: f64,
    /// Eq. 11 coefficients [γ, μ, β, ε, η, α].
    pub eq11: [f64; 6],
    /// Simple [γ, μ].
    pub simple_sf: [f64; 2],
    /// Simple bias [k0 g, k1 g/°C].
    pub simple_bias: [f64; 2],
    /// RMS residual of the Eq. 11 fit, pulses/(g·s).
    pub rms_sf_hysteresis: f64,
    /// The bias grid's branch tie and shape `table.bin` holds, chosen by cross-validation
    /// on every program the table is fitted on (`crate::fit::fit_table`), with every
    /// candidate's figures: the structure the held-out figures are of too
    /// (`crate::fit::fit_held_out`).
    pub branch: crate::fit::BranchChoice,
}

/// `report.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Log rows.
    pub rows: usize,
    /// Programs the held-out figures' tables were fitted on.
    pub fit_programs: Vec<String>,
    /// Programs the written tables (`table.*`, `table_simple.*`) and the PX4 / ArduPilot
    /// parameters were fitted on: every program with a ±1 g pair.
    pub table_programs: Vec<String>,
    /// Which rows each figure and output comes from, in words.
    pub figures: String,
    /// Programs the figures come from.
    pub eval_programs: Vec<String>,
    /// Whether the figures are held out (false only for a one-program log).
    pub held_out: bool,
    /// Table-4 sensitivity, ppm/°C, held out.
    pub sensitivity_ppm_per_c: Variants,
    /// Bias residual, µg RMS, held out.
    pub bias_residual_ug: Variants,
    /// Bias residual of the bias-only peers (fitted on the same fit programs), µg RMS, held out.
    pub peers_bias_residual_ug: PeerBias,
    /// Metric definition, in words.
    pub metric: String,
    /// Fit diagnostics.
    pub fit: FitSummary,
    /// Readings the compensator rejected in the held-out runs, by reason.
    pub rejected_readings: crate::compensate::Rejections,
    /// Rows the reader skipped as one-row glitches in the pulse rate (`qfa_log::cycling::Glitch`):
    /// not fitted, not scored.
    pub skipped_glitches: Vec<qfa_log::cycling::Glitch>,
    /// Temperature and rate ranges the fit programs cover (heating, cooling) and the
    /// limits `table.bin` clamps to: beyond them the firmware clamps and flags.
    pub coverage: crate::coverage::CalCoverage,
    /// Step timings, s (left out when [`crate::CalibrateOptions::reproducible`] asks for
    /// bytes that depend on the log alone).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub timings_s: Option<Timings>,
}

/// Why a one-program log's held-out figures are not computed.
pub const IN_SAMPLE: &str = "one program only: the figures are in-sample, not held out";

/// Why the held-out figures are not computed when the fit programs are every program of a
/// log of several (`--fit-programs` naming them all).
pub const ALL_FITTED: &str = "every program of the log fitted: the figures are in-sample, not held out";

impl Report {
    /// `table.bin`'s held-out Table-4 sensitivity (ppm/°C) and bias residual (µg RMS): what
    /// its limits judge, its verdict expects in use and a batch compares. Not computed on a
    /// one-program log ([`IN_SAMPLE`]), nor when the fit programs are all of them
    /// ([`ALL_FITTED`]): their figures were scored on the rows they were fitted on.
    #[must_use]
    pub fn held_out_table_figures(&self) -> (Measured, Measured) {
        let figure = |x: f64| {
            if self.held_out {
                Measured::Value(x)
            } else {
                Measured::NotComputed { not_computed: self.in_sample_reason().into() }
            }
        };
        (figure(self.sensitivity_ppm_per_c.hysteresis), figure(self.bias_residual_ug.hysteresis))
    }

    /// Why nothing was held out, when nothing was: the log holds one program
    /// ([`IN_SAMPLE`]), or the fit programs are every program it holds ([`ALL_FITTED`]).
    #[must_use]
    pub fn in_sample_reason(&self) -> &'static str {
        if self.table_programs.len() <= 1 {
            IN_SAMPLE
        } else {
            ALL_FITTED
        }
    }
}

/// Step timings, s.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Timings {
    /// Reading the log.
    pub read: f64,
    /// Fitting.
    pub fit: f64,
    /// Held-out compensation and metrics.
    pub evaluate: f64,
    /// Plots.
    pub plots: f64,
    /// Total.
    pub total: f64,
}

impl Report {
    /// What its figures are: `Held-out`, or `In-sample` for a log of one program, whose
    /// tables are scored on the rows they were fitted on.
    #[must_use]
    pub fn scored(&self) -> &'static str {
        if self.held_out {
            "Held-out"
        } else {
            "In-sample"
        }
    }
}

/// The held-out figures of a cycling calibration in Markdown (after the verdict in
/// `report.md`).
#[must_use]
pub(crate) fn markdown(r: &Report) -> String {
    let (s, b, pb) = (r.sensitivity_ppm_per_c, r.bias_residual_ug, r.peers_bias_residual_ug);
    format!(
        "## {} figures\n\nTables fitted on programs {}, figures from programs {}; the written tables are \
         fitted on programs {}.\n\n\
         | model | scale-factor sensitivity, ppm/°C | bias residual, µg RMS |\n|---|---|---|\n\
         | no compensation | {:.2} | {:.2} |\n| simple (Eq. 3–4) | {:.2} | {:.2} |\n\
         | hysteresis ({}), table.bin | {:.2} | {:.2} |\n\
         | PX4 / tofupilot cubic (bias only, in the table's place) | - | {:.2} |\n\
         | ArduPilot TCAL (bias only, in the table's place) | - | {:.2} |\n\n\
         A bias-only peer is scored with the table's scale factor, on its rows and bins.\n\n\
         Metric: {}.\n",
        r.scored(),
        r.fit_programs.join(", "),
        r.eval_programs.join(", "),
        r.table_programs.join(", "),
        s.none,
        b.none,
        s.simple,
        b.simple,
        crate::held_out_structure(&r.fit),
        s.hysteresis,
        b.hysteresis,
        pb.cubic,
        pb.ardupilot,
        r.metric
    )
}

/// Metric definition written into the report.
pub(crate) const METRIC_TEXT: &str = "Table-4 sensitivity (max-min)/(mean*span)*1e6 ppm/degC over the scored bins \
(program, branch segment, 1 degC of T-hat; bins >= 60 s); compensated scale factor (a+ - a-)/2 from the root \
crate's Compensator<1,32>; bias residual = RMS of binned (a+ + a-)/2 and 0 g outputs, ug";

fn branch_color(b: Branch) -> plotters::style::RGBColor {
    match b {
        Branch::Heating => plotters::style::RGBColor(200, 30, 30),
        Branch::Cooling => plotters::style::RGBColor(30, 60, 200),
        Branch::Unknown => plotters::style::RGBColor(120, 120, 120),
    }
}

use qfa_report::plot_png::{Area, Plot, PlotError};

/// Room above the data for a legend of `entries` lines, in data units: the y range grows
/// by 12 % of the data's span per entry (a legend line is about 20 px of a 370–430 px
/// panel), so the legend sits in empty space above every point instead of on them.
fn legend_headroom(lo: f64, hi: f64, entries: u32) -> f64 {
    ((hi - lo) * (0.05 + 0.12 * f64::from(entries))).max(1.0)
}

/// File name of the held-out scale factor against temperature plot.
pub const SF_PLOT: &str = "sf_vs_temp.png";
/// File name of the held-out residuals against time plot.
pub const RESIDUAL_PLOT: &str = "residual_vs_time.png";

/// `sf_vs_temp.png`: scale factor (ppm from its mean) against temperature, before and
/// after, heating red, cooling blue, hold grey, with a legend above each panel; only
/// held-out bins are drawn (the title says which programs they come from).
///
/// # Errors
/// Drawing or encoding errors.
pub(crate) fn plot_sf_vs_temp(title: &str, ev: &Evaluation, bins_word: &str) -> Result<Plot, PlotError> {
    Plot::draw(SF_PLOT, (1500, 500), |root| draw_sf_vs_temp(root, title, ev, bins_word))
}

fn draw_sf_vs_temp(
    root: &Area<'_>,
    title: &str,
    ev: &Evaluation,
    bins_word: &str,
) -> Result<(), qfa_report::plot_legend::DrawError> {
    use plotters::prelude::*;
    root.fill(&WHITE)?;
    let (top, body) = root.split_vertically(30);
    top.titled(title, ("sans-serif", 20))?;
    let panels = body.split_evenly((1, 3));
    let names = ["no compensation", "simple (Eq. 3-4)", "hysteresis (Eq. 11 + branched bias)"];
    for (k, area) in panels.iter().enumerate() {
        let bins = &ev.bins[k].sf;
        if bins.is_empty() {
            continue;
        }
        let mean = bins.iter().map(|b| b.value).sum::<f64>() / bins.len() as f64;
        let ppm: Vec<f64> = bins.iter().map(|b| (b.value / mean - 1.0) * 1e6).collect();
        let lo = ppm.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = ppm.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let pad = ((hi - lo) * 0.05).max(1.0);
        let tmin = bins.iter().map(|b| b.temp_c).fold(f64::INFINITY, f64::min) - 2.0;
        let tmax = bins.iter().map(|b| b.temp_c).fold(f64::NEG_INFINITY, f64::max) + 2.0;
        let branches =
            [(Branch::Heating, "heating"), (Branch::Cooling, "cooling"), (Branch::Unknown, "hold / not known")];
        let drawn: Vec<(Branch, &str)> =
            branches.into_iter().filter(|(br, _)| bins.iter().any(|b| b.branch == *br)).collect();
        // The legend in a strip above the chart: in the chart it covered bins.
        let entries: Vec<qfa_report::plot_legend::Entry> = drawn
            .iter()
            .map(|(br, label)| (format!("{label}, {bins_word}"), branch_color(*br), qfa_report::plot_legend::Mark::Dot))
            .collect();
        let body = qfa_report::plot_legend::heading(area, names[k], &entries)?;
        let mut chart = ChartBuilder::on(&body)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(60)
            .build_cartesian_2d(tmin..tmax, (lo - pad)..(hi + pad))?;
        chart.configure_mesh().x_desc("T (°C, DS18B20)").y_desc("scale factor − mean (ppm)").draw()?;
        for (branch, _) in drawn {
            let c = branch_color(branch);
            let pts: Vec<(f64, f64)> =
                bins.iter().zip(&ppm).filter(|(b, _)| b.branch == branch).map(|(b, &y)| (b.temp_c, y)).collect();
            chart.draw_series(pts.into_iter().map(|p| Circle::new(p, 2, c.filled())))?;
        }
    }
    Ok(())
}

/// `residual_vs_time.png`: held-out residuals against time, bias (µg) and scale factor
/// (ppm) for simple and hysteresis, each program's time from its own start.
///
/// # Errors
/// Drawing or encoding errors.
pub(crate) fn plot_residual_vs_time(title: &str, ev: &Evaluation, bins_word: &str) -> Result<Plot, PlotError> {
    Plot::draw(RESIDUAL_PLOT, (1400, 800), |root| draw_residual_vs_time(root, title, ev, bins_word))
}

fn draw_residual_vs_time(
    root: &Area<'_>,
    title: &str,
    ev: &Evaluation,
    bins_word: &str,
) -> Result<(), qfa_report::plot_legend::DrawError> {
    use plotters::prelude::*;
    root.fill(&WHITE)?;
    let (top, body) = root.split_vertically(30);
    top.titled(title, ("sans-serif", 20))?;
    let rows = body.split_evenly((2, 1));
    let colors = [RGBColor(230, 140, 0), RGBColor(0, 130, 60)];
    for (k, area) in rows.iter().enumerate() {
        let series: Vec<Vec<(f64, f64)>> = (1..3)
            .map(|v| {
                let bins = if k == 0 { &ev.bins[v].sf } else { &ev.bins[v].bias };
                let mean =
                    if k == 0 { bins.iter().map(|b| b.value).sum::<f64>() / bins.len().max(1) as f64 } else { 0.0 };
                bins.iter()
                    .map(|b| (b.time_s / 3600.0, if k == 0 { (b.value / mean - 1.0) * 1e6 } else { b.value * 1e6 }))
                    .collect()
            })
            .collect();
        let all: Vec<&(f64, f64)> = series.iter().flatten().collect();
        if all.is_empty() {
            continue;
        }
        let xmax = all.iter().map(|p| p.0).fold(0.0, f64::max);
        let lo = all.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
        let hi = all.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
        let pad = ((hi - lo) * 0.05).max(0.5);
        let mut chart = ChartBuilder::on(area)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..xmax, (lo - pad)..(hi + legend_headroom(lo, hi, 2)))?;
        let ydesc = if k == 0 { "scale-factor residual (ppm)" } else { "bias residual (ug)" };
        chart.configure_mesh().x_desc("time since program start (h)").y_desc(ydesc).draw()?;
        for (s, (pts, c)) in series.iter().zip(colors).enumerate() {
            let label = format!("{}, {bins_word}", if s == 0 { "simple" } else { "hysteresis" });
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 2, c.filled())))?
                .label(label)
                .legend(move |(x, y)| Circle::new((x, y), 4, c.filled()));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    Ok(())
}

/// Held-out bias residual of the bias-only peers on a cycling log, µg, each in the
/// hysteresis table's place ([`bias_in_place`]: its scale factor, rows and bins), by its
/// own formula (finer than the firmware's 16-node grid can hold).
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct PeerBias {
    /// PX4 / tofupilot cubic of K0 in T.
    pub cubic: f64,
    /// ArduPilot TCAL cubic about 35 °C (learner rule: points on rises).
    pub ardupilot: f64,
}

/// A bias model for [`bias_in_place`]: g at a temperature reading (°C) on a branch.
pub type BiasModel<'a> = &'a dyn Fn(f64, Branch) -> f64;

/// Fit the peers on the ±1 g pairs of `fit_programs` (K0 against the pair's mean T̂) and
/// score each in the hysteresis table's place ([`bias_in_place`]).
///
/// Returns the figures and the fitted peers (for the PX4 / ArduPilot parameter files).
///
/// # Errors
/// No fit pairs, a failed fit, a table the compensator refuses, or no held-out bin.
pub(crate) fn peer_bias(
    paired: &PairedLog<'_>,
    fit_programs: &[String],
    eval_programs: &[String],
    hysteresis: &Table,
) -> Result<(PeerBias, crate::peers::Peers), crate::CalibrateError> {
    let peers = peer_fit(paired, fit_programs, hysteresis.axes[0].bias.deadband_c_per_min)?;
    let (cubic, ardupilot) = (|t: f64, _| peers.cubic.eval(t), |t: f64, _| peers.ardupilot.eval(t));
    let f = bias_in_place(paired, eval_programs, hysteresis, &[&cubic, &ardupilot])?;
    Ok((PeerBias { cubic: f[0], ardupilot: f[1] }, peers))
}

/// The held-out bias residual, µg RMS, of each of `models` put in the place of
/// `hysteresis`'s bias: the same scale factor (Eq. 11), rows (those the table compensates)
/// and bins as [`evaluate`]'s figure of the table. Per row, the compensator's output with
/// the table's scale factor and no bias, less the model at the row's reading and branch.
///
/// Why: scored on each pair's measured K0 instead, a bias-only peer was given the pair's
/// own scale factor, so the table's figure carried the scale factor's run-to-run error and
/// the peer's did not (default simulated log, on the simulator's earlier run streams: the
/// PX4 cubic 9.58 µg that way, 9.68 in the table's place, the table itself 9.68).
///
/// # Errors
/// A table the compensator refuses, or no held-out bin.
pub fn bias_in_place(
    paired: &PairedLog<'_>,
    programs: &[String],
    hysteresis: &Table,
    models: &[BiasModel<'_>],
) -> Result<Vec<f64>, crate::CalibrateError> {
    let log = paired.log;
    let deadband = hysteresis.axes[0].bias.deadband_c_per_min;
    let mut no_bias = hysteresis.clone();
    for b in no_bias.axes.iter_mut().map(|a| &mut a.bias) {
        b.heating_g.iter_mut().chain(b.cooling_g.iter_mut()).for_each(|v| *v = 0.0);
    }
    let mut bins: Vec<Vec<Bin>> = vec![Vec::new(); models.len()];
    for prog in programs {
        // Per run: its trace, the rows the table compensates, the output with no bias.
        let mut runs: Vec<(usize, Trace, Vec<bool>, Vec<f64>)> = Vec::new();
        for (i, run) in log.runs.iter().enumerate().filter(|(_, r)| r.program == *prog) {
            let tr = trace_run(run, &qfa_thermal::Extensions::default(), deadband);
            let status = compensate_run(hysteresis, run).map_err(crate::CalibrateError::Evaluate)?.status;
            let ok = valid_rows(&tr, Some(&status));
            runs.push((i, tr, ok, compensate_run(&no_bias, run).map_err(crate::CalibrateError::Evaluate)?.accel_g));
        }
        let find = |i: usize| runs.iter().find(|r| r.0 == i);
        if let Some((pp, (_, tp, okp, ap), (_, tm, okm, am))) =
            paired.program(prog).and_then(|pp| Some((pp, find(pp.plus)?, find(pp.minus)?)))
        {
            let sp = &log.runs[pp.plus].samples;
            let g_mean = 0.5 * (log.runs[pp.plus].input_g + log.runs[pp.minus].input_g);
            let temp: Vec<f64> = pp.rows.iter().map(|&(i, j)| 0.5 * (tp.temp_c[i] + tm.temp_c[j])).collect();
            let br: Vec<Branch> = pp.rows.iter().map(|&(i, _)| tp.branch[i]).collect();
            let time: Vec<f64> = pp.rows.iter().map(|&(i, _)| sp[i].time_s).collect();
            let ivl: Vec<f64> = pp.rows.iter().map(|&(i, _)| sp[i].interval_s).collect();
            let use_row: Vec<bool> = pp.rows.iter().map(|&(i, j)| okp[i] && okm[j]).collect();
            for (b, m) in bins.iter_mut().zip(models) {
                let v: Vec<f64> = (pp.rows.iter())
                    .map(|&(i, j)| {
                        0.5 * (ap[i] - m(tp.temp_c[i], tp.branch[i]) + am[j] - m(tm.temp_c[j], tm.branch[j]))
                    })
                    .map(|x| x - g_mean)
                    .collect();
                b.extend(bin_series(prog, &temp, &br, &time, &ivl, &v, &use_row));
            }
        }
        for (i, tr, ok, a) in runs.iter().filter(|r| log.runs[r.0].input_g == 0.0) {
            let s = &log.runs[*i].samples;
            let (time, ivl): (Vec<f64>, Vec<f64>) = s.iter().map(|s| (s.time_s, s.interval_s)).unzip();
            for (b, m) in bins.iter_mut().zip(models) {
                let v: Vec<f64> = (0..a.len()).map(|k| a[k] - m(tr.temp_c[k], tr.branch[k])).collect();
                b.extend(bin_series(prog, &tr.temp_c, &tr.branch, &time, &ivl, &v, ok));
            }
        }
    }
    if bins.iter().any(Vec::is_empty) {
        return Err(crate::CalibrateError::NotComputable(crate::NotComputable::NoPeerBiasBin));
    }
    Ok(bins.iter().map(|b| rms(&b.iter().map(|x| x.value * 1e6).collect::<Vec<_>>())).collect())
}

/// The bias-only peers fitted on the ±1 g pairs of `programs` (K0 against the pair's mean
/// T̂, branch deadband `deadband` °C/min), as [`peer_bias`] fits them.
///
/// # Errors
/// No pair with temperatures in `programs`, or a failed fit.
pub(crate) fn peer_fit(
    paired: &PairedLog<'_>,
    programs: &[String],
    deadband: f32,
) -> Result<crate::peers::Peers, crate::CalibrateError> {
    let log = paired.log;
    let ext = qfa_thermal::Extensions::default();
    let (mut t, mut k0) = (Vec::new(), Vec::new());
    for prog in programs {
        let Some(pp) = paired.program(prog) else { continue };
        let (tp, tm) = (trace_run(&log.runs[pp.plus], &ext, deadband), trace_run(&log.runs[pp.minus], &ext, deadband));
        for (k, &(i, j)) in pp.rows.iter().enumerate() {
            if tp.valid[i] && tm.valid[j] {
                t.push(0.5 * (tp.temp_c[i] + tm.temp_c[j]));
                k0.push(pp.k1_k0(log, k).1);
            }
        }
    }
    if t.is_empty() {
        return Err(crate::CalibrateError::NoPeerPair);
    }
    crate::peers::fit_peers(&t, &k0).map_err(crate::CalibrateError::PeerFit)
}
