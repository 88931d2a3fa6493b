//! `qfa-lab discover`'s reports tell one story: on a simulated cycling log and a simulated
//! static log, the verdict lines printed on the console are the `- **key:** text` items of
//! `report.md`, `verdict.lines` of `report.json` and the `<li>` texts of the page's
//! `<section id="verdict">`; stdout is those lines and a `detail:` line, never JSON,
//! unless `--json` asks for the report (then stdout is exactly `report.json`). On the real
//! chamber log (`--start paper`) every rendering says in words, axis by axis, whether the
//! named model is worse held out than the start model, as `report.json`'s figures are.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("qfa-discover-reports-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Run qfa-lab; (stdout, stderr), failing the test when it fails.
fn lab(args: &[&str]) -> (String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_qfa-lab")).args(args).output().expect("run qfa-lab");
    let (so, se) =
        (String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned());
    assert!(out.status.success(), "qfa-lab {args:?} failed:\n{so}\n{se}");
    (so, se)
}

/// The `- **key:** text` items of `report.md`'s verdict section, as `key: text`.
fn markdown_lines(md: &str) -> Vec<String> {
    let section = md.split_once("## Verdict\n\n").map(|(_, s)| s).unwrap_or_else(|| panic!("no verdict in:\n{md}"));
    section
        .lines()
        .take_while(|l| l.starts_with("- **"))
        .map(|l| l.trim_start_matches("- **").replacen(":** ", ": ", 1))
        .collect()
}

fn unescape(s: &str) -> String {
    s.replace("&lt;", "<").replace("&gt;", ">").replace("&quot;", "\"").replace("&#39;", "'").replace("&amp;", "&")
}

/// The text of each `<li>` of the page's `<section id="verdict">` (tags dropped).
fn page_lines(html: &str) -> Vec<String> {
    let start = html.find("<section id=\"verdict\"").unwrap_or_else(|| panic!("no verdict section"));
    let section = &html[start..start + html[start..].find("</section>").expect("section closed")];
    section
        .split("<li")
        .skip(1)
        .map(|li| {
            let body = &li[li.find('>').unwrap() + 1..li.find("</li>").expect("li closed")];
            let mut text = String::new();
            let mut in_tag = false;
            for c in body.chars() {
                match c {
                    '<' => in_tag = true,
                    '>' => in_tag = false,
                    c if !in_tag => text.push(c),
                    _ => {}
                }
            }
            unescape(&text)
        })
        .collect()
}

/// The verdict as each rendering gives it: (console, report.md, report.json, report.html).
struct Renderings {
    console: Vec<String>,
    markdown: Vec<String>,
    json: Vec<String>,
    page: Vec<String>,
}

/// Run `discover ARGS --out OUT`, check stdout's shape, and read the verdict back from
/// every rendering; with `json_too`, run it again with `--json` and check that stdout is
/// then `report.json` (one log suffices for that: the flag's path is the same for every
/// log, and each run is a whole discovery).
fn discover(args: &[&str], out: &Path, json_too: bool) -> Renderings {
    let out_s = out.to_str().unwrap();
    let mut a = vec!["discover", "--out", out_s];
    a.extend(args);
    let (stdout, _) = lab(&a);
    assert!(serde_json::from_str::<serde_json::Value>(&stdout).is_err(), "stdout is JSON without --json:\n{stdout}");
    let mut console: Vec<String> = stdout.lines().map(String::from).collect();
    let detail = console.pop().expect("stdout has lines");
    assert_eq!(detail, format!("detail: {out_s}/report.md, report.html, report.json"));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let json_text = std::fs::read_to_string(out.join("report.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&json_text).unwrap();
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let lines = json["verdict"]["lines"].as_array().expect("verdict.lines in report.json");
    let r = Renderings {
        console,
        markdown: markdown_lines(&md),
        json: lines.iter().map(|l| l.as_str().unwrap().to_string()).collect(),
        page: page_lines(&html),
    };
    if !json_too {
        return r;
    }
    // With --json: stdout is the report, which parses; the verdict goes to stderr.
    a.push("--json");
    let (stdout, stderr) = lab(&a);
    let printed: serde_json::Value = serde_json::from_str(&stdout).expect("stdout is JSON with --json");
    let again: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(printed, again, "--json prints report.json");
    assert!(stderr.contains(&r.console[0]), "the verdict on stderr with --json:\n{stderr}");
    r
}

fn assert_one_story(r: &Renderings) {
    for l in &r.console {
        println!("{l}");
    }
    assert!(r.console.len() >= 4, "{:?}", r.console);
    assert!(r.console[0].starts_with("verdict: RESULT: "), "{}", r.console[0]);
    // A figure to expect, or a table held back for having none (a cycling log of one
    // program, as `calibrate` holds it back).
    let held_back = r.console.iter().any(|l| l.starts_with("file: table.bin: held back: "));
    assert!(held_back || r.console.iter().any(|l| l.starts_with("expect in use: ")), "{:?}", r.console);
    assert_eq!(r.console.iter().filter(|l| l.starts_with("held-out: ")).count(), 1, "one definition of held-out");
    assert_eq!(r.markdown, r.console, "report.md's verdict");
    assert_eq!(r.json, r.console, "report.json's verdict.lines");
    assert_eq!(r.page, r.console, "report.html's verdict section");
}

#[test]
fn a_cycling_discovery_tells_one_story_on_every_rendering() {
    let d = tmp("cycling");
    let log = d.join("lag.csv");
    let log_s = log.to_str().unwrap();
    lab(&["simulate", "--out", log_s, "--row-s", "10", "--rates", "0.5,0.9", "--effects", "sensor_lag", "--seed", "3"]);
    let out = d.join("disc");
    let r = discover(&["--log", log_s], &out, true);
    assert_one_story(&r);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    // The answer names table.bin's structure and states both held-out figures of the bias
    // channel as the report has them: the table's (`flashed`) and the start model's.
    let (start, named) =
        (json["heldout_gap_before"]["bias_ug"].as_f64(), json["flashed"]["heldout"]["bias_ug"].as_f64());
    let (start, named) = (start.unwrap(), named.unwrap());
    let structure = json["table"]["structure"].as_str().expect("a cycling log's table");
    assert!(r.console[0].starts_with(&format!("verdict: RESULT: named {structure} = table.bin")), "{}", r.console[0]);
    let both = format!("bias: named {named:.2} µg, start {start:.2} µg");
    assert!(r.console[0].contains(&both), "{both} in {}", r.console[0]);
    // Every table on the page is a table, not Markdown in a <pre>.
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(!html.contains("<pre") && !html.contains("|---|"), "Markdown on the page");
    assert!(html.matches("<figcaption>").count() >= 4 && html.contains("Look at the lower panel"), "captions");
    candidates_say_why_not(&std::fs::read_to_string(out.join("report.md")).unwrap());
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_static_discovery_tells_one_story_on_every_rendering() {
    let d = tmp("static");
    let log = d.join("static.tsv");
    // 2-s rows: the same two hours at half the rows, so the debug-build test stays short.
    common::write_static_log_every(&log, 2);
    let out = d.join("disc");
    let flags = ["--columns", "time=time,temp=temp,ax=ax,ay=ay,az=az", "--time-unit", "s", "--accel-unit", "g"];
    let mut args = vec!["--log", log.to_str().unwrap()];
    args.extend(flags);
    let r = discover(&args, &out, false);
    assert_one_story(&r);
    // One clause per axis, each naming table.bin's structure as the named one.
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    for a in json["axes"].as_array().unwrap() {
        let clause =
            format!("{}: named {} = table.bin", a["axis"].as_str().unwrap(), a["named_structure"].as_str().unwrap());
        assert!(r.console[0].contains(&clause), "{clause} in {}", r.console[0]);
    }
    assert_eq!(r.console[0].matches(" = table.bin").count(), 3, "{}", r.console[0]);
    // The page: tables as tables, and no figure of another scheme called held-out.
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(!html.contains("<pre") && !html.contains("|---|"), "Markdown on the page");
    assert!(html.contains("CV RMS"), "the structure choice's figure is called CV");
    for axis in ["ax", "ay", "az"] {
        let page = std::fs::read_to_string(out.join(axis).join("report.html")).unwrap();
        let lines = page_lines(&page);
        let md = markdown_lines(&std::fs::read_to_string(out.join(axis).join("report.md")).unwrap());
        assert_eq!(lines, md, "{axis}: page and report.md");
        for h in ["Held-out gaps", "held-out RMS", "held-out gain", "Peers on the same held-out split"] {
            assert!(!page.contains(h), "{axis}: a selection-fold figure called {h:?}");
        }
        assert!(page.contains("Selection-fold gaps"), "{axis}");
        let md = std::fs::read_to_string(out.join(axis).join("report.md")).unwrap();
        candidates_say_why_not(&md);
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// Every candidate row of a discovery's `report.md` says "yes", or "no" with the first test
/// that refused it, and what it says agrees with the row's own figures: "no: gain/SE" only where gain/SE is not above its critical
/// value, "no: raw gain/SE" or "no: weight z" only where the whitened gain passed. (Before, the column read "no" alone, also beside a gain/SE
/// above the critical value that the weight's z had refused.)
fn candidates_say_why_not(md: &str) {
    let rounds = md.split("## Candidates per round").nth(1).expect("a candidates section");
    let mut rows = 0;
    for line in rounds.lines().filter(|l| l.starts_with("| `")) {
        let c: Vec<&str> = line.split(" | ").map(|x| x.trim_matches(|ch| ch == '|' || ch == ' ')).collect();
        let (gain, t, critical, significant) =
            (c[2].parse::<f64>().unwrap(), c[4].parse::<f64>().unwrap(), c[5].parse::<f64>().unwrap(), c[7]);
        let whitened_passes = gain > 0.0 && t > critical;
        match significant {
            "yes" => assert!(whitened_passes, "{line}"),
            "no: gain/SE" => assert!(!whitened_passes, "{line}"),
            s if s.starts_with("no: raw gain/SE ") || s.starts_with("no: weight z ") => {
                assert!(whitened_passes, "{line}")
            }
            other => panic!("a significance without its reason: {other:?} in {line}"),
        }
        rows += 1;
    }
    assert!(rows > 0, "no candidate rows in {rounds}");
}

/// The real log: each axis's clause names the structure `table.bin` holds and states how its
/// held-out figure stands against the start model's, in the words and figures of
/// `report.json`; a warning says so on exactly the axes where the named model is worse; and
/// the block test's own model is scored beside it. (Before the search was one, the named
/// model was the block test's, worse than the start on x and z: 1.99 against 1.15 mg and
/// 15.57 against 6.45 mg.)
#[test]
fn the_real_log_says_how_the_named_model_stands_on_every_rendering() {
    let Some(log) = common::real_log() else { return };
    let d = tmp("real");
    let out = d.join("disc");
    let args = [
        "--start",
        "paper",
        "--log",
        log.to_str().unwrap(),
        "--columns",
        "time=timestamp,temp=imu.temperature,ax=imu.acc.x,ay=imu.acc.y,az=imu.acc.z",
        "--time-unit",
        "us",
        "--accel-unit",
        "m/s2",
    ];
    let r = discover(&args, &out, false);
    assert_one_story(&r);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let axes = json["axes"].as_array().unwrap();
    for (k, a) in axes.iter().enumerate() {
        let axis = a["axis"].as_str().unwrap();
        let (start, named) = (a["before"]["rms_mg"].as_f64().unwrap(), a["after"]["rms_mg"].as_f64().unwrap());
        let worse = format!("{named:.2}") != format!("{start:.2}") && named > start;
        let head = format!("{axis}: named {} = table.bin", a["named_structure"].as_str().unwrap());
        let clause = r.console[0]
            .split(&head)
            .nth(1)
            .map(|c| {
                axes.get(k + 1)
                    .map_or(c, |n| c.split(&format!("; {}: named", n["axis"].as_str().unwrap())).next().unwrap())
            })
            .unwrap_or_else(|| panic!("{head} in {}", r.console[0]));
        let words = if format!("{named:.2}") == format!("{start:.2}") {
            "holds out the same as the start model `paper`"
        } else if worse {
            "is worse held out than the start model `paper`"
        } else {
            "beats the start model `paper` held out"
        };
        let says = format!("{words} (named {named:.2} mg, start {start:.2} mg)");
        assert!(clause.contains(&says), "{axis}: {says} in {clause}");
        let warning = format!("warning: {axis}: the named model (table.bin) is worse held out than the start model");
        assert_eq!(r.console.iter().any(|l| l.starts_with(&warning)), worse, "{axis}: {:?}", r.console);
        assert!(a["block_test_model"]["rms_mg"].as_f64().is_some_and(|x| x > 0.0), "{a}");
    }
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("the search, step by step, held out"), "{md}");
    let _ = std::fs::remove_dir_all(&d);
}
