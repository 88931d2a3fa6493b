//! The exports: a fitted cubic (the peers' fit, `crate::peers`) written in the parameter
//! names PX4 and ArduPilot load (`px4_tc.params`, `ardupilot_tcal_*.parm`), with the checks
//! that decide whether each file can be loaded as written.

use std::fmt::Write as _;

use crate::fit::FitError;
use crate::peers::{ardupilot_reason, Poly, ARDUPILOT_SCALE};
use qfa_log::spelling::{CalibrateOption, Spelling};
use qfa_log::static_log::G0_MPS2;

/// The first ArduPilot file: only `INS_TCAL1_ENABLE` (see [`write_exports`]).
pub const ARDUPILOT_ENABLE_FILE: &str = "ardupilot_tcal_1_enable.parm";
/// The second ArduPilot file: the range and the coefficients.
pub const ARDUPILOT_VALUES_FILE: &str = "ardupilot_tcal_2_values.parm";
/// The PX4 file.
pub const PX4_FILE: &str = "px4_tc.params";
/// Every file [`write_exports`] manages in an output directory (older names included, so a
/// file from an earlier run never sits beside this run's as if it were current).
pub const EXPORT_FILES: [&str; 4] = [PX4_FILE, ARDUPILOT_ENABLE_FILE, ARDUPILOT_VALUES_FILE, "ardupilot_tcal.parm"];

/// The range ArduPilot accepts for `INS_TCALn_TMIN` / `TMAX`, °C (their `@Range: -70 80`
/// in `AP_InertialSensor_tempcal.cpp`).
pub(crate) const ARDUPILOT_T_RANGE_C: (f64, f64) = (-70.0, 80.0);

/// One IMU axis of an export.
#[derive(Clone, Debug)]
pub struct ExportAxis {
    /// Role: `ax`, `ay` or `az` (PX4 index 0–2, ArduPilot `X`/`Y`/`Z`).
    pub axis: String,
    /// Where it came from, for the files' comments (a log column, or the cycling log's
    /// accelerometer).
    pub source: String,
    /// The PX4 / tofupilot cubic.
    pub cubic: Poly,
    /// The ArduPilot cubic about 35 °C, or why its learner formed none (it learns on rises
    /// only: a cooling-only log has none).
    pub ardupilot: Result<Poly, FitError>,
}

/// How to write the exports.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ExportOptions {
    /// PX4 `TC_A0_ID`: the device ID of the accelerometer the file is for. Without it no
    /// PX4 file is written (PX4 would match it to no accelerometer).
    pub px4_device_id: Option<i32>,
    /// Temperature range of the shared fields (PX4 `TC_A0_TREF` = its middle, `TMIN`,
    /// `TMAX`; ArduPilot `INS_TCAL1_TMIN`/`TMAX`), °C. Needed when the export has fewer than
    /// three axes, so every axis's file carries the same shared values.
    pub range_c: Option<(f64, f64)>,
    /// PX4 thermal-compensation slot `n` of `TC_An_*` (0 for a one-accelerometer export).
    pub px4_slot: u8,
    /// ArduPilot IMU instance (0-based, the log's `IMU.I`): the file sets
    /// `INS_TCAL{instance + 1}_*`.
    pub ardupilot_instance: u8,
}

/// What [`write_exports`] wrote and why it left files out.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Exports {
    /// File names written.
    pub written: Vec<&'static str>,
    /// Why a file was not written, one each.
    pub notes: Vec<ExportNote>,
}

/// Why an export file was not written: a note, not an error (the calibration stands).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum ExportNote {
    /// Fewer than three axes and no range for the fields all three share.
    SharedFieldsNeedRange {
        /// The axes exported (`ax`, ...), in export order.
        axes: Vec<String>,
        /// The training temperatures every axis saw, °C.
        training_c: (f64, f64),
    },
    /// The range asked for is not inside an axis's training temperatures.
    RangeOutsideTraining {
        /// The range asked for, °C.
        range_c: (f64, f64),
        /// The axis's training temperatures, °C.
        training_c: (f64, f64),
        /// The axis.
        axis: String,
    },
    /// No PX4 device ID: PX4 would apply the file to no accelerometer.
    NoPx4DeviceId,
    /// The ArduPilot learner formed no fit (why, in its terms).
    NoArdupilotFit(String),
    /// TMIN/TMAX outside what ArduPilot accepts (`ARDUPILOT_T_RANGE_C`).
    ArdupilotRange {
        /// The range asked for, °C; `None`: the training temperatures were the range.
        range_c: Option<(f64, f64)>,
        /// The training temperatures, °C.
        training_c: (f64, f64),
        /// ArduPilot IMU number (1-based, as in `INS_TCAL1_*`).
        imu: u16,
    },
}

impl ExportNote {
    /// The note, with every option spelled for `sp` (`--export-range TMIN,TMAX` for the
    /// CLI, `export_range=(TMIN, TMAX)` for Python).
    #[must_use]
    pub fn message(&self, sp: Spelling) -> String {
        let range = CalibrateOption::ExportRange;
        // A range as given: the CLI's sentence keeps its `lo..hi °C` form.
        let given = |(lo, hi): (f64, f64)| match sp {
            Spelling::Cli | Spelling::Manifest => format!("{} {lo}..{hi} °C", range.name(sp)),
            Spelling::Python => range.with(sp, &format!("{lo},{hi}")),
        };
        match self {
            Self::SharedFieldsNeedRange { axes, training_c: (lo, hi) } => {
                let mut distinct = axes.clone();
                distinct.sort_unstable();
                distinct.dedup();
                format!(
                "PX4 and ArduPilot files not written: this export has {} of the 3 axes ({}), and TC_A0_TREF/TMIN/TMAX \
                 (PX4) and INS_TCAL1_TMIN/TMAX (ArduPilot) are shared by all three; pass {}, the same for every axis \
                 you export, inside each axis's training temperatures (here {lo:.2}..{hi:.2} °C)",
                distinct.len(),
                axes.join(", "),
                range.with(sp, "TMIN,TMAX")
            )
            }
            Self::RangeOutsideTraining { range_c, training_c: (lo, hi), axis } => format!(
                "PX4 and ArduPilot files not written: {} is not inside the training temperatures {lo:.2}..{hi:.2} °C \
                 of {axis} (a cubic is not to be extrapolated)",
                given(*range_c)
            ),
            Self::NoPx4DeviceId => format!(
                "px4_tc.params not written: PX4 applies TC_A0_* only to the accelerometer whose device ID equals \
                 TC_A0_ID (with 0 nothing matches and compensation is silently off); pass {}, the vehicle's \
                 CAL_ACC0_ID parameter (or device_id in `listener sensor_accel` on the PX4 console)",
                CalibrateOption::Px4DeviceId.with(sp, "ID")
            ),
            Self::NoArdupilotFit(why) => format!("ArduPilot files not written: its learner formed no fit: {why}"),
            Self::ArdupilotRange { range_c, training_c: (tmin, tmax), imu } => {
                let what = match range_c {
                    Some(r) => format!("{} is", given(*r)),
                    None => format!("the training temperatures span {tmin:.2}..{tmax:.2} °C,"),
                };
                let (rmin, rmax) = ARDUPILOT_T_RANGE_C;
                format!(
                    "ArduPilot files not written: {what} outside the {rmin}..{rmax} °C that INS_TCAL{imu}_TMIN/TMAX \
                     accept; pass {} inside both",
                    range.with(sp, "TMIN,TMAX")
                )
            }
        }
    }
}

impl std::fmt::Display for ExportNote {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message(Spelling::Cli))
    }
}

fn px4_index(axis: &str) -> usize {
    match axis {
        "ax" => 0,
        "ay" => 1,
        _ => 2,
    }
}

/// The axis's ArduPilot cubic; the PX4 cubic stands in where there is none, and is never
/// written: the ArduPilot files are then left out with the reason.
fn ardupilot_or_cubic(a: &ExportAxis) -> Poly {
    a.ardupilot.clone().unwrap_or_else(|_| a.cubic.clone())
}

fn ardupilot_axis(axis: &str) -> &'static str {
    ["X", "Y", "Z"][px4_index(axis)]
}

/// The export files' texts (name, text) and the notes for those left out; see
/// [`write_exports`].
#[must_use]
pub fn export_texts(axes: &[ExportAxis], opts: &ExportOptions) -> (Vec<(&'static str, String)>, Vec<ExportNote>) {
    let mut notes = Vec::new();
    let mut roles: Vec<&str> = axes.iter().map(|a| a.axis.as_str()).collect();
    roles.sort_unstable();
    roles.dedup();
    let complete = roles == ["ax", "ay", "az"];
    let Some(polys) = export_polys(axes, opts, complete, &mut notes) else { return (Vec::new(), notes) };
    let partial_note = partial_note(axes, opts, complete);
    let sources = axes.iter().map(|a| a.source.as_str()).collect::<Vec<_>>().join(", ");
    let mut files = Vec::new();
    match opts.px4_device_id {
        None => notes.push(ExportNote::NoPx4DeviceId),
        Some(id) => files.push((PX4_FILE, px4_text(axes, &polys, opts.px4_slot, id, &partial_note, &sources))),
    }
    match ardupilot_texts(axes, &polys, opts, &partial_note, &sources) {
        Ok((enable, values)) => {
            files.push((ARDUPILOT_ENABLE_FILE, enable));
            files.push((ARDUPILOT_VALUES_FILE, values));
        }
        Err(note) => notes.push(note),
    }
    (files, notes)
}

/// Each axis's (PX4 cubic, ArduPilot polynomial) to export; `None` (the reason in
/// `notes`) when the axes cannot share the stacks' common fields: no axis, axes that are
/// not the three (`complete`) with one training range and no `range_c`, or a `range_c`
/// outside an axis's training temperatures.
fn export_polys(
    axes: &[ExportAxis],
    opts: &ExportOptions,
    complete: bool,
    notes: &mut Vec<ExportNote>,
) -> Option<Vec<(Poly, Poly)>> {
    let first = axes.first()?;
    // The training temperatures every axis saw (the same rows for a static log).
    let lo = axes.iter().map(|a| a.cubic.tmin_c).fold(f64::NEG_INFINITY, f64::max);
    let hi = axes.iter().map(|a| a.cubic.tmax_c).fold(f64::INFINITY, f64::min);
    let same = axes.iter().all(|a| a.cubic.tmin_c == first.cubic.tmin_c && a.cubic.tmax_c == first.cubic.tmax_c);
    match opts.range_c {
        None if complete && same => Some(axes.iter().map(|a| (a.cubic.clone(), ardupilot_or_cubic(a))).collect()),
        None => {
            notes.push(ExportNote::SharedFieldsNeedRange {
                axes: axes.iter().map(|a| a.axis.clone()).collect(),
                training_c: (lo, hi),
            });
            None
        }
        Some((rlo, rhi)) => {
            // Exported about a range inside the training temperatures only: outside them
            // the cubic would be extrapolated.
            if let Some(a) = axes.iter().find(|a| rlo < a.cubic.tmin_c || rhi > a.cubic.tmax_c) {
                notes.push(ExportNote::RangeOutsideTraining {
                    range_c: (rlo, rhi),
                    training_c: (a.cubic.tmin_c, a.cubic.tmax_c),
                    axis: a.axis.clone(),
                });
                return None;
            }
            let mid = 0.5 * (rlo + rhi);
            Some(
                axes.iter()
                    .map(|a| {
                        let ap = Poly { tmin_c: rlo, tmax_c: rhi, ..ardupilot_or_cubic(a) };
                        (a.cubic.about(mid, rlo, rhi), ap)
                    })
                    .collect(),
            )
        }
    }
}

/// The note the files of an export about `range_c` carry when it is not of the three axes
/// (`complete`): only files exported with the same range may be loaded together.
fn partial_note(axes: &[ExportAxis], opts: &ExportOptions, complete: bool) -> Option<String> {
    let (rlo, rhi) = opts.range_c?;
    let names = || axes.iter().map(|a| a.axis.as_str()).collect::<Vec<_>>().join(", ");
    (!complete).then(|| {
        format!(
            "This file sets the fields the three axes share for {} only: load onto one vehicle only qfa-lab \
             files exported with the same --export-range {rlo},{rhi}.",
            names()
        )
    })
}

/// `px4_tc.params` for slot `slot`, device `id`.
///
/// PX4: `TemperatureCompensation::calc_thermal_offsets_3D` (PX4-Autopilot,
/// src/modules/temperature_compensation) computes offset = X0 + X1·dT + X2·dT² + X3·dT³
/// with dT = T clipped to TMIN..TMAX minus TREF, for the accelerometer whose device ID
/// equals TC_A0_ID; `calibration::Accelerometer::Correct` subtracts it in the sensor
/// frame, before the rotation. TC_A_ENABLE is read at startup (`reboot_required`).
fn px4_text(
    axes: &[ExportAxis],
    polys: &[(Poly, Poly)],
    slot: u8,
    id: i32,
    partial_note: &Option<String>,
    sources: &str,
) -> String {
    let cubic0 = &polys[0].0;
    let mut s = String::from("# Onboard parameters for Vehicle 1\n");
    let _ = writeln!(
        s,
        "# qfa-lab: PX4 thermal compensation of accelerometer slot {slot} (TC_A{slot}_*), the cubic of the bias in \
         temperature fitted on every row of the log.\n\
         # TC_A{slot}_ID = {id}: PX4 applies TC_A{slot}_* only to the accelerometer with this device ID (its CAL_ACCn_ID, CAL_ACC0_ID for the first, \
         parameter, or device_id in `listener sensor_accel`).\n\
         # TC_A{slot}_Xk_0/1/2 are the sensor's own x, y, z (PX4 subtracts the offset before the board rotation): \
         here from the log's {sources}; m/s2 per degC^k of T - TC_A{slot}_TREF, T clamped to TC_A{slot}_TMIN..TC_A{slot}_TMAX."
    );
    if let Some(n) = partial_note {
        let _ = writeln!(s, "# {n}");
    }
    let _ = write!(
        s,
        "# After loading (QGroundControl: Vehicle Setup > Parameters > Tools > Load from file):\n\
         #  1. Reboot: TC_A_ENABLE is read only at startup.\n\
         #  2. Run the ordinary accelerometer calibration: TC_A{slot}_X0_* are 0 here, so its offsets take up the \
         constant bias at the calibration temperature.\n\
         #  3. Reboot again before flying: PX4 reads the thermal compensation parameters at startup.\n\
         # Vehicle-Id\tComponent-Id\tName\tValue\tType\n",
    );
    let _ = writeln!(s, "1\t1\tTC_A_ENABLE\t1\t6");
    let _ = writeln!(s, "1\t1\tTC_A{slot}_ID\t{id}\t6");
    for (name, v) in [("TREF", cubic0.tref_c), ("TMIN", cubic0.tmin_c), ("TMAX", cubic0.tmax_c)] {
        let _ = writeln!(s, "1\t1\tTC_A{slot}_{name}\t{v:.6}\t9");
    }
    for (a, (p, _)) in axes.iter().zip(polys) {
        let i = px4_index(&a.axis);
        for k in 0..4 {
            // X0 = 0 as PX4's own calibration writes it ("zero at the reference
            // temperature"): the ordinary accelerometer calibration holds the offset.
            let v = if k == 0 { 0.0 } else { p.coef[k] * G0_MPS2 };
            let _ = writeln!(s, "1\t1\tTC_A{slot}_X{k}_{i}\t{v:.9e}\t9");
        }
    }
    s
}

/// The two ArduPilot files (enable, values) for IMU `opts.ardupilot_instance + 1`, or the
/// note saying why they are left out (an axis without an ArduPilot fit, or a range
/// ArduPilot refuses).
///
/// ArduPilot: `AP_InertialSensor::TCal::correct_sensor` (ArduPilot,
/// libraries/AP_InertialSensor/AP_InertialSensor_tempcal.cpp) clips T and the
/// accelerometer calibration temperature to TMIN..TMAX and corrects by
/// −p(T − 35) + p(CALTEMP − 35), p(d) = (ACC1·d + ACC2·d² + ACC3·d³)·10⁻⁶. ENABLE
/// carries AP_PARAM_FLAG_ENABLE (the group's other parameters are hidden until it is
/// set) and @RebootRequired; TMIN/TMAX have @Range -70 80.
fn ardupilot_texts(
    axes: &[ExportAxis],
    polys: &[(Poly, Poly)],
    opts: &ExportOptions,
    partial_note: &Option<String>,
    sources: &str,
) -> Result<(String, String), ExportNote> {
    let imu = u16::from(opts.ardupilot_instance) + 1;
    if let Some(why) = axes.iter().find_map(|a| a.ardupilot.as_ref().err()) {
        return Err(ExportNote::NoArdupilotFit(ardupilot_reason(why)));
    }
    let (tmin, tmax) = (polys[0].1.tmin_c, polys[0].1.tmax_c);
    let (rmin, rmax) = ARDUPILOT_T_RANGE_C;
    // As written (two decimals, as ArduPilot prints them), so the check is on the file's values.
    let (wmin, wmax) = ((tmin * 100.0).round() / 100.0, (tmax * 100.0).round() / 100.0);
    if wmin < rmin || wmax > rmax {
        return Err(ExportNote::ArdupilotRange { range_c: opts.range_c, training_c: (tmin, tmax), imu });
    }
    let n_values = 2 + 3 * axes.len();
    let enable = format!(
        "# qfa-lab: ArduPilot temperature calibration of IMU {imu} (INS_TCAL{imu}_*), file 1 of 2.\n\
         # INS_TCAL{imu}_ENABLE hides every other INS_TCAL{imu}_* parameter until it is set, and a ground station loads only\n\
         # the names the vehicle already lists, so the values come in a second file:\n\
         #  1. Load this file and write it (Mission Planner: Config > Full Parameter List > Load from file, then Write Params).\n\
         #  2. Reboot (INS_TCAL{imu}_ENABLE takes effect at boot), then refresh the parameter list: INS_TCAL{imu}_TMIN, _TMAX,\n\
         #     _ACC* and _GYR* appear.\n\
         #  3. Load {ARDUPILOT_VALUES_FILE} the same way and write it: all {n_values} values must be written.\n\
         #  4. Reboot, then run the accelerometer calibration: it records INS_ACC{imu}_CALTEMP, and ArduPilot corrects by\n\
         #     p(CALTEMP - 35) - p(T - 35), so the calibration's offsets hold the constant bias.\n\
         INS_TCAL{imu}_ENABLE,1\n"
    );
    let mut values = format!(
        "# qfa-lab: ArduPilot temperature calibration of IMU {imu} (INS_TCAL{imu}_*), file 2 of 2: load it after\n\
         # {ARDUPILOT_ENABLE_FILE}, a reboot and a parameter refresh (the steps are in that file).\n\
         # INS_TCAL{imu}_ACCk_X/Y/Z: coefficients of (T - 35 degC)^k in m/s2 x 10^6 for the log's {sources}.\n\
         # TMIN/TMAX clamp T (ArduPilot accepts -70..80 degC); they also clamp the gyro terms INS_TCAL{imu}_GYR*,\n\
         # which this file leaves as they are.\n"
    );
    if let Some(n) = partial_note {
        let _ = writeln!(values, "# {n}");
    }
    let _ = writeln!(values, "INS_TCAL{imu}_TMIN,{tmin:.2}");
    let _ = writeln!(values, "INS_TCAL{imu}_TMAX,{tmax:.2}");
    for k in 1..4 {
        for (a, (_, p)) in axes.iter().zip(polys) {
            let _ = writeln!(
                values,
                "INS_TCAL{imu}_ACC{k}_{},{:.6}",
                ardupilot_axis(&a.axis),
                p.coef[k] * G0_MPS2 * ARDUPILOT_SCALE
            );
        }
    }
    Ok((enable, values))
}

/// Write the PX4 and ArduPilot parameter files of `axes` into `dir`, each only when the
/// stack will load and apply every value in it:
///
/// * `px4_tc.params` (QGroundControl format: vehicle, component, name, value, type 9 =
///   float, 6 = int32): `TC_A_ENABLE`, `TC_A0_ID`, `TC_A0_TREF/TMIN/TMAX`, `TC_A0_X0..3_i`
///   in m/s² (X0 = 0: the ordinary calibration holds the offset), and comment lines with
///   the steps after loading. Only with [`ExportOptions::px4_device_id`].
/// * `ardupilot_tcal_1_enable.parm` (`INS_TCAL1_ENABLE,1` and the steps), then
///   `ardupilot_tcal_2_values.parm` (`INS_TCAL1_TMIN/TMAX`, `INS_TCAL1_ACC1..3_X/Y/Z` about
///   35 °C, ×10⁶): two files because ENABLE hides the others until it is set and a ground
///   station loads only names the vehicle lists. Only when TMIN/TMAX lie in −70…80 °C.
/// * The fields an accelerometer's three axes share are written only for a complete
///   export (all three axes from one fit) or about [`ExportOptions::range_c`] (then the
///   cubic re-expanded about its middle, `Poly::about`, the range inside every axis's
///   training temperatures). So a one-axis file never re-references the other axes.
///
/// Older export files in `dir` are removed first, so what is there is this run's.
///
/// # Errors
/// A file could not be removed or written.
pub fn write_exports(dir: &std::path::Path, axes: &[ExportAxis], opts: &ExportOptions) -> std::io::Result<Exports> {
    for f in EXPORT_FILES {
        qfa_log::io_fault::remove_if_present(&dir.join(f))?;
    }
    let (files, notes) = export_texts(axes, opts);
    let mut written = Vec::new();
    for (name, text) in files {
        std::fs::write(dir.join(name), text)?;
        written.push(name);
    }
    Ok(Exports { written, notes })
}
