//! Cycling log: CSV reader and writer for `program,run,time_s,input_g,temp_c,pulses,interval_s`.
//! Static multi-axis logs (a board at one orientation, CSV or TSV) are read by [`super::static_log`].
//!
//! The format (one row per counting interval of one index-head position, and what each
//! column means) is described once, in docs/lab.md, "The cycling log".
//!
//! The reader checks every row, counts **every** malformed one and keeps the first
//! `LogError::KEPT` with their 1-based line numbers as an editor shows them (the header is
//! line 1; CRLF, CR-only and blank lines counted, see `super::lines`); nothing is dropped
//! silently. It reads the file into memory (the line numbers are counted from the bytes)
//! and parses through `csv::ByteRecord` into one reused record, so a row costs no
//! allocation (its speed: docs/measurements.md, "Lab: calibration"; `qfa-lab demo` prints
//! it).

use std::fmt;
use std::io::{BufWriter, Read, Write};
use std::path::Path;

use crate::io_fault::IoFault;

/// The header, in order.
pub const COLUMNS: [&str; 7] = ["program", "run", "time_s", "input_g", "temp_c", "pulses", "interval_s"];

/// One counting interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// End of the interval, s since the program's start.
    pub time_s: f64,
    /// Latest DS18B20 reading, °C, or none yet.
    pub temp_c: Option<f64>,
    /// Signed I/F pulses in the interval.
    pub pulses: i64,
    /// Interval length, s.
    pub interval_s: f64,
}

/// All rows of one index-head position under one program, in time order.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// Program id.
    pub program: String,
    /// Run name within the program (any non-empty text: `0`, `rate0.3_pos0`); runs and
    /// programs are matched by name.
    pub run: String,
    /// Specific force along the input axis, g (+1, 0 or −1 in the paper's test).
    pub input_g: f64,
    /// Rows.
    pub samples: Vec<Sample>,
}

/// A whole log: runs in order of first appearance.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Log {
    /// Runs.
    pub runs: Vec<Run>,
    /// Rows the reader skipped as one-row glitches in the pulse rate, run by run in time
    /// order ([`Glitch`]); the runs do not hold them.
    pub glitches: Vec<Glitch>,
    /// Rows the reader skipped as written twice: each repeats its run's previous row
    /// exactly (time, temperature, count and interval), so it holds no reading of its own
    /// and kept it would count that interval's pulses twice. The static reader skips such a
    /// row too (as a repeated timestamp).
    pub repeated: crate::lines::SkipCount,
}

/// A row skipped as a one-row glitch: its pulse rate (pulses / interval) deviates from its
/// run's ±5-row neighbourhood by more than [`crate::robust::GLITCH_SIGMAS`] robust σ of
/// that run's rate, by at least [`GLITCH_MIN_PULSES`] pulses over its interval, and by at
/// least [`crate::robust::GLITCH_MIN_ACCEL_G`] at its program's scale factor (the rule of
/// [`crate::robust::glitches`] and the floor of the static reader's axes). A burst of pulses in one row
/// (electrical noise, a counter fault) is not thermal, and a least-squares fit would spread
/// it over the model.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Glitch {
    /// Program id.
    pub program: String,
    /// Run name.
    pub run: String,
    /// End of the row's interval, s.
    pub time_s: f64,
    /// Its pulses.
    pub pulses: i64,
    /// Its interval, s.
    pub interval_s: f64,
}

/// What a log's skipped glitch rows mean to its user, in one sentence; none when there are
/// none.
#[must_use]
pub fn glitches_sentence(glitches: &[Glitch]) -> Option<String> {
    let g = glitches.first()?;
    Some(format!(
        "the reader skipped {} row(s) as one-row glitches in the pulse counts (a burst in one row is not thermal, and \
         a fit would spread it over the model), the first in {} {} at t = {} s ({} pulses in {} s)",
        glitches.len(),
        g.program,
        g.run,
        g.time_s,
        g.pulses,
        g.interval_s
    ))
}

/// Smallest deviation of a row's pulses from its neighbourhood's line that counts as a
/// glitch, pulses over the row's interval (a count is exact to a pulse, so a quiet run can
/// have a robust σ near 0; 4 pulses, as the temperature floor is 4 DS18B20 steps).
pub const GLITCH_MIN_PULSES: f64 = 4.0;

/// Each program's scale factor, pulses/(g·s), as its runs' median rates tell it: half the
/// difference of the +1 g and −1 g runs' medians over their inputs' difference (0 for a
/// program without runs on both sides).
fn scale_factors(log: &Log) -> Vec<(String, f64)> {
    log.programs()
        .into_iter()
        .map(|p| {
            let side = |up: bool| -> Option<(f64, f64)> {
                let rates: Vec<f64> = log
                    .runs_of(&p)
                    .filter(|r| if up { r.input_g > 0.5 } else { r.input_g < -0.5 })
                    .flat_map(|r| r.samples.iter().map(move |s| s.pulses as f64 / s.interval_s / r.input_g.abs()))
                    .collect();
                let g = log.runs_of(&p).find(|r| if up { r.input_g > 0.5 } else { r.input_g < -0.5 })?.input_g;
                Some((crate::robust::median(&rates)?, g))
            };
            let k1 = match (side(true), side(false)) {
                (Some((a, _)), Some((b, _))) => (0.5 * (a - b)).abs(),
                _ => 0.0,
            };
            (p, k1)
        })
        .collect()
}

/// Skip every run's one-row glitches ([`Glitch`]), recording them in `log.glitches`.
fn drop_glitches(log: &mut Log) {
    let k1 = scale_factors(log);
    for r in &mut log.runs {
        let rate: Vec<f64> = r.samples.iter().map(|s| s.pulses as f64 / s.interval_s).collect();
        let Some(interval) = crate::robust::median(&r.samples.iter().map(|s| s.interval_s).collect::<Vec<_>>()) else {
            continue;
        };
        let k1 = k1.iter().find(|(p, _)| *p == r.program).map_or(0.0, |(_, k)| *k);
        let floor = (GLITCH_MIN_PULSES / interval).max(crate::robust::GLITCH_MIN_ACCEL_G * k1);
        let bad = crate::robust::glitches(&rate, crate::robust::GLITCH_SIGMAS, floor);
        for &i in &bad {
            let s = r.samples[i];
            log.glitches.push(Glitch {
                program: r.program.clone(),
                run: r.run.clone(),
                time_s: s.time_s,
                pulses: s.pulses,
                interval_s: s.interval_s,
            });
        }
        let mut k = 0;
        r.samples.retain(|_| {
            k += 1;
            !bad.contains(&(k - 1))
        });
    }
}

impl Log {
    /// Each run's start on the log's own clock, s: a cycling log's times restart with each
    /// run, so the runs are taken back to back in the log's order, each starting where the
    /// one before it ended (a pause between runs is not seen). The one clock of a unit's
    /// ageing and of its sensor's drift.
    #[must_use]
    pub fn run_starts_s(&self) -> Vec<f64> {
        let mut t = 0.0;
        self.runs
            .iter()
            .map(|run| {
                let start = t;
                t += run.samples.last().map_or(0.0, |s| s.time_s);
                start
            })
            .collect()
    }

    /// Number of rows.
    #[must_use]
    pub fn rows(&self) -> usize {
        self.runs.iter().map(|r| r.samples.len()).sum()
    }

    /// Program ids in order of first appearance.
    #[must_use]
    pub fn programs(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for r in &self.runs {
            if !out.contains(&r.program) {
                out.push(r.program.clone());
            }
        }
        out
    }

    /// Runs of one program.
    pub fn runs_of<'a>(&'a self, program: &'a str) -> impl Iterator<Item = &'a Run> + 'a {
        self.runs.iter().filter(move |r| r.program == program)
    }

    /// Whether the runs of `programs` hold what a fit can be right on: rows, no run whose pulse
    /// count never moves (an I/F converter's count moves with its noise and its
    /// temperature), counting intervals in the unit of the rows' spacing, no ±1 g pair whose
    /// scale factor comes out negative (swapped positions), and readings that span what the core's bias grid needs (its
    /// `MAX_BIAS_POINTS` nodes at least `MIN_GRID_STEP_C` apart). Calibration and discovery
    /// both ask it of the programs they fit.
    ///
    /// # Errors
    /// The first [`ContentFault`].
    pub fn check_contents(&self, programs: &[String]) -> Result<(), ContentFault> {
        let runs: Vec<&Run> = self.runs.iter().filter(|r| programs.contains(&r.program)).collect();
        // A log of no row at all; a log whose rows hold no ±1 g pair is the fit's to name.
        if self.runs.iter().all(|r| r.samples.is_empty()) {
            return Err(ContentFault::NoRows);
        }
        for r in &runs {
            let Some(first) = r.samples.first() else { continue };
            if r.samples.len() > 1 && r.samples.iter().all(|s| s.pulses == first.pulses) {
                return Err(ContentFault::StuckPulses {
                    program: r.program.clone(),
                    run: r.run.clone(),
                    pulses: first.pulses,
                    rows: r.samples.len(),
                });
            }
        }
        // The counting interval against the rows' spacing: a rig counts over (about) the time
        // between its rows, so an order of magnitude between them is a unit (ms in `interval_s`
        // gives pulse rates 1000× low, which the table refused as "another unit scale").
        let ratios: Vec<f64> = runs
            .iter()
            .flat_map(|r| r.samples.windows(2).map(|w| w[1].interval_s / (w[1].time_s - w[0].time_s)))
            .filter(|x| x.is_finite() && *x > 0.0)
            .collect();
        if let Some(ratio) = crate::robust::median(&ratios).filter(|x| !(0.1..=10.0).contains(x)) {
            return Err(ContentFault::IntervalUnit { ratio });
        }
        for p in programs {
            let Some(pp) = crate::pairing::pair_program(self, p) else { continue };
            let k1: Vec<f64> = (0..pp.rows.len()).map(|k| pp.k1_k0(self, k).0).collect();
            if let Some(k1) = crate::robust::median(&k1).filter(|k1| *k1 < 0.0) {
                return Err(ContentFault::NegativeScaleFactor { program: p.clone(), k1 });
            }
        }
        let temps = runs.iter().flat_map(|r| r.samples.iter().filter_map(|s| s.temp_c));
        let (lo_c, hi_c) = temps.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), t| (lo.min(t), hi.max(t)));
        let needed_c = crate::grid_span_needed_c(qfa_thermal::model::MAX_BIAS_POINTS);
        if lo_c.is_finite() && hi_c - lo_c < needed_c {
            return Err(ContentFault::SpanTooSmall { lo_c, hi_c, needed_c });
        }
        Ok(())
    }
}

/// Why the runs a fit is about to be made on cannot give a right table ([`Log::check_contents`]).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum ContentFault {
    /// No row to fit: the log holds no row (its header alone, or a chamber log's unit whose
    /// cells are empty on every row).
    NoRows,
    /// A run's pulse count is the same on every row: a stuck counter, or a column the
    /// logger filled with a constant.
    StuckPulses {
        /// Program.
        program: String,
        /// Run.
        run: String,
        /// The one count.
        pulses: i64,
        /// Rows of the run.
        rows: usize,
    },
    /// The counting intervals (`interval_s`) are an order of magnitude off the rows' spacing
    /// in `time_s` (the median ratio): one of the two columns is in another unit.
    IntervalUnit {
        /// Median of `interval_s` over the time since the run's previous row.
        ratio: f64,
    },
    /// A program's ±1 g pair gives a negative scale factor (median over its rows): its runs'
    /// `input_g` are swapped, or the counter's sign is; a table holds a positive one.
    NegativeScaleFactor {
        /// Program.
        program: String,
        /// Median K1 = (A₊ − A₋)/(g₊ − g₋), pulses/(g·s).
        k1: f64,
    },
    /// The temperature readings span less than the bias grid needs: a stuck sensor, or a
    /// program that never moved the temperature.
    SpanTooSmall {
        /// Lowest reading, °C.
        lo_c: f64,
        /// Highest reading, °C.
        hi_c: f64,
        /// Span needed, °C.
        needed_c: f64,
    },
}

impl fmt::Display for ContentFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::StuckPulses { program, run, pulses, rows } => write!(
                f,
                "run {run} of program {program} counts {pulses} pulses on every one of its {rows} rows: a stuck counter \
                 or a constant column (an I/F converter's count moves with its noise and its temperature); check the \
                 converter and the log's `pulses` column"
            ),
            Self::IntervalUnit { ratio } => write!(
                f,
                "wrong unit? the counting intervals (`interval_s`) are {ratio} times the rows' spacing in `time_s` \
                 (the median over the runs); a rig counts over the time between its rows, so both columns are in \
                 seconds: {}",
                if *ratio > 10.0 { "`interval_s` in ms or µs?" } else { "`time_s` in ms or µs?" }
            ),
            Self::NegativeScaleFactor { program, k1 } => write!(
                f,
                "program {program}: its ±1 g pair gives a negative scale factor, K1 = (A₊ − A₋)/(g₊ − g₋) = {k1:.0} \
                 pulses/(g·s) (the median over its rows): the runs' `input_g` look swapped, or the counter's sign is; \
                 check which position is +1 g"
            ),
            Self::NoRows => f.write_str(
                "no row to fit: the log holds no row (its header alone, or a unit whose cells are empty on every row)",
            ),
            Self::SpanTooSmall { lo_c, hi_c, needed_c } => write!(
                f,
                "the temperature span is too small: {:.2} °C ({lo_c:.2}..{hi_c:.2} °C); the bias grid needs at least \
                 {needed_c:.2} °C ({} nodes at least {} °C apart, the root crate's smallest grid step): a stuck \
                 temperature sensor, or a program that never moved the temperature",
                hi_c - lo_c,
                qfa_thermal::model::MAX_BIAS_POINTS,
                qfa_thermal::table::limits::MIN_GRID_STEP_C
            ),
        }
    }
}

impl std::error::Error for ContentFault {}

/// What is wrong with a row.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum RowFault {
    /// The header is not exactly `COLUMNS`.
    Header(String),
    /// Wrong number of fields.
    FieldCount(usize),
    /// A field does not parse or is not finite / in range; names the column.
    Field {
        /// Column name.
        column: &'static str,
        /// The offending text.
        text: String,
    },
    /// `time_s` is not after the run's previous row.
    TimeNotIncreasing,
    /// `input_g` differs from the run's first row.
    InputChanged,
    /// The CSV layer failed.
    Csv(crate::io_fault::CsvFault),
    /// The file could not be opened.
    Open(crate::io_fault::IoFault),
}

impl fmt::Display for RowFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Header(h) => write!(f, "header is `{h}`, expected `{}`", COLUMNS.join(",")),
            Self::FieldCount(n) => write!(f, "{n} fields, expected 7"),
            Self::Field { column, text } => write!(f, "bad {column} `{text}`"),
            Self::TimeNotIncreasing => f.write_str("time_s not after the run's previous row"),
            Self::InputChanged => f.write_str("input_g changed within a run"),
            Self::Csv(e) => write!(f, "csv: {e}"),
            Self::Open(e) => write!(f, "{e}"),
        }
    }
}

/// A malformed row and its line number (1-based; the header is line 1).
#[derive(Clone, Debug, PartialEq)]
pub struct RowError {
    /// Line number.
    pub line: u64,
    /// What is wrong.
    pub fault: RowFault,
}

impl fmt::Display for RowError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}: {}", self.line, self.fault)
    }
}

/// Every malformed row of a log (the first `LogError::KEPT` are kept, all are counted).
#[derive(Clone, Debug, PartialEq)]
pub struct LogError {
    /// The first errors, in line order.
    pub errors: Vec<RowError>,
    /// How many rows were malformed in all.
    pub total: u64,
}

impl LogError {
    /// Errors kept in detail (all are counted).
    pub(crate) const KEPT: usize = 20;

    fn single(line: u64, fault: RowFault) -> Self {
        Self { errors: vec![RowError { line, fault }], total: 1 }
    }
}

impl fmt::Display for LogError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{} malformed row(s) in the log:", self.total)?;
        for e in &self.errors {
            writeln!(f, "  {e}")?;
        }
        if self.total > self.errors.len() as u64 {
            writeln!(f, "  ... and {} more", self.total - self.errors.len() as u64)?;
        }
        Ok(())
    }
}

impl std::error::Error for LogError {}

fn field_str(rec: &csv::ByteRecord, i: usize) -> &[u8] {
    let b = rec.get(i).unwrap_or(b"");
    // Trim ASCII spaces some spreadsheet exports add.
    let start = b.iter().position(|c| *c != b' ').unwrap_or(b.len());
    let end = b.iter().rposition(|c| *c != b' ').map_or(start, |e| e + 1);
    &b[start..end]
}

fn bad(column: &'static str, b: &[u8]) -> RowFault {
    RowFault::Field { column, text: String::from_utf8_lossy(b).into_owned() }
}

fn parse_f64(b: &[u8], column: &'static str) -> Result<f64, RowFault> {
    std::str::from_utf8(b)
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .filter(|x| x.is_finite())
        .ok_or_else(|| bad(column, b))
}

/// A parsed row: time_s, input_g, temp_c, pulses, interval_s (program and run are read
/// in place, without allocating).
type Parsed = (f64, f64, Option<f64>, i64, f64);

fn parse_row(rec: &csv::ByteRecord) -> Result<Parsed, RowFault> {
    if rec.len() != COLUMNS.len() {
        return Err(RowFault::FieldCount(rec.len()));
    }
    let prog = field_str(rec, 0);
    if prog.is_empty() || std::str::from_utf8(prog).is_err() {
        return Err(bad("program", prog));
    }
    let run_b = field_str(rec, 1);
    if run_b.is_empty() || std::str::from_utf8(run_b).is_err() {
        return Err(bad("run", run_b));
    }
    let time_s = parse_f64(field_str(rec, 2), "time_s")?;
    if time_s < 0.0 {
        return Err(bad("time_s", field_str(rec, 2)));
    }
    let input_g = parse_f64(field_str(rec, 3), "input_g")?;
    if input_g.abs() > 100.0 {
        return Err(bad("input_g", field_str(rec, 3)));
    }
    let tb = field_str(rec, 4);
    let temp_c = if tb.is_empty() {
        None
    } else {
        let t = parse_f64(tb, "temp_c")?;
        if !(-60.0..=130.0).contains(&t) {
            return Err(bad("temp_c", tb));
        }
        Some(t)
    };
    let pb = field_str(rec, 5);
    let pulses = std::str::from_utf8(pb).ok().and_then(|s| s.parse::<i64>().ok()).ok_or_else(|| bad("pulses", pb))?;
    let ib = field_str(rec, 6);
    let interval_s = parse_f64(ib, "interval_s")?;
    if interval_s <= 0.0 {
        return Err(bad("interval_s", ib));
    }
    Ok((time_s, input_g, temp_c, pulses, interval_s))
}

/// The header row: exactly [`COLUMNS`], or the error for line 1.
fn check_header(rdr: &mut csv::Reader<&[u8]>, rec: &mut csv::ByteRecord) -> Result<(), LogError> {
    match rdr.read_byte_record(rec) {
        Ok(true) => {
            let got: Vec<&[u8]> = (0..rec.len()).map(|i| field_str(rec, i)).collect();
            if got.len() != COLUMNS.len() || got.iter().zip(COLUMNS).any(|(g, c)| *g != c.as_bytes()) {
                let h = got.iter().map(|g| String::from_utf8_lossy(g).into_owned()).collect::<Vec<_>>().join(",");
                return Err(LogError::single(1, RowFault::Header(h)));
            }
            Ok(())
        }
        Ok(false) => Err(LogError::single(1, RowFault::Header(String::new()))),
        Err(e) => Err(LogError::single(1, RowFault::Csv(crate::io_fault::CsvFault::of(&e)))),
    }
}

/// The index in `log.runs` of the run `(prog, run)`, added with `input_g` when new;
/// `current`, the previous row's, is tried first (consecutive rows usually share it).
fn run_index(log: &mut Log, current: Option<usize>, prog: &[u8], run: &[u8], input_g: f64) -> usize {
    let same = |r: &Run| r.run.as_bytes() == run && r.program.as_bytes() == prog;
    match current {
        Some(i) if same(&log.runs[i]) => i,
        _ => match log.runs.iter().position(same) {
            Some(i) => i,
            None => {
                log.runs.push(Run {
                    program: String::from_utf8_lossy(prog).into_owned(),
                    run: String::from_utf8_lossy(run).into_owned(),
                    input_g,
                    samples: Vec::new(),
                });
                log.runs.len() - 1
            }
        },
    }
}

/// Read a log from any reader.
///
/// # Errors
/// Every malformed row, with line numbers.
pub fn read_log_from<R: Read>(mut reader: R) -> Result<Log, LogError> {
    let mut text = Vec::new();
    reader
        .read_to_end(&mut text)
        .map_err(|e| LogError::single(0, RowFault::Csv(crate::io_fault::CsvFault::Io(e.kind()))))?;
    let mut lines = super::lines::LineCounter::new(&text);
    let mut rdr = csv::ReaderBuilder::new().has_headers(false).flexible(true).from_reader(&text[..]);
    let mut rec = csv::ByteRecord::new();
    let mut line: u64 = 1;
    check_header(&mut rdr, &mut rec)?;
    let mut log = Log::default();
    let mut errors = LogError { errors: Vec::new(), total: 0 };
    // Index of the run of the previous row: consecutive rows usually share it.
    let mut current: Option<usize> = None;
    let push_err = |errors: &mut LogError, line: u64, fault: RowFault| {
        errors.total += 1;
        if errors.errors.len() < LogError::KEPT {
            errors.errors.push(RowError { line, fault });
        }
    };
    loop {
        line += 1;
        match rdr.read_byte_record(&mut rec) {
            Ok(false) => break,
            Ok(true) => {}
            Err(e) => {
                push_err(&mut errors, line, RowFault::Csv(crate::io_fault::CsvFault::of(&e)));
                continue;
            }
        }
        if let Some(pos) = rec.position() {
            line = lines.line_of(pos.byte());
        }
        let (time_s, input_g, temp_c, pulses, interval_s) = match parse_row(&rec) {
            Ok(v) => v,
            Err(f) => {
                push_err(&mut errors, line, f);
                continue;
            }
        };
        let idx = run_index(&mut log, current, field_str(&rec, 0), field_str(&rec, 1), input_g);
        current = Some(idx);
        let r = &mut log.runs[idx];
        if r.input_g != input_g {
            push_err(&mut errors, line, RowFault::InputChanged);
            continue;
        }
        if let Some(last) = r.samples.last() {
            if *last == (Sample { time_s, temp_c, pulses, interval_s }) {
                log.repeated.add(line);
                continue;
            }
            if time_s <= last.time_s {
                push_err(&mut errors, line, RowFault::TimeNotIncreasing);
                continue;
            }
        }
        r.samples.push(Sample { time_s, temp_c, pulses, interval_s });
    }
    if errors.total > 0 {
        Err(errors)
    } else {
        drop_glitches(&mut log);
        Ok(log)
    }
}

/// Read a log file.
///
/// # Errors
/// The file cannot be opened, or the rows' errors.
pub fn read_log(path: &Path) -> Result<Log, LogError> {
    let f = std::fs::File::open(path).map_err(|e| LogError::single(0, RowFault::Open(IoFault::new(path, &e))))?;
    read_log_from(f)
}

/// Write one row (no newline handling beyond the trailing `\n`), with optional extra column.
fn write_row<W: Write>(w: &mut W, run: &Run, s: &Sample, extra: Option<f64>) -> std::io::Result<()> {
    write!(w, "{},{},{},{},", run.program, run.run, s.time_s, run.input_g)?;
    if let Some(t) = s.temp_c {
        write!(w, "{t}")?;
    }
    write!(w, ",{},{}", s.pulses, s.interval_s)?;
    if let Some(x) = extra {
        write!(w, ",{x:.9}")?;
    }
    w.write_all(b"\n")
}

/// Write a log as CSV, run after run.
///
/// # Errors
/// I/O errors.
pub fn write_log_to<W: Write>(w: W, log: &Log) -> std::io::Result<()> {
    let mut w = BufWriter::with_capacity(1 << 20, w);
    writeln!(w, "{}", COLUMNS.join(","))?;
    for run in &log.runs {
        for s in &run.samples {
            write_row(&mut w, run, s, None)?;
        }
    }
    w.flush()
}

/// Write a log file.
///
/// # Errors
/// I/O errors.
pub fn write_log(path: &Path, log: &Log) -> std::io::Result<()> {
    write_log_to(std::fs::File::create(path)?, log)
}

/// Write a log with an added `accel_g` column (`accel[run][row]`).
///
/// # Errors
/// I/O errors.
pub fn write_compensated<W: Write>(w: W, log: &Log, accel: &[Vec<f64>]) -> std::io::Result<()> {
    let mut w = BufWriter::with_capacity(1 << 20, w);
    writeln!(w, "{},accel_g", COLUMNS.join(","))?;
    for (run, acc) in log.runs.iter().zip(accel) {
        for (s, a) in run.samples.iter().zip(acc) {
            write_row(&mut w, run, s, Some(*a))?;
        }
    }
    w.flush()
}
