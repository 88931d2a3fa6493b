//! PX4 ULog and ArduPilot DataFlash logs through `qfa-lab calibrate`, with no device ID
//! typed, and the 1 °C temperature measurement on the real chamber log.
//!
//! The logs come from `tests/fixtures/autopilot_logs.py` (standard-library Python, checked
//! against pyulog and pymavlink's DFReader by `tests/fixtures/test_autopilot_logs.py`), run
//! at test time: three instances each (0.01 °C temperature with compensation on, 1 °C
//! steps, no temperature), biases a known cubic of the true temperature. The exported files
//! are checked by applying each stack's published formula (`tests/common`, written from
//! the stacks' sources, not from the exporter) to the raw samples the generator wrote
//! beside each log. Without python3 the tests print SKIPPED; with `CI=true` they fail.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use common::{ardupilot_correction_imu, lab, px4_offset_slot, read_parm, read_px4_params, G0};

/// The generated logs' directory, or None (SKIPPED) without python3. Generated once per
/// test process: the tests run in parallel, and a second run of the generator rewrote the
/// files one test was reading (a samples line cut short, seen once in CI).
fn generated() -> Option<PathBuf> {
    static DIR: std::sync::OnceLock<Option<PathBuf>> = std::sync::OnceLock::new();
    DIR.get_or_init(generate).clone()
}

/// Run the generator into this process's directory.
fn generate() -> Option<PathBuf> {
    let dir = std::env::temp_dir().join(format!("qfa-aplogs-{}", std::process::id()));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/autopilot_logs.py");
    let status = Command::new("python3").arg(&script).arg("--out").arg(&dir).status();
    match status {
        Ok(s) if s.success() => Some(dir),
        other => {
            let msg = format!(
                "SKIPPED: python3 {} failed or is missing ({other:?}); install python3 (standard library only)",
                script.display()
            );
            assert!(std::env::var("CI").as_deref() != Ok("true"), "{msg}");
            eprintln!("{msg}");
            None
        }
    }
}

/// One instance's samples as the generator wrote them.
#[derive(Default)]
struct Samples {
    temp: Vec<f64>,
    temp_true: Vec<f64>,
    acc: [Vec<f64>; 3],
}

fn samples(path: &Path) -> BTreeMap<u8, Samples> {
    let mut out: BTreeMap<u8, Samples> = BTreeMap::new();
    let text = std::fs::read_to_string(path).unwrap();
    for l in text.lines().skip(1) {
        let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
        let s = out.entry(f[0] as u8).or_default();
        s.temp.push(f[2]);
        for a in 0..3 {
            s.acc[a].push(f[3 + a]);
        }
        s.temp_true.push(f[6]);
    }
    out
}

/// The generator's truth: per instance, device ID and (c1, c2, c3) per axis.
fn truth(path: &Path) -> Vec<(u32, [[f64; 3]; 3])> {
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    j["instances"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| {
            let c = |a: usize, k: usize| i["coef"][a][k].as_f64().unwrap();
            (i["device_id"].as_u64().unwrap() as u32, [0, 1, 2].map(|a| [c(a, 0), c(a, 1), c(a, 2)]))
        })
        .collect()
}

fn bias(c: &[f64; 3], t: f64) -> f64 {
    let x = (t - 25.0) / 40.0;
    c[0] * x + c[1] * x * x + c[2] * x * x * x
}

/// RMS after the mean (the constant the ordinary accelerometer calibration takes up), m/s².
fn rms_centred(v: &[f64]) -> f64 {
    let m = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / v.len() as f64).sqrt()
}

fn report(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap()
}

/// Per axis of one instance: (corrected by `correction`, best the stack can do: the true
/// bias at the logged temperature removed, uncorrected), RMS in m/s².
fn figures(s: &Samples, coef: &[[f64; 3]; 3], correction: impl Fn(usize, f64) -> f64) -> Vec<(f64, f64, f64)> {
    (0..3)
        .map(|a| {
            let corrected: Vec<f64> = (0..s.temp.len()).map(|r| s.acc[a][r] - correction(a, s.temp[r])).collect();
            let best: Vec<f64> = (0..s.temp.len()).map(|r| s.acc[a][r] - bias(&coef[a], s.temp[r])).collect();
            (rms_centred(&corrected), rms_centred(&best), rms_centred(&s.acc[a]))
        })
        .collect()
}

/// The PX4 ULog: instance 0 (logged with TC_A_ENABLE = 1 and TC_A0_ID = its ID) is
/// calibrated with that stated, instance 1 (1 °C steps) is named and calibrated, instance 2
/// (no temperature) refused; `px4_tc.params` holds a slot per calibrated instance whose
/// `TC_An_ID` is that instance's device ID from the log, and PX4's formula with that slot,
/// applied to the instance's raw samples, leaves within 10 % of the RMS the true bias
/// leaves (the noise), where the uncorrected samples are at least 5× it and the other
/// instance's slot at least 2× it (so a swapped or mistyped ID fails).
#[test]
fn ulog_every_instance_its_id_and_px4_formula() {
    let Some(dir) = generated() else { return };
    let log = dir.join("thermal.ulg");
    let out = dir.join("cal-ulg");
    // An earlier run's plot in an instance's folder: this run draws none (`--no-plots`), so
    // a plot left there would read as this run's.
    let stale = out.join("instance0").join("bias_vs_temp.png");
    std::fs::create_dir_all(stale.parent().unwrap()).unwrap();
    std::fs::write(&stale, b"an earlier run's plot").unwrap();
    let (ok, text) = lab(&["calibrate", "--log", log.to_str().unwrap(), "--out", out.to_str().unwrap(), "--no-plots"]);
    assert!(ok, "{text}");
    assert!(!stale.exists(), "an earlier run's plot stayed in instance0/");
    println!("{text}");
    let r = report(&out);
    let inst = r["instances"].as_array().unwrap();
    let warnings = |i: usize| inst[i]["warnings"].to_string();
    assert!(inst[0]["refused"].is_null() && warnings(0).contains("TC_A_ENABLE = 1 and TC_A0_ID"), "{}", inst[0]);
    assert!(inst[1]["refused"].is_null() && warnings(1).contains("1.000 °C steps"), "{}", inst[1]);
    assert_eq!(inst[1]["temp_dequantized"], true);
    assert!(inst[2]["refused"].as_str().unwrap().contains("has no temperature"), "{}", inst[2]);
    // The log's own page opens with the verdict of every instance, refusals said in words.
    if let Some(items) = common::browser::assert_verdict_first(&out.join("report.html")) {
        assert!(items.iter().any(|i| i.starts_with("warning: instance 2 refused: ")), "{items:?}");
        assert!(items.iter().any(|i| i.starts_with("expect in use: held-out bias RMS: instance 0 ax ")), "{items:?}");
    }

    let truth = truth(&dir.join("thermal.ulg.truth.json"));
    let s = samples(&dir.join("thermal.ulg.samples.csv"));
    let p = read_px4_params(&std::fs::read_to_string(out.join("px4_tc.params")).unwrap());
    assert_eq!(p["TC_A_ENABLE"].0, "1");
    let slot_of = |id: u32| -> Vec<usize> {
        (0..4)
            .filter(|k| p.get(&format!("TC_A{k}_ID")).is_some_and(|v| v.0.parse::<i64>().unwrap() as u32 == id))
            .collect()
    };
    assert!(slot_of(truth[2].0).is_empty(), "the refused instance has no slot");
    let slots: Vec<usize> = (0..2)
        .map(|i| {
            let s = slot_of(truth[i].0);
            assert_eq!(s.len(), 1, "device {} in slots {s:?}", truth[i].0);
            s[0]
        })
        .collect();
    for i in 0..2 {
        let f = figures(&s[&(i as u8)], &truth[i].1, |a, t| px4_offset_slot(&p, slots[i], a, t));
        let wrong = figures(&s[&(i as u8)], &truth[i].1, |a, t| px4_offset_slot(&p, slots[1 - i], a, t));
        for (a, ((got, best, none), (w, _, _))) in f.iter().zip(&wrong).enumerate() {
            println!(
                "instance {i} axis {a}: PX4 formula on TC_A{}: {:.3} mg, true bias removed {:.3} mg, none {:.3} mg, \
                 other slot {:.3} mg",
                slots[i],
                got / G0 * 1e3,
                best / G0 * 1e3,
                none / G0 * 1e3,
                w / G0 * 1e3
            );
            assert!(*got <= 1.10 * best, "instance {i} axis {a}: {got} vs {best}");
            assert!(*none >= 5.0 * best && *w >= 2.0 * best, "the check could not fail: {none} {w} vs {best}");
        }
    }
    // The ID is the log's: typing one is refused.
    let (ok, text) = lab(&[
        "calibrate",
        "--log",
        log.to_str().unwrap(),
        "--out",
        dir.join("typed").to_str().unwrap(),
        "--px4-device-id",
        "1",
    ]);
    assert!(!ok && text.contains("the log holds each accelerometer's"), "{text}");
}

/// The DataFlash log: IMU 0 (INS_TCAL1_ENABLE = 1) refused as already compensated, IMU 2
/// (T = 0 throughout) refused for no temperature, IMU 1 (1 °C steps) named and exported as
/// `INS_TCAL2_*` only; ArduPilot's formula with `INS_TCAL2_*` on IMU 1's raw samples leaves
/// within 10 % of what the true bias leaves, the uncorrected samples at least 5× it.
#[test]
fn dataflash_refuses_the_compensated_imu_and_exports_the_other_as_its_instance() {
    let Some(dir) = generated() else { return };
    let out = dir.join("cal-bin");
    let (ok, text) = lab(&[
        "calibrate",
        "--log",
        dir.join("thermal.bin").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
    ]);
    assert!(ok, "{text}");
    println!("{text}");
    let r = report(&out);
    let inst = r["instances"].as_array().unwrap();
    let refused = |i: usize| inst[i]["refused"].as_str().unwrap_or("").to_string();
    assert!(refused(0).contains("INS_TCAL1_ENABLE = 1") && refused(0).contains("compensate twice"), "{}", inst[0]);
    assert!(refused(2).contains("has no temperature"), "{}", inst[2]);
    assert!(inst[1]["refused"].is_null() && inst[1]["warnings"].to_string().contains("1.000 °C steps"), "{}", inst[1]);
    let truth = truth(&dir.join("thermal.bin.truth.json"));
    assert_eq!(inst[1]["device_id"].as_u64(), Some(u64::from(truth[1].0)), "INS_ACC2_ID");
    assert!(!out.join("px4_tc.params").exists(), "a DataFlash log's IDs are ArduPilot's: no PX4 file");
    let mut p = read_parm(&std::fs::read_to_string(out.join("ardupilot_tcal_1_enable.parm")).unwrap());
    p.extend(read_parm(&std::fs::read_to_string(out.join("ardupilot_tcal_2_values.parm")).unwrap()));
    assert_eq!(p.get("INS_TCAL2_ENABLE"), Some(&1.0));
    assert!(p.keys().all(|k| !k.starts_with("INS_TCAL1_") && !k.starts_with("INS_TCAL3_")), "{:?}", p.keys());
    let s = samples(&dir.join("thermal.bin.samples.csv"));
    let f = figures(&s[&1], &truth[1].1, |a, t| ardupilot_correction_imu(&p, 2, ["X", "Y", "Z"][a], t, 25.0));
    for (a, (got, best, none)) in f.iter().enumerate() {
        println!(
            "IMU 1 axis {a}: ArduPilot formula on INS_TCAL2: {:.3} mg, true bias removed {:.3} mg, none {:.3} mg",
            got / G0 * 1e3,
            best / G0 * 1e3,
            none / G0 * 1e3
        );
        assert!(*got <= 1.10 * best, "axis {a}: {got} vs {best}");
        assert!(*none >= 5.0 * best, "the check could not fail: {none} vs {best}");
    }
}
