//! The verdict a calibration report opens with, read back from every place a user meets
//! it: the console, `report.md`, `report.json`, and `report.html` as Chromium renders it.
//! They must be the same lines in the same order, the page must show the verdict first,
//! and a unit that fails a limit given with `--limits` exits with status 3 and names the
//! limit on the console and the page.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::browser;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("qfa-verdict-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn as_str(a: &[String]) -> Vec<&str> {
    a.iter().map(String::as_str).collect()
}

/// Run qfa-lab: (exit code, stdout, stderr).
fn run(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_qfa-lab")).args(args).output().expect("run qfa-lab");
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    (out.status.code().unwrap_or(-1), text(&out.stdout), text(&out.stderr))
}

/// The verdict's lines from each of the four places, `key: text` each.
struct Told {
    console: Vec<String>,
    markdown: Vec<String>,
    json: Vec<String>,
    page: Option<Vec<String>>,
}

fn told(stdout: &str, out: &Path) -> Told {
    let console = stdout.lines().take_while(|l| !l.starts_with("detail: ")).map(String::from).collect();
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let section = md.split("## Verdict\n\n").nth(1).expect("report.md has a verdict").split("\n\n").next().unwrap();
    let markdown =
        section.lines().map(|l| l.strip_prefix("- **").expect("a verdict item").replacen(":** ", ": ", 1)).collect();
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let json = v["verdict"]["lines"].as_array().expect("report.json has verdict.lines");
    let json = json.iter().map(|l| l.as_str().unwrap().to_string()).collect();
    Told { console, markdown, json, page: browser::assert_verdict_first(&out.join("report.html")) }
}

/// The same lines everywhere, and the verdict first on the console.
fn assert_one_story(t: &Told) {
    assert!(t.console.first().is_some_and(|l| l.starts_with("verdict: ")), "console: {:?}", t.console);
    assert_eq!(t.markdown, t.console, "report.md and the console tell different stories");
    assert_eq!(t.json, t.console, "report.json and the console tell different stories");
    if let Some(page) = &t.page {
        assert_eq!(page, &t.console, "report.html (as rendered) and the console tell different stories");
    }
}

fn figures(lines: &[String]) -> Vec<String> {
    lines.iter().filter(|l| l.starts_with("expect in use: ")).cloned().collect()
}

#[test]
fn the_real_logs_verdict_is_one_story_on_console_report_md_json_and_page() {
    let Some(log) = common::real_log() else { return };
    let d = tmp("real");
    let out = d.join("cal");
    let (code, stdout, stderr) = run(&[
        "calibrate",
        "--log",
        log.to_str().unwrap(),
        "--time-unit",
        "us",
        "--accel-unit",
        "m/s2",
        "--temp-unit",
        "C",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{stdout}{stderr}");
    let t = told(&stdout, &out);
    assert_one_story(&t);
    // The held-out figures: the same three numbers as report.json's own per-axis records.
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let from_axes: Vec<String> = v["axes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| format!("{} {:.2} mg", a["axis"].as_str().unwrap(), a["ours"]["rms_mg"].as_f64().unwrap()))
        .collect();
    assert_eq!(figures(&t.console), vec![format!("expect in use: held-out bias RMS: {}", from_axes.join(", "))]);
    println!("{}", t.console.join("\n"));
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_unit_failing_a_limit_exits_with_status_3_and_names_the_limit_everywhere() {
    let d = tmp("limits");
    let log = d.join("static.tsv");
    common::write_static_log(&log);
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let args = |out: &Path, limits: &Path| {
        let mut a = vec!["calibrate".to_string(), "--log".into(), s(&log), "--out".into(), s(out)];
        a.extend(["--limits".into(), s(limits)]);
        a.extend(common::STATIC_FLAGS.iter().map(|f| (*f).to_string()));
        a
    };

    // A limit no unit meets: every file is still written, the exit status is 3.
    let strict = d.join("strict.toml");
    std::fs::write(&strict, "held_out_bias_mg = 0.001\n").unwrap();
    let out = d.join("fails");
    let (code, stdout, stderr) = run(&as_str(&args(&out, &strict)));
    assert_eq!(code, 3, "a failed limit exits with 3:\n{stdout}{stderr}");
    assert!(stderr.contains("error: the unit fails 3 limit(s): held_out_bias_mg ax"), "{stderr}");
    let t = told(&stdout, &out);
    assert_one_story(&t);
    assert!(t.console[0].starts_with("verdict: FAIL against the limits in "), "{:?}", t.console);
    let failed: Vec<&String> = t.console.iter().filter(|l| l.starts_with("limit: ") && l.ends_with("(FAIL)")).collect();
    assert_eq!(failed.len(), 3, "one failed line per axis: {:?}", t.console);
    assert!(
        t.console.iter().any(|l| l.starts_with("file: table.bin: held back")),
        "a failed unit's table is not offered for flashing: {:?}",
        t.console
    );
    for f in ["table.bin", "table.toml", "report.json", "report.md", "report.html", "bias_vs_temp.png"] {
        assert!(out.join(f).is_file(), "{f} written before the exit");
    }

    // The defaults pass the same unit; a limits file that passes exits 0.
    let loose = d.join("loose.toml");
    std::fs::write(&loose, "held_out_bias_mg = 50\nmin_span_c = 10\n").unwrap();
    let out = d.join("passes");
    let (code, stdout, stderr) = run(&as_str(&args(&out, &loose)));
    assert_eq!(code, 0, "{stdout}{stderr}");
    let t = told(&stdout, &out);
    assert_one_story(&t);
    assert!(t.console[0].starts_with("verdict: PASS against the limits in "), "{:?}", t.console);

    // A limit in the wrong unit (µg typed into the mg key) is refused before any work.
    let wrong = d.join("wrong.toml");
    std::fs::write(&wrong, "held_out_bias_mg = 800\n").unwrap();
    let out = d.join("wrong-unit");
    let (code, stdout, stderr) = run(&as_str(&args(&out, &wrong)));
    // A usage error, as the lab guide's exit statuses say (it exited 1 before they were kept).
    assert_eq!(code, 2, "{stdout}{stderr}");
    assert!(stderr.contains("held_out_bias_mg = 800 mg is outside"), "{stderr}");
    assert!(!out.join("table.bin").exists(), "nothing written for a refused limits file");

    // A file of cycling-log keys on a static log would check only defaults under its name.
    let cycling = d.join("cycling.toml");
    std::fs::write(&cycling, "held_out_bias_ug = 0.5\n").unwrap();
    let out = d.join("other-kind");
    let (code, stdout, stderr) = run(&as_str(&args(&out, &cycling)));
    assert_eq!(code, 2, "{stdout}{stderr}");
    assert!(stderr.contains("none of the keys a static log is checked against"), "{stderr}");
    assert!(!out.join("table.bin").exists(), "nothing written for a limits file that does not apply");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_cycling_logs_verdict_is_one_story_too() {
    let d = tmp("cycling");
    let log = d.join("log.csv");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let (code, o, e) = run(&["simulate", "--out", &s(&log), "--row-s", "10", "--seed", "5"]);
    assert_eq!(code, 0, "{o}{e}");
    let out = d.join("cal");
    let (code, stdout, stderr) = run(&["calibrate", "--log", &s(&log), "--out", &s(&out), "--no-plots"]);
    assert_eq!(code, 0, "{stdout}{stderr}");
    let t = told(&stdout, &out);
    assert_one_story(&t);
    let fig = figures(&t.console);
    assert!(
        fig.len() == 1
            && fig[0].contains("held-out scale-factor sensitivity: ax ")
            && fig[0].contains("held-out bias residual RMS: ax "),
        "{fig:?}"
    );
    let _ = std::fs::remove_dir_all(&d);
}
