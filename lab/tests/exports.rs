//! The PX4 and ArduPilot exports of `calibrate` on synthetic logs: what each file must
//! carry so the stack loads and applies it, and that applying each stack's own
//! formula (`tests/common`, independent of the exporter) to the log gives the report's
//! peer figures.

mod common;

use std::path::{Path, PathBuf};

use common::{lab, read_parm, read_px4_params, G0};

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("qfa-exports-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A static log as the test knows it: time (s), temperature (°C), acceleration (m/s²) per
/// axis, written as TSV with ms timestamps.
struct Synthetic {
    time_s: Vec<f64>,
    temp_c: Vec<f64>,
    acc: Vec<Vec<f64>>,
}

/// 1-s rows through `legs` (target °C, 3 °C/min), axes `names` (`acc_x`, …). Each axis's
/// bias (g) is a cubic in T with its own coefficients, plus ±0.3 mg between heating and
/// cooling and ±0.2 mg of deterministic pseudo-noise, so no peer fits it exactly.
fn synthetic(path: &Path, start_c: f64, legs: &[f64], names: &[&str]) -> Synthetic {
    // In steps of 0.05 °C counted as integers, so the ends are exactly the targets.
    let (mut temps, mut dirs) = (Vec::new(), Vec::new());
    let mut k = (start_c / 0.05).round() as i64;
    for &target in legs {
        let goal = (target / 0.05).round() as i64;
        let step = if goal < k { -1 } else { 1 };
        while k != goal {
            temps.push(k as f64 * 0.05);
            dirs.push(step as f64);
            k += step;
        }
    }
    // A hash of (row, axis), so an axis gets the same noise whichever other axes the log has.
    let noise = |i: usize, g: usize| -> f64 {
        let z = qfa_rng::splitmix64((i as u64) << 2 | g as u64);
        ((z >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 4e-4
    };
    let gravity = [0.01, -0.02, -1.0];
    let mut s = format!("time_ms\timu.temperature\t{}\n", names.join("\t"));
    let mut out = Synthetic { time_s: Vec::new(), temp_c: Vec::new(), acc: vec![Vec::new(); names.len()] };
    for (i, (&tc, &d)) in temps.iter().zip(&dirs).enumerate() {
        let x = (tc - 25.0) / 40.0;
        s.push_str(&format!("{}\t{tc:.4}", i * 1000));
        for (k, name) in names.iter().enumerate() {
            let g = match *name {
                "acc_x" => 0,
                "acc_y" => 1,
                _ => 2,
            };
            let c = [1.0e-3, -0.6e-3, 2.0e-3][g];
            let bias = c * x + 0.4 * c * x * x - 0.3 * c * x * x * x + 0.3e-3 * d;
            let a = ((gravity[g] + bias + noise(i, g)) * G0 * 1e6).round() / 1e6;
            s.push_str(&format!("\t{a:.6}"));
            out.acc[k].push(a);
        }
        s.push('\n');
        out.time_s.push(i as f64);
        out.temp_c.push((tc * 1e4).round() / 1e4);
    }
    std::fs::write(path, s).unwrap();
    out
}

const FLAGS: [&str; 4] = ["--time-unit", "ms", "--accel-unit", "m/s2"];

fn calibrate(log: &Path, out: &Path, extra: &[&str]) -> (bool, String) {
    let mut a = vec!["calibrate", "--log", log.to_str().unwrap(), "--out", out.to_str().unwrap()];
    a.extend(FLAGS);
    a.extend(extra);
    lab(&a)
}

const NO_ID: &str = "px4_tc.params not written: PX4 applies TC_A0_* only to the accelerometer whose device ID \
                     equals TC_A0_ID (with 0 nothing matches and compensation is silently off); pass \
                     --px4-device-id ID, the vehicle's CAL_ACC0_ID parameter (or device_id in `listener \
                     sensor_accel` on the PX4 console)";

#[test]
fn px4_file_is_written_only_with_the_device_id_and_says_what_to_do_after_loading() {
    let d = dir("px4");
    let log = d.join("log.tsv");
    synthetic(&log, 20.0, &[-10.0, 60.0, 30.0], &["acc_x", "acc_y", "acc_z"]);
    // Without the ID: the calibration succeeds, the PX4 file is not written, and the
    // message says where the ID comes from.
    let (ok, text) = calibrate(&log, &d.join("a"), &[]);
    assert!(ok, "{text}");
    assert!(text.contains(NO_ID), "{text}");
    assert!(!d.join("a/px4_tc.params").exists());
    // A 0 ID matches no accelerometer: refused before any work.
    let (ok, text) = calibrate(&log, &d.join("b"), &["--px4-device-id", "0"]);
    assert!(!ok, "{text}");
    assert!(text.contains("invalid value '0' for '--px4-device-id <ID>': 0 matches no accelerometer"), "{text}");
    // With the ID: TC_A0_ID as an int32 (type 6), and the steps after loading.
    let (ok, text) = calibrate(&log, &d.join("c"), &["--px4-device-id", "1310988"]);
    assert!(ok, "{text}");
    let params = std::fs::read_to_string(d.join("c/px4_tc.params")).unwrap();
    let p = read_px4_params(&params);
    assert_eq!(p["TC_A0_ID"], ("1310988".to_string(), 6));
    assert_eq!(p["TC_A_ENABLE"], ("1".to_string(), 6));
    for k in 0..4 {
        for i in 0..3 {
            assert_eq!(p[&format!("TC_A0_X{k}_{i}")].1, 9, "{params}");
        }
    }
    let comments: String = params.lines().filter(|l| l.starts_with('#')).collect::<Vec<_>>().join("\n");
    for want in ["Reboot", "TC_A_ENABLE", "accelerometer calibration", "CAL_ACC0_ID", "acc_x, acc_y, acc_z"] {
        assert!(comments.contains(want), "`{want}` not in the comments:\n{comments}");
    }
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn exported_files_applied_with_each_stacks_formula_give_the_report_figures() {
    let d = dir("formula");
    let log = d.join("log.tsv");
    let s = synthetic(&log, 20.0, &[-10.0, 60.0, 30.0], &["acc_x", "acc_y", "acc_z"]);
    let out = d.join("cal");
    let (ok, text) = calibrate(&log, &out, &["--px4-device-id", "1310988"]);
    assert!(ok, "{text}");
    for line in common::check_exports_against_report(&out, &s.time_s, &s.temp_c, &s.acc, 0.03) {
        println!("{line}");
    }
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn ardupilot_enable_comes_in_its_own_file_before_the_values() {
    let d = dir("ap");
    let log = d.join("log.tsv");
    synthetic(&log, 20.0, &[-10.0, 60.0, 30.0], &["acc_x", "acc_y", "acc_z"]);
    let (ok, text) = calibrate(&log, &d.join("cal"), &[]);
    assert!(ok, "{text}");
    let one = std::fs::read_to_string(d.join("cal/ardupilot_tcal_1_enable.parm")).unwrap();
    let two = std::fs::read_to_string(d.join("cal/ardupilot_tcal_2_values.parm")).unwrap();
    // Step 1 sets only the enable flag, which un-hides the rest; step 2 holds every value.
    let p1 = read_parm(&one);
    assert_eq!(p1.into_iter().collect::<Vec<_>>(), [("INS_TCAL1_ENABLE".to_string(), 1.0)]);
    let p2 = read_parm(&two);
    assert!(!p2.contains_key("INS_TCAL1_ENABLE"), "{two}");
    let mut names: Vec<String> = vec!["INS_TCAL1_TMIN".into(), "INS_TCAL1_TMAX".into()];
    for k in 1..=3 {
        for a in ["X", "Y", "Z"] {
            names.push(format!("INS_TCAL1_ACC{k}_{a}"));
        }
    }
    names.sort();
    assert_eq!(p2.keys().cloned().collect::<Vec<_>>(), names, "{two}");
    assert!((-70.0..=80.0).contains(&p2["INS_TCAL1_TMIN"]) && (-70.0..=80.0).contains(&p2["INS_TCAL1_TMAX"]));
    // The steps, in order, in the first file.
    let steps = ["Load this file", "Reboot", "refresh the parameter list", "ardupilot_tcal_2_values.parm"];
    let at: Vec<usize> = steps.iter().map(|s| one.find(s).unwrap_or_else(|| panic!("`{s}` in\n{one}"))).collect();
    assert!(at.windows(2).all(|w| w[0] < w[1]), "steps out of order:\n{one}");
    assert!(two.contains("ardupilot_tcal_1_enable.parm"), "{two}");
    // The old single file is gone.
    assert!(!d.join("cal/ardupilot_tcal.parm").exists());
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn ardupilot_files_outside_minus_70_to_80_c_are_refused_and_export_range_brings_them_in() {
    let d = dir("aprange");
    let log = d.join("log.tsv");
    synthetic(&log, 20.0, &[-10.0, 85.0, 30.0], &["acc_x", "acc_y", "acc_z"]);
    let (ok, text) = calibrate(&log, &d.join("a"), &["--px4-device-id", "7"]);
    assert!(ok, "{text}");
    assert!(
        text.contains(
            "ArduPilot files not written: the training temperatures span -10.00..85.00 °C, outside the -70..80 °C \
             that INS_TCAL1_TMIN/TMAX accept; pass --export-range TMIN,TMAX inside both"
        ),
        "{text}"
    );
    assert!(!d.join("a/ardupilot_tcal_1_enable.parm").exists() && !d.join("a/ardupilot_tcal_2_values.parm").exists());
    // PX4 has no such limit: its file is written.
    assert!(d.join("a/px4_tc.params").exists());
    let (ok, text) = calibrate(&log, &d.join("b"), &["--export-range", "-5,75"]);
    assert!(ok, "{text}");
    let p2 = read_parm(&std::fs::read_to_string(d.join("b/ardupilot_tcal_2_values.parm")).unwrap());
    assert_eq!((p2["INS_TCAL1_TMIN"], p2["INS_TCAL1_TMAX"]), (-5.0, 75.0));
    let _ = std::fs::remove_dir_all(&d);
}

/// A file that sets the shared fields of an accelerometer (PX4 TC_A0_TREF/TMIN/TMAX,
/// ArduPilot INS_TCAL1_TMIN/TMAX) for fewer than its three axes would re-reference the
/// axes it does not carry. Such an export needs `--export-range`, the same for every axis,
/// and then carries exactly those shared values; the cubic is the same function, re-expanded
/// about the range's middle.
#[test]
fn a_partial_export_never_rewrites_the_shared_fields_of_the_other_axes() {
    let d = dir("partial");
    let full_log = d.join("full.tsv");
    synthetic(&full_log, 20.0, &[-10.0, 60.0, 30.0], &["acc_x", "acc_y", "acc_z"]);
    let z_log = d.join("z.tsv");
    synthetic(&z_log, 20.0, &[-10.0, 60.0, 30.0], &["acc_z"]);
    let (ok, text) = calibrate(&z_log, &d.join("a"), &["--px4-device-id", "7"]);
    assert!(ok, "{text}");
    assert!(
        text.contains(
            "PX4 and ArduPilot files not written: this export has 1 of the 3 axes (az), and TC_A0_TREF/TMIN/TMAX \
             (PX4) and INS_TCAL1_TMIN/TMAX (ArduPilot) are shared by all three; pass --export-range TMIN,TMAX, the \
             same for every axis you export, inside each axis's training temperatures (here -10.00..60.00 °C)"
        ),
        "{text}"
    );
    for f in ["px4_tc.params", "ardupilot_tcal_1_enable.parm", "ardupilot_tcal_2_values.parm"] {
        assert!(!d.join("a").join(f).exists(), "{f}");
    }
    // A range outside the training temperatures would extrapolate the cubic: refused.
    let (ok, text) = calibrate(&z_log, &d.join("b"), &["--px4-device-id", "7", "--export-range", "-20,50"]);
    assert!(ok, "{text}");
    assert!(
        text.contains(
            "PX4 and ArduPilot files not written: --export-range -20..50 °C is not inside the training temperatures \
             -10.00..60.00 °C of az (a cubic is not to be extrapolated)"
        ),
        "{text}"
    );
    // Inside: the shared fields are the range's, only z's coefficients are written.
    let (ok, text) = calibrate(&z_log, &d.join("c"), &["--px4-device-id", "7", "--export-range", "-5,55"]);
    assert!(ok, "{text}");
    let pz = read_px4_params(&std::fs::read_to_string(d.join("c/px4_tc.params")).unwrap());
    let f = |p: &std::collections::BTreeMap<String, (String, u32)>, n: &str| -> f64 { p[n].0.parse().unwrap() };
    assert_eq!((f(&pz, "TC_A0_TREF"), f(&pz, "TC_A0_TMIN"), f(&pz, "TC_A0_TMAX")), (25.0, -5.0, 55.0));
    assert!(pz.keys().all(|k| !k.ends_with("_0") && !k.ends_with("_1")), "{pz:?}");
    let az = read_parm(&std::fs::read_to_string(d.join("c/ardupilot_tcal_2_values.parm")).unwrap());
    assert_eq!((az["INS_TCAL1_TMIN"], az["INS_TCAL1_TMAX"]), (-5.0, 55.0));
    assert!(az.keys().all(|k| !k.ends_with("_X") && !k.ends_with("_Y")), "{az:?}");
    // The same axis from the three-axis log (same rows, same fit, TREF at the middle of
    // the training temperatures): PX4's formula gives the same offsets inside the range.
    let (ok, text) = calibrate(&full_log, &d.join("full"), &["--px4-device-id", "7"]);
    assert!(ok, "{text}");
    let pf = read_px4_params(&std::fs::read_to_string(d.join("full/px4_tc.params")).unwrap());
    for t in [-5.0, 0.0, 12.5, 25.0, 40.0, 55.0] {
        let (a, b) = (common::px4_offset(&pz, 2, t), common::px4_offset(&pf, 2, t));
        assert!((a - b).abs() < 1e-6 * G0, "{t} °C: {a} vs {b} m/s²");
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// A cycling log's export is one axis (`--axis`): the same rule. The simulated unit (JB-KT8
/// #1 preset) has bias 120 µg + 12 µg/°C·ΔT + 0.02 µg/°C²·ΔT² about 22 °C, so the cubic's
/// slope at TREF is 12 + 0.04·(TREF − 22) µg/°C (× g0 in m/s²); 10 % covers the log's noise
/// and its heating/cooling split.
#[test]
fn a_cycling_log_exports_its_axis_about_the_shared_range() {
    let d = dir("cycling");
    let log = d.join("log10.csv");
    let (ok, text) = lab(&["simulate", "--out", log.to_str().unwrap(), "--row-s", "10", "--seed", "3"]);
    assert!(ok, "{text}");
    let out = d.join("cal");
    let (ok, text) = lab(&[
        "calibrate",
        "--log",
        log.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
        "--axis",
        "z",
        "--px4-device-id",
        "7",
        "--export-range",
        "-40,60",
    ]);
    assert!(ok, "{text}");
    let p = read_px4_params(&std::fs::read_to_string(out.join("px4_tc.params")).unwrap());
    let v = |n: &str| -> f64 { p[n].0.parse().unwrap() };
    assert_eq!((v("TC_A0_TREF"), v("TC_A0_TMIN"), v("TC_A0_TMAX")), (10.0, -40.0, 60.0));
    let want = (12e-6 + 0.04e-6 * (10.0 - 22.0)) * G0;
    let got = v("TC_A0_X1_2");
    assert!((got - want).abs() < 0.1 * want, "TC_A0_X1_2 {got} vs {want}");
    assert!(!p.contains_key("TC_A0_X1_0") && !p.contains_key("TC_A0_X1_1"));
    let a = read_parm(&std::fs::read_to_string(out.join("ardupilot_tcal_2_values.parm")).unwrap());
    assert!(a.contains_key("INS_TCAL1_ACC1_Z") && !a.contains_key("INS_TCAL1_ACC1_X"), "{a:?}");
    let _ = std::fs::remove_dir_all(&d);
}
