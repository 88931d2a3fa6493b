//! Pairing of the +1 g and −1 g runs, and the firmware's view of each run's temperature.
//!
//! # Pairing
//! Runs of one program follow the same temperature program, so their rows are matched by
//! `time_s` (within half an interval). With `A = pulses/interval_s` (pulses/s) and the
//! model `A = K1·(K0 + a)`:
//! `K1 = (A₊ − A₋)/2` (pulses/(g·s)) and `K0 = (A₊ + A₋)/(2·K1)` (g).
//!
//! **The paper's Eq. 13–14 are inconsistent as printed:** Eq. 13 forms K1 from the 90° and
//! 270° positions, but by Fig. 4 those are both 0 g, so `(A₉₀ − A₂₇₀)/2 ≈ 0`. The formulas
//! above use the +1 g (0°) and −1 g (180°) positions, which is what Eq. 13 must mean.
//!
//! # Trace
//! [`trace_run`] replays a run's `temp_c` column through the firmware's view
//! ([`crate::replay::FirmwareRows`]: its readings, its `RateEstimator<32>`, its branch) and
//! `AxisModel::evaluate` once per row ([`trace_axis`] says why not on every reading), so
//! the fit sees the T̂, Ṫ and branch the firmware will see; a run's row (its pulses counted
//! over the row's interval) is seen at the interval's centre.

use std::ops::Range;

use qfa_thermal::model::{AxisState, Branch};
use qfa_thermal::{AxisModel, BiasGrid, Extensions, ScaleFactor};

use crate::cycling::{Log, Run};
use crate::replay::{FirmwareRows, RowInstant};

/// The firmware's view of one run, row by row.
#[derive(Clone, Debug, Default)]
pub struct Trace {
    /// A temperature had been received by this row.
    pub valid: Vec<bool>,
    /// T̂ from the rate estimator, °C.
    pub temp_c: Vec<f64>,
    /// Ṫ, °C/min.
    pub rate_c_per_min: Vec<f64>,
    /// Temperature the model uses (element with `sensor_lag`, else T̂ clamped), °C.
    pub model_temp_c: Vec<f64>,
    /// Bias branch in force.
    pub branch: Vec<Branch>,
    /// Bias from the extension slots (play + creep) with the given parameters, g; from
    /// [`trace_axis`], the whole model's K0.
    pub ext_k0_g: Vec<f64>,
    /// The model clamped T̂ or Ṫ to its calibrated range at this row.
    pub clamped: Vec<bool>,
}

/// Replay `run` through the firmware's view and model with extension slots `ext` and
/// branch deadband `deadband` (°C/min); each row is seen at its interval's centre.
#[must_use]
pub fn trace_run(run: &Run, ext: &Extensions, deadband: f32) -> Trace {
    let rows = run.samples.iter().map(|s| (s.time_s, s.temp_c));
    let view = FirmwareRows::new(rows, RowInstant::IntervalCentre, deadband);
    trace_axis(&view, run.samples.len(), &probe_axis(ext, deadband))
}

/// The extension slots `ext` at unit gains over `view`, each row seen as the view sees it,
/// the branch switching past `deadband` (°C/min): what a fit regresses on.
#[must_use]
pub fn trace_view(view: &FirmwareRows, ext: &Extensions, deadband: f32) -> Trace {
    trace_axis(view, view.rows().len(), &probe_axis(ext, deadband))
}

/// A model with unit gains and a flat zero grid over the sensor's range: its states are
/// the extension slots' and the branch's alone.
fn probe_axis(ext: &Extensions, deadband: f32) -> AxisModel {
    let zeros = [0.0f32; 16];
    let mut bias = BiasGrid::single_valued(-60.0, 190.0 / 15.0, &zeros).expect("2 to 16 grid values");
    bias.deadband_c_per_min = deadband;
    AxisModel { scale: ScaleFactor::simple(22.0, 1.0, 0.0), bias, rate_limit_c_per_min: 20.0, ext: *ext }
}

/// `axis.evaluate` over the first `end` rows of the firmware's `view` (replayed under the
/// axis's own deadband when the view's differs); each row gets the state at the reading
/// that stands for it. `ext_k0_g` is then the model's K0 (g).
///
/// T̂, Ṫ and the branch are the firmware's on every reading; the model's own states (lag,
/// play, creep) step once per row, at the reading that stands for it, with the time since
/// the previous row's, as discovery's do ([`crate::channels::Trace::evaluate_rows`]).
/// Stepping them on every filled-in reading as well made the test that calibrates a 58-h
/// static log at 10-s rows take 278 s instead of 83 s, for held-out figures that moved by
/// about 1 % (`cargo test -p qfa-lab --test discover_independent`, its desk log).
#[must_use]
pub fn trace_axis(view: &FirmwareRows, end: usize, axis: &AxisModel) -> Trace {
    trace_axis_rows(view, 0..end, axis)
}

/// [`trace_axis`] of the rows `rows` only (entry `k` of the trace is row `rows.start + k`):
/// the model's states step through the earlier rows with `AxisModel::advance`, which steps
/// them as `evaluate` does without forming K1 and K0 nobody reads there. A
/// cross-validation block needs its own rows' K0 alone, and stepping the rows before it
/// was about half the cost of evaluating them.
#[must_use]
pub fn trace_axis_rows(view: &FirmwareRows, rows: Range<usize>, axis: &AxisModel) -> Trace {
    trace_axis_rows_from(view, rows, axis, &Resume::start())
}

/// A model's states part-way through a view, where a trace may resume instead of stepping
/// every row before it again ([`resume_points`], [`trace_axis_rows_from`]).
#[derive(Clone, Copy, Debug)]
pub struct Resume {
    /// Rows stepped through.
    row: usize,
    state: AxisState,
    /// The clock of the last reading stepped, ms.
    last_ms: Option<u32>,
}

impl Resume {
    /// Before the first row.
    #[must_use]
    pub fn start() -> Self {
        Self { row: 0, state: AxisState::default(), last_ms: None }
    }
}

/// Step to the reading `s` that stands for a row: the state's branch is the firmware's
/// (which also saw the readings between rows: `Branch::next` of the branch after this
/// reading, at this reading's Ṫ, is itself), `last_ms` moves to its clock; the time since
/// the previous reading stepped, s (0 at the first). One rule for a resume point's pass and a
/// trace.
fn next_reading(st: &mut AxisState, last_ms: &mut Option<u32>, s: &crate::replay::ReadingState) -> f32 {
    st.branch = s.branch;
    let dt = last_ms.map_or(0.0, |p| s.clock_ms.wrapping_sub(p) as f32 * 1e-3);
    *last_ms = Some(s.clock_ms);
    dt
}

/// The row a trace of the rows from `start` on evaluates from: a row whose reading was
/// refused keeps the previous row's values, so the last row before `start` with a reading
/// of its own is evaluated whole.
fn evaluate_from(rows: &[crate::replay::RowView], start: usize) -> usize {
    rows[..start].iter().rposition(|r| r.standing.is_some()).unwrap_or(start)
}

/// For each of `starts` (ascending rows of `view`), where a trace of the rows from it on
/// ([`trace_axis_rows_from`]) resumes, for any model whose slots are `ext`'s at any gains and
/// whose branch deadband is `deadband` (°C/min): one pass over the view for them all.
///
/// Why any gains: the states stepped before a trace's rows (the element temperature, the
/// play's and the creep's) follow the temperatures through the slots' time constants and
/// widths alone; the gains, the grid and the rate limit enter K0 and the state's doubts,
/// never those states (`AxisModel::advance`), and the branch is set from the view at every
/// reading. So a cross-validation's folds, each its own fit, share one pass (the
/// states at each fold's first row) where each fold's trace stepped every row before it,
/// once per axis. A test holds this bit for bit against a trace from the first row.
#[must_use]
pub fn resume_points(view: &FirmwareRows, ext: &Extensions, deadband: f32, starts: &[usize]) -> Vec<Resume> {
    let view = view.for_deadband(deadband);
    let all = view.rows();
    let axis = probe_axis(ext, deadband);
    let mut out = Vec::with_capacity(starts.len());
    let mut at = Resume::start();
    for &start in starts {
        let to = evaluate_from(all, start.min(all.len()));
        debug_assert!(to >= at.row, "starts ascending");
        for row in &all[at.row.min(to)..to] {
            if let Some(s) = row.standing {
                let dt = next_reading(&mut at.state, &mut at.last_ms, &s);
                axis.advance(&mut at.state, s.estimate.temp_c, s.estimate.rate_c_per_min, dt, deadband);
            }
        }
        at.row = at.row.max(to);
        out.push(at);
    }
    out
}

/// [`trace_axis_rows`], its states resumed at `from` (the states of a model with `axis`'s
/// slots after the rows before it: [`resume_points`] or [`Resume::start`]); the same bits
/// as a trace from the first row.
#[must_use]
pub fn trace_axis_rows_from(view: &FirmwareRows, rows: Range<usize>, axis: &AxisModel, from: &Resume) -> Trace {
    let view = view.for_deadband(axis.bias.deadband_c_per_min);
    let all = &view.rows()[..rows.end.min(view.rows().len())];
    let start = rows.start.min(all.len());
    let evaluate_from = evaluate_from(all, start);
    // A resume point past the rows this trace evaluates cannot serve it: from the start.
    let from = if from.row <= evaluate_from { *from } else { Resume::start() };
    let n = all.len() - start;
    let ext = &axis.ext;
    let mut st = from.state;
    let mut tr = Trace {
        valid: Vec::with_capacity(n),
        temp_c: Vec::with_capacity(n),
        rate_c_per_min: Vec::with_capacity(n),
        model_temp_c: Vec::with_capacity(n),
        branch: Vec::with_capacity(n),
        ext_k0_g: Vec::with_capacity(n),
        clamped: Vec::with_capacity(n),
    };
    // (valid, T̂, Ṫ, model temperature, branch, K0, clamped) at the latest row's reading.
    let mut cur = (false, f64::NAN, 0.0, f64::NAN, Branch::Unknown, 0.0, false);
    let mut last_ms = from.last_ms;
    for (i, row) in all.iter().enumerate().skip(from.row) {
        if let Some(s) = row.standing {
            let e = s.estimate;
            let dt = next_reading(&mut st, &mut last_ms, &s);
            if i < evaluate_from {
                axis.advance(&mut st, e.temp_c, e.rate_c_per_min, dt, axis.bias.deadband_c_per_min);
                continue;
            }
            let ev = axis.evaluate(&mut st, e.temp_c, e.rate_c_per_min, dt);
            let te = if ext.sensor_lag.is_some() { st.element_c } else { e.temp_c.clamp(-60.0, 130.0) };
            cur = (
                true,
                f64::from(e.temp_c),
                f64::from(e.rate_c_per_min),
                f64::from(te),
                s.branch,
                f64::from(ev.k0),
                ev.temp_clamped || ev.rate_clamped,
            );
        } else if let Some(branch) = row.branch_after {
            // The reading that stands for the row was refused (a time not after the previous
            // one): the row keeps the previous row's state, as the firmware keeps its last
            // good coefficients; its branch is the firmware's after the row's readings.
            cur.4 = branch;
        }
        if i < start {
            continue;
        }
        tr.valid.push(cur.0);
        tr.temp_c.push(cur.1);
        tr.rate_c_per_min.push(cur.2);
        tr.model_temp_c.push(cur.3);
        tr.branch.push(cur.4);
        tr.ext_k0_g.push(cur.5);
        tr.clamped.push(cur.6);
    }
    tr
}

/// The +1 g and −1 g runs of one program, matched row by row.
#[derive(Clone, Debug)]
pub struct ProgramPairs {
    /// Program id.
    pub program: String,
    /// Index of the +1 g run in `log.runs`.
    pub plus: usize,
    /// Index of the −1 g run in `log.runs`.
    pub minus: usize,
    /// Matched `(row in plus, row in minus)`.
    pub rows: Vec<(usize, usize)>,
}

impl ProgramPairs {
    /// K1 (pulses/(g·s)) and K0 (g) of matched row `k`.
    #[must_use]
    pub fn k1_k0(&self, log: &Log, k: usize) -> (f64, f64) {
        let (i, j) = self.rows[k];
        let p = &log.runs[self.plus].samples[i];
        let m = &log.runs[self.minus].samples[j];
        let ap = p.pulses as f64 / p.interval_s;
        let am = m.pulses as f64 / m.interval_s;
        let gp = log.runs[self.plus].input_g;
        let gm = log.runs[self.minus].input_g;
        // General inputs: A± = K1·(K0 + g±) ⇒ K1 = (A₊ − A₋)/(g₊ − g₋).
        let k1 = (ap - am) / (gp - gm);
        let k0 = (ap + am) / (2.0 * k1) - (gp + gm) / 2.0;
        (k1, k0)
    }
}

/// A cycling log with every program paired once ([`pair_program`]): what a calibration's
/// fit, held-out evaluation and peers read, so none of them pairs the log again. It borrows
/// the log, so the pairs' run indices cannot be read against another log.
#[derive(Clone, Debug)]
pub struct PairedLog<'a> {
    /// The log.
    pub log: &'a Log,
    /// Each program with a +1 g and a −1 g run, in order of first appearance.
    pairs: Vec<ProgramPairs>,
}

impl<'a> PairedLog<'a> {
    /// Pair every program of `log`.
    #[must_use]
    pub fn new(log: &'a Log) -> Self {
        Self { log, pairs: log.programs().iter().filter_map(|p| pair_program(log, p)).collect() }
    }

    /// The pairs of `program`, if it has a +1 g and a −1 g run.
    #[must_use]
    pub fn program(&self, program: &str) -> Option<&ProgramPairs> {
        self.pairs.iter().find(|p| p.program == program)
    }
}

/// Pair the first +1 g run with the first −1 g run of `program`, matching rows by time.
#[must_use]
pub fn pair_program(log: &Log, program: &str) -> Option<ProgramPairs> {
    let plus = log.runs.iter().position(|r| r.program == program && r.input_g > 0.5)?;
    let minus = log.runs.iter().position(|r| r.program == program && r.input_g < -0.5)?;
    let (a, b) = (&log.runs[plus].samples, &log.runs[minus].samples);
    let mut rows = Vec::with_capacity(a.len().min(b.len()));
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        let tol = 0.5 * a[i].interval_s.min(b[j].interval_s);
        let d = a[i].time_s - b[j].time_s;
        if d.abs() <= tol && a[i].interval_s == b[j].interval_s {
            rows.push((i, j));
            i += 1;
            j += 1;
        } else if d < 0.0 {
            i += 1;
        } else {
            j += 1;
        }
    }
    Some(ProgramPairs { program: program.to_string(), plus, minus, rows })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cycling::Sample;

    /// A view replayed once serves a model of another deadband by replaying its rows under
    /// that deadband: the branch a trace reports is the axis's own, never the view's. Rows:
    /// a slow ramp at 0.1 °C/min, between the deadbands 0.05 and 0.182, so the two
    /// deadbands give different branches.
    #[test]
    fn a_model_of_another_deadband_gets_its_own_branch() {
        let rows: Vec<(f64, Option<f64>)> =
            (0..3000).map(|i| (f64::from(i), Some(20.0 + f64::from(i) / 600.0))).collect();
        let wide = FirmwareRows::new(rows.iter().copied(), RowInstant::OwnReading, 0.182);
        let narrow = FirmwareRows::new(rows.iter().copied(), RowInstant::OwnReading, 0.05);
        let axis = probe_axis(&Extensions::NONE, 0.05);
        let through_wide = trace_axis(&wide, rows.len(), &axis);
        let through_narrow = trace_axis(&narrow, rows.len(), &axis);
        assert_eq!(through_wide.branch, through_narrow.branch);
        assert!(through_narrow.branch.contains(&Branch::Heating), "the ramp heats past 0.05 °C/min");
        let wide_axis = trace_axis(&wide, rows.len(), &probe_axis(&Extensions::NONE, 0.182));
        assert!(!wide_axis.branch.contains(&Branch::Heating), "0.1 °C/min stays inside 0.182 °C/min");
    }

    /// A trace of some rows is those rows of the whole trace, bit for bit: over random
    /// ranges of a log with rows refused now and then (a time not after the previous, so a
    /// range may open on rows that carry an earlier row's values), missing readings, and a
    /// model with every extension slot.
    #[test]
    fn a_trace_of_some_rows_is_those_rows_of_the_whole_trace() {
        let mut rng = qfa_rng::seeded(17);
        let mut next = || qfa_rng::uniform(&mut rng);
        let (mut t, mut temp) = (0.0, 20.0);
        let rows: Vec<(f64, Option<f64>)> = (0..4000)
            .map(|i| {
                if i % 37 != 0 {
                    t += 1.0 + 9.0 * next();
                }
                temp += 0.4 * next() - 0.19;
                (t, (i % 53 != 0).then_some(temp))
            })
            .collect();
        let view = FirmwareRows::new(rows.iter().copied(), RowInstant::OwnReading, 0.182);
        let mut axis = probe_axis(
            &Extensions {
                sensor_lag: Some(qfa_thermal::model::SensorLag { tau_s: 120.0 }),
                bias_branch_hysteresis: Some(qfa_thermal::model::BranchHysteresis {
                    half_width_c: 0.8,
                    weight_g: 3e-4,
                }),
                bias_creep: Some(qfa_thermal::model::Creep {
                    gain_g_per_c: 2e-6,
                    tau_ref_s: 900.0,
                    t_ref_c: 25.0,
                    activation_k: 3000.0,
                }),
            },
            0.182,
        );
        axis.bias.heating_g.iter_mut().enumerate().for_each(|(j, v)| *v = 1e-4 * j as f32);
        let whole = trace_axis(&view, rows.len(), &axis);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for _ in 0..40 {
            let a = (next() * rows.len() as f64) as usize;
            let b = (a + (next() * 600.0) as usize).min(rows.len());
            let part = trace_axis_rows(&view, a..b, &axis);
            assert_eq!(part.valid, whole.valid[a..b]);
            assert_eq!(bits(&part.temp_c), bits(&whole.temp_c[a..b]));
            assert_eq!(bits(&part.rate_c_per_min), bits(&whole.rate_c_per_min[a..b]));
            assert_eq!(bits(&part.model_temp_c), bits(&whole.model_temp_c[a..b]));
            assert_eq!(part.branch, whole.branch[a..b]);
            assert_eq!(bits(&part.ext_k0_g), bits(&whole.ext_k0_g[a..b]), "rows {a}..{b}");
            assert_eq!(part.clamped, whole.clamped[a..b]);
        }
    }

    /// A trace resumed where [`resume_points`] put it, the points stepped by a model of the
    /// same slots at other gains, another grid and another rate limit, is the trace from the
    /// first row, bit for bit: over random logs (rows refused now and then, missing
    /// readings), every combination of slots, and random sets of starts. A resume point
    /// stepped with another lag's τ must not be (the check can fail).
    #[test]
    fn a_trace_resumed_at_its_resume_point_is_the_trace_from_the_first_row() {
        let mut rng = qfa_rng::seeded(qfa_rng::stream_seed(49, qfa_rng::Stream::named("resume test"), 0));
        let mut next = || qfa_rng::uniform(&mut rng);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let (mut compared, mut other_tau_differs) = (0usize, 0usize);
        for case in 0..8u32 {
            let (mut t, mut temp) = (0.0, -20.0 + 60.0 * next());
            let rows: Vec<(f64, Option<f64>)> = (0..3000)
                .map(|i| {
                    if i % 41 != 0 {
                        t += 1.0 + 4.0 * next();
                    }
                    temp += 0.3 * next() - 0.14;
                    (t, (i % 59 != 0).then_some(temp))
                })
                .collect();
            let view = FirmwareRows::new(rows.iter().copied(), RowInstant::OwnReading, 0.182);
            let slots = |gain: f32, tau: f32| Extensions {
                sensor_lag: (case & 1 != 0).then_some(qfa_thermal::model::SensorLag { tau_s: tau }),
                bias_branch_hysteresis: (case & 2 != 0)
                    .then_some(qfa_thermal::model::BranchHysteresis { half_width_c: 0.6, weight_g: 2e-4 * gain }),
                bias_creep: (case & 4 != 0).then_some(qfa_thermal::model::Creep {
                    gain_g_per_c: 3e-6 * gain,
                    tau_ref_s: 600.0,
                    t_ref_c: 25.0,
                    activation_k: 0.0,
                }),
            };
            // The model traced: its own gains, a grid over part of the range, a low rate limit.
            let mut axis = probe_axis(&slots(1.7, 120.0), 0.182);
            axis.bias = BiasGrid::single_valued(-10.0, 2.0, &[0.0; 16]).expect("16 values");
            axis.bias.heating_g.iter_mut().enumerate().for_each(|(j, v)| *v = 2e-4 * j as f32);
            axis.bias.cooling_g.iter_mut().enumerate().for_each(|(j, v)| *v = -1e-4 * j as f32);
            axis.bias.deadband_c_per_min = 0.182;
            axis.rate_limit_c_per_min = 0.5;
            let whole = trace_axis(&view, rows.len(), &axis);
            let mut starts: Vec<usize> = (0..5).map(|_| (next() * rows.len() as f64) as usize).collect();
            starts.sort_unstable();
            let points = resume_points(&view, &slots(1.0, 120.0), 0.182, &starts);
            let other = resume_points(&view, &slots(1.0, 240.0), 0.182, &starts);
            for ((&a, from), other) in starts.iter().zip(&points).zip(&other) {
                let b = (a + 1 + (next() * 400.0) as usize).min(rows.len());
                let part = trace_axis_rows_from(&view, a..b, &axis, from);
                assert_eq!(part.valid, whole.valid[a..b]);
                assert_eq!(bits(&part.model_temp_c), bits(&whole.model_temp_c[a..b]), "case {case} rows {a}..{b}");
                assert_eq!(part.branch, whole.branch[a..b]);
                assert_eq!(bits(&part.ext_k0_g), bits(&whole.ext_k0_g[a..b]), "case {case} rows {a}..{b}");
                assert_eq!(part.clamped, whole.clamped[a..b]);
                compared += 1;
                if case & 1 != 0 && a > 100 {
                    let wrong = trace_axis_rows_from(&view, a..b, &axis, other);
                    other_tau_differs += usize::from(bits(&wrong.ext_k0_g) != bits(&whole.ext_k0_g[a..b]));
                }
            }
        }
        assert_eq!(compared, 40);
        assert!(other_tau_differs >= 10, "a resume point of another lag gave the same trace: {other_tau_differs}");
    }

    fn run(program: &str, input_g: f64, pulses: &[i64], t0: f64) -> Run {
        let samples = pulses
            .iter()
            .enumerate()
            .map(|(i, &p)| Sample { time_s: t0 + i as f64, temp_c: Some(22.0), pulses: p, interval_s: 1.0 })
            .collect();
        Run { program: program.to_string(), run: "0".to_string(), input_g, samples }
    }

    #[test]
    fn pairing_by_time_gives_k1_and_k0() {
        // K1 = 1000, K0 = 0.01: A₊ = 1010, A₋ = −990.
        let log = Log {
            runs: vec![run("p", 1.0, &[1010, 1010, 1010], 1.0), run("p", -1.0, &[-990, -990], 2.0)],
            ..Log::default()
        };
        let pp = pair_program(&log, "p").unwrap();
        assert_eq!(pp.rows, vec![(1, 0), (2, 1)]);
        let (k1, k0) = pp.k1_k0(&log, 0);
        assert_eq!(k1, 1000.0);
        assert!((k0 - 0.01).abs() < 1e-15);
    }
}
