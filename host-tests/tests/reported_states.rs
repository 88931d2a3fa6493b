//! States an integrator reached with the public API in which the output was wrong and the
//! status OK. Each test failed on the code before its fix; the names say which state.

use host_tests::scenarios;
use qfa_thermal::model::{BiasGrid, Creep, Extensions, SensorLag, MAX_BIAS_POINTS};
use qfa_thermal::table::Table;
use qfa_thermal::{Compensator, Config, SampleError, Status};

type Comp = Compensator<3, 32, 3>;

/// A 600-s sensor lag and a creep slot on every axis (the reported table).
fn lag_and_creep_table() -> Table {
    let ext = Extensions {
        sensor_lag: Some(SensorLag { tau_s: 600.0 }),
        bias_creep: Some(Creep { gain_g_per_c: 2e-5, tau_ref_s: 900.0, t_ref_c: 25.0, activation_k: 3_000.0 }),
        ..Extensions::default()
    };
    scenarios::table(0, [ext; 3], None)
}

/// 20 °C, then a 1 °C/min ramp, read at 1 Hz: raw 1/16 °C, rounded.
fn ramp_raw(t_s: u32) -> i16 {
    let t_c = 20.0 + f64::from(t_s) / 60.0;
    (t_c * 16.0).round() as i16
}

fn feed(c: &mut Comp, t_s: u32) {
    for s in 0..3 {
        c.on_raw(s, t_s * 1_000 + 10 * s as u32, ramp_raw(t_s)).unwrap();
    }
}

/// Reloading the very table in force is a no-op: every later output is bit-identical to a
/// compensator that never reloaded. Before the fix the reload restarted the lag and creep
/// states from the current reading, a step of about 1 100 µg on a 1 °C/min ramp, with
/// the status OK.
#[test]
fn reloading_the_same_table_keeps_the_model_state() {
    let mut kept = Comp::new(Config::default()).unwrap();
    kept.set_table(lag_and_creep_table()).unwrap();
    let mut reloaded = Comp::new(Config::default()).unwrap();
    reloaded.set_table(lag_and_creep_table()).unwrap();
    let mut compared = 0;
    for t_s in 0..2_400u32 {
        feed(&mut kept, t_s);
        feed(&mut reloaded, t_s);
        if t_s == 1_200 {
            reloaded.set_table(lag_and_creep_table()).unwrap();
        }
        let a = kept.cycle([1_601, 1_601, 1_601], 5_000);
        let b = reloaded.cycle([1_601, 1_601, 1_601], 5_000);
        if t_s >= 1_200 {
            assert_eq!(a, b, "t = {t_s} s: a reload of the same table changed the output");
            assert_eq!(kept.evaluations(), reloaded.evaluations(), "t = {t_s} s");
            compared += 1;
        }
    }
    assert_eq!(compared, 1_200);
}

/// Mixing the entry points of the unsplit compensator never counts a pulse twice: after a
/// `cycle` the counter base is unknown, so the next `cycle_counters` is flagged, not OK.
/// Before the fix it returned Δv for the counters' whole advance (both cycles' pulses)
/// with the status OK: 0.098 m/s instead of 0.049.
#[test]
fn cycle_between_two_counter_cycles_never_double_counts() {
    let mut c = Comp::new(Config::default()).unwrap();
    c.set_table(scenarios::table(0, [Extensions::default(); 3], None)).unwrap();
    // A warming ramp (about 0.9 °C/min), so the bias branch is known and the status OK.
    for t_s in 0..40 {
        for s in 0..3 {
            c.on_raw(s, t_s * 1_000, 352 + (t_s / 4) as i16).unwrap();
        }
    }
    let mut counters = [0u32; 3];
    c.prime_counters(counters);
    counters[2] = counters[2].wrapping_add(1_601);
    let first = c.cycle_counters(counters, 5_000);
    assert!(first.status.is_ok(), "{first:?}");
    let one_cycle = first.dv_mps[2];
    // A cycle reported through `cycle`: its pulses advance the hardware counters too.
    let mid = c.cycle([0, 0, 1_601], 5_000);
    counters[2] = counters[2].wrapping_add(1_601);
    // The next cycle's pulses.
    counters[2] = counters[2].wrapping_add(1_601);
    let second = c.cycle_counters(counters, 5_000);
    if second.status.is_ok() {
        assert!(
            (second.dv_mps[2] - one_cycle).abs() < 1e-6,
            "status OK but Δv {} for one cycle's pulses (one cycle is {one_cycle}); the cycle between gave {}",
            second.dv_mps[2],
            mid.dv_mps[2]
        );
    } else {
        assert!(second.status.contains(Status::NO_COUNTER_BASE), "{second:?}");
        assert_eq!(second.dv_mps, [0.0; 3]);
    }
}

/// A sensor index past the last one is reported as given. Before the fix sensor 256 was
/// reported as sensor 0, which exists.
#[test]
fn no_such_sensor_names_the_index_given() {
    let mut c = Comp::new(Config::default()).unwrap();
    for sensor in [3usize, 255, 256, 1_000, usize::MAX] {
        match c.on_raw(sensor, 1_000, 352) {
            Err(SampleError::NoSuchSensor { sensor: reported }) => assert_eq!(reported, sensor),
            other => panic!("sensor {sensor}: {other:?}"),
        }
        match c.on_missed_reading(sensor, 1_000) {
            Err(SampleError::NoSuchSensor { sensor: reported }) => assert_eq!(reported, sensor),
            other => panic!("sensor {sensor}: {other:?}"),
        }
    }
}

/// A grid with more values than a branch holds is refused, not cut short. Before the fix
/// 17 values from −40 °C by 7.5 °C (meant to reach 80 °C) silently became a grid ending at
/// 72.5 °C.
#[test]
fn a_grid_longer_than_a_branch_is_refused() {
    let values = [1e-4f32; MAX_BIAS_POINTS + 1];
    assert!(BiasGrid::single_valued(-40.0, 7.5, &values).is_err());
    let fits = BiasGrid::single_valued(-40.0, 8.0, &values[..MAX_BIAS_POINTS]).expect("16 values fit");
    assert_eq!(fits.t_end_c(), 80.0);
}

/// The samples' scale is the part's sensitivity, configured, never a multiplier written by
/// hand. A MEMS table in the lab's scale (2²⁰ units per g) on a compensator that states the
/// part's 4 096 LSB/g takes the part's raw LSB as they come: −4 096 LSB reads −1 g. Before,
/// the compensator was configured in the table's scale and the firmware multiplied by 256;
/// raw LSB fed without it read −0.0039 g, and a ±16 g part given the ±8 g multiplier read
/// 0.5 g, both with the status OK. Now a samples configuration without the sensitivity is
/// refused, a table that records the range it was calibrated at refuses another, and a
/// table in another unit scale is refused, each naming both sides.
#[test]
fn the_parts_sensitivity_is_configured_and_checked_against_the_table() {
    use qfa_thermal::table::{self, Input};
    let mut t = scenarios::table(0, [Extensions::default(); 3], None);
    t.input = Input::Samples;
    for a in &mut t.axes {
        a.scale = qfa_thermal::ScaleFactor::simple(22.0, table::SAMPLE_UNITS_PER_G, 0.0);
    }
    let at = |lsb: f32| Config { input: Input::Samples, sample_lsb_per_g: lsb, ..Config::default() };

    // Not stated: refused at configuration.
    let unstated = Config { input: Input::Samples, ..Config::default() };
    assert_eq!(unstated.validate(), Err(qfa_thermal::ConfigError::SampleScaleNotStated));

    // Stated: raw LSB in, g out.
    let mut c = Comp::new(at(4_096.0)).unwrap();
    c.set_table(t.clone()).unwrap();
    for t_s in 0..40 {
        for s in 0..3 {
            c.on_raw(s, t_s * 1_000, 352 + (t_s / 4) as i16).unwrap();
        }
    }
    let out = c.cycle_samples([0, 0, -4_096], 2_500); // the part at −1 g on z, raw
    let az_g = f64::from(out.accel_mps2[2]) / 9.806_65;
    assert!((az_g + 1.0).abs() < 2e-4, "{az_g} g (the bias is about 1e-4 g)");

    // A table that knows its part was at ±16 g (2 048 LSB/g) refuses a firmware at ±8 g.
    let mut sixteen = t.clone();
    sixteen.part_lsb_per_g = Some(2_048.0);
    let mut c = Comp::new(at(4_096.0)).unwrap();
    assert_eq!(
        c.set_table(sixteen.clone()),
        Err(table::Error::PartScale { table_lsb_per_g: 2_048, config_lsb_per_g: 4_096 })
    );
    assert!(c.table().is_none(), "nothing changed");
    let mut c = Comp::new(at(2_048.0)).unwrap();
    c.set_table(sixteen).unwrap();

    // A table in the part's own LSB (γ 4 096) is another unit scale than 2²⁰: refused.
    let mut own = t;
    for a in &mut own.axes {
        a.scale = qfa_thermal::ScaleFactor::simple(22.0, 4_096.0, 0.0);
    }
    let mut c = Comp::new(at(4_096.0)).unwrap();
    assert_eq!(c.set_table(own), Err(table::Error::Scale { table_k1: 4_096, nominal_k1: 1_048_576 }));
}
