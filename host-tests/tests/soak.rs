//! A shortened soak that still crosses the µs wrap (twice) and the ms wrap (once):
//! the firmware recipe (`MsClock` → `on_scratchpad`, split applier) must reject no
//! good reading and flag no healthy cycle stale; and the fault schedule, compressed. The
//! 1 200-h figure comes from the release binary (`cargo run --release -p host-tests --bin
//! soak -- --hours 1200`), the field-fault one from `-- --faults` (README). The file takes
//! 4.7 s in the dev profile.
//!
//! The faulted test was seen to fail (not committed): with `on_missed_reading` ignored and
//! the fast path's tick count switched off, `silent_wrong_cycles=3002` (the bus dropout);
//! with missed readings ignored and the stale flag from a wrapped difference, the 1 320-h
//! run gave 58 silent cycles outside the frozen day (at one whole wrap after the dead
//! sensor's last reading, and at its return).

use host_tests::soak::{run, Faults, Settings};

#[test]
fn short_soak_crosses_every_wrap_without_a_stale_cycle() {
    for sensors in [3, 1] {
        // 2.5 h: the µs clock starts 10 min before its wrap and wraps again 71.6 min later;
        // the ms clock starts 1 h before its wrap.
        let set = Settings {
            hours: 2.5,
            imu_hz: 5,
            us_before_wrap: 600_000_000,
            ms_before_wrap: 3_600_000,
            sensors,
            faults: None,
        };
        let f = run(&set, |_| {});
        println!("sensors={sensors}: {}", f.lines().join(" "));
        assert!(f.wraps_us >= 2, "{f:?}");
        assert_eq!(f.wraps_ms, 1, "{f:?}");
        assert_eq!(f.readings, 9_000 * sensors as u64);
        assert_eq!(f.driver_errors, 0);
        assert_eq!(f.rejected_good_readings, 0, "{f:?}");
        assert_eq!(f.stale_fraction, 0.0, "{f:?}");
        // ±1/32 °C quantization amplified ≤ 2× by the line fit, plus the fit's curvature.
        assert!(f.max_temp_error_c < 0.075, "{f:?}");
        // The silent-wrong check judges the cycles with status OK: on a healthy soak those
        // must be most cycles, or "no silent wrong cycle" checked nothing. (It was 0: the
        // soak ran its IMU at 5–10 Hz against the default 400-Hz period, so every cycle was
        // DT_IMPLAUSIBLE.)
        let flag = |name: &str| f.flags.iter().find(|(n, _)| *n == name).map_or(0, |(_, c)| *c);
        assert_eq!(flag("DT_IMPLAUSIBLE"), 0, "{f:?}");
        assert!(f.ok_cycles * 2 > f.healthy_cycles, "{f:?}");
    }
}

/// The recipe the driver docs gave before (`completed_us / 1000`) jumps back at the µs
/// wrap. Fed that way, the compensator refuses the readings after the jump until three
/// agree (before the confirmed-restart rule it refused them for 71 min), and its rate
/// window restarts: the soak's `rejected_good_readings == 0` catches it.
#[test]
fn the_old_recipe_fails_the_soak_figures() {
    use qfa_thermal::compensator::{Compensator, Config, Status};
    let mut c = Compensator::<1, 32>::new(Config::default()).unwrap();
    c.load_table(&one_axis_table()).unwrap();
    let start_us = u32::MAX - 30_000_000; // 30 s before the µs wrap
    let mut rejected = 0;
    let mut not_ready_after_wrap = 0;
    for k in 0..120u32 {
        let us = start_us.wrapping_add(k * 1_000_000);
        if c.on_raw(0, us / 1000, 352).is_err() {
            rejected += 1;
        }
        let out = c.cycle([800], 1_000_000);
        if k > 31 && out.status.contains(Status::RATE_NOT_READY) {
            not_ready_after_wrap += 1;
        }
    }
    assert_eq!(rejected, 2, "refused until confirm_samples = 3 readings agree");
    assert!(not_ready_after_wrap > 0, "the rate window restarted");
}

fn one_axis_table() -> Vec<u8> {
    use qfa_thermal::model::{AxisModel, BiasGrid, Extensions};
    use qfa_thermal::table::{Table, MAX_TABLE_BYTES};
    let mut t = Table {
        input: qfa_thermal::Input::PulseCounts,
        rate_window: 32,
        axes: heapless::Vec::new(),
        misalignment: None,
        part_lsb_per_g: None,
    };
    let scale = qfa_thermal::fixtures::JB_KT8_1;
    let bias = BiasGrid::single_valued(-60.0, 65.0, &[1e-4, 1.5e-4, 3e-4]).expect("2 to 16 grid values");
    t.axes.push(AxisModel { scale, bias, rate_limit_c_per_min: 2.0, ext: Extensions::default() }).unwrap();
    let mut buf = [0u8; MAX_TABLE_BYTES];
    t.encode(&mut buf).unwrap().to_vec()
}

/// The fault schedule compressed into 2.75 h (`Faults::compressed`): sensor 1 dead from
/// 10 to 70 min, across the ms wrap at 30 min; brown-outs of a genuine part (0550h, byte 6
/// 0Ch) and of a clone part (byte 6 10h), one and five in a row; 10-min dropouts of two
/// sensors and of the whole bus; a reload (two refused tables, then the good one). Every
/// failed read goes to `on_missed_reading`. No cycle may be OK on a temperature older than
/// 3 s or off by more than 0.5 °C, and every fault must be flagged on every cycle from its
/// first missed read until its sensor's next good one.
#[test]
fn short_soak_with_faults_has_no_silent_wrong_cycle() {
    for sensors in [3, 1] {
        let set = Settings {
            hours: 2.75,
            imu_hz: 5,
            us_before_wrap: 600_000_000,
            ms_before_wrap: 1_800_000,
            sensors,
            faults: Some(Faults::compressed()),
        };
        let f = run(&set, |_| {});
        println!("sensors={sensors}: {}", f.lines().join(" "));
        assert_eq!(f.wraps_ms, 1, "{f:?}");
        assert_eq!(f.silent_wrong_cycles, 0, "{f:?}");
        let faults = ["dead", "dead_stale", "brown_out_0", "brown_out_1", "clone_brown_out_0", "clone_brown_out_1"];
        for name in faults.iter().chain(&["dropout_0", "dropout_1", "bus_dropout_0"]) {
            let x = f.fault(name).unwrap_or_else(|| panic!("no fault {name}"));
            assert!(x.cycles > 0, "{x:?}");
            assert_eq!(x.flagged, x.cycles, "{name}: a cycle in the fault's window without its flag: {x:?}");
        }
        // The dead sensor is flagged stale across the wrap: 60 min less the 3-s limit.
        assert!(f.fault("dead_stale").unwrap().cycles >= 5 * (3_600 - 4), "{f:?}");
        assert!(f.flag("TEMP_STALE") > 0 && f.flag("TEMP_INVALID") > 0);
        // Every failed read, and only those, counted (and reported as missed): the dead
        // hour, the genuine part's six brown-outs (with one sensor it is the clone part),
        // the two sensor dropouts and the bus dropout on every sensor.
        let genuine = if sensors == 3 { 6 } else { 0 };
        assert_eq!(f.driver_errors, 3_600 + genuine + 2 * 600 + 600 * sensors as u64, "{f:?}");
        // The clone part's 85 °C readings reached the compensator and were refused there.
        assert!(f.compensator_rejections >= 6, "{f:?}");
        assert_eq!((f.tables_refused, f.tables_applied), (2, 1));
        assert!(f.healthy_cycles > 5 * 3_600, "{f:?}");
        assert_eq!(f.stale_fraction, 0.0, "{f:?}");
        assert_eq!(f.rejected_good_readings, 0, "{f:?}");
    }
}

/// A frozen sensor for 1 h (`Faults::frozen_only`): every Convert T is lost, so the
/// scratchpad keeps the previous conversion with a good CRC. The driver sees it through its
/// read-slot check after Convert T (`Error::ConversionNotStarted`, which the soak reports
/// with `on_missed_reading`). Before that check the driver returned the old value as a new
/// sample with a fresh timestamp, the compensator took it, and this test failed with
/// `silent_wrong_cycles=35981` (all in the frozen hour and the 10 s after it) and
/// `fault_frozen=0/35999`.
#[test]
fn frozen_sensor_is_flagged_not_silent() {
    let set = Settings { hours: 1.25, faults: Some(Faults::frozen_only()), ..Settings::default() };
    let f = run(&set, |_| {});
    println!("{}", f.lines().join(" "));
    let frozen = f.fault("frozen").expect("frozen window");
    assert!(frozen.cycles > 0);
    assert_eq!(frozen.flagged, frozen.cycles, "{f:?}");
    assert_eq!(f.silent_wrong_cycles, 0, "{f:?}");
}
