//! Soak: the simulated 1-Wire bus, the DS18B20 driver and the split compensator run
//! through hours to weeks of simulated time, across every clock wrap, healthy or with a
//! fault schedule.
//!
//! The firmware recipe under test, exactly as the driver docs give it:
//! `t_ms = clock.ms(sample.completed_us)` with one [`MsClock`] for the system, then
//! `updater.on_scratchpad(sensor, t_ms, &sample.scratchpad)`; a read that fails
//! (no presence, pin error, CRC, the power-on value, a lost conversion) is reported with
//! `updater.on_missed_reading(sensor, clock.ms(now_us))`, as the board does. The IMU
//! interrupt calls `applier.cycle(pulses, dt_ticks)` `imu_hz` times per simulated second,
//! at its place in the second (before, between and after the bus transactions), so the
//! fast path's tick count and the simulated clock agree. The µs clock the driver sees
//! starts `us_before_wrap` before its 2³² µs wrap (71.6 min) and the ms clock
//! `ms_before_wrap` before its 2³² ms wrap (49.7 days), so even a short run crosses both.
//! The sensors are externally powered and the driver polls read slots
//! ([`Ds18b20::use_read_slots`]), the mode in which a lost conversion can be seen.
//!
//! # Silent wrong cycles
//! The figure that matters: IMU cycles whose status is OK ([`Status::is_ok`]) while the
//! temperature behind an axis is older than the stale limit (3 s: the time since the
//! conversion that produced the stream's latest accepted reading, which for a frozen
//! sensor is its last real conversion) or more than 0.5 °C from the simulated case
//! temperature at the cycle. It must be 0.
//!
//! Figures (docs/measurements.md; release build on the shared 2-core machine):
//! `cargo run --release -p host-tests --bin soak -- --hours 1200` (healthy):
//! `ok_cycles=43193482 silent_wrong_cycles=0 stale_fraction=0 max_temp_error_c=0.0439`, 86 s;
//! `-- --faults` (1 320 h, [`Faults::field`]): `silent_wrong_cycles=863981`, all in the frozen
//! day (`fault_frozen=0/863999`), every other fault flagged on every cycle of its window,
//! 51 s. This branch's driver returns a lost conversion's predecessor as a new sample; with
//! the driver's Convert T read-slot check (branch `board`, cd015de) the same run prints
//! `silent_wrong_cycles=0` and `fault_frozen=863999/863999`.

use std::time::Instant;

use qfa_thermal::compensator::{Compensator, Config, Status};
use qfa_thermal::ds18b20::Resolution;
use qfa_thermal::ds18b20_driver::{Ds18b20, Sample};
use qfa_thermal::time::MsClock;
use qfa_thermal::{Input, Table};

use crate::fuzzing::stream_table;
use crate::onewire_sim::{Device, Sim};

const NS_PER_S: u64 = 1_000_000_000;
const NS_PER_MS: u64 = 1_000_000;

/// A fault on one sensor (or, for bus dropouts, on all) from `start_s` to `end_s`,
/// simulated seconds from the start of the run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    /// The sensor (taken modulo the number of sensors).
    pub sensor: usize,
    /// First second of the fault.
    pub start_s: u64,
    /// First second after it.
    pub end_s: u64,
}

impl Window {
    const fn new(sensor: usize, start_s: u64, len_s: u64) -> Self {
        Self { sensor, start_s, end_s: start_s + len_s }
    }

    fn contains(&self, second: u64) -> bool {
        (self.start_s..self.end_s).contains(&second)
    }
}

/// A fault schedule.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Faults {
    /// A sensor that answers nothing (no presence pulse).
    pub dead: Window,
    /// A frozen sensor: every Convert T is lost, so its scratchpad keeps the previous
    /// conversion with a good CRC ([`Device::drop_convert_t`]).
    pub frozen: Option<Window>,
    /// Brown-outs of a genuine part in the middle of a conversion, one per second of each
    /// window: the scratchpad reads 0550h (+85 °C) with byte 6 = 0Ch.
    pub brown_outs: Vec<Window>,
    /// The sensor that is a clone part: its power-on scratchpad has byte 6 = 10h, so a
    /// brown-out decodes as a real +85 °C reading.
    pub clone_part: usize,
    /// Brown-outs of the clone part.
    pub clone_brown_outs: Vec<Window>,
    /// Dropouts of one sensor (no presence).
    pub dropouts: Vec<Window>,
    /// Dropouts of the whole bus (every pin call fails).
    pub bus_dropouts: Vec<Window>,
    /// At this second the table is reloaded: a bad CRC and a table for the other input (both
    /// refused), then the good table (applied: every axis state starts again).
    pub reload_at_s: u64,
}

impl Faults {
    /// Simulated hours the [`Faults::field`] schedule needs.
    pub const FIELD_HOURS: f64 = 1_320.0;

    /// The field schedule, for a [`Faults::FIELD_HOURS`] run with the ms clock starting 1 h
    /// before its wrap (wraps at 1 h and 1 194.05 h). Sensor 1 is dead for 50 days, from
    /// 0.5 h to 1 200.5 h: across both ms wraps, and through the instant one whole wrap after
    /// its last reading (1 193.55 h), where a wrapped difference of timestamps reads 0. The
    /// other faults come after it, while the other sensors are healthy (a dead sensor flags
    /// every cycle, which would hide them): sensor 0 frozen for a day from 1 210 h,
    /// brown-outs of sensor 2 (a genuine part: 1 s at 1 250 h, 5 s a minute later) and of
    /// sensor 0 (a clone part: the same at 1 260 h), 10-min dropouts of sensor 2 at 1 270 h
    /// and sensor 0 at 1 280 h, a 10-min bus dropout at 1 290 h, reloads at 1 300 h.
    #[must_use]
    pub fn field() -> Self {
        const H: u64 = 3_600;
        Self {
            dead: Window { sensor: 1, start_s: H / 2, end_s: 1_200 * H + H / 2 },
            frozen: Some(Window::new(0, 1_210 * H, 24 * H)),
            brown_outs: vec![Window::new(2, 1_250 * H, 1), Window::new(2, 1_250 * H + 60, 5)],
            clone_part: 0,
            clone_brown_outs: vec![Window::new(0, 1_260 * H, 1), Window::new(0, 1_260 * H + 60, 5)],
            dropouts: vec![Window::new(2, 1_270 * H, 600), Window::new(0, 1_280 * H, 600)],
            bus_dropouts: vec![Window::new(0, 1_290 * H, 600)],
            reload_at_s: 1_300 * H,
        }
    }

    /// The same faults compressed into 2.75 h, with the ms clock starting 30 min before its
    /// wrap: sensor 1 dead from 10 min to 70 min (across the ms wrap), brown-outs at 80 and
    /// 90 min, dropouts at 100 and 115 min, the bus at 130 min, reloads at 150 min. No frozen
    /// sensor: see [`Faults::frozen_only`].
    #[must_use]
    pub fn compressed() -> Self {
        const M: u64 = 60;
        Self {
            dead: Window { sensor: 1, start_s: 10 * M, end_s: 70 * M },
            frozen: None,
            brown_outs: vec![Window::new(2, 80 * M, 1), Window::new(2, 81 * M, 5)],
            clone_part: 0,
            clone_brown_outs: vec![Window::new(0, 90 * M, 1), Window::new(0, 91 * M, 5)],
            dropouts: vec![Window::new(2, 100 * M, 600), Window::new(0, 115 * M, 600)],
            bus_dropouts: vec![Window::new(0, 130 * M, 600)],
            reload_at_s: 150 * M,
        }
    }

    /// Only a frozen sensor 0, for 1 h from 10 min on (the dead window lies past any run
    /// shorter than 10 000 h).
    #[must_use]
    pub fn frozen_only() -> Self {
        let never = Window::new(0, u64::MAX / 2, 0);
        Self {
            dead: never,
            frozen: Some(Window::new(0, 600, 3_600)),
            brown_outs: vec![],
            clone_part: 0,
            clone_brown_outs: vec![],
            dropouts: vec![],
            bus_dropouts: vec![],
            reload_at_s: u64::MAX,
        }
    }
}

/// Soak settings.
#[derive(Clone, Debug)]
pub struct Settings {
    /// Simulated hours.
    pub hours: f64,
    /// IMU cycles per second (coarse: the fast path's cost is measured in bench-target).
    pub imu_hz: u32,
    /// The driver's µs clock starts this many µs before it wraps.
    pub us_before_wrap: u32,
    /// The ms time base starts this many ms before it wraps.
    pub ms_before_wrap: u32,
    /// Temperature sensors (one per accelerometer case: 3; or one for all axes: 1).
    pub sensors: usize,
    /// The fault schedule, or none (a healthy bus).
    pub faults: Option<Faults>,
}

impl Default for Settings {
    fn default() -> Self {
        Self { hours: 1.0, imu_hz: 10, us_before_wrap: 60_000_000, ms_before_wrap: 3_600_000, sensors: 3, faults: None }
    }
}

/// How one scheduled fault was flagged: IMU cycles in its window and those with the flag.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FaultFlags {
    /// The fault, e.g. `dead_stale`.
    pub name: String,
    /// Cycles in the window.
    pub cycles: u64,
    /// Of those, cycles with the expected flag.
    pub flagged: u64,
}

/// What a soak measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Figures {
    /// Simulated hours run.
    pub soak_hours: f64,
    /// Times the driver's µs clock wrapped.
    pub wraps_us: u32,
    /// Times the ms time base wrapped.
    pub wraps_ms: u32,
    /// Temperature readings the driver returned.
    pub readings: u64,
    /// IMU cycles run.
    pub cycles: u64,
    /// IMU cycles while every sensor was healthy (no fault within the last 10 s).
    pub healthy_cycles: u64,
    /// Fraction of those flagged stale.
    pub stale_fraction: f64,
    /// Good readings (driver OK, a real conversion) the compensator refused while every
    /// sensor was healthy.
    pub rejected_good_readings: u64,
    /// Good readings refused within 10 s after a fault (a step after a gap waits for
    /// `confirm_samples` readings that agree).
    pub rejected_after_fault: u64,
    /// Worst |T̂ − truth| at a reading's completion time while healthy, °C.
    pub max_temp_error_c: f64,
    /// Reads the driver failed (each one reported with `on_missed_reading`).
    pub driver_errors: u64,
    /// Readings the driver returned that the compensator refused (brown-outs of the clone
    /// part, steps waiting for confirmation).
    pub compensator_rejections: u64,
    /// Cycles with status OK: the cycles the silent-wrong check judges (a soak whose every
    /// cycle is flagged would pass that check with nothing checked).
    pub ok_cycles: u64,
    /// Cycles with status OK and a temperature older than the limit or off by > 0.5 °C.
    pub silent_wrong_cycles: u64,
    /// Of those, cycles in the frozen sensor's window or the 10 s after it.
    pub silent_wrong_frozen: u64,
    /// Cycles with each status flag, by name.
    pub flags: Vec<(&'static str, u64)>,
    /// Each scheduled fault's window and how many of its cycles were flagged.
    pub faults: Vec<FaultFlags>,
    /// Table loads refused and applied.
    pub tables_refused: u32,
    /// Table loads applied after the start.
    pub tables_applied: u32,
    /// Wall-clock seconds.
    pub wall_s: f64,
}

impl Figures {
    /// `key=value` lines.
    #[must_use]
    pub fn lines(&self) -> Vec<String> {
        let mut l = vec![
            format!("soak_hours={}", self.soak_hours),
            format!("wraps_us={}", self.wraps_us),
            format!("wraps_ms={}", self.wraps_ms),
            format!("readings={}", self.readings),
            format!("imu_cycles={}", self.cycles),
            format!("healthy_cycles={}", self.healthy_cycles),
            format!("stale_fraction={}", self.stale_fraction),
            format!("rejected_good_readings={}", self.rejected_good_readings),
            format!("rejected_after_fault={}", self.rejected_after_fault),
            format!("max_temp_error_c={:.4}", self.max_temp_error_c),
            format!("driver_errors={}", self.driver_errors),
            format!("compensator_rejections={}", self.compensator_rejections),
            format!("ok_cycles={}", self.ok_cycles),
            format!("silent_wrong_cycles={}", self.silent_wrong_cycles),
            format!("silent_wrong_frozen={}", self.silent_wrong_frozen),
        ];
        l.extend(self.flags.iter().map(|(n, c)| format!("flag_{n}={c}")));
        l.extend(self.faults.iter().map(|f| format!("fault_{}={}/{}", f.name, f.flagged, f.cycles)));
        l.push(format!("tables_refused={}", self.tables_refused));
        l.push(format!("tables_applied={}", self.tables_applied));
        l.push(format!("wall_s={:.1}", self.wall_s));
        l
    }

    /// The fault named `name`.
    #[must_use]
    pub fn fault(&self, name: &str) -> Option<&FaultFlags> {
        self.faults.iter().find(|f| f.name == name)
    }

    /// Cycles with the flag named `name` (as `Status` spells it).
    #[must_use]
    pub fn flag(&self, name: &str) -> u64 {
        self.flags.iter().find(|(n, _)| *n == name).map_or(0, |(_, c)| *c)
    }
}

/// The simulated case temperature of sensor `s`: 20 ± 25 °C over a 6-h cycle (at most
/// 0.44 °C/min), each case shifted by 1 °C.
#[must_use]
pub fn truth_c(s: usize, t_s: f64) -> f64 {
    20.0 + s as f64 + 25.0 * (2.0 * std::f64::consts::PI * t_s / 21_600.0).sin()
}

/// A cycle is checked against the fault windows it may belong to, as `[start, end]` in ns
/// of schedule time (`second · 10⁹ + the cycle's place in it`: the simulated seconds run a
/// little over 1 s, by the bus time's sub-µs rest, so the simulated clock drifts from the
/// schedule by seconds over weeks): from the first cycle after the fault's first read (the reads come
/// 0.78-0.82 s into a second, so from +0.9 s) to the last cycle before the first read after
/// it (+0.75 s), so a fault must be flagged on every cycle from when it can be seen until it
/// is gone. `settle_s` delays the start (TEMP_STALE needs the 3-s limit to pass).
struct Check {
    name: String,
    from_ns: u64,
    to_ns: u64,
    want: Status,
    cycles: u64,
    flagged: u64,
}

impl Check {
    fn new(name: &str, w: &Window, settle_s: u64, want: Status) -> Self {
        Self {
            name: name.to_owned(),
            from_ns: (w.start_s.saturating_add(settle_s).saturating_mul(NS_PER_S)).saturating_add(900 * NS_PER_MS),
            to_ns: w.end_s.saturating_mul(NS_PER_S).saturating_add(750 * NS_PER_MS),
            want,
            cycles: 0,
            flagged: 0,
        }
    }
}

/// Per-stream truth the harness keeps (never read from the compensator).
#[derive(Clone, Copy, Debug, Default)]
struct StreamTruth {
    /// Simulated time of the latest conversion that really happened on this sensor.
    real_conversion_ns: Option<u64>,
    /// Simulated time of the conversion behind the stream's latest accepted reading.
    accepted_data_ns: Option<u64>,
}

/// The status flags, by name, in bit order.
fn flag_names() -> Vec<(&'static str, Status)> {
    Status::all().iter_names().collect()
}

/// Run a soak. `progress` is called once per simulated hour with the hours done.
///
/// # Panics
/// On a driver or table setup failure.
#[must_use]
pub fn run(set: &Settings, mut progress: impl FnMut(f64)) -> Figures {
    let wall = Instant::now();
    let sensors = set.sensors.clamp(1, 3);
    let faults = set.faults.clone().map(|mut f| {
        // Every fault on a sensor that exists.
        let m = |w: &mut Window| w.sensor %= sensors;
        m(&mut f.dead);
        f.frozen.iter_mut().for_each(m);
        f.brown_outs.iter_mut().for_each(m);
        f.clone_brown_outs.iter_mut().for_each(m);
        f.dropouts.iter_mut().for_each(m);
        f.clone_part %= sensors;
        f
    });
    let mut devices: Vec<Device> =
        (0..sensors).map(|s| Device::ds18b20(0x0042_1E50 + s as u64, (truth_c(s, 0.0) * 16.0) as i16)).collect();
    if let Some(f) = &faults {
        devices[f.clone_part].power_on_byte6 = 0x10;
    }
    let sim = Sim::new(devices);
    let mut bus = sim.bus();
    let mut found = Ds18b20::search::<_, _, 4>(&mut bus).expect("search");
    assert_eq!(found.len(), sensors, "every simulated sensor answers the search");
    // The search order is by ROM; map each driver to the device with its serial.
    found.sort_by_key(|d| d.rom().map(|r| r.bytes()[1..7].iter().rev().fold(0u64, |a, &b| (a << 8) | u64::from(b))));
    for d in found.iter_mut() {
        d.set_resolution(&mut bus, Resolution::Bits12).expect("resolution");
        d.use_read_slots(&mut bus).expect("power supply");
    }

    let table = stream_table();
    let imu_hz = set.imu_hz.max(1);
    // The IMU's own period: with the default 400 Hz against this soak's 5–10 Hz every cycle
    // was DT_IMPLAUSIBLE, so no cycle was OK and the silent-wrong check judged none.
    let cfg = Config { imu_period_s: 1.0 / imu_hz as f32, ..Config::default() };
    let stale_ns = (f64::from(cfg.stale_after_ticks) * f64::from(cfg.tick_s) * 1e9).round() as u64;
    // With the misalignment stage: the table has a matrix.
    let mut c3 = Compensator::<3, 32, 3, Table, 3>::new(cfg).expect("valid config");
    let mut c1 = Compensator::<3, 32, 1, Table, 3>::new(cfg).expect("valid config");
    let per_axis = sensors == 3;
    c3.load_table(&table).expect("table");
    c1.load_table(&table).expect("table");
    let (mut up3, mut ap3) = c3.split();
    let (mut up1, mut ap1) = c1.split();
    let streams = if per_axis { 3 } else { 1 };

    let us_origin = 0u32.wrapping_sub(set.us_before_wrap);
    let clock_us = |sim: &Sim| sim.now_us().wrapping_add(us_origin);
    let mut clock = MsClock::starting_at(0u32.wrapping_sub(set.ms_before_wrap));
    let period_ns = NS_PER_S / u64::from(imu_hz);
    let dt_ticks = 1_000_000 / imu_hz;
    let pulses = [320_000 / imu_hz as i32; 3];

    let origin_ns = sim.now_ns();
    let mut checks: Vec<Check> = Vec::new();
    if let Some(f) = &faults {
        let either = Status::TEMP_INVALID | Status::TEMP_STALE;
        checks.push(Check::new("dead", &f.dead, 0, either));
        checks.push(Check::new("dead_stale", &f.dead, 3, Status::TEMP_STALE));
        if let Some(w) = &f.frozen {
            checks.push(Check::new("frozen", w, 0, either));
        }
        for (i, w) in f.brown_outs.iter().enumerate() {
            checks.push(Check::new(&format!("brown_out_{i}"), w, 0, either));
        }
        for (i, w) in f.clone_brown_outs.iter().enumerate() {
            checks.push(Check::new(&format!("clone_brown_out_{i}"), w, 0, either));
        }
        for (i, w) in f.dropouts.iter().enumerate() {
            checks.push(Check::new(&format!("dropout_{i}"), w, 0, either));
        }
        for (i, w) in f.bus_dropouts.iter().enumerate() {
            checks.push(Check::new(&format!("bus_dropout_{i}"), w, 3, Status::TEMP_STALE));
        }
    }
    let names = flag_names();
    let mut flag_counts = vec![0u64; names.len()];

    let total_s = (set.hours * 3600.0).round() as u64;
    let mut f = Figures::default();
    let (mut last_us, mut last_ms): (Option<u32>, Option<u32>) = (None, None);
    let (mut stale_cycles, mut last_fault_s): (u64, Option<u64>) = (0, None);
    let mut truth = [StreamTruth::default(); 3];
    let mut max_err = 0.0f64;
    const GRACE_S: u64 = 10;
    for second in 0..total_s {
        let t0_ns = sim.now_ns();
        let t_s = (t0_ns - origin_ns) as f64 * 1e-9;
        // The faults in force this second, per sensor.
        let mut down = [false; 3];
        let mut frozen = [false; 3];
        let mut brown = [false; 3];
        let mut bus_down = false;
        if let Some(fs) = &faults {
            if fs.dead.contains(second) {
                down[fs.dead.sensor] = true;
            }
            for w in fs.dropouts.iter().filter(|w| w.contains(second)) {
                down[w.sensor] = true;
            }
            for w in fs.frozen.iter().filter(|w| w.contains(second)) {
                frozen[w.sensor] = true;
            }
            for w in fs.brown_outs.iter().chain(fs.clone_brown_outs.iter()).filter(|w| w.contains(second)) {
                brown[w.sensor] = true;
            }
            bus_down = fs.bus_dropouts.iter().any(|w| w.contains(second));
            if second == fs.reload_at_s {
                reload(&mut f, &table, &mut up3, &mut up1);
            }
        }
        let any_fault = bus_down || (0..sensors).any(|s| down[s] || frozen[s] || brown[s]);
        if any_fault {
            last_fault_s = Some(second);
        }
        let healthy = second > 0 && last_fault_s.is_none_or(|l| second - l > GRACE_S);
        // In a frozen window or within 10 s after it (until the sensor's next real reading).
        let after_frozen = faults
            .as_ref()
            .and_then(|fs| fs.frozen)
            .is_some_and(|w| (w.start_s..w.end_s.saturating_add(GRACE_S)).contains(&second));
        // The case temperatures of this second's conversions, and the faults on the bus.
        sim.with(|w| {
            w.pin_error = bus_down;
            for (s, d) in w.devices.iter_mut().enumerate() {
                d.temp_raw = (truth_c(s, t_s + 0.75) * 16.0).round() as i16;
                d.present = !down[s];
                d.drop_convert_t = u32::from(frozen[s]);
                // A brown-out 100 ms into the conversion: the conversion is lost.
                d.brown_out_at_ns = brown[s].then_some(t0_ns + 100 * NS_PER_MS);
            }
        });

        // The IMU cycles of this second, each run when the simulated clock reaches it.
        let mut next_cycle = 0u32;
        let mut run_cycles = |upto_ns: u64,
                              up3: &qfa_thermal::Updater<'_, 3, 32, 3, Table, 3>,
                              up1: &qfa_thermal::Updater<'_, 3, 32, 1, Table, 3>,
                              ap3: &mut qfa_thermal::Applier<'_, 3, 3>,
                              ap1: &mut qfa_thermal::Applier<'_, 3, 3>,
                              truth: &[StreamTruth; 3],
                              f: &mut Figures| {
            while next_cycle < imu_hz && t0_ns + u64::from(next_cycle) * period_ns <= upto_ns {
                let vt_ns = t0_ns + u64::from(next_cycle) * period_ns;
                let schedule_ns = second * NS_PER_S + u64::from(next_cycle) * period_ns;
                next_cycle += 1;
                let out = if per_axis { ap3.cycle(pulses, dt_ticks) } else { ap1.cycle(pulses, dt_ticks) };
                f.cycles += 1;
                for (count, (_, flag)) in flag_counts.iter_mut().zip(names.iter()) {
                    *count += u64::from(out.status.contains(*flag));
                }
                if healthy {
                    f.healthy_cycles += 1;
                    stale_cycles += u64::from(out.status.contains(Status::TEMP_STALE));
                }
                for c in checks.iter_mut().filter(|c| (c.from_ns..=c.to_ns).contains(&schedule_ns)) {
                    c.cycles += 1;
                    c.flagged += u64::from(out.status.intersects(c.want));
                }
                if out.status.is_ok() {
                    f.ok_cycles += 1;
                    let vt_s = (vt_ns - origin_ns) as f64 * 1e-9;
                    let wrong = (0..streams).any(|j| {
                        let est = if per_axis { up3.estimate_of(j) } else { up1.estimate_of(j) };
                        let old = truth[j].accepted_data_ns.is_none_or(|t| vt_ns.saturating_sub(t) > stale_ns);
                        let off = est.is_none_or(|e| (f64::from(e.temp_c) - truth_c(j, vt_s)).abs() > 0.5);
                        old || off
                    });
                    if wrong {
                        f.silent_wrong_cycles += 1;
                        f.silent_wrong_frozen += u64::from(after_frozen);
                    }
                }
            }
        };
        run_cycles(t0_ns, &up3, &up1, &mut ap3, &mut ap1, &truth, &mut f);

        // Conversions on every sensor, then read each one.
        let mut started = [false; 3];
        for (s, d) in found.iter_mut().enumerate() {
            started[s] = d.start(&mut bus, clock_us(&sim)).is_ok();
            // A conversion really happens when the sensor answers, takes the command and
            // does not brown out in the middle of it.
            if started[s] && !down[s] && !bus_down && !frozen[s] && !brown[s] {
                truth[s].real_conversion_ns = Some(sim.now_ns() + 600 * NS_PER_MS);
            }
        }
        let read_at = sim.now_ns() + 760 * NS_PER_MS;
        run_cycles(read_at, &up3, &up1, &mut ap3, &mut ap1, &truth, &mut f);
        sim.idle_us((read_at - sim.now_ns()) / 1_000);
        for (s, d) in found.iter_mut().enumerate() {
            run_cycles(sim.now_ns(), &up3, &up1, &mut ap3, &mut ap1, &truth, &mut f);
            let result: Result<Sample, ()> = if started[s] {
                match d.is_ready(&mut bus, clock_us(&sim)) {
                    Ok(true) => d.read(&mut bus).map_err(|_| ()),
                    Ok(false) | Err(_) => Err(()),
                }
            } else {
                Err(())
            };
            let j = if per_axis { s } else { 0 };
            let Ok(sample) = result else {
                // The board's recipe: every failed read reaches the slow path.
                f.driver_errors += 1;
                let t_ms = clock.ms(clock_us(&sim));
                let r = if per_axis { up3.on_missed_reading(j, t_ms) } else { up1.on_missed_reading(j, t_ms) };
                assert!(r.is_err(), "a missed reading is an error");
                continue;
            };
            f.readings += 1;
            if last_us.is_some_and(|l| sample.completed_us < l) {
                f.wraps_us += 1;
            }
            last_us = Some(sample.completed_us);
            let t_ms = clock.ms(sample.completed_us);
            if last_ms.is_some_and(|l| t_ms < l) {
                f.wraps_ms += 1;
            }
            last_ms = Some(t_ms);
            let res = if per_axis {
                up3.on_scratchpad(j, t_ms, &sample.scratchpad)
            } else {
                up1.on_scratchpad(j, t_ms, &sample.scratchpad)
            };
            // A good reading: a real conversion this second, delivered as measured.
            let good = !frozen[s] && !brown[s] && sample.reading.raw == sim.with(|w| w.devices[s].temp_raw);
            match res {
                Ok(_) => {
                    // The data behind the stream is the latest real conversion (for a frozen
                    // sensor, an old one; for a brown-out, none at all).
                    truth[j].accepted_data_ns = if brown[s] { None } else { truth[s].real_conversion_ns };
                    if healthy && good {
                        let est = if per_axis { up3.estimate_of(j) } else { up1.estimate_of(j) };
                        if let Some(e) = est {
                            max_err = max_err.max((f64::from(e.temp_c) - truth_c(s, t_s + 0.75)).abs());
                        }
                    }
                }
                Err(_) => {
                    f.compensator_rejections += 1;
                    if good && healthy {
                        f.rejected_good_readings += 1;
                    } else if good {
                        f.rejected_after_fault += 1;
                    }
                }
            }
        }
        // The rest of the second: the remaining IMU cycles at their times.
        for k in 0..u64::from(imu_hz) {
            let vt = t0_ns + k * period_ns;
            if vt > sim.now_ns() {
                sim.idle_us((vt - sim.now_ns()).div_ceil(1_000));
            }
            run_cycles(vt, &up3, &up1, &mut ap3, &mut ap1, &truth, &mut f);
        }
        let spent_us = (sim.now_ns() - t0_ns) / 1000;
        sim.idle_us(1_000_000 - spent_us.min(1_000_000));
        if (second + 1) % 3600 == 0 {
            progress((second + 1) as f64 / 3600.0);
        }
    }
    f.soak_hours = total_s as f64 / 3600.0;
    f.stale_fraction = if f.healthy_cycles == 0 { 1.0 } else { stale_cycles as f64 / f.healthy_cycles as f64 };
    f.max_temp_error_c = max_err;
    f.flags = names.iter().zip(flag_counts).map(|((n, _), c)| (*n, c)).collect();
    f.faults = checks.into_iter().map(|c| FaultFlags { name: c.name, cycles: c.cycles, flagged: c.flagged }).collect();
    f.wall_s = wall.elapsed().as_secs_f64();
    f
}

/// The reload: a table with a bad CRC and one fitted for samples are refused (the
/// compensation goes on unchanged), then the good table is applied.
fn reload(
    f: &mut Figures,
    good: &[u8],
    up3: &mut qfa_thermal::Updater<'_, 3, 32, 3, Table, 3>,
    up1: &mut qfa_thermal::Updater<'_, 3, 32, 1, Table, 3>,
) {
    let mut bad_crc = good.to_vec();
    bad_crc[qfa_thermal::table::HEADER_LEN + 3] ^= 0x01;
    assert!(Table::decode(&bad_crc).is_err(), "a flipped payload bit fails the CRC");
    f.tables_refused += 1;
    let mut samples = Table::decode(good).expect("good table");
    samples.input = Input::Samples;
    assert!(up3.set_table(samples.clone()).is_err() && up1.set_table(samples).is_err());
    f.tables_refused += 1;
    let t = Table::decode(good).expect("good table");
    up3.set_table(t.clone()).expect("good table");
    up1.set_table(t).expect("good table");
    f.tables_applied += 1;
}
