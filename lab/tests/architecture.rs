//! docs/architecture.md's crate table is what Cargo resolves: every workspace crate is
//! listed once, in the folder its manifest is in, with exactly the workspace crates it
//! depends on (normal dependencies, `cargo metadata --no-deps`). A crate added, moved or
//! given a new dependency without the table changing fails here, naming the row.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// `crate → (folder, workspace crates it uses)` from the table under "## Today".
fn documented(doc: &str) -> BTreeMap<String, (String, BTreeSet<String>)> {
    let mut out = BTreeMap::new();
    let section = doc.split("\n## Today").nth(1).expect("a \"## Today\" section");
    for line in section.lines().skip_while(|l| !l.starts_with("| crate")).skip(2) {
        if !line.starts_with('|') {
            break;
        }
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        let ticked = |s: &str| s.split('`').skip(1).step_by(2).map(str::to_string).collect::<Vec<_>>();
        let names = ticked(cells[1]);
        let (name, folder) = (names[0].clone(), names[1].trim_end_matches('/').to_string());
        let uses = ticked(cells[2]).into_iter().collect();
        assert!(out.insert(name.clone(), (folder, uses)).is_none(), "{name} is listed twice");
    }
    out
}

/// The same from `cargo metadata`.
fn resolved(root: &Path) -> BTreeMap<String, (String, BTreeSet<String>)> {
    let cargo = option_env!("CARGO").unwrap_or("cargo");
    let out = std::process::Command::new(cargo)
        .current_dir(root)
        .args(["metadata", "--format-version", "1", "--no-deps", "--offline"])
        .output()
        .expect("cargo metadata runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).expect("cargo metadata's JSON");
    let packages = meta["packages"].as_array().expect("packages");
    let members: BTreeSet<String> = packages.iter().map(|p| p["name"].as_str().unwrap().to_string()).collect();
    packages
        .iter()
        .map(|p| {
            let manifest = Path::new(p["manifest_path"].as_str().unwrap());
            let dir = manifest.parent().unwrap().strip_prefix(root).unwrap().to_string_lossy().to_string();
            let folder = if dir.is_empty() { "src".to_string() } else { dir };
            let uses = p["dependencies"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|d| d["kind"].is_null())
                .map(|d| d["name"].as_str().unwrap().to_string())
                .filter(|n| members.contains(n))
                .collect();
            (p["name"].as_str().unwrap().to_string(), (folder, uses))
        })
        .collect()
}

#[test]
fn the_crate_table_is_what_cargo_resolves() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("the repository");
    let doc = std::fs::read_to_string(root.join("docs/architecture.md")).expect("docs/architecture.md");
    let (doc, cargo) = (documented(&doc), resolved(root));
    assert!(cargo.len() >= 10, "cargo metadata lists {} crates", cargo.len());
    let mut wrong = Vec::new();
    for (name, (folder, uses)) in &cargo {
        match doc.get(name) {
            None => wrong.push(format!("{name} ({folder}/) is not in the table")),
            Some((f, u)) => {
                if f != folder {
                    wrong.push(format!("{name}: the table says `{f}/`, its manifest is in `{folder}/`"));
                }
                if u != uses {
                    wrong.push(format!("{name}: the table says it uses {u:?}, Cargo resolves {uses:?}"));
                }
            }
        }
    }
    for name in doc.keys().filter(|n| !cargo.contains_key(*n)) {
        wrong.push(format!("{name} is in the table but not in the workspace"));
    }
    assert!(wrong.is_empty(), "docs/architecture.md's crate table:\n{}", wrong.join("\n"));
}

/// Lines of every `.rs` file under `dir`.
fn rust_lines(dir: &Path) -> usize {
    let mut n = 0;
    for entry in std::fs::read_dir(dir).expect("a crate folder").map(|e| e.expect("a folder entry").path()) {
        if entry.is_dir() {
            n += rust_lines(&entry);
        } else if entry.extension().is_some_and(|e| e == "rs") {
            n += std::fs::read_to_string(&entry).expect("a source file").lines().count();
        }
    }
    n
}

/// The lab's crates whose `src/` is over `limit` lines, with their counts.
fn lab_crates_over(root: &Path, limit: usize) -> Vec<String> {
    resolved(root)
        .into_iter()
        .filter(|(_, (folder, _))| folder == "lab" || folder.starts_with("lab/"))
        .map(|(name, (folder, _))| (name, rust_lines(&root.join(folder).join("src"))))
        .filter(|(_, lines)| *lines > limit)
        .map(|(name, lines)| format!("{name}: {lines} lines in src/"))
        .collect()
}

/// A lab crate is one product: its `src/` (the code and its unit tests; the lab's
/// end-to-end tests in `lab/tests/` are counted apart) stays under 8 000 lines. Today the
/// largest are `qfa-discover` and `qfa-calibrate`, about 7 400 each; at a limit of 7 000 this
/// test names both.
#[test]
fn no_lab_crate_is_over_8000_lines() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("the repository");
    assert!(lab_crates_over(root, 1000).len() >= 5, "the walk finds too few lab crates over 1 000 lines");
    let over = lab_crates_over(root, 8000);
    assert!(over.is_empty(), "lab crates over 8 000 lines:\n{}", over.join("\n"));
}

/// Every lab library crate is built at opt-level 2 in the dev profile (`.cargo/config.toml`):
/// the lab's tests spend their time in these crates' numerics, several times slower at
/// opt-level 0 (discovery's unit tests took 123 s instead of 30 when its new crate was left
/// off the list).
#[test]
fn every_lab_library_is_optimized_in_the_tests() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("the repository");
    let config = std::fs::read_to_string(root.join(".cargo/config.toml")).expect(".cargo/config.toml");
    let optimized = |name: &str| config.contains(&format!("[profile.dev.package.{name}]\nopt-level = 2\n"));
    let missing: Vec<String> = resolved(root)
        .into_iter()
        .filter(|(_, (folder, _))| folder.starts_with("lab/") || folder == "rng")
        .map(|(name, _)| name)
        .filter(|name| !optimized(name))
        .collect();
    assert!(optimized("qfa-calibrate"), "the check reads .cargo/config.toml wrongly");
    assert!(missing.is_empty(), "lab crates at opt-level 0 in the tests (add them to .cargo/config.toml): {missing:?}");
}

/// `(file, function)` of every lab and `rng` function over 80 lines, by the page's rule: a
/// function runs from its `fn` line (not a declaration ending in `;`) to the first line that
/// is only `}` at the `fn` line's indent, end-to-end tests (`tests/` folders) left out.
fn functions_over_80_lines(root: &Path) -> BTreeSet<(String, String)> {
    let mut out = BTreeSet::new();
    let mut stack = vec![root.join("lab"), root.join("rng")];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("a source folder").flatten() {
            let p = e.path();
            let name = p.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
            if p.is_dir() {
                if name != "tests" && name != "target" {
                    stack.push(p);
                }
                continue;
            }
            if !name.ends_with(".rs") {
                continue;
            }
            let text = std::fs::read_to_string(&p).expect("readable source");
            let mut open: Option<(usize, usize, String)> = None;
            for (i, line) in text.lines().enumerate() {
                let indent = line.len() - line.trim_start().len();
                let code = line.trim_start();
                let head = ["pub(crate) ", "pub(super) ", "pub ", ""]
                    .iter()
                    .find_map(|v| code.strip_prefix(v))
                    .map(|c| c.strip_prefix("const ").unwrap_or(c))
                    .and_then(|c| c.strip_prefix("fn "));
                if let (None, Some(h)) = (&open, head) {
                    let f: String = h.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
                    if !f.is_empty() && !line.trim_end().ends_with(';') {
                        open = Some((i, indent, f));
                    }
                } else if let Some((start, at, f)) = &open {
                    if code == "}" && indent == *at {
                        if i - start + 1 > 80 {
                            let rel = p.strip_prefix(root).unwrap_or(&p).to_string_lossy().to_string();
                            out.insert((rel, f.clone()));
                        }
                        open = None;
                    }
                }
            }
        }
    }
    out
}

/// The functions over 80 lines are the ones docs/architecture.md names (each as
/// `` `file` `function` `` in the list under "Functions over 80 lines"): a function that grows
/// past it, or one split without the page changing, fails here.
#[test]
fn the_functions_over_80_lines_are_the_ones_the_page_names() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("the repository");
    let page = std::fs::read_to_string(root.join("docs/architecture.md")).expect("docs/architecture.md");
    let list = page.split("Functions over 80 lines").nth(1).expect("the page's list of long functions");
    let named: BTreeSet<(String, String)> = list
        .lines()
        .skip(1)
        .take_while(|l| l.starts_with("- "))
        .filter_map(|l| {
            let mut ticks = l.split('`').skip(1).step_by(2);
            Some((ticks.next()?.to_string(), ticks.next()?.to_string()))
        })
        .collect();
    let found = functions_over_80_lines(root);
    assert!(found.len() >= 3, "the walk finds too few long functions: {found:?}");
    assert_eq!(found, named, "functions over 80 lines (left) against the page's list (right)");
}
