//! A shortened soak that still crosses the µs wrap (twice) and the ms wrap (once):
//! the firmware recipe (`MsClock` → `on_scratchpad_from`, split applier) must reject no
//! good reading and flag no healthy cycle stale. The 1 200-h figure comes from the
//! release binary (`cargo run --release -p host-tests --bin soak -- --hours 1200`).

use host_tests::soak::{run, Settings};

#[test]
fn short_soak_crosses_every_wrap_without_a_stale_cycle() {
    for sensors in [3, 1] {
        // 2.5 h: the µs clock starts 10 min before its wrap and wraps again 71.6 min later;
        // the ms clock starts 1 h before its wrap.
        let set = Settings { hours: 2.5, imu_hz: 5, us_before_wrap: 600_000_000, ms_before_wrap: 3_600_000, sensors };
        let f = run(set, |_| {});
        println!("sensors={sensors}: {}", f.lines().join(" "));
        assert!(f.wraps_us >= 2, "{f:?}");
        assert_eq!(f.wraps_ms, 1, "{f:?}");
        assert_eq!(f.readings, 9_000 * sensors as u64);
        assert_eq!(f.driver_errors, 0);
        assert_eq!(f.rejected_good_readings, 0, "{f:?}");
        assert_eq!(f.stale_fraction, 0.0, "{f:?}");
        // ±1/32 °C quantization amplified ≤ 2× by the line fit, plus the fit's curvature.
        assert!(f.max_temp_error_c < 0.075, "{f:?}");
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
        if c.on_raw(us / 1000, 352).is_err() {
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
    use qfa_thermal::model::{AxisModel, BiasGrid, Extensions, ScaleFactor};
    use qfa_thermal::table::{Table, MAX_TABLE_BYTES};
    let mut t = Table {
        input: qfa_thermal::Input::PulseCounts,
        rate_window: 32,
        axes: heapless::Vec::new(),
        misalignment: None,
    };
    let scale = ScaleFactor::JB_KT8_1;
    let bias = BiasGrid::single_valued(-60.0, 65.0, &[1e-4, 1.5e-4, 3e-4]);
    t.axes.push(AxisModel { scale, bias, rate_limit_c_per_min: 2.0, ext: Extensions::default() }).unwrap();
    let mut buf = [0u8; MAX_TABLE_BYTES];
    t.encode(&mut buf).unwrap().to_vec()
}
