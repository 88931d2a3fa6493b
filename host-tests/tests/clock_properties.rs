//! Property tests on an unwrapped clock.
//!
//! Each history is timed by a `u64` ms clock that runs for months (gaps up to 2³¹ − 1 ms,
//! several 2³² ms wraps, a random start) and is fed to the compensator as the wrapped `u32`
//! it takes (`t as u32`). One or three temperature streams (`Compensator<3, 32, 1>` and
//! `<3, 32, 3>`); per sensor, random dropouts (its reads fail and are reported with
//! `on_missed_reading`, the board's recipe), random readings (mostly plausible steps, some
//! jumps, some 0550h, some values no DS18B20 gives, raw or through a scratchpad), random
//! missed readings and random table reloads (good tables and one with a bad CRC).
//!
//! The IMU runs all the time: the harness runs a fast-path cycle right before every
//! slow-path call (with the ticks since the previous cycle) and up to three inside every
//! wait, and checks each one. What a cycle must show comes from a model kept in `u64`
//! from the compensator's return values only (which readings were accepted, when), never
//! from its internal state.
//!
//! `cargo test -p host-tests --test clock_properties`: 5.0 s for the whole file in the dev
//! profile on the shared 2-core machine (the tests run in parallel; 512 histories per
//! property, about 10 ms wraps per history). `-- --ignored` runs the two that pin the
//! staleness lag (a root-crate bug, see `staleness_strict_three_streams`).
//!
//! Each property was seen to fail on a broken crate (not committed): the stale flag from a
//! wrapped difference of timestamps (`staleness_…_three_streams`: no TEMP_STALE at
//! 2³² ms + 400 ms after a stream's last reading), the fast path's tick count switched off
//! (both staleness properties), `clone` with a fresh shared set (both clone properties),
//! 0550h taken after any gap (`0550h accepted at 4294967296 ms after (0, 1359)`), a rejection
//! counted as a good sample (both staleness properties).

use std::sync::OnceLock;

use host_tests::scenarios;
use proptest::prelude::*;
use proptest::strategy::ValueTree;
use proptest::test_runner::{Config as RunnerConfig, RngSeed, TestRunner};
use qfa_thermal::ds18b20::{encode_scratchpad, Resolution, POWER_ON_RAW, RAW_RANGE};
use qfa_thermal::model::Evaluation;
use qfa_thermal::rate::Estimate;
use qfa_thermal::{Compensator, Config, Extensions, Input, SampleError, Status};

/// The slow path must hear of every sensor at least once every 2³¹ ms (`on_missed_reading`
/// docs): the harness keeps to it by reporting a missed read when a wait would break it.
const HEARD_EVERY_MS: u64 = i32::MAX as u64;
const PULSES: [i32; 3] = [800, -7, 3];
const SAMPLES: [i32; 3] = [1 << 20, 5, -9];

/// The stale limit of `Config::default()` in ms, from its documented fields
/// (`stale_after_ticks` × `tick_s`): 3 000.
fn stale_ms() -> u64 {
    let c = Config::default();
    (f64::from(c.stale_after_ticks) * f64::from(c.tick_s) * 1e3).round() as u64
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    /// The case temperature moves by a plausible step, 1/16 °C.
    Step(i8),
    /// The case temperature jumps (a real step: used once confirmed).
    Jump(i16),
    /// The case temperature moves to 85 °C + this (so 0550h can be a real continuation).
    Near85(i8),
    /// A brown-out: the sensor reports 0550h whatever the case temperature.
    PowerOn,
    /// A raw value, often one no DS18B20 reports.
    Garbage(i16),
}

#[derive(Clone, Copy, Debug)]
enum Ev {
    /// Time passes; `cycles` IMU cycles are checked at even points inside the wait.
    Wait { ms: u64, cycles: u8, samples: bool },
    /// A reading of `sensor`, raw (`byte6 = None`) or as a scratchpad with that byte 6.
    Read { sensor: usize, kind: Kind, byte6: Option<u8> },
    /// A read of `sensor` failed (bus, CRC): `on_missed_reading`.
    Missed { sensor: usize },
    /// `sensor` is gone for `ms`: its reads in that time fail and are reported as missed.
    Drop { sensor: usize, ms: u64 },
    /// Load table 0 or 1 (valid), or 2 (a bad CRC: refused).
    Reload { table: usize },
    /// Time passes until `sensor`'s latest accepted reading is `wraps` whole 2³² ms wraps
    /// plus `offset_ms` old: where a wrapped difference of timestamps reads "fresh" again.
    WrapAlias { sensor: usize, wraps: u64, offset_ms: i64 },
    /// The board's round: `ms` pass (checked at half and at the end), then every sensor is
    /// read (a plausible step each), in order.
    Round { ms: u64, steps: [i8; 3] },
}

#[derive(Clone, Debug)]
struct History {
    start_ms: u64,
    input: Input,
    with_table: bool,
    events: Vec<Ev>,
}

fn gap() -> impl Strategy<Value = u64> {
    prop_oneof![
        6 => 1u64..1_500,
        2 => 1_500u64..8_000,
        1 => 8_000u64..3_600_000,
        4 => 3_600_000u64..=HEARD_EVERY_MS,
    ]
}

fn kind() -> impl Strategy<Value = Kind> {
    prop_oneof![
        12 => (-3i8..=3).prop_map(Kind::Step),
        2 => (-400i16..=400).prop_map(Kind::Jump),
        1 => (-20i8..=20).prop_map(Kind::Near85),
        3 => Just(Kind::PowerOn),
        1 => any::<i16>().prop_map(Kind::Garbage),
    ]
}

fn event(sensors: usize) -> impl Strategy<Value = Ev> {
    // 0Ch is the genuine power-on byte 6 (the decoder refuses 0550h with it); 10h is what
    // a clone part or a real 85 °C conversion shows.
    let byte6 = prop::option::of(prop_oneof![Just(0x0Cu8), Just(0x10u8), any::<u8>()]);
    prop_oneof![
        8 => (gap(), 0u8..=3, any::<bool>()).prop_map(|(ms, cycles, samples)| Ev::Wait { ms, cycles, samples }),
        10 => (0..sensors, kind(), byte6).prop_map(|(sensor, kind, byte6)| Ev::Read { sensor, kind, byte6 }),
        1 => (0..sensors).prop_map(|sensor| Ev::Missed { sensor }),
        1 => (0..sensors, gap()).prop_map(|(sensor, ms)| Ev::Drop { sensor, ms }),
        1 => (0usize..3).prop_map(|table| Ev::Reload { table }),
        1 => (0..sensors, 1u64..=2, -5_000i64..5_000)
            .prop_map(|(sensor, wraps, offset_ms)| Ev::WrapAlias { sensor, wraps, offset_ms }),
        8 => (200u64..1_500, any::<[i8; 3]>()).prop_map(|(ms, steps)| Ev::Round { ms, steps: steps.map(|d| d % 3) }),
    ]
}

fn history(sensors: usize) -> impl Strategy<Value = History> {
    let input = prop_oneof![Just(Input::PulseCounts), Just(Input::Samples)];
    (0u64..1 << 34, input, any::<bool>(), prop::collection::vec(event(sensors), 50..300))
        .prop_map(|(start_ms, input, with_table, events)| History { start_ms, input, with_table, events })
}

/// Encoded tables for `input`: JB-KT8 #1 with no slot; #3 with every slot and a
/// misalignment; the first with one payload byte flipped (a CRC failure).
fn tables(input: Input) -> &'static [Vec<u8>; 3] {
    static PULSES_T: OnceLock<[Vec<u8>; 3]> = OnceLock::new();
    static SAMPLES_T: OnceLock<[Vec<u8>; 3]> = OnceLock::new();
    let make = || {
        let all = Extensions {
            sensor_lag: Some(scenarios::LAG),
            bias_branch_hysteresis: Some(scenarios::PLAY),
            bias_creep: Some(scenarios::CREEP),
        };
        let enc = |t: qfa_thermal::Table| {
            let t = if input == Input::Samples { scenarios::as_samples(&t) } else { t };
            let mut buf = [0u8; qfa_thermal::table::MAX_TABLE_BYTES];
            t.encode(&mut buf).expect("valid table").to_vec()
        };
        let a = enc(scenarios::table(0, [Extensions::default(); 3], None));
        let b = enc(scenarios::table(2, [all; 3], Some(scenarios::MISALIGN)));
        let mut bad = a.clone();
        bad[qfa_thermal::table::HEADER_LEN + 5] ^= 0x20;
        [a, b, bad]
    };
    match input {
        Input::PulseCounts => PULSES_T.get_or_init(make),
        Input::Samples => SAMPLES_T.get_or_init(make),
    }
}

/// Everything a caller can observe, compared bit for bit between a compensator and its clone.
#[derive(Clone, Debug, PartialEq)]
enum Obs {
    Slow(Result<Status, SampleError>),
    Table(Result<(), qfa_thermal::table::Error>),
    Cycle([u32; 3], Status),
    State(Vec<Option<Estimate>>, [Evaluation; 3], Status),
}

/// How often each situation the properties speak of came up (so no property is vacuous).
#[derive(Clone, Copy, Debug, Default)]
struct Coverage {
    cycles: u64,
    /// Every stream fresh: TEMP_STALE must be clear.
    fresh: u64,
    /// A stream older than the limit where the slow path or the tick counter knows it.
    must_stale: u64,
    /// A stream older than the limit that neither knows yet (see `lag` below).
    lag_window: u64,
    /// No accepted reading for longer than the limit: only the fast path's tick counter knows.
    only_ticks_know: u64,
    wraps: u64,
    power_on_ok: u64,
    power_on_refused_after_gap_or_jump: u64,
    reloads: u64,
    keep_alives: u64,
    wrap_aliases: u64,
}

/// The model: kept in u64 from what the compensator returned, never from its state.
#[derive(Clone, Debug)]
struct Model<const S: usize> {
    now: u64,
    stale: u64,
    cfg: Config,
    /// Time of the latest slow-path call that carried a time.
    last_slow: Option<u64>,
    /// Per stream: time and raw value of the latest accepted reading.
    accepted: [Option<(u64, i16)>; S],
    /// Per stream: its latest slow-path event was a rejection or a missed read.
    invalid: [bool; S],
    /// Per stream: readings delivered since its last missed read (time, raw), newest last.
    run: [Vec<(u64, i16)>; S],
    truth: [i16; S],
    down_until: [u64; S],
    last_cycle: u64,
    has_table: bool,
    input: Input,
    /// Check the properties (off for the clone comparison, which checks equality only).
    check: bool,
    /// Also check the per-stream rule without the slow-path lag (see `lag` tests).
    strict: bool,
    cov: Coverage,
}

// With the misalignment stage: the tables have a matrix.
type Comp<const S: usize> = Compensator<3, 32, S, qfa_thermal::Table, 3>;

impl<const S: usize> Model<S> {
    fn new(h: &History, check: bool, strict: bool) -> (Self, Comp<S>) {
        let cfg = match h.input {
            Input::Samples => scenarios::samples_config(Config::default()),
            Input::PulseCounts => Config::default(),
        };
        let mut c = Comp::<S>::new(cfg).expect("valid config");
        if h.with_table {
            c.load_table(&tables(h.input)[0]).expect("valid table");
        }
        let m = Self {
            now: h.start_ms,
            stale: stale_ms(),
            cfg,
            last_slow: None,
            accepted: [None; S],
            invalid: [false; S],
            run: core::array::from_fn(|_| Vec::new()),
            truth: [352; S],
            down_until: [0; S],
            last_cycle: h.start_ms,
            has_table: h.with_table,
            input: h.input,
            check,
            strict,
            cov: Coverage::default(),
        };
        (m, c)
    }

    fn t32(&self) -> u32 {
        // The wrapped u32 ms the firmware's clock gives.
        self.now as u32
    }

    fn advance_to(&mut self, t: u64) {
        if t >> 32 != self.now >> 32 {
            self.cov.wraps += t / (1 << 32) - self.now / (1 << 32);
        }
        self.now = t;
    }

    /// One IMU cycle at `now`, with the ticks (µs) since the previous one, and its checks.
    fn cycle(&mut self, c: &mut Comp<S>, samples: bool, obs: &mut Vec<Obs>) -> Result<(), TestCaseError> {
        let dt_ticks = ((self.now - self.last_cycle) * 1_000).min(u64::from(u32::MAX)) as u32;
        self.last_cycle = self.now;
        // m/s² from samples, m/s from pulses: only their bits and finiteness matter here.
        let (values, st) = if samples {
            let o = c.cycle_samples(SAMPLES, dt_ticks);
            (o.accel_mps2, o.status)
        } else {
            let o = c.cycle(PULSES, dt_ticks);
            (o.dv_mps, o.status)
        };
        obs.push(Obs::Cycle(values.map(f32::to_bits), st));
        self.cov.cycles += 1;
        if !self.check {
            return Ok(());
        }
        prop_assert!(values.iter().all(|v| v.is_finite()), "{values:?} {st:?}");
        let age = |a: &Option<(u64, i16)>| a.map(|(t, _)| self.now - t);
        // Fresh: every stream has a reading at most the limit old.
        let fresh = self.accepted.iter().all(|a| age(a).is_some_and(|x| x <= self.stale));
        // What the compensator can know: the slow path's ages as of its latest call, and
        // the fast path's ticks since the latest accepted reading of any stream.
        let slow_knows = self.accepted.iter().any(|a| match (a, self.last_slow) {
            (None, _) => true,
            (Some((t, _)), Some(l)) => l - t > self.stale,
            (Some(_), None) => false,
        });
        let newest = self.accepted.iter().flatten().map(|(t, _)| *t).max();
        let ticks_know = newest.is_none_or(|g| self.now - g > self.stale);
        let must = slow_knows || ticks_know;
        let stale = st.contains(Status::TEMP_STALE);
        if fresh {
            self.cov.fresh += 1;
            prop_assert!(!stale, "every stream fresh but TEMP_STALE at {} ms: {st:?} {:?}", self.now, self.accepted);
        }
        if must {
            self.cov.must_stale += 1;
            self.cov.only_ticks_know += u64::from(ticks_know && !slow_knows);
            prop_assert!(stale, "a stream is stale and the compensator knows it, yet no TEMP_STALE at {} ms", self.now);
        } else if !fresh {
            self.cov.lag_window += 1;
            if self.strict {
                prop_assert!(
                    stale,
                    "stream older than {} ms without TEMP_STALE at {} ms (last slow call {:?}): {:?}",
                    self.stale,
                    self.now,
                    self.last_slow,
                    self.accepted
                );
            }
        }
        // The other flags this history decides exactly.
        prop_assert_eq!(st.contains(Status::TEMP_INVALID), self.invalid.iter().any(|&b| b), "{:?}", st);
        prop_assert_eq!(st.contains(Status::NO_TABLE), !self.has_table);
        prop_assert_eq!(st.contains(Status::WRONG_INPUT), samples != (self.input == Input::Samples));
        prop_assert!(!st.contains(Status::NO_COUNTER_BASE));
        Ok(())
    }

    /// A slow-path call at `now`: the IMU cycle right before it, the call, the model update.
    fn slow(
        &mut self,
        c: &mut Comp<S>,
        obs: &mut Vec<Obs>,
        call: impl FnOnce(&mut Comp<S>, u32) -> Result<Status, SampleError>,
    ) -> Result<Result<Status, SampleError>, TestCaseError> {
        self.cycle(c, false, obs)?;
        let r = call(c, self.t32());
        self.last_slow = Some(self.now);
        obs.push(Obs::Slow(r));
        Ok(r)
    }

    fn missed(&mut self, c: &mut Comp<S>, sensor: usize, obs: &mut Vec<Obs>) -> Result<(), TestCaseError> {
        let r = self.slow(c, obs, |c, t| c.on_missed_reading(sensor, t))?;
        if self.check {
            prop_assert_eq!(r, Err(SampleError::Missed));
        }
        self.invalid[sensor] = true;
        self.run[sensor].clear();
        Ok(())
    }

    /// Time passes by `ms` with `cycles` checked IMU cycles inside; if the slow path would
    /// go unheard for longer than 2³¹ ms, a read of sensor 0 fails first (its precondition).
    fn wait(
        &mut self,
        c: &mut Comp<S>,
        ms: u64,
        cycles: u8,
        samples: bool,
        obs: &mut Vec<Obs>,
    ) -> Result<(), TestCaseError> {
        let start = self.now;
        let n = u64::from(cycles);
        // The checked cycles at even points of the wait; with none, time just passes (the
        // next cycle gets all of its ticks).
        let points: Vec<(u64, bool)> =
            if n == 0 { vec![(start + ms, false)] } else { (1..=n).map(|k| (start + ms * k / n, true)).collect() };
        for (p, checked) in points {
            while p - self.last_slow.unwrap_or(p) > HEARD_EVERY_MS {
                let t = self.last_slow.unwrap_or(p) + HEARD_EVERY_MS;
                self.advance_to(t);
                self.cov.keep_alives += 1;
                self.missed(c, 0, obs)?;
            }
            self.advance_to(p);
            if checked {
                self.cycle(c, samples, obs)?;
            }
        }
        Ok(())
    }

    /// Readings `a` then `b`, `gap` ms apart, are consistent in the documented sense (later
    /// in time, and within `max_step_raw` plus `max_slew_raw_per_min` over the gap, the
    /// slew counted over at most the stale limit).
    fn consistent(&self, a: (u64, i16), b: (u64, i16)) -> bool {
        let gap = b.0.saturating_sub(a.0);
        let allowed = i64::from(self.cfg.max_step_raw)
            + i64::from(self.cfg.max_slew_raw_per_min) * gap.min(self.stale) as i64 / 60_000;
        gap > 0 && (i64::from(b.1) - i64::from(a.1)).abs() <= allowed
    }

    fn read(
        &mut self,
        c: &mut Comp<S>,
        s: usize,
        kind: Kind,
        byte6: Option<u8>,
        obs: &mut Vec<Obs>,
    ) -> Result<(), TestCaseError> {
        if self.now < self.down_until[s] {
            return self.missed(c, s, obs);
        }
        let clamp = |x: i32| x.clamp(i32::from(*RAW_RANGE.start()), i32::from(*RAW_RANGE.end())) as i16;
        let raw = match kind {
            Kind::Step(d) => {
                self.truth[s] = clamp(i32::from(self.truth[s]) + i32::from(d));
                self.truth[s]
            }
            Kind::Jump(d) => {
                self.truth[s] = clamp(i32::from(self.truth[s]) + i32::from(d));
                self.truth[s]
            }
            Kind::Near85(d) => {
                self.truth[s] = POWER_ON_RAW + i16::from(d);
                self.truth[s]
            }
            Kind::PowerOn => POWER_ON_RAW,
            Kind::Garbage(x) => x,
        };
        let r = match byte6 {
            None => self.slow(c, obs, |c, t| c.on_raw(s, t, raw))?,
            Some(b6) => {
                let sp = encode_scratchpad(raw, Resolution::Bits12, b6);
                self.slow(c, obs, |c, t| c.on_scratchpad(s, t, &sp))?
            }
        };
        let decoded = !matches!(r, Err(SampleError::Decode(_)));
        let this = (self.now, raw);
        if raw == POWER_ON_RAW {
            // The rule for 0550h: taken after a gap longer than the stale limit, or as a jump
            // larger than max_step_raw from the last accepted reading (or as the first), only
            // once `confirm_samples` consistent readings, this one the last, came in a row.
            let prev = self.accepted[s];
            let continuation = prev.is_some_and(|(t, r0)| {
                self.now - t <= self.stale
                    && (i32::from(POWER_ON_RAW) - i32::from(r0)).unsigned_abs()
                        <= u32::from(self.cfg.max_step_raw.unsigned_abs())
            });
            let need = usize::from(self.cfg.confirm_samples);
            let run = &self.run[s];
            let confirmed = run.len() + 1 >= need && {
                let mut chain: Vec<(u64, i16)> = run[run.len() + 1 - need..].to_vec();
                chain.push(this);
                chain.windows(2).all(|w| self.consistent(w[0], w[1]))
            };
            if r.is_ok() {
                self.cov.power_on_ok += 1;
                if self.check {
                    prop_assert!(
                        continuation || confirmed,
                        "0550h accepted at {} ms after {:?} (run {:?})",
                        self.now,
                        prev,
                        run
                    );
                }
            } else if !continuation {
                self.cov.power_on_refused_after_gap_or_jump += 1;
            }
        }
        match r {
            Ok(_) => {
                self.accepted[s] = Some(this);
                self.invalid[s] = false;
            }
            Err(_) => self.invalid[s] = true,
        }
        if decoded {
            self.run[s].push(this);
        } else {
            self.run[s].clear();
        }
        Ok(())
    }

    fn apply(&mut self, c: &mut Comp<S>, ev: Ev, obs: &mut Vec<Obs>) -> Result<(), TestCaseError> {
        match ev {
            Ev::Wait { ms, cycles, samples } => self.wait(c, ms, cycles, samples, obs)?,
            Ev::Read { sensor, kind, byte6 } => self.read(c, sensor, kind, byte6, obs)?,
            Ev::Missed { sensor } => self.missed(c, sensor, obs)?,
            Ev::Drop { sensor, ms } => self.down_until[sensor] = self.now + ms,
            Ev::WrapAlias { sensor, wraps, offset_ms } => {
                let last = self.accepted[sensor].map_or(self.now, |(t, _)| t);
                let target = (last + (wraps << 32)).saturating_add_signed(offset_ms);
                if target > self.now {
                    self.cov.wrap_aliases += 1;
                    self.wait(c, target - self.now, 1, false, obs)?;
                }
            }
            Ev::Round { ms, steps } => {
                self.wait(c, ms, 2, false, obs)?;
                for (s, d) in steps.into_iter().enumerate().take(S) {
                    self.read(c, s, Kind::Step(d), None, obs)?;
                }
            }
            Ev::Reload { table } => {
                let r = c.load_table(&tables(self.input)[table]);
                if self.check {
                    prop_assert_eq!(r.is_ok(), table != 2, "{:?}", r);
                }
                if r.is_ok() {
                    self.has_table = true;
                    self.cov.reloads += 1;
                }
                obs.push(Obs::Table(r));
            }
        }
        let est = (0..S).map(|s| c.estimate_of(s)).collect();
        obs.push(Obs::State(est, *c.evaluations(), c.status()));
        Ok(())
    }
}

/// Run a history with the checks on; the coverage it reached.
fn run_checked<const S: usize>(h: &History, strict: bool) -> Result<Coverage, TestCaseError> {
    let (mut m, mut c) = Model::<S>::new(h, true, strict);
    let mut obs = Vec::new();
    for &ev in &h.events {
        m.apply(&mut c, ev, &mut obs)?;
        obs.clear();
    }
    // A final check well after the last event: whatever happened, a long silence is stale.
    m.wait(&mut c, 3_600_000, 1, false, &mut obs)?;
    Ok(m.cov)
}

/// Run `h` up to event `at`, clone, then drive both with the rest: every observation equal.
fn run_cloned<const S: usize>(h: &History, at: usize) -> Result<(), TestCaseError> {
    let (mut m, mut c) = Model::<S>::new(h, false, false);
    let at = at % (h.events.len() + 1);
    let mut sink = Vec::new();
    for &ev in &h.events[..at] {
        m.apply(&mut c, ev, &mut sink)?;
    }
    let mut c2 = c.clone();
    let mut m2 = m.clone();
    for (i, &ev) in h.events[at..].iter().enumerate() {
        let (mut a, mut b) = (Vec::new(), Vec::new());
        m.apply(&mut c, ev, &mut a)?;
        m2.apply(&mut c2, ev, &mut b)?;
        prop_assert_eq!(a, b, "event {} after the clone at {}: {:?}", i, at, ev);
    }
    // And the fast path alone, with no slow-path call in between.
    for _ in 0..3 {
        prop_assert_eq!(c.cycle_samples(SAMPLES, 2_500), c2.cycle_samples(SAMPLES, 2_500));
        prop_assert_eq!(c.cycle(PULSES, 2_500), c2.cycle(PULSES, 2_500));
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    /// Three streams: TEMP_STALE whenever the compensator can know a stream is older than
    /// the limit (its slow path saw it at its latest call, or no stream has had an accepted
    /// reading for longer than the limit, which only the fast path's tick count knows); never
    /// when every stream is fresh. TEMP_INVALID exactly while a stream's latest event was a
    /// rejection or a missed read; NO_TABLE exactly before the first table; WRONG_INPUT
    /// exactly on the path of the other input; never NO_COUNTER_BASE. 0550h only by the rule.
    #[test]
    fn staleness_on_an_unwrapped_clock_three_streams(h in history(3)) {
        run_checked::<3>(&h, false)?;
    }

    /// One stream: the same, and here the strict rule holds too (every true age above the
    /// limit is flagged on the very next cycle): the one stream's age is the tick count.
    #[test]
    fn staleness_on_an_unwrapped_clock_one_stream_strict(h in history(1)) {
        run_checked::<1>(&h, true)?;
    }

    /// A clone at any point of any history behaves exactly as the original from then on.
    #[test]
    fn clone_is_exact_at_every_point_three_streams(h in history(3), at in any::<usize>()) {
        run_cloned::<3>(&h, at)?;
    }

    /// As above with one stream.
    #[test]
    fn clone_is_exact_at_every_point_one_stream(h in history(1), at in any::<usize>()) {
        run_cloned::<1>(&h, at)?;
    }
}

proptest! {
    // Expected to fail until the crate is fixed: no regression file for it.
    #![proptest_config(ProptestConfig { cases: 128, failure_persistence: None, ..ProptestConfig::default() })]

    /// The documented rule without the slow-path lag: a stream whose true age exceeds the
    /// limit gives TEMP_STALE on the next cycle. It failed with three streams while the fast
    /// path's tick count restarted at any stream's accepted reading (a dead stream was then
    /// flagged up to one slow-path call interval late, `lag_dead_stream_flagged_late`);
    /// each set now carries the oldest stream's age, which starts the countdown.
    #[test]
    fn staleness_strict_three_streams(h in history(3)) {
        run_checked::<3>(&h, true)?;
    }
}

/// The smallest history that showed the lag: sensors 0 and 2 read every second, sensor 1
/// dies. At 3.5 s after its last reading, with the latest slow-path call at 3.0 s (when its
/// age, 3.0 s, was not yet above the limit), the cycle was not flagged; it must be.
#[test]
fn lag_dead_stream_flagged_late() {
    let mut c = Comp::<3>::new(Config::default()).unwrap();
    c.load_table(&tables(Input::PulseCounts)[0]).unwrap();
    // 0..=10 s: all three read every second; the IMU is checked every 0.5 s.
    for k in 0..=10u32 {
        for s in 0..3 {
            c.on_raw(s, 1_000 * k, 352).unwrap();
        }
        c.cycle(PULSES, 500_000);
        c.cycle(PULSES, 500_000);
    }
    // 11..=13 s: sensor 1 is silent, the others go on.
    for k in 11..=13u32 {
        for s in [0, 2] {
            c.on_raw(s, 1_000 * k, 352).unwrap();
        }
        if k < 13 {
            c.cycle(PULSES, 500_000);
            c.cycle(PULSES, 500_000);
        }
    }
    // 13.5 s: sensor 1 is 3.5 s old; the slow path last saw it at 3.0 s, not above the limit.
    let out = c.cycle(PULSES, 500_000);
    assert!(out.status.contains(Status::TEMP_STALE), "sensor 1 is 3.5 s old: {out:?}");
}

/// The generator reaches every situation the properties speak of, on a fixed seed: fresh
/// cycles, stale ones each compensator path knows of, the lag window, several ms wraps per
/// history, 0550h taken as a continuation and refused after a gap or as a jump, reloads, and
/// the keep-alive the precondition asks for. The seed is fixed in the runner's config: with
/// proptest's default (a random seed per run) the one-stream count of 0550h readings taken as
/// a continuation ran 17–34 over 24 seeds and a CI run once drew 10, under the bound of 11.
#[test]
fn histories_reach_every_situation() {
    let mut runner =
        TestRunner::new(RunnerConfig { cases: 64, rng_seed: RngSeed::Fixed(1), ..RunnerConfig::default() });
    let mut total = [Coverage::default(); 2];
    let mut histories = 0u64;
    for (i, sensors) in [1usize, 3].into_iter().enumerate() {
        let strategy = history(sensors);
        for _ in 0..64 {
            let h = strategy.new_tree(&mut runner).unwrap().current();
            let cov = if sensors == 1 { run_checked::<1>(&h, true) } else { run_checked::<3>(&h, false) };
            let cov = cov.unwrap_or_else(|e| panic!("{e}: {h:?}"));
            let t = &mut total[i];
            t.cycles += cov.cycles;
            t.fresh += cov.fresh;
            t.must_stale += cov.must_stale;
            t.lag_window += cov.lag_window;
            t.only_ticks_know += cov.only_ticks_know;
            t.wraps += cov.wraps;
            t.power_on_ok += cov.power_on_ok;
            t.power_on_refused_after_gap_or_jump += cov.power_on_refused_after_gap_or_jump;
            t.reloads += cov.reloads;
            t.keep_alives += cov.keep_alives;
            t.wrap_aliases += cov.wrap_aliases;
            histories += 1;
        }
    }
    println!("{histories} histories: one stream {:?}", total[0]);
    println!("three streams {:?}", total[1]);
    for t in &total {
        assert!(t.fresh > t.cycles / 20, "{t:?}");
        assert!(t.must_stale > t.cycles / 20, "{t:?}");
        assert!(t.only_ticks_know > 100, "{t:?}");
        assert!(t.wraps >= 2 * 64, "two ms wraps or more per history on average: {t:?}");
        assert!(t.power_on_ok > 10, "{t:?}");
        assert!(t.power_on_refused_after_gap_or_jump > 100, "{t:?}");
        assert!(t.reloads > 50 && t.keep_alives > 10 && t.wrap_aliases > 20, "{t:?}");
    }
    assert_eq!(total[0].lag_window, 0, "one stream: its age is the tick count");
    assert!(total[1].lag_window > 100, "three streams reach the lag window: {:?}", total[1]);
}
