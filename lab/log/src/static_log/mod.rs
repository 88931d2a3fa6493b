//! Static multi-axis log: time, temperature and one or more acceleration axes of a board at
//! constant orientation (a board on a chamber shelf), as CSV or TSV with a header.
//!
//! Columns are found by common names (see [`COMMON_NAMES`]) or given with a
//! [`ColumnMap`] (`time=timestamp,temp=imu.temperature,ax=imu.acc.x,...`); the delimiter
//! (comma, tab or semicolon) is taken from the header line. Units come from
//! [`TimeUnit`] / [`AccelUnit`], or from a column-name suffix (`time_s`, `timestamp_us`,
//! `ax_g`, `acc_x_mps2`); a unit that is neither given nor in the name is an error, never a
//! guess; the temperature is °C unless [`StaticOptions::temp_unit`] or the name (`temp_f`,
//! `temp_k`) says otherwise, and an option that contradicts a name's unit is refused. Time is
//! shifted to start at 0 s (logs often count from power-up or the epoch).
//!
//! What the reader does with each kind of bad row, so nothing reaches a fit unnoticed:
//! * a field that does not parse as a number (`abc`), or a temperature outside
//!   −60…130 °C: **error** ([`StaticError::Rows`], every row with its line number);
//! * time going backwards: **error** (same);
//! * an empty or `NaN` field: the row is **skipped**, counted in [`Skipped::nan`];
//! * a timestamp equal to the previous row's: the later row is **skipped**, counted in
//!   [`Skipped::duplicate`];
//! * a glitch row (a spike in one row; the tofupilot log's first row is one): **skipped**,
//!   counted in [`Skipped::glitch`]. A row is a glitch when one channel deviates from what
//!   its ±5-row neighbourhood predicts (a robust local line: median slope, median level) by
//!   more than `GLITCH_SIGMAS` robust σ of that channel (σ = 1.4826 · the median of those
//!   deviations), and
//!   by more than a floor too (`GLITCH_MIN_TEMP_C`, `GLITCH_MIN_ACCEL_G`: a quantised
//!   channel has a median deviation of 0);
//! * irregular sampling: **reported** in [`Sampling`] (intervals outside 0.5…2 × the
//!   median, and gaps longer than the rate estimator's 30-s restart), not skipped: the
//!   root crate's estimator handles irregular spacing by design.
//!
//! Whole-log checks (errors): no header, no data rows, an unknown or missing column, a
//! unit that makes the data implausible, each from both sides where the data allow it
//! ([`crate::units`]: the median |a| outside [`crate::units::REST_G`] with all three axes,
//! above it with fewer; a median row interval outside 10 µs…60 s, or a temperature
//! changing faster than `MAX_SLEW_C_PER_MIN`, see `max_slew`; readings outside
//! −60…130 °C that another temperature unit puts inside), every one refused as
//! [`StaticError::Unit`] with the figure and the unit that fits; fewer than `MIN_ROWS`
//! rows left.
//!
//! Decimal commas (`20,5` in a `;`- or tab-separated file, a spreadsheet export in many
//! locales) are read with [`StaticOptions::decimal_comma`]; without it, a log whose first
//! bad field is such a number is refused with [`StaticError::DecimalComma`], which says
//! so, rather than as thousands of rows that are "not a number".
//!
//! Line numbers are as an editor shows them (CRLF, CR-only and blank lines counted, see
//! `crate::lines`).

pub mod checks;
pub mod columns;
pub(crate) mod error;
mod unit_checks;

use unit_checks::{check_accel_unit, check_time_unit, columns_used, range_c, resolve, temp_fits, unit_evidence};

use std::fmt;
use std::io::Read;

use serde::Serialize;

use crate::robust::glitches;
use crate::robust::median;
use crate::static_log::checks::centred_median;
pub(crate) use crate::static_log::checks::{max_slew, Slew};
pub use crate::static_log::columns::{AccelUnit, ColumnMap, TimeUnit, COMMON_NAMES};
pub use crate::static_log::error::{StaticError, StaticRowFault};
use crate::units::{ReaderOption, TempUnit, UnitEvidence, UnitMismatch, UnitSource, REST_G};

/// Standard gravity, m/s², to convert m/s² to g.
pub const G0_MPS2: f64 = 9.806_65;

pub(crate) use crate::robust::GLITCH_SIGMAS;

/// Smallest temperature deviation that counts as a glitch, °C (4 DS18B20 LSB).
pub(crate) const GLITCH_MIN_TEMP_C: f64 = 0.25;

pub(crate) use crate::robust::GLITCH_MIN_ACCEL_G;

/// Fewest good rows a static log must keep.
pub(crate) const MIN_ROWS: usize = 16;

/// Fastest temperature change a board in a climate chamber can show, °C/min; a log whose
/// time unit implies more is refused. 30 °C/min is the figure taken for chambers;
/// it is about 4× the steepest ramp of the real tofupilot log (−8 °C/min, its SOURCE.md)
/// and 3–30× the 1–10 °C/min a chamber program uses (the paper's programs run at
/// 0.3–0.9 °C/min). The mistake it catches is a factor of 1 000 (µs read as ns, ms as µs),
/// so the bound needs no precision. It was chosen before any run of the check.
pub(crate) const MAX_SLEW_C_PER_MIN: f64 = 30.0;

/// Window over which [`max_slew`] measures a temperature change, s: one minute, so the
/// figure is a per-minute change and quantisation (1/16 °C for a DS18B20, 0.01 °C for an
/// IMU's own sensor) adds at most 0.06 °C/min to it.
pub(crate) const SLEW_WINDOW_S: f64 = 60.0;

/// Line numbers kept per kind of skip or error (all are counted).
pub(crate) const KEPT_LINES: usize = 20;

/// How to read a static log.
#[derive(Clone, Debug, Default)]
pub struct StaticOptions {
    /// Column choices.
    pub columns: ColumnMap,
    /// Time unit (else from the column name's suffix).
    pub time_unit: Option<TimeUnit>,
    /// Acceleration unit (else from the column names' suffix).
    pub accel_unit: Option<AccelUnit>,
    /// Temperature unit (else from the column name's suffix, else °C, assumed).
    pub temp_unit: Option<TempUnit>,
    /// Numbers use a decimal comma (`20,5`); needs a `;` or tab delimiter.
    pub decimal_comma: bool,
}

pub use crate::lines::SkipCount;

/// Rows the reader skipped.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Skipped {
    /// An empty or NaN field.
    pub nan: SkipCount,
    /// Same timestamp as the previous row.
    pub duplicate: SkipCount,
    /// One-row spike (see the module docs).
    pub glitch: SkipCount,
}

impl Skipped {
    /// Total rows skipped.
    #[must_use]
    pub fn total(&self) -> usize {
        self.nan.count + self.duplicate.count + self.glitch.count
    }
}

impl fmt::Display for Skipped {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut first = true;
        for (name, s) in
            [("NaN/empty field", &self.nan), ("duplicate timestamp", &self.duplicate), ("glitch", &self.glitch)]
        {
            if s.count == 0 {
                continue;
            }
            if !first {
                f.write_str("; ")?;
            }
            first = false;
            write!(f, "{} {name} row(s) skipped (line {})", s.count, s.listed())?;
        }
        if first {
            f.write_str("no rows skipped")?;
        }
        Ok(())
    }
}

/// Sampling regularity (reported, not corrected).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Sampling {
    /// Median row interval, s.
    pub median_interval_s: f64,
    /// Intervals outside 0.5…2 × the median.
    pub irregular_intervals: usize,
    /// Gaps longer than 30 s (the rate estimator restarts its window there).
    pub gaps_over_30s: usize,
    /// Longest interval, s.
    pub max_interval_s: f64,
    /// Fastest temperature change, °C/min: `max_slew` over the kept rows.
    pub max_slew_c_per_min: f64,
}

/// One acceleration axis.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisColumn {
    /// Role: `ax`, `ay` or `az`.
    pub name: String,
    /// Column name in the file.
    pub column: String,
    /// Specific force, g, one per kept row.
    pub accel_g: Vec<f64>,
}

/// A static multi-axis log, after the skips.
#[derive(Clone, Debug, PartialEq)]
pub struct StaticLog {
    /// Time since the first kept row, s.
    pub time_s: Vec<f64>,
    /// The first kept row's time on the log's own clock, s (what `time_s` counts from):
    /// logs of one chamber run line up on it.
    pub time_origin_s: f64,
    /// Temperature, °C.
    pub temp_c: Vec<f64>,
    /// Axes, in the order ax, ay, az (those present).
    pub axes: Vec<AxisColumn>,
    /// Line number of each kept row.
    pub line: Vec<u64>,
    /// Columns used: `(role, column, unit)`.
    pub columns: Vec<(String, String, String)>,
    /// Skipped rows.
    pub skipped: Skipped,
    /// Sampling regularity.
    pub sampling: Sampling,
    /// How each unit was decided and what the data show in it.
    pub units: UnitEvidence,
}

impl fmt::Display for Sampling {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "median row interval {:.3} s, {} interval(s) outside 0.5..2x the median, {} gap(s) over 30 s (longest {:.1} s), \
             fastest temperature change {:.1} °C/min",
            self.median_interval_s,
            self.irregular_intervals,
            self.gaps_over_30s,
            self.max_interval_s,
            self.max_slew_c_per_min
        )
    }
}

impl StaticLog {
    /// Kept rows.
    #[must_use]
    pub fn rows(&self) -> usize {
        self.time_s.len()
    }
}

/// Whether a header column matches a common name.
pub fn matches_common(col: &str, name: &str) -> bool {
    let c = col.to_ascii_lowercase();
    c == name || c.ends_with(&format!(".{name}")) || c.ends_with(&format!("_{name}"))
}

fn find_column(header: &[String], role: &str, opts: &StaticOptions) -> Result<Option<usize>, StaticError> {
    if let Some((_, col)) = opts.columns.roles.iter().find(|(r, _)| r == role) {
        return header.iter().position(|h| h == col).map(Some).ok_or_else(|| StaticError::UnknownColumn {
            role: role.to_string(),
            column: col.clone(),
            header: header.to_vec(),
        });
    }
    let names = COMMON_NAMES.iter().find(|(r, _)| *r == role).map_or(&[][..], |(_, n)| *n);
    // Names in priority order: the first name any column matches wins.
    Ok(names.iter().find_map(|n| header.iter().position(|h| matches_common(h, n))))
}

/// Whether `s` is a number written with a decimal comma (`-20,5`, `1,5e-3`).
fn is_decimal_comma(s: &str) -> bool {
    s.matches(',').count() == 1 && s.replacen(',', ".", 1).parse::<f64>().is_ok()
}

/// Field text → value: `Ok(None)` for an empty or NaN field, `Err` for text that is no number.
/// With `decimal_comma` the one comma of a field is its decimal point.
fn parse_field(b: &[u8], column: &str, decimal_comma: bool) -> Result<Option<f64>, StaticRowFault> {
    let s = std::str::from_utf8(b).unwrap_or("").trim();
    if s.is_empty() || s.eq_ignore_ascii_case("nan") {
        return Ok(None);
    }
    let parsed =
        if decimal_comma && s.contains(',') { s.replacen(',', ".", 1).parse::<f64>() } else { s.parse::<f64>() };
    match parsed {
        Ok(x) if x.is_finite() => Ok(Some(x)),
        Ok(_) => Ok(None),
        Err(_) => Err(StaticRowFault::NotANumber { column: column.to_string(), text: s.to_string() }),
    }
}

/// Read a static log from text.
///
/// # Errors
/// See [`StaticError`]; skipped rows are in [`StaticLog::skipped`].
pub fn read_static_from<R: Read>(reader: R, opts: &StaticOptions) -> Result<StaticLog, StaticError> {
    let mut text = Vec::new();
    let mut reader = reader;
    reader
        .read_to_end(&mut text)
        .map_err(|e| StaticError::Csv { line: None, fault: crate::io_fault::CsvFault::Io(e.kind()) })?;
    let delim = delimiter(&text, opts)?;
    let mut rdr = csv::ReaderBuilder::new().delimiter(delim).has_headers(false).flexible(true).from_reader(&text[..]);
    let mut lines_of = crate::lines::LineCounter::new(&text);
    let mut rec = csv::ByteRecord::new();
    if !rdr
        .read_byte_record(&mut rec)
        .map_err(|e| StaticError::Csv { line: Some(1), fault: crate::io_fault::CsvFault::of(&e) })?
    {
        return Err(StaticError::Empty);
    }
    let header: Vec<String> = rec.iter().map(|b| String::from_utf8_lossy(b).trim().to_string()).collect();
    let layout = layout_of(header, opts)?;
    let mut rows = read_rows(&mut rdr, &mut rec, &mut lines_of, &layout, delim, opts.decimal_comma)?;
    if rows.n_faults > 0 {
        return Err(faults_error(rows, layout.temp_unit, layout.temp_src));
    }
    if !rows.any_row {
        return Err(StaticError::NoRows);
    }
    let keep = drop_glitches(&mut rows)?;
    let t0 = rows.raw_t[keep[0]];
    let time_s: Vec<f64> = keep.iter().map(|&i| (rows.raw_t[i] - t0) * layout.time_unit.seconds()).collect();
    let kept_temp: Vec<f64> = keep.iter().map(|&k| rows.temp[k]).collect();
    let line: Vec<u64> = keep.iter().map(|&k| rows.lines[k]).collect();
    let sampling = check_time_unit(&time_s, &kept_temp, &line, &layout)?;
    let axes: Vec<AxisColumn> = layout
        .axes_idx
        .iter()
        .zip(&rows.acc)
        .map(|((role, i), a)| AxisColumn {
            name: (*role).to_string(),
            column: layout.header[*i].clone(),
            accel_g: keep.iter().map(|&k| a[k]).collect(),
        })
        .collect();
    let med_mag = check_accel_unit(&axes, keep.len(), &layout)?;
    let units = unit_evidence(&layout, &sampling, med_mag, axes.len(), &kept_temp, &rows.file_temps);
    let columns = columns_used(&layout, &axes);
    Ok(StaticLog {
        time_s,
        time_origin_s: t0 * layout.time_unit.seconds(),
        temp_c: kept_temp,
        axes,
        line,
        columns,
        skipped: rows.skipped,
        sampling,
        units,
    })
}

/// The delimiter of a log: the most frequent of tab, comma and semicolon in its first line.
/// An empty first line, or decimal commas asked for in a comma-separated file, is refused.
fn delimiter(text: &[u8], opts: &StaticOptions) -> Result<u8, StaticError> {
    let first_line = text.split(|&c| c == b'\n').next().unwrap_or(b"");
    if first_line.iter().all(u8::is_ascii_whitespace) {
        return Err(StaticError::Empty);
    }
    // The delimiter is the most frequent of tab, comma and semicolon in the header.
    let delim =
        [b'\t', b',', b';'].into_iter().max_by_key(|d| first_line.iter().filter(|c| *c == d).count()).unwrap_or(b',');
    if opts.decimal_comma && delim == b',' {
        return Err(StaticError::DecimalCommaDelimiter);
    }
    Ok(delim)
}

/// The columns a static log is read from, and the unit of each with where it came from.
struct Layout {
    /// Column names, trimmed.
    header: Vec<String>,
    /// Time column.
    ti: usize,
    /// Temperature column.
    tc: usize,
    /// Acceleration columns with their roles, in the order ax, ay, az (those present).
    axes_idx: Vec<(&'static str, usize)>,
    /// Time unit.
    time_unit: TimeUnit,
    /// Where the time unit came from.
    time_src: UnitSource,
    /// Acceleration unit.
    accel_unit: AccelUnit,
    /// Where the acceleration unit came from.
    accel_src: UnitSource,
    /// Temperature unit.
    temp_unit: TempUnit,
    /// Where the temperature unit came from.
    temp_src: UnitSource,
}

/// Find the time, temperature and acceleration columns in `header` and decide their units:
/// a missing time, temperature or every acceleration column is refused, so is a time or
/// acceleration unit neither given nor in the name; the temperature is °C when neither says.
/// A `--columns` map that names an acceleration column names them all.
fn layout_of(header: Vec<String>, opts: &StaticOptions) -> Result<Layout, StaticError> {
    let need = |role: &str| -> Result<usize, StaticError> {
        find_column(&header, role, opts)?
            .ok_or_else(|| StaticError::MissingColumn { role: role.to_string(), header: header.clone() })
    };
    let ti = need("time")?;
    let tc = need("temp")?;
    let mut axes_idx: Vec<(&str, usize)> = Vec::new();
    // A `--columns` map that names an axis names the axes: the others are not looked for
    // by their common names. `ax=…,ay=…` on a log with an `az` column calibrated az too,
    // and the table held an axis the user had left out.
    let axes_named = opts.columns.roles.iter().any(|(r, _)| ["ax", "ay", "az"].contains(&r.as_str()));
    for role in ["ax", "ay", "az"] {
        if axes_named && !opts.columns.roles.iter().any(|(r, _)| r == role) {
            continue;
        }
        if let Some(i) = find_column(&header, role, opts)? {
            axes_idx.push((role, i));
        }
    }
    if axes_idx.is_empty() {
        return Err(StaticError::MissingColumn { role: "ax/ay/az".to_string(), header: header.clone() });
    }
    let (time_unit, time_src) = resolve(
        opts.time_unit,
        &[(TimeUnit::from_suffix(&header[ti]), &header[ti])],
        ReaderOption::TimeUnit,
        TimeUnit::name,
    )?
    .ok_or_else(|| StaticError::UnitUnknown { option: ReaderOption::TimeUnit, column: header[ti].clone() })?;
    let named: Vec<(Option<AccelUnit>, &String)> =
        axes_idx.iter().map(|(_, i)| (AccelUnit::from_suffix(&header[*i]), &header[*i])).collect();
    let (accel_unit, accel_src) =
        resolve(opts.accel_unit, &named, ReaderOption::AccelUnit, AccelUnit::name)?.ok_or_else(|| {
            StaticError::UnitUnknown { option: ReaderOption::AccelUnit, column: header[axes_idx[0].1].clone() }
        })?;
    let (temp_unit, temp_src) = resolve(
        opts.temp_unit,
        &[(TempUnit::from_suffix(&header[tc]), &header[tc])],
        ReaderOption::TempUnit,
        TempUnit::name,
    )?
    .unwrap_or((TempUnit::C, UnitSource::Assumed));
    Ok(Layout { header, ti, tc, axes_idx, time_unit, time_src, accel_unit, accel_src, temp_unit, temp_src })
}

/// What the row loop keeps (before glitches are removed) and what it found on the way.
#[derive(Default)]
struct Rows {
    /// Time in the file's unit.
    raw_t: Vec<f64>,
    /// Temperature, °C.
    temp: Vec<f64>,
    /// Specific force per axis, g.
    acc: Vec<Vec<f64>>,
    /// Line number of each row.
    lines: Vec<u64>,
    /// Rows skipped so far (NaN and duplicates; glitches come later).
    skipped: Skipped,
    /// Every parsed temperature in the file's unit, for the unit check of out-of-range rows.
    file_temps: Vec<f64>,
    /// The first [`KEPT_LINES`] bad rows, with their line numbers.
    faults: Vec<(u64, StaticRowFault)>,
    /// Bad rows, all counted.
    n_faults: usize,
    /// Rows whose bad field is a decimal-comma number.
    comma_rows: usize,
    /// The first of them: line, column, text.
    first_comma: Option<(u64, String, String)>,
    /// Any row that is not blank.
    any_row: bool,
}

impl Rows {
    /// Count a bad row; keep it with its line number while fewer than [`KEPT_LINES`] are kept.
    fn fault(&mut self, line: u64, f: StaticRowFault) {
        self.n_faults += 1;
        if self.faults.len() < KEPT_LINES {
            self.faults.push((line, f));
        }
    }
}

/// Read every row after the header: blank lines passed over, a row with the wrong field
/// count or a field that is no number counted as a fault, the rest to [`keep_row`]. Only
/// an unreadable record stops the loop (an error).
fn read_rows(
    rdr: &mut csv::Reader<&[u8]>,
    rec: &mut csv::ByteRecord,
    lines_of: &mut crate::lines::LineCounter<'_>,
    layout: &Layout,
    delim: u8,
    decimal_comma: bool,
) -> Result<Rows, StaticError> {
    let ncol = layout.header.len();
    let mut rows = Rows { acc: vec![Vec::new(); layout.axes_idx.len()], ..Rows::default() };
    let mut line: u64 = 1;
    loop {
        line += 1;
        match rdr.read_byte_record(rec) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => return Err(StaticError::Csv { line: Some(line), fault: crate::io_fault::CsvFault::of(&e) }),
        }
        if let Some(p) = rec.position() {
            line = lines_of.line_of(p.byte());
        }
        if rec.len() == 1 && rec.get(0).is_some_and(|b| b.iter().all(u8::is_ascii_whitespace)) {
            continue; // a blank line
        }
        rows.any_row = true;
        if rec.len() != ncol {
            rows.fault(line, StaticRowFault::FieldCount { got: rec.len(), want: ncol });
            continue;
        }
        if let Some(vals) = parse_row(rec, layout, line, delim, decimal_comma, &mut rows) {
            keep_row(&mut rows, layout, line, vals);
        }
    }
    Ok(rows)
}

/// The fields of one row in the order time, temperature, axes (`None` for an empty or NaN
/// field), or `None` when one is no number: that is a fault, and noted as a decimal comma
/// when it reads as one in a file not separated by commas.
fn parse_row(
    rec: &csv::ByteRecord,
    layout: &Layout,
    line: u64,
    delim: u8,
    decimal_comma: bool,
    rows: &mut Rows,
) -> Option<Vec<Option<f64>>> {
    let mut cols: Vec<usize> = vec![layout.ti, layout.tc];
    cols.extend(layout.axes_idx.iter().map(|(_, i)| *i));
    let mut vals = Vec::with_capacity(cols.len());
    for &c in &cols {
        match parse_field(rec.get(c).unwrap_or(b""), &layout.header[c], decimal_comma) {
            Ok(v) => vals.push(v),
            Err(f) => {
                if let StaticRowFault::NotANumber { column, text } = &f {
                    if delim != b',' && is_decimal_comma(text) {
                        rows.comma_rows += 1;
                        rows.first_comma.get_or_insert_with(|| (line, column.clone(), text.clone()));
                    }
                }
                rows.fault(line, f);
                return None;
            }
        }
    }
    Some(vals)
}

/// Keep a parsed row, in °C and g, unless a field is empty or NaN (skipped), its
/// temperature is outside [`TEMP_RANGE_C`] (a fault), its time goes backwards (a fault) or
/// repeats the previous row's (skipped).
fn keep_row(rows: &mut Rows, layout: &Layout, line: u64, vals: Vec<Option<f64>>) {
    if vals.iter().any(Option::is_none) {
        rows.skipped.nan.add(line);
        return;
    }
    let vals: Vec<f64> = vals.into_iter().flatten().collect();
    let (t, tc_v) = (vals[0], layout.temp_unit.to_c(vals[1]));
    rows.file_temps.push(vals[1]);
    if !TEMP_RANGE_C.contains(&tc_v) {
        rows.fault(line, StaticRowFault::TempOutOfRange(tc_v));
        return;
    }
    if let Some(&prev) = rows.raw_t.last() {
        if t < prev {
            rows.fault(line, StaticRowFault::TimeBackwards { previous: prev, time: t });
            return;
        }
        if t == prev {
            rows.skipped.duplicate.add(line);
            return;
        }
    }
    rows.raw_t.push(t);
    rows.temp.push(tc_v);
    for (k, a) in rows.acc.iter_mut().enumerate() {
        a.push(vals[2 + k] * layout.accel_unit.g());
    }
    rows.lines.push(line);
}

/// The error for a log with bad rows: a decimal comma when the first bad field is one, the
/// temperature unit when a reading is out of range and every reading fits another unit,
/// else the rows themselves.
fn faults_error(rows: Rows, temp_unit: TempUnit, temp_src: UnitSource) -> StaticError {
    // The first bad field a decimal-comma number: say that, not "not a number" rows.
    let faults = rows.faults;
    if let Some((line, column, text)) = rows.first_comma.filter(|(l, _, _)| faults.first().is_some_and(|f| f.0 == *l)) {
        return StaticError::DecimalComma { line, column, text, rows: rows.comma_rows };
    }
    // Temperatures out of range in the unit read, and every one in range in another:
    // the unit is wrong, not the rows.
    let file_temps = rows.file_temps;
    if faults.iter().any(|(_, f)| matches!(f, StaticRowFault::TempOutOfRange(_))) {
        let fits = temp_fits(&file_temps, temp_unit);
        if !fits.is_empty() {
            let (lo, hi) = range_c(&file_temps, temp_unit);
            let out = file_temps.iter().filter(|&&x| !TEMP_RANGE_C.contains(&temp_unit.to_c(x))).count();
            return StaticError::Unit(Box::new(UnitMismatch {
                option: ReaderOption::TempUnit,
                stated: temp_unit.name(),
                source: temp_src,
                evidence: format!(
                    "the temperature spans {lo:.1}..{hi:.1} °C ({out} of {} rows outside -60..130 °C)",
                    file_temps.len()
                ),
                expected: "a board in a climate chamber reads -60..130 °C".to_string(),
                fits: fits.into_iter().map(|(u, (a, b))| (u.name(), format!("{a:.1}..{b:.1} °C"))).collect(),
            }));
        }
    }
    StaticError::Rows { first: faults, total: rows.n_faults }
}

/// The rows left once glitch rows (any channel spiking, see the module docs) are skipped
/// and counted; fewer than [`MIN_ROWS`] is an error.
fn drop_glitches(rows: &mut Rows) -> Result<Vec<usize>, StaticError> {
    // Glitch rows: any channel spiking marks the row.
    let mut glitch = vec![false; rows.raw_t.len()];
    for i in glitches(&rows.temp, GLITCH_SIGMAS, GLITCH_MIN_TEMP_C) {
        glitch[i] = true;
    }
    for a in &rows.acc {
        for i in glitches(a, GLITCH_SIGMAS, GLITCH_MIN_ACCEL_G) {
            glitch[i] = true;
        }
    }
    let keep: Vec<usize> = (0..rows.raw_t.len()).filter(|&i| !glitch[i]).collect();
    for (i, _) in glitch.iter().enumerate().filter(|(_, g)| **g) {
        rows.skipped.glitch.add(rows.lines[i]);
    }
    if keep.len() < MIN_ROWS {
        return Err(StaticError::TooFewRows { kept: keep.len(), skipped: std::mem::take(&mut rows.skipped) });
    }
    Ok(keep)
}

/// Readings outside this range, °C, are refused.
pub(crate) const TEMP_RANGE_C: std::ops::RangeInclusive<f64> = -60.0..=130.0;

/// Plausible median row intervals, s.
const INTERVAL_S: std::ops::RangeInclusive<f64> = 1e-5..=60.0;

#[cfg(test)]
mod tests;
