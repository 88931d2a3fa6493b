//! Open a page in a real headless Chromium and check it: it loads without a console
//! message or error, and every `<img>` decodes (`naturalWidth > 0`).
//!
//! How: a copy of the page (in a fresh temporary folder, so anything it does not embed
//! breaks) gets a small probe script as the first thing in `<head>`; it records script and
//! resource errors and `console.error`, and on `load` writes the image results into the
//! DOM, which `--dump-dom` prints. The reports themselves carry no script, so any
//! `CONSOLE` line Chromium logs to stderr (`--enable-logging=stderr`) is a failure too.
//!
//! Chromium missing: with `CI=true` a failure; otherwise a loud SKIPPED line.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// How to install it (Debian).
pub const INSTALL: &str = "apt-get install chromium";

const PROBE: &str = r#"<script>
window.__qfaErrors = [];
window.addEventListener('error', function (e) {
  var t = e.target;
  window.__qfaErrors.push(e.message ? 'error: ' + e.message : 'resource failed: ' + ((t && (t.src || t.href)) || '?').slice(0, 80));
}, true);
(function () { var ce = console.error; console.error = function () {
  window.__qfaErrors.push('console.error: ' + Array.prototype.join.call(arguments, ' ')); ce.apply(console, arguments); }; })();
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var bad = imgs.filter(function (i) { return !(i.complete && i.naturalWidth > 0); })
    .map(function (i) { return i.alt || i.src.slice(0, 60); });
  var d = document.createElement('pre');
  // The markers are split so that the script's own text (also in the dump) never holds them.
  d.textContent = 'QFA' + '-PROBE images=' + imgs.length + ' broken=' + JSON.stringify(bad) + ' errors=' +
    JSON.stringify(window.__qfaErrors) + ' QFA' + '-END';
  document.body.appendChild(d);
  // What a reader sees first: the first section or h2 of the body, and the verdict's items.
  var first = document.body.querySelector('section, h2');
  var v = document.getElementById('verdict');
  var items = v ? Array.prototype.map.call(v.querySelectorAll('li'), function (li) { return li.textContent; }) : [];
  var e = document.createElement('pre');
  e.textContent = 'QFA' + '-VERDICT ' + JSON.stringify({ first: first ? (first.id || first.tagName) : '', items: items }) +
    ' QFA' + '-VEND';
  document.body.appendChild(e);
});
</script>"#;

/// The Chromium binary: `$QFA_CHROMIUM`, else the first of `chromium`, `chromium-browser`,
/// `google-chrome` that runs.
pub fn chromium() -> Option<PathBuf> {
    let names: Vec<PathBuf> = match std::env::var_os("QFA_CHROMIUM") {
        Some(p) => vec![PathBuf::from(p)],
        None => ["chromium", "chromium-browser", "google-chrome"].iter().map(PathBuf::from).collect(),
    };
    names.into_iter().find(|n| {
        Command::new(n).arg("--version").stdout(Stdio::null()).stderr(Stdio::null()).status().is_ok_and(|s| s.success())
    })
}

/// Chromium, or `None` after printing SKIPPED; with `CI=true` a missing Chromium panics.
pub fn chromium_or_skip(what: &str) -> Option<PathBuf> {
    let c = chromium();
    if c.is_none() {
        let msg = format!(
            "SKIPPED: {what}: headless Chromium not found (chromium, chromium-browser, google-chrome or \
             $QFA_CHROMIUM); install it with `{INSTALL}`"
        );
        assert!(std::env::var("CI").as_deref() != Ok("true"), "{msg}");
        eprintln!("\n*** {msg} ***\n");
    }
    c
}

/// What the browser showed of a page.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Shown {
    /// Images that decoded.
    pub images: usize,
    /// The id (else the tag) of the body's first `<section>` or `<h2>`.
    pub first: String,
    /// The text of each item of `<section id="verdict">`, as rendered.
    pub verdict: Vec<String>,
}

/// Open `page` in `chromium`; `Ok(images)` when it loads with no console message or error
/// and every one of its `images` decodes, else what went wrong.
pub fn check(chromium: &Path, page: &Path) -> Result<usize, String> {
    show(chromium, page).map(|s| s.images)
}

/// [`check`], returning what the page showed first and its verdict's items.
pub fn show(chromium: &Path, page: &Path) -> Result<Shown, String> {
    let html = std::fs::read_to_string(page).map_err(|e| format!("{}: {e}", page.display()))?;
    let probed = match html.find("<head>") {
        Some(i) => format!("{}{PROBE}{}", &html[..i + 6], &html[i + 6..]),
        None => format!("{PROBE}{html}"),
    };
    static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "qfa-chromium-{}-{}",
        std::process::id(),
        N.fetch_add(1, std::sync::atomic::Ordering::SeqCst)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("profile")).map_err(|e| e.to_string())?;
    let copy = dir.join("page.html");
    std::fs::write(&copy, probed).map_err(|e| e.to_string())?;
    let mut child = Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--enable-logging=stderr",
            "--v=0",
        ])
        .arg(format!("--user-data-dir={}", dir.join("profile").display()))
        .arg("--dump-dom")
        .arg(format!("file://{}", copy.display()))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("{}: {e}", chromium.display()))?;
    // Read both pipes on threads (a full pipe would stall Chromium), with a time limit.
    let mut so = child.stdout.take().ok_or("no stdout")?;
    let mut se = child.stderr.take().ok_or("no stderr")?;
    let t_out = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut so, &mut s);
        s
    });
    let t_err = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut se, &mut s);
        s
    });
    let deadline = Instant::now() + Duration::from_secs(90);
    let status = loop {
        match child.try_wait() {
            Ok(Some(s)) => break s,
            Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(50)),
            Ok(None) => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(format!("chromium timed out after 90 s on {}", page.display()));
            }
            Err(e) => return Err(e.to_string()),
        }
    };
    let (out, err) = (t_out.join().unwrap_or_default(), t_err.join().unwrap_or_default());
    let _ = std::fs::remove_dir_all(&dir);
    if !status.success() {
        return Err(format!("chromium exited with {status} on {}:\n{err}", page.display()));
    }
    let console: Vec<&str> = err.lines().filter(|l| l.contains(":CONSOLE")).collect();
    let Some(probe) = out.split("QFA-PROBE ").nth(1).and_then(|s| s.split(" QFA-END").next()) else {
        return Err(format!("{}: the page never finished loading (no probe output); stderr:\n{err}", page.display()));
    };
    let field = |k: &str| probe.split(&format!("{k}=")).nth(1).map(|s| s.split(' ').next().unwrap_or(""));
    let images: usize = field("images").and_then(|s| s.parse().ok()).ok_or_else(|| format!("probe: {probe}"))?;
    let broken = probe.split("broken=").nth(1).and_then(|s| s.split(" errors=").next()).unwrap_or("?");
    let errors = probe.split("errors=").nth(1).unwrap_or("?");
    let mut why = Vec::new();
    if broken != "[]" {
        why.push(format!("images that do not decode: {broken}"));
    }
    if errors != "[]" {
        why.push(format!("errors: {errors}"));
    }
    if !console.is_empty() {
        why.push(format!("console messages:\n{}", console.join("\n")));
    }
    let shown = out
        .split("QFA-VERDICT ")
        .nth(1)
        .and_then(|s| s.split(" QFA-VEND").next())
        // --dump-dom escapes a text node's <, > and &.
        .map(|s| s.replace("&lt;", "<").replace("&gt;", ">").replace("&amp;", "&"))
        .ok_or_else(|| format!("{}: no verdict probe output", page.display()))?;
    let v: serde_json::Value = serde_json::from_str(&shown).map_err(|e| format!("verdict probe: {e}: {shown}"))?;
    let first = v["first"].as_str().unwrap_or("").to_string();
    let verdict = v["items"]
        .as_array()
        .map_or_else(Vec::new, |a| a.iter().filter_map(|x| x.as_str()).map(String::from).collect());
    if why.is_empty() {
        Ok(Shown { images, first, verdict })
    } else {
        Err(format!("{}: {}", page.display(), why.join("; ")))
    }
}

/// [`show`] when Chromium is installed (else SKIPPED and `None`), asserting the page loads
/// cleanly and opens with its verdict: the body's first section is `<section id="verdict">`
/// and it has items. Returns the verdict's items as the browser rendered them.
pub fn assert_verdict_first(page: &Path) -> Option<Vec<String>> {
    assert!(page.is_file(), "{} not written", page.display());
    let c = chromium_or_skip(&format!("verdict check of {}", page.display()))?;
    let s = show(&c, page).unwrap_or_else(|e| panic!("browser check failed: {e}"));
    assert_eq!(s.first, "verdict", "{}: the first section a reader sees is not the verdict", page.display());
    assert!(!s.verdict.is_empty(), "{}: an empty verdict", page.display());
    assert!(s.verdict[0].starts_with("verdict: "), "{}: {:?}", page.display(), s.verdict);
    println!("chromium: {} opens with its verdict: {}", page.display(), s.verdict[0]);
    Some(s.verdict)
}

/// [`show`] when Chromium is installed (else SKIPPED, see [`chromium_or_skip`]), asserting
/// the page loads cleanly, holds at least `min_images` images, and opens with its verdict
/// (every report does); prints what it checked.
pub fn assert_page(page: &Path, min_images: usize) {
    assert!(page.is_file(), "{} not written", page.display());
    let Some(c) = chromium_or_skip(&format!("browser check of {}", page.display())) else { return };
    match show(&c, page) {
        Ok(s) => {
            println!("chromium: {} loaded, no console message, {} image(s) decoded", page.display(), s.images);
            assert!(
                s.images >= min_images,
                "{}: {} image(s), expected at least {min_images}",
                page.display(),
                s.images
            );
            assert_eq!(s.first, "verdict", "{}: the first section a reader sees is not the verdict", page.display());
            assert!(
                s.verdict.first().is_some_and(|v| v.starts_with("verdict: ")),
                "{}: {:?}",
                page.display(),
                s.verdict
            );
        }
        Err(e) => panic!("browser check failed: {e}"),
    }
}
