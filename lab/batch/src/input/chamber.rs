//! A chamber log holding every unit, split into one log per unit (`time`, then
//! `SERIAL.temp`, `SERIAL.ax`, `SERIAL.ay`, `SERIAL.az` per unit; or a cycling log's shared
//! columns and `SERIAL.temp_c`, `SERIAL.pulses`). The split is one pass, its cost per unit
//! flat in the number of units; the fields are copied as written, so each unit's reader sees
//! what the logger wrote. A log read from its file is streamed: the units' rows wait in files
//! of their own, never the whole log in memory.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::{check_serials, UnitInput, UnitRows};
use crate::{BatchError, ChamberFault};
use qfa_log::open::ReadFlags;
use qfa_log::static_log::columns::ColumnMap;

/// The roles a chamber log's unit columns carry, after the serial and a dot.
pub(crate) const UNIT_ROLES: [&str; 4] = ["temp", "ax", "ay", "az"];

fn chamber(path: &Path, fault: ChamberFault) -> BatchError {
    BatchError::Chamber { path: path.to_path_buf(), fault }
}

/// The units of a chamber log: every header column `SERIAL.ROLE` (`UNIT_ROLES`) is unit
/// SERIAL's; the time column is `--columns time=NAME`, or else the one column without a
/// serial. Each unit needs its `temp` and at least one axis. Each unit's log is held in
/// memory ([`from_chamber_file`] streams a log from its file instead).
///
/// # Errors
/// No unit columns, no or several candidate time columns, a unit without `temp` or axes, a
/// serial rule broken, or a CSV error.
pub fn from_chamber_log(path: &Path, bytes: &[u8], base: &ReadFlags) -> Result<Vec<UnitInput>, BatchError> {
    let first = bytes.split(|b| *b == b'\n').next().unwrap_or_default();
    split_chamber(path, first, bytes, base, None)
}

/// A chamber log's units, read from its file as a stream: each unit's rows go to its own
/// file in a folder made in `out` (removed when the result is dropped), in pieces of at most
/// [`SPILL_BYTES`] for all units together. So a batch holds a bounded part of the chamber
/// log at any time, however many units it holds, and each unit's log is read when its turn
/// comes, as a manifest's are. The units are the same as [`from_chamber_log`]'s, their logs
/// the same bytes.
///
/// # Errors
/// The file or the folder cannot be read or written, or [`from_chamber_log`]'s.
pub fn from_chamber_file(path: &Path, base: &ReadFlags, out: &Path) -> Result<ChamberUnits, BatchError> {
    use std::io::Read;
    fn io(p: &Path) -> impl Fn(std::io::Error) -> BatchError + '_ {
        move |source| BatchError::Io { path: p.to_path_buf(), source }
    }
    let mut head = Vec::new();
    std::fs::File::open(path).and_then(|f| f.take(64 * 1024).read_to_end(&mut head)).map_err(io(path))?;
    let first = head.split(|b| *b == b'\n').next().unwrap_or_default();
    std::fs::create_dir_all(out).map_err(io(out))?;
    let rows = tempfile::Builder::new().prefix(".chamber-rows-").tempdir_in(out).map_err(io(out))?;
    let file = std::io::BufReader::new(std::fs::File::open(path).map_err(io(path))?);
    let units = split_chamber(path, first, file, base, Some((rows.path(), SPILL_BYTES)))?;
    Ok(ChamberUnits { units, _rows: rows })
}

/// A chamber log's units whose logs are files in a folder of their own, which goes when
/// this does: keep it until the batch has run.
#[derive(Debug)]
pub struct ChamberUnits {
    /// The units.
    pub units: Vec<UnitInput>,
    _rows: tempfile::TempDir,
}

/// What the split holds of all units' rows before it appends them to their files, bytes.
pub const SPILL_BYTES: usize = 8 << 20;

/// Units' logs being written: in memory (`spill` `None`), or appended to one file per unit
/// in `spill` whenever they hold [`SPILL_BYTES`] together.
struct UnitLogs<'a> {
    spill: Option<&'a Path>,
    files: Vec<PathBuf>,
    held: usize,
    budget: usize,
}

impl<'a> UnitLogs<'a> {
    fn new(spill: Option<(&'a Path, usize)>, serials: &[String], ext: &str) -> Self {
        let files =
            spill.map_or_else(Vec::new, |(d, _)| serials.iter().map(|s| d.join(format!("{s}.{ext}"))).collect());
        Self { spill: spill.map(|s| s.0), files, held: 0, budget: spill.map_or(usize::MAX, |s| s.1) }
    }

    /// After a record added `added` bytes over all units: append every unit's bytes to its
    /// file when they reach the budget.
    fn added(&mut self, added: usize, bufs: &mut [&mut Vec<u8>]) -> Result<(), BatchError> {
        self.held += added;
        if self.spill.is_some() && self.held >= self.budget {
            self.flush(bufs)?;
        }
        Ok(())
    }

    fn flush(&mut self, bufs: &mut [&mut Vec<u8>]) -> Result<(), BatchError> {
        use std::io::Write;
        for (buf, file) in bufs.iter_mut().zip(&self.files) {
            std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(file)
                .and_then(|mut f| f.write_all(buf))
                .map_err(|source| BatchError::Io { path: file.clone(), source })?;
            buf.clear();
        }
        self.held = 0;
        Ok(())
    }

    /// Where unit `i`'s log is, its remaining bytes appended first when spilled.
    fn finish(&mut self, mut bufs: Vec<Vec<u8>>) -> Result<Vec<UnitRows>, BatchError> {
        if self.spill.is_none() {
            return Ok(bufs.into_iter().map(UnitRows::Bytes).collect());
        }
        self.flush(&mut bufs.iter_mut().collect::<Vec<_>>())?;
        Ok(self.files.iter().cloned().map(UnitRows::File).collect())
    }
}

/// [`from_chamber_log`] on any reader of the log's bytes, its header line `first`; each
/// unit's log in memory or spilled to `spill`'s folder in pieces of its budget
/// ([`UnitLogs`]).
fn split_chamber<R: std::io::Read>(
    path: &Path,
    first: &[u8],
    source: R,
    base: &ReadFlags,
    spill: Option<(&Path, usize)>,
) -> Result<Vec<UnitInput>, BatchError> {
    // The static reader's own rule: the delimiter the header line holds most of.
    let delim =
        [b'\t', b',', b';'].into_iter().max_by_key(|d| first.iter().filter(|c| *c == d).count()).unwrap_or(b',');
    let mut rd = csv::ReaderBuilder::new().delimiter(delim).flexible(true).from_reader(source);
    let header: Vec<String> =
        rd.headers().map_err(|e| chamber(path, ChamberFault::Csv(e)))?.iter().map(|h| h.trim().to_string()).collect();
    if header.iter().any(|h| h.ends_with(".pulses")) {
        return from_cycling_chamber(path, &header, rd, base, spill);
    }
    let (mut order, mut others) = (Vec::new(), Vec::new());
    let cols = serial_columns(path, &header, &mut order, &mut others)?;
    let time_col = time_column(path, &header, &others, base)?;
    check_serials(order.iter().map(String::as_str))?;
    // Per unit: the (role, column) pairs it has, and its one-unit log's bytes.
    let mut picked = Vec::with_capacity(order.len());
    let mut texts: Vec<Vec<u8>> = Vec::with_capacity(order.len());
    for s in &order {
        let p = unit_roles(path, s, &cols[s])?;
        texts.push(header_line(&p).into_bytes());
        picked.push(p);
    }
    let mut logs = UnitLogs::new(spill, &order, "tsv");
    for rec in rd.records() {
        let rec = rec.map_err(|e| chamber(path, ChamberFault::Csv(e)))?;
        let field = |i: usize| rec.get(i).unwrap_or("").trim().as_bytes();
        let t = field(time_col);
        let mut added = 0;
        for (text, p) in texts.iter_mut().zip(&picked) {
            let before = text.len();
            text.extend_from_slice(t);
            for (_, i) in p {
                text.push(b'\t');
                text.extend_from_slice(field(*i));
            }
            text.push(b'\n');
            added += text.len() - before;
        }
        logs.added(added, &mut texts.iter_mut().collect::<Vec<_>>())?;
    }
    let rows = logs.finish(texts)?;
    // Each unit's one-unit log names its columns by their roles.
    let columns =
        ColumnMap { roles: ["time", "temp", "ax", "ay", "az"].map(|r| (r.to_string(), r.to_string())).to_vec() };
    Ok(order
        .into_iter()
        .zip(picked)
        .zip(rows)
        .map(|((serial, picked), rows)| unit_input(path, &header, &columns, base, serial, &picked, rows))
        .collect())
}

/// A unit of a cycling chamber log being split.
struct CyclingUnit {
    serial: String,
    /// Its columns in the cycling reader's order.
    picked: Vec<usize>,
    /// Its `pulses` column.
    pulses: usize,
    /// The writer of its log's text.
    writer: csv::Writer<Vec<u8>>,
    /// Rows left out: its `pulses` cell empty.
    left_out: usize,
}

/// A cycling chamber log's columns per unit, after the serial and a dot: the unit's own
/// temperature sensor and pulse count.
pub(crate) const CYCLING_UNIT_ROLES: [&str; 2] = ["temp_c", "pulses"];

/// The units of a multi-unit cycling log (QFA units on one index head through one program
/// and one position sequence): the cycling log's shared columns (`program`, `run`,
/// `time_s`, `input_g`, `interval_s`) once, and per unit `SERIAL.temp_c` and
/// `SERIAL.pulses`. Each unit becomes the text of a one-unit cycling log, its fields as
/// written, for the one cycling reader.
///
/// # Errors
/// A shared column missing, a unit without both of its columns, a serial rule broken, or a
/// CSV error.
fn from_cycling_chamber<R: std::io::Read>(
    path: &Path,
    header: &[String],
    mut rd: csv::Reader<R>,
    base: &ReadFlags,
    spill: Option<(&Path, usize)>,
) -> Result<Vec<UnitInput>, BatchError> {
    use qfa_log::cycling::COLUMNS;
    // A cycling log's columns and units are fixed: a static reader option given with one is
    // a mistake of the command, refused here once, not as a failure of every unit.
    if base.any() {
        return Err(chamber(path, ChamberFault::OptionsOnCyclingLog));
    }
    let shared: Vec<&'static str> = COLUMNS.into_iter().filter(|c| !CYCLING_UNIT_ROLES.contains(c)).collect();
    let missing: Vec<&'static str> = shared.iter().copied().filter(|c| !header.iter().any(|h| h == c)).collect();
    if !missing.is_empty() {
        return Err(chamber(path, ChamberFault::CyclingColumns { missing }));
    }
    let col = |name: &str| header.iter().position(|h| h == name);
    let mut order: Vec<String> = Vec::new();
    for h in header {
        if let Some((serial, role)) = h.rsplit_once('.') {
            if CYCLING_UNIT_ROLES.contains(&role) && !serial.is_empty() && !order.iter().any(|s| s == serial) {
                order.push(serial.to_string());
            }
        }
    }
    check_serials(order.iter().map(String::as_str))?;
    // Per unit: serial, the columns of its one-unit log in the cycling reader's order, and a
    // writer of that log's text.
    let mut units: Vec<CyclingUnit> = Vec::with_capacity(order.len());
    for s in order {
        let picked: Vec<Option<usize>> = COLUMNS
            .iter()
            .map(|c| if CYCLING_UNIT_ROLES.contains(c) { col(&format!("{s}.{c}")) } else { col(c) })
            .collect();
        if picked.iter().any(Option::is_none) {
            let roles = CYCLING_UNIT_ROLES.into_iter().filter(|r| col(&format!("{s}.{r}")).is_some()).collect();
            return Err(chamber(path, ChamberFault::CyclingUnit { serial: s, roles }));
        }
        let mut w = csv::Writer::from_writer(Vec::new());
        w.write_record(COLUMNS).map_err(|e| chamber(path, ChamberFault::Csv(e)))?;
        let pulses = col(&format!("{s}.pulses")).unwrap_or(usize::MAX);
        units.push(CyclingUnit {
            serial: s,
            picked: picked.into_iter().flatten().collect(),
            pulses,
            writer: w,
            left_out: 0,
        });
    }
    let csv_fault = |e: csv::Error| chamber(path, ChamberFault::Csv(e));
    let serials: Vec<String> = units.iter().map(|u| u.serial.clone()).collect();
    let mut logs = UnitLogs::new(spill, &serials, "csv");
    // The writers' bytes, each writer replaced by a new one (no header: the rows go on).
    let drained = |units: &mut [CyclingUnit]| -> Result<Vec<Vec<u8>>, BatchError> {
        units
            .iter_mut()
            .map(|u| {
                let w = std::mem::replace(&mut u.writer, csv::Writer::from_writer(Vec::new()));
                w.into_inner().map_err(|e| csv_fault(e.into_error().into()))
            })
            .collect()
    };
    for rec in rd.records() {
        let rec = rec.map_err(csv_fault)?;
        let mut added = 0;
        for u in &mut units {
            // A row without the unit's count is not a row of its log: the unit was not
            // counted then (taken off the head, or its counter not logged). Written, the
            // cycling reader refused the unit's whole log as malformed.
            if rec.get(u.pulses).is_none_or(|f| f.trim().is_empty()) {
                u.left_out += 1;
                continue;
            }
            let fields = u.picked.iter().map(|&i| rec.get(i).unwrap_or("").trim());
            added += fields.clone().map(|f| f.len() + 1).sum::<usize>();
            u.writer.write_record(fields).map_err(csv_fault)?;
        }
        if logs.spill.is_some() && logs.held + added >= logs.budget {
            let mut bufs = drained(&mut units)?;
            logs.flush(&mut bufs.iter_mut().collect::<Vec<_>>())?;
        } else {
            logs.held += added;
        }
    }
    let rows = logs.finish(drained(&mut units)?)?;
    units
        .into_iter()
        .zip(rows)
        .map(|(u, rows)| {
            let source = format!(
                "{}, columns {}",
                path.display(),
                u.picked.iter().map(|&i| format!("`{}`", header[i])).collect::<Vec<_>>().join(", ")
            );
            Ok(UnitInput { serial: u.serial, source, rows, flags: base.clone(), left_out: u.left_out, spelling: None })
        })
        .collect()
}

/// The header's unit columns, serial → role → column index; the serials in the header's
/// order go to `order`, the columns without a serial to `others`.
fn serial_columns(
    path: &Path,
    header: &[String],
    order: &mut Vec<String>,
    others: &mut Vec<usize>,
) -> Result<BTreeMap<String, BTreeMap<&'static str, usize>>, BatchError> {
    // serial → role → column index, in the header's order of serials.
    let mut cols: BTreeMap<String, BTreeMap<&'static str, usize>> = BTreeMap::new();
    for (i, h) in header.iter().enumerate() {
        let role = h.rsplit_once('.').and_then(|(s, r)| UNIT_ROLES.iter().find(|x| **x == r).map(|x| (s, *x)));
        match role {
            Some((serial, role)) if !serial.is_empty() => {
                if !cols.contains_key(serial) {
                    order.push(serial.to_string());
                }
                if cols.entry(serial.to_string()).or_default().insert(role, i).is_some() {
                    return Err(chamber(path, ChamberFault::DuplicateColumn(h.clone())));
                }
            }
            _ => others.push(i),
        }
    }
    if order.is_empty() {
        return Err(chamber(path, ChamberFault::NoUnitColumns));
    }
    Ok(cols)
}

/// The time column: the one `--columns time=NAME` names, or else the one column without a
/// serial (`others`).
fn time_column(path: &Path, header: &[String], others: &[usize], base: &ReadFlags) -> Result<usize, BatchError> {
    let time_name =
        base.columns.as_ref().and_then(|c| c.roles.iter().find(|(r, _)| r == "time").map(|(_, c)| c.clone()));
    let time_col = match time_name {
        Some(name) => header
            .iter()
            .position(|h| *h == name)
            .ok_or_else(|| chamber(path, ChamberFault::NoNamedTimeColumn(name)))?,
        None => match others {
            [i] => *i,
            [] => return Err(chamber(path, ChamberFault::NoTimeColumn)),
            many => {
                let names = many.iter().map(|&i| header[i].clone()).collect();
                return Err(chamber(path, ChamberFault::SeveralTimeColumns(names)));
            }
        },
    };
    Ok(time_col)
}

/// Unit `s`'s (role, column) pairs in [`UNIT_ROLES`]' order; refused without `temp` and
/// an axis.
fn unit_roles(
    path: &Path,
    s: &str,
    roles: &BTreeMap<&'static str, usize>,
) -> Result<Vec<(&'static str, usize)>, BatchError> {
    if !roles.contains_key("temp") || roles.len() < 2 {
        return Err(chamber(
            path,
            ChamberFault::UnitColumns { serial: s.to_string(), roles: roles.keys().copied().collect() },
        ));
    }
    Ok(UNIT_ROLES.iter().filter_map(|r| roles.get(r).map(|&i| (*r, i))).collect())
}

/// The header line of a unit's one-unit log: `time`, then its roles.
fn header_line(picked: &[(&'static str, usize)]) -> String {
    let mut text = String::from("time");
    for (r, _) in picked {
        text.push('\t');
        text.push_str(r);
    }
    text.push('\n');
    text
}

/// A unit's input: its one-unit log `rows` (columns `picked` of the chamber log), read
/// with the chamber log's flags and the unit's roles.
fn unit_input(
    path: &Path,
    header: &[String],
    columns: &ColumnMap,
    base: &ReadFlags,
    serial: String,
    picked: &[(&'static str, usize)],
    rows: UnitRows,
) -> UnitInput {
    let mut roles = columns.clone();
    roles.roles.retain(|(r, _)| r == "time" || picked.iter().any(|(p, _)| p == r));
    let source = format!(
        "{}, columns {}",
        path.display(),
        picked.iter().map(|(_, i)| format!("`{}`", header[*i])).collect::<Vec<_>>().join(", ")
    );
    // The static reader skips a row with an empty field itself, and counts it.
    UnitInput {
        serial,
        source,
        rows,
        flags: ReadFlags { columns: Some(roles), ..base.clone() },
        left_out: 0,
        spelling: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use qfa_log::static_log::columns::TimeUnit;

    /// A chamber log splits into one log per unit holding that unit's fields as written,
    /// under the time column, in the header's order of serials.
    #[test]
    fn chamber_log_splits_by_serial() {
        let log = "time,B7.temp,B7.ax,A1.temp,A1.az\n0,20.5,0.001,21.0,-1.0\n1,20.6,0.002,21.1,-0.999\n";
        let u = from_chamber_log(Path::new("c.csv"), log.as_bytes(), &ReadFlags::default()).unwrap();
        assert_eq!(u.iter().map(|u| u.serial.as_str()).collect::<Vec<_>>(), ["B7", "A1"]);
        assert_eq!(
            String::from_utf8(u[1].bytes().unwrap().into_owned()).unwrap(),
            "time\ttemp\taz\n0\t21.0\t-1.0\n1\t21.1\t-0.999\n"
        );
        assert_eq!(u[0].flags.columns.as_ref().unwrap().roles.len(), 3);
    }

    /// The mistakes a user makes are refused with what to do: no unit columns, two
    /// candidate time columns, a unit without its temperature, a duplicate or unsafe serial.
    #[test]
    fn chamber_log_mistakes_are_refused() {
        let f = ReadFlags::default();
        let cases = [
            ("time,temp,ax\n0,1,2\n", "no unit columns"),
            ("time,stamp,A.temp,A.ax\n0,0,1,2\n", "--columns time=NAME"),
            ("time,A.ax,A.ay\n0,1,2\n", "needs SERIAL.temp"),
            ("time,../x.temp,../x.ax\n0,1,2\n", "may hold only"),
        ];
        for (log, want) in cases {
            let e = from_chamber_log(Path::new("c.csv"), log.as_bytes(), &f).unwrap_err().to_string();
            assert!(e.contains(want), "{log:?}: {e}");
        }
        assert!(check_serials(["A", "B", "A"]).unwrap_err().to_string().contains("units 1 and 3"));
    }

    /// A multi-unit cycling log splits into one cycling log per unit, the shared columns
    /// with the unit's own temperature and pulses, fields as written; a unit without its
    /// pulses or a log without `input_g` is refused with what is missing.
    #[test]
    fn a_cycling_chamber_log_splits_by_serial() {
        let log = "program,run,time_s,input_g,interval_s,Q2.temp_c,Q2.pulses,Q1.temp_c,Q1.pulses\n\
                   p,0,10,1,10,,3203545,,3100001\np,0,20,1,10,22.125,3203561,21.9375,3100020\n";
        let u = from_chamber_log(Path::new("c.csv"), log.as_bytes(), &ReadFlags::default()).unwrap();
        assert_eq!(u.iter().map(|u| u.serial.as_str()).collect::<Vec<_>>(), ["Q2", "Q1"]);
        assert_eq!(
            String::from_utf8(u[1].bytes().unwrap().into_owned()).unwrap(),
            "program,run,time_s,input_g,temp_c,pulses,interval_s\np,0,10,1,,3100001,10\np,0,20,1,21.9375,3100020,10\n"
        );
        let f = ReadFlags::default();
        let e = from_chamber_log(Path::new("c.csv"), b"program,run,time_s,input_g,interval_s,Q.temp_c\n", &f);
        assert!(e.is_err(), "no pulses column at all: not a cycling chamber log, and no static unit either");
        let e = from_chamber_log(Path::new("c.csv"), b"program,run,time_s,interval_s,Q.temp_c,Q.pulses\n", &f)
            .unwrap_err()
            .to_string();
        assert!(e.contains("input_g"), "{e}");
        let e = from_chamber_log(Path::new("c.csv"), b"program,run,time_s,input_g,interval_s,Q.pulses\n", &f)
            .unwrap_err()
            .to_string();
        assert!(e.contains("Q.temp_c"), "{e}");
        let unit = ReadFlags { time_unit: Some(TimeUnit::S), ..ReadFlags::default() };
        let e = from_chamber_log(Path::new("c.csv"), log.as_bytes(), &unit).unwrap_err().to_string();
        assert!(e.contains("give none"), "{e}");
    }

    /// Streamed through files in pieces (a budget of 40 bytes: a piece every row or two),
    /// a static and a cycling chamber log give the units and the bytes the split in memory
    /// gives; and the public reader of a file removes its folder when dropped.
    #[test]
    fn a_streamed_split_writes_the_bytes_the_split_in_memory_holds() {
        let dir = std::env::temp_dir().join(format!("qfa-chamber-spill-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let static_log = "time,B7.temp,B7.ax,A1.temp,A1.az\n0,20.5,0.001,21.0,-1.0\n1,20.6,0.002,21.1,-0.999\n\
                          2,20.7,0.003,21.2,-0.998\n3,20.8,0.004,21.3,-0.997\n";
        let cycling_log = "program,run,time_s,input_g,interval_s,Q2.temp_c,Q2.pulses,Q1.temp_c,Q1.pulses\n\
                           p,0,10,1,10,,3203545,,3100001\np,0,20,1,10,22.125,3203561,21.9375,3100020\n\
                           p,0,30,1,10,22.25,3203570,22.0,3100031\n";
        let f = ReadFlags::default();
        for (k, log) in [static_log, cycling_log].into_iter().enumerate() {
            let path = Path::new("c.csv");
            let first = log.lines().next().unwrap().as_bytes();
            let spill = dir.join(k.to_string());
            std::fs::create_dir_all(&spill).unwrap();
            let memory = from_chamber_log(path, log.as_bytes(), &f).unwrap();
            let streamed = split_chamber(path, first, log.as_bytes(), &f, Some((spill.as_path(), 40))).unwrap();
            assert_eq!(memory.len(), streamed.len());
            for (m, s) in memory.iter().zip(&streamed) {
                assert!(matches!(s.rows, UnitRows::File(_)), "{s:?}");
                assert_eq!((&m.serial, &m.source), (&s.serial, &s.source));
                assert_eq!(format!("{:?}", m.flags), format!("{:?}", s.flags));
                assert_eq!(m.bytes().unwrap(), s.bytes().unwrap(), "{}", m.serial);
            }
        }
        let file = dir.join("chamber.csv");
        std::fs::write(&file, static_log).unwrap();
        let out = dir.join("out");
        let units = from_chamber_file(&file, &f, &out).unwrap();
        let UnitRows::File(one) = &units.units[0].rows else { panic!("a file") };
        assert!(one.starts_with(&out) && one.exists(), "{one:?}");
        let rows = one.parent().unwrap().to_path_buf();
        drop(units);
        assert!(!rows.exists(), "{rows:?} left behind");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
