//! Programs run on QEMU and their output against the `.out` snapshots in the repository.

use super::*;

/// What a program's output holds besides its behaviour.
#[derive(Clone, Copy)]
pub(super) enum Figures {
    /// Nothing: every line is compared as printed.
    None,
    /// Measurements in `name=value` lines, masked by [`normalise`].
    Measured,
}

/// A QEMU program and the file its console output is checked against.
pub(super) struct Snapshot {
    /// The ELF's name: the binary or example.
    pub(super) program: &'static str,
    /// The expected output, relative to the repository root: beside the program's source.
    pub(super) expected: &'static str,
    pub(super) figures: Figures,
    /// The single-program command that re-records it with `--overwrite` (`test` re-records all).
    pub(super) command: &'static str,
}

pub(super) const VECTORS_SNAPSHOT: Snapshot = Snapshot {
    program: "qemu_vectors",
    expected: "examples/qemu_vectors.out",
    figures: Figures::None,
    command: "test",
};
pub(super) const BENCH_SNAPSHOT: Snapshot =
    Snapshot { program: "bench", expected: "examples/bench.out", figures: Figures::Measured, command: "bench-target" };
pub(super) const DEMO_SNAPSHOT: Snapshot = Snapshot {
    program: DEMO_EXAMPLE,
    expected: "examples/qemu_demo.out",
    figures: Figures::None,
    command: "demo-qemu",
};

/// What a measured figure reads as in an expected file.
pub(super) const MEASURED: &str = "<measured>";

/// The one rule by which a checked output differs from the printed one. With
/// [`Figures::Measured`], the value of each `name=value` line that is a decimal number
/// becomes [`MEASURED`]: instruction counts, sizes and errors are deterministic under
/// `-icount`, but move with any change to the library or the compiler, and
/// `xtask/budgets.txt` and docs/measurements.md are where they are judged and recorded;
/// pinned here too, every such change would be re-recorded by reflex. What stays checked:
/// which figures are printed, in which order, and the non-decimal values (the status words
/// in hexadecimal). Lines end in `\n`.
pub(super) fn normalise(output: &str, figures: Figures) -> String {
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
pub(super) fn first_difference(expected: &str, printed: &str) -> Option<String> {
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
pub(super) fn check_snapshot(snapshot: &Snapshot, output: &str, overwrite: bool) -> Result {
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
pub(super) fn run_snapshot(snapshot: &Snapshot, kernel: &Path, icount: bool, overwrite: bool) -> Result<String> {
    let (status, out) = run_qemu(kernel, icount)?;
    if !status.success() {
        return fail(format!("{} exited with {status} (its output is above)", snapshot.program));
    }
    check_snapshot(snapshot, &out, overwrite)?;
    Ok(out)
}
