use super::*;

fn alongside(script: &str, name: &str) -> Result<String> {
    let mut c = Command::new("sh");
    c.args(["-c", script]);
    Alongside::spawn(c, env::temp_dir().join(format!("xtask-alongside-{}-{name}.log", std::process::id())))?.finish()
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

/// The longest a source file may be: past it, a file holds more than one idea and is split
/// along them (the repository's layout is its architecture).
const MAX_SOURCE_LINES: usize = 700;

/// Every Rust source file of the repository (build output and hidden folders left out).
fn rust_sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).expect("a readable folder").flatten() {
        let p = e.path();
        let name = e.file_name().to_string_lossy().to_string();
        if p.is_dir() {
            if name != "target" && !name.starts_with('.') {
                rust_sources(&p, out);
            }
        } else if name.ends_with(".rs") {
            out.push(p);
        }
    }
}

/// No source file is over [`MAX_SOURCE_LINES`] lines; the check reads this repository's
/// own files, so a long file added anywhere fails it.
#[test]
fn no_source_file_is_over_its_line_limit() {
    let mut files = Vec::new();
    rust_sources(&root(), &mut files);
    assert!(files.len() > 100, "the walk found the sources: {}", files.len());
    let long: Vec<String> = files
        .iter()
        .filter_map(|p| {
            let n = std::fs::read_to_string(p).expect("readable source").lines().count();
            (n > MAX_SOURCE_LINES).then(|| format!("{}: {n} lines", p.strip_prefix(root()).unwrap_or(p).display()))
        })
        .collect();
    assert!(long.is_empty(), "over {MAX_SOURCE_LINES} lines:\n{}", long.join("\n"));
}
