//! An autopilot's own chamber log (PX4 ULog, ArduPilot DataFlash `.bin`), read by
//! `super::ulog` and `super::dataflash` into one shape: every accelerometer instance with
//! its device ID, samples and temperature, and the parameters in force when logging began.
//!
//! What this module decides, per instance, before anything is fitted ([`check`]):
//! * **compensation already on.** ArduPilot applies `INS_TCALn` inside the IMU backend
//!   (`AP_InertialSensor_Backend::_rotate_and_correct_accel`), before the sample reaches the
//!   `IMU` log message, so an instance logged with `INS_TCAL{I+1}_ENABLE = 1` holds
//!   compensated samples: fitting them would fit the residual and the file would compensate
//!   twice. It is **refused**, naming the parameter. PX4 applies `TC_A*` in the sensors
//!   module, downstream of the `sensor_accel` topic the lab reads (PX4's thermal-calibration
//!   guide even sets `TC_A_ENABLE = 1` before logging), so a PX4 instance logged with
//!   `TC_A_ENABLE = 1` and a `TC_An_ID` equal to its device ID is **calibrated, with that
//!   stated**: its samples are uncompensated, and the new file replaces slot n.
//! * **no temperature** (PX4 `temperature` NaN, ArduPilot `T` identically 0, or fewer than
//!   `MIN_TEMP_SAMPLES` finite readings): **refused**, named.
//! * **coarse temperature** ([`resolution`]: the smallest step between readings, when the
//!   readings sit on that lattice and it is at least `COARSE_STEP_C`): **named**, and the
//!   temperature is rebuilt between its steps (`dequantize`) before the firmware's rate
//!   estimator sees it. A 1 °C staircase read as it is gives the 32-reading rate window a
//!   rate of zero between steps and a spike at each one.
//! * ArduPilot with `AHRS_ORIENTATION ≠ 0`: the `IMU` message is rotated to the vehicle
//!   frame after `INS_TCALn` is applied in the board frame, so its axes are not the ones the
//!   file would set: **refused**, named.
//!
//! An instance is turned into a static log ([`AccelInstance::to_static`]) by averaging its
//! samples over `BIN_S`-s bins (autopilots log accelerometers at tens to hundreds of hertz;
//! the fit's blocks are 10 rows) and handing the rows to the static reader, so its checks
//! (glitches, units, slew) apply unchanged.

use std::collections::BTreeMap;
use std::fmt;
use std::fmt::Write as _;

use crate::static_log::columns::{AccelUnit, TimeUnit};
use crate::static_log::{read_static_from, StaticError, StaticLog, StaticOptions};

/// Length of the bins samples are averaged over, s.
pub(crate) const BIN_S: f64 = 1.0;

/// Smallest temperature step that counts as coarse, °C: 4 DS18B20 steps (1/16 °C); a
/// sensor at 0.25 °C or coarser leaves the rate estimator's 32-s window without a reading
/// change for 30 s at 0.5 °C/min.
pub(crate) const COARSE_STEP_C: f64 = 0.25;

/// Fewest samples, and finite nonzero temperature readings, an instance needs (the
/// static reader's `MIN_ROWS`).
pub(crate) const MIN_TEMP_SAMPLES: usize = 16;

/// Which autopilot wrote the log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stack {
    /// PX4 ULog.
    Px4,
    /// ArduPilot DataFlash.
    ArduPilot,
}

impl fmt::Display for Stack {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Px4 => "PX4 ULog",
            Self::ArduPilot => "ArduPilot DataFlash log",
        })
    }
}

/// One accelerometer instance: PX4 `sensor_accel` multi-instance, ArduPilot `IMU.I`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AccelInstance {
    /// PX4 multi_id / ArduPilot `IMU.I` (0-based).
    pub index: u8,
    /// Device ID: PX4 `sensor_accel.device_id`; ArduPilot `INS_ACC{,2,3}_ID` from the
    /// parameters (None when absent).
    pub device_id: Option<u32>,
    /// Sample time, s, on the log's clock.
    pub time_s: Vec<f64>,
    /// Temperature, °C (NaN where the log has none).
    pub temp_c: Vec<f64>,
    /// Specific force x, y, z, m/s², as logged.
    pub accel_mps2: [Vec<f64>; 3],
}

/// An autopilot log as the lab uses it.
#[derive(Clone, Debug, PartialEq)]
pub struct AutopilotLog {
    /// Which stack.
    pub stack: Stack,
    /// Parameters in force when logging began (PX4 definitions section; ArduPilot the
    /// first `PARM` of each name).
    pub params: BTreeMap<String, f64>,
    /// Parameters changed while logging: (name, first value, last value).
    pub changed_params: Vec<(String, f64, f64)>,
    /// Accelerometer instances, by index.
    pub instances: Vec<AccelInstance>,
    /// What the reader found but did not use, one sentence each (dropouts, unread bytes).
    pub reader_notes: Vec<String>,
}

/// The temperature channel of an instance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Temperature {
    /// No usable reading.
    Missing {
        /// Finite readings found.
        finite: usize,
    },
    /// Readings at this resolution, °C.
    Resolution {
        /// Smallest step between readings, °C.
        step_c: f64,
        /// At least `COARSE_STEP_C` and the readings on its lattice.
        coarse: bool,
    },
}

/// What [`check`] decided for one instance.
#[derive(Clone, Debug, PartialEq)]
pub struct InstanceCheck {
    /// Instance index.
    pub index: u8,
    /// Device ID.
    pub device_id: Option<u32>,
    /// Samples.
    pub samples: usize,
    /// The temperature channel.
    pub temperature: Temperature,
    /// Why it is not calibrated (None: it is).
    pub refused: Option<String>,
    /// What the user must know, one sentence each.
    pub warnings: Vec<String>,
}

impl InstanceCheck {
    /// `instance 1 (device ID 3014666)`.
    #[must_use]
    pub fn name(&self) -> String {
        match self.device_id {
            Some(id) => format!("accelerometer instance {} (device ID {id})", self.index),
            None => format!("accelerometer instance {} (no device ID in the log)", self.index),
        }
    }
}

/// The temperature resolution of `temp_c` (finite readings in log order): the smallest
/// nonzero step between consecutive readings (steps under 1e-6 °C are float noise), and
/// whether the readings sit on that lattice (95 % of them within 1 % of a step of
/// `first + k·step`) with a step of at least `COARSE_STEP_C`.
#[must_use]
pub fn resolution(temp_c: &[f64]) -> Temperature {
    let finite: Vec<f64> = temp_c.iter().copied().filter(|t| t.is_finite()).collect();
    let nonzero = finite.iter().filter(|&&t| t != 0.0).count();
    if nonzero == 0 || (temp_c.len() >= MIN_TEMP_SAMPLES && nonzero < MIN_TEMP_SAMPLES) {
        return Temperature::Missing { finite: nonzero };
    }
    let step = finite.windows(2).map(|w| (w[1] - w[0]).abs()).filter(|&d| d > 1e-6).fold(f64::INFINITY, f64::min);
    if !step.is_finite() {
        // One constant reading: no step at all.
        return Temperature::Resolution { step_c: 0.0, coarse: false };
    }
    let on_lattice = finite
        .iter()
        .filter(|&&t| {
            let k = (t - finite[0]) / step;
            (k - k.round()).abs() < 0.01
        })
        .count();
    let coarse = step >= COARSE_STEP_C && on_lattice as f64 >= 0.95 * finite.len() as f64;
    Temperature::Resolution { step_c: step, coarse }
}

/// The temperature between the steps of a quantised reading: each change of the reading
/// (from a to b at sample i) marks the time the true value crossed (a + b)/2, taken at the
/// middle of the last sample before and the first after; the temperature is linear between
/// those crossings and held before the first and after the last. On a ramp this recovers
/// the slope that a staircase hides; on a hold dithering between two steps it gives the
/// value between them. Non-finite readings stay non-finite.
#[must_use]
pub(crate) fn dequantize(time_s: &[f64], temp_c: &[f64]) -> Vec<f64> {
    let idx: Vec<usize> = (0..temp_c.len()).filter(|&i| temp_c[i].is_finite()).collect();
    let mut knots: Vec<(f64, f64)> = Vec::new();
    for w in idx.windows(2) {
        let (i, j) = (w[0], w[1]);
        if temp_c[j] != temp_c[i] {
            knots.push((0.5 * (time_s[i] + time_s[j]), 0.5 * (temp_c[i] + temp_c[j])));
        }
    }
    if knots.is_empty() {
        return temp_c.to_vec();
    }
    let mut out = temp_c.to_vec();
    let mut k = 0usize;
    for &i in &idx {
        let t = time_s[i];
        while k + 1 < knots.len() && knots[k + 1].0 <= t {
            k += 1;
        }
        out[i] = if t <= knots[0].0 {
            knots[0].1
        } else if k + 1 >= knots.len() {
            knots[k].1
        } else {
            let ((t0, v0), (t1, v1)) = (knots[k], knots[k + 1]);
            v0 + (v1 - v0) * (t - t0) / (t1 - t0)
        };
    }
    out
}

/// Slot of PX4's `TC_An_ID` equal to `device_id` (PX4 keeps the uint32 in an int32
/// parameter), among the slots the log has.
fn px4_slot_of(params: &BTreeMap<String, f64>, device_id: u32) -> Option<u8> {
    (0..4u8).find(|n| params.get(&format!("TC_A{n}_ID")).is_some_and(|&v| v as i64 as i32 as u32 == device_id))
}

/// ArduPilot's parameter prefix of IMU instance `i` (0-based): `INS_` for the first three
/// (`INS_ACC_ID`, `INS_ACC2_ID`, `INS_TCAL1_ENABLE` …), as the lab names them.
#[must_use]
pub(crate) fn ardupilot_id_param(i: u8) -> String {
    match i {
        0 => "INS_ACC_ID".to_string(),
        n => format!("INS_ACC{}_ID", n + 1),
    }
}

/// Check each instance of `log` (see the module docs).
#[must_use]
pub fn check(log: &AutopilotLog) -> Vec<InstanceCheck> {
    log.instances.iter().map(|inst| check_instance(log, inst)).collect()
}

/// Check one instance: its sample count and temperature, then its stack's parameters.
fn check_instance(log: &AutopilotLog, inst: &AccelInstance) -> InstanceCheck {
    let temperature = resolution(&inst.temp_c);
    let mut c = InstanceCheck {
        index: inst.index,
        device_id: inst.device_id,
        samples: inst.time_s.len(),
        temperature,
        refused: None,
        warnings: Vec::new(),
    };
    let name = c.name();
    if c.samples < MIN_TEMP_SAMPLES {
        c.refused = Some(format!(
            "{name} has only {} sample(s) in the log: PX4's default logging profile records sensor_accel a few \
             times per log; record the chamber run with SDLOG_PROFILE bit 2 (thermal calibration), ArduPilot \
             with IMU logging on",
            c.samples
        ));
    }
    match temperature {
        Temperature::Missing { finite } => {
            c.refused = c.refused.take().or(Some(format!(
                "{name} has no temperature ({finite} nonzero finite reading(s) of {}): a thermal calibration \
                 needs the sensor's own temperature; PX4 logs NaN and ArduPilot 0 for a part without one",
                c.samples
            )));
        }
        Temperature::Resolution { step_c, coarse: true } => c.warnings.push(format!(
            "{name} reports temperature in {step_c:.3} °C steps: the temperature is rebuilt between its steps \
             before the rate is estimated (a staircase gives the rate estimator zero between steps and a spike \
             at each); the PX4/ArduPilot files still see the steps on the vehicle"
        )),
        Temperature::Resolution { .. } => {}
    }
    match log.stack {
        Stack::Px4 => check_px4_params(log, inst, &name, &mut c),
        Stack::ArduPilot => check_ardupilot_params(log, inst, &name, &mut c),
    }
    c
}

/// PX4: a warning when the instance was logged with its TC_A slot enabled; refused
/// without a device ID.
fn check_px4_params(log: &AutopilotLog, inst: &AccelInstance, name: &str, c: &mut InstanceCheck) {
    let enabled = log.params.get("TC_A_ENABLE").is_some_and(|&v| v != 0.0);
    if let (true, Some(id)) = (enabled, inst.device_id) {
        if let Some(slot) = px4_slot_of(&log.params, id) {
            c.warnings.push(format!(
                "{name} was logged with TC_A_ENABLE = 1 and TC_A{slot}_ID = {id}: PX4 applies TC_A{slot}_* \
                 in the sensors module, after the sensor_accel topic read here, so these samples are \
                 uncompensated and are calibrated; the new px4_tc.params replaces the vehicle's \
                 TC_A{slot}_* values"
            ));
        }
    }
    if inst.device_id.is_none_or(|id| id == 0) {
        c.refused = c.refused.take().or_else(|| {
            Some(format!(
                "{name}: sensor_accel.device_id is 0, and PX4 applies TC_An_* only to the accelerometer \
                 whose device ID equals TC_An_ID"
            ))
        });
    }
}

/// ArduPilot: refused when logged with its INS_TCAL compensation on or with a board
/// rotation; a warning while ArduPilot was learning.
fn check_ardupilot_params(log: &AutopilotLog, inst: &AccelInstance, name: &str, c: &mut InstanceCheck) {
    let p = format!("INS_TCAL{}_ENABLE", u16::from(inst.index) + 1);
    match log.params.get(&p).map(|&v| v.round() as i64) {
        Some(1) => {
            c.refused = c.refused.take().or_else(|| {
                Some(format!(
                    "{name} was logged with {p} = 1: ArduPilot applies INS_TCAL{n}_* in the IMU backend, \
                     before the IMU message is logged, so these samples are already compensated and a \
                     fit to them would compensate twice; set {p} = 0 (or 2 to let ArduPilot learn), \
                     reboot and record again",
                    n = u16::from(inst.index) + 1
                ))
            });
        }
        Some(2) => c.warnings.push(format!(
            "{name} was logged with {p} = 2 (ArduPilot learning): samples are uncompensated while it \
             learns, and are calibrated; ArduPilot overwrites INS_TCAL{}_* when its learner finishes",
            u16::from(inst.index) + 1
        )),
        _ => {}
    }
    if let Some(&rot) = log.params.get("AHRS_ORIENTATION") {
        if rot != 0.0 {
            c.refused = c.refused.take().or_else(|| {
                Some(format!(
                    "{name}: AHRS_ORIENTATION = {rot}: the IMU message is rotated to the vehicle frame \
                     after INS_TCAL is applied in the board frame, so its axes are not those of \
                     INS_TCAL{}_ACC*_X/Y/Z; record with AHRS_ORIENTATION = 0",
                    u16::from(inst.index) + 1
                ))
            });
        }
    }
}

/// Why an instance could not be turned into a static log.
#[derive(Debug, PartialEq)]
#[non_exhaustive]
pub enum AutopilotError {
    /// The static reader refused the binned rows.
    Static {
        /// The instance.
        index: u8,
        /// Its error.
        error: Box<StaticError>,
    },
}

impl fmt::Display for AutopilotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Static { index, error } => write!(f, "accelerometer instance {index} (in {BIN_S}-s bins): {error}"),
        }
    }
}

impl std::error::Error for AutopilotError {}

impl AccelInstance {
    /// The instance as a static log: its temperature rebuilt between steps when `coarse`
    /// (`dequantize`), then every quantity averaged over `BIN_S`-s bins of the log's
    /// clock (a sample with a non-finite value is left out of its bin), read by the static
    /// reader with columns `time_s`, `temp_c`, `ax`, `ay`, `az` (m/s²). A row's line number
    /// is its bin's number + 1.
    ///
    /// # Errors
    /// [`AutopilotError::Static`]: the static reader's refusal.
    pub fn to_static(&self, coarse: bool) -> Result<StaticLog, AutopilotError> {
        let temp = if coarse { dequantize(&self.time_s, &self.temp_c) } else { self.temp_c.clone() };
        let mut text = String::from("time_s\ttemp_c\tax\tay\taz\n");
        let mut sum = [0.0f64; 5];
        let mut n = 0usize;
        let mut key: Option<i64> = None;
        let flush = |text: &mut String, sum: &mut [f64; 5], n: &mut usize| {
            if *n > 0 {
                let m: Vec<f64> = sum.iter().map(|s| s / *n as f64).collect();
                let _ = writeln!(text, "{}\t{}\t{}\t{}\t{}", m[0], m[1], m[2], m[3], m[4]);
            }
            *sum = [0.0; 5];
            *n = 0;
        };
        for (i, (&t, &tc)) in self.time_s.iter().zip(&temp).enumerate() {
            let v = [t, tc, self.accel_mps2[0][i], self.accel_mps2[1][i], self.accel_mps2[2][i]];
            if v.iter().any(|x| !x.is_finite()) {
                continue;
            }
            let k = (v[0] / BIN_S).floor() as i64;
            if key != Some(k) {
                flush(&mut text, &mut sum, &mut n);
                key = Some(k);
            }
            for (s, x) in sum.iter_mut().zip(v) {
                *s += x;
            }
            n += 1;
        }
        flush(&mut text, &mut sum, &mut n);
        let opts = StaticOptions {
            time_unit: Some(TimeUnit::S),
            accel_unit: Some(AccelUnit::Mps2),
            ..StaticOptions::default()
        };
        read_static_from(text.as_bytes(), &opts)
            .map_err(|e| AutopilotError::Static { index: self.index, error: Box::new(e) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolution_names_whole_degrees_and_missing_temperature() {
        // A ramp read at 0.01 °C, the same ramp rounded to 1 °C, NaN, all zero.
        let fine: Vec<f64> =
            (0..200).map(|i| 20.0 + 0.013 * f64::from(i)).map(|t| (t * 100.0).round() / 100.0).collect();
        let whole: Vec<f64> = fine.iter().map(|t| t.round()).collect();
        assert!(
            matches!(resolution(&fine), Temperature::Resolution { coarse: false, step_c } if (step_c - 0.01).abs() < 1e-9)
        );
        assert!(
            matches!(resolution(&whole), Temperature::Resolution { coarse: true, step_c } if (step_c - 1.0).abs() < 1e-9)
        );
        assert_eq!(resolution(&[f64::NAN; 100]), Temperature::Missing { finite: 0 });
        assert_eq!(resolution(&[0.0; 100]), Temperature::Missing { finite: 0 });
        // Few samples with a temperature are not "no temperature" (check refuses them as few).
        assert!(matches!(resolution(&[20.0, 20.5, 21.0]), Temperature::Resolution { .. }));
    }

    #[test]
    fn dequantize_recovers_a_ramp_from_its_staircase() {
        // 0.05 °C/s ramp sampled at 1 Hz, rounded to 1 °C: rebuilt within 0.1 °C inside the
        // steps (the staircase itself is off by up to 0.5 °C).
        let t: Vec<f64> = (0..400).map(f64::from).collect();
        let truth: Vec<f64> = t.iter().map(|s| 10.3 + 0.05 * s).collect();
        let steps: Vec<f64> = truth.iter().map(|v| v.round()).collect();
        let re = dequantize(&t, &steps);
        let worst = |v: &[f64]| (20..380).map(|i| (v[i] - truth[i]).abs()).fold(0.0, f64::max);
        assert!(worst(&steps) > 0.45, "{}", worst(&steps));
        assert!(worst(&re) < 0.1, "{}", worst(&re));
    }
}
