//! The navigation study flies the firmware's recommended configuration, one
//! `Compensator<3, 32, 3>` with a DS18B20 stream per axis. Against three independent
//! `Compensator<1, 32>` fed the same streams (the configuration flown before), every Δv
//! must be bit-identical: the per-axis streams really are independent.

use qfa_nav::accel::{axis_compensator, AccelCompensation, TableCompensation};
use qfa_thermal::model::{AxisModel, BiasGrid, Extensions, ScaleFactor};
use qfa_thermal::Table;

fn one_axis(gamma: f32, b0: f32) -> Table {
    let mut t = Table {
        input: qfa_thermal::Input::PulseCounts,
        rate_window: 32,
        axes: heapless::Vec::new(),
        misalignment: None,
        part_lsb_per_g: None,
    };
    let axis = AxisModel {
        scale: ScaleFactor { t0_c: 22.0, gamma, mu: -32.76, beta: 0.1008, epsilon: 88.14, eta: -0.02409, alpha: 273.0 },
        bias: BiasGrid::single_valued(-60.0, 65.0, &[b0, 1.5e-4, 3e-4]).expect("2 to 16 grid values"),
        rate_limit_c_per_min: 2.0,
        ext: Extensions::default(),
    };
    t.axes.push(axis).unwrap();
    t
}

#[test]
fn three_axis_per_sensor_equals_three_one_axis_compensators() {
    let tables = [one_axis(320_320.0, 1e-4), one_axis(308_000.0, -2e-4), one_axis(328_000.0, 5e-5)];
    let mut three = TableCompensation::new([&tables[0], &tables[1], &tables[2]], 200.0).unwrap(); // 5-ms cycles
    let mut ones: Vec<_> = tables
        .iter()
        .map(|t| {
            let mut c = axis_compensator(200.0);
            c.set_table(t.clone()).unwrap();
            c
        })
        .collect();
    let truth = [(0.0, 0.0); 3];
    let mut compared = 0;
    for k in 0..3_000u32 {
        if k % 200 == 0 {
            // Each case at its own temperature, ramping at its own rate.
            let raw: [i16; 3] =
                core::array::from_fn(|i| 320 + (i as i16) * 40 + ((k / 200) as i16) * (i as i16 + 1) / 4);
            three.on_temperatures(k * 5, raw);
            for (c, r) in ones.iter_mut().zip(raw) {
                c.on_raw(0, k * 5, r).unwrap();
            }
        }
        let pulses = [1_602 + (k % 7) as i32, -3_203, 320_320 / 200];
        let dv = three.compensate(pulses, 5_000, &truth);
        for i in 0..3 {
            let one = ones[i].cycle([pulses[i]], 5_000).dv_mps[0];
            assert_eq!(dv[i].to_bits(), f64::from(one).to_bits(), "axis {i}, cycle {k}");
            compared += 1;
        }
    }
    assert_eq!(three.rejected, 0);
    assert_eq!(compared, 9_000);
}
