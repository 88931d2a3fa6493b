//! The host tests, their binaries two at a time.
//!
//! `cargo test` runs one test binary after another, and most of the lab's binaries hold one
//! to five long tests: while such a binary finishes its last test, one of the two cores
//! idles. Here cargo builds every test binary (`cargo test --no-run`, its JSON messages
//! naming each executable), and this runs them on a pool of workers as cargo would run each
//! one (from its package's folder, with cargo's runtime variables), the longest first by
//! the previous run's times. Each binary's output is printed whole when it ends; any
//! failure fails the step, naming the binaries. The doctests follow (`cargo test --doc`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Mutex;
use std::time::Instant;

use super::{capture, cargo, fail, run, target_dir, Result};

/// One test binary cargo built.
struct TestBinary {
    /// `package/target` (e.g. `qfa-lab/batch`), the name its times are kept under.
    name: String,
    executable: PathBuf,
    /// The package's folder: cargo runs a test binary from there.
    package_dir: PathBuf,
    package_name: String,
}

/// The test binaries of the default members, built by `cargo test --no-run`.
fn build() -> Result<Vec<TestBinary>> {
    let mut c = cargo();
    c.args(["test", "--no-run", "--message-format=json-render-diagnostics"]);
    // Diagnostics (and cargo's progress) go to the console as a build's would.
    c.stderr(Stdio::inherit());
    let (status, out, _) = capture(c)?;
    if !status.success() {
        return fail("cargo test --no-run failed (the compiler's messages are above)");
    }
    let mut bins = Vec::new();
    for line in out.lines() {
        let Ok(msg) = serde_json::from_str::<serde_json::Value>(line) else { continue };
        let is_test = msg["reason"] == "compiler-artifact" && msg["profile"]["test"] == true;
        let (Some(exe), Some(manifest)) = (msg["executable"].as_str(), msg["manifest_path"].as_str()) else {
            continue;
        };
        if !is_test {
            continue;
        }
        let package_dir = Path::new(manifest).parent().map_or_else(|| PathBuf::from("."), Path::to_path_buf);
        let package_name = msg["package_id"]
            .as_str()
            .and_then(|id| id.rsplit('#').next())
            .map_or("?", |v| v.split('@').next().unwrap_or(v))
            .to_string();
        let package_name = if package_name.is_empty() || package_name.chars().next().is_some_and(char::is_numeric) {
            // `path+file:///…/qfa-lab#0.1.0`: the name is the folder's.
            package_dir.file_name().map_or("?", |n| n.to_str().unwrap_or("?")).to_string()
        } else {
            package_name
        };
        let target = msg["target"]["name"].as_str().unwrap_or("?");
        bins.push(TestBinary {
            name: format!("{package_name}/{target}"),
            executable: PathBuf::from(exe),
            package_dir,
            package_name,
        });
    }
    if bins.is_empty() {
        return fail("cargo test --no-run named no test binary");
    }
    Ok(bins)
}

/// The previous run's wall seconds per binary (`name\tseconds` lines).
fn previous_times(path: &Path) -> BTreeMap<String, f64> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| l.split_once('\t').and_then(|(n, s)| Some((n.to_string(), s.parse().ok()?))))
        .collect()
}

/// Build the host test binaries, run them on `workers` workers, then the doctests.
pub(crate) fn run_all(workers: usize) -> Result {
    let mut bins = build()?;
    let times_path = target_dir()?.join("xtask-test-times.txt");
    let before = previous_times(&times_path);
    // Longest first (one never timed counts as long), so the last to end are short.
    bins.sort_by(|a, b| {
        let t = |x: &TestBinary| before.get(&x.name).copied().unwrap_or(f64::INFINITY);
        t(b).total_cmp(&t(a)).then_with(|| a.name.cmp(&b.name))
    });
    println!("{} test binaries on {workers} workers, longest first", bins.len());
    let next = Mutex::new(0usize);
    let console = Mutex::new(());
    let done: Mutex<Vec<(String, f64, bool)>> = Mutex::new(Vec::new());
    let started = Instant::now();
    std::thread::scope(|s| {
        for _ in 0..workers.max(1) {
            s.spawn(|| loop {
                let i = {
                    let Ok(mut n) = next.lock() else { return };
                    let i = *n;
                    *n += 1;
                    i
                };
                let Some(b) = bins.get(i) else { return };
                let mut c = Command::new(&b.executable);
                c.current_dir(&b.package_dir)
                    .env("CARGO_MANIFEST_DIR", &b.package_dir)
                    .env("CARGO_PKG_NAME", &b.package_name);
                let line = b.executable.display().to_string();
                let t = Instant::now();
                let out = c.output();
                let secs = t.elapsed().as_secs_f64();
                let ok = out.as_ref().is_ok_and(|o| o.status.success());
                if let Ok(_guard) = console.lock() {
                    println!("\n$ {line}   ({}, {secs:.1} s)", b.name);
                    match &out {
                        Ok(o) => {
                            print!("{}", String::from_utf8_lossy(&o.stdout));
                            eprint!("{}", String::from_utf8_lossy(&o.stderr));
                            if !o.status.success() {
                                println!("FAILED: {} exited with {}", b.name, o.status);
                            }
                        }
                        Err(e) => println!("FAILED: {} could not start: {e}", b.name),
                    }
                }
                if let Ok(mut d) = done.lock() {
                    d.push((b.name.clone(), secs, ok));
                }
            });
        }
    });
    let done = done.into_inner().unwrap_or_default();
    let sum: f64 = done.iter().map(|d| d.1).sum();
    println!(
        "\n{} test binaries: {sum:.0} s of runs in {:.0} s wall on {workers} workers",
        done.len(),
        started.elapsed().as_secs_f64()
    );
    let times: String = done.iter().map(|(n, s, _)| format!("{n}\t{s:.1}\n")).collect();
    // The next run's order; a write that fails costs only the order.
    let _ = std::fs::write(&times_path, times);
    let failed: Vec<&str> = done.iter().filter(|d| !d.2).map(|d| d.0.as_str()).collect();
    if !failed.is_empty() {
        return fail(format!("test binaries failed: {}", failed.join(", ")));
    }
    let mut c = cargo();
    c.args(["test", "--doc"]);
    run(c)
}
