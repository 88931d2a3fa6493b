//! Every command's `report.html` (calibrate cycling and static, discover cycling and
//! static, navigate, demo), opened in a real headless Chromium: it loads with no console
//! message or error and every image decodes ([`common::browser`]). The check itself is
//! shown to fail on a broken image and on a console error. The demo's pages and
//! navigate's are opened where those already run, in `nav_demo_reports` (one run serves
//! both checks).

mod common;

use std::path::{Path, PathBuf};

use common::{browser, lab_ok};
use qfa_discover::DiscoverError;

fn tmp(name: &str) -> PathBuf {
    common::fresh_dir("report-html", name)
}

#[test]
fn the_browser_check_fails_on_a_broken_image_and_on_a_console_error() {
    let Some(c) = browser::chromium_or_skip("the browser check's own test") else { return };
    let d = tmp("probe");
    // A 2×2 plot with nothing drawn on it: black pixels, a PNG all the same.
    let dot = qfa_report::plot_png::Plot::draw("dot.png", (2, 2), |_| Ok(())).unwrap();
    let mut p = qfa_report::html_report::Page::new("probe");
    p.plot(&dot, "a dot");
    let good = p.write(&d).unwrap();
    assert_eq!(browser::check(&c, &good), Ok(1), "a page with one good image passes");
    // The verdict-first check: this page has none; one with a verdict below a section fails
    // it too, and one that opens with it passes.
    assert_ne!(browser::show(&c, &good).unwrap().first, "verdict", "a page without a verdict fails the check");
    let v = qfa_report::verdict::Verdict::new("a probe", "nothing held out", vec![]);
    let mut late = qfa_report::html_report::Page::new("late");
    late.section("Something else first");
    v.to_page(&mut late);
    let late_dir = d.join("late");
    std::fs::create_dir_all(&late_dir).unwrap();
    let shown = browser::show(&c, &late.write(&late_dir).unwrap()).unwrap();
    assert_ne!(shown.first, "verdict", "a verdict below another section is not first");
    let mut first = qfa_report::html_report::Page::new("first");
    v.to_page(&mut first);
    let first_dir = d.join("first");
    std::fs::create_dir_all(&first_dir).unwrap();
    let shown = browser::show(&c, &first.write(&first_dir).unwrap()).unwrap();
    assert_eq!(
        (shown.first.as_str(), shown.verdict),
        ("verdict", v.lines().iter().map(|(k, t)| format!("{k}: {t}")).collect())
    );
    // The same page with the image's data cut short: it no longer decodes.
    let html = std::fs::read_to_string(&good).unwrap();
    let b64 = qfa_report::html_report::base64(dot.png());
    let broken = d.join("broken.html");
    std::fs::write(&broken, html.replace(&b64, &b64[..12])).unwrap();
    let e = browser::check(&c, &broken).unwrap_err();
    assert!(e.contains("images that do not decode"), "{e}");
    // A console error (the reports carry no script; this page does).
    let noisy = d.join("noisy.html");
    std::fs::write(&noisy, html.replace("</body>", "<script>console.error('boom')</script></body>")).unwrap();
    let e = browser::check(&c, &noisy).unwrap_err();
    assert!(e.contains("boom"), "{e}");
    // A script error.
    let thrown = d.join("thrown.html");
    std::fs::write(&thrown, html.replace("</body>", "<script>undefinedFunction()</script></body>")).unwrap();
    let e = browser::check(&c, &thrown).unwrap_err();
    assert!(e.contains("undefinedFunction"), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn calibrate_and_discover_on_a_cycling_log_write_pages_that_load() {
    let d = tmp("cycling");
    let log = d.join("log.csv");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    lab_ok(&["simulate", "--out", &s(&log), "--row-s", "10", "--seed", "5"]);
    let cal = d.join("cal");
    lab_ok(&["calibrate", "--log", &s(&log), "--out", &s(&cal)]);
    let html = std::fs::read_to_string(cal.join("report.html")).unwrap();
    for want in [
        "Held-out scheme",
        "paper-0.5",
        "rows cover, against what the model needs",
        "heating leg",
        "cooling leg",
        "table clamps to",
    ] {
        assert!(html.contains(want), "calibrate's page lacks {want:?}");
    }
    browser::assert_page(&cal.join("report.html"), 2);
    // Compensating a cycling log writes its flag counts beside the CSV, as a static log's
    // compensation does: before, they went to the console only (and a static run's
    // sidecar of the same name stayed beside the new CSV). Its rows are the CSV's.
    let comp = d.join("comp.csv");
    lab_ok(&["compensate", "--log", &s(&log), "--table", &s(&cal.join("table.bin")), "--out", &s(&comp)]);
    let sidecar: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(comp.with_extension("flags.json")).unwrap()).unwrap();
    let csv_rows = std::fs::read_to_string(&comp).unwrap().lines().count() - 1;
    assert_eq!(sidecar["rows"].as_u64(), Some(csv_rows as u64), "{sidecar}");
    let disc = d.join("disc");
    // A plot an earlier run left in the folder (a single-channel log's discovery writes
    // this name; a cycling log's does not): before, the page inlined every PNG it found
    // there, captioned as this run's residual.
    std::fs::create_dir_all(&disc).unwrap();
    std::fs::copy(cal.join("sf_vs_temp.png"), disc.join("residual_value_vs_time.png")).unwrap();
    lab_ok(&["discover", "--log", &s(&log), "--out", &s(&disc)]);
    let html = std::fs::read_to_string(disc.join("report.html")).unwrap();
    for want in ["Held-out scheme", "Effects added", "What the log covers", "report.md"] {
        assert!(html.contains(want), "discover's page lacks {want:?}");
    }
    assert!(!html.contains("residual_value_vs_time.png"), "discover's page shows a plot it did not draw");
    assert!(html.contains("residual_bias_vs_time.png"), "discover's page lacks its own plot");
    browser::assert_page(&disc.join("report.html"), 1);
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn static_calibrate_and_discover_write_pages_that_load() {
    let d = tmp("static");
    let log = d.join("static.tsv");
    common::write_static_log(&log);
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let flags = ["--columns", "time=time,temp=temp,ax=ax,ay=ay,az=az", "--time-unit", "s", "--accel-unit", "g"];
    let cal = d.join("cal");
    let mut args = vec!["calibrate".to_string(), "--log".into(), s(&log), "--out".into(), s(&cal)];
    args.extend(flags.iter().map(|f| (*f).to_string()));
    lab_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(cal.join("bias_vs_temp.png").is_file(), "static calibrate writes its plot");
    let html = std::fs::read_to_string(cal.join("report.html")).unwrap();
    for want in ["Held-out scheme", "after-max", "What the log covers", "heating leg", "bias_vs_temp.png"] {
        assert!(html.contains(want), "static calibrate's page lacks {want:?}");
    }
    browser::assert_page(&cal.join("report.html"), 1);
    let disc = d.join("disc");
    let mut args = vec!["discover".to_string(), "--log".into(), s(&log), "--out".into(), s(&disc)];
    args.extend(flags.iter().map(|f| (*f).to_string()));
    lab_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    browser::assert_page(&disc.join("report.html"), 3);
    for a in ["ax", "ay", "az"] {
        browser::assert_page(&disc.join(a).join("report.html"), 1);
    }
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_heating_only_static_log_says_what_to_record_next() {
    let d = tmp("heating");
    let log = d.join("heat.tsv");
    let mut s = String::from("time\ttemp\taz\n");
    for i in 0..3000 {
        let temp = 20.0 + 30.0 * f64::from(i) / 3000.0;
        s.push_str(&format!("{i}\t{:.4}\t{:.7}\n", (temp * 16.0).round() / 16.0, -1.0 + 1e-4 * (temp - 20.0)));
    }
    std::fs::write(&log, s).unwrap();
    let cal = d.join("cal");
    lab_ok(&[
        "calibrate",
        "--log",
        log.to_str().unwrap(),
        "--out",
        cal.to_str().unwrap(),
        "--columns",
        "time=time,temp=temp,az=az",
        "--time-unit",
        "s",
        "--accel-unit",
        "g",
    ]);
    let html = std::fs::read_to_string(cal.join("report.html")).unwrap();
    assert!(html.contains("What to record next: the cooling leg holds 0 rows"), "no advice in:\n{html}");
    assert!(html.contains("record a cooling leg after the maximum"), "no later-leg advice");
    browser::assert_page(&cal.join("report.html"), 1);
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn the_demo_fails_when_a_hook_fails() {
    let d = tmp("demo-fails");
    let opts = qfa_lab::demo::DemoOptions {
        out: d.clone(),
        row_s: 10,
        seed: 1,
        threads: 1,
        progress: false,
        full_logs: false,
        nav_duration_s: None,
    };
    let fail = |_: &Path, _: &Path| Err(DiscoverError::NoModel { axis: "the hook's".into(), fold: None });
    let e = qfa_lab::demo::run(&opts, Some(fail), None).unwrap_err();
    // The error says which step and unit, and carries discovery's own error as a value.
    assert!(
        matches!(&e, qfa_lab::demo::DemoError::Discover { unit, source: DiscoverError::NoModel { .. } } if unit == "JB-KT8 #1"),
        "{e:?}"
    );
    assert!(e.to_string().contains("the hook's: discovery gave no model"), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}
