//! Helpers shared by the CLI tests: run `qfa-lab`, read the exported parameter files, and
//! apply each stack's published compensation formula to a log. The formulas are written
//! here from the stacks' sources, independently of `qfa_calibrate::peers` (the fitter
//! and the exporter), so a test that compares their result with the report checks the
//! exported file, not the code that wrote it.

#![allow(dead_code)]

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::Command;

/// Standard gravity, m/s² (both stacks work in m/s²; the report is in mg).
pub const G0: f64 = 9.806_65;

/// Run qfa-lab, which must succeed; its stdout + stderr.
pub fn lab_ok(args: &[&str]) -> String {
    let (ok, text) = lab(args);
    assert!(ok, "qfa-lab {args:?} failed:\n{text}");
    text
}

/// A fresh folder for test `test`'s case `name` in the system's temporary folder.
pub fn fresh_dir(test: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("qfa-{test}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Run qfa-lab; (success, stdout + stderr).
pub fn lab(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_qfa-lab")).args(args).output().expect("run qfa-lab");
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    (out.status.success(), text)
}

/// A QGroundControl `.params` file (tab-separated: vehicle, component, name, value, type;
/// `#` comment lines): name → (value text, type).
pub fn read_px4_params(text: &str) -> BTreeMap<String, (String, u32)> {
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split('\t').collect();
            assert_eq!(f.len(), 5, "not a .params line: {l:?}");
            (f[2].to_string(), (f[3].to_string(), f[4].parse().expect("type")))
        })
        .collect()
}

/// A Mission Planner `.parm` file (`NAME,VALUE`, `#` comment lines): name → value.
pub fn read_parm(text: &str) -> BTreeMap<String, f64> {
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let (n, v) = l.split_once(',').unwrap_or_else(|| panic!("not a .parm line: {l:?}"));
            (n.to_string(), v.trim().parse().unwrap_or_else(|_| panic!("value of {l:?}")))
        })
        .collect()
}

/// PX4's thermal offset of accelerometer 0, axis `i` (0 = X), m/s², at temperature `t`:
/// `TemperatureCompensation::calc_thermal_offsets_3D` (PX4-Autopilot,
/// src/modules/temperature_compensation): dT = T clipped to [TMIN, TMAX] minus TREF, offset
/// = X0 + X1·dT + X2·dT² + X3·dT³; `calibration::Accelerometer::Correct` subtracts it (and
/// the ordinary calibration's offset) from the raw sensor-frame reading.
pub fn px4_offset(p: &BTreeMap<String, (String, u32)>, i: usize, t: f64) -> f64 {
    px4_offset_slot(p, 0, i, t)
}

/// [`px4_offset`] of thermal-compensation slot `slot` (`TC_A{slot}_*`).
pub fn px4_offset_slot(p: &BTreeMap<String, (String, u32)>, slot: usize, i: usize, t: f64) -> f64 {
    let f = |n: &str| -> f64 { p[n].0.parse().unwrap_or_else(|_| panic!("{n} = {}", p[n].0)) };
    let d = t.clamp(f(&format!("TC_A{slot}_TMIN")), f(&format!("TC_A{slot}_TMAX"))) - f(&format!("TC_A{slot}_TREF"));
    (0..4).map(|k: i32| f(&format!("TC_A{slot}_X{k}_{i}")) * d.powi(k)).sum()
}

/// ArduPilot's correction subtracted from accelerometer axis `a` (`X`, `Y`, `Z`) of IMU 1,
/// m/s², at temperature `t`, for an accelerometer calibrated at `cal_temp`:
/// `AP_InertialSensor::TCal::correct_sensor` (ArduPilot,
/// libraries/AP_InertialSensor/AP_InertialSensor_tempcal.cpp): both temperatures clipped to
/// [TMIN, TMAX]; p(d) = (ACC1·d + ACC2·d² + ACC3·d³)·10⁻⁶ about the fixed 35 °C; the reading
/// is corrected by −p(T − 35) + p(CALTEMP − 35).
pub fn ardupilot_correction(p: &BTreeMap<String, f64>, a: &str, t: f64, cal_temp: f64) -> f64 {
    ardupilot_correction_imu(p, 1, a, t, cal_temp)
}

/// [`ardupilot_correction`] of IMU `n` (1-based: `INS_TCAL{n}_*`, IMU instance n − 1).
pub fn ardupilot_correction_imu(p: &BTreeMap<String, f64>, n: usize, a: &str, t: f64, cal_temp: f64) -> f64 {
    let (lo, hi) = (p[&format!("INS_TCAL{n}_TMIN")], p[&format!("INS_TCAL{n}_TMAX")]);
    let poly = |x: f64| -> f64 {
        let d = x.clamp(lo, hi) - 35.0;
        (1..=3).map(|k| p[&format!("INS_TCAL{n}_ACC{k}_{a}")] * d.powi(k)).sum::<f64>() * 1e-6
    };
    poly(t) - poly(cal_temp)
}

/// RMS over every row, mg, of `corrected` (m/s²) after its mean (the constant the ordinary
/// accelerometer calibration takes up).
pub fn all_rows_rms_mg(corrected: &[f64]) -> f64 {
    let m = corrected.iter().sum::<f64>() / corrected.len() as f64;
    (corrected.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / corrected.len() as f64).sqrt() / G0 * 1e3
}

/// Check the exported files in `dir` against `report.json` there: apply PX4's and
/// ArduPilot's formula to the log (`time_s` from its first kept row, `temp_c`, `acc` per
/// axis in m/s²) and compare the RMS over every row (the files are fitted on every row)
/// with the report's `exported_cubic` / `exported_ardupilot` figures of each axis. Returns the lines of a table (axis, PX4 formula vs report,
/// ArduPilot formula vs report) and asserts each within `tol` (relative).
pub fn check_exports_against_report(
    dir: &std::path::Path,
    time_s: &[f64],
    temp_c: &[f64],
    acc: &[Vec<f64>],
    tol: f64,
) -> Vec<String> {
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
    let px4 = read_px4_params(&std::fs::read_to_string(dir.join("px4_tc.params")).expect("px4_tc.params"));
    let mut ap = read_parm(&std::fs::read_to_string(dir.join("ardupilot_tcal_1_enable.parm")).expect("enable file"));
    ap.extend(read_parm(&std::fs::read_to_string(dir.join("ardupilot_tcal_2_values.parm")).expect("values file")));
    let mut lines = Vec::new();
    for (k, a) in report["axes"].as_array().unwrap().iter().enumerate() {
        let (i, name) = match a["axis"].as_str().unwrap() {
            "ax" => (0, "X"),
            "ay" => (1, "Y"),
            _ => (2, "Z"),
        };
        let corr_px4: Vec<f64> = (0..time_s.len()).map(|r| acc[k][r] - px4_offset(&px4, i, temp_c[r])).collect();
        // Any calibration temperature: its term is a constant, which the training mean takes up.
        let corr_ap: Vec<f64> =
            (0..time_s.len()).map(|r| acc[k][r] - ardupilot_correction(&ap, name, temp_c[r], 25.0)).collect();
        let _ = time_s;
        let (got_px4, got_ap) = (all_rows_rms_mg(&corr_px4), all_rows_rms_mg(&corr_ap));
        let want_px4 = a["exported_cubic"]["rms_mg"].as_f64().expect("exported_cubic");
        let want_ap = a["exported_ardupilot"]["rms_mg"].as_f64().expect("exported_ardupilot");
        lines.push(format!(
            "{}: PX4 formula {got_px4:.4} mg vs report cubic {want_px4:.4} mg ({:+.2} %); ArduPilot formula \
             {got_ap:.4} mg vs report {want_ap:.4} mg ({:+.2} %)",
            a["axis"].as_str().unwrap(),
            100.0 * (got_px4 / want_px4 - 1.0),
            100.0 * (got_ap / want_ap - 1.0)
        ));
        assert!((got_px4 - want_px4).abs() <= tol * want_px4, "{}", lines.last().unwrap());
        assert!((got_ap - want_ap).abs() <= tol * want_ap, "{}", lines.last().unwrap());
    }
    lines
}

pub mod browser;
pub mod html;

/// The real chamber log: from `QFA_REAL_IMU_LOG`, else beside the repository in
/// `shared/real/`; absent, a loud SKIPPED line that says how to get it (and, with `CI=true`,
/// a failure).
pub fn real_log() -> Option<PathBuf> {
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

/// The reader flags of [`write_static_log`]'s log.
pub const STATIC_FLAGS: [&str; 6] =
    ["--columns", "time=time,temp=temp,ax=ax,ay=ay,az=az", "--time-unit", "s", "--accel-unit", "g"];

/// A static three-axis log (columns `time temp ax ay az`, [`STATIC_FLAGS`]), 1-s rows for 2 h:
/// 25 → 60 → −10 → 40 °C, each axis's bias a different curve in T with a small branch split,
/// and deterministic noise.
pub fn write_static_log(path: &std::path::Path) {
    write_static_log_every(path, 1);
}

/// [`write_static_log`] with a row every `step_s` seconds (the same 2 h, fewer rows).
pub fn write_static_log_every(path: &std::path::Path, step_s: u32) {
    let mut s = String::from("time\ttemp\tax\tay\taz\n");
    let mut rng = qfa_rng::seeded(7);
    let mut noise = || (qfa_rng::uniform(&mut rng) - 0.5) * 2e-4;
    let legs = [(25.0, 60.0, 1800 / step_s), (60.0, -10.0, 3600 / step_s), (-10.0, 40.0, 1800 / step_s)];
    let mut t = 0;
    for (a, b, n) in legs {
        for i in 0..n {
            let temp: f64 = a + (b - a) * f64::from(i) / f64::from(n);
            let dir: f64 = if b > a { 1.0 } else { -1.0 };
            let dt = temp - 25.0;
            let ax = 1e-4 * dt + 2e-7 * dt * dt + 1e-4 * dir + noise();
            let ay = -5e-5 * dt + 3e-5 * dir + noise();
            let az = -1.0 + 2e-7 * dt * dt * dt / 10.0 + noise();
            s.push_str(&format!("{t}\t{:.4}\t{ax:.7}\t{ay:.7}\t{az:.7}\n", (temp * 16.0).round() / 16.0));
            t += step_s;
        }
    }
    std::fs::write(path, s).unwrap();
}

/// Exact (Clopper–Pearson) one-sided 95 % upper bound of a binomial rate, by bisection
/// on the binomial tail P(X ≤ k | n, p) = 0.05.
pub fn upper_bound(k: usize, n: usize) -> f64 {
    let cdf = |p: f64| {
        let mut term = (1.0 - p).powi(n as i32);
        let mut sum = term;
        for j in 1..=k {
            term *= (n - j + 1) as f64 / j as f64 * p / (1.0 - p);
            sum += term;
        }
        sum
    };
    let (mut lo, mut hi) = (k as f64 / n as f64, 1.0 - 1e-12);
    for _ in 0..60 {
        let m = 0.5 * (lo + hi);
        if cdf(m) > 0.05 {
            lo = m;
        } else {
            hi = m;
        }
    }
    hi
}

/// Every `.csv` under `dir` reads as `pandas.read_csv(path)` and Python's `csv` read a
/// file given no options: the first line is the header (no `#` comment), every line has
/// the header's field count, and every field is finite where it parses as a number (a
/// column of NaN is a figure that could not be computed). Returns the files checked.
pub fn assert_plain_csvs(dir: &std::path::Path) -> usize {
    let mut checked = 0;
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "csv") {
                let text = std::fs::read_to_string(&p).unwrap();
                let mut lines = text.lines();
                let header = lines.next().unwrap_or_else(|| panic!("{}: empty", p.display()));
                assert!(!header.starts_with('#'), "{}: opens with a comment line: {header}", p.display());
                let fields = header.split(',').count();
                for (i, line) in lines.enumerate() {
                    let row: Vec<&str> = line.split(',').collect();
                    assert_eq!(row.len(), fields, "{} line {}: {line}", p.display(), i + 2);
                    for f in row {
                        let lower = f.trim().to_ascii_lowercase();
                        assert!(
                            !matches!(lower.as_str(), "nan" | "inf" | "-inf" | "null" | ""),
                            "{} line {}: `{f}` in {line}",
                            p.display(),
                            i + 2
                        );
                    }
                }
                checked += 1;
            }
        }
    }
    checked
}

/// RMS (mg) over `span` (°C) in 1-°C steps, both branches, of a unit's true bias `truth(t,
/// heating)` (g, at the temperature `t` it is written in) less what `table`'s axis `k`
/// applies at the unit's reading `t + offset_c`, after removing their mean difference (a
/// constant is the orientation's, which no static log tells apart). The population studies'
/// error of a table against the truth, for either generator.
pub fn table_error_mg(
    table: &qfa_thermal::Table,
    k: usize,
    offset_c: f64,
    span: [f64; 2],
    truth: impl Fn(f64, bool) -> f64,
) -> f64 {
    use qfa_thermal::model::Branch;
    let mut d = Vec::new();
    let mut t = span[0].ceil();
    while t <= span[1].floor() {
        for (b, heating) in [(Branch::Heating, true), (Branch::Cooling, false)] {
            d.push(truth(t, heating) - f64::from(table.axes[k].bias.k0((t + offset_c) as f32, b)));
        }
        t += 1.0;
    }
    let m = d.iter().sum::<f64>() / d.len() as f64;
    (d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / d.len() as f64).sqrt() * 1e3
}

/// Eq. 11's K1 of `c` at ΔT `d` (°C) and Ṫ `r` (°C/min), pulses/(g·s), in f64 (written
/// here from the paper, not by the crate).
pub fn eq11_k1(c: &qfa_thermal::ScaleFactor, d: f64, r: f64) -> f64 {
    let f = |x: f32| f64::from(x);
    f(c.gamma) + f(c.mu) * d + f(c.beta) * d * d + f(c.epsilon) * r + f(c.eta) * r * d + f(c.alpha) * r * r
}

/// A QFA table's (axis 0) error against its unit's truth over `span` in 1-°C steps, the
/// truth in case temperature at rest and the table in the sensor's (`offset_c` above it):
/// the scale factor's RMS over rates of 0, ±0.15 and ±0.3 °C/min (the rates the paper's
/// staircases hold the case at) relative to the truth's K1 at rest, ppm, and the bias's RMS
/// on both branches, µg. `k1(T, Ṫ)` in pulses/(g·s) and `k0(T)` in g are the truth's own;
/// the table's Eq. 11 is evaluated here in f64 from its coefficients, not by the crate.
pub fn qfa_table_error(
    table: &qfa_thermal::Table,
    offset_c: f64,
    span: [f64; 2],
    k1: impl Fn(f64, f64) -> f64,
    k0: impl Fn(f64) -> f64,
) -> (f64, f64) {
    use qfa_thermal::model::Branch;
    let axis = &table.axes[0];
    let c = &axis.scale;
    let f = |x: f32| f64::from(x);
    let table_k1 = |d: f64, r: f64| eq11_k1(c, d, r);
    let (mut sf, mut bias) = (Vec::new(), Vec::new());
    let mut t = span[0].ceil();
    while t <= span[1].floor() {
        let sensor = t + offset_c;
        let at_rest = k1(t, 0.0);
        for r in [-0.3, -0.15, 0.0, 0.15, 0.3] {
            sf.push((table_k1(sensor - f(c.t0_c), r) - k1(t, r)) / at_rest * 1e6);
        }
        for b in [Branch::Heating, Branch::Cooling] {
            bias.push((f(axis.bias.k0(sensor as f32, b)) - k0(t)) * 1e6);
        }
        t += 1.0;
    }
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    (rms(&sf), rms(&bias))
}

/// The largest robust distance any unit `good` says is good reached on any of `fleet`'s
/// figures (the flag studies' margin below the flag line), each against the yardstick the
/// fleet compares it with (its lot's, when the fleet holds two).
pub fn largest_good_distance(fleet: &qfa_batch::fleet::Fleet, good: impl Fn(&str) -> bool) -> f64 {
    fleet
        .stats
        .iter()
        .flat_map(|s| {
            s.values
                .iter()
                .filter(|(serial, _)| good(serial))
                .map(|(serial, v)| s.distance(*v, fleet.lot_of(serial)).abs())
                .collect::<Vec<_>>()
        })
        .fold(0.0, f64::max)
}

/// Every file in each unit's folder of `out` is one the batch clears before it calibrates
/// the unit again ([`qfa_batch::UNIT_FILES`]): a new output missing from that list would
/// outlive a later batch in which its unit failed.
pub fn assert_unit_files_are_listed(out: &std::path::Path) {
    for unit in std::fs::read_dir(out).unwrap().filter_map(Result::ok).filter(|e| e.path().is_dir()) {
        for f in std::fs::read_dir(unit.path()).unwrap().filter_map(Result::ok) {
            let name = f.file_name().to_string_lossy().into_owned();
            assert!(
                qfa_batch::UNIT_FILES.contains(&name.as_str()),
                "{}: {name} is not in UNIT_FILES",
                unit.path().display()
            );
        }
    }
}

/// Rewrite the log at `path`: its first line (the header) kept, each later line replaced by
/// `row(line)` (which may return several lines, or none); returns how many lines it mapped.
pub fn rewrite_rows(path: &std::path::Path, row: impl Fn(&str) -> String) -> usize {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let mut out = format!("{}\n", lines.next().unwrap());
    let mut mapped = 0usize;
    for l in lines {
        out.push_str(&row(l));
        mapped += 1;
    }
    std::fs::write(path, out).unwrap();
    mapped
}
