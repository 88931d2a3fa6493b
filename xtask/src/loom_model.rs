//! The loom model of the compensator's seqlock, clean and with its mutants.

use super::*;

/// A cargo command for the loom build: `--cfg loom` on every crate, in `dir` (its own
/// target directory, so the normal build cache keeps its flags).
pub(super) fn loom_cargo(dir: &Path) -> Command {
    let mut c = cargo();
    c.env("CARGO_TARGET_DIR", dir).env("RUSTFLAGS", "--cfg loom").env_remove("CARGO_ENCODED_RUSTFLAGS");
    c
}

/// Build qfa-thermal's unit tests under `--cfg loom`, with `--cfg qfa_mutant="NAME"` on
/// qfa-thermal alone for a mutant (`cargo rustc`: a RUSTFLAGS change would rebuild every
/// dependency for each mutant); the test binary. The test profile: this workspace builds
/// qfa-thermal and every dependency at opt-level 2 there, without the release profile's
/// fat LTO on each of the seven builds, and with overflow checks on.
pub(super) fn build_loom_model(dir: &Path, mutant: Option<&str>) -> Result<PathBuf> {
    let mut c = loom_cargo(dir);
    c.args(["rustc", "-p", "qfa-thermal", "--lib", "--profile", "test", "--message-format", "json-render-diagnostics"]);
    if let Some(m) = mutant {
        c.args(["--", "--cfg", &format!("qfa_mutant=\"{m}\"")]);
    }
    let line = show(&c);
    println!("$ {line}");
    // stdout is JSON, read for the test binary; stderr (progress, diagnostics) is shown.
    let out = c.stderr(Stdio::inherit()).output().map_err(|e| Failure(format!("`{line}` could not start: {e}")))?;
    if !out.status.success() {
        return fail(format!("`{line}` exited with {}", out.status));
    }
    let json = String::from_utf8_lossy(&out.stdout);
    let key = "\"executable\":\"";
    let exe = json.lines().find_map(|l| {
        let start = l.find(key)? + key.len();
        Some(PathBuf::from(&l[start..start + l[start..].find('"')?]))
    });
    exe.map_or_else(|| fail(format!("`{line}` reported no test executable")), Ok)
}

/// Run the model's tests in `exe`: exit status, whole output (stdout then stderr) and run time.
pub(super) fn run_loom_model(exe: &Path) -> Result<(ExitStatus, String, Duration)> {
    let mut c = Command::new(exe);
    c.args([LOOM_MODEL, "--nocapture"]).env("RUST_BACKTRACE", "0");
    println!("$ {}", show(&c));
    let start = Instant::now();
    let (status, out, err) = capture(c)?;
    Ok((status, out + &err, start.elapsed()))
}

/// `N` of the harness's `test result: ... N passed; M failed` line.
pub(super) fn count(out: &str, what: &str) -> Option<usize> {
    let result = out.lines().find(|l| l.starts_with("test result:"))?;
    result.split(';').find_map(|part| part.trim().strip_suffix(what)?.split_whitespace().last()?.parse().ok())
}

/// The clean model: built, run, and every one of its tests passed.
pub(super) fn loom_model_passes(dir: &Path) -> Result {
    let exe = build_loom_model(dir, None)?;
    let (status, out, took) = run_loom_model(&exe)?;
    print!("{out}");
    let passed = count(&out, "passed").unwrap_or(0);
    if !status.success() || passed == 0 || count(&out, "failed") != Some(0) {
        return fail(format!("the seqlock's loom model failed or ran no test ({status}, {passed} passed)"));
    }
    println!("loom model: {passed} tests passed in {:.1} s (run only)", took.as_secs_f64());
    Ok(())
}

pub(super) fn loom() -> Result {
    let start = Instant::now();
    let dir = target_dir()?.join("loom");

    step("clippy, --cfg loom (qfa-thermal, all targets)");
    let mut c = loom_cargo(&dir);
    c.args(["clippy", "-p", "qfa-thermal", "--all-targets", "--", "-D", "warnings"]);
    run(c)?;

    step("loom model of the seqlock, clean: must pass");
    loom_model_passes(&dir)?;

    let mut caught = 0;
    for (name, what) in MUTANTS {
        step(&format!("mutant {name} ({what}): the model must fail"));
        let exe = build_loom_model(&dir, Some(name))?;
        let (status, out, took) = run_loom_model(&exe)?;
        let failed = count(&out, "failed").unwrap_or(0);
        let tests = failed + count(&out, "passed").unwrap_or(0);
        // The model's own assertion, not loom or the harness, must be what failed.
        let own = format!("panicked at {LOOM_MODEL_FILE}");
        let message = out.lines().skip_while(|l| !l.contains(&own)).nth(1);
        match message {
            Some(m) if !status.success() && failed > 0 => {
                caught += 1;
                println!("caught by {failed} of {tests} tests in {:.1} s: {m}", took.as_secs_f64());
            }
            _ => {
                print!("{out}");
                println!("NOT caught ({status}, {failed} of {tests} tests failed, none at {LOOM_MODEL_FILE})");
            }
        }
    }

    println!("\nmutants_caught={caught} of {}", MUTANTS.len());
    println!("xtask loom: {:.0} s", start.elapsed().as_secs_f64());
    if caught < MUTANTS.len() {
        return fail(format!("the loom model missed {} of {} seqlock mutants", MUTANTS.len() - caught, MUTANTS.len()));
    }
    Ok(())
}
