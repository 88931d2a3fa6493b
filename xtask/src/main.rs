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

mod host_tests;

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
/// The STM32F405 board example (built, not run: no hardware in CI), its own workspace.
const BOARD: &str = "qfa-board-stm32f405";
/// The board's workspace, relative to the repository root.
const BOARD_DIR: &str = "boards/stm32f405";
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
        return fail("experiment: which one? (the files in lab/examples/: nav_deadband, nav_branches)");
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

/// Cargo in the board's own workspace: run from its directory, so its `.cargo/config.toml`
/// and `memory.x` apply, with the repository's target directory (shared build cache, and
/// the ELF where `elf` looks for it).
fn board_cargo(args: &[&str]) -> Result<Command> {
    let target = target_dir()?;
    let mut c = cargo();
    c.current_dir(root().join(BOARD_DIR));
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

fn found(program: &str, arg: &str) -> bool {
    Command::new(program).arg(arg).stdout(Stdio::null()).stderr(Stdio::null()).status().is_ok_and(|s| s.success())
}

fn is_root_with_apt() -> bool {
    let uid = Command::new("id").arg("-u").output().ok().map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned());
    uid.as_deref() == Some("0") && found("apt-get", "--version")
}

/// Run an apt install line as root, or fail with the exact command to run.
fn apt_install(what: &str, line: &str) -> Result {
    if !is_root_with_apt() {
        return fail(format!("{what} is missing; install it with:\n    {line}"));
    }
    println!("{what} is missing: installing it (root, apt available)");
    let mut c = Command::new("sh");
    c.args(["-c", line]).env("DEBIAN_FRONTEND", "noninteractive");
    run(c)
}

fn ensure_target() -> Result {
    step(&format!("rustup target {TARGET}"));
    let mut c = Command::new("rustup");
    c.current_dir(root()).args(["target", "list", "--installed"]);
    let (status, out, err) = capture(c)?;
    if !status.success() {
        return fail(format!("`rustup target list --installed` failed: {err}"));
    }
    if out.lines().any(|l| l.trim() == TARGET) {
        println!("{TARGET} is installed");
        return Ok(());
    }
    let mut c = Command::new("rustup");
    c.current_dir(root()).args(["target", "add", TARGET]);
    run(c)
}

fn ensure_qemu() -> Result {
    if found(QEMU, "--version") {
        return Ok(());
    }
    apt_install(QEMU, QEMU_INSTALL)?;
    if found(QEMU, "--version") {
        Ok(())
    } else {
        fail(format!("{QEMU} still missing after `{QEMU_INSTALL}`"))
    }
}

/// Chromium for the lab's page tests (`lab/tests/report_html.rs`): installed as root with
/// apt; otherwise missing is a failure under `CI=true`, and elsewhere those tests print
/// SKIPPED (said here too, loudly).
fn ensure_chromium() -> Result {
    if found(CHROMIUM, "--version") || env::var_os("QFA_CHROMIUM").is_some() {
        return Ok(());
    }
    if is_root_with_apt() || env::var("CI").as_deref() == Ok("true") {
        apt_install(CHROMIUM, CHROMIUM_INSTALL)?;
        return if found(CHROMIUM, "--version") {
            Ok(())
        } else {
            fail(format!("{CHROMIUM} still missing after `{CHROMIUM_INSTALL}`"))
        };
    }
    println!(
        "\n*** {CHROMIUM} is missing: the lab's report.html browser checks will print SKIPPED; install it with:\n    \
         {CHROMIUM_INSTALL} ***\n"
    );
    Ok(())
}

/// A size tool printing Berkeley format: llvm-size, arm-none-eabi-size, or rustup's llvm-tools.
fn ensure_size_tool() -> Result<PathBuf> {
    for t in ["llvm-size", "arm-none-eabi-size"] {
        if found(t, "--version") {
            return Ok(PathBuf::from(t));
        }
    }
    let llvm_tools = || -> Option<PathBuf> {
        let o = Command::new("rustc").current_dir(root()).args(["--print", "sysroot"]).output().ok()?;
        let sysroot = PathBuf::from(String::from_utf8_lossy(&o.stdout).trim());
        let o = Command::new("rustc").current_dir(root()).arg("-vV").output().ok()?;
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        let host = text.lines().find_map(|l| l.strip_prefix("host: "))?.trim().to_owned();
        let p = sysroot.join("lib/rustlib").join(host).join("bin/llvm-size");
        p.exists().then_some(p)
    };
    if let Some(p) = llvm_tools() {
        return Ok(p);
    }
    apt_install("a size tool (llvm-size or arm-none-eabi-size)", SIZE_INSTALL)?;
    if found("arm-none-eabi-size", "--version") {
        Ok(PathBuf::from("arm-none-eabi-size"))
    } else {
        fail(format!("arm-none-eabi-size still missing after `{SIZE_INSTALL}`"))
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

/// What a program's output holds besides its behaviour.
#[derive(Clone, Copy)]
enum Figures {
    /// Nothing: every line is compared as printed.
    None,
    /// Measurements in `name=value` lines, masked by [`normalise`].
    Measured,
}

/// A QEMU program and the file its console output is checked against.
struct Snapshot {
    /// The ELF's name: the binary or example.
    program: &'static str,
    /// The expected output, relative to the repository root: beside the program's source.
    expected: &'static str,
    figures: Figures,
    /// The single-program command that re-records it with `--overwrite` (`test` re-records all).
    command: &'static str,
}

const VECTORS_SNAPSHOT: Snapshot = Snapshot {
    program: "qemu_vectors",
    expected: "examples/qemu_vectors.out",
    figures: Figures::None,
    command: "test",
};
const BENCH_SNAPSHOT: Snapshot =
    Snapshot { program: "bench", expected: "examples/bench.out", figures: Figures::Measured, command: "bench-target" };
const DEMO_SNAPSHOT: Snapshot = Snapshot {
    program: DEMO_EXAMPLE,
    expected: "examples/qemu_demo.out",
    figures: Figures::None,
    command: "demo-qemu",
};

/// What a measured figure reads as in an expected file.
const MEASURED: &str = "<measured>";

/// The one rule by which a checked output differs from the printed one. With
/// [`Figures::Measured`], the value of each `name=value` line that is a decimal number
/// becomes [`MEASURED`]: instruction counts, sizes and errors are deterministic under
/// `-icount`, but move with any change to the library or the compiler, and
/// `xtask/budgets.txt` and docs/measurements.md are where they are judged and recorded;
/// pinned here too, every such change would be re-recorded by reflex. What stays checked:
/// which figures are printed, in which order, and the non-decimal values (the status words
/// in hexadecimal). Lines end in `\n`.
fn normalise(output: &str, figures: Figures) -> String {
    let mut text = String::new();
    for line in output.lines() {
        match (figures, line.split_once('=')) {
            (Figures::Measured, Some((name, value))) if value.trim().parse::<f64>().is_ok() => {
                text.push_str(&format!("{name}={MEASURED}"));
            }
            _ => text.push_str(line),
        }
        text.push('\n');
    }
    text
}

/// The first line where `printed` differs from `expected`, as a diff-style message (one
/// line of context, `-` expected, `+` printed); `None` when they are equal line by line.
fn first_difference(expected: &str, printed: &str) -> Option<String> {
    let (want, got): (Vec<&str>, Vec<&str>) = (expected.lines().collect(), printed.lines().collect());
    let differs = |i: &usize| want.get(*i) != got.get(*i);
    let total = want.len().max(got.len());
    let first = (0..total).find(differs)?;
    let shown = |lines: &[&str]| {
        lines.get(first).map_or_else(|| "(none: the text ends before this line)".to_string(), |l| (*l).to_string())
    };
    let mut message = format!(
        "first difference at line {} ({} of {total} lines differ; - expected, + printed):\n",
        first + 1,
        (0..total).filter(differs).count()
    );
    if let Some(before) = first.checked_sub(1).and_then(|i| want.get(i)) {
        message.push_str(&format!("  {before}\n"));
    }
    message.push_str(&format!("- {}\n+ {}", shown(&want), shown(&got)));
    Some(message)
}

/// Compare a run's output with the program's expected file, or re-record the file.
fn check_snapshot(snapshot: &Snapshot, output: &str, overwrite: bool) -> Result {
    let path = root().join(snapshot.expected);
    let checked = normalise(output, snapshot.figures);
    if overwrite {
        std::fs::write(&path, &checked).map_err(|e| Failure(format!("{}: {e}", snapshot.expected)))?;
        println!("{}: recorded {} ({} lines)", snapshot.program, snapshot.expected, checked.lines().count());
        return Ok(());
    }
    let rerecord = format!("cargo xtask {} --overwrite", snapshot.command);
    let expected = std::fs::read_to_string(&path)
        .map_err(|e| Failure(format!("{}: {e} (record it with `{rerecord}`)", snapshot.expected)))?;
    match first_difference(&expected, &checked) {
        None => {
            println!("{}: output matches {} ({} lines)", snapshot.program, snapshot.expected, checked.lines().count());
            Ok(())
        }
        Some(diff) => fail(format!(
            "{}: output differs from {}; {diff}\nIf the change is intended, re-record with `{rerecord}` and \
             review the diff.",
            snapshot.program, snapshot.expected
        )),
    }
}

/// Run `kernel` under QEMU; it must exit 0 and print its expected output. Returns the output.
fn run_snapshot(snapshot: &Snapshot, kernel: &Path, icount: bool, overwrite: bool) -> Result<String> {
    let (status, out) = run_qemu(kernel, icount)?;
    if !status.success() {
        return fail(format!("{} exited with {status} (its output is above)", snapshot.program));
    }
    check_snapshot(snapshot, &out, overwrite)?;
    Ok(out)
}

/// `cargo xtask test`: the host half here, the target half ([`test_target`]) in a second
/// process alongside it. The two share the 2 cores where one half waits (the host tests'
/// run, QEMU, Chromium) and Cargo's lock on the target directory where both build; the
/// target half's output is printed after the host half's, so neither interleaves.
fn test(overwrite: bool) -> Result {
    ensure_target()?;
    let target_half = Alongside::start("test-target", overwrite)?;

    step("rustfmt --check (rustfmt.toml: 120 columns), workspace and board");
    let mut c = cargo();
    c.args(["fmt", "--all", "--check"]);
    run(c)?;
    let mut c = cargo();
    c.current_dir(root().join(BOARD_DIR)).args(["fmt", "--all", "--check"]);
    run(c)?;

    step("clippy, host (workspace and board, all targets)");
    let mut c = cargo();
    c.args(["clippy", "--workspace", "--all-targets", "--", "-D", "warnings"]);
    run(c)?;
    run(board_cargo(&["clippy", "--all-targets", "--", "-D", "warnings"])?)?;

    step("host tests and doctests (default members; the README's example is a doctest)");
    ensure_chromium()?;
    host_tests::run_all(thread::available_parallelism().map_or(2, std::num::NonZero::get))?;

    step("rustdoc of the crate, the generator and the lab's crates, -D warnings");
    let mut c = cargo();
    c.arg("doc").env("RUSTDOCFLAGS", "-D warnings");
    for package in ["qfa-thermal", "qfa-rng", "qfa-report", "qfa-log", "qfa-sim", "qfa-calibrate", "qfa-nav", "qfa-lab"]
    {
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

    step(&format!("clippy, {TARGET} (core and its examples, board example)"));
    let mut c = cargo();
    // With the measuring features, or the benchmark (required-features) is skipped unseen.
    c.args(["clippy", "-p", CORE, "--lib", "--examples", "--features", EXAMPLE_FEATURES, "--target", TARGET]);
    c.args(["--", "-D", "warnings"]);
    run(c)?;
    run(board_cargo(&["clippy", "--target", TARGET, "--", "-D", "warnings"])?)?;

    step("loom model of the seqlock (clean; `cargo xtask loom` adds the mutants)");
    loom_model_passes(&target_dir()?.join("loom"))?;

    step(&format!("target build, release ({})", TARGET_EXAMPLES.join(", ")));
    build_examples(&TARGET_EXAMPLES)?;

    step("reference vectors on QEMU mps2-an386 (Cortex-M4F)");
    run_snapshot(&VECTORS_SNAPSHOT, &example_elf(VECTORS_SNAPSHOT.program)?, false, overwrite)?;

    // The benchmark's figures against their budgets and the docs (as `bench-target` does).
    check_figures(&measure_figures(overwrite)?)?;

    step(&format!("demo example ({DEMO_EXAMPLE}) on QEMU mps2-an386, the root memory.x"));
    run_demo_example(overwrite)?;

    panic_check()?;

    step("board example (STM32F405, its own workspace): host tests, then the firmware build");
    run(board_cargo(&["test"])?)?;
    build_board()?;

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

fn build_board() -> Result {
    run(board_cargo(&["build", "--release", "--target", TARGET])?)
}

/// Berkeley `text data bss` of an ELF.
fn berkeley(tool: &Path, file: &Path) -> Result<(u64, u64, u64)> {
    let mut c = Command::new(tool);
    c.arg("-B").arg(file);
    let (status, out, err) = capture(c)?;
    if !status.success() {
        return fail(format!("{} {}: {err}", tool.display(), file.display()));
    }
    let nums: Vec<u64> =
        out.lines().nth(1).unwrap_or("").split_whitespace().take(3).filter_map(|w| w.parse().ok()).collect();
    match nums[..] {
        [t, d, b] => Ok((t, d, b)),
        _ => fail(format!("unexpected size output:\n{out}")),
    }
}

/// The budgets file (`name = limit` lines), relative to the repository root.
const BUDGETS: &str = "xtask/budgets.txt";

/// `name = limit` lines; `#` starts a comment.
fn parse_budgets(text: &str) -> Result<Vec<(String, u64)>> {
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let parsed = line.split_once('=').and_then(|(k, v)| Some((k.trim().to_string(), v.trim().parse().ok()?)));
        match parsed {
            Some(b) => out.push(b),
            None => return fail(format!("{BUDGETS}:{}: not `name = limit`: {line}", n + 1)),
        }
    }
    Ok(out)
}

/// Every budget against the `name=value` lines of `printed`: the lines over budget, or an
/// error for a budget whose figure was not printed (a budget nobody measures enforces nothing).
fn over_budget(budgets: &[(String, u64)], printed: &str) -> Result<Vec<String>> {
    let mut over = Vec::new();
    for (name, limit) in budgets {
        let value = printed.lines().find_map(|l| l.strip_prefix(&format!("{name}="))?.trim().parse::<f64>().ok());
        match value {
            Some(v) if v > *limit as f64 => over.push(format!("{name}={v} is over its budget {limit}")),
            Some(_) => {}
            None => return fail(format!("no {name}= figure was printed to check against its budget")),
        }
    }
    Ok(over)
}

/// The firmware's figures the docs state: (printed key, the README row that gives it).
/// docs/measurements.md gives each in its table's row for the key, as the first number of
/// the "measured" cell; the README, anywhere in the row's value cell. Both are checked against what the benchmark prints today.
const STATED_FIGURES: [(&str, &str); 7] = [
    ("fast_path_insns_3axis", "[fast path, 3 axes"),
    ("fast_path_insns_3axis_misalign", "[fast path, 3 axes"),
    ("slow_path_insns_sensor_per_axis", "[slow path, every slot on"),
    ("slow_path_insns_3axis_all_on", "[slow path, every slot on"),
    ("core_ram_bytes", "[RAM and flash of the core"),
    ("core_flash_bytes_static_table", "[RAM and flash of the core"),
    ("core_flash_bytes", "[RAM and flash of the core"),
];
const MEASUREMENTS: &str = "docs/measurements.md";

/// A printed figure as the docs write it: thousands grouped by a space, a zero fraction
/// dropped (`1980.5` → `1 980.5`, `16056` → `16 056`, `28.0` → `28`).
fn as_written(value: &str) -> String {
    let value = value.trim();
    let (int, frac) = value.split_once('.').unwrap_or((value, ""));
    let digits: Vec<char> = int.chars().collect();
    let mut out = String::new();
    for (i, c) in digits.iter().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(' ');
        }
        out.push(*c);
    }
    if !frac.trim_end_matches('0').is_empty() {
        out.push('.');
        out.push_str(frac);
    }
    out
}

/// Whether `text` holds `figure` as a whole number: not inside a longer one, whether that
/// continues with digits, a decimal point or a space-grouped digit group ("1 980.5").
fn holds_figure(text: &str, figure: &str) -> bool {
    let digit = |c: Option<char>| c.is_some_and(|c| c.is_ascii_digit());
    text.match_indices(figure).any(|(i, _)| {
        let mut back = text[..i].chars().rev();
        let (b1, b2) = (back.next(), back.next());
        let mut ahead = text[i + figure.len()..].chars();
        let (a1, a2) = (ahead.next(), ahead.next());
        let joined_before = digit(b1) || b1 == Some('.') || (b1 == Some(' ') && digit(b2));
        let joined_after = digit(a1) || ((a1 == Some('.') || a1 == Some(' ')) && digit(a2));
        !joined_before && !joined_after
    })
}

/// Each stated figure the README or docs/measurements.md gives differently from `printed`.
fn stated_disagreements(readme: &str, measurements: &str, printed: &str) -> Result<Vec<String>> {
    let mut out = Vec::new();
    for (key, row) in STATED_FIGURES {
        let Some(value) = printed.lines().find_map(|l| l.strip_prefix(&format!("{key}="))) else {
            return fail(format!("no {key}= figure was printed to check the docs against"));
        };
        let figure = as_written(value);
        // The row's value cell only: its label holds numbers too ("3 axes").
        let value_cell = |l: &str| l.trim().trim_end_matches('|').rsplit(" | ").next().unwrap_or("").to_string();
        match readme.lines().find(|l| l.starts_with(&format!("| {row}"))).map(value_cell) {
            Some(c) if holds_figure(&c, &figure) => {}
            Some(c) => out.push(format!("README.md gives {key} not as {figure}: `{c}`")),
            None => out.push(format!("README.md has no row `| {row}` for {key}")),
        }
        let cell = measurements.lines().find(|l| l.starts_with(&format!("| `{key}`"))).and_then(|l| {
            let cells: Vec<&str> = l.trim().trim_matches('|').split(" | ").collect();
            cells.len().checked_sub(2).map(|i| cells[i].trim().trim_start_matches("**").to_string())
        });
        match cell {
            Some(c) if c.starts_with(&figure) && holds_figure(&c, &figure) => {}
            Some(c) => out.push(format!("{MEASUREMENTS} gives {key} as `{c}`, printed {figure}")),
            None => out.push(format!("{MEASUREMENTS} has no table row for `{key}`")),
        }
    }
    Ok(out)
}

/// Run the benchmark and size the core's flash: the figures, as `key=value` lines.
fn measure_figures(overwrite: bool) -> Result<String> {
    let mut printed = String::new();
    step("benchmark example (examples/bench.rs), QEMU -icount shift=0");
    build_examples(&["bench", "size_baseline"])?;
    // The expected file pins which figures are printed; their values are judged below.
    printed.push_str(&run_snapshot(&BENCH_SNAPSHOT, &example_elf(BENCH_SNAPSHOT.program)?, true, overwrite)?);

    step("flash of the core: panic_check and static_table_link (core paths + runtime) minus size_baseline (runtime)");
    build_panic_check()?;
    build_panic_free(STATIC_TABLE_LINK)?;
    let tool = ensure_size_tool()?;
    let (ct, cd, cb) = berkeley(&tool, &example_elf(PANIC_CHECK)?)?;
    let (st, sd, sb) = berkeley(&tool, &example_elf(STATIC_TABLE_LINK)?)?;
    let (bt, bd, bb) = berkeley(&tool, &example_elf("size_baseline")?)?;
    println!(
        "panic_check: text={ct} data={cd} bss={cb}; static_table_link: text={st} data={sd} bss={sb}; \
         size_baseline: text={bt} data={bd} bss={bb}"
    );
    let core = format!(
        "core_flash_bytes={}\ncore_flash_bytes_static_table={}\ncore_static_ram_bytes={}\n",
        (ct + cd).saturating_sub(bt + bd),
        (st + sd).saturating_sub(bt + bd),
        (cd + cb).saturating_sub(bd + bb)
    );
    print!("{core}");
    printed.push_str(&core);
    Ok(printed)
}

/// Fail when a figure is over its budget or the docs state it differently.
fn check_figures(printed: &str) -> Result {
    let read = |p: &str| std::fs::read_to_string(root().join(p)).map_err(|e| Failure(format!("{p}: {e}")));
    let budgets = parse_budgets(&read(BUDGETS)?)?;
    step(&format!("budgets ({BUDGETS}) and the figures README.md and {MEASUREMENTS} state"));
    let mut wrong = over_budget(&budgets, printed)?;
    wrong.extend(stated_disagreements(&read("README.md")?, &read(MEASUREMENTS)?, printed)?);
    if !wrong.is_empty() {
        return fail(format!("figures:\n{}", wrong.join("\n")));
    }
    println!("figures: all {} within their budgets; the {} the docs state match", budgets.len(), STATED_FIGURES.len());
    Ok(())
}

fn bench_target(overwrite: bool) -> Result {
    ensure_target()?;
    let printed = measure_figures(overwrite)?;

    step("flash and RAM of the STM32F405 board example (whole image, release)");
    build_board()?;
    let tool = ensure_size_tool()?;
    let (t, d, b) = berkeley(&tool, &target_dir()?.join(TARGET).join("release").join(BOARD))?;
    println!("{BOARD}: text={t} data={d} bss={b}");
    println!("board_flash_bytes={}", t + d);
    println!("board_ram_bytes={}", d + b);

    check_figures(&printed)
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

/// The compensator's mutants (`--cfg qfa_mutant="NAME"`, in src/): each must make the oracle
/// property (host-tests/tests/oracle_property.rs) fail.
const ORACLE_MUTANTS: [(&str, &str); 5] = [
    ("reload_drops_state", "a reload restarts every model state, as before the fix"),
    ("branch_on_unready_rate", "the branch follows the slope of an unready rate window"),
    ("clamp_after_state_update", "the lag state follows the temperature before the clamp"),
    ("one_reading_delay", "each reading is evaluated with the window before it"),
    ("settling_never_flagged", "states started without their history are never flagged MODEL_SETTLING"),
];

/// The oracle property, long: `QFA_ORACLE_HISTORIES` histories in release.
fn oracle_property(histories: &str, seed: &str, mutant: Option<&str>) -> Result<(ExitStatus, String)> {
    let mut c = cargo();
    c.args(["test", "--release", "-p", "host-tests", "--test", "oracle_property", "--", "--nocapture"]);
    c.env("QFA_ORACLE_HISTORIES", histories).env("QFA_ORACLE_SEED", seed);
    if let Some(m) = mutant {
        // Its own target directory: RUSTFLAGS changes every crate's fingerprint.
        c.env("CARGO_TARGET_DIR", target_dir()?.join("oracle-mutants"))
            .env("RUSTFLAGS", format!("--cfg qfa_mutant=\"{m}\""))
            .env_remove("CARGO_ENCODED_RUSTFLAGS");
    }
    let (status, out, err) = capture(c)?;
    Ok((status, format!("{out}{err}")))
}

fn oracle(args: &[String]) -> Result {
    let value = |flag: &str, default: &str| {
        args.iter().position(|a| a == flag).and_then(|i| args.get(i + 1)).map_or(default.to_string(), Clone::clone)
    };
    let (histories, seed) = (value("--histories", "2000"), value("--seed", "1"));
    step(&format!("oracle property: {histories} histories, seed {seed}"));
    let start = Instant::now();
    let (status, out) = oracle_property(&histories, &seed, None)?;
    for l in out.lines().filter(|l| l.starts_with("silent_wrong_cycles=") || l.contains("silent wrong cycles; first:"))
    {
        println!("{l}");
    }
    println!("seconds={:.1}", start.elapsed().as_secs_f64());
    if !status.success() {
        return fail(format!("the oracle property failed:\n{out}"));
    }
    if !args.iter().any(|a| a == "--mutants") {
        return Ok(());
    }
    let mut caught = 0;
    for (m, what) in ORACLE_MUTANTS {
        step(&format!("mutant {m}: {what}"));
        let (status, out) = oracle_property(&histories, &seed, Some(m))?;
        let first =
            out.lines().find(|l| l.contains("silent wrong cycles; first:")).unwrap_or("(no failing cycle printed)");
        if status.success() {
            println!("NOT caught: the property held on {m}");
        } else {
            caught += 1;
            println!("caught: {}", first.trim());
            // The history proptest shrank the failure to, as a regression test would take it.
            if let Some(h) = out.lines().find(|l| l.contains("minimal failing input")) {
                println!("{}", h.trim());
            }
        }
    }
    println!("mutants_caught={caught} of {}", ORACLE_MUTANTS.len());
    if caught == ORACLE_MUTANTS.len() {
        Ok(())
    } else {
        fail("a mutant of the compensator passed the oracle property")
    }
}

/// A cargo command for the loom build: `--cfg loom` on every crate, in `dir` (its own
/// target directory, so the normal build cache keeps its flags).
fn loom_cargo(dir: &Path) -> Command {
    let mut c = cargo();
    c.env("CARGO_TARGET_DIR", dir).env("RUSTFLAGS", "--cfg loom").env_remove("CARGO_ENCODED_RUSTFLAGS");
    c
}

/// Build qfa-thermal's unit tests under `--cfg loom`, with `--cfg qfa_mutant="NAME"` on
/// qfa-thermal alone for a mutant (`cargo rustc`: a RUSTFLAGS change would rebuild every
/// dependency for each mutant); the test binary. The test profile: this workspace builds
/// qfa-thermal and every dependency at opt-level 2 there, without the release profile's
/// fat LTO on each of the seven builds, and with overflow checks on.
fn build_loom_model(dir: &Path, mutant: Option<&str>) -> Result<PathBuf> {
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
fn run_loom_model(exe: &Path) -> Result<(ExitStatus, String, Duration)> {
    let mut c = Command::new(exe);
    c.args([LOOM_MODEL, "--nocapture"]).env("RUST_BACKTRACE", "0");
    println!("$ {}", show(&c));
    let start = Instant::now();
    let (status, out, err) = capture(c)?;
    Ok((status, out + &err, start.elapsed()))
}

/// `N` of the harness's `test result: ... N passed; M failed` line.
fn count(out: &str, what: &str) -> Option<usize> {
    let result = out.lines().find(|l| l.starts_with("test result:"))?;
    result.split(';').find_map(|part| part.trim().strip_suffix(what)?.split_whitespace().last()?.parse().ok())
}

/// The clean model: built, run, and every one of its tests passed.
fn loom_model_passes(dir: &Path) -> Result {
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

fn loom() -> Result {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn alongside(script: &str, name: &str) -> Result<String> {
        let mut c = Command::new("sh");
        c.args(["-c", script]);
        Alongside::spawn(c, env::temp_dir().join(format!("xtask-alongside-{}-{name}.log", std::process::id())))?
            .finish()
    }

    /// The half run alongside: its output comes back on success; a non-zero exit fails the
    /// whole command, naming the status, and its output is still shown.
    #[test]
    fn a_half_run_alongside_passes_its_output_and_fails_the_run_when_it_fails() {
        let ok = alongside("echo target half; echo to stderr >&2", "ok").unwrap_or_else(|e| panic!("{e}"));
        assert!(ok.contains("target half") && ok.contains("to stderr"), "{ok}");
        let Err(e) = alongside("echo half way; exit 3", "fails") else { panic!("a failed half passed") };
        assert!(e.0.contains("exited with exit status: 3"), "{}", e.0);
    }

    fn budgets() -> Vec<(String, u64)> {
        match parse_budgets(include_str!("../budgets.txt")) {
            Ok(b) => b,
            Err(e) => panic!("{e}"),
        }
    }

    /// The checked-in budgets parse and name the four figures the firmware promises.
    #[test]
    fn the_budgets_file_names_the_promised_figures() {
        let names: Vec<String> = budgets().into_iter().map(|b| b.0).collect();
        for n in ["fast_path_insns_3axis", "slow_path_insns_3axis_all_on", "core_flash_bytes", "core_ram_bytes"] {
            assert!(names.iter().any(|m| m == n), "{n} missing from {names:?}");
        }
    }

    /// A figure one over its budget fails the check; at the budget it passes; a budget with
    /// no printed figure is an error, not a pass.
    #[test]
    fn a_figure_over_its_budget_fails() {
        let b = budgets();
        let at: String = b.iter().map(|(n, l)| format!("{n}={l}\n")).collect();
        assert!(matches!(over_budget(&b, &at), Ok(v) if v.is_empty()));
        for (name, limit) in &b {
            let broken: String =
                b.iter().map(|(n, l)| format!("{n}={}\n", if n == name { limit + 1 } else { *l })).collect();
            match over_budget(&b, &broken) {
                Ok(v) => assert_eq!(v.len(), 1, "{name}: {v:?}"),
                Err(e) => panic!("{e}"),
            }
        }
        assert!(over_budget(&b, "fast_path_insns_3axis=1\n").is_err());
    }

    /// A figure is written as the docs write it, and found only as a whole number.
    #[test]
    fn figures_are_written_and_found_whole() {
        assert_eq!(as_written("1980.5"), "1 980.5");
        assert_eq!(as_written("16056"), "16 056");
        assert_eq!(as_written("1016"), "1 016");
        assert_eq!(as_written("28.0"), "28");
        assert_eq!(as_written("453"), "453");
        assert!(holds_figure("| 28 instructions |", "28"));
        assert!(!holds_figure("| 128 instructions |", "28"));
        assert!(!holds_figure("| 28.5 instructions |", "28"));
        assert!(!holds_figure("| 1 980.5 |", "980.5"));
        assert!(!holds_figure("| 1 980 |", "1"));
        assert!(holds_figure("28 (45 with a misalignment matrix)", "45"));
    }

    /// The README and the measurements page pass when they give the printed figures, and a
    /// figure changed in either (or a row gone) fails, naming the key.
    #[test]
    fn a_stated_figure_that_differs_from_the_printed_one_fails() {
        let readme = "| [fast path, 3 axes, M4F](m) | 28 instructions (45 with a matrix) |\n\
                      | [slow path, every slot on](m) | 1 126.5 per reading (1 980.5 with one sensor) |\n\
                      | [RAM and flash of the core](m) | 1 016 B RAM, 14 400 B flash (16 056 loadable) |\n";
        let measurements = "| `fast_path_insns_3axis`, text | 28 | ≤ 32 |\n\
                            | `fast_path_insns_3axis_misalign` | 45 | ≤ 52 |\n\
                            | `slow_path_insns_sensor_per_axis` (text) | **1 126.5** | ≤ 1 160 |\n\
                            | `slow_path_insns_3axis_all_on` (status) | 1 980.5 (2 001.5 before) | ≤ 2 000 |\n\
                            | `core_ram_bytes` = size | **1 016** | ≤ 1 024 |\n\
                            | `core_flash_bytes_static_table` (text) | **14 400** | ≤ 14 848 |\n\
                            | `core_flash_bytes` (text) | 16 056 | ≤ 16 384 |\n";
        let printed = "fast_path_insns_3axis=28.0\nfast_path_insns_3axis_misalign=45.0\n\
                       slow_path_insns_sensor_per_axis=1126.5\nslow_path_insns_3axis_all_on=1980.5\n\
                       core_ram_bytes=1016\ncore_flash_bytes_static_table=14400\ncore_flash_bytes=16056\n";
        assert!(matches!(stated_disagreements(readme, measurements, printed), Ok(v) if v.is_empty()));
        for (key, _) in STATED_FIGURES {
            let moved: String = printed
                .lines()
                .map(|l| if l.starts_with(&format!("{key}=")) { format!("{key}=3\n") } else { format!("{l}\n") })
                .collect();
            match stated_disagreements(readme, measurements, &moved) {
                Ok(v) => assert!(v.len() == 2 && v.iter().all(|m| m.contains(key)), "{key}: {v:?}"),
                Err(e) => panic!("{e}"),
            }
        }
        let stale = measurements.replace("| 1 980.5 (", "| 2 001.5 (");
        assert!(matches!(stated_disagreements(readme, &stale, printed), Ok(v) if v.len() == 1));
        assert!(matches!(stated_disagreements("", measurements, printed), Ok(v) if v.len() == STATED_FIGURES.len()));
        assert!(stated_disagreements(readme, measurements, "core_ram_bytes=1016\n").is_err());
    }

    /// The checked-in docs have a row for every stated figure.
    #[test]
    fn the_docs_have_a_row_for_every_stated_figure() {
        let (readme, measurements) = (include_str!("../../README.md"), include_str!("../../docs/measurements.md"));
        for (key, row) in STATED_FIGURES {
            assert!(readme.lines().any(|l| l.starts_with(&format!("| {row}"))), "README.md: {row}");
            assert!(measurements.lines().any(|l| l.starts_with(&format!("| `{key}`"))), "{MEASUREMENTS}: {key}");
        }
    }

    const DEMO_LINES: &str = "demo: 3 axes\n  30 s +0.000012 ok\n  60 s +0.000015 ok\ndemo done\n";

    /// Identical output passes; one changed line fails, and the message names that line and
    /// shows both versions; a missing or an extra line fails too.
    #[test]
    fn a_changed_line_fails_the_comparison() {
        assert_eq!(first_difference(DEMO_LINES, DEMO_LINES), None);
        assert_eq!(first_difference(DEMO_LINES, &DEMO_LINES.replace('\n', "\r\n")), None);

        let changed = DEMO_LINES.replace("+0.000015", "+0.000016");
        let Some(message) = first_difference(DEMO_LINES, &changed) else { panic!("a changed line passed") };
        println!("{message}");
        assert!(message.starts_with("first difference at line 3 (1 of 4 lines differ"), "{message}");
        assert!(message.contains("\n    30 s +0.000012 ok\n"), "context line: {message}");
        assert!(message.ends_with("\n-   60 s +0.000015 ok\n+   60 s +0.000016 ok"), "{message}");

        let shorter = DEMO_LINES.replace("demo done\n", "");
        let Some(message) = first_difference(DEMO_LINES, &shorter) else { panic!("a missing line passed") };
        assert!(
            message.starts_with("first difference at line 4 ")
                && message.ends_with("+ (none: the text ends before this line)")
        );
        let longer = format!("{DEMO_LINES}panic: oops\n");
        assert!(first_difference(DEMO_LINES, &longer).is_some_and(|m| m.starts_with("first difference at line 5 ")));
    }

    /// The benchmark's decimal figures are masked and nothing else: a moved figure still
    /// matches, a renamed figure or a changed status word does not.
    #[test]
    fn only_measured_figures_are_masked() {
        let printed = "fast_path_insns_3axis=32.0\nexpf_libm_max_rel_err=6.21e-8\nslow_path_status_all_on=0x0100\n";
        let expected =
            "fast_path_insns_3axis=<measured>\nexpf_libm_max_rel_err=<measured>\nslow_path_status_all_on=0x0100\n";
        assert_eq!(normalise(printed, Figures::Measured), expected);
        assert_eq!(normalise(printed, Figures::None), printed);

        let moved = printed.replace("32.0", "33.0");
        assert_eq!(first_difference(expected, &normalise(&moved, Figures::Measured)), None);
        for broken in [printed.replace("fast_path_insns", "fast_insns"), printed.replace("0x0100", "0x0000")] {
            assert!(first_difference(expected, &normalise(&broken, Figures::Measured)).is_some(), "{broken}");
        }
    }
}
