//! Channels: the scale-factor and bias series the discovery workflow compares the model
//! against, formed from a cycling log (±1 g runs paired by time) or a single-channel log.
//!
//! Every program keeps its temperature trace as the firmware sees it ([`crate::replay`]:
//! its readings, one a second, and its `RateEstimator<32>`); the measured channels are
//! averaged into bins (default 60 s) to cut noise. A model is evaluated on every row
//! ([`Trace::evaluate_rows`]) and averaged over the same bins.

use std::path::Path;

use qfa_thermal::model::{Advanced, AxisState, Branch, Evaluation};
use qfa_thermal::AxisModel;

use crate::open::{open, open_bytes, OpenedLog, ReadFlags};
use crate::replay::{branch_deadband_c_per_min, FirmwareRows, Motion, RowInstant, RowSeen};
use crate::single::SingleLog;

/// Kind of log the channels came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LogKind {
    /// Four-position cycling log: scale factor (pulses/(g·s)) and bias (g) channels.
    Cycling,
    /// `time_s,temp_c,value`: one output in any unit, treated as the bias channel.
    Single,
}

/// Unit of the bias channel's values as the channels hold them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BiasUnit {
    /// g: a cycling log's K0 (reported in µg).
    G,
    /// µg: a static axis, converted by the lab.
    Ug,
    /// A single-channel log's own unit, which the lab does not know.
    Value,
}

impl BiasUnit {
    /// Unit of the bias in reports.
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            Self::G | Self::Ug => "µg",
            Self::Value => "value units",
        }
    }

    /// Factor from the held value to the reported one.
    #[must_use]
    pub fn to_report(self) -> f64 {
        if self == Self::G {
            1e6
        } else {
            1.0
        }
    }

    /// A bias parameter's report name: `stem`, the unit, then `per` (`weight_ug`,
    /// `drift_ug_per_h`; `drift_per_h` when the unit is the log's own).
    #[must_use]
    pub fn param(self, stem: &str, per: &str) -> String {
        match self {
            Self::G | Self::Ug => format!("{stem}_ug{per}"),
            Self::Value => format!("{stem}{per}"),
        }
    }
}

/// One averaging bin: rows `lo..hi` of its trace.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bin {
    /// First row.
    pub lo: usize,
    /// One past the last row.
    pub hi: usize,
    /// Mean time of the rows, s.
    pub time_s: f64,
    /// Measured K1, pulses/(g·s) (NaN for a single-channel log).
    pub sf: f64,
    /// Measured K0 in g (cycling) or the mean value (single-channel).
    pub bias: f64,
}

/// One temperature program: the firmware's view of its temperature and the measured bins.
#[derive(Clone, Debug)]
pub struct Trace {
    /// Program id from the log.
    pub program: String,
    /// Row times, s.
    pub time_s: Vec<f64>,
    /// DS18B20 raw readings, 1/16 °C.
    pub temp_raw: Vec<i16>,
    /// The estimator's temperature at the reading that stands for each row, °C.
    pub est_t: Vec<f32>,
    /// The estimator's Ṫ there, °C/min.
    pub est_rate: Vec<f32>,
    /// Seconds since the previous row (0 for the first).
    pub dt_s: Vec<f32>,
    /// The firmware's bias branch at each row ([`crate::replay::Seen::branch`]).
    pub branch: Vec<Branch>,
    /// Bins.
    pub bins: Vec<Bin>,
}

/// The kept rows (`time_s`, and `keep`: each one's index in the measured channels) in
/// bins of `bin_s` seconds: `sf` averaged and the bias as `mean(sf·bias)/mean(sf)` when
/// `sf` is given, else the bias averaged.
fn bin_rows(time_s: &[f64], keep: &[usize], sf: Option<&[f64]>, bias: &[f64], bin_s: f64) -> Vec<Bin> {
    let mut bins = Vec::new();
    let mut lo = 0;
    while lo < time_s.len() {
        let key = (time_s[lo] / bin_s).floor();
        let mut hi = lo + 1;
        while hi < time_s.len() && (time_s[hi] / bin_s).floor() == key {
            hi += 1;
        }
        let m = (hi - lo) as f64;
        let t_mean = time_s[lo..hi].iter().sum::<f64>() / m;
        let (sf_b, bias_b) = match sf {
            Some(sf) => {
                let s: f64 = keep[lo..hi].iter().map(|&k| sf[k]).sum::<f64>() / m;
                let sb: f64 = keep[lo..hi].iter().map(|&k| sf[k] * bias[k]).sum::<f64>() / m;
                (s, sb / s)
            }
            None => (f64::NAN, keep[lo..hi].iter().map(|&k| bias[k]).sum::<f64>() / m),
        };
        if sf_b.is_finite() || sf.is_none() {
            bins.push(Bin { lo, hi, time_s: t_mean, sf: sf_b, bias: bias_b });
        }
        lo = hi;
    }
    bins
}

impl Trace {
    /// Build a trace from rows `(time_s, temp_c)` through the firmware's view and bin the
    /// measured channels. `sf` and `bias` are per-row measured values; bins average `sf` and
    /// form the bias as `mean(sf·bias)/mean(sf)` (the pairing's K0) when `sf` is given. With
    /// `sf` the rows are pulse counts over their intervals, seen at the intervals' centres.
    #[must_use]
    pub fn new(program: String, rows: &[(f64, f32)], sf: Option<&[f64]>, bias: &[f64], bin_s: f64) -> Self {
        let n = rows.len();
        let instant = if sf.is_some() { RowInstant::IntervalCentre } else { RowInstant::OwnReading };
        let view = FirmwareRows::new(
            rows.iter().map(|&(t, temp)| (t, Some(f64::from(temp)))),
            instant,
            branch_deadband_c_per_min(),
        );
        let mut time_s = Vec::with_capacity(n);
        let mut temp_raw = Vec::with_capacity(n);
        let mut est_t = Vec::with_capacity(n);
        let mut est_rate = Vec::with_capacity(n);
        let mut dt_s = Vec::with_capacity(n);
        let mut branch = Vec::with_capacity(n);
        let mut keep = Vec::with_capacity(n);
        let mut last: Option<f64> = None;
        for (i, (&(t, _), row)) in rows.iter().zip(view.rows()).enumerate() {
            // A row whose own reading was refused (time not after the previous) is dropped:
            // the firmware rejects it too.
            let (RowSeen::Accepted, Some(own)) = (row.seen, row.own) else { continue };
            let at_row = row.standing.unwrap_or(own);
            time_s.push(t);
            temp_raw.push(own.raw);
            est_t.push(at_row.estimate.temp_c);
            est_rate.push(at_row.estimate.rate_c_per_min);
            branch.push(at_row.branch);
            dt_s.push(last.map_or(0.0, |p| (t - p) as f32));
            last = Some(t);
            keep.push(i);
        }
        let bins = bin_rows(&time_s, &keep, sf, bias, bin_s);
        Self { program, time_s, temp_raw, est_t, est_rate, dt_s, branch, bins }
    }

    /// Run `model` over the rows, each with its T̂, Ṫ and the seconds since the previous
    /// row, and call `at_row(row, state, evaluation)` after each: the one loop in which
    /// discovery evaluates a model.
    ///
    /// The model's states (lag, play, creep) step once per row, not on every filled-in
    /// reading as the firmware's do: discovery evaluates a model per candidate and per
    /// nonlinear parameter, and stepping on every reading made its tests on 10-s rows take
    /// 158 s instead of 75 s for gains that moved by under 1 % (`cargo test -p qfa-lab
    /// --test discover -- --nocapture`).
    /// T̂, Ṫ and the branch are the firmware's either way (calibration's trace steps the same
    /// way, [`crate::pairing::trace_axis`]).
    pub fn evaluate_rows(&self, model: &AxisModel, mut at_row: impl FnMut(usize, &AxisState, &Evaluation)) {
        self.step_rows(|i, st| {
            let e = model.evaluate(st, self.est_t[i], self.est_rate[i], self.dt_s[i]);
            at_row(i, st, &e);
        });
    }

    /// [`Self::evaluate_rows`] stepping the model's states only ([`AxisModel::advance`],
    /// at the table's deadband as `evaluate` steps them): for a caller that reads the states
    /// (Te, play, creep) and not K1, K0 or the settling flag.
    pub fn advance_rows(&self, model: &AxisModel, mut at_row: impl FnMut(usize, &AxisState, &Advanced)) {
        let deadband = model.bias.deadband_c_per_min;
        self.step_rows(|i, st| {
            let a = model.advance(st, self.est_t[i], self.est_rate[i], self.dt_s[i], deadband);
            at_row(i, st, &a);
        });
    }

    /// `step(row, state)` for each row, one model state carried through, its branch set to
    /// the firmware's at the row before the step.
    fn step_rows(&self, mut step: impl FnMut(usize, &mut AxisState)) {
        let mut st = AxisState::default();
        for i in 0..self.est_t.len() {
            // The model's branch is the firmware's, which also saw the readings between rows
            // (`Branch::next` of the branch after a reading, at its Ṫ, is itself).
            st.branch = self.branch[i];
            step(i, &mut st);
        }
    }

    /// Ramp rate of the program, °C/min: the number at the end of its id when there is
    /// one (the lab's `paper-0.5`), else the mean |Ṫ| while ramping ([`Motion::direction`]).
    #[must_use]
    pub fn ramp_rate(&self) -> f64 {
        self.named_rate().unwrap_or_else(|| self.measured_ramp_rate())
    }

    /// The rate at the end of the program's id (the lab's `paper-0.5`), °C/min, if any.
    fn named_rate(&self) -> Option<f64> {
        let tail = self.program.rsplit(['-', '_', '@', ' ', '=']).next().unwrap_or("");
        tail.parse::<f64>().ok().filter(|x| *x > 0.0 && *x <= 20.0)
    }

    /// The program's rate in words: its id's rate beside what the unit's Ṫ reads while
    /// ramping when the two differ by over a tenth (a staircase's dwells keep the unit
    /// below its steps' rate: the lab's `paper-0.9` reads about 0.24 °C/min), else the one.
    #[must_use]
    pub fn ramp_rate_words(&self) -> String {
        let measured = self.measured_ramp_rate();
        match self.named_rate() {
            Some(named) if (named - measured).abs() > 0.1 * named => {
                format!("{named:.1} °C/min in its name; the unit's Ṫ reads {measured:.2} while ramping")
            }
            _ => format!("{:.2} °C/min", self.ramp_rate()),
        }
    }

    /// Mean |Ṫ| while ramping ([`Motion::direction`]), °C/min; 0 for a trace that holds.
    #[must_use]
    pub fn measured_ramp_rate(&self) -> f64 {
        let r: Vec<f64> = self
            .est_rate
            .iter()
            .map(|&x| f64::from(x))
            .filter(|&x| Motion::direction(x) != Motion::Holding)
            .map(f64::abs)
            .collect();
        if r.is_empty() {
            0.0
        } else {
            r.iter().sum::<f64>() / r.len() as f64
        }
    }

    /// Mean T̂ (°C) and Ṫ (°C/min) of the rows of `bin`.
    #[must_use]
    pub fn bin_means(&self, bin: &Bin) -> (f64, f64) {
        let m = (bin.hi - bin.lo) as f64;
        let t = self.est_t[bin.lo..bin.hi].iter().map(|&x| f64::from(x)).sum::<f64>() / m;
        let r = self.est_rate[bin.lo..bin.hi].iter().map(|&x| f64::from(x)).sum::<f64>() / m;
        (t, r)
    }
}

/// The channels of one log.
#[derive(Clone, Debug)]
pub struct Channels {
    /// Which kind of log.
    pub kind: LogKind,
    /// Unit of the bias channel.
    pub bias_unit: BiasUnit,
    /// One trace per program.
    pub traces: Vec<Trace>,
    /// Rows the cycling reader skipped as one-row glitches ([`crate::cycling::Glitch`]).
    pub skipped_glitches: Vec<crate::cycling::Glitch>,
}

/// Why a log gives no discovery channels.
#[derive(Debug)]
#[non_exhaustive]
pub enum ChannelsError {
    /// The log could not be opened or read (the file, and its reader's error).
    Open(crate::open::OpenError),
    /// Log text its reader refused (each malformed row with its line).
    Read(crate::open::ReadError),
    /// A cycling log in which no program has paired ±1 g runs with at least 8 rows.
    NoPairedRuns,
    /// The paired runs hold what no fit can be right on (a stuck counter or sensor).
    Contents(crate::cycling::ContentFault),
    /// A static multi-axis log: its channels are formed per axis, by discovery's own reader.
    StaticLog,
    /// An autopilot log (PX4 ULog or ArduPilot DataFlash): calibrated, not discovered.
    AutopilotLog {
        /// The stack that wrote it.
        stack: crate::autopilot::Stack,
    },
}

impl std::fmt::Display for ChannelsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Open(e) => write!(f, "{e}"),
            Self::Read(e) => write!(f, "{e}"),
            Self::NoPairedRuns => f.write_str("no program has paired +1 g and -1 g runs with at least 8 rows"),
            Self::Contents(e) => write!(f, "{e}"),
            Self::StaticLog => f.write_str(
                "a static multi-axis log: its channels are formed per axis (discover reads it with the static \
                 reader's flags); expected program,run,time_s,input_g,temp_c,pulses,interval_s or time_s,temp_c,value",
            ),
            Self::AutopilotLog { stack } => {
                write!(
                    f,
                    "a {stack}: calibrate reads it (one calibration per accelerometer instance); discover does not"
                )
            }
        }
    }
}

impl std::error::Error for ChannelsError {}

impl Channels {
    /// Number of bins over all traces.
    #[must_use]
    pub fn n_bins(&self) -> usize {
        self.traces.iter().map(|t| t.bins.len()).sum()
    }

    /// Channels of a cycling log: per program, the first +1 g and −1 g runs paired by
    /// [`crate::pairing::pair_program`]; the program temperature of a pair is the
    /// mean of both runs' readings (either one when only one has a reading yet).
    ///
    /// # Errors
    /// No program has paired ±1 g runs with at least 8 rows.
    pub(crate) fn from_cycling(log: &crate::cycling::Log, bin_s: f64) -> Result<Self, ChannelsError> {
        // The programs with a ±1 g pair are the ones discovery fits: checked as calibration
        // checks its fit programs, so a stuck counter or sensor is named, not fitted.
        let paired: Vec<String> =
            log.programs().into_iter().filter(|p| crate::pairing::pair_program(log, p).is_some()).collect();
        log.check_contents(&paired).map_err(ChannelsError::Contents)?;
        let mut traces = Vec::new();
        for prog in log.programs() {
            let Some(pp) = crate::pairing::pair_program(log, &prog) else {
                continue; // a program without both ±1 g runs gives no channels
            };
            let (plus, minus) = (&log.runs[pp.plus].samples, &log.runs[pp.minus].samples);
            let (mut rows, mut sf, mut bias) = (Vec::new(), Vec::new(), Vec::new());
            for (k, &(i, j)) in pp.rows.iter().enumerate() {
                let temp = match (plus[i].temp_c, minus[j].temp_c) {
                    (Some(a), Some(b)) => 0.5 * (a + b),
                    (Some(a), None) | (None, Some(a)) => a,
                    (None, None) => continue,
                };
                let (k1, k0) = pp.k1_k0(log, k);
                rows.push((plus[i].time_s, temp as f32));
                sf.push(k1);
                bias.push(k0);
            }
            if rows.len() >= 8 {
                traces.push(Trace::new(prog, &rows, Some(&sf), &bias, bin_s));
            }
        }
        if traces.is_empty() {
            return Err(ChannelsError::NoPairedRuns);
        }
        Ok(Self { kind: LogKind::Cycling, bias_unit: BiasUnit::G, traces, skipped_glitches: log.glitches.clone() })
    }

    /// Channels of a single-channel log: its value is the bias channel, in its own unit.
    #[must_use]
    pub(crate) fn from_single(log: &SingleLog, bin_s: f64) -> Self {
        let rows: Vec<(f64, f32)> = log.time_s.iter().copied().zip(log.temp_c.iter().copied()).collect();
        Self {
            kind: LogKind::Single,
            bias_unit: BiasUnit::Value,
            traces: vec![Trace::new("log".into(), &rows, None, &log.value, bin_s)],
            skipped_glitches: Vec::new(),
        }
    }

    /// Channels of an opened log (cycling or single-channel; a static log's axes are
    /// formed per axis by discovery's `static_axes` in qfa-calibrate).
    ///
    /// # Errors
    /// A static log, or a cycling log without paired ±1 g runs.
    pub fn from_opened(log: &OpenedLog, bin_s: f64) -> Result<Self, ChannelsError> {
        match log {
            OpenedLog::Cycling(l) => Self::from_cycling(l, bin_s),
            OpenedLog::Single(l) => Ok(Self::from_single(l, bin_s)),
            OpenedLog::Static(_) => Err(ChannelsError::StaticLog),
            OpenedLog::Autopilot(l) => Err(ChannelsError::AutopilotLog { stack: l.stack }),
        }
    }

    /// Read a cycling or single-channel log ([`crate::open`] decides which).
    ///
    /// # Errors
    /// The reader's error (each malformed row with its line), or as [`Channels::from_opened`].
    pub fn read(path: &Path, bin_s: f64) -> Result<Self, ChannelsError> {
        Self::from_opened(&open(path, &ReadFlags::default()).map_err(ChannelsError::Open)?, bin_s)
    }

    /// Parse log text (see [`Channels::read`]).
    ///
    /// # Errors
    /// As [`Channels::read`].
    pub fn parse(text: &str, bin_s: f64) -> Result<Self, ChannelsError> {
        Self::from_opened(&open_bytes(text.as_bytes(), &ReadFlags::default()).map_err(ChannelsError::Read)?, bin_s)
    }
}

/// A log with its channels, what discovery reads: a cycling log (its channels, and the log
/// whose ±1 g pairs its table is fitted on, as `calibrate` fits them) or a single-channel log.
#[derive(Debug)]
pub enum Source {
    /// A cycling log and its channels.
    Cycling {
        /// The log.
        log: Box<crate::cycling::Log>,
        /// Its channels.
        channels: Channels,
    },
    /// A single-channel log's channels.
    Single(Channels),
}

impl Source {
    /// The source of an opened log, binned at `bin_s`.
    ///
    /// # Errors
    /// As [`Channels::from_opened`]: a static or autopilot log, a cycling log without pairs.
    pub fn from_opened(opened: OpenedLog, bin_s: f64) -> Result<Self, ChannelsError> {
        let channels = Channels::from_opened(&opened, bin_s)?;
        Ok(match opened {
            OpenedLog::Cycling(log) => Self::Cycling { log: Box::new(log), channels },
            _ => Self::Single(channels),
        })
    }

    /// Read a cycling or single-channel log.
    ///
    /// # Errors
    /// The reader's error, or as [`Source::from_opened`].
    pub fn read(path: &Path, bin_s: f64) -> Result<Self, ChannelsError> {
        Self::from_opened(open(path, &ReadFlags::default()).map_err(ChannelsError::Open)?, bin_s)
    }

    /// Parse log text (see [`Source::read`]).
    ///
    /// # Errors
    /// As [`Source::read`].
    pub fn parse(text: &str, bin_s: f64) -> Result<Self, ChannelsError> {
        Self::from_opened(open_bytes(text.as_bytes(), &ReadFlags::default()).map_err(ChannelsError::Read)?, bin_s)
    }

    /// The channels the catalog reads.
    #[must_use]
    pub fn channels(&self) -> &Channels {
        match self {
            Self::Cycling { channels, .. } | Self::Single(channels) => channels,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each log that gives no channels says why, as its own variant: malformed rows with
    /// their lines, a cycling log without a ±1 g pair.
    #[test]
    fn a_log_without_channels_is_a_typed_error() {
        let header = "program,run,time_s,input_g,temp_c,pulses,interval_s\n";
        let bad = format!("{header}p,0,1,1,22.0,100,1\np,0,x,1,22.0,100,1\n");
        match Channels::parse(&bad, 60.0) {
            Err(e @ ChannelsError::Read(_)) => assert!(e.to_string().contains("line 3"), "{e}"),
            other => panic!("{other:?}"),
        }
        let plus_only: String =
            std::iter::once(header.to_string()).chain((1..20).map(|i| format!("p,0,{i},1,22.0,320000,1\n"))).collect();
        assert!(matches!(Channels::parse(&plus_only, 60.0), Err(ChannelsError::NoPairedRuns)));
    }

    /// A staircase named for its steps' rate says what its unit's Ṫ reads too; a trace
    /// whose name carries no rate, or the rate it reads, says one figure.
    #[test]
    fn a_programs_rate_in_words_is_what_its_rows_read() {
        let trace = |program: &str, rate: f32| Trace {
            program: program.into(),
            time_s: (0..10).map(f64::from).collect(),
            temp_raw: vec![0; 10],
            est_t: vec![0.0; 10],
            est_rate: vec![rate; 10],
            dt_s: vec![1.0; 10],
            branch: vec![Branch::Unknown; 10],
            bins: Vec::new(),
        };
        assert_eq!(
            trace("paper-0.9", 0.24).ramp_rate_words(),
            "0.9 °C/min in its name; the unit's Ṫ reads 0.24 while ramping"
        );
        assert_eq!(trace("paper-0.9", -0.88).ramp_rate_words(), "0.90 °C/min");
        assert_eq!(trace("chamber", 0.37).ramp_rate_words(), "0.37 °C/min");
        assert_eq!(trace("paper-0.9", 0.24).ramp_rate(), 0.9, "the folds' order keeps the name's rate");
    }
}
