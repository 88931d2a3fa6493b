//! Compensation of a log through the root crate's `Compensator<1, 32>`, as the firmware runs it.
//!
//! Per row, in order: the firmware's readings up to the one at the row's interval's centre
//! ([`qfa_log::replay`]: the row's own when no 1-s readings were filled in before it), each
//! through `on_raw` (a rejected reading leaves the last good compensation in force, as on
//! target); then `cycle([pulses], interval_s·10⁶ ticks)` with the default 1-µs tick; then
//! the rest of the row's readings. The fit sees each row at the same reading (see
//! [`qfa_log::pairing::trace_run`]).
//! `accel_g = Δv / (g0 · interval_s)`: the compensated mean specific force of the interval.
//! Each run starts a fresh compensator (each run is a fresh power-up in the test).
//! The staleness limit is at least 1.5 rows (see [`compensate_run`]).

use qfa_thermal::compensator::{Compensator, Config, Status, G0};
use qfa_thermal::table::Input;
use qfa_thermal::Table;

use qfa_log::cycling::{Log, Run};
use qfa_log::replay::{clock_ms, Readings, RowInstant, FILL_FROM_S, RATE_WINDOW, READING_PERIOD_S};

/// K1 of a static log's table, LSB/g. A static log holds accelerations as numbers (g after
/// the unit flags), while the firmware's sample path takes integer LSB:
/// `raw = round(a·2²⁰)` quantizes to 0.95 µg, three orders below the figures that matter,
/// and keeps |raw| below 2²⁴ for |a| < 16 g, where f32 holds every integer exactly.
pub const STATIC_LSB_PER_G: f32 = qfa_thermal::table::SAMPLE_UNITS_PER_G;

/// Why a log could not be compensated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Error {
    /// The table was refused.
    Table(qfa_thermal::table::Error),
    /// The log's row length gives a compensator configuration the firmware refuses (rows
    /// longer than the rate window's 30-s gap limit, say).
    Config(qfa_thermal::ConfigError),
}

/// What kind of log gives `input`, and the table of which kind of calibration converts it.
fn log_kind(input: Input) -> (&'static str, &'static str) {
    match input {
        Input::PulseCounts => ("cycling log", "a cycling log"),
        Input::Samples => ("static multi-axis log", "a static multi-axis log"),
    }
}

/// The refusal of a table of the other kind, naming both (`table` is what it converts,
/// `log` what the log gives).
fn wrong_input(f: &mut std::fmt::Formatter<'_>, table: Input, log: Input) -> std::fmt::Result {
    let (log_name, _) = log_kind(log);
    let (_, table_from) = log_kind(table);
    let want = match log {
        Input::PulseCounts => "a cycling log",
        Input::Samples => "a static log",
    };
    write!(
        f,
        "table refused: it converts {table} (calibrated on {table_from}), and this {log_name} gives {log}: compensate \
         it with a table calibrated on {want}"
    )
}

/// The kind check, before any other: a table of the other kind may also differ in its
/// axis count, and "3 axes, expected 1" would hide the real mistake.
fn check_input(table: &Table, log: Input) -> Result<(), qfa_thermal::table::Error> {
    if table.input == log {
        Ok(())
    } else {
        Err(qfa_thermal::table::Error::Input { table: table.input, compensator: log })
    }
}

impl std::fmt::Display for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Table(qfa_thermal::table::Error::Input { table, compensator }) => {
                wrong_input(f, *table, *compensator)
            }
            Self::Table(e) => write!(f, "table refused: {e}"),
            Self::Config(e) => write!(f, "rows too long for the firmware's settings: {e}"),
        }
    }
}

impl std::error::Error for Error {}

/// Compensated output of one run.
#[derive(Clone, Debug, Default)]
pub struct Compensated {
    /// Specific force per row, g.
    pub accel_g: Vec<f64>,
    /// Status word per row.
    pub status: Vec<u16>,
    /// The log's readings the compensator rejected, by reason (the 1-s readings the replay
    /// fills in between rows are not counted).
    pub rejected: Rejections,
}

/// Temperature readings the firmware refused, by reason: a count alone gave no cause.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Rejections {
    /// Outside the DS18B20's −55…+125 °C, which its decoder refuses (a chamber program that
    /// goes to −60 °C, as the paper's does, leaves the sensor's range there).
    pub outside_sensor_range: usize,
    /// Refused for any other reason (a jump, a time step, the power-on value).
    pub other: usize,
}

impl Rejections {
    /// Count one refusal by its reason.
    pub fn count(&mut self, e: &qfa_thermal::SampleError) {
        match e {
            qfa_thermal::SampleError::Decode(qfa_thermal::ds18b20::Error::OutOfRange { .. }) => {
                self.outside_sensor_range += 1;
            }
            _ => self.other += 1,
        }
    }

    /// Every refusal.
    #[must_use]
    pub fn total(&self) -> usize {
        self.outside_sensor_range + self.other
    }

    /// Both counts added.
    pub fn add(&mut self, o: Rejections) {
        self.outside_sensor_range += o.outside_sensor_range;
        self.other += o.other;
    }
}

/// The firmware's IMU period for a log whose rows are its cycles: the median row spacing
/// (a logging gap is then a cycle the firmware flags `DT_IMPLAUSIBLE`, as it would flag
/// missed IMU cycles), kept within what [`Config::imu_period_s`] takes (1 ms..60 s).
fn row_period_s(spacings_s: impl Iterator<Item = f64>) -> f32 {
    let mut d: Vec<f64> = spacings_s.filter(|d| d.is_finite() && *d > 0.0).collect();
    d.sort_by(f64::total_cmp);
    let median = d.get(d.len() / 2).copied().unwrap_or(1.0);
    median.clamp(1e-3, 60.0) as f32
}

/// Compensate one run with `table`.
///
/// A row longer than [`FILL_FROM_S`] is run as the firmware runs those seconds: cycles of
/// at most [`READING_PERIOD_S`] on a 1-s grid from the row's start, the row's pulses shared
/// among them in proportion to their length (the input is taken as steady within a row),
/// each cycle after the readings taken by its end ([`qfa_log::replay`] fills in the 1-s
/// readings between rows). One coefficient per 10-s row instead would put one sample of the
/// estimator's Ṫ jitter on each row, where the firmware averages ten. A shorter row is one
/// cycle after its reading.
///
/// # Errors
/// A table of the other kind (samples, from a static log), a table that does not load into
/// a `Compensator<1, 32>`, or rows too long for it.
pub fn compensate_run(table: &Table, run: &Run) -> Result<Compensated, Error> {
    check_input(table, Input::PulseCounts).map_err(Error::Table)?;
    // With the readings filled in and long rows cut into 1-s cycles, the firmware's own
    // configuration applies: its staleness limit and sample period; rows further apart
    // than the estimator's gap limit are then stale, as the firmware would find them.
    let config = Config {
        imu_period_s: row_period_s(run.samples.iter().map(|s| s.interval_s.min(READING_PERIOD_S))),
        ..Config::default()
    };
    let mut c = Compensator::<1, RATE_WINDOW>::new(config).map_err(Error::Config)?;
    c.set_table(table.clone()).map_err(Error::Table)?;
    let tick_us = f64::from(c.config().tick_s) * 1e6;
    let mut out = Compensated {
        accel_g: Vec::with_capacity(run.samples.len()),
        status: Vec::with_capacity(run.samples.len()),
        rejected: Rejections::default(),
    };
    let mut readings = Readings::new();
    let mut buf = Vec::new();
    for s in &run.samples {
        readings.row(s.time_s, s.temp_c, RowInstant::OwnReading, &mut buf);
        let start_ms = clock_ms(s.time_s - s.interval_s);
        let total_ms = f64::from(clock_ms(s.time_s).wrapping_sub(start_ms).max(1));
        let step_ms = if s.interval_s > FILL_FROM_S { (READING_PERIOD_S * 1000.0) as u32 } else { u32::MAX };
        // Milliseconds since the row's start; a filled reading before it (a missing row) is
        // taken before the first cycle.
        let since_start = |ms: u32| (ms.wrapping_sub(start_ms) as i32).max(0) as u32;
        let (mut done_ms, mut sent, mut dv, mut status) = (0u32, 0i64, 0.0f64, Status::empty());
        let mut next = 0;
        while done_ms < total_ms as u32 {
            let end_ms = done_ms.saturating_add(step_ms).min(total_ms as u32);
            while next < buf.len() && since_start(buf[next].clock_ms) <= end_ms {
                let r = buf[next];
                // Only the log's own readings are counted: a filled-in one is the lab's.
                if let (Err(e), true) = (c.on_raw(0, r.clock_ms, r.raw), r.own) {
                    out.rejected.count(&e);
                }
                next += 1;
            }
            let target = (s.pulses as f64 * f64::from(end_ms) / total_ms).round() as i64;
            let ticks = ((f64::from(end_ms) - f64::from(done_ms)) * 1000.0 / tick_us).round() as u32;
            let o = c.cycle([(target - sent) as i32], ticks);
            dv += f64::from(o.dv_mps[0]);
            status |= o.status;
            (sent, done_ms) = (target, end_ms);
        }
        out.accel_g.push(dv / (f64::from(G0) * s.interval_s));
        out.status.push(status.bits());
    }
    Ok(out)
}

/// Compensate every run of a log.
///
/// # Errors
/// As [`compensate_run`].
pub fn compensate_log(
    table: &Table,
    log: &Log,
    progress: Option<&indicatif::ProgressBar>,
) -> Result<Vec<Compensated>, Error> {
    log.runs
        .iter()
        .map(|r| {
            let c = compensate_run(table, r);
            if let Some(pb) = progress {
                pb.inc(1);
            }
            c
        })
        .collect()
}

/// Whether a status word means "no temperature-based compensation yet".
#[must_use]
pub fn not_compensated(status: u16) -> bool {
    Status::from_bits_retain(status).intersects(Status::NO_TABLE | Status::TEMP_STALE)
}

/// Why a static log cannot be compensated.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum StaticCompensateError {
    /// The table has a different number of axes than the log.
    AxisCount {
        /// Table axes.
        table: usize,
        /// Log axes.
        log: usize,
    },
    /// The columns differ in length.
    Length {
        /// Rows of the time column.
        time: usize,
        /// Rows of the temperature column.
        temp: usize,
        /// Rows of each acceleration column.
        accel: Vec<usize>,
    },
    /// The firmware refuses the table.
    Table(qfa_thermal::table::Error),
    /// The log's row spacing gives a configuration the firmware refuses.
    Config(qfa_thermal::ConfigError),
    /// Writing failed: the system's error kind (the writer has no path).
    Write(std::io::ErrorKind),
}

impl std::fmt::Display for StaticCompensateError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::AxisCount { table, log } => {
                write!(f, "the table has {table} axis(es), the log {log}: use the table calibrated on this kind of log")
            }
            Self::Length { time, temp, accel } => {
                write!(f, "columns of unequal length: time {time}, temperature {temp}, acceleration {accel:?} rows")
            }
            Self::Table(qfa_thermal::table::Error::Input { table, compensator }) => {
                wrong_input(f, *table, *compensator)
            }
            Self::Table(e) => write!(f, "table refused: {e}"),
            Self::Config(e) => write!(f, "rows too far apart for the firmware's settings: {e}"),
            Self::Write(kind) => write!(f, "cannot write the compensated rows: {kind}"),
        }
    }
}

impl std::error::Error for StaticCompensateError {}

/// Status of a compensated static row.
#[must_use]
pub fn static_status(status: Status) -> String {
    // RATE_NOT_READY only says Ṫ = 0 is used for the first readings: not a fault of the row.
    let shown = status - Status::RATE_NOT_READY;
    if shown.is_empty() {
        return "ok".to_string();
    }
    if shown == Status::TEMP_STALE {
        return "no_temperature".to_string();
    }
    shown.iter_names().map(|(n, _)| n).collect::<Vec<_>>().join("|")
}

/// A static log's rows compensated by [`compensate_samples`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StaticCompensated {
    /// Per axis, per row: the firmware's output `a = raw·(g0/K1) − K0·g0` back in g.
    pub accel_g: Vec<Vec<f64>>,
    /// Per row: the firmware's status flags, OR-ed over the axes.
    pub status: Vec<Status>,
}

/// Compensate rows of a static log given as columns (time, temperature, one acceleration
/// column per table axis), through the firmware's own sample path: per axis a
/// `Compensator<1, 32>` with that axis's model, fed each row's reading (`on_raw`) and the
/// row's acceleration as pseudo-LSB (`cycle_samples([round(a·2²⁰)])`, see
/// [`STATIC_LSB_PER_G`]). What [`compensate_static`] writes, before
/// formatting; the Python package returns it as arrays. A million three-axis rows took
/// 0.69 s in release on the project's 2-core machine (docs/measurements.md, "Python
/// package", with the command).
///
/// # Errors
/// A table of the other kind (pulse counts) or whose axis count differs from the columns',
/// columns of unequal lengths, or a table or row spacing the firmware refuses.
pub fn compensate_samples(
    table: &Table,
    time_s: &[f64],
    temp_c: &[f64],
    accel_g: &[&[f64]],
) -> Result<StaticCompensated, StaticCompensateError> {
    check_input(table, Input::Samples).map_err(StaticCompensateError::Table)?;
    if table.axes.len() != accel_g.len() {
        return Err(StaticCompensateError::AxisCount { table: table.axes.len(), log: accel_g.len() });
    }
    let rows = time_s.len();
    if temp_c.len() != rows || accel_g.iter().any(|a| a.len() != rows) {
        return Err(StaticCompensateError::Length {
            time: rows,
            temp: temp_c.len(),
            accel: accel_g.iter().map(|a| a.len()).collect(),
        });
    }
    // Rows may be slower than 1 Hz: the replay fills in the firmware's 1-s readings
    // between them, so the sample period stays the firmware's; where it cannot (rows over
    // the estimator's gap limit apart) staleness means no reading for 1.5 rows, as for
    // cycling logs, and the estimator's restart flags the rows instead.
    let default = Config::default();
    let max_dt_s = time_s.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    let config = Config {
        stale_after_ticks: default
            .stale_after_ticks
            .max((1.5 * max_dt_s / f64::from(default.tick_s)).ceil().min(f64::from(i32::MAX - 1)) as u32),
        input: qfa_thermal::Input::Samples,
        imu_period_s: row_period_s(time_s.windows(2).map(|w| w[1] - w[0])),
        // The rows enter as a·2²⁰ pseudo-LSB: a "part" of 2²⁰ LSB per g, the tables' own scale.
        sample_lsb_per_g: STATIC_LSB_PER_G,
        ..default
    };
    let mut out = StaticCompensated { accel_g: Vec::with_capacity(accel_g.len()), status: vec![Status::empty(); rows] };
    let lsb = f64::from(STATIC_LSB_PER_G);
    let tick_s = f64::from(config.tick_s);
    // Axis after axis: each axis has its own compensator, so the order of the calls within
    // one compensator (reading, then sample, row after row) is the firmware's either way.
    for (axis, column) in table.axes.iter().zip(accel_g) {
        let mut c = Compensator::<1, RATE_WINDOW>::new(config).map_err(StaticCompensateError::Config)?;
        let mut one = Table {
            input: table.input,
            rate_window: table.rate_window,
            axes: heapless::Vec::new(),
            misalignment: None,
            // The rows enter as the lab's 2²⁰ pseudo-LSB per g, not the part's own LSB: the
            // part's sensitivity (which the firmware checks) does not apply to them.
            part_lsb_per_g: None,
        };
        let _ = one.axes.push(axis.clone());
        c.set_table(one).map_err(StaticCompensateError::Table)?;
        let mut axis_g = Vec::with_capacity(rows);
        let mut readings = Readings::new();
        let mut buf = Vec::new();
        for i in 0..rows {
            // The first row has no spacing of its own: it takes the log's typical one.
            let dt_s = if i == 0 { f64::from(config.imu_period_s) } else { time_s[i] - time_s[i - 1] };
            let dt_ticks = (dt_s / tick_s).round() as u32;
            // A refused reading raises TEMP_INVALID in the output's status: nothing is lost.
            readings.row(time_s[i], Some(temp_c[i]), RowInstant::OwnReading, &mut buf);
            for r in &buf {
                let _ = c.on_raw(0, r.clock_ms, r.raw);
            }
            let raw = (column[i] * lsb).round().clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32;
            let o = c.cycle_samples([raw], dt_ticks);
            out.status[i] |= o.status;
            axis_g.push(f64::from(o.accel_mps2[0]) / f64::from(G0));
        }
        out.accel_g.push(axis_g);
    }
    Ok(out)
}

/// How many rows carry each status flag: what `compensate` prints on the console and writes
/// beside its output (`<out>.flags.json`), so a flag raised on some rows is never left to
/// be found in the status column.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FlagSummary {
    /// Rows compensated.
    pub rows: usize,
    /// Rows whose status is not `ok` (RATE_NOT_READY alone, Ṫ = 0 on the first readings,
    /// is not a fault of the row, see [`static_status`]).
    pub flagged: usize,
    /// Every flag of the firmware's status word, in its bit order, with the rows it is on.
    pub by_flag: Vec<(&'static str, usize)>,
}

impl FlagSummary {
    /// Count the flags of `status`, one word per row.
    #[must_use]
    pub fn of(status: impl IntoIterator<Item = Status>) -> Self {
        let mut s = Self { by_flag: Status::all().iter_names().map(|(n, _)| (n, 0)).collect(), ..Self::default() };
        for st in status {
            s.rows += 1;
            if !(st - Status::RATE_NOT_READY).is_empty() {
                s.flagged += 1;
            }
            for (n, f) in Status::all().iter_names() {
                if st.contains(f) {
                    if let Some(c) = s.by_flag.iter_mut().find(|(m, _)| *m == n) {
                        c.1 += 1;
                    }
                }
            }
        }
        s
    }

    fn share(&self, n: usize) -> f64 {
        if self.rows == 0 {
            0.0
        } else {
            100.0 * n as f64 / self.rows as f64
        }
    }

    /// The summary as JSON: `{"rows", "flagged", "rows_by_flag": {FLAG: rows}}`.
    #[must_use]
    pub fn json(&self) -> serde_json::Value {
        let by_flag: serde_json::Map<String, serde_json::Value> =
            self.by_flag.iter().map(|(n, c)| ((*n).to_string(), (*c).into())).collect();
        serde_json::json!({ "rows": self.rows, "flagged": self.flagged, "rows_by_flag": by_flag })
    }

    /// The summary as lines: `<rows> rows, <n> flagged (<share> %)`, then one line per
    /// flag `<FLAG>: <n> rows (<share> %)`.
    #[must_use]
    pub fn lines(&self) -> Vec<String> {
        let mut v = vec![format!("{} rows, {} flagged ({:.2} %)", self.rows, self.flagged, self.share(self.flagged))];
        v.extend(self.by_flag.iter().map(|(n, c)| format!("{n}: {c} rows ({:.2} %)", self.share(*c))));
        v
    }
}

/// Compensate a static log with a table of the same axes ([`compensate_samples`]) and
/// write `time_s,temp_c,<axes…>,status` in g, a plain CSV whose first line is its header
/// (it opens in `pandas.read_csv` and Python's `csv` without options); the count and share
/// of rows with each status flag is returned ([`FlagSummary`]), for the console and the
/// sidecar JSON ([`FlagSummary::json`]). `status` is `ok`, `no_temperature` (no
/// reading yet: compensated at T0 and flagged stale), or the firmware's flags joined by
/// `|` (`TEMP_OUT_OF_RANGE`, `TEMP_INVALID`, …), OR-ed over the axes ([`static_status`]).
///
/// # Errors
/// As [`compensate_samples`], or a write failure.
pub fn compensate_static<W: std::io::Write>(
    table: &Table,
    log: &qfa_log::static_log::StaticLog,
    w: W,
) -> Result<FlagSummary, StaticCompensateError> {
    let columns: Vec<&[f64]> = log.axes.iter().map(|a| a.accel_g.as_slice()).collect();
    let out = compensate_samples(table, &log.time_s, &log.temp_c, &columns)?;
    let io = |e: csv::Error| match e.into_kind() {
        csv::ErrorKind::Io(e) => StaticCompensateError::Write(e.kind()),
        _ => StaticCompensateError::Write(std::io::ErrorKind::InvalidData),
    };
    let summary = FlagSummary::of(out.status.iter().copied());
    let mut wr = csv::Writer::from_writer(w);
    let mut head = vec!["time_s".to_string(), "temp_c".to_string()];
    head.extend(log.axes.iter().map(|a| a.name.clone()));
    head.push("status".to_string());
    wr.write_record(&head).map_err(io)?;
    for i in 0..log.rows() {
        let mut rec = vec![format!("{:.6}", log.time_s[i]), format!("{:.4}", log.temp_c[i])];
        rec.extend(out.accel_g.iter().map(|a| format!("{:.9}", a[i])));
        rec.push(static_status(out.status[i]));
        wr.write_record(&rec).map_err(io)?;
    }
    wr.flush().map_err(|e| StaticCompensateError::Write(e.kind()))?;
    Ok(summary)
}
