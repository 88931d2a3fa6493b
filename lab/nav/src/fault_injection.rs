//! The fault injector: which faults to inject ([`FaultSet`]), the faulty reading and cycle
//! streams it makes from the clean ones ([`Injector`]), and the compensation that flies
//! them while logging every injected fault and the flag it raised ([`FaultyCompensation`]).

use std::cell::RefCell;
use std::rc::Rc;

use nalgebra::Vector3;
use qfa_thermal::compensator::{SampleError, Status};
use qfa_thermal::ds18b20::{self, encode_scratchpad, Resolution, POWER_ON_RAW};
use qfa_thermal::table::Table;

use super::faults::*;
use crate::accel::AccelCompensation;
use qfa_rng::{below, seeded, uniform, LabRng};

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

/// Turns the clean streams into faulty ones, per a [`FaultSet`].
#[derive(Clone, Debug)]
pub struct Injector {
    set: FaultSet,
    rng: LabRng,
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
    /// Injector `index` of `set` (0–2 an axis's readings, 3 the IMU cycle's jitter), drawing
    /// from its own stream of the set's seed.
    #[must_use]
    pub fn new(set: FaultSet, index: u64) -> Self {
        let rng = seeded(crate::seeds::faults(set.seed, index));
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
        if self.set.spike_rate > 0.0 && uniform(&mut self.rng) < self.set.spike_rate {
            let sign = if below(&mut self.rng, 2) == 0 { 1.0 } else { -1.0 };
            let r = raw.saturating_add((sign * self.set.spike_c * 16.0).round() as i16);
            return Injected { delivered: Delivered::Scratchpad(intact(r)), fault: Some(Kind::Spike) };
        }
        let mut sp = intact(raw);
        if self.set.crc_error_rate > 0.0 && uniform(&mut self.rng) < self.set.crc_error_rate {
            let bit = below(&mut self.rng, 72);
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
        let off = below(&mut self.rng, 2 * j as usize + 1) as i64 - i64::from(j);
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
        let injs: [Injector; 3] = core::array::from_fn(|i| Injector::new(set.clone(), i as u64));
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
            jitter: Injector::new(set.clone(), 3),
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
