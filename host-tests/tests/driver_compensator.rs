//! The DS18B20 driver on the simulated bus feeding `Compensator::<3, 32>` through
//! `on_scratchpad(0, completed_ms, &scratchpad)`, as the driver's module docs describe,
//! over a long run with every fault the simulation supports injected again and again.
//!
//! The requirement: "The driver plus the compensator must come through every injected fault with
//! a typed error or flag, never a wrong temperature." Checked here:
//!
//! * every fault event gives a typed driver error or a compensator `SampleError` (or,
//!   for a single flipped bit within the retry budget, the true value: the retry
//!   absorbed it);
//! * every reading the driver returns is exactly what the device measured;
//! * the compensator's temperature estimate stays within [`TOL_C`] of the simulated true
//!   temperature at the estimate's timestamp;
//! * when readings stop for longer than `stale_after_ticks`, the fast path reports
//!   `TEMP_STALE` and the compensation is bit-identical to the one at the last good
//!   reading; the flag clears with the next good reading.

use std::collections::BTreeMap;

use host_tests::fuzzing::stream_table;
use host_tests::onewire_sim::{Device, Sim};
use qfa_rng::LabRng;
use qfa_thermal::compensator::{Compensator, Config, SampleError, Status};
use qfa_thermal::ds18b20::{self, Resolution};
use qfa_thermal::ds18b20_driver::{self as drv, Ds18b20};
use qfa_thermal::onewire as ow;
use qfa_thermal::Table;

/// Scheduler tick (IMU cycle), µs.
const TICK_US: u64 = 5_000;
/// Simulated run length, s.
const RUN_S: u64 = 3_600;
/// A fault event every this many seconds (the kinds in turn).
const FAULT_EVERY_S: u64 = 15;
/// Tolerance of the compensator's temperature estimate against the truth at its
/// timestamp, °C: rounding to 1/16 °C is ±1/32 °C, and the least-squares line evaluated
/// at its newest sample amplifies a worst-case quantization pattern by at most 2
/// (sum of the absolute endpoint weights), so 2/32 °C; plus 0.0125 °C for the fit's
/// curvature bias on the sine (< 0.005 °C over a 32 s window), the read-time vs.
/// completion-time skew (≤ 10 ms at < 1 °C/min) and f32 rounding.
const TOL_C: f64 = 2.0 / 32.0 + 0.0125;
/// Pulses of a fixed probe cycle: the compensation in force, independent of the input.
const PROBE: [i32; 3] = [320_000, -160_000, 80_000];

/// The simulated true temperature: 25 ± 8 °C over an hour (at most 0.84 °C/min).
fn truth_c(t_us: u64) -> f64 {
    let t = t_us as f64 * 1e-6;
    25.0 + 8.0 * (2.0 * std::f64::consts::PI * t / 3600.0).sin()
}

fn truth_raw(t_us: u64) -> i16 {
    (truth_c(t_us) * 16.0).round() as i16
}

/// An error's variant, without its fields.
fn kind_name(e: &dyn std::fmt::Debug) -> String {
    let s = format!("{e:?}");
    s.split(" {").next().unwrap_or(&s).to_string()
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Kind {
    /// One flipped scratchpad bit, within the retry budget (retries = 1).
    FlipRetried,
    /// The same bit flipped on two reads: beyond the budget.
    FlipExhausted,
    /// The sensor stops answering resets for 0.8–12 s.
    NoPresence,
    /// The line is held low for 0.8–8 s.
    StuckLow,
    /// A brown-out during a conversion: power-on scratchpad, then the EEPROM resolution.
    BrownOut,
    /// Every pin call fails for 0.8–3 s.
    PinError,
    /// The sensor measures +3 °C for one conversion (interference): CRC-valid, wrong.
    Spike,
    /// No presence for 45 s: a dropout longer than the rate window's gap limit.
    Dropout,
}

const KINDS: [Kind; 8] = [
    Kind::FlipRetried,
    Kind::FlipExhausted,
    Kind::NoPresence,
    Kind::StuckLow,
    Kind::BrownOut,
    Kind::PinError,
    Kind::Spike,
    Kind::Dropout,
];

#[derive(Debug, Default)]
struct Event {
    kind: Option<Kind>,
    /// Simulated µs when the fault is cleared (bus faults).
    clear_at_us: u64,
    driver_errors: Vec<drv::Error>,
    sample_errors: Vec<SampleError>,
    true_readings_during: u32,
    stale_seen: bool,
    /// The event is over: the fault is cleared and a good reading came after it.
    closed: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum App {
    /// Start a conversion at or after this time (µs).
    Idle {
        at_us: u64,
    },
    Converting,
}

#[allow(clippy::too_many_lines)]
#[test]
fn driver_and_compensator_come_through_every_fault() {
    let mut rng = qfa_rng::seeded(0x0DD5_EED5);
    let mut dev = Device::ds18b20(0x0042_1E55, truth_raw(0));
    // EEPROM holds 11 bits, so a brown-out also reverts the resolution the driver set.
    dev.eeprom = [0x4B, 0x46, Resolution::Bits11.config_byte()];
    let sim = Sim::new(vec![dev]);
    let mut bus = sim.bus();
    let mut sensor = Ds18b20::single().with_retries(1);
    sensor.set_resolution(&mut bus, Resolution::Bits12).unwrap();

    let mut comp = Compensator::<3, 32, 1, Table, 3>::new(Config::default()).expect("the default config is valid");
    comp.load_table(&stream_table()).unwrap();
    let stale_after_us = u64::from(comp.config().stale_after_ticks); // 1 tick = 1 µs
    let probe = |c: &Compensator<3, 32, 1, Table, 3>| c.clone().cycle(PROBE, 2_500).dv_mps;

    let mut clock = qfa_thermal::time::MsClock::new();
    let mut app = App::Idle { at_us: 0 };
    let mut last_cycle_ns = sim.now_ns();
    let mut last_good_us: Option<u64> = None;
    let mut probe_at_last_good = probe(&comp);
    let mut spike_pending = false;
    let mut events: Vec<Event> = vec![Event { closed: true, ..Event::default() }];
    let mut next_fault_us = 20_000_000u64; // after the estimator has warmed up
    let mut kind_i = 0usize;

    let (mut good, mut max_err_c, mut max_rate_err) = (0u32, 0.0f64, 0.0f64);
    let (mut stale_cycles, mut cycles) = (0u64, 0u64);
    let mut stale_periods = 0u32;
    let mut was_stale = false;
    let mut driver_error_kinds: BTreeMap<String, u32> = BTreeMap::new();
    let mut sample_error_kinds: BTreeMap<String, u32> = BTreeMap::new();

    while sim.now_ns() < RUN_S * 1_000_000_000 {
        let tick_start_ns = sim.now_ns();
        let now_us = tick_start_ns / 1000;
        // The device measures the truth (plus a pending spike).
        sim.with(|w| w.devices[0].temp_raw = truth_raw(now_us) + if spike_pending { 48 } else { 0 });

        // Clear a bus fault whose time is up.
        let ev = events.last_mut().unwrap();
        if !ev.closed && ev.clear_at_us != 0 && now_us >= ev.clear_at_us {
            sim.with(|w| {
                w.devices[0].present = true;
                w.stuck_low_at_ns = None;
                w.pin_error = false;
            });
            ev.clear_at_us = 0;
        }

        // Inject the next fault right after a conversion started, so the read sees it.
        if app == App::Converting && now_us >= next_fault_us && events.last().unwrap().closed {
            let kind = KINDS[kind_i % KINDS.len()];
            kind_i += 1;
            next_fault_us = now_us + FAULT_EVERY_S * 1_000_000;
            let dur_us = |lo: f64, hi: f64, rng: &mut LabRng| ((lo + (hi - lo) * qfa_rng::uniform(rng)) * 1e6) as u64;
            let mut ev = Event { kind: Some(kind), ..Event::default() };
            match kind {
                Kind::FlipRetried | Kind::FlipExhausted => {
                    let bit = (qfa_rng::uniform(&mut rng) * 72.0) as usize;
                    sim.with(|w| {
                        w.devices[0].flip_bit = bit;
                        w.devices[0].flip_times = if kind == Kind::FlipRetried { 1 } else { 2 };
                    });
                }
                Kind::NoPresence => {
                    ev.clear_at_us = now_us + dur_us(0.8, 12.0, &mut rng);
                    sim.with(|w| w.devices[0].present = false);
                }
                Kind::Dropout => {
                    ev.clear_at_us = now_us + 45_000_000;
                    sim.with(|w| w.devices[0].present = false);
                }
                Kind::StuckLow => {
                    ev.clear_at_us = now_us + dur_us(0.8, 8.0, &mut rng);
                    sim.with(|w| w.stuck_low_at_ns = Some(w.now_ns));
                }
                Kind::PinError => {
                    ev.clear_at_us = now_us + dur_us(0.8, 3.0, &mut rng);
                    sim.with(|w| w.pin_error = true);
                }
                Kind::BrownOut => {
                    let at = sim.now_ns() + (qfa_rng::uniform(&mut rng) * 700e6) as u64;
                    sim.with(|w| w.devices[0].brown_out_at_ns = Some(at));
                }
                Kind::Spike => {
                    spike_pending = true;
                    sim.with(|w| w.devices[0].temp_raw += 48);
                }
            }
            events.push(ev);
        }

        // The slow path: the driver's non-blocking state machine.
        match app {
            App::Idle { at_us } if now_us >= at_us => match sensor.start(&mut bus, sim.now_us()) {
                Ok(()) => app = App::Converting,
                Err(e) => {
                    *driver_error_kinds.entry(kind_name(&e)).or_default() += 1;
                    events.last_mut().unwrap().driver_errors.push(e);
                    app = App::Idle { at_us: now_us + 100_000 };
                }
            },
            App::Idle { .. } => {}
            App::Converting => match sensor.is_ready(&mut bus, sim.now_us()) {
                Ok(false) => {}
                Ok(true) => {
                    let measured = sim.with(|w| w.devices[0].temp_raw);
                    let result = sensor.read(&mut bus);
                    app = App::Idle { at_us: 0 };
                    let ev = events.last_mut().unwrap();
                    match result {
                        Ok(s) => {
                            // Never a wrong temperature from the driver: exactly what the device measured.
                            assert_eq!(s.reading.raw, measured, "driver returned a value the sensor did not measure");
                            spike_pending = false;
                            let t_ms = clock.ms(s.completed_us);
                            match comp.on_scratchpad(0, t_ms, &s.scratchpad) {
                                Ok(_) => {
                                    assert_ne!(measured, truth_raw(now_us) + 48, "a spike was accepted");
                                    good += 1;
                                    ev.true_readings_during += 1;
                                    let t_done = u64::from(s.completed_us);
                                    last_good_us = Some(t_done);
                                    let est = comp.estimate().expect("a good reading leaves an estimate");
                                    let err = (f64::from(est.temp_c) - truth_c(t_done)).abs();
                                    max_err_c = max_err_c.max(err);
                                    assert!(
                                        err <= TOL_C,
                                        "estimate {} °C vs truth {:.4} °C at {t_done} µs",
                                        est.temp_c,
                                        truth_c(t_done)
                                    );
                                    if est.ready {
                                        let rate = (truth_c(t_done + 1_000) - truth_c(t_done - 1_000)) / 2e-3 * 60.0;
                                        max_rate_err = max_rate_err.max((f64::from(est.rate_c_per_min) - rate).abs());
                                    }
                                    probe_at_last_good = probe(&comp);
                                    if ev.kind.is_some() && ev.clear_at_us == 0 && ev.true_readings_during > 0 {
                                        ev.closed = true;
                                    }
                                }
                                Err(e) => {
                                    *sample_error_kinds.entry(kind_name(&e)).or_default() += 1;
                                    ev.sample_errors.push(e);
                                    assert!(comp.status().contains(Status::TEMP_INVALID));
                                    assert_eq!(
                                        probe(&comp),
                                        probe_at_last_good,
                                        "a rejected reading changed the compensation"
                                    );
                                }
                            }
                        }
                        Err(e) => {
                            *driver_error_kinds.entry(kind_name(&e)).or_default() += 1;
                            ev.driver_errors.push(e);
                            if let drv::Error::ResolutionChanged(_) = e {
                                // The documented recovery: set the resolution again.
                                if let Err(e2) = sensor.set_resolution(&mut bus, Resolution::Bits12) {
                                    ev.driver_errors.push(e2);
                                }
                            }
                        }
                    }
                }
                Err(e) => {
                    *driver_error_kinds.entry(kind_name(&e)).or_default() += 1;
                    events.last_mut().unwrap().driver_errors.push(e);
                    app = App::Idle { at_us: now_us + 100_000 };
                }
            },
        }

        // The fast path, with the real elapsed time (bus transactions included).
        let dt_ticks = u32::try_from((sim.now_ns() - last_cycle_ns) / 1000).unwrap();
        last_cycle_ns = sim.now_ns();
        let out = comp.cycle(PROBE, dt_ticks);
        cycles += 1;
        assert!(out.dv_mps.iter().all(|v| v.is_finite()));
        let now_us = sim.now_ns() / 1000;
        let since = last_good_us.map_or(u64::MAX, |t| now_us - t);
        let stale = out.status.contains(Status::TEMP_STALE);
        if let Some(t) = last_good_us {
            // The fast path counts whole cycles since the reading was passed to it (the
            // cycle that follows a reading counts in full), so the flag's onset has one
            // cycle of granularity around the 3 s limit.
            if since > stale_after_us + 2 * TICK_US {
                assert!(stale, "{since} µs without a reading and not stale");
            }
            if since + 2 * TICK_US <= stale_after_us {
                assert!(!stale, "stale only {since} µs after the last good reading at {t}");
            }
        }
        if stale {
            stale_cycles += 1;
            events.last_mut().unwrap().stale_seen = true;
            // Stale: flagged only, the compensation is the one of the last good reading.
            assert_eq!(probe(&comp), probe_at_last_good, "stale changed the compensation");
            if !was_stale {
                stale_periods += 1;
            }
        }
        was_stale = stale;
        sim.idle_us(TICK_US.saturating_sub((sim.now_ns() - tick_start_ns) / 1000));
    }

    // Every fault event was flagged: a typed driver error or a compensator SampleError,
    // except a flip within the retry budget, which must have given the true value.
    let mut table: BTreeMap<Kind, [u32; 4]> = BTreeMap::new();
    for ev in events.iter().skip(1) {
        let kind = ev.kind.unwrap();
        let flagged = !ev.driver_errors.is_empty() || !ev.sample_errors.is_empty();
        let row = table.entry(kind).or_default();
        row[0] += 1;
        row[1] += u32::from(flagged);
        row[2] += u32::from(ev.stale_seen);
        match kind {
            Kind::FlipRetried => {
                assert!(ev.driver_errors.is_empty() && ev.true_readings_during > 0, "{ev:?}");
                row[3] += 1;
            }
            Kind::FlipExhausted => {
                assert!(matches!(ev.driver_errors[..], [drv::Error::Scratchpad(ds18b20::Error::Crc { .. })]), "{ev:?}");
            }
            Kind::NoPresence | Kind::Dropout => {
                assert!(
                    ev.driver_errors.iter().all(|e| *e == drv::Error::Bus(ow::Error::NoPresence)) && flagged,
                    "{ev:?}"
                );
            }
            Kind::StuckLow => {
                assert!(ev.driver_errors.contains(&drv::Error::Bus(ow::Error::BusStuckLow)), "{ev:?}");
            }
            Kind::PinError => {
                assert!(ev.driver_errors.iter().all(|e| *e == drv::Error::Bus(ow::Error::Pin)) && flagged, "{ev:?}");
            }
            Kind::BrownOut => {
                assert!(ev.driver_errors.contains(&drv::Error::Scratchpad(ds18b20::Error::PowerOn)), "{ev:?}");
                assert!(ev.driver_errors.contains(&drv::Error::ResolutionChanged(Resolution::Bits11)), "{ev:?}");
            }
            Kind::Spike => {
                assert!(matches!(ev.sample_errors[..], [SampleError::Implausible { .. }]), "{ev:?}");
            }
        }
        if kind != Kind::FlipRetried {
            assert!(flagged, "fault not flagged: {ev:?}");
        }
        if kind == Kind::Dropout {
            assert!(ev.stale_seen, "45 s dropout not flagged stale: {ev:?}");
        }
    }

    println!("driver + compensator, {RUN_S} s simulated, {cycles} cycles, {good} good readings");
    println!(
        "max |T̂ − T| = {max_err_c:.4} °C (tolerance {TOL_C:.4}); max |Ṫ̂ − Ṫ| = {max_rate_err:.3} °C/min when ready"
    );
    println!("stale cycles {stale_cycles} in {stale_periods} periods");
    println!("fault            events flagged stale retried");
    for (k, r) in &table {
        println!("{:<16} {:>6} {:>7} {:>5} {:>7}", format!("{k:?}"), r[0], r[1], r[2], r[3]);
    }
    println!("driver errors: {driver_error_kinds:?}");
    println!("compensator errors: {sample_error_kinds:?}");
    assert_eq!(table.len(), KINDS.len(), "every fault kind injected");
    assert!(table.values().all(|r| r[0] >= 10), "each kind at least 10 times: {table:?}");
    assert!(stale_periods >= 10);
    assert!(good > 2_500);
}
