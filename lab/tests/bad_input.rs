//! The bad-input matrix: each class of bad input fed to `calibrate` and `compensate` (and,
//! for static logs, `discover`, which shares the static reader) through the CLI, as a user
//! runs them, asserting the exact message. `discover` reads cycling logs through the same
//! reader, so it gets the same messages.
//!
//! | input | static log (`--columns`/unit flags) | cycling log |
//! |---|---|---|
//! | unknown column | error `unknown column ...` | error `header is ...` |
//! | wrong unit | error `wrong unit? read with --accel-unit g the median |a| ...: pass --accel-unit m/s2` / `--time-unit ...: expected s|ms|us|ns` (both sides: `tests/units.rs`) | – |
//! | non-monotonic time | error `line N: time goes backwards` | error `line N: time_s not after ...` |
//! | a single run / no ±1 g pair | – | calibrate: error `no +1 g / −1 g pair`; compensate: each run compensated |
//! | empty file | error `empty log: no header line` | error `line 1: header is ``` |
//! | NaN fields | rows skipped, counted with line numbers on stderr and in report.json | error `bad temp_c `NaN`` |
//! | time unit 1000× too fine (µs read as ns, ms as µs) | error `wrong unit? read with --time-unit ... °C/min ...: pass --time-unit ms (...)` with the implied slew and the unit that fits | – |
//! | decimal commas (`20,5` with `;`) | error `... a decimal comma? ... pass --decimal-comma`; read with `--decimal-comma` | – |
//! | CRLF line ends, blank lines | line numbers as an editor shows them | same |
//! | `--out` unusable (a file where a directory goes, a directory where a file goes, a missing directory) | error naming `--out`, before the log is read | same |
//! | a table of the other kind (samples vs pulse counts) | compensate: error naming both kinds | same |
//! | temperature span under the grid's need (25.0 → 25.3 °C) | calibrate, discover: error `the temperature span is too small: ...` (found and needed) | – |
//! | a part of the span with too few rows (a jump) | calibrate, discover: error `too few rows per degree: ...` (where, found and needed) | – |
//! | heating only, no later leg | calibrate, discover: held out by blocks (`--holdout after-max` asked for: error `held-out split: ...`) | – |
//! | `--holdout` not a scheme | error `--holdout `...`: expected auto, after-max, blocks:K (K ≥ 2) or none` | error `--holdout ...: static logs only` |
//! | `--holdout none` | calibrate: table written, every held-out figure `not_computed` with the reason | – |

use std::path::{Path, PathBuf};
use std::process::Command;

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("qfa-bad-input-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Run qfa-lab; (success, stdout + stderr).
fn lab(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_qfa-lab")).args(args).output().expect("run qfa-lab");
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    (out.status.success(), text)
}

fn fails_with(args: &[&str], want: &str) {
    let (ok, text) = lab(args);
    assert!(!ok, "{args:?} succeeded:\n{text}");
    assert!(text.contains(want), "{args:?}: expected `{want}` in\n{text}");
}

/// A static 3-axis log, 1-s rows in ms, m/s²: 20 → −10 → 60 → 30 °C at 3 °C/min, bias
/// quadratic in T. `edit` may change rows (index, text).
fn static_log(path: &Path, edit: impl Fn(usize, String) -> String) {
    static_log_of(path, &ramps(20.0, &[(-10.0, -0.05), (60.0, 0.05), (30.0, -0.05)]), edit);
}

/// Temperatures from `t0` through each `(target, step per row)`.
fn ramps(t0: f64, legs: &[(f64, f64)]) -> Vec<f64> {
    let mut temps = Vec::new();
    let mut t = t0;
    for &(target, step) in legs {
        while (step < 0.0 && t > target) || (step > 0.0 && t < target) {
            temps.push(t);
            t += step;
        }
    }
    temps
}

/// [`static_log`] with these temperatures, one per row.
fn static_log_of(path: &Path, temps: &[f64], edit: impl Fn(usize, String) -> String) {
    let mut s = String::from("time_ms\timu.temperature\tacc_x\tacc_y\tacc_z\n");
    for (i, &tc) in temps.iter().enumerate() {
        let b = 1e-3 * (tc - 20.0) / 40.0 + 2e-6 * (tc - 20.0).powi(2);
        let g = 9.806_65;
        let row = format!("{}\t{tc:.4}\t{:.6}\t{:.6}\t{:.6}", i * 1000, b * g, (0.01 - b) * g, (-1.0 + b) * g);
        s.push_str(&edit(i, row));
        s.push('\n');
    }
    std::fs::write(path, s).unwrap();
}

const FLAGS: [&str; 4] = ["--time-unit", "ms", "--accel-unit", "m/s2"];

fn static_args<'a>(cmd: &'a str, log: &'a str, out: &'a str, table: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut v = vec![cmd, "--log", log, "--out", out];
    if cmd == "compensate" {
        v.extend(["--table", table]);
    }
    v.extend(extra);
    v
}

#[test]
fn static_log_bad_inputs_get_their_exact_errors() {
    let d = dir();
    let good = d.join("good.tsv");
    static_log(&good, |_, r| r);
    let cal = d.join("cal");
    let (ok, text) = lab(&static_args("calibrate", good.to_str().unwrap(), cal.to_str().unwrap(), "", &FLAGS));
    assert!(ok, "{text}");
    let table = cal.join("table.bin");
    let table_s = table.to_str().unwrap();
    let out = d.join("comp.csv");
    let out_s = out.to_str().unwrap();
    let (ok, text) = lab(&static_args("compensate", good.to_str().unwrap(), out_s, table_s, &FLAGS));
    assert!(ok, "{text}");

    let backwards = d.join("backwards.tsv");
    // Row 100 (line 102) at 98.5 s, after 99 s.
    static_log(&backwards, |i, r| if i == 100 { r.replacen("100000\t", "98500\t", 1) } else { r });
    let nan_fields = d.join("nan_fields.tsv");
    // Two rows with a NaN temperature field (lines 52 and 72: header is line 1).
    static_log(&nan_fields, |i, r| {
        if i == 50 || i == 70 {
            let mut f: Vec<String> = r.split('\t').map(str::to_string).collect();
            f[1] = "NaN".into();
            f.join("\t")
        } else {
            r
        }
    });
    let empty = d.join("empty.tsv");
    std::fs::write(&empty, "").unwrap();
    // The backwards row again, with CRLF line ends, and with a blank line before it (line 103).
    let backwards_crlf = d.join("backwards_crlf.tsv");
    std::fs::write(&backwards_crlf, std::fs::read_to_string(&backwards).unwrap().replace('\n', "\r\n")).unwrap();
    let backwards_blank = d.join("backwards_blank.tsv");
    static_log(&backwards_blank, |i, r| match i {
        50 => format!("\n{r}"),
        100 => r.replacen("100000\t", "98500\t", 1),
        _ => r,
    });
    // Decimal commas with `;` (a spreadsheet export in many locales).
    let comma = d.join("comma.csv");
    let good_text = std::fs::read_to_string(&good).unwrap();
    let (head, rows) = good_text.split_once('\n').unwrap();
    std::fs::write(&comma, format!("{}\n{}", head.replace('\t', ";"), rows.replace('.', ",").replace('\t', ";")))
        .unwrap();
    let comma_rows = std::fs::read_to_string(&good).unwrap().lines().count() - 1;
    let good_commas = d.join("good_commas.csv");
    std::fs::write(&good_commas, std::fs::read_to_string(&good).unwrap().replace('\t', ",")).unwrap();
    // 20 °C for 50 rows, +0.05 °C per 1-s row to 30 °C, 30 °C for 50 rows, ms timestamps.
    // Read as µs the 300 rows span 0.299 s: 10 °C in 0.299 s is 2007 °C/min. Read as ms
    // (right) the fastest 60 s holds 3.0 °C: 3.0 °C/min.
    let slew = d.join("slew.tsv");
    // No unit in the time column's name: a name's unit that contradicts the flag is refused
    // before any figure is looked at.
    let mut text = String::from("timestamp\timu.temperature\tacc_x\tacc_y\tacc_z\n");
    for i in 0..300i32 {
        let tc = 20.0 + 0.05 * f64::from((i - 50).clamp(0, 200));
        text.push_str(&format!("{}\t{tc:.4}\t0.05\t-0.1\t-9.8\n", i * 1000));
    }
    std::fs::write(&slew, text).unwrap();
    let a_file = d.join("a_file");
    std::fs::write(&a_file, "").unwrap();
    let missing_log = d.join("no-such-log.tsv");

    for cmd in ["calibrate", "compensate", "discover"] {
        let g = good.to_str().unwrap();
        let o = if cmd == "compensate" { out.clone() } else { d.join(format!("out-{cmd}")) };
        let o = o.to_str().unwrap().to_string();
        // Unknown column.
        let mut f = FLAGS.to_vec();
        f.extend(["--columns", "temp=board.temp"]);
        fails_with(
            &static_args(cmd, g, &o, table_s, &f),
            "unknown column `board.temp` for temp; the header has: time_ms, imu.temperature, acc_x, acc_y, acc_z",
        );
        // Wrong unit: m/s² data read as g; an unknown unit name.
        fails_with(
            &static_args(cmd, g, &o, table_s, &["--time-unit", "ms", "--accel-unit", "g"]),
            "wrong unit? read with --accel-unit g the median |a| over acc_x, acc_y, acc_z is 9.",
        );
        fails_with(&static_args(cmd, g, &o, table_s, &["--time-unit", "h"]), "--time-unit `h`: expected s|ms|us|ns");
        // Non-monotonic time.
        fails_with(
            &static_args(cmd, backwards.to_str().unwrap(), &o, table_s, &FLAGS),
            "1 malformed row(s)\n  line 102: time goes backwards (98500 after 99000)",
        );
        // CRLF line ends and a blank line: line numbers as an editor shows them.
        fails_with(
            &static_args(cmd, backwards_crlf.to_str().unwrap(), &o, table_s, &FLAGS),
            "1 malformed row(s)\n  line 102: time goes backwards (98500 after 99000)",
        );
        fails_with(
            &static_args(cmd, backwards_blank.to_str().unwrap(), &o, table_s, &FLAGS),
            "1 malformed row(s)\n  line 103: time goes backwards (98500 after 99000)",
        );
        // Empty file.
        fails_with(&static_args(cmd, empty.to_str().unwrap(), &o, table_s, &FLAGS), "empty log: no header line");
        // A time unit 1000x too fine: the implied temperature slew, and the unit that fits.
        fails_with(
            &static_args(cmd, slew.to_str().unwrap(), &o, table_s, &["--time-unit", "us", "--accel-unit", "m/s2"]),
            "wrong unit? read with --time-unit us the temperature changes by 2007 °C/min (10.00 °C within 0.299 s: \
             from 20.00 °C at line 52 to 30.00 °C at line 252); a board in a climate chamber changes by at most 30 \
             °C/min: pass --time-unit ms (rows 1.00 s apart, 3.0 °C/min)",
        );
        // Decimal commas: recognised, with the flag that reads them.
        fails_with(
            &static_args(cmd, comma.to_str().unwrap(), &o, table_s, &FLAGS),
            &format!(
                "column `imu.temperature` holds `20,0000` at line 2: a decimal comma? {comma_rows} row(s) have \
                 numbers like it; pass --decimal-comma to read them"
            ),
        );
        let mut f = FLAGS.to_vec();
        f.push("--decimal-comma");
        let (ok, text) = lab(&static_args(cmd, comma.to_str().unwrap(), &o, table_s, &f));
        assert!(ok, "{cmd} --decimal-comma: {text}");
        let mut f = FLAGS.to_vec();
        f.push("--decimal-comma");
        fails_with(
            &static_args(cmd, good_commas.to_str().unwrap(), &o, table_s, &f),
            "--decimal-comma needs a `;` or tab delimiter: this header is comma-separated, so a decimal comma cannot \
             be told from a field separator",
        );
        // An unusable --out is refused before the log is read (the log here does not exist).
        let (out_arg, want) = if cmd == "compensate" {
            (
                d.to_str().unwrap().to_string(),
                format!("--out {}: a directory; compensate writes one CSV file", d.display()),
            )
        } else {
            (
                a_file.to_str().unwrap().to_string(),
                format!(
                    "--out {}: a file of that name exists; {cmd} writes a directory of files there",
                    a_file.display()
                ),
            )
        };
        fails_with(&static_args(cmd, missing_log.to_str().unwrap(), &out_arg, table_s, &FLAGS), &want);
        let nested = d.join("no-such-dir").join("x.csv");
        if cmd == "compensate" {
            fails_with(
                &static_args(cmd, missing_log.to_str().unwrap(), nested.to_str().unwrap(), table_s, &FLAGS),
                &format!(
                    "--out {}: the directory {} does not exist",
                    nested.display(),
                    d.join("no-such-dir").display()
                ),
            );
        } else {
            let under_file = a_file.join("cal");
            fails_with(
                &static_args(cmd, missing_log.to_str().unwrap(), under_file.to_str().unwrap(), table_s, &FLAGS),
                &format!(
                    "--out {}: {} is a file, so the directory cannot be created",
                    under_file.display(),
                    a_file.display()
                ),
            );
        }
        // NaN fields: skipped and reported, with their lines.
        let (ok, text) = lab(&static_args(cmd, nan_fields.to_str().unwrap(), &o, table_s, &FLAGS));
        assert!(ok, "{text}");
        assert!(text.contains("2 NaN/empty field row(s) skipped (line 52, 72)"), "{text}");
    }
    // Static discovery writes one flashable table for all axes; the per-axis directories
    // hold the named model for reading, not a table `compensate` would refuse (1 axis vs 3).
    let disc = d.join("out-discover");
    assert!(disc.join("table.bin").is_file());
    for axis in ["ax", "ay", "az"] {
        assert!(!disc.join(axis).join("table.bin").exists() && !disc.join(axis).join("model.bin").exists(), "{axis}");
        let md = std::fs::read_to_string(disc.join(axis).join("report.md")).unwrap();
        assert!(md.contains("not a table to flash; the flashable table of all axes is `../table.bin`"), "{md}");
        assert!(!md.contains("compensate --table DIR/table.bin"), "{md}");
    }
    // Logs refused for a cause in the log itself, each with its exact message, and logs
    // with no later leg, which calibrate (held out by blocks).
    let small = d.join("small_span.tsv");
    static_log_of(&small, &(0..300).map(|i| 25.0 + 0.001 * f64::from(i)).collect::<Vec<_>>(), |_, r| r);
    let mut jump = ramps(20.0, &[(30.0, 0.05)]);
    jump.extend(ramps(50.0, &[(60.0, 0.05)]));
    let gap = d.join("jump.tsv");
    static_log_of(&gap, &jump, |_, r| r);
    let heating = d.join("heating.tsv");
    static_log_of(&heating, &ramps(-10.0, &[(60.0, 0.05)]), |_, r| r);
    let cooling = d.join("cooling.tsv");
    static_log_of(&cooling, &ramps(60.0, &[(-10.0, -0.05)]), |_, r| r);
    for cmd in ["calibrate", "discover"] {
        let o = d.join(format!("out-{cmd}"));
        let o = o.to_str().unwrap();
        fails_with(
            &static_args(cmd, small.to_str().unwrap(), o, "", &FLAGS),
            "the temperature span is too small: 0.30 °C (25.00..25.30 °C); the model needs at least 1.50 °C (16 \
             bias-grid nodes at least 0.1 °C apart, the root crate's smallest grid step)",
        );
        fails_with(
            &static_args(cmd, gap.to_str().unwrap(), o, "", &FLAGS),
            "too few rows per degree: 0 row(s) between 30.67 and 33.33 °C (0.00 per °C); the model needs 10 there \
             (3.75 per °C): one 10-row averaged equation in each of the 15 bias-grid intervals over 20.00..60.00 °C",
        );
        let mut f = FLAGS.to_vec();
        f.extend(["--holdout", "after-max"]);
        fails_with(
            &static_args(cmd, heating.to_str().unwrap(), o, "", &f),
            "held-out split: the highest temperature (60.00 °C) is at row 1401 of 1401: fewer than a tenth of the \
             rows lie after it, no later leg to evaluate on",
        );
        let mut f = FLAGS.to_vec();
        f.extend(["--holdout", "blocks:1"]);
        fails_with(
            &static_args(cmd, good.to_str().unwrap(), o, "", &f),
            "--holdout `blocks:1`: expected auto, after-max, blocks:K (K ≥ 2) or none",
        );
    }
    for log in [&heating, &cooling] {
        let o = d.join("one-leg");
        let (ok, text) = lab(&static_args("calibrate", log.to_str().unwrap(), o.to_str().unwrap(), "", &FLAGS));
        assert!(ok, "{text}");
        let want = "scheme `blocks:5` (asked `auto`), auto: the highest temperature";
        assert!(text.contains(&format!("held-out: {want}")), "the console's verdict: {text}");
        let md = std::fs::read_to_string(Path::new(&o).join("report.md")).unwrap();
        assert!(md.contains(&format!("**held-out:** {want}")), "report.md's verdict: {md}");
    }
    let none = d.join("none");
    let mut f = FLAGS.to_vec();
    f.extend(["--holdout", "none"]);
    let (ok, text) = lab(&static_args("calibrate", good.to_str().unwrap(), none.to_str().unwrap(), "", &f));
    assert!(ok, "without --limits a failed verdict does not fail the command: {text}");
    assert!(text.contains("verdict: FAIL against the default limits"), "no held-out figure, no pass: {text}");
    assert!(text.contains("held_out_bias_mg ax: not computed"), "{text}");
    let md = std::fs::read_to_string(none.join("report.md")).unwrap();
    assert!(md.contains("Held-out bias RMS: not computed (--holdout none: no row is held out)."), "{md}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(none.join("report.json")).unwrap()).unwrap();
    for a in r["axes"].as_array().unwrap() {
        for k in ["ours", "cubic", "ardupilot", "simple", "none"] {
            assert_eq!(a[k], serde_json::json!({"not_computed": "--holdout none: no row is held out"}), "{k}");
        }
        assert!(a["table_rms_mg"].as_f64().unwrap() > 0.0, "{a}");
    }
    assert!(none.join("table.bin").is_file());

    // The compensated output leaves the NaN rows out and says so in the count of rows
    // (after its `# ` lines: the rows per status flag).
    let rows = std::fs::read_to_string(&out).unwrap().lines().filter(|l| !l.starts_with('#')).count();
    let good_rows = std::fs::read_to_string(&good).unwrap().lines().count();
    assert_eq!(rows, good_rows - 2);
    let _ = std::fs::remove_dir_all(&d);
}

const CYCLING_HEADER: &str = "program,run,time_s,input_g,temp_c,pulses,interval_s\n";

/// An axis that reads one value on every row (a stuck output, or a column the logger filled
/// with a constant) is refused, by `calibrate`, `discover` and `lint` alike, naming the axis,
/// its column and the value. Before, such a unit got a flat table whose held-out residual
/// was zero, and its verdict, and a batch's, was PASS. The column is overwritten here as
/// text, with no code of the lab's.
#[test]
fn a_stuck_axis_is_refused_not_passed() {
    let d = dir();
    let stuck = d.join("stuck.tsv");
    static_log(&stuck, |_, r| {
        let mut f: Vec<String> = r.split('\t').map(str::to_string).collect();
        f[4] = "-9.806650".into();
        f.join("\t")
    });
    let log = stuck.to_str().unwrap();
    for cmd in ["calibrate", "discover"] {
        let out = d.join(format!("stuck-{cmd}"));
        fails_with(
            &static_args(cmd, log, out.to_str().unwrap(), "", &FLAGS),
            "az (column `acc_z`) reads -1 g on every one of its",
        );
    }
    let mut args = vec!["lint", "--log", log];
    args.extend(FLAGS);
    let (_, text) = lab(&args);
    assert!(text.contains("[error] outputs: az (column `acc_z`) reads -1 g"), "{text}");
}

/// A cycling log with a stuck counter in one run, a stuck temperature sensor, one
/// program's ±1 g positions labelled the other way round, or its counting intervals in ms,
/// is refused naming it, before any fit, by `calibrate`, `discover` and `lint` alike (the
/// swap was "table rejected: scale.gamma out of range", the ms "table K1 320 per g is not
/// within a factor of 2 of the nominal 320000"). Before, in a
/// batch the counter failed as "cross-validation: non-finite fold MSE NaN" and the sensor
/// as "table rejected: bias.t_step_c out of range"; `calibrate` alone exited 0 on the
/// counter, and `discover` wrote a `table.bin` for it. The columns are overwritten as
/// text, with no code of the lab's. A log of its header alone is refused as having no row
/// to fit.
#[test]
fn a_stuck_counter_or_sensor_on_a_cycling_log_is_named() {
    let d = dir().join("stuck-cycling");
    std::fs::create_dir_all(&d).unwrap();
    let log = d.join("log.csv");
    let (ok, text) =
        lab(&["simulate", "--out", log.to_str().unwrap(), "--unit", "kt8-1", "--rates", "0.3,0.9", "--row-s", "10"]);
    assert!(ok, "{text}");
    let text = std::fs::read_to_string(&log).unwrap();
    let header = text.lines().next().unwrap();
    assert_eq!(header, CYCLING_HEADER.trim_end(), "the simulator's columns");
    let edit = |name: &str, f: &dyn Fn(&mut Vec<String>)| {
        let mut out = String::from(CYCLING_HEADER);
        for line in text.lines().skip(1) {
            let mut fields: Vec<String> = line.split(',').map(str::to_string).collect();
            f(&mut fields);
            out.push_str(&fields.join(","));
            out.push('\n');
        }
        let p = d.join(name);
        std::fs::write(&p, out).unwrap();
        p
    };
    // Columns: program, run, time_s, input_g, temp_c, pulses, interval_s.
    let counter = edit("counter.csv", &|f| {
        if f[0] == "paper-0.3" && f[1] == "2" {
            f[5] = "-3203000".into();
        }
    });
    let sensor = edit("sensor.csv", &|f| f[4] = "22.0625".into());
    // The +1 g and −1 g positions of one program labelled the other way round.
    let swapped = edit("swapped.csv", &|f| {
        if f[0] == "paper-0.9" && (f[3] == "1" || f[3] == "-1") {
            f[3] = if f[3] == "1" { "-1".into() } else { "1".into() };
        }
    });
    // Counting intervals written in ms.
    let ms = edit("ms.csv", &|f| f[6] = format!("{}", f[6].parse::<f64>().unwrap() * 1000.0));
    for (log, want) in [
        (&ms, "wrong unit? the counting intervals (`interval_s`) are 1000 times the rows' spacing"),
        (&counter, "run 2 of program paper-0.3 counts -3203000 pulses on every one of its"),
        (&sensor, "the temperature span is too small: 0.00 °C (22.06..22.06 °C)"),
        (&swapped, "program paper-0.9: its ±1 g pair gives a negative scale factor"),
    ] {
        let out = d.join("out");
        fails_with(&["calibrate", "--log", log.to_str().unwrap(), "--out", out.to_str().unwrap(), "--no-plots"], want);
        fails_with(&["discover", "--log", log.to_str().unwrap(), "--out", out.to_str().unwrap()], want);
        let (_, text) = lab(&["lint", "--log", log.to_str().unwrap()]);
        assert!(text.contains(&format!("[error] outputs: {want}")), "{text}");
    }
    // The header alone (a chamber log's unit blank on every row gives the same): said as
    // such, where the fit said "0 equations for 2 unknowns".
    let header = d.join("header.csv");
    std::fs::write(&header, CYCLING_HEADER).unwrap();
    let want = "no row to fit: the log holds no row (its header alone";
    let out = d.join("out");
    fails_with(&["calibrate", "--log", header.to_str().unwrap(), "--out", out.to_str().unwrap(), "--no-plots"], want);
    fails_with(&["discover", "--log", header.to_str().unwrap(), "--out", out.to_str().unwrap()], want);
    let (_, text) = lab(&["lint", "--log", header.to_str().unwrap()]);
    assert!(text.contains(&format!("[error] outputs: {want}")), "{text}");
}

fn cycling(rows: &[(&str, &str, f64)], n: usize) -> String {
    let mut s = CYCLING_HEADER.to_string();
    for &(prog, run, g) in rows {
        for i in 0..n {
            let t = 20.0 + 0.01 * i as f64;
            // The count moves row to row, as an I/F converter's does (a count that never
            // moves is refused as a stuck counter).
            let pulses = (g * 3_200_000.0) as i64 + 100 + (i % 7) as i64;
            s.push_str(&format!("{prog},{run},{},{g},{t:.4},{pulses},10\n", 10 * (i + 1)));
        }
    }
    s
}

#[test]
fn cycling_log_bad_inputs_get_their_exact_errors() {
    let d = dir().join("cycling");
    std::fs::create_dir_all(&d).unwrap();
    let w = |name: &str, text: &str| {
        let p = d.join(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_string()
    };
    let out = d.join("out").to_str().unwrap().to_string();
    // compensate writes a file, calibrate and discover a directory.
    let out_csv = d.join("out.csv").to_str().unwrap().to_string();
    let single = w("single.csv", &cycling(&[("rate0.3", "rate0.3_pos0", 1.0)], 50));
    let no_pair = w("nopair.csv", &cycling(&[("rate0.3", "pos1", 0.0), ("rate0.3", "pos3", 0.0)], 50));
    let bad_header = w("header.csv", "program,run,time,input_g,temp_c,pulses,interval_s\np,0,1,1,,1,1\n");
    let backwards = w("backwards.csv", &format!("{CYCLING_HEADER}p,a,10,1,20,1,10\np,a,5,1,20,1,10\n"));
    let nan = w("nan.csv", &format!("{CYCLING_HEADER}p,a,10,1,NaN,1,10\n"));
    let empty = w("empty.csv", "");
    let backwards_crlf =
        w("backwards_crlf.csv", &format!("{CYCLING_HEADER}p,a,10,1,20,1,10\np,a,5,1,20,1,10\n").replace('\n', "\r\n"));
    // Named runs are runs: calibrate fails for the missing pair, not for the names.
    fails_with(&["calibrate", "--log", &single, "--out", &out], "program `rate0.3` has no +1 g / −1 g pair of runs");
    fails_with(&["calibrate", "--log", &no_pair, "--out", &out], "program `rate0.3` has no +1 g / −1 g pair of runs");
    for cmd in ["calibrate", "discover"] {
        fails_with(
            &[cmd, "--log", &single, "--out", &out, "--holdout", "blocks:3"],
            "--holdout blocks:3: static logs only (a cycling log is held out by program)",
        );
    }
    for cmd in ["calibrate", "compensate", "discover"] {
        let args = |log: &str| -> Vec<String> {
            let o = if cmd == "compensate" { &out_csv } else { &out };
            let mut v: Vec<String> = [cmd, "--log", log, "--out", o].iter().map(|s| s.to_string()).collect();
            if cmd == "compensate" {
                v.extend(["--table".to_string(), "missing.bin".to_string()]);
            }
            v
        };
        let run = |log: &str, want: &str| {
            let a = args(log);
            fails_with(&a.iter().map(String::as_str).collect::<Vec<_>>(), want);
        };
        run(&bad_header, "line 1: header is `program,run,time,input_g,temp_c,pulses,interval_s`");
        run(&backwards, "line 3: time_s not after the run's previous row");
        run(&backwards_crlf, "line 3: time_s not after the run's previous row");
        run(&nan, "line 2: bad temp_c `NaN`");
        run(&empty, "line 1: header is ``");
    }
}

#[test]
fn cycling_reader_reports_the_first_20_malformed_rows_and_the_count() {
    let mut text = CYCLING_HEADER.to_string();
    for i in 0..500 {
        text.push_str(&format!("p,rate0.3_pos0,{},1,oops,1,1\n", i + 1));
    }
    let err = qfa_log::cycling::read_log_from(text.as_bytes()).unwrap_err();
    assert_eq!(err.total, 500);
    assert_eq!(err.errors.len(), 20);
    assert_eq!(err.errors[19].line, 21);
    let s = err.to_string();
    assert!(s.starts_with("500 malformed row(s) in the log:\n  line 2: bad temp_c `oops`"), "{s}");
    assert!(s.ends_with("  ... and 480 more\n"), "{s}");
}

#[test]
fn ten_second_rows_give_real_figures_and_missing_bins_are_an_error() {
    let d = dir().join("ten");
    std::fs::create_dir_all(&d).unwrap();
    let log = d.join("log10.csv");
    let out = d.join("cal");
    let (ok, text) = lab(&["simulate", "--out", log.to_str().unwrap(), "--row-s", "10", "--seed", "3"]);
    assert!(ok, "{text}");
    let (ok, text) = lab(&[
        "calibrate",
        "--log",
        log.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
        "--axis",
        "z",
    ]);
    assert!(ok, "{text}");
    // The PX4 / ArduPilot exports of this run are checked in tests/exports.rs.
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    // Before the staleness fix every compensated row was flagged stale: sensitivity null and
    // bias residual 0.0. Now each is a number, and the models beat no compensation.
    for v in ["none", "simple", "hysteresis"] {
        assert!(r["sensitivity_ppm_per_c"][v].is_f64(), "{v}: {}", r["sensitivity_ppm_per_c"]);
        assert!(r["bias_residual_ug"][v].as_f64().unwrap() > 0.0, "{v}: {}", r["bias_residual_ug"]);
    }
    let b = &r["bias_residual_ug"];
    assert!(b["hysteresis"].as_f64().unwrap() < b["none"].as_f64().unwrap(), "{b}");
    // The peers' rows exist, are numbers, and are far from no compensation.
    for p in ["cubic", "ardupilot"] {
        let v = r["peers_bias_residual_ug"][p].as_f64().unwrap();
        assert!(v > 0.0 && v < 0.5 * b["none"].as_f64().unwrap(), "{p}: {}", r["peers_bias_residual_ug"]);
    }
    // An evaluation without bins is an error with its reason, never a figure.
    let e = qfa_calibrate::check_figures(&qfa_calibrate::report::Evaluation::default()).unwrap_err();
    assert!(matches!(e, qfa_calibrate::CalibrateError::NotComputable(_)), "{e:?}");
    assert!(
        e.to_string().starts_with("bias residual (no compensation) not computable: no held-out bin qualified"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn single_channel_logs_still_reach_discover() {
    // `time_s,temp_c,value` is discover's own single-channel format, not a static log.
    let d = dir().join("single");
    std::fs::create_dir_all(&d).unwrap();
    let log = d.join("single.csv");
    let mut s = String::from("time_s,temp_c,value\n");
    for i in 0..1500 {
        let t = 20.0 + 10.0 * (f64::from(i) / 200.0).sin();
        s.push_str(&format!("{},{t:.4},{:.9}\n", i * 10, 1e-4 * t));
    }
    std::fs::write(&log, s).unwrap();
    let (ok, text) = lab(&["discover", "--log", log.to_str().unwrap(), "--out", d.join("out").to_str().unwrap()]);
    assert!(ok, "{text}");
    assert!(d.join("out").join("report.json").is_file());
    let _ = std::fs::remove_dir_all(&d);
}

/// The single-channel format goes through the same opening as the others: one sniff of the
/// header, its own `csv` reader (editor line numbers on CRLF too), and a command that does
/// not take it says so instead of reading it as something else.
#[test]
fn single_channel_logs_get_their_exact_errors() {
    let d = dir().join("single_bad");
    std::fs::create_dir_all(&d).unwrap();
    let w = |name: &str, text: String| {
        let p = d.join(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_string()
    };
    let rows: String = (0..20).map(|i| format!("{},{}.5,{}\n", i * 10, 20 + i, i)).collect();
    let good = w("good.csv", format!("time_s,temp_c,value\n{rows}"));
    let bad = w("bad.csv", format!("time_s,temp_c,value\n{rows}x,20,1\n\n5,20,NaN\n").replace('\n', "\r\n"));
    let short = w("short.csv", "time_s,temp_c,value\n0,20,1\n".to_string());
    let out = d.join("out").to_str().unwrap().to_string();
    let out_csv = d.join("out.csv").to_str().unwrap().to_string();
    fails_with(
        &["calibrate", "--log", &good, "--out", &out],
        "calibrate takes a cycling or a static log, not a single-channel log (time_s,temp_c,value)",
    );
    fails_with(
        &["compensate", "--log", &good, "--table", "missing.bin", "--out", &out_csv],
        "compensate takes a cycling or a static log, not a single-channel log (time_s,temp_c,value)",
    );
    fails_with(
        &["discover", "--log", &bad, "--out", &out],
        "2 malformed row(s):\nline 22: time_s: invalid float literal\nline 24: value: not finite",
    );
    fails_with(&["discover", "--log", &short, "--out", &out], "too few rows: 1 with a reading, 8 needed");
    let _ = std::fs::remove_dir_all(&d);
}

/// A table records what it converts (format 2): a static log's table converts samples, a
/// cycling log's pulse counts. `compensate` refuses the other kind, naming both.
#[test]
fn compensate_refuses_a_table_of_the_other_kind() {
    let d = dir().join("kinds");
    std::fs::create_dir_all(&d).unwrap();
    let st = d.join("static.tsv");
    static_log(&st, |_, r| r);
    let (ok, text) = lab(&static_args("calibrate", st.to_str().unwrap(), d.join("st").to_str().unwrap(), "", &FLAGS));
    assert!(ok, "{text}");
    let cy = d.join("cycling.csv");
    let (ok, text) = lab(&["simulate", "--out", cy.to_str().unwrap(), "--row-s", "10", "--rates", "0.3,0.9"]);
    assert!(ok, "{text}");
    let (ok, text) =
        lab(&["calibrate", "--log", cy.to_str().unwrap(), "--out", d.join("cy").to_str().unwrap(), "--no-plots"]);
    assert!(ok, "{text}");
    let out = d.join("out.csv");
    let out_s = out.to_str().unwrap();
    let st_table = d.join("st").join("table.bin");
    let cy_table = d.join("cy").join("table.bin");
    fails_with(
        &["compensate", "--log", cy.to_str().unwrap(), "--table", st_table.to_str().unwrap(), "--out", out_s],
        "table refused: it converts samples (calibrated on a static multi-axis log), and this cycling log gives pulse \
         counts: compensate it with a table calibrated on a cycling log",
    );
    fails_with(
        &static_args("compensate", st.to_str().unwrap(), out_s, cy_table.to_str().unwrap(), &FLAGS),
        "table refused: it converts pulse counts (calibrated on a cycling log), and this static multi-axis log gives \
         samples: compensate it with a table calibrated on a static log",
    );
    // Each table on its own kind of log works (the refusals are about the kind).
    let (ok, text) =
        lab(&["compensate", "--log", cy.to_str().unwrap(), "--table", cy_table.to_str().unwrap(), "--out", out_s]);
    assert!(ok, "{text}");
    let (ok, text) = lab(&static_args("compensate", st.to_str().unwrap(), out_s, st_table.to_str().unwrap(), &FLAGS));
    assert!(ok, "{text}");
    let _ = std::fs::remove_dir_all(&d);
}
