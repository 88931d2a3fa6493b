//! ArduPilot DataFlash (`.bin`) reader: every `IMU` instance (`I`, `TimeUS`, `AccX/Y/Z`
//! m/s², `T` °C) and the `PARM` records, into an
//! [`AutopilotLog`]; the device IDs come from
//! `INS_ACC_ID`, `INS_ACC2_ID`, `INS_ACC3_ID`.
//!
//! Parsing is the `ardupilot-binlog` crate's (MIT/Apache-2.0; message layouts from the
//! log's own `FMT` records, so any ArduPilot version). It resynchronises on a corrupt
//! record by scanning for the next `A3 95` and stops after repeated failures, both without
//! saying so; the lab therefore counts the bytes of the records it was given against the
//! file's size and reports the difference ([`AutopilotLog::reader_notes`]).
//!
//! `PARM` values are logged as float32, so a device ID above 2²⁴ is not exact in the log:
//! that only affects the comment in the ArduPilot file (ArduPilot ties `INS_TCALn` to the
//! IMU instance, not to an ID).

use std::collections::BTreeMap;
use std::fmt;
use std::io::Cursor;

use ardupilot_binlog::Reader;

use super::autopilot::{ardupilot_id_param, AccelInstance, AutopilotLog, Stack};

/// A DataFlash record starts `A3 95`; the first is the `FMT` of `FMT` (type 128).
pub(crate) const MAGIC: [u8; 3] = [0xA3, 0x95, 0x80];

/// Why a DataFlash log was not read.
#[derive(Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum DataflashError {
    /// No `IMU` record with the fields the lab needs.
    NoImu {
        /// Message names the log has, for the message.
        messages: Vec<String>,
    },
    /// An `IMU` record without a field the lab needs.
    Field {
        /// The field.
        field: &'static str,
    },
}

impl fmt::Display for DataflashError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoImu { messages } => write!(
                f,
                "the DataFlash log has no IMU records (messages: {}); log IMU data (LOG_BITMASK: IMU) through the \
                 chamber run",
                if messages.is_empty() { "none".to_string() } else { messages.join(", ") }
            ),
            Self::Field { field } => write!(f, "the DataFlash log's IMU records have no `{field}` field"),
        }
    }
}

impl std::error::Error for DataflashError {}

/// Read a DataFlash log from its bytes.
///
/// # Errors
/// [`DataflashError`].
pub(crate) fn read_dataflash(bytes: &[u8]) -> Result<AutopilotLog, DataflashError> {
    let mut reader = Reader::new(Cursor::new(bytes));
    let mut by_i: BTreeMap<u8, AccelInstance> = BTreeMap::new();
    let mut params: BTreeMap<String, f64> = BTreeMap::new();
    let mut changed: BTreeMap<String, (f64, f64)> = BTreeMap::new();
    let mut messages: Vec<String> = Vec::new();
    let mut record_bytes: BTreeMap<u8, usize> = BTreeMap::new();
    let mut decode_errors = 0usize;
    for entry in &mut reader {
        let Ok(e) = entry else {
            decode_errors += 1;
            continue;
        };
        *record_bytes.entry(e.msg_type).or_default() += 1;
        match e.name.as_str() {
            "IMU" => {
                let get = |f: &'static str| e.get_f64(f).ok_or(DataflashError::Field { field: f });
                let i = get("I")? as u8;
                let t = get("TimeUS")?;
                let temp = e.get_f64("T").unwrap_or(f64::NAN);
                let acc = [get("AccX")?, get("AccY")?, get("AccZ")?];
                let inst = by_i.entry(i).or_insert_with(|| AccelInstance { index: i, ..AccelInstance::default() });
                inst.time_s.push(t * 1e-6);
                inst.temp_c.push(temp);
                for (a, v) in inst.accel_mps2.iter_mut().zip(acc) {
                    a.push(v);
                }
            }
            "PARM" => {
                if let (Some(n), Some(v)) = (e.get_str("Name"), e.get_f64("Value")) {
                    match params.get(n) {
                        None => {
                            params.insert(n.to_string(), v);
                        }
                        Some(&first) if first != v => changed.entry(n.to_string()).or_insert((first, v)).1 = v,
                        Some(_) => {}
                    }
                }
            }
            name => {
                if !messages.iter().any(|m| m == name) {
                    messages.push(name.to_string());
                }
            }
        }
    }
    // Bytes the reader handed over as records, against the file.
    let formats = reader.formats();
    let read: usize = record_bytes.iter().map(|(t, n)| n * formats.get(t).map_or(0, |f| usize::from(f.msg_len))).sum();
    if by_i.is_empty() {
        return Err(DataflashError::NoImu { messages });
    }
    for inst in by_i.values_mut() {
        inst.device_id = params.get(&ardupilot_id_param(inst.index)).map(|&v| v as u32).filter(|&v| v != 0);
    }
    let mut reader_notes = Vec::new();
    if read != bytes.len() || decode_errors > 0 {
        reader_notes.push(format!(
            "{} of the log's {} bytes were not read as records (corrupt or truncated records, skipped by the reader){}",
            bytes.len().saturating_sub(read),
            bytes.len(),
            if decode_errors > 0 { format!("; {decode_errors} record(s) failed to decode") } else { String::new() }
        ));
    }
    Ok(AutopilotLog {
        stack: Stack::ArduPilot,
        params,
        changed_params: changed.into_iter().map(|(n, (a, b))| (n, a, b)).collect(),
        instances: by_i.into_values().collect(),
        reader_notes,
    })
}
