//! Temperature in 1 °C steps, measured on the real chamber log (tofupilot IMU thermal
//! cycle): its temperature rounded to whole degrees, read as an autopilot instance
//! (`qfa_log::autopilot`: the resolution named, the temperature rebuilt between
//! steps, 1-s bins), must calibrate with cross-validation and cubic held-out figures within
//! 10 % of the same log unrounded through the same path.
//!
//! The file is not in this repository: GitHub `tofupilot/examples`,
//! `templates/imu_thermal_calibration/data/imu_raw_data.csv` at commit
//! fc190f7cd507ec6b53fba4c4368b1a2a0a8e5125 (MIT), tab-separated; looked for at
//! `$QFA_REAL_IMU_LOG`, else `<repo>/../shared/real/tofupilot-imu-thermal-cycle/imu_raw_data.tsv`.
//! Missing, the test prints SKIPPED; with `CI=true` it fails.

mod common;

use qfa_calibrate::static_cal::{calibrate_static, Figure, StaticCalOptions, StaticCalibration};
use qfa_log::autopilot::{resolution, AccelInstance, Temperature};
use qfa_log::static_log::{read_static_from, AccelUnit, ColumnMap, StaticOptions, TimeUnit, G0_MPS2};

fn rms(f: &Figure) -> f64 {
    match f {
        Figure::Score(s) => s.rms_mg,
        other => panic!("no figure: {other:?}"),
    }
}

fn calibrate(inst: &AccelInstance, rebuild: bool) -> StaticCalibration {
    let log = inst.to_static(rebuild).expect("binned rows read");
    calibrate_static(&log, &StaticCalOptions::default(), false).expect("calibrates")
}

/// Rounded to 1 °C and rebuilt, each axis's cross-validation RMS of the table's structure
/// (over every row) and the PX4-style cubic's held-out bias RMS are within 10 % of the
/// unrounded figures; the resolution is named 1 °C rounded and 0.01 °C or finer unrounded.
/// Our held-out figure is printed, not asserted: it fits the table's structure on the rows
/// before the later leg, and whole-degree steps move that fit far more than the table's
/// (y's lag 60 s + creep 600 s read 0.619 → 0.791 mg held out, z 1.838 → 0.797, while
/// their cross-validation read 0.482 → 0.463 and 1.412 → 1.480). It was within 10 % while
/// the figure scored a structure chosen inside the training rows, which the table did not
/// hold. The figures of the rounded log read as it is (no rebuild) are printed beside
/// them, not asserted.
#[test]
fn whole_degree_temperature_calibrates_within_ten_percent_of_the_unrounded_log() {
    let Some(path) = common::real_log() else { return };
    let opts = StaticOptions {
        columns: "time=timestamp,temp=imu.temperature,ax=imu.acc.x,ay=imu.acc.y,az=imu.acc.z"
            .parse::<ColumnMap>()
            .unwrap(),
        time_unit: Some(TimeUnit::Us),
        accel_unit: Some(AccelUnit::Mps2),
        temp_unit: None,
        decimal_comma: false,
    };
    let log = read_static_from(std::fs::File::open(&path).unwrap(), &opts).unwrap();
    let fine = AccelInstance {
        index: 0,
        device_id: None,
        time_s: log.time_s.clone(),
        temp_c: log.temp_c.clone(),
        accel_mps2: [0, 1, 2].map(|a| log.axes[a].accel_g.iter().map(|g| g * G0_MPS2).collect()),
    };
    let rounded = AccelInstance { temp_c: fine.temp_c.iter().map(|t| t.round()).collect(), ..fine.clone() };
    let (fine_res, round_res) = (resolution(&fine.temp_c), resolution(&rounded.temp_c));
    println!("resolution: unrounded {fine_res:?}, rounded {round_res:?}");
    assert!(matches!(fine_res, Temperature::Resolution { coarse: false, step_c } if step_c <= 0.01 + 1e-9));
    assert!(matches!(round_res, Temperature::Resolution { coarse: true, step_c } if (step_c - 1.0).abs() < 1e-9));

    let (a, b, c) = (calibrate(&fine, false), calibrate(&rounded, true), calibrate(&rounded, false));
    println!("held-out bias RMS, mg (after-max split, 1-s bins): unrounded / rounded rebuilt / rounded as read");
    for k in 0..3 {
        let (fa, fb, fc) = (&a.report.axes[k], &b.report.axes[k], &c.report.axes[k]);
        let (o, r, n) = (rms(&fa.ours), rms(&fb.ours), rms(&fc.ours));
        let (co, cr, cn) = (rms(&fa.cubic), rms(&fb.cubic), rms(&fc.cubic));
        println!(
            "{}: ours {o:.3} / {r:.3} ({:+.1} %) / {n:.3} ({:+.1} %); cubic {co:.3} / {cr:.3} ({:+.1} %) / {cn:.3} \
             ({:+.1} %); structures {} / {} / {}",
            fa.axis,
            100.0 * (r / o - 1.0),
            100.0 * (n / o - 1.0),
            100.0 * (cr / co - 1.0),
            100.0 * (cn / co - 1.0),
            fa.structure,
            fb.structure,
            fc.structure
        );
        let (cvo, cvr) = (fa.cv_rms_mg, fb.cv_rms_mg);
        println!("{}: cross-validation {cvo:.3} / {cvr:.3} / {:.3}", fa.axis, fc.cv_rms_mg);
        assert!((cvr / cvo - 1.0).abs() <= 0.10, "{}: cross-validation {cvr} vs {cvo}", fa.axis);
        assert!((cr / co - 1.0).abs() <= 0.10, "{}: cubic {cr} vs {co}", fa.axis);
    }
}
