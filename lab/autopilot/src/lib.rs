//! Calibration of an autopilot's own log (PX4 ULog, ArduPilot DataFlash): each
//! accelerometer instance the log holds is checked ([`qfa_log::autopilot::check`]),
//! calibrated as a static log ([`qfa_calibrate::static_cal`]) into its own folder `instance{I}/`,
//! and exported to that stack's parameter file with the identity the log gives it, so
//! nothing is typed:
//!
//! * PX4: one `px4_tc.params` with a `TC_An_*` slot per calibrated instance (slots 0, 1, …
//!   in instance order), `TC_An_ID` = the instance's `sensor_accel.device_id`. A slot the
//!   log's parameters hold beyond those, whose `TC_Am_ID` names one of these devices, is
//!   written with `TC_Am_ID = 0`: PX4 takes the first slot whose ID matches, so a stale
//!   slot must not keep the device.
//! * ArduPilot: `ardupilot_tcal_1_enable.parm` and `ardupilot_tcal_2_values.parm` with
//!   `INS_TCAL{I+1}_*` for each calibrated `IMU` instance I (ArduPilot ties `INS_TCALn` to
//!   IMU instance n − 1).
//!
//! Only the log's own stack's files are written: a device ID means something only to the
//! stack that assigned it.

use std::fmt;
use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;

use qfa_calibrate::export::{
    export_texts, ExportNote, ExportOptions, ARDUPILOT_ENABLE_FILE, ARDUPILOT_VALUES_FILE, EXPORT_FILES, PX4_FILE,
};
use qfa_calibrate::output_error::OutputError;
use qfa_calibrate::static_cal::{self, Figure, StaticCalError, StaticCalOptions};
use qfa_calibrate::verdict::static_verdict;
use qfa_log::autopilot::{check, AutopilotLog, Stack, Temperature};
use qfa_report::verdict::{FileUse, LimitsChoice, Verdict};

/// One instance's outcome.
#[derive(Clone, Debug, Serialize)]
pub struct InstanceOutcome {
    /// `IMU.I` / `sensor_accel` multi_id.
    pub index: u8,
    /// Device ID from the log.
    pub device_id: Option<u32>,
    /// Samples in the log.
    pub samples: usize,
    /// Temperature resolution, °C (None: no temperature).
    pub temp_step_c: Option<f64>,
    /// Whether the temperature was rebuilt between coarse steps.
    pub temp_dequantized: bool,
    /// Why it was not calibrated.
    pub refused: Option<String>,
    /// What the user must know.
    pub warnings: Vec<String>,
    /// Its calibration folder (relative to `--out`).
    pub dir: Option<String>,
    /// The parameters it is exported as (`TC_A1_*`, `INS_TCAL2_*`).
    pub exported_as: Option<String>,
    /// Held-out bias RMS per axis, mg: (axis, ours, PX4/tofupilot cubic).
    pub heldout_rms_mg: Vec<(String, Option<f64>, Option<f64>)>,
}

/// What [`calibrate_autopilot`] did.
#[derive(Clone, Debug, Serialize)]
pub struct AutopilotCalibration {
    /// The verdict the reports open with (in `report.json` beside these fields, not
    /// inside them).
    #[serde(skip)]
    pub verdict: Verdict,
    /// `PX4 ULog` or `ArduPilot DataFlash log`.
    pub log: String,
    /// The parameters that decide what is refused, as logged.
    pub params: Vec<(String, f64)>,
    /// Parameters changed while logging.
    pub changed_params: Vec<(String, f64, f64)>,
    /// The reader's notes.
    pub reader_notes: Vec<String>,
    /// Per instance.
    pub instances: Vec<InstanceOutcome>,
    /// Export files written.
    pub written: Vec<String>,
    /// Why export files or parts of them were left out.
    pub export_notes: Vec<String>,
}

/// Why the calibration of an autopilot log failed as a whole.
#[derive(Debug)]
#[non_exhaustive]
pub enum AutopilotCalError {
    /// Every instance was refused: their reasons.
    NothingCalibrated(Vec<String>),
    /// A file could not be written.
    Output(OutputError),
    /// An instance's folder could not be written.
    Instance(StaticCalError),
}

impl From<OutputError> for AutopilotCalError {
    fn from(e: OutputError) -> Self {
        Self::Output(e)
    }
}

impl fmt::Display for AutopilotCalError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NothingCalibrated(r) => {
                write!(f, "no accelerometer instance could be calibrated:\n  {}", r.join("\n  "))
            }
            Self::Output(e) => write!(f, "{e}"),
            Self::Instance(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for AutopilotCalError {}

fn figure(f: &Figure) -> Option<f64> {
    match f {
        Figure::Score(s) => Some(s.rms_mg),
        _ => None,
    }
}

/// The log parameters [`check`] reads, as logged.
fn deciding_params(log: &AutopilotLog) -> Vec<(String, f64)> {
    log.params
        .iter()
        .filter(|(n, _)| {
            n.starts_with("TC_A") && (n.ends_with("_ID") || n.as_str() == "TC_A_ENABLE")
                || n.starts_with("INS_TCAL") && n.ends_with("_ENABLE")
                || n.starts_with("INS_ACC") && n.ends_with("_ID")
                || n.as_str() == "AHRS_ORIENTATION"
        })
        .map(|(n, v)| (n.clone(), *v))
        .collect()
}

/// Calibrate every instance of `log` into `out` (see the module docs).
///
/// # Errors
/// Every instance refused, or a write failed. An instance refused (by [`check`], by the
/// static reader or by static calibration) is recorded with its reason; the others are
/// calibrated.
pub fn calibrate_autopilot(
    log: &AutopilotLog,
    out: &Path,
    opts: &StaticCalOptions,
    plots: bool,
    progress: bool,
    limits: &LimitsChoice,
) -> Result<AutopilotCalibration, AutopilotCalError> {
    remove_old_exports(out)?;
    let mut outcomes = Vec::new();
    let mut verdicts = Vec::new();
    // (instance index, device ID, export axes, outcome index) of each calibrated instance.
    let mut calibrated = Vec::new();
    for (inst, c) in log.instances.iter().zip(check(log)) {
        let mut o = instance_outcome(&c);
        if o.refused.is_none() {
            match calibrate_instance(inst, &c, opts, progress) {
                Err(e) => o.refused = Some(e),
                Ok(cal) => {
                    let v = write_instance(out, &cal, plots, limits, &mut o)?;
                    verdicts.push((format!("instance {}", c.index), v));
                    calibrated.push((c.index, c.device_id, static_cal::export_axes(&cal), outcomes.len()));
                }
            }
        }
        outcomes.push(o);
    }
    if calibrated.is_empty() {
        return Err(AutopilotCalError::NothingCalibrated(outcomes.iter().filter_map(|o| o.refused.clone()).collect()));
    }
    // The folder holds this run's files only: a static or cycling run's table.bin left at
    // its top would read as this log's.
    qfa_calibrate::clear_outputs(out).map_err(AutopilotCalError::Output)?;
    let mut export_notes = Vec::new();
    let files = match log.stack {
        Stack::Px4 => px4_export(log, &calibrated, &mut outcomes, &mut export_notes),
        Stack::ArduPilot => ardupilot_export(&calibrated, &mut outcomes, &mut export_notes),
    };
    let mut written = Vec::new();
    for (name, text) in files {
        let path = out.join(name);
        std::fs::write(&path, text).map_err(OutputError::io(&path))?;
        written.push(name.to_string());
    }
    let verdict = merged_verdict(&verdicts, limits, &written, &outcomes, &export_notes);
    let cal = AutopilotCalibration {
        verdict,
        log: log.stack.to_string(),
        params: deciding_params(log),
        changed_params: log.changed_params.clone(),
        reader_notes: log.reader_notes.clone(),
        instances: outcomes,
        written,
        export_notes,
    };
    write_reports(out, &cal)?;
    Ok(cal)
}

/// Create `out` and remove the export files an older run left in it, so none is taken
/// for this run's.
fn remove_old_exports(out: &Path) -> Result<(), AutopilotCalError> {
    std::fs::create_dir_all(out).map_err(OutputError::io(out))?;
    for f in EXPORT_FILES {
        let path = out.join(f);
        qfa_log::io_fault::remove_if_present(&path).map_err(OutputError::io(&path))?;
    }
    Ok(())
}

/// What [`check`] found for one instance, as its outcome before calibration.
fn instance_outcome(c: &qfa_log::autopilot::InstanceCheck) -> InstanceOutcome {
    let (temp_step_c, coarse) = match c.temperature {
        Temperature::Resolution { step_c, coarse } => (Some(step_c), coarse),
        Temperature::Missing { .. } => (None, false),
    };
    InstanceOutcome {
        index: c.index,
        device_id: c.device_id,
        samples: c.samples,
        temp_step_c,
        temp_dequantized: coarse,
        refused: c.refused.clone(),
        warnings: c.warnings.clone(),
        dir: None,
        exported_as: None,
        heldout_rms_mg: Vec::new(),
    }
}

/// One instance read as a static log (its temperature rebuilt between coarse steps when
/// [`check`] found them) and calibrated; the error is the reason it is refused.
fn calibrate_instance(
    inst: &qfa_log::autopilot::AccelInstance,
    c: &qfa_log::autopilot::InstanceCheck,
    opts: &StaticCalOptions,
    progress: bool,
) -> Result<static_cal::StaticCalibration, String> {
    let coarse = matches!(c.temperature, Temperature::Resolution { coarse: true, .. });
    let name = c.name();
    inst.to_static(coarse)
        .map_err(|e| e.to_string())
        .and_then(|l| static_cal::calibrate_static(&l, opts, progress).map_err(|e| format!("{name}: {e}")))
}

/// Write a calibrated instance's folder `out/instance{I}/` (table, reports, page) and
/// record it and its held-out figures in `o`; its verdict.
fn write_instance(
    out: &Path,
    cal: &static_cal::StaticCalibration,
    plots: bool,
    limits: &LimitsChoice,
    o: &mut InstanceOutcome,
) -> Result<Verdict, AutopilotCalError> {
    let dir = format!("instance{}", o.index);
    let d = out.join(&dir);
    let files = static_cal::static_files(plots, &[]);
    let v = static_verdict(cal, limits, &files, &o.warnings);
    // The instance's folder holds this run's files only (an earlier run's plot, when this
    // one draws none, would read as this run's).
    std::fs::create_dir_all(&d)
        .map_err(|e| AutopilotCalError::Output(qfa_calibrate::output_error::OutputError::io(&d)(e)))?;
    qfa_calibrate::clear_outputs(&d).map_err(AutopilotCalError::Output)?;
    static_cal::write_static(&d, cal, &v).map_err(AutopilotCalError::Instance)?;
    static_cal::write_static_page(&d, cal, plots, &v).map_err(AutopilotCalError::Instance)?;
    o.heldout_rms_mg = cal.report.axes.iter().map(|a| (a.axis.clone(), figure(&a.ours), figure(&a.cubic))).collect();
    o.dir = Some(dir);
    Ok(v)
}

/// PX4's `px4_tc.params`: a `TC_An_*` slot per calibrated instance with a device ID, and
/// stale slots of the log that name one of those devices cleared; each exported outcome
/// gets its slot, `notes` the export's notes that concern PX4.
fn px4_export(
    log: &AutopilotLog,
    calibrated: &[(u8, Option<u32>, Vec<qfa_calibrate::export::ExportAxis>, usize)],
    outcomes: &mut [InstanceOutcome],
    notes_out: &mut Vec<String>,
) -> Vec<(&'static str, String)> {
    let mut text = String::new();
    let mut ids = Vec::new();
    for (slot, (index, id, axes, k)) in calibrated.iter().enumerate() {
        let slot = slot as u8;
        let Some(id) = id else { continue };
        let eo = ExportOptions { px4_device_id: Some(*id as i32), px4_slot: slot, ..ExportOptions::default() };
        let (texts, notes) = export_texts(axes, &eo);
        notes_out.extend(
            notes
                .into_iter()
                .filter(|n| !matches!(n, ExportNote::NoArdupilotFit(_) | ExportNote::ArdupilotRange { .. }))
                .map(|n| format!("instance {index}: {n}")),
        );
        let Some((_, t)) = texts.into_iter().find(|(n, _)| *n == PX4_FILE) else { continue };
        ids.push(*id);
        outcomes[*k].exported_as = Some(format!("TC_A{slot}_* (TC_A{slot}_ID = {id})"));
        if text.is_empty() {
            text = t;
        } else {
            let _ = writeln!(text, "# TC_A{slot}: accelerometer instance {index} of the log, device ID {id}");
            for l in t.lines().filter(|l| !l.starts_with('#') && !l.contains("\tTC_A_ENABLE\t")) {
                let _ = writeln!(text, "{l}");
            }
        }
    }
    if text.is_empty() {
        return Vec::new();
    }
    // Stale slots that name one of these devices would be matched first.
    for m in ids.len()..4 {
        let name = format!("TC_A{m}_ID");
        if let Some(&v) = log.params.get(&name) {
            if ids.contains(&(v as i64 as i32 as u32)) {
                let _ = writeln!(
                    text,
                    "# {name} named device {} in the log: cleared so it cannot shadow the slot above",
                    v as i64 as i32 as u32
                );
                let _ = writeln!(text, "1\t1\t{name}\t0\t6");
            }
        }
    }
    vec![(PX4_FILE, text)]
}

/// ArduPilot's two `.parm` files: `INS_TCAL{I+1}_*` for each calibrated IMU instance I;
/// each exported outcome gets its parameters, `notes` the export's notes that concern
/// ArduPilot.
fn ardupilot_export(
    calibrated: &[(u8, Option<u32>, Vec<qfa_calibrate::export::ExportAxis>, usize)],
    outcomes: &mut [InstanceOutcome],
    notes_out: &mut Vec<String>,
) -> Vec<(&'static str, String)> {
    let (mut enable, mut values) = (String::new(), String::new());
    let mut imus = Vec::new();
    for (index, id, axes, k) in calibrated {
        let eo = ExportOptions { ardupilot_instance: *index, ..ExportOptions::default() };
        let (texts, notes) = export_texts(axes, &eo);
        notes_out.extend(
            notes.into_iter().filter(|n| *n != ExportNote::NoPx4DeviceId).map(|n| format!("instance {index}: {n}")),
        );
        let get = |f: &str| texts.iter().find(|(n, _)| *n == f).map(|(_, t)| t.clone());
        let (Some(e), Some(v)) = (get(ARDUPILOT_ENABLE_FILE), get(ARDUPILOT_VALUES_FILE)) else { continue };
        let n = u16::from(*index) + 1;
        imus.push(n);
        outcomes[*k].exported_as = Some(format!(
            "INS_TCAL{n}_* (IMU instance {index}{})",
            id.map_or(String::new(), |id| format!(", device ID {id}"))
        ));
        for (all, t) in [(&mut enable, e), (&mut values, v)] {
            if all.is_empty() {
                all.push_str(&t);
            } else {
                let _ = writeln!(all, "# INS_TCAL{n}: IMU instance {index} of the log");
                for l in t.lines().filter(|l| !l.starts_with('#')) {
                    let _ = writeln!(all, "{l}");
                }
            }
        }
    }
    if enable.is_empty() {
        return Vec::new();
    }
    vec![(ARDUPILOT_ENABLE_FILE, enable), (ARDUPILOT_VALUES_FILE, values)]
}

/// The log's verdict: the calibrated instances' verdicts merged, over the files written
/// and each instance's folder, with the export notes and the refusals as warnings.
fn merged_verdict(
    verdicts: &[(String, Verdict)],
    limits: &LimitsChoice,
    written: &[String],
    outcomes: &[InstanceOutcome],
    export_notes: &[String],
) -> Verdict {
    let mut all_files: Vec<FileUse> = written.iter().map(|f| FileUse::of(f)).collect();
    all_files.extend(["report.json", "report.md", "report.html"].map(FileUse::of));
    all_files.extend(outcomes.iter().filter_map(|o| o.dir.as_ref()).map(|d| FileUse {
        file: format!("{d}/"),
        action: "that instance's table (table.bin: flash this), reports and plot".to_string(),
    }));
    let mut verdict = Verdict::merge(verdicts, &limits.source(), all_files);
    verdict.warnings.extend(export_notes.iter().cloned());
    for o in outcomes.iter().filter(|o| o.refused.is_some()) {
        verdict.warnings.push(format!("instance {} refused: {}", o.index, o.refused.as_deref().unwrap_or("")));
    }
    verdict
}

/// Write the log's `report.json`, `report.md` and `report.html` into `out`.
fn write_reports(out: &Path, cal: &AutopilotCalibration) -> Result<(), AutopilotCalError> {
    let (json_path, md_path) = (out.join("report.json"), out.join("report.md"));
    let json = qfa_report::verdict::json_with_verdict(&cal.verdict, cal).map_err(OutputError::json(&json_path))?;
    std::fs::write(&json_path, json).map_err(OutputError::io(&json_path))?;
    std::fs::write(&md_path, static_cal::with_verdict(&cal.verdict, &markdown(cal)))
        .map_err(OutputError::io(&md_path))?;
    page(cal).write(out).map_err(OutputError::io(out))?;
    Ok(())
}

/// The log's `report.html`: the verdict, then each instance with a link to its own page.
#[must_use]
pub(crate) fn page(c: &AutopilotCalibration) -> qfa_report::html_report::Page {
    use qfa_report::html_report::escape;
    let mut p = qfa_report::html_report::Page::new(&format!("Calibration of a {}", c.log));
    c.verdict.to_page(&mut p);
    p.section("Instances");
    for o in &c.instances {
        let id = o.device_id.map_or("no device ID".to_string(), |d| format!("device ID {d}"));
        let what = match (&o.refused, &o.dir) {
            (Some(r), _) => format!("refused: {r}"),
            (None, Some(d)) => format!(
                "calibrated; exported as {}; <a href=\"{}/{}\">its report</a>",
                escape(o.exported_as.as_deref().unwrap_or("nothing (see the warnings)")),
                escape(d),
                qfa_report::html_report::FILE
            ),
            (None, None) => "not calibrated".to_string(),
        };
        // `what` is escaped piece by piece above (it holds a link); the refusal text here.
        let what = if o.refused.is_some() { escape(&what) } else { what };
        p.raw(&format!("<p><b>instance {} ({}, {} samples):</b> {what}</p>\n", o.index, escape(&id), o.samples));
    }
    p.details("report.md", &markdown(c));
    p
}

/// The report in words: each instance, refused or calibrated, with its warnings and
/// held-out figures, and the files written.
#[must_use]
pub(crate) fn markdown(c: &AutopilotCalibration) -> String {
    let mut s = format!("# Calibration of a {}\n\n", c.log);
    for n in &c.reader_notes {
        let _ = writeln!(s, "* reader: {n}");
    }
    for (n, a, b) in &c.changed_params {
        let _ = writeln!(s, "* parameter {n} changed while logging: {a} → {b}");
    }
    for o in &c.instances {
        let id = o.device_id.map_or("no device ID".to_string(), |d| format!("device ID {d}"));
        let temp = match o.temp_step_c {
            None => "no temperature".to_string(),
            Some(st) if st < 0.001 => "temperature finer than 0.001 °C".to_string(),
            Some(st) => format!(
                "temperature in {st:.3} °C steps{}",
                if o.temp_dequantized { ", rebuilt between steps" } else { "" }
            ),
        };
        let _ = writeln!(s, "\n## Instance {} ({id}, {} samples, {temp})\n", o.index, o.samples);
        match &o.refused {
            Some(r) => {
                let _ = writeln!(s, "**Refused**: {r}");
            }
            None => {
                let _ = writeln!(
                    s,
                    "Calibrated in `{}/`; exported as {}.",
                    o.dir.as_deref().unwrap_or("?"),
                    o.exported_as.as_deref().unwrap_or("nothing (see the export notes)")
                );
                for (axis, ours, cubic) in &o.heldout_rms_mg {
                    let f = |v: &Option<f64>| v.map_or("not computed".to_string(), |x| format!("{x:.3} mg"));
                    let _ = writeln!(s, "* {axis}: held-out bias RMS ours {}, PX4-style cubic {}", f(ours), f(cubic));
                }
            }
        }
        for w in &o.warnings {
            let _ = writeln!(s, "* warning: {w}");
        }
    }
    let _ = writeln!(
        s,
        "\nFiles: {}",
        if c.written.is_empty() { "no parameter file".to_string() } else { c.written.join(", ") }
    );
    for n in &c.export_notes {
        let _ = writeln!(s, "* {n}");
    }
    s
}
