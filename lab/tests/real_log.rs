//! The real measured log (tofupilot IMU thermal cycle), end to end through the CLI with only
//! `--columns` and unit flags: calibrate, compensate, discover.
//!
//! The file is not in this repository. It is GitHub `tofupilot/examples`,
//! `templates/imu_thermal_calibration/data/imu_raw_data.csv` at commit
//! fc190f7cd507ec6b53fba4c4368b1a2a0a8e5125 (MIT), tab-separated. The test looks for it at
//! `$QFA_REAL_IMU_LOG`, else at `<repo>/../shared/real/tofupilot-imu-thermal-cycle/imu_raw_data.tsv`.
//! Missing, it prints a SKIPPED line; with `CI=true` a missing file fails.

mod common;

use std::path::PathBuf;
use std::process::Command;

fn real_log() -> Option<PathBuf> {
    let p = std::env::var_os("QFA_REAL_IMU_LOG").map(PathBuf::from).unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/real/tofupilot-imu-thermal-cycle/imu_raw_data.tsv")
    });
    if p.is_file() {
        return Some(p);
    }
    let msg = format!(
        "SKIPPED: real IMU log not found at {} (set QFA_REAL_IMU_LOG): fetch it from GitHub tofupilot/examples, \
         templates/imu_thermal_calibration/data/imu_raw_data.csv at commit fc190f7cd507ec6b53fba4c4368b1a2a0a8e5125",
        p.display()
    );
    assert!(std::env::var("CI").as_deref() != Ok("true"), "{msg}");
    eprintln!("{msg}");
    None
}

const FLAGS: [&str; 6] = [
    "--columns",
    "time=timestamp,temp=imu.temperature,ax=imu.acc.x,ay=imu.acc.y,az=imu.acc.z",
    "--time-unit",
    "us",
    "--accel-unit",
    "m/s2",
];

fn lab(args: &[&str]) -> std::process::Output {
    let out = Command::new(env!("CARGO_BIN_EXE_qfa-lab")).args(args).output().expect("run qfa-lab");
    assert!(out.status.success(), "qfa-lab {args:?} failed:\n{}", String::from_utf8_lossy(&out.stderr));
    out
}

#[test]
fn calibrate_beats_the_cubic_on_every_axis_and_compensate_agrees() {
    let Some(log) = real_log() else { return };
    let dir = std::env::temp_dir().join(format!("qfa-real-{}", std::process::id()));
    let out_dir = dir.join("cal");
    let log_s = log.to_str().unwrap();
    let mut args = vec!["calibrate", "--log", log_s, "--out", out_dir.to_str().unwrap()];
    args.extend(FLAGS);
    let out = lab(&args);
    println!("{}", String::from_utf8_lossy(&out.stdout));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("report.json")).unwrap()).unwrap();
    // The reader: 8 400 data rows, the first (line 2) a glitch, skipped and reported.
    assert_eq!(report["rows"], 8399);
    assert_eq!(report["skipped"]["glitch"]["count"], 1);
    assert_eq!(report["skipped"]["glitch"]["lines"][0], 2);
    let axes = report["axes"].as_array().unwrap();
    assert_eq!(axes.len(), 3);
    let f = |a: &serde_json::Value, k: &str| a[k]["rms_mg"].as_f64().unwrap();
    for a in axes {
        let (ours, cubic, none) = (f(a, "ours"), f(a, "cubic"), f(a, "none"));
        // Sanity that the comparison can fail: no compensation is far worse than the cubic.
        assert!(none > cubic, "{a}");
        // The acceptance rule (fixed before the result): ours beats the cubic.
        assert!(ours > 0.0 && ours < cubic, "{}: ours {ours:.2} mg vs cubic {cubic:.2} mg", a["axis"]);
    }
    for file in ["table.bin", "table.toml", "report.md", "ardupilot_tcal_1_enable.parm", "ardupilot_tcal_2_values.parm"]
    {
        assert!(out_dir.join(file).is_file(), "{file}");
    }
    // Without --px4-device-id no PX4 file: PX4 would ignore it (TC_A0_ID 0 matches no
    // accelerometer). With it: `exported_parameter_files_reproduce_the_report_peer_figures`.
    assert!(!out_dir.join("px4_tc.params").exists());

    // Compensate with the flashed table; the held-out rows of the output, measured from each
    // axis's reference, give back the report's figure (an independent path: CSV text).
    let comp = dir.join("comp.csv");
    let table = out_dir.join("table.bin");
    let mut args =
        vec!["compensate", "--log", log_s, "--table", table.to_str().unwrap(), "--out", comp.to_str().unwrap()];
    args.extend(FLAGS);
    lab(&args);
    let mut rdr = csv::Reader::from_path(&comp).unwrap();
    let head: Vec<String> = rdr.headers().unwrap().iter().map(str::to_string).collect();
    assert_eq!(head, ["time_s", "temp_c", "ax", "ay", "az", "status"]);
    let rows: Vec<csv::StringRecord> = rdr.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 8399);
    let split_t = report["split_time_s"].as_f64().unwrap();
    for (k, a) in axes.iter().enumerate() {
        let got = heldout_rms_mg(&rows, k, a["reference_g"].as_f64().unwrap(), split_t);
        let want = f(a, "ours");
        assert!((got - want).abs() < 0.01 * want, "{}: compensate {got:.3} mg vs report {want:.3} mg", a["axis"]);
    }

    // Discovery on each axis (a static log's axis is a single-channel bias log for it), on
    // the same split: its peer figures are calibrate's, formed by a different path.
    let disc = dir.join("disc");
    let drep = discover_real(log_s, &disc);
    let daxes = drep["axes"].as_array().unwrap();
    assert_eq!(daxes.len(), 3);
    assert_eq!(drep["split_time_s"], report["split_time_s"]);
    for (d, a) in daxes.iter().zip(axes) {
        for peer in ["cubic", "ardupilot", "simple", "none"] {
            let (got, want) = (f(d, peer), f(a, peer));
            assert!((got - want).abs() < 1e-9, "{} {peer}: discover {got} mg vs calibrate {want} mg", d["axis"]);
        }
        for k in ["before", "after"] {
            assert!(f(d, k).is_finite() && f(d, k) > 0.0, "{d}");
        }
        assert!(disc.join(d["axis"].as_str().unwrap()).join("report.json").is_file());
    }
    // Discover, then compensate: the flashed table gives back the report's held-out figure
    // of the flashed model on every axis.
    let comp = dir.join("comp-disc.csv");
    let table = disc.join("table.bin");
    let mut args =
        vec!["compensate", "--log", log_s, "--table", table.to_str().unwrap(), "--out", comp.to_str().unwrap()];
    args.extend(FLAGS);
    lab(&args);
    let rows: Vec<csv::StringRecord> = csv::Reader::from_path(&comp).unwrap().records().map(Result::unwrap).collect();
    for (k, d) in daxes.iter().enumerate() {
        let got = heldout_rms_mg(&rows, k, d["reference_g"].as_f64().unwrap(), split_t);
        let want = f(d, "final_model");
        assert!((got - want).abs() < 0.01 * want, "{}: compensate {got:.3} mg vs discover {want:.3} mg", d["axis"]);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// RMS (mg) of axis `k` of `compensate`'s output rows after the split, less `reference` g:
/// computed here from the CSV, independently of the report it is compared with.
fn heldout_rms_mg(rows: &[csv::StringRecord], k: usize, reference: f64, split_t: f64) -> f64 {
    let r: Vec<f64> = rows
        .iter()
        .filter(|r| r[0].parse::<f64>().unwrap() > split_t + 1e-3 && &r[5] != "no_temperature")
        .map(|r| r[2 + k].parse::<f64>().unwrap() - reference)
        .collect();
    (r.iter().map(|x| x * x).sum::<f64>() / r.len() as f64).sqrt() * 1e3
}

/// Run `qfa-lab discover` on the real log into `out`; its `report.json`.
fn discover_real(log_s: &str, out: &std::path::Path) -> serde_json::Value {
    let mut args = vec!["discover", "--start", "paper", "--log", log_s, "--out", out.to_str().unwrap()];
    args.extend(FLAGS);
    let o = lab(&args);
    let text = String::from_utf8_lossy(&o.stdout);
    println!("{text}");
    for axis in ["ax", "ay", "az"] {
        assert!(text.contains(&format!("{axis} (imu.acc.")), "{text}");
    }
    serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

/// Issue 12's acceptance rule for the real log, fixed before the result: on the held-out
/// leg the workflow's model (the one `discover` flashes into `DIR/table.bin`) beats the
/// PX4/tofupilot cubic on every axis. The named model alone does not (measured: x 1.99 mg
/// vs 1.08, z 6.45 vs 5.94; y 1.45 vs 3.47): the 52-min training leg leaves the block test
/// 8 blocks, too few to name what still predicts better, which is why the flashed model is
/// the cross-validated one (module docs of `discover::static_axes`). The test also checks
/// that the flashed choice was made inside the training rows only: its cross-validation
/// RMS is reported, and a model scored on the held-out rows would make the held-out
/// figure of every axis equal the best candidate's, which the README's figures show it is
/// not (x: 0.55 mg flashed, 0.39 mg for the best lag+creep candidate).
#[test]
fn discovery_beats_the_cubic_on_every_axis() {
    let Some(log) = real_log() else { return };
    let dir = std::env::temp_dir().join(format!("qfa-real-disc-{}", std::process::id()));
    let d = discover_real(log.to_str().unwrap(), &dir);
    let mut worse = Vec::new();
    for a in d["axes"].as_array().unwrap() {
        let g = |k: &str| a[k]["rms_mg"].as_f64().unwrap();
        let (flashed, named, cubic, none) = (g("final_model"), g("after"), g("cubic"), g("none"));
        println!(
            "{}: flashed {flashed:.2} mg ({}), named model {named:.2} mg, cubic {cubic:.2} mg",
            a["axis"], a["final_structure"]
        );
        // The comparison can fail: no compensation is far worse than the cubic.
        assert!(none > cubic, "{a}");
        assert!(a["final_cv_rms_mg"].as_f64().unwrap() > 0.0, "{a}");
        if flashed.partial_cmp(&cubic) != Some(std::cmp::Ordering::Less) {
            worse.push(format!("{}: {flashed:.2} mg vs cubic {cubic:.2} mg", a["axis"]));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(worse.is_empty(), "discovery's flashed model not better than the cubic: {worse:?}");
}

/// Issue 13's acceptance rule for the exports, fixed before the result: with
/// `--px4-device-id 1310988` the PX4 file carries `TC_A0_ID 1310988` (int32), and the
/// coefficients of `px4_tc.params` and of the two ArduPilot files, applied to the log with
/// each stack's own formula (`tests/common`, written from the stacks' sources, not from the
/// exporter), give the report's held-out cubic and ArduPilot figures within 3 % on every
/// axis. The log is read here from the TSV text, not through the lab's reader; only the
/// rows the reader dropped (listed with their lines in `report.json`) are left out.
#[test]
fn exported_parameter_files_reproduce_the_report_peer_figures() {
    let Some(log) = real_log() else { return };
    let dir = std::env::temp_dir().join(format!("qfa-real-export-{}", std::process::id()));
    let out_dir = dir.join("cal");
    let mut args = vec![
        "calibrate",
        "--log",
        log.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
        "--px4-device-id",
        "1310988",
    ];
    args.extend(FLAGS);
    lab(&args);
    let params = std::fs::read_to_string(out_dir.join("px4_tc.params")).unwrap();
    let p = common::read_px4_params(&params);
    assert_eq!(p["TC_A0_ID"], ("1310988".to_string(), 6), "{params}");
    assert_eq!(p["TC_A_ENABLE"], ("1".to_string(), 6), "{params}");

    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("report.json")).unwrap()).unwrap();
    let mut dropped: Vec<u64> = Vec::new();
    for kind in ["nan", "duplicate", "glitch"] {
        let s = &report["skipped"][kind];
        let lines = s["lines"].as_array().unwrap();
        // Every dropped row is listed (the report keeps 20 lines per kind).
        assert_eq!(s["count"].as_u64().unwrap(), lines.len() as u64, "{s}");
        dropped.extend(lines.iter().map(|l| l.as_u64().unwrap()));
    }
    let mut rdr = csv::ReaderBuilder::new().delimiter(b'\t').from_path(&log).unwrap();
    let head: Vec<String> = rdr.headers().unwrap().iter().map(str::to_string).collect();
    let col = |n: &str| head.iter().position(|h| h == n).unwrap();
    let (c_time, c_temp) = (col("timestamp"), col("imu.temperature"));
    let ca = [col("imu.acc.x"), col("imu.acc.y"), col("imu.acc.z")];
    let (mut t_us, mut temp, mut acc) = (Vec::new(), Vec::new(), vec![Vec::new(); 3]);
    for (i, r) in rdr.records().enumerate() {
        let r = r.unwrap();
        if dropped.contains(&(i as u64 + 2)) {
            continue;
        }
        t_us.push(r[c_time].parse::<f64>().unwrap());
        temp.push(r[c_temp].parse::<f64>().unwrap());
        for k in 0..3 {
            acc[k].push(r[ca[k]].parse::<f64>().unwrap());
        }
    }
    assert_eq!(t_us.len() as u64, report["rows"].as_u64().unwrap());
    let time_s: Vec<f64> = t_us.iter().map(|t| (t - t_us[0]) * 1e-6).collect();
    for line in common::check_exports_against_report(&out_dir, &time_s, &temp, &acc, 0.03) {
        println!("{line}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
