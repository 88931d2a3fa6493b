//! A calibration's verdict ([`qfa_report::verdict::Verdict`]): built here from a static or a
//! cycling calibration, so every rendering of it says the same thing.

use crate::report::Report;
use crate::static_cal::report::{PlotRows, StaticCalibration};
use qfa_report::verdict::{Expected, FileUse, LimitsChoice, Measured, Verdict};

/// The held-out rows' mean residual minus the training rows', per axis, mg, with the
/// held-out RMS: `(axis, step_mg, heldout_rms_mg)`. Axes without held-out or training rows
/// are left out.
#[must_use]
pub(crate) fn heldout_steps(plot: &PlotRows) -> Vec<(String, f64, f64)> {
    let mut out = Vec::new();
    for (name, _, after) in &plot.axes {
        let (mut held, mut train) = ((0.0, 0.0, 0usize), (0.0, 0usize));
        for (i, &r) in after.iter().enumerate() {
            if !r.is_finite() {
                continue;
            }
            if plot.heldout.get(i).copied().unwrap_or(false) {
                held = (held.0 + r, held.1 + r * r, held.2 + 1);
            } else {
                train = (train.0 + r, train.1 + 1);
            }
        }
        if held.2 == 0 || train.1 == 0 {
            continue;
        }
        let n = held.2 as f64;
        out.push((name.clone(), held.0 / n - train.0 / train.1 as f64, (held.1 / n).sqrt()));
    }
    out
}

/// Per axis of `plot` whose held-out rows sit off the training rows' mean residual by most
/// of their error (the step above half the held-out RMS): the axis and the warning, with what the leg looks like
/// ([`leg_shape`]). Calibration's verdict and discovery's say it in these words.
#[must_use]
pub fn later_leg_warnings(plot: &PlotRows) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for (axis, step, rms) in heldout_steps(plot) {
        if step.abs() <= STEP_SHARE * rms {
            continue;
        }
        let after = plot.axes.iter().find(|a| a.0 == axis).map_or(&[][..], |a| &a.2[..]);
        let rows: Vec<usize> = (0..after.len()).filter(|&i| plot.heldout[i] && after[i].is_finite()).collect();
        let pick = |v: &[f64]| rows.iter().map(|&i| v[i]).collect::<Vec<f64>>();
        let shape = leg_shape(&pick(&plot.time_s), &pick(after), &pick(&plot.temp_c));
        let w = format!(
            "{axis}: the held-out rows sit {step:+.2} mg off the training rows (held-out RMS {rms:.2} mg): the later \
             rows' bias differs from the earlier rows' at the same temperature, which the training rows could not \
             show; expect such a step in use{}",
            shape.map_or(String::new(), |s| format!("; {s}"))
        );
        out.push((axis, w));
    }
    out
}

/// What the held-out leg's residual `r` (mg; times `t` s, temperatures `temp` °C) looks
/// like, with its evidence: the share of the mean square about the leg's mean that a line in
/// time takes (a drift) and a settling `a + b·exp(−t/τ)`, τ 2…64 min (a creep), by the lab's
/// one solver; named at a quarter or more (a rule, as the held-out step's), else a shift.
pub fn leg_shape(t: &[f64], r: &[f64], temp: &[f64]) -> Option<String> {
    let n = t.len() as f64;
    let mean = |v: &[f64]| v.iter().sum::<f64>() / n;
    let (mr, t0) = (mean(r), t.first()?);
    let ms_shift = r.iter().map(|x| (x - mr).powi(2)).sum::<f64>() / n;
    let left = |x: Vec<f64>| crate::solver::lstsq(&x, 2, r).ok().map_or(ms_shift, |f| f.rms * f.rms);
    let drift = 1.0 - left(t.iter().flat_map(|x| [1.0, x - t0]).collect()) / ms_shift;
    let (settle, tau) = (1..=6)
        .map(|k| 60.0 * f64::from(1 << k))
        .map(|tau| (1.0 - left(t.iter().flat_map(|x| [1.0, (-(x - t0) / tau).exp()]).collect()) / ms_shift, tau))
        .fold((f64::NEG_INFINITY, 0.0), |a, b| if b.0 > a.0 { b } else { a });
    (ms_shift > 0.0 && drift.is_finite() && settle.is_finite()).then_some(())?;
    let (mt, mtemp) = (mean(t), mean(temp));
    let cov = |a: &[f64], ma: f64, b: &[f64], mb: f64| a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum::<f64>();
    let corr = cov(t, mt, temp, mtemp) / (cov(t, mt, t, mt) * cov(temp, mtemp, temp, mtemp)).sqrt();
    let name = if drift.max(settle) < 0.25 {
        "a shift"
    } else if drift >= settle {
        "a drift"
    } else {
        "a settling"
    };
    let confound =
        (corr.abs() >= 0.5).then(|| format!(", though time and temperature move together there (r = {corr:.2})"));
    Some(format!(
        "over the later leg it looks like {name}: about its mean, a line in time takes {:.0} % of the rest and a \
         settling {:.0} % (τ {}){}; to tell a shift, a drift and a creep apart, record a hold at one \
         temperature after the run (a drift keeps moving, a creep settles, a shift stays) and a return to the first \
         leg's temperature (a shift stays off the first leg there)",
        100.0 * drift,
        100.0 * settle,
        // At a limit of the τ tried, the settling says only that it is faster or slower.
        match tau / 60.0 {
            m if m <= 2.0 => "≤ 2 min, the shortest tried".to_string(),
            m if m >= 64.0 => "≥ 64 min, the longest tried".to_string(),
            m => format!("{m:.0} min"),
        },
        confound.unwrap_or_default()
    ))
}

/// A held-out step is worth a sentence when a constant offset is most of the held-out
/// error: |step| above half the held-out RMS means the offset alone carries more than a
/// quarter of the held-out mean square. (A rule, not a tuned threshold: on the real IMU log
/// the steps carry 56, 85 and 84 % of it on x, y and z, so all three are said.)
const STEP_SHARE: f64 = 0.5;

/// The verdict of a static calibration written into a folder holding `files`; `notes` are
/// what the run must say in words (an export left out, a lint finding).
#[must_use]
pub fn static_verdict(cal: &StaticCalibration, limits: &LimitsChoice, files: &[String], notes: &[String]) -> Verdict {
    let r = &cal.report;
    let held: Vec<(String, Measured)> = r
        .axes
        .iter()
        .map(|a| {
            let m = match &a.ours {
                crate::static_cal::Figure::Score(s) => Measured::Value(s.rms_mg),
                crate::static_cal::Figure::NotComputed { not_computed } => {
                    Measured::NotComputed { not_computed: not_computed.clone() }
                }
            };
            (a.axis.clone(), m)
        })
        .collect();
    let span = r.coverage.temp_c[1] - r.coverage.temp_c[0];
    let checks = limits.limits.static_checks(&held, span);
    let answer = match held.iter().find_map(|(axis, v)| match v {
        Measured::NotComputed { not_computed } => Some((axis, not_computed)),
        Measured::Value(_) => None,
    }) {
        Some((axis, why)) => {
            format!("no held-out figure could be formed ({axis}: {why}), so nothing says what to expect in use")
        }
        None if checks.iter().all(|c| c.pass) => passing_answer(files),
        None => format!(
            "table.bin fails {}",
            checks
                .iter()
                .filter(|c| !c.pass)
                .map(|c| format!("{} on {}", c.limit, c.axis))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let h = &r.holdout;
    let mut v = Verdict::new(answer, format!("scheme `{}` (asked `{}`), {}", h.scheme, h.requested, h.rule), checks);
    v.limits_from = limits.source_for(&v.checks);
    v.expect = held
        .iter()
        .filter_map(|(a, x)| match x {
            Measured::Value(x) => {
                Some(Expected { axis: a.clone(), what: "held-out bias RMS".into(), value: *x, unit: "mg".into() })
            }
            Measured::NotComputed { .. } => None,
        })
        .collect();
    v.covers = Some(r.coverage.covers());
    v.warnings.extend(later_leg_warnings(&cal.plot).into_iter().map(|(_, w)| w));
    for a in &r.axes {
        let (Some(ours), Some(cubic)) = (a.ours.score(), a.cubic.score()) else { continue };
        // Said when it shows at the printed precision (0.01 mg): a difference the reader
        // cannot see in the figures is not worth a sentence.
        if (ours.rms_mg * 100.0).round() > (cubic.rms_mg * 100.0).round() {
            v.warnings.push(format!(
                "{}: our model ({:.2} mg) is worse held out than the PX4 cubic ({:.2} mg)",
                a.axis, ours.rms_mg, cubic.rms_mg
            ));
        }
        if a.clamped_rows > 0 {
            v.warnings.push(format!(
                "{}: {} held-out rows clamped (T or Ṫ outside what the training rows calibrated)",
                a.axis, a.clamped_rows
            ));
        }
    }
    v.warnings.extend(notes.iter().cloned());
    v.files = files.iter().map(|f| FileUse::of(f)).collect();
    v.hold_back_if_failed();
    v.advice = r.record_next.clone();
    v
}

/// The verdict of a cycling calibration of accelerometer `axis` (its IMU axis, or its
/// serial in a batch) written into a folder holding `files`.
#[must_use]
/// What a run whose table meets every limit says to do: flash it, or load the parameter
/// files among `files` when any was written (never a file the run did not write).
fn passing_answer(files: &[String]) -> String {
    let exported = files.iter().any(|f| crate::export::EXPORT_FILES.contains(&f.as_str()));
    format!(
        "table.bin meets every limit held out; flash it{}",
        if exported { ", or load the exported parameters" } else { "" }
    )
}

pub(crate) fn cycling_verdict(
    r: &Report,
    axis: &str,
    limits: &LimitsChoice,
    files: &[String],
    notes: &[String],
) -> Verdict {
    let (sensitivity, bias) = r.held_out_table_figures();
    let c = &r.coverage.covered;
    let span = c.temp_c[1] - c.temp_c[0];
    // One program: the held-out limits have no figure to judge, and each check fails saying
    // why (so the reasons a batch or `--limits` gives are those checks, never an empty list).
    let checks = limits.limits.cycling_checks(axis, sensitivity.clone(), bias.clone(), span);
    let answer = if !r.held_out {
        format!("{}, so nothing says what to expect in use", r.in_sample_reason().replace(", not held out", ""))
    } else if checks.iter().all(|c| c.pass) {
        passing_answer(files)
    } else {
        format!("table.bin fails {}", checks.iter().filter(|c| !c.pass).map(|c| c.limit).collect::<Vec<_>>().join(", "))
    };
    let held_out = held_out_line(r);
    let mut v = Verdict::new(answer, held_out, checks);
    v.limits_from = limits.source_for(&v.checks);
    // In-sample figures say nothing of use: the report's figures section shows them,
    // marked in-sample, and nothing is expected in use.
    let expect = |what: &str, m: &Measured, unit: &str| match m {
        Measured::Value(value) => {
            Some(Expected { axis: axis.into(), what: what.into(), value: *value, unit: unit.into() })
        }
        Measured::NotComputed { .. } => None,
    };
    v.expect = [
        expect("held-out scale-factor sensitivity", &sensitivity, "ppm/°C"),
        expect("held-out bias residual RMS", &bias, "µg"),
    ]
    .into_iter()
    .flatten()
    .collect();
    v.covers = Some(c.covers());
    let rej = r.rejected_readings;
    // A log of one program has no held-out run: its runs are scored in-sample.
    let runs = if r.held_out { "the held-out runs" } else { "the runs scored in-sample" };
    if rej.outside_sensor_range > 0 {
        v.warnings.push(format!(
            "the compensator refused {} temperature readings in {runs} as outside the DS18B20's \
             -55..125 °C: the program leaves the sensor's range there (the paper's goes to -60 °C), so in use \
             the table holds only within it; a chamber program inside -55..125 °C avoids the gap",
            rej.outside_sensor_range
        ));
    }
    if rej.other > 0 {
        v.warnings.push(format!(
            "the compensator refused {} temperature readings in {runs} (jumps, time steps or the \
             power-on value: the log's temperature column has faults the firmware would flag)",
            rej.other
        ));
    }
    v.warnings.extend(
        qfa_log::cycling::glitches_sentence(&r.skipped_glitches)
            .map(|s| format!("{s}; each is in report.json's skipped_glitches")),
    );
    v.warnings.extend(worse_than_a_peer(r.bias_residual_ug.hysteresis, r.peers_bias_residual_ug, r.held_out));
    v.warnings.extend(notes.iter().cloned());
    v.files = files.iter().map(|f| FileUse::of(f)).collect();
    v.hold_back_if_failed();
    v.advice = c.record_next();
    v
}

/// The verdict's `held-out` line: which programs were fitted and scored, or why none was
/// held out.
fn held_out_line(r: &Report) -> String {
    if r.held_out {
        format!(
            "tables fitted on programs {}, scored on programs {} (whole programs the fit never saw)",
            r.fit_programs.join(", "),
            r.eval_programs.join(", ")
        )
    } else if r.table_programs.len() <= 1 {
        format!(
            "none: the log holds one program ({}), so the tables were scored on the rows they were fitted on",
            r.fit_programs.join(", ")
        )
    } else {
        format!(
            "none: the fit programs are every program of the log ({}), so the tables were scored on the rows they \
             were fitted on; name fewer with --fit-programs to hold the others out",
            r.fit_programs.join(", ")
        )
    }
}

/// How much worse than a bias-only peer the table's held-out bias residual may be before
/// the verdict says so: two fits of one cubic on the same rows, one the table's 16-node grid
/// and one the peer's formula, differ held out by up to 0.2 % on six simulated units
/// (the lab guide's "Peers"); 1 % is five times that, set after that measurement.
pub const PEER_TOLERANCE: f64 = 0.01;

/// The warning when the table's bias residual `b` (µg) is worse than a peer's by more than
/// [`PEER_TOLERANCE`], both scored in the table's place: held out, or in-sample when the
/// log has no held-out program (`held_out` false).
#[must_use]
pub fn worse_than_a_peer(b: f64, p: crate::report::PeerBias, held_out: bool) -> Option<String> {
    let scored = if held_out { "held out" } else { "in-sample" };
    (b > p.cubic.min(p.ardupilot) * (1.0 + PEER_TOLERANCE)).then(|| {
        format!(
            "the bias residual ({b:.2} µg) is worse {scored} than a bias-only peer in the table's place (PX4 cubic \
             {:.2}, ArduPilot {:.2} µg): a bias model the search did not hold",
            p.cubic, p.ardupilot
        )
    })
}
