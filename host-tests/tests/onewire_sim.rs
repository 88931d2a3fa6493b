//! The DS18B20 driver against the bit-level bus simulation: timing within the
//! datasheet limits, SEARCH ROM, resolutions, the non-blocking state machine, and
//! every injected fault giving a typed error, never a wrong temperature.

use host_tests::onewire_sim::{sim_slot_lock, Device, Interrupt, Sim, SimDelay, SimPin};
use qfa_thermal::ds18b20::{self, Resolution};
use qfa_thermal::ds18b20_driver::{self as drv, Ds18b20, PowerSupply, Sample};
use qfa_thermal::onewire::{self as ow, Rom};

const RESOLUTIONS: [Resolution; 4] = [Resolution::Bits9, Resolution::Bits10, Resolution::Bits11, Resolution::Bits12];

/// Datasheet Table 1 (raw, °C).
const TABLE: [(i16, f32); 10] = [
    (0x07D0, 125.0),
    (0x0550, 85.0),
    (0x0191, 25.0625),
    (0x00A2, 10.125),
    (0x0008, 0.5),
    (0x0000, 0.0),
    (-0x0008, -0.5),
    (-0x00A2, -10.125),
    (-0x0191, -25.0625),
    (-0x0370, -55.0),
];

/// The temperature a sensor at `raw` reports at `res`: truncated toward −∞ to the
/// resolution step (independent of the decoder's mask).
fn expected_celsius(raw: i16, res: Resolution) -> f32 {
    let step = match res {
        Resolution::Bits9 => 0.5,
        Resolution::Bits10 => 0.25,
        Resolution::Bits11 => 0.125,
        Resolution::Bits12 => 0.0625,
    };
    ((f64::from(raw) / 16.0 / step).floor() * step) as f32
}

fn assert_no_violations(sim: &Sim) {
    assert_eq!(sim.violations(), Vec::<String>::new(), "master timing outside datasheet limits");
}

/// Run one sensor to a successful reading, for setup.
fn ok_measure(sim: &Sim, sensor: &mut Ds18b20) -> Sample {
    let mut bus = sim.bus();
    sensor.measure(&mut bus, sim.now_us()).unwrap()
}

#[test]
fn presence_and_read_rom_at_worst_case_device_timing() {
    let sim = Sim::new(vec![Device::ds18b20(0x0316_0F1E_64FF, 0x0191)]);
    let mut bus = sim.bus();
    assert_eq!(bus.reset(), Ok(()));
    let rom = bus.read_rom().unwrap();
    assert_eq!(rom.bytes(), sim.with(|w| w.devices[0].rom));
    assert_eq!(rom.family(), 0x28);
    assert_no_violations(&sim);
}

#[test]
fn empty_bus_has_no_presence() {
    let sim = Sim::new(vec![]);
    let mut bus = sim.bus();
    assert_eq!(bus.reset(), Err(ow::Error::NoPresence));
    assert_eq!(bus.search::<4>(None), Err(ow::Error::NoPresence));
}

#[test]
fn search_finds_every_device_and_filters_family() {
    let serials = [0x0000_0000_0001u64, 0x8000_0000_0001, 0x0000_00FF_0000, 0x1234_5678_9ABC, 0x1234_5678_9ABD];
    let mut devices: Vec<Device> = serials.iter().map(|&s| Device::ds18b20(s, 0x0191)).collect();
    devices.push(Device::with_family(0x10, 0x0000_0000_0001, 0)); // a DS18S20 on the same bus
    let sim = Sim::new(devices);
    let mut expected: Vec<[u8; 8]> = sim.with(|w| w.devices.iter().map(|d| d.rom).collect());
    expected.sort();

    let mut bus = sim.bus();
    let mut all: Vec<[u8; 8]> = bus.search::<8>(None).unwrap().iter().map(Rom::bytes).collect();
    all.sort();
    assert_eq!(all, expected);

    let sensors = Ds18b20::search::<_, _, 8>(&mut bus).unwrap();
    assert_eq!(sensors.len(), 5);
    assert!(sensors.iter().all(|s| s.rom().unwrap().family() == 0x28));

    assert_eq!(bus.search::<4>(None), Err(ow::Error::TooManyDevices));
    assert_no_violations(&sim);
}

#[test]
fn every_resolution_and_datasheet_temperature_through_match_rom() {
    for res in RESOLUTIONS {
        for (raw, c12) in TABLE {
            let sim = Sim::new(vec![Device::ds18b20(7, raw), Device::ds18b20(8, 0x0123)]);
            let mut bus = sim.bus();
            let rom = bus.search::<2>(Some(0x28)).unwrap()[0];
            let mut sensor = Ds18b20::new(rom).unwrap();
            let own = sim.with(|w| w.devices.iter().position(|d| d.rom == rom.bytes()).unwrap());
            sim.with(|w| w.devices[1 - own].temp_raw = 0x0123);
            sim.with(|w| w.devices[own].temp_raw = raw);
            sensor.set_resolution(&mut bus, res).unwrap();
            let t0 = sim.now_ns();
            let s = sensor.measure(&mut bus, sim.now_us()).unwrap();
            let took_us = (sim.now_ns() - t0) / 1000;
            let want = expected_celsius(raw, res);
            assert_eq!(s.reading.celsius(), want, "{res:?} raw {raw:04X}");
            if res == Resolution::Bits12 {
                assert_eq!(s.reading.celsius(), c12);
            }
            assert!(took_us <= u64::from(Ds18b20::max_blocking_measure_us(res, 1)), "{took_us} µs");
            assert_no_violations(&sim);
        }
    }
}

#[test]
fn non_blocking_state_machine_by_timer() {
    let sim = Sim::new(vec![Device::ds18b20(1, -0x00A2)]);
    let mut bus = sim.bus();
    let mut sensor = Ds18b20::single();
    sensor.set_resolution(&mut bus, Resolution::Bits11).unwrap();
    let start = sim.now_us();
    sensor.start(&mut bus, start).unwrap();
    let mut polls = 0;
    // A 1 ms scheduler tick; the loop ends by the datasheet maximum (375 ms).
    while !sensor.is_ready(&mut bus, sim.now_us()).unwrap() {
        polls += 1;
        assert!(polls <= 400, "never ready");
        sim.idle_us(1_000);
    }
    assert!(sim.now_us() - start >= 375_000);
    let s = sensor.read(&mut bus).unwrap();
    assert_eq!(s.reading.celsius(), -10.125);
    assert_eq!(s.completed_us, start + 375_000);
    assert_no_violations(&sim);
}

#[test]
fn read_slot_polling_finishes_early_when_externally_powered() {
    let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
    sim.with(|w| w.devices[0].conversion_fraction = 0.5);
    let mut bus = sim.bus();
    let mut sensor = Ds18b20::single();
    assert_eq!(sensor.use_read_slots(&mut bus), Ok(PowerSupply::External));
    let start = sim.now_us();
    sensor.start(&mut bus, start).unwrap();
    let mut polls = 0;
    while !sensor.is_ready(&mut bus, sim.now_us()).unwrap() {
        polls += 1;
        assert!(polls <= 800);
        sim.idle_us(1_000);
    }
    let s = sensor.read(&mut bus).unwrap();
    assert_eq!(s.reading.celsius(), 25.0625);
    let took = s.completed_us - start;
    assert!((375_000..390_000).contains(&took), "completed after {took} µs, device takes 375 ms");
    assert_no_violations(&sim);
}

#[test]
fn parasite_sensor_keeps_the_timer() {
    let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
    sim.with(|w| w.devices[0].parasite = true);
    let mut bus = sim.bus();
    let mut sensor = Ds18b20::single();
    assert_eq!(sensor.use_read_slots(&mut bus), Ok(PowerSupply::Parasite));
    let start = sim.now_us();
    sensor.start(&mut bus, start).unwrap();
    sim.idle_us(1_000);
    // A parasite device does not drive read slots: polling would say "done" at once.
    assert_eq!(sensor.is_ready(&mut bus, sim.now_us()), Ok(false));
    sim.idle_us(750_000);
    assert_eq!(sensor.is_ready(&mut bus, sim.now_us()), Ok(true));
    assert_eq!(sensor.read(&mut bus).unwrap().reading.celsius(), 25.0625);
}

#[test]
fn convert_all_then_read_each() {
    let temps = [0x0191i16, -0x0191, 0x07D0];
    let sim = Sim::new(temps.iter().enumerate().map(|(i, &t)| Device::ds18b20(i as u64 + 1, t)).collect());
    let mut bus = sim.bus();
    let mut sensors = Ds18b20::search::<_, _, 4>(&mut bus).unwrap();
    Ds18b20::start_all(&mut bus, &mut sensors, sim.now_us()).unwrap();
    sim.idle_us(750_000);
    for s in &mut sensors {
        assert!(s.is_ready(&mut bus, sim.now_us()).unwrap());
        let sample = s.read(&mut bus).unwrap();
        let dev = sim.with(|w| w.devices.iter().find(|d| d.rom == s.rom().unwrap().bytes()).unwrap().temp_raw);
        assert_eq!(sample.reading.celsius(), f32::from(dev) / 16.0);
    }
    assert_no_violations(&sim);
}

// ---------- Faults ----------

/// Start, poll every millisecond (the driver's non-blocking recipe), read.
fn convert_and_read(
    sim: &Sim,
    bus: &mut ow::OneWire<SimPin, SimDelay>,
    sensor: &mut Ds18b20,
) -> Result<Sample, drv::Error> {
    sensor.start(bus, sim.now_us())?;
    for _ in 0..2_000 {
        if sensor.is_ready(bus, sim.now_us())? {
            return sensor.read(bus);
        }
        sim.idle_us(1_000);
    }
    panic!("not ready after 2 s");
}

/// Scenario 5, a frozen sensor: a Convert T the sensor never took (dropped here by the
/// simulator) leaves the previous conversion in the scratchpad, CRC good. Read after it,
/// that conversion came back as a new sample with a fresh timestamp, and so on for every
/// lost command: the status stayed OK on a value that no longer moved. With read slots,
/// the slot right after Convert T must read 0 (converting); a 1 means the command was
/// not taken, and the driver says so instead of reading.
#[test]
fn frozen_sensor_lost_convert_t_is_a_typed_error_not_the_previous_sample() {
    let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
    let mut bus = sim.bus();
    let mut sensor = Ds18b20::single();
    assert_eq!(sensor.use_read_slots(&mut bus), Ok(PowerSupply::External));
    assert_eq!(convert_and_read(&sim, &mut bus, &mut sensor).map(|s| s.reading.raw), Ok(0x0191));

    // The case warms by 1 °C, and the next Convert T is lost.
    sim.with(|w| {
        w.devices[0].temp_raw = 0x01A1;
        w.devices[0].drop_convert_t = 1;
    });
    sim.idle_us(200_000);
    assert_eq!(convert_and_read(&sim, &mut bus, &mut sensor), Err(drv::Error::ConversionNotStarted));
    // Nothing is left to read: the lost conversion is never delivered later either.
    assert_eq!(sensor.read(&mut bus), Err(drv::Error::NotStarted));
    // The next command is taken: the new temperature.
    assert_eq!(convert_and_read(&sim, &mut bus, &mut sensor).map(|s| s.reading.raw), Ok(0x01A1));

    // `measure` starts again within its retry budget (1 retry), and gives up past it.
    sim.with(|w| {
        w.devices[0].temp_raw = 0x01B1;
        w.devices[0].drop_convert_t = 1;
    });
    assert_eq!(sensor.measure(&mut bus, sim.now_us()).map(|s| s.reading.raw), Ok(0x01B1));
    sim.with(|w| w.devices[0].drop_convert_t = 2);
    assert_eq!(sensor.measure(&mut bus, sim.now_us()), Err(drv::Error::ConversionNotStarted));
    assert_no_violations(&sim);
}

/// `start_all` on externally powered sensors: every command lost is seen (the slot after
/// it reads 1); one lost among three is not (the others drive it to 0), as documented.
#[test]
fn frozen_sensor_start_all_sees_only_every_command_lost() {
    let sim = Sim::new((1..=3).map(|i| Device::ds18b20(i, 0x0191)).collect());
    let mut bus = sim.bus();
    let mut sensors = Ds18b20::search::<_, _, 4>(&mut bus).unwrap();
    for s in &mut sensors {
        assert_eq!(s.use_read_slots(&mut bus), Ok(PowerSupply::External));
    }
    sim.with(|w| w.devices.iter_mut().for_each(|d| d.drop_convert_t = 1));
    assert_eq!(Ds18b20::start_all(&mut bus, &mut sensors, sim.now_us()), Err(drv::Error::ConversionNotStarted));
    assert!(sensors.iter_mut().all(|s| s.read(&mut bus) == Err(drv::Error::NotStarted)));
    sim.with(|w| w.devices[1].drop_convert_t = 1);
    assert_eq!(Ds18b20::start_all(&mut bus, &mut sensors, sim.now_us()), Ok(()));
    assert_no_violations(&sim);
}

/// Scenario 5, the other way to freeze: a conversion that starts and never ends (here
/// five times the datasheet maximum). Judged by the timer, the read after 750 ms returned
/// the previous conversion. Judged by the read slot, the sensor is still converting past
/// the maximum, which is a typed error.
#[test]
fn frozen_sensor_conversion_that_never_ends_is_overdue_not_the_previous_sample() {
    let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
    let mut bus = sim.bus();
    let mut sensor = Ds18b20::single();
    assert_eq!(sensor.use_read_slots(&mut bus), Ok(PowerSupply::External));
    assert_eq!(convert_and_read(&sim, &mut bus, &mut sensor).map(|s| s.reading.raw), Ok(0x0191));
    sim.with(|w| {
        w.devices[0].temp_raw = 0x01A1;
        w.devices[0].conversion_fraction = 5.0;
    });
    let start = sim.now_us();
    assert_eq!(convert_and_read(&sim, &mut bus, &mut sensor), Err(drv::Error::ConversionOverdue));
    let waited = sim.now_us() - start;
    // Not before the datasheet maximum and its margin, and not much after.
    assert!((825_000..830_000).contains(&waited), "overdue after {waited} µs");
    assert_eq!(sensor.read(&mut bus), Err(drv::Error::NotStarted));
    // `measure` waits the maximum, sees the sensor still converting, and does not read.
    assert_eq!(sensor.measure(&mut bus, sim.now_us()), Err(drv::Error::ConversionOverdue));
    assert_no_violations(&sim);
}

/// A parasite-powered sensor cannot tell a lost conversion (it does not drive read
/// slots while converting), so `use_read_slots` leaves it on the timer, and a lost
/// Convert T still gives the previous value: why the board refuses such a sensor.
#[test]
fn parasite_sensor_cannot_see_a_lost_convert_t() {
    let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
    sim.with(|w| w.devices[0].parasite = true);
    let mut bus = sim.bus();
    let mut sensor = Ds18b20::single();
    assert_eq!(sensor.use_read_slots(&mut bus), Ok(PowerSupply::Parasite));
    assert_eq!(convert_and_read(&sim, &mut bus, &mut sensor).map(|s| s.reading.raw), Ok(0x0191));
    sim.with(|w| {
        w.devices[0].temp_raw = 0x01A1;
        w.devices[0].drop_convert_t = 1;
    });
    assert_eq!(convert_and_read(&sim, &mut bus, &mut sensor).map(|s| s.reading.raw), Ok(0x0191));
}

/// `read_keeping_bytes` gives back a scratchpad that failed decoding, so the caller can
/// hand it to the compensator (which rejects it with the same typed error), and no bytes
/// when nothing was read.
#[test]
fn read_keeping_bytes_gives_the_failed_scratchpad_and_only_that() {
    let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
    let mut bus = sim.bus();
    let mut sensor = Ds18b20::single().with_retries(1);
    // The CRC byte's lowest bit, flipped on the read and on its retry.
    sim.with(|w| {
        w.devices[0].flip_bit = 64;
        w.devices[0].flip_times = 2;
    });
    sensor.start(&mut bus, sim.now_us()).unwrap();
    sim.idle_us(750_000);
    assert!(sensor.is_ready(&mut bus, sim.now_us()).unwrap());
    let f = sensor.read_keeping_bytes(&mut bus).unwrap_err();
    let sp = f.scratchpad.expect("the bytes that failed");
    assert_eq!(f.error, drv::Error::Scratchpad(ds18b20::decode_scratchpad(&sp).unwrap_err()));
    assert!(matches!(f.error, drv::Error::Scratchpad(ds18b20::Error::Crc { .. })), "{f:?}");
    assert_eq!(sp[..8], sim.with(|w| w.devices[0].scratchpad()));

    // No presence: an error without bytes.
    sensor.start(&mut bus, sim.now_us()).unwrap();
    sim.idle_us(750_000);
    assert!(sensor.is_ready(&mut bus, sim.now_us()).unwrap());
    sim.with(|w| w.devices[0].present = false);
    let f = sensor.read_keeping_bytes(&mut bus).unwrap_err();
    assert_eq!(f, drv::ReadFailure { error: drv::Error::Bus(ow::Error::NoPresence), scratchpad: None });
}

/// Scenario 8(c): an interrupt inside a slot. A 12 µs handler every 997 µs (a period that
/// walks across every slot phase) lands between some slots' falling edge and their sample:
/// without the slot lock the sample comes after the device's 15 µs window (a 0 reads 1)
/// and a write-1 is held low past 15 µs (written as 0). With the lock, the interrupt waits
/// for the locked part of the slot (at most 10 µs of delay) and then runs.
#[test]
fn interrupt_cannot_stretch_a_slot_under_the_slot_lock() {
    let reads = |locked: bool| {
        let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
        let bus = sim.bus();
        let mut bus = if locked { bus.with_slot_lock(sim_slot_lock) } else { bus };
        let mut sensor = Ds18b20::single().with_retries(0);
        sensor.measure(&mut bus, sim.now_us()).unwrap();
        sim.with(|w| w.interrupt = Some(Interrupt { next_ns: w.now_ns, period_ns: 997_000, duration_ns: 12_000 }));
        let mut bad = 0;
        for _ in 0..300 {
            match sensor.read_scratchpad(&mut bus) {
                Ok((_, r)) if r.raw == 0x0191 => {}
                _ => bad += 1,
            }
        }
        let (stretching, deferred) = sim.with(|w| (w.interrupts_stretching, w.interrupts_deferred));
        (bad, sim.violations(), stretching, deferred)
    };
    // Without the lock (the bus as it was): wrong bits and late samples.
    let (bad, violations, stretching, deferred) = reads(false);
    println!(
        "without the lock: {bad} bad reads of 300, {} violations, {stretching} interrupts held the master up",
        violations.len()
    );
    assert!(bad >= 10, "{bad} bad reads of 300");
    assert!(violations.iter().any(|v| v.starts_with("read sampled")), "{violations:?}");
    assert!(violations.iter().any(|v| v.starts_with("write low")), "{violations:?}");
    assert_eq!(deferred, 0);
    // With it: every read right, every slot in time, and interrupts did come inside locked
    // parts (and waited), while others still ran between slots.
    let (bad, violations, stretching, deferred) = reads(true);
    assert_eq!((bad, violations), (0, Vec::<String>::new()));
    println!(
        "with the lock: {deferred} interrupts waited for a locked part, {stretching} held the master up elsewhere"
    );
    assert!(deferred >= 50 && stretching >= 50, "{deferred} deferred, {stretching} in between");
}

/// Without retries, a flip of any of the 72 scratchpad bits is a typed error.
#[test]
fn fault_flipped_scratchpad_bit_is_an_error_without_retries() {
    for bit in 0..72 {
        let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
        let mut sensor = Ds18b20::single().with_retries(0);
        ok_measure(&sim, &mut sensor);
        sim.with(|w| {
            w.devices[0].flip_bit = bit;
            w.devices[0].flip_times = 1;
        });
        let mut bus = sim.bus();
        let r = sensor.measure(&mut bus, sim.now_us());
        assert!(matches!(r, Err(drv::Error::Scratchpad(ds18b20::Error::Crc { .. }))), "bit {bit}: {r:?}");
    }
}

/// With one retry, a single flipped read is re-read and the true value returned.
#[test]
fn fault_flipped_scratchpad_bit_is_retried() {
    for bit in 0..72 {
        let sim = Sim::new(vec![Device::ds18b20(1, -0x0191)]);
        let mut sensor = Ds18b20::single().with_retries(1);
        let mut bus = sim.bus();
        sensor.start(&mut bus, sim.now_us()).unwrap();
        sim.idle_us(750_000);
        assert!(sensor.is_ready(&mut bus, sim.now_us()).unwrap());
        sim.with(|w| {
            w.devices[0].flip_bit = bit;
            w.devices[0].flip_times = 1;
        });
        assert_eq!(sensor.read(&mut bus).unwrap().reading.celsius(), -25.0625, "bit {bit}");
        // Two bad reads exceed one retry.
        sensor.start(&mut bus, sim.now_us()).unwrap();
        sim.idle_us(750_000);
        assert!(sensor.is_ready(&mut bus, sim.now_us()).unwrap());
        sim.with(|w| w.devices[0].flip_times = 2);
        assert!(matches!(sensor.read(&mut bus), Err(drv::Error::Scratchpad(ds18b20::Error::Crc { .. }))));
    }
}

#[test]
fn fault_flipped_rom_bit() {
    for bit in 0..64 {
        let sim = Sim::new(vec![Device::ds18b20(0xABCDEF, 0)]);
        sim.with(|w| {
            w.devices[0].flip_bit = bit;
            w.devices[0].flip_times = 1;
        });
        let mut bus = sim.bus();
        let r = bus.read_rom();
        assert!(matches!(r, Err(ow::Error::RomCrc { .. })), "bit {bit}: {r:?}");
        // In a search pass the flip hits bit or complement slot `bit`.
        sim.with(|w| w.devices[0].flip_times = 1);
        let r = bus.search::<2>(None);
        assert!(
            matches!(r, Err(ow::Error::SearchNoResponse | ow::Error::SearchInconsistent | ow::Error::RomCrc { .. })),
            "search slot {bit}: {r:?}"
        );
    }
}

#[test]
fn fault_no_presence() {
    let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
    let mut sensor = Ds18b20::single();
    ok_measure(&sim, &mut sensor);
    sim.with(|w| w.devices[0].present = false);
    let mut bus = sim.bus();
    let e = Err(drv::Error::Bus(ow::Error::NoPresence));
    assert_eq!(sensor.measure(&mut bus, sim.now_us()), e);
    assert_eq!(sensor.start(&mut bus, sim.now_us()), Err(drv::Error::Bus(ow::Error::NoPresence)));
    assert_eq!(sensor.set_resolution(&mut bus, Resolution::Bits9), Err(drv::Error::Bus(ow::Error::NoPresence)));

    // Disappears between start and read.
    sim.with(|w| w.devices[0].present = true);
    sensor.start(&mut bus, sim.now_us()).unwrap();
    sim.idle_us(750_000);
    assert!(sensor.is_ready(&mut bus, sim.now_us()).unwrap());
    sim.with(|w| w.devices[0].present = false);
    assert_eq!(sensor.read(&mut bus), Err(drv::Error::Bus(ow::Error::NoPresence)));
}

#[test]
fn fault_stuck_low_bus() {
    let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
    let mut sensor = Ds18b20::single();
    ok_measure(&sim, &mut sensor);
    sim.with(|w| w.stuck_low_at_ns = Some(w.now_ns));
    let mut bus = sim.bus();
    let stuck = Err(drv::Error::Bus(ow::Error::BusStuckLow));
    assert_eq!(sensor.measure(&mut bus, sim.now_us()), stuck);
    assert_eq!(bus.search::<2>(None), Err(ow::Error::BusStuckLow));
    assert_eq!(sensor.read_power_supply(&mut bus), Err(drv::Error::Bus(ow::Error::BusStuckLow)));
}

/// The line sticks low in the middle of a scratchpad transfer, at every bit position:
/// the partial read fails its checks and the retry finds the bus stuck. (Sticking
/// during the last slots can leave the bits read unchanged: then the true value.)
#[test]
fn fault_stuck_low_during_read() {
    let mut stuck = 0;
    for slot in 0..72u64 {
        let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
        let mut sensor = Ds18b20::single().with_retries(2);
        let mut bus = sim.bus();
        sensor.start(&mut bus, sim.now_us()).unwrap();
        sim.idle_us(750_000);
        assert!(sensor.is_ready(&mut bus, sim.now_us()).unwrap());
        // Reset (~961 µs) + 16 write slots (70 µs), then `slot` read slots (65 µs).
        let t = sim.now_ns() + 1_000_000 + 16 * 72_000 + slot * 67_000;
        sim.with(|w| w.stuck_low_at_ns = Some(t));
        match sensor.read(&mut bus) {
            Err(drv::Error::Bus(ow::Error::BusStuckLow)) => stuck += 1,
            Ok(s) => assert_eq!(s.reading.celsius(), 25.0625, "slot {slot}"),
            Err(e) => panic!("slot {slot}: {e:?}"),
        }
        assert_eq!(bus.reset(), Err(ow::Error::BusStuckLow));
    }
    assert!(stuck >= 68, "{stuck} of 72 detected");
}

#[test]
fn fault_brown_out_gives_power_on_error_then_recovers() {
    let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
    let mut sensor = Ds18b20::single().with_retries(0);
    let mut bus = sim.bus();
    // Power-up: the scratchpad holds 0550h/0Ch before any conversion.
    let mut fresh = Ds18b20::single();
    sim.with(|w| w.devices[0].temp_raw = 0x0550); // a real 85 °C is still accepted after conversion
    assert_eq!(fresh.measure(&mut bus, sim.now_us()).unwrap().reading.celsius(), 85.0);
    sim.with(|w| w.devices[0].temp_raw = 0x0191);

    // Brown-out during a conversion: the read finds the power-on value.
    sensor.start(&mut bus, sim.now_us()).unwrap();
    sim.with(|w| w.devices[0].brown_out_at_ns = Some(w.now_ns + 100_000_000));
    sim.idle_us(750_000);
    assert!(sensor.is_ready(&mut bus, sim.now_us()).unwrap());
    assert_eq!(sensor.read(&mut bus), Err(drv::Error::Scratchpad(ds18b20::Error::PowerOn)));
    assert_eq!(sensor.read(&mut bus), Err(drv::Error::NotStarted), "power-on needs a new conversion");

    // measure() reconverts within its retry budget.
    let mut sensor = sensor.with_retries(1);
    sim.with(|w| w.devices[0].brown_out_at_ns = Some(w.now_ns + 100_000_000));
    let s = sensor.measure(&mut bus, sim.now_us()).unwrap();
    assert_eq!(s.reading.celsius(), 25.0625);
    assert_no_violations(&sim);
}

/// After a brown-out the sensor is back at its EEPROM resolution (12 bits) while the
/// driver expects 9 bits and waits only 93.75 ms: every read in the following cycles
/// is a typed error (power-on value, or resolution changed), never a stale or wrong
/// value, until the resolution is set again.
#[test]
fn fault_brown_out_reverts_resolution() {
    let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
    let mut bus = sim.bus();
    let mut sensor = Ds18b20::single().with_retries(0);
    sensor.set_resolution(&mut bus, Resolution::Bits9).unwrap();
    assert_eq!(ok_measure(&sim, &mut sensor).reading.celsius(), 25.0);

    sim.with(|w| w.devices[0].brown_out_at_ns = Some(w.now_ns + 1_000));
    sim.with(|w| w.devices[0].temp_raw = -0x0191);
    let mut errors = Vec::new();
    for _ in 0..4 {
        match sensor.measure(&mut bus, sim.now_us()) {
            Ok(s) => panic!("wrong or stale value accepted: {}", s.reading.celsius()),
            Err(e) => errors.push(e),
        }
        sim.idle_us(1_000_000);
    }
    assert_eq!(errors[0], drv::Error::Scratchpad(ds18b20::Error::PowerOn));
    assert!(errors.contains(&drv::Error::ResolutionChanged(Resolution::Bits12)), "{errors:?}");
    sensor.set_resolution(&mut bus, Resolution::Bits9).unwrap();
    assert_eq!(ok_measure(&sim, &mut sensor).reading.celsius(), -25.5);
}

#[test]
fn fault_pin_error() {
    let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
    sim.with(|w| w.pin_error = true);
    let mut bus = sim.bus();
    assert_eq!(Ds18b20::single().measure(&mut bus, 0), Err(drv::Error::Bus(ow::Error::Pin)));
}

/// A campaign of random faults at random times over many measurement cycles: every
/// result is the true temperature or a typed error.
#[test]
fn fault_campaign_never_returns_a_wrong_temperature() {
    let mut seed = 0x2545_F491_4F6C_DD1Du64;
    let mut rng = move |n: u64| {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed % n
    };
    let (mut ok, mut err) = (0, 0);
    for _ in 0..150 {
        let raw = rng(2001) as i16 - 1000;
        let sim = Sim::new(vec![Device::ds18b20(1 + rng(1000), raw), Device::ds18b20(5000 + rng(1000), -raw)]);
        let mut bus = sim.bus();
        let mut sensors = Ds18b20::search::<_, _, 2>(&mut bus).unwrap();
        let target = &mut sensors[0];
        let idx = sim.with(|w| w.devices.iter().position(|d| d.rom == target.rom().unwrap().bytes()).unwrap());
        let truth = sim.with(|w| w.devices[idx].temp_raw);
        let res = RESOLUTIONS[rng(4) as usize];
        target.set_resolution(&mut bus, res).unwrap();
        let mut target = target.with_retries(rng(3) as u8);
        let at = sim.now_ns() + rng(900_000_000);
        sim.with(|w| match rng(5) {
            0 => {
                w.devices[idx].flip_bit = rng(72) as usize;
                w.devices[idx].flip_times = 1 + rng(3) as u32;
            }
            1 => w.devices[idx].present = rng(2) == 0,
            2 => w.stuck_low_at_ns = Some(at),
            3 => w.devices[idx].brown_out_at_ns = Some(at),
            _ => w.devices[1 - idx].brown_out_at_ns = Some(at),
        });
        for _ in 0..2 {
            match target.measure(&mut bus, sim.now_us()) {
                Ok(s) => {
                    ok += 1;
                    assert_eq!(s.reading.celsius(), expected_celsius(truth, res), "{res:?} raw {truth}");
                }
                Err(_) => err += 1,
            }
        }
    }
    println!("fault campaign: {ok} true readings, {err} typed errors");
    assert!(ok > 50 && err > 50, "{ok} ok, {err} errors: the campaign must exercise both");
}

/// The async measure (embassy users) shares the protocol with the blocking one: same
/// reading, same retries and errors; only the conversion wait is awaited.
#[test]
fn async_measure_matches_blocking_and_awaits_the_conversion() {
    use host_tests::onewire_sim::{block_on, SimAsyncDelay};
    for res in RESOLUTIONS {
        for (raw, _) in TABLE {
            let sim_b = Sim::new(vec![Device::ds18b20(7, raw)]);
            let sim_a = Sim::new(vec![Device::ds18b20(7, raw)]);
            let (mut bus_b, mut bus_a) = (sim_b.bus(), sim_a.bus());
            let (mut sb, mut sa) = (Ds18b20::single(), Ds18b20::single());
            sb.set_resolution(&mut bus_b, res).unwrap();
            sa.set_resolution(&mut bus_a, res).unwrap();
            let blocking = sb.measure(&mut bus_b, sim_b.now_us()).unwrap();
            let mut wait = SimAsyncDelay::new(&sim_a);
            let t0 = sim_a.now_ns();
            let asynced = block_on(sa.measure_async(&mut bus_a, &mut wait, sim_a.now_us())).unwrap();
            assert_eq!(asynced.scratchpad, blocking.scratchpad, "{res:?} {raw:04X}");
            assert_eq!(asynced.reading, blocking.reading);
            assert_eq!(asynced.completed_us, blocking.completed_us, "same completion time on the same clock");
            assert_eq!(wait.awaited_ns, u64::from(res.max_conversion_us()) * 1000, "the conversion is awaited");
            let blocking_part_us = (sim_a.now_ns() - t0 - wait.awaited_ns) / 1000;
            assert!(blocking_part_us < 10_000, "only bus transactions block: {blocking_part_us} µs");
            assert_no_violations(&sim_a);
        }
    }
    // A flipped bit on the first read: retried within the budget, like the blocking call.
    let sim = Sim::new(vec![Device::ds18b20(7, 0x0191)]);
    let mut bus = sim.bus();
    let mut s = Ds18b20::single().with_retries(1);
    sim.with(|w| {
        w.devices[0].flip_bit = 17;
        w.devices[0].flip_times = 1;
    });
    let mut wait = SimAsyncDelay::new(&sim);
    let got = block_on(s.measure_async(&mut bus, &mut wait, sim.now_us())).unwrap();
    assert_eq!(got.reading.celsius(), 25.0625);
    // No presence: the same typed bus error.
    let sim = Sim::new(vec![]);
    let mut bus = sim.bus();
    let mut wait = SimAsyncDelay::new(&sim);
    let err = block_on(Ds18b20::single().measure_async(&mut bus, &mut wait, 0)).unwrap_err();
    assert_eq!(err, drv::Error::Bus(ow::Error::NoPresence));
}
