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

/// A MEMS table in the lab's scale (2²⁰ units per g) set on a compensator configured for
/// the part's own 4 096 LSB/g is refused with both scales named. Before the check it was
/// accepted, and the part's −4 096 LSB (−1 g) came out as −0.0039 g with the status OK; the
/// same table with the compensator in its scale and the samples scaled to it gives −1 g.
#[test]
fn a_table_in_another_unit_scale_is_refused() {
    use qfa_thermal::table::{self, Input};
    let lab_scale = 1_048_576.0f32;
    let mut t = scenarios::table(0, [Extensions::default(); 3], None);
    t.input = Input::Samples;
    for a in &mut t.axes {
        a.scale = qfa_thermal::ScaleFactor::simple(22.0, lab_scale, 0.0);
    }
    let part = Config { input: Input::Samples, nominal_k1: 4_096.0, ..Config::default() };
    let mut c = Comp::new(part).unwrap();
    assert_eq!(c.set_table(t.clone()), Err(table::Error::Scale { table_k1: 1_048_576, nominal_k1: 4_096 }));
    assert!(c.table().is_none(), "nothing changed");

    let lab = Config { input: Input::Samples, nominal_k1: lab_scale, ..Config::default() };
    let mut c = Comp::new(lab).unwrap();
    c.set_table(t).unwrap();
    for t_s in 0..40 {
        for s in 0..3 {
            c.on_raw(s, t_s * 1_000, 352 + (t_s / 4) as i16).unwrap();
        }
    }
    let raw_lsb = -4_096i32; // the part at −1 g on z
    let out = c.cycle_samples([0, 0, raw_lsb * ((1 << 20) / 4_096)], 2_500); // × 256
    let az_g = f64::from(out.accel_mps2[2]) / 9.806_65;
    assert!((az_g + 1.0).abs() < 2e-4, "{az_g} g (the bias is about 1e-4 g)");
}
