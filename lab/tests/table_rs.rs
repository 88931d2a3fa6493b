//! `qfa-lab table-rs` on the reference vectors' every-slot table writes exactly the source
//! checked in as `host-tests/tests/generated/ext_all_table.rs`, which `host-tests` compiles
//! and compares with the table's decoding; and a name that is no static's is refused.

use std::path::Path;
use std::process::Command;

#[test]
fn table_rs_writes_the_checked_in_source_and_refuses_a_bad_name() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let bytes = root.join("host-tests/fuzz-corpus/table/ext_all_valid.bin");
    let dir = std::env::temp_dir().join(format!("qfa-table-rs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // Copied so the header names the same file as the checked-in one.
    let table = dir.join("ext_all_valid.bin");
    std::fs::copy(&bytes, &table).unwrap();
    let out = dir.join("table.rs");
    let run = |name: &str| {
        Command::new(env!("CARGO_BIN_EXE_qfa-lab"))
            .args(["table-rs", "--table", table.to_str().unwrap(), "--out", out.to_str().unwrap(), "--name", name])
            .output()
            .expect("run qfa-lab")
    };
    let ok = run("EXT_ALL");
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let want = std::fs::read_to_string(root.join("host-tests/tests/generated/ext_all_table.rs")).unwrap();
    assert_eq!(std::fs::read_to_string(&out).unwrap(), want, "regenerate it with this command");
    let bad = run("table");
    assert_eq!(bad.status.code(), Some(2), "{}", String::from_utf8_lossy(&bad.stderr));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("upper case"));
    let _ = std::fs::remove_dir_all(&dir);
}
