//! `cargo xtask trace-target`: the paths of `examples/trace_paths.rs` under QEMU one
//! instruction at a time (`-singlestep -d exec,nochain`: one log line per executed
//! instruction), cut into segments at each call of its `marker` function, and each segment's
//! instructions attributed to the functions that ran them (the ELF's symbols, from `llvm-nm`
//! or `arm-none-eabi-nm`). The benchmark counts how many instructions a path takes; this says
//! where they go.

use std::collections::HashMap;

use super::*;

/// The traced example.
const EXAMPLE: &str = "trace_paths";

/// What each segment measures, and the calls it holds (the example's `READINGS` and
/// `CYCLES`).
const SEGMENTS: [(usize, &str, u32); 4] = [
    (1, "slow path, a sensor per axis, every slot on (per reading)", 30),
    (3, "slow path, one shared sensor, every slot on (per reading)", 30),
    (5, "slow path, one shared sensor, every slot off (per reading)", 30),
    (7, "fast path, 3 axes, no matrix (per cycle)", 100),
];

/// Functions shown per segment.
const TOP: usize = 12;

/// A symbol tool printing `address size type name` lines.
fn nm() -> Result<&'static str> {
    ["llvm-nm", "arm-none-eabi-nm"]
        .into_iter()
        .find(|t| found(t, "--version"))
        .map_or_else(|| fail("trace-target needs llvm-nm or arm-none-eabi-nm (apt-get install llvm)"), Ok)
}

/// The ELF's function symbols, sorted by address, names without their hash.
fn functions(elf: &Path) -> Result<Vec<(u32, String)>> {
    let mut c = Command::new(nm()?);
    c.args(["-n", "-C"]).arg(elf);
    let (status, out, err) = capture(c)?;
    if !status.success() {
        return fail(format!("nm {}: {err}", elf.display()));
    }
    let mut syms: Vec<(u32, String)> = out
        .lines()
        .filter_map(|l| {
            let mut it = l.splitn(3, ' ');
            let addr = u32::from_str_radix(it.next()?, 16).ok()?;
            let kind = it.next()?;
            let name = it.next()?;
            ["t", "T", "W"].contains(&kind).then(|| {
                let name = name.rsplit_once("::h").filter(|(_, h)| h.len() == 16).map_or(name, |(n, _)| n);
                (addr & !1, name.to_string())
            })
        })
        .collect();
    syms.sort();
    Ok(syms)
}

/// The program counter of a `-d exec` line: `Trace N: HOST [CS_BASE/PC/FLAGS/CFLAGS] …`.
fn pc_of(line: &str) -> Option<u32> {
    let fields = line.split_once('[')?.1.split_once(']')?.0;
    u32::from_str_radix(fields.split('/').nth(1)?, 16).ok()
}

pub(super) fn trace_target() -> Result {
    step("trace example (examples/trace_paths.rs), QEMU -singlestep -d exec");
    ensure_qemu()?;
    run(example_build(EXAMPLE))?;
    let elf = example_elf(EXAMPLE)?;
    let log = target_dir()?.join("trace_paths.exec.log");
    let mut c = qemu(&elf, false);
    c.args(["-singlestep", "-d", "exec,nochain", "-D"]).arg(&log);
    run(c)?;
    let syms = functions(&elf)?;
    let Some(marker) = syms.iter().find(|(_, n)| n.ends_with("trace_paths::target::marker")).map(|(a, _)| *a) else {
        return fail("no `marker` symbol in the trace example");
    };
    let name_of = |pc: u32| {
        let i = syms.partition_point(|(a, _)| *a <= (pc & !1));
        i.checked_sub(1).map_or("?", |i| syms[i].1.as_str())
    };
    let text = std::fs::read_to_string(&log).map_err(|e| Failure(format!("{}: {e}", log.display())))?;
    let mut segment = 0usize;
    let mut counts: HashMap<usize, HashMap<&str, u64>> = HashMap::new();
    for pc in text.lines().filter_map(pc_of) {
        if pc & !1 == marker {
            segment += 1;
        }
        *counts.entry(segment).or_default().entry(name_of(pc)).or_default() += 1;
    }
    for (segment, what, calls) in SEGMENTS {
        let Some(by_fn) = counts.get(&segment) else {
            return fail(format!("the trace has no segment {segment}"));
        };
        let total: u64 = by_fn.values().sum();
        println!(
            "\n{what}: {:.1} instructions, the timing loop and the marker included",
            total as f64 / f64::from(calls)
        );
        let mut rows: Vec<(&&str, &u64)> = by_fn.iter().collect();
        rows.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
        for (name, n) in rows.into_iter().take(TOP) {
            println!("  {:8.1}  {name}", *n as f64 / f64::from(calls));
        }
    }
    Ok(())
}
