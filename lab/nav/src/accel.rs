//! Accelerometer channels: truth-model corruption into I/F pulses, and compensation.
//!
//! Two small traits split the channel where the hardware splits it:
//!
//! * [`AccelTruth`] is the physical accelerometer plus its I/F converter on one axis:
//!   it turns the true velocity increment of an IMU cycle into an integer pulse count,
//!   carrying the fractional pulse to the next cycle so nothing is lost.
//! * [`AccelCompensation`] is what the navigation computer does with the pulses of the
//!   three axes: DS18B20 readings arrive on the slow path, pulse counts on the fast path.
//!
//! [`LabAccel`] wires in the lab's truth model: `E = K1·(K0 + a/g₀ + n)` pulses per second
//! (paper Eq. 2), K1 from Eq. 11 and K0 a smooth bias plus any extension effects.

use std::fmt;

use nalgebra::Vector3;
use qfa_thermal::compensator::{self, Compensator};
use qfa_thermal::table::Table;
use serde::{Deserialize, Serialize};

use super::earth::G0;
use qfa_sim::thermal::Temps;
use qfa_sim::truth::{SensorTruth, Truth, TruthModel};
use qfa_sim::NoiseGen;

/// One physical accelerometer axis with its I/F converter.
pub trait AccelTruth {
    /// Advance one cycle of `dt_s` at temperatures `th`, with true velocity increment
    /// `dv_mps` along the input axis; returns the signed pulse count of the cycle
    /// (fraction carried).
    fn corrupt(&mut self, th: &Temps, dv_mps: f64, dt_s: f64) -> i32;
    /// Thermal K1 (pulses/(g·s)) and K0 (g) of the truth model during the last cycle
    /// (without noise and bias instability): what the oracle compensation uses.
    fn coefficients(&self) -> (f64, f64);
    /// The DS18B20 on this unit's case (offset, noise), if it has one.
    fn sensor(&self) -> Option<SensorTruth> {
        None
    }
}

/// The navigation computer's accelerometer compensation, three axes.
pub trait AccelCompensation {
    /// Slow path: one DS18B20 raw reading (1/16 °C) for the whole IMU, taken at `t_ms`.
    fn on_temperature(&mut self, t_ms: u32, raw: i16);
    /// Slow path: each axis's own DS18B20 reading (one sensor per case, as in the lab's
    /// calibration), taken at `t_ms`. The default uses the x-axis reading for the IMU.
    fn on_temperatures(&mut self, t_ms: u32, raw: [i16; 3]) {
        self.on_temperature(t_ms, raw[0]);
    }
    /// Fast path: pulses of the three axes over `dt_ticks` µs; `truth` carries each axis's
    /// true (K1, K0) for the oracle and is ignored by real compensations.
    fn compensate(&mut self, pulses: [i32; 3], dt_ticks: u32, truth: &[(f64, f64); 3]) -> Vector3<f64>;
    /// Every status flag the compensation raised so far, counted per cycle; `None` for a
    /// compensation without a status word (the oracle).
    fn flags(&self) -> Option<FlagCounts> {
        None
    }
}

/// Why a compensation could not be built, or its flag shares not computed.
#[derive(Debug)]
#[non_exhaustive]
pub enum AccelError {
    /// No compensated cycle counted: a share of cycles has no denominator.
    NoCycles,
    /// The compensator refused its settings.
    Config(compensator::ConfigError),
    /// The three tables could not be joined into one 3-axis table.
    Table(super::calib::CalibError),
    /// The compensator refused the 3-axis table.
    Refused(qfa_thermal::table::Error),
}

impl fmt::Display for AccelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoCycles => f.write_str("no compensated cycle counted: flag share not computed"),
            Self::Config(_) => f.write_str("config"),
            Self::Table(e) => write!(f, "{e}"),
            Self::Refused(_) => f.write_str("table refused"),
        }
    }
}

impl std::error::Error for AccelError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::NoCycles => None,
            Self::Config(e) => Some(e),
            // Printed as it is (above): its cause comes next.
            Self::Table(e) => e.source(),
            Self::Refused(e) => Some(e),
        }
    }
}

impl From<super::calib::CalibError> for AccelError {
    fn from(e: super::calib::CalibError) -> Self {
        Self::Table(e)
    }
}

/// Per-flag cycle counts of a `Compensator`'s status word: `counts[b]` is the number of
/// fast-path cycles whose status had bit `b` set. `TableCompensation` used to keep only
/// the last status, so a flight compensated with a clamped rate most of the time looked
/// clean in every report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct FlagCounts {
    /// Fast-path cycles counted.
    pub cycles: u64,
    /// Cycles with any flag set.
    pub any: u64,
    /// Cycles per bit of the status word (`counts[b]`: bit `b`), every bit the word has, so
    /// a flag the firmware adds is counted without a change here; named by the firmware's
    /// own `Status` (its `iter_names`). A list of nine names kept here once missed
    /// `DT_IMPLAUSIBLE`, bit 9.
    pub counts: [u64; STATUS_BITS],
}

/// Bits in the firmware's status word.
pub const STATUS_BITS: usize = u16::BITS as usize;

impl FlagCounts {
    /// Count one cycle's status.
    pub fn add(&mut self, st: compensator::Status) {
        self.cycles += 1;
        if !st.is_ok() {
            self.any += 1;
        }
        for (b, c) in self.counts.iter_mut().enumerate() {
            if st.bits() & (1 << b) != 0 {
                *c += 1;
            }
        }
    }

    /// The counts since `earlier` (a snapshot of the same counter).
    #[must_use]
    pub fn since(&self, earlier: &Self) -> Self {
        let mut c = [0u64; STATUS_BITS];
        for (b, x) in c.iter_mut().enumerate() {
            *x = self.counts[b] - earlier.counts[b];
        }
        Self { cycles: self.cycles - earlier.cycles, any: self.any - earlier.any, counts: c }
    }

    /// Share of cycles with `flag` set.
    ///
    /// # Errors
    /// No cycle counted: the share is not computed.
    pub fn share(&self, flag: compensator::Status) -> Result<f64, AccelError> {
        crate::ensure(self.cycles > 0, AccelError::NoCycles)?;
        let b = flag.bits().trailing_zeros() as usize;
        Ok(self.counts[b] as f64 / self.cycles as f64)
    }

    /// The shares the reports carry.
    ///
    /// # Errors
    /// No cycle counted.
    pub fn shares(&self) -> Result<FlagShares, AccelError> {
        Ok(FlagShares {
            cycles: self.cycles,
            rate_clamped: self.share(compensator::Status::RATE_OUT_OF_RANGE)?,
            temp_clamped: self.share(compensator::Status::TEMP_OUT_OF_RANGE)?,
            any_flag: self.any as f64 / self.cycles as f64,
            by_flag: compensator::Status::all()
                .iter_names()
                .map(|(n, f)| (n, self.counts[f.bits().trailing_zeros() as usize]))
                .filter(|(_, c)| *c > 0)
                .map(|(n, c)| (n.to_string(), c as f64 / self.cycles as f64))
                .collect(),
        })
    }
}

/// Shares of a flight's IMU cycles on which the firmware raised a flag.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FlagShares {
    /// Cycles counted (the flight's, alignment excluded).
    pub cycles: u64,
    /// Share with `RATE_OUT_OF_RANGE`: Ṫ beyond the table's limit, clamped.
    pub rate_clamped: f64,
    /// Share with `TEMP_OUT_OF_RANGE`: T̂ outside the table's grid, clamped.
    pub temp_clamped: f64,
    /// Share with any flag.
    pub any_flag: f64,
    /// Share per flag that was raised at least once.
    pub by_flag: std::collections::BTreeMap<String, f64>,
}

/// Above this share of clamped cycles the console, `report.json` and `mc_runs.csv` say
/// the compensation ran out of its calibrated range most of the time ("most": a half).
pub const CLAMPED_WARN_SHARE: f64 = 0.5;

/// [`AccelTruth`] from the lab's truth model: [`qfa_sim::truth::TruthModel`] (Eq. 11 scale
/// factor, cubic bias, extension effects, on the case temperature and its rate) and
/// [`qfa_sim::NoiseGen`] (white noise + Gauss–Markov instability), with the I/F carry of
/// [`qfa_sim::Accelerometer::step`] (that type keeps K1 and K0 private, and the oracle
/// needs them, so its five lines are mirrored here).
#[derive(Debug)]
pub struct LabAccel {
    sensor: SensorTruth,
    model: TruthModel,
    noise: NoiseGen,
    counter: qfa_sim::IfConverter,
    k1: f64,
    k0: f64,
}

impl LabAccel {
    /// Unit `truth` with noise seed `seed`.
    #[must_use]
    pub fn new(truth: &Truth, seed: u64) -> Self {
        Self {
            sensor: truth.sensor,
            model: truth.model(),
            noise: NoiseGen::new(truth.noise, seed),
            counter: qfa_sim::IfConverter::default(),
            k1: 0.0,
            k0: 0.0,
        }
    }
}

impl AccelTruth for LabAccel {
    fn corrupt(&mut self, th: &Temps, dv_mps: f64, dt_s: f64) -> i32 {
        let e = self.model.step(th.case_c, th.case_rate_c_per_min, dt_s);
        let n = self.noise.step(dt_s);
        self.k1 = e.k1;
        self.k0 = e.k0;
        // A cycle's count is a few hundred pulses: it fits an i32 by orders of magnitude.
        self.counter.count(e.k1 * ((e.k0 + n) * dt_s + dv_mps / G0)) as i32
    }

    fn coefficients(&self) -> (f64, f64) {
        (self.k1, self.k0)
    }

    fn sensor(&self) -> Option<SensorTruth> {
        Some(self.sensor)
    }
}

/// A one-axis compensator: the root crate's `Compensator<1, 32>` (the configuration the
/// navigation study flew before the 3-axis one; kept to show the two agree).
pub type AxisCompensator = Compensator<1, 32>;

/// The configuration the navigation study flies, the one the firmware recommends: one
/// 3-axis compensator with one temperature stream per axis (each DS18B20 on its own case)
/// and a misalignment stage for the matrix (`ThreeAxisSensorPerAxisWithMatrix`, with the
/// table owned).
pub type ImuCompensator = Compensator<3, 32, 3, qfa_thermal::Table, 3>;

/// The firmware's default settings (1 µs ticks) for an IMU cycling at `imu_rate_hz`: the
/// IMU period is the one setting a flight must state, or every cycle of another rate than
/// the default 400 Hz is flagged `DT_IMPLAUSIBLE`.
#[must_use]
pub fn firmware_config(imu_rate_hz: f64) -> compensator::Config {
    compensator::Config { imu_period_s: (1.0 / imu_rate_hz) as f32, ..compensator::Config::default() }
}

/// A fresh [`AxisCompensator`] with [`firmware_config`].
///
/// # Panics
/// If `imu_rate_hz` is outside what a scenario allows (0, 10 000] Hz.
#[must_use]
pub fn axis_compensator(imu_rate_hz: f64) -> AxisCompensator {
    Compensator::new(firmware_config(imu_rate_hz)).expect("a scenario's IMU rate is a valid period")
}

/// Compensation through the root crate's [`Compensator`], exactly as the firmware runs it:
/// one [`ImuCompensator`] with a stream per axis, each fed by the DS18B20 on its own case,
/// loaded with the three units' 1-axis tables joined into one 3-axis table
/// ([`super::calib::table3_with`]) with the triad's misalignment matrix when given (the
/// lab's cycling calibration does not estimate one: the navigation study carries the
/// scenario's known triad misalignment, [`super::errors::AccelErrors::carried_misalignment`]).
#[derive(Clone, Debug)]
pub struct TableCompensation {
    comp: ImuCompensator,
    /// Slow-path rejections seen (should stay 0 in simulation).
    pub rejected: u32,
    /// Status of the last IMU cycle.
    pub last_status: compensator::Status,
    /// Every cycle's status, counted per flag.
    pub flag_counts: FlagCounts,
}

impl TableCompensation {
    /// With the x, y, z tables loaded and [`firmware_config`] at `imu_rate_hz`.
    ///
    /// # Errors
    /// A table's validation error.
    pub fn new(tables: [&Table; 3], imu_rate_hz: f64) -> Result<Self, AccelError> {
        Self::with_misalignment(tables, None, imu_rate_hz)
    }

    /// With the x, y, z tables and the misalignment matrix `misalignment` (row-major) in
    /// one 3-axis table.
    ///
    /// # Errors
    /// A table's validation error.
    pub fn with_misalignment(
        tables: [&Table; 3],
        misalignment: Option<[f32; 9]>,
        imu_rate_hz: f64,
    ) -> Result<Self, AccelError> {
        let mut comp = ImuCompensator::new(firmware_config(imu_rate_hz)).map_err(AccelError::Config)?;
        comp.set_table(super::calib::table3_with(tables, misalignment)?).map_err(AccelError::Refused)?;
        Ok(Self { comp, rejected: 0, last_status: compensator::Status::empty(), flag_counts: FlagCounts::default() })
    }

    /// The compensator.
    #[must_use]
    pub fn compensator(&self) -> &ImuCompensator {
        &self.comp
    }
}

impl AccelCompensation for TableCompensation {
    fn on_temperature(&mut self, t_ms: u32, raw: i16) {
        self.on_temperatures(t_ms, [raw; 3]);
    }

    fn on_temperatures(&mut self, t_ms: u32, raw: [i16; 3]) {
        for (axis, r) in raw.into_iter().enumerate() {
            if self.comp.on_raw(axis, t_ms, r).is_err() {
                self.rejected += 1;
            }
        }
    }

    fn compensate(&mut self, pulses: [i32; 3], dt_ticks: u32, _truth: &[(f64, f64); 3]) -> Vector3<f64> {
        let out = self.comp.cycle(pulses, dt_ticks);
        self.last_status = out.status;
        self.flag_counts.add(out.status);
        Vector3::from_fn(|i, _| f64::from(out.dv_mps[i]))
    }

    fn flags(&self) -> Option<FlagCounts> {
        Some(self.flag_counts)
    }
}

/// The limit: the truth model itself as the compensation, `Δv = g₀·(N/K1 − K0·dt)` with
/// the true thermal K1 and K0 of the cycle (f64), then the triad's known misalignment
/// inverse when given (the one the tables carry). What is left is the non-thermal error
/// common to every variant (white noise, bias instability) and quantization.
#[derive(Clone, Copy, Debug, Default)]
pub struct OracleCompensation {
    /// `(I + K)⁻¹`, applied after the thermal compensation.
    pub misalignment: Option<nalgebra::Matrix3<f64>>,
}

impl OracleCompensation {
    /// The oracle with the known triad misalignment inverse `m` (none: orthogonal).
    #[must_use]
    pub const fn carrying(m: Option<nalgebra::Matrix3<f64>>) -> Self {
        Self { misalignment: m }
    }
}

impl AccelCompensation for OracleCompensation {
    fn on_temperature(&mut self, _t_ms: u32, _raw: i16) {}

    fn compensate(&mut self, pulses: [i32; 3], dt_ticks: u32, truth: &[(f64, f64); 3]) -> Vector3<f64> {
        let dt = f64::from(dt_ticks) * 1e-6;
        let v = Vector3::from_fn(|i, _| G0 * (f64::from(pulses[i]) / truth[i].0 - truth[i].1 * dt));
        self.misalignment.map_or(v, |m| m * v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every flag the firmware's status word defines is counted and named by its own name,
    /// alone and together with the others; a cycle with none is counted as a cycle only.
    #[test]
    fn every_flag_of_the_status_word_is_counted_by_its_name() {
        let mut c = FlagCounts::default();
        let flags: Vec<(&str, compensator::Status)> = compensator::Status::all().iter_names().collect();
        for (_, f) in &flags {
            c.add(*f);
        }
        c.add(compensator::Status::all());
        c.add(compensator::Status::empty());
        let shares = c.shares().unwrap();
        assert_eq!(shares.cycles, flags.len() as u64 + 2);
        assert_eq!(shares.by_flag.len(), flags.len(), "{:?}", shares.by_flag);
        for (n, _) in &flags {
            assert_eq!(shares.by_flag[*n], 2.0 / shares.cycles as f64, "{n}");
        }
        assert!(shares.by_flag.contains_key("DT_IMPLAUSIBLE"));
    }
}
