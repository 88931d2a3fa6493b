//! Build and test commands: `cargo xtask test | demo-qemu | bench-target | panic-check | loom`.
//!
//! Every step prints the command it runs and stops the whole run on the first failure.
//! Nothing is skipped silently: a missing tool is installed (as root with apt) or the run
//! fails with the exact command that installs it. The one exception is Chromium outside CI
//! without root: the lab's page checks then print SKIPPED, and this says so first.
//!
//! Every program these commands run under QEMU has its expected console output checked in
//! beside its source, as `NAME.out` next to `NAME.rs` (defmt's `test-snapshot` practice):
//! the pair is found, reviewed and renamed together, and the diff of a change to a program
//! shows the change to its output in the same folder. After a run, the output is compared
//! line by line and the first differing line fails the step; `--overwrite` (on `test`,
//! `demo-qemu` and `bench-target`) re-records the files instead. The benchmark's figures
//! are measurements, judged by `budgets.txt`, not behaviour: [`normalise`] masks them, the
//! one rule by which a checked output differs from the printed one. The programs that are
//! only linked (`panic_check`, `size_baseline`) print nothing worth a file: their result is
//! the link and the size.

mod figures;
mod host_tests;
mod loom_model;
mod oracle;
mod snapshot;
mod tools;
mod trace;

use figures::*;
use loom_model::*;
use oracle::oracle;
use snapshot::*;
use tools::*;

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{exit, Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};
use std::{env, fmt, thread};

const TARGET: &str = "thumbv7em-none-eabihf";
/// The package whose examples are the QEMU programs (examples/).
const CORE: &str = "qfa-thermal";
/// The features the measuring examples need (`bench` requires both). Every target example
/// but the demo builds with them, so panic_check links the same library the benchmark
/// measures.
const EXAMPLE_FEATURES: &str = "fixtures,bench-internals";
/// The firmware images of the STM32F405 (built, not run: no hardware in CI), each its own
/// workspace: (directory from the repository root, binary, the prefix of its printed
/// figures). The board example, and the same wiring as an RTIC 2 app and as an embassy app.
const FIRMWARES: [(&str, &str, &str); 3] = [
    ("boards/stm32f405", "qfa-board-stm32f405", "board"),
    ("boards/stm32f405-rtic", "qfa-app-rtic-stm32f405", "app_rtic"),
    ("boards/stm32f405-embassy", "qfa-app-embassy-stm32f405", "app_embassy"),
];
/// The board example's workspace: the one with host tests.
const BOARD_DIR: &str = FIRMWARES[0].0;
/// The root crate's example that runs under QEMU (examples/qemu_demo.rs).
const DEMO_EXAMPLE: &str = "qemu_demo";
const QEMU: &str = "qemu-system-arm";
const QEMU_INSTALL: &str = "apt-get update && apt-get install -y qemu-system-arm";
const SIZE_INSTALL: &str = "apt-get update && apt-get install -y binutils-arm-none-eabi";
/// The headless browser the lab's `report.html` tests open each page in.
const CHROMIUM: &str = "chromium";
const CHROMIUM_INSTALL: &str = "apt-get update && apt-get install -y chromium";
/// Target examples built by `test` (panic_check is built by its own step, the demo by its own).
const TARGET_EXAMPLES: [&str; 3] = ["qemu_vectors", "bench", "size_baseline"];
const QEMU_TIMEOUT: Duration = Duration::from_secs(300);
/// The example whose link proves that no panic is reachable from the core.
const PANIC_CHECK: &str = "panic_check";
/// The recommended link (a sensor per axis, a `&'static Table`), sized; its link is a panic
/// check of that configuration too.
const STATIC_TABLE_LINK: &str = "static_table_link";
/// The undefined symbol the size programs' panic handlers call.
const PANIC_SYMBOL: &str = "qfa_panic_is_reachable_from_the_core";
/// The seqlock's loom model: the test-name filter of its tests in qfa-thermal's unit tests.
const LOOM_MODEL: &str = "compensator::seqlock::model::";
/// Where a failure of the model's own assertions panics (not loom, not the harness).
const LOOM_MODEL_FILE: &str = "src/compensator/seqlock.rs";
/// The seqlock's mutants (`--cfg qfa_mutant="NAME"`, in src/compensator/seqlock.rs): each
/// must make the loom model fail.
const MUTANTS: [(&str, &str); 6] = [
    ("writer_no_release_fence", "writer: no Release fence after the odd sequence store"),
    ("writer_relaxed_even_store", "writer: the even sequence stored Relaxed, not Release"),
    ("reader_relaxed_seq_load", "reader: the first sequence load Relaxed, not Acquire"),
    ("reader_no_acquire_fence", "reader: no Acquire fence before the re-check"),
    ("reader_no_recheck", "reader: no re-check of the sequence"),
    ("reader_accepts_odd", "reader: copies under an odd sequence"),
];

const USAGE: &str = "usage: cargo xtask <command>

commands:
  test [--overwrite]
                the host half: rustfmt, clippy (host, -D warnings), host tests and doctests
                (the lab's report.html opened in headless Chromium), rustdoc -D warnings;
                alongside it, in a second process whose output is printed at the end, the
                target half (test-target)
  test-target [--overwrite]
                the target half alone: clippy for the target, the seqlock's loom model,
                target build, reference vectors, benchmark and demo example on QEMU
                mps2-an386 (each output checked against its .out file), the figures against
                their budgets, panic-check, the STM32F405 board (its own workspace: host
                tests and firmware build), publish dry run
  demo-qemu [--overwrite]
                run the demo example (examples/qemu_demo.rs) on QEMU, output checked against
                examples/qemu_demo.out
  bench-target [--overwrite]
                instruction counts (QEMU -icount shift=0, SysTick), flash/RAM of the core and
                of the STM32F405 board example; the figures against xtask/budgets.txt
  panic-check   link-time proof that no panic is reachable from the core's paths
  trace-target  where the paths' instructions go: examples/trace_paths.rs under QEMU one
                instruction at a time, per function and per call (needs llvm-nm)
  loom          the seqlock's loom model (clippy and tests under --cfg loom), then each seqlock
                mutant, which the model must fail: prints mutants_caught=N of M
  oracle [--histories N] [--seed S] [--mutants]
                the firmware against its f64 oracle over N random field histories (default
                2 000), release: prints silent_wrong_cycles=… cycles=… histories=…; with
                --mutants, each compensator mutant must make it fail: mutants_caught=K of M
  experiment NAME [ARGS]
                a lab study that asserts nothing (lab/examples/NAME.rs: nav_deadband,
                nav_branches [tally]), in release, printing its figures

  --overwrite   re-record the expected output (.out) of each QEMU program the command runs,
                instead of comparing with it";

/// A failed step: what failed, and why.
struct Failure(String);

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

type Result<T = ()> = std::result::Result<T, Failure>;

fn fail<T>(msg: impl Into<String>) -> Result<T> {
    Err(Failure(msg.into()))
}

fn main() {
    let args: Vec<String> = env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some(command @ "test") => overwrite_flag(command, &args[1..]).and_then(test),
        Some(command @ "test-target") => overwrite_flag(command, &args[1..]).and_then(test_target),
        Some(command @ "demo-qemu") => overwrite_flag(command, &args[1..]).and_then(demo_qemu),
        Some(command @ "bench-target") => overwrite_flag(command, &args[1..]).and_then(bench_target),
        Some("panic-check") => panic_check(),
        Some("trace-target") => trace::trace_target(),
        Some("loom") => loom(),
        Some("oracle") => oracle(&args[1..]),
        Some("experiment") => experiment(&args[1..]),
        Some("-h" | "--help" | "help") => {
            println!("{USAGE}");
            Ok(())
        }
        _ => {
            eprintln!("{USAGE}");
            exit(2);
        }
    };
    if let Err(e) = result {
        eprintln!("\nxtask: FAILED: {e}");
        exit(1);
    }
}

/// `cargo xtask experiment NAME [ARGS]`: run the lab's example NAME in release.
fn experiment(args: &[String]) -> Result {
    let Some(name) = args.first() else {
        return fail("experiment: which one? (the files in lab/examples/: nav_deadband, nav_branches, batch_bench, selection_study, static_table_study)");
    };
    let mut c = cargo();
    c.args(["run", "--release", "-p", "qfa-lab", "--example", name, "--"]).args(&args[1..]);
    run(c)
}

fn root() -> PathBuf {
    // xtask/ sits in the workspace root.
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

fn cargo() -> Command {
    let mut c = Command::new(env::var_os("CARGO").unwrap_or_else(|| "cargo".into()));
    c.current_dir(root());
    c
}

/// Cargo in the board example's own workspace (see [`firmware_cargo`]).
fn board_cargo(args: &[&str]) -> Result<Command> {
    firmware_cargo(BOARD_DIR, args)
}

/// Cargo in a firmware's own workspace: run from its directory, so its
/// `.cargo/config.toml` and `memory.x` apply, with the repository's target directory
/// (shared build cache, and the ELF where the size step looks for it).
fn firmware_cargo(dir: &str, args: &[&str]) -> Result<Command> {
    let target = target_dir()?;
    let mut c = cargo();
    c.current_dir(root().join(dir));
    let (sub, rest) = args.split_first().map_or((None, args), |(s, r)| (Some(s), r));
    c.args(sub).arg("--target-dir").arg(target).args(rest);
    Ok(c)
}

/// The command line, with the variables it sets in front (`RUSTFLAGS="--cfg loom" cargo ...`).
fn show(c: &Command) -> String {
    let mut s = String::new();
    for (k, v) in c.get_envs() {
        if let Some(v) = v {
            let v = v.to_string_lossy();
            let v = if v.contains(' ') { format!("\"{v}\"") } else { v.into_owned() };
            s.push_str(&format!("{}={v} ", k.to_string_lossy()));
        }
    }
    s.push_str(&c.get_program().to_string_lossy());
    for a in c.get_args() {
        s.push(' ');
        s.push_str(&a.to_string_lossy());
    }
    s
}

fn step(title: &str) {
    finish_step();
    if let Ok(mut t) = STEP_TIMES.lock() {
        t.push(StepTime { title: title.to_string(), start: Instant::now(), cpu_start: children_cpu(), took: None });
    }
    println!("\n==> {title}");
}

/// One step's title, start and wall and CPU time: where a run's minutes go.
struct StepTime {
    title: String,
    start: Instant,
    cpu_start: Option<f64>,
    /// Wall time, and the CPU seconds its commands used (where /proc says).
    took: Option<(Duration, Option<f64>)>,
}

/// Every step so far, printed at the end of a run.
static STEP_TIMES: std::sync::Mutex<Vec<StepTime>> = std::sync::Mutex::new(Vec::new());

/// User plus system CPU seconds of this process's finished, waited-for children (fields 16
/// and 17 of `/proc/self/stat`, in clock ticks of 1/100 s, the value Linux reports on every
/// architecture it runs CI on); `None` off Linux. On 2 cores a run is bound by its CPU
/// seconds, not by any one step's wall time, so this is the figure to cut.
fn children_cpu() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The command name (field 2) may hold spaces; the fields after it start at field 3.
    let after_name = &stat[stat.rfind(')')? + 1..];
    let fields: Vec<&str> = after_name.split_whitespace().collect();
    let ticks = |i: usize| fields.get(i - 3)?.parse::<f64>().ok();
    Some((ticks(16)? + ticks(17)?) / 100.0)
}

fn finish_step() {
    if let Ok(mut t) = STEP_TIMES.lock() {
        if let Some(last) = t.last_mut().filter(|l| l.took.is_none()) {
            let cpu = children_cpu().zip(last.cpu_start).map(|(now, then)| now - then);
            last.took = Some((last.start.elapsed(), cpu));
        }
    }
}

/// The steps' wall and CPU times, longest first, and their sums.
fn print_step_times() {
    finish_step();
    let Ok(mut t) = STEP_TIMES.lock() else { return };
    t.sort_by_key(|s| std::cmp::Reverse(s.took.map(|(wall, _)| wall)));
    let wall: Duration = t.iter().filter_map(|s| s.took).map(|(wall, _)| wall).sum();
    let cpu: f64 = t.iter().filter_map(|s| s.took?.1).sum();
    println!("\nwall and CPU time by step (total {:.0} s wall, {cpu:.0} CPU-s):", wall.as_secs_f64());
    for step in t.iter() {
        let title: String = step.title.chars().take(90).collect();
        let (wall, cpu) = step.took.unwrap_or_default();
        let cpu = cpu.map_or("   ?".to_string(), |c| format!("{c:>4.0}"));
        println!("  {:>6.0} s  {cpu} CPU-s  {title}", wall.as_secs_f64());
    }
}

/// Run `c` with inherited output; fail unless it exits 0.
fn run(mut c: Command) -> Result {
    let line = show(&c);
    println!("$ {line}");
    match c.status() {
        Ok(s) if s.success() => Ok(()),
        Ok(s) => fail(format!("`{line}` exited with {s}")),
        Err(e) => fail(format!("`{line}` could not start: {e}")),
    }
}

/// Run `c` and capture stdout and stderr (for commands whose output is parsed).
fn capture(mut c: Command) -> Result<(ExitStatus, String, String)> {
    let line = show(&c);
    match c.output() {
        Ok(o) => Ok((
            o.status,
            String::from_utf8_lossy(&o.stdout).into_owned(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )),
        Err(e) => fail(format!("`{line}` could not start: {e}")),
    }
}

/// Cargo's target directory (honours CARGO_TARGET_DIR and config), from `cargo metadata`.
fn target_dir() -> Result<PathBuf> {
    let mut c = cargo();
    c.args(["metadata", "--format-version", "1", "--no-deps"]);
    let (status, out, err) = capture(c)?;
    if !status.success() {
        return fail(format!("cargo metadata failed: {err}"));
    }
    let key = "\"target_directory\":\"";
    let Some(start) = out.find(key).map(|i| i + key.len()) else {
        return fail("cargo metadata printed no target_directory");
    };
    let Some(len) = out[start..].find('"') else {
        return fail("cargo metadata: unterminated target_directory");
    };
    Ok(PathBuf::from(out[start..start + len].replace("\\\\", "\\")))
}

/// The release ELF of one of the core's examples.
fn example_elf(example: &str) -> Result<PathBuf> {
    Ok(target_dir()?.join(TARGET).join("release").join("examples").join(example))
}

/// The build of one of the core's target examples: release, LTO, the measuring features,
/// and the example's own crate at opt-level 3. The examples belong to the core's package, so
/// its profile line (`opt-level = "s"` for qfa-thermal, Cargo.toml) reaches them too; an
/// application is its own crate, built at the release level, and the figures measure that
/// (at "s" the fast path took 53 instructions instead of 28). `cargo rustc` passes the flag
/// to the example alone: the library keeps the profile's level.
fn example_build(example: &str) -> Command {
    let mut c = cargo();
    c.args(["rustc", "-p", CORE, "--release", "--target", TARGET, "--features", EXAMPLE_FEATURES]);
    c.args(["--example", example, "--", "-C", "opt-level=3"]);
    c
}

/// Build each of the core's target examples (see [`example_build`]).
fn build_examples(examples: &[&str]) -> Result {
    examples.iter().try_for_each(|e| run(example_build(e)))
}

fn qemu(kernel: &Path, icount: bool) -> Command {
    let mut c = Command::new(QEMU);
    c.args(["-machine", "mps2-an386", "-cpu", "cortex-m4", "-nographic"]);
    c.args(["-semihosting-config", "enable=on,target=native"]);
    if icount {
        c.args(["-icount", "shift=0"]);
    }
    c.arg("-kernel").arg(kernel);
    c
}

fn kill_on_timeout(child: &mut Child, line: &str) -> Result<ExitStatus> {
    let deadline = Instant::now() + QEMU_TIMEOUT;
    loop {
        match child.try_wait() {
            Ok(Some(s)) => return Ok(s),
            Ok(None) if Instant::now() < deadline => thread::sleep(Duration::from_millis(20)),
            Ok(None) => {
                let _ = child.kill();
                let _ = child.wait();
                return fail(format!("`{line}` timed out after {} s (killed)", QEMU_TIMEOUT.as_secs()));
            }
            Err(e) => return fail(format!("waiting for `{line}`: {e}")),
        }
    }
}

/// Run a firmware under QEMU with a timeout, echoing and returning its stdout.
fn run_qemu(kernel: &Path, icount: bool) -> Result<(ExitStatus, String)> {
    ensure_qemu()?;
    let mut c = qemu(kernel, icount);
    let line = show(&c);
    println!("$ {line}");
    let mut child = c
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .map_err(|e| Failure(format!("`{line}` could not start: {e}")))?;
    let Some(stdout) = child.stdout.take() else {
        return fail("no stdout pipe");
    };
    let reader = thread::spawn(move || {
        let mut all = String::new();
        for l in BufReader::new(stdout).lines().map_while(std::result::Result::ok) {
            println!("{l}");
            all.push_str(&l);
            all.push('\n');
        }
        all
    });
    let status = kill_on_timeout(&mut child, &line)?;
    let out = reader.join().unwrap_or_default();
    Ok((status, out))
}

/// `--overwrite` or nothing: the one option of the commands that run QEMU programs.
fn overwrite_flag(command: &str, args: &[String]) -> Result<bool> {
    match args {
        [] => Ok(false),
        [a] if a == "--overwrite" => Ok(true),
        _ => fail(format!("{command}: unexpected arguments {args:?} (its one option is --overwrite)")),
    }
}

/// `cargo xtask test`: the host half here, the target half ([`test_target`]) in a second
/// process alongside it. The two share the 2 cores where one half waits (the host tests'
/// run, QEMU, Chromium) and Cargo's lock on the target directory where both build; the
/// target half's output is printed after the host half's, so neither interleaves.
fn test(overwrite: bool) -> Result {
    ensure_target()?;
    let target_half = Alongside::start("test-target", overwrite)?;

    step("rustfmt --check (rustfmt.toml: 120 columns), workspace, board and apps");
    let mut c = cargo();
    c.args(["fmt", "--all", "--check"]);
    run(c)?;
    for (dir, _, _) in FIRMWARES {
        let mut c = cargo();
        c.current_dir(root().join(dir)).args(["fmt", "--all", "--check"]);
        run(c)?;
    }

    step("clippy, host (workspace, board and apps, all targets)");
    let mut c = cargo();
    c.args(["clippy", "--workspace", "--all-targets", "--", "-D", "warnings"]);
    run(c)?;
    for (dir, _, _) in FIRMWARES {
        run(firmware_cargo(dir, &["clippy", "--all-targets", "--", "-D", "warnings"])?)?;
    }

    step("host tests and doctests (default members; the README's example is a doctest)");
    ensure_chromium()?;
    host_tests::run_all(thread::available_parallelism().map_or(2, std::num::NonZero::get))?;

    step("rustdoc of the crate, the generator and the lab's crates, -D warnings");
    let mut c = cargo();
    c.arg("doc").env("RUSTDOCFLAGS", "-D warnings");
    // The published crate, the generator and every lab crate (a new lab crate goes here too).
    let packages =
        "qfa-thermal qfa-rng qfa-report qfa-log qfa-sim qfa-calibrate qfa-lint qfa-discover qfa-batch qfa-autopilot qfa-nav qfa-lab";
    for package in packages.split(' ') {
        c.args(["-p", package]);
    }
    c.arg("--no-deps");
    run(c)?;

    // The target half is this process's child, so its CPU seconds land in this step when
    // it is waited for: the host half's total includes them.
    step("the target half (started alongside the host steps): waiting for it, its CPU-s counted here");
    let target_log = target_half.finish();
    print_step_times();
    print!("{}", target_log?);
    println!("\nxtask test: all steps passed");
    Ok(())
}

/// The target half of `test`: clippy for the target, the loom model, the QEMU programs
/// against their `.out` files, the figures against their budgets, panic-check, the board,
/// the publish dry run.
fn test_target(overwrite: bool) -> Result {
    ensure_target()?;

    step(&format!("clippy, {TARGET} (core and its examples, board example and apps)"));
    let mut c = cargo();
    // With the measuring features, or the benchmark (required-features) is skipped unseen.
    c.args(["clippy", "-p", CORE, "--lib", "--examples", "--features", EXAMPLE_FEATURES, "--target", TARGET]);
    c.args(["--", "-D", "warnings"]);
    run(c)?;
    for (dir, _, _) in FIRMWARES {
        run(firmware_cargo(dir, &["clippy", "--target", TARGET, "--", "-D", "warnings"])?)?;
    }

    step("loom model of the seqlock (clean; `cargo xtask loom` adds the mutants)");
    loom_model_passes(&target_dir()?.join("loom"))?;

    step(&format!("target build, release ({})", TARGET_EXAMPLES.join(", ")));
    build_examples(&TARGET_EXAMPLES)?;

    step("reference vectors on QEMU mps2-an386 (Cortex-M4F)");
    run_snapshot(&VECTORS_SNAPSHOT, &example_elf(VECTORS_SNAPSHOT.program)?, false, overwrite)?;

    // The benchmark's, the board's and the apps' figures against their budgets and the
    // docs (as `bench-target` does).
    let mut printed = measure_figures(overwrite)?;
    printed.push_str(&firmware_figures()?);
    check_figures(&printed)?;

    step(&format!("demo example ({DEMO_EXAMPLE}) on QEMU mps2-an386, the root memory.x"));
    run_demo_example(overwrite)?;

    panic_check()?;

    step("board example (STM32F405, its own workspace): host tests (its firmware was built above)");
    run(board_cargo(&["test"])?)?;

    step("publish dry run of qfa-thermal (needs the crates.io index)");
    let mut c = cargo();
    c.args(["publish", "--dry-run", "-p", "qfa-thermal", "--allow-dirty"]);
    run(c)?;

    print_step_times();
    println!("\nxtask test-target: all steps passed");
    Ok(())
}

/// An xtask command running in a second process, its output into a file under the target
/// directory; killed if dropped before [`Alongside::finish`] (the host half failed).
struct Alongside {
    child: Child,
    log: PathBuf,
    started: Instant,
}

impl Alongside {
    fn start(command: &str, overwrite: bool) -> Result<Self> {
        let exe = env::current_exe().map_err(|e| Failure(format!("xtask's own path: {e}")))?;
        let mut c = Command::new(exe);
        c.current_dir(root()).arg(command).args(overwrite.then_some("--overwrite"));
        Self::spawn(c, target_dir()?.join(format!("xtask-{command}.log")))
    }

    /// Start `c` with its stdout and stderr into `log`.
    fn spawn(mut c: Command, log: PathBuf) -> Result<Self> {
        let opened = std::fs::File::create(&log).and_then(|f| Ok((f.try_clone()?, f)));
        let Ok((out, err)) = opened else { return fail(format!("cannot write {}", log.display())) };
        c.stdout(out).stderr(err);
        println!("$ {}  (alongside; output in {}, printed at the end)", show(&c), log.display());
        match c.spawn() {
            Ok(child) => Ok(Self { child, log, started: Instant::now() }),
            Err(e) => fail(format!("`{}` could not start: {e}", show(&c))),
        }
    }

    /// Wait for it; its output, headed by its wall time, or a failure naming its log.
    fn finish(mut self) -> Result<String> {
        let status = self.child.wait().map_err(|e| Failure(format!("waiting for {}: {e}", self.log.display())));
        let took = self.started.elapsed().as_secs_f64();
        let out = std::fs::read_to_string(&self.log).unwrap_or_default();
        let text = format!("\n==> the target half's output ({took:.0} s wall, alongside the host steps)\n{out}");
        match status? {
            s if s.success() => Ok(text),
            s => {
                print!("{text}");
                fail(format!("the target half exited with {s} (its output is above, and in {})", self.log.display()))
            }
        }
    }
}

impl Drop for Alongside {
    fn drop(&mut self) {
        // A no-op once `finish` has waited; otherwise the host half failed first.
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = self.child.kill();
            let _ = self.child.wait();
            eprintln!("(the target half was stopped; its output so far is in {})", self.log.display());
        }
    }
}

fn demo_qemu(overwrite: bool) -> Result {
    ensure_target()?;
    step(&format!("demo example ({DEMO_EXAMPLE})"));
    run_demo_example(overwrite)
}

/// Build the root crate's demo example for the target and run it under QEMU: it must exit 0
/// and print its expected output.
fn run_demo_example(overwrite: bool) -> Result {
    let mut c = cargo();
    c.args(["build", "-p", CORE, "--release", "--target", TARGET, "--features", "fixtures", "--example", DEMO_EXAMPLE]);
    run(c)?;
    run_snapshot(&DEMO_SNAPSHOT, &example_elf(DEMO_EXAMPLE)?, false, overwrite).map(drop)
}

/// Build panic_check; on a link failure, return the linker's lines about the panic symbol.
fn build_panic_check() -> Result {
    build_panic_free(PANIC_CHECK)
}

/// Build `program`, whose panic handler calls [`PANIC_SYMBOL`]; on a link failure, return the
/// linker's lines about that symbol.
fn build_panic_free(program: &str) -> Result {
    let mut c = example_build(program);
    let line = show(&c);
    println!("$ {line}");
    let mut child = c
        .stdout(Stdio::inherit())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| Failure(format!("`{line}` could not start: {e}")))?;
    let mut err = String::new();
    if let Some(mut s) = child.stderr.take() {
        let _ = s.read_to_string(&mut err);
    }
    let status = child.wait().map_err(|e| Failure(format!("waiting for `{line}`: {e}")))?;
    if status.success() {
        return Ok(());
    }
    eprintln!("{err}");
    if err.contains(PANIC_SYMBOL) {
        let refs: Vec<&str> = err.lines().filter(|l| l.contains(PANIC_SYMBOL) || l.contains(">>>")).collect();
        fail(format!(
            "{program}: a panic is reachable from the core (its handler references the undefined \
             `{PANIC_SYMBOL}`):\n{}\nTo find it: give {program}'s handler a `loop {{}}` body, build, \
             and look for the calls to core::panicking::* in `llvm-objdump -d -l` of the ELF (the \
             source lines are in the debug info).",
            refs.join("\n")
        ))
    } else {
        fail(format!("`{line}` failed with {status} (not the panic symbol: see the output above)"))
    }
}

fn panic_check() -> Result {
    ensure_target()?;
    step("panic-check: link examples/panic_check.rs with an undefined panic handler (release, LTO)");
    build_panic_check()?;
    println!(
        "panic-check: OK, no panic reachable from Compensator::load_table, on_scratchpad, on_raw, \
         cycle, cycle_counters (all inputs through black_box)"
    );
    Ok(())
}

#[cfg(test)]
mod tests;
