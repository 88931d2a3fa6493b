//! A batch's units, from either input a production line has: one chamber log holding every
//! unit (`time`, then `SERIAL.temp`, `SERIAL.ax`, `SERIAL.ay`, `SERIAL.az` per unit), or a
//! manifest (`batch.toml`) naming one log per serial.
//!
//! Either way each unit ends as the bytes of a one-unit static log and the reader flags to
//! read it with, so every unit goes through the one static reader with all its checks (units,
//! time order, gaps, skipped rows). A chamber log is split in one pass (its cost per unit does
//! not grow with the number of units); its fields are copied as written, so the reader sees
//! what the logger wrote.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::{BatchError, ChamberFault, ManifestFault, SerialFault};
use qfa_log::open::ReadFlags;
use qfa_log::static_log::columns::{AccelUnit, ColumnMap, TimeUnit};
use qfa_log::static_log::StaticError;
use qfa_log::units::TempUnit;

/// The roles a chamber log's unit columns carry, after the serial and a dot.
pub(crate) const UNIT_ROLES: [&str; 4] = ["temp", "ax", "ay", "az"];

/// One unit to calibrate.
#[derive(Clone, Debug)]
pub struct UnitInput {
    /// Serial number (its output folder's name).
    pub serial: String,
    /// Where its rows came from, in words (the certificate's `source`).
    pub source: String,
    /// A one-unit log.
    pub rows: UnitRows,
    /// How to read it.
    pub flags: ReadFlags,
}

/// Where a unit's one-unit log is.
#[derive(Clone, Debug)]
pub enum UnitRows {
    /// In memory (split from a chamber log).
    Bytes(Vec<u8>),
    /// A file, read when the unit's turn comes (a manifest's logs are not all held at once).
    File(PathBuf),
}

impl UnitInput {
    /// The log's bytes.
    ///
    /// # Errors
    /// The file cannot be read.
    pub(crate) fn bytes(&self) -> Result<std::borrow::Cow<'_, [u8]>, BatchError> {
        match &self.rows {
            UnitRows::Bytes(b) => Ok(std::borrow::Cow::Borrowed(b)),
            UnitRows::File(p) => std::fs::read(p)
                .map(std::borrow::Cow::Owned)
                .map_err(|source| BatchError::Io { path: p.clone(), source }),
        }
    }

    /// The kind of log it is, from its first 64 KiB (the magic bytes and the header line):
    /// the decision its reader will take. `None` when the file cannot be read now (its
    /// unit then fails when its turn comes, saying why).
    pub(crate) fn format(&self) -> Option<qfa_log::open::LogFormat> {
        use std::io::Read;
        const HEAD: u64 = 64 * 1024;
        let mut head = Vec::new();
        let bytes: &[u8] = match &self.rows {
            UnitRows::Bytes(b) => b,
            UnitRows::File(p) => {
                std::fs::File::open(p).ok()?.take(HEAD).read_to_end(&mut head).ok()?;
                &head
            }
        };
        Some(qfa_log::open::format_of_bytes(bytes, &self.flags))
    }
}

/// Reader settings a manifest may give once for every unit and override per unit.
#[derive(Clone, Debug, Default)]
struct Reading {
    columns: Option<String>,
    time_unit: Option<String>,
    accel_unit: Option<String>,
    temp_unit: Option<String>,
    decimal_comma: Option<bool>,
}

// serde's `flatten` disables `deny_unknown_fields`, so the reader keys are written out in
// both tables, and a typo in either is refused.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ManifestUnit {
    serial: String,
    log: PathBuf,
    columns: Option<String>,
    time_unit: Option<String>,
    accel_unit: Option<String>,
    temp_unit: Option<String>,
    decimal_comma: Option<bool>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    columns: Option<String>,
    time_unit: Option<String>,
    accel_unit: Option<String>,
    temp_unit: Option<String>,
    decimal_comma: Option<bool>,
    #[serde(default)]
    unit: Vec<ManifestUnit>,
}

impl ManifestUnit {
    fn reading(&self) -> Reading {
        Reading {
            columns: self.columns.clone(),
            time_unit: self.time_unit.clone(),
            accel_unit: self.accel_unit.clone(),
            temp_unit: self.temp_unit.clone(),
            decimal_comma: self.decimal_comma,
        }
    }
}

impl Manifest {
    fn reading(&self) -> Reading {
        Reading {
            columns: self.columns.clone(),
            time_unit: self.time_unit.clone(),
            accel_unit: self.accel_unit.clone(),
            temp_unit: self.temp_unit.clone(),
            decimal_comma: self.decimal_comma,
        }
    }
}

impl Reading {
    /// These settings over `base` (the command line's), each one set here replacing it.
    fn flags(&self, base: &ReadFlags, path: &Path, serial: Option<&str>) -> Result<ReadFlags, BatchError> {
        let bad = |key: &'static str, source: StaticError| BatchError::Manifest {
            path: path.to_path_buf(),
            fault: ManifestFault::Setting { serial: serial.map(str::to_string), key, source: Box::new(source) },
        };
        let mut f = base.clone();
        if let Some(c) = &self.columns {
            f.columns = Some(c.parse::<ColumnMap>().map_err(|e| bad("columns", e))?);
        }
        if let Some(u) = &self.time_unit {
            f.time_unit = Some(u.parse::<TimeUnit>().map_err(|e| bad("time_unit", StaticError::BadUnit(e)))?);
        }
        if let Some(u) = &self.accel_unit {
            f.accel_unit = Some(u.parse::<AccelUnit>().map_err(|e| bad("accel_unit", StaticError::BadUnit(e)))?);
        }
        if let Some(u) = &self.temp_unit {
            f.temp_unit = Some(u.parse::<TempUnit>().map_err(|e| bad("temp_unit", StaticError::BadUnit(e)))?);
        }
        if let Some(d) = self.decimal_comma {
            f.decimal_comma = d;
        }
        Ok(f)
    }
}

/// A serial becomes a folder name: letters, digits, `-`, `_` and `.`, not starting with a
/// dot, at most 64 characters; never two units with one serial.
///
/// # Errors
/// [`BatchError::Serial`] naming the serial and the rule.
pub(crate) fn check_serials<'a>(serials: impl IntoIterator<Item = &'a str>) -> Result<(), BatchError> {
    let mut seen = BTreeMap::new();
    for (i, s) in serials.into_iter().enumerate() {
        let ok = !s.is_empty()
            && s.len() <= 64
            && !s.starts_with('.')
            && s.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'));
        if !ok {
            return Err(BatchError::Serial(SerialFault::NotAFolderName(s.to_string())));
        }
        if let Some(first) = seen.insert(s.to_string(), i) {
            return Err(BatchError::Serial(SerialFault::Shared { serial: s.to_string(), units: [first + 1, i + 1] }));
        }
    }
    Ok(())
}

/// The units a manifest names, each log read from disk (paths relative to the manifest's
/// folder). `base` is the command line's reader flags, which the manifest's keys override.
///
/// # Errors
/// The manifest unreadable or unknown keys in it (a typo is refused, never ignored), a bad
/// unit name, a serial rule broken, or a log that does not exist.
pub fn from_manifest(path: &Path, base: &ReadFlags) -> Result<Vec<UnitInput>, BatchError> {
    let text = std::fs::read_to_string(path).map_err(|source| BatchError::Io { path: path.to_path_buf(), source })?;
    let manifest = |fault| BatchError::Manifest { path: path.to_path_buf(), fault };
    let m: Manifest = toml::from_str(&text).map_err(|e| {
        // A log given by mistake: a header line of separated columns, with no `=` or `[`.
        let first = text.lines().next().unwrap_or("");
        let columns = first.split([',', '\t']).count();
        if columns > 2 && !first.contains('=') && !first.trim_start().starts_with('[') {
            manifest(ManifestFault::IsALog { columns })
        } else {
            manifest(ManifestFault::Toml(e))
        }
    })?;
    if m.unit.is_empty() {
        return Err(manifest(ManifestFault::NoUnits));
    }
    check_serials(m.unit.iter().map(|u| u.serial.as_str()))?;
    let dir = path.parent().unwrap_or_else(|| Path::new("."));
    let defaults = m.reading().flags(base, path, None)?;
    m.unit
        .iter()
        .map(|u| {
            let flags = u.reading().flags(&defaults, path, Some(&u.serial))?;
            let log = dir.join(&u.log);
            if !log.is_file() {
                return Err(manifest(ManifestFault::NoLog { serial: u.serial.clone(), log }));
            }
            Ok(UnitInput {
                serial: u.serial.clone(),
                source: log.display().to_string(),
                rows: UnitRows::File(log),
                flags,
            })
        })
        .collect()
}

fn chamber(path: &Path, fault: ChamberFault) -> BatchError {
    BatchError::Chamber { path: path.to_path_buf(), fault }
}

/// The units of a chamber log: every header column `SERIAL.ROLE` (`UNIT_ROLES`) is unit
/// SERIAL's; the time column is `--columns time=NAME`, or else the one column without a
/// serial. Each unit needs its `temp` and at least one axis.
///
/// # Errors
/// No unit columns, no or several candidate time columns, a unit without `temp` or axes, a
/// serial rule broken, or a CSV error.
pub fn from_chamber_log(path: &Path, bytes: &[u8], base: &ReadFlags) -> Result<Vec<UnitInput>, BatchError> {
    let first = bytes.split(|b| *b == b'\n').next().unwrap_or_default();
    // The static reader's own rule: the delimiter the header line holds most of.
    let delim =
        [b'\t', b',', b';'].into_iter().max_by_key(|d| first.iter().filter(|c| *c == d).count()).unwrap_or(b',');
    let mut rd = csv::ReaderBuilder::new().delimiter(delim).flexible(true).from_reader(bytes);
    let header: Vec<String> =
        rd.headers().map_err(|e| chamber(path, ChamberFault::Csv(e)))?.iter().map(|h| h.trim().to_string()).collect();
    if header.iter().any(|h| h.ends_with(".pulses")) {
        return from_cycling_chamber(path, &header, rd, base);
    }
    let (mut order, mut others) = (Vec::new(), Vec::new());
    let cols = serial_columns(path, &header, &mut order, &mut others)?;
    let time_col = time_column(path, &header, &others, base)?;
    check_serials(order.iter().map(String::as_str))?;
    // Per unit: serial, the (role, column) pairs it has, and its one-unit log's text.
    struct Split {
        serial: String,
        picked: Vec<(&'static str, usize)>,
        text: String,
    }
    let mut units: Vec<Split> = Vec::new();
    for s in &order {
        let picked = unit_roles(path, s, &cols[s])?;
        let text = header_line(&picked);
        units.push(Split { serial: s.clone(), picked, text });
    }
    for rec in rd.records() {
        let rec = rec.map_err(|e| chamber(path, ChamberFault::Csv(e)))?;
        let field = |i: usize| rec.get(i).unwrap_or("").trim();
        let t = field(time_col);
        for u in &mut units {
            u.text.push_str(t);
            for (_, i) in &u.picked {
                u.text.push('\t');
                u.text.push_str(field(*i));
            }
            u.text.push('\n');
        }
    }
    // Each unit's one-unit log names its columns by their roles.
    let columns =
        ColumnMap { roles: ["time", "temp", "ax", "ay", "az"].map(|r| (r.to_string(), r.to_string())).to_vec() };
    Ok(units
        .into_iter()
        .map(|Split { serial, picked, text }| unit_input(path, &header, &columns, base, serial, &picked, text))
        .collect())
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
fn from_cycling_chamber(
    path: &Path,
    header: &[String],
    mut rd: csv::Reader<&[u8]>,
    base: &ReadFlags,
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
    let mut units: Vec<(String, Vec<usize>, csv::Writer<Vec<u8>>)> = Vec::with_capacity(order.len());
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
        units.push((s, picked.into_iter().flatten().collect(), w));
    }
    for rec in rd.records() {
        let rec = rec.map_err(|e| chamber(path, ChamberFault::Csv(e)))?;
        for (_, picked, w) in &mut units {
            w.write_record(picked.iter().map(|&i| rec.get(i).unwrap_or("").trim()))
                .map_err(|e| chamber(path, ChamberFault::Csv(e)))?;
        }
    }
    units
        .into_iter()
        .map(|(serial, picked, w)| {
            let text = w.into_inner().map_err(|e| chamber(path, ChamberFault::Csv(e.into_error().into())))?;
            let source = format!(
                "{}, columns {}",
                path.display(),
                picked.iter().map(|&i| format!("`{}`", header[i])).collect::<Vec<_>>().join(", ")
            );
            Ok(UnitInput { serial, source, rows: UnitRows::Bytes(text), flags: base.clone() })
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

/// A unit's input: its one-unit log `text` (columns `picked` of the chamber log), read
/// with the chamber log's flags and the unit's roles.
fn unit_input(
    path: &Path,
    header: &[String],
    columns: &ColumnMap,
    base: &ReadFlags,
    serial: String,
    picked: &[(&'static str, usize)],
    text: String,
) -> UnitInput {
    let mut roles = columns.clone();
    roles.roles.retain(|(r, _)| r == "time" || picked.iter().any(|(p, _)| p == r));
    let source = format!(
        "{}, columns {}",
        path.display(),
        picked.iter().map(|(_, i)| format!("`{}`", header[*i])).collect::<Vec<_>>().join(", ")
    );
    UnitInput {
        serial,
        source,
        rows: UnitRows::Bytes(text.into_bytes()),
        flags: ReadFlags { columns: Some(roles), ..base.clone() },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

    /// A manifest's keys override the command line's, a unit's override the manifest's, and
    /// a misspelt key is refused rather than ignored.
    #[test]
    fn manifest_keys_override_and_typos_are_refused() {
        let dir = std::env::temp_dir().join(format!("qfa-manifest-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.tsv"), "t\n").unwrap();
        let m = dir.join("batch.toml");
        std::fs::write(&m, "time_unit = \"ms\"\n[[unit]]\nserial = \"A\"\nlog = \"a.tsv\"\naccel_unit = \"mg\"\n")
            .unwrap();
        let base = ReadFlags { time_unit: Some(TimeUnit::S), ..ReadFlags::default() };
        let u = from_manifest(&m, &base).unwrap();
        assert_eq!(u[0].flags.time_unit, Some(TimeUnit::Ms));
        assert_eq!(u[0].flags.accel_unit, Some(AccelUnit::Mg));
        std::fs::write(&m, "[[unit]]\nserial = \"A\"\nlog = \"a.tsv\"\naccel_units = \"mg\"\n").unwrap();
        assert!(from_manifest(&m, &base).unwrap_err().to_string().contains("accel_units"));
        std::fs::write(&m, "[[units]]\nserial = \"A\"\nlog = \"a.tsv\"\n").unwrap();
        assert!(from_manifest(&m, &base).is_err());
        // A chamber log given as the manifest says what it is and where it goes.
        std::fs::write(&m, "program,run,time_s,input_g,interval_s,A.temp_c,A.pulses\np,0,10,1,10,,3\n").unwrap();
        let e = from_manifest(&m, &base).unwrap_err().to_string();
        assert!(e.contains("not a manifest") && e.contains("--log"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
