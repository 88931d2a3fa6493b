//! A batch's units, from either input a production line has: one chamber log holding every
//! unit (`time`, then `SERIAL.temp`, `SERIAL.ax`, `SERIAL.ay`, `SERIAL.az` per unit), or a
//! manifest (`batch.toml`) naming one log per serial.
//!
//! Either way each unit ends as a one-unit log (its bytes, or a file read when its turn
//! comes) and the reader flags to read it with, so every unit goes through the one reader
//! with all its checks (units, time order, gaps, skipped rows). The chamber log's split is
//! `input/chamber.rs`'s.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::{BatchError, ManifestFault, SerialFault};
use qfa_log::open::ReadFlags;
use qfa_log::static_log::columns::{AccelUnit, ColumnMap, TimeUnit};
use qfa_log::static_log::StaticError;
use qfa_log::units::{ReaderOption, TempUnit};

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
    /// Rows of a chamber log that hold no count of this unit (its `pulses` cell empty: the
    /// unit was not on the head, or its counter was not logged), left out of its log; said
    /// with its log's warnings. 0 for a manifest's log, which is the unit's own.
    pub left_out: usize,
    /// How a message about this unit names its reader options: a manifest's unit by the
    /// manifest's keys (`accel_unit = "mg"`, where its reader is set); `None`, by the front
    /// end's ([`crate::unit::UnitOptions::spelling`]).
    pub spelling: Option<qfa_log::spelling::Spelling>,
}

/// Where a unit's one-unit log is.
#[derive(Clone, Debug)]
pub enum UnitRows {
    /// In memory (a chamber log split in memory).
    Bytes(Vec<u8>),
    /// A file, read when the unit's turn comes (a manifest's logs, or a streamed chamber
    /// log's units' rows: never all held at once).
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
        // The manifest's own keys replace the command line's for every unit: a flag that
        // says otherwise would change nothing, so it is refused (a unit's key is its own
        // exception, and may differ).
        if serial.is_none() {
            let differs = |option: ReaderOption, flag: Option<String>, key: Option<String>| match (flag, key) {
                (Some(flag), Some(key)) if flag != key => Err(BatchError::Manifest {
                    path: path.to_path_buf(),
                    fault: ManifestFault::OverridesFlag { option, flag, key },
                }),
                _ => Ok(()),
            };
            let parsed = |t: &Option<String>, name: fn(&str) -> Option<&'static str>| {
                t.as_deref().map(|v| name(v).map_or_else(|| v.to_string(), str::to_string))
            };
            differs(
                ReaderOption::TimeUnit,
                base.time_unit.map(|u| u.name().to_string()),
                parsed(&self.time_unit, |v| v.parse::<TimeUnit>().ok().map(TimeUnit::name)),
            )?;
            differs(
                ReaderOption::AccelUnit,
                base.accel_unit.map(|u| u.name().to_string()),
                parsed(&self.accel_unit, |v| v.parse::<AccelUnit>().ok().map(AccelUnit::name)),
            )?;
            differs(
                ReaderOption::TempUnit,
                base.temp_unit.map(|u| u.name().to_string()),
                parsed(&self.temp_unit, |v| v.parse::<TempUnit>().ok().map(TempUnit::name)),
            )?;
            differs(
                ReaderOption::Columns,
                base.columns.as_ref().map(ToString::to_string),
                parsed(&self.columns, |_| None).map(|c| c.parse::<ColumnMap>().map_or(c, |m| m.to_string())),
            )?;
            if base.decimal_comma && self.decimal_comma == Some(false) {
                differs(ReaderOption::DecimalComma, Some("true".into()), Some("false".into()))?;
            }
        }
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
                left_out: 0,
                spelling: Some(qfa_log::spelling::Spelling::Manifest),
            })
        })
        .collect()
}

mod chamber;
pub use chamber::{from_chamber_file, from_chamber_log, ChamberUnits, SPILL_BYTES};

#[cfg(test)]
mod tests {
    use super::*;

    /// A manifest's keys stand for the command line's where it gives none, a unit's override
    /// both, a flag the manifest's own key contradicts is refused (it would change nothing),
    /// and a misspelt key is refused rather than ignored.
    #[test]
    fn manifest_keys_override_and_typos_are_refused() {
        let dir = std::env::temp_dir().join(format!("qfa-manifest-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.tsv"), "t\n").unwrap();
        let m = dir.join("batch.toml");
        std::fs::write(&m, "time_unit = \"ms\"\n[[unit]]\nserial = \"A\"\nlog = \"a.tsv\"\naccel_unit = \"mg\"\n")
            .unwrap();
        let base = ReadFlags { accel_unit: Some(AccelUnit::G), ..ReadFlags::default() };
        let u = from_manifest(&m, &base).unwrap();
        assert_eq!(u[0].flags.time_unit, Some(TimeUnit::Ms));
        assert_eq!(u[0].flags.accel_unit, Some(AccelUnit::Mg));
        // `--time-unit s` against the manifest's `time_unit = "ms"`: before, the flag was
        // dropped without a word. The same unit spelt alike is no contradiction.
        let e = from_manifest(&m, &ReadFlags { time_unit: Some(TimeUnit::S), ..ReadFlags::default() }).unwrap_err();
        let e = e.to_string();
        assert!(e.contains("--time-unit s on the command line, and `time_unit = \"ms\"` here"), "{e}");
        assert!(from_manifest(&m, &ReadFlags { time_unit: Some(TimeUnit::Ms), ..ReadFlags::default() }).is_ok());
        let base = ReadFlags::default();
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
