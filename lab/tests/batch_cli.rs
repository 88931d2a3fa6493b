//! Production batches as an engineer runs them from the command line, with the mistakes
//! they make: a manifest's slips (one log named for two serials, a unit logged in another
//! unit, a flag the manifest overrides), a logger that repeats itself, a batch run again
//! into an earlier one's folder, and the command's own refusals.

mod common;

use std::path::PathBuf;

/// Three good static units of seed 7 simulated into `dir/sim` (`batch.toml`, `units/`).
fn simulated(dir: &std::path::Path) -> PathBuf {
    let sim = dir.join("sim");
    let (ok, text) =
        common::lab(&["simulate-batch", "--units", "3", "--no-bad", "--seed", "7", "--out", sim.to_str().unwrap()]);
    assert!(ok, "{text}");
    sim
}

fn scratch(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A unit whose logger wrote every row twice: the reader keeps one of each and the unit is
/// judged on those (it passes, as the others do); the batch's console
/// and the unit's certificate say what the log's checks found, where before only the
/// unit's own `report.md` did. The units logged well get no such line.
#[test]
fn rows_written_twice_are_said_on_the_console_and_the_certificate() {
    let dir = scratch("batch-rows-twice");
    let sim = simulated(&dir);
    let written = common::rewrite_rows(&sim.join("units").join("SN0002.tsv"), |l| format!("{l}\n{l}\n"));
    let out = dir.join("out");
    let (ok, console) =
        common::lab(&["batch", "--manifest", sim.join("batch.toml").to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(ok, "{console}");
    assert!(console.contains("verdict: 3 units: 3 PASS"), "{console}");
    let said = format!("log: SN0002: [warning] rows: {written} row(s) skipped ({written} duplicate timestamp row(s)");
    assert!(console.contains(&said), "{console}");
    assert_eq!(console.matches("log: ").count(), 1, "{console}");
    let page = std::fs::read_to_string(out.join("SN0002").join("certificate.html")).unwrap();
    assert!(page.contains(&format!("{written} duplicate timestamp row(s) skipped")), "{page}");
    let other = std::fs::read_to_string(out.join("SN0001").join("certificate.html")).unwrap();
    assert!(!other.contains("checks warn"), "{other}");
}

/// A manifest that names one unit's log for a second serial (a copy-and-paste slip): both
/// units FAIL, each naming the other, where before both PASSed and the second serial's
/// certificate named the first's table to flash. A unit with its own log passes.
#[test]
fn one_log_named_for_two_serials_fails_both_naming_each_other() {
    let dir = scratch("batch-one-log-twice");
    let sim = simulated(&dir);
    let manifest = sim.join("batch.toml");
    let m = std::fs::read_to_string(&manifest).unwrap();
    assert_eq!(m.matches("units/SN0003.tsv").count(), 1, "{m}");
    std::fs::write(&manifest, m.replace("units/SN0003.tsv", "units/SN0002.tsv")).unwrap();
    let out = dir.join("out");
    let (ok, console) =
        common::lab(&["batch", "--manifest", manifest.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(!ok, "{console}");
    assert!(
        console.contains("verdict: 3 units: 1 PASS, 0 REVIEW (limits met, outside the population), 2 FAIL"),
        "{console}"
    );
    for (unit, other) in [("SN0002", "SN0003"), ("SN0003", "SN0002")] {
        assert!(console.contains(&format!("fail: {unit}: its table.bin is {other}'s, byte for byte")), "{console}");
        let page = std::fs::read_to_string(out.join(unit).join("certificate.html")).unwrap();
        assert!(page.contains("none: the unit FAILs"), "{unit}: {page}");
    }
    // One unit's readings, counted twice, would weigh double in every yardstick and in the
    // capability table: neither copy counts.
    let fleet: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("fleet.json")).unwrap()).unwrap();
    assert_eq!(fleet["reference_units"], 1, "{fleet}");
    for c in fleet["capability"].as_array().unwrap() {
        assert_eq!(c["n"], 1, "{c}");
    }
}

/// A manifest's unit logged in mg while the manifest says g: its failure names the key to
/// set, in the manifest's words; the flag a user then tries, `--accel-unit mg`, which the
/// manifest's own `accel_unit = "g"` overrides, is refused rather than dropped (before, the
/// batch ran again and failed with the same message); the key on the unit's `[[unit]]`
/// calibrates it.
#[test]
fn a_unit_in_another_unit_is_told_the_manifest_key_and_a_flag_the_manifest_overrides_is_refused() {
    let dir = scratch("batch-manifest-units");
    let sim = simulated(&dir);
    common::rewrite_rows(&sim.join("units").join("SN0002.tsv"), |l| {
        let f: Vec<&str> = l.split('\t').collect();
        let a = |k: usize| format!("{}", f[k].parse::<f64>().unwrap() * 1000.0);
        format!("{}\t{}\t{}\t{}\t{}\n", f[0], f[1], a(2), a(3), a(4))
    });
    let manifest = sim.join("batch.toml");
    let run = |out: &str, extra: &[&str]| {
        let out = dir.join(out);
        let mut args = vec!["batch", "--manifest", manifest.to_str().unwrap(), "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        common::lab(&args)
    };
    let (ok, console) = run("a", &[]);
    assert!(!ok, "{console}");
    assert!(
        console.contains("fail: SN0002: not calibrated: wrong unit? read with accel_unit = \"g\"")
            && console.contains("pass accel_unit = \"mg\""),
        "{console}"
    );
    let (ok, console) = run("b", &["--accel-unit", "mg"]);
    assert!(!ok, "{console}");
    assert!(
        console.contains("--accel-unit mg on the command line, and `accel_unit = \"g\"` here for every unit")
            && console.contains("the flag would change nothing"),
        "{console}"
    );
    let m = std::fs::read_to_string(&manifest).unwrap();
    let m = m.replace("log = \"units/SN0002.tsv\"", "log = \"units/SN0002.tsv\"\naccel_unit = \"mg\"");
    std::fs::write(&manifest, m).unwrap();
    let (ok, console) = run("c", &[]);
    assert!(ok && console.contains("verdict: 3 units: 3 PASS"), "{console}");
}

/// A batch run again into the folder of an earlier one, with one unit's log now refused:
/// that unit's folder keeps no table from the earlier batch. Before, its `table.bin`,
/// `table.toml` and ArduPilot files stayed beside a certificate that says FAIL, ready to be
/// flashed by a script that takes `SERIAL/table.bin`.
#[test]
fn a_unit_that_fails_keeps_no_table_an_earlier_batch_wrote() {
    let dir = scratch("batch-rerun");
    let sim = simulated(&dir);
    let out = dir.join("out");
    let run = || {
        common::lab(&[
            "batch",
            "--manifest",
            sim.join("batch.toml").to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--plots",
        ])
    };
    let (ok, console) = run();
    assert!(ok, "{console}");
    assert!(out.join("SN0002").join("table.bin").is_file());
    common::assert_unit_files_are_listed(&out);
    std::fs::write(sim.join("units").join("SN0002.tsv"), "time\ttemp\tax\tay\taz\n").unwrap();
    let (ok, console) = run();
    assert!(!ok && console.contains("fail: SN0002: not calibrated"), "{console}");
    let left: Vec<String> = std::fs::read_dir(out.join("SN0002"))
        .unwrap()
        .filter_map(Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    for gone in ["table.bin", "table.toml", "report.json", "bias_vs_temp.png", "ardupilot_tcal_2_values.parm"] {
        assert!(!left.iter().any(|f| f == gone), "SN0002 keeps {gone}: {left:?}");
    }
    assert!(left.iter().any(|f| f == "certificate.json"), "{left:?}");
    assert!(out.join("SN0001").join("table.bin").is_file());
}

/// The command as a production engineer types it: a manifest with a misspelt key is
/// refused naming the key; without --log or --manifest the command says what it needs;
/// `batch merge` on a folder no shard wrote says what to run first.
#[test]
fn the_command_refuses_a_users_mistakes_with_what_to_do() {
    let dir = scratch("batch-cli");
    std::fs::write(dir.join("a.tsv"), "time\ttemp\tax\n").unwrap();
    std::fs::write(dir.join("batch.toml"), "[[unit]]\nserial = \"A\"\nlog = \"a.tsv\"\ntime_units = \"s\"\n").unwrap();
    let out = dir.join("out");
    let (ok, text) =
        common::lab(&["batch", "--manifest", dir.join("batch.toml").to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(!ok && text.contains("time_units"), "{text}");
    let (ok, text) = common::lab(&["batch", "--out", out.to_str().unwrap()]);
    assert!(!ok && text.contains("--log CHAMBER_LOG or --manifest"), "{text}");
    let (ok, text) = common::lab(&["batch", "merge", dir.to_str().unwrap()]);
    assert!(!ok && text.contains("--shard K/N"), "{text}");
    // A flag every unit needs, forgotten: one line for all of them, and a failing status.
    let sim = dir.join("sim");
    let (ok, text) = common::lab(&["simulate-batch", "--units", "3", "--no-bad", "--out", sim.to_str().unwrap()]);
    assert!(ok, "{text}");
    let chamber = sim.join("chamber.tsv");
    let (ok, text) =
        common::lab(&["batch", "--log", chamber.to_str().unwrap(), "--out", dir.join("f").to_str().unwrap()]);
    assert!(!ok, "{text}");
    assert!(
        text.contains("fail: 3 units (SN0001, SN0002, SN0003): not calibrated: the unit of column `time` is not known"),
        "{text}"
    );
    // With no unit calibrated the fleet page draws nothing and says so.
    let page = std::fs::read_to_string(dir.join("f").join("fleet.html")).unwrap();
    assert!(page.contains("No unit was calibrated") && !dir.join("f").join("fleet_figures.png").exists());
}
