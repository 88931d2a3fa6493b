//! Fault injection on the streams the navigation run feeds into the compensator, and the
//! navigation scenario flown with faults.
//!
//! The navigation run ([`crate::navigate::run::fly`]) gives every variant one DS18B20 reading
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

use std::cell::RefCell;
use std::fmt::Write as _;
use std::rc::Rc;

use nalgebra::Vector3;
use qfa_thermal::compensator::{Compensator, PulseOutput, SampleError, Status};
use qfa_thermal::ds18b20::{self, encode_scratchpad, Resolution, POWER_ON_RAW};
use qfa_thermal::table::{self, Table};

use crate::navigate::accel::{AccelCompensation, ImuCompensator, OracleCompensation, TableCompensation};
use crate::navigate::run::{self, Figures, Variant};
use crate::navigate::scenario::Scenario;

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

/// A fresh [`ImuCompensator`] with the firmware's default settings.
#[must_use]
pub fn imu_compensator() -> ImuCompensator {
    Compensator::new(qfa_thermal::Config::default()).expect("the default config is valid")
}

/// Which faults to inject. Times are seconds since the start of the flight.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaultSet {
    /// Probability that a reading arrives with one flipped bit (CRC error).
    pub crc_error_rate: f64,
    /// Brown-outs: the first reading at or after each time is the power-on scratchpad.
    pub brown_outs_s: Vec<f64>,
    /// Dropouts: (start, duration), no reading at all.
    pub dropouts_s: Vec<(f64, f64)>,
    /// Probability that a reading is a spike.
    pub spike_rate: f64,
    /// Spike size, °C (sign drawn per spike).
    pub spike_c: f64,
    /// Stuck sensor: (start, duration), the reading repeats the value before the window.
    pub stuck_s: Vec<(f64, f64)>,
    /// Offer the table with byte `i` XOR-ed with `x` first: `Some((i, x))`.
    pub corrupt_table: Option<(usize, u8)>,
    /// IMU cycle jitter: the firmware's cycle length is off by uniform ±this many µs.
    pub imu_jitter_us: u32,
    /// Seed of the injector's own draws.
    pub seed: u64,
    /// Take-off on the compensator's clock, s (the alignment's length): fault times are
    /// relative to it, and nothing is injected before it.
    pub takeoff_s: f64,
}

impl FaultSet {
    /// No fault.
    #[must_use]
    pub fn none() -> Self {
        Self::default()
    }

    /// `crc_error_rate` readings with a CRC error.
    #[must_use]
    pub fn crc(rate: f64) -> Self {
        Self { crc_error_rate: rate, ..Self::default() }
    }

    /// One dropout.
    #[must_use]
    pub fn dropout(start_s: f64, dur_s: f64) -> Self {
        Self { dropouts_s: vec![(start_s, dur_s)], ..Self::default() }
    }
}

/// What a reading became.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Delivered {
    /// A scratchpad reaches the compensator.
    Scratchpad([u8; 9]),
    /// Nothing arrives.
    Nothing,
}

/// Kinds of fault, for the log.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Kind {
    /// A flipped bit.
    Crc,
    /// Power-on value after a brown-out.
    PowerOn,
    /// A missing reading (counted per dropout window).
    Dropout,
    /// A spike.
    Spike,
    /// A stuck reading (counted per window).
    Stuck,
    /// A corrupted table offered.
    CorruptTable,
    /// A jittered cycle length (counted per cycle).
    Jitter,
}

/// Counts per fault kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Count {
    /// Injected.
    pub injected: u64,
    /// Flagged by the compensator with the right flag for this fault (see the module table).
    pub flagged: u64,
    /// Refused, but for another reason than this fault's.
    pub wrong: u64,
}

/// Whether `e` is the right [`SampleError`] for a reading fault of kind `k`.
#[must_use]
pub fn right_flag(k: Kind, e: &SampleError) -> bool {
    match k {
        Kind::Crc => matches!(e, SampleError::Decode(ds18b20::Error::Crc { .. })),
        Kind::PowerOn => matches!(e, SampleError::Decode(ds18b20::Error::PowerOn) | SampleError::PowerOnJump),
        Kind::Spike | Kind::Stuck => matches!(e, SampleError::Implausible { .. }),
        Kind::Dropout | Kind::CorruptTable | Kind::Jitter => false,
    }
}

/// What happened in one faulty run.
#[derive(Clone, Debug, Default)]
pub struct FaultLog {
    /// Per kind.
    pub counts: std::collections::BTreeMap<Kind, Count>,
    /// Readings passed on, and how many the compensator refused.
    pub readings: u64,
    /// Readings refused (any reason).
    pub refused: u64,
    /// Refusals of intact readings (a false alarm).
    pub refused_intact: u64,
    /// Cycles with `TEMP_STALE`.
    pub stale_cycles: u64,
    /// Cycles with a non-finite output.
    pub non_finite: u64,
    /// A corrupted table was made active.
    pub corrupt_table_applied: bool,
    /// The table was loaded in the end.
    pub table_loaded: bool,
}

impl FaultLog {
    fn count(&mut self, k: Kind) -> &mut Count {
        self.counts.entry(k).or_default()
    }
}

/// xorshift64*: the injector's own reproducible draws.
#[derive(Clone, Debug)]
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn uniform(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

/// Turns the clean streams into faulty ones, per a [`FaultSet`].
#[derive(Clone, Debug)]
pub struct Injector {
    set: FaultSet,
    rng: Rng,
    brown_outs_done: usize,
    /// The last value delivered intact, repeated while stuck.
    last_raw: Option<i16>,
    stuck_raw: Option<i16>,
    in_stuck: Option<usize>,
}

/// What the injector did to a reading.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Injected {
    /// What reaches the compensator.
    pub delivered: Delivered,
    /// The fault applied, if any.
    pub fault: Option<Kind>,
}

impl Injector {
    /// An injector of `set`.
    #[must_use]
    pub fn new(set: FaultSet) -> Self {
        let rng = Rng::new(set.seed ^ 0xFA17);
        Self { set, rng, brown_outs_done: 0, last_raw: None, stuck_raw: None, in_stuck: None }
    }

    /// The fault set.
    #[must_use]
    pub fn set(&self) -> &FaultSet {
        &self.set
    }

    fn window(ws: &[(f64, f64)], t_s: f64) -> Option<usize> {
        ws.iter().position(|&(s, d)| t_s >= s && t_s < s + d)
    }

    /// Whether `t_s` lies in a dropout (the fast path should then go stale).
    #[must_use]
    pub fn in_dropout(&self, t_s: f64) -> bool {
        Self::window(&self.set.dropouts_s, t_s).is_some()
    }

    /// A reading of `raw` (12-bit, 1/16 °C) completed at `t_ms`.
    pub fn reading(&mut self, t_ms: u32, raw: i16) -> Injected {
        let t_s = f64::from(t_ms) * 1e-3 - self.set.takeoff_s;
        let intact = |r: i16| encode_scratchpad(r, Resolution::Bits12, 0x10 - (r.to_le_bytes()[0] & 0x0F));
        if t_s < 0.0 {
            return Injected { delivered: Delivered::Scratchpad(intact(raw)), fault: None };
        }
        if Self::window(&self.set.dropouts_s, t_s).is_some() {
            return Injected { delivered: Delivered::Nothing, fault: Some(Kind::Dropout) };
        }
        if self.brown_outs_done < self.set.brown_outs_s.len() && t_s >= self.set.brown_outs_s[self.brown_outs_done] {
            self.brown_outs_done += 1;
            // Power-on scratchpad: 0550h, the EEPROM config, byte 6 = 0Ch, valid CRC.
            let mut sp = encode_scratchpad(POWER_ON_RAW, Resolution::Bits12, 0x0C);
            sp[8] = ds18b20::crc8(&sp[..8]);
            return Injected { delivered: Delivered::Scratchpad(sp), fault: Some(Kind::PowerOn) };
        }
        match Self::window(&self.set.stuck_s, t_s) {
            Some(i) => {
                if self.in_stuck != Some(i) {
                    self.in_stuck = Some(i);
                    self.stuck_raw = self.last_raw.or(Some(raw));
                }
                let r = self.stuck_raw.unwrap_or(raw);
                return Injected { delivered: Delivered::Scratchpad(intact(r)), fault: Some(Kind::Stuck) };
            }
            None => self.in_stuck = None,
        }
        self.last_raw = Some(raw);
        if self.set.spike_rate > 0.0 && self.rng.uniform() < self.set.spike_rate {
            let sign = if self.rng.below(2) == 0 { 1.0 } else { -1.0 };
            let r = raw.saturating_add((sign * self.set.spike_c * 16.0).round() as i16);
            return Injected { delivered: Delivered::Scratchpad(intact(r)), fault: Some(Kind::Spike) };
        }
        let mut sp = intact(raw);
        if self.set.crc_error_rate > 0.0 && self.rng.uniform() < self.set.crc_error_rate {
            let bit = self.rng.below(72) as usize;
            sp[bit / 8] ^= 1 << (bit % 8);
            return Injected { delivered: Delivered::Scratchpad(sp), fault: Some(Kind::Crc) };
        }
        Injected { delivered: Delivered::Scratchpad(sp), fault: None }
    }

    /// The cycle length the firmware measures for a true cycle of `dt_ticks`.
    pub fn cycle_ticks(&mut self, dt_ticks: u32) -> (u32, bool) {
        let j = self.set.imu_jitter_us;
        if j == 0 {
            return (dt_ticks, false);
        }
        let off = self.rng.below(2 * u64::from(j) + 1) as i64 - i64::from(j);
        (u32::try_from((i64::from(dt_ticks) + off).max(0)).unwrap_or(0), true)
    }

    /// The byte strings offered to the table loader, in order: a corrupted copy first
    /// when configured, then the intact bytes.
    #[must_use]
    pub fn table_loads(&self, good: &[u8]) -> Vec<(Vec<u8>, bool)> {
        let mut v = Vec::new();
        if let Some((i, x)) = self.set.corrupt_table {
            let mut bad = good.to_vec();
            let i = i % bad.len();
            bad[i] ^= if x == 0 { 0x01 } else { x };
            v.push((bad, true));
        }
        v.push((good.to_vec(), false));
        v
    }
}

/// A compensation that runs the faulty streams into one [`ThermalCompensator`] (x, y,
/// z, each with its own sensor stream) and logs.
pub struct FaultyCompensation<C: ThermalCompensator> {
    comp: C,
    injs: [Injector; 3],
    log: Rc<RefCell<FaultLog>>,
    /// Time of the last reading offered, s, for the dropout bookkeeping.
    t_s: f64,
    /// Per axis and window: counted injected / flagged.
    dropout_seen: [Vec<bool>; 3],
    dropout_flagged: [Vec<bool>; 3],
    stuck_seen: [Vec<bool>; 3],
    stuck_flagged: [Vec<bool>; 3],
    jitter: Injector,
}

/// Refusals this long after a stuck window count for it (the jump back to the truth).
const STUCK_RELEASE_S: f64 = 10.0;

impl<C: ThermalCompensator> FaultyCompensation<C> {
    /// Load the 3-axis table's bytes (a corrupted copy first if configured) and return the
    /// compensation and its shared log.
    #[must_use]
    pub fn new(mut comp: C, set: &FaultSet, table: &[u8]) -> (Self, Rc<RefCell<FaultLog>>) {
        let injs: [Injector; 3] = core::array::from_fn(|i| {
            Injector::new(FaultSet { seed: set.seed.wrapping_add(i as u64 * 0x1000), ..set.clone() })
        });
        let mut log = FaultLog { table_loaded: true, ..FaultLog::default() };
        let good = Table::decode(table).ok();
        for (offered, corrupted) in injs[0].table_loads(table) {
            let r = comp.load_table(&offered);
            if corrupted {
                let c = log.count(Kind::CorruptTable);
                c.injected += 1;
                if r.is_err() {
                    c.flagged += 1;
                } else {
                    log.corrupt_table_applied = true;
                }
            }
        }
        log.table_loaded &= comp.table().is_some();
        // Never a corrupted table: what is active is exactly the intact one.
        if comp.table().cloned() != good {
            log.corrupt_table_applied = true;
        }
        let windows = |w: &[(f64, f64)]| -> [Vec<bool>; 3] { core::array::from_fn(|_| vec![false; w.len()]) };
        let log = Rc::new(RefCell::new(log));
        let me = Self {
            comp,
            log: Rc::clone(&log),
            t_s: 0.0,
            dropout_seen: windows(&set.dropouts_s),
            dropout_flagged: windows(&set.dropouts_s),
            stuck_seen: windows(&set.stuck_s),
            stuck_flagged: windows(&set.stuck_s),
            jitter: Injector::new(FaultSet { seed: set.seed ^ 0x5EED, ..set.clone() }),
            injs,
        };
        (me, log)
    }

    fn reading(&mut self, axis: usize, t_ms: u32, raw: i16) {
        let t_s = f64::from(t_ms) * 1e-3 - self.injs[axis].set.takeoff_s;
        let got = self.injs[axis].reading(t_ms, raw);
        let set = &self.injs[axis].set;
        let mut log = self.log.borrow_mut();
        match got.fault {
            Some(Kind::Dropout) => {
                if let Some(i) = Injector::window(&set.dropouts_s, t_s) {
                    if !self.dropout_seen[axis][i] {
                        self.dropout_seen[axis][i] = true;
                        log.count(Kind::Dropout).injected += 1;
                    }
                }
            }
            Some(Kind::Stuck) => {
                if let Some(i) = Injector::window(&set.stuck_s, t_s) {
                    if !self.stuck_seen[axis][i] {
                        self.stuck_seen[axis][i] = true;
                        log.count(Kind::Stuck).injected += 1;
                    }
                }
            }
            Some(k) => log.count(k).injected += 1,
            None => {}
        }
        let Delivered::Scratchpad(sp) = got.delivered else { return };
        log.readings += 1;
        if let Err(e) = self.comp.on_scratchpad(axis, t_ms, &sp) {
            log.refused += 1;
            // A stuck window is flagged if a reading in it, or the jump back within
            // STUCK_RELEASE_S after it, is refused as implausible.
            let stuck = set.stuck_s.iter().position(|&(s, d)| t_s >= s && t_s < s + d + STUCK_RELEASE_S);
            match (got.fault, stuck) {
                (Some(Kind::Stuck) | None, Some(i)) => {
                    if !right_flag(Kind::Stuck, &e) {
                        log.count(Kind::Stuck).wrong += 1;
                    } else if !self.stuck_flagged[axis][i] {
                        self.stuck_flagged[axis][i] = true;
                        log.count(Kind::Stuck).flagged += 1;
                    }
                }
                (Some(k), _) if right_flag(k, &e) => log.count(k).flagged += 1,
                (Some(k), _) => log.count(k).wrong += 1,
                (None, None) => log.refused_intact += 1,
            }
        }
    }
}

impl<C: ThermalCompensator> AccelCompensation for FaultyCompensation<C> {
    fn on_temperature(&mut self, t_ms: u32, raw: i16) {
        self.on_temperatures(t_ms, [raw; 3]);
    }

    fn on_temperatures(&mut self, t_ms: u32, raw: [i16; 3]) {
        self.t_s = f64::from(t_ms) * 1e-3 - self.jitter.set.takeoff_s;
        for (axis, r) in raw.into_iter().enumerate() {
            self.reading(axis, t_ms, r);
        }
    }

    fn compensate(&mut self, pulses: [i32; 3], dt_ticks: u32, _truth: &[(f64, f64); 3]) -> Vector3<f64> {
        // One timer for the IMU: the same (possibly jittered) cycle length for every axis.
        let (ticks, jittered) = if self.t_s >= 0.0 { self.jitter.cycle_ticks(dt_ticks) } else { (dt_ticks, false) };
        let mut log = self.log.borrow_mut();
        if jittered {
            log.count(Kind::Jitter).injected += 1;
        }
        let (v, status) = self.comp.cycle(pulses, ticks);
        if status.contains(Status::TEMP_STALE) {
            log.stale_cycles += 1;
            // One status for the IMU: a window is flagged when its axis's sensor is in a
            // dropout while the compensator reports stale.
            for axis in 0..3 {
                if let Some(i) = Injector::window(&self.injs[axis].set.dropouts_s, self.t_s) {
                    if !self.dropout_flagged[axis][i] {
                        self.dropout_flagged[axis][i] = true;
                        log.count(Kind::Dropout).flagged += 1;
                    }
                }
            }
        }
        let mut dv = Vector3::zeros();
        for axis in 0..3 {
            if !v[axis].is_finite() {
                log.non_finite += 1;
            }
            dv[axis] = f64::from(v[axis]);
        }
        dv
    }
}

/// What a row flies in place of the real compensation: the fault test's deliberately
/// broken compensations, which show that [`check`] can fail, live in that test.
#[derive(Clone, Copy, Debug)]
pub struct Replacement {
    /// The compensator, fresh.
    pub compensator: fn() -> Box<dyn ThermalCompensator>,
    /// The per-axis tables it loads (x, y, z), made from the real ones.
    pub tables: fn([&Table; 3]) -> anyhow::Result<[Table; 3]>,
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

fn encode(t: &Table) -> anyhow::Result<Vec<u8>> {
    crate::calibrate::fit::encode(t).map_err(|e| anyhow::anyhow!("table: {e}"))
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
) -> anyhow::Result<FaultReport> {
    // One 3-axis table for the IMU's compensator, as the firmware flies it.
    let m = sc.imu.accel.carried_misalignment();
    let good = encode(&crate::navigate::calib::table3_with(tables, m)?)?;
    let (clean, clean_log) = FaultyCompensation::new(imu_compensator(), &FaultSet::none(), &good);
    anyhow::ensure!(clean_log.borrow().table_loaded, "a table was refused");
    let mut variants = vec![
        Variant { name: "oracle".into(), comp: Box::new(OracleCompensation::carrying(sc.imu.accel.triad_inverse())) },
        Variant { name: "clean".into(), comp: Box::new(clean) },
        Variant { name: "simple".into(), comp: Box::new(TableCompensation::with_misalignment(simple, m)?) },
    ];
    let mut logs = Vec::new();
    for r in rows {
        let set = FaultSet { takeoff_s: sc.align_steps() as f64 / sc.imu_rate_hz, ..r.set.clone() };
        let log = if let Some(rep) = r.replaced {
            let bt = (rep.tables)(tables)?;
            for t in &bt {
                t.validate().map_err(|e| anyhow::anyhow!("{}: replaced table invalid: {e}", r.name))?;
            }
            let bytes = encode(&crate::navigate::calib::table3_with([&bt[0], &bt[1], &bt[2]], m)?)?;
            let (c, log) = FaultyCompensation::new((rep.compensator)(), &set, &bytes);
            variants.push(Variant { name: r.name.clone(), comp: Box::new(c) });
            log
        } else {
            let (c, log) = FaultyCompensation::new(imu_compensator(), &set, &good);
            variants.push(Variant { name: r.name.clone(), comp: Box::new(c) });
            log
        };
        logs.push(log);
    }
    let units = crate::navigate::units();
    let res = run::fly(sc, &mut crate::navigate::truths(&units), variants)?;
    anyhow::ensure!(clean_log.borrow().refused == 0, "the fault-free twin refused readings");
    let growth = |a: &run::Track, b: &run::Track| -> f64 {
        let d = |x: &[f64], y: &[f64]| -> Vec<f64> { x.iter().zip(y).map(|(p, q)| p - q).collect() };
        let tr = run::Track { dn: d(&a.dn, &b.dn), de: d(&a.de, &b.de), vn: d(&a.vn, &b.vn), ve: d(&a.ve, &b.ve) };
        Figures::of(&res.t, &tr).cep_nmi_per_h
    };
    let (oracle, clean) = (&res.tracks[0], &res.tracks[1]);
    let clean_thermal = growth(clean, oracle);
    let simple_thermal = growth(&res.tracks[2], oracle);
    anyhow::ensure!(
        clean_thermal > 1e-9 && simple_thermal > 1e-9,
        "thermal-only CEP rates twin {clean_thermal}, simple {simple_thermal}: nothing to compare with"
    );
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
    use qfa_thermal::model::{AxisModel, BiasGrid, Extensions};

    /// A 3-axis table, each axis JB-KT8 #1-like.
    fn table_bytes() -> Vec<u8> {
        let a = AxisModel {
            scale: crate::simulate::truth::Truth::jb_kt8(1).scale,
            bias: BiasGrid::single_valued(-60.0, 65.0, &[1e-4, 1.5e-4, 3e-4]),
            rate_limit_c_per_min: 2.0,
            ext: Extensions::default(),
        };
        let t = crate::calibrate::fit::table_of_axes(qfa_thermal::Input::PulseCounts, [a.clone(), a.clone(), a])
            .expect("a valid table");
        crate::calibrate::fit::encode(&t).expect("encodes")
    }

    fn comps() -> ImuCompensator {
        imu_compensator()
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
