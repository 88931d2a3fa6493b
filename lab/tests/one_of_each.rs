//! The lab's concepts that decide its answers exist once. Each check reads the lab's
//! library sources (their test modules left out, inline or in a `tests.rs` their parent
//! declares under `#[cfg(test)]`) and names every place that breaks it.
//!
//! - The firmware's view of a log's temperatures (`qfa_log::replay`): the only module that
//!   constructs the rate estimator or turns a temperature into a DS18B20 code. The
//!   simulator's sensor quantizes on its own side of the seam (it is the sensor), so
//!   `lab/sim` is not searched for the rounding, nor the navigation study's fault injector,
//!   which adds a spike to the sensor's codes.
//! - Heating, cooling and holding: `replay::Motion` and the firmware's `Branch::next`, the
//!   only comparisons of a rate with the branch deadband.
//! - Least squares: `qfa_calibrate`'s solver module, the only place a matrix is factored or
//!   inverted for a fit. The navigation study's filters (`lab/nav`) are not fits and are not
//!   searched; discovery's change-point scan whitens by a Kalman filter and sums, and calls
//!   no factorization.
//! - Robust statistics: `qfa_log::robust`, the one median (the textbook one: the mean of
//!   the two middle values of an even count) and the one MAD-to-SD scale.
//! - Random draws: every seed a named stream of `qfa_rng::stream_seed`, and one
//!   Gauss–Markov process (`qfa_rng::GaussMarkov`).
//! - Errors are types: no public function of a lab library returns `Result<_, String>` (the
//!   command line's own value parsers, in the binary's `lab/src/cli_args.rs`, are clap's convention).
//! - Error enums hold types, not text: a `String` in a library error enum (`…Error`,
//!   `…Fault`) is a name or a value the user or the log gave (a column, a serial, a
//!   program, the text of a field), each listed below with its variant; any other is text
//!   built from an error, and this check names it.

use std::path::{Path, PathBuf};

/// Library sources under `dir`, each with its text up to its test module.
fn sources(dir: &Path) -> Vec<(PathBuf, String)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("a lab source folder").flatten() {
            let p = e.path();
            if p.is_dir() {
                if p.file_name().is_some_and(|n| n != "tests" && n != "examples") {
                    stack.push(p);
                }
            } else if p.file_name().is_some_and(|n| n == "tests.rs") {
                // A test module in a file of its own: its parent declares it under
                // `#[cfg(test)]`, or it would be library code and is read as such.
                if !declared_as_test_module(&p) {
                    out.push((p.clone(), std::fs::read_to_string(&p).expect("readable source")));
                }
            } else if p.extension().is_some_and(|x| x == "rs") && p.to_string_lossy().contains("/src/") {
                let text = std::fs::read_to_string(&p).expect("readable source");
                let library = without_test_modules(&text);
                out.push((p, library));
            }
        }
    }
    out
}

/// `text` without its `#[cfg(test)]` items (a test module, with its braces matched, or a
/// `mod tests;` line): library code after a test module is kept.
fn without_test_modules(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(at) = rest.find("\n#[cfg(test)]") {
        out.push_str(&rest[..at]);
        let item = &rest[at + "\n#[cfg(test)]".len()..];
        let (brace, semi) = (item.find('{'), item.find(';'));
        let end = match (brace, semi) {
            (Some(b), Some(s)) if s < b => s + 1,
            (Some(b), _) => {
                let mut depth = 0usize;
                let mut end = item.len();
                for (i, c) in item[b..].char_indices() {
                    match c {
                        '{' => depth += 1,
                        '}' => {
                            depth -= 1;
                            if depth == 0 {
                                end = b + i + 1;
                                break;
                            }
                        }
                        _ => {}
                    }
                }
                end
            }
            (None, Some(s)) => s + 1,
            (None, None) => item.len(),
        };
        rest = &item[end..];
    }
    out.push_str(rest);
    out
}

/// Whether `dir/tests.rs` is declared `#[cfg(test)] mod tests;` by its parent module,
/// `dir.rs` or `dir/mod.rs`.
fn declared_as_test_module(tests_rs: &Path) -> bool {
    let dir = tests_rs.parent().expect("a folder");
    [dir.with_extension("rs"), dir.join("mod.rs"), dir.join("lib.rs")]
        .iter()
        .filter_map(|p| std::fs::read_to_string(p).ok())
        .any(|t| t.contains("#[cfg(test)]\nmod tests;"))
}

fn lab() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).to_path_buf()
}

/// Lines of `files` (outside `allowed`) containing any of `needles`, as `file:line: text`.
fn offenders(files: &[(PathBuf, String)], needles: &[&str], allowed: &[&str]) -> Vec<String> {
    let mut out = Vec::new();
    for (p, text) in files {
        let rel = p.strip_prefix(lab()).unwrap_or(p).to_string_lossy().to_string();
        if allowed.iter().any(|a| rel == *a) {
            continue;
        }
        for (i, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            if needles.iter().any(|n| code.contains(n)) {
                out.push(format!("{rel}:{}: {}", i + 1, line.trim()));
            }
        }
    }
    out
}

#[test]
fn the_firmware_view_of_a_log_is_built_in_one_module() {
    let files = sources(&lab());
    assert!(files.len() > 50, "only {} lab sources found: the walk is broken", files.len());
    let estimator = offenders(&files, &["RateEstimator::new", "RateEstimator::<"], &["log/src/replay.rs"]);
    assert!(
        estimator.is_empty(),
        "the rate estimator is constructed outside qfa_log::replay:\n{}",
        estimator.join("\n")
    );
    let without_sim: Vec<_> = files.iter().filter(|(p, _)| !p.starts_with(lab().join("sim"))).cloned().collect();
    let rounding = offenders(
        &without_sim,
        &["* 16.0).round", "*16.0).round"],
        &["log/src/replay.rs", "nav/src/fault_injection.rs"],
    );
    assert!(
        rounding.is_empty(),
        "a temperature is rounded to a code outside qfa_log::replay:\n{}",
        rounding.join("\n")
    );
}

#[test]
fn heating_cooling_and_holding_are_told_apart_in_one_place() {
    let files = sources(&lab());
    let compare = offenders(&files, &["> deadband", "< -deadband", "> 0.05 {", "< -0.05 {"], &["log/src/replay.rs"]);
    assert!(compare.is_empty(), "a rate is classified outside replay::Motion:\n{}", compare.join("\n"));
    // A deadband by any name: the MEMS population's truth compared its rate with its own
    // named constant.
    let named: Vec<String> = offenders(&files, &["DEADBAND"], &["log/src/replay.rs"])
        .into_iter()
        .filter(|l| l.contains(" > ") || l.contains(" < -"))
        .collect();
    assert!(named.is_empty(), "a rate is classified outside replay::Motion:\n{}", named.join("\n"));
}

/// Every seed of the lab's library code is a named stream of `qfa_rng::stream_seed`, never
/// an offset or an XOR of another seed (which collided: a Monte Carlo run's IMU errors drew
/// its variation's numbers, two logs' runs shared noise).
#[test]
fn seeds_come_from_named_streams() {
    let files = sources(&lab());
    let derived = offenders(&files, &["seed ^", "seed.wrapping_add(", "seed + ", "+ seed)"], &[]);
    assert!(derived.is_empty(), "a seed derived by arithmetic:\n{}", derived.join("\n"));
}

/// The Gauss–Markov process is stepped in one place (`qfa_rng::GaussMarkov`): its innovation
/// `√(1 − φ²)` was written out in the simulator, the navigation study and discovery's null.
#[test]
fn the_gauss_markov_process_is_written_once() {
    let files = sources(&lab());
    let copies = offenders(&files, &["(1.0 - phi * phi).sqrt()", "(1.0 - phi * phi).max(0.0).sqrt()"], &[]);
    assert!(copies.is_empty(), "a Gauss–Markov step outside qfa_rng:\n{}", copies.join("\n"));
}

#[test]
fn least_squares_are_solved_in_one_module() {
    let files: Vec<_> = sources(&lab()).into_iter().filter(|(p, _)| !p.starts_with(lab().join("nav"))).collect();
    let solves = offenders(
        &files,
        &[".svd(", ".qr()", "pseudo_inverse", "try_inverse", ".cholesky()", ".lu()", "solve_lower_triangular"],
        &["calibrate/src/solver.rs"],
    );
    assert!(solves.is_empty(), "a least-squares problem is solved outside the solver:\n{}", solves.join("\n"));
}

#[test]
fn no_public_function_returns_its_error_as_text() {
    let files: Vec<_> = sources(&lab())
        .into_iter()
        .filter(|(p, _)| !p.ends_with("src/main.rs") && !p.ends_with("src/cli_args.rs"))
        .collect();
    let mut found = Vec::new();
    for (p, text) in &files {
        // A public signature, possibly over several lines, up to its body.
        for (i, _) in text.match_indices("pub fn ") {
            let sig = &text[i..text[i..].find('{').map_or(text.len(), |e| i + e)];
            let flat: String = sig.split_whitespace().collect::<Vec<_>>().join(" ");
            if flat.contains("-> Result<") && flat.trim_end().ends_with(", String>") {
                let line = text[..i].lines().count() + 1;
                found.push(format!("{}:{line}: {flat}", p.strip_prefix(lab()).unwrap_or(p).display()));
            }
        }
    }
    assert!(found.is_empty(), "public functions returning their error as a String:\n{}", found.join("\n"));
}

#[test]
fn the_median_and_its_scale_are_defined_once() {
    let files = sources(&lab());
    let copies = offenders(&files, &["fn median(", "1.4826", "MAD_TO_SD *"], &["log/src/robust.rs"]);
    assert!(copies.is_empty(), "a median or the MAD's scale outside qfa_log::robust:\n{}", copies.join("\n"));
}

/// The `String` fields of library error enums that hold a name or a value the user or the
/// log gave, not a message: `Enum::Variant`. The last holds text from elsewhere and is
/// listed apart.
const NAMES_AND_VALUES: &[&str] = &[
    "BatchError::Shard",
    "BatchError::MergeClash",
    "ManifestFault::Setting",
    "ManifestFault::NoLog",
    "ManifestFault::OverridesFlag",
    "ChamberFault::DuplicateColumn",
    "ChamberFault::NoNamedTimeColumn",
    "ChamberFault::SeveralTimeColumns",
    "ChamberFault::UnitColumns",
    "ChamberFault::CyclingUnit",
    "SerialFault::NotAFolderName",
    "SerialFault::Shared",
    "UnitFault::Descriptor",
    "PriorError::NoPopulation",
    "PriorError::NotInvertible",
    "CoverageError::NoValidRow",
    "FitError::NoPair",
    "FitError::NotInLog",
    "CalibrateError::Axis",
    "StaticCalError::UnknownHoldout",
    "StaticCalError::Fit",
    "StaticCalError::StuckAxis",
    "ContentFault::StuckPulses",
    "ContentFault::NegativeScaleFactor",
    "FigureFault::NoModelOutput",
    "FigureFault::NonFinite",
    "FigureFault::NoCandidate",
    "DiscoverError::UnknownStart",
    "DiscoverError::NoModel",
    "RowFault::Header",
    "RowFault::Field",
    "DataflashError::NoImu",
    "StaticRowFault::NotANumber",
    "StaticError::UnknownColumn",
    "StaticError::MissingColumn",
    "StaticError::BadColumnSpec",
    "StaticError::UnitUnknown",
    "StaticError::DecimalComma",
    "UlogError::NoAccel",
    "CalibError::LabProgram",
    "CalibError::ValidationFit",
    "CalibError::HeldOut",
    "CalibError::Figures",
    "CalibError::Fit",
    "FaultsError::ReplacedTable",
    "ReportError::Flags",
    "SummaryError::Column",
    "LimitsError::NoneApply",
    "ProfileError::Header",
    "ProfileError::Row",
    "TruthError::UnknownEffect",
    // Text from elsewhere: each refused autopilot instance's reason as its report records it.
    "AutopilotCalError::NothingCalibrated",
];

/// `Enum::Variant` of every field typed `String` (alone, in a `Vec`, an `Option` or an
/// array) in the `pub enum …Error` and `pub enum …Fault` blocks of `text`.
fn string_fields_of_error_enums(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(at) = rest.find("pub enum ") {
        rest = &rest[at + "pub enum ".len()..];
        let name: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
        let Some(open) = rest.find('{') else { break };
        let (mut depth, mut end) = (0usize, open);
        for (i, c) in rest[open..].char_indices() {
            match c {
                '{' => depth += 1,
                '}' => depth -= 1,
                _ => {}
            }
            if depth == 0 {
                end = open + i;
                break;
            }
        }
        if name.ends_with("Error") || name.ends_with("Fault") {
            let mut variant = String::new();
            for line in rest[open + 1..end].lines() {
                let code = line.trim();
                if code.starts_with("//") || code.starts_with('#') {
                    continue;
                }
                // A variant starts at the enum's own indentation (four spaces).
                if line.starts_with("    ") && !line.starts_with("     ") {
                    variant = code.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
                }
                let typed = code.split_once(':').map_or(code, |(_, t)| t);
                if typed.contains("String") || code.contains("(String") {
                    out.push(format!("{name}::{variant}"));
                }
            }
        }
        rest = &rest[end..];
    }
    out.dedup();
    out
}

#[test]
fn error_enums_hold_types_and_names_not_messages() {
    let files: Vec<_> = sources(&lab()).into_iter().filter(|(p, _)| !p.starts_with(lab().join("src"))).collect();
    let all: Vec<String> = files.iter().flat_map(|(_, text)| string_fields_of_error_enums(text)).collect();
    assert!(all.len() >= 30, "only {} `String` fields found: the scan is broken", all.len());
    let messages: Vec<&String> = all.iter().filter(|v| !NAMES_AND_VALUES.contains(&v.as_str())).collect();
    assert!(messages.is_empty(), "error variants holding text built from an error:\n{messages:#?}");
    let gone: Vec<&&str> = NAMES_AND_VALUES.iter().filter(|n| !all.iter().any(|v| v == *n)).collect();
    assert!(gone.is_empty(), "listed variants that no longer hold a `String`: take them off the list\n{gone:#?}");
}
