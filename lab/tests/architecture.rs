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
