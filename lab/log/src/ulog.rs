//! PX4 ULog reader: every `sensor_accel` instance (multi_id, `device_id`, `timestamp` µs,
//! `x`/`y`/`z` m/s², `temperature` °C) and the parameters, into an
//! [`AutopilotLog`].
//!
//! Parsing is the `px4-ulog` crate's (PX4's own Rust reader, MIT; its streaming parser
//! reports multi-instance subscriptions, parameters with the section they appear in, and
//! dropouts). Chosen over `yule_log` (also complete, but pulls in `regex`, `env_logger` and
//! `lazy_static` for what this needs) and `ulog-rs` (0.0.x, a `clap`/`dirs` dependency in a
//! library). The log is parsed from memory in one pass; ULog's appended-data sections (a
//! crash dump after the main log) are not read, and a log that has them says so.

use std::collections::BTreeMap;
use std::fmt;

use px4_ulog::stream_parser::file_reader::LogParser;
use px4_ulog::stream_parser::model::{DataMessage, DropoutMessage, LogStage, ParameterMessage};

use super::autopilot::{AccelInstance, AutopilotLog, Stack};

/// The ULog file magic (`ULog` 01 12 35).
pub(crate) const MAGIC: [u8; 7] = *b"ULog\x01\x12\x35";

/// Why a ULog was not read.
#[derive(Debug)]
#[non_exhaustive]
pub enum UlogError {
    /// The parser refused the file: its own error.
    Parse(px4_ulog::stream_parser::model::UlogParseError),
    /// No `sensor_accel` sample.
    NoAccel {
        /// Topics the log has, for the message.
        topics: Vec<String>,
    },
    /// A `sensor_accel` format without a field the lab needs.
    Field {
        /// The field.
        field: &'static str,
    },
}

impl fmt::Display for UlogError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Parse(e) => write!(f, "not a readable ULog: {e}"),
            Self::NoAccel { topics } => write!(
                f,
                "the ULog has no sensor_accel samples (topics: {}); record the chamber run with SDLOG_PROFILE bit 2 \
                 (thermal calibration), which logs every sensor_accel instance",
                if topics.is_empty() { "none".to_string() } else { topics.join(", ") }
            ),
            Self::Field { field } => write!(f, "the ULog's sensor_accel has no `{field}` field the lab can read"),
        }
    }
}

impl std::error::Error for UlogError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Parse(e) => Some(e),
            _ => None,
        }
    }
}

/// Read a ULog from its bytes.
///
/// # Errors
/// [`UlogError`].
pub(crate) fn read_ulog(bytes: &[u8]) -> Result<AutopilotLog, UlogError> {
    let mut by_multi: BTreeMap<u8, AccelInstance> = BTreeMap::new();
    let mut field_error: Option<&'static str> = None;
    let mut topics: Vec<String> = Vec::new();
    let mut on_data = |m: &DataMessage| record_accel_sample(m, &mut by_multi, &mut field_error, &mut topics);
    let mut params: BTreeMap<String, f64> = BTreeMap::new();
    let mut changed: BTreeMap<String, (f64, f64)> = BTreeMap::new();
    let mut on_param = |p: &ParameterMessage| record_param(p, &mut params, &mut changed);
    let mut dropouts = (0usize, 0u64);
    let mut on_dropout = |d: &DropoutMessage| {
        dropouts.0 += 1;
        dropouts.1 += u64::from(d.duration_ms);
    };
    let mut parser = LogParser::default();
    parser.set_data_message_callback(&mut on_data);
    parser.set_parameter_message_callback(&mut on_param);
    parser.set_dropout_message_callback(&mut on_dropout);
    parser.consume_bytes(bytes).map_err(UlogError::Parse)?;
    let leftover = parser.has_leftover();
    let appended = parser.appended_offsets().iter().any(|&o| o != 0);
    drop(parser);
    if let Some(field) = field_error {
        return Err(UlogError::Field { field });
    }
    if by_multi.is_empty() {
        return Err(UlogError::NoAccel { topics });
    }
    Ok(AutopilotLog {
        stack: Stack::Px4,
        params,
        changed_params: changed.into_iter().map(|(n, (a, b))| (n, a, b)).collect(),
        instances: by_multi.into_values().collect(),
        reader_notes: reader_notes(dropouts, leftover, appended),
    })
}

/// Add a `sensor_accel` message's sample to its instance in `by_multi`, or note another
/// topic's name in `topics`; a format without a needed field goes into `field_error`.
fn record_accel_sample(
    m: &DataMessage,
    by_multi: &mut BTreeMap<u8, AccelInstance>,
    field_error: &mut Option<&'static str>,
    topics: &mut Vec<String>,
) {
    let fmt = m.flattened_format;
    let name = fmt.message_name();
    if name != "sensor_accel" {
        if !topics.iter().any(|t| t == name) {
            topics.push(name.to_string());
        }
        return;
    }
    macro_rules! field {
        ($t:ty, $n:literal) => {
            match fmt.get_field_parser::<$t>($n) {
                Ok(p) => p.parse(m.data),
                Err(_) => {
                    field_error.get_or_insert($n);
                    return;
                }
            }
        };
    }
    let ts = field!(u64, "timestamp");
    let id = field!(u32, "device_id");
    let (x, y, z) = (field!(f32, "x"), field!(f32, "y"), field!(f32, "z"));
    // A driver without a temperature sensor leaves the field NaN; a format without it, too.
    let temp = fmt.get_field_parser::<f32>("temperature").map_or(f32::NAN, |p| p.parse(m.data));
    let multi = m.multi_id.value();
    let inst = by_multi.entry(multi).or_insert_with(|| AccelInstance {
        index: multi,
        device_id: Some(id),
        ..AccelInstance::default()
    });
    inst.time_s.push(ts as f64 * 1e-6);
    inst.temp_c.push(f64::from(temp));
    for (a, v) in inst.accel_mps2.iter_mut().zip([x, y, z]) {
        a.push(f64::from(v));
    }
}

/// A parameter's value: from the definitions into `params`, a change during the log into
/// `changed` (its first and last value).
fn record_param(p: &ParameterMessage, params: &mut BTreeMap<String, f64>, changed: &mut BTreeMap<String, (f64, f64)>) {
    let (name, v, stage) = match p {
        ParameterMessage::Float(n, v, s) => (*n, f64::from(*v), s),
        ParameterMessage::Int32(n, v, s) => (*n, f64::from(*v), s),
    };
    match stage {
        LogStage::Definitions => {
            params.insert(name.to_string(), v);
        }
        LogStage::Data => {
            let first = params.get(name).copied().unwrap_or(f64::NAN);
            changed.entry(name.to_string()).or_insert((first, v)).1 = v;
        }
    }
}

/// What the reader could not read: dropouts (count, ms), a truncated last message,
/// appended data sections.
fn reader_notes(dropouts: (usize, u64), leftover: bool, appended: bool) -> Vec<String> {
    let mut reader_notes = Vec::new();
    if dropouts.0 > 0 {
        reader_notes.push(format!(
            "the logger dropped data {} time(s), {} ms in all (ULog dropout messages)",
            dropouts.0, dropouts.1
        ));
    }
    if leftover {
        reader_notes.push("the ULog ends inside a message (a truncated file): that message is not read".to_string());
    }
    if appended {
        reader_notes.push("the ULog has appended data sections, which are not read".to_string());
    }
    reader_notes
}
