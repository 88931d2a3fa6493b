//! Re-record the reference vectors: `cargo run -p host-tests --bin record`.
//!
//! Regenerates every `replay/vectors/*.vec` from `host_tests::scenarios` with the
//! current code. Review the result as a diff: any changed bit shows up line by line.

use std::fmt::Write as _;
use std::path::Path;

fn main() {
    // The vectors live with their replay (`replay/vectors`), which both targets use.
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../replay/vectors");
    std::fs::create_dir_all(&dir).expect("create vectors dir");
    let mut total = 0;
    for (name, lines) in host_tests::scenarios::all() {
        let text = lines.join("\n");
        let mut outputs: Vec<String> = Vec::new();
        let n = qfa_replay::replay(name, &text, false, &mut |s| {
            let mut o = String::new();
            for w in s.computed {
                let _ = write!(o, " {w:08x}");
            }
            outputs.push(o);
        })
        .unwrap_or_else(|e| panic!("{name}: {e:?}"));
        let mut out = String::new();
        let mut it = outputs.into_iter();
        for line in &lines {
            if line.trim_start().starts_with('#') || line.trim().is_empty() {
                out.push_str(line);
            } else {
                let o = it.next().expect("one output per event line");
                let _ = write!(out, "{line} =>{o}");
            }
            out.push('\n');
        }
        std::fs::write(dir.join(name), out).expect("write vector file");
        println!("{name}: {n} vectors");
        total += n;
    }
    println!("{total} vectors recorded");
}
