//! Random field histories, run through the compensator and judged by the [`oracle`].
//!
//! A [`History`] composes what a navigation computer sees in service: power-up at any
//! temperature, at rest or ramping (rates past the table's limit included), excursions
//! past the table's grid and back, readings quantized to 1/16 °C with flicker on code
//! edges, missed readings, dead sensors, CRC errors, the DS18B20's power-on value as a
//! glitch, table loads at any moment (the same table, another one, a refused one),
//! `clone()`, and the µs clock wrapping under [`MsClock`]. [`run`] drives the public API
//! with it and counts the cycles whose status is OK while their output is further from
//! the oracle's ideal than its tolerance: `silent_wrong_cycles`.
//!
//! The history starts before power-up (up to an hour of it): the oracle's states follow it,
//! the firmware's cannot, so it must flag `MODEL_SETTLING` until they have converged.
//!
//! Faults reach the compensator as its interface sees them: a frozen or clone DS18B20
//! (a lost or refused Convert T) is an error from the driver (`ds18b20_driver`), so here a
//! missed reading or a dead stretch; a sensor that reboots reads 0550h; a bit flipped on the
//! bus fails the scratchpad's CRC. Not drawn here: the ms counter's own 49.7-day wrap and a
//! clock that restarts (`tests/clock_properties.rs` and the soak), and the interrupt
//! preempting a publication (the seqlock's unit tests and its loom model).
//!
//! The strategies shrink: a failing history reduces to a short one with few events, which
//! `tests/oracle_property.rs` prints and which becomes a named regression test there.

use proptest::prelude::*;
use qfa_thermal::ds18b20::{encode_scratchpad, Resolution, POWER_ON_RAW};
use qfa_thermal::model::{BiasGrid, BranchHysteresis, Creep, Extensions, SensorLag};
use qfa_thermal::table::Input;
use qfa_thermal::table::{Table, MAX_TABLE_BYTES};
use qfa_thermal::time::MsClock;
use qfa_thermal::{Compensator, Config, PulseOutput, Status};

use crate::oracle::{Oracle, LSB_C};
use crate::physics::{Physics, Profile, CONVERSION_DELAY_S};
use crate::scenarios;

const AXES: usize = 3;

// A history's draws, each family its own stream of the history's seed: where each axis
// stood before power-up, each reading's rounding coin, each cycle's pulses. XORs of
// shifted indices into the seed, as these were, drew second 0's rounding coins from the
// numbers of its first cycle's pulses.
const PRIOR_STATE: qfa_rng::Stream = qfa_rng::Stream::named("field: state before power-up");
const QUANTIZATION: qfa_rng::Stream = qfa_rng::Stream::named("field: reading rounding");
const PULSES: qfa_rng::Stream = qfa_rng::Stream::named("field: pulses");
type Comp = Compensator<AXES, 32, AXES, Table>;

/// One axis's extension slots, drawn.
#[derive(Clone, Copy, Debug)]
pub struct Slots {
    /// Sensor lag τ, s.
    pub lag_s: Option<f32>,
    /// Play half-width °C and weight g.
    pub play: Option<(f32, f32)>,
    /// Creep gain g/°C, τ_ref s, activation K.
    pub creep: Option<(f32, f32, f32)>,
}

impl Slots {
    fn ext(self) -> Extensions {
        Extensions {
            sensor_lag: self.lag_s.map(|tau_s| SensorLag { tau_s }),
            bias_branch_hysteresis: self
                .play
                .map(|(half_width_c, weight_g)| BranchHysteresis { half_width_c, weight_g }),
            bias_creep: self.creep.map(|(gain_g_per_c, tau_ref_s, activation_k)| Creep {
                gain_g_per_c,
                tau_ref_s,
                t_ref_c: 25.0,
                activation_k,
            }),
        }
    }
}

/// A table, drawn: one of the paper's units, a grid, a rate limit and slots per axis.
#[derive(Clone, Debug)]
pub struct TableSpec {
    /// JB-KT8 unit 0..3.
    pub unit: usize,
    /// Bottom of the grid, °C, and its step.
    pub grid: (f32, f32),
    /// Heating/cooling split of the bias, g.
    pub split_g: f32,
    /// Rate limit, °C/min.
    pub rate_limit: f32,
    /// Slots per axis.
    pub slots: [Slots; AXES],
}

impl TableSpec {
    /// The table.
    #[must_use]
    pub fn table(&self) -> Table {
        let mut t = scenarios::table(self.unit, self.slots.map(Slots::ext), None);
        for (i, a) in t.axes.iter_mut().enumerate() {
            let pts: Vec<f32> = (0..12)
                .map(|k| {
                    let d = self.grid.0 + self.grid.1 * k as f32 - 22.0;
                    1e-4 - 3e-5 * i as f32 + 6e-6 * d + 3e-8 * d * d
                })
                .collect();
            let mut g = BiasGrid::single_valued(self.grid.0, self.grid.1, &pts).expect("12 values");
            for (h, c) in g.heating_g.iter_mut().zip(g.cooling_g.iter_mut()) {
                *h += self.split_g;
                *c -= self.split_g;
            }
            a.bias = g;
            a.rate_limit_c_per_min = self.rate_limit;
        }
        t
    }
}

/// Something that happens to one sensor's reading or to the compensator, at a second.
#[derive(Clone, Copy, Debug)]
pub enum Event {
    /// The reading never arrives, reported with `on_missed_reading`.
    Missed,
    /// Silent for this many seconds, every read reported missed.
    Dead(u16),
    /// A bit flipped on the bus: the scratchpad's CRC fails.
    Crc,
    /// The power-on value 0550h (+85 °C) instead of the temperature.
    PowerOnGlitch,
    /// The same table set again.
    ReloadSame,
    /// The other table set.
    LoadOther,
    /// The table's bytes with one byte flipped: refused, nothing changes.
    LoadCorrupt,
    /// The compensator replaced by its clone.
    Clone,
}

/// The fast-path entry a history drives (the compensator is configured for its input).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Entry {
    /// `cycle(pulses, dt)`.
    Pulses,
    /// `cycle_counters(cumulative counters, dt)`, primed after the table load.
    Counters,
    /// `cycle_samples(raw, dt)` with a samples table.
    Samples,
}

/// A field history.
#[derive(Clone, Debug)]
pub struct History {
    /// Temperature at the history's start, °C (at rest for ever before it).
    pub start_c: f64,
    /// Seconds of history before power-up.
    pub before_power_up_s: u32,
    /// Segments: (seconds, rate °C/min), from the history's start.
    pub segments: Vec<(u32, f64)>,
    /// Each sensor's offset from the common temperature, °C.
    pub offsets_c: [f64; AXES],
    /// Seed of the flicker on code edges.
    pub flicker_seed: u64,
    /// The µs counter at power-up (the clock wraps every 71.6 min).
    pub clock_start_us: u32,
    /// The table loaded at power-up and the other one.
    pub tables: [TableSpec; 2],
    /// Events: (second, sensor, event); the sensor is ignored for table events and clones.
    pub events: Vec<(u32, usize, Event)>,
    /// IMU cycles per second (1..=4).
    pub cycles_per_s: u32,
    /// The fast-path entry.
    pub entry: Entry,
}

impl History {
    /// Seconds covered after power-up.
    #[must_use]
    pub fn seconds(&self) -> u32 {
        self.segments.iter().map(|s| s.0).sum::<u32>().saturating_sub(self.before_power_up_s)
    }

    /// The common true rate at `t_s` seconds after the history's start, °C/min.
    #[must_use]
    pub fn rate(&self, t_s: f64) -> f64 {
        let mut t0 = 0.0;
        for &(len, rate) in &self.segments {
            t0 += f64::from(len);
            if t_s < t0 {
                return rate;
            }
        }
        0.0
    }

    /// The common true temperature at `t_s` seconds after the history's start, °C.
    #[must_use]
    pub fn temperature(&self, t_s: f64) -> f64 {
        let mut temp = self.start_c;
        let mut t0 = 0.0;
        for &(len, rate) in &self.segments {
            let len = f64::from(len);
            let dt = (t_s - t0).clamp(0.0, len);
            temp += rate / 60.0 * dt;
            if t_s < t0 + len {
                break;
            }
            t0 += len;
        }
        temp
    }
}

fn slots() -> impl Strategy<Value = Slots> {
    (
        prop::option::weighted(0.4, 30.0f32..600.0),
        prop::option::weighted(0.3, (0.3f32..3.0, -5e-5f32..5e-5)),
        prop::option::weighted(0.3, (-1e-5f32..1e-5, 300.0f32..1_200.0, 0.0f32..3_000.0)),
    )
        .prop_map(|(lag_s, play, creep)| Slots { lag_s, play, creep })
}

fn table_spec() -> impl Strategy<Value = TableSpec> {
    // Half the tables have no history slot at all; the others the same slots on every axis.
    (0usize..3, -45.0f32..0.0, 7.0f32..11.0, 0.0f32..3e-5, 1.0f32..4.0, prop::option::weighted(0.5, slots()))
        .prop_map(|(unit, start, step, split_g, rate_limit, slots)| {
            let slots = slots.unwrap_or(Slots { lag_s: None, play: None, creep: None });
            TableSpec { unit, grid: (start, step), split_g, rate_limit, slots: [slots; AXES] }
        })
        // The tables a calibration could write: valid ones (the refused load is its own event).
        .prop_filter("a valid table", |t| t.table().validate().is_ok())
}

fn event() -> impl Strategy<Value = Event> {
    prop_oneof![
        4 => Just(Event::Missed),
        1 => (5u16..90).prop_map(Event::Dead),
        2 => Just(Event::Crc),
        1 => Just(Event::PowerOnGlitch),
        1 => Just(Event::ReloadSame),
        1 => Just(Event::LoadOther),
        1 => Just(Event::LoadCorrupt),
        1 => Just(Event::Clone),
    ]
}

/// Histories of up to `max_segments` segments of up to 20 min each.
pub fn history(max_segments: usize) -> impl Strategy<Value = History> {
    (
        (
            -20.0f64..60.0,
            prop::collection::vec((60u32..1_800, prop_oneof![1 => Just(0.0), 2 => -3.0f64..3.0]), 1..=max_segments),
            0u32..3_600,
        ),
        [-0.5f64..0.5, -0.5f64..0.5, -0.5f64..0.5],
        any::<u64>(),
        any::<u32>(),
        [table_spec(), table_spec()],
        prop::collection::vec((0u32..7_200, 0usize..AXES, event()), 0..12),
        (1u32..=4, prop_oneof![Just(Entry::Pulses), Just(Entry::Counters), Just(Entry::Samples)]),
    )
        .prop_map(
            |(
                (start_c, mut segments, before),
                offsets_c,
                flicker_seed,
                clock_start_us,
                tables,
                events,
                (cycles_per_s, entry),
            )| {
                // Power-up within the history, with at least a minute after it.
                let total: u32 = segments.iter().map(|s| s.0).sum();
                let before_power_up_s = before.min(total.saturating_sub(60));
                // Kept within −40…80 °C: the truth stays clear of the power-on value's 85 °C,
                // which the firmware rightly takes as a reading when the stream is already
                // there (a 0550h glitch at a true 86 °C cannot be told from a reading). A
                // segment that would leave the range runs the other way, and if that leaves it
                // too (a long fast segment), it stops at the bound.
                let mut temp = start_c;
                for seg in &mut segments {
                    let len = f64::from(seg.0);
                    if !(-40.0..=80.0).contains(&(temp + seg.1 / 60.0 * len)) {
                        seg.1 = -seg.1;
                    }
                    let end = temp + seg.1 / 60.0 * len;
                    if !(-40.0..=80.0).contains(&end) {
                        seg.1 = (end.clamp(-40.0, 80.0) - temp) * 60.0 / len;
                    }
                    temp += seg.1 / 60.0 * len;
                }
                History {
                    start_c,
                    before_power_up_s,
                    segments,
                    offsets_c,
                    flicker_seed,
                    clock_start_us,
                    tables,
                    events,
                    cycles_per_s,
                    entry,
                }
            },
        )
}

/// What a run found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Verdict {
    /// Cycles run.
    pub cycles: u64,
    /// Cycles with status OK.
    pub ok_cycles: u64,
    /// Cycles with status OK and an output outside the oracle's tolerance, or OK where the
    /// oracle has no ideal.
    pub silent_wrong_cycles: u64,
    /// The first such cycle, described.
    pub first: Option<String>,
    /// Cycles with status OK and an output outside the physics oracle's tolerance of the
    /// simulated unit ([`crate::physics`]), or OK where no correct compensator can be.
    pub physics_wrong_cycles: u64,
    /// The first such cycle, described.
    pub first_physics: Option<String>,
    /// Cycles per status bit (bit 0 `TEMP_STALE` … the last, [`FLAGS`] − 1).
    pub flagged: [u64; FLAGS],
}

/// How many status bits the firmware has: [`Verdict::flagged`]'s length.
pub const FLAGS: usize = (u16::BITS - Status::all().bits().leading_zeros()) as usize;

/// A reading of `true_c`, quantized to 1/16 °C; near a code edge it may land one code
/// either way (flicker), as a DS18B20 at rest does.
fn quantize(true_c: f64, coin: u64) -> i16 {
    let x = true_c * 16.0;
    let frac = x - x.floor();
    let raw = if (frac - 0.5).abs() < 0.15 && !coin.is_multiple_of(3) {
        if coin.is_multiple_of(2) {
            x.floor()
        } else {
            x.ceil()
        }
    } else {
        x.round()
    };
    raw as i16
}

/// Run `h` through the compensator and the oracle.
#[must_use]
pub fn run(h: &History) -> Verdict {
    let input = if h.entry == Entry::Samples { Input::Samples } else { Input::PulseCounts };
    // The oracle reads the tables' K1 in the input's own units; a samples compensator is
    // given them in its tables' 2²⁰ units per g and reads the part at its LSB per g.
    let tables = [h.tables[0].table(), h.tables[1].table()].map(|mut t| {
        t.input = input;
        t
    });
    let config = match input {
        Input::Samples => scenarios::samples_config(Config::default()),
        Input::PulseCounts => Config::default(),
    };
    let mut comp = Comp::new(config).expect("default config");
    let loaded = tables.clone().map(|t| if input == Input::Samples { scenarios::as_samples(&t) } else { t });
    let mut counters = [0u32; AXES];
    let mut oracle = Oracle::new(AXES, &tables, 1e-6);
    let before = h.before_power_up_s;
    // The unit itself: where each axis stood before the history (its branch, its play
    // output within the half-width) is drawn, as nobody knows it.
    let drawn: [u64; AXES] = core::array::from_fn(|j| qfa_rng::stream_seed(h.flicker_seed, PRIOR_STATE, j as u64));
    let branches = drawn.map(|d| if d & 1 == 0 { 1i8 } else { -1 });
    let play_fracs = drawn.map(|d| ((d >> 8) % 2_001) as f64 / 1_000.0 - 1.0);
    let mut physics =
        Physics::new(Profile::new(h.start_c, &h.segments), &h.offsets_c, &tables, &branches, &play_fracs, 1e-6);
    for j in 0..AXES {
        // One step a second, at the instants (ms from power-up) the sensor would have read.
        let steps: Vec<(i64, f64, f64)> = (0..before)
            .map(|t| {
                let t_ms = (i64::from(t) - i64::from(before)) * 1_000 + 100 + 150 * j as i64;
                let t_s = f64::from(before) + t_ms as f64 * 1e-3;
                (t_ms, h.temperature(t_s) + h.offsets_c[j], h.rate(t_s))
            })
            .collect();
        oracle.before_power_up(j, &steps);
    }
    let mut current = 0usize;
    comp.set_table(loaded[0].clone()).expect("drawn tables are valid");
    comp.prime_counters(counters);
    oracle.load(0);
    physics.load(0);
    let mut clock = MsClock::new();
    let mut verdict = Verdict::default();
    let mut dead_until = [0u32; AXES];
    for s in 0..h.seconds() {
        for &(_, sensor, ev) in h.events.iter().filter(|e| e.0 == s) {
            match ev {
                Event::ReloadSame => {
                    comp.set_table(loaded[current].clone()).expect("valid");
                    oracle.load(current);
                    physics.load(current);
                }
                Event::LoadOther => {
                    current = 1 - current;
                    comp.set_table(loaded[current].clone()).expect("valid");
                    oracle.load(current);
                    physics.load(current);
                }
                Event::LoadCorrupt => {
                    let mut buf = [0u8; MAX_TABLE_BYTES];
                    let mut bytes = loaded[1 - current].encode(&mut buf).expect("encodes").to_vec();
                    let k = (qfa_rng::splitmix64(u64::from(s)) as usize) % bytes.len();
                    bytes[k] ^= 0x5A;
                    assert!(comp.load_table(&bytes).is_err(), "a flipped byte is refused (CRC)");
                }
                Event::Clone => comp = comp.clone(),
                Event::Dead(secs) => dead_until[sensor] = dead_until[sensor].max(s + u32::from(secs)),
                _ => {}
            }
        }
        #[allow(clippy::needless_range_loop)] // j is the sensor index the API takes
        for j in 0..AXES {
            // Each sensor's conversion completes at its own ms within the second.
            let t_ms_true = i64::from(s) * 1_000 + 100 + 150 * j as i64;
            let us = h.clock_start_us.wrapping_add((t_ms_true * 1_000) as u32);
            let t_ms = clock.ms(us);
            // The conversion reports the temperature of its middle, before the stamp.
            let stamp_s = f64::from(before) + t_ms_true as f64 * 1e-3;
            let true_c = h.temperature(stamp_s - CONVERSION_DELAY_S) + h.offsets_c[j];
            let here = h.events.iter().find(|e| e.0 == s && e.1 == j).map(|e| e.2);
            if s < dead_until[j] || matches!(here, Some(Event::Missed)) {
                let _ = comp.on_missed_reading(j, t_ms);
                continue;
            }
            let coin = qfa_rng::stream_seed(h.flicker_seed, QUANTIZATION, (u64::from(s) << 8) | j as u64);
            let raw = quantize(true_c, coin);
            match here {
                Some(Event::Crc) => {
                    let mut sp = encode_scratchpad(raw, Resolution::Bits12, 0x10);
                    sp[1] ^= 0x04;
                    assert!(comp.on_scratchpad(j, t_ms, &sp).is_err(), "a CRC error is refused");
                }
                Some(Event::PowerOnGlitch) => {
                    // Refused unless the stream was already at 85 °C; the truth stays below 80.
                    let _ = comp.on_raw(j, t_ms, POWER_ON_RAW);
                }
                _ => {
                    if comp.on_raw(j, t_ms, raw).is_ok() {
                        oracle.reading(j, t_ms_true, true_c, f64::from(raw) * LSB_C);
                        physics.reading(j, stamp_s);
                    } else {
                        // A refused true reading (a step the plausibility rules hold back)
                        // is flagged; the oracle does not count it as good either.
                    }
                }
            }
        }
        for c in 0..h.cycles_per_s {
            let pulses: [i32; AXES] = core::array::from_fn(|i| {
                let r =
                    qfa_rng::stream_seed(h.flicker_seed, PULSES, (u64::from(s) << 20) | (u64::from(c) << 4) | i as u64);
                1_601 - (r % 3_203) as i32
            });
            let dt = 5_000;
            // Samples of about ±1 g, as raw LSB at the table's K1 (≈ 320 000 per g).
            let raw: [i32; AXES] = pulses.map(|p| p * 200);
            let (out_v, status) = match h.entry {
                Entry::Pulses => {
                    let o = comp.cycle(pulses, dt);
                    (o.dv_mps, o.status)
                }
                Entry::Counters => {
                    for (n, p) in counters.iter_mut().zip(pulses) {
                        *n = n.wrapping_add_signed(p);
                    }
                    let o = comp.cycle_counters(counters, dt);
                    (o.dv_mps, o.status)
                }
                Entry::Samples => {
                    let o = comp.cycle_samples(raw, dt);
                    (o.accel_mps2, o.status)
                }
            };
            let out = PulseOutput { dv_mps: out_v, status };
            // The cycle's instant: after the second's readings, before the next second's.
            let t_cycle = f64::from(before) + f64::from(s) + 0.45 + 0.25 * f64::from(c) / f64::from(h.cycles_per_s);
            verdict.cycles += 1;
            for (b, n) in verdict.flagged.iter_mut().enumerate() {
                *n += u64::from(out.status.bits() >> b & 1);
            }
            if !out.status.is_ok() {
                continue;
            }
            verdict.ok_cycles += 1;
            #[allow(clippy::needless_range_loop)] // i is the axis, in three arrays and the oracle
            for i in 0..AXES {
                let ideal = match h.entry {
                    Entry::Samples => oracle.accel(i, i64::from(raw[i])),
                    _ => oracle.dv(i, i64::from(pulses[i]), dt),
                };
                let wrong = match ideal {
                    None => Some("status OK where the oracle has no ideal (no table or rate not ready)".to_string()),
                    Some((want, tol)) => {
                        let got = f64::from(out.dv_mps[i]);
                        ((got - want).abs() > tol).then(|| {
                            format!("dv {got:.9e} vs ideal {want:.9e}, |Δ| {:.3e} > tol {tol:.3e}", (got - want).abs())
                        })
                    }
                };
                if let Some(why) = wrong {
                    verdict.silent_wrong_cycles += 1;
                    if verdict.first.is_none() {
                        verdict.first =
                            Some(format!("t = {s} s, cycle {c}, axis {i}: {why} (status {:?})", out.status));
                    }
                }
                let truth = match h.entry {
                    Entry::Samples => physics.accel(i, t_cycle, i64::from(raw[i])),
                    _ => physics.dv(i, t_cycle, i64::from(pulses[i]), dt),
                };
                let wrong = match truth {
                    None => Some("status OK where no compensator can know (no table, or no rate yet)".to_string()),
                    Some((want, tol)) => {
                        let got = f64::from(out.dv_mps[i]);
                        ((got - want).abs() > tol).then(|| {
                            format!(
                                "{got:.9e} vs the unit's {want:.9e}, |Δ| {:.3e} > tol {tol:.3e}",
                                (got - want).abs()
                            )
                        })
                    }
                };
                if let Some(why) = wrong {
                    verdict.physics_wrong_cycles += 1;
                    if verdict.first_physics.is_none() {
                        verdict.first_physics =
                            Some(format!("t = {s} s, cycle {c}, axis {i}: {why} (status {:?})", out.status));
                    }
                }
            }
        }
    }
    verdict
}
