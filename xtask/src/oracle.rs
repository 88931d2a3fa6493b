//! `cargo xtask oracle`: the oracle property (host-tests/tests/oracle_property.rs: the
//! guide's oracle and the unit's physics) over many histories, and its mutants.

use std::process::ExitStatus;
use std::time::Instant;

use super::{capture, cargo, fail, step, target_dir, Result};

/// The compensator's mutants (`--cfg qfa_mutant="NAME"`, in src/): each must make the oracle
/// property (host-tests/tests/oracle_property.rs) fail.
const ORACLE_MUTANTS: [(&str, &str); 6] = [
    ("reload_drops_state", "a reload restarts every model state, as before the fix"),
    ("branch_on_unready_rate", "the branch follows the slope of an unready window, at the full window's floor"),
    ("clamp_before_state_update", "the lag state follows the temperature held to the range (the old rule)"),
    ("full_window_floor", "the branch decides on a partial window at the full window's floor (the old rule)"),
    ("one_reading_delay", "each reading is evaluated with the window before it"),
    ("settling_never_flagged", "states started without their history are never flagged MODEL_SETTLING"),
];

/// A failing property's line naming its first wrong cycle (against the guide's oracle or
/// the unit's physics).
fn is_first_wrong(line: &str) -> bool {
    line.contains("silent wrong cycles") && line.contains("first:")
}

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

pub(super) fn oracle(args: &[String]) -> Result {
    let value = |flag: &str, default: &str| {
        args.iter().position(|a| a == flag).and_then(|i| args.get(i + 1)).map_or(default.to_string(), Clone::clone)
    };
    let (histories, seed) = (value("--histories", "2000"), value("--seed", "1"));
    step(&format!("oracle property: {histories} histories, seed {seed}"));
    let start = Instant::now();
    let (status, out) = oracle_property(&histories, &seed, None)?;
    for l in out.lines().filter(|l| l.starts_with("silent_wrong_cycles=") || is_first_wrong(l)) {
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
        let first = out.lines().find(|l| is_first_wrong(l)).unwrap_or("(no failing cycle printed)");
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
