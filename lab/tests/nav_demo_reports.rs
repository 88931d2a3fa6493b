//! `navigate`, `navigate merge` and `demo` tell one story: the console's verdict lines
//! (from `verdict:` to the `detail:` line), `report.md`'s `- **key:** text` items,
//! `report.json`'s `verdict.lines` and the `<li>` items of `report.html`'s
//! `<section id="verdict">` (read with an HTML reader, right after the title) are the same
//! lines, and `report.json`'s verdict holds no null. Every link on the demo's page resolves to a file beside it. The comparison is
//! shown to fail on a page whose verdict differs by one line and on a link to a missing
//! file.
//!
//! Runs reduced: the built-in flight's first 15 min at 20 Hz with one Monte Carlo run, and
//! the demo at 10-s rows with 20 min of flight. The navigate run and the demo's also open
//! their pages in a real headless Chromium ([`common::browser`]), and the demo's outputs'
//! size is checked (under 20 MB): one run serves both checks.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{browser, html};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("qfa-nav-demo-reports-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Run qfa-lab; its stdout (the verdict's console), after asserting success.
fn lab_stdout(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_qfa-lab")).args(args).output().expect("run qfa-lab");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "qfa-lab {args:?} failed:\n{stdout}{}", String::from_utf8_lossy(&out.stderr));
    stdout
}

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

/// The console's verdict lines: from the `verdict:` line up to the `detail:` line, which
/// must name `dir`'s three reports.
fn console_verdict(stdout: &str, dir: &Path) -> Vec<String> {
    let lines: Vec<&str> = stdout.lines().collect();
    let start =
        lines.iter().position(|l| l.starts_with("verdict: ")).unwrap_or_else(|| panic!("no verdict:\n{stdout}"));
    let end = start
        + lines[start..]
            .iter()
            .position(|l| l.starts_with("detail: "))
            .unwrap_or_else(|| panic!("no detail:\n{stdout}"));
    assert_eq!(lines[end], format!("detail: {}/report.md, report.html, report.json", dir.display()));
    lines[start..end].iter().map(|l| (*l).to_string()).collect()
}

/// `report.md`'s verdict: the `- **key:** text` items under `## Verdict`, as `key: text`.
fn markdown_verdict(md: &str) -> Vec<String> {
    let body = md.split_once("\n## Verdict\n").unwrap_or_else(|| panic!("no ## Verdict in:\n{md}")).1;
    let section = body.split("\n## ").next().unwrap();
    section.lines().filter_map(|l| l.strip_prefix("- **")).map(|l| l.replacen(":** ", ": ", 1)).collect()
}

/// `report.json`'s `verdict.lines`.
fn json_verdict(json: &str) -> Vec<String> {
    let v: serde_json::Value = serde_json::from_str(json).unwrap();
    let first = v.as_object().and_then(|o| o.keys().next().cloned());
    assert!(v["verdict"].is_object(), "report.json has no verdict (first key {first:?})");
    let text = v["verdict"].to_string();
    assert!(!text.contains("null"), "a verdict holds no null (a NaN serializes as null): {text}");
    v["verdict"]["lines"].as_array().unwrap().iter().map(|l| l.as_str().unwrap().to_string()).collect()
}

/// `report.html`'s verdict items, after checking the section opens the page: the first
/// heading after the title is its own.
fn html_verdict(page: &str) -> Result<Vec<String>, String> {
    let doc = html::parse(page);
    let first_h2 = doc.iter().position(|e| e.name == "h2").ok_or("no section heading")?;
    let section = doc.iter().position(|e| e.attr("id") == Some("verdict")).ok_or("no <section id=\"verdict\">")?;
    if doc[section].name != "section" || !html::inside(&doc, first_h2, section) {
        return Err(format!("the verdict is not the page's first section (first heading: {:?})", doc[first_h2].text));
    }
    html::list_items_in(page, "verdict").ok_or_else(|| "no verdict items".to_string())
}

/// The four renderings of `dir`'s verdict, compared line by line with the console's;
/// returns the lines.
fn assert_one_story(dir: &Path, stdout: &str) -> Vec<String> {
    let console = console_verdict(stdout, dir);
    let read =
        |f: &str| std::fs::read_to_string(dir.join(f)).unwrap_or_else(|e| panic!("{}: {e}", dir.join(f).display()));
    assert_eq!(markdown_verdict(&read("report.md")), console, "report.md against the console");
    assert_eq!(json_verdict(&read("report.json")), console, "report.json against the console");
    assert_eq!(html_verdict(&read("report.html")).unwrap(), console, "report.html against the console");
    assert!(read("report.md").starts_with("# "), "report.md opens with its title");
    for l in &console {
        println!("{l}");
    }
    console
}

/// The links of a page that point at files (not anchors, not data), each resolved
/// against the page's folder; `Err` names the first that does not resolve.
fn links_resolve(page: &Path) -> Result<Vec<String>, String> {
    let hrefs: Vec<String> = html::hrefs(&std::fs::read_to_string(page).unwrap())
        .into_iter()
        .filter(|h| !h.starts_with('#') && !h.starts_with("data:"))
        .collect();
    let dir = page.parent().unwrap();
    for h in &hrefs {
        if h.contains("://") || h.starts_with('/') {
            return Err(format!("{h}: not relative to the page"));
        }
        if !dir.join(html::percent_decode(h)).is_file() {
            return Err(format!("{h}: no such file beside {}", page.display()));
        }
    }
    Ok(hrefs)
}

#[test]
fn navigate_with_a_monte_carlo_run_and_its_merged_shard_tell_one_story() {
    let d = tmp("nav");
    let scenario = d.join("short.toml");
    let sc = qfa_nav::scenario::Scenario::builtin().truncated(900.0);
    std::fs::write(&scenario, toml::to_string(&sc).unwrap()).unwrap();
    let sc_path = s(&scenario);
    let quick = ["--scenario", &sc_path, "--imu-rate-hz", "20", "--runs", "1", "--jobs", "1", "--no-mc-discovered"];
    let out = d.join("nav");
    let mut args = vec!["navigate", "--out"];
    let o = s(&out);
    args.push(&o);
    args.extend(quick);
    let lines = assert_one_story(&out, &lab_stdout(&args));
    assert!(lines[0].starts_with("verdict: RESULT: hysteresis compensation "), "{}", lines[0]);
    assert!(lines[0].contains("over 1 run of the Monte Carlo study"), "{}", lines[0]);
    assert!(lines.iter().any(|l| l.starts_with("held-out: tables fitted on the lab program `covering`")), "{lines:?}");
    assert!(lines.iter().any(|l| l.starts_with("expect in use: CEP rate")), "{lines:?}");
    assert!(lines.iter().any(|l| l.starts_with("warning: the flight is only 15 min")), "{lines:?}");
    assert!(!lines.iter().any(|l| l.starts_with("limit: ")), "a study has no limits: {lines:?}");
    // The page itself: its sections, and it loads in a real browser with its plot.
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    for want in ["Held-out scheme", "Figures per variant", "What the lab program covers"] {
        assert!(html.contains(want), "navigate's page lacks {want:?}");
    }
    browser::assert_page(&out.join("report.html"), 1);

    // The shard path: shard 0 of 1 flies the nominal run and the Monte Carlo run, merge
    // judges the study.
    let shard = d.join("shard");
    let mut args = vec!["navigate", "--shard", "0/1", "--no-plots", "--out"];
    let sh = s(&shard);
    args.push(&sh);
    args.extend(quick);
    lab_stdout(&args);
    let merged = d.join("merged");
    let m = s(&merged);
    let lines = assert_one_story(&merged, &lab_stdout(&["navigate", "merge", &sh, "--out", &m]));
    assert!(lines[0].starts_with("verdict: RESULT: over 1 run of the Monte Carlo study"), "{}", lines[0]);
    assert!(lines.iter().any(|l| l.starts_with("held-out: each run's tables fitted")), "{lines:?}");

    // The comparison fails on a page whose verdict differs by one line.
    let page = std::fs::read_to_string(merged.join("report.html")).unwrap();
    let changed = page.replacen("<b>held-out:</b> each", "<b>held-out:</b> every", 1);
    assert_ne!(page, changed);
    assert_ne!(html_verdict(&changed).unwrap(), lines);
    let moved = page.replacen("<section id=\"verdict\"", "<h2>Before</h2>\n<section id=\"verdict\"", 1);
    assert!(html_verdict(&moved).unwrap_err().contains("not the page's first section"));
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn the_reduced_demo_tells_one_story_links_every_sub_page_loads_and_stays_under_20_mb() {
    let d = tmp("demo");
    let out = d.join("out");
    let t = std::time::Instant::now();
    let stdout = lab_stdout(&["demo", "--out", &s(&out), "--row-s", "10", "--nav-duration-s", "1200"]);
    let secs = t.elapsed().as_secs_f64();
    let bytes = qfa_lab::demo::dir_bytes(&out).unwrap();
    println!("reduced demo (10-s rows, 1200 s of flight): {secs:.1} s, {:.2} MB", bytes as f64 / 1e6);
    assert!(bytes < 20_000_000, "demo outputs {bytes} B, over 20 MB:\n{stdout}");
    for u in 1..=3 {
        assert!(!out.join(format!("kt8-{u}/log.csv")).exists(), "log.csv kept without --full-logs");
        browser::assert_page(&out.join(format!("kt8-{u}/report.html")), 2);
    }
    browser::assert_page(&out.join("kt8-1/discover/report.html"), 1);
    browser::assert_page(&out.join("navigation/report.html"), 1);
    browser::assert_page(&out.join("report.html"), 4);
    // Every CSV of the demo (discovery's residuals, the flight's time series) reads as
    // pandas reads a file given no options.
    let csvs = common::assert_plain_csvs(&out);
    assert!(csvs >= 2, "{csvs} CSV files in the demo's outputs");
    let lines = assert_one_story(&out, &stdout);
    assert!(
        stdout.trim_end().lines().last().is_some_and(|l| l.starts_with("detail: ")),
        "the console ends with the verdict and where the detail is:\n{stdout}"
    );
    for part in ["JB-KT8 #1 PASS", "JB-KT8 #2 PASS", "JB-KT8 #3 PASS", "navigation RESULT"] {
        assert!(lines[0].contains(part), "{part} in {}", lines[0]);
    }
    let page = out.join("report.html");
    let links = links_resolve(&page).unwrap();
    println!("links: {links:?}");
    for want in [
        "kt8-1/report.html",
        "kt8-2/report.html",
        "kt8-3/report.html",
        "kt8-1/discover/report.html",
        "navigation/report.html",
        "report.md",
        "report.json",
        "table4.json",
    ] {
        assert!(links.iter().any(|l| l == want), "the demo's page links {want}: {links:?}");
    }
    // The navigation sub-page tells its own story the same way.
    let nav = std::fs::read_to_string(out.join("navigation/report.json")).unwrap();
    let nav_md = std::fs::read_to_string(out.join("navigation/report.md")).unwrap();
    assert_eq!(json_verdict(&nav), markdown_verdict(&nav_md));

    // A link to a missing file is caught.
    let broken = out.join("broken.html");
    let html = std::fs::read_to_string(&page).unwrap();
    std::fs::write(&broken, html.replacen("href=\"kt8-2/report.html\"", "href=\"kt8-2/missing.html\"", 1)).unwrap();
    assert!(links_resolve(&broken).unwrap_err().contains("kt8-2/missing.html"));
    let _ = std::fs::remove_dir_all(&d);
}
