//! Fault injection on the streams the navigation run feeds into the compensator, and the
//! navigation scenario flown with faults.
//!
//! The navigation run ([`crate::run::fly`]) gives every variant one DS18B20 reading
//! per accelerometer case once a second (`on_temperatures(t_ms, [raw; 3])`) and the
//! pulses of each IMU cycle (`compensate(pulses, dt_ticks, ..)`). [`FaultyCompensation`]
//! sits on those streams exactly where the nav's own `TableCompensation` does (one
//! `Compensator<3, 32, 3>` with the three units' 3-axis table, each axis fed by its own
//! case sensor, as the firmware recommends): an
//! [`Injector`] per sensor stream turns each reading into what the firmware would
//! receive (a scratchpad, possibly corrupted, or nothing) and each cycle length into what
//! the firmware's timer would measure, and the result goes to a [`ThermalCompensator`]
//! (the root crate's compensator, through the same `on_scratchpad` path the driver uses).
//! Windowed faults (brown-out, dropout, stuck) hit the three sensors at the same times,
//! as on one shared 1-Wire bus; CRC errors and spikes are drawn per reading. Every outcome is logged in a [`FaultLog`]: faults injected, faults
//! flagged **with the flag of that fault** (the column below; a refusal for another
//! reason counts as `wrong`), refusals of intact readings, non-finite outputs.
//!
//! | fault | model | the right flag |
//! |---|---|---|
//! | CRC errors at rate p | each reading, with probability p, arrives with one flipped bit | `SampleError::Decode(ds18b20::Error::Crc)` |
//! | power-on 85 °C after a brown-out | at given times the next reading is the power-on scratchpad (0550h, byte 6 = 0Ch, valid CRC) | `SampleError::Decode(ds18b20::Error::PowerOn)` or `SampleError::PowerOnJump` |
//! | dropout 10 s – 10 min | no reading in a window | `Status::TEMP_STALE` on the fast path during the window (one status word for the IMU) |
//! | spikes at rate p | a reading off by ±`magnitude` | `SampleError::Implausible` |
//! | stuck sensor | the reading repeats the value at the start of a window | not detectable from the value alone (a plausible constant); the jump back may give `SampleError::Implausible` |
//! | corrupted table bytes at load | the 3-axis table is first offered with one byte changed, then intact | `load_table` refuses it; the previous (intact) table stays active |
//! | IMU cycle jitter | the cycle length the firmware passes is off by a uniform ±j µs (the pulses are of the true cycle) | not a fault the compensator can see |
//!
//! [`fly_with_faults`] flies the scenario once with every fault set in lock-step beside
//! a fault-free twin and the oracle (same sensor data, same noise). Its figures are on
//! the **thermal-only** error, not total CEP (gyro errors dominate total CEP and would
//! hide a broken compensation): `thermal` is the radial growth of (row − oracle)
//! position, and `added` the radial growth of (row − fault-free twin) position divided by
//! the `simple` variant's thermal-only CEP rate (flown beside them): the fault's cost as a
//! share of the thermal error the compensation is there to remove. The twin's own
//! thermal-only rate is not a stable denominator: the alignment's response to DS18B20
//! flicker moves it by ×4 between 20 and 200 Hz on the same seed (0.085 and 0.021
//! nmile/h), while the fault's absolute cost stays put; this choice was made after seeing
//! that. `added_vs_twin` keeps the other ratio for the table.
//! [`check`] lists every violated expectation; [`Replacement`] rows fly a deliberately broken
//! compensation to show each expectation can fail.

use std::fmt::{self, Write as _};

use qfa_thermal::compensator::{Compensator, PulseOutput, SampleError, Status};
use qfa_thermal::table::{self, Table};

use crate::accel::{AccelError, ImuCompensator, OracleCompensation, TableCompensation};
use crate::calib::CalibError;
use crate::run::{self, Figures, RunError, Variant};
use crate::scenario::Scenario;

pub use super::fault_injection::{
    right_flag, Count, Delivered, FaultLog, FaultSet, FaultyCompensation, Injected, Injector, Kind,
};

/// Why the fault runs could not be flown or compared.
#[derive(Debug)]
#[non_exhaustive]
pub enum FaultsError {
    /// A 3-axis table that does not encode.
    Encode(table::Error),
    /// The per-axis tables could not be joined into one 3-axis table.
    Table(CalibError),
    /// The fault-free twin refused its table.
    Refused,
    /// The `simple` compensation could not be built.
    Compensation(AccelError),
    /// A row's replacement table does not validate.
    ReplacedTable {
        /// The row.
        row: String,
        /// The validation's error.
        source: table::Error,
    },
    /// The flight failed.
    Flight(RunError),
    /// The fault-free twin refused readings: the comparison has no clean reference.
    TwinRefused,
    /// A thermal-only CEP rate too small to divide by.
    NothingToCompare {
        /// The fault-free twin's, nmile/h.
        twin: f64,
        /// The `simple` variant's, nmile/h.
        simple: f64,
    },
}

impl fmt::Display for FaultsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Encode(_) => f.write_str("table"),
            Self::Table(e) => write!(f, "{e}"),
            Self::Refused => f.write_str("a table was refused"),
            Self::Compensation(e) => write!(f, "{e}"),
            Self::ReplacedTable { row, .. } => write!(f, "{row}: replaced table invalid"),
            Self::Flight(e) => write!(f, "{e}"),
            Self::TwinRefused => f.write_str("the fault-free twin refused readings"),
            Self::NothingToCompare { twin, simple } => {
                write!(f, "thermal-only CEP rates twin {twin}, simple {simple}: nothing to compare with")
            }
        }
    }
}

impl std::error::Error for FaultsError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Encode(e) | Self::ReplacedTable { source: e, .. } => Some(e),
            // Printed as they are (above): their causes come next.
            Self::Table(e) => e.source(),
            Self::Compensation(e) => e.source(),
            Self::Flight(e) => e.source(),
            Self::Refused | Self::TwinRefused | Self::NothingToCompare { .. } => None,
        }
    }
}

impl From<CalibError> for FaultsError {
    fn from(e: CalibError) -> Self {
        Self::Table(e)
    }
}

impl From<AccelError> for FaultsError {
    fn from(e: AccelError) -> Self {
        Self::Compensation(e)
    }
}

impl From<RunError> for FaultsError {
    fn from(e: RunError) -> Self {
        Self::Flight(e)
    }
}

/// The compensator interface the injector drives: the firmware's entry points for the
/// whole IMU, in the recommended configuration (one 3-axis compensator, one DS18B20
/// stream per axis).
pub trait ThermalCompensator {
    /// Decode, validate and activate a 3-axis table (atomic).
    ///
    /// # Errors
    /// The table error; the active table is unchanged.
    fn load_table(&mut self, bytes: &[u8]) -> table::Result<()>;
    /// Slow path: axis `axis`'s scratchpad, whose conversion completed at `t_ms`.
    ///
    /// # Errors
    /// Why the reading was not used.
    fn on_scratchpad(&mut self, axis: usize, t_ms: u32, sp: &[u8; 9]) -> Result<Status, SampleError>;
    /// Fast path: Δv per axis (m/s) and status.
    fn cycle(&mut self, pulses: [i32; 3], dt_ticks: u32) -> ([f32; 3], Status);
    /// The active table.
    fn table(&self) -> Option<&Table>;
}

impl ThermalCompensator for ImuCompensator {
    fn load_table(&mut self, bytes: &[u8]) -> table::Result<()> {
        Compensator::load_table(self, bytes)
    }
    fn on_scratchpad(&mut self, axis: usize, t_ms: u32, sp: &[u8; 9]) -> Result<Status, SampleError> {
        Compensator::on_scratchpad(self, axis, t_ms, sp)
    }
    fn cycle(&mut self, pulses: [i32; 3], dt_ticks: u32) -> ([f32; 3], Status) {
        let PulseOutput { dv_mps, status } = Compensator::cycle(self, pulses, dt_ticks);
        (dv_mps, status)
    }
    fn table(&self) -> Option<&Table> {
        Compensator::table(self)
    }
}

/// A fresh [`ImuCompensator`] with the firmware's default settings at `imu_rate_hz`
/// ([`crate::accel::firmware_config`]).
///
/// # Panics
/// If `imu_rate_hz` is outside what a scenario allows (0, 10 000] Hz.
#[must_use]
pub fn imu_compensator(imu_rate_hz: f64) -> ImuCompensator {
    Compensator::new(crate::accel::firmware_config(imu_rate_hz)).expect("a scenario's IMU rate is a valid period")
}

/// What a row flies in place of the real compensation: the fault test's deliberately
/// broken compensations, which show that [`check`] can fail, live in that test.
#[derive(Clone, Copy, Debug)]
pub struct Replacement {
    /// The compensator, fresh.
    pub compensator: fn(f64) -> Box<dyn ThermalCompensator>,
    /// The per-axis tables it loads (x, y, z), made from the real ones. It cannot fail:
    /// what it makes is validated before it flies ([`FaultsError::ReplacedTable`]).
    pub tables: fn([&Table; 3]) -> [Table; 3],
}

/// One row to fly: a named fault set, a limit on its `added` share, and what it flies in
/// place of the real compensation, if anything.
#[derive(Clone, Debug)]
pub struct RowSpec {
    /// Name.
    pub name: String,
    /// Faults injected.
    pub set: FaultSet,
    /// Largest `added` share allowed (0.01 = the fault may add 1 % of the fault-free
    /// twin's thermal-only CEP rate); `None`: measured, not asserted.
    pub limit: Option<f64>,
    /// A compensation flown in place of the real one (`None`: the real one).
    pub replaced: Option<Replacement>,
}

/// One row of the fault table.
#[derive(Clone, Debug)]
pub struct FaultRow {
    /// What was flown.
    pub spec: RowSpec,
    /// Navigation figures (total) with the faults.
    pub figures: Figures,
    /// Thermal-only CEP rate, nmile/h: radial growth of (row − oracle) position.
    pub thermal_nmi_per_h: f64,
    /// Radial growth of (row − fault-free twin) position over the `simple` variant's
    /// thermal-only CEP rate (0.01 = 1 %): what [`check`] limits.
    pub added: f64,
    /// The same growth over the twin's own thermal-only CEP rate.
    pub added_vs_twin: f64,
    /// What happened.
    pub log: FaultLog,
}

/// The fault-free twin and every faulty run.
#[derive(Clone, Debug)]
pub struct FaultReport {
    /// Flight duration, s.
    pub duration_s: f64,
    /// IMU rate, Hz.
    pub imu_rate_hz: f64,
    /// The fault-free twin (total figures).
    pub clean: Figures,
    /// Its thermal-only CEP rate, nmile/h.
    pub clean_thermal_nmi_per_h: f64,
    /// The `simple` variant's thermal-only CEP rate, nmile/h (the denominator of `added`).
    pub simple_thermal_nmi_per_h: f64,
    /// One row per fault set.
    pub rows: Vec<FaultRow>,
}

/// [`ThermalCompensator`] behind a box, so rows can mix real and broken compensators.
impl ThermalCompensator for Box<dyn ThermalCompensator> {
    fn load_table(&mut self, bytes: &[u8]) -> table::Result<()> {
        (**self).load_table(bytes)
    }
    fn on_scratchpad(&mut self, axis: usize, t_ms: u32, sp: &[u8; 9]) -> Result<Status, SampleError> {
        (**self).on_scratchpad(axis, t_ms, sp)
    }
    fn cycle(&mut self, pulses: [i32; 3], dt_ticks: u32) -> ([f32; 3], Status) {
        (**self).cycle(pulses, dt_ticks)
    }
    fn table(&self) -> Option<&Table> {
        (**self).table()
    }
}

fn encode(t: &Table) -> Result<Vec<u8>, FaultsError> {
    Ok(t.to_bytes().map_err(FaultsError::Encode)?.to_vec())
}

/// Fly `sc` once with each axis's table (`tables`, x, y, z: the `hysteresis` variant's
/// 1-axis unit tables, usually) loaded into a fault-free twin and into one compensation
/// per row (or the row's [`Replacement`]), beside the oracle and the `simple` tables (`simple`,
/// fault-free), all in lock-step on the same sensor data.
///
/// # Errors
/// A table the compensator refuses, a replacement table that does not validate, the
/// flight's errors, or a thermal-only error of `simple` too small to divide by.
pub fn fly_with_faults(
    sc: &Scenario,
    tables: [&Table; 3],
    simple: [&Table; 3],
    rows: &[RowSpec],
) -> Result<FaultReport, FaultsError> {
    // One 3-axis table for the IMU's compensator, as the firmware flies it.
    let m = sc.imu.accel.carried_misalignment();
    let good = encode(&crate::calib::table3_with(tables, m)?)?;
    let hz = sc.imu_rate_hz;
    let (clean, clean_log) = FaultyCompensation::new(imu_compensator(hz), &FaultSet::none(), &good);
    crate::ensure(clean_log.borrow().table_loaded, FaultsError::Refused)?;
    let mut variants = vec![
        Variant { name: "oracle".into(), comp: Box::new(OracleCompensation::carrying(sc.imu.accel.triad_inverse())) },
        Variant { name: "clean".into(), comp: Box::new(clean) },
        Variant { name: "simple".into(), comp: Box::new(TableCompensation::with_misalignment(simple, m, hz)?) },
    ];
    let mut logs = Vec::new();
    for r in rows {
        let set = FaultSet { takeoff_s: sc.align_steps() as f64 / sc.imu_rate_hz, ..r.set.clone() };
        let log = if let Some(rep) = r.replaced {
            let bt = (rep.tables)(tables);
            for t in &bt {
                t.validate().map_err(|e| FaultsError::ReplacedTable { row: r.name.clone(), source: e })?;
            }
            let bytes = encode(&crate::calib::table3_with([&bt[0], &bt[1], &bt[2]], m)?)?;
            let (c, log) = FaultyCompensation::new((rep.compensator)(hz), &set, &bytes);
            variants.push(Variant { name: r.name.clone(), comp: Box::new(c) });
            log
        } else {
            let (c, log) = FaultyCompensation::new(imu_compensator(hz), &set, &good);
            variants.push(Variant { name: r.name.clone(), comp: Box::new(c) });
            log
        };
        logs.push(log);
    }
    let units = crate::units();
    let res = run::fly(sc, &mut crate::truths_seeded(&units, sc.seed), variants)?;
    crate::ensure(clean_log.borrow().refused == 0, FaultsError::TwinRefused)?;
    let growth = |a: &run::Track, b: &run::Track| -> f64 {
        let d = |x: &[f64], y: &[f64]| -> Vec<f64> { x.iter().zip(y).map(|(p, q)| p - q).collect() };
        let tr = run::Track { dn: d(&a.dn, &b.dn), de: d(&a.de, &b.de), vn: d(&a.vn, &b.vn), ve: d(&a.ve, &b.ve) };
        Figures::of(&res.t, &tr).cep_nmi_per_h
    };
    let (oracle, clean) = (&res.tracks[0], &res.tracks[1]);
    let clean_thermal = growth(clean, oracle);
    let simple_thermal = growth(&res.tracks[2], oracle);
    crate::ensure(
        clean_thermal > 1e-9 && simple_thermal > 1e-9,
        FaultsError::NothingToCompare { twin: clean_thermal, simple: simple_thermal },
    )?;
    let rows = rows
        .iter()
        .zip(&res.tracks[3..])
        .zip(&logs)
        .map(|((spec, tr), log)| FaultRow {
            spec: spec.clone(),
            figures: Figures::of(&res.t, tr),
            thermal_nmi_per_h: growth(tr, oracle),
            added: growth(tr, clean) / simple_thermal,
            added_vs_twin: growth(tr, clean) / clean_thermal,
            log: log.borrow().clone(),
        })
        .collect();
    Ok(FaultReport {
        duration_s: res.t.last().copied().unwrap_or(0.0),
        imu_rate_hz: sc.imu_rate_hz,
        clean: Figures::of(&res.t, clean),
        clean_thermal_nmi_per_h: clean_thermal,
        simple_thermal_nmi_per_h: simple_thermal,
        rows,
    })
}

/// Every expectation `row` violates: a non-finite output, a corrupted or missing table,
/// an intact reading refused, a detectable fault not flagged every time with its own
/// flag (stuck values and cycle jitter are invisible, see the module table), a refusal
/// with the wrong flag, an `added` share above the row's limit.
#[must_use]
pub fn check(row: &FaultRow) -> Vec<String> {
    let mut v = Vec::new();
    let l = &row.log;
    if l.non_finite > 0 {
        v.push(format!("{} non-finite outputs", l.non_finite));
    }
    if l.corrupt_table_applied || !l.table_loaded {
        v.push("table: corrupted applied or none loaded".into());
    }
    if l.refused_intact > 0 {
        v.push(format!("{} intact readings refused", l.refused_intact));
    }
    for (k, c) in &l.counts {
        if c.injected == 0 {
            v.push(format!("{k:?}: counted but never injected"));
        }
        if !matches!(k, Kind::Stuck | Kind::Jitter) && c.flagged != c.injected {
            v.push(format!("{k:?}: flagged {} of {} with its own flag", c.flagged, c.injected));
        }
        if c.wrong > 0 {
            v.push(format!("{k:?}: {} refusals with the wrong flag", c.wrong));
        }
    }
    if let Some(lim) = row.spec.limit {
        if row.added.is_nan() || row.added.abs() >= lim {
            v.push(format!(
                "adds {:.3} % of simple's thermal-only CEP rate (limit {:.1} %)",
                100.0 * row.added,
                100.0 * lim
            ));
        }
    }
    v
}

/// The fault sets on a flight whose cruise runs from `cruise_s.0` to
/// `cruise_s.1`, with the fault limits now on the thermal-only error: 5 % CRC errors may
/// add 1 %, a 2-minute dropout 5 % of `simple`'s thermal-only CEP rate.
#[must_use]
pub fn standard_sets(cruise_s: (f64, f64)) -> Vec<RowSpec> {
    let mid = 0.5 * (cruise_s.0 + cruise_s.1);
    let seed = 0x7_0001;
    let s = |f: FaultSet| FaultSet { seed, ..f };
    let row = |name: &str, set: FaultSet, limit: Option<f64>| RowSpec {
        name: name.into(),
        set: s(set),
        limit,
        replaced: None,
    };
    vec![
        row("CRC errors 5 %", FaultSet::crc(0.05), Some(0.01)),
        row("CRC errors 20 %", FaultSet::crc(0.20), None),
        row(
            "power-on 85 °C after brown-out ×10",
            FaultSet { brown_outs_s: (1..=10).map(|k| f64::from(k) * 700.0).collect(), ..FaultSet::default() },
            None,
        ),
        row("dropout 10 s mid-cruise", FaultSet::dropout(mid - 5.0, 10.0), None),
        row("dropout 2 min mid-cruise", FaultSet::dropout(mid - 60.0, 120.0), Some(0.05)),
        row("dropout 10 min mid-cruise", FaultSet::dropout(mid - 300.0, 600.0), None),
        row("spikes ±5 °C, 1 %", FaultSet { spike_rate: 0.01, spike_c: 5.0, ..FaultSet::default() }, None),
        row(
            "stuck sensor 2 min mid-cruise",
            FaultSet { stuck_s: vec![(mid - 60.0, 120.0)], ..FaultSet::default() },
            None,
        ),
        row("corrupted table byte at load", FaultSet { corrupt_table: Some((37, 0x5A)), ..FaultSet::default() }, None),
        row("IMU cycle jitter ±50 µs", FaultSet { imu_jitter_us: 50, ..FaultSet::default() }, None),
        row("all of the above together", all_faults(mid, seed), None),
    ]
}

/// Every fault at once, around the cruise's middle `mid` (s).
#[must_use]
pub fn all_faults(mid: f64, seed: u64) -> FaultSet {
    FaultSet {
        crc_error_rate: 0.05,
        brown_outs_s: (1..=10).map(|k| f64::from(k) * 700.0).collect(),
        dropouts_s: vec![(mid - 60.0, 120.0)],
        spike_rate: 0.01,
        spike_c: 5.0,
        stuck_s: vec![(mid + 600.0, 120.0)],
        corrupt_table: Some((37, 0x5A)),
        imu_jitter_us: 50,
        seed,
        takeoff_s: 0.0,
    }
}

/// The fault table as Markdown.
#[must_use]
pub fn markdown(r: &FaultReport) -> String {
    let mut s = format!(
        "Fault-free twin over {:.2} h at {} Hz: CEP {:.4} nmile/h total, thermal-only {:.5} nmile/h (twin − oracle); \
         simple's thermal-only {:.5} nmile/h.\n\n\
         | fault | injected | flagged (own flag) | wrong flag | refused intact | stale cycles | non-finite | thermal-only nmile/h | added (of simple's) | added (of twin's) | limit | check |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
        r.duration_s / 3600.0,
        r.imu_rate_hz,
        r.clean.cep_nmi_per_h,
        r.clean_thermal_nmi_per_h,
        r.simple_thermal_nmi_per_h
    );
    for row in &r.rows {
        let mut inj = String::new();
        let mut flg = String::new();
        let mut wrong = 0;
        for (k, c) in &row.log.counts {
            let _ = write!(inj, "{k:?} {} ", c.injected);
            let _ = write!(flg, "{k:?} {} ", c.flagged);
            wrong += c.wrong;
        }
        let bad = check(row);
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {:.5} | {:+.3} % | {:+.3} % | {} | {} |",
            row.spec.name,
            inj.trim(),
            flg.trim(),
            wrong,
            row.log.refused_intact,
            row.log.stale_cycles,
            row.log.non_finite,
            row.thermal_nmi_per_h,
            100.0 * row.added,
            100.0 * row.added_vs_twin,
            row.spec.limit.map_or("–".to_string(), |l| format!("< {:.0} %", 100.0 * l)),
            if bad.is_empty() { "pass".to_string() } else { format!("FAIL: {}", bad.join("; ")) }
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::AccelCompensation;
    use qfa_thermal::model::{AxisModel, BiasGrid, Extensions};

    /// A 3-axis table, each axis JB-KT8 #1-like.
    fn table_bytes() -> Vec<u8> {
        let a = AxisModel {
            scale: qfa_sim::truth::Truth::jb_kt8(1).scale,
            bias: BiasGrid::single_valued(-60.0, 65.0, &[1e-4, 1.5e-4, 3e-4]).expect("2 to 16 grid values"),
            rate_limit_c_per_min: 2.0,
            ext: Extensions::default(),
        };
        let t = qfa_calibrate::fit::table_of_axes(qfa_thermal::Input::PulseCounts, [a.clone(), a.clone(), a])
            .expect("a valid table");
        t.to_bytes().expect("encodes").to_vec()
    }

    fn comps() -> ImuCompensator {
        imu_compensator(200.0) // the 5-ms cycles below
    }

    #[test]
    fn every_detectable_reading_fault_is_refused_and_flagged() {
        let b = table_bytes();
        let set = FaultSet {
            crc_error_rate: 0.3,
            brown_outs_s: vec![50.0, 120.0],
            spike_rate: 0.05,
            spike_c: 5.0,
            dropouts_s: vec![(200.0, 20.0), (300.0, 20.0)],
            corrupt_table: Some((5, 0x10)),
            seed: 3,
            ..FaultSet::default()
        };
        let (mut c, log) = FaultyCompensation::new(comps(), &set, &b);
        for k in 1..=400u32 {
            let raw = 352 + (k / 40) as i16;
            c.on_temperatures(k * 1000, [raw, raw + 1, raw - 1]);
            for _ in 0..200 {
                let v = c.compensate([3000, -3000, 10], 5000, &[(0.0, 0.0); 3]);
                assert!(v.iter().all(|x| x.is_finite()));
            }
        }
        let log = log.borrow();
        assert!(!log.corrupt_table_applied && log.table_loaded);
        assert_eq!(log.refused_intact, 0);
        assert_eq!(log.non_finite, 0);
        for k in [Kind::Crc, Kind::PowerOn, Kind::Spike, Kind::Dropout, Kind::CorruptTable] {
            let c = log.counts[&k];
            assert!(c.injected > 0, "{k:?}");
            assert_eq!(c.flagged, c.injected, "{k:?}: {c:?}");
        }
    }

    #[test]
    fn corrupt_table_is_never_applied_at_any_byte() {
        let b = table_bytes();
        for i in 0..b.len() {
            for x in [0x01u8, 0x80, 0xFF] {
                let set = FaultSet { corrupt_table: Some((i, x)), ..FaultSet::default() };
                let (_, log) = FaultyCompensation::new(comps(), &set, &b);
                let log = log.borrow();
                assert!(!log.corrupt_table_applied && log.table_loaded, "byte {i} ^ {x:#x}");
                assert_eq!(
                    log.counts[&Kind::CorruptTable],
                    Count { injected: 1, flagged: 1, wrong: 0 },
                    "byte {i} ^ {x:#x}"
                );
            }
        }
    }
}
