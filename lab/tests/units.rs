//! Unit mistakes on a synthetic static log (every machine): each is refused through the CLI
//! with the one message style (`wrong unit? read with <flag> <unit> <figure>; <what it must
//! be>: pass <flag> <unit that fits> (<its figure>)`), and the right unit reads the log.
//!
//! Every test here fails on the code before `--temp-unit` and the two-sided acceleration
//! check: there, a unit that makes |a| too small calibrated (exit 0), `--temp-unit` did
//! not exist, and a Fahrenheit log over 130 was refused as malformed rows naming no unit.

use std::path::{Path, PathBuf};
use std::process::Command;

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("qfa-units-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Run `qfa-lab calibrate` on `log` with `flags`; (success, stdout + stderr).
fn calibrate(log: &Path, out: &Path, flags: &[&str]) -> (bool, String) {
    let mut args = vec!["calibrate", "--no-plots", "--log", log.to_str().unwrap(), "--out", out.to_str().unwrap()];
    args.extend(flags);
    let o = Command::new(env!("CARGO_BIN_EXE_qfa-lab")).args(&args).output().expect("run qfa-lab");
    (o.status.success(), format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr)))
}

fn refused(log: &Path, out: &Path, flags: &[&str], want: &str) {
    let (ok, text) = calibrate(log, out, flags);
    assert!(!ok, "{flags:?} calibrated:\n{text}");
    assert!(text.contains(want), "{flags:?}: expected `{want}` in\n{text}");
    assert!(!out.join("table.bin").exists(), "{flags:?}: a table was written");
}

/// A board on a chamber shelf, 1-s rows: 20 → −10 → 60 → 30 °C at 3 °C/min, three axes
/// (z along gravity) in `unit` (`g`, `mg`, `m/s2`), the temperature written by `temp`
/// from °C, under the header `temp_col`.
fn board(path: &Path, unit: &str, temp_col: &str, temp: impl Fn(f64) -> f64) {
    let scale = match unit {
        "g" => 1.0,
        "mg" => 1e3,
        _ => 9.806_65,
    };
    let mut temps = Vec::new();
    let mut t: f64 = 20.0;
    for (target, step) in [(-10.0, -0.05), (60.0, 0.05), (30.0, -0.05)] {
        while (step < 0.0 && t > target) || (step > 0.0 && t < target) {
            temps.push(t);
            t += step;
        }
    }
    let mut s = format!("time_s,{temp_col},acc_x,acc_y,acc_z\n");
    for (i, &tc) in temps.iter().enumerate() {
        let b = 1e-3 * (tc - 20.0) / 40.0 + 2e-6 * (tc - 20.0).powi(2);
        s.push_str(&format!(
            "{i},{:.4},{:.7},{:.7},{:.7}\n",
            temp(tc),
            b * scale,
            (0.01 - b) * scale,
            (-1.0 + b) * scale
        ));
    }
    std::fs::write(path, s).unwrap();
}

/// Both acceleration mistakes of the real log's kind, on a board log: m/s² read as mg (100×
/// too small) and g read as m/s² (9.8× too small), each refused naming the unit that fits;
/// the too-large side (m/s² read as g) still refused.
#[test]
fn accel_units_too_small_or_too_large_are_refused_naming_the_unit_that_fits() {
    let d = dir("accel");
    let mps2 = d.join("mps2.csv");
    board(&mps2, "m/s2", "temp_c", |t| t);
    let g = d.join("g.csv");
    board(&g, "g", "temp_c", |t| t);
    let out = d.join("cal");
    refused(
        &mps2,
        &out,
        &["--accel-unit", "mg"],
        "wrong unit? read with --accel-unit mg the median |a| over acc_x, acc_y, acc_z is 0.00980 g; a board at rest \
         reads |a| = 1 g (0.67..1.50 g): pass --accel-unit m/s2 (median |a| 0.999 g)",
    );
    refused(&g, &out, &["--accel-unit", "m/s2"], "read with --accel-unit m/s2 the median |a| over acc_x, acc_y, acc_z is 0.102 g; a board at rest reads |a| = 1 g (0.67..1.50 g): pass --accel-unit g (median |a| 0.999 g)");
    refused(&mps2, &out, &["--accel-unit", "g"], "pass --accel-unit m/s2 (median |a| 0.999 g)");
    for (log, unit) in [(&mps2, "m/s2"), (&g, "g")] {
        let (ok, text) = calibrate(log, &d.join(format!("ok-{}", unit.replace('/', ""))), &["--accel-unit", unit]);
        assert!(ok, "{unit}: {text}");
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// A Fahrenheit log whose readings pass 130 (a chamber run to 60 °C is 140 °F) is refused
/// as a unit, naming F, and read with `--temp-unit F`; a column named `temp_f` is read in
/// °F without the flag and contradicts `--temp-unit C`; kelvin read as °C names K.
#[test]
fn fahrenheit_and_kelvin_logs_are_refused_as_units_or_read_with_temp_unit() {
    let d = dir("temp");
    let f = d.join("f.csv");
    board(&f, "g", "imu.temperature", |t| 32.0 + 1.8 * t);
    let out = d.join("cal");
    refused(
        &f,
        &out,
        &["--accel-unit", "g"],
        "wrong unit? read in C (assumed: no unit given) the temperature spans 14.0..140.1 °C (",
    );
    refused(
        &f,
        &out,
        &["--accel-unit", "g"],
        "a board in a climate chamber reads -60..130 °C: pass --temp-unit F (-10.0..60.0 °C)",
    );
    let (ok, text) = calibrate(&f, &d.join("ok-f"), &["--accel-unit", "g", "--temp-unit", "F"]);
    assert!(ok, "{text}");
    // The log's own span, in report.md (the console's verdict gives the span the firmware's
    // estimator sees, which a turning point stretches by a few hundredths).
    let span = |out: &str| std::fs::read_to_string(d.join(out).join("report.md")).unwrap();
    assert!(span("ok-f").contains("-10.0..60.0 °C"), "{}", span("ok-f"));

    let named = d.join("named.csv");
    board(&named, "g", "temp_f", |t| 32.0 + 1.8 * t);
    let (ok, text) = calibrate(&named, &d.join("ok-named"), &["--accel-unit", "g"]);
    assert!(ok && span("ok-named").contains("-10.0..60.0 °C"), "{text}");
    refused(
        &named,
        &out,
        &["--accel-unit", "g", "--temp-unit", "C"],
        "wrong unit? read with --temp-unit C the column `temp_f` is named for F; a unit in a column's name and the one \
         passed must agree: pass --temp-unit F (the column name's unit)",
    );

    let k = d.join("k.csv");
    board(&k, "g", "imu.temperature", |t| t + 273.15);
    refused(&k, &out, &["--accel-unit", "g"], "pass --temp-unit K (-10.0..60.");
    refused(&f, &out, &["--accel-unit", "g", "--temp-unit", "K"], "pass --temp-unit F (-10.0..60.0 °C)");
    let _ = std::fs::remove_dir_all(&d);
}
